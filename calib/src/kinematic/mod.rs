//! Kinematic calibration: a robot model's parameters together with the measuring device's frame,
//! the target-to-tool offset and joint offsets, from measured poses.
//!
//! # Model
//! `T_device_target(q) = F * FK(p, q + dq) * T_tool`, with
//! - `F = Exp(f) F0`: the device-to-base frame, a 6-vector increment `f` on a registration `F0`;
//! - `FK(p, .)`: the robot model's forward kinematics with parameter vector `p` (a selection of
//!   it is free; `base.*` and `tool.*` of a serial chain are always fixed, being the same
//!   freedoms as `F` and `T_tool`);
//! - `dq`: joint offsets (zero readings);
//! - `T_tool = T0_tool Exp(t)`: the target on the tool (translation only when orientation is not
//!   measured: it is then not identifiable).
//!
//! Residuals are positions (and orientations when measured and wanted), each divided by its
//! standard deviation, so different units are never mixed unweighted.
//!
//! # State layout
//! The candidate vector is `[f (6) | t (3 or 6) | dq (n) | selected model parameters]`;
//! [`StateLayout`] names every entry. The identifiability analysis keeps a subset; the others
//! stay at their start values (zero increments, zero offsets, nominal model values).

use std::ops::Range;

use ferrocal_robot::{JointKind, Kinematics, Parameterized, RobotModel, Unit};
use nalgebra::{DMatrix, Isometry3, Point3};
use serde::{Deserialize, Serialize};

use crate::effects::EffectSpec;
use crate::error::{CalibError, Result};
use crate::frames::{fit_rigid, log6};
use crate::identifiability::Identifiability;
use crate::lsq::{covariance, solve, LmOptions, LmSummary, Loss};
use crate::measurement::PoseMeasurement;

pub mod correct;
mod design;
mod layout;
mod model;
mod outliers;
mod point_start;
mod problem;
mod refit;
pub(crate) mod select;
mod split;
#[cfg(test)]
mod tests;

pub use design::design_jacobian;
pub use layout::StateLayout;
use model::row_error;
pub use model::{model_for_row, CalibratedModel, ErrorStats};
pub use outliers::{DroppedRow, OutlierScreen};
use problem::{whitening_matrices, KinProblem};
pub use refit::{refit_frame, FrameRefit};
use select::{analyze_subset, frames_first};
pub use select::{describe_trade_offs, TradeOff, TradePartner};
pub use split::{split_rows, split_rows_by_plane, split_rows_in_blocks, SplitPlane};

/// Which of the model's own parameters are free.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ModelParams {
    /// The default for the model kind: a serial chain's per-joint correction transforms and the
    /// couplings of its mimic joints (`mimic<k>.coupling`), every parameter of a parallel robot.
    Default,
    /// All parameters but a serial chain's `base.*` and `tool.*`.
    All,
    /// None: only frames, tool and joint offsets.
    None,
    /// Parameters whose names start with one of these prefixes.
    Prefixes {
        /// Name prefixes, e.g. `arm1.` or `joint2.corr_`.
        prefixes: Vec<String>,
    },
}

/// The cost whose squares are summed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Cost {
    /// Measured minus predicted pose through the forward kinematics (any model).
    #[default]
    ForwardKinematics,
    /// Parallel robots: the closure equations of every leg at the measured pose, as leg-length
    /// errors `||A(q) - B(T)|| - L` (metres). Always real-valued, even far from the nominal
    /// model where the forward kinematics has no solution; the arms of a Gantry-Tau decouple
    /// (the Jacobian is block-diagonal per arm when the frames are fixed). Needs measured
    /// orientations unless the platform keeps a constant orientation.
    Closure,
}

/// Options of [`calibrate`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct KinematicOptions {
    /// The model parameters to identify.
    pub model_params: ModelParams,
    /// Whether to identify the device frame (else it stays at the start value: identity, or
    /// `fixed_device_frame`).
    pub estimate_device_frame: bool,
    /// A known device-to-base frame (translation mm-free SI, as a pose); `None` registers one.
    #[serde(skip)]
    pub fixed_device_frame: Option<Isometry3<f64>>,
    /// Whether to identify joint offsets.
    pub joint_offsets: bool,
    /// Whether to identify the target-to-tool offset.
    pub estimate_tool: bool,
    /// Use measured orientations when every row has one.
    pub use_orientation: bool,
    /// Position standard deviation for rows without `sigma`.
    pub sigma_position_m: f64,
    /// Orientation standard deviation for rows without one.
    pub sigma_orientation_rad: f64,
    /// Whiten the residual of a row that carries a full covariance
    /// ([`PoseMeasurement::covariance`]) with it (a Cholesky factor of the block the residual
    /// uses); `false` treats such rows like the others (their `sigma_m` / `sigma_rad`, else the
    /// standard deviations above). Rows without a covariance are weighted the same either way.
    #[serde(default = "default_use_covariance")]
    pub use_covariance: bool,
    /// Robust loss on each pose's whitened residual.
    pub loss: Loss,
    /// Relative singular-value tolerance of the structural identifiability.
    pub rank_tolerance: f64,
    /// Drop identifiable parameters whose parameter-to-noise ratio (deviation from the start
    /// value over its standard deviation) stays below this, and refit (practical
    /// identifiability); `None` keeps them.
    pub practical_threshold: Option<f64>,
    /// Physical effects identified together with the geometry.
    pub effects: Vec<EffectSpec>,
    /// The cost.
    pub cost: Cost,
    /// Solver options.
    pub lm: LmOptions,
    /// The residual test that names and drops rows far beyond the others ([`OutlierScreen`]);
    /// `None` (the default of the library, whose studies and diagnosis keep every row) fits all
    /// rows. `ferrocal calibrate` turns it on.
    #[serde(default)]
    pub outliers: Option<OutlierScreen>,
}

fn default_use_covariance() -> bool {
    true
}

impl Default for KinematicOptions {
    fn default() -> Self {
        Self {
            model_params: ModelParams::Default,
            estimate_device_frame: true,
            fixed_device_frame: None,
            joint_offsets: true,
            estimate_tool: true,
            use_orientation: true,
            sigma_position_m: 20e-6,
            sigma_orientation_rad: 1e-4,
            use_covariance: true,
            loss: Loss::Squared,
            rank_tolerance: 1e-8,
            practical_threshold: None,
            effects: Vec::new(),
            cost: Cost::ForwardKinematics,
            lm: LmOptions { max_iterations: 200, ..LmOptions::default() },
            outliers: None,
        }
    }
}

/// One parameter of a calibration result.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ParamResult {
    /// Name (see [`StateLayout`]).
    pub name: String,
    /// Unit.
    pub unit: Unit,
    /// Start value (nominal; zero for increments and offsets).
    pub start: f64,
    /// Identified value.
    pub value: f64,
    /// Standard deviation, when free.
    pub std: Option<f64>,
    /// Whether it was identified (else fixed at its start value).
    pub free: bool,
    /// Why it was fixed, when it was.
    pub fixed_because: Option<String>,
    /// Parameter-to-noise ratio `|value - start| / std`.
    pub nu: Option<f64>,
}

/// The result of [`calibrate`].
#[derive(Clone, Debug)]
pub struct KinematicCalibration {
    /// The calibrated model.
    pub calibrated: CalibratedModel,
    /// The candidate layout.
    pub layout: StateLayout,
    /// Per candidate parameter.
    pub params: Vec<ParamResult>,
    /// Covariance of the free parameters (in the order of [`KinematicCalibration::free`]).
    pub covariance: DMatrix<f64>,
    /// Indices (into the candidates) of the free parameters.
    pub free: Vec<usize>,
    /// A-posteriori standard deviation of unit weight (1 when the noise model is right).
    pub s0: f64,
    /// Identifiability where the selection is judged (a serial chain: after the frames-first
    /// fit, `select::frames_first`; else at the start values) over the candidates the options
    /// leave free (its `names` say which).
    pub identifiability_before: Identifiability,
    /// Identifiability at the solution (all candidates).
    pub identifiability_after: Identifiability,
    /// Parameters dropped by the practical-identifiability reduction, with the training RMS
    /// change it caused (mm).
    pub practical_dropped: Vec<(String, f64)>,
    /// Solver summary.
    pub summary: LmSummary,
    /// Errors on the training rows before calibration (nominal model, registered frames).
    pub train_before: ErrorStats,
    /// Errors on the training rows after calibration.
    pub train_after: ErrorStats,
    /// Whether orientations were used.
    pub used_orientation: bool,
    /// Advice for parameters the data cannot identify.
    pub advice: Vec<String>,
    /// Rows the residual test dropped ([`KinematicOptions::outliers`]); the fit above is without
    /// them.
    pub dropped_rows: Vec<DroppedRow>,
    /// Why the residual test dropped nothing although rows were beyond its threshold.
    pub outlier_note: Option<String>,
    /// The residual test's statistic at its last round: the largest normalised residual of the
    /// rows kept over their robust scale (compared with the threshold); `None` without the test.
    pub largest_residual_ratio: Option<f64>,
    /// The position standard deviation of rows that carry none (the options'), m.
    pub sigma_position_m: f64,
}

/// The largest change a calibration makes to the robot model in one unit
/// ([`KinematicCalibration::largest_model_changes`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelChange {
    /// The parameter (`joint2.corr_a_m`, `offset.q3_rad`).
    pub name: String,
    /// Its identified value minus its start (nominal) value, in millimetres for a length and
    /// degrees for an angle.
    pub change: f64,
}

impl KinematicCalibration {
    /// The largest changes the calibration makes to the robot model itself: its lengths (mm)
    /// and its angles (degrees), over the identified joint zero offsets and model parameters
    /// (not the device frame, the tool or the effects, whose size is the cell's, not the
    /// robot's). A robot differs from its model by tenths of a millimetre and hundredths of a
    /// degree; a change of centimetres says the table is of another robot (`--robot`) or in
    /// another unit.
    pub fn largest_model_changes(&self) -> (Option<ModelChange>, Option<ModelChange>) {
        let mut mm: Option<ModelChange> = None;
        let mut deg: Option<ModelChange> = None;
        for i in self.layout.offsets.clone().chain(self.layout.model.clone()) {
            let Some(p) = self.params.get(i).filter(|p| p.free) else { continue };
            let (slot, change) = match p.unit {
                Unit::Metre => (&mut mm, (p.value - p.start) * 1e3),
                Unit::Radian => (&mut deg, (p.value - p.start).to_degrees()),
                _ => continue,
            };
            if change.is_finite() && slot.as_ref().is_none_or(|m| change.abs() > m.change.abs()) {
                *slot = Some(ModelChange { name: p.name.clone(), change });
            }
        }
        (mm, deg)
    }

    /// Why this calibration should not be delivered as converged, if it should not: the solver
    /// stopped at its iteration limit or without a convergence test passing.
    pub fn convergence_problem(&self) -> Option<String> {
        (!self.summary.converged).then(|| {
            format!(
                "the solver did not converge ({} after {} iterations; cost {:.4e} -> {:.4e})",
                self.summary.termination, self.summary.iterations, self.summary.initial_cost, self.summary.final_cost
            )
        })
    }

    /// A note when the a-posteriori standard deviation of unit weight `s0` is far from 1
    /// (outside 1/3 to 3): the standard deviations the rows were weighted with do not describe
    /// their scatter, so the reported parameter standard deviations (scaled by `s0`) rest on
    /// the residuals alone. Not an error: the fit itself is unaffected by a common scale of the
    /// weights. Above 3 the residuals are larger than the stated noise: most often the model
    /// leaves errors of that size out (a laser tracker's stated 0.02 mm is right; the 0.5 mm
    /// left over the UR10 series B is the arm's, not the tracker's), so the note points to
    /// `diagnose` first and to the sigma second; below 1/3 the stated sigma is too large.
    pub fn noise_warning(&self) -> Option<String> {
        let s0 = self.s0;
        if !s0.is_finite() || (1.0 / 3.0..=3.0).contains(&s0) {
            return None;
        }
        let rms = self.train_after.rms_mm;
        Some(if s0 > 3.0 {
            format!(
                "the residuals (training RMS {rms:.3} mm) are {s0:.1} times the stated measurement noise (s0 = {s0:.2}): the model leaves errors of this size unexplained (ferrocal diagnose looks for what), unless the device is noisier than its stated sigma; standard deviations are scaled by s0"
            )
        } else {
            format!(
                "the residuals (training RMS {rms:.3} mm) are {s0:.2} times the stated measurement noise (s0 = {s0:.2}): the stated sigma (the rows' sigma, or --sigma-mm / --sigma-deg) is larger than the device's noise; standard deviations are scaled by s0"
            )
        })
    }
}

/// Calibrates `model` from `rows` (the training rows).
pub fn calibrate(
    model: &RobotModel,
    rows: &[&PoseMeasurement],
    opts: &KinematicOptions,
) -> Result<KinematicCalibration> {
    if let Some(screen) = &opts.outliers {
        return outliers::screened(model, rows, opts, screen);
    }
    let n_j = model.dof();
    if rows.is_empty() {
        return Err(CalibError::TooFew("no measured poses to calibrate from".into()));
    }
    for r in rows {
        if r.q.len() != n_j {
            return Err(row_error(
                r,
                format!("{} joint values, but the robot model '{}' has {n_j} joints", r.q.len(), model.name()),
            ));
        }
        if r.q.iter().any(|v| !v.is_finite()) || !r.position_m.iter().all(|v| v.is_finite()) {
            return Err(row_error(r, "non-finite value"));
        }
    }
    let use_ori = opts.use_orientation && rows.iter().all(|r| r.orientation.is_some());
    if opts.cost == Cost::Closure {
        let Some(p) = model.parallel() else {
            return Err(CalibError::Data(format!(
                "the closure cost needs a parallel robot; '{}' is serial",
                model.name()
            )));
        };
        if p.mobility() != ferrocal_robot::Mobility::Translation3 && !use_ori {
            return Err(CalibError::Data(format!(
                "the closure cost of '{}' needs measured orientations (its platform orientation varies)",
                model.name()
            )));
        }
    }
    let tool_dim = if use_ori { 6 } else { 3 };
    for e in &opts.effects {
        e.validate(model)?;
        if let Some(r) = rows.iter().find(|r| e.missing_input(r).is_some()) {
            return Err(row_error(
                r,
                format!("effect {} needs {}, which this row lacks", e.name(), e.missing_input(r).unwrap_or("inputs")),
            ));
        }
    }
    let layout = StateLayout::for_rows(model, tool_dim, opts, rows)?;
    let mut problem = start_problem(model, rows, opts, &layout, use_ori)?;
    let start = problem.start.clone();
    let all = problem.free.clone();
    let train_before = problem.calibrated(&start)?.evaluate(rows)?;

    // Frames, tool and zero offsets first; structural identifiability there, on the scaled
    // Jacobian.
    let at = frames_first(&mut problem, &layout, opts)?;
    let scaled = |jac: &DMatrix<f64>| scale_columns(jac, &layout);
    let (mut fixed_reason, allowed, id_before) = structural_selection(&problem, &layout, &at, opts)?;
    let mut free: Vec<usize> = all.iter().copied().filter(|i| fixed_reason[*i].is_none()).collect();
    if rows.len() * problem.block() <= free.len() {
        return Err(CalibError::TooFew(format!(
            "{} poses give {} equations for {} identifiable parameters: measure more poses",
            rows.len(),
            rows.len() * problem.block(),
            free.len()
        )));
    }
    problem.free = free.clone();
    let lm = LmOptions { loss: opts.loss, ..opts.lm.clone() };
    let x0: Vec<f64> = free.iter().map(|&i| at[i]).collect();
    let mut res = solve(&problem, &x0, &lm)?;
    let mut full = problem.full(&res.x);

    // Practical identifiability: drop parameters the data do not resolve, refit.
    let mut practical_dropped = Vec::new();
    if let Some(th) = opts.practical_threshold {
        let (cov, _) = covariance(&res.jacobian, &res.residuals)?;
        let rms_before = problem.calibrated(&full)?.evaluate(rows)?.rms_mm;
        let weak: Vec<usize> = free
            .iter()
            .enumerate()
            .filter(|(k, &i)| {
                layout.model.contains(&i) && {
                    let sd = cov[(*k, *k)].sqrt();
                    (full[i] - start[i]).abs() / sd < th
                }
            })
            .map(|(_, &i)| i)
            .collect();
        if !weak.is_empty() {
            for &i in &weak {
                fixed_reason[i] = Some(format!("parameter-to-noise ratio below {th}: the data do not resolve it"));
            }
            free.retain(|i| !weak.contains(i));
            problem.free = free.clone();
            let x0: Vec<f64> = free.iter().map(|&i| at[i]).collect();
            res = solve(&problem, &x0, &lm)?;
            full = problem.full(&res.x);
            let rms_after = problem.calibrated(&full)?.evaluate(rows)?.rms_mm;
            for &i in &weak {
                practical_dropped.push((layout.names[i].clone(), rms_after - rms_before));
            }
        }
    }
    let calibrated = problem.calibrated(&full)?;
    let train_after = calibrated.evaluate(rows)?;
    if !res.summary.converged && train_after.rms_mm > train_before.rms_mm {
        return Err(CalibError::Diverged(format!(
            "{} after {} iterations; RMS {:.3} mm before, {:.3} mm after. Check the units of the table, the robot model and the joint order",
            res.summary.termination, res.summary.iterations, train_before.rms_mm, train_after.rms_mm
        )));
    }
    let (cov, s0) = covariance(&res.jacobian, &res.residuals)?;
    let j_after = problem.full_jacobian(&full)?;
    let serial = matches!(model, RobotModel::Serial(_));
    let id_after = analyze_subset(&scaled(&j_after), &layout.names, &allowed, opts.rank_tolerance, serial)?;
    let mut out_params = Vec::with_capacity(layout.len());
    for i in 0..layout.len() {
        let k = free.iter().position(|&f| f == i);
        let std = k.map(|k| cov[(k, k)].sqrt());
        out_params.push(ParamResult {
            name: layout.names[i].clone(),
            unit: layout.units[i],
            start: start[i],
            value: full[i],
            std,
            free: k.is_some(),
            fixed_because: fixed_reason[i].clone(),
            nu: std.map(|s| (full[i] - start[i]).abs() / s),
        });
    }
    let advice = advise(model, rows, &id_before);
    Ok(KinematicCalibration {
        calibrated,
        layout: layout.clone(),
        params: out_params,
        covariance: cov,
        free,
        s0,
        identifiability_before: id_before,
        identifiability_after: id_after,
        practical_dropped,
        summary: res.summary,
        train_before,
        train_after,
        used_orientation: use_ori,
        advice,
        dropped_rows: Vec::new(),
        outlier_note: None,
        largest_residual_ratio: None,
        sigma_position_m: opts.sigma_position_m,
    })
}

/// The candidates [`calibrate`] would identify from `rows` with `opts`: its candidate layout,
/// and the indices (into the layout) of the candidates its structural identifiability analysis
/// keeps free (at the frames-first fit of a serial chain, see [`select::frames_first`], else at
/// the start), with that analysis. The same selection `calibrate` makes before
/// it solves (no practical-identifiability reduction, which needs the solution); other
/// adjustments that estimate the same robot from other observations (the joint adjustment of
/// robot and camera, [`crate::handeye::joint`]) take their robot parameters from it.
pub fn identifiable_candidates(
    model: &RobotModel,
    rows: &[&PoseMeasurement],
    opts: &KinematicOptions,
) -> Result<(StateLayout, Vec<usize>, Identifiability)> {
    if rows.is_empty() {
        return Err(CalibError::TooFew("no measured poses to select parameters from".into()));
    }
    if let Some(r) = rows.iter().find(|r| r.q.len() != model.dof()) {
        return Err(row_error(r, format!("{} joint values, the model has {}", r.q.len(), model.dof())));
    }
    let use_ori = opts.use_orientation && rows.iter().all(|r| r.orientation.is_some());
    let layout = StateLayout::for_rows(model, if use_ori { 6 } else { 3 }, opts, rows)?;
    let mut problem = start_problem(model, rows, opts, &layout, use_ori)?;
    let at = frames_first(&mut problem, &layout, opts)?;
    let (fixed_reason, _, id) = structural_selection(&problem, &layout, &at, opts)?;
    let free = (0..layout.len()).filter(|i| fixed_reason[*i].is_none()).collect();
    Ok((layout, free, id))
}

/// The kinematic problem at its start, every candidate of `layout` free: the start frames, each
/// row's standard deviations (checked positive) and whitening. [`calibrate`] and
/// [`identifiable_candidates`] both begin here, so they select from the same problem.
fn start_problem<'a>(
    model: &RobotModel,
    rows: &'a [&'a PoseMeasurement],
    opts: &KinematicOptions,
    layout: &'a StateLayout,
    use_ori: bool,
) -> Result<KinProblem<'a>> {
    let (f0, tool0) = start_frames(model, rows, opts, use_ori)?;
    let sigma_pos: Vec<f64> = rows.iter().map(|r| r.sigma_m.unwrap_or(opts.sigma_position_m)).collect();
    let sigma_ori: Vec<f64> = rows.iter().map(|r| r.sigma_rad.unwrap_or(opts.sigma_orientation_rad)).collect();
    if sigma_pos.iter().chain(&sigma_ori).any(|s| !(s.is_finite() && *s > 0.0)) {
        return Err(CalibError::Data("every standard deviation must be positive".into()));
    }
    let whiten = whitening_matrices(rows, use_ori, &sigma_ori, opts.use_covariance, opts.cost)?;
    Ok(KinProblem {
        base_model: model.clone(),
        rows,
        layout,
        f0,
        tool0,
        use_ori,
        start: layout.start_values(model),
        free: (0..layout.len()).collect(),
        sigma_pos,
        sigma_ori,
        whiten,
        effects: opts.effects.clone(),
        cost: opts.cost,
        n_legs: model.parallel().and_then(|p| p.mechanism().ok()).map_or(0, |m| m.legs.len()),
    })
}

/// The start of the device frame and the tool frame: the given device frame, else the rigid
/// registration of the nominal model's positions to the measured ones, or (with orientations)
/// the closed form of `AX = ZB`, or (positions only, serial chains) the closed form of the device
/// frame and the target point ([`point_start`]) when it fits the training positions better.
fn start_frames(
    model: &RobotModel,
    rows: &[&PoseMeasurement],
    opts: &KinematicOptions,
    use_ori: bool,
) -> Result<(Isometry3<f64>, Isometry3<f64>)> {
    // Start: register the nominal model's positions to the measurements.
    let mut nominal = Vec::with_capacity(rows.len());
    for r in rows {
        nominal.push(model_for_row(model, r)?.forward(&r.q).map_err(|e| row_error(r, e))?);
    }
    let nominal_pts: Vec<Point3<f64>> = nominal.iter().map(|t| Point3::from(t.translation.vector)).collect();
    let measured: Vec<Point3<f64>> = rows.iter().map(|r| Point3::from(r.position_m)).collect();
    Ok(match opts.fixed_device_frame {
        Some(f) => (f, Isometry3::identity()),
        None => {
            let rigid = (fit_rigid(&nominal_pts, &measured)?, Isometry3::identity());
            // With measured orientations, the device frame and the whole tool frame also follow in
            // closed form (AX = ZB): needed when the target sits far from the flange on a robot
            // whose flange origin hardly moves (a positioner). The start that fits the training
            // positions better is taken, so the positions-only start stays where it serves.
            // With positions only, a serial chain's device frame and target point follow in
            // closed form too (point_start): needed when the device is far off and the target far
            // from the flange (the rigid registration of flange origins then misses by metres).
            let closed = if use_ori {
                pose_start(&nominal, rows)
            } else if matches!(model, RobotModel::Serial(c) if !c.is_tree()) {
                point_start::device_and_point(&nominal, &measured)
            } else {
                None
            };
            match closed {
                Some(closed) if start_rms(&nominal, &measured, &closed) < start_rms(&nominal, &measured, &rigid) => {
                    closed
                }
                _ => rigid,
            }
        }
    })
}

/// `jac` with every column multiplied by its candidate's typical scale.
fn scale_columns(jac: &DMatrix<f64>, layout: &StateLayout) -> DMatrix<f64> {
    let mut s = jac.clone();
    for (c, sc) in layout.scales.iter().enumerate() {
        s.column_mut(c).scale_mut(*sc);
    }
    s
}

/// The structural identifiability at `start` (the selection point): which candidates the
/// options fix, and, over the others, the selection on the scaled Jacobian (see
/// [`analyze_subset`]). Returns the reason every fixed candidate is fixed, the candidates the
/// options leave free and the analysis.
#[allow(clippy::type_complexity)]
fn structural_selection(
    problem: &KinProblem,
    layout: &StateLayout,
    start: &[f64],
    opts: &KinematicOptions,
) -> Result<(Vec<Option<String>>, Vec<usize>, Identifiability)> {
    let all: Vec<usize> = (0..layout.len()).collect();
    let scaled = |jac: &DMatrix<f64>| scale_columns(jac, layout);
    let mut fixed_reason: Vec<Option<String>> = vec![None; layout.len()];
    if !opts.estimate_device_frame {
        for i in layout.frame.clone() {
            fixed_reason[i] = Some("device frame given".into());
        }
    }
    if !opts.estimate_tool {
        for i in layout.tool.clone() {
            fixed_reason[i] = Some("tool offset given".into());
        }
    }
    if !opts.joint_offsets {
        for i in layout.offsets.clone() {
            fixed_reason[i] = Some("joint offsets not identified (option)".into());
        }
    }
    // Structural identifiability at the selection point over the candidates the options leave free.
    let allowed: Vec<usize> = all.iter().copied().filter(|i| fixed_reason[*i].is_none()).collect();
    if allowed.is_empty() {
        return Err(CalibError::Data("nothing to identify: every parameter is fixed by the options".into()));
    }
    let j0 = problem.full_jacobian(start)?;
    let serial = matches!(problem.base_model, RobotModel::Serial(_));
    let id_before = analyze_subset(&scaled(&j0), &layout.names, &allowed, opts.rank_tolerance, serial)?;
    for &i in &id_before.fixed {
        fixed_reason[allowed[i]] =
            Some("not identifiable from these measurements (redundant with the kept parameters)".into());
    }
    Ok((fixed_reason, allowed, id_before))
}

/// The Jacobian of the predicted target positions (device frame, 3 rows per row, each divided
/// by the row's `sigma_m`) with respect to every candidate of `cal`'s layout at the calibrated
/// model: the calibration's own Jacobian (analytic for the frame, tool, joint offsets and serial
/// corrections; central differences for effect parameters and parameters without an analytic
/// form), with the increments re-based at the calibrated model (a left increment of the device
/// frame, a right increment of the tool, additive offsets, model and effect parameters), where
/// its analytic columns are exact. Positions only, scalar sigmas: what the diagnose's
/// linearisation whitens with.
pub(crate) fn prediction_jacobian(
    cal: &KinematicCalibration,
    rows: &[&PoseMeasurement],
    sigma_m: &[f64],
) -> Result<DMatrix<f64>> {
    let cm = &cal.calibrated;
    let layout = &cal.layout;
    if sigma_m.len() != rows.len() {
        return Err(CalibError::Data(format!("{} standard deviations for {} rows", sigma_m.len(), rows.len())));
    }
    let mut start = layout.start_values(&cm.model);
    start[layout.offsets.clone()].copy_from_slice(&cm.joint_offsets);
    for (r, (_, theta)) in layout.effects.iter().zip(&cm.effects) {
        start[r.clone()].copy_from_slice(theta);
    }
    let problem = KinProblem {
        base_model: cm.load_model.clone(),
        rows,
        layout,
        f0: cm.device_frame,
        tool0: cm.tool,
        use_ori: false,
        start: start.clone(),
        free: (0..layout.len()).collect(),
        sigma_pos: sigma_m.to_vec(),
        sigma_ori: vec![1.0; rows.len()],
        whiten: vec![None; rows.len()],
        effects: cm.effects.iter().map(|(e, _)| e.clone()).collect(),
        cost: Cost::ForwardKinematics,
        n_legs: 0,
    };
    // The residual is measured minus predicted: its Jacobian is minus the prediction's.
    Ok(-problem.full_jacobian(&start)?)
}

/// Plain-words advice for what the data cannot identify: joints that barely moved.
fn advise(model: &RobotModel, rows: &[&PoseMeasurement], id: &Identifiability) -> Vec<String> {
    let mut out = Vec::new();
    let kinds = model.joint_kinds();
    for (i, k) in kinds.iter().enumerate() {
        let (lo, hi) = rows.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), r| (l.min(r.q[i]), h.max(r.q[i])));
        let range = hi - lo;
        let small = match k {
            JointKind::Revolute => range < 5f64.to_radians(),
            JointKind::Prismatic => range < 0.02,
        };
        if small {
            let unit = match k {
                JointKind::Revolute => format!("{:.2} deg", range.to_degrees()),
                JointKind::Prismatic => format!("{:.1} mm", range * 1e3),
            };
            out.push(format!(
                "joint {} moved only {unit} over the measurements: its offset and the parameters after it cannot be separated; measure poses that move joint {} over a wide range",
                i + 1,
                i + 1
            ));
        }
    }
    let dead: Vec<&str> = id
        .classes
        .iter()
        .enumerate()
        .filter(|(_, c)| **c == crate::identifiability::ParamClass::NotIdentifiable)
        .map(|(i, _)| id.names[i].as_str())
        .collect();
    if !dead.is_empty() {
        out.push(format!(
            "these parameters have no effect on the measured quantities and keep their nominal values: {}",
            dead.join(", ")
        ));
    }
    out
}

/// The device frame as `(translation mm, rotation vector deg)`.
pub fn frame_mm_deg(t: &Isometry3<f64>) -> ([f64; 3], [f64; 3]) {
    let v = log6(t);
    ([v[0] * 1e3, v[1] * 1e3, v[2] * 1e3], [v[3].to_degrees(), v[4].to_degrees(), v[5].to_degrees()])
}

/// The device frame and the tool frame from measured poses by the closed form of `AX = ZB`
/// (Shah): `FK_i T_tool M_i^-1 = F^-1` for every row with measured pose `M_i`. `None` when a row
/// lacks an orientation or the closed form fails.
fn pose_start(nominal: &[Isometry3<f64>], rows: &[&PoseMeasurement]) -> Option<(Isometry3<f64>, Isometry3<f64>)> {
    let measured: Vec<Isometry3<f64>> =
        rows.iter().map(|r| Some(Isometry3::from_parts(r.position_m.into(), r.orientation?))).collect::<Option<_>>()?;
    device_and_tool(nominal, &measured).ok()
}

/// `(T_device_base, T_flange_target)` with `T_device_base FK_i T_flange_target = M_i` for flange
/// poses `FK_i` and target poses `M_i` in the device frame, by the closed form of `AX = ZB`
/// (Shah; at least 3 poses whose orientations differ about two axes).
pub(crate) fn device_and_tool(
    flange: &[Isometry3<f64>],
    measured: &[Isometry3<f64>],
) -> Result<(Isometry3<f64>, Isometry3<f64>)> {
    let pairs: Vec<crate::handeye::PosePair> = flange
        .iter()
        .zip(measured)
        .map(|(fk, m)| crate::handeye::PosePair { t_base_flange: *fk, c: m.inverse() })
        .collect();
    let (tool, base_in_device_inv) = crate::handeye::closed::solve_ax_zb(&pairs)?;
    Ok((base_in_device_inv.inverse(), tool))
}

/// RMS of the position residuals of a start `(device frame, tool frame)` over the rows, metres.
pub(crate) fn start_rms(
    nominal: &[Isometry3<f64>],
    measured: &[Point3<f64>],
    start: &(Isometry3<f64>, Isometry3<f64>),
) -> f64 {
    let sum: f64 = nominal
        .iter()
        .zip(measured)
        .map(|(fk, p)| ((start.0 * fk * start.1).translation.vector - p.coords).norm_squared())
        .sum();
    (sum / nominal.len().max(1) as f64).sqrt()
}
