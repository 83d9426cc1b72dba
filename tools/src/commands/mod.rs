//! One module per command; each is a library call plus I/O.

pub mod calibrate;
pub mod camera;
pub mod corner_study;
pub mod correct;
mod demo;
pub mod detect;
pub mod diagnose;
mod doctor;
pub mod dynamics;
pub mod handeye;
pub mod motion;
pub mod plan;
pub mod recording;
mod robot;
pub mod simulate;
pub mod stiffness;

use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Result;
use ferrocal_report::verdict::VerdictSettings;
use ferrocal_report::Report;

use crate::cli::{Cli, Command};

/// Runs the parsed command: the thresholds file is read first (a bad one stops before any
/// work), then the command, which ends with its verdict (`ferrocal_report::verdict`).
pub fn run(cli: Cli) -> Result<ExitCode> {
    let vs = &VerdictSettings::new(cli.thresholds.as_deref(), cli.keep)?;
    match cli.command {
        Command::Demo(a) => demo::run(&a, vs),
        Command::Doctor => doctor::run(vs),
        Command::Robot(c) => robot::run(c, vs),
        Command::Detect(a) => detect::run(&a, vs),
        Command::CornerStudy(a) => corner_study::run(&a, vs),
        Command::Camera(c) => camera::run(c, vs),
        Command::Simulate(a) => simulate::run_simulate(&a, vs),
        Command::Import(a) => simulate::run_import(&a, vs),
        Command::Measure(a) => simulate::run_measure(&a, vs),
        Command::Correct(a) => correct::run(&a, vs),
        Command::Plan(a) => plan::run(&a, vs),
        Command::Calibrate(a) => calibrate::run_calibrate(&a, vs),
        Command::Diagnose(a) => diagnose::run(&a, vs),
        Command::Handeye(a) => handeye::run(&a, vs),
        Command::Evaluate(a) => calibrate::run_evaluate(&a, vs),
        Command::Export(a) => calibrate::run_export(&a, vs),
        Command::Dynamics(a) => dynamics::run(&a, vs),
        Command::Stiffness(a) => stiffness::run(&a, vs),
        Command::Motion(a) => motion::run(&a, vs),
    }
}

/// Ends a study started at `t0`: how long on stdout, then its report folder `out` written
/// with the verdict from the report's checks (a failed check exits 2).
pub fn finish_study(report: Report, out: &Path, t0: Instant, vs: &VerdictSettings) -> Result<ExitCode> {
    ferrocal_report::say!("ran in {:.1} s", t0.elapsed().as_secs_f64());
    Ok(ferrocal_report::verdict::conclude_report(vs, report, out, "study")?)
}
