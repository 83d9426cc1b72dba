//! `ferrocal robot ...`: model information, kinematics and safety checks, each ending with its
//! verdict (`docs/verdicts.md`).

use ferrocal_report::say;
use std::process::ExitCode;

use anyhow::{Context, Result};
use ferrocal_calib::verdict::commands::{self as verdict, IkOutcome};
use ferrocal_datasets::kinematics::{
    check_safety, format_joints, forward_within_limits, limit_margins, mid_limits, parse_joints, parse_pose, solve_ik,
    unlimited_joints,
};
use ferrocal_report::robot::{info_json, info_lines, pose_lines};
use ferrocal_report::verdict::VerdictSettings;
use ferrocal_robot::{Kinematics, Parameterized, RobotModel};

use crate::cli::RobotCommand;

pub fn run(cmd: RobotCommand, vs: &VerdictSettings) -> Result<ExitCode> {
    let t = &vs.thresholds;
    match cmd {
        RobotCommand::Info { robot, json } => {
            let model = load(&robot)?;
            info_lines(&model).iter().for_each(|l| say!("{l}"));
            let v = verdict::robot_info(model.dof(), model.parameters().len(), &unlimited_joints(&model));
            ferrocal_report::Outputs::verdict_json(json.as_deref(), || info_json(&model), &v)?.write()?;
            Ok(vs.conclude(&v))
        }
        RobotCommand::Fk { robot, joints, tip } => {
            let model = match &tip {
                None => load(&robot)?,
                Some(tip) => RobotModel::Serial(
                    ferrocal_robot::serial::parse_urdf_tree(std::path::Path::new(&robot), std::slice::from_ref(tip))
                        .with_context(|| format!("cannot load robot model '{robot}' with the tip '{tip}'"))?,
                ),
            };
            let q = parse_joints(&joints, &model)?;
            pose_lines(&forward_within_limits(&model, &q, &joints)?).iter().for_each(|l| say!("{l}"));
            Ok(vs.conclude(&verdict::robot_fk(t, q.len(), &limit_margins(&model, &q))))
        }
        RobotCommand::Ik { robot, pose, seed } => {
            let model = load(&robot)?;
            let target = parse_pose(&pose)?;
            let seed = seed.map(|s| parse_joints(&s, &model)).transpose()?.unwrap_or_else(|| mid_limits(&model));
            let (q, outcome) = solve_ik(&model, &target, &seed).context("inverse kinematics")?;
            match (&q, &outcome) {
                (Some(q), _) => say!("{}", format_joints(q, &model)),
                (None, IkOutcome::NoSolution(e)) => eprintln!("ferrocal: inverse kinematics: {e}"),
                (None, _) => {}
            }
            Ok(vs.conclude(&verdict::robot_ik(t, &outcome)))
        }
        RobotCommand::Check { robot, safety, joints, to } => {
            let model = load(&robot)?;
            let violations = std::cell::Cell::new(0usize);
            let ok = check_safety(&model, &safety, &joints, to.as_deref(), &|l| {
                violations.set(violations.get() + 1);
                say!("{l}");
            })?;
            say!("{}", if ok { "safe" } else { "NOT safe" });
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
