//! `diagnose` for a camera on rendered images of a chessboard printed 0.5 % too long along its
//! x axis, and of the same board printed to scale.
//!
//! The physics of the print error lives in the renderer: the board's printed geometry (plate,
//! squares, corners) is stretched by `TargetGeometry::printed` before it is drawn, and OpenCV
//! finds the corners in the 8-bit images (blur, vignetting, shot and read noise). The diagnosis
//! knows only the nominal board. Its `target_print_scale` candidate models the same family of
//! effect (a per-axis scale of the printed spacing), so the test checks that this candidate is
//! chosen over the lens and flatness candidates and sized right, not that the model family is
//! the only one that could explain such images.

use crate::calib_support;

use calib_support as sim;
use ferrocal_calib::diagnose::camera::{diagnose_camera, CameraDiagnoseOptions, CameraDiagnoseReport};
use ferrocal_datasets::render::{RenderConfig, Renderer, TargetConfig};
use ferrocal_vision::calib::corners::{chessboard_corners_opencv_gray, SubpixWindow};
use ferrocal_vision::calib::{PlanarTarget, View};
use nalgebra::{Isometry3, Point3, Vector3};

const VIEWS: usize = 12;

/// Renders `VIEWS` views of the 9x6 board (25 mm squares) printed with `scale_x` along x, finds
/// the corners and diagnoses them against the nominal board. Poses and noise depend on the seed
/// only (the same for both prints); every other board is turned 90 deg in its plane, as one does
/// when calibrating.
fn diagnose_rendered(scale_x: f64) -> CameraDiagnoseReport {
    let camera = sim::vga_camera();
    let config = TargetConfig::Chessboard { inner_cols: 9, inner_rows: 6, square_m: 0.025, margin_m: 0.02 };
    let nominal = config.build().unwrap();
    let renderer =
        Renderer::with_geometry(camera, nominal.printed(scale_x, 0.0).unwrap(), RenderConfig::default()).unwrap();
    // The whole plate (corners and outline) stays in view.
    let mut plate: Vec<Point3<f64>> = nominal.corners.iter().map(|c| c.p_target_m).collect();
    plate.extend(nominal.outline_m.iter().map(|p| Point3::new(p.x * 1.01, p.y * 1.01, 0.0)));
    let plate = PlanarTarget { points_m: plate, reversible: false };
    let mut rng = sim::rng(21);
    let mut views = Vec::new();
    let mut attempt = 0;
    while views.len() < VIEWS {
        attempt += 1;
        assert!(attempt < 40, "only {} boards found in {attempt} renderings", views.len());
        let mut t = sim::random_calibration_pose(&mut rng, &camera, &plate, (0.32, 0.55), (15.0, 40.0));
        if views.len() % 2 == 1 {
            t *= Isometry3::rotation(Vector3::z() * std::f64::consts::FRAC_PI_2);
            if !sim::fully_visible(&camera, &plate, &t, 5.0) {
                continue;
            }
        }
        let out = renderer.render(&t, 300 + attempt).unwrap();
        if let Some(corners) = chessboard_corners_opencv_gray(&out.image, 9, 6, SubpixWindow::Adaptive).unwrap() {
            views.push(View::new(format!("render{attempt:02}"), camera.image_size, corners));
        }
    }
    let board = PlanarTarget::chessboard(9, 6, 0.025);
    diagnose_camera(&views, &board, &CameraDiagnoseOptions::default()).unwrap()
}

fn effects(r: &CameraDiagnoseReport) -> Vec<&str> {
    r.findings.iter().map(|f| f.effect.as_str()).collect()
}

#[test]
fn a_board_printed_half_a_percent_long_in_x_is_found_as_a_print_scale() {
    let r = diagnose_rendered(0.005);
    println!("printed 0.5 % long in x: {:?}\ncandidates {:#?}", r.findings, r.candidates);
    assert_eq!(effects(&r), ["target_print_scale"], "{:#?}", r.candidates);
    let f = &r.findings[0];
    let e = f.parameters["scale_x_minus_y"];
    // The detector's corner errors (blur, noise) are not in the truth: 10 % of the effect.
    assert!((e - 0.005).abs() < 5e-4, "estimated {e}, printed 0.005");
    assert!(f.heldout_rms_after_px < 0.8 * f.heldout_rms_before_px, "{f:?}");
    assert!(f.statement.contains("ppm") && f.statement.contains("x axis") && f.statement.contains("longer"));
}

#[test]
fn a_board_printed_to_scale_gives_no_finding() {
    let r = diagnose_rendered(0.0);
    println!("printed to scale: held-out {:.4} px; candidates {:#?}", r.nominal.heldout_rms_px, r.candidates);
    assert!(r.findings.is_empty(), "{:?}", effects(&r));
}
