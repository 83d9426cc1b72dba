//! The commands' own behaviour through the built binary: a bad image does not stop `detect`,
//! `dynamics identify` refuses a quasi-static model, `stiffness identify` takes any serial arm
//! and refuses a parallel robot.

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
