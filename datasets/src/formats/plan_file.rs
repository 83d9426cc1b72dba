//! The plan file of `ferrocal plan` (TOML, `docs/plan-format.md`): the robot, safety zones,
//! workspace search, cameras with their target or a laser tracker, the parameters to identify,
//! the design, the Monte Carlo check, the path and the programs; and the measuring device it
//! describes. The planned poses leave as a `[plan]` table of a cell file
//! ([`session_plan_toml`]).

use std::path::Path;

use ferrocal_calib::design::flow::DesignSettings;
use ferrocal_calib::design::kinematic::IdentifySettings;
use ferrocal_robot::program::{PathSettings, PathStep, PlannedPath, ProgramSettings, StepKind};
use ferrocal_robot::safety::SafetyConfig;
use ferrocal_robot::workspace::{
    CameraView, CameraVisibility, MeasuringDevice, TargetShape, TrackerView, VisibilitySettings, WorkspaceSettings,
};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use serde::Deserialize;

use crate::error::{DatasetError, Result};
use crate::sim::{CameraSection, GeometricErrors, TargetSection};

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

/// Most simulated calibrations a plan's Monte Carlo check may ask for (each is a full
/// calibration; 10,000 already take minutes, and the sampling error of a standard deviation is
/// then 0.7 %).
pub const MAX_SIMULATION_RUNS: usize = 10_000;

/// Refuses a number of simulated calibrations beyond [`MAX_SIMULATION_RUNS`], naming `what`
/// (the plan file's key or the flag).
pub fn check_runs(runs: usize, what: &str) -> Result<()> {
    if runs > MAX_SIMULATION_RUNS {
        return Err(DatasetError::Input(format!(
            "{what} = {runs} simulated calibrations is more than {MAX_SIMULATION_RUNS} (each is a full calibration; 200 give the standard deviations to 5 %): ask for fewer"
        )));
    }
    Ok(())
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
            std::fs::read_to_string(path).map_err(|source| DatasetError::Io { path: path.to_path_buf(), source })?;
        let mut plan: PlanFile = toml::from_str(&text).map_err(|e| {
            let (line, column) = e.span().map_or((1, 1), |s| ferrocal_robot::error::line_col(&text, s.start));
            DatasetError::Input(format!("{}:{line}:{column}: {}", path.display(), e.message()))
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
        let bad = |m: String| Err(DatasetError::Input(format!("{}: {m}", path.display())));
        if let Err(e) = plan.safety.validate() {
            return bad(format!("[safety]: {e}"));
        }
        if let Err(e) = check_runs(plan.simulation.runs, "[simulation] runs") {
            return bad(e.to_string());
        }
        match (plan.cameras.is_empty(), &plan.tracker) {
            (true, None) => bad("give [[camera]] sections (with [target]) or a [tracker]".into()),
            (false, Some(_)) => bad("give either cameras or a tracker, not both".into()),
            (false, None) if plan.target.is_none() => {
                bad("the cameras need a [target] section (the pattern on the tool)".into())
            }
            _ => Ok(plan),
        }
    }
}

/// A camera view from the cell format's camera section (projection by the vision crate's lens
/// model, within its one-to-one field of view).
pub fn camera_view(c: &CameraSection) -> Result<CameraView> {
    let model = c.model;
    let named = |e: DatasetError| DatasetError::Input(format!("camera '{}': {e}", c.name));
    model.validate().map_err(|e| named(e.into()))?;
    let max_angle = model.max_field_angle_rad();
    let t = c.t_world_cam().map_err(named)?;
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
            return Err(DatasetError::Input("[tracker] range_m must be [min, max] with 0 <= min < max".into()));
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
    let target = plan.target.as_ref().ok_or_else(|| DatasetError::Input("the cameras need a [target]".into()))?;
    let geo = target.pattern.build().map_err(|e| DatasetError::Input(format!("[target]: {e}")))?;
    let corners: Vec<Point3<f64>> = geo.corners.iter().map(|c| c.p_target_m).collect();
    let shape = TargetShape::new(&geo.outline_m, &geo.dark_m, &corners);
    let cams = plan.cameras.iter().map(camera_view).collect::<Result<Vec<_>>>()?;
    let rig = CameraVisibility::new(
        cams,
        shape,
        target.t_tool_target.isometry(),
        plan.measure.clone(),
        plan.safety.obstacles.clone(),
    )
    .map_err(|e| DatasetError::Input(format!("camera rig: {e}")))?;
    Ok(Box::new(rig))
}

/// The planned measurement poses as the `[plan]` table of a cell file (`ferrocal simulate`):
/// the home configuration and the measured steps of `path`, SI joint values.
pub fn session_plan_toml(home: &[f64], path: &PlannedPath, dwell_s: f64) -> String {
    let join = |q: &[f64]| q.iter().map(|v| format!("{v:.9}")).collect::<Vec<_>>().join(", ");
    let mut s = String::from("# The planned poses as the [plan] table of a cell file (ferrocal simulate).\n");
    s.push_str(&format!("[plan]\nkind = \"list\"\nseconds_per_pose = {}\n", dwell_s.max(1.0)));
    s.push_str(&format!("home_si = [{}]\njoints_si = [\n", join(home)));
    for st in path.steps.iter().filter(|s| s.kind == StepKind::Measure) {
        s.push_str(&format!("  [{}],\n", join(&st.q)));
    }
    s.push_str("]\n");
    s
}

/// A path of measurement steps at `poses[k]` for every `k` of `indices`, in that order, with no
/// travel: the poses of a grid written as a path table.
pub fn measure_steps(poses: &[Vec<f64>], indices: &[usize]) -> PlannedPath {
    PlannedPath {
        steps: indices
            .iter()
            .map(|&k| PathStep {
                q: poses[k].clone(),
                kind: StepKind::Measure,
                pose: Some(k),
                dir: vec![0; poses[k].len()],
                label: None,
            })
            .collect(),
        ..Default::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn example() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("cells/plan_gantry_tau_l1.toml")
    }

    #[test]
    fn example_plan_file_parses() {
        let plan = PlanFile::from_file(&example()).unwrap();
        assert_eq!(plan.cameras.len(), 1);
        assert_eq!(plan.design.wanted_poses, 100);
        assert!(device(&plan).unwrap().name().contains("left"));
    }

    #[test]
    fn errors_name_the_file_line_and_column() {
        let dir = std::env::temp_dir().join(format!("ferrocal-planfile-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("bad.toml");
        std::fs::write(&p, "name = \"x\"\n[robot]\nmodel = \"ur5\"\nsurplus = 1\n").unwrap();
        let e = PlanFile::from_file(&p).unwrap_err().to_string();
        assert!(e.contains("bad.toml:4:"), "{e}");
        std::fs::write(&p, "[robot]\nmodel = \"ur5\"\n").unwrap();
        let e = PlanFile::from_file(&p).unwrap_err().to_string();
        assert!(e.contains("[[camera]]") && e.contains("[tracker]"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn session_plan_lists_the_measured_steps() {
        let path = measure_steps(&[vec![0.0, 1.0], vec![2.0, 3.0], vec![4.0, 5.0]], &[2, 0]);
        let t = session_plan_toml(&[0.5, 0.5], &path, 0.2);
        assert!(t.contains("seconds_per_pose = 1\n"), "{t}");
        assert!(t.contains("home_si = [0.500000000, 0.500000000]"), "{t}");
        let rows: Vec<&str> = t.lines().filter(|l| l.starts_with("  [")).collect();
        assert_eq!(rows, ["  [4.000000000, 5.000000000],", "  [0.000000000, 1.000000000],"]);
    }
}
