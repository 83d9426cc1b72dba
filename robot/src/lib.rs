//! Robot models for ferrocal.
//!
//! One abstraction, [`Kinematics`], covers every robot the suite measures and calibrates:
//!
//! - serial chains ([`serial::SerialChain`]): URDF import, standard and modified DH tables, the
//!   `ur5` and `ur10` presets; forward kinematics of every frame, geometric Jacobian, damped
//!   least-squares inverse kinematics, gravity torques from the links' inertials;
//! - parallel robots built from legs ([`parallel`]): the 3-DOF Gantry-Tau, its six-link error
//!   model, the 6-DOF F1 Gantry-Tau and Stewart/hexapod platforms;
//! - safety zones ([`safety`]): joint and spherical-joint limits, obstacle boxes with margins, a
//!   margin from the workspace edge, and checks for single poses and straight joint-space moves.
//!
//! Every model exposes a named, unit-carrying parameter vector ([`Parameterized`]) so that
//! identification never reaches into model internals. [`RobotModel::load`] resolves a preset name,
//! a URDF file or a TOML model file.
//!
//! # Conventions
//! SI units inside (metres, radians); `T_a_b` maps frame-b coordinates into frame a; joint numbers
//! in messages are 1-based. The full list is in `docs/conventions.md` at the workspace root.
#![deny(missing_docs)]

pub mod check;
pub mod dynamics;
pub mod error;
pub mod geometry;
pub mod kinematics;
pub mod model;
pub mod parallel;
pub mod params;
pub mod presets;
pub mod program;
pub mod safety;
pub mod serial;
pub mod stiffness;
pub mod workspace;

pub use error::{Result, RobotError};
pub use geometry::Pose;
pub use kinematics::{JointKind, JointLimits, Kinematics, Mobility};
pub use model::RobotModel;
pub use parallel::ParallelRobot;
pub use params::{ParamInfo, Parameterized, Unit};
