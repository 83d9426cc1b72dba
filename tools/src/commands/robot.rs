//! `ferrocal robot ...`: model information, kinematics and safety checks.

use std::process::ExitCode;

use anyhow::{Context, Result};
use ferrocal_datasets::kinematics::{format_joints, forward_within_limits, mid_limits, parse_joints, parse_pose};
use ferrocal_report::robot::{info_json, info_lines, pose_lines};
use ferrocal_robot::safety::{SafetyChecker, SafetyConfig};
use ferrocal_robot::{Kinematics, RobotModel};

use crate::cli::RobotCommand;

pub fn run(cmd: RobotCommand) -> Result<ExitCode> {
    match cmd {
        RobotCommand::Info { robot, json } => {
            let model = load(&robot)?;
            info_lines(&model).iter().for_each(|l| println!("{l}"));
            if let Some(path) = json {
                crate::report::write_atomic(&path, serde_json::to_string_pretty(&info_json(&model))?.as_bytes())?;
            }
            Ok(ExitCode::SUCCESS)
        }
        RobotCommand::Fk { robot, joints } => {
            let model = load(&robot)?;
            let q = parse_joints(&joints, &model)?;
            pose_lines(&forward_within_limits(&model, &q, &joints)?).iter().for_each(|l| println!("{l}"));
            Ok(ExitCode::SUCCESS)
        }
        RobotCommand::Ik { robot, pose, seed } => {
            let model = load(&robot)?;
            let target = parse_pose(&pose)?;
            let seed = match seed {
                Some(s) => parse_joints(&s, &model)?,
                None => mid_limits(&model),
            };
            let q = model.inverse(&target, &seed).context("inverse kinematics")?;
            println!("{}", format_joints(&q, &model));
            Ok(ExitCode::SUCCESS)
        }
        RobotCommand::Check { robot, safety, joints, to } => {
            let model = load(&robot)?;
            let cfg = SafetyConfig::from_file(&safety)?;
            let q = parse_joints(&joints, &model)?;
            let checker = SafetyChecker::new(&model, cfg)?;
            let v = checker.violations(&q, 0.0);
            for x in &v {
                println!("unsafe: {x}");
            }
            let mut ok = v.is_empty();
            if let Some(to) = to {
                let qb = parse_joints(&to, &model)?;
                if let Err((s, x)) = checker.check_move(&q, &qb) {
                    println!("unsafe move at {:.1} % of the way: {x}", s * 100.0);
                    ok = false;
                }
            }
            println!("{}", if ok { "safe" } else { "NOT safe" });
            Ok(if ok { ExitCode::SUCCESS } else { ExitCode::from(3) })
        }
    }
}

fn load(spec: &str) -> Result<RobotModel> {
    RobotModel::load(spec).with_context(|| format!("cannot load robot model '{spec}'"))
}
