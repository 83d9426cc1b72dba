//! Parallel robots built from legs.
//!
//! A parallel robot is a moving platform (the `flange` frame, pose `T_base_flange` with position
//! `T` and rotation `R`) connected to the base by legs. Every leg has
//!
//! - a base-side spherical-joint centre `A` that moves with the leg's actuators: on a guideway cart
//!   (`A(q) = A0 + q v`), on a small serial carriage of prismatic and revolute stages (F1), or fixed
//!   (hexapod);
//! - a platform-side spherical-joint centre `B = T + R B0`;
//! - a length constraint `||A - B||^2 = L^2`, where `L` is constant (guideway robots) or driven by
//!   an actuator (`L = L0 + q`, hexapod).
//!
//! Each model lowers itself to that common description, a [`Mechanism`], which evaluates the
//! constraint residuals and their derivatives with respect to the actuators, the tool pose and the
//! parameters, and runs the Newton solvers the models share. The models are:
//!
//! - [`GantryTau3`]: the nominal / modified 3-DOF Gantry-Tau (one link per arm, constant
//!   orientation), closed-form inverse and forward kinematics;
//! - [`GantryTau6`]: the six-link Gantry-Tau error model (clusters of 1, 2 and 3 links; the platform
//!   orientation follows from the links);
//! - [`GantryTauF1`]: the 6-DOF F1 Gantry-Tau with a rotating plate on cart 2 and a rotating and
//!   tilting plate on cart 3;
//! - [`Hexapod`]: a Stewart platform with six extensible legs.
//!
//! Models are written to and read from TOML files with [`file`](mod@file) (schema in
//! `docs/model-format.md`).

mod f1;
pub mod file;
mod gantry_tau3;
mod gantry_tau6;
mod hexapod;
pub mod legs;
pub mod presets;

pub use f1::{GantryTauF1, RotaryStage};
pub use gantry_tau3::{GantryArm, GantryTau3};
pub use gantry_tau6::GantryTau6;
pub use hexapod::{Hexapod, HexapodLeg};
pub use legs::{Carriage, Leg, LegSide, LegState, Mechanism, Stage};

use nalgebra::{DMatrix, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{Result, RobotError};
use crate::geometry::Pose;
use crate::kinematics::{JointLimits, Kinematics};

/// The joints of a Gantry-Tau with three carts, inside an `impl Kinematics`: `dof` 3,
/// `joint_names` `cart1..cart3`, `joint_kinds` prismatic, and `joint_limits` the `limits` of the
/// entries of the field `$carts` (one per cart).
macro_rules! three_cart_joints {
    ($carts:ident) => {
        fn dof(&self) -> usize {
            3
        }

        fn joint_names(&self) -> Vec<String> {
            (1..=3).map(|i| format!("cart{i}")).collect()
        }

        fn joint_kinds(&self) -> Vec<JointKind> {
            vec![JointKind::Prismatic; 3]
        }

        fn joint_limits(&self) -> Vec<JointLimits> {
            self.$carts.iter().map(|c| c.limits).collect()
        }
    };
}
pub(crate) use three_cart_joints;

/// One of two solutions of a quadratic constraint: the sign in front of its square root.
///
/// For a guideway arm the branch is the sign of `v . (A - B)`: `Minus` means the cart's joint
/// centre lies behind the platform joint along the direction of travel `v` (the link leans
/// towards `+v`), `Plus` that it lies ahead. For the forward kinematics of a Gantry-Tau the
/// assembly mode is the sign of `((C2 - C1) x (C3 - C1)) . (T - C1)` where `C_i` are the sphere
/// centres of the three arms.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Branch {
    /// The `+` solution.
    Plus,
    /// The `-` solution.
    Minus,
}

impl Branch {
    /// `+1.0` or `-1.0`.
    pub fn sign(self) -> f64 {
        match self {
            Branch::Plus => 1.0,
            Branch::Minus => -1.0,
        }
    }

    /// The branch a signed quantity lies on (zero counts as `Plus`).
    pub fn of(value: f64) -> Self {
        if value >= 0.0 {
            Branch::Plus
        } else {
            Branch::Minus
        }
    }

    /// `"plus"` or `"minus"`, as in model files.
    pub fn as_str(self) -> &'static str {
        match self {
            Branch::Plus => "plus",
            Branch::Minus => "minus",
        }
    }
}

/// Settings of the Newton solvers (forward kinematics of the six-link, F1 and hexapod models,
/// inverse kinematics of the six-link and F1 models) and of their assembly-mode guard.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SolverOptions {
    /// Iteration limit of one Newton solve.
    pub max_iterations: usize,
    /// Convergence threshold on the largest leg-length error `|f_k| / (2 L_k)`, metres.
    pub tolerance_m: f64,
    /// Largest Newton step; longer steps are shortened (metres, or radians for rotations and
    /// revolute joints).
    pub max_step: f64,
    /// Guard: a converged pose farther than this from the start position is rejected as another
    /// assembly mode.
    pub max_translation_m: f64,
    /// Guard: a converged orientation rotated more than this from the start is rejected as another
    /// assembly mode.
    pub max_rotation_rad: f64,
    /// Number of equal steps of the joint-space continuation used when Newton from the start pose
    /// fails (F1, hexapod).
    pub continuation_steps: usize,
}

impl Default for SolverOptions {
    fn default() -> Self {
        Self {
            max_iterations: 60,
            tolerance_m: 1e-12,
            max_step: 0.2,
            max_translation_m: 0.5,
            max_rotation_rad: 1.0,
            continuation_steps: 8,
        }
    }
}

/// A linear guideway with its cart (6-link and F1 Gantry-Tau).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Guideway {
    /// Displacement of the cart per metre of actuator travel, base frame. Not normalised: its norm
    /// absorbs a transmission scale error.
    pub v: Vector3<f64>,
    /// Cart travel limits, metres.
    pub limits: JointLimits,
    /// Configuration of the links on this cart: the sign of `v . (A - B)` (see [`Branch`]).
    pub branch: Branch,
}

/// One link with spherical joints at both ends (6-link and F1 Gantry-Tau).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Link {
    /// 0-based arm (guideway) that carries the link.
    pub arm: usize,
    /// Base-side joint centre: for the 6-link model `A0` (base frame, cart at `q = 0`); for the F1
    /// the point in the last frame of the arm's carriage (cart 1: base axes, origin at the cart;
    /// arm 2: the rotating plate; arm 3: the tilting plate).
    pub a_m: Vector3<f64>,
    /// Platform-side joint centre in the platform (flange) frame.
    pub b0_m: Vector3<f64>,
    /// Distance between the two joint centres.
    pub length_m: f64,
    /// Axis of the base-side spherical joint, in the same frame as `a_m`; `None`: the link
    /// direction `B - A` at `q = 0`.
    pub base_axis: Option<Vector3<f64>>,
    /// Axis of the platform-side spherical joint, platform frame; `None`: the direction `A - B` at
    /// `q = 0`.
    pub platform_axis: Option<Vector3<f64>>,
}

/// One link as a segment in the base frame, for collision checks.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkSegment {
    /// Link (leg) name, e.g. `link2_1` or `leg4`.
    pub link: String,
    /// Base-side joint centre, base frame.
    pub a_m: Vector3<f64>,
    /// Platform-side joint centre, base frame.
    pub b_m: Vector3<f64>,
}

/// Angles of one link at its two spherical joints: the angle between the link and the stated
/// joint axis (base side: `B - A` against the base-side axis; platform side: `A - B` against the
/// platform-side axis). A safety checker compares them with the joints' cone half-angles.
#[derive(Clone, Debug, PartialEq)]
pub struct SphericalJointAngles {
    /// Link (leg) name.
    pub link: String,
    /// Angle at the base-side joint.
    pub base_rad: f64,
    /// Angle at the platform-side joint.
    pub platform_rad: f64,
}

/// What every parallel model offers beyond [`Kinematics`]: its leg description, the closure
/// equations used by calibration, link segments and spherical-joint angles.
pub trait ParallelRobot: Kinematics {
    /// The model lowered to the common leg description (rebuilt from the model's fields).
    fn mechanism(&self) -> Result<Mechanism>;

    /// The tool's velocity Jacobian at `q` through the mechanism at the forward kinematics' pose
    /// ([`Mechanism::velocity_jacobian`], `translation_only` as there): every model's
    /// [`Kinematics::jacobian`].
    fn mechanism_jacobian(&self, q: &[f64], translation_only: bool) -> Result<DMatrix<f64>> {
        let pose = self.forward(q)?;
        self.mechanism()?.velocity_jacobian(q, &pose, translation_only)
    }

    /// Closure residuals `f_k = ||A_k - B_k||^2 - L_k^2` (m^2), one per leg, at joint values `q`
    /// and tool pose `t_base_tool` (for [`Mobility::Translation3`](crate::Mobility) models the
    /// rotation is ignored).
    fn constraint_residuals(&self, q: &[f64], t_base_tool: &Pose) -> Result<Vec<f64>> {
        let m = self.mechanism()?;
        Ok(m.residuals(q, t_base_tool)?.iter().copied().collect())
    }

    /// Derivative of the closure residuals with respect to the joint values (legs x dof).
    fn constraint_jacobian_joints(&self, q: &[f64], t_base_tool: &Pose) -> Result<DMatrix<f64>> {
        let m = self.mechanism()?;
        Ok(m.linearize(q, t_base_tool)?.fq)
    }

    /// Derivative of the closure residuals with respect to a small motion `(dp, dw)` of the tool
    /// frame (legs x 6; `dp` the tool point's displacement, `dw` a rotation vector applied on the
    /// left, both in the base frame).
    fn constraint_jacobian_pose(&self, q: &[f64], t_base_tool: &Pose) -> Result<DMatrix<f64>> {
        let m = self.mechanism()?;
        Ok(m.linearize(q, t_base_tool)?.fx)
    }

    /// Derivative of the closure residuals with respect to the parameter vector (legs x
    /// [`Parameterized::n_parameters`](crate::Parameterized::n_parameters)).
    fn constraint_jacobian_parameters(&self, q: &[f64], t_base_tool: &Pose) -> Result<DMatrix<f64>> {
        let m = self.mechanism()?;
        m.parameter_jacobian(q, t_base_tool)
    }

    /// The links as segments in the base frame at joint values `q` (runs the forward kinematics).
    fn link_segments(&self, q: &[f64]) -> Result<Vec<LinkSegment>> {
        let pose = self.forward(q)?;
        self.mechanism()?.segments(q, &pose)
    }

    /// The angles of every link at its spherical joints at joint values `q` (runs the forward
    /// kinematics; joints without a stated axis use the link direction at `q = 0`, which runs the
    /// forward kinematics there too).
    fn spherical_joint_angles(&self, q: &[f64]) -> Result<Vec<SphericalJointAngles>> {
        let m = self.mechanism()?;
        let pose = self.forward(q)?;
        let reference = if m.needs_reference_axes() {
            let q0 = vec![0.0; self.dof()];
            let p0 = self.forward(&q0).map_err(|e| RobotError::Unreachable {
                reason: format!(
                    "a spherical joint has no stated axis and its default (the link direction at q = 0) is unavailable: {e}"
                ),
            })?;
            Some((q0, p0))
        } else {
            None
        };
        m.joint_angles(q, &pose, reference.as_ref().map(|(q0, p0)| (q0.as_slice(), p0)))
    }
}

/// Returns `Err(BadParameter)` unless `value` is finite and positive.
pub(crate) fn check_positive(name: &str, value: f64) -> Result<()> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(RobotError::BadParameter {
            name: name.to_string(),
            value,
            reason: "a length must be finite and positive".into(),
        })
    }
}

/// Returns `Err(BadParameter)` unless the direction has a usable (finite, non-zero) length.
pub(crate) fn check_direction(name: &str, v: &Vector3<f64>) -> Result<()> {
    let n = v.norm();
    if n.is_finite() && n > 1e-9 {
        Ok(())
    } else {
        Err(RobotError::BadParameter {
            name: name.to_string(),
            value: n,
            reason: "a direction must have a finite, non-zero length".into(),
        })
    }
}

/// Returns `Err(BadParameter)` unless every component is finite.
pub(crate) fn check_vector(name: &str, v: &Vector3<f64>) -> Result<()> {
    for (k, c) in v.iter().enumerate() {
        if !c.is_finite() {
            return Err(RobotError::BadParameter {
                name: format!("{name}[{}]", ["x", "y", "z"][k]),
                value: *c,
                reason: "not finite".into(),
            });
        }
    }
    Ok(())
}

/// Names of the components of a vector parameter: `prefix.{x,y,z}{suffix}`.
pub(crate) fn vec_names(prefix: &str, suffix: &str) -> [String; 3] {
    [format!("{prefix}_x{suffix}"), format!("{prefix}_y{suffix}"), format!("{prefix}_z{suffix}")]
}
