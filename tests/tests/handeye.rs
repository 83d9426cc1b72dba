//! `ferrocal handeye` and `ferrocal import ic-handeye` end to end through the binary: a rendered
//! chessboard recording with known truth (`ferrocal handeye simulate`, the project's renderer
//! with blur, vignetting and sensor noise; the chain, camera and noise model are the estimator's
//! own family, the corners come from the project's chessboard detector), the JSON contract of
//! `shared/spec/cli.md`, the importer on the ROS-Industrial industrial_calibration example data
//! (Apache-2.0), and bad input.

use ferrocal_tests::{data, ferrocal, json, ok, run};

fn vec3(v: &serde_json::Value) -> [f64; 3] {
    [0, 1, 2].map(|i| v[i].as_f64().unwrap())
}

/// Rendered eye-to-hand chessboard recording (10 training, 6 held-out images): the JSON has
/// every field of the contract; X's translation lies within 4.5 of its stated sigmas and 0.5 mm
/// of the truth; the held-out chain RMS is below 0.5 px and OpenCV's results are reported beside.
/// The recording's flange poses carry 0.05 mm and 0.005 deg of simulated noise, so they are taken
/// as measurements (`--robot-poses-as-measurements`; exact poses are the default).
#[test]
fn handeye_on_a_rendered_chessboard_recording() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("rec");
    let out = run(ferrocal().args(["handeye", "simulate", "--mount", "eye-to-hand", "--seed", "4", "--out"]).arg(&dir));
    assert!(out.status.success());
    let truth = json(&dir.join("truth.json"));
    let pattern = truth["pattern"].as_str().unwrap();
    let res = tmp.path().join("he.json");
    let html = tmp.path().join("he.html");
    let out = run(ferrocal()
        .args(["handeye", "--images"])
        .arg(dir.join("images"))
        .arg("--poses")
        .arg(dir.join("poses.csv"))
        .args(["--pattern", pattern, "--mount", "eye-to-hand", "--robot-poses-as-measurements", "--intrinsics"])
        .arg(dir.join("camera.yaml"))
        .arg("--json")
        .arg(&res)
        .arg("--report")
        .arg(&html));
    assert!(out.status.success());
    let r = json(&res);
    for key in ["mount", "camera", "hand_eye", "world", "train_rms_px", "heldout_rms_px", "per_image", "std"] {
        assert!(r.get(key).is_some(), "missing '{key}'");
    }
    assert_eq!(r["mount"], "eye-to-hand");
    assert_eq!(r["per_image"].as_array().unwrap().len(), 16);
    assert_eq!(r["per_image"][15]["split"], "test");
    let est = vec3(&r["hand_eye"]["translation_mm"]);
    let std = vec3(&r["std"]["hand_eye"]["translation_mm"]);
    let t = vec3(&truth["hand_eye"]["translation"]);
    for i in 0..3 {
        let err = (est[i] - t[i] * 1e3).abs();
        assert!(err < 4.5 * std[i] && err < 0.5, "coordinate {i}: {} vs {} mm (std {})", est[i], t[i] * 1e3, std[i]);
    }
    let held = r["heldout_rms_px"].as_f64().unwrap();
    assert!(held < 0.5, "held-out chain RMS {held} px");
    assert_eq!(r["opencv"].as_array().unwrap().len(), 7);
    let page = std::fs::read_to_string(&html).unwrap();
    assert!(page.contains("Chain residual per image") && page.contains("calibrateRobotWorldHandEye"));
    // The cell in 3-D: the fixed camera, one target outline per image (16), the flange dots.
    let cell = page.split("id=\"cell-3d\"").nth(1).expect("the 3-D cell section");
    let cell = cell.split("</svg>").next().unwrap();
    assert!(cell.contains("class=\"scene3d\"") && cell.contains(">camera</text>"));
    assert_eq!(cell.matches("<polygon ").count(), 16 + 1, "16 target outlines and the camera's image plane");
    ferrocal_tests::assert_verdict_box(&html, &r);
    // A camera file of another resolution (the same numbers, a 640 x 480 image size) is refused
    // with both sizes named, by `handeye` and by `measure`.
    let yaml = std::fs::read_to_string(dir.join("camera.yaml")).unwrap();
    let width = yaml.lines().find_map(|l| l.strip_prefix("image_width: ")).unwrap().trim().to_string();
    let height = yaml.lines().find_map(|l| l.strip_prefix("image_height: ")).unwrap().trim().to_string();
    let other = tmp.path().join("other.yaml");
    std::fs::write(
        &other,
        yaml.replace(&format!("image_width: {width}"), "image_width: 640")
            .replace(&format!("image_height: {height}"), "image_height: 480"),
    )
    .unwrap();
    for cmd in ["handeye", "measure"] {
        let out = ferrocal()
            .args([cmd, "--images"])
            .arg(dir.join("images"))
            .arg("--poses")
            .arg(dir.join("poses.csv"))
            .args(["--pattern", pattern, "--mount", "eye-to-hand", "--intrinsics"])
            .arg(&other)
            .arg("--json")
            .arg(tmp.path().join(format!("{cmd}-other.json")))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{cmd}: {err}");
        assert!(
            err.contains("is for 640 x 480 px images") && err.contains(&format!("{width} x {height} px")),
            "{cmd}: {err}"
        );
    }
}

/// The joint adjustment through the binary: `handeye simulate --robot ur5` renders the joint
/// study's UR5 cell (true kinematic errors of 0.5 mm / 0.5 mrad on the parameters the selection
/// keeps, 24 training and 12 held-out views, detected corners) and writes a simulated tracker's readings of the held-out
/// poses; `handeye --robot ur5 --out` writes the calibration file and `evaluate --refit-frame`
/// scores it against those readings. Truth: the true robot scores the tracker's noise floor
/// (about 0.03 mm), the nominal one 0.75 mm; the joint model must be within 1.5 times the floor
/// and below a tenth of the nominal (measured: 0.0264 mm; floor 0.0254 mm, nominal 0.7478 mm;
/// 0.0319 / 0.0288 / 0.8119 mm with the earlier selection and its 26 perturbed parameters).
#[test]
fn joint_adjustment_through_the_binary_calibrates_the_robot() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("cell");
    ok(ferrocal()
        .args(["handeye", "simulate", "--mount", "eye-to-hand", "--robot", "ur5", "--seed", "3"])
        .args(["--train", "24", "--test", "12", "--out"])
        .arg(&dir));
    let truth = json(&dir.join("truth.json"));
    let cal = tmp.path().join("calibration.json");
    let out = ok(ferrocal()
        .args(["handeye", "--images"])
        .arg(dir.join("images"))
        .arg("--poses")
        .arg(dir.join("poses.csv"))
        .args(["--robot", "ur5", "--pattern", truth["pattern"].as_str().unwrap(), "--mount", "eye-to-hand", "--out"])
        .arg(&cal));
    let stdout = String::from_utf8_lossy(&out.stdout);
    // 19 since the selection keeps the plate's pose on the flange (the tool) and the zero offsets
    // before per-joint corrections: joint 6's six corrections, counted in the earlier 26, are
    // that pose.
    assert!(stdout.contains("joint adjustment: 19 robot parameters"), "{stdout}");
    let file = json(&cal);
    assert_eq!(file["robot"], "ur5");
    let ev = tmp.path().join("ev.json");
    ok(ferrocal()
        .args(["evaluate", "--robot", "ur5", "--refit-frame", "--calibration"])
        .arg(&cal)
        .arg("--measurements")
        .arg(dir.join("heldout.csv"))
        .arg("--json")
        .arg(&ev));
    let mean_mm = json(&ev)["mean_mm"].as_f64().unwrap();
    let floor_mm = truth["truth_heldout"]["mean_mm"].as_f64().unwrap();
    let nominal_mm = truth["nominal_heldout"]["mean_mm"].as_f64().unwrap();
    eprintln!("joint model {mean_mm:.4} mm, truth {floor_mm:.4} mm, nominal {nominal_mm:.4} mm");
    assert!(floor_mm < 0.05 && nominal_mm > 0.5, "truth {floor_mm} mm, nominal {nominal_mm} mm");
    assert!(
        mean_mm < 1.5 * floor_mm && mean_mm < 0.1 * nominal_mm,
        "joint model {mean_mm} mm, truth {floor_mm} mm, nominal {nominal_mm} mm"
    );
}

/// The importer on both industrial_calibration hand-eye sets: rows, mount, the pattern string,
/// every second image held out, the charuco set's camera as OpenCV YAML.
#[test]
fn import_ic_handeye_reads_both_real_sets() {
    let tmp = tempfile::tempdir().unwrap();
    for (set, rows, mount, pattern) in [
        ("test_set_10x10", 15, "eye-in-hand", "circlegrid:10x10:25.4mm:modified"),
        ("test_set_charuco", 16, "eye-to-hand", "charuco:5x7:36.195mm:18.256mm:DICT_6X6_250"),
    ] {
        let csv = tmp.path().join(format!("{set}.csv"));
        let cam = tmp.path().join(format!("{set}.yaml"));
        let out = run(ferrocal()
            .args(["import", "ic-handeye", "--test-every", "2", "--input"])
            .arg(data(&format!("industrial_calibration/{set}")))
            .arg("--out")
            .arg(&csv)
            .arg("--intrinsics-out")
            .arg(&cam));
        assert!(out.status.success());
        let text = std::fs::read_to_string(&csv).unwrap();
        let lines: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
        assert_eq!(lines.len(), rows + 1, "{set}");
        assert_eq!(lines.iter().filter(|l| l.ends_with(",test")).count(), rows / 2, "{set}");
        assert!(
            text.contains(&format!("# mount: {mount}")) && text.contains(&format!("# pattern: {pattern}")),
            "{text}"
        );
        assert!(text.contains("ROS-Industrial industrial_calibration example data, Apache-2.0"));
        // 0.png of the 10x10 set: x 0.7169496300523684 m, qw -0.002133951223335981 (scalar first here).
        if set == "test_set_10x10" {
            assert!(lines[1].starts_with("0.png,716.9496300523684,") && lines[1].contains(",-0.002133951223335981,"));
        }
        let yaml = std::fs::read_to_string(&cam).unwrap();
        if set == "test_set_charuco" {
            assert!(yaml.contains("1352.02747") && yaml.contains("image_width: 1600"), "{yaml}");
        }
    }
}

fn isometry(t: &serde_json::Value) -> nalgebra::Isometry3<f64> {
    let p = vec3(&t["translation_mm"]);
    let q: Vec<f64> = (0..4).map(|i| t["rotation_wxyz"][i].as_f64().unwrap()).collect();
    nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::new(p[0] * 1e-3, p[1] * 1e-3, p[2] * 1e-3),
        nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3])),
    )
}

/// `handeye --corners-out` on the real 10x10 set (every second image held out): every image
/// with its split as in the table, its robot pose as read, 100 corners with distinct point ids;
/// and the held-out chain RMS recomputed from the exported corners, target points and robot
/// poses with the JSON's camera (Brown-5 in OpenCV's order), X, W and print scale is the
/// command's own `heldout_rms_px`: what other tools are given is exactly what ferrocal scored.
#[test]
fn handeye_corners_out_reproduces_the_heldout_figure() {
    let tmp = tempfile::tempdir().unwrap();
    let set = data("industrial_calibration/test_set_10x10");
    let csv = tmp.path().join("poses.csv");
    ok(ferrocal().args(["import", "ic-handeye", "--test-every", "2", "--input"]).arg(&set).arg("--out").arg(&csv));
    let (res, corners) = (tmp.path().join("r.json"), tmp.path().join("corners.json"));
    // No --pattern, no --mount: both come from the lines `import` wrote into the table's header.
    ok(ferrocal()
        .args(["handeye", "--images"])
        .arg(set.join("images"))
        .arg("--poses")
        .arg(&csv)
        .arg("--json")
        .arg(&res)
        .arg("--corners-out")
        .arg(&corners));
    let (r, c) = (json(&res), json(&corners));
    assert_eq!(c["mount"], "eye-in-hand");
    assert_eq!(c["pattern"], "circlegrid:10x10:25.4mm:modified");
    // A table without those lines and no flags: refused, naming the flag and the file.
    let bare = tmp.path().join("bare.csv");
    let text = std::fs::read_to_string(&csv).unwrap();
    std::fs::write(&bare, text.lines().filter(|l| !l.starts_with("# pattern:")).collect::<Vec<_>>().join("\n"))
        .unwrap();
    let out =
        ferrocal().args(["handeye", "--images"]).arg(set.join("images")).arg("--poses").arg(&bare).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--pattern is required") && err.contains("bare.csv"), "{err}");
    assert_eq!(c["data_source"], "ROS-Industrial industrial_calibration example data, Apache-2.0");
    let target: Vec<nalgebra::Point3<f64>> =
        c["target_points_m"].as_array().unwrap().iter().map(|p| nalgebra::Point3::from(vec3(p))).collect();
    assert_eq!(target.len(), 100);
    let views = c["views"].as_array().unwrap();
    assert_eq!(views.len(), 15);
    assert_eq!(views[0]["image"], "0.png");
    assert!((views[0]["t_base_flange"]["translation_mm"][0].as_f64().unwrap() - 716.9496300523684).abs() < 1e-9);
    let k = &r["camera"];
    let f = |key: &str| k[key].as_f64().unwrap();
    let d: Vec<f64> = (0..5).map(|i| k["distortion"][i].as_f64().unwrap()).collect();
    let (x, w, scale) = (isometry(&r["hand_eye"]), isometry(&r["world"]), r["target_scale"]["value"].as_f64().unwrap());
    let mut sums = [(0.0, 0usize); 2];
    for (i, v) in views.iter().enumerate() {
        let split = v["split"].as_str().unwrap();
        assert_eq!(split, if i % 2 == 1 { "test" } else { "train" }, "{v}");
        assert_eq!(v["used"], true);
        let ids: Vec<usize> = v["point_ids"].as_array().unwrap().iter().map(|i| i.as_u64().unwrap() as usize).collect();
        let px = v["corners_px"].as_array().unwrap();
        assert_eq!((ids.len(), px.len()), (100, 100));
        assert_eq!(ids.iter().collect::<std::collections::BTreeSet<_>>().len(), 100);
        // Eye-in-hand: T_camera_target = X^-1 T_base_flange^-1 W.
        let t = x.inverse() * isometry(&v["t_base_flange"]).inverse() * w;
        for (&id, uv) in ids.iter().zip(px) {
            let p = t * nalgebra::Point3::from(target[id].coords * scale);
            let (a, b) = (p.x / p.z, p.y / p.z);
            let r2 = a * a + b * b;
            let radial = 1.0 + d[0] * r2 + d[1] * r2 * r2 + d[4] * r2 * r2 * r2;
            let xd = a * radial + 2.0 * d[2] * a * b + d[3] * (r2 + 2.0 * a * a);
            let yd = b * radial + d[2] * (r2 + 2.0 * b * b) + 2.0 * d[3] * a * b;
            let (u, vv) = (f("fx") * xd + f("cx"), f("fy") * yd + f("cy"));
            let e2 = (u - uv[0].as_f64().unwrap()).powi(2) + (vv - uv[1].as_f64().unwrap()).powi(2);
            let s = &mut sums[usize::from(split == "test")];
            s.0 += e2;
            s.1 += 1;
        }
    }
    let rms = |(s, n): (f64, usize)| (s / n as f64).sqrt();
    let (train, held) = (rms(sums[0]), rms(sums[1]));
    assert!((train - r["train_rms_px"].as_f64().unwrap()).abs() < 1e-6, "train {train} against {}", r["train_rms_px"]);
    assert!(
        (held - r["heldout_rms_px"].as_f64().unwrap()).abs() < 1e-6,
        "held-out {held} against {}",
        r["heldout_rms_px"]
    );
}

/// Bad input: a missing set folder, a pose file with a bad value (file, line, column), a
/// poses table with a bad quaternion, joint columns without a robot; nothing is written.
#[test]
fn handeye_bad_input_is_located() {
    let tmp = tempfile::tempdir().unwrap();
    let out_csv = tmp.path().join("out.csv");
    let out = run(ferrocal()
        .args(["import", "ic-handeye", "--input"])
        .arg(tmp.path().join("nope"))
        .arg("--out")
        .arg(&out_csv));
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("cal_data.yaml"));

    let set = tmp.path().join("set");
    std::fs::create_dir_all(set.join("poses")).unwrap();
    std::fs::write(set.join("cal_data.yaml"), "data:\n  - pose: poses/0.yaml\n    image: images/0.png\n").unwrap();
    std::fs::write(set.join("poses/0.yaml"), "x: 0.5\ny: zero\nz: 0.1\nqx: 0\nqy: 0\nqz: 0\nqw: 1\n").unwrap();
    let out = run(ferrocal().args(["import", "ic-handeye", "--input"]).arg(&set).arg("--out").arg(&out_csv));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("0.yaml: line 2"), "{err}");
    assert!(!out_csv.exists());

    let poses = tmp.path().join("poses.csv");
    std::fs::write(&poses, "image,x_mm,y_mm,z_mm,qw,qx,qy,qz\na.png,1,2,3,2,0,0,0\n").unwrap();
    let res = tmp.path().join("r.json");
    let out = run(ferrocal()
        .args(["handeye", "--images"])
        .arg(tmp.path())
        .arg("--poses")
        .arg(&poses)
        .args(["--pattern", "chessboard:9x6:30mm", "--mount", "eye-in-hand", "--json"])
        .arg(&res));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("line 2, column 'qw'") && err.contains("norm 2"), "{err}");
    std::fs::write(&poses, "image,q1_deg,q2_deg\na.png,1,2\n").unwrap();
    let out = run(ferrocal().args(["handeye", "--images"]).arg(tmp.path()).arg("--poses").arg(&poses).args([
        "--pattern",
        "chessboard:9x6:30mm",
        "--mount",
        "eye-in-hand",
    ]));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("line 2") && err.contains("--robot"), "{err}");
    assert!(!res.exists());
}
