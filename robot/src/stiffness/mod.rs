//! Elastostatic model of serial robots by the virtual joint method (Klimchik et al. 2015).
//!
//! `T = T_base prod_i [T_joint(q_i + theta_Ac,i) T_link,i T_VJM(theta_link,i)] T_tool`: every
//! actuated joint is a one-dimensional spring, every link (the base included) a 6-DOF virtual
//! spring at its far end with a 6 x 6 compliance matrix ([`VjmModel`]). From it:
//!
//! - the Cartesian compliance `k_C = J_theta K_theta^-1 J_theta^T` and the tool's deflection under a
//!   wrench, the links' weight and a gravity compensator ([`VjmModel::deflection`]);
//! - the exact compliant kinematics for given deflections ([`VjmModel::deflected_pose`]);
//! - the identification equation `dt_j = A(q_j, w_j) pi + eps_j`, linear in the compliance entries
//!   ([`regressor`]), with rows for the whole pose or for markers on the tool and their weights
//!   from the measurement noise ([`NoiseModel`]);
//! - the structure the model reduction needs: each spring's beam template ([`beam`]) and the
//!   joint compliances indistinguishable from a spring's ([`VjmModel::aggregations`]);
//! - wrenches from named frames, checked for plausible units ([`wrench`]);
//! - the KR 270-like arm and the Orthoglide link ([`presets`]).
//!
//! # Conventions
//! SI inside: compliances in m/N, rad/(N m) and 1/N; a deflection `(dp, dphi)` is the tool's
//! translation and rotation vector in the base frame; spring deflections are expressed in the
//! spring's own frame. Joint numbers in names and messages are 1-based.

pub mod beam;
pub mod compensator;
pub mod error;
pub mod model;
pub mod presets;
pub mod regressor;
pub mod wrench;

pub use beam::{beam_template, BeamStiffness};
pub use compensator::GravityCompensator;
pub use error::StiffnessError;
pub use model::{Aggregation, Deflections, Loading, Transmitted, VirtualSpring, VjmJacobians, VjmModel};
pub use regressor::{ComplianceLayout, ComplianceParam, NoiseModel, ParamKind};
pub use wrench::{Wrench, WrenchLimits, WrenchSpec};
