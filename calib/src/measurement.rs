//! The one measurement type of robot calibration: a measured pose row.
//!
//! A row holds what the robot was told (actuator readings) and what an external device saw (a
//! laser tracker, a camera system, a CMM), plus the conditions of the measurement. Values are SI
//! (metres, radians); the CSV format of `../shared/spec/measurements.md` is read and written by
//! `ferrocal-datasets`.

use std::collections::BTreeMap;

use nalgebra::{Matrix3, Matrix6, UnitQuaternion, Vector3};
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

/// The full covariance of one measured pose, in SI units and in the device frame.
///
/// The pose error is the 6-vector `[dx_m, dy_m, dz_m, drx_rad, dry_rad, drz_rad]`: position first
/// (measured minus true, metres), then the orientation error as a rotation vector (radians)
/// applied on the left in the device frame, `R_measured = Exp(dr) R_true` (the chart of
/// `docs/conventions.md`, "Uncertainty"). Entries are m^2 (position block), m rad (cross terms)
/// and rad^2 (orientation block).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
#[allow(clippy::large_enum_variant)] // 72 vs 288 bytes, one per row: not worth a box
pub enum PoseCovariance {
    /// Position only (a tracker's reflector): 3 x 3, m^2.
    Position {
        /// Covariance of `[dx_m, dy_m, dz_m]`, m^2.
        m2: Matrix3<f64>,
    },
    /// Position and orientation (a camera system's target pose): 6 x 6 over
    /// `[dx_m, dy_m, dz_m, drx_rad, dry_rad, drz_rad]`, with the cross terms.
    Pose {
        /// Covariance, m^2 / m rad / rad^2 by block.
        si: Matrix6<f64>,
    },
}

impl PoseCovariance {
    /// The position block, m^2.
    pub fn position_m2(&self) -> Matrix3<f64> {
        match self {
            PoseCovariance::Position { m2 } => *m2,
            PoseCovariance::Pose { si } => si.fixed_view::<3, 3>(0, 0).into_owned(),
        }
    }

    /// The 6 x 6 covariance, when orientation is covered.
    pub fn pose(&self) -> Option<&Matrix6<f64>> {
        match self {
            PoseCovariance::Position { .. } => None,
            PoseCovariance::Pose { si } => Some(si),
        }
    }

    /// A 6 x 6 covariance from one with the position in millimetres (mm^2, mm rad, rad^2 by
    /// block), as [`ferrocal_vision::pose::PoseEstimate::covariance`] reports it.
    pub fn from_mm_rad(cov_mm_rad: &Matrix6<f64>) -> Self {
        let mut si = *cov_mm_rad;
        for i in 0..6 {
            for j in 0..6 {
                let scale = if i < 3 { 1e-3 } else { 1.0 } * if j < 3 { 1e-3 } else { 1.0 };
                si[(i, j)] *= scale;
            }
        }
        PoseCovariance::Pose { si }
    }

    /// Whether every entry is finite and the matrix symmetric positive definite (a Cholesky
    /// factor exists); the message says what is wrong.
    pub fn validate(&self) -> std::result::Result<(), String> {
        let check = |m: nalgebra::DMatrix<f64>| -> std::result::Result<(), String> {
            if !m.iter().all(|v| v.is_finite()) {
                return Err("the covariance has a non-finite entry".into());
            }
            let scale = m.diagonal().iter().fold(0.0f64, |a, v| a.max(v.abs()));
            if (&m - m.transpose()).amax() > 1e-9 * scale {
                return Err("the covariance is not symmetric".into());
            }
            if m.cholesky().is_none() {
                return Err("the covariance is not positive definite".into());
            }
            Ok(())
        };
        match self {
            PoseCovariance::Position { m2 } => check(nalgebra::DMatrix::from_column_slice(3, 3, m2.as_slice())),
            PoseCovariance::Pose { si } => check(nalgebra::DMatrix::from_column_slice(6, 6, si.as_slice())),
        }
    }
}

/// One measured robot pose.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
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
    /// The full covariance of the measurement, when known (SI units: see [`PoseCovariance`]).
    /// When present, the kinematic calibration whitens this row's residual with it (a Cholesky
    /// factor of the block it uses) instead of with `sigma_m` / `sigma_rad`; `sigma_m` and
    /// `sigma_rad` stay what the measurement table carries.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub covariance: Option<PoseCovariance>,
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
            covariance: None,
            t_s: None,
            temp_c: None,
            payload_kg: None,
            dir: None,
            split: None,
            source_line: None,
            meta: BTreeMap::new(),
        }
    }

    /// The measured link of a tree-shaped robot: the table's `tip` column (kept in
    /// [`PoseMeasurement::meta`]), when the row names one.
    pub fn tip(&self) -> Option<&str> {
        self.meta.get("tip").map(String::as_str).filter(|s| !s.is_empty())
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn covariance_units_and_validation() {
        // 1 mm^2 in x, 0.5 mm rad cross term, 1e-6 rad^2 in rx.
        let mut mm = Matrix6::identity() * 1e-6;
        mm[(0, 0)] = 1.0;
        mm[(0, 3)] = 5e-4;
        mm[(3, 0)] = 5e-4;
        let c = PoseCovariance::from_mm_rad(&mm);
        let si = c.pose().unwrap();
        assert!((si[(0, 0)] - 1e-6).abs() < 1e-18, "mm^2 -> m^2");
        assert!((si[(0, 3)] - 5e-7).abs() < 1e-18, "mm rad -> m rad");
        assert!((si[(3, 3)] - 1e-6).abs() < 1e-18, "rad^2 unchanged");
        assert!((c.position_m2()[(0, 0)] - 1e-6).abs() < 1e-18);
        assert!(c.validate().is_ok());
        let not_pd = PoseCovariance::Position { m2: Matrix3::new(1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 1.0) };
        assert!(not_pd.validate().unwrap_err().contains("positive definite"));
        let asym = PoseCovariance::Position { m2: Matrix3::new(1.0, 0.5, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0) };
        assert!(asym.validate().unwrap_err().contains("symmetric"));
        let nan = PoseCovariance::Position { m2: Matrix3::identity() * f64::NAN };
        assert!(nan.validate().is_err());
    }
}
