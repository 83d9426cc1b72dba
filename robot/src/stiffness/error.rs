//! The error type of the stiffness model.

/// Everything that can go wrong when building or evaluating a virtual joint model.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StiffnessError {
    /// The kinematic model refused something (joint count, non-finite joint value).
    #[error(transparent)]
    Robot(#[from] crate::RobotError),
    /// A wrench names a frame the model does not have.
    #[error("wrench frame '{name}' does not exist; known frames: {}", known.join(", "))]
    UnknownFrame {
        /// The name given.
        name: String,
        /// Frames the model knows.
        known: Vec<String>,
    },
    /// A wrench whose size cannot be right (wrong units, typing errors).
    #[error("implausible wrench: {reason}")]
    ImplausibleWrench {
        /// What is wrong and what to check.
        reason: String,
    },
    /// A compliance or stiffness value that cannot describe a physical spring.
    #[error("{what}: {reason}")]
    BadCompliance {
        /// The spring or joint.
        what: String,
        /// Why.
        reason: String,
    },
    /// The model's structure does not allow the request (e.g. a compensator on a prismatic joint).
    #[error("{0}")]
    Structure(String),
}

/// Result alias of the stiffness model.
pub type Result<T, E = StiffnessError> = std::result::Result<T, E>;
