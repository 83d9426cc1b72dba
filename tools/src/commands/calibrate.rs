//! `ferrocal calibrate` and `ferrocal evaluate`: kinematic calibration from a measurement table,
//! and prediction of a table with a calibrated model.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::Args;
use ferrocal_calib::file::CalibrationFile;
use ferrocal_calib::kinematic::{
    calibrate, split_rows, split_rows_by_plane, ErrorStats, KinematicCalibration, KinematicOptions, ModelParams,
};
use ferrocal_calib::lsq::Loss;
use ferrocal_calib::PoseMeasurement;
use ferrocal_robot::{Kinematics, RobotModel};
use serde_json::json;

use crate::plot::{self, Series};
use crate::report::{write_atomic, Provenance, Report, Section};

/// `ferrocal calibrate`.
#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// Robot model: a preset name (ur5, ur10, gantry-tau-l1, ...), a URDF file or a TOML model file.
    #[arg(long)]
    pub robot: String,
    /// Measurement table (CSV per shared/spec/measurements.md).
    #[arg(long)]
    pub measurements: PathBuf,
    /// Where to write the calibration (what `ferrocal evaluate` needs).
    #[arg(long)]
    pub out: PathBuf,
    /// Write the calibration report as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the calibration report as HTML (with plots) here.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Model parameters to identify: `default` (per-joint corrections of a serial arm, every
    /// parameter of a parallel robot), `all`, `none`, or comma-separated name prefixes.
    #[arg(long, default_value = "default")]
    pub params: String,
    /// Robust loss: `none`, `huber:<sigmas>` or `cauchy:<sigmas>`.
    #[arg(long, default_value = "none")]
    pub loss: String,
    /// Position standard deviation for rows without a sigma column, mm.
    #[arg(long, default_value_t = 0.02)]
    pub sigma_mm: f64,
    /// Orientation standard deviation for rows with orientations, degrees.
    #[arg(long, default_value_t = 0.005)]
    pub sigma_deg: f64,
    /// Ignore measured orientations (fit positions only).
    #[arg(long)]
    pub positions_only: bool,
    /// Without a `split` column: skip the validation fit on every second pose.
    #[arg(long)]
    pub no_validation: bool,
    /// Drop parameters whose parameter-to-noise ratio is below this (practical identifiability).
    #[arg(long)]
    pub practical_threshold: Option<f64>,
    /// The cost: `fk` (measured minus predicted pose; any robot) or `closure` (parallel robots:
    /// leg-length errors at the measured pose; converges from poor start models).
    #[arg(long, default_value = "fk")]
    pub cost: String,
}

/// `ferrocal evaluate`.
#[derive(Debug, Args)]
pub struct EvaluateArgs {
    /// Robot model (the one the calibration was made for).
    #[arg(long)]
    pub robot: String,
    /// Calibration file written by `ferrocal calibrate`.
    #[arg(long)]
    pub calibration: PathBuf,
    /// Measurement table to predict.
    #[arg(long)]
    pub measurements: PathBuf,
    /// Write `{"n", "mean_mm", "rms_mm", "max_mm", ...}` here.
    #[arg(long)]
    pub json: PathBuf,
}

/// Loads a model and a measurement table and checks that they agree.
pub fn load_model_and_rows(robot: &str, measurements: &Path) -> Result<(RobotModel, Vec<PoseMeasurement>)> {
    let model = RobotModel::load(robot).with_context(|| format!("cannot load robot model '{robot}'"))?;
    let table = ferrocal_datasets::import::read_measurements(measurements)?;
    let n = model.dof();
    if table.joint_units.len() != n {
        bail!(
            "{}: the table has {} joint columns but the robot model '{}' has {n} joints",
            measurements.display(),
            table.joint_units.len(),
            model.name()
        );
    }
    table.check_joint_kinds(&model.joint_kinds()).with_context(|| {
        format!("{}: joint units do not match the joint kinds of '{}'", measurements.display(), model.name())
    })?;
    Ok((model, table.set.rows))
}

fn parse_loss(s: &str) -> Result<Loss> {
    let (kind, val) = s.split_once(':').unwrap_or((s, ""));
    let delta = || -> Result<f64> {
        let d: f64 = val.parse().with_context(|| format!("--loss {s}: '{val}' is not a number"))?;
        if !(d.is_finite() && d > 0.0) {
            bail!("--loss {s}: the scale must be positive");
        }
        Ok(d)
    };
    Ok(match kind {
        "none" | "squared" => Loss::Squared,
        "huber" => Loss::Huber { delta: delta()? },
        "cauchy" => Loss::Cauchy { delta: delta()? },
        _ => bail!("--loss {s}: use none, huber:<sigmas> or cauchy:<sigmas>"),
    })
}

fn parse_params(s: &str) -> ModelParams {
    match s {
        "default" => ModelParams::Default,
        "all" => ModelParams::All,
        "none" => ModelParams::None,
        list => ModelParams::Prefixes { prefixes: list.split(',').map(|p| p.trim().to_string()).collect() },
    }
}

/// The options from the arguments.
pub fn options(args: &CalibrateArgs) -> Result<KinematicOptions> {
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if !positive(args.sigma_mm) || !positive(args.sigma_deg) {
        bail!("--sigma-mm and --sigma-deg must be positive");
    }
    Ok(KinematicOptions {
        model_params: parse_params(&args.params),
        use_orientation: !args.positions_only,
        sigma_position_m: args.sigma_mm * 1e-3,
        sigma_orientation_rad: args.sigma_deg.to_radians(),
        loss: parse_loss(&args.loss)?,
        practical_threshold: args.practical_threshold,
        cost: match args.cost.as_str() {
            "fk" => ferrocal_calib::kinematic::Cost::ForwardKinematics,
            "closure" => ferrocal_calib::kinematic::Cost::Closure,
            other => bail!("--cost {other}: use fk or closure"),
        },
        ..KinematicOptions::default()
    })
}

pub fn run_calibrate(args: &CalibrateArgs) -> Result<ExitCode> {
    let opts = options(args)?;
    let (model, rows) = load_model_and_rows(&args.robot, &args.measurements)?;
    let fixed_split = rows.iter().any(|r| r.split.is_some());
    let (train, test) = split_rows(&rows, !args.no_validation);
    let progress = crate::progress::bar(2, "calibrating");
    // Validation: fit on the training rows, evaluate on the held-out rows.
    let validation = if test.is_empty() {
        None
    } else {
        let cal = calibrate(&model, &train, &opts).context("calibration on the training rows")?;
        let before = nominal_stats(&model, &train, &test)?;
        let after = cal.calibrated.evaluate(&test)?;
        Some((cal, before, after))
    };
    progress.inc(1);
    // The delivered calibration: all rows, unless the table fixes the split.
    let final_rows: Vec<&PoseMeasurement> = if fixed_split { train.clone() } else { rows.iter().collect() };
    let cal = match (&validation, fixed_split) {
        (Some((c, _, _)), true) => c.clone(),
        _ => calibrate(&model, &final_rows, &opts).context("calibration")?,
    };
    progress.finish_and_clear();
    let file = CalibrationFile::new(&args.robot, &cal.calibrated);
    write_atomic(&args.out, serde_json::to_string_pretty(&file)?.as_bytes())?;
    let mut summary = report_json(&cal, &validation, final_rows.len(), fixed_split);
    // A spatially separated check beside the default one (new key; the others are unchanged).
    if validation.is_some() && !fixed_split {
        if let Some((tr, te, plane)) = split_rows_by_plane(&rows) {
            let c = calibrate(&model, &tr, &opts).context("calibration on the spatial training rows")?;
            let (before, after) = (nominal_stats(&model, &tr, &te)?, c.calibrated.evaluate(&te)?);
            summary["heldout_spatial"] = json!({"split": "rows beyond the median plane normal to the positions' first principal axis held out", "plane": plane, "n_train": tr.len(), "before": before, "after": after});
        }
    }
    if let Some(j) = &args.json {
        write_atomic(j, serde_json::to_string_pretty(&summary)?.as_bytes())?;
    }
    if let Some(h) = &args.report {
        let mut prov = Provenance::new(json!({"robot": args.robot, "options": opts}));
        prov.add_input(&args.measurements);
        let mut rep = Report::new(&format!("Calibration of {}", model.name()), prov);
        rep.sections.extend(calibration_sections(&cal, &validation, &final_rows));
        let html = rep.to_html();
        write_atomic(h, html.as_bytes())?;
    }
    eprintln!(
        "calibrated {} on {} poses: RMS {:.4} mm -> {:.4} mm (mean {:.4} mm){}",
        model.name(),
        final_rows.len(),
        cal.train_before.rms_mm,
        cal.train_after.rms_mm,
        cal.train_after.mean_mm,
        validation
            .as_ref()
            .map(|(_, b, a)| format!("; held out ({} poses): mean {:.4} -> {:.4} mm", a.n, b.mean_mm, a.mean_mm))
            .unwrap_or_default()
    );
    Ok(ExitCode::SUCCESS)
}

/// Errors of the nominal model on `test` with frames registered on `train`.
fn nominal_stats(model: &RobotModel, train: &[&PoseMeasurement], test: &[&PoseMeasurement]) -> Result<ErrorStats> {
    let opts =
        KinematicOptions { model_params: ModelParams::None, joint_offsets: false, ..KinematicOptions::default() };
    let cal = calibrate(model, train, &opts).context("registering the nominal model")?;
    Ok(cal.calibrated.evaluate(test)?)
}

pub fn report_json(
    cal: &KinematicCalibration,
    validation: &Option<(KinematicCalibration, ErrorStats, ErrorStats)>,
    n_final: usize,
    fixed_split: bool,
) -> serde_json::Value {
    json!({
        "n_poses": n_final,
        "split": if fixed_split { "from the table" } else if validation.is_some() { "validation on every second pose, final fit on all" } else { "none" },
        "train_before": cal.train_before,
        "train_after": cal.train_after,
        "heldout": validation.as_ref().map(|(v, b, a)| json!({"n_train": v.train_after.n, "before": b, "after": a})),
        "s0": cal.s0,
        "used_orientation": cal.used_orientation,
        "parameters": cal.params,
        "identifiability": {
            "rank": cal.identifiability_before.rank,
            "candidates": cal.layout.len(),
            "condition_number": cal.identifiability_after.condition_number,
            "dressler_ratio": cal.identifiability_after.dressler_ratio,
            "singular_values": cal.identifiability_after.singular_values,
            "classes": cal.identifiability_before.names.iter().zip(&cal.identifiability_before.classes).map(|(n, c)| json!({"name": n, "class": c})).collect::<Vec<_>>(),
            "coupled_groups": cal.identifiability_before.describe_groups(),
        },
        "practical_dropped": cal.practical_dropped,
        "advice": cal.advice,
        "solver": cal.summary,
        "device_frame": ferrocal_calib::file::FrameJson::from_isometry(&cal.calibrated.device_frame),
        "tool": ferrocal_calib::file::FrameJson::from_isometry(&cal.calibrated.tool),
    })
}

/// Report sections of a calibration (also used by the demo).
pub fn calibration_sections(
    cal: &KinematicCalibration,
    validation: &Option<(KinematicCalibration, ErrorStats, ErrorStats)>,
    rows: &[&PoseMeasurement],
) -> Vec<Section> {
    let mut out = Vec::new();
    let mut s = Section::new("calibration-summary", "Calibration: before and after");
    let row = |name: &str, e: &ErrorStats| {
        vec![
            name.to_string(),
            e.n.to_string(),
            format!("{:.4}", e.mean_mm),
            format!("{:.4}", e.rms_mm),
            format!("{:.4}", e.max_mm),
            format!("{:.4} / {:.4} / {:.4}", e.rms_axis_mm[0], e.rms_axis_mm[1], e.rms_axis_mm[2]),
            e.mean_deg.map(|v| format!("{v:.4}")).unwrap_or_default(),
        ]
    };
    let mut rows_t =
        vec![row("training, nominal model", &cal.train_before), row("training, calibrated", &cal.train_after)];
    if let Some((_, b, a)) = validation {
        rows_t.push(row("held out, nominal model", b));
        rows_t.push(row("held out, calibrated", a));
    }
    s.table(
        "Position errors [mm]",
        &["set", "poses", "mean", "RMS", "max", "RMS x / y / z", "mean orientation [deg]"],
        rows_t,
    );
    s.text(format!(
        "Solver: {} after {} iterations; a-posteriori factor s0 = {:.3} (1 when the stated noise is right). {} of {} candidate parameters identified; {} fixed as not identifiable.",
        cal.summary.termination,
        cal.summary.iterations,
        cal.s0,
        cal.free.len(),
        cal.layout.len(),
        cal.layout.len() - cal.free.len()
    ));
    for a in &cal.advice {
        s.text(format!("Advice: {a}"));
    }
    if let Ok((pos, _)) = cal.calibrated.errors(rows) {
        let norms: Vec<f64> = pos.iter().map(|e| e.norm() * 1e3).collect();
        s.figure(
            "Position errors after calibration (training poses)",
            plot::histogram("Residual position errors", "error [mm]", &norms, 40),
        );
        let pts: Vec<(f64, f64)> = norms.iter().enumerate().map(|(k, v)| (k as f64, *v)).collect();
        s.figure(
            "Residual error per pose in measuring order (structure here points at effects the model leaves out: run `ferrocal diagnose`)",
            plot::xy_plot("Residual per pose", "pose (measuring order)", "error [mm]", &[Series { name: "error", points: &pts, line: false }]),
        );
    }
    out.push(s);
    let mut p = Section::new("calibration-parameters", "Identified parameters");
    p.table(
        "Parameters (lengths in mm, angles in mrad for readability; nu = parameter-to-noise ratio)",
        &["parameter", "start", "value", "std", "nu", "status"],
        cal.params
            .iter()
            .map(|q| {
                let f = match q.unit {
                    ferrocal_robot::Unit::Metre | ferrocal_robot::Unit::Radian => 1e3,
                    _ => 1.0,
                };
                vec![
                    q.name.clone(),
                    format!("{:.4}", q.start * f),
                    format!("{:.4}", q.value * f),
                    q.std.map(|v| format!("{:.4}", v * f)).unwrap_or_default(),
                    q.nu.map(|v| format!("{v:.1}")).unwrap_or_default(),
                    q.fixed_because.clone().unwrap_or_else(|| "identified".into()),
                ]
            })
            .collect(),
    );
    for g in cal.identifiability_before.describe_groups() {
        p.text(format!("Coupled: {g}"));
    }
    // Correlation picture of the free parameters.
    let n = cal.free.len();
    if n > 1 && n <= 80 {
        let c = &cal.covariance;
        let corr: Vec<Vec<f64>> =
            (0..n).map(|i| (0..n).map(|j| c[(i, j)] / (c[(i, i)] * c[(j, j)]).sqrt()).collect()).collect();
        let labels: Vec<String> = cal.free.iter().map(|&i| cal.layout.names[i].clone()).collect();
        p.figure(
            "Correlation of the identified parameters (blue -1, white 0, red +1)",
            plot::matrix_map("Parameter correlation", &labels, &corr, -1.0, 1.0),
        );
    }
    let sv: Vec<(f64, f64)> = cal
        .identifiability_after
        .singular_values
        .iter()
        .enumerate()
        .map(|(k, v)| (k as f64 + 1.0, v.max(1e-300).log10()))
        .collect();
    p.figure(
        "Singular values of the scaled Jacobian (log10); those below the tolerance are the parameter combinations the data cannot see",
        plot::xy_plot("Singular values", "index", "log10(singular value)", &[Series { name: "sigma", points: &sv, line: false }]),
    );
    p.data = json!({"condition_number": cal.identifiability_after.condition_number});
    out.push(p);
    out
}

pub fn run_evaluate(args: &EvaluateArgs) -> Result<ExitCode> {
    let (model, rows) = load_model_and_rows(&args.robot, &args.measurements)?;
    let file = CalibrationFile::read(&args.calibration)?;
    let cm = file.apply(&model).with_context(|| format!("applying {}", args.calibration.display()))?;
    let refs: Vec<&PoseMeasurement> = rows.iter().collect();
    let (pos, ori) = cm.errors(&refs)?;
    let stats = ErrorStats::from_errors(&pos, &ori);
    let per_pose: Vec<serde_json::Value> = rows
        .iter()
        .zip(&pos)
        .map(|(r, e)| json!({"pose_id": r.pose_id, "error_mm": e.norm() * 1e3, "dx_mm": e.x * 1e3, "dy_mm": e.y * 1e3, "dz_mm": e.z * 1e3}))
        .collect();
    let out = json!({
        "n": stats.n, "mean_mm": stats.mean_mm, "rms_mm": stats.rms_mm, "max_mm": stats.max_mm,
        "rms_axis_mm": stats.rms_axis_mm, "mean_deg": stats.mean_deg, "max_deg": stats.max_deg,
        "per_pose": per_pose,
    });
    write_atomic(&args.json, serde_json::to_string_pretty(&out)?.as_bytes())?;
    eprintln!(
        "{} poses: mean {:.4} mm, RMS {:.4} mm, max {:.4} mm",
        stats.n, stats.mean_mm, stats.rms_mm, stats.max_mm
    );
    Ok(ExitCode::SUCCESS)
}
