//! The common leg description of parallel robots and the solvers built on it.
//!
//! A [`Mechanism`] holds carriages (small serial chains of actuated prismatic and revolute
//! stages; a guideway cart is a carriage with one prismatic stage) and legs. Leg `k` closes
//!
//! ```text
//! f_k(q, X, s) = ||A_k(q) - B_k(X)||^2 - L_k(q)^2 = 0,
//! A_k = (carriage frame at q) * a_k,   B_k = T_base_flange * b0_k,   L_k = L0_k (+ q_j),
//! ```
//!
//! where `X = T_base_tool = T_base_flange * T_flange_tool` is the tool pose and `s` the parameter
//! vector. With `d = A - B` and `r = B - p_tool` the derivatives are
//!
//! - `df/dq_j = 2 d . dA/dq_j - 2 L dL/dq_j`, with `dA/dq_j = R v` (prismatic stage) or
//!   `n x (A - o)` (revolute stage about the unit axis `n` through `o`);
//! - `df/d(dp, dw) = [-2 d^T, -2 (r x d)^T]` for a small tool motion (translation `dp`, rotation
//!   vector `dw` applied on the left);
//! - `df/ds` through `dA/da = R_end`, `dB/db0 = R_flange`, `dL/dL0 = 1`, stage offsets and axes
//!   (revolute axes through the left Jacobian of SO(3), since only the axis direction counts).
//!
//! The velocity (geometric) Jacobian follows by implicit differentiation:
//! `(dp, dw)/dq = -(df/dX)^-1 df/dq`.

use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Point3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};

use super::{Branch, LinkSegment, SolverOptions, SphericalJointAngles};
use crate::error::{Result, RobotError};
use crate::geometry::{skew, Pose};
use crate::kinematics::{check_len, JointKind};

mod solve;

/// One actuated stage of a carriage: `T_prev_next = Trans(offset) * motion(axis, q)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Stage {
    /// 0-based actuator that drives the stage.
    pub joint: usize,
    /// Prismatic (moves along `axis` by `q axis`) or revolute (turns by `q` about `axis`).
    pub kind: JointKind,
    /// Translation from the previous frame's origin to this stage's origin (a point on a revolute
    /// axis), previous frame.
    pub offset_m: Vector3<f64>,
    /// Prismatic: displacement per metre of `q` (its norm is a transmission scale); revolute: the
    /// axis direction (normalised when used), previous frame.
    pub axis: Vector3<f64>,
    /// Index of `offset_m.x` in the model's parameter vector (then `y`, `z`), if a parameter.
    pub offset_param: Option<usize>,
    /// Index of `axis.x` in the model's parameter vector (then `y`, `z`), if a parameter.
    pub axis_param: Option<usize>,
}

impl Stage {
    /// A guideway cart: actuator `joint` moves it by `q axis` from the previous frame's origin;
    /// `axis.x` is parameter `axis_param` (then `y`, `z`).
    pub fn cart(joint: usize, axis: Vector3<f64>, axis_param: usize) -> Self {
        Stage {
            joint,
            kind: JointKind::Prismatic,
            offset_m: Vector3::zeros(),
            axis,
            offset_param: None,
            axis_param: Some(axis_param),
        }
    }
}

/// The carriages `arm1`, `arm2`, `arm3` of a Gantry-Tau with one cart each: cart `i` moves along
/// `axes[i]`, whose parameters start at `axis_param(i)`.
pub(crate) fn cart_carriages(axes: [Vector3<f64>; 3], axis_param: impl Fn(usize) -> usize) -> Vec<Carriage> {
    (0..3)
        .map(|i| Carriage { name: format!("arm{}", i + 1), stages: vec![Stage::cart(i, axes[i], axis_param(i))] })
        .collect()
}

/// A serial carriage carrying the base-side joints of one or more legs.
#[derive(Clone, Debug, PartialEq)]
pub struct Carriage {
    /// Name used in messages (e.g. `arm2`).
    pub name: String,
    /// Stages from the base outwards.
    pub stages: Vec<Stage>,
}

/// Which of the two leg configurations a leg must stay in: the sign of `direction . (A - B)`.
#[derive(Clone, Debug, PartialEq)]
pub struct LegSide {
    /// A base-frame direction (the guideway direction, or the base's up axis for a hexapod).
    pub direction: Vector3<f64>,
    /// Required sign of `direction . (A - B)`.
    pub branch: Branch,
}

/// One leg: base-side joint centre `A`, platform-side joint centre `B`, length `L`.
#[derive(Clone, Debug, PartialEq)]
pub struct Leg {
    /// Name used in messages and results (e.g. `link2_1`, `leg4`).
    pub name: String,
    /// The carriage that carries `A`, or `None` for a fixed base point.
    pub carriage: Option<usize>,
    /// `A` in the carriage's last frame (base frame when fixed).
    pub a_m: Vector3<f64>,
    /// `B` in the platform (flange) frame.
    pub b0_m: Vector3<f64>,
    /// Length, or the length at zero actuator value when `length_joint` is set.
    pub length_m: f64,
    /// The actuator that extends the leg (`L = length_m + q_j`), if any.
    pub length_joint: Option<usize>,
    /// Index of `a_m.x` in the parameter vector, if a parameter.
    pub a_param: Option<usize>,
    /// Index of `b0_m.x` in the parameter vector, if a parameter.
    pub b0_param: Option<usize>,
    /// Index of `length_m` in the parameter vector, if a parameter.
    pub length_param: Option<usize>,
    /// Configuration the leg must stay in (checked by the solvers' guard).
    pub side: Option<LegSide>,
    /// Axis of the base-side spherical joint in the frame of `a_m`; `None`: the leg direction
    /// `B - A` at the reference configuration.
    pub base_axis: Option<Vector3<f64>>,
    /// Axis of the platform-side spherical joint in the platform frame; `None`: the direction
    /// `A - B` at the reference configuration.
    pub platform_axis: Option<Vector3<f64>>,
}

/// A parallel robot as carriages and legs.
#[derive(Clone, Debug, PartialEq)]
pub struct Mechanism {
    /// Actuator names, in model order (their number is the model's dof).
    pub joint_names: Vec<String>,
    /// Length of the model's parameter vector.
    pub n_params: usize,
    /// The carriages.
    pub carriages: Vec<Carriage>,
    /// The legs.
    pub legs: Vec<Leg>,
    /// `T_flange_tool`.
    pub tool: Pose,
}

/// A leg evaluated at one configuration (base frame).
#[derive(Clone, Debug, PartialEq)]
pub struct LegState {
    /// Base-side joint centre.
    pub a_m: Vector3<f64>,
    /// Platform-side joint centre.
    pub b_m: Vector3<f64>,
    /// `B` minus the tool point.
    pub r_m: Vector3<f64>,
    /// Current leg length `L`.
    pub length_m: f64,
}

impl LegState {
    /// Closure residual `||A - B||^2 - L^2`.
    pub fn residual(&self) -> f64 {
        (self.a_m - self.b_m).norm_squared() - self.length_m * self.length_m
    }

    /// Leg-length error `||A - B|| - L` (metres).
    pub fn length_error_m(&self) -> f64 {
        (self.a_m - self.b_m).norm() - self.length_m
    }
}

/// Residuals and first derivatives of all closure equations at one configuration.
#[derive(Clone, Debug)]
pub struct Linearization {
    /// Residuals `f_k` (m^2).
    pub f: DVector<f64>,
    /// `df/dq` (legs x dof).
    pub fq: DMatrix<f64>,
    /// `df/dX` (legs x 6) for a tool motion `(dp, dw)`.
    pub fx: DMatrix<f64>,
    /// The evaluated legs.
    pub states: Vec<LegState>,
}

impl Linearization {
    /// Largest leg-length error `|f_k| / (2 L_k)` (metres, first order).
    pub fn max_length_error_m(&self) -> f64 {
        self.f.iter().zip(&self.states).map(|(f, s)| f.abs() / (2.0 * s.length_m.abs().max(1e-9))).fold(0.0, f64::max)
    }
}

#[derive(Clone, Debug)]
struct StageEval {
    kind: JointKind,
    joint: usize,
    rot_before: Matrix3<f64>,
    origin: Vector3<f64>,
    dir: Vector3<f64>,
    q: f64,
}

#[derive(Clone, Debug)]
struct CarriageEval {
    stages: Vec<StageEval>,
    rot: Matrix3<f64>,
    pos: Vector3<f64>,
}

impl CarriageEval {
    fn point(&self, a: &Vector3<f64>) -> Vector3<f64> {
        self.pos + self.rot * a
    }
}

fn eval_carriage(c: &Carriage, q: &[f64]) -> CarriageEval {
    let mut rot = Matrix3::identity();
    let mut pos = Vector3::zeros();
    let mut stages = Vec::with_capacity(c.stages.len());
    for st in &c.stages {
        let origin = pos + rot * st.offset_m;
        let qj = q[st.joint];
        match st.kind {
            JointKind::Prismatic => {
                let dir = rot * st.axis;
                stages.push(StageEval { kind: st.kind, joint: st.joint, rot_before: rot, origin, dir, q: qj });
                pos = origin + dir * qj;
            }
            JointKind::Revolute => {
                let n = st.axis / st.axis.norm();
                let dir = rot * n;
                stages.push(StageEval { kind: st.kind, joint: st.joint, rot_before: rot, origin, dir, q: qj });
                rot *= Rotation3::from_axis_angle(&Unit::new_unchecked(n), qj).into_inner();
                pos = origin;
            }
        }
    }
    CarriageEval { stages, rot, pos }
}

/// Left Jacobian of SO(3) at the rotation vector `u`.
fn left_jacobian(u: &Vector3<f64>) -> Matrix3<f64> {
    let th = u.norm();
    let k = skew(u);
    let (c1, c2) = if th < 1e-4 {
        let t2 = th * th;
        (0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0)
    } else {
        ((1.0 - th.cos()) / (th * th), (th - th.sin()) / (th * th * th))
    };
    Matrix3::identity() + k * c1 + k * k * c2
}

/// Applies a small tool motion `(dp, dw)` to a pose (rotation applied on the left).
pub(crate) fn apply_twist(pose: &Pose, dp: &Vector3<f64>, dw: &Vector3<f64>) -> Pose {
    Isometry3::from_parts(
        Translation3::from(pose.translation.vector + dp),
        UnitQuaternion::from_scaled_axis(*dw) * pose.rotation,
    )
}

/// Solves the square system `a x = b`; `None` when `a` is singular or the result not finite.
pub(crate) fn solve_square(a: DMatrix<f64>, b: &DVector<f64>) -> Option<DVector<f64>> {
    let x = a.lu().solve(b)?;
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Shortens `step` so that its norm does not exceed `max`.
fn cap_step(step: &mut DVector<f64>, max: f64) {
    let n = step.norm();
    if n > max {
        *step *= max / n;
    }
}

/// The root of `||a + q v - t||^2 = L^2` on `branch` (the sign of `v . (a + q v - t)`), computed
/// without cancellation; `None` when the line along `v` does not meet the sphere of radius `L`
/// about `t`.
pub fn cart_root(a: &Vector3<f64>, v: &Vector3<f64>, t: &Vector3<f64>, length_m: f64, branch: Branch) -> Option<f64> {
    let w = a - t;
    let qa = v.norm_squared();
    let qb = v.dot(&w);
    let qc = w.norm_squared() - length_m * length_m;
    let disc = qb * qb - qa * qc;
    if disc.is_nan() || disc < 0.0 || qa <= 0.0 {
        return None;
    }
    let s = disc.sqrt();
    let sig = branch.sign();
    let q = if -qb * sig >= 0.0 {
        (-qb + sig * s) / qa
    } else {
        let other = -qb - sig * s;
        if other != 0.0 {
            qc / other
        } else {
            (-qb + sig * s) / qa
        }
    };
    q.is_finite().then_some(q)
}

/// Intersection of three spheres (centres `c`, radii `r`) on the side `assembly` of the plane
/// through the centres: the sign of `((c2 - c1) x (c3 - c1)) . (T - c1)`. `Err` explains why
/// there is none.
pub fn trilaterate(c: &[Vector3<f64>; 3], r: &[f64; 3], assembly: Branch) -> std::result::Result<Vector3<f64>, String> {
    let e12 = c[1] - c[0];
    let d = e12.norm();
    if d.is_nan() || d <= 1e-9 {
        return Err("the sphere centres of arms 1 and 2 coincide".into());
    }
    let ex = e12 / d;
    let c13 = c[2] - c[0];
    let i = ex.dot(&c13);
    let ey_raw = c13 - ex * i;
    let j = ey_raw.norm();
    if j.is_nan() || j <= 1e-9 * (1.0 + d) {
        return Err("the three sphere centres are collinear".into());
    }
    let ey = ey_raw / j;
    let ez = ex.cross(&ey);
    let x = (r[0] * r[0] - r[1] * r[1] + d * d) / (2.0 * d);
    let y = (r[0] * r[0] - r[2] * r[2] + i * i + j * j) / (2.0 * j) - i * x / j;
    let z2 = r[0] * r[0] - x * x - y * y;
    if z2.is_nan() || z2 < 0.0 {
        return Err(format!(
            "the three link spheres do not meet (they miss by about {:.3e} m)",
            (-z2).sqrt().min(f64::MAX)
        ));
    }
    Ok(c[0] + ex * x + ey * y + ez * (assembly.sign() * z2.sqrt()))
}

impl Mechanism {
    /// Number of actuators.
    pub fn dof(&self) -> usize {
        self.joint_names.len()
    }

    /// Checks that indices, directions and numbers are usable.
    pub fn validate(&self) -> Result<()> {
        let n = self.dof();
        let bad = |what: String| RobotError::BadParameter { name: "mechanism".into(), value: f64::NAN, reason: what };
        let param_ok = |p: Option<usize>, width: usize| p.is_none_or(|i| i + width <= self.n_params);
        for c in &self.carriages {
            for (k, st) in c.stages.iter().enumerate() {
                if st.joint >= n {
                    return Err(bad(format!(
                        "{} stage {}: actuator index {} out of range",
                        c.name,
                        k + 1,
                        st.joint + 1
                    )));
                }
                let an = st.axis.norm();
                if !(an.is_finite() && an > 1e-12) || st.offset_m.iter().any(|v| !v.is_finite()) {
                    return Err(bad(format!("{} stage {}: axis or offset is zero or not finite", c.name, k + 1)));
                }
                if !param_ok(st.offset_param, 3) || !param_ok(st.axis_param, 3) {
                    return Err(bad(format!("{} stage {}: parameter index out of range", c.name, k + 1)));
                }
            }
        }
        for leg in &self.legs {
            if leg.carriage.is_some_and(|c| c >= self.carriages.len()) || leg.length_joint.is_some_and(|j| j >= n) {
                return Err(bad(format!("{}: carriage or actuator index out of range", leg.name)));
            }
            if leg.a_m.iter().chain(leg.b0_m.iter()).any(|v| !v.is_finite()) || !leg.length_m.is_finite() {
                return Err(bad(format!("{}: a joint centre or the length is not finite", leg.name)));
            }
            if !param_ok(leg.a_param, 3) || !param_ok(leg.b0_param, 3) || !param_ok(leg.length_param, 1) {
                return Err(bad(format!("{}: parameter index out of range", leg.name)));
            }
        }
        Ok(())
    }

    fn check(&self, q: &[f64]) -> Result<()> {
        self.validate()?;
        check_len(q, self.dof())
    }

    fn carriage_evals(&self, q: &[f64]) -> Vec<CarriageEval> {
        self.carriages.iter().map(|c| eval_carriage(c, q)).collect()
    }

    fn flange(&self, t_base_tool: &Pose) -> Pose {
        t_base_tool * self.tool.inverse()
    }

    fn state(&self, leg: &Leg, evals: &[CarriageEval], flange: &Pose, tool_p: &Vector3<f64>, q: &[f64]) -> LegState {
        let a = match leg.carriage {
            Some(c) => evals[c].point(&leg.a_m),
            None => leg.a_m,
        };
        let b = flange.transform_point(&Point3::from(leg.b0_m)).coords;
        let length = leg.length_m + leg.length_joint.map_or(0.0, |j| q[j]);
        LegState { a_m: a, b_m: b, r_m: b - tool_p, length_m: length }
    }

    /// Every leg evaluated at joint values `q` and tool pose `t_base_tool`.
    pub fn leg_states(&self, q: &[f64], t_base_tool: &Pose) -> Result<Vec<LegState>> {
        self.check(q)?;
        Ok(self.states_unchecked(q, t_base_tool))
    }

    fn states_unchecked(&self, q: &[f64], t_base_tool: &Pose) -> Vec<LegState> {
        let evals = self.carriage_evals(q);
        let flange = self.flange(t_base_tool);
        let p = t_base_tool.translation.vector;
        self.legs.iter().map(|l| self.state(l, &evals, &flange, &p, q)).collect()
    }

    /// Closure residuals `||A_k - B_k||^2 - L_k^2`.
    pub fn residuals(&self, q: &[f64], t_base_tool: &Pose) -> Result<DVector<f64>> {
        let s = self.leg_states(q, t_base_tool)?;
        Ok(DVector::from_iterator(s.len(), s.iter().map(LegState::residual)))
    }

    /// Residuals and their derivatives with respect to `q` and the tool motion.
    pub fn linearize(&self, q: &[f64], t_base_tool: &Pose) -> Result<Linearization> {
        self.check(q)?;
        Ok(self.linearize_unchecked(q, t_base_tool))
    }

    fn linearize_unchecked(&self, q: &[f64], t_base_tool: &Pose) -> Linearization {
        let evals = self.carriage_evals(q);
        let flange = self.flange(t_base_tool);
        let p = t_base_tool.translation.vector;
        let m = self.legs.len();
        let mut f = DVector::zeros(m);
        let mut fq = DMatrix::zeros(m, self.dof());
        let mut fx = DMatrix::zeros(m, 6);
        let mut states = Vec::with_capacity(m);
        for (k, leg) in self.legs.iter().enumerate() {
            let s = self.state(leg, &evals, &flange, &p, q);
            let d = s.a_m - s.b_m;
            f[k] = d.norm_squared() - s.length_m * s.length_m;
            if let Some(c) = leg.carriage {
                for st in &evals[c].stages {
                    let da = match st.kind {
                        JointKind::Prismatic => st.dir,
                        JointKind::Revolute => st.dir.cross(&(s.a_m - st.origin)),
                    };
                    fq[(k, st.joint)] += 2.0 * d.dot(&da);
                }
            }
            if let Some(j) = leg.length_joint {
                fq[(k, j)] -= 2.0 * s.length_m;
            }
            let rxd = s.r_m.cross(&d);
            for i in 0..3 {
                fx[(k, i)] = -2.0 * d[i];
                fx[(k, 3 + i)] = -2.0 * rxd[i];
            }
            states.push(s);
        }
        Linearization { f, fq, fx, states }
    }

    /// Derivative of the residuals with respect to the parameter vector (legs x `n_params`).
    pub fn parameter_jacobian(&self, q: &[f64], t_base_tool: &Pose) -> Result<DMatrix<f64>> {
        self.check(q)?;
        let evals = self.carriage_evals(q);
        let flange = self.flange(t_base_tool);
        let r_flange = flange.rotation.to_rotation_matrix().into_inner();
        let p = t_base_tool.translation.vector;
        let mut jac = DMatrix::zeros(self.legs.len(), self.n_params);
        let add3 = |jac: &mut DMatrix<f64>, k: usize, i: usize, g: Vector3<f64>| {
            for c in 0..3 {
                jac[(k, i + c)] += g[c];
            }
        };
        for (k, leg) in self.legs.iter().enumerate() {
            let s = self.state(leg, &evals, &flange, &p, q);
            let d = s.a_m - s.b_m;
            let eval = leg.carriage.map(|c| &evals[c]);
            if let Some(i) = leg.a_param {
                let r_end = eval.map_or(Matrix3::identity(), |e| e.rot);
                add3(&mut jac, k, i, r_end.transpose() * d * 2.0);
            }
            if let Some(i) = leg.b0_param {
                add3(&mut jac, k, i, r_flange.transpose() * d * -2.0);
            }
            if let Some(i) = leg.length_param {
                jac[(k, i)] -= 2.0 * s.length_m;
            }
            let (Some(c), Some(e)) = (leg.carriage, eval) else {
                continue;
            };
            for (st, ev) in self.carriages[c].stages.iter().zip(&e.stages) {
                if let Some(i) = st.offset_param {
                    add3(&mut jac, k, i, ev.rot_before.transpose() * d * 2.0);
                }
                if let Some(i) = st.axis_param {
                    match st.kind {
                        JointKind::Prismatic => add3(&mut jac, k, i, ev.rot_before.transpose() * d * (2.0 * ev.q)),
                        JointKind::Revolute => {
                            let norm = st.axis.norm();
                            let n = st.axis / norm;
                            let w = s.a_m - ev.origin;
                            let proj = (Matrix3::identity() - n * n.transpose()) * (ev.q / norm);
                            let da = -skew(&w) * ev.rot_before * left_jacobian(&(n * ev.q)) * proj;
                            add3(&mut jac, k, i, da.transpose() * d * 2.0);
                        }
                    }
                }
            }
        }
        Ok(jac)
    }

    /// Velocity Jacobian of the tool (6 x dof: linear velocity of the tool point, then angular
    /// velocity, base frame) by implicit differentiation of the closure equations. With
    /// `translation_only` (constant-orientation models with three legs) the angular rows are zero
    /// and only the position columns of `df/dX` are used.
    pub fn velocity_jacobian(&self, q: &[f64], t_base_tool: &Pose, translation_only: bool) -> Result<DMatrix<f64>> {
        let lin = self.linearize(q, t_base_tool)?;
        let nx = if translation_only { 3 } else { 6 };
        if self.legs.len() != nx {
            return Err(RobotError::Singular {
                reason: format!("{} legs cannot determine {} pose coordinates", self.legs.len(), nx),
            });
        }
        let fx = lin.fx.columns(0, nx).into_owned();
        let svd = fx.clone().svd(false, false);
        let smax = svd.singular_values.max();
        let smin = svd.singular_values.min();
        if smin.is_nan() || smin <= 1e-12 * smax {
            return Err(RobotError::Singular {
                reason: format!(
                    "the closure equations' pose derivative is singular (singular values {smin:.3e} .. {smax:.3e})"
                ),
            });
        }
        let lu = fx.lu();
        let mut jac = DMatrix::zeros(6, self.dof());
        for j in 0..self.dof() {
            let col = -lin.fq.column(j);
            let x = lu.solve(&col.into_owned()).ok_or_else(|| RobotError::Singular {
                reason: "the closure equations' pose derivative is singular".into(),
            })?;
            for i in 0..nx {
                jac[(i, j)] = x[i];
            }
        }
        Ok(jac)
    }

    /// The first leg that is not in its required configuration, as a message.
    pub fn side_violation(&self, states: &[LegState]) -> Option<String> {
        states.iter().enumerate().find_map(|(k, s)| self.leg_side_violation(k, s))
    }

    /// Whether leg `k` in state `s` left its required configuration, as a message.
    pub fn leg_side_violation(&self, k: usize, s: &LegState) -> Option<String> {
        let leg = self.legs.get(k)?;
        let side = leg.side.as_ref()?;
        let v = side.direction.dot(&(s.a_m - s.b_m));
        (Branch::of(v) != side.branch || v == 0.0).then(|| {
            format!("{} left its '{}' configuration (direction . (A - B) = {v:.3e} m)", leg.name, side.branch.as_str())
        })
    }

    /// The legs as segments in the base frame.
    pub fn segments(&self, q: &[f64], t_base_tool: &Pose) -> Result<Vec<LinkSegment>> {
        let states = self.leg_states(q, t_base_tool)?;
        Ok(self
            .legs
            .iter()
            .zip(states)
            .map(|(l, s)| LinkSegment { link: l.name.clone(), a_m: s.a_m, b_m: s.b_m })
            .collect())
    }

    /// Whether some spherical joint has no stated axis (and needs a reference configuration).
    pub fn needs_reference_axes(&self) -> bool {
        self.legs.iter().any(|l| l.base_axis.is_none() || l.platform_axis.is_none())
    }

    /// Angles between each leg and its joints' axes at `(q, t_base_tool)`. Joints without a stated
    /// axis take the leg direction at `reference = (q_ref, T_base_tool_ref)`; an error if one is
    /// needed and not given.
    pub fn joint_angles(
        &self,
        q: &[f64],
        t_base_tool: &Pose,
        reference: Option<(&[f64], &Pose)>,
    ) -> Result<Vec<SphericalJointAngles>> {
        self.check(q)?;
        let evals = self.carriage_evals(q);
        let flange = self.flange(t_base_tool);
        let p = t_base_tool.translation.vector;
        let refs = match reference {
            Some((q0, x0)) => {
                self.check(q0)?;
                Some((self.carriage_evals(q0), self.flange(x0), x0.translation.vector, q0))
            }
            None => None,
        };
        let angle = |u: &Vector3<f64>, w: &Vector3<f64>| u.cross(w).norm().atan2(u.dot(w));
        let mut out = Vec::with_capacity(self.legs.len());
        for leg in &self.legs {
            let s = self.state(leg, &evals, &flange, &p, q);
            let r_end = leg.carriage.map_or(Matrix3::identity(), |c| evals[c].rot);
            let r_fl = flange.rotation.to_rotation_matrix().into_inner();
            let reference_dirs = || -> Result<(Vector3<f64>, Vector3<f64>)> {
                let Some((ev0, fl0, p0, q0)) = &refs else {
                    return Err(RobotError::Unreachable {
                        reason: format!(
                            "{}: a spherical joint has no axis and no reference configuration was given",
                            leg.name
                        ),
                    });
                };
                let s0 = self.state(leg, ev0, fl0, p0, q0);
                let r_end0 = leg.carriage.map_or(Matrix3::identity(), |c| ev0[c].rot);
                let r_fl0 = fl0.rotation.to_rotation_matrix().into_inner();
                let dir = s0.b_m - s0.a_m;
                Ok((r_end0.transpose() * dir, r_fl0.transpose() * -dir))
            };
            let base_local = match leg.base_axis {
                Some(a) => a,
                None => reference_dirs()?.0,
            };
            let plat_local = match leg.platform_axis {
                Some(a) => a,
                None => reference_dirs()?.1,
            };
            let dir = s.b_m - s.a_m;
            out.push(SphericalJointAngles {
                link: leg.name.clone(),
                base_rad: angle(&dir, &(r_end * base_local)),
                platform_rad: angle(&-dir, &(r_fl * plat_local)),
            });
        }
        Ok(out)
    }
}
