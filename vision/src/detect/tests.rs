//! Unit tests of the detectors' internals on procedural images.

use nalgebra::Vector2;

use super::grid::grow_grids;
use super::plate::{apply_h, homography4};
use super::xcorner::{find_xcorners, XCornerOptions};
use super::*;
use crate::detect::synth;

#[test]
fn xcorners_and_grid_of_a_chessboard() {
    let scene = synth::chessboard_scene(640, 480, 7, 5, 45.0, 2, 1.0, 2.0);
    let img = synth::render(&scene);
    let truth = synth::chessboard_truth(&scene);
    let f = GrayF32::from_gray8(&img).unwrap();
    let cands = find_xcorners(&f, &XCornerOptions::default(), None).unwrap();
    for t in &truth {
        let best = cands.iter().map(|c| (c.p - t.coords).norm()).fold(f64::INFINITY, f64::min);
        assert!(best < 0.3, "no candidate near {t:?} ({best})");
    }
    let grids = grow_grids(&cands, 4, 4, 100, (640.0, 480.0), Some(35));
    assert_eq!(grids[0].at.len(), 35);
    assert!((grids[0].rows, grids[0].cols) == (5, 7) || (grids[0].rows, grids[0].cols) == (7, 5));
}

/// A board seen upside down is labelled as printed: a 9 x 6 board's colours tell its
/// orientation (corner 0 is then at the bottom right of the image).
#[test]
fn chessboard_labels_follow_the_print_not_the_image() {
    let pattern: Pattern = "chessboard:9x6:25mm".parse().unwrap();
    let mut scene = synth::chessboard_scene(640, 480, 9, 6, 40.0, 0, 1.0, 1.0);
    let f = 1.2 * 640.0;
    scene.h = synth::homography(f, 319.5, 239.5, (7, 10), 0.025, f * 0.025 / 40.0, 183.0, 8.0, -6.0, (0.0, 0.0));
    let img = synth::render(&scene);
    let truth = synth::chessboard_truth(&scene);
    let d = detect(&img, &pattern, &DetectOptions::default(), None).unwrap();
    assert!(truth[0].x > 320.0 && truth[0].y > 240.0);
    for (c, t) in d[0].corners.iter().zip(&truth) {
        assert!((c.position_px - t).norm() < 0.05);
    }
    assert_eq!(d[0].corners[10].grid_index, Some([1, 1]));
    let t = d[0].corners[0].target_m.unwrap();
    assert!((t.x + 0.1).abs() < 1e-12 && (t.y - 0.0625).abs() < 1e-12);
}

#[test]
fn homography_of_four_points() {
    let src = [Vector2::new(0.0, 0.0), Vector2::new(1.0, 0.0), Vector2::new(0.0, 1.0), Vector2::new(1.0, 1.0)];
    let dst = [Vector2::new(10.0, 20.0), Vector2::new(50.0, 22.0), Vector2::new(12.0, 60.0), Vector2::new(55.0, 65.0)];
    let h = homography4(&src, &dst).unwrap();
    for (s, d) in src.iter().zip(&dst) {
        assert!((apply_h(&h, s.x, s.y) - d).norm() < 1e-9);
    }
}

#[test]
fn apriltag_board_layout_matches_the_renderer() {
    // ferrocal_datasets: tag (r, c) centred at ((c - (cols-1)/2) pitch, ((rows-1)/2 - r) pitch),
    // corners bottom-left, bottom-right, top-right, top-left.
    let board: Pattern = "aprilboard:3x2:60mm:20mm:10".parse().unwrap();
    let at = apriltag::board_target(&board).unwrap();
    let t = |id: u32| id.checked_sub(10).and_then(&at);
    assert!(t(9).is_none() && t(16).is_none());
    let c = t(14).unwrap(); // r = 1, c = 1
    assert!((c[0].x - (-0.03)).abs() < 1e-12 && (c[0].y - (-0.04 - 0.03)).abs() < 1e-12);
    assert!((c[2].x - 0.03).abs() < 1e-12 && (c[2].y - (-0.04 + 0.03)).abs() < 1e-12);
}

#[test]
fn kalibr_aprilgrid_layout() {
    // Kalibr: tag k at row k / cols from the bottom, column k % cols; origin at the bottom-left
    // corner of tag 0's black border; pitch = tag (1 + tagSpacing).
    let grid: Pattern = "aprilgrid:6x6:80mm:0.25".parse().unwrap();
    let at = apriltag::board_target(&grid).unwrap();
    let c0 = at(0).unwrap();
    assert!(c0[0].coords.norm() < 1e-12 && (c0[2].x - 0.08).abs() < 1e-12 && (c0[2].y - 0.08).abs() < 1e-12);
    let c = at(7).unwrap(); // r = 1, c = 1: bottom-left corner at (100, 100) mm
    assert!((c[0].x - 0.1).abs() < 1e-12 && (c[0].y - 0.1).abs() < 1e-12);
    assert!(at(36).is_none());
    assert_eq!(grid.target_points_m().unwrap().len(), 144);
}

#[test]
fn empty_and_blank_images() {
    let pattern: Pattern = "plate:40mm".parse().unwrap();
    let empty = GrayImage::new(0, 0);
    assert!(matches!(detect(&empty, &pattern, &DetectOptions::default(), None), Err(VisionError::BadImage { .. })));
    let blank = GrayImage::from_pixel(64, 48, ::image::Luma([200]));
    let e = detect(&blank, &pattern, &DetectOptions::default(), None).unwrap_err().to_string();
    assert!(e.contains("not found"), "{e}");
    let tags: Pattern = "apriltag:tag36h11".parse().unwrap();
    assert!(matches!(detect(&blank, &tags, &DetectOptions::default(), None), Err(VisionError::PatternNotFound { .. })));
    // A background of the wrong size is a clear error, not a panic.
    let small = GrayImage::from_pixel(10, 10, ::image::Luma([0]));
    assert!(detect(&blank, &pattern, &DetectOptions::default(), Some(&small)).is_err());
    assert!(median_background(&[]).is_err());
    assert!(median_background(&[blank.clone(), small]).is_err());
}
