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
mod verdicts;

use std::process::ExitCode;

use anyhow::{bail, Result};
use ferrocal_report::verdict::VerdictSettings;
use ferrocal_robot::{JointKind, Kinematics};

use crate::cli::{Cli, Command};

/// Runs the parsed command: the thresholds file is read first (a bad one stops before any
/// work), then the command, which ends with its verdict (`ferrocal_report::verdict`).
pub fn run(cli: Cli) -> Result<ExitCode> {
    let vs = &VerdictSettings::new(cli.thresholds.as_deref(), cli.keep)?;
    match cli.command {
        Command::Demo(a) => demo::run(&a, vs),
        Command::Doctor => doctor::run(vs),
        Command::Robot(c) => robot::run(c),
        Command::Detect(a) => detect::run(&a, vs),
        Command::CornerStudy(a) => corner_study::run(&a, vs),
        Command::Camera(c) => camera::run(c, vs),
        Command::Simulate(a) => simulate::run_simulate(&a),
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

/// Parses comma-separated joint values given in user units (degrees for revolute joints,
/// millimetres for prismatic ones) into SI values for `model`.
pub fn parse_joints(text: &str, model: &dyn Kinematics) -> Result<Vec<f64>> {
    let kinds = model.joint_kinds();
    let parts: Vec<&str> = text.split(',').map(str::trim).filter(|s| !s.is_empty()).collect();
    if parts.len() != kinds.len() {
        bail!("the robot has {} joints but {} values were given ('{text}')", kinds.len(), parts.len());
    }
    parts
        .iter()
        .zip(&kinds)
        .enumerate()
        .map(|(i, (p, k))| {
            let v: f64 = p.parse().map_err(|_| anyhow::anyhow!("joint {}: '{p}' is not a number", i + 1))?;
            if !v.is_finite() {
                bail!("joint {}: '{p}' is not finite", i + 1);
            }
            Ok(match k {
                JointKind::Revolute => v.to_radians(),
                JointKind::Prismatic => v * 1e-3,
            })
        })
        .collect()
}

/// Formats SI joint values in user units.
pub fn format_joints(q: &[f64], model: &dyn Kinematics) -> String {
    q.iter()
        .zip(model.joint_kinds())
        .map(|(v, k)| match k {
            JointKind::Revolute => format!("{:.6}", v.to_degrees()),
            JointKind::Prismatic => format!("{:.6}", v * 1e3),
        })
        .collect::<Vec<_>>()
        .join(",")
}
