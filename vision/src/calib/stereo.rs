//! Calibration of a rig of cameras that see the same target poses (stereo: two cameras).

use nalgebra::{DMatrix, Isometry3, Point2, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use super::bundle::{Bundle, CameraLayout, Obs};
use super::{
    calibrate_camera, median, CalibrationOptions, CameraCalibration, CovarianceMethod, PlanarTarget, View, ViewReport,
};
use crate::camera::io::StereoPair;
use crate::camera::rectify::StereoRectification;
use crate::error::{Result, VisionError};
use crate::pose::{so3, CameraRig, LocalPose};

/// A calibrated rig.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RigCalibration {
    /// Every camera: model, standard deviations and covariance from the joint adjustment, RMS
    /// and per-view reports over its own corners in the joint adjustment; `summary` is that of
    /// the camera's own calibration, which started the joint one.
    pub cameras: Vec<CameraCalibration>,
    /// `T_cam_cam0` of every camera (the first is the identity), metres.
    pub t_cam_cam0: Vec<Isometry3<f64>>,
    /// Standard deviations of `T_cam_cam0`: rotation error (left, radians) then translation
    /// (metres); zeros for camera 0.
    pub extrinsic_std: Vec<[f64; 6]>,
    /// Covariance of the rig parameters in the layout of [`CameraRig::covariance`].
    pub covariance: DMatrix<f64>,
    /// RMS reprojection error over all cameras' corners, pixels.
    pub rms_px: f64,
    /// A-posteriori standard error of unit weight of the joint adjustment, pixels.
    pub s0_px: f64,
    /// Condition number of the correlation-scaled normal matrix of the rig parameters.
    pub normal_condition: f64,
    /// Views (target poses) in the joint adjustment.
    pub n_views: usize,
    /// Views seen by at least two cameras.
    pub n_shared_views: usize,
    /// `(camera, view name)` of views whose corner numbering was reversed to match camera 0.
    pub reversed_views: Vec<(usize, String)>,
    /// Ceres iterations of the joint adjustment.
    pub iterations: usize,
    /// Ceres' report of the joint adjustment.
    pub solver_report: String,
}

impl RigCalibration {
    /// The rig, with its covariance, for [`crate::pose::estimate_pose_rig`].
    pub fn rig(&self) -> CameraRig {
        CameraRig {
            cameras: self.cameras.iter().map(|c| c.camera).collect(),
            t_cam_cam0: self.t_cam_cam0.clone(),
            covariance: Some(self.covariance.clone()),
        }
    }
}

/// A calibrated stereo pair: `T_right_left` (OpenCV's `R`, `T`) with its uncertainty.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StereoCalibration {
    /// The joint calibration (camera 0 = left, camera 1 = right).
    pub calibration: RigCalibration,
    /// `T_right_left`, metres.
    pub t_right_left: Isometry3<f64>,
    /// Its rotation vector, degrees.
    pub rotation_deg: Vector3<f64>,
    /// Standard deviation of the rotation vector's components, degrees.
    pub rotation_std_deg: Vector3<f64>,
    /// Its translation, millimetres.
    pub translation_mm: Vector3<f64>,
    /// Standard deviation of the translation, millimetres.
    pub translation_std_mm: Vector3<f64>,
    /// Distance between the projection centres, millimetres.
    pub baseline_mm: f64,
    /// Its standard deviation, millimetres.
    pub baseline_std_mm: f64,
}

impl StereoCalibration {
    /// The left camera.
    pub fn left(&self) -> &CameraCalibration {
        &self.calibration.cameras[0]
    }

    /// The right camera.
    pub fn right(&self) -> &CameraCalibration {
        &self.calibration.cameras[1]
    }

    /// The rig, with its covariance.
    pub fn rig(&self) -> CameraRig {
        self.calibration.rig()
    }

    /// The pair as the stereo files hold it (`T` in metres), with its rectification
    /// ([`crate::camera::rectify::stereo_rectify`]).
    pub fn pair(&self) -> Result<StereoPair> {
        StereoPair::new(
            self.left().camera,
            self.right().camera,
            self.t_right_left.rotation.to_rotation_matrix().into_inner(),
            self.t_right_left.translation.vector,
        )
    }

    /// Every corner seen in both images of a pair, rectified in both (`left[i]`, `right[i]` as
    /// given to [`calibrate_stereo`]; the right view's corner numbering flipped where the
    /// calibration found it reversed). A corner that cannot be rectified is left out.
    pub fn rectified_corners(
        &self,
        rectification: &StereoRectification,
        left: &[Option<View>],
        right: &[Option<View>],
        target: &PlanarTarget,
    ) -> Vec<RectifiedCorner> {
        let n = target.points_m.len();
        let (cl, cr) = (&self.left().camera, &self.right().camera);
        let mut out = Vec::new();
        for (lv, rv) in left.iter().zip(right) {
            let (Some(lv), Some(rv)) = (lv, rv) else { continue };
            let reversed = self.calibration.reversed_views.iter().any(|(k, name)| *k == 1 && *name == rv.name);
            for (id, pl) in lv.point_ids.iter().zip(&lv.corners_px) {
                let want = if reversed { n.wrapping_sub(1 + id) } else { *id };
                let Some(j) = rv.point_ids.iter().position(|p| *p == want) else { continue };
                let (Ok(ql), Ok(qr)) = (
                    rectification.rectify_pixel(cl, false, pl),
                    rectification.rectify_pixel(cr, true, &rv.corners_px[j]),
                ) else {
                    continue;
                };
                out.push(RectifiedCorner { view: lv.name.clone(), point_id: *id, left_px: ql, right_px: qr });
            }
        }
        out
    }
}

/// A corner seen in both images of a pair, in both rectified images.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RectifiedCorner {
    /// The left view's name.
    pub view: String,
    /// The corner's point id in the left view.
    pub point_id: usize,
    /// Rectified left pixel.
    pub left_px: Point2<f64>,
    /// Rectified right pixel.
    pub right_px: Point2<f64>,
}

/// The RMS of the rectified row difference `v_left - v_right` of corresponding corners
/// (`u_left - u_right` for vertical stereo), pixels; NaN without corners.
pub fn rectified_row_rms_px(corners: &[RectifiedCorner], vertical: bool) -> f64 {
    let d = |c: &RectifiedCorner| if vertical { c.left_px.x - c.right_px.x } else { c.left_px.y - c.right_px.y };
    (corners.iter().map(|c| d(c).powi(2)).sum::<f64>() / corners.len() as f64).sqrt()
}

/// Calibrates a stereo pair from views taken at the same time: `left[i]` and `right[i]` see the
/// same target pose (`None` where the target was not found in that image). See
/// [`calibrate_rig`].
pub fn calibrate_stereo(
    left: &[Option<View>],
    right: &[Option<View>],
    target: &PlanarTarget,
    options: &CalibrationOptions,
) -> Result<StereoCalibration> {
    if left.len() != right.len() {
        return Err(VisionError::InvalidInput {
            detail: format!(
                "{} left and {} right images: a stereo calibration pairs them by order, give as many of each",
                left.len(),
                right.len()
            ),
        });
    }
    let cal = calibrate_rig(&[left.to_vec(), right.to_vec()], target, options)?;
    let t = cal.t_cam_cam0[1];
    let theta = so3::log(&t.rotation.to_rotation_matrix());
    // The extrinsic block is [t, dtheta]. Covariance of the left increment -> covariance of the
    // rotation vector.
    let off = cal.covariance.nrows() - 6;
    let cov_t = cal.covariance.fixed_view::<3, 3>(off, off).into_owned();
    let cov_d = cal.covariance.fixed_view::<3, 3>(off + 3, off + 3).into_owned();
    let jinv = so3::left_jacobian(&theta).try_inverse().unwrap_or_else(nalgebra::Matrix3::identity);
    let cov_theta = jinv * cov_d * jinv.transpose();
    let tv = t.translation.vector;
    let baseline = tv.norm();
    let dir = if baseline > 0.0 { tv / baseline } else { Vector3::x() };
    let var_b = (dir.transpose() * cov_t * dir)[(0, 0)];
    Ok(StereoCalibration {
        t_right_left: t,
        rotation_deg: theta.map(f64::to_degrees),
        rotation_std_deg: Vector3::from_fn(|i, _| cov_theta[(i, i)].max(0.0).sqrt().to_degrees()),
        translation_mm: tv * 1e3,
        translation_std_mm: Vector3::from_fn(|i, _| cov_t[(i, i)].max(0.0).sqrt() * 1e3),
        baseline_mm: baseline * 1e3,
        baseline_std_mm: var_b.max(0.0).sqrt() * 1e3,
        calibration: cal,
    })
}

/// How well the pairs of a stereo recording agree on the cameras' relative pose, each camera
/// calibrated alone ([`check_pairing`]): left image `i` and right image `i` must show one target
/// pose, so `T_right_target(i) T_left_target(i)^-1` is the same rigid transform for every pair.
/// Swapped lists keep that (the baseline's sign tells them, `camera stereo`'s verdict); lists
/// shifted by an image do not.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PairingCheck {
    /// Pairs compared (both images posed by their camera's own calibration).
    pub n_pairs: usize,
    /// The left images of the pairs whose relative pose is farther than the limit from the
    /// consensus of all pairs.
    pub disagreeing: Vec<String>,
    /// When the lists as given disagree: the shift `s` of the right list (left image `i` with
    /// right image `i + s`, `s` in -2..=2) that makes the largest share of pairs agree, with the
    /// pairs that agree and the pairs compared at that shift, and the first such pair's images.
    pub best_shift: Option<ShiftFit>,
}

/// A shift of the right image list and how well it pairs the images ([`PairingCheck`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShiftFit {
    /// Left image `i` pairs with right image `i + shift`.
    pub shift: i64,
    /// Pairs that agree at this shift.
    pub agreeing: usize,
    /// Pairs compared at this shift.
    pub compared: usize,
    /// An example pair at this shift: the left and the right image.
    pub example: (String, String),
}

impl PairingCheck {
    /// The share of the pairs that disagree (0 without pairs).
    pub fn disagree_fraction(&self) -> f64 {
        if self.n_pairs == 0 {
            0.0
        } else {
            self.disagreeing.len() as f64 / self.n_pairs as f64
        }
    }
}

/// Per image slot of one camera: the image's name and its pose `T_cam_target` from the camera's
/// own calibration (`None`: no usable view).
type PosedSlots = Vec<Option<(String, Isometry3<f64>)>>;

/// The relative poses `T_right_target(i + shift) T_left_target(i)^-1` of the pairs at `shift`
/// (with the target's reversal when it has one), and per pair whether it lies within `limit`
/// ([`pose_distance`]) of the consensus (the relative pose with the most others within the
/// limit); with the pairs' left and right image names.
fn pairs_at_shift(
    poses: [&PosedSlots; 2],
    flip: Option<Isometry3<f64>>,
    shift: i64,
    limit: f64,
) -> Vec<(bool, String, String)> {
    let [left, right] = poses;
    let mut pairs: Vec<(Vec<Isometry3<f64>>, String, String)> = Vec::new();
    for (i, l) in left.iter().enumerate() {
        let j = i as i64 + shift;
        if j < 0 || j as usize >= right.len() {
            continue;
        }
        let (Some((ln, tl)), Some((rn, tr))) = (l, &right[j as usize]) else { continue };
        let mut cands = vec![tr * tl.inverse()];
        if let Some(f) = flip {
            cands.push(tr * f * tl.inverse());
        }
        pairs.push((cands, ln.clone(), rn.clone()));
    }
    let all: Vec<&Isometry3<f64>> = pairs.iter().flat_map(|p| p.0.iter()).collect();
    let Some(reference) =
        all.iter().max_by_key(|a| all.iter().filter(|b| pose_distance(a, b) < limit).count()).map(|a| **a)
    else {
        return Vec::new();
    };
    pairs.into_iter().map(|(cands, l, r)| (cands.iter().any(|c| pose_distance(c, &reference) < limit), l, r)).collect()
}

/// Checks that `left[i]` and `right[i]` show the same target pose: each camera is calibrated
/// alone, every pair's relative pose is compared with the consensus of all pairs (`limit`: the
/// rotation difference in radians plus the translation difference relative to the baseline,
/// 0.1 in `camera stereo`'s thresholds, `stereo.pair_distance`), and when some disagree, the
/// right list shifted by -2 to 2 images is tried. Errors as [`calibrate_camera`] on either
/// camera's views.
pub fn check_pairing(
    left: &[Option<View>],
    right: &[Option<View>],
    target: &PlanarTarget,
    options: &CalibrationOptions,
    limit: f64,
) -> Result<PairingCheck> {
    let mono_options = CalibrationOptions { covariance: CovarianceMethod::Independent, ..options.clone() };
    let mut poses: Vec<PosedSlots> = Vec::with_capacity(2);
    for (k, cam_views) in [left, right].into_iter().enumerate() {
        let present: Vec<View> = cam_views.iter().flatten().cloned().collect();
        let cal = calibrate_camera(&present, target, &mono_options).map_err(|e| match e {
            VisionError::TooFewViews { usable, needed, detail } => {
                VisionError::TooFewViews { usable, needed, detail: format!("camera {k}: {detail}") }
            }
            other => other,
        })?;
        let mut idx = 0;
        let mut slot = Vec::with_capacity(cam_views.len());
        for v in cam_views {
            match v {
                Some(v) => {
                    let r = &cal.views[idx];
                    slot.push(r.used.then(|| (v.name.clone(), r.t_cam_target)));
                    idx += 1;
                }
                None => slot.push(None),
            }
        }
        poses.push(slot);
    }
    let flip = reversal(target);
    let given = pairs_at_shift([&poses[0], &poses[1]], flip, 0, limit);
    let disagreeing: Vec<String> = given.iter().filter(|p| !p.0).map(|p| p.1.clone()).collect();
    let share = |p: &[(bool, String, String)]| p.iter().filter(|x| x.0).count() as f64 / p.len().max(1) as f64;
    let mut best_shift: Option<ShiftFit> = None;
    if !disagreeing.is_empty() {
        let mut best_share = share(&given);
        for shift in [-1i64, 1, -2, 2] {
            let at = pairs_at_shift([&poses[0], &poses[1]], flip, shift, limit);
            // A shift must pair at least 3 images, and more of them than the lists as given.
            if at.len() < 3 || share(&at) <= best_share {
                continue;
            }
            best_share = share(&at);
            let example = at.iter().find(|p| p.0).map(|p| (p.1.clone(), p.2.clone())).unwrap_or_default();
            best_shift =
                Some(ShiftFit { shift, agreeing: at.iter().filter(|p| p.0).count(), compared: at.len(), example });
        }
    }
    Ok(PairingCheck { n_pairs: given.len(), disagreeing, best_shift })
}

/// The flip of a reversible target: the point of reversed index, `X_{n-1-j} = 2 c - X_j`,
/// as a rotation by pi about the plane normal through the centroid `c` (target frame).
fn reversal(target: &PlanarTarget) -> Option<Isometry3<f64>> {
    if !target.reversible {
        return None;
    }
    let n = target.points_m.len();
    let c = target.points_m.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n as f64;
    let t_target_plane = crate::pose::plane_frame(&target.points_m).ok()?;
    let normal = t_target_plane.rotation * Vector3::z();
    let rot = UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(normal), std::f64::consts::PI);
    let f = Isometry3::from_parts(Translation3::from(c - rot * c), rot);
    let scale = target.points_m.iter().map(|p| (p.coords - c).norm()).fold(0.0, f64::max);
    let ok = (0..n).all(|j| (f * target.points_m[j] - target.points_m[n - 1 - j]).norm() <= 1e-9 * scale.max(1.0));
    ok.then_some(f)
}

/// Distance between two rigid transforms for clustering: rotation angle (rad) plus the
/// translation difference relative to the larger translation.
fn pose_distance(a: &Isometry3<f64>, b: &Isometry3<f64>) -> f64 {
    let ang = a.rotation.angle_to(&b.rotation);
    let scale = a.translation.vector.norm().max(b.translation.vector.norm()).max(1e-9);
    ang + (a.translation.vector - b.translation.vector).norm() / scale
}

/// Mean of rigid transforms: quaternions sign-aligned and averaged, translations by the
/// component-wise median.
fn mean_pose(poses: &[Isometry3<f64>]) -> Isometry3<f64> {
    let q0 = poses[0].rotation;
    let mut acc = nalgebra::Vector4::zeros();
    for p in poses {
        let q = p.rotation.into_inner().coords;
        acc += if q.dot(&q0.into_inner().coords) < 0.0 { -q } else { q };
    }
    let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::from(acc));
    let t = Vector3::from_fn(|i, _| median(&poses.iter().map(|p| p.translation.vector[i]).collect::<Vec<_>>()));
    Isometry3::from_parts(Translation3::from(t), q)
}

/// Calibrates a rig: `views[k][i]` is what camera `k` saw of target pose `i` (`None` when it did
/// not see the target). Every camera is calibrated alone first ([`calibrate_camera`], which
/// also sets the minimum of views per camera); for a reversible target (a chessboard) the
/// corner numbering of each camera's views is made consistent with camera 0's (a detector may
/// number a grid from either end); `T_cam_cam0` starts from the mean of the per-view
/// relative poses; then one bundle adjustment refines all cameras, the extrinsics and one
/// target pose per view, and gives their joint covariance.
pub fn calibrate_rig(
    views: &[Vec<Option<View>>],
    target: &PlanarTarget,
    options: &CalibrationOptions,
) -> Result<RigCalibration> {
    options.validate()?;
    target.validate()?;
    let nc = views.len();
    if nc == 0 {
        return Err(VisionError::InvalidInput { detail: "a rig needs at least one camera".into() });
    }
    let nv = views[0].len();
    if views.iter().any(|v| v.len() != nv) {
        return Err(VisionError::InvalidInput {
            detail: format!(
                "every camera needs one entry per target pose; counts are {:?}",
                views.iter().map(Vec::len).collect::<Vec<_>>()
            ),
        });
    }
    // 1. Every camera alone (its covariance is replaced by the joint adjustment's).
    let mono_options = CalibrationOptions { covariance: CovarianceMethod::Independent, ..options.clone() };
    let mut mono: Vec<CameraCalibration> = Vec::with_capacity(nc);
    let mut slots: Vec<Vec<Option<usize>>> = Vec::with_capacity(nc); // view slot -> index in mono views
    for (k, cam_views) in views.iter().enumerate() {
        let present: Vec<View> = cam_views.iter().flatten().cloned().collect();
        let cal = calibrate_camera(&present, target, &mono_options).map_err(|e| match e {
            VisionError::TooFewViews { usable, needed, detail } => {
                VisionError::TooFewViews { usable, needed, detail: format!("camera {k}: {detail}") }
            }
            VisionError::DegenerateViews { detail } => {
                VisionError::DegenerateViews { detail: format!("camera {k}: {detail}") }
            }
            other => other,
        })?;
        let mut idx = 0;
        let mut s = Vec::with_capacity(nv);
        for v in cam_views {
            if v.is_some() {
                s.push(cal.views[idx].used.then_some(idx));
                idx += 1;
            } else {
                s.push(None);
            }
        }
        slots.push(s);
        mono.push(cal);
    }
    let n_points = target.points_m.len();
    let flip = reversal(target);
    // Per camera and slot: pose T_cam_target and whether its numbering is reversed.
    let mut reversed = vec![vec![false; nv]; nc];
    let mut t_cam_cam0 = vec![Isometry3::identity(); nc];
    let view_pose = |k: usize, i: usize| slots[k][i].map(|j| mono[k].views[j].t_cam_target);
    for k in 1..nc {
        let mut cands: Vec<(usize, bool, Isometry3<f64>)> = Vec::new();
        for i in 0..nv {
            if let (Some(t0), Some(tk)) = (view_pose(0, i), view_pose(k, i)) {
                cands.push((i, false, tk * t0.inverse()));
                if let Some(f) = flip {
                    cands.push((i, true, tk * f * t0.inverse()));
                }
            }
        }
        if cands.is_empty() {
            return Err(VisionError::TooFewViews {
                usable: 0,
                needed: 1,
                detail: format!("camera {k} and camera 0 never saw the target at the same time"),
            });
        }
        // Consensus: the candidate with the most others close to it.
        let close = |a: &Isometry3<f64>, b: &Isometry3<f64>| pose_distance(a, b) < 0.1;
        let reference = cands
            .iter()
            .max_by_key(|(_, _, a)| cands.iter().filter(|(_, _, b)| close(a, b)).count())
            .map(|c| c.2)
            .unwrap_or_else(Isometry3::identity);
        let mut chosen = Vec::new();
        for (i, rev) in reversed[k].iter_mut().enumerate() {
            let mine: Vec<&(usize, bool, Isometry3<f64>)> = cands.iter().filter(|c| c.0 == i).collect();
            if let Some(best) =
                mine.iter().min_by(|a, b| pose_distance(&a.2, &reference).total_cmp(&pose_distance(&b.2, &reference)))
            {
                *rev = best.1;
                if close(&best.2, &reference) {
                    chosen.push(best.2);
                }
            }
        }
        if chosen.is_empty() {
            chosen.push(reference);
        }
        t_cam_cam0[k] = mean_pose(&chosen);
    }
    // 2. Initial target poses T_cam0_target.
    let mut view_of_slot: Vec<Option<usize>> = vec![None; nv];
    let mut poses: Vec<LocalPose> = Vec::new();
    for i in 0..nv {
        let start = (0..nc).find_map(|k| {
            view_pose(k, i).map(|t| {
                let t = if reversed[k][i] { t * flip.unwrap_or_else(Isometry3::identity) } else { t };
                t_cam_cam0[k].inverse() * t
            })
        });
        if let Some(t) = start {
            view_of_slot[i] = Some(poses.len());
            poses.push(LocalPose::from_isometry(&t));
        }
    }
    // 3. Observations.
    let mut obs = Vec::new();
    let mut reversed_views = Vec::new();
    for k in 0..nc {
        for i in 0..nv {
            let (Some(v), Some(_), Some(vi)) = (&views[k][i], slots[k][i], view_of_slot[i]) else { continue };
            if reversed[k][i] {
                reversed_views.push((k, v.name.clone()));
            }
            for (pid, px) in v.point_ids.iter().zip(&v.corners_px) {
                let pid = if reversed[k][i] { n_points - 1 - pid } else { *pid };
                obs.push(Obs { cam: k, view: vi, point_id: pid, point: target.points_m[pid], pixel: *px });
            }
        }
    }
    let layouts: Vec<CameraLayout> = mono
        .iter()
        .map(|c| CameraLayout {
            kind: options.model,
            fix_aspect: options.fix_aspect,
            aspect: 1.0,
            image_size: c.camera.image_size,
        })
        .collect();
    let mut bundle = Bundle {
        cameras: layouts.iter().zip(&mono).map(|(l, c)| l.free_from_model(&c.camera)).collect(),
        layouts: layouts.clone(),
        extrinsics: t_cam_cam0[1..].iter().map(LocalPose::from_isometry).collect(),
        views: poses,
        obs,
        loss: options.loss,
        deform: None,
        fixed_globals: false,
    };
    let (report, iterations) = bundle.solve(options.max_iterations)?;
    let (cov_global, s0_px, normal_condition) = match bundle.global_covariance() {
        Ok(c) => (c.covariance, c.s0_px, c.condition),
        // Over-parameterised lens models: keep the calibration, report NaN uncertainties.
        Err(VisionError::DegenerateViews { .. }) => {
            let n = bundle.n_global();
            (DMatrix::from_element(n, n, f64::NAN), f64::NAN, f64::INFINITY)
        }
        Err(e) => return Err(e),
    };
    // Free -> model parameters (extrinsics unchanged).
    let n_model: usize = layouts.iter().map(CameraLayout::n_model).sum();
    let n_rig = n_model + 6 * (nc - 1);
    let mut m = DMatrix::<f64>::zeros(n_rig, bundle.n_global());
    let mut row = 0;
    for (k, l) in layouts.iter().enumerate() {
        let mk = l.free_to_model();
        m.view_mut((row, bundle.global_index_camera(k)), (mk.nrows(), mk.ncols())).copy_from(&mk);
        row += mk.nrows();
    }
    for k in 1..nc {
        let col = bundle.global_index_extrinsic(k);
        for i in 0..6 {
            m[(row + 6 * (k - 1) + i, col + i)] = 1.0;
        }
    }
    let covariance = &m * &cov_global * m.transpose();

    // Reports.
    let res = bundle.residuals()?;
    let mut sq_all = 0.0;
    let mut n_all = 0usize;
    let mut cameras = Vec::with_capacity(nc);
    let mut row = 0;
    for k in 0..nc {
        let camera = bundle.camera_model(k)?;
        camera.validate()?;
        let nmk = layouts[k].n_model();
        let cov_k = covariance.view((row, row), (nmk, nmk)).into_owned();
        row += nmk;
        let std: Vec<f64> =
            (0..nmk).map(|i| if cov_k[(i, i)].is_nan() { f64::NAN } else { cov_k[(i, i)].max(0.0).sqrt() }).collect();
        let mut view_sq = vec![0.0; bundle.views.len()];
        let mut view_n = vec![0usize; bundle.views.len()];
        for (o, r) in bundle.obs.iter().zip(&res) {
            if o.cam != k {
                continue;
            }
            if let Some(r) = r {
                view_sq[o.view] += r.norm_squared();
                view_n[o.view] += 1;
            }
        }
        let sq: f64 = view_sq.iter().sum();
        let n: usize = view_n.iter().sum();
        sq_all += sq;
        n_all += n;
        let rms_views: Vec<f64> =
            view_sq.iter().zip(&view_n).filter(|(_, n)| **n > 0).map(|(s, n)| (s / *n as f64).sqrt()).collect();
        let med = median(&rms_views);
        let mut reports: Vec<ViewReport> = Vec::new();
        for i in 0..nv {
            let Some(v) = &views[k][i] else { continue };
            let (rms, used, t) = match (slots[k][i], view_of_slot[i]) {
                (Some(_), Some(vi)) if view_n[vi] > 0 => {
                    let t = if k == 0 {
                        bundle.views[vi].to_isometry()
                    } else {
                        bundle.extrinsics[k - 1].to_isometry() * bundle.views[vi].to_isometry()
                    };
                    ((view_sq[vi] / view_n[vi] as f64).sqrt(), true, t)
                }
                _ => (f64::NAN, false, Isometry3::identity()),
            };
            reports.push(ViewReport {
                name: v.name.clone(),
                rms_px: rms,
                n_corners: v.corners_px.len(),
                outlier: rms.is_finite() && rms > options.outlier_view_factor * med,
                used,
                n_outlier_corners: 0,
                t_cam_target: t,
            });
        }
        let mut cal = mono[k].clone();
        cal.camera = camera;
        cal.std = std;
        cal.covariance = cov_k;
        cal.rms_px = if n > 0 { (sq / n as f64).sqrt() } else { f64::NAN };
        cal.views = reports;
        cameras.push(cal);
    }
    let mut extrinsic_std = vec![[0.0; 6]; nc];
    for (k, e) in extrinsic_std.iter_mut().enumerate().skip(1) {
        let off = n_model + 6 * (k - 1);
        for (i, v) in e.iter_mut().enumerate() {
            *v = covariance[(off + i, off + i)].max(0.0).sqrt();
        }
    }
    let t_final: Vec<Isometry3<f64>> =
        std::iter::once(Isometry3::identity()).chain(bundle.extrinsics.iter().map(|e| e.to_isometry())).collect();
    let n_shared_views = (0..nv).filter(|&i| (0..nc).filter(|&k| slots[k][i].is_some()).count() >= 2).count();
    Ok(RigCalibration {
        cameras,
        t_cam_cam0: t_final,
        extrinsic_std,
        covariance,
        rms_px: if n_all > 0 { (sq_all / n_all as f64).sqrt() } else { f64::NAN },
        s0_px,
        normal_condition,
        n_views: bundle.views.len(),
        n_shared_views,
        reversed_views,
        iterations,
        solver_report: report,
    })
}
