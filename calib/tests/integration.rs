//! All integration tests of this crate in one binary: one link instead of one per file,
//! which keeps the build small and fast (each file is a module, named as before).

mod camera_diagnose;
mod design_excitation;
mod design_selection;
mod engine_diagnose;
mod stereo_diagnose;
mod stiffness_onelink;
