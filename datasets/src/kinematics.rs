//! The `robot` command's workflows: joint values in user units (degrees for revolute joints,
//! millimetres for prismatic ones) read ([`parse_joints`]) and written ([`format_joints`]), a
//! tool pose from text ([`parse_pose`]), forward kinematics refused outside the joint limits
//! ([`forward_within_limits`]), the start of inverse kinematics ([`mid_limits`]) and the safety
//! check of joint values and a move ([`check_safety`]).

use std::path::Path;

use ferrocal_robot::safety::{SafetyChecker, SafetyConfig};
use ferrocal_robot::{JointKind, Kinematics, RobotModel};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use crate::error::{DatasetError, Result};

/// Parses comma-separated joint values given in user units (degrees for revolute joints,
/// millimetres for prismatic ones) into SI values for `model`.
pub fn parse_joints(text: &str, model: &dyn Kinematics) -> Result<Vec<f64>> {
    let kinds = model.joint_kinds();
    let parts: Vec<&str> = text.split(',').map(str::trim).filter(|s| !s.is_empty()).collect();
    if parts.len() != kinds.len() {
        return Err(DatasetError::Input(format!(
            "the robot has {} joints but {} values were given ('{text}')",
            kinds.len(),
            parts.len()
        )));
    }
    parts
        .iter()
        .zip(&kinds)
        .enumerate()
        .map(|(i, (p, k))| {
            let v: f64 =
                p.parse().map_err(|_| DatasetError::Input(format!("joint {}: '{p}' is not a number", i + 1)))?;
            if !v.is_finite() {
                return Err(DatasetError::Input(format!("joint {}: '{p}' is not finite", i + 1)));
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

/// A joint value or limit in user units (degrees or millimetres), with the unit.
pub fn user_value(v: f64, kind: JointKind) -> String {
    let (v, unit) = match kind {
        JointKind::Revolute => (v.to_degrees(), "deg"),
        JointKind::Prismatic => (v * 1e3, "mm"),
    };
    if v.abs() < 1e6 {
        format!("{v:.3} {unit}")
    } else {
        format!("{v:.3e} {unit}")
    }
}

/// A tool pose from `x,y,z` in mm, optionally followed by a rotation vector `rx,ry,rz` in
/// degrees.
pub fn parse_pose(text: &str) -> Result<Isometry3<f64>> {
    let v: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>().map_err(|e| DatasetError::Input(format!("pose: '{s}' is not a number: {e}"))))
        .collect::<Result<_>>()?;
    if v.len() != 3 && v.len() != 6 {
        return Err(DatasetError::Input(format!(
            "pose needs 3 (x,y,z mm) or 6 (plus rx,ry,rz deg) numbers, got {}",
            v.len()
        )));
    }
    let rot = if v.len() == 6 {
        UnitQuaternion::from_scaled_axis(Vector3::new(v[3], v[4], v[5]).map(f64::to_radians))
    } else {
        UnitQuaternion::identity()
    };
    Ok(Isometry3::from_parts(Translation3::new(v[0] * 1e-3, v[1] * 1e-3, v[2] * 1e-3), rot))
}

/// The tool pose of `model` at the joint values `q` (SI; `text` as given, for the message):
/// values outside the limits are refused by name (far outside, the pose is meaningless or not
/// even finite), and so is a pose that is not finite.
pub fn forward_within_limits(model: &RobotModel, q: &[f64], text: &str) -> Result<Isometry3<f64>> {
    let kinds = model.joint_kinds();
    for (i, (v, l)) in q.iter().zip(model.joint_limits()).enumerate() {
        if !l.contains(*v, 0.0) {
            return Err(DatasetError::Input(format!(
                "joint {}: {} is outside the limits [{}, {}] of '{}'",
                i + 1,
                user_value(*v, kinds[i]),
                user_value(l.lower, kinds[i]),
                user_value(l.upper, kinds[i]),
                model.name()
            )));
        }
    }
    let t = model.forward(q).map_err(|e| DatasetError::from(e).context("forward kinematics"))?;
    if !(t.translation.vector.iter().all(|v| v.is_finite()) && t.rotation.coords.iter().all(|v| v.is_finite())) {
        return Err(DatasetError::Input(format!("forward kinematics gave a non-finite pose (joints {text})")));
    }
    Ok(t)
}

/// The middle of every joint's limits (0 where a limit is infinite): the start of inverse
/// kinematics without a seed.
pub fn mid_limits(model: &RobotModel) -> Vec<f64> {
    model
        .joint_limits()
        .iter()
        .map(|l| if l.lower.is_finite() && l.upper.is_finite() { 0.5 * (l.lower + l.upper) } else { 0.0 })
        .collect()
}

/// Checks the joint values `joints` (user units) of `model` against the safety configuration
/// file `safety`, and with `to` the straight joint-space move to those joint values as
/// well. Every violation is given to `report` as it is found (`unsafe: ...`, `unsafe move at
/// ...`); true when there is none.
pub fn check_safety(
    model: &RobotModel,
    safety: &Path,
    joints: &str,
    to: Option<&str>,
    report: &dyn Fn(&str),
) -> Result<bool> {
    let cfg = SafetyConfig::from_file(safety)?;
    let q = parse_joints(joints, model)?;
    let checker = SafetyChecker::new(model, cfg)?;
    let v = checker.violations(&q, 0.0);
    for x in &v {
        report(&format!("unsafe: {x}"));
    }
    let mut ok = v.is_empty();
    if let Some(to) = to {
        let qb = parse_joints(to, model)?;
        if let Err((s, x)) = checker.check_move(&q, &qb) {
            report(&format!("unsafe move at {:.1} % of the way: {x}", s * 100.0));
            ok = false;
        }
    }
    Ok(ok)
}

/// The names of the joints without both limits (which `robot fk`, `plan` and the safety checks
/// cannot hold to a range).
pub fn unlimited_joints(model: &RobotModel) -> Vec<String> {
    model
        .joint_names()
        .into_iter()
        .zip(model.joint_limits())
        .filter(|(_, l)| !(l.lower.is_finite() && l.upper.is_finite()))
        .map(|(n, _)| n)
        .collect()
}

/// The distance of every limited joint of `q` from its nearer limit, a fraction of its range
/// (joint name, fraction; 0 for a joint whose range is empty).
pub fn limit_margins(model: &RobotModel, q: &[f64]) -> Vec<(String, f64)> {
    model
        .joint_names()
        .into_iter()
        .zip(model.joint_limits())
        .zip(q)
        .filter(|((_, l), _)| l.lower.is_finite() && l.upper.is_finite())
        .map(|((n, l), v)| {
            let range = l.upper - l.lower;
            (n, if range > 0.0 { (v - l.lower).min(l.upper - v) / range } else { 0.0 })
        })
        .collect()
}

/// Inverse kinematics of `target` from `seed`: the joints and how closely they reach it, or no
/// solution with the reason (not converged, unreachable, outside the limits); other errors are
/// errors.
pub fn solve_ik(
    model: &RobotModel,
    target: &Isometry3<f64>,
    seed: &[f64],
) -> Result<(Option<Vec<f64>>, ferrocal_calib::verdict::commands::IkOutcome)> {
    use ferrocal_calib::verdict::commands::IkOutcome;
    use ferrocal_robot::RobotError;
    match model.inverse(target, seed) {
        Ok(q) => {
            let reached = model.forward(&q)?;
            let outcome = IkOutcome::Solved {
                position_mm: (reached.translation.vector - target.translation.vector).norm() * 1e3,
                orientation_deg: reached.rotation.angle_to(&target.rotation).to_degrees(),
            };
            Ok((Some(q), outcome))
        }
        Err(
            e @ (RobotError::IkNotConverged { .. } | RobotError::Unreachable { .. } | RobotError::OutsideLimits { .. }),
        ) => Ok((None, IkOutcome::NoSolution(e.to_string()))),
        Err(e) => Err(e.into()),
    }
}
