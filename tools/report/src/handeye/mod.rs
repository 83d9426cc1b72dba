//! `ferrocal handeye`'s presentation: its JSON ([`json`], keys per `shared/spec/cli.md`), its
//! HTML report ([`html`]), all its output files ([`handeye_outputs`]), its verdict ([`verdict`]),
//! the terminal summary, and the demo's
//! hand-eye sections ([`demo`], [`joint_demo`]). The workflow lives in
//! `ferrocal_datasets::handeye::workflow`, the method in `ferrocal_calib::handeye`.

pub mod demo;
pub mod html;
pub mod joint_demo;
pub mod json;
pub mod physics;
pub mod physics_demo;
pub mod rig;
pub mod rig_demo;
pub mod rig_html;
pub mod scene;
pub mod verdict;

use std::path::Path;
use std::process::ExitCode;

use ferrocal_calib::handeye::JointCalibration;
use ferrocal_calib::verdict::Verdict;
use ferrocal_datasets::handeye::{CoverageSummary, HandEyeFit, HandEyeInput, HandEyeRunOptions, StudyMode};
use serde_json::{json, Value};

use crate::error::Result;
use crate::outputs::Outputs;
use crate::report::{Provenance, Report};

/// Presents a one-camera run on the terminal (the summary with OpenCV's best beside it, the
/// joint adjustment's line when it ran) and returns its verdict: the chain's checks, the motion
/// check `motion`, the joint adjustment's (`joint`, whose calibration went to `joint_out`).
pub fn present_run(
    t: &ferrocal_calib::verdict::Thresholds,
    input: &HandEyeInput,
    fit: &HandEyeFit,
    joint: Option<&JointCalibration>,
    motion: ferrocal_calib::verdict::Check,
    joint_out: Option<&Path>,
    flags: verdict::RunFlags,
) -> Verdict {
    use ferrocal_calib::handeye::opencv::best_baseline;
    print_summary(&fit.result, best_baseline(&fit.baselines), input.table.source.as_deref());
    if let Some(p) = &fit.physics {
        crate::say!("{}", physics::physics_line(p));
    }
    let mut checks = verdict::fit_checks(t, &input.data, &fit.result);
    checks.push(motion);
    if let (Some(joint), Some(out)) = (joint, joint_out) {
        checks.extend(verdict::joint_checks(t, joint));
        crate::say!("{}", joint_line(joint, out));
    }
    verdict::run_verdict(checks, &fit.result, joint_out, flags)
}

/// Prints the hand-eye calibration's summary on stdout (its warnings on stderr).
pub fn print_summary(
    r: &ferrocal_calib::handeye::HandEyeResult,
    best: Option<&ferrocal_calib::handeye::opencv::BaselineReport>,
    source: Option<&str>,
) {
    let p = r.hand_eye.transform.translation.vector * 1e3;
    let s = r.hand_eye.translation_std_mm();
    crate::say!(
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
    crate::say!(
        "chain RMS: train {:.4} px, held-out {} px; PnP agreement: train {} mm / {} deg, held-out {} mm / {} deg",
        f.train_rms_px,
        opt(f.heldout_rms_px),
        opt(f.train_pnp_position_mm),
        opt(f.train_pnp_rotation_deg),
        opt(f.heldout_pnp_position_mm),
        opt(f.heldout_pnp_rotation_deg)
    );
    if let Some(b) = best.and_then(|b| b.figures.as_ref().map(|f| (b, f))) {
        crate::say!(
            "OpenCV best ({} {}): train {:.4} px, held-out {} px",
            b.0.function,
            b.0.method,
            b.1.train_rms_px,
            opt(b.1.heldout_rms_px)
        );
    }
    if let Some(src) = source {
        crate::say!("data: {src}");
    }
    detail_lines(r).iter().for_each(|l| crate::detail!("{l}"));
    for w in &r.warnings {
        eprintln!("ferrocal handeye: warning: {w}");
    }
}

/// The internals `--verbose` adds to a hand-eye run: the closed-form starts with their training
/// RMS, the noise levels the fit weighted with, the solver's end, and every image's chain RMS.
pub fn detail_lines(r: &ferrocal_calib::handeye::HandEyeResult) -> Vec<String> {
    let starts: Vec<String> = r
        .starts
        .iter()
        .map(|s| {
            let what = match (&s.train_rms_px, &s.error) {
                (Some(rms), _) => format!("{rms:.4} px"),
                (None, Some(e)) => format!("failed: {e}"),
                (None, None) => "-".into(),
            };
            format!("{} {what}{}", s.method.name(), if s.chosen { " (chosen)" } else { "" })
        })
        .collect();
    let n = &r.noise;
    let mut out = vec![
        format!("closed-form starts (training chain RMS): {}", starts.join(", ")),
        format!(
            "noise: corner variance factor {:.4}, robot poses {:.4} mm / {:.5} deg ({}); s0 {:.4}; solver: {} after {} iterations, {} residual blocks down-weighted",
            n.corner_variance_factor,
            n.robot_sigma_m * 1e3,
            n.robot_sigma_rad.to_degrees(),
            if n.estimated { "estimated" } else { "as given" },
            r.s0,
            r.termination,
            r.iterations,
            r.n_downweighted
        ),
    ];
    out.extend(
        r.figures.views.iter().map(|v| {
            format!("  {} ({:?}): chain RMS {:.4} px over {} corners", v.name, v.split, v.rms_px, v.n_corners)
        }),
    );
    out
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
    crate::say!(
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
            "calibrate ({}): ferrocal handeye --images {}/images --poses {} --pattern {pattern} --mount {mount_name} --json <result.json>",
            if n_test == 0 {
                "no row marked test: handeye fits every image and scores the training images".to_string()
            } else {
                format!("handeye holds out the {n_test} rows marked test and scores them")
            },
            input.display(),
            out.display()
        ),
        Some(_) => "the set holds too few images for a hand-eye calibration: record more poses".into(),
    }
    });
    vs.conclude(&verdict)
}

/// The terminal line of the joint adjustment whose calibration is written to `out`.
pub fn joint_line(joint: &JointCalibration, out: &Path) -> String {
    let opt = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{x:.4}"));
    format!(
        "joint adjustment: {} robot parameters, chain RMS train {:.4} px, held-out {} px, s0 {:.3}; calibration written to {}",
        joint.free.len(),
        joint.figures.train_rms_px,
        opt(joint.figures.heldout_rms_px),
        joint.s0,
        out.display()
    )
}

/// Where `ferrocal handeye` writes (each file only when asked for).
#[derive(Clone, Copy, Debug, Default)]
pub struct HandeyeFiles<'a> {
    /// The JSON result.
    pub json: Option<&'a Path>,
    /// The HTML report.
    pub report: Option<&'a Path>,
    /// The joint adjustment's calibration file (the format `evaluate` reads).
    pub out: Option<&'a Path>,
    /// The fit's inputs: target points, and per image split, robot pose and corners
    /// ([`json::corners_json`]).
    pub corners: Option<&'a Path>,
}

impl HandeyeFiles<'_> {
    /// Every output asked for, in the order of the arguments (JSON, report, calibration,
    /// corners).
    pub fn all(&self) -> Vec<&Path> {
        [self.json, self.report, self.out, self.corners].into_iter().flatten().collect()
    }
}

/// The JSON of `ferrocal handeye study --json`: the settings and every mount's coverage.
pub fn study_json(simulations: usize, seed: u64, mode: StudyMode, rows: &[CoverageSummary]) -> Value {
    json!({"simulations": simulations, "seed": seed, "mode": mode, "mounts": rows})
}

/// The files of `ferrocal handeye` for the run `run` on `input`, composed (not written): the
/// JSON with every image left out and the verdict, the joint adjustment's calibration file of
/// the robot `run.robot`, the HTML report opening with the verdict.
pub fn handeye_outputs(
    run: &HandEyeRunOptions,
    input: &HandEyeInput,
    fit: &HandEyeFit,
    joint: Option<&JointCalibration>,
    verdict: &Verdict,
    files: &HandeyeFiles,
) -> Result<Outputs> {
    let (result, baselines, source) = (&fit.result, &fit.baselines, input.table.source.as_deref());
    let mut out = Outputs::default();
    if let (Some(p), Some(joint), Some(spec)) = (files.out, joint, &run.robot) {
        out.json(p, &joint.file(spec))?;
    }
    if let Some(p) = files.corners {
        out.json(p, &json::corners_json(&input.data, &run.pattern, result, source))?;
    }
    if let Some(h) = files.report {
        let (mount, pattern) = (run.mount.name(), &run.pattern);
        let settings = json!({"pattern": pattern, "mount": mount, "options": format!("{:?}", fit.options)});
        let mut prov = Provenance::new(settings);
        prov.add_input(&run.poses);
        let mut sections = html::handeye_sections(result, baselines, source);
        sections.insert(1.min(sections.len()), scene::cell_section(result, &input.data));
        if let Some(p) = &fit.physics {
            sections.insert(2.min(sections.len()), physics::physics_section(p, result));
        }
        out.html(h, Report::of(&format!("Hand-eye calibration ({mount}, {pattern})"), prov, sections), verdict);
    }
    if let Some(p) = files.json {
        let mut v = result_json(input, fit);
        crate::verdict::add_verdict(&mut v, verdict);
        out.json_first(p, &v)?;
    }
    Ok(out)
}

/// The JSON of one camera's hand-eye fit on `input` (without the verdict): the result, every
/// image left out and the motion check.
pub fn result_json(input: &HandEyeInput, fit: &HandEyeFit) -> Value {
    let (result, baselines, source) = (&fit.result, &fit.baselines, input.table.source.as_deref());
    let mut skipped: Vec<Value> = input
        .skipped_images
        .iter()
        .map(|s| json!({"image": s.image.display().to_string(), "reason": s.reason}))
        .collect();
    skipped.extend(input.skipped.iter().map(|s| json!({"image": s.what, "reason": s.reason})));
    skipped.extend(result.skipped.iter().map(|s| json!({"image": s.name, "reason": s.reason})));
    let mut v = json::handeye_json(result, baselines, Value::Array(skipped), source);
    if let Some(m) = &input.motion {
        v["motion_check"] = m.to_json();
    }
    if let Some(p) = &fit.physics {
        v["physics"] = serde_json::to_value(p).unwrap_or(Value::Null);
    }
    v
}

/// The verdict of `handeye study`: per mount, the runs, the failures and the 3-sigma coverage of
/// the translation and rotation errors.
pub fn study_verdict(t: &ferrocal_calib::verdict::Thresholds, rows: &[CoverageSummary]) -> Verdict {
    let figures: Vec<ferrocal_calib::verdict::commands::CoverageFigures> = rows
        .iter()
        .map(|r| ferrocal_calib::verdict::commands::CoverageFigures {
            mount: r.mount.name().to_string(),
            runs: r.n_runs,
            failed: r.n_failed,
            translation: r.translation_coverage_3sigma,
            rotation: r.rotation_coverage_3sigma,
        })
        .collect();
    ferrocal_calib::verdict::commands::handeye_study(t, &figures)
}
