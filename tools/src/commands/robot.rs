//! `ferrocal robot ...`: model information, kinematics and safety checks, each ending with its
//! verdict (`docs/verdicts.md`).

use std::process::ExitCode;

use anyhow::{Context, Result};
use ferrocal_calib::verdict::commands::{self as verdict, IkOutcome};
use ferrocal_datasets::kinematics::{
    check_safety, format_joints, forward_within_limits, mid_limits, parse_joints, parse_pose,
};
use ferrocal_report::robot::{info_json, info_lines, pose_lines};
use ferrocal_report::verdict::{add_verdict, VerdictSettings};
use ferrocal_robot::{Kinematics, Parameterized, RobotError, RobotModel};

use crate::cli::RobotCommand;

pub fn run(cmd: RobotCommand, vs: &VerdictSettings) -> Result<ExitCode> {
    let t = &vs.thresholds;
    match cmd {
        RobotCommand::Info { robot, json } => {
            let model = load(&robot)?;
            info_lines(&model).iter().for_each(|l| println!("{l}"));
            let unlimited: Vec<String> = model
                .joint_names()
                .into_iter()
                .zip(model.joint_limits())
                .filter(|(_, l)| !(l.lower.is_finite() && l.upper.is_finite()))
                .map(|(n, _)| n)
                .collect();
            let v = verdict::robot_info(model.dof(), model.parameters().len(), &unlimited);
            if let Some(path) = json {
                let mut j = info_json(&model);
                add_verdict(&mut j, &v);
                crate::report::write_atomic(&path, serde_json::to_string_pretty(&j)?.as_bytes())?;
            }
            Ok(vs.conclude(&v))
        }
        RobotCommand::Fk { robot, joints } => {
            let model = load(&robot)?;
            let q = parse_joints(&joints, &model)?;
            pose_lines(&forward_within_limits(&model, &q, &joints)?).iter().for_each(|l| println!("{l}"));
            // The distance of every limited joint from its nearer limit, a fraction of its range.
            let margins: Vec<(String, f64)> = model
                .joint_names()
                .into_iter()
                .zip(model.joint_limits())
                .zip(&q)
                .filter(|((_, l), _)| l.lower.is_finite() && l.upper.is_finite())
                .map(|((n, l), v)| {
                    let range = l.upper - l.lower;
                    let m = if range > 0.0 { (v - l.lower).min(l.upper - v) / range } else { 0.0 };
                    (n, m)
                })
                .collect();
            Ok(vs.conclude(&verdict::robot_fk(t, q.len(), &margins)))
        }
        RobotCommand::Ik { robot, pose, seed } => {
            let model = load(&robot)?;
            let target = parse_pose(&pose)?;
            let seed = seed.map(|s| parse_joints(&s, &model)).transpose()?.unwrap_or_else(|| mid_limits(&model));
            let outcome = match model.inverse(&target, &seed) {
                Ok(q) => {
                    println!("{}", format_joints(&q, &model));
                    let reached = model.forward(&q).context("forward kinematics of the solution")?;
                    IkOutcome::Solved {
                        position_mm: (reached.translation.vector - target.translation.vector).norm() * 1e3,
                        orientation_deg: reached.rotation.angle_to(&target.rotation).to_degrees(),
                    }
                }
                Err(
                    e @ (RobotError::IkNotConverged { .. }
                    | RobotError::Unreachable { .. }
                    | RobotError::OutsideLimits { .. }),
                ) => {
                    eprintln!("ferrocal: inverse kinematics: {e}");
                    IkOutcome::NoSolution(e.to_string())
                }
                Err(e) => return Err(anyhow::Error::new(e).context("inverse kinematics")),
            };
            Ok(vs.conclude(&verdict::robot_ik(t, &outcome)))
        }
        RobotCommand::Check { robot, safety, joints, to } => {
            let model = load(&robot)?;
            let violations = std::cell::Cell::new(0usize);
            let ok = check_safety(&model, &safety, &joints, to.as_deref(), &|l| {
                violations.set(violations.get() + 1);
                println!("{l}");
            })?;
            println!("{}", if ok { "safe" } else { "NOT safe" });
            // The exit status is the answer (3: not safe), with or without --keep: a safety
            // check has no result to keep.
            let v = verdict::robot_check(if ok { 0 } else { violations.get().max(1) });
            println!("{}", v.line());
            Ok(if ok { ExitCode::SUCCESS } else { ExitCode::from(3) })
        }
    }
}

fn load(spec: &str) -> Result<RobotModel> {
    RobotModel::load(spec).with_context(|| format!("cannot load robot model '{spec}'"))
}
