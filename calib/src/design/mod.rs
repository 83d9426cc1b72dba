//! Experiment design: which measurements to take.
//!
//! - [`criteria`]: the A, D, K and N criteria and the source's `sigma_max^2 / sigma_min` check
//!   on a Fisher information matrix;
//! - [`pool`]: candidates (poses, samples) with their regressor rows or information
//!   contributions, independent of the kind of regressor (positions, wrenches, torques);
//! - [`selection`]: greedy deletion with rank-one downdates (the criterion against the count,
//!   down to the smallest full-rank set) and exchange refinement;
//! - [`kinematic`]: kinematic calibration as a design problem: pools of robot poses measured
//!   by a camera rig or a tracker, predicted parameter deviations and held-out accuracy, and
//!   their check against simulated calibrations;
//! - [`flow`]: the source's automated calibration flow up to the chosen poses;
//! - [`excitation`]: Fourier-series excitation trajectories optimised for a linear regressor
//!   (dynamics and force-sensor identification).

pub mod criteria;
pub mod excitation;
pub mod flow;
pub mod kinematic;
pub mod pool;
pub mod selection;

pub use criteria::{CriteriaSummary, Criterion};
pub use pool::InformationPool;
pub use selection::{exchange, greedy_deletion, select, DeletionHistory, Selection, SelectionSettings};
