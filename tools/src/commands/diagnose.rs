//! `ferrocal diagnose`: the missing-physics analysis of a measurement table (JSON per
//! `shared/spec/diagnose.md`, optional HTML report with the evidence).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::Args;
use ferrocal_calib::diagnose::{diagnose, DiagnoseOptions, DiagnoseReport, Evidence, InputStructure};
use serde_json::json;

use crate::plot::{self, Series};
use crate::report::{write_atomic, Provenance, Report, Section};

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
    /// Position standard deviation of rows without a sigma column, mm.
    #[arg(long, default_value_t = 0.02)]
    pub sigma_mm: f64,
    /// Data attribution printed in the HTML report (source and licence of the recording).
    #[arg(long)]
    pub attribution: Option<String>,
}

/// Runs `ferrocal diagnose`.
pub fn run(args: &DiagnoseArgs) -> Result<ExitCode> {
    if args.out.is_some() && (!args.images.is_empty() || args.pattern.is_some() || args.forces.is_some()) {
        bail!("--out writes a robot calibration: it needs --robot and --measurements, not --images or --forces");
    }
    if !args.images.is_empty() || args.pattern.is_some() {
        return run_camera(args);
    }
    if let Some(path) = &args.forces {
        return run_forces(args, path);
    }
    let (Some(robot), Some(meas)) = (&args.robot, &args.measurements) else {
        bail!("diagnose needs --robot <model> and --measurements <csv> (or --images and --pattern for a camera, --forces for a force-sensing end-effector)");
    };
    if !(args.sigma_mm.is_finite() && args.sigma_mm > 0.0) {
        bail!("--sigma-mm must be positive");
    }
    let opts = DiagnoseOptions {
        folds: args.folds,
        alpha: args.alpha,
        validation_fraction: args.validation_fraction,
        sigma_position_m: args.sigma_mm * 1e-3,
        ..DiagnoseOptions::default()
    };
    let (model, rows) = super::calibrate::load_model_and_rows(robot, meas)?;
    let progress = crate::progress::bar(1, "diagnosing");
    let rep = diagnose(&model, &rows, &opts).context("diagnosis")?;
    progress.finish_and_clear();
    let compensated = match &args.out {
        Some(_) => Some(
            ferrocal_calib::diagnose::compensated_calibration(&model, &rows, &rep)
                .context("refitting the calibration with the accepted effects")?,
        ),
        None => None,
    };
    write_atomic(&args.json, serde_json::to_string_pretty(&rep)?.as_bytes())?;
    if let (Some(path), Some(cal)) = (&args.out, &compensated) {
        let file = ferrocal_calib::file::CalibrationFile::new(robot, &cal.calibrated);
        write_atomic(path, serde_json::to_string_pretty(&file)?.as_bytes())?;
        eprintln!(
            "wrote {} ({} effect(s) with the geometry; training RMS {:.4} mm)",
            path.display(),
            cal.calibrated.effects.len(),
            cal.train_after.rms_mm
        );
    }
    if let Some(h) = &args.report {
        let mut prov = Provenance::new(json!({"robot": robot, "options": opts}));
        prov.add_input(meas);
        let mut r = Report::new(&format!("Missing physics: {} on {}", model.name(), meas.display()), prov);
        r.sections = sections(&rep, args.attribution.as_deref());
        write_atomic(h, r.to_html().as_bytes())?;
    }
    if let Some(d) = &rep.declined {
        eprintln!("diagnose: {d}");
    }
    eprintln!(
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
    for f in &rep.findings {
        eprintln!("  {}: {}", f.effect, f.statement);
    }
    Ok(ExitCode::SUCCESS)
}

/// The camera variant: detect the pattern in every image, calibrate with the default lens model
/// and a flat target, test what the images show beyond it.
fn run_camera(args: &DiagnoseArgs) -> Result<ExitCode> {
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
        for c in dets.iter().filter(|d| d.complete).flat_map(|d| &d.corners) {
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
    write_atomic(&args.json, serde_json::to_string_pretty(&rep)?.as_bytes())?;
    if let Some(h) = &args.report {
        let prov = Provenance::new(json!({"images": args.images, "pattern": pattern_text, "options": opts}));
        let mut r =
            Report::new(&format!("Missing physics of a camera ({} views of {pattern_text})", views.len()), prov);
        let mut s = Section::new("camera-diagnose", "Camera: what the 5-coefficient model and a flat target leave out");
        if let Some(a) = &args.attribution {
            s.attribution(a);
        }
        s.text(format!(
            "Default model: reprojection RMS {:.4} px on all views, {:.4} px on held-out views (each view held out once over {} folds; its pose alone refitted). Final: {:.4} px held out.",
            rep.nominal.train_rms_px, rep.nominal.heldout_rms_px, opts.folds, rep.final_fit.heldout_rms_px
        ));
        if let Some(d) = &rep.declined {
            s.text(d.clone());
        }
        for f in &rep.findings {
            s.text(format!("{}: {}", f.effect, f.statement));
        }
        if rep.findings.is_empty() && rep.declined.is_none() && !rep.unexplained.structure_found {
            s.text("No candidate passes: the default model describes these images.");
        }
        if rep.unexplained.structure_found {
            s.text(format!(
                "Structure no candidate explains remains, depending on {}:",
                rep.unexplained.depends_on.join(" and ")
            ));
            s.pre(rep.unexplained.evidence.join("\n"));
        }
        for (k, round) in rep.candidates.iter().enumerate() {
            let rows = round.iter().map(|c| (&c.candidate, c.heldout_rms_px, c.p_value, &c.verdict));
            candidate_table(&mut s, k, "px", rows);
        }
        r.sections.push(s);
        write_atomic(h, r.to_html().as_bytes())?;
    }
    if let Some(d) = &rep.declined {
        eprintln!("diagnose: {d}");
    }
    eprintln!(
        "diagnosed a camera from {} views: held-out reprojection RMS {:.4} px -> {:.4} px; {} finding(s)",
        rep.n_views,
        rep.nominal.heldout_rms_px,
        rep.final_fit.heldout_rms_px,
        rep.findings.len()
    );
    for f in &rep.findings {
        eprintln!("  {}: {}", f.effect, f.statement);
    }
    if rep.unexplained.structure_found {
        eprintln!("  unexplained structure, depending on {}:", rep.unexplained.depends_on.join(" and "));
        for e in &rep.unexplained.evidence {
            eprintln!("    {e}");
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// The force-sensor variant: identify the rigid body and offsets, test the deformation terms on
/// held-out poses.
fn run_forces(args: &DiagnoseArgs, path: &std::path::Path) -> Result<ExitCode> {
    use ferrocal_calib::diagnose::force::{diagnose_force_sensor, ForceDiagnoseOptions};
    let (poses, forces) = super::dynamics::read_static_table(path)?;
    let reg = super::dynamics::rig_sensor_regressor()?;
    let opts = ForceDiagnoseOptions { folds: args.folds, alpha: args.alpha, ..ForceDiagnoseOptions::default() };
    let rep = diagnose_force_sensor(&reg, &poses, &forces, &opts)
        .with_context(|| format!("force-sensor diagnosis of {}", path.display()))?;
    write_atomic(&args.json, serde_json::to_string_pretty(&rep)?.as_bytes())?;
    if let Some(h) = &args.report {
        let prov = Provenance::new(json!({"forces": path.display().to_string(), "options": opts}));
        let mut r =
            Report::new(&format!("Missing physics of a force-sensing end-effector ({} poses)", poses.len()), prov);
        let mut s = Section::new("force-diagnose", "Force sensors: what the rigid-body model leaves out");
        if let Some(a) = &args.attribution {
            s.attribution(a);
        }
        s.text(format!(
            "Model 0 (rigid body and sensor offsets): force RMS {:.3} N on all poses, {:.3} N held out (each pose held out once over {} folds); mass {:.2} kg, centre of gravity {:.1} mm above the flange. Final (model {}): {:.3} N held out; mass {:.2} kg, centre of gravity {:.1} mm.",
            rep.nominal.train_rms_n, rep.nominal.heldout_rms_n, opts.folds, rep.mass_kg[0], rep.cog_z_m[0] * 1e3,
            rep.final_fit.model, rep.final_fit.heldout_rms_n, rep.mass_kg[1], rep.cog_z_m[1] * 1e3
        ));
        if let Some(d) = &rep.declined {
            s.text(d.clone());
        }
        for f in &rep.findings {
            s.text(format!("{}: {}", f.effect, f.statement));
        }
        if rep.unexplained.structure_found {
            s.text(format!(
                "Structure no candidate explains remains, depending on {}.",
                rep.unexplained.depends_on.join(", ")
            ));
        }
        for (k, round) in rep.candidates.iter().enumerate() {
            let rows = round.iter().map(|c| (&c.candidate, c.heldout_rms_n, c.p_value, &c.verdict));
            candidate_table(&mut s, k, "N", rows);
        }
        r.sections.push(s);
        write_atomic(h, r.to_html().as_bytes())?;
    }
    if let Some(d) = &rep.declined {
        eprintln!("diagnose: {d}");
    }
    eprintln!(
        "diagnosed a force-sensing end-effector from {} poses: held-out force RMS {:.3} N -> {:.3} N; {} finding(s); mass {:.2} -> {:.2} kg",
        poses.len(),
        rep.nominal.heldout_rms_n,
        rep.final_fit.heldout_rms_n,
        rep.findings.len(),
        rep.mass_kg[0],
        rep.mass_kg[1]
    );
    for f in &rep.findings {
        eprintln!("  {}: {}", f.effect, f.statement);
    }
    Ok(ExitCode::SUCCESS)
}

/// The candidates of step `k` (0-based) as a table: name, held-out RMS in `unit`, corrected
/// p-value, verdict.
fn candidate_table<'a>(
    s: &mut Section,
    k: usize,
    unit: &str,
    rows: impl Iterator<Item = (&'a String, f64, f64, &'a String)>,
) {
    s.table(
        &format!("Candidates, step {}", k + 1),
        &["candidate", &format!("held-out RMS [{unit}]"), "p (corrected)", "verdict"],
        rows.map(|(c, rms, p, v)| vec![c.clone(), f4(rms), p_text(p), v.clone()]).collect(),
    );
}

fn f4(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.4}")
    } else {
        "-".into()
    }
}

fn p_text(p: f64) -> String {
    if p < 1e-15 {
        "< 1e-15".into()
    } else {
        format!("{p:.2e}")
    }
}

/// Report sections of a diagnosis.
pub fn sections(rep: &DiagnoseReport, attribution: Option<&str>) -> Vec<Section> {
    let mut out = Vec::new();
    let mut s = Section::new("diagnose-summary", "What the model leaves out");
    s.status(rep.declined.is_none(), if rep.declined.is_some() { "declined" } else { "analysed" });
    if let Some(d) = &rep.declined {
        s.text(format!("Nothing is claimed: {d}."));
    }
    s.table(
        "Fits (RMS position error, mm)",
        &["model", "training poses", "training RMS", "held-out poses", "held-out RMS", "cross-validated RMS"],
        vec![
            vec![
                "geometric (identifiable parameters)".into(),
                rep.nominal.n_train.to_string(),
                f4(rep.nominal.train_rms_mm),
                rep.nominal.n_heldout.to_string(),
                f4(rep.nominal.heldout_rms_mm),
                f4(rep.nominal.cv_rms_mm),
            ],
            vec![
                "with the accepted effects".into(),
                rep.nominal.n_train.to_string(),
                f4(rep.final_fit.train_rms_mm),
                rep.nominal.n_heldout.to_string(),
                f4(rep.final_fit.heldout_rms_mm),
                f4(rep.final_fit.cv_rms_mm),
            ],
        ],
    );
    s.text(format!("Held-out rows: {}.", rep.split));
    if rep.findings.is_empty() && rep.declined.is_none() {
        s.text("No effect beyond the geometric model is supported by these data.");
    }
    for (k, f) in rep.findings.iter().enumerate() {
        s.text(format!("{}. {} (joints {:?}): {}", k + 1, f.effect, f.joints, f.statement));
    }
    if rep.unexplained.structure_found {
        s.text(format!(
            "Structure no candidate explains remains in the held-out residuals; it depends on: {}.",
            rep.unexplained.depends_on.join(", ")
        ));
    } else if rep.declined.is_none() {
        s.text("No structure remains in the held-out residuals against any recorded input.");
    }
    for n in &rep.notes {
        s.text(format!("Note: {n}"));
    }
    if let Some(a) = attribution {
        s.attribution(a);
    }
    s.data = serde_json::to_value(rep).unwrap_or_default();
    out.push(s);

    for (k, f) in rep.findings.iter().enumerate() {
        let mut fs = Section::new(&format!("finding-{}", k + 1), &format!("Finding {}: {}", k + 1, f.effect));
        fs.text(f.statement.clone());
        fs.table(
            "Identified parameters",
            &["parameter", "value"],
            f.parameters.iter().map(|(n, v)| vec![n.clone(), format!("{v:.6e}")]).collect(),
        );
        fs.table(
            "Evidence",
            &[
                "held-out RMS before [mm]",
                "after [mm]",
                "explained fraction",
                "p (corrected)",
                "p (uncorrected)",
                "candidates tried",
                "jackknife rel. std",
                "sin(angle to geometry)",
            ],
            vec![vec![
                f4(f.heldout_rms_before_mm),
                f4(f.heldout_rms_after_mm),
                format!("{:.3}", f.explained_fraction),
                p_text(f.p_value),
                p_text(f.p_value_uncorrected),
                f.candidates_tried.to_string(),
                format!("{:.3}", f.relative_std),
                format!("{:.3}", f.sin_angle_to_geometry),
            ]],
        );
        if let Some(ev) = rep.evidence.iter().find(|e| e.finding == k) {
            fs.figure(
                &format!(
                    "Cross-validated residual against {}: before (blue points, green line: binned means) and after (red points, orange line) modelling the effect",
                    f.telling_input
                ),
                evidence_plot(ev),
            );
        }
        out.push(fs);
    }

    let mut c = Section::new("diagnose-candidates", "Candidates tried");
    for (k, st) in rep.steps.iter().enumerate() {
        c.table(
            &format!(
                "Step {} ({} candidates; accepted: {})",
                k + 1,
                st.candidates.len(),
                st.accepted.clone().unwrap_or_else(|| "none".into())
            ),
            &["candidate", "CV RMS before [mm]", "CV RMS after [mm]", "improvement [%]", "p", "p corrected", "verdict"],
            st.candidates
                .iter()
                .map(|x| {
                    vec![
                        x.label.clone(),
                        f4(x.cv_rms_before_mm),
                        f4(x.cv_rms_after_mm),
                        format!("{:.2}", x.improvement * 100.0),
                        p_text(x.p_value),
                        p_text(x.p_corrected),
                        x.verdict.clone(),
                    ]
                })
                .collect(),
        );
    }
    out.push(c);

    let mut u = Section::new("diagnose-untestable", "Candidates that could not be tested");
    if rep.untestable.is_empty() {
        u.text("Every candidate could be tested on this recording.");
    } else {
        u.table(
            "Untestable candidates",
            &["effect", "joints", "why"],
            rep.untestable
                .iter()
                .map(|x| vec![x.effect.clone(), format!("{:?}", x.joints), x.reason.clone()])
                .collect(),
        );
    }
    out.push(u);

    let mut sc = Section::new("diagnose-screening", "Held-out residuals against every recorded input");
    sc.text(
        "Weighted one-way analysis of variance of each joint's implied angle error and of the implied relative length change over bins of each input (cross-validated residuals; p corrected by Bonferroni over all tests).",
    );
    let row = |a: &InputStructure, b: Option<&InputStructure>| {
        vec![
            a.quantity.clone(),
            a.input.clone(),
            p_text(a.p_corrected),
            format!("{:.3}", a.explained_fraction),
            b.map(|b| p_text(b.p_corrected)).unwrap_or_default(),
            b.map(|b| format!("{:.3}", b.explained_fraction)).unwrap_or_default(),
        ]
    };
    let mut rows: Vec<Vec<String>> = rep
        .screening_nominal
        .iter()
        .map(|a| row(a, rep.screening_final.iter().find(|b| b.quantity == a.quantity && b.input == a.input)))
        .collect();
    rows.sort_by(|a, b| a[2].cmp(&b[2]));
    sc.table(
        "Screening (geometric model, then with the accepted effects)",
        &[
            "residual quantity",
            "input",
            "p corrected (geometric)",
            "explained (geometric)",
            "p corrected (final)",
            "explained (final)",
        ],
        rows,
    );
    out.push(sc);
    out
}

/// Scatter of the residual quantity against the input, before and after, with binned means.
fn evidence_plot(ev: &Evidence) -> String {
    let before: Vec<(f64, f64)> = ev.x.iter().copied().zip(ev.before.iter().copied()).collect();
    let after: Vec<(f64, f64)> = ev.x.iter().copied().zip(ev.after.iter().copied()).collect();
    let bins = |pts: &[(f64, f64)]| -> Vec<(f64, f64)> {
        let mut v: Vec<(f64, f64)> = pts.iter().copied().filter(|p| p.0.is_finite() && p.1.is_finite()).collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        let nb = (v.len() / 25).clamp(2, 12);
        let mut out = Vec::new();
        for chunk in v.chunks(v.len().div_ceil(nb).max(1)) {
            let n = chunk.len() as f64;
            out.push((chunk.iter().map(|p| p.0).sum::<f64>() / n, chunk.iter().map(|p| p.1).sum::<f64>() / n));
        }
        out
    };
    let mb = bins(&before);
    let ma = bins(&after);
    // Large recordings: every k-th point in the scatter (the binned means use all).
    let step = before.len().div_ceil(2500).max(1);
    let before: Vec<(f64, f64)> = before.into_iter().step_by(step).collect();
    let after: Vec<(f64, f64)> = after.into_iter().step_by(step).collect();
    plot::xy_plot(
        "Residual against the telling input",
        &ev.x_label,
        &ev.y_label,
        &[
            Series { name: "before", points: &before, line: false },
            Series { name: "after", points: &after, line: false },
            Series { name: "binned mean before", points: &mb, line: true },
            Series { name: "binned mean after", points: &ma, line: true },
        ],
    )
}
