//! Simulated calibration scenes shared by the calibration and pose tests (and the studies in
//! `datasets/examples/vision_*.rs`, which include this file): cameras, random board poses that
//! keep the board in view, and corners projected exactly plus Gaussian noise.
#![allow(dead_code)]

use ferrocal_vision::calib::{PlanarTarget, View};
use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};
use nalgebra::{Isometry3, Point2, Point3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// A deterministic random source (ChaCha8, as the conventions require).
pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// A VGA camera like OpenCV's stereo sample (fx != fy slightly, Brown 5).
pub fn vga_camera() -> CameraModel {
    CameraModel::new(
        Intrinsics { fx_px: 536.1, fy_px: 535.4, cx_px: 341.7, cy_px: 236.2 },
        Distortion::Brown5 { k1: -0.27, k2: 0.05, p1: 0.0018, p2: -0.0003, k3: 0.08 },
        ImageSize { width_px: 640, height_px: 480 },
    )
    .unwrap()
}

/// A 5 MP machine-vision camera: 2448 x 2048 px of 3.45 um behind a 16 mm lens (fx about
/// 4640 px), mild barrel distortion.
pub fn camera_5mp(variant: u32) -> CameraModel {
    let d = f64::from(variant);
    CameraModel::new(
        Intrinsics {
            fx_px: 4638.0 + 3.0 * d,
            fy_px: 4638.9 + 2.0 * d,
            cx_px: 1226.4 - 5.0 * d,
            cy_px: 1021.8 + 4.0 * d,
        },
        Distortion::Brown5 { k1: -0.082 + 0.01 * d, k2: 0.21, p1: 2.1e-4, p2: -1.3e-4, k3: -0.35 },
        ImageSize { width_px: 2448, height_px: 2048 },
    )
    .unwrap()
}

/// The centroid of a target's points.
pub fn centre(target: &PlanarTarget) -> Vector3<f64> {
    target.points_m.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / target.points_m.len() as f64
}

/// `T_cam_target` with the target's centre at `centre_cam`, its face towards the camera,
/// tilted by `tilt_rad` about the in-plane axis at `axis_angle_rad` and rolled by `roll_rad`.
pub fn board_pose(
    target: &PlanarTarget,
    centre_cam: Vector3<f64>,
    tilt_rad: f64,
    axis_angle_rad: f64,
    roll_rad: f64,
) -> Isometry3<f64> {
    let face = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    let roll = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), roll_rad);
    let axis = nalgebra::Unit::new_normalize(Vector3::new(axis_angle_rad.cos(), axis_angle_rad.sin(), 0.0));
    let tilt = UnitQuaternion::from_axis_angle(&axis, tilt_rad);
    let r = tilt * roll * face;
    let t = centre_cam - r * centre(target);
    Isometry3::from_parts(Translation3::from(t), r)
}

/// Whether every target point projects inside the image with `margin_px` to spare.
pub fn fully_visible(camera: &CameraModel, target: &PlanarTarget, t: &Isometry3<f64>, margin_px: f64) -> bool {
    let (w, h) = (camera.image_size.width_px as f64, camera.image_size.height_px as f64);
    target.points_m.iter().all(|p| {
        let q = t * p;
        q.z > 0.0
            && camera.project(&q).is_ok_and(|u| {
                u.x >= margin_px && u.y >= margin_px && u.x <= w - 1.0 - margin_px && u.y <= h - 1.0 - margin_px
            })
    })
}

/// A random calibration pose: depth in `depth_m`, tilt in `tilt_deg` about a random in-plane
/// axis, any roll within +-30 deg, the board anywhere in the image (fully visible).
pub fn random_calibration_pose(
    rng: &mut ChaCha8Rng,
    camera: &CameraModel,
    target: &PlanarTarget,
    depth_m: (f64, f64),
    tilt_deg: (f64, f64),
) -> Isometry3<f64> {
    let k = camera.intrinsics;
    for _ in 0..10_000 {
        let z = rng.random_range(depth_m.0..depth_m.1);
        let u = rng.random_range(0.0..camera.image_size.width_px as f64);
        let v = rng.random_range(0.0..camera.image_size.height_px as f64);
        let c = Vector3::new((u - k.cx_px) / k.fx_px * z, (v - k.cy_px) / k.fy_px * z, z);
        let tilt = rng.random_range(tilt_deg.0..tilt_deg.1).to_radians();
        let axis = rng.random_range(0.0..std::f64::consts::TAU);
        let roll = rng.random_range(-30.0f64..30.0).to_radians();
        let t = board_pose(target, c, tilt, axis, roll);
        if fully_visible(camera, target, &t, 5.0) {
            return t;
        }
    }
    panic!("no visible board pose found: depth range too small for the board?");
}

/// The target's corners seen by `camera` at `t_cam_target`, exact plus isotropic Gaussian
/// noise of `sigma_px`; only points inside the image (and in front of the camera) are kept.
pub fn observe(
    rng: &mut ChaCha8Rng,
    name: &str,
    camera: &CameraModel,
    target: &PlanarTarget,
    t_cam_target: &Isometry3<f64>,
    sigma_px: f64,
) -> View {
    let noise = Normal::new(0.0, sigma_px.max(1e-300)).unwrap();
    let mut ids = Vec::new();
    let mut corners = Vec::new();
    for (i, p) in target.points_m.iter().enumerate() {
        let q: Point3<f64> = t_cam_target * p;
        if q.z <= 0.0 {
            continue;
        }
        let Ok(u) = camera.project(&q) else { continue };
        if !camera.contains_pixel(&u) {
            continue;
        }
        let (nx, ny) = if sigma_px > 0.0 { (noise.sample(rng), noise.sample(rng)) } else { (0.0, 0.0) };
        ids.push(i);
        corners.push(Point2::new(u.x + nx, u.y + ny));
    }
    View { name: name.to_string(), image_size: camera.image_size, point_ids: ids, corners_px: corners }
}

/// `n` calibration views of `target` by `camera`.
pub fn calibration_views(
    rng: &mut ChaCha8Rng,
    camera: &CameraModel,
    target: &PlanarTarget,
    n: usize,
    depth_m: (f64, f64),
    sigma_px: f64,
) -> Vec<View> {
    (0..n)
        .map(|i| {
            let t = random_calibration_pose(rng, camera, target, depth_m, (15.0, 45.0));
            observe(rng, &format!("view{i:02}"), camera, target, &t, sigma_px)
        })
        .collect()
}

/// `T_world_cam` of a camera at `eye` looking at `at` (camera y roughly along `down`).
pub fn look_at(eye: Vector3<f64>, at: Vector3<f64>, down: Vector3<f64>) -> Isometry3<f64> {
    let z = (at - eye).normalize();
    let x = down.cross(&z).normalize();
    let y = z.cross(&x);
    let r = nalgebra::Rotation3::from_matrix_unchecked(nalgebra::Matrix3::from_columns(&[x, y, z]));
    Isometry3::from_parts(Translation3::from(eye), UnitQuaternion::from_rotation_matrix(&r))
}

/// The stereo cell of the pose tests and studies: two 5 MP cameras 1 m apart, 2.5 m from a 1 m
/// workspace; calibration from a large board, measurement of a small target.
pub mod cell {
    use super::{self as sim};
    use ferrocal_vision::calib::{calibrate_stereo, CalibrationOptions, PlanarTarget, View};
    use ferrocal_vision::pose::{estimate_pose_rig, CornerNoise, RigObservation};
    use nalgebra::{Isometry3, Vector3};
    use rand::Rng;

    /// The cell: `T_world_cam` of both cameras (world origin at the workspace centre).
    pub fn cameras_in_world() -> [Isometry3<f64>; 2] {
        let down = Vector3::new(0.0, 1.0, 0.0);
        [
            sim::look_at(Vector3::new(-0.5, -0.2, -2.45), Vector3::zeros(), down),
            sim::look_at(Vector3::new(0.5, -0.2, -2.45), Vector3::zeros(), down),
        ]
    }

    /// A pose of `target` with its centre at `p_world`, facing the cameras (target z towards -z
    /// world) and tilted up to `max_tilt_deg` about a random axis.
    pub fn target_in_world(
        rng: &mut impl Rng,
        target: &PlanarTarget,
        p_world: Vector3<f64>,
        tilt_deg: (f64, f64),
    ) -> Isometry3<f64> {
        let tilt = rng.random_range(tilt_deg.0..tilt_deg.1).to_radians();
        let axis = rng.random_range(0.0..std::f64::consts::TAU);
        let roll = rng.random_range(-0.5..0.5);
        sim::board_pose(target, p_world, tilt, axis, roll)
    }

    /// The two cameras and where they are.
    pub struct Cell {
        pub cams: [ferrocal_vision::camera::CameraModel; 2],
        pub t_world_cam: [Isometry3<f64>; 2],
    }

    impl Cell {
        pub fn new() -> Self {
            Self { cams: [sim::camera_5mp(0), sim::camera_5mp(1)], t_world_cam: cameras_in_world() }
        }

        pub fn t_cam_world(&self, k: usize) -> Isometry3<f64> {
            self.t_world_cam[k].inverse()
        }

        /// Both cameras' views of a target at `t_world_target`.
        pub fn observe(
            &self,
            rng: &mut rand_chacha::ChaCha8Rng,
            name: &str,
            target: &PlanarTarget,
            t_world_target: &Isometry3<f64>,
            sigma_px: f64,
        ) -> [View; 2] {
            [0, 1].map(|k| {
                sim::observe(
                    rng,
                    &format!("{name}_cam{k}"),
                    &self.cams[k],
                    target,
                    &(self.t_cam_world(k) * t_world_target),
                    sigma_px,
                )
            })
        }
    }

    pub fn random_in_cube(rng: &mut impl Rng, half_m: f64) -> Vector3<f64> {
        Vector3::new(
            rng.random_range(-half_m..half_m),
            rng.random_range(-half_m..half_m),
            rng.random_range(-half_m..half_m),
        )
    }

    /// Calibrates the pair from `n` views of a 13 x 9 board with 60 mm squares placed through the
    /// workspace.
    pub fn calibrate(cell: &Cell, seed: u64, n: usize, sigma_px: f64) -> ferrocal_vision::calib::StereoCalibration {
        let board = PlanarTarget::chessboard(13, 9, 0.06);
        let mut rng = sim::rng(seed);
        let (mut left, mut right) = (Vec::new(), Vec::new());
        while left.len() < n {
            let p = random_in_cube(&mut rng, 0.4);
            let t = target_in_world(&mut rng, &board, p, (15.0, 40.0));
            let [a, b] = cell.observe(&mut rng, &format!("calib{:02}", left.len()), &board, &t, sigma_px);
            // Keep views where each camera sees most of the board.
            if a.corners_px.len() < 80 || b.corners_px.len() < 80 {
                continue;
            }
            left.push(Some(a));
            right.push(Some(b));
        }
        calibrate_stereo(&left, &right, &board, &CalibrationOptions::default()).unwrap()
    }

    /// What measuring `n` target poses all over the workspace with `rig` gave.
    pub struct Measured {
        /// Mean and max error of the target centre in cam0, millimetres.
        pub mean_mm: f64,
        pub max_mm: f64,
        /// The same after the best rigid alignment of the measured set onto the truth (what a
        /// kinematic calibration that identifies the camera-to-base frame sees).
        pub aligned_mean_mm: f64,
        pub aligned_max_mm: f64,
        /// Errors of the distances between all pairs of target positions.
        pub distance_mean_mm: f64,
        /// Mean normalised squared error of the reported position against its covariance.
        pub mean_nees: f64,
        /// Mean predicted position sigma from corner noise alone and in total, millimetres.
        pub sigma_corners_mm: f64,
        pub sigma_total_mm: f64,
    }

    pub fn measure(
        cell: &Cell,
        rig: &ferrocal_vision::pose::CameraRig,
        seed: u64,
        n: usize,
        sigma_px: f64,
    ) -> Measured {
        // The measured target: 7 x 5 inner corners, 40 mm squares.
        let target = PlanarTarget::chessboard(7, 5, 0.04);
        let c = nalgebra::Point3::from(sim::centre(&target));
        let mut rng = sim::rng(seed);
        let (mut errs, mut nees, mut sc, mut st) = (Vec::new(), 0.0, 0.0, 0.0);
        let (mut measured, mut true_pts) = (Vec::new(), Vec::new());
        while errs.len() < n {
            let p = random_in_cube(&mut rng, 0.5);
            let t_world_target = target_in_world(&mut rng, &target, p, (0.0, 25.0));
            let views = cell.observe(&mut rng, "m", &target, &t_world_target, sigma_px);
            if views.iter().any(|v| v.corners_px.len() < 35) {
                continue; // not fully in view of both cameras
            }
            let obs: Vec<RigObservation> = views
                .iter()
                .enumerate()
                .map(|(k, v)| RigObservation {
                    camera: k,
                    point_ids: v.point_ids.clone(),
                    corners_px: v.corners_px.clone(),
                    noise: CornerNoise::Isotropic { sigma_px },
                })
                .collect();
            let est = estimate_pose_rig(rig, &target.points_m, &obs).unwrap();
            let truth = cell.t_cam_world(0) * t_world_target;
            let (m, t) = ((est.t_cam_target * c).coords * 1e3, (truth * c).coords * 1e3);
            errs.push((m - t).norm());
            measured.push(m);
            true_pts.push(t);
            let e_origin = est.position_mm - truth.translation.vector * 1e3;
            let cov_p = est.covariance.fixed_view::<3, 3>(0, 0).into_owned();
            nees += (e_origin.transpose() * cov_p.try_inverse().unwrap() * e_origin)[(0, 0)];
            sc += (est.covariance_corners.fixed_view::<3, 3>(0, 0).trace() / 3.0).sqrt();
            st += (cov_p.trace() / 3.0).sqrt();
        }
        let aligned = rigid_fit_residuals(&measured, &true_pts);
        let mut dist = Vec::new();
        for i in 0..n {
            for j in i + 1..n {
                dist.push(((measured[i] - measured[j]).norm() - (true_pts[i] - true_pts[j]).norm()).abs());
            }
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let max = |v: &[f64]| v.iter().fold(0.0f64, |a, b| a.max(*b));
        Measured {
            mean_mm: mean(&errs),
            max_mm: max(&errs),
            aligned_mean_mm: mean(&aligned),
            aligned_max_mm: max(&aligned),
            distance_mean_mm: mean(&dist),
            mean_nees: nees / n as f64,
            sigma_corners_mm: sc / n as f64,
            sigma_total_mm: st / n as f64,
        }
    }

    /// Distances (mm) between `a` and `b` after the rigid transform that best maps `a` onto `b`
    /// (Kabsch).
    pub fn rigid_fit_residuals(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> Vec<f64> {
        let n = a.len() as f64;
        let ca = a.iter().sum::<Vector3<f64>>() / n;
        let cb = b.iter().sum::<Vector3<f64>>() / n;
        let mut h = nalgebra::Matrix3::zeros();
        for (p, q) in a.iter().zip(b) {
            h += (p - ca) * (q - cb).transpose();
        }
        let svd = h.svd(true, true);
        let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
        let mut d = nalgebra::Matrix3::identity();
        d[(2, 2)] = (vt.transpose() * u.transpose()).determinant().signum();
        let r = vt.transpose() * d * u.transpose();
        a.iter().zip(b).map(|(p, q)| (r * (p - ca) + cb - q).norm()).collect()
    }
}
