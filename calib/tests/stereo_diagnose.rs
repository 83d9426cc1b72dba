//! `diagnose` for a stereo pair: simulated pairs of views with known truth. The data are exact
//! projections plus Gaussian corner noise (0.05 px) of a 9x6 chessboard (30 mm squares), bent
//! (or not) by the bowl of the diagnosis's own target model (`z = b (u^2 + v^2)`, `u, v` the
//! in-plane offset from the centroid over the half-size), seen by a rig of two pinhole cameras
//! with OpenCV-model lenses (Brown 5-coefficient, or the rational 8-coefficient model for a
//! wide-angle right camera) 120 mm apart, slightly toed in.

use ferrocal_calib::diagnose::camera::CameraDiagnoseOptions;
use ferrocal_calib::diagnose::stereo::{diagnose_stereo, StereoDiagnoseReport};
use ferrocal_vision::calib::{PlanarTarget, View};
use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};
use nalgebra::{Isometry3, Point2, Point3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

fn camera(f_px: f64, distortion: Distortion) -> CameraModel {
    CameraModel::new(
        Intrinsics { fx_px: f_px, fy_px: f_px, cx_px: 641.0, cy_px: 479.0 },
        distortion,
        ImageSize { width_px: 1280, height_px: 960 },
    )
    .unwrap()
}

fn brown() -> Distortion {
    Distortion::Brown5 { k1: -0.28, k2: 0.09, p1: 0.0005, p2: -0.0003, k3: -0.01 }
}

/// `T_cam1_cam0`: camera 1 120 mm to the right of camera 0, turned `toe_deg` towards it.
fn t_cam1_cam0(toe_deg: f64) -> Isometry3<f64> {
    let rot = UnitQuaternion::from_scaled_axis(Vector3::y() * (-toe_deg).to_radians());
    Isometry3::from_parts(Translation3::new(-0.12, 0.0, 0.0), rot)
}

/// Pairs of views.
type Pairs = (Vec<Option<View>>, Vec<Option<View>>, PlanarTarget);

/// `n` pairs of views of the board bent by `sag_m` (bowl) seen by `cams` (both images show the
/// whole board), target poses drawn from `seed`.
fn pairs(cams: [&CameraModel; 2], sag_m: f64, seed: u64, n: usize) -> Pairs {
    pairs_spread(cams, sag_m, seed, n, (1.0, 4.0))
}

/// As [`pairs`], with the board's lateral positions spread `spread` times as far (towards the
/// image borders) and camera 1 turned `toe_deg` towards camera 0.
fn pairs_spread(cams: [&CameraModel; 2], sag_m: f64, seed: u64, n: usize, (spread, toe_deg): (f64, f64)) -> Pairs {
    let target = PlanarTarget::chessboard(9, 6, 0.03);
    let c = target.points_m.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / target.points_m.len() as f64;
    let half = target.points_m.iter().map(|p| (p.x - c.x).abs().max((p.y - c.y).abs())).fold(0.0, f64::max);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.05).unwrap();
    let rig = [Isometry3::identity(), t_cam1_cam0(toe_deg)];
    let (mut left, mut right) = (Vec::new(), Vec::new());
    while left.len() < n {
        let tilt = rng.random_range(15f64..45.0).to_radians();
        let dir = rng.random_range(0.0..std::f64::consts::TAU);
        let rot = UnitQuaternion::from_scaled_axis(Vector3::new(dir.cos(), dir.sin(), 0.0) * tilt)
            * UnitQuaternion::from_scaled_axis(Vector3::z() * rng.random_range(-0.3..0.3));
        let t = Vector3::new(
            0.06 + spread * rng.random_range(-0.11..0.11),
            spread * rng.random_range(-0.1..0.1),
            rng.random_range(0.4..0.65),
        );
        let pose = Isometry3::from_parts(Translation3::from(t), rot) * Isometry3::translation(-c.x, -c.y, 0.0);
        let views: Vec<Option<View>> = (0..2)
            .map(|k| {
                let mut px = Vec::new();
                for p in &target.points_m {
                    let (u, v) = ((p.x - c.x) / half, (p.y - c.y) / half);
                    let q = Point3::new(p.x, p.y, sag_m * (u * u + v * v));
                    match cams[k].project(&(rig[k] * pose * q)) {
                        Ok(x) if cams[k].contains_pixel(&x) => {
                            px.push(Point2::new(x.x + noise.sample(&mut rng), x.y + noise.sample(&mut rng)))
                        }
                        _ => return None,
                    }
                }
                Some(View::new(format!("{}{:02}", ["left", "right"][k], left.len() + 1), cams[k].image_size, px))
            })
            .collect();
        if views.iter().all(Option::is_some) {
            left.push(views[0].clone());
            right.push(views[1].clone());
        }
    }
    (left, right, target)
}

fn effects(r: &StereoDiagnoseReport) -> Vec<(&str, Option<usize>)> {
    r.findings.iter().map(|f| (f.effect.as_str(), f.camera)).collect()
}

#[test]
fn nothing_to_find_when_the_default_model_holds() {
    let (c0, c1) = (camera(700.0, brown()), camera(720.0, brown()));
    let (l, r, t) = pairs([&c0, &c1], 0.0, 1, 12);
    let rep = diagnose_stereo(&l, &r, &t, &CameraDiagnoseOptions::default()).unwrap();
    eprintln!(
        "nominal pair: held-out {:.4} px; baseline {:.2} mm; candidates {:#?}",
        rep.nominal.heldout_rms_px, rep.baseline_mm, rep.candidates
    );
    assert!(rep.findings.is_empty(), "{:?}", rep.findings);
    assert_eq!(rep.n_pairs, 12);
    assert!(rep.nominal.heldout_rms_px < 0.1, "{}", rep.nominal.heldout_rms_px);
    assert!((rep.baseline_mm - 120.0).abs() < 1.0, "baseline {} mm", rep.baseline_mm);
    assert!(!rep.unexplained.structure_found, "{:?}", rep.unexplained);
}

#[test]
fn a_bent_target_is_found_once_for_both_cameras() {
    let sag_m = 0.0008;
    let (c0, c1) = (camera(700.0, brown()), camera(720.0, brown()));
    let (l, r, t) = pairs([&c0, &c1], sag_m, 2, 12);
    let rep = diagnose_stereo(&l, &r, &t, &CameraDiagnoseOptions::default()).unwrap();
    eprintln!("bent: {:#?}\ncandidates {:#?}", rep.findings, rep.candidates);
    assert_eq!(effects(&rep), [("target_nonflatness", None)], "{:#?}", rep.candidates);
    let f = &rep.findings[0];
    let (bowl, std) = (f.parameters["bowl_sag_m"], f.parameters_std["bowl_sag_m"]);
    assert!(std > 0.0 && std < 0.0001, "std {std}");
    assert!((bowl - sag_m).abs() < 3.0 * std, "bowl {bowl} +- {std} m, truth {sag_m} m");
    assert!(f.heldout_rms_after_px < 0.8 * f.heldout_rms_before_px, "{f:?}");
}

#[test]
fn a_fisheye_lens_on_one_camera_is_found_for_that_camera_only() {
    // Camera 1: a fisheye (Kannala-Brandt, nearly equidistant: fx = 420 px over 1280 px is a
    // 170 deg field), turned 50 deg towards camera 0 so that the boards both cameras see lie in
    // its outer field, where the 5-coefficient model cannot follow it; camera 0 as in the other
    // tests (Brown).
    let c0 = camera(700.0, brown());
    let c1 = camera(420.0, Distortion::KannalaBrandt { k1: -0.02, k2: 0.01, k3: -0.004, k4: 0.001 });
    let (l, r, t) = pairs_spread([&c0, &c1], 0.0, 3, 12, (1.0, 50.0));
    let rep = diagnose_stereo(&l, &r, &t, &CameraDiagnoseOptions::default()).unwrap();
    eprintln!(
        "fisheye right lens: held-out {:.4} px; {:#?}\ncandidates {:#?}",
        rep.nominal.heldout_rms_px, rep.findings, rep.candidates
    );
    assert!(!rep.findings.is_empty(), "{:#?}", rep.candidates);
    assert_eq!(effects(&rep)[0], ("lens_distortion", Some(1)), "{:#?}", rep.candidates);
    assert!(
        rep.findings.iter().all(|f| f.camera != Some(0) && f.effect != "target_nonflatness"),
        "{:?}",
        effects(&rep)
    );
}

#[test]
fn too_few_pairs_declines() {
    let c = camera(700.0, brown());
    let (l, r, t) = pairs([&c, &c], 0.0, 4, 5);
    let rep = diagnose_stereo(&l, &r, &t, &CameraDiagnoseOptions::default()).unwrap();
    assert!(rep.findings.is_empty() && rep.declined.as_deref().is_some_and(|d| d.contains("at least 6")), "{rep:?}");
}
