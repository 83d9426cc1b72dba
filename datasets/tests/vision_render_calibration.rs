//! Camera calibration end to end on rendered images: the physically modelled renderer draws a
//! chessboard (blur, vignetting, shot and read noise), OpenCV finds the corners, ferrocal
//! calibrates; the result is compared with the renderer's exact camera.

use crate::calib_support;

use calib_support as sim;
use ferrocal_datasets::render::{RenderConfig, Renderer, TargetConfig};
use ferrocal_vision::calib::corners::{chessboard_corners_opencv_gray, SubpixWindow};
use ferrocal_vision::calib::{calibrate_camera, CalibrationOptions, PlanarTarget, View};
use nalgebra::Point3;

#[test]
fn rendered_chessboard_views_calibrate_to_the_true_camera() {
    let camera = sim::vga_camera();
    let config = TargetConfig::Chessboard { inner_cols: 9, inner_rows: 6, square_m: 0.025, margin_m: 0.02 };
    let renderer = Renderer::new(camera, &config, RenderConfig::default()).unwrap();
    // Poses keep the whole plate (corners and outline) in view.
    let geometry = renderer.target();
    let mut plate: Vec<Point3<f64>> = geometry.corners.iter().map(|c| c.p_target_m).collect();
    plate.extend(geometry.outline_m.iter().map(|p| Point3::new(p.x, p.y, 0.0)));
    let plate = PlanarTarget { points_m: plate, reversible: false };
    let mut rng = sim::rng(4);
    let mut views = Vec::new();
    let mut worst_px: f64 = 0.0;
    for i in 0..14 {
        let t = sim::random_calibration_pose(&mut rng, &camera, &plate, (0.3, 0.6), (15.0, 40.0));
        let out = renderer.render(&t, 100 + i).unwrap();
        let Some(corners) = chessboard_corners_opencv_gray(&out.image, 9, 6, SubpixWindow::Adaptive).unwrap() else {
            continue;
        };
        // Detector error against the exact corners (either numbering direction).
        let truth: Vec<_> = out.truth.corners.iter().map(|c| c.pixel.unwrap()).collect();
        let err = |rev: bool| {
            (0..truth.len())
                .map(|k| (corners[if rev { truth.len() - 1 - k } else { k }] - truth[k]).norm())
                .fold(0.0f64, f64::max)
        };
        worst_px = worst_px.max(err(false).min(err(true)));
        views.push(View::new(format!("render{i:02}"), camera.image_size, corners));
    }
    assert!(views.len() >= 12, "board found in {} of 14 renderings", views.len());
    let board = PlanarTarget::chessboard(9, 6, 0.025);
    let cal = calibrate_camera(&views, &board, &CalibrationOptions::default()).unwrap();
    let est = cal.camera.parameters();
    println!("worst detected corner {worst_px:.3} px; RMS {:.4} px; s0 {:.4} px", cal.rms_px, cal.summary.s0_px);
    for (i, p) in camera.parameters().iter().enumerate() {
        println!(
            "{:>6}: true {:>11.5}  estimated {:>11.5} +- {:.5}  ({:+.2} sigma)",
            p.name,
            p.value,
            est[i].value,
            cal.std[i],
            (est[i].value - p.value) / cal.std[i]
        );
    }
    assert!(cal.rms_px < 0.1, "rms {}", cal.rms_px);
    // Focal lengths and principal point within 4 sigma (the detector's small systematic corner
    // errors are not in the noise model), and within a pixel.
    for ((e, t), s) in est.iter().zip(camera.parameters()).zip(&cal.std).take(4) {
        let d = (e.value - t.value).abs();
        assert!(d < 4.0 * s && d < 1.0, "{}: off by {d} px (std {s})", e.name);
    }
}
