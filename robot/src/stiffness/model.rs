//! The virtual joint model of a serial chain: compliant actuated joints, a 6-DOF virtual spring
//! at the end of each link, and optionally a gravity compensator.
//!
//! `T = T_base S_0 prod_i [J_i(q_i + theta_i) S_i] T_tool`, where `J_i` is joint `i`'s rigid
//! transform, `theta_i` its deflection, and `S_i = P_i Exp(delta_i) P_i^-1` the virtual spring of
//! link `i` placed at `P_i` in the link frame, deflected by the 6-vector `delta_i` (translation,
//! rotation vector) in its own frame. Link 0 is the base (the foundation and pedestal).
//!
//! Loads: a wrench at the tool point, and (optionally) the weight of every link from the chain's
//! inertials. A link's weight acts at its centre of mass, proximal to that link's own spring
//! (the spring lumps the link's flexibility at its far end): it loads the joints and springs
//! before it. Deflections are linear in the loads: `theta_j = k_j tau_j`,
//! `delta_s = C_s v_s` with `tau_j` the torque joint `j` transmits and `v_s` the wrench spring
//! `s` transmits (in its frame), and the tool moves by `dt = sum J_j theta_j + sum J_s delta_s`.
//! For a tool wrench alone this is `dt = k_C w` with `k_C = J K^-1 J^T`.

use nalgebra::{
    DMatrix, Isometry3, Matrix3, Matrix6, Point3, Rotation3, Translation3, UnitQuaternion, Vector3, Vector6,
};
use serde::{Deserialize, Serialize};

use crate::geometry::{skew, Pose};
use crate::kinematics::{JointKind, Kinematics};
use crate::serial::{ChainFrames, SerialChain};
use crate::stiffness::compensator::GravityCompensator;
use crate::stiffness::error::{Result, StiffnessError};
use crate::stiffness::wrench::{Wrench, WrenchLimits, WrenchSpec};

/// A 6-DOF virtual spring lumping a link's flexibility.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VirtualSpring {
    /// Name used in parameter names (`link2`).
    pub name: String,
    /// The link carrying it: 0 the base, `i` the link moved by joint `i`.
    pub link: usize,
    /// `T_link_spring`: the spring frame in the link frame.
    pub t_link_spring: Pose,
    /// The axis of the spring frame along which the link runs as a beam (0 x, 1 y, 2 z), which
    /// fixes its sparsity template; `None` when unknown.
    pub beam_axis: Option<usize>,
    /// Compliance matrix in the spring frame (SI; `(translation, rotation)` per `(force, moment)`).
    pub compliance: Matrix6<f64>,
}

/// Deflections of every virtual joint.
#[derive(Clone, Debug, PartialEq)]
pub struct Deflections {
    /// Actuated joints (rad or m).
    pub joints: Vec<f64>,
    /// Virtual springs, `(translation m, rotation vector rad)` in each spring's frame.
    pub springs: Vec<Vector6<f64>>,
}

/// Loads on the robot for one measurement.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Loading {
    /// The wrench at the tool point (base axes): a payload's weight, an applied force.
    pub tool_wrench: Wrench,
    /// Whether the links' own weights (from the chain's inertials) act too.
    pub self_weight: bool,
    /// Whether the gravity compensator's torque acts (absolute deflections; a difference of two
    /// measurements at the same configuration cancels it).
    pub compensator: bool,
}

impl Loading {
    /// Only a tool wrench (e.g. a loaded-minus-unloaded difference).
    pub fn tool(w: Wrench) -> Self {
        Self { tool_wrench: w, self_weight: false, compensator: false }
    }

    /// Everything gravity does: the links' weight, the compensator, and a tool wrench.
    pub fn gravity(tool_wrench: Wrench) -> Self {
        Self { tool_wrench, self_weight: true, compensator: true }
    }
}

/// Loads transmitted through each virtual joint.
#[derive(Clone, Debug, PartialEq)]
pub struct Transmitted {
    /// Torque (force for prismatic joints) each actuated joint transmits from external loads.
    pub joints: Vec<f64>,
    /// Wrench each spring transmits, `(force, moment about its origin)` in its frame.
    pub springs: Vec<Vector6<f64>>,
    /// The compensator terms `(-s s', s')` when the loading includes the compensator.
    pub compensator: Option<[f64; 2]>,
}

/// Jacobians of a point's motion (rows: linear velocity, angular velocity; base frame) with
/// respect to every virtual joint.
#[derive(Clone, Debug, PartialEq)]
pub struct VjmJacobians {
    /// The point.
    pub point: Point3<f64>,
    /// `T_base_tool` at the configuration.
    pub tool: Pose,
    /// 6 x n, actuated joints.
    pub joints: DMatrix<f64>,
    /// One 6 x 6 matrix per spring.
    pub springs: Vec<Matrix6<f64>>,
}

/// A joint compliance that cannot be told apart from a spring's compliance about the same axis
/// (step M3 of the model reduction: their regressor columns are identical).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Aggregation {
    /// The joint (0-based).
    pub joint: usize,
    /// The spring (index into the model's springs).
    pub spring: usize,
    /// The spring's diagonal entry (0-based, 3..6 for rotation) along the joint axis.
    pub entry: usize,
}

/// The virtual joint model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VjmModel {
    /// The kinematics with link inertials.
    pub chain: SerialChain,
    /// Compliance of each actuated joint: rad/(N m) or m/N.
    pub joint_compliance: Vec<f64>,
    /// Virtual springs, ordered along the chain (by link).
    pub springs: Vec<VirtualSpring>,
    /// A gravity compensator, if the arm has one.
    pub compensator: Option<GravityCompensator>,
}

/// A point load: the first link that carries it, force, point of application, extra moment.
type PointLoad = (usize, Vector3<f64>, Point3<f64>, Vector3<f64>);

/// A rotation whose z axis is `z` and whose x axis is the part of `x_hint` perpendicular to it
/// (or of `fallback` when `x_hint` is along `z`).
fn frame_from_z(z: &Vector3<f64>, x_hint: &Vector3<f64>, fallback: &Vector3<f64>) -> Rotation3<f64> {
    let z = z.normalize();
    let mut x = x_hint - z * z.dot(x_hint);
    if x.norm() < 1e-6 * x_hint.norm().max(1e-300) || x.norm() < 1e-12 {
        x = fallback - z * z.dot(fallback);
        if x.norm() < 1e-9 {
            let other = if z.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
            x = other - z * z.dot(&other);
        }
    }
    let x = x.normalize();
    let y = z.cross(&x);
    Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]))
}

impl VjmModel {
    /// A model with the given parts, checked.
    pub fn new(
        chain: SerialChain,
        joint_compliance: Vec<f64>,
        springs: Vec<VirtualSpring>,
        compensator: Option<GravityCompensator>,
    ) -> Result<Self> {
        let m = Self { chain, joint_compliance, springs, compensator };
        m.validate()?;
        Ok(m)
    }

    /// A rigid-link, compliant-joint model.
    pub fn rigid_links(chain: SerialChain, joint_compliance: Vec<f64>) -> Result<Self> {
        Self::new(chain, joint_compliance, Vec::new(), None)
    }

    /// A model with one spring per link (base included) placed by [`VjmModel::auto_springs`], all
    /// of zero compliance, and zero joint compliances: the structure for identification.
    pub fn with_link_springs(chain: SerialChain) -> Result<Self> {
        let springs = Self::auto_springs(&chain)?;
        let n = chain.joints.len();
        Self::new(chain, vec![0.0; n], springs, None)
    }

    /// One spring at the far end of every link, base (link 0) to flange (link n): on the next
    /// joint's axis with its z axis along that axis and its x axis along the link (the part of
    /// the link's run perpendicular to the axis); the last at the flange with the flange's z
    /// axis. The beam axis is x when the link runs mostly across the next axis, z when along it.
    pub fn auto_springs(chain: &SerialChain) -> Result<Vec<VirtualSpring>> {
        chain.require_no_mimic("the stiffness model")?;
        let n = chain.joints.len();
        if n == 0 {
            return Err(StiffnessError::Structure("a chain without joints has no links".into()));
        }
        let q0 = vec![0.0; n];
        let fr = chain.frames(&q0)?;
        let mut out = Vec::with_capacity(n + 1);
        for s in 0..=n {
            let link_pose = if s == 0 { chain.base } else { fr.links[s - 1] };
            let (origin, z) = if s < n {
                (fr.axis_points[s], fr.axes[s])
            } else {
                (Point3::from(fr.flange.translation.vector), fr.flange.rotation * Vector3::z())
            };
            let start = if s == 0 { Point3::from(chain.base.translation.vector) } else { fr.axis_points[s - 1] };
            let v = origin - start;
            let along = v.dot(&z).abs();
            let across = (v - z * v.dot(&z)).norm();
            let beam_axis = if v.norm() < 1e-6 || along >= across { 2 } else { 0 };
            let fallback = link_pose.rotation * Vector3::x();
            let rot = frame_from_z(&z, &v, &fallback);
            let t_base_spring = Isometry3::from_parts(Translation3::from(origin.coords), UnitQuaternion::from(rot));
            out.push(VirtualSpring {
                name: format!("link{s}"),
                link: s,
                t_link_spring: link_pose.inverse() * t_base_spring,
                beam_axis: Some(beam_axis),
                compliance: Matrix6::zeros(),
            });
        }
        Ok(out)
    }

    /// Checks sizes, finiteness, spring placement order and the compensator.
    pub fn validate(&self) -> Result<()> {
        self.chain.require_no_mimic("the stiffness model")?;
        let n = self.chain.joints.len();
        if self.joint_compliance.len() != n {
            return Err(StiffnessError::Structure(format!(
                "{} joint compliances for {n} joints",
                self.joint_compliance.len()
            )));
        }
        for (i, k) in self.joint_compliance.iter().enumerate() {
            if !k.is_finite() {
                return Err(StiffnessError::BadCompliance {
                    what: format!("joint {}", i + 1),
                    reason: format!("compliance {k} is not finite"),
                });
            }
        }
        let mut last = 0;
        for s in &self.springs {
            if s.link > n {
                return Err(StiffnessError::Structure(format!(
                    "spring '{}' is on link {} but the chain has links 0 to {n}",
                    s.name, s.link
                )));
            }
            if s.link < last {
                return Err(StiffnessError::Structure(format!(
                    "spring '{}': springs must be listed from the base to the tip",
                    s.name
                )));
            }
            last = s.link;
            if s.compliance.iter().any(|v| !v.is_finite()) {
                return Err(StiffnessError::BadCompliance {
                    what: format!("spring '{}'", s.name),
                    reason: "non-finite compliance entry".into(),
                });
            }
            if s.beam_axis.is_some_and(|a| a > 2) {
                return Err(StiffnessError::Structure(format!("spring '{}': beam axis must be 0, 1 or 2", s.name)));
            }
        }
        if let Some(c) = &self.compensator {
            c.validate(&self.chain)?;
        }
        Ok(())
    }

    /// Number of actuated joints.
    pub fn dof(&self) -> usize {
        self.chain.joints.len()
    }

    /// `T_base_link` of link `link` (0: the base) from the frames of a configuration.
    pub fn link_pose(&self, frames: &ChainFrames, link: usize) -> Pose {
        if link == 0 {
            self.chain.base
        } else {
            frames.links[link - 1]
        }
    }

    /// `T_base_spring` of every spring at the frames of a configuration.
    pub fn spring_poses(&self, frames: &ChainFrames) -> Vec<Pose> {
        self.springs.iter().map(|s| self.link_pose(frames, s.link) * s.t_link_spring).collect()
    }

    /// Jacobians of `point` (default: the tool point) with respect to every virtual joint at `q`.
    pub fn jacobians(&self, q: &[f64], point: Option<Point3<f64>>) -> Result<VjmJacobians> {
        let frames = self.chain.frames(q)?;
        Ok(self.jacobians_at(&frames, point))
    }

    pub(crate) fn jacobians_at(&self, frames: &ChainFrames, point: Option<Point3<f64>>) -> VjmJacobians {
        let p = point.unwrap_or_else(|| Point3::from(frames.tool.translation.vector));
        let kinds = self.chain.joint_kinds();
        let n = self.dof();
        let joints = SerialChain::point_jacobian(frames, &kinds, n - 1, &p);
        let springs = self
            .spring_poses(frames)
            .iter()
            .map(|t| {
                let r = t.rotation.to_rotation_matrix().into_inner();
                let o = Point3::from(t.translation.vector);
                let mut j = Matrix6::zeros();
                j.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
                j.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-skew(&(p - o)) * r));
                j.fixed_view_mut::<3, 3>(3, 3).copy_from(&r);
                j
            })
            .collect();
        VjmJacobians { point: p, tool: frames.tool, joints, springs }
    }

    /// Loads transmitted through every virtual joint at `q` under `loading`.
    pub fn transmitted(&self, q: &[f64], loading: &Loading) -> Result<Transmitted> {
        let frames = self.chain.frames(q)?;
        self.transmitted_at(&frames, loading)
    }

    pub(crate) fn transmitted_at(&self, frames: &ChainFrames, loading: &Loading) -> Result<Transmitted> {
        let n = self.dof();
        let p_tool = Point3::from(frames.tool.translation.vector);
        let g = Vector3::from(self.chain.gravity_m_s2);
        // Point loads: (first link index that carries it, force, point, extra moment).
        let mut loads: Vec<PointLoad> = Vec::new();
        loads.push((n + 1, loading.tool_wrench.force_n, p_tool, loading.tool_wrench.torque_nm));
        if loading.self_weight {
            for (i, j) in self.chain.joints.iter().enumerate() {
                if let Some(inr) = &j.inertial {
                    let com = frames.links[i] * Point3::from(inr.com_m);
                    loads.push((i + 1, g * inr.mass_kg, com, Vector3::zeros()));
                }
            }
        }
        // A load on link L is carried by joints 1..=L and by springs of links < L; the tool
        // wrench (L = n + 1) by everything.
        let kinds = self.chain.joint_kinds();
        let joints = (0..n)
            .map(|j| {
                let (u, c) = (frames.axes[j], frames.axis_points[j]);
                loads
                    .iter()
                    .filter(|(l, ..)| *l > j)
                    .map(|(_, f, p, m)| match kinds[j] {
                        JointKind::Revolute => u.dot(&((p - c).cross(f) + m)),
                        JointKind::Prismatic => u.dot(f),
                    })
                    .sum()
            })
            .collect();
        let poses = self.spring_poses(frames);
        let springs = self
            .springs
            .iter()
            .zip(&poses)
            .map(|(s, t)| {
                let o = Point3::from(t.translation.vector);
                let (mut f_tot, mut m_tot) = (Vector3::zeros(), Vector3::zeros());
                for (l, f, p, m) in &loads {
                    if *l > s.link {
                        f_tot += f;
                        m_tot += (p - o).cross(f) + m;
                    }
                }
                let rt = t.rotation.inverse();
                let (fl, ml) = (rt * f_tot, rt * m_tot);
                Vector6::new(fl.x, fl.y, fl.z, ml.x, ml.y, ml.z)
            })
            .collect();
        let compensator = match (&self.compensator, loading.compensator) {
            (Some(c), true) => Some(c.basis(&self.chain, frames)?),
            _ => None,
        };
        Ok(Transmitted { joints, springs, compensator })
    }

    /// Deflections of every virtual joint at `q` under `loading` (linear model).
    pub fn deflections(&self, q: &[f64], loading: &Loading) -> Result<Deflections> {
        let tr = self.transmitted(q, loading)?;
        let mut joints: Vec<f64> = tr.joints.iter().zip(&self.joint_compliance).map(|(t, k)| t * k).collect();
        if let (Some(c), Some(_)) = (&self.compensator, tr.compensator) {
            let frames = self.chain.frames(q)?;
            joints[c.joint - 1] += self.joint_compliance[c.joint - 1] * c.torque_nm(&self.chain, &frames)?;
        }
        let springs = tr.springs.iter().zip(&self.springs).map(|(v, s)| s.compliance * v).collect();
        Ok(Deflections { joints, springs })
    }

    /// The tool's small displacement `(dp m, dphi rad)` in the base frame at `q` under `loading`
    /// (linear model).
    pub fn deflection(&self, q: &[f64], loading: &Loading) -> Result<Vector6<f64>> {
        let d = self.deflections(q, loading)?;
        let jac = self.jacobians(q, None)?;
        Ok(Self::twist(&jac, &d))
    }

    /// The displacement of the Jacobians' point caused by deflections `d` (first order).
    pub fn twist(jac: &VjmJacobians, d: &Deflections) -> Vector6<f64> {
        let mut dt = Vector6::zeros();
        for (j, th) in d.joints.iter().enumerate() {
            dt += jac.joints.fixed_view::<6, 1>(0, j) * *th;
        }
        for (js, ds) in jac.springs.iter().zip(&d.springs) {
            dt += js * ds;
        }
        dt
    }

    /// The Cartesian compliance `k_C = J K^-1 J^T` of the tool point at `q` (6 x 6, base frame).
    pub fn cartesian_compliance(&self, q: &[f64]) -> Result<Matrix6<f64>> {
        let jac = self.jacobians(q, None)?;
        let mut k = Matrix6::zeros();
        for (j, kj) in self.joint_compliance.iter().enumerate() {
            let c = jac.joints.fixed_view::<6, 1>(0, j);
            k += c * c.transpose() * *kj;
        }
        for (js, s) in jac.springs.iter().zip(&self.springs) {
            k += js * s.compliance * js.transpose();
        }
        Ok(k)
    }

    /// The tool pose with every virtual joint deflected by `d` (exact compliant kinematics).
    pub fn deflected_pose(&self, q: &[f64], d: &Deflections) -> Result<Pose> {
        let n = self.dof();
        if d.joints.len() != n || d.springs.len() != self.springs.len() {
            return Err(StiffnessError::Structure(format!(
                "deflections for {} joints and {} springs, the model has {n} and {}",
                d.joints.len(),
                d.springs.len(),
                self.springs.len()
            )));
        }
        let qd: Vec<f64> = q.iter().zip(&d.joints).map(|(a, b)| a + b).collect();
        let fr = self.chain.frames(&qd)?;
        let spring_of = |link: usize, t: &mut Pose| {
            for (s, ds) in self.springs.iter().zip(&d.springs).filter(|(s, _)| s.link == link) {
                *t = *t * s.t_link_spring * crate::geometry::exp6(ds.as_slice()) * s.t_link_spring.inverse();
            }
        };
        let mut t = self.chain.base;
        spring_of(0, &mut t);
        let mut prev = self.chain.base;
        for i in 0..n {
            t *= prev.inverse() * fr.links[i];
            prev = fr.links[i];
            spring_of(i + 1, &mut t);
        }
        Ok(t * self.chain.tool)
    }

    /// The joint compliances that cannot be told from a spring's: a joint whose axis passes
    /// through the origin of the last spring before it, along one of that spring's axes.
    pub fn aggregations(&self) -> Result<Vec<Aggregation>> {
        let n = self.dof();
        let fr = self.chain.frames(&vec![0.0; n])?;
        let poses = self.spring_poses(&fr);
        let kinds = self.chain.joint_kinds();
        let mut out = Vec::new();
        for (j, kind) in kinds.iter().enumerate() {
            // The last spring before joint j: on a link < j + 1.
            let Some(s) = self.springs.iter().rposition(|s| s.link <= j) else { continue };
            let t = &poses[s];
            let u = fr.axes[j];
            let o = Point3::from(t.translation.vector);
            for a in 0..3 {
                let e = t.rotation * Vector3::ith(a, 1.0);
                if e.dot(&u).abs() < 1.0 - 1e-9 {
                    continue;
                }
                match kind {
                    JointKind::Revolute => {
                        let r = o - fr.axis_points[j];
                        if (r - u * r.dot(&u)).norm() < 1e-9 {
                            out.push(Aggregation { joint: j, spring: s, entry: 3 + a });
                        }
                    }
                    JointKind::Prismatic => out.push(Aggregation { joint: j, spring: s, entry: a }),
                }
            }
        }
        Ok(out)
    }

    /// Frame names a [`WrenchSpec`] may use.
    pub fn frame_names(&self) -> Vec<String> {
        let mut v: Vec<String> = ["base", "world", "flange", "tool"].iter().map(|s| s.to_string()).collect();
        v.extend((0..=self.dof()).map(|i| format!("link{i}")));
        v.extend(self.chain.joints.iter().map(|j| j.name.clone()));
        v
    }

    /// `T_base_frame` of a frame a [`WrenchSpec`] may name, at `q`.
    pub fn frame_pose(&self, q: &[f64], frame: &str) -> Result<Pose> {
        let frames = self.chain.frames(q)?;
        self.frame_pose_at(&frames, frame)
    }

    fn frame_pose_at(&self, frames: &ChainFrames, frame: &str) -> Result<Pose> {
        let name = frame.trim();
        let lname = name.to_ascii_lowercase();
        Ok(match lname.as_str() {
            "world" => Pose::identity(),
            "base" => self.chain.base,
            "flange" => frames.flange,
            "tool" => frames.tool,
            _ => {
                let link = lname
                    .strip_prefix("link")
                    .and_then(|r| r.parse::<usize>().ok())
                    .filter(|l| *l <= self.dof())
                    .or_else(|| self.chain.joints.iter().position(|j| j.name == name).map(|i| i + 1));
                match link {
                    Some(l) => self.link_pose(frames, l),
                    None => {
                        return Err(StiffnessError::UnknownFrame { name: frame.to_string(), known: self.frame_names() })
                    }
                }
            }
        })
    }

    /// The wrench of `spec` at `q` in base axes about the tool point, checked against `limits`.
    pub fn resolve_wrench(&self, q: &[f64], spec: &WrenchSpec, limits: &WrenchLimits) -> Result<Wrench> {
        let frames = self.chain.frames(q)?;
        let t = self.frame_pose_at(&frames, &spec.frame)?;
        let f_local = Vector3::from(spec.force_n);
        let m_local = Vector3::from(spec.torque_nm);
        let local = Wrench::new(f_local, m_local);
        local.check(limits)?;
        if spec.point_m.iter().any(|v| !v.is_finite()) {
            return Err(StiffnessError::ImplausibleWrench { reason: "point of application is not finite".into() });
        }
        let f = t.rotation * f_local;
        let m = t.rotation * m_local;
        let p_app = t * Point3::from(spec.point_m);
        let p_tool = Point3::from(frames.tool.translation.vector);
        let w = Wrench::new(f, m).moved(&p_app, &p_tool);
        w.check(limits)?;
        Ok(w)
    }
}
