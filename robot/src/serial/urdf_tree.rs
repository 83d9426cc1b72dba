//! URDF import of a whole tree: every moving joint in the file's order, each link's inertial on
//! the joint that moves it, and the measurable tips (see `tree.rs`).
//!
//! Fixed joints are folded into the next moving joint's origin (or into a tip's transform); the
//! inertial of a link hanging on fixed joints is merged into the moving link that carries it
//! (links carried by no moving joint weigh on the base and are left out). No branch is lumped:
//! every link is placed by its own joints' values.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::Isometry3;

use super::tree::{ChainTree, TreeTip};
use super::urdf::{check_mimics, with_raw, Ctx, Raw, RawInertial};
use super::{Inertial, SerialChain};
use crate::error::{Result, RobotError};
use crate::geometry::Pose;

/// Reads a URDF as a tree of chains with the measurable `tips` (link names; empty: every leaf
/// link, in the file's link order).
pub fn parse_urdf_tree(path: &Path, tips: &[String]) -> Result<SerialChain> {
    let text = std::fs::read_to_string(path).map_err(|source| RobotError::Io { path: path.to_path_buf(), source })?;
    with_raw(&text, path.to_path_buf(), |ctx, raw| tree_from_raw(ctx, raw, tips))
}

/// [`parse_urdf_tree`] of URDF text (errors name `<string>` as the file).
pub fn parse_urdf_tree_str(text: &str, tips: &[String]) -> Result<SerialChain> {
    with_raw(text, PathBuf::from("<string>"), |ctx, raw| tree_from_raw(ctx, raw, tips))
}

/// How many actuated (moving, not mimic) joints the URDF at `path` has in all its branches.
pub fn urdf_tree_joint_count(path: &Path) -> Result<usize> {
    use crate::Kinematics;
    Ok(parse_urdf_tree(path, &[])?.dof())
}

/// The nearest moving joint above link `link` (raw index) and the fixed transform from its link
/// frame to `link`'s frame; `None` when only fixed joints lead to the root.
fn carrier(raw: &Raw, link: &str) -> (Option<usize>, Pose) {
    let mut t = Isometry3::identity();
    let mut cur = link.to_string();
    while let Some(k) = raw.depth[&cur].1 {
        let j = &raw.joints[k];
        if j.kind.is_some() {
            return (Some(k), t);
        }
        t = j.origin * t;
        cur = j.parent.clone();
    }
    (None, t)
}

fn tree_from_raw(ctx: &Ctx, raw: Raw, tips: &[String]) -> Result<SerialChain> {
    // Moving joints in file order; raw index -> output index.
    let moving: Vec<usize> = (0..raw.joints.len()).filter(|&k| raw.joints[k].kind.is_some()).collect();
    let out_of: HashMap<usize, usize> = moving.iter().enumerate().map(|(o, &k)| (k, o)).collect();
    if moving.is_empty() {
        return Err(ctx.err(raw.root, "the URDF has no moving joint"));
    }
    check_mimics(ctx, &raw.joints, &moving, &raw.root_link, "every tip")?;
    let mut parent = Vec::with_capacity(moving.len());
    let mut joints = Vec::with_capacity(moving.len());
    for (o, &k) in moving.iter().enumerate() {
        let j = &raw.joints[k];
        let (up, fixed) = carrier(&raw, &j.parent);
        let p = up.map(|u| out_of[&u]);
        if let (Some(p), Some(u)) = (p, up) {
            if p > o {
                return Err(ctx.err(
                    j.node,
                    format!(
                        "joint '{}' is listed before the joint that carries it ('{}'): a tree's table numbers its joints in the file's order, so list every joint after its parent",
                        j.name, raw.joints[u].name
                    ),
                ));
            }
        }
        parent.push(p);
        joints.push(j.moving(j.kind.expect("moving"), &(fixed * j.origin)));
    }
    // Every link's inertial on the moving joint that carries it.
    let mut carried: Vec<Option<RawInertial>> = vec![None; joints.len()];
    for l in &raw.link_order {
        let (Some(inr), Some(&(_, Some(_)))) = (raw.inertials.get(l), raw.depth.get(l)) else { continue };
        let (Some(up), t) = carrier(&raw, l) else { continue };
        let moved = inr.transformed(&t);
        let slot = &mut carried[out_of[&up]];
        *slot = Some(match slot {
            Some(prev) => RawInertial::merged(*prev, moved),
            None => moved,
        });
    }
    for (j, c) in joints.iter_mut().zip(carried) {
        j.inertial = c.filter(|c| c.mass > 0.0).map(|c| Inertial {
            mass_kg: c.mass,
            com_m: c.com.into(),
            inertia_kgm2: c.inertia.transpose().as_slice().try_into().expect("3x3"),
        });
    }
    // Tips: the named links, or every leaf.
    let names: Vec<String> = if tips.is_empty() {
        raw.link_order.iter().filter(|l| !raw.children.contains_key(l.as_str())).cloned().collect()
    } else {
        tips.to_vec()
    };
    let mut tree_tips = Vec::with_capacity(names.len());
    for name in &names {
        if !raw.links.contains_key(name) {
            let mut known: Vec<&str> = raw.link_order.iter().map(String::as_str).collect();
            known.truncate(40);
            return Err(ctx.err(raw.root, format!("tip link '{name}' is not defined (links: {})", known.join(", "))));
        }
        let (Some(up), tool) = carrier(&raw, name) else {
            return Err(ctx.err(raw.links[name], format!("tip link '{name}' is not moved by any joint")));
        };
        tree_tips.push(TreeTip { link: name.clone(), joint: out_of[&up], tool });
    }
    if tree_tips.is_empty() {
        return Err(ctx.err(raw.root, "the URDF has no tip link"));
    }
    let mut chain = SerialChain::new(&raw.robot_name, joints);
    chain.tool = tree_tips[0].tool;
    chain.tree = Some(ChainTree { parent, tips: tree_tips, active: 0 });
    chain.sources()?;
    Ok(chain)
}
