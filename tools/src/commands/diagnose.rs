//! `ferrocal diagnose`: the missing-physics analysis of a measurement table (JSON per
//! `shared/spec/diagnose.md`, optional HTML report with the evidence).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::Args;
use ferrocal_calib::diagnose::{diagnose, DiagnoseOptions};
use ferrocal_report::diagnose::{camera_section, force_section, sections};
use serde_json::json;

use ferrocal_report::verdict::{add_verdict, VerdictSettings};
use ferrocal_report::{Provenance, Report};

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
    let mut rep_json = serde_json::to_value(&rep)?;
    let rerun = format!(
        "ferrocal calibrate --robot {robot} --measurements {} --effects {} --out <calibration.json>",
        meas.display(),
        args.json.display()
    );
    let verdict = super::verdicts::diagnose(&vs.thresholds, &rep_json, "mm", &rerun);
    add_verdict(&mut rep_json, &verdict);
    let mut files: Vec<(&Path, Vec<u8>)> = vec![(&args.json, serde_json::to_string_pretty(&rep_json)?.into_bytes())];
    if let (Some(path), Some(cal)) = (&args.out, &compensated) {
        let file = ferrocal_calib::file::CalibrationFile::new(robot, &cal.calibrated);
        files.push((path, serde_json::to_string_pretty(&file)?.into_bytes()));
    }
    if let Some(h) = &args.report {
        let mut prov = Provenance::new(json!({"robot": robot, "options": opts}));
        prov.add_input(meas);
        let mut r = Report::new(&format!("Missing physics: {} on {}", model.name(), meas.display()), prov);
        r.sections = sections(&rep, args.attribution.as_deref());
        r.verdict = Some(verdict.clone());
        files.push((h, r.to_html().into_bytes()));
    }
    ferrocal_report::write_all_atomic(&files.iter().map(|(p, b)| (*p, b.as_slice())).collect::<Vec<_>>())?;
    if let (Some(path), Some(cal)) = (&args.out, &compensated) {
        println!(
            "wrote {} ({} effect(s) with the geometry; training RMS {:.4} mm)",
            path.display(),
            cal.calibrated.effects.len(),
            cal.train_after.rms_mm
        );
    }
    if let Some(d) = &rep.declined {
        println!("diagnose: {d}");
    }
    println!(
        "diagnosed {} on {} poses in {:.1} s: held-out RMS {:.4} mm (geometric model) -> {:.4} mm; {} finding(s){}",
        model.name(),
        rep.n_poses,
        rep.elapsed_s,
        rep.nominal.heldout_rms_mm,
        rep.final_fit.heldout_rms_mm,
        rep.findings.len(),
        if rep.unexplained.structure_found {
            format!("; unexplained structure against {}", rep.unexplained.depends_on.join(", "))
        } else {
            String::new()
        }
    );
    println!("  {}", rep.summary);
    for f in &rep.findings {
        println!("  {}: {}", f.effect, f.statement);
    }
    Ok(vs.conclude(&verdict))
}

/// The camera variant: detect the pattern in every image, calibrate with the default lens model
/// and a flat target, test what the images show beyond it.
fn run_camera(args: &DiagnoseArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    use ferrocal_calib::diagnose::camera::{diagnose_camera, CameraDiagnoseOptions};
    use ferrocal_vision::calib::{PlanarTarget, View};
    use ferrocal_vision::camera::ImageSize;
    use ferrocal_vision::detect::{load_gray, DetectOptions, Detector, Pattern};
    let Some(pattern_text) = &args.pattern else {
        bail!("diagnose --images needs --pattern (e.g. chessboard:9x6:25mm)");
    };
    if args.images.is_empty() {
        bail!("diagnose --pattern needs --images");
    }
    let pattern: Pattern = pattern_text.parse()?;
    let mut detector = Detector::new(pattern, DetectOptions::default(), None)?;
    let mut files = Vec::new();
    for spec in &args.images {
        let folder = ferrocal_datasets::import::list_images(spec, &Default::default())?;
        for s in &folder.skipped {
            eprintln!("ferrocal: skipped {}: {}", s.path.display(), s.reason);
        }
        files.extend(folder.images.into_iter().map(|e| e.path));
    }
    // Target points by their position on the target (1 um grid), views by image.
    let mut points: Vec<nalgebra::Point3<f64>> = Vec::new();
    let mut key_of = std::collections::HashMap::new();
    let mut views = Vec::new();
    let pb = crate::progress::bar(files.len() as u64, "detecting");
    for f in &files {
        pb.inc(1);
        let found = load_gray(f).and_then(|img| {
            let size = ImageSize { width_px: img.width(), height_px: img.height() };
            detector.detect(&img).map(|d| (d, size))
        });
        let (dets, size) = match found {
            Ok(x) => x,
            Err(e) => {
                eprintln!("ferrocal: {}: {e}", f.display());
                continue;
            }
        };
        let mut ids = Vec::new();
        let mut px = Vec::new();
        for c in dets.iter().filter(|d| d.anchored).flat_map(|d| &d.corners) {
            let Some(t) = c.target_m else { continue };
            let key = ((t.x * 1e6).round() as i64, (t.y * 1e6).round() as i64, (t.z * 1e6).round() as i64);
            let id = *key_of.entry(key).or_insert_with(|| {
                points.push(t);
                points.len() - 1
            });
            ids.push(id);
            px.push(c.position_px);
        }
        if px.len() < 4 {
            eprintln!(
                "ferrocal: {}: the pattern was not found whole (or has no size in the pattern string)",
                f.display()
            );
            continue;
        }
        let mut v = View::new(f.display().to_string(), size, px);
        v.point_ids = ids;
        views.push(v);
    }
    pb.finish_and_clear();
    if let Some(first) = views.first() {
        let size = first.image_size;
        if let Some(bad) = views.iter().find(|v| v.image_size != size) {
            bail!(
                "{} is {}x{} px but {} is {}x{}: one camera, one image size",
                bad.name,
                bad.image_size.width_px,
                bad.image_size.height_px,
                first.name,
                size.width_px,
                size.height_px
            );
        }
    }
    let target = PlanarTarget { points_m: points, reversible: false };
    let opts = CameraDiagnoseOptions { folds: args.folds, alpha: args.alpha, ..CameraDiagnoseOptions::default() };
    let rep = diagnose_camera(&views, &target, &opts).context("camera diagnosis")?;
    let mut rep_json = serde_json::to_value(&rep)?;
    let verdict = super::verdicts::diagnose(
        &vs.thresholds,
        &rep_json,
        "px",
        "calibrate with the lens model or target shape the findings name (ferrocal camera calibrate --model ...)",
    );
    add_verdict(&mut rep_json, &verdict);
    // Both files together: no report without its JSON.
    let mut files: Vec<(&Path, Vec<u8>)> = vec![(&args.json, serde_json::to_string_pretty(&rep_json)?.into_bytes())];
    if let Some(h) = &args.report {
        let prov = Provenance::new(json!({"images": args.images, "pattern": pattern_text, "options": opts}));
        let mut r =
            Report::new(&format!("Missing physics of a camera ({} views of {pattern_text})", views.len()), prov);
        r.sections.push(camera_section(&rep, opts.folds, args.attribution.as_deref()));
        r.verdict = Some(verdict.clone());
        files.push((h, r.to_html().into_bytes()));
    }
    ferrocal_report::write_all_atomic(&files.iter().map(|(p, b)| (*p, b.as_slice())).collect::<Vec<_>>())?;
    if let Some(d) = &rep.declined {
        println!("diagnose: {d}");
    }
    println!(
        "diagnosed a camera from {} views: held-out reprojection RMS {:.4} px -> {:.4} px; {} finding(s)",
        rep.n_views,
        rep.nominal.heldout_rms_px,
        rep.final_fit.heldout_rms_px,
        rep.findings.len()
    );
    for f in &rep.findings {
        println!("  {}: {}", f.effect, f.statement);
    }
    if rep.unexplained.structure_found {
        println!("  unexplained structure, depending on {}:", rep.unexplained.depends_on.join(" and "));
        for e in &rep.unexplained.evidence {
            println!("    {e}");
        }
    }
    Ok(vs.conclude(&verdict))
}

/// The force-sensor variant: identify the rigid body and offsets, test the deformation terms on
/// held-out poses.
fn run_forces(args: &DiagnoseArgs, path: &std::path::Path, vs: &VerdictSettings) -> Result<ExitCode> {
    use ferrocal_calib::diagnose::force::{diagnose_force_sensor, ForceDiagnoseOptions};
    let (poses, forces) = super::dynamics::read_static_table(path)?;
    let reg = super::dynamics::rig_sensor_regressor()?;
    let opts = ForceDiagnoseOptions { folds: args.folds, alpha: args.alpha, ..ForceDiagnoseOptions::default() };
    let rep = diagnose_force_sensor(&reg, &poses, &forces, &opts)
        .with_context(|| format!("force-sensor diagnosis of {}", path.display()))?;
    let mut rep_json = serde_json::to_value(&rep)?;
    let verdict = super::verdicts::diagnose(
        &vs.thresholds,
        &rep_json,
        "n",
        "identify the sensor with the terms the findings name (docs/dynamics.md)",
    );
    add_verdict(&mut rep_json, &verdict);
    // Both files together: no report without its JSON.
    let mut files: Vec<(&Path, Vec<u8>)> = vec![(&args.json, serde_json::to_string_pretty(&rep_json)?.into_bytes())];
    if let Some(h) = &args.report {
        let prov = Provenance::new(json!({"forces": path.display().to_string(), "options": opts}));
        let mut r =
            Report::new(&format!("Missing physics of a force-sensing end-effector ({} poses)", poses.len()), prov);
        r.sections.push(force_section(&rep, opts.folds, args.attribution.as_deref()));
        r.verdict = Some(verdict.clone());
        files.push((h, r.to_html().into_bytes()));
    }
    ferrocal_report::write_all_atomic(&files.iter().map(|(p, b)| (*p, b.as_slice())).collect::<Vec<_>>())?;
    if let Some(d) = &rep.declined {
        println!("diagnose: {d}");
    }
    println!(
        "diagnosed a force-sensing end-effector from {} poses: held-out force RMS {:.3} N -> {:.3} N; {} finding(s); mass {:.2} -> {:.2} kg",
        poses.len(),
        rep.nominal.heldout_rms_n,
        rep.final_fit.heldout_rms_n,
        rep.findings.len(),
        rep.mass_kg[0],
        rep.mass_kg[1]
    );
    for f in &rep.findings {
        println!("  {}: {}", f.effect, f.statement);
    }
    Ok(vs.conclude(&verdict))
}
