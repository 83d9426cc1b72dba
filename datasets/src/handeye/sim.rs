//! Simulated hand-eye recordings with known truth, and the Monte Carlo study of the hand-eye
//! covariance.
//!
//! The model family that generates the data is the one the estimator fits: a pinhole camera
//! with Brown-Conrady distortion, a flat chessboard-like grid of points with its nominal
//! spacing, the rigid chain of [`ferrocal_calib::handeye`], corner noise that is Gaussian with
//! the covariance handed to the estimator, and robot-pose noise that is Gaussian in the `Se3`
//! product chart (`t_reported = t + n_t`, `R_reported = Exp(n_r) R`) with the standard deviations
//! handed to the estimator. The study therefore checks the covariance computation, not the
//! robustness of the model to effects it leaves out.
//!
//! Geometry: eye-in-hand, the target lies face up 0.8 m in front of the robot and the camera
//! looks at it from 0.35 to 0.6 m, tilted by up to 35 degrees, with any roll; eye-to-hand, the
//! camera looks down at the workspace from 1 m and the target, 0.05 to 0.1 m off the flange,
//! faces it from 0.5 to 0.8 m, tilted by up to 35 degrees.

use nalgebra::{Isometry3, Matrix2, Point2, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

use ferrocal_calib::handeye::{calibrate_hand_eye, HandEyeData, HandEyeOptions, HandEyeView, IntrinsicsMode, Mount};
use ferrocal_calib::Split;
use ferrocal_vision::calib::CalibrationOptions;
use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};

use crate::error::{DatasetError, Result};

/// A simulated recording's settings.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HandEyeSimConfig {
    /// The mount.
    pub mount: Mount,
    /// Training images.
    pub n_train: usize,
    /// Held-out images.
    pub n_test: usize,
    /// Grid points per row and column of the target.
    pub grid: (u32, u32),
    /// Grid spacing, metres.
    pub spacing_m: f64,
    /// The true camera.
    pub camera: CameraModel,
    /// Standard deviation of each corner coordinate, pixels.
    pub corner_sigma_px: f64,
    /// Standard deviation of each reported flange position coordinate, metres.
    pub robot_sigma_m: f64,
    /// Standard deviation of each reported flange rotation-vector coordinate, radians.
    pub robot_sigma_rad: f64,
    /// The printed target's true spacing over the nominal one (1: printed exactly).
    pub print_scale: f64,
    /// Keep only views that show every grid point (for rendered images of a whole chessboard).
    pub full_view: bool,
    /// The printed x spacing over the printed y spacing (1: the same scale along both axes).
    pub print_aspect: f64,
    /// The target rolled about an axis parallel to its y axis through its centre, with this
    /// radius (metres; `None`: flat): a sheet bent this way keeps its printed lengths along the
    /// arc, so its corners lie on a cylinder (`x = R sin(a)`, `z = R (1 - cos a)`, `a = dx / R`),
    /// not on the quadratic bending model of the estimators.
    pub roll_radius_m: Option<f64>,
}

impl HandEyeSimConfig {
    /// A 1280 x 960 camera (f = 1100 px, mild barrel distortion), a 9 x 6 grid at 30 mm, 0.1 px
    /// corner noise, 0.05 mm and 0.005 degrees of robot-pose noise, 16 training and 8 test images.
    pub fn default_for(mount: Mount) -> Self {
        let camera = CameraModel {
            intrinsics: Intrinsics { fx_px: 1100.0, fy_px: 1102.0, cx_px: 645.0, cy_px: 478.0 },
            distortion: Distortion::Brown5 { k1: -0.08, k2: 0.05, p1: 0.0004, p2: -0.0003, k3: 0.0 },
            image_size: ImageSize { width_px: 1280, height_px: 960 },
        };
        Self {
            mount,
            n_train: 16,
            n_test: 8,
            grid: (9, 6),
            spacing_m: 0.03,
            camera,
            corner_sigma_px: 0.1,
            robot_sigma_m: 5e-5,
            robot_sigma_rad: 0.005f64.to_radians(),
            print_scale: 1.0,
            full_view: false,
            print_aspect: 1.0,
            roll_radius_m: None,
        }
    }
}

impl HandEyeSimConfig {
    /// Where the nominal grid point `p` really is on the target: printed at `print_scale` (and
    /// `print_aspect` along x), rolled onto the cylinder of `roll_radius_m` about the axis
    /// through the grid's `centre`.
    fn printed(&self, p: &Point3<f64>, centre: Vector3<f64>) -> Point3<f64> {
        let x = p.x * self.print_scale * self.print_aspect;
        let y = p.y * self.print_scale;
        let cx = centre.x * self.print_scale * self.print_aspect;
        match self.roll_radius_m {
            None => Point3::new(x, y, p.z),
            Some(r) => {
                let a = (x - cx) / r;
                Point3::new(cx + r * a.sin(), y, p.z + r * (1.0 - a.cos()))
            }
        }
    }
}

/// The truth of a simulated recording.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HandEyeTruth {
    /// `X`.
    pub hand_eye: Isometry3<f64>,
    /// `W`.
    pub world: Isometry3<f64>,
    /// The camera.
    pub camera: CameraModel,
    /// Every view's true `T_camera_target` (grid frame: origin at the first grid point).
    pub t_camera_target: Vec<Isometry3<f64>>,
}

fn pose(t: [f64; 3], r: [f64; 3]) -> Isometry3<f64> {
    Isometry3::new(Vector3::from(t), Vector3::from(r))
}

/// A frame at `eye` whose z axis points at `at`, rolled by `roll` about it.
fn looking_at(eye: Vector3<f64>, at: Vector3<f64>, roll: f64) -> Isometry3<f64> {
    let z = (at - eye).normalize();
    let helper = if z.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let x = helper.cross(&z).normalize();
    let y = z.cross(&x);
    let r = Rotation3::from_basis_unchecked(&[x, y, z]) * Rotation3::from_axis_angle(&Vector3::z_axis(), roll);
    Isometry3::from_parts(Translation3::from(eye), UnitQuaternion::from_rotation_matrix(&r))
}

/// One random `T_camera_target` that sees the target's centre `c` (target frame) from the
/// mount's distance range with a tilt up to 35 degrees.
fn random_view(rng: &mut ChaCha8Rng, mount: Mount, c: Vector3<f64>) -> Isometry3<f64> {
    let (d_lo, d_hi) = match mount {
        Mount::EyeInHand => (0.35, 0.6),
        Mount::EyeToHand => (0.5, 0.8),
    };
    let d = rng.random_range(d_lo..d_hi);
    let tilt = rng.random_range(0.0..35f64.to_radians());
    let az = rng.random_range(0.0..std::f64::consts::TAU);
    let eye = c + d * Vector3::new(tilt.sin() * az.cos(), tilt.sin() * az.sin(), tilt.cos());
    let aim = c + Vector3::new(rng.random_range(-0.03..0.03), rng.random_range(-0.03..0.03), 0.0);
    // T_target_camera with the camera's z towards the target; the target's z faces the camera.
    let t_target_camera = looking_at(eye, aim, rng.random_range(0.0..std::f64::consts::TAU));
    t_target_camera.inverse()
}

/// Simulates one recording (see the module documentation); deterministic for a seed.
pub fn simulate_hand_eye(config: &HandEyeSimConfig, seed: u64) -> Result<(HandEyeData, HandEyeTruth)> {
    if config.n_train < 3 || config.corner_sigma_px.is_nan() || config.corner_sigma_px <= 0.0 {
        return Err(DatasetError::Input(
            "hand-eye simulation: at least 3 training images and a corner sigma > 0".into(),
        ));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (cols, rows) = config.grid;
    let points: Vec<Point3<f64>> = (0..rows)
        .flat_map(|r| (0..cols).map(move |c| (c, r)))
        .map(|(c, r)| Point3::new(c as f64 * config.spacing_m, r as f64 * config.spacing_m, 0.0))
        .collect();
    let centre = Vector3::new((cols - 1) as f64, (rows - 1) as f64, 0.0) * (0.5 * config.spacing_m);
    let (x, w) = match config.mount {
        Mount::EyeInHand => (pose([0.04, -0.02, 0.09], [0.05, -0.08, 1.6]), pose([0.75, -0.1, 0.02], [0.0, 0.0, 0.3])),
        Mount::EyeToHand => (pose([0.02, 0.05, 0.08], [2.9, 0.1, -0.2]), pose([1.1, 0.4, 1.0], [2.6, 0.9, -0.3])),
    };
    let noise_px = Normal::new(0.0, config.corner_sigma_px).map_err(|e| DatasetError::Input(e.to_string()))?;
    let noise_t = Normal::new(0.0, config.robot_sigma_m.max(1e-300)).map_err(|e| DatasetError::Input(e.to_string()))?;
    let noise_r =
        Normal::new(0.0, config.robot_sigma_rad.max(1e-300)).map_err(|e| DatasetError::Input(e.to_string()))?;
    let cov = Matrix2::identity() * config.corner_sigma_px.powi(2);
    let mut views = Vec::new();
    let mut true_poses = Vec::new();
    let n = config.n_train + config.n_test;
    let mut attempts = 0;
    while views.len() < n {
        attempts += 1;
        if attempts > 50 * n {
            return Err(DatasetError::Input(
                "hand-eye simulation: the target is rarely in view; check the camera".into(),
            ));
        }
        let t_cam_target = random_view(&mut rng, config.mount, centre);
        // T_base_flange X C = W with C = T_camera_target (eye-in-hand) or its inverse.
        let t_base_flange = match config.mount {
            Mount::EyeInHand => w * t_cam_target.inverse() * x.inverse(),
            Mount::EyeToHand => w * t_cam_target * x.inverse(),
        };
        let mut corners = Vec::new();
        let mut ids = Vec::new();
        for (id, p) in points.iter().enumerate() {
            let printed = config.printed(p, centre);
            let Ok(px) = config.camera.project(&(t_cam_target * printed)) else { continue };
            let px = Point2::new(px.x + noise_px.sample(&mut rng), px.y + noise_px.sample(&mut rng));
            let inside = px.x > 5.0
                && px.y > 5.0
                && px.x < f64::from(config.camera.image_size.width_px) - 6.0
                && px.y < f64::from(config.camera.image_size.height_px) - 6.0;
            if inside {
                corners.push(px);
                ids.push(id);
            }
        }
        if corners.len() < points.len() / 2 || (config.full_view && corners.len() < points.len()) {
            continue;
        }
        let dt = Vector3::from_fn(|_, _| noise_t.sample(&mut rng)) * f64::from(u8::from(config.robot_sigma_m > 0.0));
        let dr = Vector3::from_fn(|_, _| noise_r.sample(&mut rng)) * f64::from(u8::from(config.robot_sigma_rad > 0.0));
        let reported = Isometry3::from_parts(
            Translation3::from(t_base_flange.translation.vector + dt),
            UnitQuaternion::from_scaled_axis(dr) * t_base_flange.rotation,
        );
        let k = views.len();
        true_poses.push(t_cam_target);
        views.push(HandEyeView {
            name: format!("sim{k:03}"),
            split: if k < config.n_train { Split::Train } else { Split::Test },
            t_base_flange: reported,
            image_size: config.camera.image_size,
            point_ids: ids,
            covariances_px2: vec![Some(cov); corners.len()],
            corners_px: corners,
        });
    }
    Ok((
        HandEyeData { mount: config.mount, target_points_m: points, views },
        HandEyeTruth { hand_eye: x, world: w, camera: config.camera, t_camera_target: true_poses },
    ))
}

/// Errors of one estimate against the truth, in the covariance's chart.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct HandEyeErrors {
    /// `t_est - t_true` of `X`, metres.
    pub translation_m: [f64; 3],
    /// `Log(R_est R_true^T)` of `X`, radians.
    pub rotation_rad: [f64; 3],
    /// The estimate's standard deviations of the translation, metres.
    pub translation_std_m: [f64; 3],
    /// The estimate's standard deviations of the rotation, radians.
    pub rotation_std_rad: [f64; 3],
    /// Held-out chain RMS, pixels.
    pub heldout_rms_px: f64,
}

/// One mount's Monte Carlo summary.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CoverageSummary {
    /// The mount.
    pub mount: Mount,
    /// Simulations that gave an estimate.
    pub n_runs: usize,
    /// Simulations whose calibration failed.
    pub n_failed: usize,
    /// Fraction of translation coordinates (3 per run) within 3 standard deviations.
    pub translation_coverage_3sigma: f64,
    /// Fraction of rotation coordinates within 3 standard deviations.
    pub rotation_coverage_3sigma: f64,
    /// RMS of the translation errors over runs and coordinates, mm.
    pub translation_rms_error_mm: f64,
    /// RMS of the stated translation standard deviations, mm.
    pub translation_rms_std_mm: f64,
    /// RMS of the rotation errors, degrees.
    pub rotation_rms_error_deg: f64,
    /// RMS of the stated rotation standard deviations, degrees.
    pub rotation_rms_std_deg: f64,
    /// Mean held-out chain RMS, pixels.
    pub mean_heldout_rms_px: f64,
}

/// How the study calibrates each recording.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct StudyMode {
    /// Calibrate the intrinsics from the training images (else held at the truth).
    pub free_intrinsics: bool,
    /// Estimate the noise levels by variance components, starting from twice the true robot
    /// sigmas (else the true sigmas are given).
    pub estimate_noise: bool,
}

/// Calibrates one simulated recording (intrinsics fixed to the truth or calibrated; noise
/// levels given or estimated) and returns its errors.
pub fn run_one(config: &HandEyeSimConfig, seed: u64, mode: StudyMode) -> Result<HandEyeErrors> {
    let (data, truth) = simulate_hand_eye(config, seed)?;
    let options = HandEyeOptions {
        intrinsics: if mode.free_intrinsics {
            IntrinsicsMode::Calibrate(CalibrationOptions::default())
        } else {
            IntrinsicsMode::Fixed(truth.camera)
        },
        robot_sigma_m: config.robot_sigma_m * if mode.estimate_noise { 2.0 } else { 1.0 },
        robot_sigma_rad: config.robot_sigma_rad * if mode.estimate_noise { 2.0 } else { 1.0 },
        estimate_noise: mode.estimate_noise,
        huber_sigmas: 0.0,
        ..HandEyeOptions::default()
    };
    let r = calibrate_hand_eye(&data, &options).map_err(|e| DatasetError::Input(format!("seed {seed}: {e}")))?;
    let x = r.hand_eye.transform;
    let dt = x.translation.vector - truth.hand_eye.translation.vector;
    let dr = (x.rotation * truth.hand_eye.rotation.inverse()).scaled_axis();
    let s = |i: usize| r.hand_eye.covariance[(i, i)].max(0.0).sqrt();
    Ok(HandEyeErrors {
        translation_m: [dt.x, dt.y, dt.z],
        rotation_rad: [dr.x, dr.y, dr.z],
        translation_std_m: [s(0), s(1), s(2)],
        rotation_std_rad: [s(3), s(4), s(5)],
        heldout_rms_px: r.figures.heldout_rms_px.unwrap_or(f64::NAN),
    })
}

/// The Monte Carlo study: `n` simulations per mount (seeds `seed`, `seed + 1`, ...), the
/// 3-sigma coverage of the hand-eye translation and rotation. `progress(k, total)` is called
/// after each run.
pub fn coverage_study(n: usize, seed: u64, mode: StudyMode, progress: &dyn Fn(usize, usize)) -> Vec<CoverageSummary> {
    let mounts = [Mount::EyeInHand, Mount::EyeToHand];
    let mut out = Vec::new();
    for (m, mount) in mounts.iter().enumerate() {
        let config = HandEyeSimConfig::default_for(*mount);
        let mut errs = Vec::new();
        let mut failed = 0;
        for k in 0..n {
            match run_one(&config, seed.wrapping_add(k as u64), mode) {
                Ok(e) => errs.push(e),
                Err(_) => failed += 1,
            }
            progress(m * n + k + 1, 2 * n);
        }
        out.push(summarise(*mount, &errs, failed));
    }
    out
}

fn summarise(mount: Mount, errs: &[HandEyeErrors], n_failed: usize) -> CoverageSummary {
    type Pick<'a> = &'a dyn Fn(&HandEyeErrors) -> ([f64; 3], [f64; 3]);
    let cover = |f: Pick| {
        let (mut inside, mut total, mut e2, mut s2) = (0usize, 0usize, 0.0, 0.0);
        for e in errs {
            let (v, s) = f(e);
            for i in 0..3 {
                inside += usize::from(v[i].abs() <= 3.0 * s[i]);
                total += 1;
                e2 += v[i] * v[i];
                s2 += s[i] * s[i];
            }
        }
        let t = total.max(1) as f64;
        (inside as f64 / t, (e2 / t).sqrt(), (s2 / t).sqrt())
    };
    let (tc, te, ts) = cover(&|e| (e.translation_m, e.translation_std_m));
    let (rc, re, rs) = cover(&|e| (e.rotation_rad, e.rotation_std_rad));
    CoverageSummary {
        mount,
        n_runs: errs.len(),
        n_failed,
        translation_coverage_3sigma: tc,
        rotation_coverage_3sigma: rc,
        translation_rms_error_mm: te * 1e3,
        translation_rms_std_mm: ts * 1e3,
        rotation_rms_error_deg: re.to_degrees(),
        rotation_rms_std_deg: rs.to_degrees(),
        mean_heldout_rms_px: errs.iter().map(|e| e.heldout_rms_px).sum::<f64>() / errs.len().max(1) as f64,
    }
}

/// What [`write_rendered_recording`] wrote, with the truth in the detector's target frame
/// (origin at the chessboard's centre).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RenderedRecording {
    /// The pattern string of the rendered chessboard (nominal spacing).
    pub pattern: String,
    /// `X` in the detector's target frame.
    pub hand_eye: Isometry3<f64>,
    /// `W` in the detector's target frame.
    pub world: Isometry3<f64>,
    /// The true camera.
    pub camera: CameraModel,
    /// Images written.
    pub n_images: usize,
}

/// Simulates a recording (views that show the whole chessboard), renders every view with the
/// project's renderer (blur, vignetting, sensor noise) and writes `images/simNNN.png`,
/// `poses.csv` (flange poses with the split), `camera.yaml` (the true camera, OpenCV YAML) and
/// `truth.json` into `dir` (created; an existing `poses.csv` there is an error).
pub fn write_rendered_recording(
    config: &HandEyeSimConfig,
    dir: &std::path::Path,
    seed: u64,
) -> Result<RenderedRecording> {
    use crate::render::{RenderConfig, Renderer, TargetConfig};
    if dir.join("poses.csv").exists() {
        return Err(DatasetError::Input(format!("{} already holds a recording (poses.csv)", dir.display())));
    }
    let mut config = config.clone();
    config.full_view = true;
    let (data, truth) = simulate_hand_eye(&config, seed)?;
    let (cols, rows) = config.grid;
    let target = TargetConfig::Chessboard {
        inner_cols: cols,
        inner_rows: rows,
        square_m: config.spacing_m * config.print_scale,
        margin_m: config.spacing_m,
    };
    let renderer = Renderer::new(config.camera, &target, RenderConfig::default())?;
    // The renderer's target frame has its origin at the pattern's centre.
    let centre =
        Vector3::new((cols - 1) as f64, (rows - 1) as f64, 0.0) * (0.5 * config.spacing_m * config.print_scale);
    let t_grid_render = Isometry3::from_parts(Translation3::from(centre), UnitQuaternion::identity());
    let images = dir.join("images");
    std::fs::create_dir_all(&images).map_err(|source| DatasetError::Write { path: images.clone(), source })?;
    let mut rows_out = Vec::new();
    for (k, (v, t)) in data.views.iter().zip(&truth.t_camera_target).enumerate() {
        let img = renderer.render(&(t * t_grid_render), seed.wrapping_mul(1000).wrapping_add(k as u64))?;
        let path = images.join(format!("{}.png", v.name));
        img.image.save(&path).map_err(|e| DatasetError::Image { path: path.clone(), reason: e.to_string() })?;
        rows_out.push((format!("{}.png", v.name), v.t_base_flange, v.split));
    }
    let comments = vec![format!("simulated {} recording, seed {seed}", config.mount.name())];
    super::poses::write_atomic(
        &dir.join("poses.csv"),
        super::poses::flange_poses_to_string(&rows_out, &comments).as_bytes(),
        &[],
    )?;
    let yaml = ferrocal_vision::camera::io::to_opencv_yaml(&config.camera)?;
    super::poses::write_atomic(&dir.join("camera.yaml"), yaml.as_bytes(), &[])?;
    let (hand_eye, world) = match config.mount {
        Mount::EyeInHand => (truth.hand_eye, truth.world * t_grid_render),
        Mount::EyeToHand => (truth.hand_eye * t_grid_render, truth.world),
    };
    let out = RenderedRecording {
        pattern: format!("chessboard:{cols}x{rows}:{}mm", config.spacing_m * 1e3),
        hand_eye,
        world,
        camera: config.camera,
        n_images: rows_out.len(),
    };
    let json = serde_json::to_string_pretty(&out)?;
    super::poses::write_atomic(&dir.join("truth.json"), json.as_bytes(), &[])?;
    Ok(out)
}
