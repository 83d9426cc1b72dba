//! `diagnose` for a camera: simulated views (exact projections plus corner noise) with and
//! without a lens or target effect the default calibration leaves out.

use ferrocal_calib::diagnose::camera::{diagnose_camera, CameraDiagnoseOptions};
use ferrocal_vision::calib::{PlanarTarget, View};
use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};
use nalgebra::{Isometry3, Point2, Point3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

fn camera(distortion: Distortion) -> CameraModel {
    CameraModel::new(
        Intrinsics { fx_px: 700.0, fy_px: 700.0, cx_px: 641.0, cy_px: 479.0 },
        distortion,
        ImageSize { width_px: 1280, height_px: 960 },
    )
    .unwrap()
}

/// Views of a 9x6 board (30 mm squares) bent by `sag_m` (bowl), seen by `cam`.
fn views(cam: &CameraModel, sag_m: f64, seed: u64) -> (Vec<View>, PlanarTarget) {
    views_spread(cam, sag_m, seed, 0.12)
}

/// As [`views`], with the board centres spread laterally up to `spread_m`.
fn views_spread(cam: &CameraModel, sag_m: f64, seed: u64, spread_m: f64) -> (Vec<View>, PlanarTarget) {
    let target = PlanarTarget::chessboard(9, 6, 0.03);
    let c = target.points_m.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / target.points_m.len() as f64;
    let half = target.points_m.iter().map(|p| (p.x - c.x).abs().max((p.y - c.y).abs())).fold(0.0, f64::max);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.05).unwrap();
    let mut out = Vec::new();
    while out.len() < 16 {
        let tilt = rng.random_range(15f64..45.0).to_radians();
        let dir = rng.random_range(0.0..std::f64::consts::TAU);
        let rot = UnitQuaternion::from_scaled_axis(Vector3::new(dir.cos(), dir.sin(), 0.0) * tilt)
            * UnitQuaternion::from_scaled_axis(Vector3::z() * rng.random_range(-0.3..0.3));
        let t = Vector3::new(
            rng.random_range(-spread_m..spread_m),
            rng.random_range(-0.7 * spread_m..0.7 * spread_m),
            rng.random_range(0.35..0.6),
        );
        let pose = Isometry3::from_parts(Translation3::from(t), rot) * Isometry3::translation(-c.x, -c.y, 0.0);
        let mut px = Vec::new();
        let mut ok = true;
        for p in &target.points_m {
            let (u, v) = ((p.x - c.x) / half, (p.y - c.y) / half);
            let q = Point3::new(p.x, p.y, sag_m * (u * u + v * v));
            match cam.project(&(pose * q)) {
                Ok(x) if cam.contains_pixel(&x) => {
                    px.push(Point2::new(x.x + noise.sample(&mut rng), x.y + noise.sample(&mut rng)))
                }
                _ => ok = false,
            }
        }
        if ok {
            out.push(View::new(format!("view{}", out.len() + 1), cam.image_size, px));
        }
    }
    (out, target)
}

fn brown() -> Distortion {
    Distortion::Brown5 { k1: -0.28, k2: 0.09, p1: 0.0005, p2: -0.0003, k3: -0.01 }
}

#[test]
fn nothing_to_find_when_the_default_model_holds() {
    let (v, t) = views(&camera(brown()), 0.0, 1);
    let r = diagnose_camera(&v, &t, &CameraDiagnoseOptions::default()).unwrap();
    eprintln!("no effect: held-out {:.4} px, candidates {:?}", r.nominal.heldout_rms_px, r.candidates);
    assert!(r.findings.is_empty(), "{:?}", r.findings);
    assert!(r.nominal.heldout_rms_px < 0.1);
    assert!(!r.unexplained.structure_found, "{:?}", r.unexplained);
}

#[test]
fn structure_no_candidate_explains_is_reported_with_what_it_depends_on() {
    // A sensor defect no lens or target model describes: corners in the image's right quarter
    // appear 0.3 px lower (e.g. a tile of a multi-tap sensor read out with a row offset).
    let cam = camera(brown());
    let (mut v, t) = views_spread(&cam, 0.0, 5, 0.2);
    for view in &mut v {
        for p in &mut view.corners_px {
            if p.x > 0.75 * 1280.0 {
                p.y += 0.3;
            }
        }
    }
    let r = diagnose_camera(&v, &t, &CameraDiagnoseOptions::default()).unwrap();
    eprintln!(
        "tile offset: {:?} findings {:?}",
        r.unexplained,
        r.findings.iter().map(|f| &f.effect).collect::<Vec<_>>()
    );
    assert!(r.unexplained.structure_found, "{:?}", r.unexplained);
    assert!(r.unexplained.depends_on.iter().any(|d| d == "image position"), "{:?}", r.unexplained);
}

#[test]
fn a_bent_target_is_found() {
    let (v, t) = views(&camera(brown()), 0.0008, 2);
    let r = diagnose_camera(&v, &t, &CameraDiagnoseOptions::default()).unwrap();
    eprintln!("bent: {:?}", r.findings.iter().map(|f| &f.statement).collect::<Vec<_>>());
    assert_eq!(r.findings.len(), 1, "{:?}", r.candidates);
    assert_eq!(r.findings[0].effect, "target_nonflatness");
    let bowl = r.findings[0].parameters["bowl_sag_m"];
    assert!((bowl - 0.0008).abs() < 0.0002, "bowl sag {bowl}");
    assert!(r.findings[0].heldout_rms_after_px < r.findings[0].heldout_rms_before_px);
}

#[test]
fn a_lens_the_five_coefficients_cannot_describe_is_found() {
    // A wide-angle (fisheye) lens: 1280 px across at fx = 420 px is a 113 deg field.
    let mut cam = camera(Distortion::KannalaBrandt { k1: -0.02, k2: 0.01, k3: -0.004, k4: 0.001 });
    cam.intrinsics.fx_px = 420.0;
    cam.intrinsics.fy_px = 420.0;
    let (v, t) = views_spread(&cam, 0.0, 3, 0.4);
    let r = diagnose_camera(&v, &t, &CameraDiagnoseOptions::default()).unwrap();
    eprintln!(
        "lens: nominal held-out {:.4} px; {:?}",
        r.nominal.heldout_rms_px,
        r.findings.iter().map(|f| &f.statement).collect::<Vec<_>>()
    );
    assert!(!r.findings.is_empty(), "{:?}", r.candidates);
    assert_eq!(r.findings[0].effect, "lens_distortion");
    assert!(r.findings.iter().all(|f| f.effect != "target_nonflatness"), "{:?}", r.findings);
}

#[test]
fn too_few_views_declines() {
    let (v, t) = views(&camera(brown()), 0.0, 4);
    let r = diagnose_camera(&v[..4], &t, &CameraDiagnoseOptions::default()).unwrap();
    assert!(r.findings.is_empty() && r.declined.as_deref().is_some_and(|d| d.contains("at least 6")));
}
