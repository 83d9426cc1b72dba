//! Errors of the elastostatic identification.

/// Everything that can go wrong when identifying or using a compliance model.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StiffnessIdError {
    /// The stiffness model refused something (frames, wrenches, structure).
    #[error(transparent)]
    Model(#[from] ferrocal_robot::stiffness::StiffnessError),
    /// The kinematic model refused something (joint count, inverse kinematics).
    #[error(transparent)]
    Robot(#[from] ferrocal_robot::RobotError),
    /// The shared identification machinery failed (SVD, design selection).
    #[error(transparent)]
    Calib(#[from] crate::error::CalibError),
    /// An observation is unusable.
    #[error("observation '{id}': {reason}")]
    Observation {
        /// The observation's id.
        id: String,
        /// What is wrong.
        reason: String,
    },
    /// The loads leave parameters without effect on the measurements.
    #[error(
        "the loads do not excite {} parameter(s): {}{}; parameters that can be trusted: {}",
        unexcited.len(),
        unexcited.join(", "),
        if coupled.is_empty() { String::new() } else { format!("; only combinations of these are seen: {}", coupled.join(" | ")) },
        if trusted.is_empty() { "none".to_string() } else { trusted.join(", ") }
    )]
    Unexcited {
        /// Parameters with no effect at all (G2).
        unexcited: Vec<String>,
        /// Groups of parameters seen only in combination (G3), one text per group.
        coupled: Vec<String>,
        /// Parameters the data determine on their own (G1).
        trusted: Vec<String>,
    },
    /// An identified compliance that no physical spring can have.
    #[error("the compliance estimate is not physical: {}; parameters that can be trusted: {}", problems.join("; "), if trusted.is_empty() { "none".to_string() } else { trusted.join(", ") })]
    NotPhysical {
        /// Each problem (a negative diagonal entry, a matrix that is not positive definite,
        /// an asymmetric estimate), with the values.
        problems: Vec<String>,
        /// Parameters whose estimates are resolved (parameter-to-noise ratio above the threshold)
        /// and belong to no failing spring.
        trusted: Vec<String>,
    },
    /// Options that cannot work.
    #[error("{0}")]
    Options(String),
}

/// Result alias of the elastostatic identification.
pub type Result<T, E = StiffnessIdError> = std::result::Result<T, E>;

impl From<ferrocal_lsq::LsqError> for StiffnessIdError {
    fn from(e: ferrocal_lsq::LsqError) -> Self {
        Self::Calib(e.into())
    }
}
