//! The least-squares layer's error type.

/// Everything that can go wrong while posing or solving a problem.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LsqError {
    /// The problem is malformed: sizes that do not match, unknown blocks, bad options.
    #[error("{0}")]
    Setup(String),
    /// Too few residuals for what was asked (for instance a covariance with `m <= n`).
    #[error("{0}")]
    TooFew(String),
    /// A linear least-squares problem does not determine every parameter and its rank policy
    /// refuses it ([`crate::linear::RankPolicy::Refuse`]); the message names the parameters.
    #[error("{message}")]
    RankDeficient {
        /// Numerical rank.
        rank: usize,
        /// Number of parameters.
        n_params: usize,
        /// Parameters without any effect on the measurements.
        no_effect: Vec<String>,
        /// Groups of parameters that trade against each other (only combinations are seen).
        coupled: Vec<Vec<String>>,
        /// The whole explanation.
        message: String,
    },
    /// The optimisation could not start or diverged.
    #[error("the fit diverged: {0}")]
    Diverged(String),
    /// A linear-algebra step failed (a singular normal matrix).
    #[error("linear algebra: {0}")]
    Numeric(String),
    /// The model behind a residual refused to evaluate; the caller's own error, kept whole.
    #[error(transparent)]
    Model(Box<dyn std::error::Error + Send + Sync>),
}

impl LsqError {
    /// Wraps a caller's error so that it can travel through the solver and be recovered with
    /// [`LsqError::into_model`].
    pub fn model<E: std::error::Error + Send + Sync + 'static>(e: E) -> Self {
        Self::Model(Box::new(e))
    }

    /// The caller's error of type `E`, if this is one; otherwise `self` back.
    pub fn into_model<E: std::error::Error + 'static>(self) -> std::result::Result<E, Self> {
        match self {
            Self::Model(b) => match b.downcast::<E>() {
                Ok(e) => Ok(*e),
                Err(b) => Err(Self::Model(b)),
            },
            other => Err(other),
        }
    }
}

/// Result alias of the least-squares layer.
pub type Result<T, E = LsqError> = std::result::Result<T, E>;
