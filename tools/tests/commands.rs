//! The commands' own behaviour through the built binary: a bad image does not stop `detect`,
//! `dynamics identify` refuses a quasi-static model, `stiffness identify` takes any serial arm
//! and refuses a parallel robot; `camera stereo` writes the rectified pair (OpenCV, ROS) and its
//! report.

use std::path::Path;
use std::process::{Command, Output};

fn ferrocal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ferrocal")).args(args).output().unwrap()
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn write_board(path: &Path) {
    // A plain 4 x 3 inner-corner chessboard, 40 px squares.
    let (w, h) = (320u32, 260u32);
    let img = image::GrayImage::from_fn(w, h, |x, y| {
        let (u, v) = (x as f64 - 60.0, y as f64 - 50.0);
        let inside = (0.0..200.0).contains(&u) && (0.0..160.0).contains(&v);
        let dark = inside && ((u / 40.0).floor() as i64 + (v / 40.0).floor() as i64) % 2 == 0;
        image::Luma([if dark { 30 } else { 210 }])
    });
    img.save(path).unwrap();
}

#[test]
fn detect_reports_bad_images_and_the_batch_continues() {
    let dir = std::env::temp_dir().join(format!("ferrocal_detect_test_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    write_board(&dir.join("a_board.png"));
    std::fs::write(dir.join("b_empty.png"), b"").unwrap();
    image::GrayImage::from_pixel(100, 80, image::Luma([128])).save(dir.join("c_blank.png")).unwrap();
    let json = dir.join("out.json");
    let out = ferrocal(&["detect", "--images", path(&dir), "--pattern", "chessboard:4x3:20mm", "--json", path(&json)]);
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let a = v.as_array().unwrap();
    assert_eq!(a.len(), 3);
    assert_eq!(a[0]["detections"][0]["corners_px"].as_array().unwrap().len(), 12);
    assert!(a[0].get("error").is_none());
    assert!(
        a[1]["error"].as_str().unwrap().contains("b_empty.png")
            || a[1]["image"].as_str().unwrap().contains("b_empty.png")
    );
    assert!(a[2]["error"].as_str().unwrap().contains("not found"));
    assert!(a[0].get("timings").is_none());
    // --timings: every stage per image, printed and in the JSON (unreadable files have none).
    let args = ["detect", "--images", path(&dir), "--pattern", "chessboard:4x3:20mm", "--json", path(&json)];
    let out = ferrocal(&[&args[..], &["--timings"]].concat());
    assert_eq!(out.status.code(), Some(2));
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let t = &v[0]["timings"];
    for stage in ["read_ms", "candidates_ms", "grid_ms", "refine_ms", "covariance_ms", "total_ms"] {
        assert!(t[stage].as_f64().is_some_and(|ms| ms >= 0.0), "{stage}: {t}");
    }
    assert_eq!(t["corners"].as_u64(), Some(12));
    let printed = String::from_utf8_lossy(&out.stdout);
    assert!(printed.contains("a_board.png: read") && printed.contains("refinement"), "{printed}");
    let out = ferrocal(&["detect", "--images", path(&dir), "--pattern", "chessboard:4x3", "--json", path(&json)]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.code() == Some(1) && e.contains("'chessboard:4x3'") && e.contains("expected"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A quasi-static model on streams is refused with the reason (before any file is read).
#[test]
fn dynamics_identify_refuses_a_quasi_static_model() {
    let out = ferrocal(&["dynamics", "identify", "--legs", "legs.csv", "--forces", "forces.csv", "--model", "2"]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && e.contains("quasi-static"), "{e}");
}

/// Any serial model runs (without design estimates); a parallel robot is refused.
#[test]
fn stiffness_identify_takes_any_serial_arm() {
    let dir = std::env::temp_dir().join(format!("ferrocal-stiff-{}", std::process::id()));
    let out = ferrocal(&["stiffness", "simulate", "--out", path(&dir), "--seed", "3", "--configurations", "25"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let csv = dir.join("deflections.csv");
    let id = dir.join("id");
    let out = ferrocal(&["stiffness", "identify", "--measurements", path(&csv), "--out", path(&id)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(id.join("index.html").exists() && id.join("parameters.json").exists());
    let out = ferrocal(&["stiffness", "identify", "--measurements", path(&csv), "--model", "ur5"]);
    assert!(out.status.code() != Some(1), "{}", String::from_utf8_lossy(&out.stderr));
    let out = ferrocal(&["stiffness", "identify", "--measurements", path(&csv), "--model", "hexapod"]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.code() == Some(1) && e.contains("not a serial arm"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `camera stereo` on OpenCV's stereo sample with OpenCV's corner recipe (`--corners opencv`),
/// every output asked for: the baseline agrees with OpenCV's `stereoCalibrate` on the same
/// corners (translation [-83.429, 0.956, 0.157] mm, baseline 83.435 mm; measured by
/// `cargo test -p ferrocal-vision --test integration stereo_baseline_matches -- --nocapture`)
/// within 3 of the reported standard deviations; the corners of every pair land on the same
/// rectified row to 0.5 px RMS (measured 0.2657 px, as with OpenCV's stereoRectify); the OpenCV
/// and ROS files read back to the JSON's numbers; an output over an input image is refused.
#[test]
fn camera_stereo_exports_the_rectified_pair_and_a_report() {
    use ferrocal_vision::camera::io;
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/opencv_stereo");
    assert!(data.is_dir(), "{} is missing: ../shared must be beside the checkout", data.display());
    let dir = std::env::temp_dir().join(format!("ferrocal_stereo_test_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (left, right) = (data.join("left*.jpg"), data.join("right*.jpg"));
    let f = |name: &str| dir.join(name);
    let out = ferrocal(&[
        "camera",
        "stereo",
        "--left",
        path(&left),
        "--right",
        path(&right),
        "--pattern",
        "chessboard:9x6:25mm",
        "--fix-aspect",
        "--corners",
        "opencv",
        "--json",
        path(&f("stereo.json")),
        "--opencv-stereo-yaml",
        path(&f("stereo.yml")),
        "--ros-left",
        path(&f("left.yaml")),
        "--right-ros-yaml",
        path(&f("right.yaml")),
        "--report",
        path(&f("report.html")),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(f("stereo.json")).unwrap()).unwrap();
    let num = |x: &serde_json::Value| x.as_f64().unwrap();
    let page = std::fs::read_to_string(f("report.html")).unwrap();
    let status = v["verdict"]["status"].as_str().unwrap();
    assert!(page.contains(&format!("class=\"verdict v-{status}\"")), "the stereo report opens with its verdict");
    let (b, sb) = (num(&v["baseline_mm"]), num(&v["baseline_std_mm"]));
    assert!((b - 83.435).abs() < 3.0 * sb, "baseline {b} +- {sb} mm vs OpenCV's 83.435 mm");
    let rect = &v["rectification"];
    let row_rms = num(&rect["row_rms_px"]);
    assert!(row_rms < 0.5 && rect["n_corner_pairs"].as_u64() == Some(13 * 54), "row RMS {row_rms} px, {rect}");
    assert!((num(&rect["baseline_mm"]) - b).abs() < 1e-9);

    // The files read back to the JSON's numbers.
    let pair = io::read_opencv_stereo_yaml(&f("stereo.yml")).unwrap();
    assert_eq!(pair.left.intrinsics.fx_px, num(&v["left"]["fx"]));
    assert_eq!(pair.right.intrinsics.cy_px, num(&v["right"]["cy"]));
    assert!((pair.t_m.norm() * 1e3 - b).abs() < 1e-9);
    for (i, t) in v["translation_mm"].as_array().unwrap().iter().enumerate() {
        assert!((pair.t_m[i] * 1e3 - num(t)).abs() < 1e-9);
    }
    for (i, row) in rect["P2"].as_array().unwrap().iter().enumerate() {
        for (j, x) in row.as_array().unwrap().iter().enumerate() {
            assert_eq!(pair.rectification.p2[(i, j)], num(x), "P2[{i}][{j}]");
        }
    }
    let l = io::read_ros_camera_info(&f("left.yaml")).unwrap();
    let r = io::read_ros_camera_info(&f("right.yaml")).unwrap();
    assert_eq!((l.camera, r.camera), (pair.left, pair.right));
    assert_eq!((l.rectification, l.projection), (pair.rectification.r1, pair.rectification.p1));
    assert_eq!((r.rectification, r.projection), (pair.rectification.r2, pair.rectification.p2));
    // ROS: P2[0][3] = -fx' B with B in metres.
    assert!((r.projection[(0, 3)] + r.projection[(0, 0)] * b * 1e-3).abs() < 1e-9);

    // The report: both cameras' figures, the rig in 3-D, the rectification check.
    let html = std::fs::read_to_string(f("report.html")).unwrap();
    assert!(html.matches("<svg").count() >= 10, "report figures");
    // The rig and the board poses as one 3-D view that turns.
    assert_eq!(html.matches("class=\"scene3d\"").count(), 1, "3-D view");
    for s in ["Left camera: Reprojection error per view", "Right camera: Residuals", "The rig and the board poses"] {
        assert!(html.contains(s), "{s}");
    }
    assert!(html.contains(&format!("row difference RMS {row_rms:.4} px")));
    assert!(!dir.read_dir().unwrap().any(|e| e.unwrap().file_name().to_string_lossy().contains(".tmp")));

    // An output over an input image is refused before anything is written.
    let image = data.join("left01.jpg");
    let before = std::fs::metadata(&image).unwrap().len();
    let out = ferrocal(&[
        "camera",
        "stereo",
        "--left",
        path(&left),
        "--right",
        path(&right),
        "--pattern",
        "chessboard:9x6:25mm",
        "--corners",
        "opencv",
        "--opencv-stereo-yaml",
        path(&image),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("left01.jpg") && err.contains("input"), "{err}");
    assert_eq!(std::fs::metadata(&image).unwrap().len(), before);
    std::fs::remove_dir_all(&dir).ok();
}
