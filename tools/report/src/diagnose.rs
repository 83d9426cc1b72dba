//! Report sections of `ferrocal diagnose`: the robot variant (fits, findings with their
//! evidence plots, candidates, untestable candidates, the screening of every input), the camera
//! and the force-sensor variants; their JSON with the verdict ([`diagnose_json`]), the robot
//! variant's output files ([`robot_outputs`]) and their terminal summaries.

use ferrocal_calib::diagnose::camera::{CameraCandidateScore, CameraDiagnoseReport, CameraUnexplained};
use ferrocal_calib::diagnose::force::ForceDiagnoseReport;
use std::path::Path;

use ferrocal_calib::diagnose::{DiagnoseOptions, DiagnoseReport, Evidence, InputStructure};
use ferrocal_calib::file::CalibrationFile;
use ferrocal_calib::kinematic::KinematicCalibration;
use ferrocal_calib::verdict::{Thresholds, Verdict};
use serde::Serialize;
use serde_json::{json, Value};

use crate::error::Result;
use crate::outputs::Outputs;
use crate::plot::{self, Series};
use crate::report::{Provenance, Report, Section};
use crate::verdict::add_verdict;

/// The JSON of a diagnosis (any variant) with its verdict added, and the verdict
/// ([`ferrocal_calib::verdict::commands::diagnose`]; `unit`: `mm`, `px` or `n`; `next`: the next
/// step when effects were found).
pub fn diagnose_json(t: &Thresholds, rep: &impl Serialize, unit: &str, next: &str) -> Result<(Value, Verdict)> {
    let mut v = serde_json::to_value(rep)?;
    let verdict = ferrocal_calib::verdict::commands::diagnose(t, &v, unit, next);
    add_verdict(&mut v, &verdict);
    Ok((v, verdict))
}

/// The outputs of the camera and force variants of `ferrocal diagnose`: the JSON of `rep` with
/// its verdict ([`diagnose_json`]) at `json` and, when `html` is given, a report of the one
/// `section` (`page`: its title, the settings its provenance records, the section).
pub fn variant_outputs(
    t: &Thresholds,
    rep: &impl Serialize,
    (unit, next): (&str, &str),
    json: &Path,
    html: Option<&Path>,
    page: impl FnOnce() -> (String, Value, Section),
) -> Result<(Outputs, Verdict)> {
    let (rep_json, verdict) = diagnose_json(t, rep, unit, next)?;
    let report = html.map(|h| {
        let (title, settings, section) = page();
        (h, Report::of(&title, Provenance::new(settings), vec![section]))
    });
    Ok((Outputs::json_and_report(json, &rep_json, report, &verdict)?, verdict))
}

/// Where the camera, stereo and force variants of `ferrocal diagnose` write: the JSON, the
/// optional HTML report, and the attribution of the recording printed in it.
#[derive(Clone, Copy, Debug)]
pub struct VariantFiles<'a> {
    /// The JSON report (`shared/spec/diagnose.md`).
    pub json: &'a Path,
    /// The HTML report.
    pub report: Option<&'a Path>,
    /// Data attribution printed in the HTML report.
    pub attribution: Option<&'a str>,
}

/// The camera variant's outputs: the JSON of `rep` (from `n_views` views of the images and
/// pattern string `input`) with its verdict and the report, written together; then the summary
/// and the verdict line.
pub fn camera_outputs(
    rep: &CameraDiagnoseReport,
    n_views: usize,
    (images, pattern): (&[String], &str),
    opts: &ferrocal_calib::diagnose::camera::CameraDiagnoseOptions,
    files: VariantFiles,
    vs: &crate::verdict::VerdictSettings,
) -> Result<std::process::ExitCode> {
    let next =
        "calibrate with the lens model or target shape the findings name (ferrocal camera calibrate --model ...)";
    let page = || {
        let title = format!("Missing physics of a camera ({n_views} views of {pattern})");
        let settings = json!({"images": images, "pattern": pattern, "options": opts});
        (title, settings, camera_section(rep, opts.folds, files.attribution))
    };
    // Both files together: no report without its JSON.
    let (out, verdict) = variant_outputs(&vs.thresholds, rep, ("px", next), files.json, files.report, page)?;
    out.write()?;
    camera_summary_lines(rep).iter().for_each(|l| crate::say!("{l}"));
    Ok(vs.conclude(&verdict))
}

/// The force-sensor variant of `ferrocal diagnose` on the quasi-static table at `path`:
/// identifies the rigid body and offsets, tests the deformation terms on held-out poses, writes
/// the JSON (and the report), prints the summary and ends with the verdict.
pub fn run_forces(
    path: &Path,
    opts: &ferrocal_calib::diagnose::force::ForceDiagnoseOptions,
    files: VariantFiles,
    vs: &crate::verdict::VerdictSettings,
) -> Result<std::process::ExitCode> {
    let (n_poses, rep) = ferrocal_datasets::dynsim::identify::diagnose_static_table(path, opts)?;
    let next = "identify the sensor with the terms the findings name (docs/dynamics.md)";
    let page = || {
        let title = format!("Missing physics of a force-sensing end-effector ({n_poses} poses)");
        let settings = json!({"forces": path.display().to_string(), "options": opts});
        (title, settings, force_section(&rep, opts.folds, files.attribution))
    };
    // Both files together: no report without its JSON.
    let (out, verdict) = variant_outputs(&vs.thresholds, &rep, ("n", next), files.json, files.report, page)?;
    out.write()?;
    force_summary_lines(&rep, n_poses).iter().for_each(|l| crate::say!("{l}"));
    Ok(vs.conclude(&verdict))
}

/// Where the robot variant of `ferrocal diagnose` writes, and what it read.
#[derive(Clone, Copy, Debug)]
pub struct DiagnoseFiles<'a> {
    /// The robot model as given (preset, URDF or TOML).
    pub robot: &'a str,
    /// The measurement table.
    pub measurements: &'a Path,
    /// The JSON report.
    pub json: &'a Path,
    /// The HTML report with the evidence.
    pub report: Option<&'a Path>,
    /// The calibration refitted with the accepted effects.
    pub out: Option<&'a Path>,
    /// Data attribution printed in the HTML report.
    pub attribution: Option<&'a str>,
    /// The advice of the table's unit doubts, put first in the verdict
    /// ([`ferrocal_calib::verdict::with_unit_doubts`]).
    pub unit_doubts: &'a [String],
}

/// The files of the robot variant, composed (not written), and its verdict: the JSON with the
/// verdict, the refitted calibration (`compensated`) and the HTML report of the model named
/// `model` (its provenance: the robot and `opts`).
pub fn robot_outputs(
    t: &Thresholds,
    rep: &DiagnoseReport,
    model: &str,
    compensated: Option<(&KinematicCalibration, &[&ferrocal_calib::PoseMeasurement])>,
    opts: &DiagnoseOptions,
    files: &DiagnoseFiles,
) -> Result<(Outputs, Verdict)> {
    let (robot, meas) = (files.robot, files.measurements);
    let rerun = format!(
        "ferrocal calibrate --robot {robot} --measurements {} --effects {} --out <calibration.json>",
        meas.display(),
        files.json.display()
    );
    let (mut rep_json, verdict) = diagnose_json(t, rep, "mm", &rerun)?;
    let doubts: Vec<&str> = files.unit_doubts.iter().map(String::as_str).collect();
    let verdict = ferrocal_calib::verdict::with_unit_doubts(verdict, &doubts);
    add_verdict(&mut rep_json, &verdict);
    let mut out = Outputs::default();
    out.json(files.json, &rep_json)?;
    if let (Some(path), Some((cal, rows))) = (files.out, compensated) {
        let uncertainty = ferrocal_calib::kinematic::correct::Uncertainty::from_kinematic(cal, rows)?;
        out.json(path, &CalibrationFile::delivered(robot, &cal.calibrated, rows, Some(uncertainty))?)?;
    }
    if let Some(h) = files.report {
        let mut prov = Provenance::new(json!({"robot": robot, "options": opts}));
        prov.add_input(meas);
        let title = format!("Missing physics: {model} on {}", meas.display());
        out.html(h, Report::of(&title, prov, sections(rep, files.attribution)), &verdict);
    }
    Ok((out, verdict))
}

/// The terminal line of the refitted calibration written to `path`.
pub fn compensated_line(path: &Path, cal: &KinematicCalibration) -> String {
    format!(
        "wrote {} ({} effect(s) with the geometry; training RMS {:.4} mm)",
        path.display(),
        cal.calibrated.effects.len(),
        cal.train_after.rms_mm
    )
}

/// The terminal summary of the robot variant on the model named `model`: why it declined (if
/// it did), the held-out RMS before and after, the summary and every finding.
pub fn summary_lines(rep: &DiagnoseReport, model: &str) -> Vec<String> {
    let mut out: Vec<String> = rep.declined.iter().map(|d| format!("diagnose: {d}")).collect();
    out.push(format!(
        "diagnosed {model} on {} poses in {:.1} s: held-out RMS {:.4} mm (geometric model) -> {:.4} mm; {} finding(s){}",
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
    ));
    out.push(format!("  {}", rep.summary));
    out.extend(rep.findings.iter().map(|f| format!("  {}: {}", f.effect, f.statement)));
    out
}

/// The terminal summary of the camera variant: why it declined (if it did), the held-out
/// reprojection RMS before and after, every finding and the unexplained structure.
pub fn camera_summary_lines(rep: &CameraDiagnoseReport) -> Vec<String> {
    let mut out: Vec<String> = rep.declined.iter().map(|d| format!("diagnose: {d}")).collect();
    out.push(format!(
        "diagnosed a camera from {} views: held-out reprojection RMS {:.4} px -> {:.4} px; {} finding(s)",
        rep.n_views,
        rep.nominal.heldout_rms_px,
        rep.final_fit.heldout_rms_px,
        rep.findings.len()
    ));
    out.extend(rep.findings.iter().map(|f| format!("  {}: {}", f.effect, f.statement)));
    if rep.unexplained.structure_found {
        out.push(format!("  unexplained structure, depending on {}:", rep.unexplained.depends_on.join(" and ")));
        out.extend(rep.unexplained.evidence.iter().map(|e| format!("    {e}")));
    }
    out
}

/// The terminal summary of the force-sensor variant on `n_poses` poses: why it declined (if it
/// did), the held-out force RMS and the mass before and after, every finding.
pub fn force_summary_lines(rep: &ForceDiagnoseReport, n_poses: usize) -> Vec<String> {
    let mut out: Vec<String> = rep.declined.iter().map(|d| format!("diagnose: {d}")).collect();
    out.push(format!(
        "diagnosed a force-sensing end-effector from {n_poses} poses: held-out force RMS {:.3} N -> {:.3} N; {} finding(s); mass {:.2} -> {:.2} kg",
        rep.nominal.heldout_rms_n,
        rep.final_fit.heldout_rms_n,
        rep.findings.len(),
        rep.mass_kg[0],
        rep.mass_kg[1]
    ));
    out.extend(rep.findings.iter().map(|f| format!("  {}: {}", f.effect, f.statement)));
    out
}

/// The camera variant's section (`folds`: of the cross-validation).
pub fn camera_section(rep: &CameraDiagnoseReport, folds: usize, attribution: Option<&str>) -> Section {
    let mut s = Section::new("camera-diagnose", "Camera: what the 5-coefficient model and a flat target leave out");
    if let Some(a) = attribution {
        s.attribution(a);
    }
    s.text(format!(
        "Default model: reprojection RMS {:.4} px on all views, {:.4} px on held-out views (each view held out once over {} folds; its pose alone refitted). Final: {:.4} px held out.",
        rep.nominal.train_rms_px, rep.nominal.heldout_rms_px, folds, rep.final_fit.heldout_rms_px
    ));
    let findings: Vec<(&str, &str)> = rep.findings.iter().map(|f| (f.effect.as_str(), f.statement.as_str())).collect();
    image_family_body(&mut s, &rep.declined, &findings, &rep.unexplained, &rep.candidates, "images");
    s
}

/// What the camera and stereo sections say after their first line: why the analysis declined,
/// the findings (effect and statement), that none passed (the default model describes these
/// `units`), the structure left and every round's candidates.
pub(crate) fn image_family_body(
    s: &mut Section,
    declined: &Option<String>,
    findings: &[(&str, &str)],
    unexplained: &CameraUnexplained,
    candidates: &[Vec<CameraCandidateScore>],
    units: &str,
) {
    if let Some(d) = declined {
        s.text(d.clone());
    }
    for (effect, statement) in findings {
        s.text(format!("{effect}: {statement}"));
    }
    if findings.is_empty() && declined.is_none() && !unexplained.structure_found {
        s.text(format!("No candidate passes: the default model describes these {units}."));
    }
    if unexplained.structure_found {
        s.text(format!(
            "Structure no candidate explains remains, depending on {}:",
            unexplained.depends_on.join(" and ")
        ));
        s.pre(unexplained.evidence.join("\n"));
    }
    for (k, round) in candidates.iter().enumerate() {
        let rows = round.iter().map(|c| (&c.candidate, c.heldout_rms_px, c.p_value, &c.verdict));
        candidate_table(s, k, "px", rows);
    }
}

/// The force-sensor variant's section.
pub fn force_section(rep: &ForceDiagnoseReport, folds: usize, attribution: Option<&str>) -> Section {
    let mut s = Section::new("force-diagnose", "Force sensors: what the rigid-body model leaves out");
    if let Some(a) = attribution {
        s.attribution(a);
    }
    s.text(format!(
        "Model 0 (rigid body and sensor offsets): force RMS {:.3} N on all poses, {:.3} N held out (each pose held out once over {} folds); mass {:.2} kg, centre of gravity {:.1} mm above the flange. Final (model {}): {:.3} N held out; mass {:.2} kg, centre of gravity {:.1} mm.",
        rep.nominal.train_rms_n, rep.nominal.heldout_rms_n, folds, rep.mass_kg[0], rep.cog_z_m[0] * 1e3,
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
    s
}

/// The candidates of step `k` (0-based) as a table: name, held-out RMS in `unit`, corrected
/// p-value, verdict.
pub(crate) fn candidate_table<'a>(
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
    } else if !rep.summary.is_empty() {
        s.text(rep.summary.clone());
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

/// The demo's diagnose cases (`ferrocal_datasets::sim::scenario::diagnose_cases`): recordings
/// shaped like the real ones the fixed vetoes missed, the truth beside what was found.
pub fn cases_section(cases: &[ferrocal_datasets::sim::scenario::DiagnoseCase]) -> Section {
    let mut s = Section::new("diagnose-cases", "Diagnose: large and leading effects, found and named");
    s.text(
        "Simulated recordings (the simulator in datasets/src/sim, written apart from the analysis but in the same model families; the sag is computed at the torque equilibrium of the deflected pose, as the analysis's effect model does). The humanoid torso (when the demo runs without --quick) comes from a second simulator (datasets/src/sim/tree.rs) that shares no code with the analysis: its own kinematics over the whole tree, torques from the potential energy of both arms; the analysis reads the robot from its URDF, the unmeasured arm lumped into the torso. Sizes beyond the typical range of industrial arms are evidence, not vetoes: they are claimed on strong held-out support and marked UNUSUAL; a direction-dependent error of either sign is a finding (docs/diagnose.md). A case is right when diagnose names exactly its true effects and, where the simulator knows the true model's held-out RMS (the noise), comes within 1.15 times it.",
    );
    let words = |v: &[(String, Vec<usize>)]| -> String {
        if v.is_empty() {
            return "nothing".into();
        }
        v.iter()
            .map(|(e, j)| format!("{e} {}", j.iter().map(|j| format!("j{j}")).collect::<Vec<_>>().join("+")))
            .collect::<Vec<_>>()
            .join(", ")
    };
    s.table(
        "Each case: the truth, the right answer, what diagnose named, held-out RMS before and after",
        &["case", "truth", "right answer", "named", "held-out before [mm]", "after [mm]", "true model [mm]", "right?"],
        cases
            .iter()
            .map(|c| {
                vec![
                    c.name.clone(),
                    c.truth.clone(),
                    words(&c.expected),
                    words(&c.found),
                    f4(c.heldout_before_mm),
                    f4(c.heldout_after_mm),
                    c.truth_heldout_mm.map_or_else(|| "-".into(), f4),
                    if c.correct { "yes".into() } else { "NO".into() },
                ]
            })
            .collect(),
    );
    for c in cases {
        s.text(format!("{}: {}", c.name, c.summary));
    }
    let right = cases.iter().filter(|c| c.correct).count();
    s.check(ferrocal_calib::check::Check::from_bool(
        "diagnose cases",
        right == cases.len(),
        format!("{right} of {} cases named exactly their true effects", cases.len()),
    ));
    s.data = serde_json::json!(cases);
    s
}
