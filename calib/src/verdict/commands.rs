//! The verdicts of the commands: which numbers each holds against which limit of
//! [`Thresholds`], and the next step in words (`docs/verdicts.md`). Here the measurement and
//! calibration commands (`camera calibrate`, `camera stereo`, `calibrate`, `evaluate`, `export`,
//! `diagnose`, `import`, `detect`, `corner-study`, `plan`, `doctor`); the model commands
//! (`robot ...`, `dynamics identify`, `stiffness identify`, `handeye study`, the simulators) in
//! [`models`].

use serde_json::Value;

use super::{fmt_num, CameraLimits, Check, Status, Thresholds, Verdict};
use crate::kinematic::{ErrorStats, KinematicCalibration};

pub mod models;
pub use models::*;

/// `calibrate`: the held-out figures of the validation fit (or a warning that there are none)
/// and what the data could not identify.
pub fn calibrate(
    t: &Thresholds,
    cal: &KinematicCalibration,
    validation: Option<(&KinematicCalibration, &ErrorStats, &ErrorStats)>,
    robot: &str,
    out: &std::path::Path,
) -> Verdict {
    let l = &t.calibrate;
    let mut checks = Vec::new();
    // The model's own changes first: a table of another robot (or in another unit) can fit well
    // with centimetre link corrections, and then every held-out figure passes.
    let (mm, deg) = cal.largest_model_changes();
    let mut changes = Vec::new();
    for (m, unit, key, warn, fail) in [
        (&mm, "mm", "calibrate.model_change_mm", l.model_change_mm_warn, l.model_change_mm_fail),
        (&deg, "deg", "calibrate.model_change_deg", l.model_change_deg_warn, l.model_change_deg_fail),
    ] {
        let Some(m) = m else { continue };
        let kind = if unit == "mm" { "length" } else { "angle" };
        checks.push(Check::at_most(
            key,
            &format!("largest change of a model {kind} ({} {:+.4} {unit})", m.name, m.change),
            unit,
            m.change.abs(),
            warn,
            fail,
        ));
        changes.push((key, format!("{} by {} {unit}", m.name, fmt_num(m.change))));
    }
    match validation {
        Some((v, before, after)) => {
            checks.push(Check::at_most(
                "calibrate.heldout_rms_mm",
                &format!("held-out RMS ({} poses)", after.n),
                "mm",
                after.rms_mm,
                l.heldout_rms_mm_warn,
                l.heldout_rms_mm_fail,
            ));
            checks.push(Check::at_most(
                "calibrate.heldout_vs_nominal",
                &format!(
                    "held-out RMS calibrated over nominal ({} / {} mm)",
                    fmt_num(after.rms_mm),
                    fmt_num(before.rms_mm)
                ),
                "",
                after.rms_mm / before.rms_mm,
                l.heldout_vs_nominal_warn,
                l.heldout_vs_nominal_fail,
            ));
            checks.push(Check::at_most(
                "calibrate.heldout_over_train",
                "held-out over training RMS",
                "",
                after.rms_mm / v.train_after.rms_mm,
                l.heldout_over_train_warn,
                l.heldout_over_train_fail,
            ));
        }
        None => checks.push(Check::flag(
            "calibrate.heldout",
            "no poses held out (nothing checked on unseen poses)",
            "poses held out",
            true,
        )),
    }
    checks.push(Check::at_most(
        "calibrate.unidentified",
        "joints the poses cannot identify",
        "",
        cal.advice.len() as f64,
        l.unidentified_warn,
        f64::INFINITY,
    ));
    let dropped: Vec<String> = cal
        .dropped_rows
        .iter()
        .map(|d| format!("'{}'{}", d.pose_id, d.line.map(|l| format!(" (line {l})")).unwrap_or_default()))
        .collect();
    checks.push(match &cal.outlier_note {
        // Too many rows beyond the residual test's threshold to be typos: the noise model, the
        // units or the model is off by far; not delivered as good (`--keep` keeps it).
        Some(note) => Check {
            name: "calibrate.rows_beyond".into(),
            value: 1.0,
            limit: 0.0,
            status: Status::Fail,
            what: format!("{note} (fail)"),
        },
        None => Check::flag(
            "calibrate.dropped_rows",
            &format!("{} row(s) far beyond the others dropped: {}", dropped.len(), dropped.join(", ")),
            "no row far beyond the others",
            !dropped.is_empty(),
        ),
    });
    let advice = cal.advice.first().cloned().unwrap_or_default();
    Verdict::with_next(checks, |c| {
        match c.map(|c| c.name.as_str()) {
        Some(n @ ("calibrate.model_change_mm" | "calibrate.model_change_deg")) => {
            let which = changes.iter().find(|(k, _)| *k == n).map(|(_, w)| w.as_str()).unwrap_or_default();
            format!(
                "the calibration changes {which}, more than a {robot} is ever off its model: wrong --robot? check that the table was recorded on a {robot} (and its units); do not use this calibration (--keep delivers it anyway)"
            )
        }
        Some("calibrate.rows_beyond") => format!(
            "check the table's units (the column headers), --robot and --sigma-mm, and run ferrocal diagnose --robot {robot} --measurements <the table> for what the model leaves out; --keep delivers this calibration anyway"
        ),
        Some("calibrate.dropped_rows") => format!(
            "check {} in the table for a typo (a wrong digit, swapped columns, another unit), correct or remove it, and calibrate again",
            dropped.join(", ")
        ),
        None => format!(
            "use the calibration: ferrocal evaluate --robot {robot} --calibration {} --measurements <a table of other poses>, or ferrocal export / correct",
            out.display()
        ),
        Some("calibrate.heldout") => {
            "re-run without --no-validation (or with a split column) so that poses the fit did not see check it".into()
        }
        Some("calibrate.unidentified") => format!("record more poses: {advice}"),
        Some("calibrate.heldout_vs_nominal") if c.is_some_and(|c| c.status == Status::Fail) => {
            "the calibration predicts unseen poses worse than the nominal model: check the table (units, joint order) and --robot, or identify fewer parameters (--params)".into()
        }
        Some("calibrate.heldout_vs_nominal") => "the calibration gains little on unseen poses: measure more poses spread over the workspace, or run ferrocal diagnose for the physics the model leaves out".into(),
        Some("calibrate.heldout_over_train") => "the fit does not carry over to unseen poses: identify fewer parameters (--params, --practical-threshold) or measure more poses".into(),
        _ => format!("find what the model leaves out: ferrocal diagnose --robot {robot} --measurements <the table>"),
    }
    })
}

/// `evaluate`: the position RMS of the scored rows.
pub fn evaluate(t: &Thresholds, stats: &ErrorStats, scored: &str) -> Verdict {
    let l = &t.evaluate;
    let checks = vec![Check::at_most(
        "evaluate.rms_mm",
        &format!("position RMS on {scored}"),
        "mm",
        stats.rms_mm,
        l.rms_mm_warn,
        l.rms_mm_fail,
    )];
    Verdict::with_next(checks, |c| {
        match c.map(|c| c.status) {
        None => "use the calibration: ferrocal export (URDF, DH) or ferrocal correct (a program's commands)".into(),
        Some(Status::Warning) => {
            "look at the largest per-pose errors in the JSON, then run ferrocal diagnose on the table for what the model leaves out".into()
        }
        Some(_) => "check that the table and the calibration share the measuring device's frame (else --refit-frame) and the robot; then run ferrocal diagnose on the table".into(),
    }
    })
}

/// `export`: how far the written model, read back, is from the calibrated one.
pub fn export(t: &Thresholds, roundtrip_mm: f64, roundtrip_deg: f64) -> Verdict {
    let l = &t.export;
    let checks = vec![
        Check::at_most(
            "export.roundtrip_mm",
            "read-back position difference",
            "mm",
            roundtrip_mm,
            l.roundtrip_mm_warn,
            l.roundtrip_mm_fail,
        ),
        Check::at_most(
            "export.roundtrip_deg",
            "read-back orientation difference",
            "deg",
            roundtrip_deg,
            l.roundtrip_deg_warn,
            l.roundtrip_deg_fail,
        ),
    ];
    Verdict::with_next(checks, |c| {
        match c {
        None => "load the exported model in the other tool and check one pose against ferrocal robot fk".into(),
        Some(_) => "the written model does not reproduce the calibration: use the calibration file with ferrocal directly and report this".into(),
    }
    })
}

/// `diagnose` (all variants), from the report's JSON: held-out ratio final over nominal,
/// structure left unexplained, candidates rejected, a declined analysis. `unit` is `mm`, `px`
/// or `n`.
pub fn diagnose(t: &Thresholds, report: &Value, unit: &str, rerun: &str) -> Verdict {
    let l = &t.diagnose;
    let num = |v: &Value| v.as_f64().unwrap_or(f64::NAN);
    let key = format!("heldout_rms_{unit}");
    let (nominal, fin) = (num(&report["nominal"][&key]), num(&report["final"][&key]));
    let mut checks = Vec::new();
    let declined = report["declined"].as_str().map(str::to_string);
    if declined.is_some() {
        checks.push(Check::flag("diagnose.declined", "the analysis declined (nothing claimed)", "analysed", true));
    } else {
        checks.push(Check::at_most(
            "diagnose.heldout_ratio",
            &format!("held-out RMS with the findings over without ({} / {} {unit})", fmt_num(fin), fmt_num(nominal)),
            "",
            fin / nominal,
            l.heldout_ratio_warn,
            l.heldout_ratio_fail,
        ));
    }
    let depends: Vec<String> = report["unexplained"]["depends_on"]
        .as_array()
        .map(|a| a.iter().filter_map(|v| v.as_str().map(str::to_string)).collect())
        .unwrap_or_default();
    let structure = report["unexplained"]["structure_found"].as_bool().unwrap_or(false);
    checks.push(Check::flag(
        "diagnose.unexplained_structure",
        &if depends.is_empty() {
            "structure left unexplained".to_string()
        } else {
            format!("structure left unexplained (against {})", depends.join(", "))
        },
        "no structure left unexplained",
        structure,
    ));
    // The last step's candidates (`steps[-1].candidates` of a robot, `candidates[-1]` of a
    // camera or force sensor), by their structured `status`.
    let last_step = report["steps"]
        .as_array()
        .and_then(|s| s.last())
        .map(|s| &s["candidates"])
        .or_else(|| report["candidates"].as_array().and_then(|s| s.last()));
    let rejected: Vec<String> = last_step
        .and_then(Value::as_array)
        .map(|cs| {
            cs.iter()
                .filter(|c| c["status"] == "rejected")
                .map(|c| {
                    let label = c["label"].as_str().or_else(|| c["candidate"].as_str()).unwrap_or("a candidate");
                    format!("{label}: {}", c["verdict"].as_str().unwrap_or("rejected"))
                })
                .collect()
        })
        .unwrap_or_default();
    checks.push(Check::at_most(
        "diagnose.rejected",
        "significant candidates rejected",
        "",
        rejected.len() as f64,
        l.rejected_warn,
        f64::INFINITY,
    ));
    let n_findings = report["findings"].as_array().map_or(0, Vec::len);
    let first_rejected = rejected.first().cloned().unwrap_or_default();
    // The robot report's top sentence (why nothing was claimed, when the residuals show strong
    // structure).
    let summary = report["summary"].as_str().unwrap_or_default().to_string();
    Verdict::with_next(checks, |c| {
        match c.map(|c| c.name.as_str()) {
        None if n_findings > 0 => format!("model the findings: {rerun}"),
        None => "the model explains the data: calibrate with it as it is".into(),
        Some("diagnose.declined") => format!("record more data: {}", declined.unwrap_or_default()),
        Some("diagnose.unexplained_structure") if n_findings == 0 && !summary.is_empty() => format!(
            "{summary} Read the candidate table, then record poses that vary {} over their whole range and diagnose again (docs/diagnose.md)",
            if depends.is_empty() { "the inputs".to_string() } else { depends.join(", ") }
        ),
        Some("diagnose.unexplained_structure") => format!(
            "the residuals still follow {}: record poses that vary {} over their whole range, the other inputs spread, and diagnose again (or add a candidate effect, docs/diagnose.md)",
            if depends.is_empty() { "the inputs".to_string() } else { depends.join(", ") },
            if depends.len() == 1 { "it" } else { "them" }
        ),
        Some("diagnose.rejected") => format!("look at the rejected candidate before trusting the findings: {first_rejected}"),
        _ => "the findings do not improve held-out data: do not model them; record more data".into(),
    }
    })
}

/// What `calibrate` will hold out of a table of `rows` rows, `test_rows` of them marked `test`
/// (`has_split`: the table has a `split` column), in the words of [`crate::kinematic::split_rows`]:
/// the rows marked `test`; none when the column marks none; every second row without the column.
pub fn held_out_words(rows: usize, test_rows: usize, has_split: bool) -> String {
    match (has_split, test_rows) {
        (true, 0) => "its split column marks no row test: calibrate holds none out".into(),
        (true, n) => format!("calibrate holds out the {n} rows marked test"),
        (false, _) => format!("no split column: calibrate holds out every second row, {} of {rows}", rows / 2),
    }
}

/// `import`: the rows written; `test_rows` of them marked `test`, `has_split` when the table
/// has a `split` column (the next step says what `calibrate` will hold out).
pub fn import(t: &Thresholds, rows: usize, test_rows: usize, has_split: bool, out: &std::path::Path) -> Verdict {
    let l = &t.import;
    let checks = vec![Check::at_least("import.rows", "rows written", "", rows as f64, l.rows_warn, l.rows_fail)];
    Verdict::with_next(checks, |c| match c {
        None => format!(
            "calibrate from the table ({}): ferrocal calibrate --robot <model> --measurements {} --out <cal.json>",
            held_out_words(rows, test_rows, has_split),
            out.display()
        ),
        Some(_) => "the recording holds too few rows for a calibration: record more poses".into(),
    })
}

/// The next step of a camera verdict: when every check passes, when too few views (or pairs)
/// were used, when the third figure (held-out ratio, rectified rows) is the problem, and else.
struct CameraNext {
    ok: &'static str,
    views: &'static str,
    third: &'static str,
    other: &'static str,
}

/// A camera verdict: the fit's reprojection RMS, the views (or pairs) used and, when there is
/// one, a third figure (`third`, named `third_name`), with the next step of `next`.
fn camera_fit(rms: Check, views: Check, third: Option<Check>, third_name: &str, next: CameraNext) -> Verdict {
    let mut checks = vec![rms, views];
    checks.extend(third);
    Verdict::with_next(checks, |c| {
        match c.map(|c| c.name.as_str()) {
            None => next.ok,
            Some("camera.views") => next.views,
            Some(n) if n == third_name => next.third,
            _ => next.other,
        }
        .to_string()
    })
}

/// `camera calibrate`: fit RMS, views used, held-out over fit RMS.
pub fn camera(l: &CameraLimits, rms_px: f64, views: usize, heldout_px: Option<f64>) -> Verdict {
    let third = "camera.heldout_ratio";
    camera_fit(
        Check::at_most("camera.rms_px", "reprojection RMS", "px", rms_px, l.rms_px_warn, l.rms_px_fail),
        Check::at_least("camera.views", "views used", "", views as f64, l.views_warn, l.views_fail),
        heldout_px.map(|h| {
            Check::at_most(third, "held-out over fit RMS", "", h / rms_px, l.heldout_ratio_warn, l.heldout_ratio_fail)
        }),
        third,
        CameraNext {
            ok: "use the camera model (the JSON, or --opencv-yaml / --ros-yaml), e.g. as --intrinsics of ferrocal handeye",
            views: "record more views (10 or more), with the pattern tilted and covering the whole image, and calibrate again",
            third: "the model does not predict views it did not see: record more views reaching the image corners, or try --model rational8",
            other: "look at the per-view RMS (the JSON's per_view, or --report) and retake or drop the worst views; try --reject-outliers",
        },
    )
}

/// `camera stereo`: the lists first (the right camera's side of the left one: swapped lists;
/// pairs that disagree on the cameras' relative pose: shifted lists), then the pair's RMS, the
/// pairs used, the rectified row difference.
pub fn stereo(t: &Thresholds, rms_px: f64, pairs: usize, row_rms_px: Option<f64>, pairing: &StereoPairing) -> Verdict {
    let (l, c) = (&t.stereo, &t.camera);
    let third = "stereo.row_rms_px";
    let mut v = camera_fit(
        Check::at_most("stereo.rms_px", "reprojection RMS", "px", rms_px, l.rms_px_warn, l.rms_px_fail),
        Check::at_least("camera.views", "pairs used", "", pairs as f64, c.views_warn, c.views_fail),
        row_rms_px.map(|r| {
            Check::at_most(third, "rectified row difference RMS", "px", r, l.row_rms_px_warn, l.row_rms_px_fail)
        }),
        third,
        CameraNext {
            ok: "use the pair (--opencv-stereo-yaml or --left-ros-yaml / --right-ros-yaml for rectification)",
            views: "record more pairs (10 or more) with the pattern seen by both cameras across the image",
            third: "the pair does not rectify well: check that the images are synchronous and the rig rigid, then calibrate again",
            other: "look at the per-view RMS of both cameras in the JSON and retake or drop the worst pairs",
        },
    );
    // The lists themselves, first: swapped lists fit as well as right ones, with a negative
    // baseline; pairs that disagree on the rig are not simultaneous.
    let c_right = pairing.right_in_left_mm;
    let baseline = c_right.norm();
    let leftward = if baseline > 0.0 { -c_right.x / baseline } else { 0.0 };
    let mut swap = Check::at_most(
        "stereo.baseline_leftward",
        &format!("right camera's leftward share of the {} mm baseline", fmt_num(baseline)),
        "",
        leftward,
        l.baseline_leftward_warn,
        l.baseline_leftward_fail,
    );
    if swap.status != Status::Pass {
        swap.what = format!(
            "{}: the right camera sits {} mm to the left of the left camera, so the --left and --right images look swapped",
            swap.what,
            fmt_num(-c_right.x)
        );
    }
    let mut disagree = Check::at_most(
        "stereo.pairs_disagree_fraction",
        &format!(
            "pairs disagreeing on the cameras' relative pose ({} of {})",
            pairing.disagreeing.len(),
            pairing.n_pairs
        ),
        "",
        if pairing.n_pairs == 0 { 0.0 } else { pairing.disagreeing.len() as f64 / pairing.n_pairs as f64 },
        l.pairs_disagree_fraction_warn,
        l.pairs_disagree_fraction_fail,
    );
    if disagree.status != Status::Pass {
        disagree.what = format!("{}: {}", disagree.what, pairing.disagreeing.join(", "));
    }
    let disagreeing = pairing.disagreeing.join(", ");
    v.checks.insert(0, disagree);
    v.checks.insert(0, swap);
    v.status = super::worst(&v.checks);
    match super::first_problem(&v.checks).map(|c| c.name.as_str()) {
        Some("stereo.baseline_leftward") => {
            v.next = "give the left camera's images to --left and the right camera's to --right (the lists look swapped), then calibrate again".into();
        }
        Some("stereo.pairs_disagree_fraction") => {
            v.next = format!(
                "check that left and right image k show the same board pose (the pairs of {disagreeing} disagree with the others; a missing or extra image shifts the lists), drop them and calibrate again"
            );
        }
        _ => {}
    }
    v
}

/// What `camera stereo` knows of its lists before the verdict: where the right camera sits in
/// the left camera's frame, and the pairs that disagree on the cameras' relative pose
/// (`ferrocal_vision::calib::check_pairing`).
#[derive(Clone, Debug, Default)]
pub struct StereoPairing {
    /// The right camera's position in the left camera's frame, mm (`-R^T T` of OpenCV's R, T).
    pub right_in_left_mm: nalgebra::Vector3<f64>,
    /// Pairs compared.
    pub n_pairs: usize,
    /// The images (file names) of the pairs that disagree.
    pub disagreeing: Vec<String>,
}

/// `detect`: the fraction of the `n` images in which the pattern was found (`failed` were not).
pub fn detect(t: &Thresholds, n: usize, failed: usize) -> Verdict {
    let l = &t.detect;
    let found = (n - failed) as f64 / n as f64;
    let checks = vec![Check::at_least(
        "detect.found_fraction",
        &format!("pattern found in {} of {} images, fraction", n - failed, n),
        "",
        found,
        l.found_fraction_warn,
        l.found_fraction_fail,
    )];
    Verdict::with_next(checks, |c| {
        match c {
            None => "calibrate with these images: ferrocal camera calibrate --images ... --pattern ...",
            Some(_) => "read the failed images' reasons above (and in the JSON's error fields): check the --pattern string (inner corners for a chessboard), focus and lighting, or leave those images out",
        }
        .to_string()
    })
}

/// `corner-study`: the worst ratio of the corner RMS error to the Cramer-Rao bound (`ratio`),
/// a warning only; `table` is the study's Markdown table.
pub fn corner_study(t: &Thresholds, ratio: f64, table: &std::path::Path) -> Verdict {
    let checks = vec![Check::at_most(
        "study.corner_over_crb",
        "largest corner RMS error over the Cramer-Rao bound",
        "",
        ratio,
        t.study.corner_over_crb_warn,
        f64::INFINITY,
    )];
    Verdict::with_next(checks, |c| {
        match c {
        None => format!("read the table: {}", table.display()),
        Some(_) => "look at the rows far above the bound in corner_study.md (blur and noise levels) before trusting corners there".into(),
    }
    })
}

/// `plan`: the plan's own checks (selection, sigma ratio, predicted accuracy, path; `passed`)
/// decide; another failed section of its report (`failed`, by name; the Monte Carlo check of
/// the prediction on few runs) is a warning. `html` is the report.
pub fn plan(t: &Thresholds, passed: bool, failed: &[String], html: &str) -> Verdict {
    let l = &t.plan;
    let design_failed = if passed { 0.0 } else { failed.len().max(1) as f64 };
    let others = if failed.is_empty() {
        "report sections failed".to_string()
    } else {
        format!("report sections failed ({})", failed.join(", "))
    };
    let checks = vec![
        Check::at_most(
            "plan.failed_checks",
            "the plan's checks failed",
            "",
            design_failed,
            l.failed_checks_fail,
            l.failed_checks_fail,
        ),
        Check::at_most(
            "plan.other_checks",
            &others,
            "",
            if passed { failed.len() as f64 } else { 0.0 },
            0.0,
            f64::INFINITY,
        ),
    ];
    Verdict::with_next(checks, |c| {
        match c.map(|c| c.name.as_str()) {
        None => format!("measure the poses: {} (poses.csv and the programs beside it)", html),
        Some("plan.other_checks") => format!("the plan passed, but read the failed section of {html}; more simulations (--simulations) settle a Monte Carlo check"),
        _ => format!("read the failed checks of {html}: widen the workspace, add poses (--wanted) or change the criterion"),
    }
    })
}

/// `doctor`: every external library answers (`libraries`: each one's name and whether it did).
pub fn doctor(libraries: &[(&str, bool)]) -> Verdict {
    let checks = libraries
        .iter()
        .map(|(name, ok)| {
            let label = format!("{name} answers (1 yes, 0 no)");
            Check::at_least(&format!("doctor.{name}"), &label, "", f64::from(u8::from(*ok)), 1.0, 1.0)
        })
        .collect();
    Verdict::with_next(checks, |c| {
        match c {
        None => "every library answers: run ferrocal demo".into(),
        Some(c) => format!(
            "{} does not answer: run scripts/setup.sh (it installs the system libraries) and rebuild, or read its line above",
            c.name.trim_start_matches("doctor.")
        ),
    }
    })
}
