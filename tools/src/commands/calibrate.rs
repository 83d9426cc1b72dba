//! `ferrocal calibrate` and `ferrocal evaluate`: kinematic calibration from a measurement table,
//! and prediction of a table with a calibrated model.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::Args;
use ferrocal_calib::file::CalibrationFile;
use ferrocal_calib::kinematic::KinematicOptions;
use ferrocal_calib::PoseMeasurement;
use ferrocal_robot::RobotModel;
use serde_json::json;

use ferrocal_datasets::calibration::{calibrate_table, CalibrationRun};
use ferrocal_report::calibrate::{calibration_sections, evaluate_json, report_json, spatial_json};
use ferrocal_report::verdict::{add_verdict, VerdictSettings};
use ferrocal_report::{check_outputs, write_all_atomic, write_atomic, Provenance, Report};

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
    pub json: PathBuf,
    /// First refit only the device frame and the measured point on the tool on this table, so
    /// that a model calibrated in one device's frame (a camera) is scored against another's (a
    /// tracker); the robot's parameters, joint offsets and effects stay as calibrated.
    #[arg(long)]
    pub refit_frame: bool,
    /// Position standard deviation of rows without a sigma column, mm (weights of
    /// `--refit-frame`).
    #[arg(long, default_value_t = 0.02)]
    pub sigma_mm: f64,
}

pub use ferrocal_datasets::calibration::{check_distinct_poses, check_params};

/// Loads a model and a measurement table and checks that they agree; the table's warnings go
/// to stderr.
pub fn load_model_and_rows(robot: &str, measurements: &Path) -> Result<(RobotModel, Vec<PoseMeasurement>)> {
    let (model, rows, warnings) = ferrocal_datasets::calibration::load_model_and_rows(robot, measurements)?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    Ok((model, rows))
}
use ferrocal_datasets::calibration::{parse_loss, parse_params};

/// The options from the arguments.
pub fn options(args: &CalibrateArgs) -> Result<KinematicOptions> {
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if !positive(args.sigma_mm) || !positive(args.sigma_deg) {
        bail!("--sigma-mm and --sigma-deg must be positive");
    }
    if args.max_iterations == 0 {
        bail!("--max-iterations must be at least 1");
    }
    Ok(KinematicOptions {
        model_params: parse_params(&args.params)?,
        use_orientation: !args.positions_only,
        sigma_position_m: args.sigma_mm * 1e-3,
        sigma_orientation_rad: args.sigma_deg.to_radians(),
        loss: parse_loss(&args.loss)?,
        practical_threshold: args.practical_threshold,
        effects: match &args.effects {
            Some(e) => ferrocal_calib::effect_list::effects_from_argument(e).context("--effects")?,
            None => Vec::new(),
        },
        cost: match args.cost.as_str() {
            "fk" => ferrocal_calib::kinematic::Cost::ForwardKinematics,
            "closure" => ferrocal_calib::kinematic::Cost::Closure,
            other => bail!("--cost {other}: use fk or closure"),
        },
        lm: ferrocal_calib::lsq::LmOptions { max_iterations: args.max_iterations, ..KinematicOptions::default().lm },
        // A row far beyond the others (a typo) is named and dropped, not fitted.
        outliers: Some(ferrocal_calib::kinematic::OutlierScreen::default()),
        ..KinematicOptions::default()
    })
}

pub fn run_calibrate(args: &CalibrateArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let opts = options(args)?;
    let outputs: Vec<&Path> =
        [Some(args.out.as_path()), args.json.as_deref(), args.report.as_deref()].into_iter().flatten().collect();
    check_outputs(&outputs, &[args.measurements.as_path(), Path::new(&args.robot)])?;
    let (model, rows) = load_model_and_rows(&args.robot, &args.measurements)?;
    check_params(&opts.model_params, &model)?;
    check_distinct_poses(&rows, &args.measurements)?;
    let progress = crate::progress::bar(2, "calibrating");
    let run = calibrate_table(&model, &rows, &opts, !args.no_validation, &|| progress.inc(1))?;
    progress.finish_and_clear();
    let CalibrationRun { cal, validation, final_rows, fixed_split, heldout_spatial } = &run;
    // Repeated rows of one pose add equations but no information: the fit must be redundant
    // counting distinct poses only.
    let distinct = ferrocal_datasets::import::plausible::distinct_poses(final_rows.iter().copied());
    let block = if cal.used_orientation { 6 } else { 3 };
    if distinct * block <= cal.free.len() {
        bail!(
            "{}: the {} rows hold only {distinct} independent poses ({} equations) for {} identified parameters: the pose set is rank-deficient; measure more distinct poses; nothing was written",
            args.measurements.display(),
            final_rows.len(),
            distinct * block,
            cal.free.len()
        );
    }
    let fits = std::iter::once(("calibration", cal)).chain(validation.iter().map(|(v, _, _)| ("validation fit", v)));
    for (what, fit) in fits {
        if let Some(problem) = fit.convergence_problem() {
            if !args.accept_unconverged {
                bail!("{what}: {problem}; nothing was written (raise --max-iterations, check the data, or accept it with --accept-unconverged)");
            }
            eprintln!("warning: {what}: {problem}; delivered because of --accept-unconverged");
        }
    }
    if let Some(w) = cal.noise_warning() {
        eprintln!("note: {w}");
    }
    for d in &cal.dropped_rows {
        eprintln!("warning: {}: {}", args.measurements.display(), d.describe());
    }
    if let Some(n) = &cal.outlier_note {
        eprintln!("warning: {}: {n}", args.measurements.display());
    }
    // Everything is composed first, then written together: a failing report leaves no
    // calibration file behind, and no output is half-set.
    let file = CalibrationFile::new(&args.robot, &cal.calibrated);
    let mut files: Vec<(&Path, Vec<u8>)> = vec![(&args.out, serde_json::to_string_pretty(&file)?.into_bytes())];
    let mut summary = report_json(cal, validation, final_rows.len(), *fixed_split);
    if let Some(spatial) = heldout_spatial {
        summary["heldout_spatial"] = spatial_json(spatial);
    }
    summary["dropped_rows"] = json!(cal.dropped_rows);
    summary["outlier_note"] = json!(cal.outlier_note);
    let verdict = super::verdicts::calibrate(
        &vs.thresholds,
        cal,
        validation.as_ref().map(|(v, b, a)| (v, b, a)),
        &args.robot,
        &args.out,
    );
    add_verdict(&mut summary, &verdict);
    if let Some(j) = &args.json {
        files.push((j, serde_json::to_string_pretty(&summary)?.into_bytes()));
    }
    if let Some(h) = &args.report {
        let mut prov = Provenance::new(json!({"robot": args.robot, "options": opts}));
        prov.add_input(&args.measurements);
        let mut rep = Report::new(&format!("Calibration of {}", model.name()), prov);
        rep.sections.extend(calibration_sections(cal, validation, final_rows));
        rep.verdict = Some(verdict.clone());
        files.push((h, rep.to_html().into_bytes()));
    }
    write_all_atomic(&files.iter().map(|(p, b)| (*p, b.as_slice())).collect::<Vec<_>>())?;
    println!(
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
    for line in ferrocal_report::calibrate::physical_summary(cal) {
        println!("{line}");
    }
    Ok(vs.conclude(&verdict))
}

pub fn run_evaluate(args: &EvaluateArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    check_outputs(&[&args.json], &[&args.measurements, &args.calibration, Path::new(&args.robot)])?;
    let (model, rows) = load_model_and_rows(&args.robot, &args.measurements)?;
    let file = CalibrationFile::read(&args.calibration)?;
    file.check_robot(&args.robot, &model).with_context(|| format!("{}", args.calibration.display()))?;
    let mut cm = file.apply(&model).with_context(|| format!("applying {}", args.calibration.display()))?;
    let mut refit = None;
    if args.refit_frame {
        if !(args.sigma_mm.is_finite() && args.sigma_mm > 0.0) {
            bail!("--sigma-mm must be positive");
        }
        let refs: Vec<&PoseMeasurement> = rows.iter().collect();
        let (m, record) =
            ferrocal_calib::kinematic::refit_frame(&cm, &refs, args.sigma_mm * 1e-3).context("--refit-frame")?;
        cm = m;
        refit = Some(record);
    }
    // A table with a split column is scored on its test rows only (shared/spec/cli.md); the
    // frame refit above uses the whole table, as the spec says.
    let n_test = rows.iter().filter(|r| r.split == Some(ferrocal_calib::Split::Test)).count();
    if n_test == 0 && rows.iter().any(|r| r.split.is_some()) {
        eprintln!("note: {}: the split column marks no row 'test': every row is scored", args.measurements.display());
    }
    let has_split = n_test > 0;
    let scored: Vec<PoseMeasurement> = if has_split {
        rows.into_iter().filter(|r| r.split == Some(ferrocal_calib::Split::Test)).collect()
    } else {
        rows
    };
    if scored.is_empty() {
        bail!("{}: the table has no rows to score; give a table of measured poses", args.measurements.display());
    }
    let (mut out, stats) = evaluate_json(&cm, &scored)?;
    out["rows_scored"] = json!(if has_split { "test" } else { "all" });
    if let Some(record) = &refit {
        out["refit_frame"] = serde_json::to_value(record)?;
    }
    let scored_words =
        if has_split { format!("the {} held-out (test) rows", stats.n) } else { format!("all {} rows", stats.n) };
    let verdict = super::verdicts::evaluate(&vs.thresholds, &stats, &scored_words);
    add_verdict(&mut out, &verdict);
    write_atomic(&args.json, serde_json::to_string_pretty(&out)?.as_bytes())?;
    println!(
        "scored on {scored_words}: mean {:.4} mm, RMS {:.4} mm, max {:.4} mm",
        stats.mean_mm, stats.rms_mm, stats.max_mm
    );
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
    let file = CalibrationFile::read(&args.calibration)?;
    file.check_robot(&args.robot, &model).with_context(|| format!("{}", args.calibration.display()))?;
    let cm = file.apply(&model).with_context(|| format!("applying {}", args.calibration.display()))?;
    let companion_path = args.urdf.as_ref().map(|u| u.with_extension("calibration.json"));
    // Two outputs on one path (`--urdf X --dh X`, or a DH table named like the URDF's companion)
    // or an output naming an input are refused before anything is written.
    let outs: Vec<&Path> =
        [args.urdf.as_deref(), companion_path.as_deref(), args.dh.as_deref()].into_iter().flatten().collect();
    check_outputs(&outs, &[args.calibration.as_path(), Path::new(&args.robot)])?;
    // Everything is composed first, then written.
    let mut outputs: Vec<(PathBuf, String)> = Vec::new();
    let mut roundtrip = (0.0f64, 0.0f64);
    if let Some(dh) = &args.dh {
        let ex = ferrocal_calib::export::export_mdh(&cm)?;
        roundtrip = (ex.roundtrip_m_rad.0 * 1e3, ex.roundtrip_m_rad.1.to_degrees());
        let comment = vec![
            format!("written by ferrocal {} from {} (robot {})", env!("CARGO_PKG_VERSION"), args.calibration.display(), args.robot),
            "the measuring device's frame is in 'base', the measured target in 'tool'; effects (if any) stay in the calibration file".into(),
            format!(
                "checked: the table's forward kinematics differ from the calibrated model by at most {:.2e} mm and {:.2e} deg over 200 configurations",
                ex.roundtrip_m_rad.0 * 1e3,
                ex.roundtrip_m_rad.1.to_degrees()
            ),
        ];
        outputs.push((dh.clone(), ex.table.to_csv(&comment)));
    }
    let Some(urdf) = &args.urdf else {
        write_all_atomic(&outputs.iter().map(|(p, t)| (p.as_path(), t.as_bytes())).collect::<Vec<_>>())?;
        for (p, _) in &outputs {
            println!("wrote {}", p.display());
        }
        return Ok(vs.conclude(&super::verdicts::export(&vs.thresholds, roundtrip.0, roundtrip.1)));
    };
    let companion_path = companion_path.expect("set with the URDF");
    let comment = format!(
        "written by ferrocal {} from {} (robot {}); joint origins include the calibrated corrections and zero offsets; the measured target is link 'target', the measuring device's frame is link 'device'",
        env!("CARGO_PKG_VERSION"),
        args.calibration.display(),
        args.robot
    );
    let ex = ferrocal_calib::export::export_urdf(&cm, &args.robot, &urdf.display().to_string(), &comment)?;
    roundtrip = (roundtrip.0.max(ex.roundtrip_m_rad.0 * 1e3), roundtrip.1.max(ex.roundtrip_m_rad.1.to_degrees()));
    outputs.push((urdf.clone(), ex.urdf.clone()));
    outputs.push((companion_path.clone(), serde_json::to_string_pretty(&ex.companion)?));
    write_all_atomic(&outputs.iter().map(|(p, t)| (p.as_path(), t.as_bytes())).collect::<Vec<_>>())?;
    if let Some(dh) = &args.dh {
        println!("wrote {}", dh.display());
    }
    println!(
        "wrote {} and {} (read back: {:.2e} mm, {:.2e} deg from the calibrated model{})",
        urdf.display(),
        companion_path.display(),
        ex.roundtrip_m_rad.0 * 1e3,
        ex.roundtrip_m_rad.1.to_degrees(),
        if cm.effects.is_empty() {
            String::new()
        } else {
            format!("; {} effect(s) kept in the calibration file", cm.effects.len())
        }
    );
    Ok(vs.conclude(&super::verdicts::export(&vs.thresholds, roundtrip.0, roundtrip.1)))
}
