//! Shared glue of the planning tests: the example plan file read section by section, the camera
//! rig built from the cell format's `[[camera]]` and `[target]` sections, and the datasets
//! simulator behind the Monte Carlo check.

#![allow(dead_code)]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use ferrocal_calib::design::flow::DesignSettings;
use ferrocal_calib::design::kinematic::{row_sigma_m, CalibrationSimulator, IdentifySettings, SimulatedCell};
use ferrocal_calib::PoseMeasurement;
use ferrocal_datasets::sim::{CameraSection, Conditions, GeometricErrors, TargetSection, TrueRobot};
use ferrocal_robot::program::{PathSettings, ProgramSettings};
use ferrocal_robot::safety::SafetyConfig;
use ferrocal_robot::workspace::{CameraRig, CameraView, TargetShape, VisibilitySettings, WorkspaceSettings};
use ferrocal_robot::{Kinematics, Parameterized, RobotModel};
use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

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

fn section<T: serde::de::DeserializeOwned + Default>(v: &toml::Value, key: &str) -> T {
    match v.get(key) {
        Some(s) => s.clone().try_into().unwrap_or_else(|e| panic!("[{key}]: {e}")),
        None => T::default(),
    }
}

/// Reads the plan file's sections.
pub fn load_plan(path: &Path) -> PlanParts {
    let text = std::fs::read_to_string(path).unwrap();
    let v: toml::Value = toml::from_str(&text).unwrap();
    let model = RobotModel::load(v["robot"]["model"].as_str().unwrap()).unwrap();
    let sim = v.get("simulation").cloned().unwrap_or(toml::Value::Table(Default::default()));
    let errors: GeometricErrors = sim.get("errors").map(|e| e.clone().try_into().unwrap()).unwrap_or_default();
    PlanParts {
        model,
        safety: v["safety"].clone().try_into().unwrap(),
        workspace: section(&v, "workspace"),
        cameras: v["camera"].clone().try_into().unwrap(),
        target: v["target"].clone().try_into().unwrap(),
        measure: section(&v, "measure"),
        identify: section(&v, "identify"),
        design: section(&v, "design"),
        errors,
        path: section(&v, "path"),
        program: section(&v, "program"),
    }
}

/// A camera view from the cell format's camera section (lens model from the vision crate).
pub fn camera_view(c: &CameraSection) -> CameraView {
    let model = c.model;
    let max_angle = model.max_field_angle_rad();
    let t = c.t_world_cam().unwrap();
    CameraView::new(c.name.clone(), t, model.image_size.width_px, model.image_size.height_px, move |p: &Point3<f64>| {
        if p.x.hypot(p.y).atan2(p.z) >= max_angle {
            return None;
        }
        model.project(p).ok()
    })
}

/// The camera rig of a plan (obstacles block the line of sight).
pub fn camera_rig(parts: &PlanParts) -> CameraRig {
    let geo = parts.target.pattern.build().unwrap();
    let corners: Vec<Point3<f64>> = geo.corners.iter().map(|c| c.p_target_m).collect();
    let shape = TargetShape::new(&geo.outline_m, &geo.dark_m, &corners);
    CameraRig::new(
        parts.cameras.iter().map(camera_view).collect(),
        shape,
        parts.target.t_tool_target.isometry(),
        parts.measure.clone(),
        parts.safety.obstacles.clone(),
    )
    .unwrap()
}

/// Simulated campaigns with the datasets crate's true robot: geometric errors drawn per run,
/// the measured point in the device frame with Gaussian noise of the device's covariance.
pub struct DatasetsSimulator {
    pub nominal: RobotModel,
    pub errors: GeometricErrors,
    pub t_device_base: Isometry3<f64>,
    pub point_in_tool_m: Vector3<f64>,
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
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed.wrapping_mul(1_000_003).wrapping_add(run as u64));
        let truth = TrueRobot::new(self.nominal.clone(), &self.errors, vec![], 0.0, &mut rng)
            .map_err(|e| ferrocal_calib::CalibError::Data(e.to_string()))?;
        let cond = Conditions { temp_c: 20.0, dir: vec![0; self.nominal.dof()], ..Default::default() };
        let position = |q: &[f64]| -> ferrocal_calib::Result<Vector3<f64>> {
            let t = truth.tool_pose(q, &cond).map_err(|e| ferrocal_calib::CalibError::Data(e.to_string()))?;
            Ok((self.t_device_base * t * Point3::from(self.point_in_tool_m)).coords)
        };
        let mut rows = Vec::with_capacity(train.len());
        for (k, (q, c)) in train.iter().zip(covariances).enumerate() {
            let l = c.cholesky().ok_or_else(|| ferrocal_calib::CalibError::Data("covariance".into()))?.l();
            let z = Vector3::from_fn(|_, _| StandardNormal.sample(&mut rng));
            let mut row = PoseMeasurement::new(format!("{}", k + 1), q.clone(), position(q)? + l * z);
            row.sigma_m = Some(row_sigma_m(c));
            rows.push(row);
        }
        let mut truth_map = BTreeMap::new();
        for p in truth.truth.parameters() {
            truth_map.insert(p.name, p.value);
        }
        let validation_true_m = validation.iter().map(|q| position(q)).collect::<ferrocal_calib::Result<_>>()?;
        Ok(SimulatedCell { rows, truth: truth_map, validation_true_m })
    }
}
