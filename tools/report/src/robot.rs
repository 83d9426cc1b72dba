//! `ferrocal robot`'s presentation: a model's joints, limits and parameters as terminal lines
//! ([`info_lines`]) and as JSON ([`info_json`]), and a tool pose as terminal lines
//! ([`pose_lines`]).

use ferrocal_robot::{Kinematics, Parameterized, RobotModel};
use nalgebra::Isometry3;
use serde_json::{json, Value};

/// The terminal lines of `ferrocal robot info`: the model, every joint with its kind and
/// limits, every parameter with its value and unit.
pub fn info_lines(model: &RobotModel) -> Vec<String> {
    let mut out = vec![format!("model {} ({} joints, mobility {:?})", model.name(), model.dof(), model.mobility())];
    for (i, ((n, k), l)) in model.joint_names().iter().zip(model.joint_kinds()).zip(model.joint_limits()).enumerate() {
        out.push(format!("  joint {} {n:<16} {k:?} limits [{}, {}]", i + 1, l.lower, l.upper));
    }
    let params = model.parameters();
    out.push(format!("{} parameters:", params.len()));
    out.extend(params.iter().map(|p| format!("  {:<28} {:>14.9} {}", p.name, p.value, p.unit.symbol())));
    out
}

/// The JSON of `ferrocal robot info --json`: name, joints, kinds, limits, parameters.
pub fn info_json(model: &RobotModel) -> Value {
    json!({
        "name": model.name(),
        "joints": model.joint_names(),
        "kinds": model.joint_kinds(),
        "limits": model.joint_limits(),
        "parameters": model.parameters(),
    })
}

/// The terminal lines of a tool pose: the position in mm, the rotation vector in degrees, the
/// quaternion.
pub fn pose_lines(t: &Isometry3<f64>) -> [String; 3] {
    let p = t.translation.vector * 1e3;
    let r = t.rotation.scaled_axis().map(f64::to_degrees);
    let q = t.rotation.quaternion();
    [
        format!("position_mm {:.6} {:.6} {:.6}", p.x, p.y, p.z),
        format!("rotvec_deg  {:.6} {:.6} {:.6}", r.x, r.y, r.z),
        format!("quat_wxyz   {:.9} {:.9} {:.9} {:.9}", q.w, q.i, q.j, q.k),
    ]
}
