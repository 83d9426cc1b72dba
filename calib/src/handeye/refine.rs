//! [`calibrate_hand_eye`]: the whole method of the module documentation, and the refinement in
//! pixels through `ferrocal-lsq`.

use std::sync::Arc;

use nalgebra::{Isometry3, Matrix2, Matrix6};

use ferrocal_lsq::{BlockId, Loss, Problem, Se3};
use ferrocal_vision::calib::{calibrate_camera, PlanarTarget, View};
use ferrocal_vision::camera::CameraModel;
use ferrocal_vision::pose::{estimate_pose, CornerNoise};

use super::closed::{self, ClosedForm, PosePair};
use super::evaluate::{chain_figures, Chain};
use super::residual::{whitening, ChainCorner, RobotPosePrior, TargetBlocks};
use super::{
    HandEyeData, HandEyeOptions, HandEyeResult, HandEyeView, IntrinsicsMode, NoiseLevels, SkippedView, StartReport,
    TargetForm, TransformEstimate,
};
use crate::error::{CalibError, Result};
use crate::measurement::Split;
use ferrocal_vision::calib::TargetDeformation;

/// Fewest training images the calibration accepts.
pub const MIN_TRAIN_VIEWS: usize = 3;

/// Variance-component iterations at most.
pub const MAX_NOISE_ITERATIONS: usize = 20;

/// Variance components count as converged when every group's factor is within this of 1.
pub const NOISE_TOLERANCE: f64 = 0.01;

/// Smallest robot sigmas the estimation goes down to (metres, radians): a robot that is exact
/// to this level is exact for the fit.
const MIN_ROBOT_SIGMA: f64 = 1e-8;

fn data_error(m: String) -> CalibError {
    CalibError::Data(format!("hand-eye: {m}"))
}

/// Refuses a given camera (`--intrinsics`) whose image size is not the views': a camera file of
/// another camera or resolution would be fitted as if it were this one (120 px residuals that
/// still "converge"). Used by the hand-eye fit and by `measure`.
pub fn check_camera_size(camera: &CameraModel, views: &[HandEyeView]) -> Result<()> {
    match views.iter().find(|v| v.image_size != camera.image_size) {
        None => Ok(()),
        Some(v) => Err(CalibError::Data(format!(
            "the given camera (--intrinsics) is for {} x {} px images, but {} is {} x {} px: the file belongs to another camera or resolution; leave out --intrinsics to calibrate the camera from these images, or give this camera's own file",
            camera.image_size.width_px,
            camera.image_size.height_px,
            v.name,
            v.image_size.width_px,
            v.image_size.height_px
        ))),
    }
}

/// Checks shapes and values of the recording; returns the usable views and the skipped ones.
fn usable_views(data: &HandEyeData, options: &HandEyeOptions) -> Result<(Vec<HandEyeView>, Vec<SkippedView>)> {
    if data.target_points_m.is_empty() || data.target_points_m.iter().any(|p| !p.coords.iter().all(|v| v.is_finite())) {
        return Err(data_error("the target has no points, or a point is not finite".into()));
    }
    let mut views = Vec::new();
    let mut skipped = Vec::new();
    for v in &data.views {
        let n = v.corners_px.len();
        if v.point_ids.len() != n || v.covariances_px2.len() != n {
            return Err(data_error(format!(
                "image {}: {} point ids and {} covariances for {n} corners",
                v.name,
                v.point_ids.len(),
                v.covariances_px2.len()
            )));
        }
        if let Some(&bad) = v.point_ids.iter().find(|&&i| i >= data.target_points_m.len()) {
            return Err(data_error(format!(
                "image {}: point id {bad}, but the target has {} points",
                v.name,
                data.target_points_m.len()
            )));
        }
        let pose_ok = v.t_base_flange.translation.vector.iter().all(|x| x.is_finite())
            && v.t_base_flange.rotation.coords.iter().all(|x| x.is_finite());
        if !pose_ok {
            return Err(data_error(format!("image {}: the robot pose is not finite", v.name)));
        }
        if v.corners_px.iter().any(|p| !(p.x.is_finite() && p.y.is_finite())) {
            return Err(data_error(format!("image {}: a corner is not finite", v.name)));
        }
        if n < options.min_corners {
            skipped.push(SkippedView {
                name: v.name.clone(),
                reason: format!("{n} corners, at least {} needed", options.min_corners),
            });
            continue;
        }
        views.push(v.clone());
    }
    let n_train = views.iter().filter(|v| v.split == Split::Train).count();
    if n_train < MIN_TRAIN_VIEWS {
        return Err(CalibError::TooFew(format!(
            "hand-eye: {n_train} usable training image(s), at least {MIN_TRAIN_VIEWS} needed ({} skipped)",
            skipped.len()
        )));
    }
    Ok((views, skipped))
}

fn corner_noise(v: &HandEyeView, fallback_px: f64) -> CornerNoise {
    CornerNoise::from_detected(&v.covariances_px2, fallback_px)
}

/// The camera: given, or calibrated from the training images alone.
fn initial_camera(
    data: &HandEyeData,
    views: &[HandEyeView],
    options: &HandEyeOptions,
) -> Result<(CameraModel, Option<ferrocal_vision::calib::CameraCalibration>)> {
    match &options.intrinsics {
        IntrinsicsMode::Fixed(c) => {
            c.validate().map_err(|e| data_error(format!("the given camera: {e}")))?;
            check_camera_size(c, views)?;
            Ok((*c, None))
        }
        IntrinsicsMode::Calibrate(o) => {
            let cal_views: Vec<View> = views
                .iter()
                .filter(|v| v.split == Split::Train)
                .map(|v| View {
                    name: v.name.clone(),
                    image_size: v.image_size,
                    point_ids: v.point_ids.clone(),
                    corners_px: v.corners_px.clone(),
                })
                .collect();
            let target = PlanarTarget { points_m: data.target_points_m.clone(), reversible: false };
            let cal = calibrate_camera(&cal_views, &target, o)
                .map_err(|e| CalibError::Data(format!("hand-eye: camera calibration from the training images: {e}")))?;
            Ok((cal.camera, Some(cal)))
        }
    }
}

/// Every view's PnP pose `T_camera_target` with `camera` (`None` where PnP fails).
pub(crate) fn pnp_poses(
    camera: &CameraModel,
    target: &[nalgebra::Point3<f64>],
    views: &[HandEyeView],
    fallback_px: f64,
) -> Vec<Option<Isometry3<f64>>> {
    views
        .iter()
        .map(|v| {
            estimate_pose(camera, target, &v.point_ids, &v.corners_px, &corner_noise(v, fallback_px))
                .ok()
                .map(|e| e.t_cam_target)
        })
        .collect()
}

/// The closed-form pose pairs of the training views that have a PnP pose.
pub(crate) fn training_pairs(
    mount: super::Mount,
    views: &[HandEyeView],
    pnp: &[Option<Isometry3<f64>>],
) -> Vec<PosePair> {
    views
        .iter()
        .zip(pnp)
        .filter(|(v, _)| v.split == Split::Train)
        .filter_map(|(v, p)| p.map(|p| PosePair { t_base_flange: v.t_base_flange, c: mount.closed_form_c(&p) }))
        .collect()
}

/// What the refinement found.
struct Refined {
    chain: Chain,
    camera: CameraModel,
    hand_eye_cov: Matrix6<f64>,
    world_cov: Matrix6<f64>,
    camera_std: Option<Vec<f64>>,
    scale_std: Option<f64>,
    form: Option<TargetForm>,
    s0: f64,
    iterations: usize,
    termination: String,
    n_downweighted: usize,
    noise: NoiseLevels,
}

/// The blocks of a built problem.
struct Blocks {
    x: BlockId,
    w: BlockId,
    camera: BlockId,
    scale: Option<BlockId>,
    shape: Option<BlockId>,
    print_x: Option<BlockId>,
}

/// Poses the refinement at `chain`, `camera` with one loss for every corner.
/// What every build of the problem shares.
struct Setup<'a> {
    data: &'a HandEyeData,
    views: &'a [HandEyeView],
    options: &'a HandEyeOptions,
    camera_free: bool,
    /// The target's deformation the refinement starts from (free flags: what it fits).
    form: Option<TargetDeformation>,
}

fn build(
    setup: &Setup,
    camera: &CameraModel,
    chain: &Chain,
    form: Option<&TargetDeformation>,
    noise: &NoiseLevels,
    loss: Loss,
) -> Result<(Problem, Blocks)> {
    let Setup { data, views, options, camera_free, .. } = *setup;
    let mut p = Problem::new();
    let x = p.add_block("hand_eye", Se3::from_isometry(&chain.x).to_vec(), Arc::new(Se3))?;
    let w = p.add_block("world", Se3::from_isometry(&chain.w).to_vec(), Arc::new(Se3))?;
    p.set_scales(x, vec![1e-3; 6])?;
    p.set_scales(w, vec![1e-3; 6])?;
    let cam = p.add_euclidean("camera", camera.parameter_values())?;
    p.set_coordinate_names(cam, camera.parameters().iter().map(|c| c.name.to_string()).collect())?;
    p.set_scales(cam, (0..camera.n_parameters()).map(|i| if i < 4 { 1.0 } else { 1e-3 }).collect())?;
    p.set_constant(cam, !camera_free)?;
    let scale = if options.fit_target_scale {
        let s = p.add_euclidean("target_scale", vec![chain.scale])?;
        p.set_scales(s, vec![1e-4])?;
        Some(s)
    } else {
        None
    };
    let shape = match form.filter(|f| f.shape_free) {
        Some(f) => {
            let b = p.add_euclidean("target_shape", f.shape_m.to_vec())?;
            p.set_coordinate_names(b, vec!["bowl_sag_m".into(), "saddle_sag_m".into(), "twist_sag_m".into()])?;
            p.set_scales(b, vec![1e-4; 3])?;
            Some(b)
        }
        None => None,
    };
    let print_x = match form.filter(|f| f.scale_free) {
        Some(f) => {
            let b = p.add_euclidean("target_print_x", vec![f.scale[0]])?;
            p.set_scales(b, vec![1e-4])?;
            Some(b)
        }
        None => None,
    };
    let target = TargetBlocks { scale: scale.is_some(), form: form.copied() };
    let fallback = Matrix2::identity() * options.fallback_corner_sigma_px.powi(2);
    let corner_factor = noise.corner_variance_factor.sqrt();
    let robot_free = noise.robot_sigma_m > 0.0 && noise.robot_sigma_rad > 0.0;
    for (i, v) in views.iter().enumerate().filter(|(_, v)| v.split == Split::Train) {
        let robot = p.add_block(&format!("robot{i}"), Se3::from_isometry(&v.t_base_flange).to_vec(), Arc::new(Se3))?;
        p.set_scales(robot, vec![1e-4; 6])?;
        if robot_free {
            let prior = RobotPosePrior {
                reported: v.t_base_flange,
                sigma_m: noise.robot_sigma_m,
                sigma_rad: noise.robot_sigma_rad,
            };
            p.add_residual(&format!("{}.robot", v.name), Box::new(prior), &[robot], Loss::Squared)?;
        } else {
            p.set_constant(robot, true)?;
        }
        let mut blocks = vec![x, w, robot, cam];
        blocks.extend(scale);
        blocks.extend(shape);
        blocks.extend(print_x);
        for ((&id, px), cov) in v.point_ids.iter().zip(&v.corners_px).zip(&v.covariances_px2) {
            let whiten = cov.and_then(|c| whitening(&c)).unwrap_or_else(|| whitening(&fallback).expect("positive"))
                / corner_factor;
            let r = ChainCorner {
                mount: data.mount,
                point_m: data.target_points_m[id],
                detected_px: *px,
                whiten,
                camera: *camera,
                target,
            };
            p.add_residual(&format!("{}.c{id}", v.name), Box::new(r), &blocks, loss)?;
        }
    }
    Ok((p, Blocks { x, w, camera: cam, scale, shape, print_x }))
}

/// The current chain, camera and target deformation (`form` with the fitted values) of a solved
/// problem.
fn read_back(
    p: &Problem,
    b: &Blocks,
    template: &CameraModel,
    form: Option<TargetDeformation>,
) -> Result<(Chain, CameraModel, Option<TargetDeformation>)> {
    let chain = Chain {
        x: Se3::to_isometry(&p.block(b.x).values),
        w: Se3::to_isometry(&p.block(b.w).values),
        scale: b.scale.map_or(1.0, |s| p.block(s).values[0]),
    };
    let camera = super::residual::camera_with(template, &p.block(b.camera).values)?;
    let form = form.map(|mut f| {
        if let Some(s) = b.shape {
            f.shape_m.copy_from_slice(&p.block(s).values);
        }
        if let Some(e) = b.print_x {
            f.scale[0] = p.block(e).values[0];
        }
        f
    });
    Ok((chain, camera, form))
}

/// `1.4826 * median |r|` over the whitened corner residual components.
fn robust_sigma(p: &Problem) -> Result<f64> {
    let r = p.residuals()?;
    let idx = p.measurement_index();
    let mut a: Vec<f64> = Vec::new();
    for e in idx.entries.iter().filter(|e| !e.name.ends_with(".robot")) {
        a.extend((0..e.size).map(|k| r[e.offset + k].abs()));
    }
    Ok(1.4826 * ferrocal_vision::calib::median(&a))
}

/// The variance factors `r_g^T r_g / redundancy_g` of the corner, robot-position and
/// robot-orientation groups at the current point (`None` for a group without redundancy).
fn variance_factors(p: &Problem) -> Result<[Option<f64>; 3]> {
    let (r, j) = p.linearize()?;
    let n = j.ncols();
    let d: Vec<f64> = (0..n).map(|c| j.column(c).norm().max(1e-300)).collect();
    let mut js = j.clone();
    for (c, dc) in d.iter().enumerate() {
        js.column_mut(c).scale_mut(1.0 / dc);
    }
    // A rank-deficient normal matrix (coefficients of a rich lens model that trade with each
    // other on few images) still has its redundancies: the pseudo-inverse's hat matrix.
    let normal = js.transpose() * &js;
    let ninv = match normal.clone().cholesky() {
        Some(c) => c.inverse(),
        None => {
            let eps = 1e-12 * normal.diagonal().max();
            normal.pseudo_inverse(eps).map_err(|e| CalibError::Numeric(format!("hand-eye: the normal matrix: {e}")))?
        }
    };
    let jn = &js * ninv;
    let mut red = [0.0; 3];
    let mut ss = [0.0; 3];
    for e in p.measurement_index().entries {
        let robot = e.name.ends_with(".robot");
        for k in 0..e.size {
            let row = e.offset + k;
            let g = if !robot {
                0
            } else if k < 3 {
                1
            } else {
                2
            };
            red[g] += 1.0 - jn.row(row).dot(&js.row(row));
            ss[g] += r[row] * r[row];
        }
    }
    Ok([0, 1, 2].map(|g| (red[g] > 1.0).then(|| ss[g] / red[g])))
}

fn refine(setup: &Setup, camera: &CameraModel, start: &Chain) -> Result<Refined> {
    let (options, camera_free) = (setup.options, setup.camera_free);
    let mut noise = NoiseLevels {
        corner_variance_factor: 1.0,
        robot_sigma_m: options.robot_sigma_m,
        robot_sigma_rad: options.robot_sigma_rad,
        estimated: options.estimate_noise,
        iterations: 0,
    };
    let (mut chain, mut cam, mut form) = (*start, *camera, setup.form);
    let mut iterations = 0;
    let (mut p, b, mut summary) = loop {
        let (mut p, b) = build(setup, &cam, &chain, form.as_ref(), &noise, Loss::Squared)?;
        let sol = p.solve(&options.solver)?;
        iterations += sol.summary.iterations;
        (chain, cam, form) = read_back(&p, &b, camera, form)?;
        if !options.estimate_noise || noise.iterations >= MAX_NOISE_ITERATIONS {
            break (p, b, sol.summary);
        }
        let f = variance_factors(&p)?;
        let converged = f.iter().flatten().all(|v| (v - 1.0).abs() < NOISE_TOLERANCE);
        if converged {
            break (p, b, sol.summary);
        }
        noise.iterations += 1;
        noise.corner_variance_factor *= f[0].unwrap_or(1.0);
        if noise.robot_sigma_m > 0.0 && noise.robot_sigma_rad > 0.0 {
            noise.robot_sigma_m = (noise.robot_sigma_m * f[1].unwrap_or(1.0).sqrt()).max(MIN_ROBOT_SIGMA);
            noise.robot_sigma_rad = (noise.robot_sigma_rad * f[2].unwrap_or(1.0).sqrt()).max(MIN_ROBOT_SIGMA);
        }
    };
    if let Some(loss) = options.second_loss(robust_sigma(&p)?) {
        let (p2, _) = build(setup, &cam, &chain, form.as_ref(), &noise, loss)?;
        p = p2;
        let second = p.solve(&options.solver)?;
        iterations += second.summary.iterations;
        summary = second.summary;
    }
    let (chain, cam, form) = read_back(&p, &b, camera, form)?;
    let mut globals = vec![b.x, b.w];
    if camera_free {
        globals.push(b.camera);
    }
    globals.extend(b.scale);
    globals.extend(b.shape);
    globals.extend(b.print_x);
    let cov = p.schur_covariance(&globals)?;
    let block = |id| cov.block(id).ok_or_else(|| CalibError::Numeric("covariance block missing".into()));
    let six = |m: nalgebra::DMatrix<f64>| Matrix6::from_fn(|i, j| m[(i, j)]);
    let camera_std = if camera_free {
        let m = block(b.camera)?;
        Some((0..m.nrows()).map(|i| m[(i, i)].max(0.0).sqrt()).collect())
    } else {
        None
    };
    let scale_std = match b.scale {
        Some(s) => Some(block(s)?[(0, 0)].max(0.0).sqrt()),
        None => None,
    };
    let stds = |id: Option<BlockId>| -> Result<Option<Vec<f64>>> {
        id.map(|id| block(id).map(|m| (0..m.nrows()).map(|i| m[(i, i)].max(0.0).sqrt()).collect())).transpose()
    };
    let form = match form {
        Some(deformation) => Some(TargetForm {
            deformation,
            shape_std_m: stds(b.shape)?.map(|v| [v[0], v[1], v[2]]),
            scale_x_std: stds(b.print_x)?.map(|v| v[0]),
        }),
        None => None,
    };
    Ok(Refined {
        form,
        chain,
        camera: cam,
        hand_eye_cov: six(block(b.x)?),
        world_cov: six(block(b.w)?),
        camera_std,
        scale_std,
        s0: cov.s0,
        iterations,
        termination: summary.termination.clone(),
        n_downweighted: summary.downweighted_blocks,
        noise,
    })
}

/// Hand-eye calibration of a recording (see the module documentation for the method).
///
/// Errors: [`CalibError::TooFew`] (fewer than [`MIN_TRAIN_VIEWS`] usable training images),
/// [`CalibError::Data`] (inconsistent input, a camera that cannot be calibrated, every closed
/// form failed, with each method's reason), [`CalibError::Numeric`] (unidentifiable
/// parameters).
pub fn calibrate_hand_eye(data: &HandEyeData, options: &HandEyeOptions) -> Result<HandEyeResult> {
    calibrate_hand_eye_from(data, options, start_poses(data, options)?)
}

/// Steps 1 and 2 of [`calibrate_hand_eye`]: the usable images, the camera the fit starts from
/// and every image's PnP pose with it; for checks of the recording before the fit.
#[derive(Clone, Debug)]
pub struct StartPoses {
    /// The images with enough corners.
    pub views: Vec<HandEyeView>,
    /// The images left out, and why.
    pub skipped: Vec<SkippedView>,
    /// The camera: given, or calibrated from the training images.
    pub camera: CameraModel,
    /// The calibration the camera came from, when it was calibrated.
    pub initial: Option<ferrocal_vision::calib::CameraCalibration>,
    /// `T_camera_target` of each of `views` by PnP with `camera` (`None` where PnP failed).
    pub pnp: Vec<Option<Isometry3<f64>>>,
}

/// The usable images of `data`, the starting camera and the PnP poses (see [`StartPoses`]).
/// Errors: those of [`calibrate_hand_eye`] before its closed forms.
pub fn start_poses(data: &HandEyeData, options: &HandEyeOptions) -> Result<StartPoses> {
    options.validate()?;
    let (views, skipped) = usable_views(data, options)?;
    let (camera, initial) = initial_camera(data, &views, options)?;
    let pnp = pnp_poses(&camera, &data.target_points_m, &views, options.fallback_corner_sigma_px);
    Ok(StartPoses { views, skipped, camera, initial, pnp })
}

/// [`calibrate_hand_eye`] from its first two steps, `start` ([`start_poses`] of the same `data`
/// and `options`).
pub fn calibrate_hand_eye_from(
    data: &HandEyeData,
    options: &HandEyeOptions,
    start: StartPoses,
) -> Result<HandEyeResult> {
    let StartPoses { views, mut skipped, camera: camera0, initial, pnp: pnp0 } = start;
    let fallback = options.fallback_corner_sigma_px;
    for (v, p) in views.iter().zip(&pnp0) {
        if p.is_none() && v.split == Split::Train {
            skipped.push(SkippedView {
                name: v.name.clone(),
                reason: "no PnP pose: left out of the closed-form start (its corners are still fitted)".into(),
            });
        }
    }
    let pairs = training_pairs(data.mount, &views, &pnp0);
    let mut starts = Vec::new();
    let mut best: Option<(f64, Chain, usize)> = None;
    for method in ClosedForm::ALL {
        match closed::solve(&pairs, method) {
            Ok((x, w)) => {
                let chain = Chain { x, w, scale: 1.0 };
                let f = chain_figures(data.mount, &camera0, &data.target_points_m, &views, &pnp0, &chain);
                let rms = f.train_rms_px;
                if rms.is_finite() && best.as_ref().is_none_or(|b| rms < b.0) {
                    best = Some((rms, chain, starts.len()));
                }
                starts.push(StartReport { method, train_rms_px: Some(rms), error: None, chosen: false });
            }
            Err(e) => {
                starts.push(StartReport { method, train_rms_px: None, error: Some(e.to_string()), chosen: false })
            }
        }
    }
    let Some((_, start, k)) = best else {
        let why: Vec<String> = starts
            .iter()
            .map(|s| format!("{}: {}", s.method.name(), s.error.as_deref().unwrap_or("no finite RMS")))
            .collect();
        return Err(data_error(format!("every closed-form start failed ({})", why.join("; "))));
    };
    starts[k].chosen = true;
    let camera_free = matches!(options.intrinsics, IntrinsicsMode::Calibrate(_));
    let physics = options.target_physics;
    let form = if physics.any() {
        let mut f = TargetDeformation::of_points(&data.target_points_m)
            .map_err(|e| data_error(format!("the target's bending and print scale: {e}")))?;
        (f.shape_free, f.scale_free) = (physics.shape, physics.print_x);
        Some(f)
    } else {
        None
    };
    let setup = Setup { data, views: &views, options, camera_free, form };
    let r = refine(&setup, &camera0, &start)?;
    // The PnP yardstick uses the target geometry the chain uses (the fitted print scale and
    // deformation).
    let chain_points = match &r.form {
        Some(f) => f.points(&data.target_points_m),
        None => data.target_points_m.clone(),
    };
    let target = super::evaluate::scaled_target(&chain_points, r.chain.scale);
    let pnp = pnp_poses(&r.camera, &target, &views, fallback);
    let figures = chain_figures(data.mount, &r.camera, &chain_points, &views, &pnp, &r.chain);
    let motion = super::MotionGeometry::of(&views);
    Ok(HandEyeResult {
        mount: data.mount,
        camera: r.camera,
        camera_std: r.camera_std,
        initial_camera: initial,
        hand_eye: TransformEstimate { transform: r.chain.x, covariance: r.hand_eye_cov },
        world: TransformEstimate { transform: r.chain.w, covariance: r.world_cov },
        target_scale: r.scale_std.map(|s| (r.chain.scale, s)),
        target_form: r.form,
        figures,
        starts,
        skipped,
        noise: r.noise,
        s0: r.s0,
        iterations: r.iterations,
        termination: r.termination,
        n_downweighted: r.n_downweighted,
        motion,
        warnings: motion.warnings(),
    })
}
