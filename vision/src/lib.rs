//! Vision measurement for ferrocal: detection of pattern plates, chessboards, AprilTags,
//! ChArUco boards and circle grids,
//! sub-pixel corners, camera models, calibration and bundle adjustment.
//!
//! Entry points:
//! - [`backends`]: the external libraries (OpenCV, AprilTag C, kornia-rs, Ceres) and a probe.
//! - [`camera`]: pinhole, Brown-Conrady (5 and 8 coefficients) and Kannala-Brandt camera models
//!   with analytic Jacobians, their inverse, and OpenCV / ROS calibration files.
//!
//! # Conventions
//! Pixel (0, 0) is the centre of the top-left pixel; see `docs/conventions.md`.
#![deny(missing_docs)]

pub mod backends;
pub mod calib;
pub mod camera;
pub mod detect;
pub mod error;
pub mod pose;
pub mod subpix;

pub use error::{Result, VisionError};
