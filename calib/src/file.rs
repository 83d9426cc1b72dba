//! The calibration file: what `ferrocal evaluate` (and a user's controller) needs to predict
//! measurements with a calibrated model. JSON, lengths in millimetres and angles in degrees at
//! the frames, SI in the model's parameter vector (named, so a reader never depends on order).

use std::path::Path;

use ferrocal_robot::{Kinematics, Parameterized, RobotModel};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::effects::EffectSpec;
use crate::error::{CalibError, Result};
use crate::kinematic::correct::{Coverage, FramesSource, NominalFrames, Uncertainty};
use crate::kinematic::CalibratedModel;
use crate::measurement::PoseMeasurement;

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
    /// The device frame and tool in which the nominal model means a joint command, fitted once
    /// over the calibration's poses ([`NominalFrames`]): `ferrocal correct` reads a program's
    /// commands through them, the same for every program.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nominal_frames: Option<NominalFramesJson>,
    /// The joint ranges and the box of positions the calibration's poses covered.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coverage: Option<Coverage>,
    /// The covariance of the calibrated parameters and the scatter the model leaves
    /// unexplained: what a corrected command's landing uncertainty comes from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<Uncertainty>,
}

/// [`NominalFrames`] in the file's units.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NominalFramesJson {
    /// `T_device_base` of the nominal model.
    pub device_frame: FrameJson,
    /// `T_flange_target` of the nominal model.
    pub tool: FrameJson,
    /// Poses the frames were fitted over.
    pub n_poses: usize,
    /// RMS distance between the nominal and the calibrated model over those poses, mm.
    pub rms_mm: f64,
}

/// An effect and its identified parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EffectValues {
    /// The effect.
    pub spec: EffectSpec,
    /// Its parameter values (SI), in the order of [`EffectSpec::parameters`].
    pub values: Vec<f64>,
}

/// The largest change of a joint's geometry a calibration may make (rad): 20 degrees, ten times
/// what a misassembled or worn arm shows; a larger one is a wrong file (degrees in a radian field,
/// a value edited by hand), not a calibration.
pub const MAX_JOINT_CHANGE_RAD: f64 = 0.35;

/// The largest change of a joint's geometry a calibration may make (m): 0.25 m.
pub const MAX_JOINT_CHANGE_M: f64 = 0.25;

/// Refuses a calibration whose joint parameters (`joint<i>.*`, `mimic<k>.*`, not the base or
/// tool placement) or joint offsets change the nominal model by more than
/// [`MAX_JOINT_CHANGE_RAD`] / [`MAX_JOINT_CHANGE_M`], naming the parameter and the likely cause.
fn check_physical(
    info: &[ferrocal_robot::ParamInfo],
    values: &[f64],
    offsets: &[f64],
    kinds: &[ferrocal_robot::JointKind],
) -> Result<()> {
    // The value `v` of a parameter whose nominal value is `nominal`, read in the other unit: the
    // whole value (a twist of 90 for pi/2), or the change from the nominal value.
    let hint = |v: f64, nominal: f64, unit: ferrocal_robot::Unit| -> String {
        let (scale, limit, name, symbol) = match unit {
            ferrocal_robot::Unit::Radian => (1f64.to_radians(), MAX_JOINT_CHANGE_RAD, "degrees", "rad"),
            ferrocal_robot::Unit::Metre => (1e-3, MAX_JOINT_CHANGE_M, "millimetres", "m"),
            _ => return String::new(),
        };
        let change = [v * scale - nominal, (v - nominal) * scale].into_iter().find(|c| c.abs() <= limit);
        change.map_or(String::new(), |c| {
            format!(" (read as {name} it would change it by {c:.4} {symbol}: was it written in {name}?)")
        })
    };
    // 6 decimals for a plausible number, an exponent for 1e308.
    let show = |v: f64| if v.abs() < 1e6 { format!("{v:.6}") } else { format!("{v:.3e}") };
    for (p, v) in info.iter().zip(values) {
        if !(p.name.starts_with("joint") || p.name.starts_with("mimic")) {
            continue;
        }
        let change = v - p.value;
        let limit = match p.unit {
            ferrocal_robot::Unit::Radian => MAX_JOINT_CHANGE_RAD,
            ferrocal_robot::Unit::Metre => MAX_JOINT_CHANGE_M,
            _ => continue,
        };
        if change.abs() > limit {
            return Err(CalibError::Data(format!(
                "parameter '{}' = {} {} changes the nominal model ({} {}) by {} {}, beyond the {limit} a calibration can make{}: the file is not a calibration of this robot",
                p.name,
                show(*v),
                p.unit.symbol(),
                show(p.value),
                p.unit.symbol(),
                show(change),
                p.unit.symbol(),
                hint(*v, p.value, p.unit)
            )));
        }
    }
    for (k, (o, kind)) in offsets.iter().zip(kinds).enumerate() {
        let (limit, unit) = match kind {
            ferrocal_robot::JointKind::Revolute => (MAX_JOINT_CHANGE_RAD, ferrocal_robot::Unit::Radian),
            ferrocal_robot::JointKind::Prismatic => (MAX_JOINT_CHANGE_M, ferrocal_robot::Unit::Metre),
        };
        if o.abs() > limit {
            return Err(CalibError::Data(format!(
                "joint offset {} is {} {}, beyond the {limit} a calibration can make{}: the file is not a calibration of this robot",
                k + 1,
                show(*o),
                unit.symbol(),
                hint(*o, 0.0, unit)
            )));
        }
    }
    Ok(())
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
            nominal_frames: None,
            coverage: None,
            uncertainty: None,
        }
    }

    /// The file of a calibration delivered from `rows` (the poses it was fitted on): with the
    /// nominal frames fitted over them, the region they cover and the parameters' uncertainty.
    pub fn delivered(
        robot_spec: &str,
        cm: &CalibratedModel,
        rows: &[&PoseMeasurement],
        uncertainty: Option<Uncertainty>,
    ) -> Result<Self> {
        let mut f = Self::new(robot_spec, cm);
        let frames = NominalFrames::fit(cm, rows)?;
        f.nominal_frames = Some(NominalFramesJson {
            device_frame: FrameJson::from_isometry(&frames.device_frame),
            tool: FrameJson::from_isometry(&frames.tool),
            n_poses: frames.n_poses,
            rms_mm: frames.rms_mm,
        });
        f.coverage = Coverage::of_rows(rows);
        f.uncertainty = uncertainty;
        Ok(f)
    }

    /// The nominal frames a program's commands are read through: the file's, or, for a file
    /// without them, fitted over a fixed sample of the joint space ([`NominalFrames::over_joint_space`]).
    pub fn nominal_frames(&self, cm: &CalibratedModel) -> Result<NominalFrames> {
        match &self.nominal_frames {
            Some(n) => Ok(NominalFrames {
                device_frame: n.device_frame.to_isometry(),
                tool: n.tool.to_isometry(),
                n_poses: n.n_poses,
                rms_mm: n.rms_mm,
                source: FramesSource::CalibrationPoses,
            }),
            None => NominalFrames::over_joint_space(cm),
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
        let mut given = vec![0usize; info.len()];
        for nv in &self.parameters {
            let Some(i) = info.iter().position(|p| p.name == nv.name) else {
                return Err(CalibError::Data(format!(
                    "the calibration names parameter '{}', which the model '{}' does not have: was it made for another model?",
                    nv.name,
                    model.name()
                )));
            };
            if !nv.value.is_finite() {
                return Err(CalibError::Data(format!("parameter '{}' is not a finite number", nv.name)));
            }
            given[i] += 1;
            values[i] = nv.value;
        }
        // Every parameter exactly once: a missing one would silently take its nominal value, a
        // repeated one would leave the reader to guess which value was meant.
        let repeated: Vec<&str> =
            info.iter().zip(&given).filter(|(_, n)| **n > 1).map(|(p, _)| p.name.as_str()).collect();
        if !repeated.is_empty() {
            return Err(CalibError::Data(format!(
                "the calibration gives parameter(s) {} more than once",
                name_list(&repeated)
            )));
        }
        let missing: Vec<&str> =
            info.iter().zip(&given).filter(|(_, n)| **n == 0).map(|(p, _)| p.name.as_str()).collect();
        if !missing.is_empty() {
            return Err(CalibError::Data(format!(
                "the calibration lacks {} of the {} parameters of model '{}' ({}); a calibration file lists every parameter: was it cut or edited?",
                missing.len(),
                info.len(),
                model.name(),
                name_list(&missing)
            )));
        }
        if let Some((k, _)) = self.joint_offsets.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(CalibError::Data(format!("joint offset {} is not a finite number", k + 1)));
        }
        check_physical(&info, &values, &self.joint_offsets, &model.joint_kinds())?;
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

    /// Checks that the file was made for the robot model `spec` (as given to `--robot`) loaded
    /// as `model`: the same spec, the same file, or a spec that loads a model of the same name
    /// and parameters. A calibration of another robot with the same parameter names (a UR5's
    /// applied to a UR10) would otherwise be used without a word.
    pub fn check_robot(&self, spec: &str, model: &RobotModel) -> Result<()> {
        if self.robot == spec {
            return Ok(());
        }
        let (a, b) = (Path::new(&self.robot), Path::new(spec));
        if let (Ok(x), Ok(y)) = (a.canonicalize(), b.canonicalize()) {
            if x == y {
                return Ok(());
            }
        }
        let mismatch = |why: String| {
            CalibError::Data(format!(
                "the calibration was made for robot '{}', not '{spec}' ({why}); pass --robot {}",
                self.robot, self.robot
            ))
        };
        match RobotModel::load(&self.robot) {
            Ok(m) if m.name() == model.name() && m.parameters().len() == model.parameters().len() => Ok(()),
            Ok(m) => Err(mismatch(format!("model '{}' against '{}'", m.name(), model.name()))),
            // A file given relative to another folder: the same file name is taken as the same
            // model.
            Err(_) if a.file_name().is_some() && a.file_name() == b.file_name() => Ok(()),
            Err(e) => Err(mismatch(format!("'{}' cannot be loaded here: {e}", self.robot))),
        }
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

/// Up to eight names, quoted, then a count of the rest.
fn name_list(names: &[&str]) -> String {
    let mut s = names.iter().take(8).map(|n| format!("'{n}'")).collect::<Vec<_>>().join(", ");
    if names.len() > 8 {
        s.push_str(&format!(" and {} more", names.len() - 8));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_calibration_beyond_what_a_calibration_can_change_is_refused_with_the_likely_unit() {
        let ur5 = RobotModel::load("ur5").unwrap();
        let file = CalibrationFile::new("ur5", &CalibratedModel::nominal(ur5.clone()));
        let rad =
            file.parameters.iter().position(|p| p.name.starts_with("joint2") && p.name.ends_with("_rad")).unwrap();
        let m = file.parameters.iter().position(|p| p.name.starts_with("joint3") && p.name.ends_with("_m")).unwrap();
        // A change of 5 degrees written as 5 in a radian field.
        let mut deg = file.clone();
        deg.parameters[rad].value += 5.0;
        let e = deg.apply(&ur5).unwrap_err().to_string();
        assert!(e.contains(&file.parameters[rad].name) && e.contains("written in degrees"), "{e}");
        // 1e308 rad.
        let mut huge = file.clone();
        huge.parameters[rad].value = 1e308;
        let e = huge.apply(&ur5).unwrap_err().to_string();
        assert!(e.contains("not a calibration of this robot") && !e.contains("degrees"), "{e}");
        // 40 mm written as 40 in a metre field.
        let mut mm = file.clone();
        mm.parameters[m].value += 40.0;
        assert!(mm.apply(&ur5).unwrap_err().to_string().contains("written in millimetres"));
        // A joint offset of 90 (degrees) in radians.
        let mut off = file.clone();
        off.joint_offsets[1] = 90.0;
        let e = off.apply(&ur5).unwrap_err().to_string();
        assert!(e.contains("joint offset 2") && !e.contains("written in degrees"), "{e}");
        // Changes a calibration makes pass: 10 mrad and 5 mm.
        let mut fine = file.clone();
        fine.parameters[rad].value += 0.01;
        fine.parameters[m].value += 0.005;
        fine.joint_offsets[0] = 0.02;
        assert!(fine.apply(&ur5).is_ok());
    }

    #[test]
    fn calibration_file_missing_repeated_or_for_another_robot_is_refused() {
        let ur5 = RobotModel::load("ur5").unwrap();
        let ur10 = RobotModel::load("ur10").unwrap();
        let file = CalibrationFile::new("ur5", &CalibratedModel::nominal(ur5.clone()));
        assert!(file.apply(&ur5).is_ok());
        file.check_robot("ur5", &ur5).unwrap();
        // Another robot with the same parameter names.
        let e = file.check_robot("ur10", &ur10).unwrap_err().to_string();
        assert!(e.contains("made for robot 'ur5', not 'ur10'"), "{e}");
        // Most parameters missing.
        let mut cut = file.clone();
        cut.parameters.truncate(10);
        let e = cut.apply(&ur5).unwrap_err().to_string();
        assert!(e.contains(&format!("lacks {} of the {}", file.parameters.len() - 10, file.parameters.len())), "{e}");
        assert!(e.contains(&format!("'{}'", file.parameters[10].name)), "{e}");
        // A parameter given twice.
        let mut twice = file.clone();
        twice.parameters.push(twice.parameters[3].clone());
        let e = twice.apply(&ur5).unwrap_err().to_string();
        assert!(e.contains(&format!("'{}' more than once", file.parameters[3].name)), "{e}");
    }
}
