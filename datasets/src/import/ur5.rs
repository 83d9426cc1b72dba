//! The UR5 laser-tracker grid (`shared/data/ur5_tracker/ur5_grid_train.csv`).
//!
//! Columns: `step_order, x_t, y_t, z_t` (target position, mm), `x_dif, y_dif, z_dif` (mm),
//! `joint_1 .. joint_6` (commanded joint angles, degrees). The project's convention (see the
//! folder's README) is `measured = target + dif`; `pose_id` is `step_order`.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use ferrocal_calib::{MeasurementSet, PoseMeasurement};
use nalgebra::Vector3;

use super::table::{Table, TableFormat};
use crate::error::{DatasetError, Result};

/// Column names of the UR5 grid file, in file order.
pub const UR5_COLUMNS: [&str; 13] = [
    "step_order",
    "x_t",
    "y_t",
    "z_t",
    "x_dif",
    "y_dif",
    "z_dif",
    "joint_1",
    "joint_2",
    "joint_3",
    "joint_4",
    "joint_5",
    "joint_6",
];

/// One row of the UR5 grid file, in the file's units.
#[derive(Clone, Debug, PartialEq)]
pub struct Ur5Row {
    /// 1-based line in the file.
    pub line: u64,
    /// The row's `step_order`.
    pub step_order: u64,
    /// Target position (nominal forward kinematics plus tool offset), mm.
    pub target_mm: Vector3<f64>,
    /// Published difference between target and achieved position, mm.
    pub dif_mm: Vector3<f64>,
    /// Commanded joint angles, degrees.
    pub joints_deg: [f64; 6],
}

impl Ur5Row {
    /// Measured position, mm: `target + dif` (the project's sign convention).
    pub fn measured_mm(&self) -> Vector3<f64> {
        self.target_mm + self.dif_mm
    }

    /// Joint angles in radians.
    pub fn q_rad(&self) -> [f64; 6] {
        self.joints_deg.map(f64::to_radians)
    }
}

/// The UR5 grid recording.
#[derive(Clone, Debug, PartialEq)]
pub struct Ur5Grid {
    /// The file read.
    pub file: PathBuf,
    /// Rows in file order.
    pub rows: Vec<Ur5Row>,
}

impl Ur5Grid {
    /// The rows as measurements: `pose_id` = `step_order`, `q` in radians, `position_m` =
    /// (target + dif) / 1000; no orientation.
    pub fn to_measurement_set(&self) -> MeasurementSet {
        MeasurementSet {
            source: self.file.display().to_string(),
            rows: self
                .rows
                .iter()
                .map(|r| {
                    let mut m =
                        PoseMeasurement::new(r.step_order.to_string(), r.q_rad().to_vec(), r.measured_mm() / 1000.0);
                    m.source_line = Some(r.line);
                    m
                })
                .collect(),
        }
    }
}

/// Reads the UR5 grid file.
pub fn read_ur5_grid(path: impl AsRef<Path>) -> Result<Ur5Grid> {
    let path = path.as_ref();
    let table = Table::read(path, TableFormat::CSV, &|_| true)?;
    let cols = UR5_COLUMNS.map(|c| table.require(c));
    let mut idx = [0usize; 13];
    for (i, c) in cols.into_iter().enumerate() {
        idx[i] = c?;
    }
    let mut rows = Vec::with_capacity(table.rows.len());
    let mut seen: HashMap<u64, u64> = HashMap::new();
    for row in &table.rows {
        let text = table.text(row, idx[0])?;
        let step_order: u64 = text.parse().map_err(|_| DatasetError::Invalid {
            location: table.loc(row, idx[0]),
            message: format!("'{text}' is not a non-negative integer"),
        })?;
        if let Some(first) = seen.insert(step_order, row.line) {
            return Err(DatasetError::DuplicateId {
                location: table.loc(row, idx[0]),
                id: text.to_string(),
                first_line: first,
            });
        }
        let mut v = [0.0; 12];
        for (k, c) in idx[1..].iter().enumerate() {
            v[k] = table.number(row, *c)?;
        }
        rows.push(Ur5Row {
            line: row.line,
            step_order,
            target_mm: Vector3::new(v[0], v[1], v[2]),
            dif_mm: Vector3::new(v[3], v[4], v[5]),
            joints_deg: [v[6], v[7], v[8], v[9], v[10], v[11]],
        });
    }
    Ok(Ur5Grid { file: path.to_path_buf(), rows })
}

/// Reads the UR5 grid file straight into a measurement set.
pub fn import_ur5_grid(path: impl AsRef<Path>) -> Result<MeasurementSet> {
    Ok(read_ur5_grid(path)?.to_measurement_set())
}
