//! The lattice search (every node of a Cartesian or joint lattice classified by the first
//! constraint it breaks) and the candidate grids over the measurable region: the source's
//! regular grid at a wanted count and random pools.

use std::collections::BTreeMap;

use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::{Candidate, GridSpace, Lattice, MeasuringDevice, Stage, StageCount, WorkspaceMap, WorkspaceSettings};
use crate::error::{Result, RobotError};
use crate::kinematics::JointKind;
use crate::safety::{SafetyBody, SafetyChecker, Violation};

/// The allowed joint box: the model's limits, tightened by the safety configuration's
/// `joint_limits`, shrunk by its `joint_margin`; unbounded revolute joints span `[-pi, pi]` and
/// unbounded prismatic ones `[-1, 1]` m.
pub fn allowed_joint_box<R: SafetyBody + ?Sized>(model: &R, checker: &SafetyChecker<'_, R>) -> (Vec<f64>, Vec<f64>) {
    let cfg = checker.config();
    let kinds = model.joint_kinds();
    let mut lo = Vec::new();
    let mut hi = Vec::new();
    for (i, l) in model.joint_limits().iter().enumerate() {
        let (dlo, dhi) = match kinds[i] {
            JointKind::Revolute => (-std::f64::consts::PI, std::f64::consts::PI),
            JointKind::Prismatic => (-1.0, 1.0),
        };
        let mut a = if l.lower.is_finite() { l.lower } else { dlo };
        let mut b = if l.upper.is_finite() { l.upper } else { dhi };
        if let Some(Some([x, y])) = cfg.joint_limits.get(i) {
            a = a.max(*x);
            b = b.min(*y);
        }
        lo.push(a + cfg.joint_margin);
        hi.push(b - cfg.joint_margin);
    }
    (lo, hi)
}

fn stage_name(stage: &Stage, checker_cfg: &crate::safety::SafetyConfig, device: Option<&str>) -> String {
    match stage {
        Stage::Reachable => "reachable (kinematics has a solution)".into(),
        Stage::JointLimits => format!("joint limits with a {} margin", checker_cfg.joint_margin),
        Stage::SphericalJoints => format!("spherical-joint limit {} deg", checker_cfg.spherical_max_deg),
        Stage::WorkspaceEdge => format!("workspace-edge margin {} m", checker_cfg.workspace_edge_margin_m),
        Stage::Obstacle { index } => {
            let o = &checker_cfg.obstacles[*index];
            format!(
                "obstacle '{}' (margin {} m, plate radius {} m, link radius {} m)",
                o.name, o.margin_m, checker_cfg.plate_radius_m, checker_cfg.link_radius_m
            )
        }
        Stage::Measurable => format!("measurable by {}", device.unwrap_or("the device")),
    }
}

/// How one lattice node fared.
enum NodeResult {
    Accepted(Candidate),
    Rejected(Stage, Option<String>),
}

/// Everything needed to evaluate nodes.
struct Evaluator<'a, R: SafetyBody + ?Sized> {
    model: &'a R,
    checker: &'a SafetyChecker<'a, R>,
    device: Option<&'a dyn MeasuringDevice>,
    lattice: &'a Lattice,
    home: Vec<f64>,
}

impl<R: SafetyBody + ?Sized> Evaluator<'_, R> {
    fn evaluate(&self, coords: &[f64], orientation: usize) -> NodeResult {
        let (q, pose) = match self.lattice {
            Lattice::Cartesian { orientations, .. } => {
                let target = Isometry3::from_parts(
                    Translation3::new(coords[0], coords[1], coords[2]),
                    orientations[orientation],
                );
                match self.model.inverse(&target, &self.home) {
                    Ok(q) => match self.model.forward(&q) {
                        Ok(p) => (q, p),
                        Err(_) => return NodeResult::Rejected(Stage::Reachable, None),
                    },
                    Err(RobotError::OutsideLimits { .. }) => return NodeResult::Rejected(Stage::JointLimits, None),
                    Err(_) => return NodeResult::Rejected(Stage::Reachable, None),
                }
            }
            Lattice::Joint { lo, hi } => {
                let q: Vec<f64> = coords.iter().zip(lo.iter().zip(hi)).map(|(u, (a, b))| a + u * (b - a)).collect();
                match self.model.forward(&q) {
                    Ok(p) => (q, p),
                    Err(_) => return NodeResult::Rejected(Stage::Reachable, None),
                }
            }
        };
        let cfg = self.checker.config();
        let mut worst: Option<Stage> = None;
        for v in self.checker.violations(&q, 0.0) {
            let s = match v {
                Violation::JointLimit { .. } => Stage::JointLimits,
                Violation::SphericalJoint { .. } => Stage::SphericalJoints,
                Violation::WorkspaceEdge { .. } => Stage::WorkspaceEdge,
                Violation::Obstacle { obstacle, .. } => {
                    Stage::Obstacle { index: cfg.obstacles.iter().position(|o| o.name == obstacle).unwrap_or(0) }
                }
                _ => Stage::Reachable,
            };
            worst = Some(match worst {
                Some(w) if w <= s => w,
                _ => s,
            });
        }
        if let Some(s) = worst {
            return NodeResult::Rejected(s, None);
        }
        if let Some(dev) = self.device {
            if let Err(e) = dev.check(&pose) {
                return NodeResult::Rejected(Stage::Measurable, Some(e.reason));
            }
        }
        NodeResult::Accepted(Candidate { q, t_base_tool: pose, orientation, coords: coords.to_vec() })
    }
}

/// Nodes of a regular lattice with spacing `h` centred in the box `[lo, hi]`.
pub(super) fn lattice_axes(lo: &[f64], hi: &[f64], h: f64) -> Vec<Vec<f64>> {
    lo.iter()
        .zip(hi)
        .map(|(a, b)| {
            let extent = (b - a).max(0.0);
            let n = (extent / h + 1e-9).floor() as usize + 1;
            let off = a + 0.5 * (extent - (n - 1) as f64 * h);
            (0..n).map(|k| off + k as f64 * h).collect()
        })
        .collect()
}

pub(super) fn for_each_node(axes: &[Vec<f64>], mut f: impl FnMut(&[f64])) {
    let d = axes.len();
    if axes.iter().any(|a| a.is_empty()) {
        return;
    }
    let mut idx = vec![0usize; d];
    let mut coords: Vec<f64> = axes.iter().map(|a| a[0]).collect();
    loop {
        f(&coords);
        let mut k = 0;
        loop {
            if k == d {
                return;
            }
            idx[k] += 1;
            if idx[k] < axes[k].len() {
                coords[k] = axes[k][idx[k]];
                break;
            }
            idx[k] = 0;
            coords[k] = axes[k][0];
            k += 1;
        }
    }
}

fn node_count(axes: &[Vec<f64>]) -> usize {
    axes.iter().map(|a| a.len()).fold(1usize, |acc, n| acc.saturating_mul(n))
}

/// The home configuration: the settings' `home_si` or the middle of the allowed joint box.
pub fn home_configuration<R: SafetyBody + ?Sized>(
    model: &R,
    checker: &SafetyChecker<'_, R>,
    settings: &WorkspaceSettings,
) -> Result<Vec<f64>> {
    if settings.home_si.is_empty() {
        let (lo, hi) = allowed_joint_box(model, checker);
        Ok(lo.iter().zip(&hi).map(|(a, b)| 0.5 * (a + b)).collect())
    } else if settings.home_si.len() != model.dof() {
        Err(RobotError::JointCount { expected: model.dof(), got: settings.home_si.len() })
    } else {
        Ok(settings.home_si.clone())
    }
}

/// Builds the search lattice for `model`.
pub fn build_lattice<R: SafetyBody + ?Sized>(
    model: &R,
    checker: &SafetyChecker<'_, R>,
    settings: &WorkspaceSettings,
) -> Result<(Lattice, f64)> {
    settings.validate()?;
    let (lo, hi) = allowed_joint_box(model, checker);
    match settings.resolved_space(model.mobility()) {
        GridSpace::Joint | GridSpace::Auto => Ok((Lattice::Joint { lo, hi }, 1.0 / (settings.joint_steps - 1) as f64)),
        GridSpace::Cartesian => {
            let (min_m, max_m) = match (settings.box_min_m, settings.box_max_m) {
                (Some(a), Some(b)) => (a, b),
                _ => {
                    // The reach of random joint samples, padded by two lattice cells.
                    let mut rng = ChaCha8Rng::seed_from_u64(0);
                    let mut a = [f64::INFINITY; 3];
                    let mut b = [f64::NEG_INFINITY; 3];
                    for _ in 0..4000 {
                        let q: Vec<f64> = lo.iter().zip(&hi).map(|(x, y)| x + (y - x) * rng.random::<f64>()).collect();
                        if let Ok(p) = model.forward(&q) {
                            for k in 0..3 {
                                a[k] = a[k].min(p.translation.vector[k]);
                                b[k] = b[k].max(p.translation.vector[k]);
                            }
                        }
                    }
                    if !a[0].is_finite() {
                        return Err(RobotError::Safety(
                            "the workspace is empty: reachable (kinematics has a solution) fails for 4000 random joint samples; give box_min_m and box_max_m".into(),
                        ));
                    }
                    let pad = 2.0 * settings.search_spacing_m;
                    (a.map(|v| v - pad), b.map(|v| v + pad))
                }
            };
            let orientations = settings
                .orientations_rpy_deg
                .iter()
                .map(|r| UnitQuaternion::from_euler_angles(r[0].to_radians(), r[1].to_radians(), r[2].to_radians()))
                .collect();
            Ok((Lattice::Cartesian { min_m, max_m, orientations }, settings.search_spacing_m))
        }
    }
}

/// Searches the workspace: every lattice node is classified by the first constraint it breaks
/// (see [`Stage`]); `device` (if any) decides the measurable region. Errors only for bad
/// settings or an oversized lattice; an empty region is reported in the map (see
/// [`WorkspaceMap::require_nonempty`]).
pub fn search<R: SafetyBody + ?Sized>(
    model: &R,
    checker: &SafetyChecker<'_, R>,
    device: Option<&dyn MeasuringDevice>,
    settings: &WorkspaceSettings,
) -> Result<WorkspaceMap> {
    let (lattice, h) = build_lattice(model, checker, settings)?;
    let home = home_configuration(model, checker, settings)?;
    let (lo, hi) = lattice.bounds();
    let axes = lattice_axes(&lo, &hi, h);
    let n_o = lattice.n_orientations();
    let total = node_count(&axes).saturating_mul(n_o);
    if total > settings.max_points {
        return Err(RobotError::Safety(format!(
            "the search lattice has {total} nodes (more than max_points = {}); use a larger spacing or fewer joint steps",
            settings.max_points
        )));
    }
    let ev = Evaluator { model, checker, device, lattice: &lattice, home: home.clone() };
    let mut rejected: BTreeMap<Stage, usize> = BTreeMap::new();
    let mut unmeasurable: BTreeMap<String, usize> = BTreeMap::new();
    let mut measurable = Vec::new();
    for_each_node(&axes, |c| {
        for o in 0..n_o {
            match ev.evaluate(c, o) {
                NodeResult::Accepted(cand) => measurable.push(cand),
                NodeResult::Rejected(s, reason) => {
                    *rejected.entry(s).or_default() += 1;
                    if let Some(r) = reason {
                        *unmeasurable.entry(r).or_default() += 1;
                    }
                }
            }
        }
    });
    let cfg = checker.config();
    let mut order = vec![Stage::Reachable, Stage::JointLimits];
    if model.spherical_joint_angles(&home).map(|a| !a.is_empty()).unwrap_or(true) {
        order.push(Stage::SphericalJoints);
    }
    if cfg.workspace_edge_margin_m > 0.0 {
        order.push(Stage::WorkspaceEdge);
    }
    order.extend((0..cfg.obstacles.len()).map(|index| Stage::Obstacle { index }));
    if device.is_some() {
        order.push(Stage::Measurable);
    }
    let device_name = device.map(|d| d.name());
    let mut left = total;
    let stages = order
        .into_iter()
        .map(|s| {
            let removed = rejected.get(&s).copied().unwrap_or(0);
            left -= removed.min(left);
            StageCount { name: stage_name(&s, cfg, device_name.as_deref()), stage: s, survivors: left, removed }
        })
        .collect();
    let d = lattice.dimension();
    Ok(WorkspaceMap {
        volume_unit: match lattice {
            Lattice::Cartesian { .. } => "m^3".into(),
            Lattice::Joint { .. } => "joint-box fraction".into(),
        },
        lattice,
        spacing: h,
        cell_volume: h.powi(d as i32),
        total,
        stages,
        unmeasurable,
        measurable,
        device: device_name,
        home,
    })
}

/// The source's regular grid over the measurable region for `wanted` poses.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SpreadGrid {
    /// The wanted count.
    pub wanted: usize,
    /// Grid spacing `(volume / wanted)^(1/d)` (metres, or normalised joint units).
    pub spacing: f64,
    /// The volume it was computed from.
    pub volume: f64,
    /// Grid nodes tried (times orientations).
    pub tried: usize,
    /// Nodes that passed every check, in lattice order.
    pub poses: Vec<Candidate>,
    /// Why the others failed (stage name -> count).
    pub rejected: BTreeMap<String, usize>,
}

/// The grid spacing for `wanted` poses over the measurable volume of `map`:
/// `(volume / wanted)^(1/d)`.
pub fn spacing_for(map: &WorkspaceMap, wanted: usize) -> f64 {
    let d = map.lattice.dimension() as f64;
    (map.measurable_volume() / wanted.max(1) as f64).powf(1.0 / d)
}

fn measurable_box(map: &WorkspaceMap) -> (Vec<f64>, Vec<f64>) {
    let d = map.lattice.dimension();
    let mut lo = vec![f64::INFINITY; d];
    let mut hi = vec![f64::NEG_INFINITY; d];
    for c in &map.measurable {
        for k in 0..d {
            lo[k] = lo[k].min(c.coords[k]);
            hi[k] = hi[k].max(c.coords[k]);
        }
    }
    // Each measurable node stands for a cell around it.
    let half = 0.5 * map.spacing;
    (lo.iter().map(|v| v - half).collect(), hi.iter().map(|v| v + half).collect())
}

/// Places a regular grid for `wanted` poses over the measurable region of `map` (spacing from
/// [`spacing_for`], centred in the region's bounding box) and keeps the nodes that pass every
/// check again (safety with margins and the device).
pub fn spread_grid<R: SafetyBody + ?Sized>(
    model: &R,
    checker: &SafetyChecker<'_, R>,
    device: Option<&dyn MeasuringDevice>,
    map: &WorkspaceMap,
    wanted: usize,
) -> Result<SpreadGrid> {
    map.require_nonempty()?;
    if wanted == 0 {
        return Err(RobotError::Safety("the wanted number of poses must be at least 1".into()));
    }
    let spacing = spacing_for(map, wanted);
    grid_at_spacing(model, checker, device, map, wanted, spacing)
}

/// Like [`spread_grid`] with an explicit spacing.
pub fn grid_at_spacing<R: SafetyBody + ?Sized>(
    model: &R,
    checker: &SafetyChecker<'_, R>,
    device: Option<&dyn MeasuringDevice>,
    map: &WorkspaceMap,
    wanted: usize,
    spacing: f64,
) -> Result<SpreadGrid> {
    if !(spacing.is_finite() && spacing > 0.0) {
        return Err(RobotError::Safety(format!("grid spacing must be > 0, got {spacing}")));
    }
    let (lo, hi) = measurable_box(map);
    let axes = lattice_axes(&lo, &hi, spacing);
    let n_o = map.lattice.n_orientations();
    let tried = node_count(&axes).saturating_mul(n_o);
    if tried > 4 * map.total.max(1000) {
        return Err(RobotError::Safety(format!(
            "a grid of spacing {spacing:.4} has {tried} nodes; ask for fewer poses"
        )));
    }
    let ev = Evaluator { model, checker, device, lattice: &map.lattice, home: map.home.clone() };
    let cfg = checker.config();
    let mut poses = Vec::new();
    let mut rejected = BTreeMap::new();
    for_each_node(&axes, |c| {
        for o in 0..n_o {
            match ev.evaluate(c, o) {
                NodeResult::Accepted(cand) => poses.push(cand),
                NodeResult::Rejected(s, reason) => {
                    let key = reason.unwrap_or_else(|| stage_name(&s, cfg, map.device.as_deref()));
                    *rejected.entry(key).or_insert(0usize) += 1;
                }
            }
        }
    });
    Ok(SpreadGrid { wanted, spacing, volume: map.measurable_volume(), tried, poses, rejected })
}

/// Draws `n` random candidates uniformly over the measurable region (a random measurable cell,
/// a random point in it, every check again). Deterministic for `seed`. Fails when fewer than
/// `n` are found after `50 n + 1000` tries.
pub fn sample_measurable<R: SafetyBody + ?Sized>(
    model: &R,
    checker: &SafetyChecker<'_, R>,
    device: Option<&dyn MeasuringDevice>,
    map: &WorkspaceMap,
    n: usize,
    seed: u64,
) -> Result<Vec<Candidate>> {
    map.require_nonempty()?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let ev = Evaluator { model, checker, device, lattice: &map.lattice, home: map.home.clone() };
    let (blo, bhi) = map.lattice.bounds();
    let mut out = Vec::with_capacity(n);
    let mut tries = 0usize;
    while out.len() < n {
        tries += 1;
        if tries > 50 * n + 1000 {
            return Err(RobotError::Safety(format!(
                "found only {} of {n} random measurable poses after {tries} tries",
                out.len()
            )));
        }
        let cell = &map.measurable[rng.random_range(0..map.measurable.len())];
        let coords: Vec<f64> = cell
            .coords
            .iter()
            .enumerate()
            .map(|(k, c)| (c + (rng.random::<f64>() - 0.5) * map.spacing).clamp(blo[k], bhi[k]))
            .collect();
        if let NodeResult::Accepted(c) = ev.evaluate(&coords, cell.orientation) {
            out.push(c);
        }
    }
    Ok(out)
}
