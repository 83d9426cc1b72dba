//! The importer of ROS-Industrial industrial_calibration kinematic-calibration sets
//! (`measurements.yaml`, as in `shared/data/industrial_calibration/kinematic_calibration`) into
//! the measurement table of `shared/spec/measurements.md`.
//!
//! `measurements.yaml` maps an observation key (a timestamp) to `pose` (`x y z` metres, `qx qy qz
//! qw`: the target in the camera frame, `T_camera_target`, measured by the camera), the target
//! chain's joint readings `target_joints` (radians) and `camera_joints` (the camera chain's; the
//! importer takes sets where the camera is fixed and says so when it is not). The camera is the
//! measuring device: the table's positions and orientations are the target's in the camera frame.
//! Rows follow the keys' natural order (time order for timestamps); with `test_every = K`, every
//! K-th row is marked `test`.

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use serde::Deserialize;

use ferrocal_calib::{MeasurementSet, PoseMeasurement, Split};
use ferrocal_robot::serial::SerialChain;

use super::ic::{yaml_error, IcPose};
use super::poses::QUATERNION_NORM_TOLERANCE;
use crate::error::{DatasetError, Location, Result};
use crate::import::natural_cmp;

#[derive(Deserialize)]
struct Observation {
    #[serde(default)]
    camera_joints: Vec<f64>,
    pose: IcPose,
    target_joints: Vec<f64>,
}

/// Reads `measurements.yaml` (the file, or the folder that holds it).
pub fn read_ic_kinematic(input: &Path, test_every: Option<usize>) -> Result<MeasurementSet> {
    if test_every == Some(0) {
        return Err(DatasetError::Input("test_every must be at least 1".into()));
    }
    let path = if input.is_dir() { input.join("measurements.yaml") } else { input.to_path_buf() };
    let text = crate::import::table::read_text(&path)?;
    let map: BTreeMap<String, Observation> = serde_norway::from_str(&text).map_err(|e| yaml_error(&path, &e))?;
    let located = |key: &str, message: String| {
        let line = text.lines().position(|l| l.trim_start_matches('\'').starts_with(key)).map_or(1, |k| k as u64 + 1);
        DatasetError::Invalid { location: Location::line(&path, line), message }
    };
    let mut keys: Vec<&String> = map.keys().collect();
    keys.sort_by(|a, b| natural_cmp(a, b));
    let n_joints = map.values().next().map_or(0, |o| o.target_joints.len());
    let mut rows = Vec::with_capacity(keys.len());
    for (k, key) in keys.iter().enumerate() {
        let o = &map[*key];
        if !o.camera_joints.is_empty() {
            return Err(located(
                key,
                format!(
                    "observation '{key}': the camera moves (camera_joints given); only a fixed camera is supported"
                ),
            ));
        }
        if o.target_joints.is_empty() || o.target_joints.len() != n_joints {
            return Err(located(
                key,
                format!("observation '{key}': {} target joint(s), expected {n_joints}", o.target_joints.len()),
            ));
        }
        let p = &o.pose;
        let values = [p.x, p.y, p.z, p.qx, p.qy, p.qz, p.qw];
        if !values.iter().chain(&o.target_joints).all(|v| v.is_finite()) {
            return Err(located(key, format!("observation '{key}': a value is not finite")));
        }
        let q = Quaternion::new(p.qw, p.qx, p.qy, p.qz);
        if (q.norm() - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
            return Err(located(key, format!("observation '{key}': the quaternion has norm {:.6}, not 1", q.norm())));
        }
        let split = match test_every {
            Some(n) if k % n == n - 1 => Split::Test,
            _ => Split::Train,
        };
        rows.push(PoseMeasurement {
            pose_id: key.to_string(),
            q: o.target_joints.clone(),
            position_m: Vector3::new(p.x, p.y, p.z),
            orientation: Some(UnitQuaternion::from_quaternion(q)),
            split: Some(split),
            ..PoseMeasurement::default()
        });
    }
    if rows.is_empty() {
        return Err(DatasetError::Invalid { location: Location::line(&path, 1), message: "no observations".into() });
    }
    check_units(&rows, &text, &path)?;
    Ok(MeasurementSet { source: path.display().to_string(), rows })
}

/// A target farther than this from the camera (metres) is not one the camera measured: the
/// positions are in millimetres.
pub const MAX_TARGET_DISTANCE_M: f64 = 50.0;

/// A joint reading beyond this (radians, two turns) is not in radians.
pub const MAX_JOINT_RAD: f64 = 2.0 * std::f64::consts::TAU;

/// The 1-based line of `field` (`x`, ..., or the `index`-th item of `target_joints`) in the
/// observation `key` of `text` (the key's own line when not found).
fn value_line(text: &str, key: &str, field: &str, index: Option<usize>) -> u64 {
    let lines: Vec<&str> = text.lines().collect();
    let is_key = |l: &&str| !l.starts_with(' ') && l.trim_end().trim_end_matches(':').trim_matches(['\'', '"']) == key;
    let Some(start) = lines.iter().position(is_key) else { return 1 };
    let block = lines[start + 1..].iter().take_while(|l| l.starts_with(' ') || l.starts_with('-') || l.is_empty());
    let mut in_list = false;
    let mut item = 0;
    for (k, l) in block.enumerate() {
        let t = l.trim();
        if t.starts_with(&format!("{field}:")) && index.is_none() {
            return (start + k + 2) as u64;
        }
        if index.is_some() {
            if t.starts_with("target_joints:") {
                in_list = true;
            } else if in_list && t.starts_with('-') {
                if Some(item) == index {
                    return (start + k + 2) as u64;
                }
                item += 1;
            } else if in_list {
                in_list = false;
            }
        }
    }
    start as u64 + 1
}

/// Refuses positions or joint readings that cannot be in the units the format names (metres,
/// radians): a target more than [`MAX_TARGET_DISTANCE_M`] from the camera (millimetres), a joint
/// beyond [`MAX_JOINT_RAD`] (degrees). The error names the file, the line, the field and the
/// observation, how many observations are affected and the likely unit.
fn check_units(rows: &[PoseMeasurement], text: &str, path: &Path) -> Result<()> {
    for (c, axis) in ["x", "y", "z"].iter().enumerate() {
        let bad: Vec<&PoseMeasurement> =
            rows.iter().filter(|r| r.position_m[c].abs() > MAX_TARGET_DISTANCE_M).collect();
        if let Some(r) = bad.first() {
            return Err(DatasetError::Invalid {
                location: Location::new(path, value_line(text, &r.pose_id, axis, None), format!("pose.{axis}")),
                message: format!(
                    "observation '{}': {axis} = {} m, more than {MAX_TARGET_DISTANCE_M} m from the camera ({} of {} observations): the positions look like millimetres; the format takes metres",
                    r.pose_id,
                    r.position_m[c],
                    bad.len(),
                    rows.len()
                ),
            });
        }
    }
    let n_joints = rows.first().map_or(0, |r| r.q.len());
    for j in 0..n_joints {
        let bad: Vec<&PoseMeasurement> = rows.iter().filter(|r| r.q[j].abs() > MAX_JOINT_RAD).collect();
        if let Some(r) = bad.first() {
            return Err(DatasetError::Invalid {
                location: Location::new(path, value_line(text, &r.pose_id, "", Some(j)), format!("target_joints[{j}]")),
                message: format!(
                    "observation '{}': joint {} reads {} rad, beyond two turns ({MAX_JOINT_RAD:.4} rad) ({} of {} observations): the readings look like degrees; the format takes radians",
                    r.pose_id,
                    j + 1,
                    r.q[j],
                    bad.len(),
                    rows.len()
                ),
            });
        }
    }
    Ok(())
}

/// The nominal two-axis positioner of the industrial_calibration kinematic example, as the
/// source builds it (standard DH, `Tz(d) Rz(theta + q) Tx(a) Rx(alpha)` per joint): joint 1
/// `(d, theta, a, alpha) = (0, 0, 0, -90 deg)`, joint 2 `(-0.475 m, -90 deg, 0, 0)`. Its base
/// frame is where joint 1's axis is z; the camera frame, the base and the target mount are left
/// to the calibration.
pub fn ic_positioner_nominal() -> SerialChain {
    SerialChain::from_dh(
        "ic_positioner",
        &[0.0, 0.0],
        &[-std::f64::consts::FRAC_PI_2, 0.0],
        &[0.0, -0.475],
        &[0.0, -std::f64::consts::FRAC_PI_2],
    )
}

/// [`ic_positioner_nominal`] as URDF text, its comment naming `input`.
pub fn ic_positioner_urdf(input: &Path) -> Result<String> {
    let chain = ic_positioner_nominal();
    let frames = ferrocal_robot::serial::UrdfFrames {
        root_link: "positioner_base".into(),
        tip_link: "target_mount".into(),
        ..Default::default()
    };
    let comment = format!(
        "the nominal two-axis positioner of the industrial_calibration kinematic example, written by ferrocal {} for {}",
        env!("CARGO_PKG_VERSION"),
        input.display()
    );
    ferrocal_robot::serial::to_urdf(&chain, &[0.0, 0.0], &frames, &comment)
        .map_err(|e| DatasetError::Input(format!("the positioner model: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn observations_are_read_in_key_order_with_located_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("measurements.yaml");
        let obs = |key: &str, q1: f64| {
            format!(
                "'{key}':\n  camera_joints: []\n  pose:\n    qw: 1.0\n    qx: 0.0\n    qy: 0.0\n    qz: 0.0\n    x: 0.5\n    y: -0.25\n    z: 1.0\n  target_joints:\n  - {q1}\n  - 0.5\n"
            )
        };
        std::fs::write(&p, format!("{}{}{}", obs("20", 0.2), obs("10", 0.1), obs("30", 0.3))).unwrap();
        let set = read_ic_kinematic(dir.path(), Some(2)).unwrap();
        let ids: Vec<&str> = set.rows.iter().map(|r| r.pose_id.as_str()).collect();
        assert_eq!(ids, ["10", "20", "30"]);
        assert_eq!(set.rows[0].q, vec![0.1, 0.5]);
        assert_eq!(set.rows[1].split, Some(Split::Test));
        assert_eq!(set.rows[2].position_m, Vector3::new(0.5, -0.25, 1.0));

        std::fs::write(&p, format!("{}{}", obs("10", 0.1), obs("20", 0.2).replace("qw: 1.0", "qw: 0.5"))).unwrap();
        let e = read_ic_kinematic(&p, None).unwrap_err().to_string();
        assert!(e.contains("measurements.yaml") && e.contains("'20'") && e.contains("norm"), "{e}");

        // Millimetres and degrees, named by line and field.
        std::fs::write(&p, format!("{}{}", obs("10", 0.1), obs("20", 0.2).replace("z: 1.0", "z: 1000.0"))).unwrap();
        let e = read_ic_kinematic(&p, None).unwrap_err().to_string();
        assert!(
            e.contains("line 23, column 'pose.z'") && e.contains("look like millimetres") && e.contains("1 of 2"),
            "{e}"
        );
        std::fs::write(&p, format!("{}{}", obs("10", 0.1), obs("20", 28.6))).unwrap();
        let e = read_ic_kinematic(&p, None).unwrap_err().to_string();
        assert!(e.contains("line 25, column 'target_joints[0]'") && e.contains("look like degrees"), "{e}");
    }
}
