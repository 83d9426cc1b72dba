//! Rigid-body dynamics of parallel-robot platforms, linear in their parameters.
//!
//! Two measurement models share the pieces here:
//!
//! - the force-sensing end-effector (Friedrich & Ihlenfeldt 2021): a body carried by six 1-DOF
//!   force sensors in a strut framework on a hexapod's moving platform ([`SensorFrame`]); its
//!   sensor forces are `f_q = f_q0 + f_K(x) + J_P^T (f_Dyn - f_G)` with `J_P^-T = [n_i; h_i x n_i]`
//!   ([`SensorFrame::wrench_matrix`]) and the Newton-Euler wrench linear in ten inertial
//!   parameters ([`body_regressor`]);
//! - the hexapod itself (Abdellatif & Heimann 2009): actuator forces
//!   `Q_a = J^T [Y_rb p_rb + friction of the passive joints] + leg friction`, linear in 10
//!   rigid-body and 14 friction parameters ([`HexapodDynamics`]).
//!
//! [`motion`] turns six pose coordinates and their rates into the platform's twist and
//! acceleration, and gives the Gibbs vector used by the orientation deformation terms.
//!
//! # Conventions
//! Everything is in SI units. Poses are `T_base_flange` (the flange is the hexapod's moving
//! platform frame, called `P` in the force-sensor model). World (base-frame) quantities carry
//! no suffix; body-frame quantities live in [`BodyState`]. Gravity is `(0, 0, -9.80665) m/s^2`
//! in the base frame ([`GRAVITY_M_S2`]). The inertial parameters are
//! `(m, m c_x, m c_y, m c_z, I_xx, I_xy, I_xz, I_yy, I_yz, I_zz)` with the inertia taken about the
//! frame origin: `I_P = I_PC + m S(c)^T S(c)` (the source writes `I_PC + m S(c) S(c)` with its own
//! sign convention for `S`; both are the parallel-axis theorem).

mod hexapod;
pub mod motion;
mod rigid;
mod sensors;

pub use hexapod::{HexapodDynamics, LegKinematics, HEXAPOD_FRICTION_NAMES, HEXAPOD_PARAMETERS};
pub use motion::{gibbs_vector, BodyState, MotionState};
pub use rigid::{body_regressor, inertia_regressor, newton_euler_wrench, RigidBody, RIGID_BODY_NAMES};
pub use sensors::{SensorFrame, SensorStrut, MAX_CONDITION};

use nalgebra::Vector3;

/// Standard gravity in the base frame, m/s^2 (`docs/conventions.md`).
pub const GRAVITY_M_S2: Vector3<f64> = Vector3::new(0.0, 0.0, -9.80665);
