use nalgebra::{Translation3, UnitQuaternion};

use super::*;
use ferrocal_vision::camera::{ImageSize, Intrinsics};

fn camera(w: u32, h: u32, f: f64, distortion: Distortion) -> CameraModel {
    CameraModel::new(
        Intrinsics { fx_px: f, fy_px: 1.01 * f, cx_px: 0.5 * w as f64 - 3.7, cy_px: 0.5 * h as f64 + 2.1 },
        distortion,
        ImageSize { width_px: w, height_px: h },
    )
    .unwrap()
}

fn brown() -> Distortion {
    Distortion::Brown5 { k1: -0.21, k2: 0.04, p1: 8e-4, p2: -5e-4, k3: 0.0 }
}

fn board() -> PrintedChessboard {
    PrintedChessboard { inner_cols: 9, inner_rows: 6, square_m: 0.1, margin_m: 0.05 }
}

#[test]
fn the_lens_inversion_and_projection_agree_with_the_camera_model() {
    let cam = camera(1280, 960, 1100.0, brown());
    let r = SupersampledRenderer::new(cam, board(), SupersampledConfig::default()).unwrap();
    for j in (0..=960).step_by(60) {
        for i in (0..=1280).step_by(80) {
            let px = Point2::new(i as f64 - 0.5, j as f64 - 0.5);
            let n = r.back_project(&px).unwrap();
            let back = cam.project(&Point3::new(n.x, n.y, 1.0)).unwrap();
            assert!((back - px).norm() < 1e-8, "{px:?}: {back:?}");
            let theirs = cam.unproject_normalized(&px).unwrap();
            assert!((theirs - n).norm() < 1e-11, "{px:?}: {n:?} vs {theirs:?}");
            let pose = Isometry3::translation(0.0, 0.0, 2.0);
            let p = Point3::new(2.0 * n.x, 2.0 * n.y, 0.0);
            let fwd = r.project(&pose, &p).unwrap();
            assert!((fwd - px).norm() < 1e-8, "{px:?}: {fwd:?}");
        }
    }
}

#[test]
fn the_board_layout_has_a_dark_top_left_square_and_a_white_margin() {
    let b = board();
    assert_eq!(b.surface(0.05, 0.05), Surface::Dark);
    assert_eq!(b.surface(0.15, 0.05), Surface::White);
    assert_eq!(b.surface(0.15, 0.15), Surface::Dark);
    assert_eq!(b.surface(-0.01, 0.3), Surface::White);
    assert_eq!(b.surface(1.04, 0.69), Surface::White);
    assert_eq!(b.surface(-0.06, 0.3), Surface::Background);
    assert_eq!(b.surface(0.5, 0.76), Surface::Background);
    // 10 x 7 squares: the bottom-right square (row 6, column 9) is white.
    assert_eq!(b.surface(0.95, 0.65), Surface::White);
    assert_eq!(b.inner_corners().len(), 54);
    assert_eq!(b.inner_corner(1, 2), Point3::new(0.30000000000000004, 0.2, 0.0));
}

#[test]
fn a_flat_field_has_the_expected_mean_and_noise() {
    let cam = camera(160, 120, 200.0, brown());
    // Only the margin in view: every sub-sample sees white.
    let b = PrintedChessboard { inner_cols: 2, inner_rows: 2, square_m: 0.01, margin_m: 1.0 };
    let config = SupersampledConfig { subsamples: 3, psf_sigma_px: 0.0, vignetting: 0.0, ..Default::default() };
    let r = SupersampledRenderer::new(cam, b, config.clone()).unwrap();
    let pose = Isometry3::translation(0.5, 0.5, 0.5);
    let rho = r.render_reflectance(&pose, 1).unwrap();
    assert!(rho.iter().all(|v| (v - config.white).abs() < 1e-12));
    // The background alone: the board far to the side; the sensor's mean and spread.
    let away = Isometry3::translation(100.0, 0.0, 1.0);
    let img = r.render(&away, 7).unwrap();
    let vals: Vec<f64> = img.as_raw().iter().map(|&v| f64::from(v)).collect();
    let mean = vals.iter().sum::<f64>() / vals.len() as f64;
    let var = vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (vals.len() - 1) as f64;
    let e = config.exposure_e * config.background;
    let expected_mean = e / config.gain_e_per_dn + config.black_level_dn;
    let expected_var = (e + config.read_noise_e.powi(2)) / config.gain_e_per_dn.powi(2) + 1.0 / 12.0;
    // 19 200 pixels: the mean to 4 standard errors, the variance to about 5 %.
    assert!(
        (mean - expected_mean).abs() < 4.0 * (expected_var / vals.len() as f64).sqrt(),
        "{mean} vs {expected_mean}"
    );
    assert!((var / expected_var - 1.0).abs() < 0.05, "{var} vs {expected_var}");
    // Vignetting: the corners receive (1 - a) of the centre's light.
    let vig = SupersampledConfig { vignetting: 0.2, ..config };
    let r = SupersampledRenderer::new(cam, b, vig).unwrap();
    let ex = r.render_expected(&away, 1).unwrap();
    let (centre, corner) = (ex[60 * 160 + 80], ex[0]);
    assert!((corner / ex[0] - 1.0).abs() < 1e-12 && (corner / centre - 0.8).abs() < 0.01, "{corner} / {centre}");
}

/// Area of the part of pixel `(i, j)` where the affine function `a u + b v + c` is negative.
fn clipped_area(i: usize, j: usize, a: f64, b: f64, c: f64) -> f64 {
    let (u0, v0) = (i as f64 - 0.5, j as f64 - 0.5);
    let square = [(u0, v0), (u0 + 1.0, v0), (u0 + 1.0, v0 + 1.0), (u0, v0 + 1.0)];
    let f = |p: (f64, f64)| a * p.0 + b * p.1 + c;
    let mut poly = Vec::new();
    for k in 0..4 {
        let (p, q) = (square[k], square[(k + 1) % 4]);
        let (fp, fq) = (f(p), f(q));
        if fp < 0.0 {
            poly.push(p);
        }
        if (fp < 0.0) != (fq < 0.0) {
            let t = fp / (fp - fq);
            poly.push((p.0 + t * (q.0 - p.0), p.1 + t * (q.1 - p.1)));
        }
    }
    let n = poly.len();
    (0..n).map(|k| poly[k].0 * poly[(k + 1) % n].1 - poly[(k + 1) % n].0 * poly[k].1).sum::<f64>().abs() * 0.5
}

/// Signed coverage errors of the pixels cut by the edge between the top-left (dark) square and
/// its right neighbour, on a fronto-parallel board turned by 20 degrees (pinhole, 1 px = 1 mm).
fn edge_errors(subsamples: u32, seed: u64) -> Vec<f64> {
    let cam = CameraModel::new(
        Intrinsics { fx_px: 1000.0, fy_px: 1000.0, cx_px: 31.5, cy_px: 31.5 },
        Distortion::None,
        ImageSize { width_px: 64, height_px: 64 },
    )
    .unwrap();
    let config = SupersampledConfig { subsamples, ..Default::default() };
    let r = SupersampledRenderer::new(cam, board(), config.clone()).unwrap();
    let rot = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 20f64.to_radians());
    // The image centre looks at board point (0.1, 0.05): on the edge x = 0.1.
    let centre = rot * Vector3::new(0.1, 0.05, 0.0);
    let pose = Isometry3::from_parts(Translation3::new(-centre.x, -centre.y, 1.0), rot);
    let rho = r.render_reflectance(&pose, seed).unwrap();
    // Board x of pixel (u, v): ex . (d - t) with d = ((u - c) / f, (v - c) / f, 1), affine.
    let ex = rot * Vector3::x();
    let t = pose.translation.vector;
    let (a, b) = (ex.x / 1000.0, ex.y / 1000.0);
    let c = ex.dot(&(Vector3::new(-31.5 / 1000.0, -31.5 / 1000.0, 1.0) - t)) - 0.1;
    let mut errors = Vec::new();
    for j in 0..64 {
        for i in 0..64 {
            let cover = clipped_area(i, j, a, b, c);
            let expected = config.white + (config.dark - config.white) * cover;
            let err = (rho[j * 64 + i] - expected) / (config.dark - config.white);
            if cover > 0.0 && cover < 1.0 {
                errors.push(err);
            } else {
                assert!(err.abs() < 1e-12, "pixel ({i}, {j}) not on the edge: {err}");
            }
        }
    }
    errors
}

#[test]
fn pixels_cut_by_an_edge_have_the_analytic_coverage() {
    for (s, max_mean_abs, max_abs) in [(4u32, 0.05, 0.2), (8, 0.025, 0.1), (16, 0.012, 0.05)] {
        let e = edge_errors(s, 3);
        assert!(e.len() > 60, "{} edge pixels", e.len());
        let mean = e.iter().sum::<f64>() / e.len() as f64;
        let mean_abs = e.iter().map(|v| v.abs()).sum::<f64>() / e.len() as f64;
        let worst = e.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        // Unbiased: the edge is not displaced (the signed mean is a small fraction of 1/S^2).
        assert!(mean.abs() < 0.25 / (s * s) as f64 + 0.002, "S = {s}: mean error {mean}");
        assert!(mean_abs < max_mean_abs && worst < max_abs, "S = {s}: mean |error| {mean_abs}, worst {worst}");
    }
}

#[test]
fn the_blur_keeps_the_light_and_has_the_requested_width() {
    let (w, h) = (41, 41);
    let mut img = vec![0.0; w * h];
    img[20 * w + 20] = 1.0;
    gaussian_blur(&mut img, w, h, 1.3);
    let total: f64 = img.iter().sum();
    let var: f64 = (0..w * h).map(|k| img[k] * ((k % w) as f64 - 20.0).powi(2)).sum();
    assert!((total - 1.0).abs() < 1e-12 && (var - 1.69).abs() < 1e-3, "{total} {var}");
}

#[test]
fn renders_are_deterministic_for_a_seed() {
    let cam = camera(96, 72, 90.0, brown());
    let b = PrintedChessboard { inner_cols: 4, inner_rows: 3, square_m: 0.05, margin_m: 0.02 };
    let config = SupersampledConfig { subsamples: 2, jpeg_quality: Some(92), ..Default::default() };
    let r = SupersampledRenderer::new(cam, b, config).unwrap();
    let pose = Isometry3::translation(-0.125, -0.1, 0.5);
    let a = r.render(&pose, 5).unwrap();
    assert_eq!(a, r.render(&pose, 5).unwrap());
    assert_ne!(a, r.render(&pose, 6).unwrap());
    // The back of the board is refused.
    let back =
        Isometry3::from_parts(Translation3::new(0.0, 0.0, 0.5), UnitQuaternion::from_euler_angles(3.0, 0.0, 0.0));
    assert!(r.render(&back, 1).is_err());
}
