//! The vision crate's error type.

use std::path::PathBuf;

/// Everything that can go wrong in the vision crate.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum VisionError {
    /// A camera parameter (intrinsic or distortion coefficient) that the model cannot accept.
    #[error("camera parameter '{name}' = {value} is invalid: {reason}")]
    BadCameraParameter {
        /// Parameter name, e.g. `fx_px` or `k1`.
        name: String,
        /// Offending value.
        value: f64,
        /// Why it is invalid and what to do.
        reason: String,
    },
    /// A parameter vector of the wrong length.
    #[error("expected {expected} camera parameter values, got {got}")]
    ParameterCount {
        /// The model's number of parameters.
        expected: usize,
        /// Supplied number.
        got: usize,
    },
    /// A 3D point that the camera model cannot project (behind the camera, at the centre of
    /// projection, or outside the model's valid field of view).
    #[error("cannot project point ({x_m:.6}, {y_m:.6}, {z_m:.6}) m in the camera frame: {reason}")]
    NotProjectable {
        /// x in the camera frame.
        x_m: f64,
        /// y in the camera frame.
        y_m: f64,
        /// z in the camera frame.
        z_m: f64,
        /// Why.
        reason: String,
    },
    /// The iterative inverse of the lens distortion did not converge for a pixel.
    #[error("cannot unproject pixel ({u_px:.4}, {v_px:.4}) after {iterations} iterations (residual {residual_px:.3e} px): {reason}")]
    UnprojectionFailed {
        /// Column of the pixel.
        u_px: f64,
        /// Row of the pixel.
        v_px: f64,
        /// Newton iterations used.
        iterations: usize,
        /// Remaining reprojection error of the best estimate.
        residual_px: f64,
        /// What went wrong (no convergence, fold of the distortion, ray behind the camera).
        reason: String,
    },
    /// A calibration file could not be read or written.
    #[error("cannot access {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's reason.
        #[source]
        source: std::io::Error,
    },
    /// A calibration file (OpenCV FileStorage YAML, ROS camera_info YAML) is malformed.
    #[error("{source_name}:{line}: {message}")]
    Parse {
        /// The file, or `<string>` when parsed from memory.
        source_name: String,
        /// 1-based line (0 when the problem concerns the whole document).
        line: usize,
        /// What is wrong and what to do about it.
        message: String,
    },
    /// A distortion model or coefficient count that ferrocal does not support.
    #[error("unsupported distortion model '{model}' with {count} coefficients (supported: 5 plumb_bob / brown5, 8 rational_polynomial / rational8, 4 equidistant / kannala_brandt)")]
    UnsupportedDistortion {
        /// The model name found (empty when none was given).
        model: String,
        /// Number of coefficients found.
        count: usize,
    },
    // ---- calibration and pose estimation (`calib`, `pose`) ----
    /// An image that cannot be used: unreadable, empty, or the pattern was not found in it.
    #[error("{}: {reason}", image.display())]
    ImageUnusable {
        /// The image file (or the view's name).
        image: PathBuf,
        /// What is wrong and what to do about it.
        reason: String,
    },
    /// Fewer usable views than the calibration needs.
    #[error("{usable} usable view(s), at least {needed} needed: {detail}")]
    TooFewViews {
        /// Views that could be used.
        usable: usize,
        /// Views needed.
        needed: usize,
        /// Why the others were not usable and what to do.
        detail: String,
    },
    /// Views of different image sizes were given to one calibration.
    #[error("images of different sizes in one calibration: {detail}")]
    ImageSizeMismatch {
        /// The images and their sizes.
        detail: String,
    },
    /// The views cannot determine the requested parameters (e.g. all boards parallel).
    #[error("degenerate views: {detail}")]
    DegenerateViews {
        /// What is degenerate, the numbers that show it, and how to take better views.
        detail: String,
    },
    /// Inputs of inconsistent shape or value given to a calibration or pose function.
    #[error("invalid input: {detail}")]
    InvalidInput {
        /// What is wrong.
        detail: String,
    },
    /// The optimiser failed or returned an unusable solution.
    #[error("{stage} failed: {detail}")]
    SolverFailed {
        /// Which stage (e.g. `bundle adjustment`, `PnP`).
        stage: String,
        /// The solver's report.
        detail: String,
    },
    /// A pattern string (`--pattern`) that does not parse.
    #[error("pattern '{pattern}' does not parse: {problem}; expected {expected}")]
    PatternSyntax {
        /// The string as given.
        pattern: String,
        /// What is wrong with it.
        problem: String,
        /// The accepted forms.
        expected: String,
    },
    /// An image that cannot be opened or decoded, or that has no pixels.
    #[error("cannot read image {path}: {reason}")]
    ImageRead {
        /// The file.
        path: PathBuf,
        /// The decoder's or the file system's reason.
        reason: String,
    },
    /// An image held in memory that the detectors cannot use (empty, or a size mismatch).
    #[error("unusable image: {reason}")]
    BadImage {
        /// What is wrong.
        reason: String,
    },
    /// The pattern was not found in an image.
    #[error("pattern '{pattern}' not found: {reason}")]
    PatternNotFound {
        /// The pattern looked for (its string form).
        pattern: String,
        /// What was seen instead (e.g. how many corners, how large a grid).
        reason: String,
    },
    /// An external library (OpenCV, the AprilTag C library, kornia-rs) failed.
    #[error("{library} failed: {message}")]
    Backend {
        /// The library.
        library: &'static str,
        /// Its message.
        message: String,
    },
    /// Options that the detector or refiner cannot accept.
    #[error("invalid option '{name}' = {value}: {reason}")]
    BadOption {
        /// Option name.
        name: &'static str,
        /// Offending value.
        value: String,
        /// The accepted range.
        reason: String,
    },
}

/// Result alias of the vision crate.
pub type Result<T, E = VisionError> = std::result::Result<T, E>;
