//! The demo's rig section: `ferrocal handeye simulate --cameras 2 --robot ur5` and `ferrocal
//! handeye --images cam0 --images cam1 --robot ur5 --out` run in-process as a user would call
//! them; the camera-to-camera transform and both focal lengths against the recording's truth.

use std::path::Path;

use ferrocal_calib::check::Check;
use ferrocal_calib::handeye::physics::ChainPhysicsReport;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use serde_json::{json, Value};

use crate::demo::pipeline::RunCommand;
use crate::error::{Context, Result};
use crate::report::Section;

/// The largest `T_cam1_cam0` error in its stated standard deviations the section accepts.
pub const MAX_RIG_Z: f64 = 4.0;

fn isometry(t: &Value) -> Option<Isometry3<f64>> {
    let p: Vec<f64> = (0..3).map(|i| t["translation_mm"][i].as_f64().map(|v| v * 1e-3)).collect::<Option<_>>()?;
    let q: Vec<f64> = (0..4).map(|i| t["rotation_wxyz"][i].as_f64()).collect::<Option<_>>()?;
    Some(Isometry3::from_parts(
        Translation3::new(p[0], p[1], p[2]),
        UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3])),
    ))
}

fn read_json(path: &Path) -> Result<Value> {
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    Ok(serde_json::from_str(&text)?)
}

/// The section: seed `seed`, 30 training and 10 held-out poses (24 and 8 when `quick`), in
/// `work` (its recording replaced).
pub fn rig_section(work: &Path, seed: u64, quick: bool, run: RunCommand) -> Result<Section> {
    let mut s = Section::new("handeye-rig", "Two cameras and the robot in one adjustment (a rig)");
    let (train, test) = if quick { ("24", "8") } else { ("30", "10") };
    let rec = work.join("recording");
    if rec.exists() {
        std::fs::remove_dir_all(&rec).with_context(|| format!("removing {}", rec.display()))?;
    }
    let p = |path: &Path| path.display().to_string();
    let seed_text = seed.to_string();
    let sim = ["handeye", "simulate", "--mount", "eye-to-hand", "--robot", "ur5", "--cameras", "2"];
    let mut argv: Vec<String> = sim.iter().map(|a| a.to_string()).collect();
    argv.extend(["--seed", &seed_text, "--train", train, "--test", test, "--out"].map(String::from));
    argv.push(p(&rec));
    run(&argv)?;
    let truth = read_json(&rec.join("truth.json"))?;
    let result = work.join("rig.json");
    let pattern = truth["pattern"].as_str().unwrap_or("chessboard:9x6:30mm").to_string();
    let argv: Vec<String> = [
        "handeye",
        "--images",
        &p(&rec.join("cam0/images")),
        "--images",
        &p(&rec.join("cam1/images")),
        "--poses",
        &p(&rec.join("poses.csv")),
        "--robot",
        "ur5",
        "--pattern",
        &pattern,
        "--mount",
        "eye-to-hand",
        "--out",
        &p(&work.join("calibration.json")),
        "--json",
        &p(&result),
        "--rig-out",
        &p(&work.join("rig_files")),
        "--keep",
    ]
    .map(String::from)
    .to_vec();
    run(&argv)?;
    let r = read_json(&result)?;
    let joint = &r["rig"]["joint"];
    let est = &joint["cameras"][1]["t_cam_cam0"];
    let (Some(t_est), Some(t_true)) = (isometry(est), isometry(&truth["cameras"][1]["t_cam_cam0"])) else {
        s.skipped("the rig's result has no T_cam1_cam0".to_string());
        return Ok(s);
    };
    let dt = (t_true.translation.vector - t_est.translation.vector) * 1e3;
    let dr = (t_true.rotation * t_est.rotation.inverse()).scaled_axis().map(f64::to_degrees);
    let sd = |key: &str, i: usize| est["std"][key][i].as_f64().unwrap_or(f64::NAN);
    let z = (0..3)
        .map(|i| (dt[i] / sd("translation_mm", i)).abs().max((dr[i] / sd("rotation_deg", i)).abs()))
        .fold(0.0, f64::max);
    s.text(format!(
        "`ferrocal handeye simulate --mount eye-to-hand --robot ur5 --cameras 2 --seed {seed} --train {train} --test {test}` \
         renders two fixed cameras (1224 x 1024 px, f = 1200 px, and 1024 x 768 px, f = 875 px, on the robot's right) \
         watching a 9 x 6 chessboard on the flange of a UR5 with true kinematic errors; each camera's images are the \
         poses it sees. `ferrocal handeye --images cam0/images --images cam1/images --poses poses.csv --robot ur5 --out \
         calibration.json --rig-out rig_files` adjusts the robot, both cameras and T_cam1_cam0 in one problem in pixels. \
         The data come from the same model family the estimator fits (pinhole + Brown-5, rigid board, rigid kinematics); \
         the images are rendered and the corners detected."
    ));
    let mut rows = vec![vec![
        "T_cam1_cam0".to_string(),
        format!("{:.3} mm, {:.4} deg", dt.norm(), dr.norm()),
        format!("{z:.2} sigma (largest coordinate)"),
    ]];
    let mut focal_ok = true;
    for k in 0..2 {
        let cam = &joint["cameras"][k];
        let fx = cam["camera"]["fx"].as_f64().unwrap_or(f64::NAN);
        let sfx = cam["camera"]["std"]["fx"].as_f64().unwrap_or(f64::NAN);
        let fx_true = truth["cameras"][k]["camera"]["intrinsics"]["fx_px"].as_f64().unwrap_or(f64::NAN);
        focal_ok &= (fx - fx_true).abs() <= MAX_RIG_Z * sfx;
        let held = cam["figures"]["heldout_rms_px"].as_f64().map_or("-".into(), |h| format!("{h:.4} px"));
        rows.push(vec![
            format!("cam{k} fx"),
            format!("{:.3} px (fx {fx:.3} +- {sfx:.3} px)", fx - fx_true),
            format!("{:.2} sigma; held-out chain RMS {held}", (fx - fx_true).abs() / sfx),
        ]);
    }
    s.table("Against the recording's truth (joint adjustment)", &["quantity", "error", "in its sigmas"], rows);
    // The physics selection over both cameras (on by default): the rendered target is flat and
    // printed to scale, and each lens is Brown's, so the expected outcome is that nothing is kept.
    if let Ok(p) = serde_json::from_value::<ChainPhysicsReport>(r["rig"]["physics"].clone()) {
        s.text(format!(
            "{} (the rendered target is flat and printed to scale and both lenses are Brown's: nothing should be kept).",
            super::physics::physics_line(&p)
        ));
    }
    s.data = json!({"seed": seed, "truth": truth, "result_rig": r["rig"], "verdict": r["verdict"]});
    s.check(Check::from_bool(
        "a two-camera rig and its robot calibrated in one command",
        z <= MAX_RIG_Z && focal_ok,
        format!(
            "T_cam1_cam0 off by {:.3} mm and {:.4} deg, {z:.2} of its sigmas (limit {MAX_RIG_Z}); both focal lengths within {MAX_RIG_Z} sigma: {focal_ok}",
            dt.norm(),
            dr.norm()
        ),
    ));
    Ok(s)
}
