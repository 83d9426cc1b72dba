//! The verdicts of the commands (`camera calibrate`, `camera stereo`, `calibrate`, `evaluate`,
//! `export`, `diagnose`, `import`, `detect`, `corner-study`, `plan`, `doctor`, `robot ...`,
//! `dynamics identify`, `stiffness identify`, `handeye study`, the simulators): which numbers
//! each holds against which limit of [`Thresholds`], and the next step in words
//! (`docs/verdicts.md`).

use serde_json::Value;

use super::{fmt_num, CameraLimits, Check, Status, Thresholds, Verdict};
use crate::kinematic::{ErrorStats, KinematicCalibration};

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
    checks.push(Check::flag(
        "calibrate.dropped_rows",
        &format!("{} row(s) far beyond the others dropped: {}", dropped.len(), dropped.join(", ")),
        "no row far beyond the others",
        !dropped.is_empty(),
    ));
    let advice = cal.advice.first().cloned().unwrap_or_default();
    Verdict::with_next(checks, |c| {
        match c.map(|c| c.name.as_str()) {
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

/// `import`: the rows written.
pub fn import(t: &Thresholds, rows: usize, test_rows: usize, out: &std::path::Path) -> Verdict {
    let l = &t.import;
    let checks = vec![Check::at_least("import.rows", "rows written", "", rows as f64, l.rows_warn, l.rows_fail)];
    Verdict::with_next(checks, |c| {
        match c {
        None => format!(
            "calibrate from the table ({test_rows} rows marked test are held out): ferrocal calibrate --robot <model> --measurements {} --out <cal.json>",
            out.display()
        ),
        Some(_) => "the recording holds too few rows for a calibration: record more poses".into(),
    }
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

/// `camera stereo`: the pair's RMS, the pairs used, the rectified row difference.
pub fn stereo(t: &Thresholds, rms_px: f64, pairs: usize, row_rms_px: Option<f64>) -> Verdict {
    let (l, c) = (&t.stereo, &t.camera);
    let third = "stereo.row_rms_px";
    camera_fit(
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
    )
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

/// `robot info`: the model loaded with its joints and parameters; a warning names the joints
/// without limits (`unlimited`), which `robot fk`, `plan` and the safety checks cannot hold to
/// a range.
pub fn robot_info(joints: usize, parameters: usize, unlimited: &[String]) -> Verdict {
    let checks = vec![
        Check::at_least(
            "robot.joints",
            &format!("model loaded ({parameters} parameters), joints"),
            "",
            joints as f64,
            1.0,
            1.0,
        ),
        Check::flag(
            "robot.unlimited_joints",
            &format!("joints without limits: {}", unlimited.join(", ")),
            "every joint has limits",
            !unlimited.is_empty(),
        ),
    ];
    Verdict::with_next(checks, |c| {
        match c {
        None => "use the model: ferrocal robot fk / ik, or --robot of calibrate and plan".into(),
        Some(_) => "give the joints their travel (URDF <limit lower upper>, or the model file's limits) if the robot has one; a joint that turns endlessly may stay as it is".into(),
    }
    })
}

/// `robot fk`: how close the joints are to their limits. `margins` holds, for every joint with
/// finite limits, its name and its distance from the nearer limit as a fraction of its range
/// (joints outside their limits are refused before).
pub fn robot_fk(t: &Thresholds, joints: usize, margins: &[(String, f64)]) -> Verdict {
    let mut checks = vec![Check::flag(
        "robot.unlimited_joints",
        &format!("{} of {joints} joints without limits (not checked)", joints - margins.len()),
        &format!("{joints} joints within their limits"),
        margins.len() < joints,
    )];
    if let Some((name, m)) = margins.iter().min_by(|a, b| a.1.total_cmp(&b.1)) {
        checks.push(Check::at_least(
            "robot.limit_margin",
            &format!("smallest distance from a limit ({name}), fraction of its range"),
            "",
            *m,
            t.robot.limit_margin_warn,
            f64::NEG_INFINITY,
        ));
    }
    Verdict::with_next(checks, |c| {
        match c.map(|c| c.name.as_str()) {
        None => "use the pose; ferrocal robot ik --pose <x,y,z,rx,ry,rz> goes back to joint values".into(),
        Some("robot.limit_margin") => "the configuration is at the end of a joint's travel: the controller's soft limits may stop it there; choose joint values further inside".into(),
        _ => "the joints without limits were not checked: give them limits in the model if the robot has them (ferrocal robot info lists them)".into(),
    }
    })
}

/// The outcome of `robot ik`.
#[derive(Clone, Debug, PartialEq)]
pub enum IkOutcome {
    /// A solution, with the distance (mm) and angle (deg) of its tool pose from the target.
    Solved {
        /// Position residual, mm.
        position_mm: f64,
        /// Orientation residual, degrees.
        orientation_deg: f64,
    },
    /// No solution: why, in words (did not converge, unreachable, outside the joint limits).
    NoSolution(String),
}

/// `robot ik`: a solution whose tool pose is at the target within the limits; no solution fails.
pub fn robot_ik(t: &Thresholds, outcome: &IkOutcome) -> Verdict {
    let l = &t.robot;
    let checks = match outcome {
        IkOutcome::Solved { position_mm, orientation_deg } => vec![
            Check::at_most(
                "robot.ik_position_mm",
                "solution's tool position from the target",
                "mm",
                *position_mm,
                l.ik_position_mm_fail,
                l.ik_position_mm_fail,
            ),
            Check::at_most(
                "robot.ik_orientation_deg",
                "solution's tool orientation from the target",
                "deg",
                *orientation_deg,
                l.ik_orientation_deg_fail,
                l.ik_orientation_deg_fail,
            ),
        ],
        IkOutcome::NoSolution(why) => vec![Check {
            name: "robot.ik_solution".into(),
            value: 0.0,
            limit: 1.0,
            status: Status::Fail,
            what: format!("no solution: {why} (fail)"),
        }],
    };
    Verdict::with_next(checks, |c| {
        match c {
        None => "check the joint values with ferrocal robot check --safety <file> --joints <them> before moving there".into(),
        Some(_) => "check that the pose is within the robot's reach (mm, rotation vector in degrees), or give another start with --seed (another configuration)".into(),
    }
    })
}

/// `robot check`: the safety result itself; `violations` counts the unsafe findings (joint
/// values and the move). The limit is the safety file's, not a threshold.
pub fn robot_check(violations: usize) -> Verdict {
    let checks = vec![Check::at_most(
        "robot.safety_violations",
        "safety violations (the safety file's limits)",
        "",
        violations as f64,
        0.0,
        0.0,
    )];
    Verdict::with_next(checks, |c| {
        match c {
        None => "the joint values (and the move) are safe under this configuration: send them to the robot".into(),
        Some(_) => "do not send these joint values: read the unsafe lines above and choose others (or a move through another path)".into(),
    }
    })
}

/// The figures of a linear identification (`dynamics identify`, `identify-static`) that its
/// verdict holds against the limits.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearFitFigures {
    /// Parameters the data do not determine (infinite standard deviation or dropped), by name.
    pub undetermined: Vec<String>,
    /// Condition number of the weighted, column-scaled regressor.
    pub condition_number: f64,
    /// Relative standard deviation of the mass, when the model has one.
    pub mass_relative_std: Option<f64>,
    /// The a-posteriori variance factor when the weights are the measured noise (else `None`:
    /// with unit weights s0 is the residual RMS in newtons, which has no limit).
    pub s0_weighted: Option<f64>,
}

impl LinearFitFigures {
    /// The figures of `fit`; `weighted` when its weights are the noise measured from repeated
    /// periods.
    pub fn of(fit: &ferrocal_lsq::linear::LinearFit, weighted: bool) -> Self {
        let undetermined = (0..fit.names.len())
            .filter(|&i| !fit.std[i].is_finite() || fit.dropped.contains(&i))
            .map(|i| fit.names[i].clone())
            .collect();
        let mass_relative_std = fit.get("m_kg").map(|(v, s)| s / v.abs());
        Self {
            undetermined,
            condition_number: fit.condition_number,
            mass_relative_std,
            s0_weighted: weighted.then_some(fit.s0),
        }
    }
}

/// `dynamics identify` and `identify-static`: every parameter determined, the regressor's
/// conditioning, the mass's precision and, with measured noise, the fit against that noise.
pub fn dynamics_identify(t: &Thresholds, f: &LinearFitFigures) -> Verdict {
    let l = &t.dynamics;
    let mut checks = vec![
        Check::at_most(
            "dynamics.undetermined",
            &if f.undetermined.is_empty() {
                "parameters not determined".to_string()
            } else {
                format!("parameters not determined ({})", f.undetermined.join(", "))
            },
            "",
            f.undetermined.len() as f64,
            l.undetermined_warn,
            f64::INFINITY,
        ),
        Check::at_most(
            "dynamics.condition_number",
            "condition number",
            "",
            f.condition_number,
            l.condition_number_warn,
            f64::INFINITY,
        ),
    ];
    if let Some(r) = f.mass_relative_std {
        checks.push(Check::at_most(
            "dynamics.mass_relative_std",
            "mass relative std",
            "",
            r,
            l.mass_relative_std_warn,
            f64::INFINITY,
        ));
    }
    if let Some(s0) = f.s0_weighted {
        checks.push(Check::at_most("dynamics.s0", "s0 against the measured noise", "", s0, l.s0_warn, f64::INFINITY));
    }
    Verdict::with_next(checks, |c| {
        match c.map(|c| c.name.as_str()) {
        None => "use the parameters (the JSON with --json); identify a second recording to confirm them".into(),
        Some("dynamics.s0") => "the residuals exceed the measured noise: try the next model up (--model), or look for effects the model leaves out (cross-talk, friction)".into(),
        _ => "the recording excites the parameters poorly: record a richer excitation (ferrocal dynamics study designs one) or more poses spread over the workspace, or identify a smaller model".into(),
    }
    })
}

/// `stiffness identify`: a physical estimate (`physical_problems` empty; else a failure, exit
/// status 2), and the fit's s0 against the table's stated noise.
pub fn stiffness_identify(t: &Thresholds, physical_problems: &[String], s0: f64, kept: usize) -> Verdict {
    let checks = vec![
        Check::at_most(
            "stiffness.physical_problems",
            &if physical_problems.is_empty() {
                format!("{kept} parameters kept; estimates no spring can have")
            } else {
                format!("estimates no spring can have ({})", physical_problems.join("; "))
            },
            "",
            physical_problems.len() as f64,
            0.0,
            0.0,
        ),
        Check::at_most("stiffness.s0", "s0 against the table's sigma", "", s0, t.stiffness.s0_warn, f64::INFINITY),
    ];
    Verdict::with_next(checks, |c| {
        match c.map(|c| c.name.as_str()) {
        None => "use the parameters (parameters.json with --out) for compensation".into(),
        Some("stiffness.s0") => "the deflections scatter more than the table's sigma_mm says: check the stated noise and the measurement, or look for effects the model leaves out".into(),
        _ => "use only the trusted parameters (stderr lists them); measure more configurations with loads in more directions and identify again".into(),
    }
    })
}

/// `stiffness identify` when the loads leave parameters unexcited: no estimate at all.
pub fn stiffness_unexcited(why: &str) -> Verdict {
    let checks = vec![Check {
        name: "stiffness.unexcited".into(),
        value: 1.0,
        limit: 0.0,
        status: Status::Fail,
        what: format!("no estimate: {why} (fail)"),
    }];
    Verdict::new(
        checks,
        "measure configurations and loads that move every joint and load every link, then identify again",
    )
}

/// One mount's figures of `handeye study`.
#[derive(Clone, Debug, PartialEq)]
pub struct CoverageFigures {
    /// The mount's name.
    pub mount: String,
    /// Simulations that gave an estimate.
    pub runs: usize,
    /// Simulations whose calibration failed.
    pub failed: usize,
    /// 3-sigma coverage of the translation coordinates (fraction).
    pub translation: f64,
    /// 3-sigma coverage of the rotation coordinates.
    pub rotation: f64,
}

/// `handeye study`: the smallest 3-sigma coverage over the mounts and coordinates, and the
/// simulations that failed.
pub fn handeye_study(t: &Thresholds, rows: &[CoverageFigures]) -> Verdict {
    let l = &t.study;
    let mut worst = (f64::INFINITY, String::new());
    for r in rows {
        for (v, what) in [(r.translation, "translation"), (r.rotation, "rotation")] {
            if v < worst.0 || !v.is_finite() {
                worst = (v, format!("{} {what}", r.mount));
            }
        }
    }
    let runs: usize = rows.iter().map(|r| r.runs).sum();
    let failed: usize = rows.iter().map(|r| r.failed).sum();
    let checks = vec![
        Check::at_least(
            "study.coverage_3sigma",
            &format!("smallest 3-sigma coverage ({}, {runs} runs)", worst.1),
            "",
            if runs == 0 { f64::NAN } else { worst.0 },
            l.coverage_3sigma_warn,
            l.coverage_3sigma_fail,
        ),
        Check::at_most(
            "study.failed_runs",
            "simulations that failed",
            "",
            failed as f64,
            l.failed_runs_warn,
            f64::INFINITY,
        ),
    ];
    Verdict::with_next(checks, |c| {
        match c.map(|c| c.name.as_str()) {
        None => "the stated standard deviations can be trusted: use them with ferrocal handeye's results".into(),
        Some("study.failed_runs") => "read why the simulations failed (stderr), then run the study again".into(),
        _ => "the stated standard deviations are too small: run more simulations (--simulations) to confirm, then treat handeye's std with caution".into(),
    }
    })
}

/// The simulators (`simulate`, `dynamics simulate`, `stiffness simulate`, `handeye simulate`):
/// what was written, counted (`section` names the checks, `<section>.<what>`); a count of 0 fails.
pub fn simulated(section: &str, counts: &[(&str, usize)], next: &str) -> Verdict {
    let checks = counts
        .iter()
        .map(|(what, n)| {
            let key = what.split_whitespace().last().unwrap_or(what);
            Check::at_least(&format!("{section}.{key}"), &format!("{what} written"), "", *n as f64, 1.0, 1.0)
        })
        .collect();
    Verdict::with_next(checks, |c| match c {
        None => next.to_string(),
        Some(_) => "nothing was simulated: check the sizes given (counts, periods, poses)".into(),
    })
}
