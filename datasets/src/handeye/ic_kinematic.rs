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
    Ok(MeasurementSet { source: path.display().to_string(), rows })
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

/// Writes [`ic_positioner_nominal`] as URDF to `out` (atomically, never onto `input`).
pub fn write_ic_positioner_urdf(out: &Path, input: &Path) -> Result<()> {
    super::poses::write_atomic(out, ic_positioner_urdf(input)?.as_bytes(), &[input])
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
    }
}
