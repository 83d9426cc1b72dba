//! Robots with several chains (`docs/trees.md`): which model a table calls for, and the warning
//! when a table leaves out the motion of a branch that loads the measured chain.

use std::path::Path;

use ferrocal_calib::PoseMeasurement;
use ferrocal_robot::serial::{parse_urdf, parse_urdf_tree, SerialChain, UrdfOptions};
use ferrocal_robot::{Kinematics, RobotModel};

use crate::error::{DatasetError, Result};

/// The tips the rows name ([`PoseMeasurement::tip`]), in the order they first appear.
pub fn tips_of(rows: &[PoseMeasurement]) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for t in rows.iter().filter_map(PoseMeasurement::tip) {
        if !out.iter().any(|o| o == t) {
            out.push(t.to_string());
        }
    }
    out
}

fn is_urdf(robot: &str) -> bool {
    let ext = Path::new(robot).extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    matches!(ext.as_deref(), Some("urdf") | Some("xml"))
}

/// The model `robot` names, read for a table of `n_joints` joint columns whose rows are `rows`:
/// a URDF tree whole when the rows name tips or the table holds every moving joint of the tree,
/// else as before (a preset, a model file, or the URDF's chain to its deepest leaf). In the
/// last case `warn` hears when the tree has moving branches with mass that the table leaves out.
pub fn load_for_table(
    robot: &str,
    measurements: &Path,
    rows: &[PoseMeasurement],
    n_joints: usize,
    warn: &dyn Fn(&str),
) -> Result<RobotModel> {
    let load_err =
        |e: ferrocal_robot::RobotError| DatasetError::from(e).context(format!("cannot load robot model '{robot}'"));
    let tips = tips_of(rows);
    if !is_urdf(robot) {
        if let Some(t) = tips.first() {
            return Err(DatasetError::Input(format!(
                "{}: the rows name the measured link '{t}' (a tip column or --tip), but '{robot}' is not a URDF: only a URDF describes a tree of chains",
                measurements.display()
            )));
        }
        return RobotModel::load(robot).map_err(load_err);
    }
    let path = Path::new(robot);
    let tree = parse_urdf_tree(path, &tips).map_err(load_err)?;
    if !tips.is_empty() || (n_joints == tree.dof() && tree.tip_names().len() > 1) {
        return Ok(RobotModel::Serial(tree));
    }
    let chain = parse_urdf(path, &UrdfOptions::default()).map_err(load_err)?;
    if n_joints == chain.dof() && tree.dof() > chain.dof() {
        if let Some(w) = missing_branch_warning(&tree, &chain, measurements) {
            warn(&w);
        }
    }
    Ok(RobotModel::Serial(chain))
}

/// The warning for a table that holds only `chain`'s joints of `tree`: the moving joints of the
/// tree that are not in the chain and carry mass, or `None` when they carry none.
pub fn missing_branch_warning(tree: &SerialChain, chain: &SerialChain, measurements: &Path) -> Option<String> {
    let names = chain.joint_names();
    let tr = tree.tree.as_ref()?;
    let missing: Vec<usize> = (0..tree.joints.len())
        .filter(|&i| tree.joints[i].mimic.is_none() && !names.contains(&tree.joints[i].name))
        .collect();
    // The mass each missing joint moves (its link and everything below it).
    let moved_kg = |i: usize| -> f64 {
        (0..tree.joints.len())
            .filter(|&k| tr.moves(i, k))
            .filter_map(|k| tree.joints[k].inertial.as_ref())
            .map(|m| m.mass_kg)
            .sum()
    };
    let loaded: Vec<usize> = missing.iter().copied().filter(|&i| moved_kg(i) > 0.0).collect();
    let top: Vec<usize> =
        loaded.iter().copied().filter(|&i| !loaded.iter().any(|&k| k != i && tr.moves(k, i))).collect();
    if top.is_empty() {
        return None;
    }
    let kg: f64 = top.iter().map(|&i| moved_kg(i)).sum();
    let first: Vec<String> = top.iter().map(|&i| format!("'{}'", tree.joints[i].name)).collect();
    Some(format!(
        "{}: the table holds the {} joints of the chain ending at joint '{}', but the robot is a tree of {} moving joints: the motion of the other branches ({} joint(s) from {}, moving {kg:.1} kg) is missing from the table, so their weight is modelled as if they stood still at zero; if they moved between the poses, record every joint of the tree (q1..q{} in the URDF's order) and name the measured link (a tip column or --tip)",
        measurements.display(),
        chain.dof(),
        chain.joints.last().map(|j| j.name.as_str()).unwrap_or_default(),
        tree.dof(),
        loaded.len(),
        first.join(", "),
        tree.dof()
    ))
}
