//! `ferrocal robot ...`: model information, kinematics and safety checks.

use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use ferrocal_robot::safety::{SafetyChecker, SafetyConfig};
use ferrocal_robot::{Kinematics, Parameterized, RobotModel};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::{format_joints, parse_joints};
use crate::cli::RobotCommand;

pub fn run(cmd: RobotCommand) -> Result<ExitCode> {
    match cmd {
        RobotCommand::Info { robot, json } => info(&robot, json.as_deref()),
        RobotCommand::Fk { robot, joints } => {
            let model = load(&robot)?;
            let q = parse_joints(&joints, &model)?;
            // Outside the limits is refused by name (far outside, the pose is meaningless or
            // not even finite).
            let kinds = model.joint_kinds();
            for (i, (v, l)) in q.iter().zip(model.joint_limits()).enumerate() {
                if !l.contains(*v, 0.0) {
                    bail!(
                        "joint {}: {} is outside the limits [{}, {}] of '{}'",
                        i + 1,
                        user_value(*v, kinds[i]),
                        user_value(l.lower, kinds[i]),
                        user_value(l.upper, kinds[i]),
                        model.name()
                    );
                }
            }
            let t = model.forward(&q).context("forward kinematics")?;
            if !(t.translation.vector.iter().all(|v| v.is_finite()) && t.rotation.coords.iter().all(|v| v.is_finite()))
            {
                bail!("forward kinematics gave a non-finite pose (joints {joints})");
            }
            print_pose(&t);
            Ok(ExitCode::SUCCESS)
        }
        RobotCommand::Ik { robot, pose, seed } => {
            let model = load(&robot)?;
            let target = parse_pose(&pose)?;
            let seed = match seed {
                Some(s) => parse_joints(&s, &model)?,
                None => model
                    .joint_limits()
                    .iter()
                    .map(|l| if l.lower.is_finite() && l.upper.is_finite() { 0.5 * (l.lower + l.upper) } else { 0.0 })
                    .collect(),
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

fn parse_pose(text: &str) -> Result<Isometry3<f64>> {
    let v: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>().with_context(|| format!("pose: '{s}' is not a number")))
        .collect::<Result<_>>()?;
    if v.len() != 3 && v.len() != 6 {
        bail!("pose needs 3 (x,y,z mm) or 6 (plus rx,ry,rz deg) numbers, got {}", v.len());
    }
    let rot = if v.len() == 6 {
        UnitQuaternion::from_scaled_axis(Vector3::new(v[3], v[4], v[5]).map(f64::to_radians))
    } else {
        UnitQuaternion::identity()
    };
    Ok(Isometry3::from_parts(Translation3::new(v[0] * 1e-3, v[1] * 1e-3, v[2] * 1e-3), rot))
}

fn print_pose(t: &Isometry3<f64>) {
    let p = t.translation.vector * 1e3;
    let r = t.rotation.scaled_axis().map(f64::to_degrees);
    let q = t.rotation.quaternion();
    println!("position_mm {:.6} {:.6} {:.6}", p.x, p.y, p.z);
    println!("rotvec_deg  {:.6} {:.6} {:.6}", r.x, r.y, r.z);
    println!("quat_wxyz   {:.9} {:.9} {:.9} {:.9}", q.w, q.i, q.j, q.k);
}

fn info(spec: &str, json: Option<&std::path::Path>) -> Result<ExitCode> {
    let model = load(spec)?;
    println!("model {} ({} joints, mobility {:?})", model.name(), model.dof(), model.mobility());
    for (i, ((n, k), l)) in model.joint_names().iter().zip(model.joint_kinds()).zip(model.joint_limits()).enumerate() {
        println!("  joint {} {n:<16} {k:?} limits [{}, {}]", i + 1, l.lower, l.upper);
    }
    let params = model.parameters();
    println!("{} parameters:", params.len());
    for p in &params {
        println!("  {:<28} {:>14.9} {}", p.name, p.value, p.unit.symbol());
    }
    if let Some(path) = json {
        let v = serde_json::json!({
            "name": model.name(),
            "joints": model.joint_names(),
            "kinds": model.joint_kinds(),
            "limits": model.joint_limits(),
            "parameters": params,
        });
        crate::report::write_atomic(path, serde_json::to_string_pretty(&v)?.as_bytes())?;
    }
    Ok(ExitCode::SUCCESS)
}

/// A joint value or limit in user units (degrees or millimetres).
fn user_value(v: f64, kind: ferrocal_robot::JointKind) -> String {
    let (v, unit) = match kind {
        ferrocal_robot::JointKind::Revolute => (v.to_degrees(), "deg"),
        ferrocal_robot::JointKind::Prismatic => (v * 1e3, "mm"),
    };
    if v.abs() < 1e6 {
        format!("{v:.3} {unit}")
    } else {
        format!("{v:.3e} {unit}")
    }
}
