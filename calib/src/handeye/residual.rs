//! The residual blocks of the hand-eye refinement, with analytic Jacobians.
//!
//! [`ChainCorner`]: one detected corner predicted through the chain
//!
//! ```text
//! eye-in-hand: p_cam = X^-1 · T_base_flange^-1 · W · (s P)     X = T_flange_camera, W = T_base_target
//! eye-to-hand: p_cam = W^-1 · T_base_flange · X · (s P)        X = T_flange_target, W = T_base_camera
//! ```
//!
//! and the camera model, minus the detected pixel, whitened by the corner's covariance
//! (`r = L^-1 (projected - detected)` with `Σ = L L^T`). Blocks, in order: `X`, `W` and the
//! robot pose `T_base_flange` (each on the `Se3` manifold, product chart `t' = t + δt`,
//! `R' = Exp(δr) R`), the camera's parameter vector (`fx fy cx cy k...`, Euclidean), and, when
//! fitted, the target's scale `s` (Euclidean, 1 value), its shape `[b, s, t]` (sags of a bowl, a
//! saddle and a twist at its edge, metres) and the relative error `e_x` of its printed x spacing
//! against its y spacing ([`TargetBlocks`]; `P` is then the deformed point of
//! [`ferrocal_vision::calib::TargetDeformation`], scaled by `s`).
//!
//! [`RobotPosePrior`]: the robot pose as a measurement, `[(t - t_reported) / σ_t,
//! Log(R R_reported^T) / σ_r]`, for fits that let the reported flange poses move within their
//! noise.

use nalgebra::{DMatrix, Isometry3, Matrix2, Matrix2x3, Matrix3, Matrix3x1, Point2, Point3, Vector3};

use ferrocal_lsq::{LsqError, Residual, Se3};
use ferrocal_vision::calib::TargetDeformation;
use ferrocal_vision::camera::{CameraModel, Distortion, Intrinsics};

use super::Mount;

/// The camera of parameter vector `v` (the order of [`CameraModel::parameters`]) with the lens
/// model and image size of `template`.
pub(crate) fn camera_with(template: &CameraModel, v: &[f64]) -> ferrocal_lsq::Result<CameraModel> {
    let distortion = Distortion::from_coefficients(template.distortion.kind(), &v[4..]).map_err(LsqError::model)?;
    Ok(CameraModel {
        intrinsics: Intrinsics { fx_px: v[0], fy_px: v[1], cx_px: v[2], cy_px: v[3] },
        distortion,
        image_size: template.image_size,
    })
}

/// The whitening matrix `L^-1` of a 2 x 2 covariance `Σ = L L^T` (px^2); `None` when `Σ` is not
/// positive definite.
pub fn whitening(cov_px2: &Matrix2<f64>) -> Option<Matrix2<f64>> {
    let sym = 0.5 * (cov_px2 + cov_px2.transpose());
    let l = sym.cholesky()?.l();
    l.try_inverse()
}

/// The Jacobians a residual block is asked for (`Residual::evaluate`'s), with the corner's
/// `d r / d p_cam` (2 x 3).
pub(crate) type CornerJacobians<'a> = (&'a mut [Option<DMatrix<f64>>], Matrix2x3<f64>);

/// The reprojection residual of a corner: the camera-frame point `p_cam` projected by `camera`
/// minus the detected pixel, whitened (`corner`: the detected pixel and `L^-1`), written to
/// `residuals`. With Jacobians wanted, the camera block's (the fourth, `jacobians[3]`) is
/// filled and the Jacobians come back with `d r / d p_cam` (2 x 3) for the caller's blocks.
pub(crate) fn reproject<'a>(
    camera: &CameraModel,
    p_cam: &Vector3<f64>,
    (detected_px, whiten): (&Point2<f64>, &Matrix2<f64>),
    residuals: &mut [f64],
    jacobians: Option<&'a mut [Option<DMatrix<f64>>]>,
) -> ferrocal_lsq::Result<Option<CornerJacobians<'a>>> {
    let proj = camera.project_with_jacobians(&Point3::from(*p_cam)).map_err(LsqError::model)?;
    let r = whiten * (proj.pixel - detected_px);
    residuals[0] = r.x;
    residuals[1] = r.y;
    let Some(jacs) = jacobians else { return Ok(None) };
    fill(&mut jacs[3], (whiten * &proj.d_pixel_d_params).as_slice());
    Ok(Some((jacs, whiten * proj.d_pixel_d_point)))
}

/// Copies the column-major slice `m` of a 2 x k block into its Jacobian, when wanted.
pub(crate) fn fill(j: &mut Option<DMatrix<f64>>, m: &[f64]) {
    if let Some(j) = j {
        j.copy_from_slice(m);
    }
}

/// The camera-frame point of target point `p0` and its derivatives with respect to the
/// tangent steps of `X`, `W`, the robot pose (3 x 6 each) and the target scale (3 x 1).
pub(crate) struct ChainPoint {
    pub p_cam: Vector3<f64>,
    pub d_x: nalgebra::Matrix3x6<f64>,
    pub d_w: nalgebra::Matrix3x6<f64>,
    pub d_robot: nalgebra::Matrix3x6<f64>,
    pub d_scale: Matrix3x1<f64>,
    /// `d p_cam / d p` for the (scaled) target-frame point `p`.
    pub d_target: Matrix3<f64>,
}

impl ChainPoint {
    /// Carries the point into a further camera `k` of a rig, `p_k = T_k0 · p_0` (`t_k0` is
    /// `T_camk_cam0`, this point being in the reference camera 0), the derivatives with it, and
    /// returns the derivative of `p_k` with respect to `T_k0`'s tangent step (3 x 6, the `Se3`
    /// product chart `t' = t + δt`, `R' = Exp(δr) R`).
    pub(crate) fn move_to_camera(&mut self, t_k0: &Isometry3<f64>) -> nalgebra::Matrix3x6<f64> {
        let r = t_k0.rotation.to_rotation_matrix().into_inner();
        let rp = r * self.p_cam;
        self.p_cam = rp + t_k0.translation.vector;
        self.d_x = r * self.d_x;
        self.d_w = r * self.d_w;
        self.d_robot = r * self.d_robot;
        self.d_scale = r * self.d_scale;
        self.d_target = r * self.d_target;
        let mut d = nalgebra::Matrix3x6::zeros();
        put(&mut d, Matrix3::identity(), -rp.cross_matrix());
        d
    }
}

fn put(d: &mut nalgebra::Matrix3x6<f64>, dt: Matrix3<f64>, dr: Matrix3<f64>) {
    d.fixed_view_mut::<3, 3>(0, 0).copy_from(&dt);
    d.fixed_view_mut::<3, 3>(0, 3).copy_from(&dr);
}

/// The chain of the module documentation for one target point (nominal, metres) and its
/// derivatives.
pub(crate) fn chain_point(
    mount: Mount,
    x: &Isometry3<f64>,
    w: &Isometry3<f64>,
    t_base_flange: &Isometry3<f64>,
    scale: f64,
    p0: &Point3<f64>,
) -> ChainPoint {
    let rx = x.rotation.to_rotation_matrix().into_inner();
    let rw = w.rotation.to_rotation_matrix().into_inner();
    let rm = t_base_flange.rotation.to_rotation_matrix().into_inner();
    let (tx, tw, tm) = (x.translation.vector, w.translation.vector, t_base_flange.translation.vector);
    let p = p0.coords * scale;
    let mut out = ChainPoint {
        p_cam: Vector3::zeros(),
        d_x: nalgebra::Matrix3x6::zeros(),
        d_w: nalgebra::Matrix3x6::zeros(),
        d_robot: nalgebra::Matrix3x6::zeros(),
        d_scale: Matrix3x1::zeros(),
        d_target: Matrix3::zeros(),
    };
    match mount {
        Mount::EyeToHand => {
            let rxp = rx * p;
            let q = rxp + tx;
            let rmq = rm * q;
            let v = rmq + tm - tw;
            let rwt = rw.transpose();
            out.p_cam = rwt * v;
            let a = rwt * rm;
            put(&mut out.d_x, a, -a * rxp.cross_matrix());
            put(&mut out.d_w, -rwt, rwt * v.cross_matrix());
            put(&mut out.d_robot, rwt, -rwt * rmq.cross_matrix());
            out.d_target = a * rx;
            out.d_scale = out.d_target * p0.coords;
        }
        Mount::EyeInHand => {
            let rwp = rw * p;
            let u = rwp + tw - tm;
            let f = rm.transpose() * u;
            let g = f - tx;
            let rxt = rx.transpose();
            out.p_cam = rxt * g;
            let a = rxt * rm.transpose();
            put(&mut out.d_w, a, -a * rwp.cross_matrix());
            put(&mut out.d_robot, -a, a * u.cross_matrix());
            put(&mut out.d_x, -rxt, rxt * g.cross_matrix());
            out.d_target = a * rw;
            out.d_scale = out.d_target * p0.coords;
        }
    }
    out
}

/// One corner predicted through the chain (see the module documentation).
#[derive(Clone, Debug)]
pub struct ChainCorner {
    /// The mount.
    pub mount: Mount,
    /// The target point, metres, target frame (nominal spacing).
    pub point_m: Point3<f64>,
    /// The detected corner, pixels.
    pub detected_px: Point2<f64>,
    /// `L^-1` of the corner's covariance (`Σ = L L^T`), 1/px.
    pub whiten: Matrix2<f64>,
    /// Lens model and image size of the camera block.
    pub camera: CameraModel,
    /// The target blocks that follow the camera block.
    pub target: TargetBlocks,
}

/// The target's blocks of a [`ChainCorner`] after the camera block, in this order: the overall
/// scale `s` (1 value) when `scale`; the shape `[b, s, t]` (3 values, metres) when the
/// deformation's `shape_free`; `e_x` (1 value) when its `scale_free`. A deformation's held parts
/// keep their values; without a deformation the target is flat and printed to its nominal
/// spacing (up to `s`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TargetBlocks {
    /// Whether the overall scale is a block.
    pub scale: bool,
    /// The target's bending and anisotropic print scale.
    pub form: Option<TargetDeformation>,
}

impl TargetBlocks {
    /// Number of blocks after the camera block.
    pub fn n_blocks(&self) -> usize {
        usize::from(self.scale) + self.form.map_or(0, |f| usize::from(f.shape_free) + usize::from(f.scale_free))
    }
}

impl Residual for ChainCorner {
    fn n_residuals(&self) -> usize {
        2
    }

    fn evaluate(
        &self,
        params: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut [Option<DMatrix<f64>>]>,
    ) -> ferrocal_lsq::Result<()> {
        let x = Se3::to_isometry(params[0]);
        let w = Se3::to_isometry(params[1]);
        let m = Se3::to_isometry(params[2]);
        let camera = camera_with(&self.camera, params[3])?;
        let mut k = 4;
        let mut next = || {
            k += 1;
            params[k - 1]
        };
        let scale = if self.target.scale { next()[0] } else { 1.0 };
        let (point, form) = match &self.target.form {
            None => (self.point_m, None),
            Some(f) => {
                let shape = if f.shape_free { next() } else { &f.shape_m[..] };
                let e_x = if f.scale_free { next()[0] } else { f.scale[0] };
                let d = f.apply(&self.point_m, shape, e_x);
                (d.point, Some(d))
            }
        };
        let c = chain_point(self.mount, &x, &w, &m, scale, &point);
        let Some((jacs, sp)) = reproject(&camera, &c.p_cam, (&self.detected_px, &self.whiten), residuals, jacobians)?
        else {
            return Ok(());
        };
        fill(&mut jacs[0], (sp * c.d_x).as_slice());
        fill(&mut jacs[1], (sp * c.d_w).as_slice());
        fill(&mut jacs[2], (sp * c.d_robot).as_slice());
        let mut k = 4;
        if self.target.scale {
            fill(&mut jacs[k], (sp * c.d_scale).as_slice());
            k += 1;
        }
        if let (Some(f), Some(d)) = (&self.target.form, form) {
            let sd = sp * c.d_target * scale;
            if f.shape_free {
                fill(&mut jacs[k], (sd * d.d_shape).as_slice());
                k += 1;
            }
            if f.scale_free {
                fill(&mut jacs[k], (sd * d.d_scale_x).as_slice());
            }
        }
        Ok(())
    }

    fn row_names(&self) -> Vec<String> {
        vec!["x".into(), "y".into()]
    }
}

/// A reported robot pose as a measurement of the robot-pose block (see the module
/// documentation).
#[derive(Clone, Debug)]
pub struct RobotPosePrior {
    /// `T_base_flange` as reported.
    pub reported: Isometry3<f64>,
    /// Standard deviation of each position coordinate, metres.
    pub sigma_m: f64,
    /// Standard deviation of each rotation-vector coordinate, radians.
    pub sigma_rad: f64,
}

impl Residual for RobotPosePrior {
    fn n_residuals(&self) -> usize {
        6
    }

    fn evaluate(
        &self,
        params: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut [Option<DMatrix<f64>>]>,
    ) -> ferrocal_lsq::Result<()> {
        let t = Se3::to_isometry(params[0]);
        let dt = t.translation.vector - self.reported.translation.vector;
        let phi = (t.rotation * self.reported.rotation.inverse()).scaled_axis();
        for i in 0..3 {
            residuals[i] = dt[i] / self.sigma_m;
            residuals[3 + i] = phi[i] / self.sigma_rad;
        }
        if let Some(jacs) = jacobians {
            if let Some(j) = &mut jacs[0] {
                let jr = ferrocal_lsq::so3::left_jacobian_inverse(&phi) / self.sigma_rad;
                for i in 0..3 {
                    j[(i, i)] = 1.0 / self.sigma_m;
                    for k in 0..3 {
                        j[(3 + i, 3 + k)] = jr[(i, k)];
                    }
                }
            }
        }
        Ok(())
    }

    fn row_names(&self) -> Vec<String> {
        ["tx", "ty", "tz", "rx", "ry", "rz"].map(String::from).to_vec()
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use ferrocal_lsq::check::check_residual;
    use ferrocal_lsq::{Euclidean, Manifold};
    use ferrocal_vision::camera::ImageSize;

    use super::*;

    fn camera() -> CameraModel {
        CameraModel::new(
            Intrinsics { fx_px: 800.0, fy_px: 805.0, cx_px: 322.0, cy_px: 238.0 },
            Distortion::Brown5 { k1: -0.12, k2: 0.05, p1: 0.001, p2: -0.0007, k3: 0.0 },
            ImageSize { width_px: 640, height_px: 480 },
        )
        .unwrap()
    }

    /// The analytic Jacobians of both mounts (with the target scale, shape and print scale, off
    /// the identity of every block) agree with central differences through the manifolds.
    #[test]
    fn chain_corner_jacobians_pass_the_gradient_check() {
        let cam = camera();
        for mount in [Mount::EyeInHand, Mount::EyeToHand] {
            // A consistent geometry: the target 0.6 m in front of the camera.
            let t_cam_target = Isometry3::new(Vector3::new(0.02, -0.03, 0.6), Vector3::new(0.2, -0.3, 0.1));
            let m = Isometry3::new(Vector3::new(0.5, 0.2, 0.7), Vector3::new(2.0, 0.3, -0.4));
            let x = Isometry3::new(Vector3::new(0.03, 0.01, 0.09), Vector3::new(0.1, -1.4, 0.3));
            let w = match mount {
                Mount::EyeInHand => m * x * t_cam_target,
                Mount::EyeToHand => m * x * t_cam_target.inverse(),
            };
            let target = [Point3::new(-0.1, -0.08, 0.0), Point3::new(0.12, 0.09, 0.0)];
            let mut form = TargetDeformation::of_points(&target).unwrap();
            (form.shape_free, form.scale_free) = (true, true);
            let r = ChainCorner {
                mount,
                point_m: Point3::new(0.05, 0.03, 0.0),
                detected_px: Point2::new(300.0, 250.0),
                whiten: whitening(&Matrix2::new(0.04, 0.01, 0.01, 0.09)).unwrap(),
                camera: cam,
                target: TargetBlocks { scale: true, form: Some(form) },
            };
            let blocks: Vec<Vec<f64>> = vec![
                Se3::from_isometry(&x).to_vec(),
                Se3::from_isometry(&w).to_vec(),
                Se3::from_isometry(&m).to_vec(),
                cam.parameter_values(),
                vec![1.002],
                vec![0.4e-3, -0.2e-3, 0.1e-3],
                vec![3e-4],
            ];
            let views: Vec<&[f64]> = blocks.iter().map(|b| b.as_slice()).collect();
            let manifolds: Vec<Arc<dyn Manifold>> = vec![
                Arc::new(Se3),
                Arc::new(Se3),
                Arc::new(Se3),
                Arc::new(Euclidean { n: 9 }),
                Arc::new(Euclidean { n: 1 }),
                Arc::new(Euclidean { n: 3 }),
                Arc::new(Euclidean { n: 1 }),
            ];
            let scales = vec![
                vec![1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3],
                vec![1e-3; 6],
                vec![1e-3; 6],
                vec![1.0, 1.0, 1.0, 1.0, 1e-3, 1e-3, 1e-4, 1e-4, 1e-3],
                vec![1e-4],
                vec![1e-5; 3],
                vec![1e-5],
            ];
            let report = check_residual(&r, &views, &manifolds, &scales, 1e-3).unwrap();
            report.assert_below(1e-6, &format!("{mount:?} chain corner")).unwrap();
        }
    }

    /// The robot-pose prior's Jacobian (the inverse left Jacobian of SO(3)) passes the check
    /// away from the reported pose.
    #[test]
    fn robot_prior_jacobian_passes_the_gradient_check() {
        let reported = Isometry3::new(Vector3::new(0.5, 0.2, 0.7), Vector3::new(2.0, 0.3, -0.4));
        let current = Isometry3::new(Vector3::new(0.501, 0.199, 0.7), Vector3::new(2.1, 0.25, -0.3));
        let r = RobotPosePrior { reported, sigma_m: 1e-4, sigma_rad: 2e-4 };
        let v = Se3::from_isometry(&current).to_vec();
        let manifolds: Vec<Arc<dyn Manifold>> = vec![Arc::new(Se3)];
        let report = check_residual(&r, &[v.as_slice()], &manifolds, &[vec![1e-3; 6]], 1e-3).unwrap();
        report.assert_below(1e-6, "robot pose prior").unwrap();
    }
}
