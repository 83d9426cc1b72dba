//! The calibration file: what `ferrocal evaluate` (and a user's controller) needs to predict
//! measurements with a calibrated model. JSON, lengths in millimetres and angles in degrees at
//! the frames, SI in the model's parameter vector (named, so a reader never depends on order).

use std::path::Path;

use ferrocal_robot::{Kinematics, Parameterized, RobotModel};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::effects::EffectSpec;
use crate::error::{CalibError, Result};
use crate::kinematic::CalibratedModel;

/// A frame in the file: translation (mm) and rotation vector (deg), plus the quaternion for
/// other tools (Hamilton, `w x y z`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameJson {
    /// Translation, millimetres.
    pub translation_mm: [f64; 3],
    /// Rotation vector, degrees.
    pub rotation_deg: [f64; 3],
    /// The same rotation as a unit quaternion `w, x, y, z`.
    pub quaternion_wxyz: [f64; 4],
}

impl FrameJson {
    /// From a transform.
    pub fn from_isometry(t: &Isometry3<f64>) -> Self {
        let p = t.translation.vector * 1e3;
        let r = t.rotation.scaled_axis().map(f64::to_degrees);
        let q = t.rotation.quaternion();
        Self { translation_mm: [p.x, p.y, p.z], rotation_deg: [r.x, r.y, r.z], quaternion_wxyz: [q.w, q.i, q.j, q.k] }
    }

    /// To a transform (the rotation vector is authoritative).
    pub fn to_isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(
                self.translation_mm[0] * 1e-3,
                self.translation_mm[1] * 1e-3,
                self.translation_mm[2] * 1e-3,
            ),
            UnitQuaternion::from_scaled_axis(Vector3::from(self.rotation_deg.map(f64::to_radians))),
        )
    }
}

/// One named model parameter.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NamedValue {
    /// Name in the model's parameter vector.
    pub name: String,
    /// Value (SI).
    pub value: f64,
}

/// The calibration file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CalibrationFile {
    /// Format identifier, `ferrocal-calibration/1`.
    pub format: String,
    /// The robot model the calibration applies to (preset name or file path as given).
    pub robot: String,
    /// Number of joints (checked on load).
    pub n_joints: usize,
    /// Every parameter of the model with its calibrated value.
    pub parameters: Vec<NamedValue>,
    /// Joint offsets added to the readings (rad or m per joint).
    pub joint_offsets: Vec<f64>,
    /// `T_device_base`.
    pub device_frame: FrameJson,
    /// `T_flange_target` (after the model's own tool frame).
    pub tool: FrameJson,
    /// Whether the target's orientation was calibrated (else only positions are predicted).
    #[serde(default)]
    pub orientation_calibrated: bool,
    /// Physical effects modelled beyond the geometry, with their parameter values.
    #[serde(default)]
    pub effects: Vec<EffectValues>,
    /// The robot model (preset name or file) whose nominal geometry places the masses for the
    /// effects' loads, when it is not the model the file is applied to (a calibration exported
    /// with its URDF: the URDF holds the calibrated geometry, the loads come from the nominal
    /// one, as in the calibration that identified the effects).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub load_model: Option<String>,
}

/// An effect and its identified parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EffectValues {
    /// The effect.
    pub spec: EffectSpec,
    /// Its parameter values (SI), in the order of [`EffectSpec::parameters`].
    pub values: Vec<f64>,
}

impl CalibrationFile {
    /// From a calibrated model.
    pub fn new(robot_spec: &str, cm: &CalibratedModel) -> Self {
        Self {
            format: "ferrocal-calibration/1".into(),
            robot: robot_spec.to_string(),
            n_joints: cm.model.dof(),
            parameters: cm
                .model
                .parameters()
                .into_iter()
                .map(|p| NamedValue { name: p.name, value: p.value })
                .collect(),
            joint_offsets: cm.joint_offsets.clone(),
            device_frame: FrameJson::from_isometry(&cm.device_frame),
            tool: FrameJson::from_isometry(&cm.tool),
            orientation_calibrated: cm.orientation_calibrated,
            effects: cm
                .effects
                .iter()
                .map(|(spec, values)| EffectValues { spec: spec.clone(), values: values.clone() })
                .collect(),
            load_model: None,
        }
    }

    /// Applies the file to `model` (which must be the model it was made for).
    pub fn apply(&self, model: &RobotModel) -> Result<CalibratedModel> {
        if model.dof() != self.n_joints || self.joint_offsets.len() != self.n_joints {
            return Err(CalibError::Data(format!(
                "the calibration is for a robot with {} joints, the model '{}' has {}",
                self.n_joints,
                model.name(),
                model.dof()
            )));
        }
        let mut m = model.clone();
        let info = m.parameters();
        let mut values = m.parameter_values();
        for nv in &self.parameters {
            let Some(i) = info.iter().position(|p| p.name == nv.name) else {
                return Err(CalibError::Data(format!(
                    "the calibration names parameter '{}', which the model '{}' does not have: was it made for another model?",
                    nv.name,
                    model.name()
                )));
            };
            values[i] = nv.value;
        }
        m.set_parameter_values(&values)?;
        let load_model = match &self.load_model {
            None => model.clone(),
            Some(spec) => {
                let l = RobotModel::load(spec).map_err(|e| {
                    CalibError::Data(format!("the load model '{spec}' the calibration names cannot be loaded: {e}"))
                })?;
                if l.dof() != model.dof() {
                    return Err(CalibError::Data(format!(
                        "the load model '{spec}' has {} joints, the robot {}",
                        l.dof(),
                        model.dof()
                    )));
                }
                l
            }
        };
        Ok(CalibratedModel {
            model: m,
            device_frame: self.device_frame.to_isometry(),
            tool: self.tool.to_isometry(),
            joint_offsets: self.joint_offsets.clone(),
            orientation_calibrated: self.orientation_calibrated,
            effects: self.effects.iter().map(|e| (e.spec.clone(), e.values.clone())).collect(),
            load_model,
        })
    }

    /// Reads a file.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| CalibError::File { path: path.to_path_buf(), message: e.to_string() })?;
        let f: Self = serde_json::from_str(&text).map_err(|e| CalibError::File {
            path: path.to_path_buf(),
            message: format!("line {}, column {}: {e}", e.line(), e.column()),
        })?;
        if f.format != "ferrocal-calibration/1" {
            return Err(CalibError::File {
                path: path.to_path_buf(),
                message: format!("unknown format '{}' (expected ferrocal-calibration/1)", f.format),
            });
        }
        Ok(f)
    }
}
