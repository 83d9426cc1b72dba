//! The bundle adjustment behind every calibration: camera parameter blocks, rig extrinsics and
//! target poses solved by Ceres (through the least-squares layer, `ferrocal-lsq`) with analytic
//! Jacobians, then the covariance of the camera and
//! rig parameters with the target poses marginalised (Schur complement of the normal matrix).
//!
//! # State layout
//! Blocks, in this order (the "global" part first, then the "local" part):
//! 1. one block per camera: its *free* parameters, `fx fy cx cy k...` in
//!    [`crate::camera::CameraModel::parameters`] order, or `f cx cy k...` with a fixed aspect ratio
//!    (`fx = f`, `fy = a f`);
//! 2. one block per camera 1.. : `[t, w]` of `T_cam_cam0` (metres; left increment, radians);
//! 3. when the target's shape is estimated, one block `[b, s, t]` (metres), and when its print
//!    scale is, one block `[e_x]` ([`super::deform`]);
//! 4. one block per view: `[t, w]` of `T_cam0_target`.
//!
//! Pose blocks follow the project's 6-vector order (translation, then rotation;
//! docs/conventions.md).
//!
//! With [`Bundle::fixed_globals`] blocks 1 to 3 are held constant (only the views' poses move).
//! `Bundle::global_index_*` give the offset of a camera's, an extrinsic's or the target's block
//! in the global covariance. Measurements: one residual block per corner and camera, `projected -
//! observed` in pixels (two rows), with the robust loss applied to its squared length.

use nalgebra::{DMatrix, DVector, Matrix2x3, Matrix2xX, Matrix6, Point2, Point3, Rotation3, Vector2, Vector6};

use super::deform::TargetDeformation;
use super::RobustLoss;
use crate::camera::{CameraModel, Distortion, DistortionKind, ImageSize, Intrinsics};
use crate::error::{Result, VisionError};
use crate::pose::{observe, LocalPose};

/// How a camera's parameters are optimised.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct CameraLayout {
    pub kind: DistortionKind,
    /// `fy = aspect * fx` held fixed.
    pub fix_aspect: bool,
    /// The fixed ratio `fy / fx` (1 unless the caller says otherwise).
    pub aspect: f64,
    pub image_size: ImageSize,
}

impl CameraLayout {
    pub fn n_model(&self) -> usize {
        4 + self.kind.coefficient_names().len()
    }

    pub fn n_free(&self) -> usize {
        self.n_model() - usize::from(self.fix_aspect)
    }

    pub fn free_from_model(&self, m: &CameraModel) -> Vec<f64> {
        let k = &m.intrinsics;
        let mut v =
            if self.fix_aspect { vec![k.fx_px, k.cx_px, k.cy_px] } else { vec![k.fx_px, k.fy_px, k.cx_px, k.cy_px] };
        v.extend(m.distortion.coefficients());
        v
    }

    /// The camera of free parameters `p` (not validated: the optimiser may pass through odd
    /// values; projection fails where they make no sense).
    pub fn model(&self, p: &[f64]) -> Result<CameraModel> {
        let (intr, d) = if self.fix_aspect {
            (Intrinsics { fx_px: p[0], fy_px: self.aspect * p[0], cx_px: p[1], cy_px: p[2] }, &p[3..])
        } else {
            (Intrinsics { fx_px: p[0], fy_px: p[1], cx_px: p[2], cy_px: p[3] }, &p[4..])
        };
        Ok(CameraModel {
            intrinsics: intr,
            distortion: Distortion::from_coefficients(self.kind, d)?,
            image_size: self.image_size,
        })
    }

    /// `d(model parameters) / d(free parameters)` (n_model x n_free, constant).
    pub fn free_to_model(&self) -> DMatrix<f64> {
        let (nm, nf) = (self.n_model(), self.n_free());
        let mut m = DMatrix::zeros(nm, nf);
        if self.fix_aspect {
            m[(0, 0)] = 1.0;
            m[(1, 0)] = self.aspect;
            for i in 2..nm {
                m[(i, i - 1)] = 1.0;
            }
        } else {
            for i in 0..nm {
                m[(i, i)] = 1.0;
            }
        }
        m
    }

    /// Jacobian with respect to the free parameters from the one with respect to the model's.
    pub fn free_jacobian(&self, d_model: &Matrix2xX<f64>) -> Matrix2xX<f64> {
        if !self.fix_aspect {
            return d_model.clone();
        }
        let n = self.n_free();
        let mut j = Matrix2xX::zeros(n);
        for r in 0..2 {
            j[(r, 0)] = d_model[(r, 0)] + self.aspect * d_model[(r, 1)];
            for c in 1..n {
                j[(r, c)] = d_model[(r, c + 1)];
            }
        }
        j
    }
}

/// The bundle's residual block: one corner seen by one camera, `projected - observed` in pixels,
/// over the blocks `[camera free parameters, [t, w] of T_cam_cam0 (cameras 1..), [b, s, t] of
/// the target's shape (when free), [e_x] of its print scale (when free), [t, w] of
/// T_cam0_target]`, the pose blocks being charts around their reference rotations. Its Jacobians
/// are those of [`observe`] and, for the target's blocks, `d r / d p0 R_view d point / d block`;
/// all are checked by the least-squares layer's gradient checker in the tests.
pub(crate) struct CornerResidual {
    pub layout: CameraLayout,
    pub ext_ref: Option<Rotation3<f64>>,
    pub view_ref: Rotation3<f64>,
    /// The nominal target point.
    pub point: Point3<f64>,
    pub pixel: Point2<f64>,
    /// The target's deformation: held values, and which of its blocks are free.
    pub deform: Option<TargetDeformation>,
}

impl ferrocal_lsq::Residual for CornerResidual {
    fn n_residuals(&self) -> usize {
        2
    }

    fn evaluate(
        &self,
        p: &[&[f64]],
        out: &mut [f64],
        jacobians: Option<&mut [Option<DMatrix<f64>>]>,
    ) -> ferrocal_lsq::Result<()> {
        let chart = |r_ref: Rotation3<f64>, b: &[f64]| {
            LocalPose { r_ref, w: Default::default(), t: Default::default() }.with_block(b)
        };
        let camera = self.layout.model(p[0]).map_err(ferrocal_lsq::LsqError::model)?;
        let mut next = 1;
        let ext = self.ext_ref.map(|r| chart(r, p[1]));
        let ext_slot = ext.is_some().then(|| {
            next += 1;
            next - 1
        });
        let shape_slot = self.deform.filter(|d| d.shape_free).map(|_| {
            next += 1;
            next - 1
        });
        let scale_slot = self.deform.filter(|d| d.scale_free).map(|_| {
            next += 1;
            next - 1
        });
        let view = chart(self.view_ref, p[next]);
        let deformed = self.deform.map(|d| {
            let shape = shape_slot.map_or(&d.shape_m[..], |s| p[s]);
            d.apply(&self.point, shape, scale_slot.map_or(d.scale[0], |s| p[s][0]))
        });
        let point = deformed.map_or(self.point, |d| d.point);
        let ob = observe(&camera, ext.as_ref(), &view, &point, &self.pixel).map_err(ferrocal_lsq::LsqError::model)?;
        if !(ob.residual.x.is_finite() && ob.residual.y.is_finite()) {
            return Err(ferrocal_lsq::LsqError::Numeric("a corner projected to a non-finite pixel".into()));
        }
        out[0] = ob.residual.x;
        out[1] = ob.residual.y;
        if let Some(jac) = jacobians {
            if let Some(d) = &mut jac[0] {
                let jf = self.layout.free_jacobian(&ob.d_model);
                d.copy_from(&DMatrix::from_fn(2, jf.ncols(), |r, c| jf[(r, c)]));
            }
            if let Some(d) = ext_slot.and_then(|s| jac[s].as_mut()) {
                d.copy_from(&DMatrix::from_fn(2, 6, |r, c| ob.d_ext[(r, c)]));
            }
            if let Some(def) = deformed {
                let d_target = d_residual_d_target_point(&ob.d_view, &view);
                if let Some(d) = shape_slot.and_then(|s| jac[s].as_mut()) {
                    let m = d_target * def.d_shape;
                    d.copy_from(&DMatrix::from_fn(2, 3, |r, c| m[(r, c)]));
                }
                if let Some(d) = scale_slot.and_then(|s| jac[s].as_mut()) {
                    let m = d_target * def.d_scale_x;
                    d.copy_from(&DMatrix::from_fn(2, 1, |r, _| m[r]));
                }
            }
            if let Some(d) = &mut jac[next] {
                d.copy_from(&DMatrix::from_fn(2, 6, |r, c| ob.d_view[(r, c)]));
            }
        }
        Ok(())
    }

    fn row_names(&self) -> Vec<String> {
        vec!["x_px".into(), "y_px".into()]
    }
}

/// `d residual / d (point in the target frame)`: the view block's translation columns (the
/// first three) are `d residual / d p0` (`p0 = R_view x + t_view`), so this is those columns
/// times `R_view`.
fn d_residual_d_target_point(d_view: &nalgebra::Matrix2x6<f64>, view: &LocalPose) -> Matrix2x3<f64> {
    d_view.fixed_view::<2, 3>(0, 0) * view.rotation().matrix()
}

/// One corner seen by one camera in one view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Obs {
    pub cam: usize,
    pub view: usize,
    /// Index of the point in the target (for reports).
    pub point_id: usize,
    pub point: Point3<f64>,
    pub pixel: Point2<f64>,
}

/// A bundle-adjustment problem (see the module documentation for the layout).
#[derive(Clone, Debug)]
pub(crate) struct Bundle {
    pub layouts: Vec<CameraLayout>,
    /// Free parameters of every camera.
    pub cameras: Vec<Vec<f64>>,
    /// `T_cam_cam0` of cameras 1.. .
    pub extrinsics: Vec<LocalPose>,
    /// `T_cam0_target` of every view.
    pub views: Vec<LocalPose>,
    pub obs: Vec<Obs>,
    pub loss: RobustLoss,
    /// The target's deformation (one camera's bundles; `None`: the nominal target).
    pub deform: Option<TargetDeformation>,
    /// Hold the cameras, extrinsics and target blocks constant: only the views' poses move.
    pub fixed_globals: bool,
}

/// The marginal covariance of the global parameters.
#[derive(Clone, Debug)]
pub(crate) struct GlobalCovariance {
    /// `s0^2 S^-1`, S the Schur complement of the view blocks (free parameters).
    pub covariance: DMatrix<f64>,
    /// A-posteriori standard error of unit weight, pixels.
    pub s0_px: f64,
    /// Condition number of the correlation-scaled Schur complement.
    pub condition: f64,
    /// Per view with observations, the view's score in the global parameters with its pose
    /// marginalised, `sum_i w_i J_gi^T r_i - N_gv N_vv^-1 sum_i w_i J_vi^T r_i` (the second
    /// term is zero at an exact optimum), for the view-clustered sandwich
    /// ([`GlobalCovariance::view_sandwich`]).
    pub view_scores: Vec<DVector<f64>>,
    /// Measurements (residual rows) and unknowns of the adjustment.
    pub dof: (usize, usize),
}

impl GlobalCovariance {
    /// The view-clustered sandwich covariance `S^-1 (c sum_v g_v g_v^T) S^-1` of the global
    /// parameters, `S` the Schur complement (so `S^-1 = covariance / s0^2`), `g_v` the views'
    /// [`GlobalCovariance::view_scores`], `c = G / (G - 1) (m - 1) / (m - n)` the usual
    /// small-sample factor of clustered sandwiches (`G` views, `m` measurements, `n`
    /// unknowns). It makes no assumption about how the corners of one view are correlated,
    /// only that views are independent.
    pub fn view_sandwich(&self) -> DMatrix<f64> {
        let ng = self.covariance.nrows();
        let s_inv = &self.covariance / (self.s0_px * self.s0_px);
        let mut meat = DMatrix::<f64>::zeros(ng, ng);
        for g in &self.view_scores {
            meat += g * g.transpose();
        }
        let n_views = self.view_scores.len() as f64;
        let (m, n) = (self.dof.0 as f64, self.dof.1 as f64);
        let c = n_views / (n_views - 1.0).max(1.0) * (m - 1.0) / (m - n).max(1.0);
        let cov = &s_inv * (meat * c) * &s_inv;
        0.5 * (&cov + cov.transpose())
    }
}

/// Weight `rho'(s)` of a residual with squared length `s` under the loss.
pub(crate) fn loss_weight(loss: RobustLoss, s: f64) -> f64 {
    match loss {
        RobustLoss::None => 1.0,
        RobustLoss::Huber { scale_px } => {
            if s <= scale_px * scale_px {
                1.0
            } else {
                scale_px / s.sqrt()
            }
        }
        RobustLoss::Cauchy { scale_px } => 1.0 / (1.0 + s / (scale_px * scale_px)),
    }
}

fn solver_failed(detail: impl Into<String>) -> VisionError {
    VisionError::SolverFailed { stage: "bundle adjustment".into(), detail: detail.into() }
}

impl Bundle {
    pub fn n_global(&self) -> usize {
        self.global_index_deform() + self.deform.map_or(0, |d| d.n_free())
    }

    /// Offset of the target's free blocks (shape, then print scale) in the global vector.
    pub fn global_index_deform(&self) -> usize {
        self.layouts.iter().map(CameraLayout::n_free).sum::<usize>() + 6 * self.extrinsics.len()
    }

    /// The target point an observation sees (deformed when the bundle has a deformation).
    fn target_point(&self, o: &Obs) -> Point3<f64> {
        self.deform.map_or(o.point, |d| d.point(&o.point))
    }

    /// Offset of camera `k`'s free parameters in the global vector.
    pub fn global_index_camera(&self, k: usize) -> usize {
        self.layouts[..k].iter().map(CameraLayout::n_free).sum()
    }

    /// Offset of `T_cam_cam0` of camera `k >= 1` in the global vector.
    pub fn global_index_extrinsic(&self, k: usize) -> usize {
        self.layouts.iter().map(CameraLayout::n_free).sum::<usize>() + 6 * (k - 1)
    }

    pub fn camera_model(&self, k: usize) -> Result<CameraModel> {
        self.layouts[k].model(&self.cameras[k])
    }

    /// Solves with Ceres; rotation increments are folded into their references afterwards and
    /// the problem re-solved while an increment came out larger than 0.3 rad (at most 4
    /// rounds). Returns Ceres' brief report of the last round and the iterations in all.
    pub fn solve(&mut self, max_iterations: usize) -> Result<(String, usize)> {
        let mut report = String::new();
        let mut iterations = 0;
        for _round in 0..4 {
            let (r, it, max_w) = self.solve_once(max_iterations)?;
            report = r;
            iterations += it;
            if max_w < 0.3 {
                break;
            }
        }
        Ok((report, iterations))
    }

    /// One solve through the least-squares layer's Ceres back end: the camera blocks and the
    /// `[t, w]` charts of the extrinsics and views around their reference rotations are
    /// Euclidean blocks, one [`CornerResidual`] per observation.
    fn solve_once(&mut self, max_iterations: usize) -> Result<(String, usize, f64)> {
        let nc = self.cameras.len();
        let ne = self.extrinsics.len();
        let lsq_failed = |e: ferrocal_lsq::LsqError| match e.into_model::<VisionError>() {
            Ok(own) => own,
            Err(other) => solver_failed(other.to_string()),
        };
        let mut problem = ferrocal_lsq::Problem::new();
        let mut ids = Vec::with_capacity(nc + ne + self.views.len());
        for (k, c) in self.cameras.iter().enumerate() {
            ids.push(problem.add_euclidean(&format!("camera{k}"), c.clone()).map_err(lsq_failed)?);
        }
        for (k, e) in self.extrinsics.iter().enumerate() {
            ids.push(problem.add_euclidean(&format!("t_cam{}_cam0", k + 1), e.block().to_vec()).map_err(lsq_failed)?);
        }
        for (k, v) in self.views.iter().enumerate() {
            ids.push(problem.add_euclidean(&format!("t_cam0_view{k}"), v.block().to_vec()).map_err(lsq_failed)?);
        }
        if self.fixed_globals {
            for id in &ids[..nc + ne] {
                problem.set_constant(*id, true).map_err(lsq_failed)?;
            }
        }
        // The target's free blocks (never free with fixed globals: see `Bundle::fixed_globals`).
        let deform = self.deform.map(|mut d| {
            d.shape_free &= !self.fixed_globals;
            d.scale_free &= !self.fixed_globals;
            d
        });
        let shape_id = match deform.filter(|d| d.shape_free) {
            Some(d) => Some(problem.add_euclidean("target_shape", d.shape_m.to_vec()).map_err(lsq_failed)?),
            None => None,
        };
        let scale_id = match deform.filter(|d| d.scale_free) {
            Some(d) => Some(problem.add_euclidean("target_print_scale", vec![d.scale[0]]).map_err(lsq_failed)?),
            None => None,
        };
        let loss = match self.loss {
            RobustLoss::None => ferrocal_lsq::Loss::Squared,
            RobustLoss::Huber { scale_px } => ferrocal_lsq::Loss::Huber { delta: scale_px },
            RobustLoss::Cauchy { scale_px } => ferrocal_lsq::Loss::Cauchy { delta: scale_px },
        };
        for o in &self.obs {
            let mut blocks = vec![ids[o.cam]];
            if o.cam > 0 {
                blocks.push(ids[nc + o.cam - 1]);
            }
            blocks.extend(shape_id);
            blocks.extend(scale_id);
            blocks.push(ids[nc + ne + o.view]);
            let residual = CornerResidual {
                layout: self.layouts[o.cam],
                ext_ref: (o.cam > 0).then(|| self.extrinsics[o.cam - 1].r_ref),
                view_ref: self.views[o.view].r_ref,
                point: o.point,
                pixel: o.pixel,
                deform,
            };
            let name = format!("view{}.point{}.cam{}", o.view, o.point_id, o.cam);
            problem.add_residual(&name, Box::new(residual), &blocks, loss).map_err(lsq_failed)?;
        }
        let options = ferrocal_lsq::SolverOptions {
            backend: ferrocal_lsq::Backend::Ceres,
            max_iterations,
            cost_tolerance: 1e-14,
            step_tolerance: 1e-14,
            max_rounds: 1,
            ceres_linear_solver: ferrocal_lsq::CeresLinearSolver::DenseQr,
            ..Default::default()
        };
        let solution = problem.solve(&options).map_err(lsq_failed)?;
        let mut max_w: f64 = 0.0;
        for (k, c) in self.cameras.iter_mut().enumerate() {
            c.copy_from_slice(&problem.block(ids[k]).values);
        }
        for (k, e) in self.extrinsics.iter_mut().enumerate() {
            *e = e.with_block(&problem.block(ids[nc + k]).values);
            max_w = max_w.max(e.w.norm());
            e.rebase();
        }
        for (k, v) in self.views.iter_mut().enumerate() {
            *v = v.with_block(&problem.block(ids[nc + ne + k]).values);
            max_w = max_w.max(v.w.norm());
            v.rebase();
        }
        if let Some(d) = &mut self.deform {
            if let Some(id) = shape_id {
                d.shape_m.copy_from_slice(&problem.block(id).values);
            }
            if let Some(id) = scale_id {
                d.scale[0] = problem.block(id).values[0];
            }
        }
        Ok((solution.summary.termination, solution.summary.iterations, max_w))
    }

    /// Residuals (`projected - observed`, pixels) of every observation; `None` where the
    /// point cannot be projected.
    pub fn residuals(&self) -> Result<Vec<Option<Vector2<f64>>>> {
        self.residuals_of(&self.obs)
    }

    /// Residuals of any observations (also ones not in the bundle) at the current state.
    pub fn residuals_of(&self, obs: &[Obs]) -> Result<Vec<Option<Vector2<f64>>>> {
        let models: Vec<CameraModel> = (0..self.cameras.len()).map(|k| self.camera_model(k)).collect::<Result<_>>()?;
        Ok(obs
            .iter()
            .map(|o| {
                let ext = (o.cam > 0).then(|| self.extrinsics[o.cam - 1]);
                observe(&models[o.cam], ext.as_ref(), &self.views[o.view], &self.target_point(o), &o.pixel)
                    .ok()
                    .map(|ob| ob.residual)
            })
            .collect())
    }

    /// The covariance of the global parameters (cameras' free parameters, then extrinsics, then
    /// the target's free blocks), the view poses marginalised: `s0^2 (N_gg - sum_v N_gv N_vv^-1 N_vg)^-1` with the
    /// robust loss as weights `rho'(|r|^2)` and `s0^2 = sum w |r|^2 / (m - n)`.
    pub fn global_covariance(&self) -> Result<GlobalCovariance> {
        let ng = self.n_global();
        let nv = self.views.len();
        let models: Vec<CameraModel> = (0..self.cameras.len()).map(|k| self.camera_model(k)).collect::<Result<_>>()?;
        let mut n_gg = DMatrix::<f64>::zeros(ng, ng);
        let mut n_gv: Vec<DMatrix<f64>> = vec![DMatrix::zeros(ng, 6); nv];
        let mut n_vv: Vec<Matrix6<f64>> = vec![Matrix6::zeros(); nv];
        let mut used = vec![0usize; nv];
        let mut score_g: Vec<DVector<f64>> = vec![DVector::zeros(ng); nv];
        let mut score_v: Vec<Vector6<f64>> = vec![Vector6::zeros(); nv];
        let mut sum_wr2 = 0.0;
        let mut m = 0usize;
        for o in &self.obs {
            let ext = (o.cam > 0).then(|| self.extrinsics[o.cam - 1]);
            let deformed = self.deform.map(|d| d.apply(&o.point, &d.shape_m, d.scale[0]));
            let point = deformed.map_or(o.point, |d| d.point);
            let ob = observe(&models[o.cam], ext.as_ref(), &self.views[o.view], &point, &o.pixel)?;
            let s = ob.residual.norm_squared();
            let w = loss_weight(self.loss, s);
            sum_wr2 += w * s;
            m += 2;
            used[o.view] += 1;
            let mut jg = DMatrix::<f64>::zeros(2, ng);
            let jf = self.layouts[o.cam].free_jacobian(&ob.d_model);
            let off = self.global_index_camera(o.cam);
            jg.view_mut((0, off), (2, jf.ncols())).copy_from(&jf);
            if o.cam > 0 {
                let off = self.global_index_extrinsic(o.cam);
                jg.view_mut((0, off), (2, 6)).copy_from(&ob.d_ext);
            }
            if let (Some(d), Some(def)) = (self.deform, deformed) {
                let d_target = d_residual_d_target_point(&ob.d_view, &self.views[o.view]);
                let mut off = self.global_index_deform();
                if d.shape_free {
                    jg.view_mut((0, off), (2, 3)).copy_from(&(d_target * def.d_shape));
                    off += 3;
                }
                if d.scale_free {
                    jg.view_mut((0, off), (2, 1)).copy_from(&(d_target * def.d_scale_x));
                }
            }
            let jgt = jg.transpose();
            n_gg += w * &jgt * &jg;
            let jv = DMatrix::from_column_slice(2, 6, ob.d_view.as_slice());
            n_gv[o.view] += w * &jgt * &jv;
            n_vv[o.view] += w * ob.d_view.transpose() * ob.d_view;
            score_g[o.view] += w * &jgt * ob.residual;
            score_v[o.view] += w * ob.d_view.transpose() * ob.residual;
        }
        let active = used.iter().filter(|&&u| u > 0).count();
        let n = ng + 6 * active;
        if m <= n {
            return Err(VisionError::TooFewViews {
                usable: active,
                needed: active + 1,
                detail: format!("{m} measurements for {n} unknowns: no redundancy left to estimate the noise"),
            });
        }
        let mut s = n_gg;
        let mut view_scores = Vec::with_capacity(active);
        for v in 0..nv {
            if used[v] == 0 {
                continue;
            }
            let inv = n_vv[v].try_inverse().ok_or_else(|| VisionError::DegenerateViews {
                detail: format!("view {v}: its corners do not determine the target pose"),
            })?;
            let pose_step = DVector::from_column_slice((inv * score_v[v]).as_slice());
            view_scores.push(&score_g[v] - &n_gv[v] * pose_step);
            let inv = DMatrix::from_column_slice(6, 6, inv.as_slice());
            s -= &n_gv[v] * inv * n_gv[v].transpose();
        }
        let s = 0.5 * (&s + s.transpose());
        let d: Vec<f64> = (0..ng).map(|i| s[(i, i)]).collect();
        if d.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
            return Err(VisionError::DegenerateViews {
                detail: format!(
                    "a camera parameter has no influence on the corners (zero row in the normal matrix; state {:?})",
                    self.cameras
                ),
            });
        }
        let mut scaled = s.clone();
        for i in 0..ng {
            for j in 0..ng {
                scaled[(i, j)] /= (d[i] * d[j]).sqrt();
            }
        }
        let eig = nalgebra::SymmetricEigen::new(scaled.clone());
        let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
        for &e in eig.eigenvalues.iter() {
            lo = lo.min(e);
            hi = hi.max(e);
        }
        let condition = if lo > 0.0 { hi / lo } else { f64::INFINITY };
        if condition.is_nan() || condition >= 1e14 {
            return Err(VisionError::DegenerateViews {
                detail: format!(
                    "the views do not determine all camera parameters (condition number of the scaled normal \
                     matrix {condition:.2e}); take views with the board tilted about different axes and \
                     covering the image"
                ),
            });
        }
        let inv_scaled = scaled.cholesky().map(|c| c.inverse()).ok_or_else(|| VisionError::DegenerateViews {
            detail: "the normal matrix of the camera parameters is not positive definite".into(),
        })?;
        let s0_sq = sum_wr2 / (m - n) as f64;
        let mut cov = inv_scaled;
        for i in 0..ng {
            for j in 0..ng {
                cov[(i, j)] *= s0_sq / (d[i] * d[j]).sqrt();
            }
        }
        Ok(GlobalCovariance { covariance: cov, s0_px: s0_sq.sqrt(), condition, view_scores, dof: (m, n) })
    }
}
