//! Missing-physics diagnosis: where a calibrated geometric model and a recording disagree,
//! which physical effect left out of the model explains it, and how much better the held-out fit
//! gets once it is modelled (the JSON contract is `shared/spec/diagnose.md`).
//!
//! # Method
//! 1. The rows are split into analysis rows and validation rows (the recording's `split` column,
//!    else every `1 / validation_fraction`-th row). Validation rows are used for nothing but the
//!    reported `heldout_*` figures: not to fit, not to choose.
//! 2. The identifiable geometric model (device frame, tool offset, joint offsets, the model's
//!    default parameter set; positions only) is fitted on the analysis rows; residuals are
//!    whitened by each row's `sigma` (or [`DiagnoseOptions::sigma_position_m`]).
//! 3. Every candidate effect (each kind of [`EffectSpec`] on each joint where it applies; a
//!    periodic error with its period searched over a grid inside each training fold) is refitted
//!    JOINTLY with the geometric parameters on the training folds of a K-fold split of the
//!    analysis rows and scored on the held-out fold. A linearised refit at the current solution
//!    (the Gauss-Newton step of the full refit, see `linear.rs`) ranks all candidates; the best
//!    ones are then checked in this order:
//!    (c) identifiability: the smallest principal angle between the effect's Jacobian columns
//!    and the span of the geometric Jacobian (reject when its sine is below
//!    [`DiagnoseOptions::min_sin_angle`]: the effect would be a combination of geometric
//!    parameters);
//!    (d) physical plausibility of sign and size ([`Bounds`]);
//!    (b) stability over the folds (same sign in every fold, jackknife spread below half the
//!    value; for a periodic error the same period and amplitude);
//!    (a) significance with full non-linear refits of geometry plus effect on each training
//!    fold: a one-sided paired t test over the held-out poses of the squared errors before
//!    and after, corrected for the candidates tried in the step (weighted Bonferroni: each kind
//!    of effect gets an equal share of `alpha`, split equally among its candidates), and
//!    a held-out improvement of at least [`DiagnoseOptions::min_improvement`].
//!    The first candidate that passes is added to the model, everything is refitted and the
//!    search repeats; it stops when nothing passes.
//! 4. The held-out residuals are screened against every recorded input (joint angles, gravity
//!    torque per joint, approach directions, time, temperature, payload) by a weighted one-way
//!    analysis of variance over bins of the input, of each joint's implied angle error and of
//!    the implied relative length change; what stays significant after the accepted effects is
//!    reported as unexplained structure with the inputs it depends on.
//!
//! A candidate whose inputs the recording lacks (no `dir`, `temp_c`, `t_s`) is untestable and
//! said so; with too few poses for held-out scoring nothing is claimed.

pub mod camera;
pub mod force;
mod linear;
pub mod stats;

use std::collections::BTreeMap;

use ferrocal_robot::{JointKind, Kinematics, RobotModel};
use nalgebra::{DVector, Vector3};
use serde::{Deserialize, Serialize};

use crate::effects::EffectSpec;
use crate::error::{CalibError, Result};
use crate::kinematic::{calibrate, KinematicCalibration, KinematicOptions, ModelParams};
use crate::lsq::LmOptions;
use crate::measurement::{PoseMeasurement, Split};
use linear::{heldout_with, joint_fit, sin_angle, Basis, Fold, Lin, PeriodScan};
use stats::{binned_anova, bonferroni, paired_test, quantile_groups};

/// Physical plausibility bounds of the candidate effects.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Bounds {
    /// Largest joint deflection under load a compliance may cause, revolute joints.
    pub max_deflection_rad: f64,
    /// Largest deflection of a prismatic joint.
    pub max_deflection_m: f64,
    /// Largest backlash (dead band) of a revolute joint.
    pub max_backlash_rad: f64,
    /// Largest backlash of a prismatic joint.
    pub max_backlash_m: f64,
    /// Largest relative scale error of a joint reading.
    pub max_scale_error: f64,
    /// Largest amplitude of a periodic error, revolute joints.
    pub max_periodic_rad: f64,
    /// Largest amplitude of a periodic error, prismatic joints.
    pub max_periodic_m: f64,
    /// Range of thermal expansion coefficients accepted (metals: Invar about 1.2e-6 to zinc
    /// about 30e-6 per K).
    pub thermal_alpha_per_k: [f64; 2],
    /// Largest relative length drift per hour (a warm-up without a temperature reading).
    pub max_drift_per_hour: f64,
}

impl Default for Bounds {
    fn default() -> Self {
        Self {
            max_deflection_rad: 0.01,
            max_deflection_m: 0.002,
            max_backlash_rad: 0.01,
            max_backlash_m: 0.002,
            max_scale_error: 0.01,
            max_periodic_rad: 0.01,
            max_periodic_m: 0.002,
            thermal_alpha_per_k: [0.5e-6, 35e-6],
            max_drift_per_hour: 2e-4,
        }
    }
}

/// Settings of [`diagnose`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DiagnoseOptions {
    /// Folds of the cross-validation over the analysis poses.
    pub folds: usize,
    /// Fraction of the rows kept aside for the reported held-out figures when the recording
    /// has no `split` column (0: report cross-validated figures instead).
    pub validation_fraction: f64,
    /// Family-wise significance level of each step (weighted Bonferroni over the candidates).
    pub alpha: f64,
    /// Smallest held-out improvement (fraction of the held-out mean squared error) worth a claim.
    pub min_improvement: f64,
    /// Smallest sine of the angle between an effect's columns and the geometric Jacobian.
    pub min_sin_angle: f64,
    /// Most effects added.
    pub max_effects: usize,
    /// Candidates checked in detail per step (in order of held-out improvement).
    pub max_checked: usize,
    /// Position standard deviation of rows without a `sigma` column.
    pub sigma_position_m: f64,
    /// Shortest period searched for a periodic error of a revolute joint.
    pub shortest_period_rad: f64,
    /// Shortest period searched for a periodic error of a prismatic joint.
    pub shortest_period_m: f64,
    /// Longest period searched for a revolute joint (one turn by default).
    pub longest_period_rad: f64,
    /// The geometric parameters (see [`ModelParams`]).
    pub model_params: ModelParams,
    /// Physical plausibility bounds.
    pub bounds: Bounds,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        Self {
            folds: 5,
            validation_fraction: 0.25,
            alpha: 0.01,
            min_improvement: 0.01,
            min_sin_angle: 0.05,
            max_effects: 6,
            max_checked: 4,
            sigma_position_m: 20e-6,
            shortest_period_rad: std::f64::consts::TAU / 200.0,
            shortest_period_m: 0.002,
            longest_period_rad: std::f64::consts::TAU,
            model_params: ModelParams::Default,
            bounds: Bounds::default(),
        }
    }
}

/// The geometric model's fit (`nominal` in the JSON).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct NominalFit {
    /// Poses the parameters were fitted on.
    pub n_train: usize,
    /// Poses held out.
    pub n_heldout: usize,
    /// RMS position error on the training poses.
    pub train_rms_mm: f64,
    /// RMS position error on the held-out poses.
    pub heldout_rms_mm: f64,
    /// Cross-validated RMS over the training poses (each predicted by a fit without it).
    pub cv_rms_mm: f64,
}

/// The fit with every accepted effect (`final` in the JSON).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct FinalFit {
    /// RMS position error on the training poses.
    pub train_rms_mm: f64,
    /// RMS position error on the held-out poses.
    pub heldout_rms_mm: f64,
    /// Cross-validated RMS over the training poses.
    pub cv_rms_mm: f64,
}

/// One accepted effect.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Finding {
    /// Effect name (`shared/spec/diagnose.md`).
    pub effect: String,
    /// 1-based joints it belongs to (empty when not tied to a joint).
    pub joints: Vec<usize>,
    /// Identified parameters (names carry their units).
    pub parameters: BTreeMap<String, f64>,
    /// Held-out RMS before modelling it.
    pub heldout_rms_before_mm: f64,
    /// Held-out RMS after.
    pub heldout_rms_after_mm: f64,
    /// Fraction of the held-out mean squared error it removes.
    pub explained_fraction: f64,
    /// p-value of the held-out improvement, corrected for the candidates tried.
    pub p_value: f64,
    /// Plain words: what, where, how large, how sure.
    pub statement: String,
    /// The effect as the calibration describes it (to reuse in `calibrate`).
    pub spec: EffectSpec,
    /// p-value before the correction.
    pub p_value_uncorrected: f64,
    /// Candidates tried in the step that accepted it.
    pub candidates_tried: usize,
    /// Cross-validated RMS before and after (training poses).
    pub cv_rms_before_mm: f64,
    /// Cross-validated RMS after.
    pub cv_rms_after_mm: f64,
    /// Relative standard deviation of the main parameter (jackknife over the folds).
    pub relative_std: f64,
    /// Standard deviation of the main parameter from the fit's covariance.
    pub std_from_covariance: Option<f64>,
    /// Sine of the angle between the effect's columns and the geometric Jacobian.
    pub sin_angle_to_geometry: f64,
    /// The input against which the effect shows.
    pub telling_input: String,
    /// Other candidates the held-out data cannot tell from this one (paired test, p > 0.05).
    pub alternatives: Vec<String>,
}

/// Structure of the held-out residuals against one input.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct InputStructure {
    /// The residual quantity tested (`joint 2 angle error`, `relative length change`).
    pub quantity: String,
    /// The input (a column name of the measurement table, or `gravity_torque<j>`).
    pub input: String,
    /// F statistic of the binned means.
    pub f: f64,
    /// p-value (uncorrected).
    pub p_value: f64,
    /// p-value corrected for every test of the screening.
    pub p_corrected: f64,
    /// Fraction of the quantity's weighted variance the bin means explain.
    pub explained_fraction: f64,
    /// Whether it is significant at the options' level.
    pub significant: bool,
}

/// What remains.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Unexplained {
    /// Whether the held-out residuals still depend on some input.
    pub structure_found: bool,
    /// Those inputs.
    pub depends_on: Vec<String>,
    /// The significant tests behind it.
    pub details: Vec<InputStructure>,
}

/// A candidate's scores in one step.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CandidateScore {
    /// Effect name.
    pub effect: String,
    /// 1-based joints.
    pub joints: Vec<usize>,
    /// Readable label.
    pub label: String,
    /// Cross-validated RMS without and with the candidate (linearised refits).
    pub cv_rms_before_mm: f64,
    /// With the candidate.
    pub cv_rms_after_mm: f64,
    /// Fraction of the held-out mean squared error removed.
    pub improvement: f64,
    /// Uncorrected p-value of the paired test.
    pub p_value: f64,
    /// p-value corrected for the candidates of the step (weighted Bonferroni).
    pub p_corrected: f64,
    /// Parameters of the all-rows linearised fit (names with units).
    pub parameters: BTreeMap<String, f64>,
    /// Sine of the angle to the geometric Jacobian (when checked).
    pub sin_angle_to_geometry: Option<f64>,
    /// What happened to it.
    pub verdict: String,
}

/// A candidate that could not be tested, and why.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Untestable {
    /// Effect name.
    pub effect: String,
    /// 1-based joints.
    pub joints: Vec<usize>,
    /// Why.
    pub reason: String,
}

/// One round of the search.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Step {
    /// Candidates, best first.
    pub candidates: Vec<CandidateScore>,
    /// Label of the accepted one, if any.
    pub accepted: Option<String>,
}

/// Residuals against the telling input before and after an accepted effect (for plots).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Evidence {
    /// Index of the finding.
    pub finding: usize,
    /// Input label (x axis).
    pub x_label: String,
    /// Residual quantity label (y axis).
    pub y_label: String,
    /// Input value per analysis pose.
    pub x: Vec<f64>,
    /// Held-out residual quantity before.
    pub before: Vec<f64>,
    /// After.
    pub after: Vec<f64>,
}

/// The whole analysis (`shared/spec/diagnose.md` plus extra fields).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct DiagnoseReport {
    /// The geometric model's fit.
    pub nominal: NominalFit,
    /// Accepted effects, in order of acceptance.
    pub findings: Vec<Finding>,
    /// The fit with every accepted effect.
    #[serde(rename = "final")]
    pub final_fit: FinalFit,
    /// Structure no candidate explains.
    pub unexplained: Unexplained,
    /// Why nothing was claimed, when the analysis declined (too few poses).
    pub declined: Option<String>,
    /// Candidates that could not be tested, with the reason.
    pub untestable: Vec<Untestable>,
    /// Every round of the search with its candidates.
    pub steps: Vec<Step>,
    /// Screening of the geometric model's held-out residuals against every input.
    pub screening_nominal: Vec<InputStructure>,
    /// Screening after the accepted effects.
    pub screening_final: Vec<InputStructure>,
    /// Remarks (assumptions made, candidates rejected for physics or stability).
    pub notes: Vec<String>,
    /// The settings used.
    pub settings: DiagnoseOptions,
    /// Number of rows read.
    pub n_poses: usize,
    /// How the held-out rows were chosen.
    pub split: String,
    /// Wall time of the analysis.
    pub elapsed_s: f64,
    /// Plot data per finding (not part of the JSON).
    #[serde(skip)]
    pub evidence: Vec<Evidence>,
}

/// A candidate effect: a fixed one, or a periodic joint error whose period is searched.
#[derive(Clone, Debug, PartialEq)]
enum Cand {
    Fixed(EffectSpec),
    Periodic { joint: usize },
}

impl Cand {
    fn name(&self) -> &'static str {
        match self {
            Cand::Fixed(s) => s.name(),
            Cand::Periodic { .. } => "periodic_joint_error",
        }
    }
    fn joints(&self) -> Vec<usize> {
        match self {
            Cand::Fixed(s) => s.joints_reported(),
            Cand::Periodic { joint } => vec![*joint],
        }
    }
    /// Free parameters (a periodic error's period counts: it is searched).
    fn n_params(&self) -> usize {
        match self {
            Cand::Fixed(s) => s.scales().len(),
            Cand::Periodic { .. } => 3,
        }
    }
    fn label(&self) -> String {
        match self {
            Cand::Fixed(EffectSpec::TimeDrift) => "thermal_expansion (lengths drift with time)".into(),
            Cand::Fixed(EffectSpec::ThermalExpansion { .. }) => "thermal_expansion (lengths follow temp_c)".into(),
            Cand::Fixed(EffectSpec::PeriodicJointError { joint, period_si }) => format!(
                "periodic_joint_error on joint {joint} ({:.0} per revolution)",
                std::f64::consts::TAU / period_si
            ),
            Cand::Periodic { joint } => format!("periodic_joint_error on joint {joint} (period searched)"),
            Cand::Fixed(EffectSpec::LinkCompliance { link }) => {
                format!("link_compliance on link {link} (between joints {link} and {})", link + 1)
            }
            c => format!("{} on joint {}", c.name(), c.joints().first().copied().unwrap_or(0)),
        }
    }
    /// Whether an accepted effect rules this candidate out (same kind and joint, or the other
    /// form of the length change).
    fn covered_by(&self, s: &EffectSpec) -> bool {
        let length = |e: &EffectSpec| matches!(e, EffectSpec::ThermalExpansion { .. } | EffectSpec::TimeDrift);
        if let (
            Cand::Fixed(EffectSpec::PeriodicJointError { joint, .. }),
            EffectSpec::PeriodicJointError { joint: j, .. },
        ) = (self, s)
        {
            return joint == j;
        }
        if let (Cand::Fixed(EffectSpec::LinkCompliance { link }), EffectSpec::LinkCompliance { link: l }) = (self, s) {
            return link == l;
        }
        match self {
            Cand::Fixed(c) => {
                (length(c) && length(s))
                    || (std::mem::discriminant(c) == std::mem::discriminant(s) && c.joint() == s.joint())
            }
            Cand::Periodic { joint } => {
                matches!(s, EffectSpec::PeriodicJointError { joint: j, .. } if j == joint)
            }
        }
    }
}

/// The candidate accepted in a step: its index among the scores, the effect, the refit with
/// it, the corrected and uncorrected p-values, the cross-validated RMS before and after (mm)
/// and the jackknife relative standard deviation of its main parameter.
type Chosen = (usize, EffectSpec, KinematicCalibration, f64, f64, f64, f64, f64);

/// Linear cross-validation of one candidate.
struct LinScore {
    /// Per analysis row: whitened held-out squared error before minus after.
    d: Vec<f64>,
    /// Per analysis row: whitened held-out residual after.
    e1: Vec<Vector3<f64>>,
    /// Per fold: the candidate's parameters.
    theta_folds: Vec<DVector<f64>>,
    /// Per fold: the chosen frequency (periodic candidates).
    freq_folds: Vec<f64>,
}

/// Everything a step needs about the analysis rows.
struct Ctx<'a> {
    model: &'a RobotModel,
    rows: Vec<&'a PoseMeasurement>,
    sigma: Vec<f64>,
    folds_idx: Vec<Vec<usize>>,
    kinds: Vec<JointKind>,
    names: Vec<String>,
    opts: &'a DiagnoseOptions,
    ref_temp_c: f64,
    grids: Vec<Vec<f64>>,
}

impl Ctx<'_> {
    fn kin_opts(&self, effects: Vec<EffectSpec>) -> KinematicOptions {
        KinematicOptions {
            model_params: self.opts.model_params.clone(),
            use_orientation: false,
            sigma_position_m: self.opts.sigma_position_m,
            effects,
            lm: LmOptions { max_iterations: 100, ..LmOptions::default() },
            ..KinematicOptions::default()
        }
    }

    fn q(&self, j: usize) -> Vec<f64> {
        self.rows.iter().map(|r| r.q[j]).collect()
    }

    fn mm(&self, e_whitened: &[Vector3<f64>]) -> f64 {
        let n = e_whitened.len().max(1);
        (e_whitened.iter().zip(&self.sigma).map(|(e, s)| (e * *s).norm_squared()).sum::<f64>() / n as f64).sqrt() * 1e3
    }

    /// Held-out errors (metres) of every analysis row from non-linear fits on the other folds.
    fn nonlinear_cv(&self, effects_for_fold: &dyn Fn(usize) -> Vec<EffectSpec>) -> Result<Vec<Vector3<f64>>> {
        let mut out = vec![Vector3::zeros(); self.rows.len()];
        for (k, test) in self.folds_idx.iter().enumerate() {
            let train: Vec<&PoseMeasurement> =
                (0..self.rows.len()).filter(|i| !test.contains(i)).map(|i| self.rows[i]).collect();
            let cal = calibrate(self.model, &train, &self.kin_opts(effects_for_fold(k)))?;
            let te: Vec<&PoseMeasurement> = test.iter().map(|&i| self.rows[i]).collect();
            let (pos, _) = cal.calibrated.errors(&te)?;
            for (e, &i) in pos.into_iter().zip(test) {
                out[i] = e;
            }
        }
        Ok(out)
    }

    fn effect_columns(&self, lin: &Lin, spec: &EffectSpec) -> Option<nalgebra::DMatrix<f64>> {
        lin.effect_columns(spec, self.kinds.len(), &self.rows)
    }

    fn periodic_spec(joint: usize, f: f64) -> EffectSpec {
        EffectSpec::PeriodicJointError { joint, period_si: 1.0 / f }
    }

    /// Linear cross-validation of a candidate.
    fn linear_cv(&self, lin: &Lin, folds: &[Fold], cand: &Cand) -> Option<LinScore> {
        let n = self.rows.len();
        let mut d = vec![0.0; n];
        let mut e1v = vec![Vector3::zeros(); n];
        let mut theta_folds = Vec::new();
        let mut freq_folds = Vec::new();
        let fixed_cols = match cand {
            Cand::Fixed(s) => Some(self.effect_columns(lin, s)?),
            Cand::Periodic { .. } => None,
        };
        for fold in folds {
            let cols = match cand {
                Cand::Fixed(_) => fixed_cols.clone()?,
                Cand::Periodic { joint } => {
                    let scan = PeriodScan::new(lin, &fold.basis, joint - 1, &self.q(joint - 1));
                    let (f, _) = scan.best(&self.grids[joint - 1]);
                    freq_folds.push(f);
                    self.effect_columns(lin, &Self::periodic_spec(*joint, f))?
                }
            };
            let (e1, theta) = heldout_with(fold, &cols);
            for (k, &i) in fold.test.iter().enumerate() {
                let a = fold.e0.fixed_rows::<3>(3 * k).clone_owned();
                let b = e1.fixed_rows::<3>(3 * k).clone_owned();
                d[i] = a.norm_squared() - b.norm_squared();
                e1v[i] = b;
            }
            theta_folds.push(theta);
        }
        Some(LinScore { d, e1: e1v, theta_folds, freq_folds })
    }
}

fn sig(x: f64, digits: usize) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let mag = x.abs().log10().floor() as i32;
    if (-3..4).contains(&mag) {
        let dec = (digits as i32 - 1 - mag).max(0) as usize;
        format!("{x:.dec$}")
    } else {
        format!("{x:.prec$e}", prec = digits.saturating_sub(1))
    }
}

fn fmt_p(p: f64) -> String {
    if p < 1e-15 {
        "p < 1e-15".into()
    } else {
        format!("p = {}", sig(p, 2))
    }
}

/// Runs the diagnosis of `model` on `rows`.
pub fn diagnose(model: &RobotModel, rows: &[PoseMeasurement], opts: &DiagnoseOptions) -> Result<DiagnoseReport> {
    let t0 = std::time::Instant::now();
    if opts.folds < 2 {
        return Err(CalibError::Data("diagnose: at least 2 folds are needed".into()));
    }
    if !(0.0..=0.5).contains(&opts.validation_fraction) {
        return Err(CalibError::Data("diagnose: the validation fraction must lie in [0, 0.5]".into()));
    }
    if !(opts.alpha > 0.0 && opts.alpha < 1.0) {
        return Err(CalibError::Data("diagnose: alpha must lie in (0, 1)".into()));
    }
    if !(opts.sigma_position_m.is_finite() && opts.sigma_position_m > 0.0) {
        return Err(CalibError::Data("diagnose: the default sigma must be positive".into()));
    }
    if rows.is_empty() {
        return Err(CalibError::TooFew("diagnose: the recording has no rows".into()));
    }
    let nj = model.dof();
    if let Some(r) = rows.iter().find(|r| r.q.len() != nj) {
        return Err(CalibError::Data(format!(
            "pose '{}': {} joint values, but the robot model '{}' has {nj} joints",
            r.pose_id,
            r.q.len(),
            model.name()
        )));
    }
    if let Some(r) = rows.iter().find(|r| r.sigma_m.is_some_and(|s| !(s.is_finite() && s > 0.0))) {
        return Err(CalibError::Data(format!("pose '{}': sigma must be positive", r.pose_id)));
    }
    // Split.
    let has_split = rows.iter().any(|r| r.split.is_some());
    let (analysis, validation, split): (Vec<&PoseMeasurement>, Vec<&PoseMeasurement>, String) = if has_split {
        let a = rows.iter().filter(|r| r.split != Some(Split::Test)).collect();
        let b: Vec<&PoseMeasurement> = rows.iter().filter(|r| r.split == Some(Split::Test)).collect();
        (a, b, "the recording's split column".into())
    } else if opts.validation_fraction > 0.0 {
        let f = opts.validation_fraction;
        let held = |k: usize| ((k + 1) as f64 * f).floor() > (k as f64 * f).floor();
        let a = rows.iter().enumerate().filter(|(k, _)| !held(*k)).map(|(_, r)| r).collect();
        let b = rows.iter().enumerate().filter(|(k, _)| held(*k)).map(|(_, r)| r).collect();
        (a, b, format!("every {}-th row held out for validation ({:.0} %)", (1.0 / f).round(), f * 100.0))
    } else {
        (rows.iter().collect(), Vec::new(), "no validation rows: held-out figures are cross-validated".into())
    };
    let kinds = model.joint_kinds();
    let names = model.joint_names();
    let sigma: Vec<f64> = analysis.iter().map(|r| r.sigma_m.unwrap_or(opts.sigma_position_m)).collect();
    let k = opts.folds;
    let folds_idx: Vec<Vec<usize>> = (0..k).map(|f| (0..analysis.len()).filter(|i| i % k == f).collect()).collect();
    let mut notes = Vec::new();
    if rows.iter().any(|r| r.sigma_m.is_none()) {
        notes.push(format!(
            "rows without a sigma column are weighted with the default position standard deviation of {} mm",
            sig(opts.sigma_position_m * 1e3, 3)
        ));
    }
    if rows.iter().all(|r| r.payload_kg.is_none()) {
        notes.push("no payload_kg column: load torques are computed without a payload".into());
    }
    let temps: Vec<f64> = analysis.iter().filter_map(|r| r.temp_c).collect();
    let ref_temp_c = if temps.is_empty() { 20.0 } else { temps.iter().sum::<f64>() / temps.len() as f64 };
    let grids = period_grids(&analysis, &kinds, opts);
    let ctx = Ctx {
        model,
        rows: analysis.clone(),
        sigma,
        folds_idx,
        kinds: kinds.clone(),
        names: names.clone(),
        opts,
        ref_temp_c,
        grids,
    };
    let mut report = DiagnoseReport {
        nominal: NominalFit { n_train: analysis.len(), n_heldout: validation.len(), ..Default::default() },
        findings: Vec::new(),
        final_fit: FinalFit::default(),
        unexplained: Unexplained::default(),
        declined: None,
        untestable: Vec::new(),
        steps: Vec::new(),
        screening_nominal: Vec::new(),
        screening_final: Vec::new(),
        notes,
        settings: opts.clone(),
        n_poses: rows.len(),
        split,
        elapsed_s: 0.0,
        evidence: Vec::new(),
    };

    // The geometric model.
    let geo = match calibrate(model, &analysis, &ctx.kin_opts(Vec::new())) {
        Ok(c) => c,
        Err(CalibError::TooFew(m)) => {
            report.declined = Some(format!("too few poses for the geometric model: {m}; nothing is claimed"));
            report.elapsed_s = t0.elapsed().as_secs_f64();
            return Ok(report);
        }
        Err(e) => return Err(e),
    };
    report.nominal.train_rms_mm = geo.train_after.rms_mm;
    report.nominal.heldout_rms_mm =
        if validation.is_empty() { f64::NAN } else { geo.calibrated.evaluate(&validation)?.rms_mm };
    report.final_fit.train_rms_mm = report.nominal.train_rms_mm;
    report.final_fit.heldout_rms_mm = report.nominal.heldout_rms_mm;
    // Enough poses for held-out scoring?
    let p = geo.free.len();
    let n_train_fold = analysis.len() - analysis.len().div_ceil(k);
    let min_fold = analysis.len() / k;
    if 3 * n_train_fold < 2 * p + 30 || min_fold < 5 || (!validation.is_empty() && validation.len() < 10) {
        report.declined = Some(format!(
            "too few poses for held-out scoring: {} analysis poses give {} equations per training fold for {p} identifiable geometric parameters (at least {} needed), {} held-out poses per fold and {} validation poses; nothing is claimed",
            analysis.len(),
            3 * n_train_fold,
            2 * p + 30,
            min_fold,
            validation.len()
        ));
        if validation.is_empty() {
            // No held-out figure exists: report the training figure rather than a non-number.
            report.nominal.heldout_rms_mm = report.nominal.train_rms_mm;
            report.final_fit.heldout_rms_mm = report.nominal.train_rms_mm;
            report.notes.push("no rows were held out: the held-out figures repeat the training RMS".into());
        }
        report.elapsed_s = t0.elapsed().as_secs_f64();
        return Ok(report);
    }

    // Candidates.
    let (cands, untestable) = enumerate_candidates(&ctx, rows, &geo)?;
    report.untestable = untestable;

    let mut accepted: Vec<EffectSpec> = Vec::new();
    let mut retired: Vec<EffectSpec> = Vec::new();
    let mut capped = false;
    let mut cal = geo;
    let mut first = true;
    loop {
        let lin = Lin::build(&cal, &ctx.rows, &ctx.sigma)?;
        let folds: Vec<Fold> = ctx.folds_idx.iter().map(|t| Fold::new(&lin, t)).collect::<Result<_>>()?;
        let all: Vec<usize> = (0..ctx.rows.len()).collect();
        let basis_all = Basis::new(&lin, &all)?;
        let mut e0 = vec![Vector3::zeros(); ctx.rows.len()];
        for fold in &folds {
            for (k, &i) in fold.test.iter().enumerate() {
                e0[i] = fold.e0.fixed_rows::<3>(3 * k).clone_owned();
            }
        }
        // Backward check: an earlier effect that the later ones have made unnecessary is dropped.
        if accepted.len() >= 2 {
            let mut dropped = None;
            for e in 0..accepted.len() - 1 {
                let cols: Vec<usize> =
                    (0..cal.free.len()).filter(|&k| cal.layout.effects[e].contains(&cal.free[k])).collect();
                // Leaving it out: its parameters at zero, the rest refitted without them.
                let mut cm0 = cal.calibrated.clone();
                cm0.effects[e].1.iter_mut().for_each(|v| *v = 0.0);
                let (err0, _) = cm0.errors(&ctx.rows)?;
                let mut r0 = DVector::zeros(3 * ctx.rows.len());
                for (i, v) in err0.iter().enumerate() {
                    r0.fixed_rows_mut::<3>(3 * i).copy_from(&(v / ctx.sigma[i]));
                }
                let red = lin.without(&cols, r0);
                let mut d = vec![0.0; ctx.rows.len()];
                for (fold, t) in folds.iter().zip(&ctx.folds_idx) {
                    let f_red = Fold::new(&red, t)?;
                    for (k, &i) in t.iter().enumerate() {
                        d[i] = f_red.e0.fixed_rows::<3>(3 * k).norm_squared()
                            - fold.e0.fixed_rows::<3>(3 * k).norm_squared();
                    }
                }
                let t = paired_test(&d);
                let sse: f64 = e0.iter().map(|v| v.norm_squared()).sum::<f64>() / e0.len() as f64;
                if t.p_value >= opts.alpha || t.mean / sse < opts.min_improvement {
                    dropped = Some((e, t.p_value, t.mean / sse));
                    break;
                }
            }
            if let Some((e, p, impr)) = dropped {
                let gone = accepted.remove(e);
                retired.push(gone.clone());
                let f = report.findings.remove(e);
                report.evidence.retain(|v| v.finding != e);
                for v in &mut report.evidence {
                    if v.finding > e {
                        v.finding -= 1;
                    }
                }
                report.notes.push(format!(
                    "{} on joints {:?} was accepted first but dropped once later effects were modelled: leaving it out changes the held-out error by {:.2} % (p = {}); its statement was: {}",
                    gone.name(),
                    f.joints,
                    -impr * 100.0,
                    sig(p, 2),
                    f.statement
                ));
                cal = calibrate(model, &analysis, &ctx.kin_opts(accepted.clone()))?;
                report.final_fit.train_rms_mm = cal.train_after.rms_mm;
                if !validation.is_empty() {
                    report.final_fit.heldout_rms_mm = cal.calibrated.evaluate(&validation)?.rms_mm;
                }
                continue;
            }
        }
        let cv_before_mm = ctx.mm(&e0);
        let screening = screen(&ctx, &lin, &e0);
        if first {
            report.nominal.cv_rms_mm = cv_before_mm;
            report.screening_nominal = screening.clone();
            first = false;
        }
        report.final_fit.cv_rms_mm = cv_before_mm;
        report.screening_final = screening;
        let open: Vec<&Cand> =
            cands.iter().filter(|c| !accepted.iter().chain(&retired).any(|s| c.covered_by(s))).collect();
        if open.is_empty() || accepted.len() >= opts.max_effects {
            capped = !open.is_empty();
            break;
        }
        let m = open.len();
        // Weighted Bonferroni: every kind of effect gets an equal share of alpha, split equally
        // among its candidates (so a kind with many joints and periods does not crowd out the
        // others); the multiplier of a candidate is 1 / its weight.
        let mut kinds_open: Vec<&str> = open.iter().map(|c| c.name()).collect();
        kinds_open.sort_unstable();
        kinds_open.dedup();
        let multiplier = |c: &Cand| kinds_open.len() * open.iter().filter(|o| o.name() == c.name()).count();
        let sse0: f64 = e0.iter().map(|e| e.norm_squared()).sum::<f64>() / e0.len() as f64;
        let mut scored: Vec<(CandidateScore, &Cand, LinScore)> = Vec::new();
        for c in open.iter().copied() {
            let Some(ls) = ctx.linear_cv(&lin, &folds, c) else { continue };
            let t = paired_test(&ls.d);
            let cv_after = ctx.mm(&ls.e1);
            let score = CandidateScore {
                effect: c.name().into(),
                joints: c.joints(),
                label: c.label(),
                cv_rms_before_mm: cv_before_mm,
                cv_rms_after_mm: cv_after,
                improvement: t.mean / sse0,
                p_value: t.p_value,
                p_corrected: bonferroni(t.p_value, multiplier(c)),
                parameters: BTreeMap::new(),
                sin_angle_to_geometry: None,
                verdict: String::new(),
            };
            scored.push((score, c, ls));
        }
        scored.sort_by(|a, b| b.0.improvement.total_cmp(&a.0.improvement));
        let (mut scores, rest): (Vec<CandidateScore>, Vec<(&Cand, LinScore)>) =
            scored.into_iter().map(|(s, c, l)| (s, (c, l))).unzip();
        let mut chosen: Option<Chosen> = None;
        let mut significant = Vec::new();
        for (idx, score) in scores.iter_mut().enumerate() {
            if score.p_corrected >= opts.alpha || score.improvement < opts.min_improvement {
                let why = if score.improvement < opts.min_improvement {
                    format!(
                        "held-out improvement {:.2} % below {:.1} %",
                        score.improvement * 100.0,
                        opts.min_improvement * 100.0
                    )
                } else {
                    format!("not significant ({} after correcting for {m} candidates)", fmt_p(score.p_corrected))
                };
                score.verdict = why;
            } else {
                significant.push(idx);
            }
        }
        // Parsimony: among the candidates the held-out data cannot tell from the best one (paired
        // test of their squared errors, p > 0.05), the one with the fewest parameters first.
        let order: Vec<usize> = match significant.first() {
            None => Vec::new(),
            Some(&best) => {
                let mut twins: Vec<usize> = significant
                    .iter()
                    .copied()
                    .filter(|&i| {
                        i == best || {
                            let diff: Vec<f64> = rest[best].1.d.iter().zip(&rest[i].1.d).map(|(a, b)| a - b).collect();
                            paired_test(&diff).p_value > 0.05
                        }
                    })
                    .collect();
                twins.sort_by(|&a, &b| {
                    rest[a]
                        .0
                        .n_params()
                        .cmp(&rest[b].0.n_params())
                        .then(scores[b].improvement.total_cmp(&scores[a].improvement))
                });
                let mut o = twins.clone();
                o.extend(significant.iter().copied().filter(|i| !twins.contains(i)));
                o
            }
        };
        let mut checked = 0;
        let mut base_nl_cache: Option<Vec<Vector3<f64>>> = None;
        for &idx in &order {
            let (cand, ls) = (rest[idx].0, &rest[idx].1);
            if checked >= opts.max_checked || chosen.is_some() {
                scores[idx].verdict = "significant, not examined further this step".into();
                continue;
            }
            checked += 1;
            // The all-rows fit: parameters and the angle to the geometry.
            let spec = match cand {
                Cand::Fixed(s) => s.clone(),
                Cand::Periodic { joint } => {
                    let scan = PeriodScan::new(&lin, &basis_all, joint - 1, &ctx.q(joint - 1));
                    Ctx::periodic_spec(*joint, scan.best(&ctx.grids[joint - 1]).0)
                }
            };
            let Some(cols) = ctx.effect_columns(&lin, &spec) else { continue };
            let fit = joint_fit(&basis_all, &cols);
            let sa = sin_angle(&basis_all, &cols);
            let theta: Vec<f64> = fit.theta.iter().copied().collect();
            scores[idx].parameters = parameter_map(&spec, &theta, &kinds);
            scores[idx].sin_angle_to_geometry = Some(sa);
            if sa < opts.min_sin_angle {
                scores[idx].verdict = format!(
                    "rejected: nearly a combination of geometric parameters (sine of the angle to the geometric Jacobian {:.3}, variance inflation {:.0})",
                    sa,
                    1.0 / (sa * sa).max(1e-300)
                );
                continue;
            }
            if let Err(why) = plausible(&spec, &theta, &ctx, &lin, opts) {
                scores[idx].verdict = format!("rejected as physically implausible: {why}");
                continue;
            }
            let rel_std = match stability(&spec, &theta, ls, &ctx) {
                Ok(r) => r,
                Err(why) => {
                    scores[idx].verdict = format!("rejected as unstable across the folds: {why}");
                    continue;
                }
            };
            // (a) full non-linear refits on the folds.
            if base_nl_cache.is_none() {
                base_nl_cache = Some(ctx.nonlinear_cv(&|_| accepted.clone())?);
            }
            let base_nl = base_nl_cache.as_deref().unwrap_or_default();
            let with_spec = |fold: usize| -> Vec<EffectSpec> {
                let mut v = accepted.clone();
                v.push(match cand {
                    Cand::Periodic { joint } => Ctx::periodic_spec(*joint, ls.freq_folds[fold]),
                    Cand::Fixed(s) => s.clone(),
                });
                v
            };
            let cand_nl = match ctx.nonlinear_cv(&with_spec) {
                Ok(v) => v,
                Err(e) => {
                    scores[idx].verdict = format!("rejected: the full refit failed ({e})");
                    continue;
                }
            };
            let d: Vec<f64> = (0..ctx.rows.len())
                .map(|i| (base_nl[i].norm_squared() - cand_nl[i].norm_squared()) / ctx.sigma[i].powi(2))
                .collect();
            let t = paired_test(&d);
            let sse_nl = (0..ctx.rows.len()).map(|i| base_nl[i].norm_squared() / ctx.sigma[i].powi(2)).sum::<f64>()
                / ctx.rows.len() as f64;
            let impr = t.mean / sse_nl;
            let p_corr = bonferroni(t.p_value, multiplier(cand));
            let rms =
                |v: &[Vector3<f64>]| (v.iter().map(|e| e.norm_squared()).sum::<f64>() / v.len() as f64).sqrt() * 1e3;
            if p_corr >= opts.alpha || impr < opts.min_improvement {
                scores[idx].verdict = format!(
                    "rejected by the full refits: held-out improvement {:.2} %, {} after correcting for {m} candidates",
                    impr * 100.0,
                    fmt_p(p_corr)
                );
                continue;
            }
            let mut effects = accepted.clone();
            effects.push(spec.clone());
            let new_cal = calibrate(model, &analysis, &ctx.kin_opts(effects))?;
            scores[idx].verdict = format!("ACCEPTED ({} after correcting for {m} candidates)", fmt_p(p_corr));
            chosen = Some((idx, spec, new_cal, p_corr, t.p_value, rms(base_nl), rms(&cand_nl), rel_std));
        }
        let step_cands: Vec<CandidateScore> = scores.clone();
        let Some((idx, spec, new_cal, p_corr, p_raw, cv_b, cv_a, rel_std)) = chosen else {
            report.steps.push(Step { candidates: step_cands, accepted: None });
            break;
        };
        report.steps.push(Step { candidates: step_cands, accepted: Some(rest[idx].0.label()) });
        // Finding.
        let (before, after) = if validation.is_empty() {
            (cv_b, cv_a)
        } else {
            (cal.calibrated.evaluate(&validation)?.rms_mm, new_cal.calibrated.evaluate(&validation)?.rms_mm)
        };
        let range = new_cal.layout.effects.last().cloned().unwrap_or(0..0);
        let theta: Vec<f64> = range.clone().map(|i| new_cal.params[i].value).collect();
        let std_cov = new_cal.params.get(range.start).and_then(|p| p.std);
        let sa = scores[idx].sin_angle_to_geometry.unwrap_or(f64::NAN);
        let explained =
            if before > 0.0 { ((before * before - after * after) / (before * before)).max(0.0) } else { 0.0 };
        let telling = telling_input(&spec, &names);
        let mut statement = statement(&spec, &theta, rel_std, before, after, p_corr, m, &ctx, &lin);
        // Other effects the held-out data cannot tell from this one.
        let alternatives: Vec<String> = significant
            .iter()
            .copied()
            .filter(|&i| i != idx && !(rest[i].0.name() == spec.name() && rest[i].0.joints() == scores[idx].joints))
            .filter(|&i| {
                let diff: Vec<f64> = rest[idx].1.d.iter().zip(&rest[i].1.d).map(|(a, b)| a - b).collect();
                paired_test(&diff).p_value > 0.05
            })
            .map(|i| rest[i].0.label())
            .collect();
        if !alternatives.is_empty() {
            statement.push_str(&format!(
                "; the held-out data fit {} about as well, so that reading cannot be excluded",
                alternatives.join(" or ")
            ));
        }
        let finding = Finding {
            effect: spec.name().into(),
            joints: spec.joints_reported(),
            parameters: parameter_map(&spec, &theta, &kinds),
            heldout_rms_before_mm: before,
            heldout_rms_after_mm: after,
            explained_fraction: explained,
            p_value: p_corr,
            statement,
            spec: spec.clone(),
            p_value_uncorrected: p_raw,
            candidates_tried: m,
            cv_rms_before_mm: cv_b,
            cv_rms_after_mm: cv_a,
            relative_std: rel_std,
            std_from_covariance: std_cov,
            sin_angle_to_geometry: sa,
            telling_input: telling.clone(),
            alternatives,
        };
        report.evidence.push(evidence(report.findings.len(), &spec, &ctx, &lin, &e0, &rest[idx].1.e1, &telling));
        report.findings.push(finding);
        report.final_fit.train_rms_mm = new_cal.train_after.rms_mm;
        report.final_fit.heldout_rms_mm = if validation.is_empty() { cv_a } else { after };
        accepted.push(spec);
        cal = new_cal;
    }
    if validation.is_empty() {
        report.nominal.heldout_rms_mm = report.nominal.cv_rms_mm;
        report.final_fit.heldout_rms_mm = report.final_fit.cv_rms_mm;
    }
    // Rejected-but-significant candidates of the last step, in words.
    if let Some(last) = report.steps.last() {
        for c in last.candidates.iter().filter(|c| c.verdict.starts_with("rejected")) {
            report.notes.push(format!("{}: {}", c.label, c.verdict));
        }
        for c in last.candidates.iter().filter(|c| c.p_corrected < opts.alpha && c.improvement < opts.min_improvement) {
            report.notes.push(format!(
                "{} is statistically detectable ({} after correction) but too small to claim: it would remove only {:.2} % of the held-out mean squared error (threshold {:.1} %)",
                c.label,
                fmt_p(c.p_corrected),
                c.improvement * 100.0,
                opts.min_improvement * 100.0
            ));
        }
    }
    if let Some(f) = report.findings.last_mut() {
        if capped {
            f.statement.push_str(&format!("; the search stopped at the limit of {} effects", opts.max_effects));
        } else {
            f.statement.push_str("; no other candidate passes");
        }
    }
    if capped {
        report.notes.push(format!(
            "the search stopped at the limit of {} effects (DiagnoseOptions::max_effects); candidates beyond it were not examined",
            opts.max_effects
        ));
    }
    let sig_tests: Vec<InputStructure> = report.screening_final.iter().filter(|s| s.significant).cloned().collect();
    let mut depends: Vec<String> = Vec::new();
    for s in &sig_tests {
        if !depends.contains(&s.input) {
            depends.push(s.input.clone());
        }
    }
    report.unexplained =
        Unexplained { structure_found: !sig_tests.is_empty(), depends_on: depends, details: sig_tests };
    report.elapsed_s = t0.elapsed().as_secs_f64();
    Ok(report)
}

/// Frequency grids (cycles per joint unit) of the periodic candidates per joint.
fn period_grids(rows: &[&PoseMeasurement], kinds: &[JointKind], opts: &DiagnoseOptions) -> Vec<Vec<f64>> {
    kinds
        .iter()
        .enumerate()
        .map(|(j, kind)| {
            let (lo, hi) =
                rows.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), r| (l.min(r.q[j]), h.max(r.q[j])));
            let range = (hi - lo).max(1e-9);
            let (f_min, f_max) = match kind {
                JointKind::Revolute => (1.0 / opts.longest_period_rad, 1.0 / opts.shortest_period_rad),
                JointKind::Prismatic => (1.0 / range, 1.0 / opts.shortest_period_m),
            };
            let step = 1.0 / (4.0 * range);
            let n = (((f_max - f_min) / step).ceil() as usize).min(20_000);
            (0..=n).map(|k| f_min + k as f64 * step).filter(|f| *f <= f_max * 1.000_001).collect()
        })
        .collect()
}

/// The candidates that can be tested on this recording, and those that cannot (with why).
fn enumerate_candidates(
    ctx: &Ctx,
    all_rows: &[PoseMeasurement],
    geo: &KinematicCalibration,
) -> Result<(Vec<Cand>, Vec<Untestable>)> {
    let mut cands = Vec::new();
    let mut un = Vec::new();
    let n = ctx.rows.len();
    // Loads from the nominal link frames (see `CalibratedModel::load_model`).
    let model = &geo.calibrated.load_model;
    let mut tau = Vec::with_capacity(n);
    for r in &ctx.rows {
        tau.push(crate::effects::holding_torques(model, &r.q, r.payload_kg.unwrap_or(0.0))?);
    }
    let tau_max = tau.iter().flatten().fold(0.0f64, |a, b| a.max(b.abs()));
    for (j, kind) in ctx.kinds.iter().enumerate() {
        let jn = j + 1;
        let q = ctx.q(j);
        let (lo, hi) = q.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| (l.min(*v), h.max(*v)));
        let moved = match kind {
            JointKind::Revolute => hi - lo > 0.05,
            JointKind::Prismatic => hi - lo > 0.01,
        };
        // Compliance: the load torque must vary.
        let tj: Vec<f64> = tau.iter().map(|t| t[j]).collect();
        let mean = tj.iter().sum::<f64>() / n as f64;
        let sd = (tj.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        if tau_max == 0.0 {
            un.push(Untestable {
                effect: "joint_compliance".into(),
                joints: vec![jn],
                reason: "the model carries no masses (no link inertials, no payload): load torques are unknown".into(),
            });
        } else if sd <= 1e-3 * tau_max.max(1.0) {
            un.push(Untestable {
                effect: "joint_compliance".into(),
                joints: vec![jn],
                reason: format!("joint {jn}'s gravity torque does not vary over the poses (its axis is vertical or it carries no load)"),
            });
        } else {
            cands.push(Cand::Fixed(EffectSpec::JointCompliance { joint: jn }));
        }
        // Backlash: directions on every row, both signs seen.
        let spec = EffectSpec::Backlash { joint: jn };
        let missing = all_rows.iter().any(|r| r.dir.as_ref().and_then(|d| d.get(j)).is_none());
        if missing {
            un.push(Untestable {
                effect: "backlash".into(),
                joints: vec![jn],
                reason: "the recording has no approach directions (dir columns)".into(),
            });
        } else {
            let plus = ctx.rows.iter().filter(|r| r.dir.as_ref().is_some_and(|d| d[j] > 0)).count();
            let minus = ctx.rows.iter().filter(|r| r.dir.as_ref().is_some_and(|d| d[j] < 0)).count();
            let zero = n - plus - minus;
            if zero > 0 {
                un.push(Untestable {
                    effect: "backlash".into(),
                    joints: vec![jn],
                    reason: format!("joint {jn}'s approach direction is unknown (0) on {zero} poses"),
                });
            } else if plus < 5 || minus < 5 {
                un.push(Untestable {
                    effect: "backlash".into(),
                    joints: vec![jn],
                    reason: format!(
                        "joint {jn} was approached from one side only ({plus} positive, {minus} negative approaches)"
                    ),
                });
            } else {
                cands.push(Cand::Fixed(spec));
            }
        }
        if moved {
            cands.push(Cand::Fixed(EffectSpec::JointScaleError { joint: jn }));
            cands.push(Cand::Periodic { joint: jn });
            if *kind == JointKind::Revolute {
                // Once and twice per revolution (eccentricity, ovality), with the period fixed.
                for k in [1.0, 2.0] {
                    cands.push(Cand::Fixed(EffectSpec::PeriodicJointError {
                        joint: jn,
                        period_si: std::f64::consts::TAU / k,
                    }));
                }
            }
        } else {
            for e in ["joint_scale_error", "periodic_joint_error"] {
                un.push(Untestable {
                    effect: e.into(),
                    joints: vec![jn],
                    reason: format!("joint {jn} barely moved over the poses"),
                });
            }
        }
    }
    // Length changes.
    if all_rows.iter().any(|r| r.temp_c.is_none()) {
        un.push(Untestable {
            effect: "thermal_expansion".into(),
            joints: vec![],
            reason: "no temperature (temp_c) on every row: expansion with temperature cannot be tested".into(),
        });
    } else {
        let (lo, hi) = ctx.rows.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), r| {
            let t = r.temp_c.unwrap_or(0.0);
            (l.min(t), h.max(t))
        });
        if hi - lo < 0.2 {
            un.push(Untestable {
                effect: "thermal_expansion".into(),
                joints: vec![],
                reason: format!("the temperature varied by only {:.2} K", hi - lo),
            });
        } else {
            cands.push(Cand::Fixed(EffectSpec::ThermalExpansion { reference_temp_c: ctx.ref_temp_c }));
        }
    }
    if all_rows.iter().any(|r| r.t_s.is_none()) {
        un.push(Untestable {
            effect: "thermal_expansion".into(),
            joints: vec![],
            reason: "no time (t_s) on every row: a drift with time cannot be tested".into(),
        });
    } else {
        let (lo, hi) = ctx.rows.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), r| {
            let t = r.t_s.unwrap_or(0.0);
            (l.min(t), h.max(t))
        });
        if hi - lo < 60.0 {
            un.push(Untestable {
                effect: "thermal_expansion".into(),
                joints: vec![],
                reason: format!("the recording spans only {:.0} s", hi - lo),
            });
        } else {
            cands.push(Cand::Fixed(EffectSpec::TimeDrift));
        }
    }
    // Link compliance: serial chains with masses, per link that carries a further joint, when
    // the load moment across the next joint's axis varies over the poses.
    if let ferrocal_robot::RobotModel::Serial(_) = model {
        let mut per_row = Vec::with_capacity(n);
        for r in &ctx.rows {
            per_row.push(crate::effects::link_bendings(model, &r.q, r.payload_kg.unwrap_or(0.0))?);
        }
        for link in 1..ctx.kinds.len() {
            let moments: Vec<Vector3<f64>> = per_row.iter().map(|b| b[link - 1].0).collect();
            let mean = moments.iter().fold(Vector3::zeros(), |a, v| a + v) / n as f64;
            let sd = (moments.iter().map(|v| (v - mean).norm_squared()).sum::<f64>() / n as f64).sqrt();
            if tau_max == 0.0 {
                un.push(Untestable {
                    effect: "link_compliance".into(),
                    joints: vec![link, link + 1],
                    reason: "the model carries no masses (no link inertials, no payload): load moments are unknown"
                        .into(),
                });
            } else if sd <= 1e-3 * tau_max.max(1.0) {
                un.push(Untestable {
                    effect: "link_compliance".into(),
                    joints: vec![link, link + 1],
                    reason: format!(
                        "the load moment link {link} carries across joint {}'s axis does not vary over the poses",
                        link + 1
                    ),
                });
            } else {
                cands.push(Cand::Fixed(EffectSpec::LinkCompliance { link }));
            }
        }
    }
    Ok((cands, un))
}

/// Parameters with unit-carrying names (angles in rad and deg).
fn parameter_map(spec: &EffectSpec, theta: &[f64], kinds: &[JointKind]) -> BTreeMap<String, f64> {
    let mut m = BTreeMap::new();
    let prismatic = spec.joint().is_some_and(|j| kinds.get(j - 1) == Some(&JointKind::Prismatic));
    let t0 = theta.first().copied().unwrap_or(f64::NAN);
    let angle = |m: &mut BTreeMap<String, f64>, base: &str, v: f64| {
        if prismatic {
            m.insert(format!("{base}_m"), v);
            m.insert(format!("{base}_mm"), v * 1e3);
        } else {
            m.insert(format!("{base}_rad"), v);
            m.insert(format!("{base}_deg"), v.to_degrees());
        }
    };
    match spec {
        EffectSpec::JointCompliance { .. } => {
            m.insert(if prismatic { "compliance_m_per_n" } else { "compliance_rad_per_nm" }.into(), t0);
        }
        EffectSpec::Backlash { .. } => angle(&mut m, "backlash", t0),
        EffectSpec::JointScaleError { .. } => {
            m.insert("scale_error".into(), t0);
        }
        EffectSpec::PeriodicJointError { period_si, .. } => {
            let a = theta.first().copied().unwrap_or(0.0);
            let b = theta.get(1).copied().unwrap_or(0.0);
            angle(&mut m, "amplitude", a.hypot(b));
            angle(&mut m, "period", *period_si);
            m.insert("phase_rad".into(), b.atan2(a));
            m.insert("phase_deg".into(), b.atan2(a).to_degrees());
            m.insert("sin_coefficient".into(), a);
            m.insert("cos_coefficient".into(), b);
            if !prismatic {
                m.insert("cycles_per_revolution".into(), std::f64::consts::TAU / period_si);
            }
        }
        EffectSpec::ThermalExpansion { reference_temp_c } => {
            m.insert("alpha_per_k".into(), t0);
            m.insert("reference_temp_c".into(), *reference_temp_c);
        }
        EffectSpec::TimeDrift => {
            m.insert("drift_per_hour".into(), t0);
        }
        EffectSpec::LinkCompliance { .. } => {
            m.insert("compliance_rad_per_nm".into(), t0);
        }
    }
    m
}

/// (d): sign and size.
fn plausible(spec: &EffectSpec, theta: &[f64], ctx: &Ctx, lin: &Lin, opts: &DiagnoseOptions) -> Result<(), String> {
    let b = &opts.bounds;
    let t = theta.first().copied().unwrap_or(0.0);
    let prismatic = spec.joint().is_some_and(|j| ctx.kinds.get(j - 1) == Some(&JointKind::Prismatic));
    let (unit, scale) = if prismatic { ("mm", 1e3) } else { ("mrad", 1e3) };
    match spec {
        EffectSpec::JointCompliance { joint } => {
            if t <= 0.0 {
                return Err(format!("negative compliance ({}): joint {joint} would rise against its load", sig(t, 2)));
            }
            let tmax = lin.tau.iter().map(|v| v[joint - 1].abs()).fold(0.0, f64::max);
            let defl = t * tmax;
            let bound = if prismatic { b.max_deflection_m } else { b.max_deflection_rad };
            if defl > bound {
                return Err(format!(
                    "a deflection of {} {unit} at the largest load exceeds the bound of {} {unit}",
                    sig(defl * scale, 2),
                    sig(bound * scale, 2)
                ));
            }
        }
        EffectSpec::Backlash { .. } => {
            if t <= 0.0 {
                return Err(format!(
                    "negative backlash ({} {unit}): the joint would overshoot, not stop short",
                    sig(t * scale, 2)
                ));
            }
            let bound = if prismatic { b.max_backlash_m } else { b.max_backlash_rad };
            if t > bound {
                return Err(format!(
                    "backlash {} {unit} exceeds the bound of {} {unit}",
                    sig(t * scale, 2),
                    sig(bound * scale, 2)
                ));
            }
        }
        EffectSpec::JointScaleError { .. } => {
            if t.abs() > b.max_scale_error {
                return Err(format!("scale error {} exceeds the bound of {}", sig(t, 2), sig(b.max_scale_error, 2)));
            }
        }
        EffectSpec::PeriodicJointError { .. } => {
            let a = theta.first().copied().unwrap_or(0.0).hypot(theta.get(1).copied().unwrap_or(0.0));
            let bound = if prismatic { b.max_periodic_m } else { b.max_periodic_rad };
            if a > bound {
                return Err(format!(
                    "amplitude {} {unit} exceeds the bound of {} {unit}",
                    sig(a * scale, 2),
                    sig(bound * scale, 2)
                ));
            }
        }
        EffectSpec::ThermalExpansion { .. } => {
            let [lo, hi] = b.thermal_alpha_per_k;
            if !(lo..=hi).contains(&t) {
                return Err(format!(
                    "expansion coefficient {} per K is outside the range of metals ({} to {} per K)",
                    sig(t, 2),
                    sig(lo, 2),
                    sig(hi, 2)
                ));
            }
        }
        EffectSpec::TimeDrift => {
            if t.abs() > b.max_drift_per_hour {
                return Err(format!(
                    "a length drift of {} ppm per hour exceeds the bound of {} ppm per hour",
                    sig(t * 1e6, 2),
                    sig(b.max_drift_per_hour * 1e6, 2)
                ));
            }
        }
        EffectSpec::LinkCompliance { link } => {
            if t <= 0.0 {
                return Err(format!("negative compliance ({}): link {link} would bend against its load", sig(t, 2)));
            }
            let mmax = lin.bend.iter().filter_map(|b| b.get(link - 1)).map(|(v, _)| v.norm()).fold(0.0, f64::max);
            let defl = t * mmax;
            if defl > b.max_deflection_rad {
                return Err(format!(
                    "a bend of {} mrad at the largest load exceeds the bound of {} mrad",
                    sig(defl * 1e3, 2),
                    sig(b.max_deflection_rad * 1e3, 2)
                ));
            }
        }
    }
    Ok(())
}

/// (b): the same sign and a similar size in every fold; returns the jackknife relative standard
/// deviation of the main parameter (the amplitude of a periodic error).
fn stability(spec: &EffectSpec, theta_all: &[f64], ls: &LinScore, ctx: &Ctx) -> Result<f64, String> {
    let k = ls.theta_folds.len() as f64;
    let main = |t: &[f64]| match spec {
        EffectSpec::PeriodicJointError { .. } => {
            t.first().copied().unwrap_or(0.0).hypot(t.get(1).copied().unwrap_or(0.0))
        }
        _ => t.first().copied().unwrap_or(0.0),
    };
    let all = main(theta_all);
    let per: Vec<f64> = ls.theta_folds.iter().map(|t| main(t.as_slice())).collect();
    if let EffectSpec::PeriodicJointError { joint, period_si } = spec {
        let f_all = 1.0 / period_si;
        let grid = &ctx.grids[joint - 1];
        let step = if grid.len() > 1 { grid[1] - grid[0] } else { f_all * 0.01 };
        for (i, f) in ls.freq_folds.iter().enumerate() {
            if (f - f_all).abs() > step {
                return Err(format!(
                    "fold {} finds a period of {} instead of {}",
                    i + 1,
                    sig(1.0 / f, 3),
                    sig(*period_si, 3)
                ));
            }
        }
        for (i, a) in per.iter().enumerate() {
            if !(0.5 * all..=2.0 * all).contains(a) {
                return Err(format!("fold {} finds an amplitude of {} instead of {}", i + 1, sig(*a, 2), sig(all, 2)));
            }
        }
    } else {
        for (i, v) in per.iter().enumerate() {
            if v * all <= 0.0 {
                return Err(format!("fold {} finds the opposite sign ({} against {})", i + 1, sig(*v, 2), sig(all, 2)));
            }
        }
    }
    let mean = per.iter().sum::<f64>() / k;
    let jack = ((k - 1.0) / k * per.iter().map(|v| (v - mean).powi(2)).sum::<f64>()).sqrt();
    let rel = jack / all.abs().max(1e-300);
    if rel > 0.5 {
        return Err(format!("the folds scatter by {:.0} % of the value", rel * 100.0));
    }
    Ok(rel)
}

fn telling_input(spec: &EffectSpec, names: &[String]) -> String {
    let jn = |j: usize| names.get(j - 1).cloned().unwrap_or_default();
    match spec {
        EffectSpec::JointCompliance { joint } => format!("gravity_torque{joint} (load torque on {})", jn(*joint)),
        EffectSpec::Backlash { joint } => format!("dir{joint} (approach direction of {})", jn(*joint)),
        EffectSpec::JointScaleError { joint } | EffectSpec::PeriodicJointError { joint, .. } => {
            format!("q{joint} ({})", jn(*joint))
        }
        EffectSpec::ThermalExpansion { .. } => "temp_c".into(),
        EffectSpec::TimeDrift => "t_s".into(),
        EffectSpec::LinkCompliance { link } => {
            format!("bending moment on link {link} (between {} and {})", jn(*link), jn(link + 1))
        }
    }
}

/// Plain-words statement of an accepted effect.
#[allow(clippy::too_many_arguments)]
fn statement(
    spec: &EffectSpec,
    theta: &[f64],
    rel_std: f64,
    before: f64,
    after: f64,
    p: f64,
    m: usize,
    ctx: &Ctx,
    lin: &Lin,
) -> String {
    let t = theta.first().copied().unwrap_or(0.0);
    let pm = format!("(+-{:.0} %)", (rel_std * 100.0).max(1.0));
    let prismatic = spec.joint().is_some_and(|j| ctx.kinds.get(j - 1) == Some(&JointKind::Prismatic));
    let what = match spec {
        EffectSpec::JointCompliance { joint } => {
            let tmax = lin.tau.iter().map(|v| v[joint - 1].abs()).fold(0.0, f64::max);
            if prismatic {
                format!(
                    "joint {joint} gives way by {} m per N of load force {pm}, up to {} mm over these poses",
                    sig(t, 2),
                    sig(t * tmax * 1e3, 2)
                )
            } else {
                format!(
                    "joint {joint} deflects {} rad per N m of gravity torque {pm}, up to {} mrad over these poses",
                    sig(t, 2),
                    sig(t * tmax * 1e3, 2)
                )
            }
        }
        EffectSpec::Backlash { joint } => {
            if prismatic {
                format!(
                    "joint {joint} has {} mm of backlash {pm}: where it stops depends on the direction it was approached from",
                    sig(t * 1e3, 2)
                )
            } else {
                format!(
                    "joint {joint} has {} mrad ({} deg) of backlash {pm}: where it stops depends on the direction it was approached from",
                    sig(t * 1e3, 2),
                    sig(t.to_degrees(), 2)
                )
            }
        }
        EffectSpec::JointScaleError { joint } => format!(
            "joint {joint}'s reading is off by a factor of {} (a scale error of {} ppm {pm})",
            format_args!("{:.6}", 1.0 + t),
            sig(t * 1e6, 3)
        ),
        EffectSpec::PeriodicJointError { joint, period_si } => {
            let a = t.hypot(theta.get(1).copied().unwrap_or(0.0));
            if prismatic {
                format!(
                    "joint {joint} has a periodic error of {} mm amplitude {pm} repeating every {} mm of travel",
                    sig(a * 1e3, 2),
                    sig(period_si * 1e3, 3)
                )
            } else {
                format!(
                    "joint {joint} has a periodic error of {} mrad amplitude {pm} repeating every {} deg of its angle ({} times per revolution)",
                    sig(a * 1e3, 2),
                    sig(period_si.to_degrees(), 3),
                    sig(std::f64::consts::TAU / period_si, 3)
                )
            }
        }
        EffectSpec::ThermalExpansion { reference_temp_c } => {
            let (lo, hi) = ctx
                .rows
                .iter()
                .filter_map(|r| r.temp_c)
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| (l.min(v), h.max(v)));
            format!(
                "lengths grow by {} ppm per K of temperature {pm} (the temperature ran from {:.1} to {:.1} C; reference {:.1} C)",
                sig(t * 1e6, 3),
                lo,
                hi,
                reference_temp_c
            )
        }
        EffectSpec::LinkCompliance { link } => {
            let mmax = lin.bend.iter().filter_map(|b| b.get(link - 1)).map(|(v, _)| v.norm()).fold(0.0, f64::max);
            format!(
                "link {link} (between joints {link} and {}) bends {} rad per N m of the load moment it carries across joint {}'s axis {pm}, up to {} mrad over these poses",
                link + 1,
                sig(t, 2),
                link + 1,
                sig(t * mmax * 1e3, 2)
            )
        }
        EffectSpec::TimeDrift => {
            let hours = ctx.rows.iter().filter_map(|r| r.t_s).fold(0.0f64, f64::max) / 3600.0;
            format!(
                "lengths drift by {} ppm per hour {pm} over the {:.1} h recording, as a machine warming up does",
                sig(t * 1e6, 3),
                hours
            )
        }
    };
    format!(
        "{what}; modelling it lowers the held-out RMS from {} to {} mm ({} after correcting for {m} candidates)",
        sig(before, 3),
        sig(after, 3),
        fmt_p(p)
    )
}

/// Implied joint error (joint units) and its weight of a whitened residual, per row.
fn implied(col: &nalgebra::DMatrix<f64>, c: usize, e: &[Vector3<f64>]) -> (Vec<f64>, Vec<f64>) {
    let mut u = Vec::with_capacity(e.len());
    let mut w = Vec::with_capacity(e.len());
    for (i, ei) in e.iter().enumerate() {
        let d = col.fixed_view::<3, 1>(3 * i, c);
        let dd = d.norm_squared();
        if dd > 0.0 {
            u.push(d.dot(ei) / dd);
            w.push(dd);
        } else {
            u.push(0.0);
            w.push(0.0);
        }
    }
    (u, w)
}

fn evidence(
    finding: usize,
    spec: &EffectSpec,
    ctx: &Ctx,
    lin: &Lin,
    e0: &[Vector3<f64>],
    e1: &[Vector3<f64>],
    telling: &str,
) -> Evidence {
    let ds = nalgebra::DMatrix::from_column_slice(lin.ds.len(), 1, lin.ds.as_slice());
    let link_col;
    let (x, col, c, factor, y_label): (Vec<f64>, &nalgebra::DMatrix<f64>, usize, f64, String) = match spec {
        EffectSpec::LinkCompliance { link } => {
            // The effect's column per unit of bend: the implied bend angle per row.
            let moments: Vec<f64> = lin.bend.iter().map(|b| b.get(link - 1).map_or(0.0, |(v, _)| v.norm())).collect();
            let mut m = ctx.effect_columns(lin, spec).unwrap_or_else(|| nalgebra::DMatrix::zeros(3 * lin.n, 1));
            for (i, mi) in moments.iter().enumerate() {
                let scale = if *mi > 0.0 { *mi } else { 1.0 };
                for r in 0..3 {
                    m[(3 * i + r, 0)] /= scale;
                }
            }
            link_col = m;
            (moments, &link_col, 0, 1e3, format!("bend of link {link} implied by the held-out residual [mrad]"))
        }
        EffectSpec::ThermalExpansion { .. } => (
            ctx.rows.iter().map(|r| r.temp_c.unwrap_or(f64::NAN)).collect(),
            &ds,
            0,
            1e6,
            "implied relative length change [ppm]".into(),
        ),
        EffectSpec::TimeDrift => (
            ctx.rows.iter().map(|r| r.t_s.unwrap_or(f64::NAN) / 3600.0).collect(),
            &ds,
            0,
            1e6,
            "implied relative length change [ppm]".into(),
        ),
        _ => {
            let j = spec.joint().unwrap_or(1) - 1;
            let x = match spec {
                EffectSpec::JointCompliance { .. } => lin.tau.iter().map(|t| t[j]).collect(),
                EffectSpec::Backlash { .. } => ctx
                    .rows
                    .iter()
                    .map(|r| r.dir.as_ref().and_then(|d| d.get(j)).copied().unwrap_or(0) as f64)
                    .collect(),
                EffectSpec::PeriodicJointError { period_si, .. } => {
                    ctx.rows.iter().map(|r| (r.q[j] / period_si).rem_euclid(1.0) * 360.0).collect()
                }
                _ => ctx.rows.iter().map(|r| r.q[j].to_degrees()).collect(),
            };
            let unit = if ctx.kinds[j] == JointKind::Prismatic { "mm" } else { "mrad" };
            (x, &lin.dq, j, 1e3, format!("joint {} error implied by the held-out residual [{unit}]", j + 1))
        }
    };
    let (b, _) = implied(col, c, e0);
    let (a, _) = implied(col, c, e1);
    let x_label = match spec {
        EffectSpec::JointCompliance { .. } => format!("{telling} [N m]"),
        EffectSpec::TimeDrift => "time [h]".into(),
        EffectSpec::ThermalExpansion { .. } => "temperature [C]".into(),
        EffectSpec::LinkCompliance { .. } => format!("{telling} [N m]"),
        EffectSpec::Backlash { .. } => telling.to_string(),
        EffectSpec::PeriodicJointError { period_si, .. } => {
            format!("{telling} modulo its period of {} deg (phase in the cycle) [deg]", sig(period_si.to_degrees(), 3))
        }
        _ => format!("{telling} [deg]"),
    };
    Evidence {
        finding,
        x_label,
        y_label,
        x,
        before: b.iter().map(|v| v * factor).collect(),
        after: a.iter().map(|v| v * factor).collect(),
    }
}

/// Screening of held-out residuals `e` (whitened, per analysis row) against every input.
fn screen(ctx: &Ctx, lin: &Lin, e: &[Vector3<f64>]) -> Vec<InputStructure> {
    let n = ctx.rows.len();
    let bins = (n / 25).clamp(4, 12);
    let mut tests: Vec<(String, String, stats::BinnedTest)> = Vec::new();
    let ds = nalgebra::DMatrix::from_column_slice(lin.ds.len(), 1, lin.ds.as_slice());
    let nj = ctx.kinds.len();
    let vary = |x: &[f64]| {
        let (lo, hi) = x.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| (l.min(*v), h.max(*v)));
        hi - lo > 1e-9 * (lo.abs() + hi.abs()).max(1e-12)
    };
    for j in 0..nj {
        let (u, w) = implied(&lin.dq, j, e);
        if w.iter().all(|v| *v == 0.0) {
            continue;
        }
        let qty = format!("joint {} angle error ({})", j + 1, ctx.names.get(j).cloned().unwrap_or_default());
        for k in 0..nj {
            let x = ctx.q(k);
            if vary(&x) {
                let g = quantile_groups(&x, bins);
                tests.push((qty.clone(), format!("q{}", k + 1), binned_anova(&x, &u, &w, &g, bins)));
            }
        }
        let tau: Vec<f64> = lin.tau.iter().map(|t| t[j]).collect();
        if vary(&tau) {
            let g = quantile_groups(&tau, bins);
            tests.push((qty.clone(), format!("gravity_torque{}", j + 1), binned_anova(&tau, &u, &w, &g, bins)));
        }
        if ctx.rows.iter().all(|r| r.dir.as_ref().is_some_and(|d| d.len() > j)) {
            let x: Vec<f64> = ctx.rows.iter().map(|r| r.dir.as_ref().map_or(0, |d| d[j]) as f64).collect();
            let g: Vec<usize> = x
                .iter()
                .map(|v| {
                    if *v < 0.0 {
                        0
                    } else if *v > 0.0 {
                        1
                    } else {
                        2
                    }
                })
                .collect();
            tests.push((qty.clone(), format!("dir{}", j + 1), binned_anova(&x, &u, &w, &g, 2)));
        }
    }
    let (v, w) = implied(&ds, 0, e);
    let qty = "relative length change".to_string();
    let mut scalar = |name: &str, get: &dyn Fn(&PoseMeasurement) -> Option<f64>| {
        let x: Vec<f64> = ctx.rows.iter().filter_map(|r| get(r)).collect();
        if x.len() == n && vary(&x) {
            let g = quantile_groups(&x, bins);
            tests.push((qty.clone(), name.to_string(), binned_anova(&x, &v, &w, &g, bins)));
        }
    };
    scalar("t_s", &|r| r.t_s);
    scalar("temp_c", &|r| r.temp_c);
    scalar("payload_kg", &|r| r.payload_kg);
    let m = tests.len();
    tests
        .into_iter()
        .map(|(quantity, input, t)| {
            let pc = bonferroni(t.p_value, m);
            InputStructure {
                quantity,
                input,
                f: t.f,
                p_value: t.p_value,
                p_corrected: pc,
                explained_fraction: t.explained,
                significant: pc < ctx.opts.alpha,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn candidates_cover_one_another_only_within_their_kind() {
        let c = Cand::Fixed(EffectSpec::TimeDrift);
        assert!(c.covered_by(&EffectSpec::ThermalExpansion { reference_temp_c: 20.0 }));
        let b = Cand::Fixed(EffectSpec::Backlash { joint: 2 });
        assert!(b.covered_by(&EffectSpec::Backlash { joint: 2 }));
        assert!(!b.covered_by(&EffectSpec::Backlash { joint: 3 }));
        assert!(!b.covered_by(&EffectSpec::JointCompliance { joint: 2 }));
        let p = Cand::Periodic { joint: 1 };
        assert!(p.covered_by(&EffectSpec::PeriodicJointError { joint: 1, period_si: 0.1 }));
    }

    #[test]
    fn numbers_in_words() {
        assert_eq!(sig(0.1134, 2), "0.11");
        assert_eq!(sig(7.04e-6, 2), "7.0e-6");
        assert_eq!(fmt_p(1e-20), "p < 1e-15");
    }
}
