//! From planned measurement poses to a safe path and robot programs (the source's flow, step 7).
//!
//! [`plan_path`] orders the poses into a short path through joint space (nearest neighbour from
//! the home configuration, then 2-opt) under a time-like metric (`max_i |dq_i| / v_i`: the
//! duration of a synchronised point-to-point move), adds the approach moves the settings ask for
//! ([`Approach`]: free, always from the same side with an overshoot move, or deliberately from
//! both sides so that backlash is measurable), and checks every segment between consecutive
//! configurations with [`SafetyChecker::check_move`]. A segment that fails is routed through safe
//! via configurations found by a lazy roadmap search over the caller's safe configurations (the
//! candidate pool); when no route exists the planner fails and names the segment and the
//! violated zone. The result is safe exactly as far as `check_move` guarantees it: at every
//! instant for serial chains, at the checked samples (with a Jacobian-bounded spacing) for
//! parallel robots.
//!
//! Writers: [`rapid_module`] (ABB RAPID: one `MoveAbsJ` per step to a `jointtarget`, a
//! `WaitTime \InPos` at each measurement), [`path_csv`] (joint targets as CSV, degrees and
//! millimetres), [`gcode`] (G1 moves with a feed rate, joint axes for machines whose axes are
//! the joints, or the tool pose for a hexapod controller, with the checked joint-space segments
//! cut into short steps).

use std::collections::HashMap;

use serde::{Deserialize, Serialize};

use crate::error::{Result, RobotError};
use crate::kinematics::JointKind;
use crate::safety::{SafetyBody, SafetyChecker};

mod export;

pub use export::{gcode, krl, path_csv, rapid_module, urscript, GcodeAxes, GcodeProgram, ProgramSettings};

/// From which side each measured pose is approached.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Approach {
    /// However the path arrives.
    #[default]
    Free,
    /// Always from the same side: an overshoot configuration `q - sign * overshoot` before
    /// every pose, so every joint moves in the direction `approach_sign` into it (backlash
    /// then acts the same way at every measurement).
    Fixed,
    /// Every pose twice, from below and from above, so that backlash shows in the data.
    Both,
}

/// Settings of the path (TOML table `[path]` of a plan file).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PathSettings {
    /// Approach mode.
    #[serde(default)]
    pub approach: Approach,
    /// Direction of the final move into each pose with [`Approach::Fixed`]: `1` or `-1`.
    #[serde(default = "default_sign")]
    pub approach_sign: i8,
    /// Overshoot per joint (SI joint units); default 1 mm for prismatic, 0.2 deg for revolute
    /// joints.
    #[serde(default)]
    pub overshoot_si: Vec<f64>,
    /// Joint speeds for the path metric and time estimate (SI units per second); default
    /// 0.1 m/s and 0.5 rad/s.
    #[serde(default)]
    pub joint_speed_si: Vec<f64>,
    /// Waiting time at each measurement, seconds.
    #[serde(default = "default_dwell")]
    pub dwell_s: f64,
    /// Improve the nearest-neighbour order with 2-opt.
    #[serde(default = "default_true")]
    pub two_opt: bool,
    /// Return to the home configuration at the end.
    #[serde(default = "default_true")]
    pub return_home: bool,
    /// Neighbours per node of the detour roadmap.
    #[serde(default = "default_neighbours")]
    pub roadmap_neighbours: usize,
}

fn default_sign() -> i8 {
    1
}
fn default_dwell() -> f64 {
    2.0
}
fn default_true() -> bool {
    true
}
fn default_neighbours() -> usize {
    8
}

impl Default for PathSettings {
    fn default() -> Self {
        Self {
            approach: Approach::Free,
            approach_sign: 1,
            overshoot_si: Vec::new(),
            joint_speed_si: Vec::new(),
            dwell_s: default_dwell(),
            two_opt: true,
            return_home: true,
            roadmap_neighbours: default_neighbours(),
        }
    }
}

impl PathSettings {
    fn resolved(&self, kinds: &[JointKind]) -> Result<(Vec<f64>, Vec<f64>)> {
        let n = kinds.len();
        let bad = |m: String| Err(RobotError::Safety(format!("path settings: {m}")));
        if self.approach_sign != 1 && self.approach_sign != -1 {
            return bad(format!("approach_sign must be 1 or -1, got {}", self.approach_sign));
        }
        if !(self.dwell_s.is_finite() && self.dwell_s >= 0.0) {
            return bad(format!("dwell_s must be >= 0, got {}", self.dwell_s));
        }
        let pick = |v: &[f64], name: &str, pris: f64, rev: f64| -> Result<Vec<f64>> {
            if v.is_empty() {
                return Ok(kinds
                    .iter()
                    .map(|k| match k {
                        JointKind::Prismatic => pris,
                        JointKind::Revolute => rev,
                    })
                    .collect());
            }
            if v.len() != n {
                return Err(RobotError::Safety(format!(
                    "path settings: {name} has {} values, the robot has {n} joints",
                    v.len()
                )));
            }
            if v.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
                return Err(RobotError::Safety(format!("path settings: every {name} value must be > 0")));
            }
            Ok(v.to_vec())
        };
        let overshoot = pick(&self.overshoot_si, "overshoot_si", 1e-3, 0.2f64.to_radians())?;
        let speed = pick(&self.joint_speed_si, "joint_speed_si", 0.1, 0.5)?;
        Ok((overshoot, speed))
    }
}

/// What a step of the path is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StepKind {
    /// The home configuration (start and, optionally, end).
    Home,
    /// An overshoot configuration before a measured pose.
    Approach,
    /// A measurement.
    Measure,
    /// A via configuration around an obstacle.
    Via,
    /// A move of a user's program (e.g. a corrected command of `ferrocal correct`), joint
    /// interpolation; no measurement is made there.
    Move,
    /// A move of a user's program that the program asked to be linear in the tool (URScript
    /// `movel`); writers without a joint-target linear move write it with joint interpolation
    /// and say so in the step's comment.
    MoveLinear,
}

/// One configuration of the path.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PathStep {
    /// Joint values (SI joint units).
    pub q: Vec<f64>,
    /// What it is for.
    pub kind: StepKind,
    /// Index of the measured pose (into the planner's input) for approach and measure steps.
    pub pose: Option<usize>,
    /// Sign of every joint's last motion into this configuration (`1`, `-1`, `0`).
    pub dir: Vec<i8>,
    /// The user's name of the step (a program's pose id), written in the programs' comments.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
}

/// A checked path (the default: no steps, nothing timed or checked).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PlannedPath {
    /// The steps from home, in order.
    pub steps: Vec<PathStep>,
    /// Visiting order of the input poses.
    pub order: Vec<usize>,
    /// Estimated travel time (sum of `max_i |dq_i| / v_i` over segments), seconds.
    pub travel_s: f64,
    /// Waiting time at the measurements, seconds.
    pub dwell_s: f64,
    /// Travel time of the nearest-neighbour order before 2-opt (measured poses only).
    pub nearest_neighbour_s: f64,
    /// Travel time of the final order (measured poses only, without approach and via moves).
    pub ordered_s: f64,
    /// Segments that needed a detour.
    pub detours: usize,
    /// Segments checked with `check_move`.
    pub checked_segments: usize,
}

impl PlannedPath {
    /// Number of measurements.
    pub fn measurements(&self) -> usize {
        self.steps.iter().filter(|s| s.kind == StepKind::Measure).count()
    }

    /// Number of moves of a user's program ([`StepKind::Move`], [`StepKind::MoveLinear`]).
    pub fn program_moves(&self) -> usize {
        self.steps.iter().filter(|s| matches!(s.kind, StepKind::Move | StepKind::MoveLinear)).count()
    }
}

fn metric(a: &[f64], b: &[f64], speed: &[f64]) -> f64 {
    a.iter().zip(b).zip(speed).map(|((x, y), v)| (x - y).abs() / v).fold(0.0, f64::max)
}

fn tour_cost(home: &[f64], order: &[usize], poses: &[Vec<f64>], speed: &[f64]) -> f64 {
    let mut prev = home;
    let mut c = 0.0;
    for &i in order {
        c += metric(prev, &poses[i], speed);
        prev = &poses[i];
    }
    c
}

/// Nearest neighbour from `home`.
fn nearest_neighbour(home: &[f64], poses: &[Vec<f64>], speed: &[f64]) -> Vec<usize> {
    let mut left: Vec<usize> = (0..poses.len()).collect();
    let mut order = Vec::with_capacity(poses.len());
    let mut cur = home.to_vec();
    while !left.is_empty() {
        let (k, _) = left
            .iter()
            .enumerate()
            .map(|(k, &i)| (k, metric(&cur, &poses[i], speed)))
            .fold((0, f64::INFINITY), |best, x| if x.1 < best.1 { x } else { best });
        let i = left.swap_remove(k);
        cur = poses[i].clone();
        order.push(i);
    }
    order
}

/// 2-opt on an open path that starts at `home` (fixed) and ends anywhere.
fn two_opt(home: &[f64], order: &mut [usize], poses: &[Vec<f64>], speed: &[f64]) {
    let n = order.len();
    if n < 3 {
        return;
    }
    let at = |order: &[usize], k: isize| -> Vec<f64> {
        if k < 0 {
            home.to_vec()
        } else {
            poses[order[k as usize]].clone()
        }
    };
    for _pass in 0..100 {
        let mut improved = false;
        // Reverse order[i..=j]; edges (i-1, i) and (j, j+1) change.
        for i in 0..n - 1 {
            for j in i + 1..n {
                let a = at(order, i as isize - 1);
                let b = at(order, i as isize);
                let c = at(order, j as isize);
                let before =
                    metric(&a, &b, speed) + if j + 1 < n { metric(&c, &poses[order[j + 1]], speed) } else { 0.0 };
                let after =
                    metric(&a, &c, speed) + if j + 1 < n { metric(&b, &poses[order[j + 1]], speed) } else { 0.0 };
                if after < before - 1e-12 {
                    order[i..=j].reverse();
                    improved = true;
                }
            }
        }
        if !improved {
            break;
        }
    }
}

/// A k-nearest-neighbour roadmap over safe configurations, searched lazily: the shortest route
/// under the path metric is found first (Dijkstra), then its edges are checked with
/// `check_move`; unsafe edges are removed and the search repeats. Edge checks are cached across
/// queries.
struct Roadmap {
    nodes: Vec<Vec<f64>>,
    adj: Vec<Vec<usize>>,
    status: HashMap<(usize, usize), bool>,
    k: usize,
}

fn k_nearest(nodes: &[Vec<f64>], q: &[f64], k: usize, speed: &[f64], skip: Option<usize>) -> Vec<usize> {
    let mut d: Vec<(f64, usize)> =
        nodes.iter().enumerate().filter(|(j, _)| Some(*j) != skip).map(|(j, n)| (metric(q, n, speed), j)).collect();
    let k = k.min(d.len());
    if k == 0 {
        return Vec::new();
    }
    d.select_nth_unstable_by(k - 1, |x, y| x.0.total_cmp(&y.0));
    d[..k].iter().map(|x| x.1).collect()
}

impl Roadmap {
    fn new(nodes: Vec<Vec<f64>>, speed: &[f64], k: usize) -> Self {
        let n = nodes.len();
        let k = k.max(2);
        let mut adj: Vec<Vec<usize>> = vec![Vec::new(); n];
        for i in 0..n {
            for j in k_nearest(&nodes, &nodes[i], k, speed, Some(i)) {
                if !adj[i].contains(&j) {
                    adj[i].push(j);
                }
                if !adj[j].contains(&i) {
                    adj[j].push(i);
                }
            }
        }
        Self { nodes, adj, status: HashMap::new(), k }
    }

    /// A safe route from `a` to `b` through the roadmap: the via configurations (without `a`
    /// and `b`), or `None`.
    fn route<R: SafetyBody + ?Sized>(
        &mut self,
        checker: &SafetyChecker<'_, R>,
        a: &[f64],
        b: &[f64],
        speed: &[f64],
        checked: &mut usize,
    ) -> Option<Vec<Vec<f64>>> {
        use std::cmp::Reverse;
        use std::collections::BinaryHeap;
        let n = self.nodes.len();
        if n == 0 {
            return None;
        }
        // Temporary nodes: a = n, b = n + 1, joined to their nearest roadmap nodes.
        let na = k_nearest(&self.nodes, a, self.k, speed, None);
        let nb = k_nearest(&self.nodes, b, self.k, speed, None);
        let pos = |i: usize| -> &[f64] {
            if i == n {
                a
            } else if i == n + 1 {
                b
            } else {
                &self.nodes[i]
            }
        };
        let mut local: HashMap<(usize, usize), bool> = HashMap::new();
        let key = |i: usize, j: usize| if i < j { (i, j) } else { (j, i) };
        for _round in 0..200 {
            let mut dist = vec![f64::INFINITY; n + 2];
            let mut prev = vec![usize::MAX; n + 2];
            let mut heap = BinaryHeap::new();
            dist[n] = 0.0;
            heap.push((Reverse(OrdF64(0.0)), n));
            while let Some((Reverse(OrdF64(d)), u)) = heap.pop() {
                if d > dist[u] {
                    continue;
                }
                if u == n + 1 {
                    break;
                }
                let neighbours: Vec<usize> = if u == n {
                    na.clone()
                } else if u < n {
                    let mut v = self.adj[u].clone();
                    if na.contains(&u) {
                        v.push(n);
                    }
                    if nb.contains(&u) {
                        v.push(n + 1);
                    }
                    v
                } else {
                    Vec::new()
                };
                for v in neighbours {
                    let e = key(u, v);
                    let known = if u >= n || v >= n { local.get(&e) } else { self.status.get(&e) };
                    if known == Some(&false) {
                        continue;
                    }
                    let nd = d + metric(pos(u), pos(v), speed);
                    if nd < dist[v] {
                        dist[v] = nd;
                        prev[v] = u;
                        heap.push((Reverse(OrdF64(nd)), v));
                    }
                }
            }
            if !dist[n + 1].is_finite() {
                return None;
            }
            let mut route = vec![n + 1];
            while let Some(&last) = route.last() {
                if last == n {
                    break;
                }
                route.push(prev[last]);
            }
            route.reverse();
            let mut all_ok = true;
            for w in route.windows(2) {
                let e = key(w[0], w[1]);
                let temp = w[0] >= n || w[1] >= n;
                let cache = if temp { &mut local } else { &mut self.status };
                let ok = match cache.get(&e) {
                    Some(&ok) => ok,
                    None => {
                        *checked += 1;
                        let ok = checker.check_move(pos(w[0]), pos(w[1])).is_ok();
                        cache.insert(e, ok);
                        ok
                    }
                };
                if !ok {
                    all_ok = false;
                    break;
                }
            }
            if all_ok {
                return Some(route[1..route.len() - 1].iter().map(|&i| self.nodes[i].clone()).collect());
            }
        }
        None
    }
}

/// A total order on path lengths for the heap.
#[derive(Clone, Copy, PartialEq)]
struct OrdF64(f64);
impl Eq for OrdF64 {}
impl PartialOrd for OrdF64 {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for OrdF64 {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

fn sign(x: f64) -> i8 {
    if x > 0.0 {
        1
    } else if x < 0.0 {
        -1
    } else {
        0
    }
}

/// Orders `poses` into a checked path from `home` (see the module documentation). `roadmap`
/// holds extra safe configurations the planner may route through (unsafe ones are ignored).
/// Fails when a pose, the home configuration or an approach configuration is unsafe, or when a
/// segment has no safe route; the message names the pose or segment and the violated zone.
pub fn plan_path<R: SafetyBody + ?Sized>(
    model: &R,
    checker: &SafetyChecker<'_, R>,
    home: &[f64],
    poses: &[Vec<f64>],
    roadmap: &[Vec<f64>],
    settings: &PathSettings,
) -> Result<PlannedPath> {
    let kinds = model.joint_kinds();
    let (overshoot, speed) = settings.resolved(&kinds)?;
    let n_j = kinds.len();
    if home.len() != n_j {
        return Err(RobotError::JointCount { expected: n_j, got: home.len() });
    }
    if let Some(v) = checker.violations(home, 0.0).into_iter().next() {
        return Err(RobotError::Safety(format!("the home configuration is unsafe: {v}")));
    }
    for (i, q) in poses.iter().enumerate() {
        if q.len() != n_j {
            return Err(RobotError::JointCount { expected: n_j, got: q.len() });
        }
        if let Some(v) = checker.violations(q, 0.0).into_iter().next() {
            return Err(RobotError::Safety(format!("pose {} is unsafe: {v}", i + 1)));
        }
    }
    let mut order = nearest_neighbour(home, poses, &speed);
    let nearest_neighbour_s = tour_cost(home, &order, poses, &speed);
    if settings.two_opt {
        two_opt(home, &mut order, poses, &speed);
    }
    let ordered_s = tour_cost(home, &order, poses, &speed);

    // Waypoints: home, approach and measure steps, home.
    let mut way: Vec<(Vec<f64>, StepKind, Option<usize>)> = vec![(home.to_vec(), StepKind::Home, None)];
    let mut checked = 0usize;
    let approach_point = |q: &[f64], s: f64, checked: &mut usize| -> Result<Vec<f64>> {
        let mut scale = 1.0;
        for _ in 0..5 {
            let pre: Vec<f64> = q.iter().zip(&overshoot).map(|(v, o)| v - s * scale * o).collect();
            *checked += 1;
            if checker.check_move(&pre, q).is_ok() {
                return Ok(pre);
            }
            scale *= 0.5;
        }
        let pre: Vec<f64> = q.iter().zip(&overshoot).map(|(v, o)| v - s * scale * o).collect();
        let why = checker.check_move(&pre, q).err().map(|(_, v)| v.to_string()).unwrap_or_default();
        Err(RobotError::Safety(format!("no safe approach configuration next to the pose: {why}")))
    };
    for &i in &order {
        let q = &poses[i];
        let wrap = |e: RobotError| match e {
            RobotError::Safety(m) => RobotError::Safety(format!("pose {}: {m}", i + 1)),
            other => other,
        };
        match settings.approach {
            Approach::Free => way.push((q.clone(), StepKind::Measure, Some(i))),
            Approach::Fixed => {
                let s = settings.approach_sign as f64;
                let pre = approach_point(q, s, &mut checked).map_err(wrap)?;
                way.push((pre, StepKind::Approach, Some(i)));
                way.push((q.clone(), StepKind::Measure, Some(i)));
            }
            Approach::Both => {
                for s in [1.0, -1.0] {
                    let pre = approach_point(q, s, &mut checked).map_err(wrap)?;
                    way.push((pre, StepKind::Approach, Some(i)));
                    way.push((q.clone(), StepKind::Measure, Some(i)));
                }
            }
        }
    }
    if settings.return_home {
        way.push((home.to_vec(), StepKind::Home, None));
    }

    // The roadmap is built only when a segment needs a detour.
    let mut map: Option<Roadmap> = None;
    let mut steps: Vec<PathStep> = Vec::with_capacity(way.len());
    let mut detours = 0;
    for (k, (q, kind, pose)) in way.iter().enumerate() {
        if k > 0 {
            let a = steps.last().map(|s| s.q.clone()).unwrap_or_default();
            checked += 1;
            if let Err((_, v)) = checker.check_move(&a, q) {
                let describe = |kind: &StepKind, pose: &Option<usize>| match (kind, pose) {
                    (StepKind::Home, _) => "home".to_string(),
                    (_, Some(p)) => format!("pose {}", p + 1),
                    _ => "a via configuration".to_string(),
                };
                if *kind == StepKind::Measure && way[k - 1].1 == StepKind::Approach {
                    return Err(RobotError::Safety(format!(
                        "the approach move into {} is unsafe: {v}",
                        describe(kind, pose)
                    )));
                }
                let rm = map.get_or_insert_with(|| {
                    let nodes: Vec<Vec<f64>> = roadmap
                        .iter()
                        .filter(|q| q.len() == n_j && checker.violations(q, 0.0).is_empty())
                        .cloned()
                        .chain(poses.iter().cloned())
                        .collect();
                    Roadmap::new(nodes, &speed, settings.roadmap_neighbours)
                });
                let n_nodes = rm.nodes.len();
                let vias = rm.route(checker, &a, q, &speed, &mut checked)
                    .ok_or_else(|| {
                        RobotError::Safety(format!(
                            "no safe route from {} to {}: the straight move violates '{v}' and the roadmap of {} safe configurations offers no way around; add configurations to the pool or relax that zone",
                            describe(&way[k - 1].1, &way[k - 1].2),
                            describe(kind, pose),
                            n_nodes
                        ))
                    })?;
                detours += 1;
                for v in vias {
                    let prev = steps.last().map(|s| s.q.clone()).unwrap_or_default();
                    let dir = v.iter().zip(&prev).map(|(x, y)| sign(x - y)).collect();
                    steps.push(PathStep { q: v, kind: StepKind::Via, pose: None, dir, label: None });
                }
            }
        }
        let dir = match steps.last() {
            Some(prev) => q.iter().zip(&prev.q).map(|(x, y)| sign(x - y)).collect(),
            None => vec![0; n_j],
        };
        steps.push(PathStep { q: q.clone(), kind: *kind, pose: *pose, dir, label: None });
    }
    // Measurements repeated at the same configuration keep the direction of their approach.
    let travel_s = steps.windows(2).map(|w| metric(&w[0].q, &w[1].q, &speed)).sum();
    let n_measure = steps.iter().filter(|s| s.kind == StepKind::Measure).count();
    Ok(PlannedPath {
        steps,
        order,
        travel_s,
        dwell_s: n_measure as f64 * settings.dwell_s,
        nearest_neighbour_s,
        ordered_s,
        detours,
        checked_segments: checked,
    })
}

/// Re-checks a path: every configuration with [`SafetyChecker::violations`] and every segment
/// with [`SafetyChecker::check_move`]. Returns the first problem in words.
pub fn verify_path<R: SafetyBody + ?Sized>(
    checker: &SafetyChecker<'_, R>,
    path: &PlannedPath,
) -> std::result::Result<(), String> {
    for (k, s) in path.steps.iter().enumerate() {
        if let Some(v) = checker.violations(&s.q, 0.0).into_iter().next() {
            return Err(format!("step {} is unsafe: {v}", k + 1));
        }
    }
    for (k, w) in path.steps.windows(2).enumerate() {
        if let Err((s, v)) = checker.check_move(&w[0].q, &w[1].q) {
            return Err(format!("the move from step {} to step {} is unsafe at {:.3}: {v}", k + 1, k + 2, s));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::export::rapid_identifier;
    use super::*;

    #[test]
    fn two_opt_untangles_a_crossing() {
        let poses = vec![vec![3.0, 0.0], vec![1.0, 0.0], vec![2.0, 0.0], vec![4.0, 0.0]];
        let speed = [1.0, 1.0];
        let mut order = vec![0, 1, 2, 3];
        let before = tour_cost(&[0.0, 0.0], &order, &poses, &speed);
        two_opt(&[0.0, 0.0], &mut order, &poses, &speed);
        let after = tour_cost(&[0.0, 0.0], &order, &poses, &speed);
        assert!(after < before, "{before} -> {after}");
        assert_eq!(order, vec![1, 2, 0, 3]);
    }

    #[test]
    fn rapid_identifiers() {
        assert!(rapid_identifier("FerrocalPlan", "m").is_ok());
        assert!(rapid_identifier("1abc", "m").is_err());
        assert!(rapid_identifier("a b", "m").is_err());
    }

    /// The URScript and KRL writers refuse what their controllers cannot run, with the reason.
    #[test]
    fn program_writers_refuse_bad_settings_by_name() {
        let model = crate::RobotModel::Serial(crate::presets::ur5());
        let step = PathStep { q: vec![0.1; 6], kind: StepKind::Measure, pose: Some(0), dir: vec![0; 6], label: None };
        let path = PlannedPath { steps: vec![step], order: vec![0], ..Default::default() };
        let ok = ProgramSettings::default();
        assert!(urscript(&model, &path, 0.5, &ok, &[]).unwrap().contains("movej([0.1000000"));
        assert!(krl(&model, &path, 0.5, &ok, &[]).unwrap().contains("PTP {AXIS: A1 5.7296"));
        let err = |r: crate::Result<String>| r.unwrap_err().to_string();
        assert!(err(urscript(&model, &path, 1e300, &ok, &[])).contains("dwell time must be 0 to 3600 s"));
        assert!(err(rapid_module(&model, &path, f64::NAN, &ok, &[])).contains("dwell time"));
        let bad = ProgramSettings { krl_name: "9lives".into(), ..ok.clone() };
        assert!(err(krl(&model, &path, 0.0, &bad, &[])).contains("krl_name '9lives' is not a KRL identifier"));
        let fast = ProgramSettings { urscript_speed_rad_s: 10.0, ..ok.clone() };
        assert!(err(urscript(&model, &path, 0.0, &fast, &[])).contains("urscript_speed_rad_s"));
        let three = crate::RobotModel::Serial(crate::serial::SerialChain::from_dh(
            "rrr",
            &[0.1, 0.2, 0.3],
            &[0.0; 3],
            &[0.0; 3],
            &[0.0; 3],
        ));
        let short = PlannedPath {
            steps: vec![PathStep {
                q: vec![0.0; 3],
                kind: StepKind::Measure,
                pose: Some(0),
                dir: vec![0; 3],
                label: None,
            }],
            ..path.clone()
        };
        assert!(err(urscript(&three, &short, 0.0, &ok, &[])).contains("URScript moves six revolute joints"));
        let mut nan = path.clone();
        nan.steps[0].q[2] = f64::NAN;
        assert!(err(krl(&model, &nan, 0.0, &ok, &[])).contains("step 1: joint 3 is not a finite number"));
    }
}
