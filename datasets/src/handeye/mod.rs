//! Hand-eye recordings: the poses table of `ferrocal handeye` ([`poses`]), the importer of
//! ROS-Industrial industrial_calibration sets ([`ic`]), images and poses to a recording with the
//! camera files `--intrinsics` reads ([`recording`]), simulated recordings with the Monte
//! Carlo study of the hand-eye covariance ([`sim`]), and the study of the camera-based robot
//! calibration (two-step and joint adjustment) against a tracker's ([`joint_study`]) and with a
//! rig of cameras ([`rig_study`]), `handeye` with a rig of cameras ([`rig_run`]) and its
//! simulated recordings ([`rig_record`]), and the real positioner's weighting and baselines
//! ([`positioner`]).

pub mod ic;
pub mod ic_kinematic;
pub mod joint_record;
pub mod joint_study;
pub mod motion_check;
pub mod poses;
pub mod positioner;
pub mod recording;
pub mod rig_record;
pub mod rig_run;
pub mod rig_study;
pub mod sim;
pub mod workflow;

pub use ic::{import_ic_handeye, read_ic_set, IcSet};
pub use ic_kinematic::{ic_positioner_nominal, read_ic_kinematic};
pub use motion_check::{check_motion, FlaggedView, MotionCheck};
pub use poses::{read_handeye_poses, read_poses_header, PoseRow, PosesHeader, PosesTable, RobotReading};
pub use recording::{load_recording, read_camera_file, Skipped};
pub use rig_record::{rendered_ur5_rig, write_rig_recording, RigRecording};
pub use rig_run::{
    read_rig_extrinsics, rig_file_differences, rig_transform, RigCameraInput, RigFileDifference, RigFit, RigInput,
};
pub use sim::{
    coverage_study, simulate_hand_eye, write_rendered_recording, CoverageSummary, HandEyeSimConfig, HandEyeTruth,
    RenderedRecording, StudyMode,
};
pub use workflow::{
    check_simulated_images, huber_sigmas_of_loss, run_inputs, write_simulated_recording, HandEyeFit, HandEyeInput,
    HandEyeRunOptions,
};
