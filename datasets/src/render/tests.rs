//! Tests of the renderer against geometry and the noise model, and parity with the AprilTag C
//! detector and OpenCV's chessboard detector.

use super::*;
use ferrocal_vision::camera::{Distortion, ImageSize, Intrinsics};
use nalgebra::{Translation3, UnitQuaternion, Vector3};

fn camera(distortion: Distortion, w: u32, h: u32, f: f64) -> CameraModel {
    CameraModel::new(
        Intrinsics { fx_px: f, fy_px: f * 1.0005, cx_px: 0.5 * w as f64 - 0.3, cy_px: 0.5 * h as f64 + 0.7 },
        distortion,
        ImageSize { width_px: w, height_px: h },
    )
    .unwrap()
}

/// The OpenCV sample's lens (brief), scaled to the given focal length.
fn brown() -> Distortion {
    Distortion::Brown5 { k1: -0.26637, k2: -0.038589, p1: 0.0017832, p2: -0.00028122, k3: 0.23839 }
}

fn fisheye() -> Distortion {
    Distortion::KannalaBrandt { k1: -0.0135, k2: 0.0120, k3: -0.0085, k4: 0.0017 }
}

/// Target facing the camera (target z towards the camera), rotated `roll_deg` about the optical
/// axis and tilted `tilt_deg` about the camera's y axis, origin at `(x, y, z)` metres.
fn pose(x: f64, y: f64, z: f64, roll_deg: f64, tilt_deg: f64) -> Isometry3<f64> {
    let face = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    let roll = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), roll_deg.to_radians());
    let tilt = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), tilt_deg.to_radians());
    Isometry3::from_parts(Translation3::new(x, y, z), tilt * roll * face)
}

/// Where the image of the target line `x = x_m` crosses the row centre `v` (bisection along
/// the line).
fn edge_truth_u(cam: &CameraModel, t: &Isometry3<f64>, x_m: f64, y_lo: f64, y_hi: f64, v: f64) -> f64 {
    let px = |yt: f64| cam.project(&t.transform_point(&Point3::new(x_m, yt, 0.0))).unwrap();
    let (mut lo, mut hi) = (y_lo, y_hi);
    let s_lo = (px(lo).y - v).signum();
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if (px(mid).y - v).signum() == s_lo {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    px(0.5 * (lo + hi)).x
}

/// Area estimator of a white-to-black edge in one row: with `I'` the intensity normalised to
/// 1 (white, left) and 0 (black, right) over columns `a..=b`, the edge lies at
/// `a - 0.5 + sum I'`.
fn area_estimate(values: &[f64], a: usize, white: f64, black: f64) -> f64 {
    a as f64 - 0.5 + values.iter().map(|v| (v - black) / (white - black)).sum::<f64>()
}

/// Vertical weights of the PSF: how much each neighbouring row contributes to a row. Blur
/// along a row preserves the row's area sum, so the area estimate of a blurred row is the
/// weighted mean of the unblurred rows' estimates.
fn vertical_weights(psf: Psf) -> Vec<(i64, f64)> {
    match psf {
        Psf::None => vec![(0, 1.0)],
        Psf::Gaussian { sigma_px } => {
            let k = optics::gaussian_kernel(sigma_px);
            let r = (k.len() / 2) as i64;
            k.iter().enumerate().map(|(i, w)| (i as i64 - r, f64::from(*w))).collect()
        }
        Psf::Disc { radius_px } => {
            let (k, r) = optics::disc_kernel(radius_px);
            let n = 2 * r + 1;
            (0..n).map(|j| (j as i64 - r as i64, k[j * n..(j + 1) * n].iter().map(|w| f64::from(*w)).sum())).collect()
        }
    }
}

struct EdgeErrors {
    /// Against the exact expectation of the estimator (row-averaged edge, PSF row weights).
    linear_px: f64,
    /// Against the edge position at the row centre (what a user compares with).
    linear_vs_point_px: f64,
    /// 8-bit image (quantised, noise off) against the exact expectation.
    quantised_px: f64,
}

/// Renders the plate with its centre square's left edge (target x = -s/2, white field left,
/// black square right) near-vertical, and compares the per-row area estimate with geometry:
/// the edge's mean column over the row (16 sub-rows), mixed over rows by the PSF's vertical
/// weights.
fn edge_errors(cam: CameraModel, psf: Psf, t: Isometry3<f64>) -> EdgeErrors {
    let s = 0.1;
    let mut config = RenderConfig::ideal();
    config.optics.psf = psf;
    let target = TargetConfig::Plate { square_m: s, margin_m: 0.05 };
    let r = Renderer::new(cam, &target, config.clone()).unwrap();
    let lin = r.render_expected(&t).unwrap();
    let img = r.render(&t, 1).unwrap().image;
    let exposure = config.sensor.exposure_e;
    let white = exposure * config.scene.white_reflectance;
    let black = exposure * config.scene.black_reflectance;
    let g = config.sensor.gain_e_per_dn;
    let b = config.sensor.black_level_dn;
    let weights = vertical_weights(psf);
    let reach = weights.iter().map(|(k, _)| k.abs()).max().unwrap_or(0) as usize;
    let half_window = 6 + reach + 1;
    // Rows that see the middle 60 % of the edge.
    let v_a = cam.project(&t.transform_point(&Point3::new(-0.5 * s, 0.3 * s, 0.0))).unwrap().y;
    let v_b = cam.project(&t.transform_point(&Point3::new(-0.5 * s, -0.3 * s, 0.0))).unwrap().y;
    let (v0, v1) = (v_a.min(v_b).ceil() as i64, v_a.max(v_b).floor() as i64);
    assert!(v1 > v0 + 20, "too few rows {v0}..{v1}");
    let point = |v: f64| edge_truth_u(&cam, &t, -0.5 * s, -0.5 * s, 0.5 * s, v);
    let row_mean = |v: i64| (0..16).map(|m| point(v as f64 - 0.5 + (m as f64 + 0.5) / 16.0)).sum::<f64>() / 16.0;
    let means: std::collections::HashMap<i64, f64> =
        (v0 - reach as i64..=v1 + reach as i64).map(|v| (v, row_mean(v))).collect();
    let mut errors = EdgeErrors { linear_px: 0.0, linear_vs_point_px: 0.0, quantised_px: 0.0 };
    for v in v0..=v1 {
        let expected: f64 =
            weights.iter().map(|(k, w)| w * means[&(v + k)]).sum::<f64>() / weights.iter().map(|(_, w)| w).sum::<f64>();
        let a = (expected.round() as usize) - half_window;
        let cols = a..=a + 2 * half_window;
        let lin_row: Vec<f64> = cols.clone().map(|u| f64::from(lin.get(u as u32, v as u32).unwrap())).collect();
        let q_row: Vec<f64> = cols.map(|u| f64::from(img.get_pixel(u as u32, v as u32).0[0])).collect();
        let est = area_estimate(&lin_row, a, white, black);
        let est_q = area_estimate(&q_row, a, (white / g + b).round(), (black / g + b).round());
        errors.linear_px = errors.linear_px.max((est - expected).abs());
        errors.linear_vs_point_px = errors.linear_vs_point_px.max((est - point(v as f64)).abs());
        errors.quantised_px = errors.quantised_px.max((est_q - expected).abs());
    }
    errors
}

#[test]
fn edge_position_matches_geometry_to_0_005_px() {
    let cases = [
        ("pinhole", camera(Distortion::None, 640, 480, 800.0), pose(0.013, -0.021, 1.0, 2.0, 8.0)),
        ("brown5", camera(brown(), 640, 480, 540.0), pose(-0.18, 0.09, 0.9, 3.0, -12.0)),
        ("kannala-brandt", camera(fisheye(), 640, 480, 300.0), pose(-0.25, 0.12, 0.6, -4.0, 15.0)),
    ];
    let psfs = [Psf::None, Psf::Gaussian { sigma_px: 1.2 }, Psf::Disc { radius_px: 1.8 }];
    for (name, cam, t) in cases {
        for psf in psfs {
            let e = edge_errors(cam, psf, t);
            println!(
                "{name:15} {psf:?}: max |edge error| {:.1e} px (exact expectation), {:.1e} px (row-centre \
                 point), {:.1e} px (8-bit)",
                e.linear_px, e.linear_vs_point_px, e.quantised_px
            );
            assert!(e.linear_px < 1e-4, "{name} {psf:?}: {} px", e.linear_px);
            assert!(e.linear_vs_point_px < 0.005, "{name} {psf:?}: {} px", e.linear_vs_point_px);
            assert!(e.quantised_px < 0.05, "{name} {psf:?}: {} px", e.quantised_px);
        }
    }
}

/// Mean and variance of a flat grey patch against `E[DN] = S/g + b`,
/// `Var[DN] = (S + r^2)/g^2 + 1/12`, within 5 standard errors.
#[test]
fn noise_statistics_match_the_sensor_model() {
    let cam = camera(Distortion::None, 320, 240, 400.0);
    let target = TargetConfig::Plate { square_m: 0.05, margin_m: 0.01 };
    // The target lies far to the side: the image shows only the background.
    let t = pose(8.0, 0.0, 1.0, 0.0, 0.0);
    for shot in [ShotNoise::Gaussian, ShotNoise::Poisson, ShotNoise::Off] {
        let mut config = RenderConfig::ideal();
        config.scene.background_reflectance = 0.5;
        config.sensor = SensorConfig {
            exposure_e: 4000.0,
            full_well_e: 20000.0,
            gain_e_per_dn: 10.0,
            black_level_dn: 4.0,
            read_noise_e: 9.0,
            shot_noise: shot,
            jpeg_quality: None,
        };
        let r = Renderer::new(cam, &target, config.clone()).unwrap();
        let img = r.render(&t, 42).unwrap().image;
        let n = img.as_raw().len() as f64;
        let mean = img.as_raw().iter().map(|v| f64::from(*v)).sum::<f64>() / n;
        let var = img.as_raw().iter().map(|v| (f64::from(*v) - mean).powi(2)).sum::<f64>() / (n - 1.0);
        let s = 2000.0;
        let sc = &config.sensor;
        let shot_var = if shot == ShotNoise::Off { 0.0 } else { s };
        let want_mean = s / sc.gain_e_per_dn + sc.black_level_dn;
        let want_var = (shot_var + sc.read_noise_e.powi(2)) / sc.gain_e_per_dn.powi(2) + 1.0 / 12.0;
        let se_mean = (want_var / n).sqrt();
        let se_var = want_var * (2.0 / (n - 1.0)).sqrt();
        println!(
            "{shot:?}: mean {mean:.4} DN (model {want_mean:.4} +- {se_mean:.4}), variance {var:.4} DN^2 (model {want_var:.4} +- {se_var:.4})"
        );
        assert!((mean - want_mean).abs() < 5.0 * se_mean, "{shot:?} mean");
        assert!((var - want_var).abs() < 5.0 * se_var, "{shot:?} variance");
    }
}

#[test]
fn saturation_and_clipping() {
    let cam = camera(Distortion::None, 64, 48, 100.0);
    let target = TargetConfig::Plate { square_m: 0.05, margin_m: 0.01 };
    let t = pose(8.0, 0.0, 1.0, 0.0, 0.0);
    let mut config = RenderConfig::ideal();
    config.sensor.exposure_e = 1e6;
    let img = Renderer::new(cam, &target, config.clone()).unwrap().render(&t, 0).unwrap().image;
    // Full well 10 500 e- / 40 e-/DN + 4 = 266.5 DN: clipped at 255.
    assert!(img.as_raw().iter().all(|v| *v == 255));
    config.sensor.exposure_e = 0.0;
    config.sensor.black_level_dn = 0.0;
    config.sensor.read_noise_e = 30.0;
    let img = Renderer::new(cam, &target, config).unwrap().render(&t, 0).unwrap().image;
    assert!(img.as_raw().contains(&0));
}

fn plate_scene(jpeg: Option<u8>) -> (Renderer, Isometry3<f64>) {
    let mut config = RenderConfig::default();
    config.sensor.jpeg_quality = jpeg;
    config.scene.illumination = Illumination { gradient_x: 0.2, gradient_y: -0.1, quadratic: -0.15 };
    let cam = camera(brown(), 320, 240, 300.0);
    let r = Renderer::new(cam, &TargetConfig::Plate { square_m: 0.04, margin_m: 0.015 }, config).unwrap();
    (r, pose(0.01, -0.02, 0.5, 10.0, 20.0))
}

#[test]
fn rendering_is_deterministic_for_a_seed() {
    for jpeg in [None, Some(85)] {
        let (r, t) = plate_scene(jpeg);
        let a = r.render(&t, 7).unwrap();
        let b = r.render(&t, 7).unwrap();
        let c = r.render(&t, 8).unwrap();
        assert_eq!(a.image.as_raw(), b.image.as_raw());
        assert_ne!(a.image.as_raw(), c.image.as_raw());
        assert_eq!(a.truth, b.truth);
    }
    // JPEG changes pixels a little, not the picture.
    let (r, t) = plate_scene(None);
    let (rj, _) = plate_scene(Some(90));
    let plain = r.render(&t, 3).unwrap().image;
    let jpeg = rj.render(&t, 3).unwrap().image;
    let diff: f64 =
        plain.as_raw().iter().zip(jpeg.as_raw()).map(|(a, b)| (f64::from(*a) - f64::from(*b)).abs()).sum::<f64>()
            / plain.as_raw().len() as f64;
    assert!(diff > 0.0 && diff < 4.0, "mean |JPEG - plain| = {diff} DN");
}

#[test]
fn illumination_and_vignetting_shape_the_flat_field() {
    let cam = camera(Distortion::None, 200, 100, 150.0);
    let target = TargetConfig::Plate { square_m: 0.05, margin_m: 0.01 };
    let t = pose(8.0, 0.0, 1.0, 0.0, 0.0);
    let mut config = RenderConfig::ideal();
    config.scene.background_reflectance = 1.0;
    config.scene.illumination = Illumination { gradient_x: 0.3, gradient_y: 0.0, quadratic: 0.0 };
    config.optics.vignetting = Vignetting::Cos4 { focal_px: Some(150.0) };
    let r = Renderer::new(cam, &target, config.clone()).unwrap();
    let lin = r.render_expected(&t).unwrap();
    let k = cam.intrinsics;
    for (u, v) in [(0u32, 0u32), (199, 50), (100, 99), (37, 61)] {
        let x = (u as f64 - 99.5) / 100.0;
        let e = 1.0 + 0.3 * x;
        let r2 = (u as f64 - k.cx_px).powi(2) + (v as f64 - k.cy_px).powi(2);
        let vig = 1.0 / (1.0 + r2 / 150.0f64.powi(2)).powi(2);
        let want = config.sensor.exposure_e * e * vig;
        let got = f64::from(lin.get(u, v).unwrap());
        assert!((got - want).abs() < 1e-3 * want, "({u},{v}): {got} vs {want}");
    }
}

#[test]
fn ground_truth_and_bad_scenes() {
    let (r, t) = plate_scene(None);
    let truth = r.ground_truth(&t).unwrap();
    assert_eq!(truth.corners.len(), 20);
    assert!(truth.corners.iter().all(|c| c.in_image));
    for c in &truth.corners {
        let p = r.camera().project(&t.transform_point(&c.corner.p_target_m)).unwrap();
        assert_eq!(Some(p), c.pixel);
    }
    // Seen from the back.
    let back = t * Isometry3::rotation(Vector3::new(std::f64::consts::PI, 0.0, 0.0));
    assert!(matches!(r.render(&back, 0), Err(DatasetError::Render(_))));
    // A lens that folds inside the image.
    let folding = camera(Distortion::Brown5 { k1: -0.9, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0 }, 640, 480, 300.0);
    assert!(Renderer::new(folding, &TargetConfig::Plate { square_m: 0.04, margin_m: 0.01 }, RenderConfig::default())
        .is_err());
    // Bad configuration values.
    let mut bad = RenderConfig::default();
    bad.optics.psf = Psf::Gaussian { sigma_px: f64::NAN };
    assert!(matches!(bad.validate(), Err(DatasetError::RenderConfig { .. })));
    let mut bad = RenderConfig::default();
    bad.sensor.gain_e_per_dn = 0.0;
    assert!(bad.validate().is_err());
    let mut bad = RenderConfig::default();
    bad.sensor.jpeg_quality = Some(0);
    assert!(bad.validate().is_err());
    let mut bad = RenderConfig::default();
    bad.scene.white_reflectance = 1.5;
    assert!(bad.validate().is_err());
    // A target partly behind the camera renders (clipped) without error.
    let cam = camera(Distortion::None, 160, 120, 100.0);
    let r = Renderer::new(cam, &TargetConfig::Plate { square_m: 0.5, margin_m: 0.1 }, RenderConfig::default()).unwrap();
    let t = pose(0.0, 0.0, 0.2, 0.0, 70.0);
    let img = r.render(&t, 0).unwrap();
    assert!(img.truth.corners.iter().any(|c| !c.in_image));
}

#[test]
fn config_reads_from_toml_with_defaults() {
    let text = r#"
edge_tolerance_px = 0.001
[scene]
white_reflectance = 0.9
[optics]
psf = { kind = "disc", radius_px = 2.0 }
vignetting = { kind = "cos4", focal_px = 1200.0 }
[sensor]
shot_noise = "poisson"
jpeg_quality = 90
"#;
    let c: RenderConfig = toml::from_str(text).unwrap();
    assert_eq!(c.scene.white_reflectance, 0.9);
    assert_eq!(c.scene.black_reflectance, SceneConfig::default().black_reflectance);
    assert_eq!(c.optics.psf, Psf::Disc { radius_px: 2.0 });
    assert_eq!(c.sensor.shot_noise, ShotNoise::Poisson);
    assert_eq!(c.sensor.jpeg_quality, Some(90));
    c.validate().unwrap();
    let back: RenderConfig = toml::from_str(&toml::to_string(&c).unwrap()).unwrap();
    assert_eq!(back, c);
    assert!(toml::from_str::<RenderConfig>("[scene]\nwhite = 0.9\n").is_err());
}

/// The AprilTag C library finds every rendered tag with its id, and its corners (shifted by
/// -0.5 px to the pixel-centre convention) in the ground truth's order, within 0.3 px.
#[test]
fn apriltag_c_detector_reads_rendered_boards() {
    let cam = camera(brown(), 1024, 768, 860.0);
    let ids = vec![0u32, 5, 17, 42, 101, 586];
    let target = TargetConfig::AprilTagBoard {
        cols: 3,
        rows: 2,
        tag_size_m: 0.06,
        spacing_m: 0.02,
        first_id: 0,
        ids: Some(ids.clone()),
        margin_m: 0.02,
    };
    let r = Renderer::new(cam, &target, RenderConfig::default()).unwrap();
    let t = pose(0.02, -0.01, 0.55, 7.0, 15.0);
    let out = r.render(&t, 11).unwrap();
    let (w, h) = (out.image.width() as usize, out.image.height() as usize);
    let mut im = ::apriltag::Image::zeros_with_stride(w, h, w).unwrap();
    im.as_slice_mut().copy_from_slice(out.image.as_raw());
    let mut det =
        ::apriltag::DetectorBuilder::new().add_family_bits(::apriltag::Family::tag_36h11(), 1).build().unwrap();
    let found = det.detect(&im);
    let mut seen: Vec<u32> = found.iter().map(|d| d.id() as u32).collect();
    seen.sort_unstable();
    let mut want = ids.clone();
    want.sort_unstable();
    assert_eq!(seen, want);
    let mut worst: f64 = 0.0;
    for d in &found {
        let truth: Vec<_> = out.truth.corners.iter().filter(|c| c.corner.feature == d.id() as u32).collect();
        for (k, c) in d.corners().iter().enumerate() {
            let p = truth[k].pixel.unwrap();
            let e = (c[0] - 0.5 - p.x).hypot(c[1] - 0.5 - p.y);
            worst = worst.max(e);
        }
    }
    println!("AprilTag C detector vs ground truth: worst corner {worst:.3} px");
    assert!(worst < 0.3, "{worst}");
}

/// OpenCV's chessboard detector with `cornerSubPix` finds the rendered corners (in the same
/// row-by-row order, or reversed) within 0.1 px.
#[test]
fn opencv_chessboard_detector_reads_rendered_boards() {
    use opencv::core::{Mat, Point2f, Size, TermCriteria, Vector};
    use opencv::prelude::*;
    let cam = camera(Distortion::None, 800, 600, 900.0);
    let target = TargetConfig::Chessboard { inner_cols: 9, inner_rows: 6, square_m: 0.025, margin_m: 0.02 };
    let r = Renderer::new(cam, &target, RenderConfig::default()).unwrap();
    let t = pose(0.01, 0.005, 0.6, 4.0, 20.0);
    let out = r.render(&t, 5).unwrap();
    let (w, h) = (out.image.width() as i32, out.image.height() as i32);
    let flat = Mat::from_slice(out.image.as_raw()).unwrap();
    let img = flat.reshape(1, h).unwrap().try_clone().unwrap();
    assert_eq!(img.cols(), w);
    let mut corners: Vector<Point2f> = Vector::new();
    let found = opencv::calib3d::find_chessboard_corners(
        &img,
        Size::new(9, 6),
        &mut corners,
        opencv::calib3d::CALIB_CB_ADAPTIVE_THRESH | opencv::calib3d::CALIB_CB_NORMALIZE_IMAGE,
    )
    .unwrap();
    assert!(found);
    let criteria =
        TermCriteria::new(opencv::core::TermCriteria_COUNT + opencv::core::TermCriteria_EPS, 100, 1e-4).unwrap();
    opencv::imgproc::corner_sub_pix(&img, &mut corners, Size::new(5, 5), Size::new(-1, -1), criteria).unwrap();
    let truth: Vec<Point2<f64>> = out.truth.corners.iter().map(|c| c.pixel.unwrap()).collect();
    let err = |reverse: bool| {
        (0..truth.len())
            .map(|k| {
                let c = corners.get(if reverse { truth.len() - 1 - k } else { k }).unwrap();
                (f64::from(c.x) - truth[k].x).hypot(f64::from(c.y) - truth[k].y)
            })
            .fold(0.0f64, f64::max)
    };
    let worst = err(false).min(err(true));
    println!("OpenCV chessboard + cornerSubPix vs ground truth: worst corner {worst:.3} px");
    assert!(worst < 0.1, "{worst}");
}

/// Writes sample renderings for a person to look at (`cargo test -p ferrocal-datasets --lib
/// render::tests::write_samples -- --ignored`, PNGs in `FERROCAL_RENDER_OUT` or the temp dir).
#[test]
#[ignore]
fn write_samples() {
    let dir = std::env::var_os("FERROCAL_RENDER_OUT").map(std::path::PathBuf::from).unwrap_or_else(std::env::temp_dir);
    let cam = camera(brown(), 800, 600, 620.0);
    let scenes = [
        ("plate", TargetConfig::Plate { square_m: 0.05, margin_m: 0.02 }),
        ("chessboard", TargetConfig::Chessboard { inner_cols: 9, inner_rows: 6, square_m: 0.025, margin_m: 0.015 }),
        (
            "apriltag",
            TargetConfig::AprilTagBoard {
                cols: 4,
                rows: 3,
                tag_size_m: 0.05,
                spacing_m: 0.015,
                first_id: 0,
                ids: None,
                margin_m: 0.015,
            },
        ),
    ];
    let mut config = RenderConfig::default();
    config.scene.illumination = Illumination { gradient_x: 0.2, gradient_y: 0.0, quadratic: -0.1 };
    config.sensor.jpeg_quality = Some(80);
    for (name, target) in scenes {
        let r = Renderer::new(cam, &target, config.clone()).unwrap();
        let out = r.render(&pose(0.03, 0.02, 0.45, 8.0, 25.0), 1).unwrap();
        out.image.save(dir.join(format!("ferrocal_render_{name}.png"))).unwrap();
    }
}
