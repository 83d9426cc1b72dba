//! The kinematic family's candidates: fixed effects, searched periods, groups.

use super::*;

/// A candidate effect: a fixed one, a periodic joint error whose period is searched, or a group
/// of fixed effects of one kind tested together (compliance on every loaded joint: an effect
/// spread over several joints, each too small to pass alone).
#[derive(Clone, Debug, PartialEq)]
pub(in crate::diagnose::kinematic) enum Cand {
    Fixed(EffectSpec),
    Periodic { joint: usize },
    Group(Vec<EffectSpec>),
}

/// The effects of an accepted candidate, flattened in order.
pub(in crate::diagnose::kinematic) fn flatten(sets: &[Vec<EffectSpec>]) -> Vec<EffectSpec> {
    sets.iter().flatten().cloned().collect()
}

impl Cand {
    pub(in crate::diagnose::kinematic) fn name(&self) -> &'static str {
        match self {
            Cand::Fixed(s) => s.name(),
            Cand::Periodic { .. } => "periodic_joint_error",
            Cand::Group(v) => v.first().map_or("group", |s| s.name()),
        }
    }
    pub(in crate::diagnose::kinematic) fn joints(&self) -> Vec<usize> {
        match self {
            Cand::Fixed(s) => s.joints_reported(),
            Cand::Periodic { joint } => vec![*joint],
            Cand::Group(v) => v.iter().flat_map(|s| s.joints_reported()).collect(),
        }
    }
    /// Free parameters (a periodic error's period counts: it is searched).
    pub(in crate::diagnose::kinematic) fn n_params(&self) -> usize {
        match self {
            Cand::Fixed(s) => s.scales().len(),
            Cand::Periodic { .. } => 3,
            Cand::Group(v) => v.iter().map(|s| s.scales().len()).sum(),
        }
    }
    /// The effects of a candidate whose period (if searched) is `f`.
    pub(in crate::diagnose::kinematic) fn specs(&self, f: Option<f64>) -> Option<Vec<EffectSpec>> {
        match self {
            Cand::Fixed(s) => Some(vec![s.clone()]),
            Cand::Periodic { joint } => f.map(|f| vec![Ctx::periodic_spec(*joint, f)]),
            Cand::Group(v) => Some(v.clone()),
        }
    }
    pub(in crate::diagnose::kinematic) fn label(&self) -> String {
        match self {
            Cand::Group(v) => format!(
                "{} on joints {} together",
                self.name(),
                v.iter().filter_map(|s| s.joint()).map(|j| j.to_string()).collect::<Vec<_>>().join(", ")
            ),
            Cand::Fixed(EffectSpec::TimeDrift) => "thermal_expansion (lengths drift with time)".into(),
            Cand::Fixed(EffectSpec::ThermalExpansion { .. }) => "thermal_expansion (lengths follow temp_c)".into(),
            Cand::Fixed(EffectSpec::PeriodicJointError { joint, period_si }) => format!(
                "periodic_joint_error on joint {joint} ({:.0} per revolution)",
                std::f64::consts::TAU / period_si
            ),
            Cand::Periodic { joint } => format!("periodic_joint_error on joint {joint} (period searched)"),
            Cand::Fixed(EffectSpec::Custom(e)) => match e.joint() {
                Some(j) => format!("{} on joint {j}", e.name()),
                None => e.name().to_string(),
            },
            Cand::Fixed(EffectSpec::LinkCompliance { link }) => {
                format!("link_compliance on link {link} (between joints {link} and {})", link + 1)
            }
            Cand::Fixed(EffectSpec::CoupledTransmission { joint, driver }) => {
                format!("coupled_transmission on joint {joint} (driven by joint {driver})")
            }
            c => format!("{} on joint {}", c.name(), c.joints().first().copied().unwrap_or(0)),
        }
    }
    /// Whether an accepted effect rules this candidate out (same kind and joint, or the other
    /// form of the length change).
    pub(in crate::diagnose::kinematic) fn covered_by(&self, s: &EffectSpec) -> bool {
        let length = |e: &EffectSpec| matches!(e, EffectSpec::ThermalExpansion { .. } | EffectSpec::TimeDrift);
        if let (
            Cand::Fixed(EffectSpec::PeriodicJointError { joint, .. }),
            EffectSpec::PeriodicJointError { joint: j, .. },
        ) = (self, s)
        {
            return joint == j;
        }
        if let (Cand::Fixed(a @ EffectSpec::Custom(_)), b) = (self, s) {
            return a == b;
        }
        if let (Cand::Fixed(EffectSpec::LinkCompliance { link }), EffectSpec::LinkCompliance { link: l }) = (self, s) {
            return link == l;
        }
        if let (Cand::Fixed(a @ EffectSpec::CoupledTransmission { .. }), b @ EffectSpec::CoupledTransmission { .. }) =
            (self, s)
        {
            return a == b;
        }
        match self {
            Cand::Fixed(c) => {
                (length(c) && length(s))
                    || (std::mem::discriminant(c) == std::mem::discriminant(s) && c.joint() == s.joint())
            }
            Cand::Periodic { joint } => {
                matches!(s, EffectSpec::PeriodicJointError { joint: j, .. } if j == joint)
            }
            Cand::Group(v) => v.iter().any(|m| Cand::Fixed(m.clone()).covered_by(s)),
        }
    }
}

/// Linear cross-validation of one candidate.
pub(in crate::diagnose::kinematic) struct LinScore {
    /// Per analysis row: whitened held-out squared error before minus after.
    pub(in crate::diagnose::kinematic) d: Vec<f64>,
    /// Per analysis row: whitened held-out residual after.
    pub(in crate::diagnose::kinematic) e1: Vec<Vector3<f64>>,
    /// Per fold: the candidate's parameters.
    pub(in crate::diagnose::kinematic) theta_folds: Vec<DVector<f64>>,
    /// Per fold: the chosen frequency (periodic candidates).
    pub(in crate::diagnose::kinematic) freq_folds: Vec<f64>,
}

/// Everything a step needs about the analysis rows.
pub(in crate::diagnose::kinematic) struct Ctx<'a> {
    pub(in crate::diagnose::kinematic) model: &'a RobotModel,
    pub(in crate::diagnose::kinematic) rows: Vec<&'a PoseMeasurement>,
    pub(in crate::diagnose::kinematic) sigma: Vec<f64>,
    pub(in crate::diagnose::kinematic) folds_idx: Vec<Vec<usize>>,
    pub(in crate::diagnose::kinematic) kinds: Vec<JointKind>,
    pub(in crate::diagnose::kinematic) names: Vec<String>,
    pub(in crate::diagnose::kinematic) opts: &'a DiagnoseOptions,
    pub(in crate::diagnose::kinematic) ref_temp_c: f64,
    pub(in crate::diagnose::kinematic) grids: Vec<Vec<f64>>,
}
