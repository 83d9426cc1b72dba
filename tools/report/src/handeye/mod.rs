//! `ferrocal handeye`'s presentation: its JSON ([`json`], keys per `shared/spec/cli.md`), its
//! HTML report ([`html`]), its verdict ([`verdict`]), the terminal summary, and the demo's
//! hand-eye sections ([`demo`], [`joint_demo`]). The workflow lives in
//! `ferrocal_datasets::handeye::workflow`, the method in `ferrocal_calib::handeye`.

pub mod demo;
pub mod html;
pub mod joint_demo;
pub mod json;
pub mod verdict;

use std::path::Path;
use std::process::ExitCode;

use ferrocal_datasets::handeye::CoverageSummary;

/// Prints the hand-eye calibration's summary on stdout (its warnings on stderr).
pub fn print_summary(
    r: &ferrocal_calib::handeye::HandEyeResult,
    best: Option<&ferrocal_calib::handeye::opencv::BaselineReport>,
    source: Option<&str>,
) {
    let p = r.hand_eye.transform.translation.vector * 1e3;
    let s = r.hand_eye.translation_std_mm();
    println!(
        "{} {}: translation [{:.3}, {:.3}, {:.3}] +- [{:.3}, {:.3}, {:.3}] mm, rotation std {:.4?} deg",
        r.mount.name(),
        r.mount.hand_eye_name(),
        p.x,
        p.y,
        p.z,
        s.x,
        s.y,
        s.z,
        r.hand_eye.rotation_std_deg().as_slice()
    );
    let f = &r.figures;
    let opt = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{x:.4}"));
    println!(
        "chain RMS: train {:.4} px, held-out {} px; PnP agreement: train {} mm / {} deg, held-out {} mm / {} deg",
        f.train_rms_px,
        opt(f.heldout_rms_px),
        opt(f.train_pnp_position_mm),
        opt(f.train_pnp_rotation_deg),
        opt(f.heldout_pnp_position_mm),
        opt(f.heldout_pnp_rotation_deg)
    );
    if let Some(b) = best.and_then(|b| b.figures.as_ref().map(|f| (b, f))) {
        println!(
            "OpenCV best ({} {}): train {:.4} px, held-out {} px",
            b.0.function,
            b.0.method,
            b.1.train_rms_px,
            opt(b.1.heldout_rms_px)
        );
    }
    if let Some(src) = source {
        println!("data: {src}");
    }
    for w in &r.warnings {
        eprintln!("ferrocal handeye: warning: {w}");
    }
}

/// One line of `ferrocal handeye study`: a mount's coverage and errors.
pub fn coverage_line(r: &CoverageSummary) -> String {
    format!(
        "{}: {} runs ({} failed); 3-sigma coverage translation {:.1} %, rotation {:.1} %; RMS error {:.4} mm \
         (stated std {:.4} mm), {:.5} deg (stated {:.5} deg); held-out chain RMS {:.4} px",
        r.mount.name(),
        r.n_runs,
        r.n_failed,
        100.0 * r.translation_coverage_3sigma,
        100.0 * r.rotation_coverage_3sigma,
        r.translation_rms_error_mm,
        r.translation_rms_std_mm,
        r.rotation_rms_error_deg,
        r.rotation_rms_std_deg,
        r.mean_heldout_rms_px
    )
}

/// The end of `ferrocal import ic-handeye` (the set imported from `input` into the poses table
/// `out` by `ferrocal_datasets::handeye::import_ic_handeye`): the summary line and the verdict.
pub fn import_ic_summary(
    set: &ferrocal_datasets::handeye::IcSet,
    input: &Path,
    out: &Path,
    vs: &crate::verdict::VerdictSettings,
) -> ExitCode {
    let n_test = set.rows.iter().filter(|r| r.2 == ferrocal_calib::Split::Test).count();
    println!(
        "{} rows ({n_test} test) written to {}; mount {}{}",
        set.rows.len(),
        out.display(),
        set.mount.name(),
        set.pattern.as_ref().map(|p| format!(", pattern {p}")).unwrap_or_default()
    );
    let l = &vs.thresholds.import;
    let checks = vec![ferrocal_calib::verdict::Check::at_least(
        "import.rows",
        "rows written",
        "",
        set.rows.len() as f64,
        l.rows_warn,
        l.rows_fail,
    )];
    let mount_name = set.mount.name();
    let pattern = set.pattern.clone().unwrap_or_else(|| "<pattern>".into());
    let verdict = ferrocal_calib::verdict::Verdict::with_next(checks, |c| {
        match c {
        None => format!(
            "calibrate ({n_test} rows marked test are held out): ferrocal handeye --images {}/images --poses {} --pattern {pattern} --mount {mount_name} --json <result.json>",
            input.display(),
            out.display()
        ),
        Some(_) => "the set holds too few images for a hand-eye calibration: record more poses".into(),
    }
    });
    vs.conclude(&verdict)
}
