//! URDF import: the chain from the root link to a tip link, with limits and inertials.
//!
//! Fixed joints are folded into the next actuated joint's origin (or into the tool frame when
//! they come after the last actuated joint); the inertials of links hanging on fixed joints are
//! merged into the moving link that carries them.
//!
//! A tree's branches off the chosen chain (the other arm on a torso, a gripper's fingers) are not
//! joints of the chain, but their weight is: each branch is lumped (mass, centre of mass, inertia
//! by the parallel-axis theorem) into the chain link it hangs on, with the branch's own joints at
//! zero (a mimic joint at its offset). A branch that moves between the recorded poses is
//! therefore carried as if it stood still at zero: its torque on the shared joints is right only
//! on average.
//!
//! A `<mimic joint="leader" multiplier="m" offset="o"/>` joint becomes a coupled joint of the
//! chain ([`Mimic`], `q = m q_leader + o`; defaults `m = 1`, `o = 0`). Its leader must be an
//! actuated (not mimic, not fixed) joint on the same root-to-tip chain; otherwise the file is
//! refused with the mimic joint named.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Matrix3, Translation3, Vector3};
use roxmltree::{Document, Node};

use super::{Inertial, Joint, JointGeometry, Mimic, SerialChain};
use crate::error::{check_finite, Location, Result, RobotError};
use crate::geometry::{rpy, Pose};
use crate::kinematics::{JointKind, JointLimits};

/// Choices when a URDF is a tree rather than a chain.
#[derive(Clone, Debug, Default)]
pub struct UrdfOptions {
    /// The link to end the chain at. Default: the leaf reached through the most actuated joints
    /// (the first in document order on a tie).
    pub tip_link: Option<String>,
}

/// Reads and parses a URDF file.
pub fn parse_urdf(path: &Path, opts: &UrdfOptions) -> Result<SerialChain> {
    let text = std::fs::read_to_string(path).map_err(|source| RobotError::Io { path: path.to_path_buf(), source })?;
    parse_urdf_impl(&text, path.to_path_buf(), opts)
}

/// Parses URDF text (errors name `<string>` as the file).
pub fn parse_urdf_str(text: &str, opts: &UrdfOptions) -> Result<SerialChain> {
    parse_urdf_impl(text, PathBuf::from("<string>"), opts)
}

pub(super) struct Ctx<'a> {
    file: PathBuf,
    doc: &'a Document<'a>,
}

impl Ctx<'_> {
    pub(super) fn loc(&self, node: Node) -> Location {
        let pos = self.doc.text_pos_at(node.range().start);
        Location { file: self.file.clone(), line: pos.row, column: pos.col }
    }

    pub(super) fn err(&self, node: Node, message: impl Into<String>) -> RobotError {
        RobotError::Parse { location: self.loc(node), message: message.into() }
    }

    fn floats(&self, node: Node, attr: &str, n: usize, what: &str) -> Result<Vec<f64>> {
        let Some(s) = node.attribute(attr) else {
            return Err(self.err(node, format!("{what}: missing attribute '{attr}'")));
        };
        let parts: Vec<&str> = s.split_whitespace().collect();
        if parts.len() != n {
            return Err(
                self.err(node, format!("{what}: attribute '{attr}' needs {n} numbers, found {} ('{s}')", parts.len()))
            );
        }
        parts
            .iter()
            .map(|p| {
                let v: f64 =
                    p.parse().map_err(|_| self.err(node, format!("{what}: '{p}' in '{attr}' is not a number")))?;
                // The location is computed only for an error: finding a node's line scans the
                // text from its start, so computing it for every number made parsing quadratic.
                if v.is_finite() {
                    Ok(v)
                } else {
                    check_finite(v, &self.loc(node), &format!("{what} ('{attr}')"))
                }
            })
            .collect()
    }

    fn float(&self, node: Node, attr: &str, what: &str) -> Result<Option<f64>> {
        if node.attribute(attr).is_none() {
            return Ok(None);
        }
        Ok(Some(self.floats(node, attr, 1, what)?[0]))
    }

    fn origin(&self, parent: Node, what: &str) -> Result<Pose> {
        let Some(o) = child(parent, "origin") else {
            return Ok(Isometry3::identity());
        };
        let xyz = if o.has_attribute("xyz") { self.floats(o, "xyz", 3, what)? } else { vec![0.0; 3] };
        let r = if o.has_attribute("rpy") { self.floats(o, "rpy", 3, what)? } else { vec![0.0; 3] };
        Ok(Isometry3::from_parts(Translation3::new(xyz[0], xyz[1], xyz[2]), rpy(r[0], r[1], r[2])))
    }
}

fn child<'a, 'i>(node: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    node.children().find(|c| c.is_element() && c.tag_name().name() == name)
}

/// A parsed URDF joint before chain extraction.
pub(super) struct RawJoint<'a, 'i> {
    pub(super) node: Node<'a, 'i>,
    pub(super) name: String,
    pub(super) kind: Option<JointKind>, // None = fixed
    pub(super) parent: String,
    pub(super) child: String,
    pub(super) origin: Pose,
    pub(super) axis: Vector3<f64>,
    pub(super) limits: JointLimits,
    /// `<mimic>`: the element, leader name, multiplier, offset.
    pub(super) mimic: Option<(Node<'a, 'i>, String, f64, f64)>,
}

impl RawJoint<'_, '_> {
    /// The chain's joint of this moving joint of kind `kind`, its origin `origin` (the URDF
    /// origin with the fixed joints before it folded in).
    pub(super) fn moving(&self, kind: JointKind, origin: &Pose) -> Joint {
        let (roll, pitch, yaw) = origin.rotation.euler_angles();
        Joint {
            name: self.name.clone(),
            kind,
            geometry: JointGeometry::Origin {
                xyz_m: origin.translation.vector.into(),
                rpy_rad: [roll, pitch, yaw],
                axis: self.axis.into(),
            },
            limits: self.limits,
            inertial: None,
            correction: [0.0; 6],
            mimic: self.mimic.as_ref().map(|(_, leader, multiplier, offset)| Mimic {
                leader: leader.clone(),
                multiplier: *multiplier,
                offset: *offset,
            }),
        }
    }
}

/// A URDF's links and joints, checked to form one tree.
pub(super) struct Raw<'a, 'i> {
    pub(super) robot_name: String,
    pub(super) root: Node<'a, 'i>,
    pub(super) links: HashMap<String, Node<'a, 'i>>,
    pub(super) link_order: Vec<String>,
    pub(super) inertials: HashMap<String, RawInertial>,
    pub(super) joints: Vec<RawJoint<'a, 'i>>,
    /// Per link, the joints it carries.
    pub(super) children: HashMap<String, Vec<usize>>,
    /// Per link reachable from the root: (actuated joints above it, the joint that reaches it).
    pub(super) depth: HashMap<String, (usize, Option<usize>)>,
    pub(super) root_link: String,
}

/// A link's inertial in its own frame: mass, com, inertia about com.
#[derive(Clone, Copy)]
pub(super) struct RawInertial {
    pub(super) mass: f64,
    pub(super) com: Vector3<f64>,
    pub(super) inertia: Matrix3<f64>,
}

impl RawInertial {
    /// Expressed in a frame F where `t_f_link` maps link coordinates to F.
    pub(super) fn transformed(&self, t_f_link: &Pose) -> RawInertial {
        let r = t_f_link.rotation.to_rotation_matrix();
        RawInertial {
            mass: self.mass,
            com: (t_f_link * nalgebra::Point3::from(self.com)).coords,
            inertia: r.matrix() * self.inertia * r.matrix().transpose(),
        }
    }

    pub(super) fn merged(a: RawInertial, b: RawInertial) -> RawInertial {
        let m = a.mass + b.mass;
        if m <= 0.0 {
            return a;
        }
        let com = (a.com * a.mass + b.com * b.mass) / m;
        let shift = |i: &RawInertial| {
            let d = i.com - com;
            i.inertia + i.mass * (Matrix3::identity() * d.norm_squared() - d * d.transpose())
        };
        RawInertial { mass: m, com, inertia: shift(&a) + shift(&b) }
    }
}

fn parse_urdf_impl(text: &str, file: PathBuf, opts: &UrdfOptions) -> Result<SerialChain> {
    with_raw(text, file, |ctx, raw| chain_from_raw(ctx, raw, opts))
}

/// Parses `text`, checks that its joints form one tree and hands the result to `f`.
pub(super) fn with_raw<T>(text: &str, file: PathBuf, f: impl FnOnce(&Ctx, Raw) -> Result<T>) -> Result<T> {
    let doc = Document::parse(text).map_err(|e| {
        let pos = e.pos();
        RobotError::Parse {
            location: Location { file: file.clone(), line: pos.row, column: pos.col },
            message: format!("not valid XML: {e}"),
        }
    })?;
    let ctx = Ctx { file, doc: &doc };
    let root = doc.root_element();
    if root.tag_name().name() != "robot" {
        return Err(ctx.err(root, "the top element must be <robot>"));
    }
    let robot_name = root.attribute("name").unwrap_or("urdf").to_string();

    // Links and their inertials.
    let mut links: HashMap<String, Node> = HashMap::new();
    let mut link_order: Vec<String> = Vec::new();
    let mut inertials: HashMap<String, RawInertial> = HashMap::new();
    for l in root.children().filter(|c| c.is_element() && c.tag_name().name() == "link") {
        let name = l.attribute("name").ok_or_else(|| ctx.err(l, "<link> without a name"))?.to_string();
        if links.insert(name.clone(), l).is_some() {
            return Err(ctx.err(l, format!("link '{name}' is defined twice")));
        }
        link_order.push(name.clone());
        if let Some(inr) = child(l, "inertial") {
            let what = format!("inertial of link '{name}'");
            let origin = ctx.origin(inr, &what)?;
            let mass_node = child(inr, "mass").ok_or_else(|| ctx.err(inr, format!("{what}: missing <mass>")))?;
            let mass = ctx
                .float(mass_node, "value", &what)?
                .ok_or_else(|| ctx.err(mass_node, format!("{what}: <mass> needs 'value'")))?;
            if mass < 0.0 {
                return Err(ctx.err(mass_node, format!("{what}: negative mass {mass}")));
            }
            let mut inertia = Matrix3::zeros();
            if let Some(i) = child(inr, "inertia") {
                let g = |a: &str| -> Result<f64> { Ok(ctx.float(i, a, &what)?.unwrap_or(0.0)) };
                let (ixx, ixy, ixz, iyy, iyz, izz) = (g("ixx")?, g("ixy")?, g("ixz")?, g("iyy")?, g("iyz")?, g("izz")?);
                inertia = Matrix3::new(ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz);
            }
            // Inertia in the inertial frame -> link frame; com = origin translation.
            let r = origin.rotation.to_rotation_matrix();
            inertials.insert(
                name.clone(),
                RawInertial {
                    mass,
                    com: origin.translation.vector,
                    inertia: r.matrix() * inertia * r.matrix().transpose(),
                },
            );
        }
    }

    // Joints.
    let mut joints: Vec<RawJoint> = Vec::new();
    let mut child_of: HashMap<String, usize> = HashMap::new();
    for j in root.children().filter(|c| c.is_element() && c.tag_name().name() == "joint") {
        let name = j.attribute("name").ok_or_else(|| ctx.err(j, "<joint> without a name"))?.to_string();
        let ty = j.attribute("type").ok_or_else(|| ctx.err(j, format!("joint '{name}' has no type")))?;
        let kind = match ty {
            "revolute" | "continuous" => Some(JointKind::Revolute),
            "prismatic" => Some(JointKind::Prismatic),
            "fixed" => None,
            other => {
                return Err(ctx.err(
                    j,
                    format!("joint '{name}': type '{other}' is not supported (revolute, continuous, prismatic, fixed)"),
                ))
            }
        };
        let mimic = match child(j, "mimic") {
            None => None,
            Some(m) => {
                let what = format!("joint '{name}': <mimic>");
                let Some(leader) = m.attribute("joint") else {
                    return Err(ctx.err(m, format!("{what} needs a 'joint' attribute (the leader)")));
                };
                if kind.is_none() {
                    return Err(ctx.err(m, format!("{what}: a fixed joint cannot follow joint '{leader}'")));
                }
                if leader == name {
                    return Err(ctx.err(m, format!("{what}: the joint cannot follow itself")));
                }
                let multiplier = ctx.float(m, "multiplier", &what)?.unwrap_or(1.0);
                let offset = ctx.float(m, "offset", &what)?.unwrap_or(0.0);
                Some((m, leader.to_string(), multiplier, offset))
            }
        };
        let link_attr = |tag: &str| -> Result<String> {
            let n = child(j, tag).ok_or_else(|| ctx.err(j, format!("joint '{name}' has no <{tag}>")))?;
            n.attribute("link")
                .map(str::to_string)
                .ok_or_else(|| ctx.err(n, format!("joint '{name}': <{tag}> needs a 'link' attribute")))
        };
        let parent = link_attr("parent")?;
        let child_link = link_attr("child")?;
        if !links.contains_key(&parent) {
            return Err(ctx.err(j, format!("joint '{name}': parent link '{parent}' is not defined")));
        }
        if !links.contains_key(&child_link) {
            return Err(ctx.err(j, format!("joint '{name}': child link '{child_link}' is not defined")));
        }
        let what = format!("joint '{name}'");
        let origin = ctx.origin(j, &what)?;
        let axis = match child(j, "axis") {
            Some(a) => {
                let v = ctx.floats(a, "xyz", 3, &what)?;
                let v = Vector3::new(v[0], v[1], v[2]);
                if v.norm() < 1e-12 {
                    return Err(ctx.err(a, format!("{what}: axis is zero")));
                }
                v.normalize()
            }
            None => Vector3::x(),
        };
        let mut limits = JointLimits::UNBOUNDED;
        if ty == "revolute" || ty == "prismatic" {
            if let Some(l) = child(j, "limit") {
                let lower = ctx.float(l, "lower", &what)?.unwrap_or(0.0);
                let upper = ctx.float(l, "upper", &what)?.unwrap_or(0.0);
                if lower > upper {
                    return Err(RobotError::BadLimits {
                        joint: name.clone(),
                        lower,
                        upper,
                        location: Some(ctx.loc(l)),
                    });
                }
                limits = JointLimits { lower, upper };
            } else {
                return Err(ctx.err(j, format!("{what}: a {ty} joint needs <limit lower=.. upper=..>")));
            }
        }
        if let Some(prev) = child_of.get(&child_link) {
            return Err(RobotError::Structure {
                location: ctx.loc(j),
                message: format!(
                    "link '{child_link}' is the child of two joints ('{}' and '{name}'): a kinematic loop; URDF describes trees only",
                    joints[*prev].name
                ),
            });
        }
        child_of.insert(child_link.clone(), joints.len());
        joints.push(RawJoint { node: j, name, kind, parent, child: child_link, origin, axis, limits, mimic });
    }

    // Root: the link that is nobody's child.
    let roots: Vec<&String> = link_order.iter().filter(|l| !child_of.contains_key(*l)).collect();
    if roots.is_empty() {
        return Err(RobotError::Structure {
            location: ctx.loc(root),
            message: "every link is the child of a joint: the joints form a loop".into(),
        });
    }
    if roots.len() > 1 {
        return Err(RobotError::Structure {
            location: ctx.loc(links[roots[1]]),
            message: format!(
                "more than one root link ({}): every link but one must be the child of a joint",
                roots.iter().map(|s| s.as_str()).collect::<Vec<_>>().join(", ")
            ),
        });
    }
    let root_link = roots[0].clone();

    // Children lists, and a walk from the root that also detects cycles.
    let mut children: HashMap<String, Vec<usize>> = HashMap::new();
    for (k, j) in joints.iter().enumerate() {
        children.entry(j.parent.clone()).or_default().push(k);
    }
    // Depth (in actuated joints) of every link reachable from the root.
    let mut depth: HashMap<String, (usize, Option<usize>)> = HashMap::new(); // link -> (actuated count, joint that reaches it)
    depth.insert(root_link.clone(), (0, None));
    let mut stack = vec![root_link.clone()];
    while let Some(l) = stack.pop() {
        let d = depth[&l].0;
        for &k in children.get(l.as_str()).map(|v| v.as_slice()).unwrap_or(&[]) {
            let j = &joints[k];
            if depth.contains_key(&j.child) {
                return Err(RobotError::Structure {
                    location: ctx.loc(j.node),
                    message: format!("joint '{}' closes a loop back to link '{}'", j.name, j.child),
                });
            }
            depth.insert(j.child.clone(), (d + usize::from(j.kind.is_some()), Some(k)));
            stack.push(j.child.clone());
        }
    }
    if let Some(j) = joints.iter().find(|j| !depth.contains_key(&j.child)) {
        return Err(RobotError::Structure {
            location: ctx.loc(j.node),
            message: format!("joint '{}' is not connected to the root link '{root_link}' (a detached loop)", j.name),
        });
    }
    let raw = Raw { robot_name, root, links, link_order, inertials, joints, children, depth, root_link };
    f(&ctx, raw)
}

/// The chain from the root to the chosen tip, the branches off it lumped into it.
fn chain_from_raw(ctx: &Ctx, raw: Raw, opts: &UrdfOptions) -> Result<SerialChain> {
    let Raw { robot_name, root, links, link_order, inertials, joints, children, depth, root_link } = raw;

    let tip = match &opts.tip_link {
        Some(t) => {
            if !links.contains_key(t) {
                return Err(ctx.err(root, format!("tip link '{t}' is not defined")));
            }
            t.clone()
        }
        None => {
            let mut best: Option<(&String, usize)> = None;
            for l in &link_order {
                if children.contains_key(l.as_str()) {
                    continue; // not a leaf
                }
                let d = depth[l].0;
                if best.is_none_or(|(_, bd)| d > bd) {
                    best = Some((l, d));
                }
            }
            best.map(|(l, _)| l.clone()).unwrap_or(root_link.clone())
        }
    };

    // The path root -> tip, as joint indices.
    let mut path = Vec::new();
    let mut cur = tip.clone();
    while let Some(k) = depth[&cur].1 {
        path.push(k);
        cur = joints[k].parent.clone();
    }
    path.reverse();
    check_mimics(ctx, &joints, &path, &root_link, &tip)?;

    // Each link of the chain carries, besides its own inertial, every branch that hangs on it off
    // the chain (the other arm of a dual-arm torso, a gripper's fingers), lumped at the branch
    // joints' zero positions (a mimic joint at its offset).
    let on_path: std::collections::HashSet<usize> = path.iter().copied().collect();
    let mut lumped = inertials.clone();
    for &k in &path {
        let link = joints[k].child.as_str();
        for &c in children.get(link).map(|v| v.as_slice()).unwrap_or(&[]) {
            if on_path.contains(&c) {
                continue;
            }
            if let Some(sub) = subtree_inertial(&joints, &children, &inertials, c) {
                lumped.insert(
                    link.to_string(),
                    match lumped.get(link) {
                        Some(own) => RawInertial::merged(*own, sub),
                        None => sub,
                    },
                );
            }
        }
    }
    let inertials = lumped;

    // Fold fixed joints; collect inertials of links carried by each actuated joint.
    let mut out_joints: Vec<Joint> = Vec::new();
    let mut pending = Isometry3::identity(); // fixed transform since the last actuated frame
    let mut carried: Vec<Option<RawInertial>> = Vec::new();
    for &k in &path {
        let j = &joints[k];
        match j.kind {
            None => {
                pending *= j.origin;
                if let (Some(inr), Some(last)) = (inertials.get(&j.child), carried.last_mut()) {
                    let moved = inr.transformed(&pending);
                    *last = Some(match last {
                        Some(prev) => RawInertial::merged(*prev, moved),
                        None => moved,
                    });
                }
            }
            Some(kind) => {
                let origin = pending * j.origin;
                pending = Isometry3::identity();
                out_joints.push(j.moving(kind, &origin));
                carried.push(inertials.get(&j.child).copied());
            }
        }
    }
    if out_joints.is_empty() {
        return Err(ctx.err(root, format!("no actuated joint between root '{root_link}' and tip '{tip}'")));
    }
    for (j, c) in out_joints.iter_mut().zip(carried) {
        j.inertial = c.map(|c| Inertial {
            mass_kg: c.mass,
            com_m: c.com.into(),
            inertia_kgm2: c.inertia.transpose().as_slice().try_into().expect("3x3"),
        });
    }
    let mut chain = SerialChain::new(&robot_name, out_joints);
    chain.tool = pending;
    Ok(chain)
}

/// The inertial of the branch that joint `k` starts (its child link and everything below it),
/// in the frame of joint `k`'s parent link, with the branch's joints at zero (a mimic joint at its
/// offset); `None` when nothing in it has mass.
fn subtree_inertial(
    joints: &[RawJoint],
    children: &HashMap<String, Vec<usize>>,
    inertials: &HashMap<String, RawInertial>,
    k: usize,
) -> Option<RawInertial> {
    let j = &joints[k];
    let q = j.mimic.as_ref().map_or(0.0, |(_, _, _, offset)| *offset);
    let motion = match j.kind {
        Some(JointKind::Revolute) => {
            Isometry3::from_parts(Translation3::identity(), nalgebra::UnitQuaternion::from_scaled_axis(j.axis * q))
        }
        Some(JointKind::Prismatic) => Isometry3::translation(j.axis.x * q, j.axis.y * q, j.axis.z * q),
        None => Isometry3::identity(),
    };
    let t_parent_child = j.origin * motion;
    let mut acc = inertials.get(&j.child).copied();
    for &c in children.get(j.child.as_str()).map(|v| v.as_slice()).unwrap_or(&[]) {
        if let Some(sub) = subtree_inertial(joints, children, inertials, c) {
            acc = Some(match acc {
                Some(a) => RawInertial::merged(a, sub),
                None => sub,
            });
        }
    }
    acc.filter(|a| a.mass > 0.0).map(|a| a.transformed(&t_parent_child))
}

/// Every mimic joint on the chain `path` must follow an actuated joint on the same chain.
pub(super) fn check_mimics(ctx: &Ctx, joints: &[RawJoint], path: &[usize], root: &str, tip: &str) -> Result<()> {
    for &k in path {
        let Some((node, leader, _, _)) = &joints[k].mimic else { continue };
        let name = &joints[k].name;
        let Some(l) = joints.iter().position(|j| &j.name == leader) else {
            return Err(ctx.err(*node, format!("joint '{name}' mimics joint '{leader}', which is not defined")));
        };
        let lj = &joints[l];
        if let Some((_, ll, _, _)) = &lj.mimic {
            return Err(ctx.err(
                *node,
                format!(
                    "joint '{name}' mimics joint '{leader}', which is itself a mimic joint (of '{ll}'); a mimic joint must follow an actuated joint"
                ),
            ));
        }
        if lj.kind.is_none() {
            return Err(ctx.err(*node, format!("joint '{name}' mimics joint '{leader}', which is fixed")));
        }
        if !path.contains(&l) {
            return Err(ctx.err(
                *node,
                format!("joint '{name}' mimics joint '{leader}', which is not on the chain from '{root}' to '{tip}'"),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chain_urdf(n: usize, mimic: bool) -> String {
        let mut s = String::from("<robot name=\"long\">\n<link name=\"l0\"/>\n");
        for i in 1..=n {
            let m = if mimic && i == 2 { "<mimic joint=\"j1\" multiplier=\"1\"/>" } else { "" };
            s.push_str(&format!(
                "<link name=\"l{i}\"/>\n<joint name=\"j{i}\" type=\"revolute\"><parent link=\"l{}\"/><child link=\"l{i}\"/>\
                 <origin xyz=\"0 0 0.01\" rpy=\"0 0 0\"/><axis xyz=\"0 0 1\"/><limit lower=\"-3\" upper=\"3\"/>{m}</joint>\n",
                i - 1
            ));
        }
        s.push_str("</robot>\n");
        s
    }

    #[test]
    fn urdf_mimic_joint_is_a_coupled_joint() {
        use crate::Kinematics;
        let c = parse_urdf_str(&chain_urdf(3, true), &UrdfOptions::default()).unwrap();
        assert_eq!((c.joints.len(), c.dof()), (3, 2));
        assert_eq!(c.joint_names(), ["j1", "j3"]);
        let m = c.joints[1].mimic.as_ref().unwrap();
        assert_eq!((m.leader.as_str(), m.multiplier, m.offset), ("j1", 1.0, 0.0));
        assert_eq!(parse_urdf_str(&chain_urdf(3, false), &UrdfOptions::default()).unwrap().joints.len(), 3);
    }

    #[test]
    fn a_branch_off_the_chain_weighs_on_the_link_it_hangs_on() {
        // A torso pitch joint carrying two one-joint arms; the chain runs to the left hand, the
        // right arm (3 kg at 0.2 m and 1 kg on a fixed hand at 0.3 m, both 0.1 m behind) hangs
        // on the torso. At q = 0 every lever is along x.
        let inertial = |m: f64, x: f64| {
            format!("<inertial><origin xyz=\"{x} 0 0\"/><mass value=\"{m}\"/><inertia ixx=\"0.01\" iyy=\"0.01\" izz=\"0.01\"/></inertial>")
        };
        let joint = |name: &str, kind: &str, parent: &str, child: &str, xyz: &str| {
            format!(
                "<joint name=\"{name}\" type=\"{kind}\"><parent link=\"{parent}\"/><child link=\"{child}\"/>\
                 <origin xyz=\"{xyz}\"/><axis xyz=\"0 1 0\"/><limit lower=\"-3\" upper=\"3\"/></joint>"
            )
        };
        let text = format!(
            "<robot name=\"torso\"><link name=\"base\"/><link name=\"torso\">{}</link><link name=\"left\">{}</link>\
             <link name=\"right\">{}</link><link name=\"right_hand\">{}</link>{}{}{}{}</robot>",
            inertial(10.0, 0.05),
            inertial(2.0, 0.15),
            inertial(3.0, 0.2),
            inertial(1.0, 0.0),
            joint("pitch", "revolute", "base", "torso", "0 0 0.5"),
            joint("left1", "revolute", "torso", "left", "0 0.2 0.4"),
            joint("right1", "revolute", "torso", "right", "-0.1 -0.2 0.4"),
            joint("right_fix", "fixed", "right", "right_hand", "0.3 0 0"),
        );
        let opts = UrdfOptions { tip_link: Some("left".into()) };
        let chain = parse_urdf_str(&text, &opts).unwrap();
        assert_eq!(chain.joints.len(), 2);
        assert!((chain.total_mass_kg() - 16.0).abs() < 1e-12, "{}", chain.total_mass_kg());
        let g = -chain.gravity_m_s2[2];
        let tau = chain.gravity_torques(&[0.0, 0.0], 0.0).unwrap();
        // Actuators hold gravity: tau_y = -sum(m g x) about each axis (x of the axis is 0 for
        // the torso; the left arm's axis is at x = 0).
        let torso = -(10.0 * 0.05 + 2.0 * 0.15 + 3.0 * (0.2 - 0.1) + 1.0 * (0.3 - 0.1)) * g;
        assert!((tau[0] - torso).abs() < 1e-9, "torso {} vs {torso}", tau[0]);
        assert!((tau[1] + 2.0 * 0.15 * g).abs() < 1e-9, "left arm {}", tau[1]);
    }

    #[test]
    fn urdf_parsing_is_linear_in_the_joint_count() {
        // 5000 joints took about 25 s when every number computed its line (quadratic); linear
        // parsing takes well under a second even in the dev profile.
        let text = chain_urdf(5000, false);
        let t0 = std::time::Instant::now();
        let chain = parse_urdf_str(&text, &UrdfOptions::default()).unwrap();
        let secs = t0.elapsed().as_secs_f64();
        assert_eq!(chain.joints.len(), 5000);
        assert!(secs < 5.0, "5000-joint URDF parsed in {secs:.2} s");
    }
}
