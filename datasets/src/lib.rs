//! Recordings for ferrocal: importers for real data and the synthetic measurement cell.
//!
//! Entry points:
//! - [`import`]: the measurement CSV of `shared/spec/measurements.md`, the UR5 and UR10
//!   laser-tracker recordings, image folders; export to the measurement CSV.
//! - [`camera`]: the `camera calibrate` and `camera stereo` workflows (views, held-out split,
//!   calibration, held-out scoring, the rectified row check).
//! - [`detect`]: the `detect` workflow (a pattern found in a batch of images).
//! - [`diagnose`]: the `diagnose` workflow on a measurement table.
//! - [`handeye`]: hand-eye recordings (poses table, industrial_calibration importer, images
//!   to a recording, simulation and the Monte Carlo study of the covariance).
//! - [`kinematics`]: the `robot` command's joint values in user units, poses from text, forward
//!   kinematics within the limits.
//! - [`measure`]: from a session's images to metric target poses (camera rig calibrated from the
//!   plate views, one pose with covariance per robot pose).
//! - [`render`]: the physically modelled camera renderer of the synthetic cell.
//! - [`sim`]: the synthetic measurement cell (true robot, plan, tracker, cameras) and the
//!   recorded sessions it writes.
//! - [`dynsim`]: simulated dynamics data: the force-sensing end-effector on a hexapod and the
//!   hexapod's actuator forces with friction, noise, sampling and payload steps.
//! - [`motion`]: the compliant actuator axis of a Gantry-Tau-like machine (drive, links,
//!   platform) for identification and learning control, with encoder and tool sensors.
//! - [`stiffsim`]: the elastostatic cell (a compliant KR 270-like arm with a gravity
//!   compensator, a laser tracker measuring reflectors under payloads).
//! - [`checks`]: the pass/fail criteria of `ferrocal demo` and the UR5 target reproduction.
//! - [`formats`]: the tools' own file formats (plan file, dynamics stream and pose tables,
//!   deflection tables), readers and writers.
//! - [`error`]: the crate's error type, [`error::DatasetError`].
//!
//! # Conventions
//! SI units inside; tables at the edges in millimetres and degrees unless a column says otherwise.
//! See `docs/conventions.md`.
#![deny(missing_docs)]

pub mod atomic;
pub mod calibration;
pub mod camera;
pub mod checks;
pub mod correct;
pub mod detect;
pub mod diagnose;
pub mod dynsim;
pub mod error;
pub mod formats;
pub mod handeye;
pub mod import;
pub mod kinematics;
pub mod measure;
pub mod motion;
pub mod plan;
pub mod recording;
pub mod render;
pub mod safety;
pub mod sim;
pub mod stiffsim;
pub mod trees;

/// The environment variable of the kill tests (`tests/tests/kill.rs`): **test only**, and read
/// only by builds with the `test-hooks` feature (the end-to-end tests' build; a release build of
/// the binary never reads it). When it holds a number of milliseconds, every command that commits
/// outputs (`write_atomic`, `write_all_atomic`, the run folders of `plan` and `simulate`) says
/// `test hook: pausing before the commit` on stderr and sleeps that long right before it moves
/// its outputs into place, so that a test can kill it at exactly that moment. Unset, nothing
/// changes.
pub const TEST_PAUSE_BEFORE_COMMIT: &str = "FERROCAL_TEST_PAUSE_BEFORE_COMMIT";

/// The test-only pause of [`TEST_PAUSE_BEFORE_COMMIT`]; does nothing when the variable is unset
/// or not a number, and nothing at all without the `test-hooks` feature.
#[cfg(feature = "test-hooks")]
pub fn pause_before_commit() {
    if let Some(ms) = std::env::var(TEST_PAUSE_BEFORE_COMMIT).ok().and_then(|v| v.trim().parse::<u64>().ok()) {
        eprintln!("test hook: pausing before the commit ({ms} ms)");
        std::thread::sleep(std::time::Duration::from_millis(ms));
    }
}

/// Without the `test-hooks` feature the pause is compiled out.
#[cfg(not(feature = "test-hooks"))]
#[inline(always)]
pub fn pause_before_commit() {}
