//! File formats of the command-line tools that are not measurement tables (those are in
//! [`crate::import`]).
//!
//! - [`plan_file`]: the plan file of `ferrocal plan` (TOML) and the measuring device it
//!   describes, the planned poses as a cell file's `[plan]` table.
//! - [`dynamics_tables`]: the leg and force streams and the quasi-static pose tables of
//!   `ferrocal dynamics`.
//! - [`deflections`]: the deflection table of `ferrocal stiffness`.

pub mod deflections;
pub mod dynamics_tables;
pub mod plan_file;
