//! The calib crate's error type.

/// Everything that can go wrong in identification.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CalibError {
    /// The robot model refused something (bad joint count, failed kinematics).
    #[error(transparent)]
    Robot(#[from] ferrocal_robot::RobotError),
    /// Measurements and model disagree (joint counts, units), or a row holds an impossible value.
    #[error("{0}")]
    Data(String),
    /// Too few measurements for what was asked.
    #[error("{0}")]
    TooFew(String),
    /// The optimisation failed to make progress or diverged.
    #[error("the fit diverged: {0}")]
    Diverged(String),
    /// The compliance equilibrium `q = q0 - C tau(q)` of the `joint_compliance` effects does not
    /// converge: at joint `joint` the compliance times the gravity stiffness `d tau / d q` is 1 or
    /// more (the joint cannot hold its load; the fixed-point iteration diverges).
    #[error("joint_compliance: the equilibrium q = q0 - c tau(q) does not converge at joint {joint} ('{name}'): compliance times gravity stiffness = {factor:.3} (must be below 1)")]
    Equilibrium {
        /// The joint (1-based, actuated).
        joint: usize,
        /// Its name.
        name: String,
        /// `c_j * d tau_j / d q_j` at the last iterate.
        factor: f64,
    },
    /// A linear-algebra step failed (singular matrix, SVD did not converge).
    #[error("linear algebra: {0}")]
    Numeric(String),
    /// A calibration file could not be read or written.
    #[error("{path}: {message}")]
    File {
        /// The file.
        path: std::path::PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A linear fit does not determine every parameter and its rank policy refuses it (the
    /// layer's [`ferrocal_lsq::LsqError::RankDeficient`], kept so that a caller can name or
    /// drop the parameters); the message is the layer's.
    #[error("{message}")]
    RankDeficient {
        /// Parameters without any effect on the measurements.
        no_effect: Vec<String>,
        /// Groups of parameters that trade against each other (only combinations are seen).
        coupled: Vec<Vec<String>>,
        /// Numerical rank.
        rank: usize,
        /// The whole explanation.
        message: String,
    },
}

/// Result alias of the calib crate.
pub type Result<T, E = CalibError> = std::result::Result<T, E>;
