//! `ferrocal plan`: the source's automated calibration flow from a plan file (TOML,
//! `docs/plan-format.md`): workspace by search cut by every safety zone, the measurable region of
//! the cameras (or tracker), the regular grid for the wanted count, a denser pool, pose selection
//! by a design criterion, the predicted calibration checked against simulated calibrations, a
//! safe visiting order and the robot programs, with an HTML report.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use ferrocal_calib::design::criteria::Criterion;
use ferrocal_calib::design::flow::{plan_design, DesignSettings, PlanDesign};
use ferrocal_calib::design::kinematic::{
    monte_carlo, predict, row_sigma_m, CalibrationSimulator, IdentifySettings, MonteCarloReport, SimulatedCell,
};
use ferrocal_calib::{CalibError, PoseMeasurement};
use ferrocal_datasets::sim::{CameraSection, Conditions, GeometricErrors, TargetSection, TrueRobot};
use ferrocal_robot::program::{
    gcode, path_csv, plan_path, rapid_module, verify_path, PathSettings, PlannedPath, ProgramSettings,
};
use ferrocal_robot::safety::{SafetyChecker, SafetyConfig};
use ferrocal_robot::workspace::{
    CameraRig, CameraView, MeasuringDevice, TargetShape, TrackerView, VisibilitySettings, WorkspaceSettings,
};
use ferrocal_robot::{Kinematics, Parameterized, RobotModel};
use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Deserialize;
use serde_json::json;

use crate::plot::{self, Series};
use crate::report::{write_atomic, Provenance, Report, Section};

/// `ferrocal plan`.
#[derive(Debug, clap::Args)]
#[command(
    about = "Plan measurement poses: safe, measurable workspace, pose selection, predicted and simulated calibration, path and robot programs",
    long_about = "Runs the source's automated calibration flow on a plan file (TOML; see docs/plan-format.md and datasets/cells/plan_gantry_tau_l1.toml):\n\n  1. the workspace by grid search, cut by joint limits, spherical-joint limits, the workspace-edge margin and every obstacle box with its margin;\n  2. the measurable region: the whole target inside every image with large enough features and an acceptable viewing angle, line of sight free (or a tracker's range and line of sight);\n  3. the regular grid for the wanted count (spacing = (volume / wanted)^(1/3)) and a denser pool;\n  4. selection by the A, D, K or N criterion (greedy deletion, exchange), the sigma_max^2/sigma_min check and the predicted accuracy, adding poses while a check fails;\n  5. simulated calibrations (Monte Carlo) against the predicted parameter deviations;\n  6. a short, checked path through joint space and the programs.\n\nWrites into --out: poses.csv (the measurement poses in visiting order), path.csv (every step), grid_poses.csv (the source's regular grid), program.mod (ABB RAPID), program.ngc (G-code), session_plan.toml (a [plan] table for `ferrocal simulate`), index.html and report.json. Exits 0 when the plan passes its checks, 2 when it was written but a check failed."
)]
pub struct PlanArgs {
    /// The plan file (TOML).
    #[arg(long)]
    pub plan: PathBuf,
    /// Folder for the poses, programs and report.
    #[arg(long)]
    pub out: PathBuf,
    /// Simulated calibrations of the Monte Carlo check (0: skip; the plan file's
    /// `[simulation] runs` by default). The study of the prediction uses 200.
    #[arg(long)]
    pub simulations: Option<usize>,
    /// Override the selection criterion (a, d, k, n, dressler).
    #[arg(long)]
    pub criterion: Option<Criterion>,
    /// Override the wanted number of poses.
    #[arg(long)]
    pub wanted: Option<usize>,
    /// Random subsets of the chosen size compared with the selection.
    #[arg(long, default_value_t = 1000)]
    pub random_subsets: usize,
    /// Override the seed of the random pool, subsets and simulations.
    #[arg(long)]
    pub seed: Option<u64>,
}

/// The robot of a plan file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotRef {
    /// Preset name, URDF or TOML model (relative paths: relative to the plan file).
    pub model: String,
}

/// A laser tracker in a plan file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackerSection {
    /// Name.
    #[serde(default = "default_tracker_name")]
    pub name: String,
    /// Position in the base frame, metres.
    pub position_m: [f64; 3],
    /// Orientation, roll-pitch-yaw degrees.
    #[serde(default)]
    pub rpy_deg: [f64; 3],
    /// Usable distance range, metres.
    #[serde(default = "default_range")]
    pub range_m: [f64; 2],
    /// Constant noise, micrometres per axis.
    #[serde(default = "default_sigma_const")]
    pub sigma_const_um: f64,
    /// Distance-proportional noise, micrometres per metre.
    #[serde(default = "default_sigma_per_m")]
    pub sigma_per_m_um: f64,
    /// Reflector position in the tool frame, metres.
    #[serde(default)]
    pub reflector_in_tool_m: [f64; 3],
    /// Reflector axis in the tool frame (none: any direction).
    #[serde(default)]
    pub reflector_axis_in_tool: Option<[f64; 3]>,
    /// Half acceptance angle of the reflector, degrees.
    #[serde(default = "default_incidence")]
    pub max_incidence_deg: f64,
}

fn default_tracker_name() -> String {
    "tracker".into()
}
fn default_range() -> [f64; 2] {
    [0.5, 20.0]
}
fn default_sigma_const() -> f64 {
    15.0
}
fn default_sigma_per_m() -> f64 {
    6.0
}
fn default_incidence() -> f64 {
    30.0
}

/// The Monte Carlo check of a plan file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimulationSection {
    /// Simulated calibrations.
    #[serde(default = "default_runs")]
    pub runs: usize,
    /// Seed.
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// Geometric errors of the true robots (the a-priori model's uncertainty).
    #[serde(default = "default_errors")]
    pub errors: GeometricErrors,
}

fn default_runs() -> usize {
    50
}
fn default_seed() -> u64 {
    1
}
fn default_errors() -> GeometricErrors {
    GeometricErrors { length_sigma_mm: 1.0, angle_sigma_mrad: 1.0, dimensionless_sigma: 2e-3, ..Default::default() }
}

impl Default for SimulationSection {
    fn default() -> Self {
        Self { runs: default_runs(), seed: default_seed(), errors: default_errors() }
    }
}

/// A plan file (see `docs/plan-format.md`).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanFile {
    /// Name shown in the report.
    #[serde(default)]
    pub name: String,
    /// The a-priori model.
    pub robot: RobotRef,
    /// Safety zones.
    #[serde(default)]
    pub safety: SafetyConfig,
    /// Workspace search.
    #[serde(default)]
    pub workspace: WorkspaceSettings,
    /// The target on the tool (cameras only).
    #[serde(default)]
    pub target: Option<TargetSection>,
    /// Cameras.
    #[serde(default, rename = "camera")]
    pub cameras: Vec<CameraSection>,
    /// What the cameras must see.
    #[serde(default)]
    pub measure: VisibilitySettings,
    /// A laser tracker instead of cameras.
    #[serde(default)]
    pub tracker: Option<TrackerSection>,
    /// Parameters to identify.
    #[serde(default)]
    pub identify: IdentifySettings,
    /// Design settings.
    #[serde(default)]
    pub design: DesignSettings,
    /// Monte Carlo check.
    #[serde(default)]
    pub simulation: SimulationSection,
    /// Path settings.
    #[serde(default)]
    pub path: PathSettings,
    /// Program settings.
    #[serde(default)]
    pub program: ProgramSettings,
}

impl PlanFile {
    /// Reads a plan file; errors name the file, line and column; model paths become relative to
    /// the file.
    pub fn from_file(path: &Path) -> Result<Self> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("cannot read plan file {}", path.display()))?;
        let mut plan: PlanFile = toml::from_str(&text).map_err(|e| {
            let (line, column) = e.span().map_or((1, 1), |s| ferrocal_robot::error::line_col(&text, s.start));
            anyhow::anyhow!("{}:{line}:{column}: {}", path.display(), e.message())
        })?;
        let m = Path::new(&plan.robot.model);
        if m.extension().is_some() && m.is_relative() {
            if let Some(dir) = path.parent() {
                let cand = dir.join(m);
                if cand.exists() {
                    plan.robot.model = cand.display().to_string();
                }
            }
        }
        plan.safety.validate().map_err(|e| anyhow::anyhow!("{}: [safety]: {e}", path.display()))?;
        match (plan.cameras.is_empty(), &plan.tracker) {
            (true, None) => bail!("{}: give [[camera]] sections (with [target]) or a [tracker]", path.display()),
            (false, Some(_)) => bail!("{}: give either cameras or a tracker, not both", path.display()),
            (false, None) if plan.target.is_none() => {
                bail!("{}: the cameras need a [target] section (the pattern on the tool)", path.display())
            }
            _ => {}
        }
        Ok(plan)
    }
}

/// A camera view from the cell format's camera section (projection by the vision crate's lens
/// model, within its one-to-one field of view).
pub fn camera_view(c: &CameraSection) -> Result<CameraView> {
    let model = c.model;
    model.validate().with_context(|| format!("camera '{}'", c.name))?;
    let max_angle = model.max_field_angle_rad();
    let t = c.t_world_cam().with_context(|| format!("camera '{}'", c.name))?;
    Ok(CameraView::new(
        c.name.clone(),
        t,
        model.image_size.width_px,
        model.image_size.height_px,
        move |p: &Point3<f64>| {
            if p.x.hypot(p.y).atan2(p.z) >= max_angle {
                return None;
            }
            model.project(p).ok()
        },
    ))
}

/// The measuring device of a plan file.
pub fn device(plan: &PlanFile) -> Result<Box<dyn MeasuringDevice>> {
    if let Some(t) = &plan.tracker {
        let r = t.rpy_deg.map(f64::to_radians);
        let pose = Isometry3::from_parts(
            Translation3::new(t.position_m[0], t.position_m[1], t.position_m[2]),
            UnitQuaternion::from_euler_angles(r[0], r[1], r[2]),
        );
        if !(t.range_m[0] >= 0.0 && t.range_m[0] < t.range_m[1]) {
            bail!("[tracker] range_m must be [min, max] with 0 <= min < max");
        }
        return Ok(Box::new(TrackerView {
            name: t.name.clone(),
            t_base_tracker: pose,
            range_m: t.range_m,
            sigma_const_um: t.sigma_const_um,
            sigma_per_m_um: t.sigma_per_m_um,
            reflector_in_tool_m: Vector3::from(t.reflector_in_tool_m),
            reflector_axis_in_tool: t.reflector_axis_in_tool.map(Vector3::from),
            max_incidence_deg: t.max_incidence_deg,
            occluders: plan.safety.obstacles.clone(),
        }));
    }
    let target = plan.target.as_ref().context("the cameras need a [target]")?;
    let geo = target.pattern.build().context("[target]")?;
    let corners: Vec<Point3<f64>> = geo.corners.iter().map(|c| c.p_target_m).collect();
    let shape = TargetShape::new(&geo.outline_m, &geo.dark_m, &corners);
    let cams = plan.cameras.iter().map(camera_view).collect::<Result<Vec<_>>>()?;
    Ok(Box::new(CameraRig::new(
        cams,
        shape,
        target.t_tool_target.isometry(),
        plan.measure.clone(),
        plan.safety.obstacles.clone(),
    )?))
}

/// Simulated campaigns with the datasets crate's true robot: geometric errors drawn per run, the
/// measured point in the device frame with Gaussian noise of the device's covariance at the pose.
pub struct DatasetsSimulator {
    /// The a-priori model.
    pub nominal: RobotModel,
    /// Geometric errors of the true robots.
    pub errors: GeometricErrors,
    /// `T_device_base`.
    pub t_device_base: Isometry3<f64>,
    /// Measured point in the tool frame.
    pub point_in_tool_m: Vector3<f64>,
    /// Seed.
    pub seed: u64,
}

impl CalibrationSimulator for DatasetsSimulator {
    fn simulate(
        &mut self,
        run: usize,
        train: &[Vec<f64>],
        covariances: &[Matrix3<f64>],
        validation: &[Vec<f64>],
    ) -> ferrocal_calib::Result<SimulatedCell> {
        let data = |e: String| CalibError::Data(e);
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed.wrapping_mul(1_000_003).wrapping_add(run as u64));
        let truth = TrueRobot::new(self.nominal.clone(), &self.errors, vec![], 0.0, &mut rng)
            .map_err(|e| data(e.to_string()))?;
        let cond = Conditions { temp_c: 20.0, dir: vec![0; self.nominal.dof()], ..Default::default() };
        let position = |q: &[f64]| -> ferrocal_calib::Result<Vector3<f64>> {
            let t = truth.tool_pose(q, &cond).map_err(|e| data(e.to_string()))?;
            Ok((self.t_device_base * t * Point3::from(self.point_in_tool_m)).coords)
        };
        let mut rows = Vec::with_capacity(train.len());
        for (k, (q, c)) in train.iter().zip(covariances).enumerate() {
            let l = c.cholesky().ok_or_else(|| data(format!("pose {}: covariance not positive definite", k + 1)))?.l();
            let z = Vector3::new(gauss(&mut rng), gauss(&mut rng), gauss(&mut rng));
            let mut row = PoseMeasurement::new(format!("{}", k + 1), q.clone(), position(q)? + l * z);
            row.sigma_m = Some(row_sigma_m(c));
            rows.push(row);
        }
        let truth_map: BTreeMap<String, f64> =
            truth.truth.parameters().into_iter().map(|p| (p.name, p.value)).collect();
        let validation_true_m = validation.iter().map(|q| position(q)).collect::<ferrocal_calib::Result<_>>()?;
        Ok(SimulatedCell { rows, truth: truth_map, validation_true_m })
    }
}

/// A standard normal sample (Box-Muller).
fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>();
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Best and median criterion value of random subsets of `count` candidates.
pub fn random_subsets(
    design: &PlanDesign,
    count: usize,
    n: usize,
    criterion: Criterion,
    seed: u64,
) -> Option<(f64, f64, usize)> {
    let pool = &design.kinematic.pool;
    if n == 0 || count > pool.len() {
        return None;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut idx: Vec<usize> = (0..pool.len()).collect();
    let mut losses = Vec::with_capacity(n);
    for _ in 0..n {
        // Partial Fisher-Yates shuffle.
        for i in 0..count {
            let j = rng.random_range(i..idx.len());
            idx.swap(i, j);
        }
        losses.push(pool.loss(&idx[..count], criterion));
    }
    let singular = losses.iter().filter(|l| !l.is_finite()).count();
    losses.sort_by(|a, b| a.total_cmp(b));
    let best = criterion.value(losses[0]);
    let median = criterion.value(losses[losses.len() / 2]);
    Some((best, median, singular))
}

/// Formats a parameter value in its unit (mm for metres, 1e-3 for dimensionless, mrad).
fn fmt_param(name: &str, v: f64) -> String {
    if name.ends_with("_m") {
        format!("{:.4} mm", v * 1e3)
    } else if name.ends_with("_rad") {
        format!("{:.4} mrad", v * 1e3)
    } else {
        format!("{:.4} e-3", v * 1e3)
    }
}

fn tool_positions(model: &RobotModel, poses: &[&Vec<f64>]) -> Vec<Vector3<f64>> {
    poses.iter().filter_map(|q| model.forward(q).ok().map(|t| t.translation.vector * 1e3)).collect()
}

fn projections(title: &str, series: &[(&str, Vec<Vector3<f64>>, bool)]) -> (String, String) {
    let xy: Vec<Vec<(f64, f64)>> = series.iter().map(|s| s.1.iter().map(|p| (p.x, p.y)).collect()).collect();
    let xz: Vec<Vec<(f64, f64)>> = series.iter().map(|s| s.1.iter().map(|p| (p.x, p.z)).collect()).collect();
    fn mk<'a>(series: &'a [(&'a str, Vec<Vector3<f64>>, bool)], pts: &'a [Vec<(f64, f64)>]) -> Vec<Series<'a>> {
        series.iter().zip(pts).map(|(s, p)| Series { name: s.0, points: p, line: s.2 }).collect()
    }
    (
        plot::xy_plot(&format!("{title}: top view"), "x (mm)", "y (mm)", &mk(series, &xy)),
        plot::xy_plot(&format!("{title}: side view"), "x (mm)", "z (mm)", &mk(series, &xz)),
    )
}

/// Runs `ferrocal plan`.
pub fn run(args: &PlanArgs) -> Result<ExitCode> {
    let mut plan = PlanFile::from_file(&args.plan)?;
    if let Some(c) = args.criterion {
        plan.design.criterion = c;
    }
    if let Some(w) = args.wanted {
        plan.design.wanted_poses = w;
        plan.design.pool_size = plan.design.pool_size.max(w);
    }
    if let Some(s) = args.seed {
        plan.design.seed = s;
        plan.simulation.seed = s;
    }
    let runs = args.simulations.unwrap_or(plan.simulation.runs);
    let model = RobotModel::load(&plan.robot.model).with_context(|| format!("robot model '{}'", plan.robot.model))?;
    let checker = SafetyChecker::new(&model, plan.safety.clone()).context("[safety]")?;
    let dev = device(&plan)?;
    let t0 = std::time::Instant::now();
    let design = plan_design(&model, &checker, dev.as_ref(), &plan.workspace, &plan.identify, &plan.design, |s| {
        eprintln!("[{:6.1} s] {s}", t0.elapsed().as_secs_f64())
    })?;

    // Monte Carlo check.
    let mc: Option<MonteCarloReport> = if runs >= 2 {
        eprintln!("[{:6.1} s] {runs} simulated calibrations", t0.elapsed().as_secs_f64());
        let mut sim = DatasetsSimulator {
            nominal: model.clone(),
            errors: plan.simulation.errors.clone(),
            t_device_base: dev.t_device_base(),
            point_in_tool_m: dev.measured_point_in_tool_m(),
            seed: plan.simulation.seed,
        };
        let pb = crate::progress::bar(runs as u64, "simulated calibrations");
        let r = monte_carlo(
            &model,
            &design.options,
            &design.kinematic,
            &design.chosen,
            &design.validation,
            &mut sim,
            runs,
            |k| pb.set_position(k as u64),
        );
        pb.finish_and_clear();
        Some(r.context("Monte Carlo check")?)
    } else {
        None
    };

    // Path and programs.
    eprintln!("[{:6.1} s] ordering {} poses", t0.elapsed().as_secs_f64(), design.chosen.len());
    let poses: Vec<Vec<f64>> = design.chosen.iter().map(|&k| design.kinematic.poses[k].clone()).collect();
    let path = plan_path(&model, &checker, &design.map.home, &poses, &design.kinematic.poses, &plan.path)
        .context("ordering the poses")?;
    if let Err(e) = verify_path(&checker, &path) {
        bail!("internal error: the planned path failed its own safety check: {e}");
    }
    let header = vec![
        format!("ferrocal plan {} ({})", env!("CARGO_PKG_VERSION"), chrono::Utc::now().to_rfc3339()),
        format!("plan file {}; robot {}; device {}", args.plan.display(), model.name(), design.device),
        format!(
            "{} measurements; every configuration and joint-space segment checked against the safety zones",
            path.measurements()
        ),
    ];
    std::fs::create_dir_all(&args.out).with_context(|| format!("cannot create {}", args.out.display()))?;
    write_atomic(&args.out.join("poses.csv"), path_csv(&model, &path, true)?.as_bytes())?;
    write_atomic(&args.out.join("path.csv"), path_csv(&model, &path, false)?.as_bytes())?;
    let grid_path = PlannedPath {
        steps: design
            .grid_indices
            .iter()
            .map(|&k| ferrocal_robot::program::PathStep {
                q: design.kinematic.poses[k].clone(),
                kind: ferrocal_robot::program::StepKind::Measure,
                pose: Some(k),
                dir: vec![0; model.dof()],
            })
            .collect(),
        order: Vec::new(),
        travel_s: 0.0,
        dwell_s: 0.0,
        nearest_neighbour_s: 0.0,
        ordered_s: 0.0,
        detours: 0,
        checked_segments: 0,
    };
    write_atomic(&args.out.join("grid_poses.csv"), path_csv(&model, &grid_path, true)?.as_bytes())?;
    let rapid = rapid_module(&model, &path, plan.path.dwell_s, &plan.program, &header)?;
    write_atomic(&args.out.join("program.mod"), rapid.as_bytes())?;
    let g = gcode(&model, &path, plan.path.dwell_s, &plan.program, &header)?;
    write_atomic(&args.out.join("program.ngc"), g.text.as_bytes())?;
    let mut session = String::from("# The planned poses as the [plan] table of a cell file (ferrocal simulate).\n");
    session.push_str(&format!("[plan]\nkind = \"list\"\nseconds_per_pose = {}\n", plan.path.dwell_s.max(1.0)));
    session.push_str(&format!(
        "home_si = [{}]\njoints_si = [\n",
        design.map.home.iter().map(|v| format!("{v:.9}")).collect::<Vec<_>>().join(", ")
    ));
    for st in path.steps.iter().filter(|s| s.kind == ferrocal_robot::program::StepKind::Measure) {
        session.push_str(&format!("  [{}],\n", st.q.iter().map(|v| format!("{v:.9}")).collect::<Vec<_>>().join(", ")));
    }
    session.push_str("]\n");
    write_atomic(&args.out.join("session_plan.toml"), session.as_bytes())?;

    // Report.
    let mut prov = Provenance::new(json!({
        "plan": plan.name,
        "design": plan.design,
        "identify": plan.identify,
        "simulations": runs,
        "random_subsets": args.random_subsets,
    }));
    prov.add_input(&args.plan);
    let title = if plan.name.is_empty() { format!("Measurement plan for {}", model.name()) } else { plan.name.clone() };
    let mut rep = Report::new(&title, prov);
    let random =
        random_subsets(&design, design.chosen.len(), args.random_subsets, design.settings.criterion, plan.design.seed);
    rep.sections.push(summary_section(&design, &path, mc.as_ref(), random));
    rep.sections.push(workspace_section(&model, &design));
    rep.sections.push(selection_section(&design, random, args.random_subsets));
    rep.sections.push(prediction_section(&design, mc.as_ref()));
    rep.sections.push(path_section(&model, &path, &plan, g.max_chord_deviation_mm));
    let html = rep.write(&args.out)?;
    eprintln!(
        "[{:6.1} s] {} poses planned ({}); report {}",
        t0.elapsed().as_secs_f64(),
        path.measurements(),
        if design.passed { "checks passed" } else { "a check FAILED" },
        html.display()
    );
    Ok(if design.passed { ExitCode::SUCCESS } else { ExitCode::from(2) })
}

fn summary_section(
    d: &PlanDesign,
    path: &PlannedPath,
    mc: Option<&MonteCarloReport>,
    random: Option<(f64, f64, usize)>,
) -> Section {
    let mut s = Section::new("summary", "Summary");
    s.status(d.passed, if d.passed { "checks passed" } else { "check failed" });
    let w = &d.workspace;
    let c = d.settings.criterion;
    let mut rows = vec![
        vec!["device".into(), d.device.clone()],
        vec![
            "workspace left after obstacles".into(),
            format!(
                "{:.1} % ({:.3} of {:.3} {})",
                100.0 * w.fraction_after_obstacles,
                w.safe_volume,
                w.kinematic_volume,
                w.volume_unit
            ),
        ],
        vec![
            "measurable region".into(),
            format!(
                "{:.3} {} ({:.1} % of the workspace)",
                w.measurable_volume,
                w.volume_unit,
                100.0 * w.measurable_fraction
            ),
        ],
        vec![
            format!("regular grid for {} wanted poses", d.grid.wanted),
            format!("spacing {:.4} -> {} poses (source: 100 -> 0.1367 m -> 112)", d.grid.spacing, d.grid.count),
        ],
        vec!["optimisation pool".into(), format!("{} poses (spacing {:.4})", d.pool_grid.count, d.pool_grid.spacing)],
        vec![
            format!("criterion {c} of the chosen {} poses", d.chosen.len()),
            format!("{:.4} ({})", d.criteria.get(c), c.describe()),
        ],
        vec![
            "sigma_max^2 / sigma_min (SI Jacobian)".into(),
            format!(
                "{:.1} (sigma {:.3} .. {:.2}; limit {}{})",
                d.dressler.ratio,
                d.dressler.sigma_min,
                d.dressler.sigma_max,
                d.dressler.limit,
                if d.settings.enforce_dressler { "" } else { ", reported, not enforced" }
            ),
        ],
        vec![
            "predicted held-out RMS error".into(),
            format!(
                "{:.4} mm (model error, measurement noise {:.3} mm RMS)",
                d.prediction.heldout_rms_mm, d.prediction.noise_rms_mm
            ),
        ],
    ];
    if let Some((best, median, _)) = random {
        rows.push(vec![
            format!("random subsets of {} poses", d.chosen.len()),
            format!("best {best:.4}, median {median:.4}"),
        ]);
    }
    if let Some(m) = mc {
        rows.push(vec![
            format!("simulated calibrations ({} used)", m.used),
            format!(
                "held-out RMS {:.4} mm (predicted {:.4}); parameter scatter / prediction: median {:.3}, worst |ratio - 1| {:.3}",
                m.simulated_heldout_rms_mm, m.predicted_heldout_rms_mm, m.median_ratio, m.worst_ratio_deviation
            ),
        ]);
    }
    rows.push(vec![
        "path".into(),
        format!(
            "{} steps, {} measurements, travel {:.0} s + measuring {:.0} s, {} detour(s)",
            path.steps.len(),
            path.measurements(),
            path.travel_s,
            path.dwell_s,
            path.detours
        ),
    ]);
    s.table("The plan in numbers", &["quantity", "value"], rows);
    for n in &d.notes {
        s.text(n.clone());
    }
    s.data = json!({
        "device": d.device,
        "workspace_fraction_after_obstacles": w.fraction_after_obstacles,
        "measurable_volume": w.measurable_volume,
        "volume_unit": w.volume_unit,
        "grid_spacing": d.grid.spacing,
        "grid_count": d.grid.count,
        "wanted": d.grid.wanted,
        "pool_count": d.pool_grid.count,
        "chosen": d.chosen.len(),
        "criterion": c,
        "criterion_value": d.criteria.get(c),
        "criteria": d.criteria,
        "dressler": d.dressler,
        "predicted_heldout_rms_mm": d.prediction.heldout_rms_mm,
        "passed": d.passed,
        "notes": d.notes,
    });
    s
}

fn workspace_section(model: &RobotModel, d: &PlanDesign) -> Section {
    let mut s = Section::new("workspace", "Workspace and measurable region");
    let w = &d.workspace;
    s.text(format!(
        "Grid search over {} lattice nodes (spacing {}). Every node is classified by the first constraint it breaks, in this order; the volume is the count times the cell volume.",
        w.total, w.spacing
    ));
    let cell = if w.total > 0 && w.kinematic > 0 { w.kinematic_volume / w.kinematic as f64 } else { 0.0 };
    let rows = w
        .stages
        .iter()
        .map(|st| {
            vec![
                st.name.clone(),
                st.removed.to_string(),
                st.survivors.to_string(),
                format!("{:.4}", st.survivors as f64 * cell),
            ]
        })
        .collect();
    s.table(
        "Survivors after each constraint",
        &["constraint", "removed", "left", &format!("volume left ({})", w.volume_unit)],
        rows,
    );
    if !w.unmeasurable.is_empty() {
        s.table(
            "Why the device cannot measure",
            &["reason", "nodes"],
            w.unmeasurable.iter().map(|(r, n)| vec![r.clone(), n.to_string()]).collect(),
        );
    }
    let step = (d.map.measurable.len() / 2500).max(1);
    let region: Vec<&Vec<f64>> = d.map.measurable.iter().step_by(step).map(|c| &c.q).collect();
    let grid: Vec<&Vec<f64>> = d.grid_indices.iter().map(|&k| &d.kinematic.poses[k]).collect();
    let chosen: Vec<&Vec<f64>> = d.chosen.iter().map(|&k| &d.kinematic.poses[k]).collect();
    let (a, b) = projections(
        "Tool positions",
        &[
            ("measurable region", tool_positions(model, &region), false),
            ("regular grid", tool_positions(model, &grid), false),
            ("chosen", tool_positions(model, &chosen), false),
        ],
    );
    s.figure("Measurable region (sampled), the source's regular grid and the chosen poses, top view", a);
    s.figure("The same, side view", b);
    s.data = serde_json::to_value(w).unwrap_or_default();
    s
}

fn selection_section(d: &PlanDesign, random: Option<(f64, f64, usize)>, n_random: usize) -> Section {
    let c = d.settings.criterion;
    let mut s = Section::new("selection", &format!("Pose selection by the {c} criterion"));
    s.text(format!(
        "Greedy deletion from {} candidates (the pool and the regular grid), removing at every step the pose whose removal degrades {} least (rank-one downdates of the information), on down to the smallest set that keeps full rank ({} poses), then exchange refinement at the chosen count.",
        d.kinematic.poses.len(),
        c.describe(),
        d.selection.history.minimum_count
    ));
    let curve: Vec<(f64, f64)> = d.selection.history.curve().iter().map(|(n, v)| (*n as f64, *v)).collect();
    let chosen_pt = [(d.selection.chosen.len() as f64, d.selection.value)];
    let grid_pt: Vec<(f64, f64)> =
        d.grid_criteria.as_ref().map(|g| vec![(d.grid_indices.len() as f64, g.get(c))]).unwrap_or_default();
    let rand_pt: Vec<(f64, f64)> = random.map(|r| vec![(d.chosen.len() as f64, r.0)]).unwrap_or_default();
    let series = [
        Series { name: "greedy deletion", points: &curve, line: true },
        Series { name: "chosen (after exchange)", points: &chosen_pt, line: false },
        Series { name: "regular grid", points: &grid_pt, line: false },
        Series { name: "best random subset", points: &rand_pt, line: false },
    ];
    s.figure(
        &format!("Criterion {c} against the number of poses"),
        plot::xy_plot(&format!("{c} criterion vs count"), "poses", c.describe(), &series),
    );
    // Predicted accuracy against the count along the greedy path.
    let h = &d.selection.history;
    let n = h.start.len();
    let mut counts: Vec<usize> = Vec::new();
    let mut k = h.minimum_count.max(1) as f64;
    while (k as usize) <= n {
        counts.push(k as usize);
        k *= 1.15;
        k = k.ceil();
    }
    let acc: Vec<(f64, f64)> = counts
        .iter()
        .filter_map(|&m| {
            let sub = h.subset_at(m)?;
            let val: Vec<usize> = (0..n).filter(|i| !sub.contains(i)).collect();
            predict(&d.kinematic, &sub, &val).ok().map(|p| (m as f64, p.heldout_rms_mm))
        })
        .collect();
    s.figure(
        "Predicted held-out RMS error of the greedy sets against the count",
        plot::xy_plot(
            "Predicted accuracy vs count",
            "poses",
            "held-out RMS model error (mm)",
            &[Series { name: "greedy sets", points: &acc, line: true }],
        ),
    );
    let mut rows = vec![vec![
        format!("chosen ({})", d.chosen.len()),
        format!("{:.4}", d.criteria.a),
        format!("{:.3}", d.criteria.ln_det),
        format!("{:.2}", d.criteria.condition),
        format!("{:.4e}", d.criteria.noise_amplification),
        format!("{:.4}", d.prediction.heldout_rms_mm),
    ]];
    if let (Some(g), Some(p)) = (&d.grid_criteria, &d.grid_prediction) {
        rows.push(vec![
            format!("regular grid ({})", d.grid_indices.len()),
            format!("{:.4}", g.a),
            format!("{:.3}", g.ln_det),
            format!("{:.2}", g.condition),
            format!("{:.4e}", g.noise_amplification),
            format!("{:.4}", p.heldout_rms_mm),
        ]);
    }
    s.table(
        "Every criterion of the chosen set and of the source's grid",
        &["set", "A", "D (ln det)", "K", "N", "held-out RMS (mm)"],
        rows,
    );
    if let Some((best, median, singular)) = random {
        s.text(format!(
            "{n_random} random subsets of {} candidates: best {c} = {best:.4}, median {median:.4} ({singular} singular); the chosen set: {:.4}.",
            d.chosen.len(),
            d.selection.value
        ));
    }
    let rounds = d
        .rounds
        .iter()
        .map(|r| {
            vec![
                r.count.to_string(),
                format!("{:.4}", r.value),
                format!("{:.1}", r.dressler.ratio),
                format!("{:.4}", r.heldout_rms_mm),
                if r.passed { "passed".into() } else { r.failures.join("; ") },
            ]
        })
        .collect();
    s.table(
        "Rounds of the flow (poses are added while a check fails)",
        &["poses", c.name(), "sigma_max^2/sigma_min", "held-out RMS (mm)", "result"],
        rounds,
    );
    s.text(format!(
        "The source's check sigma_max^2 / sigma_min < C (C = {} for the L1) is computed on the unwhitened position Jacobian in SI units (metres per metre, per unit direction component), whose singular values here ({:.3} to {:.2}) have the size the source reports (0.3 to 64). With the source's own numbers the ratio is 64^2 / 0.3 = 13653, and it grows with the square root of the count: as stated it cannot hold for C = 200, so it is reported and enforced only when the plan asks for it (enforce_dressler); the flow adds poses while the predicted accuracy misses the wanted one.",
        d.dressler.limit, d.dressler.sigma_min, d.dressler.sigma_max
    ));
    s.data = json!({
        "criterion": c,
        "curve": d.selection.history.curve(),
        "minimum_count": d.selection.history.minimum_count,
        "greedy_value": c.value(d.selection.greedy_loss),
        "chosen_value": d.selection.value,
        "exchange": d.selection.exchange,
        "grid_criteria": d.grid_criteria,
        "random_subsets": random.map(|(b, m, s)| json!({"n": n_random, "best": b, "median": m, "singular": s})),
        "rounds": d.rounds,
        "accuracy_vs_count": acc,
    });
    s
}

fn prediction_section(d: &PlanDesign, mc: Option<&MonteCarloReport>) -> Section {
    let mut s = Section::new("prediction", "Predicted and simulated calibration");
    let p = &d.prediction;
    s.text(format!(
        "Predicted standard deviation of every identified parameter from the information of the chosen poses with the device's noise (per-pose covariance; the calibration weights each pose with one sigma, so the prediction is the sandwich covariance of that fit; the bound with the full covariance is shown beside it). Predicted held-out RMS model error at the {} validation poses: {:.4} mm ({:.4} mm with full-covariance weighting).",
        p.n_validation, p.heldout_rms_mm, p.heldout_rms_optimal_mm
    ));
    let mut rows = Vec::new();
    for (i, n) in p.names.iter().enumerate() {
        let mut r = vec![n.clone(), fmt_param(n, p.std_si[i]), fmt_param(n, p.std_optimal_si[i])];
        if let Some(m) = mc {
            match m.parameters.iter().find(|x| &x.name == n) {
                Some(x) => {
                    r.push(fmt_param(n, x.simulated_std_si));
                    r.push(format!("{:.3}", x.ratio));
                    r.push(fmt_param(n, x.mean_error_si));
                }
                None => r.extend(["-".to_string(), "-".to_string(), "-".to_string()]),
            }
        }
        rows.push(r);
    }
    let header: Vec<&str> = if mc.is_some() {
        vec![
            "parameter",
            "predicted std",
            "full-covariance bound",
            "simulated std",
            "simulated / predicted",
            "simulated mean error",
        ]
    } else {
        vec!["parameter", "predicted std", "full-covariance bound"]
    };
    s.table("Parameter deviations", &header, rows);
    if let Some(m) = mc {
        s.status(m.worst_ratio_deviation <= 0.2, format!("worst |sim/pred - 1| = {:.2}", m.worst_ratio_deviation));
        s.text(format!(
            "{} simulated calibrations ({} used): true robots drawn with the plan's geometric errors, measurements with the device's noise, calibrated with the same options; simulated held-out RMS model error {:.4} mm against the predicted {:.4} mm. The sampling error of a standard deviation from {} runs is about {:.0} %.",
            m.runs,
            m.used,
            m.simulated_heldout_rms_mm,
            m.predicted_heldout_rms_mm,
            m.used,
            100.0 / (2.0 * m.used as f64).sqrt()
        ));
        for sk in &m.skipped {
            s.text(sk.clone());
        }
        let pts: Vec<(f64, f64)> =
            m.parameters.iter().map(|x| (x.predicted_std_si * 1e3, x.simulated_std_si * 1e3)).collect();
        let hi = pts.iter().map(|p| p.0.max(p.1)).fold(0.0, f64::max) * 1.05;
        let diag = [(0.0, 0.0), (hi, hi)];
        s.figure(
            "Simulated against predicted standard deviation per parameter (mm, mrad or 1e-3); the line is equality",
            plot::xy_plot(
                "Predicted vs simulated deviations",
                "predicted std",
                "simulated std",
                &[
                    Series { name: "parameters", points: &pts, line: false },
                    Series { name: "equal", points: &diag, line: true },
                ],
            ),
        );
    }
    s.data = json!({ "prediction": p, "monte_carlo": mc });
    s
}

fn path_section(model: &RobotModel, path: &PlannedPath, plan: &PlanFile, chord_mm: f64) -> Section {
    let mut s = Section::new("path", "Path and programs");
    s.text(format!(
        "Nearest neighbour from home then 2-opt under the time metric max_i |dq_i| / v_i: {:.0} s -> {:.0} s between the measured poses; with approach and via moves {:.0} s of travel, {:.0} s of measuring. Approach: {:?}. Every configuration and every straight joint-space segment between consecutive steps ({} segments checked, {} detour(s) through safe via configurations) passed the safety checker.",
        path.nearest_neighbour_s,
        path.ordered_s,
        path.travel_s,
        path.dwell_s,
        plan.path.approach,
        path.checked_segments,
        path.detours
    ));
    let all: Vec<&Vec<f64>> = path.steps.iter().map(|s| &s.q).collect();
    let meas: Vec<&Vec<f64>> =
        path.steps.iter().filter(|s| s.kind == ferrocal_robot::program::StepKind::Measure).map(|s| &s.q).collect();
    let (a, b) = projections(
        "Path",
        &[("path", tool_positions(model, &all), true), ("measurements", tool_positions(model, &meas), false)],
    );
    s.figure("The path of the tool, top view", a);
    s.figure("The path of the tool, side view", b);
    s.table(
        "Files",
        &["file", "what"],
        vec![
            vec![
                "poses.csv".into(),
                "the measurement poses in visiting order (joints in deg / mm, approach directions, tool position)"
                    .into(),
            ],
            vec!["path.csv".into(), "every step: home, approach, measure, via".into()],
            vec!["grid_poses.csv".into(), "the source's regular grid for the wanted count".into()],
            vec![
                "program.mod".into(),
                format!("ABB RAPID module {} (MoveAbsJ, WaitTime \\InPos)", plan.program.rapid_module),
            ],
            vec![
                "program.ngc".into(),
                format!(
                    "G-code, {:?} axes, F{}{}",
                    plan.program.gcode_axes,
                    plan.program.gcode_feed_mm_min,
                    if chord_mm > 0.0 { format!(", largest chord deviation {chord_mm:.3} mm") } else { String::new() }
                ),
            ],
            vec!["session_plan.toml".into(), "the poses as a [plan] table for ferrocal simulate".into()],
        ],
    );
    s.data = json!({
        "steps": path.steps.len(),
        "measurements": path.measurements(),
        "travel_s": path.travel_s,
        "dwell_s": path.dwell_s,
        "nearest_neighbour_s": path.nearest_neighbour_s,
        "ordered_s": path.ordered_s,
        "detours": path.detours,
        "checked_segments": path.checked_segments,
        "gcode_max_chord_deviation_mm": chord_mm,
    });
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn example_plan_file_parses() {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../datasets/cells/plan_gantry_tau_l1.toml");
        let plan = PlanFile::from_file(&p).unwrap();
        assert_eq!(plan.cameras.len(), 1);
        assert_eq!(plan.design.wanted_poses, 100);
        assert!(device(&plan).unwrap().name().contains("left"));
    }

    #[test]
    fn plan_command_writes_the_report() {
        let dir = std::env::temp_dir().join(format!("ferrocal-plan-test-{}", std::process::id()));
        let args = PlanArgs {
            plan: Path::new(env!("CARGO_MANIFEST_DIR")).join("../datasets/cells/plan_gantry_tau_l1.toml"),
            out: dir.clone(),
            simulations: Some(8),
            criterion: None,
            wanted: Some(40),
            random_subsets: 50,
            seed: None,
        };
        let code = run(&args).unwrap();
        let _ = code;
        for f in
            ["poses.csv", "path.csv", "grid_poses.csv", "program.mod", "program.ngc", "session_plan.toml", "index.html"]
        {
            assert!(dir.join(f).exists(), "{f} missing");
        }
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
        let s = &j["sections"]["summary"]["data"];
        assert!(s["workspace_fraction_after_obstacles"].as_f64().unwrap() > 0.0);
        assert!(s["grid_spacing"].as_f64().unwrap() > 0.0);
        assert!(j["sections"]["prediction"]["data"]["monte_carlo"]["used"].as_u64().unwrap() >= 2);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
