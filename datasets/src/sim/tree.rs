//! An independent simulator of tree-shaped robots with compliant drives: a torso carrying two
//! arms, one hand measured.
//!
//! Written apart from the analysis on purpose: it does not use `ferrocal_robot`'s chain or
//! `ferrocal_calib::effects`. Its forward kinematics composes 3x3 rotations and translations
//! from the URDF-style joint origins (`origin * rot(axis, q)`), its holding torques are central
//! differences of the potential energy of every link of the tree (the branch that is not
//! measured included), and the compliant pose is the fixed point of `q = q_cmd + offset -
//! C tau(q)`, iterated to 1e-11 rad. Whatever the analysis models (URDF parsing, the lumping of a
//! branch into the link it hangs on, mimic couplings, the torque equilibrium) is checked against
//! this code rather than against itself.

use nalgebra::{Matrix3, Vector3};

/// Standard gravity (m/s^2) along -z of the base.
const G_M_S2: f64 = 9.80665;

/// A rigid transform: rotation and translation.
#[derive(Clone, Copy, Debug)]
pub struct Tf {
    /// Rotation.
    pub r: Matrix3<f64>,
    /// Translation (m).
    pub t: Vector3<f64>,
}

impl Tf {
    /// The identity.
    pub fn identity() -> Self {
        Self { r: Matrix3::identity(), t: Vector3::zeros() }
    }

    /// `self * o`.
    pub fn then(&self, o: &Tf) -> Tf {
        Tf { r: self.r * o.r, t: self.r * o.t + self.t }
    }

    /// Maps a point.
    pub fn apply(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.r * p + self.t
    }
}

/// Rotation by `angle_rad` about unit `axis` (Rodrigues).
pub fn rot(axis: &Vector3<f64>, angle_rad: f64) -> Matrix3<f64> {
    let k = axis.cross_matrix();
    Matrix3::identity() + k * angle_rad.sin() + k * k * (1.0 - angle_rad.cos())
}

/// URDF's fixed-axis roll-pitch-yaw: `Rz(yaw) Ry(pitch) Rx(roll)`.
pub fn rpy(r: &Vector3<f64>) -> Matrix3<f64> {
    rot(&Vector3::z(), r.z) * rot(&Vector3::y(), r.y) * rot(&Vector3::x(), r.x)
}

/// One revolute joint of the tree and the link it moves.
#[derive(Clone, Debug)]
pub struct TreeJoint {
    /// Name (URDF joint name; the link it moves is `<name>_link`).
    pub name: String,
    /// The joint whose link carries this one (`None`: the base).
    pub parent: Option<usize>,
    /// Origin translation in the parent link (m).
    pub xyz_m: Vector3<f64>,
    /// Origin roll-pitch-yaw in the parent link (rad).
    pub rpy_rad: Vector3<f64>,
    /// Unit axis in the joint frame.
    pub axis: Vector3<f64>,
    /// Mass of the moved link (kg).
    pub mass_kg: f64,
    /// Centre of mass in the moved link (m).
    pub com_m: Vector3<f64>,
    /// `Some((leader, multiplier, offset_rad))`: a passively coupled joint, `q = m q_leader + o`.
    pub mimic: Option<(usize, f64, f64)>,
    /// Limits of the commanded angle (rad).
    pub limits_rad: (f64, f64),
}

/// A tree of revolute joints, one tip measured: the chain from the base to `tip` moves, the
/// other branches stand still at zero (their mimic joints at their offsets).
#[derive(Clone, Debug)]
pub struct TreeRobot {
    /// The joints, parents before children.
    pub joints: Vec<TreeJoint>,
    /// The joint whose link carries the measured point.
    pub tip: usize,
    /// The measured point in the tip's link (m).
    pub tool_m: Vector3<f64>,
    /// Zero offsets of the actuated chain joints (rad), one per [`TreeRobot::actuated`] entry.
    pub offsets_rad: Vec<f64>,
    /// Drive compliances of the actuated chain joints (rad/(N m)).
    pub compliance_rad_per_nm: Vec<f64>,
}

impl TreeRobot {
    /// The joints from the base to the tip (indices, base first).
    pub fn path(&self) -> Vec<usize> {
        let mut out = vec![self.tip];
        while let Some(p) = self.joints[*out.last().expect("non-empty")].parent {
            out.push(p);
        }
        out.reverse();
        out
    }

    /// The actuated (not mimic) joints of the measured chain, base first: the coordinates of
    /// the recording's `q1..qN`.
    pub fn actuated(&self) -> Vec<usize> {
        self.path().into_iter().filter(|&j| self.joints[j].mimic.is_none()).collect()
    }

    /// Every joint's angle for actuated chain angles `q`.
    pub fn angles(&self, q: &[f64]) -> Vec<f64> {
        let mut a = vec![0.0; self.joints.len()];
        for (k, &j) in self.actuated().iter().enumerate() {
            a[j] = q[k];
        }
        for (j, joint) in self.joints.iter().enumerate() {
            if let Some((leader, m, o)) = joint.mimic {
                a[j] = m * a[leader] + o;
            }
        }
        a
    }

    /// Link frames of every joint in the base frame.
    pub fn links(&self, q: &[f64]) -> Vec<Tf> {
        let a = self.angles(q);
        let mut out: Vec<Tf> = Vec::with_capacity(self.joints.len());
        for (j, joint) in self.joints.iter().enumerate() {
            let parent = joint.parent.map_or_else(Tf::identity, |p| out[p]);
            let origin = Tf { r: rpy(&joint.rpy_rad), t: joint.xyz_m };
            out.push(parent.then(&origin).then(&Tf { r: rot(&joint.axis, a[j]), t: Vector3::zeros() }));
        }
        out
    }

    /// The measured point in the base frame.
    pub fn tool_point(&self, q: &[f64]) -> Vector3<f64> {
        self.links(q)[self.tip].apply(&self.tool_m)
    }

    /// Potential energy of every link of the tree (J).
    pub fn energy_j(&self, q: &[f64]) -> f64 {
        let links = self.links(q);
        self.joints.iter().zip(&links).map(|(j, l)| j.mass_kg * G_M_S2 * l.apply(&j.com_m).z).sum()
    }

    /// Holding torques of the actuated chain joints, `dV/dq` by central differences (1e-5 rad).
    pub fn torques_nm(&self, q: &[f64]) -> Vec<f64> {
        energy_gradient(q, |x| self.energy_j(x))
    }

    /// The angles where the drives hold the load: `q = q_cmd + offset - C tau(q)`, iterated to
    /// 1e-11 rad; `None` if it does not settle in 500 steps.
    pub fn equilibrium(&self, q_cmd: &[f64]) -> Option<Vec<f64>> {
        let q0: Vec<f64> = q_cmd.iter().zip(&self.offsets_rad).map(|(q, o)| q + o).collect();
        let mut q = q0.clone();
        for _ in 0..500 {
            let tau = self.torques_nm(&q);
            let next: Vec<f64> =
                q0.iter().zip(&self.compliance_rad_per_nm).zip(&tau).map(|((q0, c), t)| q0 - c * t).collect();
            let d = next.iter().zip(&q).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            q = next;
            if d < 1e-11 {
                return Some(q);
            }
        }
        None
    }

    /// The tree as URDF: a link per joint with its inertial (a small diagonal inertia: the
    /// simulator's statics do not use it), a fixed `<tip>_marker` link at the measured point for
    /// the measured tip and one at `other_tool_m` for every other leaf, the mimic joints with
    /// their multiplier and offset.
    pub fn urdf(&self, name: &str, other_tool_m: &Vector3<f64>) -> String {
        let mut s = format!("<robot name=\"{name}\">\n  <link name=\"base\"/>\n");
        let link = |j: usize| format!("{}_link", self.joints[j].name);
        for (j, joint) in self.joints.iter().enumerate() {
            let c = &joint.com_m;
            s.push_str(&format!(
                "  <link name=\"{}\"><inertial><origin xyz=\"{} {} {}\"/><mass value=\"{}\"/>\
                 <inertia ixx=\"0.001\" iyy=\"0.001\" izz=\"0.001\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>\n",
                link(j),
                c.x,
                c.y,
                c.z,
                joint.mass_kg
            ));
        }
        for (j, joint) in self.joints.iter().enumerate() {
            let parent = joint.parent.map_or_else(|| "base".to_string(), link);
            let (x, r, a) = (&joint.xyz_m, &joint.rpy_rad, &joint.axis);
            let mimic = joint
                .mimic
                .map(|(l, m, o)| {
                    format!("<mimic joint=\"{}\" multiplier=\"{m}\" offset=\"{o}\"/>", self.joints[l].name)
                })
                .unwrap_or_default();
            s.push_str(&format!(
                "  <joint name=\"{}\" type=\"revolute\"><parent link=\"{parent}\"/><child link=\"{}\"/>\
                 <origin xyz=\"{} {} {}\" rpy=\"{} {} {}\"/><axis xyz=\"{} {} {}\"/>\
                 <limit lower=\"{}\" upper=\"{}\" effort=\"100\" velocity=\"2\"/>{mimic}</joint>\n",
                joint.name,
                link(j),
                x.x,
                x.y,
                x.z,
                r.x,
                r.y,
                r.z,
                a.x,
                a.y,
                a.z,
                joint.limits_rad.0,
                joint.limits_rad.1,
            ));
        }
        for j in 0..self.joints.len() {
            if self.joints.iter().any(|c| c.parent == Some(j)) {
                continue;
            }
            let t = if j == self.tip { self.tool_m } else { *other_tool_m };
            let marker = format!("{}_marker", self.joints[j].name);
            s.push_str(&format!(
                "  <link name=\"{marker}\"/>\n  <joint name=\"{marker}_fix\" type=\"fixed\"><parent link=\"{}\"/>\
                 <child link=\"{marker}\"/><origin xyz=\"{} {} {}\"/></joint>\n",
                link(j),
                t.x,
                t.y,
                t.z
            ));
        }
        s.push_str("</robot>\n");
        s
    }
}

/// `dV/dq` of a potential energy `energy_j` (J) at `q` by central differences of 1e-5 rad: the
/// joint torques that hold the pose, N m.
pub(crate) fn energy_gradient(q: &[f64], energy_j: impl Fn(&[f64]) -> f64) -> Vec<f64> {
    let h = 1e-5;
    (0..q.len())
        .map(|k| {
            let (mut p, mut m) = (q.to_vec(), q.to_vec());
            p[k] += h;
            m[k] -= h;
            (energy_j(&p) - energy_j(&m)) / (2.0 * h)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn torques_are_the_energy_gradient_of_a_hand_computed_pendulum() {
        // One joint about y at the origin carrying 2 kg at 0.5 m along x: V = m g (-0.5 sin q)
        // for rot_y(q) x = (cos q, 0, -sin q); dV/dq = -m g 0.5 cos q.
        let robot = TreeRobot {
            joints: vec![TreeJoint {
                name: "j".into(),
                parent: None,
                xyz_m: Vector3::zeros(),
                rpy_rad: Vector3::zeros(),
                axis: Vector3::y(),
                mass_kg: 2.0,
                com_m: Vector3::new(0.5, 0.0, 0.0),
                mimic: None,
                limits_rad: (-1.0, 1.0),
            }],
            tip: 0,
            tool_m: Vector3::x(),
            offsets_rad: vec![0.0],
            compliance_rad_per_nm: vec![1e-3],
        };
        let q = 0.3;
        let tau = robot.torques_nm(&[q])[0];
        assert!((tau + 2.0 * G_M_S2 * 0.5 * q.cos()).abs() < 1e-6, "{tau}");
        let eq = robot.equilibrium(&[q]).unwrap()[0];
        assert!((eq - (q + 1e-3 * 2.0 * G_M_S2 * 0.5 * eq.cos())).abs() < 1e-10);
    }
}
