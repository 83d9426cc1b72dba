//! Writing a serial chain as URDF, and the chain's "origin form" that URDF can hold exactly.
//!
//! Every joint geometry of [`SerialChain`] (DH, modified DH, URDF origins, with the per-joint
//! correction transforms and joint zero offsets) is a fixed transform, a motion about or along
//! an axis, and another fixed transform. In the origin form each joint's fixed part is one
//! `origin(xyz, rpy)` in the previous link's frame: the previous joint's `post * Exp(correction)`
//! times this joint's `pre`, times the zero offset's motion (`motion(axis, q + offset) =
//! motion(axis, offset) * motion(axis, q)`), so that the readings stay the joint values. The
//! base goes into the first origin and the last joint's tail into the tool. Forward kinematics of
//! the origin form equal the original's to rounding (tested), and link frames (after each joint's
//! motion) are the same frames, so the inertials carry over unchanged.
//!
//! Mimic joints are written back as `<mimic>` with their multiplier and offset; the zero offsets
//! are per actuated joint, and a mimic joint's origin takes its leader's offset times the
//! multiplier (`m (q_leader + offset) + o = (m q_leader + o) + m offset`).

use std::fmt::Write;

use super::{Joint, JointGeometry, SerialChain};
use crate::error::{Result, RobotError};
use crate::geometry::Pose;
use crate::kinematics::{JointKind, Kinematics};

impl SerialChain {
    /// The same chain with every joint in URDF's origin form, the joint zero `offsets` (added to
    /// the readings, rad or m per actuated joint) folded into the origins, corrections folded,
    /// and the base in the first origin (see the module documentation).
    pub fn to_origin_form(&self, offsets: &[f64]) -> Result<SerialChain> {
        let n = self.dof();
        if self.is_tree() {
            return Err(RobotError::Invalid(format!(
                "'{}' is a tree of chains: writing it back in origin form (URDF, DH) is not supported yet; the calibration file holds its parameters",
                self.name
            )));
        }
        if offsets.len() != n {
            return Err(RobotError::Invalid(format!("{} joint offsets for a chain of {n} joints", offsets.len())));
        }
        // The offset of every joint of the chain: a mimic joint moves by its leader's offset
        // times the multiplier (its own offset stays in its `<mimic>`).
        let all = self.coupling_matrix()? * nalgebra::DVector::from_column_slice(offsets);
        let mut joints = Vec::with_capacity(self.joints.len());
        let mut carry = self.base;
        for (j, off) in self.joints.iter().zip(all.iter()) {
            let (pre, axis, post) = j.split_corrected(false);
            let axis = axis.normalize();
            let origin = carry * pre * j.motion(&axis, *off);
            let (roll, pitch, yaw) = origin.rotation.euler_angles();
            joints.push(Joint {
                name: j.name.clone(),
                kind: j.kind,
                geometry: JointGeometry::Origin {
                    xyz_m: origin.translation.vector.into(),
                    rpy_rad: [roll, pitch, yaw],
                    axis: axis.into(),
                },
                limits: j.limits,
                inertial: j.inertial.clone(),
                correction: [0.0; 6],
                mimic: j.mimic.clone(),
            });
            carry = post;
        }
        let mut out = SerialChain::new(&self.name, joints);
        out.tool = carry * self.tool;
        out.gravity_m_s2 = self.gravity_m_s2;
        Ok(out)
    }
}

/// Names of the frames that a written URDF adds around the chain.
#[derive(Clone, Debug, PartialEq)]
pub struct UrdfFrames {
    /// The root link (e.g. the measuring device's frame, `T_root_base` = `root_to_base`).
    pub root_link: String,
    /// `T_root_base`: where the robot's base sits in the root frame.
    pub root_to_base: Pose,
    /// The tip link (e.g. the measured target on the tool).
    pub tip_link: String,
}

impl Default for UrdfFrames {
    fn default() -> Self {
        Self { root_link: "world".into(), root_to_base: Pose::identity(), tip_link: "tool0".into() }
    }
}

fn xyz_rpy(t: &Pose) -> String {
    let p = t.translation.vector;
    let (r, pi, y) = t.rotation.euler_angles();
    format!("xyz=\"{} {} {}\" rpy=\"{} {} {}\"", p.x, p.y, p.z, r, pi, y)
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// The chain as a URDF document: `frames.root_link` -> (fixed) base link -> one link per joint
/// -> (fixed) `frames.tip_link`. Lengths in metres, angles in radians, numbers written with
/// enough digits to read back exactly. `comment` goes into an XML comment at the top (who wrote
/// it, from what).
pub fn to_urdf(chain: &SerialChain, offsets: &[f64], frames: &UrdfFrames, comment: &str) -> Result<String> {
    let form = chain.to_origin_form(offsets)?;
    let mut s = String::new();
    let _ = writeln!(s, "<?xml version=\"1.0\"?>");
    let _ = writeln!(s, "<!-- {} -->", comment.replace("--", "- -"));
    let _ = writeln!(s, "<robot name=\"{}\">", escape(&form.name));
    let base_link = format!("{}_base_link", form.name);
    let link = |s: &mut String, name: &str, joint: Option<&Joint>| {
        let _ = writeln!(s, "  <link name=\"{}\">", escape(name));
        if let Some(inr) = joint.and_then(|j| j.inertial.as_ref()) {
            let c = inr.com_m;
            let i = inr.inertia_kgm2;
            let _ = writeln!(s, "    <inertial>");
            let _ = writeln!(s, "      <origin xyz=\"{} {} {}\" rpy=\"0 0 0\"/>", c[0], c[1], c[2]);
            let _ = writeln!(s, "      <mass value=\"{}\"/>", inr.mass_kg);
            let _ = writeln!(
                s,
                "      <inertia ixx=\"{}\" ixy=\"{}\" ixz=\"{}\" iyy=\"{}\" iyz=\"{}\" izz=\"{}\"/>",
                i[0], i[1], i[2], i[4], i[5], i[8]
            );
            let _ = writeln!(s, "    </inertial>");
        }
        let _ = writeln!(s, "  </link>");
    };
    let fixed = |s: &mut String, name: &str, parent: &str, child: &str, t: &Pose| {
        let _ = writeln!(s, "  <joint name=\"{}\" type=\"fixed\">", escape(name));
        let _ = writeln!(s, "    <parent link=\"{}\"/>", escape(parent));
        let _ = writeln!(s, "    <child link=\"{}\"/>", escape(child));
        let _ = writeln!(s, "    <origin {}/>", xyz_rpy(t));
        let _ = writeln!(s, "  </joint>");
    };
    link(&mut s, &frames.root_link, None);
    link(&mut s, &base_link, None);
    fixed(&mut s, &format!("{}_to_base", frames.root_link), &frames.root_link, &base_link, &frames.root_to_base);
    let mut parent = base_link.clone();
    for (k, j) in form.joints.iter().enumerate() {
        let JointGeometry::Origin { xyz_m, rpy_rad, axis } = &j.geometry else {
            return Err(RobotError::Invalid("the origin form has a joint that is not in origin form".into()));
        };
        let child = format!("{}_link{}", form.name, k + 1);
        link(&mut s, &child, Some(j));
        let kind = match j.kind {
            JointKind::Revolute if j.limits.lower.is_finite() && j.limits.upper.is_finite() => "revolute",
            JointKind::Revolute => "continuous",
            JointKind::Prismatic => "prismatic",
        };
        let _ = writeln!(s, "  <joint name=\"{}\" type=\"{kind}\">", escape(&j.name));
        let _ = writeln!(s, "    <parent link=\"{}\"/>", escape(&parent));
        let _ = writeln!(s, "    <child link=\"{}\"/>", escape(&child));
        let _ = writeln!(
            s,
            "    <origin xyz=\"{} {} {}\" rpy=\"{} {} {}\"/>",
            xyz_m[0], xyz_m[1], xyz_m[2], rpy_rad[0], rpy_rad[1], rpy_rad[2]
        );
        let _ = writeln!(s, "    <axis xyz=\"{} {} {}\"/>", axis[0], axis[1], axis[2]);
        if let Some(m) = &j.mimic {
            let _ = writeln!(
                s,
                "    <mimic joint=\"{}\" multiplier=\"{}\" offset=\"{}\"/>",
                escape(&m.leader),
                m.multiplier,
                m.offset
            );
        }
        if kind != "continuous" {
            let (lo, hi) = (j.limits.lower, j.limits.upper);
            let (lo, hi) = if lo.is_finite() && hi.is_finite() { (lo, hi) } else { (-1e3, 1e3) };
            let _ = writeln!(s, "    <limit lower=\"{lo}\" upper=\"{hi}\" effort=\"0\" velocity=\"0\"/>");
        }
        let _ = writeln!(s, "  </joint>");
        parent = child;
    }
    link(&mut s, &frames.tip_link, None);
    fixed(&mut s, &format!("{}_to_{}", parent, frames.tip_link), &parent, &frames.tip_link, &form.tool);
    let _ = writeln!(s, "</robot>");
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serial::{parse_urdf_str, UrdfOptions};
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

    fn pose(t_m: Vector3<f64>, r: UnitQuaternion<f64>) -> Pose {
        Isometry3::from_parts(Translation3::from(t_m), r)
    }

    fn wave(k: usize) -> f64 {
        ((k as f64) * 1.618_033_988_7).sin()
    }

    #[test]
    fn origin_form_and_written_urdf_reproduce_the_corrected_chain() {
        let crate::RobotModel::Serial(mut ur5) = crate::presets::preset("ur5").unwrap() else { panic!() };
        for (i, j) in ur5.joints.iter_mut().enumerate() {
            for k in 0..6 {
                j.correction[k] = wave(6 * i + k) * if k < 3 { 2e-3 } else { 3e-3 };
            }
        }
        ur5.base = pose(Vector3::new(0.1, -0.2, 0.05), UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 0.0, 0.3)));
        ur5.tool = pose(Vector3::new(0.0, 0.01, 0.031), UnitQuaternion::identity());
        let offsets: Vec<f64> = (0..6).map(|i| wave(40 + i) * 1e-2).collect();
        let device = pose(Vector3::new(1.5, 0.3, -0.2), UnitQuaternion::from_scaled_axis(Vector3::new(0.2, -0.1, 1.2)));
        let frames = UrdfFrames { root_link: "tracker".into(), root_to_base: device, tip_link: "target".into() };
        let text = to_urdf(&ur5, &offsets, &frames, "test").unwrap();
        let back = parse_urdf_str(&text, &UrdfOptions::default()).unwrap();
        let form = ur5.to_origin_form(&offsets).unwrap();
        let mut worst: f64 = 0.0;
        for s in 0..50 {
            let q: Vec<f64> = (0..6).map(|i| 2.5 * wave(100 + 7 * s + i)).collect();
            let qq: Vec<f64> = q.iter().zip(&offsets).map(|(a, b)| a + b).collect();
            let want = device * ur5.forward(&qq).unwrap();
            let a = device * form.forward(&q).unwrap();
            let b = back.forward(&q).unwrap();
            for got in [a, b] {
                worst = worst.max((got.translation.vector - want.translation.vector).norm());
                worst = worst.max(got.rotation.angle_to(&want.rotation));
            }
        }
        assert!(worst < 1e-12, "{worst:e}");
        assert_eq!(back.joints.len(), 6);
        assert!(text.contains("<link name=\"tracker\">") && text.contains("<link name=\"target\">"));
    }
}
