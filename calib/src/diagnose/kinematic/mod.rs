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
//!
//! The selection (steps 3's tests and order) is the diagnose engine's
//! ([`crate::diagnose::engine`]); this module is the kinematic family: its candidates
//! (`candidates.rs`), the linearised screening and full refits (`family.rs`, `linear.rs`), the
//! checks (`checks.rs`), the screening of residuals (`screen.rs`) and the words (`words.rs`).

mod bounds;
mod candidates;
mod checks;
mod family;
mod linear;
mod screen;
mod words;

use bounds::default_true;

pub use bounds::Bounds;
pub use words::STRONG_STRUCTURE_P;
use words::{summary, verdict_words};

use std::collections::BTreeMap;

use ferrocal_robot::{Kinematics, RobotModel};
use serde::{Deserialize, Serialize};

use crate::diagnose::engine::{select, Correction, Improvement, Policy, Selection, Test};
use crate::diagnose::report::{fmt_p, sig, Diagnosis, Evidence};
use crate::effects::EffectSpec;
use crate::error::{CalibError, Result};
use crate::kinematic::{calibrate, KinematicOptions, ModelParams};
use crate::lsq::LmOptions;
use crate::measurement::{PoseMeasurement, Split};
use candidates::{enumerate_candidates, period_grids};
use family::{Ctx, KinematicFamily};

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
    /// Candidates confirmed by full refits per step (in order of held-out improvement; those
    /// the cheap checks reject do not count).
    pub max_checked: usize,
    /// Position standard deviation of rows without a `sigma` column.
    pub sigma_position_m: f64,
    /// When no row carries a `sigma`, take the noise level from the data (the geometric fit's
    /// RMS per coordinate, corrected for the fitted parameters) instead of
    /// [`sigma_position_m`](Self::sigma_position_m): a motion-capture table's millimetre is not
    /// a tracker's 0.02 mm. It changes no decision (the tests are scale-free) but every stated
    /// standard deviation of a parameter.
    #[serde(default = "default_true")]
    pub sigma_from_data: bool,
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
            sigma_from_data: true,
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
    /// The outcome in one word (`accepted`, `rejected`, `not_significant`, ...; see
    /// `diagnose::report::Verdict::status`).
    #[serde(default)]
    pub status: String,
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

/// The whole analysis (`shared/spec/diagnose.md` plus extra fields).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct DiagnoseReport {
    /// One or two sentences for the top of every view: what was found, or why nothing was
    /// claimed although the residuals show structure (the best candidate and its verdict).
    #[serde(default)]
    pub summary: String,
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
    let mut noted_sigma: Option<String> = None;
    let data_opts;
    let opts = if opts.sigma_from_data && rows.iter().all(|r| r.sigma_m.is_none()) {
        // The noise level from the geometric fit of the analysis rows.
        let kin = KinematicOptions {
            model_params: opts.model_params.clone(),
            use_orientation: false,
            sigma_position_m: opts.sigma_position_m,
            lm: LmOptions { max_iterations: 100, ..LmOptions::default() },
            ..KinematicOptions::default()
        };
        match calibrate(model, &analysis, &kin) {
            Ok(c) => {
                let n = 3 * analysis.len();
                let dof = n.saturating_sub(c.free.len()).max(1);
                let s = c.train_after.rms_mm * 1e-3 / 3f64.sqrt() * (n as f64 / dof as f64).sqrt();
                if s.is_finite() && s > 0.0 {
                    data_opts = DiagnoseOptions { sigma_position_m: s, ..opts.clone() };
                    noted_sigma = Some(format!(
                        "the table has no sigma column: the position noise is taken from the geometric fit, {} mm per coordinate (its residual RMS corrected for {} fitted parameters), which includes whatever the geometric model leaves out",
                        sig(s * 1e3, 3),
                        c.free.len()
                    ));
                    &data_opts
                } else {
                    opts
                }
            }
            Err(_) => opts,
        }
    } else {
        opts
    };
    let sigma: Vec<f64> = analysis.iter().map(|r| r.sigma_m.unwrap_or(opts.sigma_position_m)).collect();
    let k = opts.folds;
    let folds_idx: Vec<Vec<usize>> = (0..k).map(|f| (0..analysis.len()).filter(|i| i % k == f).collect()).collect();
    let mut notes = Vec::new();
    if let Some(n) = noted_sigma {
        notes.push(n);
    } else if rows.iter().any(|r| r.sigma_m.is_none()) {
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
        summary: String::new(),
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
            report.summary = format!("Declined: {}.", report.declined.as_deref().unwrap_or_default());
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
        report.summary = format!("Declined: {}.", report.declined.as_deref().unwrap_or_default());
        report.elapsed_s = t0.elapsed().as_secs_f64();
        return Ok(report);
    }

    // Candidates, and the engine's forward selection over them.
    let (cands, untestable) = enumerate_candidates(&ctx, rows, &geo)?;
    report.untestable = untestable;
    let heldout_mm = report.final_fit.heldout_rms_mm;
    let mut family = KinematicFamily::new(ctx, validation.clone(), cands, geo, heldout_mm);
    let policy = Policy {
        alpha: opts.alpha,
        min_improvement: opts.min_improvement,
        max_effects: opts.max_effects,
        min_sin_angle: opts.min_sin_angle,
        test: Test::PairedT,
        correction: Correction::PerKind,
        improvement: Improvement::MseFraction,
        selection: Selection::Ranked { max_checked: opts.max_checked },
    };
    let diagnosis = select(&mut family, &policy)?;
    finish(&mut report, &family, diagnosis, opts);
    report.elapsed_s = t0.elapsed().as_secs_f64();
    Ok(report)
}

/// The calibration with the physics in it (`diagnose --out`): the geometric model and the
/// accepted effects of `report` refitted together on every row of the recording that is not
/// marked `test` (the analysis and the validation rows), with the options the diagnosis used.
/// Without findings it is the geometric calibration. `evaluate` then predicts with the effects.
pub fn compensated_calibration(
    model: &RobotModel,
    rows: &[PoseMeasurement],
    report: &DiagnoseReport,
) -> Result<crate::kinematic::KinematicCalibration> {
    let train: Vec<&PoseMeasurement> = rows.iter().filter(|r| r.split != Some(Split::Test)).collect();
    let opts = KinematicOptions {
        model_params: report.settings.model_params.clone(),
        use_orientation: false,
        sigma_position_m: report.settings.sigma_position_m,
        effects: report.findings.iter().map(|f| f.spec.clone()).collect(),
        lm: LmOptions { max_iterations: 100, ..LmOptions::default() },
        ..KinematicOptions::default()
    };
    calibrate(model, &train, &opts)
}

/// The JSON view of the engine's result: steps, findings, evidence, final figures and notes.
fn finish(
    report: &mut DiagnoseReport,
    family: &KinematicFamily,
    diagnosis: Diagnosis<Vec<EffectSpec>>,
    opts: &DiagnoseOptions,
) {
    report.nominal.cv_rms_mm = family.nominal_cv_mm;
    report.screening_nominal = family.screening_nominal.clone();
    report.final_fit.cv_rms_mm = family.final_cv_mm;
    report.screening_final = family.screening_final.clone();
    report.final_fit.train_rms_mm = family.final_train_mm;
    report.final_fit.heldout_rms_mm = family.final_heldout_mm;
    report.notes.extend(diagnosis.notes);
    report.steps = diagnosis
        .steps
        .iter()
        .map(|s| Step {
            candidates: s
                .rows
                .iter()
                .map(|r| CandidateScore {
                    effect: r.effect.clone(),
                    joints: r.joints.clone(),
                    label: r.label.clone(),
                    cv_rms_before_mm: r.heldout_before,
                    cv_rms_after_mm: r.heldout_after,
                    improvement: r.improvement,
                    p_value: r.p_value,
                    p_corrected: r.p_corrected,
                    parameters: r.parameters.clone(),
                    sin_angle_to_geometry: r.overlap_sine,
                    verdict: verdict_words(r, s.candidates_tried, opts),
                    status: r.verdict.status().to_string(),
                })
                .collect(),
            accepted: s.accepted.clone(),
        })
        .collect();
    for f in diagnosis.findings.into_iter() {
        if let Some(mut ev) = f.evidence.clone() {
            ev.finding = report.findings.len();
            report.evidence.push(ev);
        }
        let d = f.decision;
        let group = f.accepted.len() > 1;
        for spec in &f.accepted {
            // A group's members are findings of their own (each with its `spec`, for
            // `calibrate --effects`), with the group's held-out figures and statement.
            let parameters = if group {
                let tag = spec.joint().map(|j| format!("joint{j}.")).unwrap_or_default();
                f.parameters
                    .iter()
                    .filter_map(|(k, v)| k.strip_prefix(tag.as_str()).map(|k| (k.to_string(), *v)))
                    .collect()
            } else {
                f.parameters.clone()
            };
            report.findings.push(Finding {
                effect: spec.name().into(),
                joints: spec.joints_reported(),
                parameters,
                heldout_rms_before_mm: f.heldout_before,
                heldout_rms_after_mm: f.heldout_after,
                explained_fraction: f.explained_fraction,
                p_value: d.p_corrected,
                statement: f.statement.clone(),
                spec: spec.clone(),
                p_value_uncorrected: d.p_uncorrected,
                candidates_tried: d.candidates_tried,
                cv_rms_before_mm: d.heldout_before,
                cv_rms_after_mm: d.heldout_after,
                relative_std: d.relative_std,
                std_from_covariance: f.std_from_covariance,
                sin_angle_to_geometry: d.overlap_sine.unwrap_or(f64::NAN),
                telling_input: f.telling_input.clone(),
                alternatives: d.alternatives.clone(),
            });
        }
    }
    let capped = diagnosis.capped;
    if family.validation.is_empty() {
        report.nominal.heldout_rms_mm = report.nominal.cv_rms_mm;
        report.final_fit.heldout_rms_mm = report.final_fit.cv_rms_mm;
    }
    // Rejected-but-significant candidates of the last step, in words.
    if let Some(last) = report.steps.last() {
        for c in last.candidates.iter().filter(|c| c.status == "rejected") {
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
    report.summary = summary(report, opts);
}
