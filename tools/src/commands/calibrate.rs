//! `ferrocal calibrate` and `ferrocal evaluate`: kinematic calibration from a measurement table,
//! and prediction of a table with a calibrated model.

use ferrocal_report::term::say_lines;
use ferrocal_report::{detail, say, tell};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::Args;
use ferrocal_calib::verdict::commands as verdict;
use ferrocal_robot::RobotModel;
use serde_json::json;

use ferrocal_datasets::calibration::{
    apply_calibration, calibrate_table, companion_path, evaluate_rows, export_calibration, CalibrateFlags,
};
use ferrocal_datasets::import::plausible::unit_advice;
use ferrocal_report::calibrate::{
    calibrate_outputs, detail_lines, evaluate_line, evaluate_run_json, export_lines, summary_lines, CalibrateFiles,
};
use ferrocal_report::verdict::{add_verdict, VerdictSettings};
use ferrocal_report::{check_outputs, write_all_atomic, write_atomic};

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
    /// Largest number of solver iterations.
    #[arg(long, default_value_t = 200)]
    pub max_iterations: usize,
    /// Deliver a calibration whose solver did not converge (with a warning) instead of exiting
    /// with an error.
    #[arg(long)]
    pub accept_unconverged: bool,
    /// Physical effects to identify with the geometry: a `diagnose --json` report (its
    /// findings), a calibration file, or a list such as
    /// `joint_compliance:2,periodic_joint_error:3:180deg,backlash:1` (docs/diagnose.md).
    #[arg(long)]
    pub effects: Option<String>,
    /// The measured link of a tree-shaped robot (a URDF with several chains), for the rows
    /// without a `tip` column value.
    #[arg(long)]
    pub tip: Option<String>,
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
    /// Write `{"n", "mean_mm", "rms_mm", "max_mm", "rows_scored", "verdict", ...}` here. A table
    /// with a `split` column is scored on its `test` rows only (`"rows_scored": "test"`), else
    /// (no column, or no row marked `test`) on every row (`"all"`).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// First refit only the device frame and the measured point on the tool on this table, so
    /// that a model calibrated in one device's frame (a camera) is scored against another's (a
    /// tracker); the robot's parameters, joint offsets and effects stay as calibrated.
    #[arg(long)]
    pub refit_frame: bool,
    /// Position standard deviation of rows without a sigma column, mm (weights of
    /// `--refit-frame`).
    #[arg(long, default_value_t = 0.02)]
    pub sigma_mm: f64,
    /// The measured link of a tree-shaped robot (a URDF with several chains), for the rows
    /// without a `tip` column value.
    #[arg(long)]
    pub tip: Option<String>,
}

pub use ferrocal_datasets::calibration::{check_distinct_poses, check_params, load_model_and_rows};

/// A table's warning, on stderr.
pub fn warn(w: &str) {
    eprintln!("warning: {w}");
}

/// [`load_model_and_rows`] with the table's warnings on stderr, and the advice of its unit
/// doubts for the verdict (`plausible::unit_advice`).
pub fn load_with_unit_doubts(
    robot: &str,
    measurements: &Path,
    tip: Option<&str>,
) -> Result<(RobotModel, Vec<ferrocal_calib::PoseMeasurement>, Vec<String>)> {
    let seen = std::cell::RefCell::new(Vec::new());
    let (model, rows) = load_model_and_rows(robot, measurements, tip, &|w| {
        warn(w);
        seen.borrow_mut().push(w.to_string());
    })?;
    let doubts = seen.into_inner().iter().filter_map(|w| unit_advice(w).map(str::to_string)).collect();
    Ok((model, rows, doubts))
}

/// An error of a command whose table raised unit doubts (`doubts`, their advice): the doubt
/// first, since it most likely caused the error (a table in metres under `_mm` leaves the fit
/// rank-deficient), then the error. Unchanged without doubts.
pub fn blame_units(e: anyhow::Error, doubts: &[String]) -> anyhow::Error {
    if doubts.is_empty() {
        return e;
    }
    e.context(format!(
        "the table's units look wrong ({}); fix them first, since they most likely caused",
        doubts.join("; ")
    ))
}

/// `v` with the unit doubts `doubts` first ([`ferrocal_calib::verdict::with_unit_doubts`]).
pub fn with_doubts(v: ferrocal_calib::verdict::Verdict, doubts: &[String]) -> ferrocal_calib::verdict::Verdict {
    ferrocal_calib::verdict::with_unit_doubts(v, &doubts.iter().map(String::as_str).collect::<Vec<_>>())
}

pub fn run_calibrate(args: &CalibrateArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let opts = CalibrateFlags {
        params: &args.params,
        loss: &args.loss,
        sigma_mm: args.sigma_mm,
        sigma_deg: args.sigma_deg,
        positions_only: args.positions_only,
        practical_threshold: args.practical_threshold,
        effects: args.effects.as_deref(),
        cost: &args.cost,
        max_iterations: args.max_iterations,
    }
    .options()?;
    let files = CalibrateFiles { out: &args.out, json: args.json.as_deref(), report: args.report.as_deref() };
    let outputs: Vec<&Path> = [Some(files.out), files.json, files.report].into_iter().flatten().collect();
    check_outputs(&outputs, &[args.measurements.as_path(), Path::new(&args.robot)])?;
    let (model, rows, doubts) = load_with_unit_doubts(&args.robot, &args.measurements, args.tip.as_deref())?;
    check_params(&opts.model_params, &model)?;
    check_distinct_poses(&rows, &args.measurements)?;
    let progress = crate::progress::bar(2, "calibrating");
    let run = calibrate_table(&model, &rows, &opts, !args.no_validation, &|| progress.inc(1))
        .map_err(|e| blame_units(e.into(), &doubts))?;
    progress.finish_and_clear();
    let limits = &vs.thresholds.calibrate;
    let change_fail = (limits.model_change_mm_fail, limits.model_change_deg_fail);
    let lines = run
        .deliverable(&args.measurements, args.accept_unconverged, change_fail)
        .map_err(|e| blame_units(e.into(), &doubts))?;
    for line in lines {
        match line.starts_with("note: ") {
            true => tell!("{line}"),
            false => eprintln!("{line}"),
        }
    }
    // Everything is composed first, then written together: a failing report leaves no
    // calibration file behind, and no output is half-set.
    let validation = run.validation.as_ref().map(|(v, b, a)| (v, b, a));
    let verdict =
        with_doubts(verdict::calibrate(&vs.thresholds, &run.cal, validation, &args.robot, &args.out), &doubts);
    let settings = json!({"robot": args.robot, "options": opts});
    let outputs = calibrate_outputs(&run, &args.robot, model.name(), &args.measurements, settings, &verdict, &files)?;
    say_lines(&summary_lines(&run, model.name()));
    detail_lines(&run.cal).iter().for_each(|l| detail!("{l}"));
    outputs.write()?;
    Ok(vs.conclude(&verdict))
}

pub fn run_evaluate(args: &EvaluateArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let outputs: Vec<&Path> = args.json.as_deref().into_iter().collect();
    check_outputs(&outputs, &[&args.measurements, &args.calibration, Path::new(&args.robot)])?;
    let (model, rows, doubts) = load_with_unit_doubts(&args.robot, &args.measurements, args.tip.as_deref())?;
    let cm = apply_calibration(&args.robot, &model, &args.calibration)?;
    // A table with a split column is scored on its test rows only (shared/spec/cli.md); the
    // frame refit uses the whole table, as the spec says.
    let run = evaluate_rows(cm, rows, args.refit_frame.then_some(args.sigma_mm))?;
    if run.no_test_marked {
        eprintln!("note: {}: the split column marks no row 'test': every row is scored", args.measurements.display());
    }
    run.check_scored(&args.measurements)?;
    let (mut out, stats) = evaluate_run_json(&run)?;
    let scored_words = run.scored_words(stats.n);
    let verdict = with_doubts(verdict::evaluate(&vs.thresholds, &stats, &scored_words), &doubts);
    add_verdict(&mut out, &verdict);
    say!("{}", evaluate_line(&scored_words, &stats));
    if let Some(json) = &args.json {
        write_atomic(json, serde_json::to_string_pretty(&out)?.as_bytes())?;
        if let Some(line) = ferrocal_report::term::wrote_line([json.as_path()]) {
            say!("{line}");
        }
    }
    Ok(vs.conclude(&verdict))
}

/// `ferrocal export`.
#[derive(Debug, Args)]
pub struct ExportArgs {
    /// Robot model the calibration was made for.
    #[arg(long)]
    pub robot: String,
    /// Calibration file (`calibrate --out` or `diagnose --out`).
    #[arg(long)]
    pub calibration: PathBuf,
    /// Write the calibrated serial robot as a URDF here (root link `device`, tip link `target`),
    /// and beside it `<name>.calibration.json`, the calibration `evaluate` takes with the URDF as
    /// the robot model (it keeps the effects a URDF cannot hold).
    #[arg(long, required_unless_present = "dh")]
    pub urdf: Option<PathBuf>,
    /// Write the calibrated serial robot as a modified DH table (CSV, Craig's convention with
    /// Hayati's angle for parallel axes; base and tool transforms in its comments).
    #[arg(long)]
    pub dh: Option<PathBuf>,
}

pub fn run_export(args: &ExportArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let model = RobotModel::load(&args.robot).with_context(|| format!("cannot load robot model '{}'", args.robot))?;
    let cm = apply_calibration(&args.robot, &model, &args.calibration)?;
    let companion = args.urdf.as_deref().map(companion_path);
    // Two outputs on one path (`--urdf X --dh X`, or a DH table named like the URDF's companion)
    // or an output naming an input are refused before anything is written.
    let outs: Vec<&Path> =
        [args.urdf.as_deref(), companion.as_deref(), args.dh.as_deref()].into_iter().flatten().collect();
    check_outputs(&outs, &[args.calibration.as_path(), Path::new(&args.robot)])?;
    // Everything is composed first, then written.
    let ex = export_calibration(&cm, &args.robot, &args.calibration, args.urdf.as_deref(), args.dh.as_deref())?;
    write_all_atomic(&ex.files.iter().map(|(p, t)| (p.as_path(), t.as_bytes())).collect::<Vec<_>>())?;
    export_lines(&ex, cm.effects.len()).iter().for_each(|l| say!("{l}"));
    let (mm, deg) = ex.roundtrip_mm_deg();
    Ok(vs.conclude(&verdict::export(&vs.thresholds, mm, deg)))
}
