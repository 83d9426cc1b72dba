//! The one measurement type of robot calibration: a measured pose row.
//!
//! A row holds what the robot was told (actuator readings) and what an external device saw (a
//! laser tracker, a camera system, a CMM), plus the conditions of the measurement. Values are SI
//! (metres, radians); the CSV format of `../shared/spec/measurements.md` is read and written by
//! `ferrocal-datasets`.

use std::collections::BTreeMap;

use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// Whether a row is for fitting or for validation, when the recording fixes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Split {
    /// Used to fit parameters.
    Train,
    /// Held out for validation.
    Test,
}

/// One measured robot pose.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseMeasurement {
    /// Unique id of the row.
    pub pose_id: String,
    /// Actuator readings in model order (rad for revolute joints, m for prismatic ones).
    pub q: Vec<f64>,
    /// Measured target position in the device frame.
    pub position_m: Vector3<f64>,
    /// Measured target orientation in the device frame, when measured.
    pub orientation: Option<UnitQuaternion<f64>>,
    /// Standard deviation of the position measurement (per axis), when known.
    pub sigma_m: Option<f64>,
    /// Standard deviation of the orientation measurement (per axis), when known.
    pub sigma_rad: Option<f64>,
    /// Time since the start of the session.
    pub t_s: Option<f64>,
    /// Temperature, degrees Celsius.
    pub temp_c: Option<f64>,
    /// Payload mass at the tool.
    pub payload_kg: Option<f64>,
    /// Sign of the last motion of each joint into this pose (`1`, `-1`, `0` unknown).
    pub dir: Option<Vec<i8>>,
    /// Train/test assignment fixed by the recording.
    pub split: Option<Split>,
    /// Where the row came from (file line), for messages.
    pub source_line: Option<u64>,
    /// Extra per-row metadata that the measurement table has no column for (column name ->
    /// value as text), e.g. a recording's own timestamp or per-axis standard deviations.
    /// Empty for most sources.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub meta: BTreeMap<String, String>,
}

impl PoseMeasurement {
    /// A row with only the required fields.
    pub fn new(pose_id: impl Into<String>, q: Vec<f64>, position_m: Vector3<f64>) -> Self {
        Self {
            pose_id: pose_id.into(),
            q,
            position_m,
            orientation: None,
            sigma_m: None,
            sigma_rad: None,
            t_s: None,
            temp_c: None,
            payload_kg: None,
            dir: None,
            split: None,
            source_line: None,
            meta: BTreeMap::new(),
        }
    }
}

/// A set of measured poses from one recording.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MeasurementSet {
    /// Where the rows were read from (a path, or a description).
    pub source: String,
    /// The rows in recording order.
    pub rows: Vec<PoseMeasurement>,
}

impl MeasurementSet {
    /// Number of joints of the rows (0 for an empty set).
    pub fn n_joints(&self) -> usize {
        self.rows.first().map_or(0, |r| r.q.len())
    }

    /// Whether every row has an orientation.
    pub fn has_orientation(&self) -> bool {
        !self.rows.is_empty() && self.rows.iter().all(|r| r.orientation.is_some())
    }

    /// Rows with the given split (rows without a split count as `Train`).
    pub fn split(&self, which: Split) -> Vec<&PoseMeasurement> {
        self.rows.iter().filter(|r| r.split.unwrap_or(Split::Train) == which).collect()
    }
}
