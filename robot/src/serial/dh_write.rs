//! A serial chain as a modified Denavit-Hartenberg table (Craig's convention) with Hayati's
//! extra angle where consecutive axes are (nearly) parallel: what a controller or a textbook
//! model takes, read off the chain's joint axes.
//!
//! Joint `i` moves frame `i` relative to frame `i - 1` by
//!
//! ```text
//! T_{i-1,i} = Rx(alpha_{i-1}) Tx(a_{i-1}) Ry(beta_{i-1}) Rz(theta_i) Tz(d_i)
//! ```
//!
//! with `theta_i = offset_i + q_i` for a revolute joint and `d_i = offset_i + q_i` for a prismatic
//! one. `z_i` is joint `i`'s axis. Where axes `i` and `i + 1` cross at an angle, `x_i` is their
//! common normal, `a_i` its length and `beta_i = 0` (Craig). Where they are within
//! [`PARALLEL_RAD`] of parallel the common normal runs off to infinity under the slightest tilt
//! (the reason a calibration cannot use plain DH there), so Hayati's convention is used instead:
//! frame `i + 1` starts where axis `i + 1` pierces the x-y plane of frame `i`, `x_i` points
//! there, `d_{i+1}` is then 0 if the next pair is parallel too, and the tilt of axis `i + 1` is
//! `alpha_i` about `x_i` and `beta_i` about the new `y`.
//!
//! Frame 0 is frame 1 at reading zero, so `a_0 = alpha_0 = beta_0 = 0`, `theta_1`'s offset and
//! `d_1` are 0, and the robot's place is the separate `base` transform (`T_base_frame0`, with the
//! chain's own base folded in); the last frame's origin is where the last common normal (or
//! plane) meets the last axis, its `x` continues the previous one, and the flange and tool are
//! the separate `tool` transform. Everything is derived at reading zero with the joint zero
//! offsets, so the table's offsets are what the controller's readings need.

use nalgebra::{Isometry3, Translation3, Vector3};

use super::SerialChain;
use crate::error::{Result, RobotError};
use crate::geometry::{position_mm_rpy_deg, rot_x, rot_y, rot_z, trans, Pose};
use crate::kinematics::JointKind;

/// Axes closer to parallel than this (radians) are described with Hayati's angle.
pub const PARALLEL_RAD: f64 = 0.05;

/// One row of the table: the transform from frame `i - 1` to frame `i`.
#[derive(Clone, Debug, PartialEq)]
pub struct MdhRow {
    /// The joint's name.
    pub joint: String,
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// `a_{i-1}`: length of the common normal (or in-plane offset) from axis `i - 1`, metres.
    pub a_m: f64,
    /// `alpha_{i-1}`: twist about `x_{i-1}`, radians.
    pub alpha_rad: f64,
    /// `beta_{i-1}`: Hayati's twist about `y` (0 where the axes cross at an angle), radians.
    pub beta_rad: f64,
    /// `d_i` at reading zero (prismatic: the offset added to the reading), metres.
    pub d_m: f64,
    /// `theta_i` at reading zero (revolute: the offset added to the reading), radians.
    pub theta_rad: f64,
    /// Whether the pair (axis `i - 1`, axis `i`) was taken as parallel (Hayati).
    pub hayati: bool,
}

/// A chain as a modified DH table with its base and tool transforms.
#[derive(Clone, Debug, PartialEq)]
pub struct MdhTable {
    /// `T_base_frame0` (the chain's base included).
    pub base: Pose,
    /// One row per joint.
    pub rows: Vec<MdhRow>,
    /// `T_frameN_tool`.
    pub tool: Pose,
}

/// A frame from its origin, z axis and (unnormalised, not necessarily perpendicular) x axis.
fn frame(origin: &Vector3<f64>, z: &Vector3<f64>, x: &Vector3<f64>) -> Result<Pose> {
    let x = (x - z * x.dot(z))
        .try_normalize(1e-12)
        .ok_or_else(|| RobotError::Invalid("DH export: an x axis along its joint axis (internal error)".into()))?;
    let y = z.cross(&x);
    let m = nalgebra::Matrix3::from_columns(&[x, y, *z]);
    // Orthonormal by construction: taken as it is (an iterative projection would not be exact).
    let r = crate::geometry::rotation_from_orthonormal(&m)
        .ok_or_else(|| RobotError::Invalid("DH export: a frame axis is not finite".into()))?;
    Ok(Isometry3::from_parts(Translation3::from(*origin), r))
}

impl MdhTable {
    /// `T_base_tool` at the joint readings `q` (the table's own forward kinematics).
    pub fn forward(&self, q: &[f64]) -> Result<Pose> {
        if q.len() != self.rows.len() {
            return Err(RobotError::Invalid(format!(
                "{} joint values for a table of {} joints",
                q.len(),
                self.rows.len()
            )));
        }
        let mut t = self.base;
        for (r, qi) in self.rows.iter().zip(q) {
            let (theta, d) = match r.kind {
                JointKind::Revolute => (r.theta_rad + qi, r.d_m),
                JointKind::Prismatic => (r.theta_rad, r.d_m + qi),
            };
            t = t * rot_x(r.alpha_rad) * trans(r.a_m, 0.0, 0.0) * rot_y(r.beta_rad) * rot_z(theta) * trans(0.0, 0.0, d);
        }
        Ok(t * self.tool)
    }

    /// The table as CSV: a header comment with the convention, one line per joint
    /// (`joint,kind,a_mm,alpha_deg,beta_deg,d_mm,theta_deg,hayati`), then the base and tool
    /// transforms as `x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg` (roll-pitch-yaw, `Rz(rz) Ry(ry) Rx(rx)`).
    pub fn to_csv(&self, comment: &[String]) -> String {
        use std::fmt::Write as _;
        let mut s = String::new();
        for c in comment {
            let _ = writeln!(s, "# {}", c.replace('\n', " "));
        }
        let _ = writeln!(
            s,
            "# modified DH (Craig) with Hayati's beta for parallel axes: T(i-1,i) = Rx(alpha) Tx(a) Ry(beta) Rz(theta + q) Tz(d)"
        );
        let _ = writeln!(
            s,
            "# (prismatic: Tz(d + q)); q the controller's reading; T_base_tool = base * T(0,1) ... T(n-1,n) * tool"
        );
        let _ = writeln!(s, "joint,kind,a_mm,alpha_deg,beta_deg,d_mm,theta_deg,hayati");
        for r in &self.rows {
            let _ = writeln!(
                s,
                "{},{},{:.9},{:.10},{:.10},{:.9},{:.10},{}",
                r.joint,
                if r.kind == JointKind::Revolute { "revolute" } else { "prismatic" },
                r.a_m * 1e3,
                r.alpha_rad.to_degrees(),
                r.beta_rad.to_degrees(),
                r.d_m * 1e3,
                r.theta_rad.to_degrees(),
                r.hayati
            );
        }
        let _ = writeln!(s, "# frame,x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg");
        for (name, t) in [("base", &self.base), ("tool", &self.tool)] {
            let (p, r) = position_mm_rpy_deg(t);
            let _ = writeln!(s, "# {name},{:.9},{:.9},{:.9},{:.10},{:.10},{:.10}", p[0], p[1], p[2], r[0], r[1], r[2]);
        }
        s
    }
}

impl SerialChain {
    /// The chain (with its per-joint corrections and the joint zero `offsets`, added to the
    /// readings) as a modified DH table with Hayati's angle for parallel axes (see the module
    /// documentation).
    pub fn to_mdh_table(&self, offsets: &[f64]) -> Result<MdhTable> {
        self.require_no_mimic("the DH export")?;
        let n = self.joints.len();
        if offsets.len() != n {
            return Err(RobotError::Invalid(format!("{} joint offsets for a chain of {n} joints", offsets.len())));
        }
        if n == 0 {
            return Err(RobotError::Invalid("DH export: the chain has no joints".into()));
        }
        let fr = self.frames(offsets)?;
        let z: Vec<Vector3<f64>> = fr.axes.clone();
        let p: Vec<Vector3<f64>> = fr.axis_points.iter().map(|p| p.coords).collect();
        // Frame origins and x axes, base coordinates.
        let mut origin: Vec<Vector3<f64>> = vec![Vector3::zeros(); n];
        let mut xs: Vec<Vector3<f64>> = vec![Vector3::zeros(); n];
        let mut hayati = vec![false; n];
        // The incoming point on axis 0 is the axis point itself.
        let mut incoming = p[0];
        for i in 0..n {
            if i + 1 == n {
                origin[i] = incoming;
                xs[i] = if i == 0 { any_perpendicular(&z[0]) } else { xs[i - 1] };
                if (xs[i] - z[i] * xs[i].dot(&z[i])).norm() < 1e-9 {
                    xs[i] = any_perpendicular(&z[i]);
                }
                break;
            }
            let (zi, zj) = (z[i], z[i + 1]);
            let cross = zi.cross(&zj);
            let sin = cross.norm();
            if sin < PARALLEL_RAD.sin() {
                // Hayati: frame i keeps the incoming point; frame i+1 starts where axis i+1
                // pierces frame i's x-y plane.
                hayati[i + 1] = true;
                origin[i] = incoming;
                let denom = zj.dot(&zi);
                let s = (origin[i] - p[i + 1]).dot(&zi) / denom;
                let pierce = p[i + 1] + zj * s;
                let v = pierce - origin[i];
                xs[i] = if v.norm() > 1e-9 {
                    v
                } else if i > 0 {
                    xs[i - 1]
                } else {
                    any_perpendicular(&zi)
                };
                incoming = pierce;
            } else {
                // Craig: the common normal from axis i to axis i+1.
                let w = p[i] - p[i + 1];
                let (b, d, e) = (zi.dot(&zj), zi.dot(&w), zj.dot(&w));
                let den = 1.0 - b * b;
                let si = (b * e - d) / den;
                let sj = (e - b * d) / den;
                let foot_i = p[i] + zi * si;
                let foot_j = p[i + 1] + zj * sj;
                origin[i] = foot_i;
                let v = foot_j - foot_i;
                xs[i] = if v.norm() > 1e-9 { v } else { cross / sin };
                incoming = foot_j;
            }
        }
        let frames: Vec<Pose> = (0..n).map(|i| frame(&origin[i], &z[i], &xs[i])).collect::<Result<Vec<_>>>()?;
        // Frame 0 is frame 1 at reading zero.
        let base = frames[0];
        let mut rows = Vec::with_capacity(n);
        let kinds: Vec<JointKind> = self.joints.iter().map(|j| j.kind).collect();
        let mut prev = base;
        for i in 0..n {
            let rel = prev.inverse() * frames[i];
            let o = rel.translation.vector;
            let zl = rel.rotation * Vector3::z();
            let beta = zl.x.clamp(-1.0, 1.0).asin();
            let alpha = (-zl.y).atan2(zl.z);
            // The origin is a x + d z (x of frame i-1, z the joint's axis): a along x, d along
            // the (tilted) axis; whatever else remains would be a construction error.
            let dd = (o.y * zl.y + o.z * zl.z) / (zl.y * zl.y + zl.z * zl.z);
            let a = o.x - dd * zl.x;
            let pre = rot_x(alpha) * trans(a, 0.0, 0.0) * rot_y(beta);
            let rest = pre.inverse() * rel;
            let r = rest.translation.vector;
            if r.x.abs() > 1e-9 || r.y.abs() > 1e-9 {
                return Err(RobotError::Invalid(format!(
                    "DH export: joint {} ({}): the frame construction left {:.3e} m off its axis (internal error)",
                    i + 1,
                    self.joints[i].name,
                    r.x.hypot(r.y)
                )));
            }
            let xl = rest.rotation * Vector3::x();
            let theta = xl.y.atan2(xl.x);
            rows.push(MdhRow {
                joint: self.joints[i].name.clone(),
                kind: kinds[i],
                a_m: a,
                alpha_rad: alpha,
                beta_rad: beta,
                d_m: r.z,
                theta_rad: theta,
                hayati: hayati[i],
            });
            prev = frames[i];
        }
        // The readings are zero here: a prismatic joint's d and a revolute joint's theta are the
        // offsets the table carries; the other is geometry. The last frame to the tool:
        let tool = frames[n - 1].inverse() * fr.tool;
        Ok(MdhTable { base, rows, tool })
    }
}

fn any_perpendicular(z: &Vector3<f64>) -> Vector3<f64> {
    let t = if z.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    (t - z * t.dot(z)).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::presets;
    use crate::Kinematics;

    fn worst(chain: &SerialChain, offsets: &[f64], table: &MdhTable) -> (f64, f64) {
        let mut w = (0.0f64, 0.0f64);
        for s in 0..100usize {
            let q: Vec<f64> =
                (0..chain.joints.len()).map(|i| 3.0 * (((s * 7 + i * 13) as f64) * 0.618).sin()).collect();
            let qq: Vec<f64> = q.iter().zip(offsets).map(|(a, b)| a + b).collect();
            let a = chain.forward(&qq).unwrap();
            let b = table.forward(&q).unwrap();
            w.0 = w.0.max((a.translation.vector - b.translation.vector).norm());
            w.1 = w.1.max(a.rotation.angle_to(&b.rotation));
        }
        w
    }

    #[test]
    fn the_ur5_nominal_table_reproduces_its_kinematics_and_its_published_lengths() {
        let chain = presets::ur5();
        let offsets = vec![0.0; 6];
        let t = chain.to_mdh_table(&offsets).unwrap();
        let (p, r) = worst(&chain, &offsets, &t);
        assert!(p < 1e-12 && r < 1e-12, "{p:e} m, {r:e} rad");
        // The UR5's upper arm and forearm lengths (425 mm, 392.25 mm) appear as a lengths of the
        // parallel joints 2-3 and 3-4, described with Hayati's angle.
        let a: Vec<f64> = t.rows.iter().map(|r| r.a_m.abs() * 1e3).collect();
        assert!(a.iter().any(|v| (v - 425.0).abs() < 1e-9), "{a:?}");
        assert!(a.iter().any(|v| (v - 392.25).abs() < 1e-9), "{a:?}");
        assert!(t.rows[2].hayati && t.rows[3].hayati && !t.rows[1].hayati);
    }

    #[test]
    fn a_perturbed_chain_with_offsets_stays_exact_and_bounded() {
        let mut chain = presets::ur5();
        for (i, j) in chain.joints.iter_mut().enumerate() {
            let k = i as f64 + 1.0;
            j.correction = [1e-3 * k, -5e-4 * k, 7e-4, 2e-3 / k, -1.5e-3, 1e-3 * k];
        }
        let offsets = vec![0.01, -0.02, 0.003, 0.0, 0.015, -0.01];
        let t = chain.to_mdh_table(&offsets).unwrap();
        let (p, r) = worst(&chain, &offsets, &t);
        assert!(p < 1e-12 && r < 1e-12, "{p:e} m, {r:e} rad");
        // Hayati keeps the parallel pairs' lengths bounded: no d or a beyond the arm's reach.
        for row in &t.rows {
            assert!(row.a_m.abs() < 1.0 && row.d_m.abs() < 1.0, "{row:?}");
        }
    }

    #[test]
    fn a_chain_with_a_prismatic_joint_round_trips() {
        let chain = SerialChain::from_mdh(
            "rpr",
            &[0.0, 0.3, 0.1],
            &[0.0, std::f64::consts::FRAC_PI_2, 0.2],
            &[0.1, 0.05, 0.2],
            &[0.0, 0.3, -0.2],
        );
        let mut chain = chain;
        chain.joints[1].kind = JointKind::Prismatic;
        let offsets = vec![0.0, 0.01, 0.02];
        let t = chain.to_mdh_table(&offsets).unwrap();
        let (p, r) = worst(&chain, &offsets, &t);
        assert!(p < 1e-12 && r < 1e-12, "{p:e} m, {r:e} rad");
    }
}
