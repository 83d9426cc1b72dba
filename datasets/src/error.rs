//! The datasets crate's error type.
//!
//! Every error about the content of a file names the file, the 1-based line (comment lines count,
//! as in the file) and, where one applies, the column by its header name.

use std::fmt;
use std::path::PathBuf;

/// Where in a table something went wrong.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Location {
    /// The file, or a description such as `<string>` when parsed from memory.
    pub file: PathBuf,
    /// 1-based line in the file; comment lines count.
    pub line: u64,
    /// The column, by its header name (or a description such as `field 3` for headerless
    /// files), when the problem belongs to one.
    pub column: Option<String>,
}

impl Location {
    /// A location with a column.
    pub fn new(file: impl Into<PathBuf>, line: u64, column: impl Into<String>) -> Self {
        Self { file: file.into(), line, column: Some(column.into()) }
    }

    /// A location of a whole line.
    pub fn line(file: impl Into<PathBuf>, line: u64) -> Self {
        Self { file: file.into(), line, column: None }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: line {}", self.file.display(), self.line)?;
        if let Some(c) = &self.column {
            write!(f, ", column '{c}'")?;
        }
        Ok(())
    }
}

/// Everything that can go wrong in the datasets crate.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DatasetError {
    /// A file or directory could not be read.
    #[error("cannot read {}: {source}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The operating system's reason.
        #[source]
        source: std::io::Error,
    },
    /// A file could not be written.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The operating system's reason.
        #[source]
        source: std::io::Error,
    },
    /// A required column is absent from the header.
    #[error("{location}: required column is missing{hint}")]
    MissingColumn {
        /// The header line; `column` names the required column.
        location: Location,
        /// Extra advice (may be empty), starting with `; `.
        hint: String,
    },
    /// A required value is empty.
    #[error("{location}: required value is missing")]
    MissingValue {
        /// Where.
        location: Location,
    },
    /// A number written with a decimal comma where the table uses a decimal point.
    #[error("{location}: decimal comma in '{text}'; this table uses '.' as the decimal point")]
    DecimalComma {
        /// Where.
        location: Location,
        /// The cell text (for a comma-separated table: the cells the comma split apart).
        text: String,
    },
    /// A number written with a decimal point where the table uses a decimal comma.
    #[error("{location}: decimal point in '{text}'; this table uses ',' as the decimal separator")]
    DecimalPoint {
        /// Where.
        location: Location,
        /// The cell text.
        text: String,
    },
    /// A cell that should hold a number does not.
    #[error("{location}: '{text}' is not a number")]
    NotANumber {
        /// Where.
        location: Location,
        /// The cell text.
        text: String,
    },
    /// A number that is NaN or infinite (or overflows to infinity).
    #[error("{location}: non-finite number '{text}'")]
    NonFinite {
        /// Where.
        location: Location,
        /// The cell text.
        text: String,
    },
    /// A row id that already occurred.
    #[error("{location}: duplicate pose_id '{id}' (first used on line {first_line})")]
    DuplicateId {
        /// Where the second occurrence is.
        location: Location,
        /// The id.
        id: String,
        /// Line of the first occurrence.
        first_line: u64,
    },
    /// Joint columns or joint vectors whose counts do not agree.
    #[error("{location}: inconsistent joint count: {message}")]
    JointCount {
        /// Where.
        location: Location,
        /// What disagrees with what.
        message: String,
    },
    /// A row with a different number of fields than the header.
    #[error("{location}: the row has {found} fields, the header has {expected}")]
    FieldCount {
        /// Where; `column` names the first missing or surplus field.
        location: Location,
        /// Fields in the row.
        found: usize,
        /// Fields in the header.
        expected: usize,
    },
    /// A value or header entry that is malformed for another reason.
    #[error("{location}: {message}")]
    Invalid {
        /// Where.
        location: Location,
        /// What is wrong and what to do about it.
        message: String,
    },
    /// A file named in a table does not exist (or is not among the files the call lists).
    #[error("{location}: file '{missing}' does not exist{detail}")]
    MissingFile {
        /// Where the name is.
        location: Location,
        /// The name as written.
        missing: String,
        /// Extra detail (may be empty), starting with `; ` or ` `.
        detail: String,
    },
    /// An image that cannot be opened or decoded.
    #[error("cannot read image {}: {reason}", path.display())]
    Image {
        /// The image file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// Input that is wrong as a whole, not at one place in a file (an empty set, a degenerate
    /// point cloud, inconsistent arguments).
    #[error("{0}")]
    Input(String),
    /// A simulated-cell configuration that cannot be used (`sim` module); the message names the
    /// file, line and column when it comes from a file.
    #[error("cell configuration: {0}")]
    Config(String),
    /// JSON could not be written or read.
    #[error("JSON: {0}")]
    Json(#[from] serde_json::Error),
    /// A renderer configuration value that cannot be used (`render` module).
    #[error("render configuration: {field} = {value}: {reason}")]
    RenderConfig {
        /// The configuration field, e.g. `optics.psf.sigma_px`.
        field: String,
        /// The offending value as written.
        value: String,
        /// Why it is rejected and what to use instead.
        reason: String,
    },
    /// A scene the renderer cannot draw: the target behind the camera or seen from its back,
    /// or a lens model that is not invertible over the image (`render` module).
    #[error("render: {0}")]
    Render(String),
    /// An error of a camera model (projection, unprojection, parameters).
    #[error(transparent)]
    Camera(#[from] ferrocal_vision::VisionError),
    /// An error of a calibration (the workflows that run one: `handeye`, `measure`).
    #[error(transparent)]
    Calib(#[from] ferrocal_calib::CalibError),
    /// An error of a robot model (loading a preset, URDF or TOML, kinematics).
    #[error(transparent)]
    Robot(#[from] ferrocal_robot::RobotError),
    /// An error of the least-squares layer (a linear fit).
    #[error(transparent)]
    Lsq(#[from] ferrocal_lsq::LsqError),
    /// An error of the elastostatic identification.
    #[error(transparent)]
    Stiffness(#[from] ferrocal_calib::stiffness::StiffnessIdError),
    /// What a workflow was doing when `source` went wrong.
    #[error("{context}")]
    Context {
        /// What was being done (e.g. `handeye: 12 usable image(s) of 14`).
        context: String,
        /// Why it failed.
        #[source]
        source: Box<DatasetError>,
    },
}

impl DatasetError {
    /// This error with `context` before it (shown as `context: error` in a chain of causes).
    pub fn context(self, context: impl Into<String>) -> Self {
        Self::Context { context: context.into(), source: Box::new(self) }
    }
}

/// Result alias of the datasets crate.
pub type Result<T, E = DatasetError> = std::result::Result<T, E>;
