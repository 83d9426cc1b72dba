//! All integration tests of this crate in one binary: one link instead of one per file,
//! which keeps the build small and fast (each file is a module, named as before).

#[path = "../../vision/tests/calib_support/mod.rs"]
mod calib_support;
mod calibration_study;
mod camera_print_scale;
mod closed_loop;
mod demo_checks;
mod diagnose_real_like;
mod diagnose_sim;
mod diagnose_support;
mod dynamics_design;
mod dynamics_models;
mod dynamics_tables;
mod dynamics_trajectories;
mod force_diagnose;
mod handeye_joint;
mod handeye_physics;
mod handeye_rig;
mod handeye_sim;
mod import_images;
mod import_measurements;
mod import_ur10;
mod import_ur5;
mod input_properties;
mod measure_recording;
mod motion_study;
mod plan_l1;
mod plan_support;
mod render_targets;
mod sim_calibration;
mod sim_cell;
mod sim_covariance;
mod sim_end_to_end;
mod stiffness_arm;
mod stiffness_diagnose;
mod stiffness_tables;
mod ur5_parameters;
mod vision_render_calibration;
