use std::path::Path;

use super::*;

fn line_matches_spec(line: &str) -> bool {
    // ^verdict: (pass|warning|fail): .+; next: .+$ without a regex crate.
    let Some(rest) = line.strip_prefix("verdict: ") else { return false };
    let Some((status, rest)) = rest.split_once(": ") else { return false };
    let Some((what, next)) = rest.rsplit_once("; next: ") else { return false };
    ["pass", "warning", "fail"].contains(&status) && !what.is_empty() && !next.is_empty() && !line.contains('\n')
}

#[test]
fn the_line_has_the_spec_format() {
    let v = Verdict::new(
        vec![
            Check::at_most("camera.rms_px", "reprojection RMS", "px", 0.178, 0.5, 2.0),
            Check::at_least("camera.views", "views", "", 13.0, 10.0, 3.0),
        ],
        "use the calibration",
    );
    assert_eq!(v.status, Status::Pass);
    assert_eq!(
        v.line(),
        "verdict: pass: reprojection RMS 0.178 px <= 0.5 px, views 13 >= 10; next: use the calibration"
    );
    assert!(line_matches_spec(&v.line()));
    // Line breaks in the words never break the line.
    let v = Verdict::new(vec![Check::flag("x.y", "a\nb", "no a", true)], "c\nd");
    assert_eq!(v.line(), "verdict: warning: a b (warning); next: c d");
    assert_eq!(Check::flag("x.y", "a", "no a", false).what, "no a");
    assert!(line_matches_spec(&v.line()));
    // Without checks.
    assert_eq!(Verdict::new(Vec::new(), "").line(), "verdict: pass: nothing to check; next: none");
}

#[test]
fn the_status_is_the_worst_of_the_checks() {
    let pass = Check::at_most("a", "a", "mm", 0.1, 1.0, 2.0);
    let warn = Check::at_most("b", "b", "mm", 1.5, 1.0, 2.0);
    let fail = Check::at_least("c", "c", "", 0.2, 1.0, 0.5);
    assert_eq!((pass.status, warn.status, fail.status), (Status::Pass, Status::Warning, Status::Fail));
    assert_eq!(fail.limit, 0.5);
    assert_eq!(warn.limit, 1.0);
    assert_eq!(worst(&[pass.clone(), warn.clone()]), Status::Warning);
    assert_eq!(worst(&[warn.clone(), fail.clone(), pass.clone()]), Status::Fail);
    assert_eq!(worst(&[]), Status::Pass);
    let v = Verdict::with_next(vec![pass.clone(), warn.clone(), fail.clone()], |c| {
        format!("fix {}", c.map_or("nothing", |c| c.name.as_str()))
    });
    assert!(v.failed());
    assert_eq!(v.next, "fix c");
    assert!(v.line().starts_with("verdict: fail: a 0.1 mm <= 1 mm, b 1.5 mm > 1 mm (warning), c 0.2 < 0.5 (fail)"));
    // A value that could not be computed is a warning, never a pass.
    assert_eq!(Check::at_most("d", "d", "px", f64::NAN, 1.0, 2.0).status, Status::Warning);
    // The JSON object of the spec.
    let j = v.to_json();
    assert_eq!(j["status"], "fail");
    assert_eq!(j["checks"][1]["status"], "warning");
    for k in ["name", "value", "limit", "status"] {
        assert!(j["checks"][0].get(k).is_some(), "{k}");
    }
    assert_eq!(j["next"], "fix c");
}

#[test]
fn numbers_are_short() {
    assert_eq!(fmt_num(0.38141), "0.3814");
    assert_eq!(fmt_num(2.0), "2");
    assert_eq!(fmt_num(1424.4), "1424");
    assert_eq!(fmt_num(1e-7), "1.00e-7");
    assert_eq!(fmt_num(-0.5), "-0.5");
}

#[test]
fn a_file_overrides_only_its_keys() {
    let t = Thresholds::from_toml(
        "[camera]\nrms_px_warn = 0.3\nviews_warn = 5\n\n[evaluate]\nrms_mm_fail = 1\n",
        Path::new("t.toml"),
    )
    .unwrap();
    assert_eq!(t.camera.rms_px_warn, 0.3);
    assert_eq!(t.camera.views_warn, 5.0);
    assert_eq!(t.camera.rms_px_fail, CameraLimits::default().rms_px_fail);
    assert_eq!(t.evaluate.rms_mm_fail, 1.0);
    assert_eq!(t.evaluate.rms_mm_warn, 1.0);
    assert_eq!(t.handeye, HandeyeLimits::default());
    assert_eq!(Thresholds::from_toml("", Path::new("e.toml")).unwrap(), Thresholds::default());
    // Every default is listed under its dotted name.
    let list = Thresholds::defaults_list();
    assert!(list.iter().any(|(k, v)| k == "camera.rms_px_warn" && *v == 0.5), "{list:?}");
}

#[test]
fn unknown_keys_and_bad_values_are_refused_by_name() {
    let e = Thresholds::from_toml("[camera]\nrms_px_warm = 0.3\n", Path::new("limits.toml")).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, ThresholdsError::UnknownKey { ref key, .. } if key == "camera.rms_px_warm"), "{msg}");
    assert!(msg.contains("limits.toml") && msg.contains("camera.rms_px_warm") && msg.contains("rms_px_warn"), "{msg}");
    let e = Thresholds::from_toml("[cameras]\nrms_px_warn = 0.3\n", Path::new("limits.toml")).unwrap_err();
    assert!(e.to_string().contains("'cameras'"), "{e}");
    let e = Thresholds::from_toml("[camera]\nrms_px_warn = \"low\"\n", Path::new("limits.toml")).unwrap_err();
    assert!(e.to_string().contains("camera.rms_px_warn") && e.to_string().contains("number"), "{e}");
    let e = Thresholds::from_toml("[camera\n", Path::new("limits.toml")).unwrap_err();
    assert!(matches!(e, ThresholdsError::Parse { .. }) && e.to_string().starts_with("limits.toml: "), "{e}");
}

#[test]
fn diagnose_counts_rejected_candidates_by_their_status_in_every_family() {
    let t = Thresholds::default();
    let robot = serde_json::json!({
        "nominal": {"heldout_rms_mm": 1.0}, "final": {"heldout_rms_mm": 0.5},
        "unexplained": {"structure_found": false, "depends_on": []},
        "findings": [{"effect": "joint_compliance"}],
        // A note that merely mentions the word is not a rejection.
        "notes": ["x: rejected by nobody, a remark"],
        "steps": [
            {"candidates": [{"label": "old", "status": "rejected", "verdict": "rejected: earlier step"}]},
            {"candidates": [
                {"label": "backlash[3]", "status": "rejected", "verdict": "rejected as unstable across the folds: why"},
                {"label": "scale[2]", "status": "not_significant", "verdict": "not significant"}
            ]}
        ]
    });
    let v = commands::diagnose(&t, &robot, "mm", "rerun");
    let c = v.checks.iter().find(|c| c.name == "diagnose.rejected").unwrap();
    assert_eq!(c.value, 1.0, "only the last step's rejected candidate counts");
    assert_eq!(v.status, Status::Warning);
    assert!(v.next.contains("backlash[3]: rejected as unstable"), "{}", v.next);
    // A camera's report: `candidates` per step, labelled `candidate`.
    let camera = serde_json::json!({
        "nominal": {"heldout_rms_px": 0.3}, "final": {"heldout_rms_px": 0.2},
        "unexplained": {"structure_found": false}, "findings": [],
        "candidates": [[{"candidate": "lens_distortion", "status": "accepted", "verdict": "accepted"}],
                       [{"candidate": "target_nonflatness", "status": "not_significant", "verdict": "not significant"}]]
    });
    let v = commands::diagnose(&t, &camera, "px", "rerun");
    assert_eq!(v.checks.iter().find(|c| c.name == "diagnose.rejected").unwrap().value, 0.0);
    assert_eq!(v.status, Status::Pass);
}

#[test]
fn robot_verdicts_follow_their_limits() {
    let t = Thresholds::default();
    assert_eq!(commands::robot_info(6, 72, &[]).status, Status::Pass);
    let v = commands::robot_info(6, 72, &["wrist_3".to_string()]);
    assert_eq!(v.status, Status::Warning);
    assert!(v.line().contains("joints without limits: wrist_3"), "{}", v.line());
    // The smallest margin decides; joints without limits are a warning of their own.
    let v = commands::robot_fk(&t, 2, &[("a".into(), 0.3), ("b".into(), 0.004)]);
    assert_eq!(v.status, Status::Warning);
    assert!(v.line().contains("(b)"), "{}", v.line());
    assert_eq!(commands::robot_fk(&t, 2, &[("a".into(), 0.3), ("b".into(), 0.2)]).status, Status::Pass);
    assert_eq!(commands::robot_fk(&t, 2, &[("a".into(), 0.3)]).status, Status::Warning);
    let solved = |mm| commands::IkOutcome::Solved { position_mm: mm, orientation_deg: 1e-9 };
    assert_eq!(commands::robot_ik(&t, &solved(1e-8)).status, Status::Pass);
    assert_eq!(commands::robot_ik(&t, &solved(0.01)).status, Status::Fail);
    let v = commands::robot_ik(&t, &commands::IkOutcome::NoSolution("did not converge".into()));
    assert!(v.failed() && v.line().contains("no solution: did not converge"), "{}", v.line());
    assert_eq!(commands::robot_check(0).status, Status::Pass);
    assert!(commands::robot_check(2).failed());
}

#[test]
fn identification_verdicts_warn_on_poor_excitation_and_fail_on_unphysical_estimates() {
    let t = Thresholds::default();
    let good = commands::LinearFitFigures {
        undetermined: vec![],
        condition_number: 52.0,
        mass_relative_std: Some(0.005),
        s0_weighted: Some(1.02),
    };
    assert_eq!(commands::dynamics_identify(&t, &good).status, Status::Pass);
    for bad in [
        commands::LinearFitFigures { undetermined: vec!["Izz_kgm2".into()], ..good.clone() },
        commands::LinearFitFigures { condition_number: 5e3, ..good.clone() },
        commands::LinearFitFigures { mass_relative_std: Some(0.2), ..good.clone() },
        commands::LinearFitFigures { s0_weighted: Some(3.0), ..good.clone() },
    ] {
        let v = commands::dynamics_identify(&t, &bad);
        assert_eq!(v.status, Status::Warning, "{}", v.line());
    }
    // Without measured noise s0 (newtons) is not checked.
    let v = commands::dynamics_identify(&t, &commands::LinearFitFigures { s0_weighted: None, ..good });
    assert!(!v.checks.iter().any(|c| c.name == "dynamics.s0"));
    assert_eq!(commands::stiffness_identify(&t, &[], 1.1, 16).status, Status::Pass);
    assert_eq!(commands::stiffness_identify(&t, &[], 2.5, 16).status, Status::Warning);
    assert!(commands::stiffness_identify(&t, &["joint2.k < 0".into()], 1.1, 16).failed());
    assert!(commands::stiffness_unexcited("link3.k11 unexcited").failed());
}

#[test]
fn study_and_simulator_verdicts() {
    let t = Thresholds::default();
    let row = |translation, failed| commands::CoverageFigures {
        mount: "eye-in-hand".into(),
        runs: 200,
        failed,
        translation,
        rotation: 0.997,
    };
    assert_eq!(commands::handeye_study(&t, &[row(0.995, 0)]).status, Status::Pass);
    assert_eq!(commands::handeye_study(&t, &[row(0.9, 0)]).status, Status::Warning);
    assert_eq!(commands::handeye_study(&t, &[row(0.995, 1)]).status, Status::Warning);
    assert!(commands::handeye_study(&t, &[row(0.5, 0)]).failed());
    assert_eq!(commands::simulated("x", &[("poses", 12)], "next").status, Status::Pass);
    assert!(commands::simulated("x", &[("poses", 0)], "next").failed());
    // The new sections load from a file, and their keys are listed with their defaults.
    let f = Thresholds::from_toml("[robot]\nlimit_margin_warn = 0.1\n[dynamics]\ns0_warn = 3\n", Path::new("t.toml"))
        .unwrap();
    assert_eq!((f.robot.limit_margin_warn, f.dynamics.s0_warn), (0.1, 3.0));
    assert_eq!(f.stiffness, StiffnessLimits::default());
    let list = Thresholds::defaults_list();
    for key in [
        "robot.ik_position_mm_fail",
        "dynamics.condition_number_warn",
        "stiffness.s0_warn",
        "study.coverage_3sigma_warn",
    ] {
        assert!(list.iter().any(|(k, _)| k == key), "{key}");
    }
}

#[test]
fn unit_doubts_come_first_and_lead_the_next_step() {
    let v = Verdict::new(vec![Check::at_most("a", "a", "mm", 0.1, 1.0, 2.0)], "use it");
    assert_eq!(with_unit_doubts(v.clone(), &[]), v);
    let advice = "the values look like metres; if so, name the columns x_m, y_m, z_m";
    let d = with_unit_doubts(v, &[advice]);
    assert_eq!(d.status, Status::Warning);
    assert_eq!(d.checks[0].name, "input.units");
    assert!(d
        .line()
        .starts_with(&format!("verdict: warning: the table's units look wrong: {advice} (warning), a 0.1 mm")));
    assert!(
        d.next.starts_with(&format!("fix the table's units first ({advice})")) && d.next.ends_with("(then: use it)")
    );
    assert!(line_matches_spec(&d.line()));
}

#[test]
fn import_says_what_calibrate_holds_out() {
    use commands::held_out_words;
    assert_eq!(held_out_words(1000, 0, false), "no split column: calibrate holds out every second row, 500 of 1000");
    assert_eq!(held_out_words(205, 51, true), "calibrate holds out the 51 rows marked test");
    assert_eq!(held_out_words(40, 0, true), "its split column marks no row test: calibrate holds none out");
    // The count is split_rows' own.
    let rows: Vec<crate::PoseMeasurement> = (0..7)
        .map(|k| {
            crate::PoseMeasurement::new(
                format!("{k}"),
                vec![0.1 * k as f64],
                nalgebra::Vector3::new(0.0, 0.0, k as f64),
            )
        })
        .collect();
    assert_eq!(crate::kinematic::split_rows(&rows, true).1.len(), 3);
    assert!(held_out_words(7, 0, false).ends_with("3 of 7"));
}

#[test]
fn stereo_lists_swapped_or_disagreeing_lead_the_verdict() {
    let t = Thresholds::default();
    let right_of_left = commands::StereoPairing {
        right_in_left_mm: nalgebra::Vector3::new(83.2, -0.9, 0.3),
        n_pairs: 13,
        disagreeing: Vec::new(),
    };
    let ok = commands::stereo(&t, 0.18, 13, Some(0.11), &right_of_left);
    assert_eq!(ok.status, Status::Pass, "{}", ok.line());
    // Swapped: the right camera to the left of the left one.
    let swapped =
        commands::StereoPairing { right_in_left_mm: -right_of_left.right_in_left_mm, ..right_of_left.clone() };
    let v = commands::stereo(&t, 0.18, 13, Some(0.11), &swapped);
    assert_eq!((v.status, v.checks[0].name.as_str()), (Status::Fail, "stereo.baseline_leftward"));
    assert!(v.checks[0].what.contains("look swapped") && v.next.contains("--left"), "{}", v.line());
    // A vertical rig (right camera below the left one) is not a swap.
    let vertical =
        commands::StereoPairing { right_in_left_mm: nalgebra::Vector3::new(0.5, 83.0, 0.0), ..right_of_left.clone() };
    assert_eq!(commands::stereo(&t, 0.18, 13, Some(0.11), &vertical).status, Status::Pass);
    // Three of 13 pairs disagree: a warning naming them.
    let some = commands::StereoPairing {
        disagreeing: vec!["l1.jpg".into(), "l2.jpg".into(), "l3.jpg".into()],
        ..right_of_left
    };
    let v = commands::stereo(&t, 0.18, 13, Some(0.11), &some);
    assert_eq!(v.status, Status::Warning);
    assert!(
        v.line().contains("(3 of 13) 0.2308 > 0.2 (warning): l1.jpg, l2.jpg, l3.jpg") && v.next.contains("l1.jpg"),
        "{}",
        v.line()
    );
}
