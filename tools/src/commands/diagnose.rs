//! `ferrocal diagnose`: the missing-physics analysis of a measurement table (JSON per
//! `shared/spec/diagnose.md`, optional HTML report with the evidence).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::Args;
use ferrocal_calib::diagnose::{diagnose, DiagnoseOptions};
use ferrocal_datasets::camera::target_point_views;
use ferrocal_datasets::dynsim::identify::diagnose_static_table;
use ferrocal_report::diagnose::{
    camera_section, camera_summary_lines, diagnose_json, force_section, force_summary_lines, sections, summary_lines,
};
use serde_json::json;

use ferrocal_report::verdict::VerdictSettings;
use ferrocal_report::{Outputs, Provenance, Report};

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
    /// Camera variant: image files, globs or folders.
    #[arg(long, num_args = 1..)]
    pub images: Vec<String>,
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
    if args.sigma_mm.is_some_and(|s| !(s.is_finite() && s > 0.0)) {
        bail!("--sigma-mm must be positive");
    }
    let opts = DiagnoseOptions {
        folds: args.folds,
        alpha: args.alpha,
        validation_fraction: args.validation_fraction,
        sigma_position_m: args.sigma_mm.map_or(DiagnoseOptions::default().sigma_position_m, |s| s * 1e-3),
        sigma_from_data: args.sigma_mm.is_none(),
        ..DiagnoseOptions::default()
    };
    let outputs: Vec<&Path> =
        [Some(args.json.as_path()), args.out.as_deref(), args.report.as_deref()].into_iter().flatten().collect();
    ferrocal_report::check_outputs(&outputs, &[meas.as_path(), Path::new(robot)])?;
    let (model, rows) = super::calibrate::load_model_and_rows(robot, meas)?;
    super::calibrate::check_distinct_poses(&rows, meas)?;
    // The diagnosis reports no steps; a spinner with the elapsed time shows it is alive (on
    // 11,911 UR10 rows it runs for minutes).
    let progress = crate::progress::spinner(&format!("diagnosing {} rows", rows.len()));
    let rep = diagnose(&model, &rows, &opts).context("diagnosis")?;
    progress.finish_and_clear();
    let compensated = match &args.out {
        Some(_) => Some(
            ferrocal_calib::diagnose::compensated_calibration(&model, &rows, &rep)
                .context("refitting the calibration with the accepted effects")?,
        ),
        None => None,
    };
    // Composed first, then written together (no half-set outputs).
    let rerun = format!(
        "ferrocal calibrate --robot {robot} --measurements {} --effects {} --out <calibration.json>",
        meas.display(),
        args.json.display()
    );
    let (rep_json, verdict) = diagnose_json(&vs.thresholds, &rep, "mm", &rerun)?;
    let mut out = Outputs::default();
    out.json(&args.json, &rep_json)?;
    if let (Some(path), Some(cal)) = (&args.out, &compensated) {
        out.json(path, &ferrocal_calib::file::CalibrationFile::new(robot, &cal.calibrated))?;
    }
    if let Some(h) = &args.report {
        let mut prov = Provenance::new(json!({"robot": robot, "options": opts}));
        prov.add_input(meas);
        let title = format!("Missing physics: {} on {}", model.name(), meas.display());
        out.html(h, Report::of(&title, prov, sections(&rep, args.attribution.as_deref())), &verdict);
    }
    out.write()?;
    if let (Some(path), Some(cal)) = (&args.out, &compensated) {
        println!(
            "wrote {} ({} effect(s) with the geometry; training RMS {:.4} mm)",
            path.display(),
            cal.calibrated.effects.len(),
            cal.train_after.rms_mm
        );
    }
    summary_lines(&rep, model.name()).iter().for_each(|l| println!("{l}"));
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
    let bars = crate::progress::Bars::default();
    let (views, target) = target_point_views(&args.images, pattern_text, &|m| eprintln!("ferrocal: {m}"), &|k, n| {
        bars.tick("detecting", k as u64, n as u64)
    })?;
    let opts = CameraDiagnoseOptions { folds: args.folds, alpha: args.alpha, ..CameraDiagnoseOptions::default() };
    let rep = diagnose_camera(&views, &target, &opts).context("camera diagnosis")?;
    let next =
        "calibrate with the lens model or target shape the findings name (ferrocal camera calibrate --model ...)";
    let (rep_json, verdict) = diagnose_json(&vs.thresholds, &rep, "px", next)?;
    // Both files together: no report without its JSON.
    let mut out = Outputs::default();
    out.json(&args.json, &rep_json)?;
    if let Some(h) = &args.report {
        let prov = Provenance::new(json!({"images": args.images, "pattern": pattern_text, "options": opts}));
        let title = format!("Missing physics of a camera ({} views of {pattern_text})", views.len());
        let section = camera_section(&rep, opts.folds, args.attribution.as_deref());
        out.html(h, Report::of(&title, prov, vec![section]), &verdict);
    }
    out.write()?;
    camera_summary_lines(&rep).iter().for_each(|l| println!("{l}"));
    Ok(vs.conclude(&verdict))
}

/// The force-sensor variant: identify the rigid body and offsets, test the deformation terms on
/// held-out poses.
fn run_forces(args: &DiagnoseArgs, path: &Path, vs: &VerdictSettings) -> Result<ExitCode> {
    use ferrocal_calib::diagnose::force::ForceDiagnoseOptions;
    let opts = ForceDiagnoseOptions { folds: args.folds, alpha: args.alpha, ..ForceDiagnoseOptions::default() };
    let (n_poses, rep) = diagnose_static_table(path, &opts)?;
    let next = "identify the sensor with the terms the findings name (docs/dynamics.md)";
    let (rep_json, verdict) = diagnose_json(&vs.thresholds, &rep, "n", next)?;
    // Both files together: no report without its JSON.
    let mut out = Outputs::default();
    out.json(&args.json, &rep_json)?;
    if let Some(h) = &args.report {
        let prov = Provenance::new(json!({"forces": path.display().to_string(), "options": opts}));
        let title = format!("Missing physics of a force-sensing end-effector ({n_poses} poses)");
        let section = force_section(&rep, opts.folds, args.attribution.as_deref());
        out.html(h, Report::of(&title, prov, vec![section]), &verdict);
    }
    out.write()?;
    force_summary_lines(&rep, n_poses).iter().for_each(|l| println!("{l}"));
    Ok(vs.conclude(&verdict))
}
