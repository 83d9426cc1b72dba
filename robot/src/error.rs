//! The robot crate's error type.

use std::path::PathBuf;

/// Where in an input file something went wrong (1-based line and column).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Location {
    /// The file, or `<string>` when parsed from memory.
    pub file: PathBuf,
    /// 1-based line.
    pub line: u32,
    /// 1-based column.
    pub column: u32,
}

impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}:{}", self.file.display(), self.line, self.column)
    }
}

/// Everything that can go wrong in the robot crate.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RobotError {
    /// A model file could not be read from disk.
    #[error("cannot read robot model {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's reason.
        #[source]
        source: std::io::Error,
    },
    /// A model file is malformed (bad XML/TOML, missing element, bad value).
    #[error("{location}: {message}")]
    Parse {
        /// Where.
        location: Location,
        /// What is wrong and what to do about it.
        message: String,
    },
    /// A number in a model is NaN or infinite.
    #[error("{location}: non-finite value in {what}")]
    NonFinite {
        /// Where.
        location: Location,
        /// The quantity that holds it.
        what: String,
    },
    /// A joint limit whose lower bound exceeds its upper bound.
    #[error("joint '{joint}': lower limit {lower} is above upper limit {upper}{}", location.as_ref().map(|l| format!(" ({l})")).unwrap_or_default())]
    BadLimits {
        /// Joint name.
        joint: String,
        /// Lower bound (model units: rad or m).
        lower: f64,
        /// Upper bound.
        upper: f64,
        /// Where it was read, when read from a file.
        location: Option<Location>,
    },
    /// The kinematic structure is not a tree or chain as required.
    #[error("{location}: {message}")]
    Structure {
        /// Where.
        location: Location,
        /// What is wrong.
        message: String,
    },
    /// A request the model cannot serve, in words.
    #[error("{0}")]
    Invalid(String),
    /// A joint vector of the wrong length.
    #[error("expected {expected} joint values, got {got}")]
    JointCount {
        /// Model's number of actuators.
        expected: usize,
        /// Supplied number.
        got: usize,
    },
    /// A parameter vector of the wrong length.
    #[error("expected {expected} parameter values, got {got}")]
    ParameterCount {
        /// Model's number of parameters.
        expected: usize,
        /// Supplied number.
        got: usize,
    },
    /// A parameter value that the model cannot accept (e.g. a non-positive link length).
    #[error("parameter '{name}' = {value} is invalid: {reason}")]
    BadParameter {
        /// Parameter name.
        name: String,
        /// Offending value.
        value: f64,
        /// Why it is invalid.
        reason: String,
    },
    /// A joint value outside its limits.
    #[error("joint {joint} ('{name}') = {value:.6} is outside its limits [{lower:.6}, {upper:.6}]")]
    OutsideLimits {
        /// 1-based joint number.
        joint: usize,
        /// Joint name.
        name: String,
        /// Value.
        value: f64,
        /// Lower limit.
        lower: f64,
        /// Upper limit.
        upper: f64,
    },
    /// The requested pose cannot be reached by the model (no real solution).
    #[error("pose outside the workspace: {reason}")]
    Unreachable {
        /// Why (which leg or joint has no solution).
        reason: String,
    },
    /// An iterative inverse kinematics did not converge.
    #[error("inverse kinematics did not converge after {iterations} iterations (residual {residual_m:.3e} m, {residual_rad:.3e} rad); try another seed")]
    IkNotConverged {
        /// Iterations used.
        iterations: usize,
        /// Remaining position error.
        residual_m: f64,
        /// Remaining orientation error.
        residual_rad: f64,
    },
    /// An iterative forward kinematics (parallel robots) did not converge or left the assembly mode.
    #[error("forward kinematics did not converge: {reason}")]
    FkNotConverged {
        /// What happened.
        reason: String,
    },
    /// The model is at or near a singular configuration for the requested operation.
    #[error("singular configuration: {reason}")]
    Singular {
        /// Which matrix and how badly conditioned.
        reason: String,
    },
    /// A preset name that does not exist.
    #[error("unknown robot preset '{0}' (known: {known})", known = crate::presets::PRESET_NAMES.join(", "))]
    UnknownPreset(String),
    /// A coupled (mimic) joint whose coupling the model cannot use, or an operation that does
    /// not support coupled joints.
    #[error("joint '{joint}': {message}")]
    Coupling {
        /// The mimic joint.
        joint: String,
        /// What is wrong.
        message: String,
    },
    /// A safety configuration that cannot hold (e.g. an empty workspace).
    #[error("safety configuration: {0}")]
    Safety(String),
}

/// Result alias of the robot crate.
pub type Result<T, E = RobotError> = std::result::Result<T, E>;

/// Returns `Err(NonFinite)` when `v` is not finite.
pub(crate) fn check_finite(v: f64, location: &Location, what: &str) -> Result<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(RobotError::NonFinite { location: location.clone(), what: what.to_string() })
    }
}

/// 1-based line and column of a byte offset in `text`.
pub fn line_col(text: &str, byte_offset: usize) -> (u32, u32) {
    let upto = &text[..byte_offset.min(text.len())];
    let line = upto.matches('\n').count() as u32 + 1;
    let col = upto.rsplit('\n').next().map_or(0, |l| l.chars().count()) as u32 + 1;
    (line, col)
}

/// Converts a TOML deserialisation error into a [`RobotError::Parse`] naming file, line and column.
pub fn toml_error(file: &std::path::Path, text: &str, err: &toml::de::Error) -> RobotError {
    let (line, column) = err.span().map_or((1, 1), |s| line_col(text, s.start));
    RobotError::Parse {
        location: Location { file: file.to_path_buf(), line, column },
        message: err.message().to_string(),
    }
}
