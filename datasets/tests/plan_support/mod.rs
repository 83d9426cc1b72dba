//! Shared glue of the planning tests: the example plan file read by the library's plan-file
//! reader, the camera rig built from its `[[camera]]` and `[target]` sections, and the datasets
//! simulator behind the Monte Carlo check (`ferrocal_datasets::sim::DatasetsSimulator`, the one
//! `ferrocal plan` uses).

#![allow(dead_code)]

use std::path::{Path, PathBuf};

use ferrocal_calib::design::flow::DesignSettings;
use ferrocal_calib::design::kinematic::IdentifySettings;
pub use ferrocal_datasets::formats::plan_file::camera_view;
use ferrocal_datasets::formats::plan_file::PlanFile;
pub use ferrocal_datasets::sim::DatasetsSimulator;
use ferrocal_datasets::sim::{CameraSection, GeometricErrors, TargetSection};
use ferrocal_robot::program::{PathSettings, ProgramSettings};
use ferrocal_robot::safety::SafetyConfig;
use ferrocal_robot::workspace::{CameraVisibility, TargetShape, VisibilitySettings, WorkspaceSettings};
use ferrocal_robot::RobotModel;
use nalgebra::Point3;

/// The example plan of the L1 with one camera.
pub fn l1_plan_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("cells/plan_gantry_tau_l1.toml")
}

/// The sections of a plan file the tests use.
pub struct PlanParts {
    pub model: RobotModel,
    pub safety: SafetyConfig,
    pub workspace: WorkspaceSettings,
    pub cameras: Vec<CameraSection>,
    pub target: TargetSection,
    pub measure: VisibilitySettings,
    pub identify: IdentifySettings,
    pub design: DesignSettings,
    pub errors: GeometricErrors,
    pub path: PathSettings,
    pub program: ProgramSettings,
}

/// Reads the plan file's sections (a camera plan).
pub fn load_plan(path: &Path) -> PlanParts {
    let plan = PlanFile::from_file(path).unwrap();
    let model = RobotModel::load(&plan.robot.model).unwrap();
    PlanParts {
        model,
        safety: plan.safety,
        workspace: plan.workspace,
        cameras: plan.cameras,
        target: plan.target.expect("a camera plan has a [target]"),
        measure: plan.measure,
        identify: plan.identify,
        design: plan.design,
        errors: plan.simulation.errors,
        path: plan.path,
        program: plan.program,
    }
}

/// The camera rig of a plan (obstacles block the line of sight).
pub fn camera_rig(parts: &PlanParts) -> CameraVisibility {
    let geo = parts.target.pattern.build().unwrap();
    let corners: Vec<Point3<f64>> = geo.corners.iter().map(|c| c.p_target_m).collect();
    let shape = TargetShape::new(&geo.outline_m, &geo.dark_m, &corners);
    CameraVisibility::new(
        parts.cameras.iter().map(|c| camera_view(c).unwrap()).collect(),
        shape,
        parts.target.t_tool_target.isometry(),
        parts.measure.clone(),
        parts.safety.obstacles.clone(),
    )
    .unwrap()
}
