//! `ferrocal handeye` with a stereo head on the flange (eye-in-hand) end to end through the
//! binary, and a rig file's `R`, `T` read back as the joint adjustment's start and checked
//! against the fit. `handeye simulate --cameras 2 --mount eye-in-hand` renders the UR5 cell with
//! two different cameras on the flange (120 mm apart, turned 15 degrees towards each other)
//! watching a chessboard on the table (the project's renderer: blur, vignetting, sensor noise;
//! the corners come from the detector; the cameras, the chain and the robot's error model are
//! the estimator's own family). Measured at the time of writing: docs/handeye.md ("Rigs through
//! the command line").

use std::path::{Path, PathBuf};

use ferrocal_tests::{ferrocal, json, ok};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde_json::Value;

fn isometry(t: &Value) -> Isometry3<f64> {
    let p: Vec<f64> = (0..3).map(|i| t["translation_mm"][i].as_f64().unwrap() * 1e-3).collect();
    let q: Vec<f64> = (0..4).map(|i| t["rotation_wxyz"][i].as_f64().unwrap()).collect();
    Isometry3::from_parts(
        Translation3::new(p[0], p[1], p[2]),
        UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3])),
    )
}

/// `truth - est`: translation (mm) and rotation vector (deg), the chart of the reported
/// standard deviations.
fn error(est: &Isometry3<f64>, truth: &Isometry3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let dt = (truth.translation.vector - est.translation.vector) * 1e3;
    let dr = (truth.rotation * est.rotation.inverse()).scaled_axis().map(f64::to_degrees);
    (dt, dr)
}

/// Asserts an estimated `T_cam1_cam0` (its JSON with `std`) within `mm`, `deg` and `sigmas`
/// of `truth` per coordinate; returns the largest error in its sigmas.
fn assert_transform(what: &str, est: &Value, truth: &Isometry3<f64>, mm: f64, deg: f64, sigmas: f64) -> f64 {
    let (dt, dr) = error(&isometry(est), truth);
    let (st, sr) = (&est["std"]["translation_mm"], &est["std"]["rotation_deg"]);
    eprintln!("{what}: T_cam1_cam0 error {:.3?} mm (std {st}), {:.4?} deg (std {sr})", dt.as_slice(), dr.as_slice());
    assert!(dt.norm() < mm && dr.norm() < deg, "{what}: T_cam1_cam0 off by {} mm, {} deg", dt.norm(), dr.norm());
    let mut worst = 0.0f64;
    for i in 0..3 {
        let (s_t, s_r) = (st[i].as_f64().unwrap(), sr[i].as_f64().unwrap());
        assert!(s_t > 0.0 && s_r > 0.0, "{what}: std {st} {sr}");
        worst = worst.max(dt[i].abs() / s_t).max(dr[i].abs() / s_r);
    }
    assert!(worst < sigmas, "{what}: T_cam1_cam0 {worst} sigma off");
    worst
}

/// `handeye simulate --cameras 2 --mount eye-in-hand` of `seed` with `train` + `test` poses.
fn simulate(dir: &Path, seed: &str, train: &str, test: &str) -> Value {
    ok(ferrocal()
        .args(["handeye", "simulate", "--mount", "eye-in-hand", "--robot", "ur5", "--cameras", "2", "--seed", seed])
        .args(["--train", train, "--test", test, "--out"])
        .arg(dir));
    json(&dir.join("truth.json"))
}

/// `handeye` on both cameras of the recording in `dir` with `poses` and further arguments.
fn rig_command(dir: &Path, poses: &str, pattern: &str) -> std::process::Command {
    let mut c = ferrocal();
    c.args(["handeye", "--images"])
        .arg(dir.join("cam0/images"))
        .arg("--images")
        .arg(dir.join("cam1/images"))
        .arg("--poses")
        .arg(dir.join(poses))
        .args(["--pattern", pattern, "--mount", "eye-in-hand"]);
    c
}

/// A stereo head on the flange (14 training, 6 held-out poses): the joint adjustment through
/// the binary (`--robot ur5 --out`) gives `T_cam1_cam0` within 2 mm and 0.1 deg of the truth and
/// within 4 of its stated sigmas per coordinate, each camera's focal length within 0.5 % and 4
/// sigma of the truth, both held-out chain RMS below 1 px, and the verdict line ends stdout;
/// without a robot model, on the true flange poses, `T_cam1_cam0` combined from the cameras' own
/// fits within the same bounds and each fx within 4 sigma.
#[test]
fn a_stereo_head_on_the_flange_is_calibrated_with_its_robot() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("rig");
    let truth = simulate(&dir, "3", "14", "6");
    assert_eq!(truth["mount"], "eye-in-hand");
    assert!(truth["cameras"][1]["t_flange_camera"].is_object() && truth["t_base_target"].is_object());
    let pattern = truth["pattern"].as_str().unwrap();
    let t_true = isometry(&truth["cameras"][1]["t_cam_cam0"]);
    let (res, cal) = (tmp.path().join("r.json"), tmp.path().join("cal.json"));
    let out =
        ok(rig_command(&dir, "poses.csv", pattern).args(["--robot", "ur5", "--out"]).arg(&cal).arg("--json").arg(&res));
    let stdout = String::from_utf8_lossy(&out.stdout);
    eprintln!("{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.trim_end().lines().last().unwrap().starts_with("verdict: "), "{stdout}");
    assert!(stdout.contains("T_cam1_cam0 (joint adjustment)"), "{stdout}");
    let r = json(&res);
    assert_eq!(r["mount"], "eye-in-hand");
    let joint = &r["rig"]["joint"];
    assert_eq!(joint["cameras"][1]["t_cam_cam0_start"], "combined from the cameras' own fits");
    assert_transform("joint adjustment", &joint["cameras"][1]["t_cam_cam0"], &t_true, 2.0, 0.1, 4.0);
    for k in 0..2 {
        let cam = &joint["cameras"][k];
        let (fx, sd) = (cam["camera"]["fx"].as_f64().unwrap(), cam["camera"]["std"]["fx"].as_f64().unwrap());
        let fx_true = truth["cameras"][k]["camera"]["intrinsics"]["fx_px"].as_f64().unwrap();
        eprintln!("joint cam{k}: fx {fx:.3} +- {sd:.3} px, true {fx_true}");
        assert!((fx - fx_true).abs() < 0.005 * fx_true && (fx - fx_true).abs() < 4.0 * sd, "cam{k} fx {fx} +- {sd}");
        let held = cam["figures"]["heldout_rms_px"].as_f64().expect("held-out chain RMS reported");
        assert!(held < 1.0, "cam{k} held-out chain RMS {held} px");
    }
    assert_eq!(json(&cal)["robot"], "ur5");
    // The cameras' own fits on the true flange poses, no robot model.
    let res2 = tmp.path().join("r2.json");
    let out = ok(rig_command(&dir, "flange_poses.csv", pattern).arg("--json").arg(&res2));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("T_cam1_cam0 (the cameras' own fits)"), "{stdout}");
    assert!(stdout.trim_end().lines().last().unwrap().starts_with("verdict: "), "{stdout}");
    let r2 = json(&res2);
    assert!(r2["rig"]["joint"].is_null());
    assert_transform("own fits", &r2["rig"]["cameras"][1]["t_cam_cam0"], &t_true, 2.0, 0.1, 4.0);
    for k in 0..2 {
        let cam = &r2["rig"]["cameras"][k]["hand_eye_fit"]["camera"];
        let (fx, sd) = (cam["fx"].as_f64().unwrap(), cam["std"]["fx"].as_f64().unwrap());
        let fx_true = truth["cameras"][k]["camera"]["intrinsics"]["fx_px"].as_f64().unwrap();
        eprintln!("own fit cam{k}: fx {fx:.3} +- {sd:.3} px, true {fx_true}");
        assert!((fx - fx_true).abs() < 4.0 * sd, "own fit cam{k} fx {fx} +- {sd}, true {fx_true}");
    }
}

/// Replaces `T`'s first number in an OpenCV FileStorage text by itself plus `add`.
fn shift_t(text: &str, add: f64) -> String {
    let (head, rest) = text.split_once("T: !!opencv-matrix").unwrap();
    let (pre, data) = rest.split_once("data: [").unwrap();
    let (first, tail) = data.split_once(',').unwrap();
    let v: f64 = first.trim().parse().unwrap();
    format!("{head}T: !!opencv-matrix{pre}data: [{:.17e},{tail}", v + add)
}

/// The rig files of `--rig-out` read back with `--intrinsics cam0.yaml --intrinsics cam1.yaml`:
/// the joint adjustment starts from the file's `T_cam1_cam0` (said in the JSON) and reproduces
/// the transform of the run that wrote the files within 0.05 of its standard deviations
/// (the same data), the difference from the file is reported (JSON, terminal, report) below
/// 0.05 sigma; a file whose `T` is moved by 3 mm is reported 3 mm (+- 0.05 mm) and many sigma
/// off, and the adjustment still reaches the same transform.
#[test]
fn a_rig_file_is_the_start_and_the_check_of_the_rig_transform() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("rig");
    let truth = simulate(&dir, "4", "12", "4");
    let pattern = truth["pattern"].as_str().unwrap().to_string();
    let files = tmp.path().join("files");
    let run = |name: &str, intrinsics: &[PathBuf]| -> (Value, String) {
        let (res, cal) = (tmp.path().join(format!("{name}.json")), tmp.path().join(format!("{name}_cal.json")));
        let html = tmp.path().join(format!("{name}.html"));
        let mut c = rig_command(&dir, "poses.csv", &pattern);
        c.args(["--robot", "ur5", "--out"]).arg(&cal).arg("--json").arg(&res).arg("--report").arg(&html);
        if intrinsics.is_empty() {
            c.arg("--rig-out").arg(&files);
        }
        for p in intrinsics {
            c.arg("--intrinsics").arg(p);
        }
        let out = ok(&mut c);
        let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
        eprintln!("{stdout}");
        let page = std::fs::read_to_string(&html).unwrap();
        (json(&res), stdout + &page)
    };
    let (first, _) = run("first", &[]);
    let t_first = &first["rig"]["joint"]["cameras"][1]["t_cam_cam0"];
    let back = [files.join("cam0.yaml"), files.join("cam1.yaml")];
    let (second, text) = run("second", &back);
    let joint = &second["rig"]["joint"]["cameras"][1];
    assert_eq!(joint["t_cam_cam0_start"], "the camera files' R, T (--intrinsics)");
    // The same transform as the run that wrote the file, well within its uncertainty.
    let worst = assert_transform("read back", &joint["t_cam_cam0"], &isometry(t_first), 0.5, 0.02, 0.05);
    eprintln!("read back: {worst:.4} sigma from the first run");
    let d = &second["rig"]["cameras"][1]["t_cam_cam0_file"]["difference"];
    eprintln!("difference from the file: {d}");
    assert_eq!(d["compared_with"], "joint adjustment");
    assert!(d["max_sigma"].as_f64().unwrap() < 0.05 && d["translation_norm_mm"].as_f64().unwrap() < 0.05, "{d}");
    assert!(text.contains("T_cam1_cam0 of") && text.contains("R, T against the fit"), "terminal and report");
    // A file 3 mm off in x: reported 3 mm off (fitted minus file: -3 mm), many sigma.
    let moved = tmp.path().join("cam1_moved.yaml");
    std::fs::write(&moved, shift_t(&std::fs::read_to_string(&back[1]).unwrap(), 0.003)).unwrap();
    let (third, _) = run("third", &[back[0].clone(), moved]);
    let d = &third["rig"]["cameras"][1]["t_cam_cam0_file"]["difference"];
    eprintln!("difference from the moved file: {d}");
    let dx = d["translation_mm"][0].as_f64().unwrap();
    assert!((dx + 3.0).abs() < 0.05, "moved by 3 mm, reported {dx} mm");
    assert!(d["max_sigma"].as_f64().unwrap() > 3.0, "{d}");
    assert_transform(
        "from the moved file",
        &third["rig"]["joint"]["cameras"][1]["t_cam_cam0"],
        &isometry(t_first),
        0.5,
        0.02,
        0.05,
    );
}
