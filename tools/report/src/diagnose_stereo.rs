//! The stereo variant of `ferrocal diagnose` (`--images left/ --images right/ --pattern ...`):
//! the pattern found in both cameras' images (paired by sorted order, as `camera stereo` pairs
//! them), the diagnosis over both cameras
//! ([`ferrocal_calib::diagnose::stereo::diagnose_stereo`]), its JSON with the verdict, its HTML
//! section and its terminal summary.

use std::process::ExitCode;

use ferrocal_calib::diagnose::camera::CameraDiagnoseOptions;
use ferrocal_calib::diagnose::stereo::{diagnose_stereo, StereoDiagnoseReport};
use ferrocal_datasets::camera::stereo_diagnosis_views;
use serde_json::json;

use crate::diagnose::{image_family_body, variant_outputs, VariantFiles};
use crate::error::{Context, Result};
use crate::report::Section;
use crate::say;
use crate::verdict::VerdictSettings;

/// Runs the stereo variant on `[left specs, right specs]` of the pattern string `pattern`:
/// writes the JSON (and the report), prints the summary and ends with the verdict.
pub fn run_stereo(
    groups: [&[String]; 2],
    pattern: &str,
    opts: &CameraDiagnoseOptions,
    files: VariantFiles,
    vs: &VerdictSettings,
) -> Result<ExitCode> {
    let (found, target) = stereo_diagnosis_views(groups[0], groups[1], pattern)?;
    for s in &found.skipped {
        eprintln!("ferrocal: skipped {s}");
    }
    let rep = diagnose_stereo(&found.left, &found.right, &target, opts).context("stereo diagnosis")?;
    let next = "calibrate the pair with the lens models or target shape the findings name (ferrocal camera stereo --model ...)";
    let page = || {
        let title = format!("Missing physics of a stereo pair ({} pairs of {pattern})", rep.n_pairs);
        let settings = json!({"images": groups, "pattern": pattern, "options": opts});
        (title, settings, stereo_section(&rep, opts.folds, files.attribution))
    };
    let (out, verdict) = variant_outputs(&vs.thresholds, &rep, ("px", next), files.json, files.report, page)?;
    out.write()?;
    stereo_summary_lines(&rep).iter().for_each(|l| say!("{l}"));
    Ok(vs.conclude(&verdict))
}

/// How many views were used, in words.
fn views_line(rep: &StereoDiagnoseReport) -> String {
    let [l, r] = rep.n_single_views;
    format!(
        "{} pairs held out in turn; {l} left-only and {r} right-only view(s) used in training only; {} right view(s) renumbered to match the left",
        rep.n_pairs, rep.n_reversed_views
    )
}

/// The terminal summary: why it declined (if it did), the held-out reprojection RMS over both
/// images before and after, every finding (lens findings name their camera) and the
/// unexplained structure.
pub fn stereo_summary_lines(rep: &StereoDiagnoseReport) -> Vec<String> {
    let mut out: Vec<String> = rep.declined.iter().map(|d| format!("diagnose: {d}")).collect();
    out.push(format!(
        "diagnosed a stereo pair from {} pairs: held-out reprojection RMS (both images) {:.4} px -> {:.4} px; {} finding(s); baseline {:.2} mm",
        rep.n_pairs,
        rep.nominal.heldout_rms_px,
        rep.final_fit.heldout_rms_px,
        rep.findings.len(),
        rep.baseline_mm
    ));
    out.push(format!("  {}", views_line(rep)));
    out.extend(rep.findings.iter().map(|f| match f.camera {
        Some(c) => format!("  {} (camera {c}): {}", f.effect, f.statement),
        None => format!("  {}: {}", f.effect, f.statement),
    }));
    if rep.unexplained.structure_found {
        out.push(format!("  unexplained structure, depending on {}:", rep.unexplained.depends_on.join(" and ")));
        out.extend(rep.unexplained.evidence.iter().map(|e| format!("    {e}")));
    }
    out
}

/// The HTML section (`folds`: of the cross-validation over pairs).
pub fn stereo_section(rep: &StereoDiagnoseReport, folds: usize, attribution: Option<&str>) -> Section {
    let mut s = Section::new(
        "stereo-diagnose",
        "Stereo pair: what two 5-coefficient cameras, one rigid baseline and a flat target leave out",
    );
    if let Some(a) = attribution {
        s.attribution(a);
    }
    s.text(format!(
        "Default model: reprojection RMS {:.4} px on all views, {:.4} px on held-out pairs (each pair held out once over {} folds; its target pose alone refitted to both images). Final: {:.4} px held out. {}.",
        rep.nominal.train_rms_px, rep.nominal.heldout_rms_px, folds, rep.final_fit.heldout_rms_px, views_line(rep)
    ));
    let findings: Vec<(&str, &str)> = rep.findings.iter().map(|f| (f.effect.as_str(), f.statement.as_str())).collect();
    image_family_body(&mut s, &rep.declined, &findings, &rep.unexplained, &rep.candidates, "image pairs");
    s
}
