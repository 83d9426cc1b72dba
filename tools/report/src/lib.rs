//! Reports of ferrocal: self-contained HTML with SVG plots and a JSON twin ([`report`], [`plot`]),
//! and the report sections of every command and study, built from the libraries' results.
//!
//! A section carries a [`Check`](ferrocal_calib::check::Check) when it has one: only a passed
//! check counts as passing, and a skipped or reported section says so in the HTML and the JSON.
//!
//! - [`calibrate`]: kinematic calibration (`ferrocal calibrate`, the demo);
//! - [`camera`]: the JSON and output files of `ferrocal camera calibrate` and `stereo`;
//! - [`corner_study`]: the Markdown table of `ferrocal corner-study`;
//! - [`handeye`]: `ferrocal handeye` (arguments, run, JSON, HTML) and its Monte Carlo study;
//! - [`plan`]: the measurement plan (`ferrocal plan`), its flow and its report;
//! - [`dynamics`]: force-sensor models and hexapod dynamics (`ferrocal dynamics study`);
//! - [`stiffness`]: elastostatic identification (`ferrocal stiffness study` and `identify`);
//! - [`diagnose_stereo`]: the stereo variant of `ferrocal diagnose` (run, JSON, HTML, summary);
//! - [`demo`]: the sections of `ferrocal demo`;
//! - [`robot`]: `ferrocal robot info` and a tool pose, as terminal lines and JSON;
//! - [`outputs`]: a command's output files, composed first and written together;
//! - [`verdict`]: how every command ends (the verdict line, its JSON, the exit status);
//! - [`term`]: how much the terminal shows (`--quiet`, `--verbose`).
#![deny(missing_docs)]

pub mod calibrate;
pub mod camera;
pub mod camera_report;
pub mod compensate;
pub mod corner_study;
pub mod demo;
pub mod diagnose;
pub mod diagnose_stereo;
pub mod dynamics;
pub mod error;
pub mod handeye;
pub mod motion;
pub mod motion_cell;
pub mod outputs;
pub mod plan;
pub mod plot;
pub mod progress;
pub mod recording;
pub mod report;
pub mod robot;
pub mod stiffness;
pub mod term;
pub mod verdict;

pub use outputs::Outputs;
pub use report::{
    check_outputs, inline_png, write_all_atomic, write_atomic, Block, Provenance, Report, Section, StagedFolder,
};
