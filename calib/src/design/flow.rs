//! The automated calibration flow of the source (Dressler 5.6), end to end up to the choice of
//! poses: a-priori model, workspace by grid search cut by every safety zone, the measurable
//! region, the regular grid for the wanted count (spacing `(volume / wanted)^(1/3)`), a denser
//! pool, selection by a design criterion, the source's `sigma_max^2 / sigma_min < C` check and
//! the predicted accuracy, adding poses and repeating while a check fails.
//!
//! What comes after (a Monte Carlo check of the prediction with a simulator, the ordering of the
//! poses and the robot programs) takes the [`PlanDesign`] this returns:
//! [`crate::design::kinematic::monte_carlo`], `ferrocal_robot::program`.

use ferrocal_robot::safety::SafetyChecker;
use ferrocal_robot::workspace::{
    grid_at_spacing, sample_measurable, search, spacing_for, MeasuringDevice, SpreadGrid, StageCount, WorkspaceMap,
    WorkspaceSettings,
};
use ferrocal_robot::RobotModel;
use serde::{Deserialize, Serialize};

use crate::design::criteria::{CriteriaSummary, Criterion};
use crate::design::kinematic::{
    dressler_check, kinematic_pool, predict, DresslerCheck, IdentifySettings, KinematicPool, Prediction,
};
use crate::design::selection::{greedy_deletion, select_from_history, Selection, SelectionSettings};
use crate::error::{CalibError, Result};
use crate::kinematic::KinematicOptions;

/// How the optimisation pool is drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PoolKind {
    /// A regular grid with the spacing for `pool_size` poses.
    #[default]
    Grid,
    /// `pool_size` random measurable poses.
    Random,
}

/// Which pose set the plan visits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PlannedSet {
    /// The optimised selection.
    #[default]
    Optimised,
    /// The source's regular grid for the wanted count.
    Grid,
}

/// Settings of the design (TOML table `[design]` of a plan file).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DesignSettings {
    /// Wanted number of poses.
    #[serde(default = "default_wanted")]
    pub wanted_poses: usize,
    /// Size of the denser pool the selection optimises over.
    #[serde(default = "default_pool")]
    pub pool_size: usize,
    /// How the pool is drawn.
    #[serde(default)]
    pub pool: PoolKind,
    /// The selection criterion.
    #[serde(default)]
    pub criterion: Criterion,
    /// Refine the greedy selection by exchange.
    #[serde(default = "default_true")]
    pub exchange: bool,
    /// The source's threshold `C` of `sigma_max^2 / sigma_min` (200 for the L1).
    #[serde(default = "default_dressler")]
    pub dressler_limit: f64,
    /// Add poses while the Dressler check fails (the source's flow). Off by default: the ratio is
    /// not scale invariant and grows with the square root of the count, so with the source's own
    /// singular values (0.3 to 64) it is 13653 and `C = 200` cannot hold; it is always reported.
    #[serde(default)]
    pub enforce_dressler: bool,
    /// Wanted accuracy: the largest acceptable predicted held-out RMS model error, mm.
    #[serde(default)]
    pub max_rms_error_mm: Option<f64>,
    /// Rounds of adding poses.
    #[serde(default = "default_rounds")]
    pub max_rounds: usize,
    /// Factor on the count per added round.
    #[serde(default = "default_growth")]
    pub growth: f64,
    /// Which set the programs visit.
    #[serde(default)]
    pub plan: PlannedSet,
    /// Seed of the random pool and the studies.
    #[serde(default = "default_seed")]
    pub seed: u64,
}

fn default_wanted() -> usize {
    100
}
fn default_pool() -> usize {
    480
}
fn default_true() -> bool {
    true
}
fn default_dressler() -> f64 {
    200.0
}
fn default_rounds() -> usize {
    4
}
fn default_growth() -> f64 {
    1.25
}
fn default_seed() -> u64 {
    1
}

impl Default for DesignSettings {
    fn default() -> Self {
        Self {
            wanted_poses: default_wanted(),
            pool_size: default_pool(),
            pool: PoolKind::Grid,
            criterion: Criterion::D,
            exchange: true,
            dressler_limit: default_dressler(),
            enforce_dressler: false,
            max_rms_error_mm: None,
            max_rounds: default_rounds(),
            growth: default_growth(),
            plan: PlannedSet::Optimised,
            seed: default_seed(),
        }
    }
}

impl DesignSettings {
    /// Checks the settings.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(CalibError::Data(format!("design settings: {m}")));
        if self.wanted_poses == 0 {
            return bad("wanted_poses must be at least 1".into());
        }
        if self.pool_size < self.wanted_poses {
            return bad(format!(
                "pool_size ({}) must be at least wanted_poses ({})",
                self.pool_size, self.wanted_poses
            ));
        }
        if !(self.dressler_limit.is_finite() && self.dressler_limit > 0.0) {
            return bad(format!("dressler_limit must be > 0, got {}", self.dressler_limit));
        }
        if !(self.growth.is_finite() && self.growth > 1.0) {
            return bad(format!("growth must be > 1, got {}", self.growth));
        }
        if let Some(m) = self.max_rms_error_mm {
            if !(m.is_finite() && m > 0.0) {
                return bad(format!("max_rms_error_mm must be > 0, got {m}"));
            }
        }
        Ok(())
    }
}

/// The workspace numbers of a plan.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct WorkspaceSummary {
    /// Lattice nodes tried.
    pub total: usize,
    /// Survivors per stage.
    pub stages: Vec<StageCount>,
    /// Why nodes were not measurable.
    pub unmeasurable: Vec<(String, usize)>,
    /// Kinematic workspace (nodes).
    pub kinematic: usize,
    /// Left after the obstacles.
    pub safe: usize,
    /// Safe and measurable.
    pub measurable: usize,
    /// `safe / kinematic`.
    pub fraction_after_obstacles: f64,
    /// `measurable / kinematic`.
    pub measurable_fraction: f64,
    /// Search spacing.
    pub spacing: f64,
    /// Volume unit.
    pub volume_unit: String,
    /// Kinematic volume.
    pub kinematic_volume: f64,
    /// Safe volume.
    pub safe_volume: f64,
    /// Measurable volume.
    pub measurable_volume: f64,
}

impl WorkspaceSummary {
    /// The summary of a map.
    pub fn of(map: &WorkspaceMap) -> Self {
        let mut unmeasurable: Vec<(String, usize)> = map.unmeasurable.iter().map(|(k, v)| (k.clone(), *v)).collect();
        unmeasurable.sort_by_key(|x| std::cmp::Reverse(x.1));
        Self {
            total: map.total,
            stages: map.stages.clone(),
            unmeasurable,
            kinematic: map.kinematic(),
            safe: map.safe(),
            measurable: map.measurable.len(),
            fraction_after_obstacles: map.fraction_after_obstacles(),
            measurable_fraction: map.measurable_fraction(),
            spacing: map.spacing,
            volume_unit: map.volume_unit.clone(),
            kinematic_volume: map.volume_of(map.kinematic()),
            safe_volume: map.volume_of(map.safe()),
            measurable_volume: map.measurable_volume(),
        }
    }
}

/// A regular grid's numbers.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct GridSummary {
    /// The count it was made for.
    pub wanted: usize,
    /// Spacing.
    pub spacing: f64,
    /// Nodes tried.
    pub tried: usize,
    /// Nodes that passed.
    pub count: usize,
}

impl GridSummary {
    fn of(g: &SpreadGrid) -> Self {
        Self { wanted: g.wanted, spacing: g.spacing, tried: g.tried, count: g.poses.len() }
    }
}

/// One round of the flow.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Round {
    /// Poses chosen.
    pub count: usize,
    /// The criterion's value.
    pub value: f64,
    /// Every criterion of the chosen set.
    pub criteria: CriteriaSummary,
    /// The source's check.
    pub dressler: DresslerCheck,
    /// Predicted held-out RMS model error, mm.
    pub heldout_rms_mm: f64,
    /// Whether every check passed.
    pub passed: bool,
    /// Why not.
    pub failures: Vec<String>,
}

/// The designed plan (before the Monte Carlo check and the path).
#[derive(Clone, Debug, Serialize)]
pub struct PlanDesign {
    /// The device's name.
    pub device: String,
    /// The settings.
    pub settings: DesignSettings,
    /// Workspace numbers.
    pub workspace: WorkspaceSummary,
    /// The source's grid for the wanted count.
    pub grid: GridSummary,
    /// The optimisation pool.
    pub pool_grid: GridSummary,
    /// Candidate poses: the pool, then the source's grid.
    #[serde(skip)]
    pub kinematic: KinematicPool,
    /// Candidate indices of the source's grid.
    pub grid_indices: Vec<usize>,
    /// The calibration options the prediction and simulations use.
    pub options: KinematicOptions,
    /// The selection (with the criterion against the count).
    pub selection: Selection,
    /// Rounds of the flow.
    pub rounds: Vec<Round>,
    /// The planned poses (candidate indices): the selection or the grid, as the settings say.
    pub chosen: Vec<usize>,
    /// Validation poses: every candidate not chosen.
    pub validation: Vec<usize>,
    /// The prediction for the planned poses.
    pub prediction: Prediction,
    /// Criteria of the planned poses.
    pub criteria: CriteriaSummary,
    /// The source's check of the planned poses.
    pub dressler: DresslerCheck,
    /// Criteria of the source's grid (for comparison).
    pub grid_criteria: Option<CriteriaSummary>,
    /// Prediction for the source's grid.
    pub grid_prediction: Option<Prediction>,
    /// Whether the final round passed every check.
    pub passed: bool,
    /// Remarks for the report.
    pub notes: Vec<String>,
    /// The workspace map (for roadmaps and plots).
    #[serde(skip)]
    pub map: WorkspaceMap,
}

/// Runs the flow up to the chosen poses (see the module documentation). `progress` receives a
/// short description of each step.
#[allow(clippy::too_many_arguments)]
pub fn plan_design(
    model: &RobotModel,
    checker: &SafetyChecker<'_, RobotModel>,
    device: &dyn MeasuringDevice,
    workspace: &WorkspaceSettings,
    identify: &IdentifySettings,
    settings: &DesignSettings,
    mut progress: impl FnMut(&str),
) -> Result<PlanDesign> {
    settings.validate()?;
    progress("searching the workspace");
    let map = search(model, checker, Some(device), workspace)?;
    map.require_nonempty()?;
    progress("placing the regular grid");
    let grid = grid_at_spacing(
        model,
        checker,
        Some(device),
        &map,
        settings.wanted_poses,
        spacing_for(&map, settings.wanted_poses),
    )?;
    progress("drawing the pool");
    let pool_poses = match settings.pool {
        PoolKind::Grid => grid_at_spacing(
            model,
            checker,
            Some(device),
            &map,
            settings.pool_size,
            spacing_for(&map, settings.pool_size),
        )?,
        PoolKind::Random => {
            let poses = sample_measurable(model, checker, Some(device), &map, settings.pool_size, settings.seed)?;
            SpreadGrid {
                wanted: settings.pool_size,
                spacing: 0.0,
                volume: map.measurable_volume(),
                tried: poses.len(),
                poses,
                rejected: Default::default(),
            }
        }
    };
    let mut notes = Vec::new();
    if grid.poses.is_empty() {
        notes.push(format!(
            "the regular grid of spacing {:.4} has no measurable node; only the pool is used",
            grid.spacing
        ));
    }
    let mut poses: Vec<Vec<f64>> = pool_poses.poses.iter().map(|c| c.q.clone()).collect();
    let grid_indices: Vec<usize> = (poses.len()..poses.len() + grid.poses.len()).collect();
    poses.extend(grid.poses.iter().map(|c| c.q.clone()));
    let mut covs = Vec::with_capacity(poses.len());
    for c in pool_poses.poses.iter().chain(&grid.poses) {
        covs.push(device.position_covariance(&c.t_base_tool)?);
    }
    progress("computing the information of every candidate");
    let options = identify.options(device.t_device_base());
    let kp = kinematic_pool(model, &poses, &covs, &options)?;
    if !kp.not_identifiable.is_empty() {
        notes.push(format!(
            "not identifiable from any pose the device can measure (kept at their start values): {}",
            kp.not_identifiable.join(", ")
        ));
    }
    let candidates: Vec<usize> = (0..poses.len()).collect();
    let sel_settings =
        SelectionSettings { criterion: settings.criterion, exchange: settings.exchange, ..Default::default() };
    progress("greedy deletion");
    let history = greedy_deletion(&kp.pool, &candidates, 0, settings.criterion, sel_settings.screen)?;
    let mut count = settings.wanted_poses.min(candidates.len()).max(history.minimum_count);
    if count != settings.wanted_poses {
        notes.push(format!(
            "{} poses wanted, {count} used (the candidates allow {}..={})",
            settings.wanted_poses,
            history.minimum_count,
            candidates.len()
        ));
    }
    let mut rounds = Vec::new();
    let mut selection;
    loop {
        progress(&format!("selecting {count} poses"));
        selection = select_from_history(&kp.pool, &candidates, count, &sel_settings, history.clone())?;
        let criteria = CriteriaSummary::of(&kp.pool.information(&selection.chosen))
            .ok_or_else(|| CalibError::Numeric("non-finite information".into()))?;
        let validation: Vec<usize> = candidates.iter().copied().filter(|k| !selection.chosen.contains(k)).collect();
        let pred = predict(&kp, &selection.chosen, &validation)?;
        let dressler = dressler_check(&kp, &selection.chosen, settings.dressler_limit)?;
        let mut failures = Vec::new();
        if settings.enforce_dressler && !dressler.passed {
            failures.push(format!(
                "sigma_max^2 / sigma_min = {:.1} is not below {}",
                dressler.ratio, settings.dressler_limit
            ));
        }
        if let Some(m) = settings.max_rms_error_mm {
            if pred.heldout_rms_mm > m {
                failures.push(format!(
                    "predicted held-out RMS error {:.4} mm is above the wanted {m} mm",
                    pred.heldout_rms_mm
                ));
            }
        }
        let passed = failures.is_empty();
        rounds.push(Round {
            count,
            value: selection.value,
            criteria,
            dressler,
            heldout_rms_mm: pred.heldout_rms_mm,
            passed,
            failures,
        });
        if passed || rounds.len() >= settings.max_rounds.max(1) || count >= candidates.len() {
            break;
        }
        count = ((count as f64 * settings.growth).ceil() as usize).min(candidates.len());
    }
    let last = rounds.last().cloned().ok_or_else(|| CalibError::Data("no design round ran".into()))?;
    if !last.passed {
        notes.push(format!("the plan still fails after {} round(s): {}", rounds.len(), last.failures.join("; ")));
    }
    let chosen = match settings.plan {
        PlannedSet::Optimised => selection.chosen.clone(),
        PlannedSet::Grid => grid_indices.clone(),
    };
    if chosen.is_empty() {
        return Err(CalibError::TooFew("the planned set is empty (the regular grid found no pose)".into()));
    }
    let validation: Vec<usize> = candidates.iter().copied().filter(|k| !chosen.contains(k)).collect();
    let prediction = predict(&kp, &chosen, &validation)?;
    let criteria = CriteriaSummary::of(&kp.pool.information(&chosen))
        .ok_or_else(|| CalibError::Numeric("non-finite information".into()))?;
    let dressler = dressler_check(&kp, &chosen, settings.dressler_limit)?;
    // The source's grid is judged by the same checks when it is the planned set.
    let passed = match settings.plan {
        PlannedSet::Optimised => last.passed,
        PlannedSet::Grid => {
            let rms_ok = settings.max_rms_error_mm.is_none_or(|m| prediction.heldout_rms_mm <= m);
            let ok = rms_ok && (!settings.enforce_dressler || dressler.passed);
            if !ok {
                notes.push("the regular grid (the planned set) fails a check".into());
            }
            ok
        }
    };
    let (grid_criteria, grid_prediction) = if grid_indices.is_empty() {
        (None, None)
    } else {
        let gv: Vec<usize> = candidates.iter().copied().filter(|k| !grid_indices.contains(k)).collect();
        (CriteriaSummary::of(&kp.pool.information(&grid_indices)), predict(&kp, &grid_indices, &gv).ok())
    };
    Ok(PlanDesign {
        device: device.name(),
        settings: settings.clone(),
        workspace: WorkspaceSummary::of(&map),
        grid: GridSummary::of(&grid),
        pool_grid: GridSummary::of(&pool_poses),
        kinematic: kp,
        grid_indices,
        options,
        selection,
        passed,
        rounds,
        chosen,
        validation,
        prediction,
        criteria,
        dressler,
        grid_criteria,
        grid_prediction,
        notes,
        map,
    })
}
