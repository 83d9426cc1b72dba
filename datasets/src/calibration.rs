//! The `calibrate` workflow: the table loaded and checked against the model
//! ([`load_model_and_rows`], [`check_distinct_poses`], [`check_params`]), and its validation protocol: a validation fit on the training rows with
//! the nominal and calibrated held-out errors, the delivered fit, and a spatially separated
//! check beside the default one ([`calibrate_table`]). The report crate turns a
//! [`CalibrationRun`] into the JSON of `ferrocal calibrate` and its report sections.

use ferrocal_calib::kinematic::{
    calibrate, split_rows, split_rows_by_plane, ErrorStats, KinematicCalibration, KinematicOptions, ModelParams,
    SplitPlane,
};
use std::path::Path;

use ferrocal_calib::lsq::Loss;
use ferrocal_calib::PoseMeasurement;
use ferrocal_robot::{Kinematics, Parameterized, RobotModel};

use crate::error::{DatasetError, Result};

/// A calibration on the training rows with the nominal and calibrated held-out errors.
pub type Validation = Option<(KinematicCalibration, ErrorStats, ErrorStats)>;

/// The spatially separated check: rows beyond the median plane normal to the positions' first
/// principal axis held out.
#[derive(Clone, Debug)]
pub struct SpatialCheck {
    /// The plane; rows on its positive side are held out.
    pub plane: SplitPlane,
    /// Training rows.
    pub n_train: usize,
    /// Held-out errors of the nominal model (frames registered on the training rows).
    pub before: ErrorStats,
    /// Held-out errors of the calibration on the training rows.
    pub after: ErrorStats,
}

/// A calibration as `ferrocal calibrate` delivers it: the fit on all rows (or on the training
/// rows when the table fixes the split) with the validation fit on the training rows.
pub struct CalibrationRun<'a> {
    /// The delivered calibration.
    pub cal: KinematicCalibration,
    /// The validation fit with the nominal and calibrated held-out errors, when rows are held out.
    pub validation: Validation,
    /// The rows of the delivered fit.
    pub final_rows: Vec<&'a PoseMeasurement>,
    /// True when the table's `split` column fixed the split.
    pub fixed_split: bool,
    /// The spatially separated check; with every-second-pose validation only.
    pub heldout_spatial: Option<SpatialCheck>,
}

fn fit(
    model: &RobotModel,
    rows: &[&PoseMeasurement],
    opts: &KinematicOptions,
    what: &str,
) -> Result<KinematicCalibration> {
    calibrate(model, rows, opts).map_err(|e| DatasetError::from(e).context(what))
}

/// Calibrates `model` from `rows`: a validation fit on the training rows (every second pose, or
/// the table's split; none when `validate` is false and the table has no split), then the
/// delivered fit on all rows unless the table fixes the split. `step` is called after each fit.
pub fn calibrate_table<'a>(
    model: &RobotModel,
    rows: &'a [PoseMeasurement],
    opts: &KinematicOptions,
    validate: bool,
    step: &dyn Fn(),
) -> Result<CalibrationRun<'a>> {
    let fixed_split = rows.iter().any(|r| r.split.is_some());
    let (mut train, mut test) = split_rows(rows, validate);
    // With the residual test (`opts.outliers`), the rows the fit on all rows drops are left out of
    // every fit and every held-out score; the other rows keep their place in the split.
    let mut screened = None;
    if opts.outliers.is_some() && !fixed_split {
        let all: Vec<&PoseMeasurement> = rows.iter().collect();
        let c = fit(model, &all, opts, "calibration")?;
        if !c.dropped_rows.is_empty() {
            let gone = |r: &&PoseMeasurement| c.dropped_rows.iter().any(|d| d.pose_id == r.pose_id);
            train.retain(|r| !gone(r));
            test.retain(|r| !gone(r));
        }
        screened = Some(c);
    }
    let dropped: Vec<String> =
        screened.as_ref().map(|c| c.dropped_rows.iter().map(|d| d.pose_id.clone()).collect()).unwrap_or_default();
    let kept = |r: &&PoseMeasurement| !dropped.contains(&r.pose_id);
    // Validation: fit on the training rows, evaluate on the held-out rows.
    let validation = if test.is_empty() {
        None
    } else {
        let cal = fit(model, &train, opts, "calibration on the training rows")?;
        let before = nominal_stats(model, &train, &test)?;
        let after = cal.calibrated.evaluate(&test)?;
        Some((cal, before, after))
    };
    step();
    // The delivered calibration: all rows, unless the table fixes the split.
    let final_rows: Vec<&PoseMeasurement> =
        if fixed_split { train.clone() } else { rows.iter().filter(kept).collect() };
    let cal = match (&validation, fixed_split, screened) {
        (Some((c, _, _)), true, _) => c.clone(),
        (_, _, Some(c)) => c,
        _ => fit(model, &final_rows, opts, "calibration")?,
    };
    // A spatially separated check beside the default one: training poses are not neighbours of
    // the held-out ones.
    let mut heldout_spatial = None;
    if validation.is_some() && !fixed_split {
        if let Some((mut tr, mut te, plane)) = split_rows_by_plane(rows) {
            tr.retain(kept);
            te.retain(kept);
            let c = fit(model, &tr, opts, "calibration on the spatial training rows")?;
            let (before, after) = (nominal_stats(model, &tr, &te)?, c.calibrated.evaluate(&te)?);
            heldout_spatial = Some(SpatialCheck { plane, n_train: tr.len(), before, after });
        }
    }
    step();
    Ok(CalibrationRun { cal, validation, final_rows, fixed_split, heldout_spatial })
}

/// Errors of the nominal model on `test` with frames registered on `train`.
pub fn nominal_stats(model: &RobotModel, train: &[&PoseMeasurement], test: &[&PoseMeasurement]) -> Result<ErrorStats> {
    let opts =
        KinematicOptions { model_params: ModelParams::None, joint_offsets: false, ..KinematicOptions::default() };
    let cal = fit(model, train, &opts, "registering the nominal model")?;
    Ok(cal.calibrated.evaluate(test)?)
}

/// Loads a model and a measurement table and checks that they agree; with the table's warnings.
pub fn load_model_and_rows(
    robot: &str,
    measurements: &Path,
) -> Result<(RobotModel, Vec<PoseMeasurement>, Vec<String>)> {
    let model = RobotModel::load(robot)
        .map_err(|e| DatasetError::from(e).context(format!("cannot load robot model '{robot}'")))?;
    let table = crate::import::read_measurements(measurements)?;
    let n = model.dof();
    if table.joint_units.len() != n {
        return Err(DatasetError::Input(format!(
            "{}: the table has {} joint columns but the robot model '{}' has {n} joints",
            measurements.display(),
            table.joint_units.len(),
            model.name()
        )));
    }
    table.check_joint_kinds(&model.joint_kinds()).map_err(|e| {
        e.context(format!("{}: joint units do not match the joint kinds of '{}'", measurements.display(), model.name()))
    })?;
    table.check_joint_values(&model.joint_limits(), model.name())?;
    Ok((model, table.set.rows, table.warnings))
}

/// Fewest distinct joint configurations a calibration or diagnosis accepts (a rigid registration
/// of the device frame alone needs three).
pub const MIN_DISTINCT_POSES: usize = 3;

/// Refuses a pose set with fewer than [`MIN_DISTINCT_POSES`] distinct joint configurations
/// (a table of one pose repeated 200 times calibrates nothing).
pub fn check_distinct_poses(rows: &[PoseMeasurement], measurements: &Path) -> Result<usize> {
    let distinct = crate::import::plausible::distinct_poses(rows);
    if distinct < MIN_DISTINCT_POSES {
        return Err(DatasetError::Input(format!(
            "{}: the {} rows hold {distinct} independent pose(s) (rows with the same joint readings are one pose); a calibration needs many distinct poses: measure more poses",
            measurements.display(),
            rows.len()
        )));
    }
    Ok(distinct)
}

/// The robust loss of `--loss`: `none` (or `squared`), `huber:<sigmas>` or `cauchy:<sigmas>`.
pub fn parse_loss(s: &str) -> Result<Loss> {
    let (kind, val) = s.split_once(':').unwrap_or((s, ""));
    let delta = || -> Result<f64> {
        let d: f64 =
            val.parse().map_err(|e| DatasetError::Input(format!("--loss {s}: '{val}' is not a number: {e}")))?;
        if !(d.is_finite() && d > 0.0) {
            return Err(DatasetError::Input(format!("--loss {s}: the scale must be positive")));
        }
        Ok(d)
    };
    Ok(match kind {
        "none" | "squared" => Loss::Squared,
        "huber" => Loss::Huber { delta: delta()? },
        "cauchy" => Loss::Cauchy { delta: delta()? },
        _ => return Err(DatasetError::Input(format!("--loss {s}: use none, huber:<sigmas> or cauchy:<sigmas>"))),
    })
}

/// The parameters of `--params`: `default`, `all`, `none` or comma-separated name prefixes.
pub fn parse_params(s: &str) -> Result<ModelParams> {
    Ok(match s {
        "default" => ModelParams::Default,
        "all" => ModelParams::All,
        "none" => ModelParams::None,
        list => {
            let prefixes: Vec<String> =
                list.split(',').map(|p| p.trim().to_string()).filter(|p| !p.is_empty()).collect();
            if prefixes.is_empty() {
                return Err(DatasetError::Input(format!(
                    "--params '{list}' names no parameter: use default, all, none or comma-separated name prefixes"
                )));
            }
            ModelParams::Prefixes { prefixes }
        }
    })
}

/// Refuses `--params` prefixes that match none of the model's parameters (a misspelt list
/// would otherwise calibrate the frames alone and report success).
pub fn check_params(params: &ModelParams, model: &RobotModel) -> Result<()> {
    if let ModelParams::Prefixes { prefixes } = params {
        let names: Vec<String> = model.parameters().into_iter().map(|p| p.name).collect();
        let unmatched: Vec<&String> =
            prefixes.iter().filter(|x| !names.iter().any(|n| n.starts_with(x.as_str()))).collect();
        if !unmatched.is_empty() {
            let examples: Vec<&str> = names.iter().take(4).map(String::as_str).collect();
            return Err(DatasetError::Input(format!(
                "--params: {} match(es) no parameter of '{}' (its names look like {}, ...; `ferrocal robot info --robot {}` lists them)",
                unmatched.iter().map(|u| format!("'{u}'")).collect::<Vec<_>>().join(", "),
                model.name(),
                examples.join(", "),
                model.name()
            )));
        }
    }
    Ok(())
}
