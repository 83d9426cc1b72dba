//! The real two-axis positioner of the ROS-Industrial industrial_calibration kinematic example
//! (Apache-2.0): a fixed camera measured the 6-DoF pose of a target on the positioner in 205
//! poses. `ferrocal import ic-kinematic` turns the recording into a measurement table (every
//! fourth pose held out) and writes the source's nominal model as URDF; `ferrocal calibrate`
//! identifies the camera frame, the target mount and the joint corrections on the training poses;
//! `ferrocal evaluate` scores the held-out poses, which no fit saw. The source's own thresholds:
//! mean position error below 2 mm and orientation below 0.2 deg. The nominal model here has its
//! camera frame and target mount fitted on the same training poses (`--params none`), which is a
//! harder baseline than the nominal model with the source's rough mount guesses.

use std::path::Path;

use ferrocal_tests::{data, ferrocal, json, ok};

fn held_out_errors(dir: &Path, params: &str) -> (f64, f64, f64, f64) {
    let cal = dir.join(format!("cal_{params}.json"));
    ok(ferrocal()
        .args(["calibrate", "--robot"])
        .arg(dir.join("positioner.urdf"))
        .arg("--measurements")
        .arg(dir.join("train_and_test.csv"))
        .args(["--params", params, "--sigma-mm", "0.3", "--sigma-deg", "0.03", "--out"])
        .arg(&cal));
    let ev = dir.join(format!("ev_{params}.json"));
    ok(ferrocal()
        .args(["evaluate", "--robot"])
        .arg(dir.join("positioner.urdf"))
        .arg("--calibration")
        .arg(&cal)
        .arg("--measurements")
        .arg(dir.join("test.csv"))
        .arg("--json")
        .arg(&ev));
    let r = json(&ev);
    let e: Vec<f64> = r["per_pose"].as_array().unwrap().iter().map(|p| p["error_mm"].as_f64().unwrap()).collect();
    let mean = e.iter().sum::<f64>() / e.len() as f64;
    let std = (e.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / e.len() as f64).sqrt();
    assert!((mean - r["mean_mm"].as_f64().unwrap()).abs() < 1e-9);
    (mean, std, r["mean_deg"].as_f64().unwrap(), r["max_deg"].as_f64().unwrap())
}

#[test]
fn the_real_positioner_is_calibrated_from_camera_poses_within_the_source_thresholds() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let table = dir.join("train_and_test.csv");
    ok(ferrocal()
        .args(["import", "ic-kinematic", "--input"])
        .arg(data("industrial_calibration/kinematic_calibration"))
        .arg("--out")
        .arg(&table)
        .args(["--test-every", "4", "--robot-out"])
        .arg(dir.join("positioner.urdf")));
    let text = std::fs::read_to_string(&table).unwrap();
    let lines: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
    assert_eq!(lines.len(), 1 + 205, "header and 205 observations");
    let test: Vec<&str> = lines[1..].iter().copied().filter(|l| l.ends_with(",test")).collect();
    assert_eq!(test.len(), 51);
    std::fs::write(dir.join("test.csv"), format!("{}\n{}\n", lines[0], test.join("\n"))).unwrap();

    let (nom_mean, nom_std, nom_deg, _) = held_out_errors(dir, "none");
    let (cal_mean, cal_std, cal_deg, cal_max_deg) = held_out_errors(dir, "default");
    eprintln!(
        "held-out (51 poses): nominal {nom_mean:.4} +- {nom_std:.4} mm, {nom_deg:.4} deg; calibrated {cal_mean:.4} +- {cal_std:.4} mm, {cal_deg:.4} deg (max {cal_max_deg:.4})"
    );
    // The source's thresholds, far inside (measured 0.42 mm, 0.049 deg).
    assert!(cal_mean < 0.5 && cal_deg < 0.06, "{cal_mean} mm, {cal_deg} deg");
    // Better than the nominal model with fitted frames in position mean and spread (measured
    // 0.4525 -> 0.4216 mm, 0.1786 -> 0.1440 mm), and no worse in orientation.
    assert!(cal_mean < 0.95 * nom_mean && cal_std < 0.9 * nom_std, "{nom_mean} {nom_std} -> {cal_mean} {cal_std}");
    assert!(cal_deg <= nom_deg * 1.001, "{nom_deg} -> {cal_deg}");
}

/// `import ic-kinematic` on the real recording with its positions written in millimetres or its
/// joint readings in degrees (the format takes metres and radians): refused naming the file, the
/// line, the field, the observation and the likely unit, with the count of observations
/// affected; nothing written.
#[test]
fn the_positioner_recording_in_millimetres_or_degrees_is_refused_naming_line_and_field() {
    let tmp = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(data("industrial_calibration/kinematic_calibration/measurements.yaml")).unwrap();
    let scaled = |field: &dyn Fn(&str) -> bool, factor: f64| {
        let mut in_joints = false;
        let lines: Vec<String> = text
            .lines()
            .map(|l| {
                let t = l.trim_start();
                in_joints = t.starts_with("target_joints:") || (in_joints && t.starts_with('-'));
                let (head, value) = match (t.split_once(": "), t.strip_prefix("- ")) {
                    (Some((k, v)), _) if field(k) => (&l[..l.len() - v.len()], v),
                    (_, Some(v)) if in_joints && field("-") => (&l[..l.len() - v.len()], v),
                    _ => return l.to_string(),
                };
                format!("{head}{}", value.parse::<f64>().unwrap() * factor)
            })
            .collect();
        lines.join("\n") + "\n"
    };
    let cases = [
        (
            "mm.yaml",
            scaled(&|k| ["x", "y", "z"].contains(&k), 1000.0),
            "line 8, column 'pose.x'",
            "look like millimetres",
        ),
        (
            "deg.yaml",
            scaled(&|k| k == "-", 180.0 / std::f64::consts::PI),
            "line 12, column 'target_joints[0]'",
            "look like degrees",
        ),
    ];
    for (name, yaml, at, unit) in cases {
        let input = tmp.path().join(name);
        std::fs::write(&input, yaml).unwrap();
        let out_csv = tmp.path().join("out.csv");
        let out = ferrocal()
            .args(["import", "ic-kinematic", "--input"])
            .arg(&input)
            .arg("--out")
            .arg(&out_csv)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name}: {err}");
        assert!(
            err.contains(name) && err.contains(at) && err.contains(unit) && err.contains("of 205 observations"),
            "{name}: {err}"
        );
        assert!(!out_csv.exists());
    }
}
