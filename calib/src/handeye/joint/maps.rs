//! How the joint adjustment's blocks map onto the robot and the two frames: [`RobotMap`] (the
//! robot block's coordinates onto the model's parameters and joint offsets) and [`FrameMap`]
//! (the device frame and tool increments onto `W` and `X`).

use nalgebra::{DMatrix, Isometry3, Matrix6, UnitQuaternion, Vector3};

use ferrocal_lsq::{so3, LsqError};
use ferrocal_robot::{Kinematics, Parameterized, RobotModel};

use crate::frames::exp6;

/// How the free robot coordinates map onto the model.
pub(super) struct RobotMap {
    pub(super) model: RobotModel,
    /// `(robot block coordinate, index in the model's parameter vector)`.
    pub(super) model_cols: Vec<(usize, usize)>,
    /// `(robot block coordinate, joint)`.
    pub(super) offset_cols: Vec<(usize, usize)>,
    pub(super) n: usize,
}

impl RobotMap {
    /// The model with the block's values and the effective joints.
    pub(super) fn apply(&self, v: &[f64], q: &[f64]) -> ferrocal_lsq::Result<(RobotModel, Vec<f64>)> {
        let mut m = self.model.clone();
        if !self.model_cols.is_empty() {
            let mut vals = m.parameter_values();
            for &(k, pi) in &self.model_cols {
                vals[pi] = v[k];
            }
            m.set_parameter_values(&vals).map_err(LsqError::model)?;
        }
        let mut qq = q.to_vec();
        for &(k, j) in &self.offset_cols {
            qq[j] += v[k];
        }
        Ok((m, qq))
    }

    /// `FK(q + dq; θ)` and its derivative (6 x n, rows `[dt; dw]` in the base frame, the
    /// product chart of [`ferrocal_lsq::Se3`]: `t' = t + dt`, `R' = Exp(dw) R`) with respect to the block's
    /// coordinates: analytic for joint offsets and serial corrections, central differences
    /// for other model parameters.
    pub(super) fn pose_jacobian(&self, v: &[f64], q: &[f64]) -> ferrocal_lsq::Result<(Isometry3<f64>, DMatrix<f64>)> {
        let (m, qq) = self.apply(v, q)?;
        let t = m.forward(&qq).map_err(LsqError::model)?;
        let p = t.translation.vector;
        let mut jac = DMatrix::zeros(6, self.n);
        let mut put = |col: usize, dt: Vector3<f64>, dw: Vector3<f64>| {
            jac.fixed_view_mut::<3, 1>(0, col).copy_from(&dt);
            jac.fixed_view_mut::<3, 1>(3, col).copy_from(&dw);
        };
        if !self.offset_cols.is_empty() {
            let jg = m.jacobian(&qq).map_err(LsqError::model)?;
            for &(k, j) in &self.offset_cols {
                put(
                    k,
                    Vector3::new(jg[(0, j)], jg[(1, j)], jg[(2, j)]),
                    Vector3::new(jg[(3, j)], jg[(4, j)], jg[(5, j)]),
                );
            }
        }
        let names = self.model.parameters();
        let frames = match &m {
            RobotModel::Serial(chain) => Some((chain, chain.frames(&qq).map_err(LsqError::model)?)),
            _ => None,
        };
        for &(k, pi) in &self.model_cols {
            let name = &names[pi].name;
            let corr = frames.as_ref().and_then(|(chain, fr)| {
                let joint = chain.joint_of_parameter(name)?;
                let comp =
                    ferrocal_robot::serial::CORRECTION_NAMES.iter().position(|c| name.ends_with(&format!(".{c}")))?;
                let c = chain.joints.get(joint)?.correction;
                let cr = Vector3::new(c[3], c[4], c[5]);
                let link = fr.links[joint];
                let r_a = link.rotation * UnitQuaternion::from_scaled_axis(cr).inverse();
                Some(if comp < 3 {
                    (r_a * Vector3::ith(comp, 1.0), Vector3::zeros())
                } else {
                    let w = r_a * so3::left_jacobian(&cr).column(comp - 3).into_owned();
                    (w.cross(&(p - link.translation.vector)), w)
                })
            });
            let (dt, dw) = match corr {
                Some(d) => d,
                None => {
                    let h = 1e-7;
                    let mut vp = v.to_vec();
                    vp[k] += h;
                    let (mp, qp) = self.apply(&vp, q)?;
                    let tp = mp.forward(&qp).map_err(LsqError::model)?;
                    vp[k] -= 2.0 * h;
                    let (mm, qm) = self.apply(&vp, q)?;
                    let tm = mm.forward(&qm).map_err(LsqError::model)?;
                    (
                        (tp.translation.vector - tm.translation.vector) / (2.0 * h),
                        (tp.rotation * tm.rotation.inverse()).scaled_axis() / (2.0 * h),
                    )
                }
            };
            put(k, dt, dw);
        }
        Ok((t, jac))
    }
}

/// The device frame's increment `f` and the tool's `t` as in the kinematic calibration
/// (`F = exp6(f) F0`, `X = X0 exp6(t)`), with `W = F^-1`, and the derivatives of `W` and `X` in
/// the [`ferrocal_lsq::Se3`] chart with respect to `f` and `t` (6 x 6 each).
pub(super) struct FrameMap {
    pub(super) f0: Isometry3<f64>,
    pub(super) x0: Isometry3<f64>,
    /// The free coordinates of `f` (the block's tangent; a residual's Jacobian has these columns).
    pub(super) frame_free: Vec<usize>,
    /// The free coordinates of `t`.
    pub(super) tool_free: Vec<usize>,
}

impl FrameMap {
    pub(super) fn w_and_x(&self, f: &[f64], t: &[f64]) -> (Isometry3<f64>, Isometry3<f64>) {
        ((exp6(f) * self.f0).inverse(), self.x0 * exp6(t))
    }

    /// `(dW/df, dX/dt)` in the `Se3` chart.
    pub(super) fn jacobians(&self, f: &[f64], t: &[f64]) -> (Matrix6<f64>, Matrix6<f64>) {
        let big_f = exp6(f) * self.f0;
        let rf = big_f.rotation.to_rotation_matrix().into_inner();
        let tf = big_f.translation.vector;
        let jl_f = so3::left_jacobian(&Vector3::new(f[3], f[4], f[5]));
        // F in its chart: dt_F = df_t + (J_l df_r) x (t_F - f_t), dr_F = J_l df_r.
        let mut m_f = Matrix6::identity();
        let lever = tf - Vector3::new(f[0], f[1], f[2]);
        m_f.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-lever.cross_matrix() * jl_f));
        m_f.fixed_view_mut::<3, 3>(3, 3).copy_from(&jl_f);
        // W = F^-1: dt_W = -R^T dt_F - R^T [t_F]x dr_F, dr_W = -R^T dr_F.
        let mut m_inv = Matrix6::zeros();
        m_inv.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-rf.transpose()));
        m_inv.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-rf.transpose() * tf.cross_matrix()));
        m_inv.fixed_view_mut::<3, 3>(3, 3).copy_from(&(-rf.transpose()));
        // X = X0 exp6(t): dt_X = R0 dt_t, dr_X = R0 J_l(t_r) dr_t.
        let r0 = self.x0.rotation.to_rotation_matrix().into_inner();
        let mut m_x = Matrix6::zeros();
        m_x.fixed_view_mut::<3, 3>(0, 0).copy_from(&r0);
        m_x.fixed_view_mut::<3, 3>(3, 3).copy_from(&(r0 * so3::left_jacobian(&Vector3::new(t[3], t[4], t[5]))));
        (m_inv * m_f, m_x)
    }
}
