//! All integration tests of this crate in one binary: one link instead of one per file,
//! which keeps the build small and fast (each file is a module, named as before).

mod cli;
mod compensate;
mod correct;
mod coupled;
mod effect_recipe;
mod handeye;
mod handeye_checks;
mod handeye_rig;
mod handeye_rig_in_hand;
mod hostile;
mod kill;
mod measure;
mod mistakes;
mod motion;
mod observations;
mod positioner;
mod reliability;
mod trees;
mod verdict;
