//! All integration tests of this crate in one binary: one link instead of one per file,
//! which keeps the build small and fast (each file is a module, named as before).

mod mimic;
mod parallel_errors;
mod parallel_kinematics;
mod parallel_toml;
mod safety;
mod serial;
mod stiffness_vjm;
mod ur5_targets;
mod workspace_devices;
mod workspace_programs;
mod workspace_safety;
