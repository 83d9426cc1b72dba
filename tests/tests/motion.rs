//! `ferrocal motion identify|ilc|track|leadthrough` through the binary, the quick variants:
//! exit codes, the reports' numbers in report.json, and bad input refused by flag name.

use std::path::Path;

use ferrocal_tests::{ferrocal, json, run};

/// Runs `ferrocal motion <args> --out <dir>/<name>` and returns its exit code and report.json.
fn motion(dir: &Path, name: &str, args: &[&str]) -> (Option<i32>, serde_json::Value) {
    let out = dir.join(name);
    let o = run(ferrocal().arg("motion").args(args).arg("--out").arg(&out));
    assert!(out.join("index.html").exists(), "{name}: no index.html");
    let report = json(&out.join("report.json"));
    ferrocal_tests::assert_verdict_box(&out.join("index.html"), &report);
    (o.status.code(), report)
}

fn num(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

#[test]
fn each_motion_experiment_runs_alone_and_reports_its_numbers() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();

    // Chapter 6: the modes within 5 % of the truth (14.00 and 103.00 Hz), validation above 90 %.
    let (code, r) = motion(d, "identify", &["identify", "--quick", "--seed", "2"]);
    assert_eq!(code, Some(0));
    let id = &r["sections"]["motion-identification"];
    assert_eq!(id["ok"], true);
    for e in id["data"]["frequency_errors"]["tracker"].as_array().unwrap() {
        assert!(num(e).abs() < 0.05, "tracker mode error {e}");
    }
    assert!(num(&id["data"]["tool_tracker"]["validation_fit_percent"]) > 90.0);
    assert!((num(&id["data"]["true_modes"][0][0]) - 14.0).abs() < 0.01);

    // Chapter 7: learning on the tool estimate at least 5x better than on the encoder; under a
    // contact force the camera-corrected estimate 3x better than the model alone.
    let (code, r) =
        motion(d, "ilc", &["ilc", "--quick", "--seed", "2", "--iterations", "4", "--contact-force-n", "20"]);
    assert_eq!(code, Some(0));
    let last = |sec: &str, case: &str| num(&r["sections"][sec]["data"]["last_trial_tool_rms_m"][case]);
    assert!(last("motion-ilc", "tool_estimate") * 5.0 < last("motion-ilc", "actuator"));
    assert!(last("motion-ilc-contact", "tool_kalman") * 3.0 < last("motion-ilc-contact", "tool_estimate"));
    let runs = r["sections"]["motion-ilc"]["data"]["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 4);
    assert!(runs.iter().all(|c| c["tool_rms_m"].as_array().unwrap().len() == 5), "4 trials after the first");

    // The rendered tracking: every frame seen, error within its stated sigma.
    let (code, r) = motion(d, "track", &["track", "--quick", "--seed", "2"]);
    assert_eq!(code, Some(0));
    let t = &r["sections"]["motion-tracking"]["data"];
    assert!(t["frames"].as_u64().unwrap() > 10 && t["missed"].as_array().unwrap().is_empty());
    assert!(num(&t["rms_error_m"]) < 5e-6 && num(&t["rms_error_over_sigma"]) < 3.0, "{t}");

    // Chapter 8: the default admittance guides the tool home; a light, unfiltered one rings,
    // the report is written and the exit code says a check failed.
    let (code, r) = motion(d, "lead", &["leadthrough"]);
    assert_eq!(code, Some(0));
    let l = &r["sections"]["motion-leadthrough"]["data"];
    assert!(l["stable"].as_bool().unwrap() && num(&l["final_error_m"]).abs() < 1e-3);
    assert!(num(&l["force_rms_n"]) > 1.0 && num(&l["force_rms_n"]) < 20.0, "{l}");
    assert_eq!(l["stability_map"].as_array().unwrap().len(), 24);
    // The placement comparison: a sensor at the carriage reads the structure's inertial forces.
    let placement = l["sensor_placement"].as_array().unwrap();
    assert_eq!(placement.len(), 3);
    assert_eq!(num(&placement[0]["probe_reading_minus_hand_rms_n"]), 0.0, "the tool's sensor reads the hand");
    assert!(num(&placement[1]["probe_reading_minus_hand_rms_n"]) > 1.0, "{}", placement[1]);
    let (code, r) = motion(d, "lead-light", &["leadthrough", "--admittance-n-s-m", "10", "--force-cutoff-hz", "0"]);
    assert_eq!(code, Some(2));
    assert_eq!(r["sections"]["motion-leadthrough"]["ok"], false);
}

#[test]
fn the_three_dof_cell_is_identified_and_learns_from_the_tool() {
    let tmp = tempfile::tempdir().unwrap();
    let (code, r) = motion(tmp.path(), "cell", &["cell", "--quick", "--seed", "3"]);
    assert_eq!(code, Some(0));
    let id = &r["sections"]["motion-cell-identification"];
    assert_eq!(id["ok"], true);
    // Six modes (8.0, 14.1, 33.0 Hz and the carts near 101 Hz) within 5 %; validated.
    let modes = id["data"]["physical_modes"].as_array().unwrap();
    assert_eq!(modes.len(), 6);
    assert!(modes.iter().all(|m| num(&m["relative_error"]).abs() < 0.05), "{modes:?}");
    assert!((num(&id["data"]["true_modes"][0][0]) - 7.96).abs() < 0.05);
    assert!(num(&id["data"]["validation_fit_percent"]) > 90.0);
    let ilc = &r["sections"]["motion-cell-ilc"];
    assert_eq!(ilc["ok"], true);
    let last = |case: &str| num(&ilc["data"]["last_trial_tool_rms_m"][case]);
    assert!(last("tool_estimate") * 5.0 < last("actuator") && last("tool_measurement") * 5.0 < last("actuator"));
    // The camera case learns from rendered, motion-blurred frames (the reduced camera when quick).
    assert!(last("tool_camera") * 5.0 < last("actuator"), "{:?}", ilc["data"]["last_trial_tool_rms_m"]);
}

#[test]
fn bad_motion_options_are_refused_by_flag_name() {
    let tmp = tempfile::tempdir().unwrap();
    for (args, flag) in [
        (vec!["ilc", "--contact-force-n", "1500"], "--contact-force-n"),
        (vec!["ilc", "--contact-force-n=-1"], "--contact-force-n"),
        (vec!["study", "--contact-force-n", "NaN"], "--contact-force-n"),
        (vec!["ilc", "--iterations", "0"], "--iterations"),
        (vec!["leadthrough", "--admittance-n-s-m", "0"], "--admittance-n-s-m"),
        (vec!["leadthrough", "--force-cutoff-hz=-2"], "--force-cutoff-hz"),
        (vec!["leadthrough", "--sensor-sigma-n", "inf"], "--sensor-sigma-n"),
    ] {
        let out = tmp.path().join("never");
        let o = ferrocal().arg("motion").args(&args).arg("--out").arg(&out).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(flag), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?} wrote a report");
    }
}
