//! The report crate's error: what the library crates report, passed on unchanged, or a message
//! of this crate with the error that caused it ([`Context`]).
//!
//! Shown as `{:#}` by the binary, an error reads as its chain of causes joined
//! by `: `, as the library crates' own errors do.

/// Everything that can go wrong while composing or writing a report.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// A message of this crate (an output that would overwrite an input, a missing folder).
    #[error("{0}")]
    Message(String),
    /// What was being done when `source` went wrong.
    #[error("{context}")]
    Context {
        /// What was being done.
        context: String,
        /// Why it failed.
        #[source]
        source: Box<ReportError>,
    },
    /// From the calibration crate.
    #[error(transparent)]
    Calib(#[from] ferrocal_calib::CalibError),
    /// From the datasets crate.
    #[error(transparent)]
    Dataset(#[from] ferrocal_datasets::error::DatasetError),
    /// From the vision crate.
    #[error(transparent)]
    Vision(#[from] ferrocal_vision::VisionError),
    /// From the robot crate.
    #[error(transparent)]
    Robot(#[from] ferrocal_robot::RobotError),
    /// From the least-squares layer.
    #[error(transparent)]
    Lsq(#[from] ferrocal_lsq::LsqError),
    /// From the elastostatic identification.
    #[error(transparent)]
    Stiffness(#[from] ferrocal_calib::stiffness::StiffnessIdError),
    /// The verdicts' limits file.
    #[error(transparent)]
    Thresholds(#[from] ferrocal_calib::verdict::ThresholdsError),
    /// Reading or writing a file.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// Composing JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

impl ReportError {
    /// An error of this crate with `message`.
    pub fn msg(message: impl Into<String>) -> Self {
        Self::Message(message.into())
    }
}

/// An error on one line, as the binary shows it: its chain of causes joined with `: `, a cause
/// whose words the line already holds left out (an error that quotes its source in its own
/// message would else say it twice: `cannot read x.csv: No such file ...: No such file ...`).
pub fn one_line(e: &(dyn std::error::Error + 'static)) -> String {
    let mut msg = String::new();
    let mut cause = Some(e);
    while let Some(c) = cause {
        let text = c.to_string().replace('\n', " ");
        if !msg.contains(&text) {
            if !msg.is_empty() {
                msg.push_str(": ");
            }
            msg.push_str(&text);
        }
        cause = c.source();
    }
    msg
}

/// The report crate's result.
pub type Result<T, E = ReportError> = std::result::Result<T, E>;

/// What was being done, added to an error (or to a missing value) on the way up.
pub trait Context<T> {
    /// The error with `context` before it.
    fn context(self, context: impl Into<String>) -> Result<T>;
    /// The error with the context `f` makes (only when there is an error).
    fn with_context<S: Into<String>>(self, f: impl FnOnce() -> S) -> Result<T>;
}

impl<T, E: Into<ReportError>> Context<T> for std::result::Result<T, E> {
    fn context(self, context: impl Into<String>) -> Result<T> {
        self.map_err(|e| ReportError::Context { context: context.into(), source: Box::new(e.into()) })
    }

    fn with_context<S: Into<String>>(self, f: impl FnOnce() -> S) -> Result<T> {
        self.map_err(|e| ReportError::Context { context: f().into(), source: Box::new(e.into()) })
    }
}

impl<T> Context<T> for Option<T> {
    fn context(self, context: impl Into<String>) -> Result<T> {
        self.ok_or_else(|| ReportError::Message(context.into()))
    }

    fn with_context<S: Into<String>>(self, f: impl FnOnce() -> S) -> Result<T> {
        self.ok_or_else(|| ReportError::Message(f().into()))
    }
}

/// Returns early with a [`ReportError::Message`] formatted from the arguments.
#[macro_export]
macro_rules! bail {
    ($($arg:tt)*) => {
        return Err($crate::error::ReportError::Message(format!($($arg)*)))
    };
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_cause_quoted_by_its_error_is_said_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory (os error 2)");
        let e = ferrocal_datasets::error::DatasetError::Io { path: "x.csv".into(), source: io };
        assert_eq!(super::one_line(&e), "cannot read x.csv: No such file or directory (os error 2)");
        let e = super::ReportError::msg("inner\nreason");
        let e = super::ReportError::Context { context: "outer".into(), source: Box::new(e) };
        assert_eq!(super::one_line(&e), "outer: inner reason");
    }
}
