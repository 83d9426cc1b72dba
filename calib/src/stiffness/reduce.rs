//! Model reduction to practically identifiable parameters (Klimchik et al. 2015, M1 to M6).
//!
//! | step | what | 6-DOF arm in the source |
//! | --- | --- | --- |
//! | M0 | complete model: every joint compliance, all 36 entries of every spring | 258 |
//! | M1 | symmetry: `k_rc = k_cr` share one parameter | 153 |
//! | M2 | sparsity template of each link's beam physics ([`beam_template`]) | 62 |
//! | M3 | aggregation: a joint compliance and the spring entry about the same axis are one parameter | 56 |
//! | M4 | SVD partition of the reduced regressor: G1 identifiable, G2 without effect (eliminated, fixed at the prior), G3 coupled | |
//! | M5 | in each coupled group `dim - rank` parameters are fixed at their prior: those whose expected contribution (column norm times prior magnitude) is smallest, by pivoted QR after the G1 columns are projected out | 26 |
//! | M6 | parameters whose parameter-to-noise ratio `nu = abs(pi) / sigma` is below the threshold (2) are fixed at their prior, one at a time, smallest first, refitting after each; a compliance that must be positive (joint, diagonal entry) with a negative estimate, or a coupling with `k_rc^2 > k_rr k_cc`, counts as `nu = 0` | |
//!
//! Every step is fitted and, with a validation problem, scored on it: the RMS of the predicted
//! position errors against the measurements (and against the truth in simulations). The
//! difference to the previous step is the step's accuracy cost; for M6 the RMS effect of the
//! dropped parameters' last estimates on the validation positions says what dropping them can
//! cost at most.
//!
//! "Prior" values are the complete-model values the fixed parameters take: design estimates
//! (CAD, beam models) when given, else zero.

use faer::Mat;
use ferrocal_robot::stiffness::{beam_template, ComplianceLayout, ParamKind};
use nalgebra::{DMatrix, DVector, Matrix6};
use serde::{Deserialize, Serialize};

use crate::identifiability::{analyze, ParamClass};
use crate::stiffness::error::{Result, StiffnessIdError};
use crate::stiffness::fit::{fit_matrix, reduced_regressor, rms_max, Fit};
use crate::stiffness::param::{Parameterization, ReducedParam};
use crate::stiffness::problem::LinearProblem;

mod physical;
pub use physical::{identify_checked, physical_problems};

/// Options of [`reduce`] and [`identify_checked`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReductionSettings {
    /// Relative singular value below which a direction counts as unobservable (on the regressor
    /// with unit-norm columns).
    pub rank_tol: f64,
    /// Smallest parameter-to-noise ratio a parameter keeps its place with (the source: 2).
    pub nu_threshold: f64,
}

impl Default for ReductionSettings {
    fn default() -> Self {
        Self { rank_tol: 1e-6, nu_threshold: 2.0 }
    }
}

impl ReductionSettings {
    /// Checks the values.
    pub fn validate(&self) -> Result<()> {
        if !(self.rank_tol > 0.0 && self.rank_tol < 1.0) {
            return Err(StiffnessIdError::Options(format!("rank tolerance {} must be in (0, 1)", self.rank_tol)));
        }
        if !(self.nu_threshold.is_finite() && self.nu_threshold >= 0.0) {
            return Err(StiffnessIdError::Options(format!(
                "parameter-to-noise threshold {} must be finite and non-negative",
                self.nu_threshold
            )));
        }
        Ok(())
    }
}

/// A parameter the reduction fixed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FixedParam {
    /// The parameter.
    pub param: ReducedParam,
    /// The value it is fixed at.
    pub value: f64,
    /// The step that fixed it (`M2` ... `M6`).
    pub step: String,
    /// Why.
    pub reason: String,
}

/// One step of the reduction.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReductionStep {
    /// `M0` to `M6`.
    pub code: String,
    /// What the step does.
    pub title: String,
    /// Free parameters after it.
    pub n_params: usize,
    /// Parameters it removed, merged or fixed.
    pub removed: Vec<String>,
    /// Rank of the regressor of the free parameters.
    pub rank: usize,
    /// Condition number of the column-scaled regressor over its rank.
    pub condition_number: f64,
    /// Whitened residual RMS of the fit (1 when the noise model is right).
    pub s0: f64,
    /// RMS predicted position error against the validation measurements.
    pub validation_rms_m: Option<f64>,
    /// RMS predicted position error against the validation truth (simulations).
    pub validation_truth_rms_m: Option<f64>,
    /// The step's accuracy cost: change of the validation RMS (truth when known) from the
    /// previous step; negative when the step improves the prediction.
    pub cost_m: Option<f64>,
    /// For M6: RMS over the validation positions of the dropped parameters' last estimates
    /// (what fixing them can cost at most).
    pub dropped_effect_m: Option<f64>,
    /// Remarks.
    pub note: String,
    /// The step's estimate as complete-model values (free and fixed).
    #[serde(skip)]
    pub complete_values: Vec<f64>,
}

/// The result of [`reduce`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Reduction {
    /// Every step, M0 first.
    pub steps: Vec<ReductionStep>,
    /// The final free parameters.
    pub param: Parameterization,
    /// Every fixed parameter with its value and reason.
    pub fixed: Vec<FixedParam>,
    /// The final fit.
    pub fit: Fit,
    /// Class of each M3 parameter in the SVD partition (M4).
    pub classes: Vec<(String, ParamClass)>,
    /// Plain-words coupled groups (M5).
    pub coupled_groups: Vec<String>,
    /// The final estimate as complete-model values (free and fixed).
    pub complete_values: Vec<f64>,
    /// Physical problems of the final estimate (empty when it is physical).
    pub physical_problems: Vec<String>,
}

impl Reduction {
    /// The step with a code.
    pub fn step(&self, code: &str) -> Option<&ReductionStep> {
        self.steps.iter().find(|s| s.code == code)
    }
}

/// M1: one parameter per symmetric pair of spring entries.
pub fn symmetric(layout: &ComplianceLayout) -> Parameterization {
    let mut params = Vec::new();
    for (i, p) in layout.params.iter().enumerate() {
        match p.kind {
            ParamKind::Spring { spring, row, col } => {
                if row > col {
                    continue;
                }
                let mut basis = vec![(i, 1.0)];
                if row < col {
                    if let Some(j) = layout.spring_index(spring, col, row) {
                        basis.push((j, 1.0));
                    }
                }
                params.push(ReducedParam { name: p.name.clone(), unit: p.unit.clone(), basis, absorbed: vec![] });
            }
            _ => params.push(ReducedParam {
                name: p.name.clone(),
                unit: p.unit.clone(),
                basis: vec![(i, 1.0)],
                absorbed: vec![],
            }),
        }
    }
    Parameterization { n_complete: layout.len(), params }
}

/// M2: the parameters of `param` allowed by each spring's beam template, and those removed.
pub fn sparsity(layout: &ComplianceLayout, param: &Parameterization) -> (Parameterization, Vec<ReducedParam>) {
    let mut keep = Vec::new();
    let mut gone = Vec::new();
    for p in &param.params {
        let allowed = match p.basis.first().map(|(i, _)| layout.params[*i].kind) {
            Some(ParamKind::Spring { spring, row, col }) => beam_template(layout.beam_axes[spring])[row][col],
            _ => true,
        };
        if allowed {
            keep.push(p.clone());
        } else {
            gone.push(p.clone());
        }
    }
    (Parameterization { n_complete: param.n_complete, params: keep }, gone)
}

/// M3: every aggregated joint compliance is carried by its spring's diagonal entry. Returns the
/// merged names.
pub fn aggregate(layout: &ComplianceLayout, param: &Parameterization) -> (Parameterization, Vec<String>) {
    let mut out = param.clone();
    let mut merged = Vec::new();
    for g in &layout.aggregations {
        let (Some(ji), Some(si)) = (layout.joint_index(g.joint), layout.spring_index(g.spring, g.entry, g.entry))
        else {
            continue;
        };
        let Some(jp) = out.params.iter().position(|p| p.basis == vec![(ji, 1.0)]) else { continue };
        let Some(sp) = out.params.iter().position(|p| p.basis.first().map(|b| b.0) == Some(si)) else { continue };
        let joint = out.params[jp].clone();
        out.params[sp].name = format!("{}+{}", out.params[sp].name, joint.name);
        out.params[sp].absorbed.push(ji);
        out.params[sp].absorbed.extend(joint.absorbed.iter().copied());
        merged.push(format!("{} into {}", joint.name, out.params[sp].name));
        out.params.remove(jp);
    }
    (out, merged)
}

fn prior_value(p: &ReducedParam, prior: Option<&[f64]>) -> f64 {
    match prior {
        None => 0.0,
        Some(pr) => {
            let den: f64 = p.basis.iter().map(|(_, c)| c * c).sum();
            let own: f64 = p.basis.iter().map(|(i, c)| c * pr[*i]).sum::<f64>() / den.max(1e-300);
            own + p.absorbed.iter().map(|i| pr[*i]).sum::<f64>()
        }
    }
}

/// Complete-model values of fixed parameters.
pub fn fixed_vector(n_complete: usize, fixed: &[FixedParam]) -> DVector<f64> {
    let mut v = DVector::zeros(n_complete);
    for f in fixed {
        for &(i, c) in &f.param.basis {
            v[i] += c * f.value;
        }
    }
    v
}

/// Fits the free parameters with the fixed ones at their values.
pub fn fit_with_fixed(
    problem: &LinearProblem,
    free: &Parameterization,
    fixed: &DVector<f64>,
    rank_tol: f64,
) -> Result<Fit> {
    let a = reduced_regressor(problem, free);
    let y = &problem.y - &problem.a * fixed;
    fit_matrix(&a, &y, free, rank_tol)
}

/// RMS of the predicted position errors of complete values on a problem: against the
/// measurements and, when known, the truth.
pub fn prediction_rms(problem: &LinearProblem, complete: &DVector<f64>) -> (f64, Option<f64>) {
    let pred = &problem.a * complete;
    let meas = rms_max(&problem.position_errors_m(&(&problem.y - &pred))).0;
    let truth = problem.y_true.as_ref().map(|t| rms_max(&problem.position_errors_m(&(t - &pred))).0);
    (meas, truth)
}

fn unit_columns(a: &DMatrix<f64>) -> DMatrix<f64> {
    let mut s = a.clone();
    for mut c in s.column_iter_mut() {
        let n = c.norm();
        if n > 0.0 {
            c /= n;
        }
    }
    s
}

struct Stage<'a> {
    problem: &'a LinearProblem,
    validation: Option<&'a LinearProblem>,
    settings: ReductionSettings,
    steps: Vec<ReductionStep>,
}

impl Stage<'_> {
    fn record(
        &mut self,
        code: &str,
        title: &str,
        free: &Parameterization,
        fixed: &[FixedParam],
        removed: Vec<String>,
        note: String,
    ) -> Result<Fit> {
        let fv = fixed_vector(free.n_complete, fixed);
        let f = fit_with_fixed(self.problem, free, &fv, self.settings.rank_tol)?;
        let complete = free.expand(&f.values) + &fv;
        let (vm, vt) = match self.validation {
            Some(v) => {
                let (m, t) = prediction_rms(v, &complete);
                (Some(m), t)
            }
            None => (None, None),
        };
        let cost =
            self.steps.last().and_then(|prev| match (vt, prev.validation_truth_rms_m, vm, prev.validation_rms_m) {
                (Some(a), Some(b), ..) => Some(a - b),
                (_, _, Some(a), Some(b)) => Some(a - b),
                _ => None,
            });
        self.steps.push(ReductionStep {
            code: code.into(),
            title: title.into(),
            n_params: free.len(),
            removed,
            rank: f.rank,
            condition_number: f.condition_number,
            s0: f.s0,
            validation_rms_m: vm,
            validation_truth_rms_m: vt,
            cost_m: cost,
            dropped_effect_m: None,
            note,
            complete_values: complete.iter().copied().collect(),
        });
        Ok(f)
    }
}

/// Reduces the complete model of `problem` step by step (see the module documentation).
/// `validation` (same model) scores each step; `prior` gives the complete-model values that
/// fixed parameters take (zero when `None`).
pub fn reduce(
    problem: &LinearProblem,
    validation: Option<&LinearProblem>,
    prior: Option<&[f64]>,
    settings: &ReductionSettings,
) -> Result<Reduction> {
    settings.validate()?;
    let layout = &problem.layout;
    if let Some(pr) = prior {
        if pr.len() != layout.len() {
            return Err(StiffnessIdError::Options(format!(
                "{} prior values for {} complete parameters",
                pr.len(),
                layout.len()
            )));
        }
    }
    if let Some(v) = validation {
        if v.layout.len() != layout.len() {
            return Err(StiffnessIdError::Options("the validation problem has another parameter layout".into()));
        }
    }
    let mut st = Stage { problem, validation, settings: *settings, steps: Vec::new() };
    let mut fixed: Vec<FixedParam> = Vec::new();

    // M0.
    let m0 = Parameterization::complete(layout);
    st.record("M0", "complete model", &m0, &fixed, vec![], String::new())?;

    // M1.
    let m1 = symmetric(layout);
    let merged: Vec<String> = m1.params.iter().filter(|p| p.basis.len() > 1).map(|p| p.name.clone()).collect();
    st.record(
        "M1",
        "symmetry of every compliance matrix",
        &m1,
        &fixed,
        merged,
        "each k_rc with r < c also stands for k_cr".into(),
    )?;

    // M2.
    let (m2, gone) = sparsity(layout, &m1);
    let gone_names = gone.iter().map(|p| p.name.clone()).collect();
    for p in gone {
        fixed.push(FixedParam {
            param: p,
            value: 0.0,
            step: "M2".into(),
            reason: "zero in the link's beam template".into(),
        });
    }
    st.record("M2", "sparsity templates from link physics", &m2, &fixed, gone_names, String::new())?;

    // M3.
    let (m3, merged) = aggregate(layout, &m2);
    st.record(
        "M3",
        "aggregation of joint and link compliances about the same axis",
        &m3,
        &fixed,
        merged,
        "identical regressor columns: only their sum is observable".into(),
    )?;

    // M4.
    let a3 = reduced_regressor(problem, &m3);
    let id = analyze(&unit_columns(&a3), &m3.names(), settings.rank_tol)?;
    let classes: Vec<(String, ParamClass)> = m3.names().into_iter().zip(id.classes.iter().copied()).collect();
    let g2: Vec<usize> = (0..m3.len()).filter(|&i| id.classes[i] == ParamClass::NotIdentifiable).collect();
    let mut g2_names = Vec::new();
    for &i in &g2 {
        let p = m3.params[i].clone();
        g2_names.push(p.name.clone());
        fixed.push(FixedParam {
            value: prior_value(&p, prior),
            param: p,
            step: "M4".into(),
            reason: "no effect on any measurement (G2)".into(),
        });
    }
    let m4 = m3.without(&g2);
    let n_g1 = id.classes.iter().filter(|c| **c == ParamClass::Identifiable).count();
    let n_g3 = id.classes.iter().filter(|c| **c == ParamClass::Coupled).count();
    st.record(
        "M4",
        "SVD partition: eliminate the parameters without effect (G2)",
        &m4,
        &fixed,
        g2_names,
        format!("rank {}; G1 {n_g1} identifiable, G2 {} without effect, G3 {n_g3} coupled", id.rank, g2.len()),
    )?;

    // M5.
    let a4 = reduced_regressor(problem, &m4);
    let g1: Vec<usize> = (0..m4.len())
        .filter(|&i| m3.index_of(&m4.params[i].name).is_some_and(|k| id.classes[k] == ParamClass::Identifiable))
        .collect();
    let g3: Vec<usize> = (0..m4.len()).filter(|i| !g1.contains(i)).collect();
    let to_fix = choose_coupled_to_fix(&a4, &m4, &g1, &g3, id.rank, prior);
    let mut fixed_names = Vec::new();
    for &i in &to_fix {
        let p = m4.params[i].clone();
        fixed_names.push(p.name.clone());
        fixed.push(FixedParam {
            value: prior_value(&p, prior),
            param: p,
            step: "M5".into(),
            reason: "coupled with others (G3); smallest expected contribution in its group".into(),
        });
    }
    let m5 = m4.without(&to_fix);
    let coupled_groups = id.describe_groups();
    st.record(
        "M5",
        "fix dim - rank parameters of every coupled group",
        &m5,
        &fixed,
        fixed_names,
        format!("{} coupled group(s)", coupled_groups.len()),
    )?;

    // M6.
    let mut free = m5;
    let mut dropped: Vec<(ReducedParam, f64)> = Vec::new();
    loop {
        let fv = fixed_vector(free.n_complete, &fixed);
        let f = fit_with_fixed(problem, &free, &fv, settings.rank_tol)?;
        // A compliance that must be positive (a joint's, a diagonal entry) and comes out
        // negative is resolved as "not distinguishable from zero" too: its ratio counts as 0.
        // Likewise a coupling that no spring can have with its diagonal (`k_rc^2 > k_rr k_cc`;
        // a beam's template pairs each coupling with two diagonal entries only, so this is
        // positive definiteness).
        let complete = free.expand(&f.values) + fixed_vector(free.n_complete, &fixed);
        let unphysical: Vec<bool> = free
            .params
            .iter()
            .enumerate()
            .map(|(i, p)| {
                if must_be_positive(layout, p) {
                    return f.values[i] < 0.0;
                }
                match p.basis.first().map(|(k, _)| layout.params[*k].kind) {
                    Some(ParamKind::Spring { spring, row, col }) if row != col => {
                        let d = |r: usize| layout.spring_index(spring, r, r).map(|k| complete[k]).unwrap_or(0.0);
                        f.values[i] * f.values[i] > d(row) * d(col)
                    }
                    _ => false,
                }
            })
            .collect();
        // Fixing at the prior must also be consistent with the data: a parameter whose estimate
        // is further than the threshold (in standard deviations) from its prior stays (without
        // a prior this is the ratio itself).
        let consistent = |i: usize| {
            let p0 = prior_value(&free.params[i], prior);
            (f.values[i] - p0).abs() < settings.nu_threshold * f.std[i]
        };
        // The source's rule first (smallest ratio first); estimates no spring can have only
        // once every remaining parameter is resolved (they often recover as weak ones go).
        let weak = (0..free.len())
            .filter(|&i| !(f.std[i].is_finite()) || (f.nu[i] < settings.nu_threshold && consistent(i)))
            .min_by(|&a, &b| f.nu[a].total_cmp(&f.nu[b]));
        let worst =
            weak.or_else(|| (0..free.len()).filter(|&i| unphysical[i]).min_by(|&a, &b| f.nu[a].total_cmp(&f.nu[b])));
        let Some(i) = worst else { break };
        let p = free.params[i].clone();
        dropped.push((p.clone(), f.values[i]));
        let reason = if unphysical[i] {
            format!(
                "estimate {:.3e} no spring can have (negative compliance or coupling beyond its diagonal)",
                f.values[i]
            )
        } else {
            format!("parameter-to-noise ratio {:.2} below {}", f.nu[i], settings.nu_threshold)
        };
        fixed.push(FixedParam { value: prior_value(&p, prior), reason, param: p, step: "M6".into() });
        free = free.without(&[i]);
        if free.is_empty() {
            break;
        }
    }
    if free.is_empty() {
        return Err(StiffnessIdError::Options(format!(
            "no parameter is resolved by these measurements (every parameter-to-noise ratio below {}): \
             more measurements, larger loads or a better measuring device are needed; parameters that \
             can be trusted: none",
            settings.nu_threshold
        )));
    }
    let dropped_names: Vec<String> = dropped.iter().map(|(p, _)| p.name.clone()).collect();
    let f = st.record(
        "M6",
        "drop parameters below the parameter-to-noise threshold",
        &free,
        &fixed,
        dropped_names,
        format!("threshold nu >= {}", settings.nu_threshold),
    )?;
    if let (Some(v), Some(last)) = (validation, st.steps.last_mut()) {
        let mut eff = DVector::zeros(layout.len());
        for (p, est) in &dropped {
            let fx = fixed.iter().find(|x| x.param.name == p.name).map(|x| x.value).unwrap_or(0.0);
            for &(i, c) in &p.basis {
                eff[i] += c * (est - fx);
            }
        }
        let e = &v.a * eff;
        last.dropped_effect_m = Some(rms_max(&v.position_errors_m(&e)).0);
    }
    let complete = free.expand(&f.values) + fixed_vector(free.n_complete, &fixed);
    let complete_values: Vec<f64> = complete.iter().copied().collect();
    let physical_problems = physical_problems(layout, &complete_values).into_iter().map(|(_, t)| t).collect();
    Ok(Reduction {
        steps: st.steps,
        param: free,
        fixed,
        fit: f,
        classes,
        coupled_groups,
        complete_values,
        physical_problems,
    })
}

/// Whether a reduced parameter is a compliance that must be positive: a joint's, or a diagonal
/// entry of a spring (possibly carrying aggregated joints).
pub fn must_be_positive(layout: &ComplianceLayout, p: &ReducedParam) -> bool {
    p.basis.len() == 1
        && match layout.params[p.basis[0].0].kind {
            ParamKind::Joint { .. } => true,
            ParamKind::Spring { row, col, .. } => row == col,
            _ => false,
        }
}

/// M5's choice: within the coupled parameters (after projecting out the identifiable columns),
/// pivoted QR on columns weighted by their expected contribution keeps the strongest; the rest
/// (`dim - rank` per group) are fixed.
fn choose_coupled_to_fix(
    a: &DMatrix<f64>,
    param: &Parameterization,
    g1: &[usize],
    g3: &[usize],
    rank: usize,
    prior: Option<&[f64]>,
) -> Vec<usize> {
    if g3.is_empty() {
        return vec![];
    }
    let m = a.nrows();
    let mut c = DMatrix::from_fn(m, g3.len(), |i, j| a[(i, g3[j])]);
    if !g1.is_empty() {
        let b = DMatrix::from_fn(m, g1.len(), |i, j| a[(i, g1[j])]);
        let q = b.qr().q();
        let proj = &q * (q.transpose() * &c);
        c -= proj;
    }
    let weights: Vec<f64> = g3
        .iter()
        .map(|&k| {
            let n = a.column(k).norm().max(1e-300);
            match prior {
                Some(pr) => prior_value(&param.params[k], Some(pr)).abs() * n,
                None => 1.0,
            }
        })
        .collect();
    let wmax = weights.iter().copied().fold(0.0, f64::max);
    let fm = Mat::from_fn(m, g3.len(), |i, j| {
        let n = a.column(g3[j]).norm().max(1e-300);
        let w = if wmax > 0.0 { weights[j].max(1e-6 * wmax) } else { 1.0 };
        c[(i, j)] / n * w
    });
    let qr = fm.col_piv_qr();
    let (fwd, _) = qr.P().arrays();
    let keep = rank.saturating_sub(g1.len()).min(g3.len());
    let mut out: Vec<usize> = fwd.iter().skip(keep).map(|&j| g3[j]).collect();
    out.sort_unstable();
    out
}
