//! All integration tests of this crate in one binary: one link instead of one per file,
//! which keeps the build small and fast (each file is a module, named as before).

mod calib_adjust;
mod calib_bad_input;
mod calib_opencv_stereo;
mod calib_simulated;
mod calib_support;
mod detect_batch;
mod detect_real;
mod detect_reallike;
mod detect_synthetic;
mod pose_pnp;
mod pose_stereo_cell;
#[path = "support/reallike.rs"]
mod reallike;
#[path = "support/synth.rs"]
mod synth;
mod targets_real;
