//! Serial chains: DH, modified DH and URDF joints behind one type.
//!
//! # Coupled joints
//! A joint may follow another (URDF `<mimic>`, [`Joint::mimic`]): it moves the chain but is not
//! an actuated coordinate. Everything indexed by joint number (the joint vector `q`, `dof`,
//! names, limits, Jacobian columns, gravity torques) counts the actuated joints only;
//! [`SerialChain::joints`] and [`ChainFrames`] list every joint. Details in `mimic.rs`
//! ([`SerialChain::all_joint_values`], [`SerialChain::coupling_matrix`]).

mod dh_write;
mod mimic;
mod tree;
mod urdf;
mod urdf_tree;
mod urdf_write;

pub use dh_write::{MdhRow, MdhTable, PARALLEL_RAD};
pub use mimic::Mimic;
pub use tree::{ChainTree, TreeTip};
pub use urdf::{parse_urdf, parse_urdf_str, UrdfOptions};
pub use urdf_tree::{parse_urdf_tree, parse_urdf_tree_str, urdf_tree_joint_count};
pub use urdf_write::{to_urdf, UrdfFrames};

use nalgebra::{DMatrix, Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{Result, RobotError};
use crate::geometry::{pose_error, pose_from_vectors, pose_to_vector, rot_x, rot_y, rot_z, rpy, Pose};
use crate::kinematics::{check_len, default_gravity, JointKind, JointLimits, Kinematics, Mobility};
use crate::params::{check_values, ParamInfo, Parameterized, Unit};

/// The geometry of one joint: where its axis sits relative to the previous frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "convention", rename_all = "snake_case")]
pub enum JointGeometry {
    /// Standard DH: `Rz(theta) Tz(d) Tx(a) Rx(alpha)`, axis = z of the previous frame.
    Dh {
        /// Link length.
        a_m: f64,
        /// Link twist.
        alpha_rad: f64,
        /// Link offset (added to `q` for prismatic joints).
        d_m: f64,
        /// Joint angle offset (added to `q` for revolute joints).
        theta_offset_rad: f64,
    },
    /// Modified DH (Craig) with Hayati's beta: `Rx(alpha) Ry(beta) Tx(a) Rz(theta) Tz(d)`.
    Mdh {
        /// Length of the previous link.
        a_m: f64,
        /// Twist of the previous link.
        alpha_rad: f64,
        /// Rotation about y (zero for the plain MDH convention).
        beta_rad: f64,
        /// Link offset.
        d_m: f64,
        /// Joint angle offset.
        theta_offset_rad: f64,
    },
    /// URDF: `origin(xyz, rpy) * motion(axis, q)`.
    Origin {
        /// Origin translation.
        xyz_m: [f64; 3],
        /// Origin rotation, roll-pitch-yaw.
        rpy_rad: [f64; 3],
        /// Unit axis in the joint frame.
        axis: [f64; 3],
    },
}

/// A rigid body's mass properties in its own frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Inertial {
    /// Mass.
    pub mass_kg: f64,
    /// Centre of mass in the link frame.
    pub com_m: [f64; 3],
    /// Inertia about the centre of mass, link-frame axes, row-major 3x3 (kg m^2).
    pub inertia_kgm2: [f64; 9],
}

/// One joint with the link it moves: an actuated joint, or a mimic joint that follows one
/// ([`Joint::mimic`]; see the module documentation's "Coupled joints").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Joint {
    /// Name used in reports and errors.
    pub name: String,
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Axis placement.
    pub geometry: JointGeometry,
    /// Limits (rad or m).
    pub limits: JointLimits,
    /// Mass properties of the link this joint moves (expressed in the joint's frame after
    /// motion), if known.
    pub inertial: Option<Inertial>,
    /// A small correction transform applied after the joint's nominal transform: translation
    /// (m) and rotation vector (rad), `T = pre * motion(q) * post * Exp(correction)`. Zero for a
    /// nominal model; calibration identifies it (a complete, singularity-free error model: six
    /// parameters per joint, of which identifiability analysis keeps the independent ones).
    #[serde(default)]
    pub correction: [f64; 6],
    /// `Some` for a mimic (coupled) joint, `q = multiplier * q_leader + offset`: not an actuated
    /// coordinate of the chain (see the module documentation's "Coupled joints").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mimic: Option<Mimic>,
}

impl Joint {
    /// Splits the joint transform into `pre * motion(axis, q) * post`; returns `(pre, axis, post)`.
    fn split(&self) -> (Pose, Vector3<f64>, Pose) {
        match (&self.geometry, self.kind) {
            (JointGeometry::Dh { a_m, alpha_rad, d_m, theta_offset_rad }, kind) => {
                let tail = Isometry3::translation(*a_m, 0.0, 0.0) * rot_x(*alpha_rad);
                match kind {
                    JointKind::Revolute => {
                        (rot_z(*theta_offset_rad), Vector3::z(), Isometry3::translation(0.0, 0.0, *d_m) * tail)
                    }
                    JointKind::Prismatic => {
                        (rot_z(*theta_offset_rad) * Isometry3::translation(0.0, 0.0, *d_m), Vector3::z(), tail)
                    }
                }
            }
            (JointGeometry::Mdh { a_m, alpha_rad, beta_rad, d_m, theta_offset_rad }, kind) => {
                let head = rot_x(*alpha_rad) * rot_y(*beta_rad) * Isometry3::translation(*a_m, 0.0, 0.0);
                match kind {
                    JointKind::Revolute => {
                        (head * rot_z(*theta_offset_rad), Vector3::z(), Isometry3::translation(0.0, 0.0, *d_m))
                    }
                    JointKind::Prismatic => (
                        head * rot_z(*theta_offset_rad) * Isometry3::translation(0.0, 0.0, *d_m),
                        Vector3::z(),
                        Isometry3::identity(),
                    ),
                }
            }
            (JointGeometry::Origin { xyz_m, rpy_rad, axis }, _) => (
                Isometry3::from_parts(
                    Translation3::new(xyz_m[0], xyz_m[1], xyz_m[2]),
                    rpy(rpy_rad[0], rpy_rad[1], rpy_rad[2]),
                ),
                Vector3::new(axis[0], axis[1], axis[2]),
                Isometry3::identity(),
            ),
        }
    }

    /// `(pre, axis, post * Exp(correction))`; with `before_motion` (the joints of a tree,
    /// `tree.rs`) `(pre * Exp(correction), axis, post)`.
    fn split_corrected(&self, before_motion: bool) -> (Pose, Vector3<f64>, Pose) {
        let (pre, axis, post) = self.split();
        if self.correction == [0.0; 6] {
            return (pre, axis, post);
        }
        let c = &self.correction;
        let e = pose_from_vectors(&Vector3::new(c[0], c[1], c[2]), &Vector3::new(c[3], c[4], c[5]));
        if before_motion {
            return (pre * e, axis, post);
        }
        (pre, axis, post * e)
    }

    fn motion(&self, axis: &Vector3<f64>, q: f64) -> Pose {
        match self.kind {
            JointKind::Revolute => {
                Isometry3::from_parts(Translation3::identity(), UnitQuaternion::from_scaled_axis(axis * q))
            }
            JointKind::Prismatic => Isometry3::from_parts(Translation3::from(axis * q), UnitQuaternion::identity()),
        }
    }

    fn geometry_params(&self, prefix: &str, out: &mut Vec<ParamInfo>) {
        let p = |n: &str, u, v| ParamInfo::new(format!("{prefix}.{n}"), u, v);
        match &self.geometry {
            JointGeometry::Dh { a_m, alpha_rad, d_m, theta_offset_rad } => {
                out.push(p("a_m", Unit::Metre, *a_m));
                out.push(p("alpha_rad", Unit::Radian, *alpha_rad));
                out.push(p("d_m", Unit::Metre, *d_m));
                out.push(p("theta_offset_rad", Unit::Radian, *theta_offset_rad));
            }
            JointGeometry::Mdh { a_m, alpha_rad, beta_rad, d_m, theta_offset_rad } => {
                out.push(p("a_m", Unit::Metre, *a_m));
                out.push(p("alpha_rad", Unit::Radian, *alpha_rad));
                out.push(p("beta_rad", Unit::Radian, *beta_rad));
                out.push(p("d_m", Unit::Metre, *d_m));
                out.push(p("theta_offset_rad", Unit::Radian, *theta_offset_rad));
            }
            JointGeometry::Origin { xyz_m, rpy_rad, .. } => {
                for (n, v) in ["x_m", "y_m", "z_m"].iter().zip(xyz_m) {
                    out.push(p(n, Unit::Metre, *v));
                }
                for (n, v) in ["roll_rad", "pitch_rad", "yaw_rad"].iter().zip(rpy_rad) {
                    out.push(p(n, Unit::Radian, *v));
                }
            }
        }
        for (k, n) in CORRECTION_NAMES.iter().enumerate() {
            out.push(p(n, if k < 3 { Unit::Metre } else { Unit::Radian }, self.correction[k]));
        }
    }

    fn set_geometry_params(&mut self, v: &[f64]) -> usize {
        let used = self.set_nominal_params(v);
        self.correction.copy_from_slice(&v[used..used + 6]);
        used + 6
    }

    fn set_nominal_params(&mut self, v: &[f64]) -> usize {
        match &mut self.geometry {
            JointGeometry::Dh { a_m, alpha_rad, d_m, theta_offset_rad } => {
                (*a_m, *alpha_rad, *d_m, *theta_offset_rad) = (v[0], v[1], v[2], v[3]);
                4
            }
            JointGeometry::Mdh { a_m, alpha_rad, beta_rad, d_m, theta_offset_rad } => {
                (*a_m, *alpha_rad, *beta_rad, *d_m, *theta_offset_rad) = (v[0], v[1], v[2], v[3], v[4]);
                5
            }
            JointGeometry::Origin { xyz_m, rpy_rad, .. } => {
                xyz_m.copy_from_slice(&v[0..3]);
                rpy_rad.copy_from_slice(&v[3..6]);
                6
            }
        }
    }
}

/// Names of the six correction parameters of every joint (after the `joint<i>.` prefix).
pub const CORRECTION_NAMES: [&str; 6] =
    ["corr_x_m", "corr_y_m", "corr_z_m", "corr_rx_rad", "corr_ry_rad", "corr_rz_rad"];

/// Frames of a serial chain at one joint configuration, one entry per joint of
/// [`SerialChain::joints`] (mimic joints included).
#[derive(Clone, Debug)]
pub struct ChainFrames {
    /// `T_base_frame_i` after each joint's motion (frame i is the link moved by joint i), i = 1..n.
    pub links: Vec<Pose>,
    /// Joint axes in the base frame (unit vectors), one per joint.
    pub axes: Vec<Vector3<f64>>,
    /// A point on each joint axis, base frame.
    pub axis_points: Vec<Point3<f64>>,
    /// `T_base_flange` (the last link frame).
    pub flange: Pose,
    /// `T_base_tool`.
    pub tool: Pose,
    /// Per joint, the joint whose link carries it (`None`: the base); `i - 1` for a chain.
    pub parent: Vec<Option<usize>>,
    /// Per joint, the frame whose last factor is the joint's correction `Exp(c)`: the link
    /// frame of a chain's joint (the correction follows the motion), the frame before the
    /// motion of a tree's joint (the correction precedes it, so that each branch's first joint
    /// has its own origin error: one after the branching link's motion could not serve both).
    pub corrected: Vec<Pose>,
}

/// An open serial chain of revolute and prismatic joints.
///
/// `T_world_tool = base * J_1(q_1) * ... * J_n(q_n) * tool`; [`Kinematics::forward`] returns
/// `T_base_tool` with `base` included, so `base` is the place for a device-to-robot frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SerialChain {
    /// Model name.
    pub name: String,
    /// `T_world_base`: pose of the robot base (identity unless placed).
    pub base: Pose,
    /// The joints, base to tip: the actuated joints and the mimic joints that follow them.
    pub joints: Vec<Joint>,
    /// `T_flange_tool`: pose of the tool point in the flange (last link) frame.
    pub tool: Pose,
    /// Gravity in the base frame, m/s^2.
    pub gravity_m_s2: [f64; 3],
    /// `Some` for a tree of chains (see `tree.rs`): the joints' parents and the tips.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tree: Option<ChainTree>,
}

/// Options of the damped-least-squares inverse kinematics.
#[derive(Clone, Copy, Debug)]
pub struct IkOptions {
    /// Maximum iterations.
    pub max_iterations: usize,
    /// Position tolerance.
    pub tol_m: f64,
    /// Orientation tolerance.
    pub tol_rad: f64,
    /// Initial damping (Levenberg-Marquardt lambda, in m^2-equivalent units).
    pub damping: f64,
    /// Length that converts rotations to translations in the error norm.
    pub characteristic_length_m: f64,
    /// Whether the result must respect joint limits.
    pub enforce_limits: bool,
}

impl Default for IkOptions {
    fn default() -> Self {
        Self {
            max_iterations: 200,
            tol_m: 1e-12,
            tol_rad: 1e-12,
            damping: 1e-6,
            characteristic_length_m: 0.5,
            enforce_limits: true,
        }
    }
}

impl SerialChain {
    /// A chain from a standard DH table (`a`, `alpha`, `d`, `theta offset` per joint), all revolute.
    pub fn from_dh(name: &str, a_m: &[f64], alpha_rad: &[f64], d_m: &[f64], theta_offset_rad: &[f64]) -> Self {
        Self::revolute(name, a_m.len(), |i| JointGeometry::Dh {
            a_m: a_m[i],
            alpha_rad: alpha_rad[i],
            d_m: d_m[i],
            theta_offset_rad: theta_offset_rad[i],
        })
    }

    /// A chain from a modified DH table, all revolute, beta = 0.
    pub fn from_mdh(name: &str, a_m: &[f64], alpha_rad: &[f64], d_m: &[f64], theta_offset_rad: &[f64]) -> Self {
        Self::revolute(name, a_m.len(), |i| JointGeometry::Mdh {
            a_m: a_m[i],
            alpha_rad: alpha_rad[i],
            beta_rad: 0.0,
            d_m: d_m[i],
            theta_offset_rad: theta_offset_rad[i],
        })
    }

    /// `n` revolute joints `joint1..` with the geometry `geometry(i)` of joint `i`, unbounded,
    /// without inertia, corrections or coupling.
    fn revolute(name: &str, n: usize, geometry: impl Fn(usize) -> JointGeometry) -> Self {
        let joints = (0..n)
            .map(|i| Joint {
                name: format!("joint{}", i + 1),
                kind: JointKind::Revolute,
                geometry: geometry(i),
                limits: JointLimits::UNBOUNDED,
                inertial: None,
                correction: [0.0; 6],
                mimic: None,
            })
            .collect();
        Self::new(name, joints)
    }

    /// A chain with identity base and tool and standard gravity.
    pub fn new(name: &str, joints: Vec<Joint>) -> Self {
        let g = default_gravity();
        Self {
            name: name.to_string(),
            base: Pose::identity(),
            joints,
            tool: Pose::identity(),
            gravity_m_s2: [g.x, g.y, g.z],
            tree: None,
        }
    }

    /// Sets every joint's limits (same for all), checked.
    pub fn with_limits(mut self, lower: f64, upper: f64) -> Result<Self> {
        for j in &mut self.joints {
            j.limits = JointLimits::new(&j.name, lower, upper)?;
        }
        Ok(self)
    }

    /// All frames at actuated joint values `q` (one entry per joint of the chain, mimic joints
    /// at their coupled values).
    pub fn frames(&self, q: &[f64]) -> Result<ChainFrames> {
        let q = &self.all_joint_values(q)?;
        let n = self.joints.len();
        let parent = self.joint_parents();
        let tree = self.is_tree();
        let mut links: Vec<Pose> = Vec::with_capacity(n);
        let mut axes = Vec::with_capacity(n);
        let mut axis_points = Vec::with_capacity(n);
        let mut corrected = Vec::with_capacity(if tree { n } else { 0 });
        for (i, (j, qi)) in self.joints.iter().zip(q).enumerate() {
            let t = parent[i].map_or(self.base, |p| links[p]);
            let (pre, axis, post) = j.split_corrected(tree);
            let before = t * pre;
            let a = before.rotation * axis;
            axes.push(a.normalize());
            axis_points.push(Point3::from(before.translation.vector));
            if tree {
                corrected.push(before);
            }
            links.push(before * j.motion(&axis, *qi) * post);
        }
        if !tree {
            corrected = links.clone();
        }
        let flange = links.get(self.tip_joint()).copied().unwrap_or(self.base);
        Ok(ChainFrames { links, axes, axis_points, flange, tool: flange * self.tool, parent, corrected })
    }

    /// Geometric Jacobian of an arbitrary point `p_base` rigidly attached to link `link`
    /// (0-based; joints after it do not move it). 6 x n, one column per joint of `frames` (every
    /// joint of the chain, mimic joints included: times [`SerialChain::coupling_matrix`] for the
    /// actuated joints); `kinds` are those of [`SerialChain::joints`].
    pub fn point_jacobian(
        frames: &ChainFrames,
        kinds: &[JointKind],
        link: usize,
        p_base: &Point3<f64>,
    ) -> DMatrix<f64> {
        let n = frames.axes.len();
        let mut jac = DMatrix::zeros(6, n);
        let mut on_path = Some(link.min(n - 1));
        while let Some(i) = on_path {
            on_path = frames.parent[i];
            let (z, kind) = (frames.axes[i], &kinds[i]);
            match kind {
                JointKind::Revolute => {
                    let r = p_base - frames.axis_points[i];
                    let v = z.cross(&r);
                    jac.fixed_view_mut::<3, 1>(0, i).copy_from(&v);
                    jac.fixed_view_mut::<3, 1>(3, i).copy_from(&z);
                }
                JointKind::Prismatic => {
                    jac.fixed_view_mut::<3, 1>(0, i).copy_from(&z);
                }
            }
        }
        jac
    }

    /// Damped-least-squares inverse kinematics with explicit options.
    pub fn inverse_with(&self, target: &Pose, seed: &[f64], opts: &IkOptions) -> Result<Vec<f64>> {
        check_len(seed, self.dof())?;
        let n = self.dof();
        let w = opts.characteristic_length_m;
        let mut q: Vec<f64> = seed.to_vec();
        let mut lambda = opts.damping;
        let err_of = |q: &[f64]| -> Result<(nalgebra::Vector6<f64>, f64)> {
            let t = self.forward(q)?;
            let e = pose_error(target, &t);
            let scaled = e.fixed_rows::<3>(0).norm_squared() + (w * w) * e.fixed_rows::<3>(3).norm_squared();
            Ok((e, scaled))
        };
        let (mut e, mut cost) = err_of(&q)?;
        for it in 0..opts.max_iterations {
            if e.fixed_rows::<3>(0).norm() <= opts.tol_m && e.fixed_rows::<3>(3).norm() <= opts.tol_rad {
                return self.finish_ik(q, opts);
            }
            let mut jac = self.jacobian(&q)?;
            // Scale angular rows so both parts count in metres.
            for c in 0..n {
                for r in 3..6 {
                    jac[(r, c)] *= w;
                }
            }
            let mut es = e;
            for r in 3..6 {
                es[r] *= w;
            }
            let jt = jac.transpose();
            let jtj = &jt * &jac;
            let g = &jt * nalgebra::DVector::from_column_slice(es.as_slice());
            let mut improved = false;
            for _ in 0..30 {
                let mut a = jtj.clone();
                for d in 0..n {
                    a[(d, d)] += lambda * (1.0 + jtj[(d, d)]);
                }
                let Some(step) = a.cholesky().map(|c| c.solve(&g)) else {
                    lambda *= 10.0;
                    continue;
                };
                let q_new: Vec<f64> = q.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
                let (e_new, cost_new) = err_of(&q_new)?;
                if cost_new < cost || cost_new == 0.0 {
                    q = q_new;
                    e = e_new;
                    cost = cost_new;
                    lambda = (lambda * 0.1).max(1e-15);
                    improved = true;
                    break;
                }
                lambda *= 10.0;
            }
            if !improved {
                // Converged as far as floating point allows, or stuck.
                let res_m = e.fixed_rows::<3>(0).norm();
                let res_rad = e.fixed_rows::<3>(3).norm();
                if res_m < 1e-10 && res_rad < 1e-10 {
                    return self.finish_ik(q, opts);
                }
                return Err(RobotError::IkNotConverged {
                    iterations: it + 1,
                    residual_m: res_m,
                    residual_rad: res_rad,
                });
            }
        }
        let res_m = e.fixed_rows::<3>(0).norm();
        let res_rad = e.fixed_rows::<3>(3).norm();
        if res_m < 1e-10 && res_rad < 1e-10 {
            return self.finish_ik(q, opts);
        }
        Err(RobotError::IkNotConverged { iterations: opts.max_iterations, residual_m: res_m, residual_rad: res_rad })
    }

    fn finish_ik(&self, mut q: Vec<f64>, opts: &IkOptions) -> Result<Vec<f64>> {
        // Bring revolute joints into their limits by whole turns where that helps.
        for (v, j) in q.iter_mut().zip(self.joints.iter().filter(|j| j.mimic.is_none())) {
            if j.kind == JointKind::Revolute && !j.limits.contains(*v, 0.0) {
                let tau = std::f64::consts::TAU;
                let k = ((j.limits.lower + j.limits.upper) * 0.5 - *v) / tau;
                if k.is_finite() {
                    let cand = *v + k.round() * tau;
                    if j.limits.contains(cand, 0.0) {
                        *v = cand;
                    }
                }
            }
        }
        if opts.enforce_limits {
            self.check_joints(&q)?;
        }
        Ok(q)
    }

    /// Torques (N m; N for prismatic joints) the actuators must exert to hold the chain still at
    /// `q` against gravity, from the links' inertials (links without an inertial weigh nothing),
    /// plus an optional payload of `payload_kg` at the tool point. One per actuated joint: a
    /// mimic joint's torque reaches its leader's drive times the multiplier
    /// (`tau_leader + m tau_mimic`, the generalized force of the actuated coordinate).
    pub fn gravity_torques(&self, q: &[f64], payload_kg: f64) -> Result<Vec<f64>> {
        let all = nalgebra::DVector::from_vec(self.gravity_torques_all(q, payload_kg)?);
        if !self.has_mimic_joints() {
            return Ok(all.iter().copied().collect());
        }
        Ok((self.coupling_matrix()?.transpose() * all).iter().copied().collect())
    }

    /// The gravity torque every joint of the chain carries at actuated values `q` (one per
    /// [`SerialChain::joints`] entry, mimic joints included): what [`SerialChain::gravity_torques`]
    /// sums onto the drives.
    pub fn gravity_torques_all(&self, q: &[f64], payload_kg: f64) -> Result<Vec<f64>> {
        let frames = self.frames(q)?;
        let kinds: Vec<JointKind> = self.joints.iter().map(|j| j.kind).collect();
        let g = Vector3::from(self.gravity_m_s2);
        let n = self.joints.len();
        let mut tau = nalgebra::DVector::zeros(n);
        for (i, j) in self.joints.iter().enumerate() {
            if let Some(inr) = &j.inertial {
                let com = frames.links[i] * Point3::from(inr.com_m);
                let jac = Self::point_jacobian(&frames, &kinds, i, &com);
                let f = -g * inr.mass_kg; // force the actuators must supply
                tau += jac.fixed_rows::<3>(0).transpose() * f;
            }
        }
        if payload_kg != 0.0 {
            let p = Point3::from(frames.tool.translation.vector);
            let jac = Self::point_jacobian(&frames, &kinds, self.tip_joint(), &p);
            tau += jac.fixed_rows::<3>(0).transpose() * (-g * payload_kg);
        }
        Ok(tau.iter().copied().collect())
    }

    /// Total mass of the links with inertials.
    pub fn total_mass_kg(&self) -> f64 {
        self.joints.iter().filter_map(|j| j.inertial.as_ref()).map(|i| i.mass_kg).sum()
    }

    /// A reach bound: the largest distance from any joint axis point to the tool over the chain's
    /// zero configuration plus all link lengths, used for conservative motion bounds.
    pub fn reach_bound_m(&self) -> f64 {
        let mut sum = 0.0;
        for j in &self.joints {
            let (pre, _, post) = j.split_corrected(self.is_tree());
            sum += pre.translation.vector.norm() + post.translation.vector.norm();
        }
        sum + self.tool.translation.vector.norm()
    }
}

impl Parameterized for SerialChain {
    fn parameters(&self) -> Vec<ParamInfo> {
        let mut out = Vec::new();
        let b = pose_to_vector(&self.base);
        for (k, n) in ["x_m", "y_m", "z_m", "rx_rad", "ry_rad", "rz_rad"].iter().enumerate() {
            let unit = if k < 3 { Unit::Metre } else { Unit::Radian };
            out.push(ParamInfo::new(format!("base.{n}"), unit, b[k]));
        }
        for (i, j) in self.joints.iter().enumerate() {
            let prefix = self.parameter_prefix(i);
            j.geometry_params(&prefix, &mut out);
            if let Some(m) = &j.mimic {
                out.push(ParamInfo::new(format!("{prefix}.coupling"), Unit::Dimensionless, m.multiplier));
            }
        }
        let t = pose_to_vector(&self.tool_for_parameters());
        for (k, n) in ["x_m", "y_m", "z_m", "rx_rad", "ry_rad", "rz_rad"].iter().enumerate() {
            let unit = if k < 3 { Unit::Metre } else { Unit::Radian };
            out.push(ParamInfo::new(format!("tool.{n}"), unit, t[k]));
        }
        self.tip_parameters(&mut out);
        out
    }

    fn set_parameter_values(&mut self, values: &[f64]) -> Result<()> {
        let info = self.parameters();
        check_values(values, info.len(), &info)?;
        self.base = pose_from_vectors(
            &Vector3::new(values[0], values[1], values[2]),
            &Vector3::new(values[3], values[4], values[5]),
        );
        let mut k = 6;
        for j in &mut self.joints {
            k += j.set_geometry_params(&values[k..]);
            if let Some(m) = &mut j.mimic {
                m.multiplier = values[k];
                k += 1;
            }
        }
        let tool = pose_from_vectors(
            &Vector3::new(values[k], values[k + 1], values[k + 2]),
            &Vector3::new(values[k + 3], values[k + 4], values[k + 5]),
        );
        self.set_tip_parameters(tool, &values[k + 6..]);
        Ok(())
    }
}

impl Kinematics for SerialChain {
    fn dof(&self) -> usize {
        self.dof_actuated()
    }

    fn joint_names(&self) -> Vec<String> {
        self.joints.iter().filter(|j| j.mimic.is_none()).map(|j| j.name.clone()).collect()
    }

    fn joint_kinds(&self) -> Vec<JointKind> {
        self.joints.iter().filter(|j| j.mimic.is_none()).map(|j| j.kind).collect()
    }

    fn joint_limits(&self) -> Vec<JointLimits> {
        self.joints.iter().filter(|j| j.mimic.is_none()).map(|j| j.limits).collect()
    }

    fn mobility(&self) -> Mobility {
        Mobility::Full6
    }

    fn forward(&self, q: &[f64]) -> Result<Pose> {
        if self.is_tree() {
            return Ok(self.frames(q)?.tool);
        }
        let all;
        let q = if self.has_mimic_joints() {
            all = self.all_joint_values(q)?;
            &all[..]
        } else {
            check_len(q, self.joints.len())?;
            q
        };
        let mut t = self.base;
        for (j, qi) in self.joints.iter().zip(q) {
            let (pre, axis, post) = j.split_corrected(false);
            t = t * pre * j.motion(&axis, *qi) * post;
        }
        Ok(t * self.tool)
    }

    fn inverse(&self, t_base_tool: &Pose, seed: &[f64]) -> Result<Vec<f64>> {
        self.inverse_with(t_base_tool, seed, &IkOptions::default())
    }

    fn jacobian(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        let frames = self.frames(q)?;
        let p = Point3::from(frames.tool.translation.vector);
        let kinds: Vec<JointKind> = self.joints.iter().map(|j| j.kind).collect();
        let jac = Self::point_jacobian(&frames, &kinds, self.tip_joint(), &p);
        if !self.has_mimic_joints() {
            return Ok(jac);
        }
        Ok(jac * self.coupling_matrix()?)
    }
}
