//! `ferrocal diagnose`: the missing-physics analysis of a measurement table (JSON per
//! `shared/spec/diagnose.md`, optional HTML report with the evidence).

use ferrocal_report::say;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::Args;
use ferrocal_datasets::camera::target_point_views;
use ferrocal_datasets::diagnose::{diagnose_options, diagnose_rows};
use ferrocal_report::diagnose::{compensated_line, robot_outputs, summary_lines, DiagnoseFiles, VariantFiles};
use ferrocal_report::diagnose_stereo::run_stereo;

use ferrocal_report::verdict::VerdictSettings;

/// `ferrocal diagnose`.
#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    /// Robot model: a preset name (ur5, ur10, ...), a URDF file (with inertials for load
    /// torques) or a TOML model file.
    #[arg(long)]
    pub robot: Option<String>,
    /// Measurement table (CSV per shared/spec/measurements.md).
    #[arg(long)]
    pub measurements: Option<PathBuf>,
    /// Force-sensor variant: a quasi-static table of poses and averaged sensor forces (the
    /// format of `ferrocal dynamics simulate`'s static.csv, docs/dynamics.md).
    #[arg(long)]
    pub forces: Option<PathBuf>,
    /// Camera variant: image files, globs or folders; given twice for a stereo pair
    /// (`--images left/ --images right/`, paired by sorted order as in `camera stereo`).
    #[arg(long, num_args = 1..)]
    pub images: Vec<String>,
    /// `--images` grouped by occurrence (filled by [`crate::cli::Cli::try_parse_grouped`]).
    #[arg(skip)]
    pub image_groups: Vec<Vec<String>>,
    /// Camera variant: the calibration pattern.
    #[arg(long)]
    pub pattern: Option<String>,
    /// Write the report (shared/spec/diagnose.md) as JSON here.
    #[arg(long)]
    pub json: PathBuf,
    /// Write an HTML report with the evidence here.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Write the calibration refitted on all training rows with the accepted effects included
    /// (the format `evaluate` reads; `evaluate` then predicts with the effects).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Folds of the cross-validation.
    #[arg(long, default_value_t = 5)]
    pub folds: usize,
    /// Family-wise significance level per step (Bonferroni over the candidates).
    #[arg(long, default_value_t = 0.01)]
    pub alpha: f64,
    /// Fraction of the rows kept aside for the reported held-out figures when the table has no
    /// split column (0: cross-validated figures).
    #[arg(long, default_value_t = 0.25)]
    pub validation_fraction: f64,
    /// Position standard deviation of rows without a sigma column, mm (default: when no row
    /// has one, the noise is taken from the geometric fit's residuals).
    #[arg(long)]
    pub sigma_mm: Option<f64>,
    /// Data attribution printed in the HTML report (source and licence of the recording).
    #[arg(long)]
    pub attribution: Option<String>,
    /// The measured link of a tree-shaped robot (a URDF with several chains), for the rows
    /// without a `tip` column value.
    #[arg(long)]
    pub tip: Option<String>,
}

/// Runs `ferrocal diagnose`.
pub fn run(args: &DiagnoseArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    if args.out.is_some() && (!args.images.is_empty() || args.pattern.is_some() || args.forces.is_some()) {
        bail!("--out writes a robot calibration: it needs --robot and --measurements, not --images or --forces");
    }
    if !args.images.is_empty() || args.pattern.is_some() {
        return run_camera(args, vs);
    }
    if let Some(path) = &args.forces {
        return run_forces(args, path, vs);
    }
    let (Some(robot), Some(meas)) = (&args.robot, &args.measurements) else {
        bail!("diagnose needs --robot <model> and --measurements <csv> (or --images and --pattern for a camera, --forces for a force-sensing end-effector)");
    };
    let opts = diagnose_options(args.folds, args.alpha, args.validation_fraction, args.sigma_mm)?;
    let files = DiagnoseFiles {
        robot,
        measurements: meas,
        json: &args.json,
        report: args.report.as_deref(),
        out: args.out.as_deref(),
        attribution: args.attribution.as_deref(),
        unit_doubts: &[],
    };
    let outputs: Vec<&Path> = [Some(files.json), files.out, files.report].into_iter().flatten().collect();
    ferrocal_report::check_outputs(&outputs, &[meas.as_path(), Path::new(robot)])?;
    let (model, rows, doubts) = super::calibrate::load_with_unit_doubts(robot, meas, args.tip.as_deref())?;
    let files = DiagnoseFiles { unit_doubts: &doubts, ..files };
    super::calibrate::check_distinct_poses(&rows, meas)?;
    // The diagnosis reports no steps; a spinner with the elapsed time shows it is alive (on
    // 11,911 UR10 rows it runs for minutes).
    let progress = crate::progress::spinner(&format!("diagnosing {} rows", rows.len()));
    let (rep, compensated) = diagnose_rows(&model, &rows, &opts, args.out.is_some())
        .map_err(|e| super::calibrate::blame_units(e.into(), &doubts))?;
    progress.finish_and_clear();
    // Composed first, then written together (no half-set outputs).
    let train: Vec<&ferrocal_calib::PoseMeasurement> =
        rows.iter().filter(|r| r.split != Some(ferrocal_calib::Split::Test)).collect();
    let delivered = compensated.as_ref().map(|c| (c, train.as_slice()));
    let (out, verdict) = robot_outputs(&vs.thresholds, &rep, model.name(), delivered, &opts, &files)?;
    if let (Some(path), Some(cal)) = (&args.out, &compensated) {
        say!("{}", compensated_line(path, cal));
    }
    summary_lines(&rep, model.name()).iter().for_each(|l| say!("{l}"));
    out.write()?;
    Ok(vs.conclude(&verdict))
}

/// The camera variant: detect the pattern in every image, calibrate with the default lens model
/// and a flat target, test what the images show beyond it.
fn run_camera(args: &DiagnoseArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    use ferrocal_calib::diagnose::camera::{diagnose_camera, CameraDiagnoseOptions};
    let Some(pattern_text) = &args.pattern else {
        bail!("diagnose --images needs --pattern (e.g. chessboard:9x6:25mm)");
    };
    if args.images.is_empty() {
        bail!("diagnose --pattern needs --images");
    }
    let opts = CameraDiagnoseOptions { folds: args.folds, alpha: args.alpha, ..CameraDiagnoseOptions::default() };
    if args.image_groups.len() > 2 {
        bail!("diagnose takes --images once (one camera) or twice (a stereo pair: --images left/ --images right/)");
    }
    if let [left, right] = args.image_groups.as_slice() {
        return Ok(run_stereo([left, right], pattern_text, &opts, files(args), vs)?);
    }
    let bars = crate::progress::Bars::default();
    let (views, target) = target_point_views(&args.images, pattern_text, &|m| eprintln!("ferrocal: {m}"), &|k, n| {
        bars.tick("detecting", k as u64, n as u64)
    })?;
    let rep = diagnose_camera(&views, &target, &opts).context("camera diagnosis")?;
    let input = (args.images.as_slice(), pattern_text.as_str());
    Ok(ferrocal_report::diagnose::camera_outputs(&rep, views.len(), input, &opts, files(args), vs)?)
}

/// The force-sensor variant: identify the rigid body and offsets, test the deformation terms on
/// held-out poses.
fn run_forces(args: &DiagnoseArgs, path: &Path, vs: &VerdictSettings) -> Result<ExitCode> {
    use ferrocal_calib::diagnose::force::ForceDiagnoseOptions;
    let opts = ForceDiagnoseOptions { folds: args.folds, alpha: args.alpha, ..ForceDiagnoseOptions::default() };
    Ok(ferrocal_report::diagnose::run_forces(path, &opts, files(args), vs)?)
}

/// The camera, stereo and force variants' output files.
fn files(args: &DiagnoseArgs) -> VariantFiles<'_> {
    VariantFiles { json: &args.json, report: args.report.as_deref(), attribution: args.attribution.as_deref() }
}
