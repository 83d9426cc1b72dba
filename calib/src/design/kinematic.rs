//! Kinematic calibration as a design problem: the candidate pool of robot poses measured by a
//! device with a known noise, the predicted parameter deviations and held-out accuracy of a pose
//! set, and their check against repeated simulated calibrations.
//!
//! # Pool
//! [`crate::kinematic::design_jacobian`] gives, per pose, the 3 x c Jacobian `J_k` of the
//! measured position (device frame, metres) with respect to the candidate parameters, each in
//! units of its typical size (1 mm, 1 mrad, 1e-3). With the device's position covariance `C_k =
//! L_k L_k^T` at that pose (anisotropic for a camera: depth is measured worse than the lateral
//! position), the pool rows are `R_k = L_k^-1 J_k`, so `F = sum R_k^T R_k` is the Fisher
//! information. Parameters the whole pool cannot separate are fixed first (the same QR with
//! column pivoting and the same preferences as [`crate::kinematic::calibrate`]: the device frame
//! goes first, then the tool offset, then joint offsets).
//!
//! # Prediction
//! [`crate::kinematic::calibrate`] weights every row with one standard deviation per pose. With
//! `w_k = 1 / s_k^2`, `s_k^2 = trace(C_k) / 3`, its covariance is the sandwich
//! `Cov = H^-1 (sum w_k^2 J_k^T C_k J_k) H^-1`, `H = sum w_k J_k^T J_k` (equal to `F^-1` when the
//! noise is isotropic). The predicted held-out accuracy is the RMS over validation poses of the
//! model's position error `sqrt(trace(J_v Cov J_v^T))` (without the measurement noise, reported
//! beside it).
//!
//! # Check
//! [`monte_carlo`] draws true robots and noisy measurements with a [`CalibrationSimulator`] (the
//! datasets crate's simulator in the tools and tests), calibrates each with `calibrate`, and
//! compares the parameter scatter and the held-out error with the prediction.

use std::collections::BTreeMap;

use ferrocal_robot::{Parameterized, RobotModel, Unit};
use nalgebra::{Cholesky, DMatrix, Isometry3, Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use crate::design::pool::InformationPool;
use crate::error::{CalibError, Result};
use crate::identifiability::analyze;
use crate::kinematic::{calibrate, design_jacobian, KinematicOptions, ModelParams};
use crate::measurement::PoseMeasurement;

/// Which parameters a plan must identify (TOML table `[identify]` of a plan file).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IdentifySettings {
    /// The robot model's own parameters (`{ kind = "all" }`, `"default"`, `"none"`, or
    /// `{ kind = "prefixes", prefixes = [...] }`).
    #[serde(default = "default_model_params")]
    pub model_params: ModelParams,
    /// Identify the device-to-base frame too (else the device's stated placement is used and
    /// the model's parameters are expressed in the device frame, the source's choice).
    #[serde(default)]
    pub estimate_device_frame: bool,
    /// Identify joint offsets.
    #[serde(default)]
    pub joint_offsets: bool,
    /// Identify the target's offset on the tool.
    #[serde(default)]
    pub estimate_tool: bool,
    /// Relative singular-value tolerance of the identifiability analysis.
    #[serde(default = "default_rank_tol")]
    pub rank_tolerance: f64,
}

fn default_model_params() -> ModelParams {
    ModelParams::All
}
fn default_rank_tol() -> f64 {
    1e-8
}

impl Default for IdentifySettings {
    fn default() -> Self {
        Self {
            model_params: ModelParams::All,
            estimate_device_frame: false,
            joint_offsets: false,
            estimate_tool: false,
            rank_tolerance: default_rank_tol(),
        }
    }
}

impl IdentifySettings {
    /// Calibration options for a device at `t_device_base` (positions only).
    pub fn options(&self, t_device_base: Isometry3<f64>) -> KinematicOptions {
        KinematicOptions {
            model_params: self.model_params.clone(),
            estimate_device_frame: self.estimate_device_frame,
            fixed_device_frame: Some(t_device_base),
            joint_offsets: self.joint_offsets,
            estimate_tool: self.estimate_tool,
            use_orientation: false,
            rank_tolerance: self.rank_tolerance,
            ..KinematicOptions::default()
        }
    }
}

/// The SI size of one scaled unit of a candidate parameter (see the state layout of
/// [`crate::kinematic`]).
pub fn scale_of(name: &str, model: &RobotModel) -> f64 {
    if let Some(p) = model.parameters().into_iter().find(|p| p.name == name) {
        return p.unit.typical_scale();
    }
    if name.ends_with("_rad") {
        Unit::Radian.typical_scale()
    } else if name.ends_with("_m") {
        Unit::Metre.typical_scale()
    } else {
        Unit::Dimensionless.typical_scale()
    }
}

/// A pool of robot poses for kinematic calibration.
#[derive(Clone, Debug)]
pub struct KinematicPool {
    /// Joint values of every candidate.
    pub poses: Vec<Vec<f64>>,
    /// Identifiable parameters (the pool's columns).
    pub names: Vec<String>,
    /// Candidates the whole pool cannot separate from the others (fixed at their start).
    pub not_identifiable: Vec<String>,
    /// SI size of one scaled unit per column.
    pub scales: Vec<f64>,
    /// Per pose: d(position, m, device frame)/d(scaled parameters), 3 x p.
    pub jacobians: Vec<DMatrix<f64>>,
    /// Per pose: the device's position covariance (m^2, device frame).
    pub covariances: Vec<Matrix3<f64>>,
    /// The whitened pool (`L_k^-1 J_k`).
    pub pool: InformationPool,
}

/// Builds the pool for `poses` with the device covariances `covariances` (one per pose).
pub fn kinematic_pool(
    model: &RobotModel,
    poses: &[Vec<f64>],
    covariances: &[Matrix3<f64>],
    opts: &KinematicOptions,
) -> Result<KinematicPool> {
    if poses.len() != covariances.len() {
        return Err(CalibError::Data(format!("{} poses but {} covariances", poses.len(), covariances.len())));
    }
    if poses.is_empty() {
        return Err(CalibError::TooFew("no candidate poses".into()));
    }
    let (j, names_all) = design_jacobian(model, poses, 1.0, false, opts)?;
    let c = names_all.len();
    let mut whitened = DMatrix::zeros(j.nrows(), c);
    let mut winv = Vec::with_capacity(poses.len());
    for (k, cov) in covariances.iter().enumerate() {
        let chol = Cholesky::new(*cov).ok_or_else(|| {
            CalibError::Data(format!("pose {}: the device covariance is not positive definite", k + 1))
        })?;
        let li = chol.l().try_inverse().ok_or_else(|| CalibError::Numeric("covariance factor".into()))?;
        let jk = j.rows(3 * k, 3).into_owned();
        let wk = DMatrix::from_fn(3, 3, |r, s| li[(r, s)]) * &jk;
        whitened.rows_mut(3 * k, 3).copy_from(&wk);
        winv.push(li);
    }
    let weighted = DMatrix::from_fn(whitened.nrows(), c, |r, s| {
        whitened[(r, s)] * crate::kinematic::select::parallel_weight(&names_all[s])
    });
    let id = analyze(&weighted, &names_all, opts.rank_tolerance)?;
    let kept = id.kept();
    let names: Vec<String> = kept.iter().map(|&i| names_all[i].clone()).collect();
    let not_identifiable: Vec<String> = id.fixed.iter().map(|&i| names_all[i].clone()).collect();
    let scales = names.iter().map(|n| scale_of(n, model)).collect();
    let mut jacobians = Vec::with_capacity(poses.len());
    let mut blocks = Vec::with_capacity(poses.len());
    for k in 0..poses.len() {
        let jk = DMatrix::from_fn(3, kept.len(), |r, s| j[(3 * k + r, kept[s])]);
        let bk = DMatrix::from_fn(3, kept.len(), |r, s| whitened[(3 * k + r, kept[s])]);
        jacobians.push(jk);
        blocks.push(bk);
    }
    let pool = InformationPool::from_blocks(&blocks, names.clone())?;
    Ok(KinematicPool {
        poses: poses.to_vec(),
        names,
        not_identifiable,
        scales,
        jacobians,
        covariances: covariances.to_vec(),
        pool,
    })
}

/// The per-row standard deviation a calibration uses for covariance `c`: `sqrt(trace(c) / 3)`.
pub fn row_sigma_m(c: &Matrix3<f64>) -> f64 {
    (c.trace() / 3.0).max(0.0).sqrt()
}

/// Predicted deviations and accuracy of a pose set.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Prediction {
    /// Parameter names.
    pub names: Vec<String>,
    /// Standard deviation of each parameter (SI) for the calibration as it runs (one sigma
    /// per row: the sandwich covariance).
    pub std_si: Vec<f64>,
    /// Standard deviation with the device's full covariance (`F^-1`), the design's bound.
    pub std_optimal_si: Vec<f64>,
    /// Predicted RMS position error of the calibrated model at the validation poses (model
    /// error only), millimetres.
    pub heldout_rms_mm: f64,
    /// The same with the optimal weighting.
    pub heldout_rms_optimal_mm: f64,
    /// RMS of the measurement noise at the validation poses (`sqrt(trace C)`), millimetres.
    pub noise_rms_mm: f64,
    /// Validation poses used.
    pub n_validation: usize,
}

/// The inverse of a symmetric positive definite information (or noise covariance) matrix: the
/// least-squares layer's predicted covariance ([`ferrocal_lsq::linear::predicted_covariance`]).
fn symmetric_inverse(m: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    ferrocal_lsq::linear::predicted_covariance(&((m + m.transpose()) * 0.5))
        .ok_or_else(|| CalibError::TooFew("the pose set does not determine every parameter".into()))
}

/// Predicts the calibration from the poses `chosen` (pool indices) over the columns `columns`
/// (indices into the pool's names), validated on the poses `validation`.
pub fn predict_columns(
    kp: &KinematicPool,
    chosen: &[usize],
    validation: &[usize],
    columns: &[usize],
) -> Result<Prediction> {
    kp.pool.check_indices(chosen)?;
    kp.pool.check_indices(validation)?;
    let p = columns.len();
    let sub = |k: usize| DMatrix::from_fn(3, p, |r, s| kp.jacobians[k][(r, columns[s])]);
    let mut h = DMatrix::zeros(p, p);
    let mut meat = DMatrix::zeros(p, p);
    let mut fisher = DMatrix::zeros(p, p);
    for &k in chosen {
        let jk = sub(k);
        let c = DMatrix::from_fn(3, 3, |r, s| kp.covariances[k][(r, s)]);
        let w = 1.0 / row_sigma_m(&kp.covariances[k]).powi(2);
        h += jk.transpose() * &jk * w;
        meat += jk.transpose() * &c * &jk * (w * w);
        let ci = symmetric_inverse(&c)?;
        fisher += jk.transpose() * ci * &jk;
    }
    let hi = symmetric_inverse(&h)?;
    let cov = &hi * meat * &hi;
    let cov_opt = symmetric_inverse(&fisher)?;
    let std =
        |m: &DMatrix<f64>| -> Vec<f64> { (0..p).map(|i| m[(i, i)].max(0.0).sqrt() * kp.scales[columns[i]]).collect() };
    let heldout = |m: &DMatrix<f64>| -> f64 {
        if validation.is_empty() {
            return 0.0;
        }
        let s: f64 = validation
            .iter()
            .map(|&v| {
                let jv = sub(v);
                (&jv * m * jv.transpose()).trace()
            })
            .sum();
        (s / validation.len() as f64).max(0.0).sqrt() * 1e3
    };
    let noise = if validation.is_empty() {
        0.0
    } else {
        (validation.iter().map(|&v| kp.covariances[v].trace()).sum::<f64>() / validation.len() as f64).sqrt() * 1e3
    };
    Ok(Prediction {
        names: columns.iter().map(|&c| kp.names[c].clone()).collect(),
        std_si: std(&cov),
        std_optimal_si: std(&cov_opt),
        heldout_rms_mm: heldout(&cov),
        heldout_rms_optimal_mm: heldout(&cov_opt),
        noise_rms_mm: noise,
        n_validation: validation.len(),
    })
}

/// [`predict_columns`] over every column of the pool.
pub fn predict(kp: &KinematicPool, chosen: &[usize], validation: &[usize]) -> Result<Prediction> {
    let all: Vec<usize> = (0..kp.names.len()).collect();
    predict_columns(kp, chosen, validation, &all)
}

/// The source's check on a pose set: the singular values of the position Jacobian in SI units
/// (metres per metre, per radian, per unit; not whitened) and `sigma_max^2 / sigma_min`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct DresslerCheck {
    /// Largest singular value.
    pub sigma_max: f64,
    /// Smallest singular value.
    pub sigma_min: f64,
    /// `sigma_max^2 / sigma_min`.
    pub ratio: f64,
    /// `sigma_max / sigma_min`.
    pub condition: f64,
    /// The threshold `C`.
    pub limit: f64,
    /// `ratio < limit`.
    pub passed: bool,
}

/// [`DresslerCheck`] of the poses `chosen` with threshold `limit`.
pub fn dressler_check(kp: &KinematicPool, chosen: &[usize], limit: f64) -> Result<DresslerCheck> {
    kp.pool.check_indices(chosen)?;
    let p = kp.names.len();
    let mut f = DMatrix::zeros(p, p);
    for &k in chosen {
        let j = DMatrix::from_fn(3, p, |r, s| kp.jacobians[k][(r, s)] / kp.scales[s]);
        f += j.transpose() * j;
    }
    let s = crate::design::criteria::Spectrum::of(&f)
        .ok_or_else(|| CalibError::Numeric("non-finite Jacobian in the Dressler check".into()))?;
    let (hi, lo) = (s.max().sqrt(), s.min().sqrt());
    let ratio = if lo > 0.0 { hi * hi / lo } else { f64::INFINITY };
    Ok(DresslerCheck {
        sigma_max: hi,
        sigma_min: lo,
        ratio,
        condition: if lo > 0.0 { hi / lo } else { f64::INFINITY },
        limit,
        passed: ratio < limit,
    })
}

/// One simulated measurement campaign.
#[derive(Clone, Debug)]
pub struct SimulatedCell {
    /// Measured rows at the training poses (device frame, with their `sigma_m`).
    pub rows: Vec<PoseMeasurement>,
    /// True values by candidate name (SI); names not listed are taken as 0 (the increments of
    /// the frame, tool and joint offsets when the device's placement is exact).
    pub truth: BTreeMap<String, f64>,
    /// True positions (device frame) of the measured point at the validation poses.
    pub validation_true_m: Vec<Vector3<f64>>,
}

/// Draws true robots and measurements for [`monte_carlo`].
pub trait CalibrationSimulator {
    /// Run `run`: a new true robot, noisy measurements at `train` (covariance per pose, device
    /// frame), and the true positions at `validation`.
    fn simulate(
        &mut self,
        run: usize,
        train: &[Vec<f64>],
        covariances: &[Matrix3<f64>],
        validation: &[Vec<f64>],
    ) -> Result<SimulatedCell>;
}

/// Predicted against simulated deviation of one parameter.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ParameterComparison {
    /// Name.
    pub name: String,
    /// Predicted standard deviation (SI).
    pub predicted_std_si: f64,
    /// Standard deviation of the simulated errors (SI).
    pub simulated_std_si: f64,
    /// Mean simulated error (SI).
    pub mean_error_si: f64,
    /// `simulated / predicted`.
    pub ratio: f64,
}

/// The result of [`monte_carlo`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct MonteCarloReport {
    /// Runs attempted.
    pub runs: usize,
    /// Runs whose calibration was used.
    pub used: usize,
    /// Runs that failed or identified a different parameter set, with reasons (first five).
    pub skipped: Vec<String>,
    /// Per parameter.
    pub parameters: Vec<ParameterComparison>,
    /// Predicted held-out RMS model error, mm.
    pub predicted_heldout_rms_mm: f64,
    /// Simulated held-out RMS model error (RMS over runs), mm.
    pub simulated_heldout_rms_mm: f64,
    /// Largest `|ratio - 1|` over the parameters.
    pub worst_ratio_deviation: f64,
    /// Median ratio.
    pub median_ratio: f64,
}

/// Calibrates `runs` simulated campaigns at the poses `chosen` and compares the parameter
/// scatter and the held-out error at `validation` with the prediction.
#[allow(clippy::too_many_arguments)]
pub fn monte_carlo(
    model: &RobotModel,
    opts: &KinematicOptions,
    kp: &KinematicPool,
    chosen: &[usize],
    validation: &[usize],
    sim: &mut dyn CalibrationSimulator,
    runs: usize,
    mut progress: impl FnMut(usize),
) -> Result<MonteCarloReport> {
    if runs < 2 {
        return Err(CalibError::TooFew("a Monte Carlo check needs at least 2 runs".into()));
    }
    kp.pool.check_indices(chosen)?;
    kp.pool.check_indices(validation)?;
    let train: Vec<Vec<f64>> = chosen.iter().map(|&k| kp.poses[k].clone()).collect();
    let covs: Vec<Matrix3<f64>> = chosen.iter().map(|&k| kp.covariances[k]).collect();
    let val: Vec<Vec<f64>> = validation.iter().map(|&k| kp.poses[k].clone()).collect();
    let mut free_set: Option<Vec<String>> = None;
    let mut errors: Vec<Vec<f64>> = Vec::new();
    let mut heldout_sq = Vec::new();
    let mut skipped = Vec::new();
    for run in 0..runs {
        progress(run);
        let cell = sim.simulate(run, &train, &covs, &val)?;
        let refs: Vec<&PoseMeasurement> = cell.rows.iter().collect();
        let cal = match calibrate(model, &refs, opts) {
            Ok(c) => c,
            Err(e) => {
                if skipped.len() < 5 {
                    skipped.push(format!("run {}: {e}", run + 1));
                }
                continue;
            }
        };
        let free: Vec<String> =
            cal.params.iter().filter(|p| p.free && kp.names.contains(&p.name)).map(|p| p.name.clone()).collect();
        match &free_set {
            None => free_set = Some(free.clone()),
            Some(f) if *f != free => {
                if skipped.len() < 5 {
                    skipped.push(format!("run {}: identified a different parameter set", run + 1));
                }
                continue;
            }
            _ => {}
        }
        let e: Vec<f64> = free
            .iter()
            .map(|n| {
                let p = cal.params.iter().find(|p| &p.name == n).map_or(0.0, |p| p.value);
                p - cell.truth.get(n).copied().unwrap_or(0.0)
            })
            .collect();
        errors.push(e);
        if !val.is_empty() {
            let mut s = 0.0;
            for (q, t) in val.iter().zip(&cell.validation_true_m) {
                let pred = cal.calibrated.predict(q)?;
                s += (pred.translation.vector - t).norm_squared();
            }
            heldout_sq.push(s / val.len() as f64);
        }
    }
    let free = free_set
        .ok_or_else(|| CalibError::Diverged(format!("every simulated calibration failed: {}", skipped.join("; "))))?;
    if errors.len() < 2 {
        return Err(CalibError::TooFew(format!("only {} usable simulated calibrations", errors.len())));
    }
    let columns: Vec<usize> = free.iter().map(|n| kp.names.iter().position(|m| m == n).unwrap_or(usize::MAX)).collect();
    if columns.contains(&usize::MAX) {
        return Err(CalibError::Data("internal: a free parameter is not a pool column".into()));
    }
    let pred = predict_columns(kp, chosen, validation, &columns)?;
    let n = errors.len() as f64;
    let mut parameters = Vec::with_capacity(free.len());
    for (i, name) in free.iter().enumerate() {
        let mean = errors.iter().map(|e| e[i]).sum::<f64>() / n;
        let var = errors.iter().map(|e| (e[i] - mean).powi(2)).sum::<f64>() / (n - 1.0);
        let sd = var.sqrt();
        let ps = pred.std_si[i];
        parameters.push(ParameterComparison {
            name: name.clone(),
            predicted_std_si: ps,
            simulated_std_si: sd,
            mean_error_si: mean,
            ratio: if ps > 0.0 { sd / ps } else { f64::INFINITY },
        });
    }
    let mut ratios: Vec<f64> = parameters.iter().map(|p| p.ratio).collect();
    ratios.sort_by(|a, b| a.total_cmp(b));
    let median_ratio = ratios.get(ratios.len() / 2).copied().unwrap_or(f64::NAN);
    let worst = ratios.iter().map(|r| (r - 1.0).abs()).fold(0.0, f64::max);
    let sim_rms = if heldout_sq.is_empty() {
        0.0
    } else {
        (heldout_sq.iter().sum::<f64>() / heldout_sq.len() as f64).sqrt() * 1e3
    };
    Ok(MonteCarloReport {
        runs,
        used: errors.len(),
        skipped,
        parameters,
        predicted_heldout_rms_mm: pred.heldout_rms_mm,
        simulated_heldout_rms_mm: sim_rms,
        worst_ratio_deviation: worst,
        median_ratio,
    })
}
