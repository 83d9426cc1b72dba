//! The `ferrocal import` workflow for measurement tables: a recording read
//! ([`ImportSource`]) and written back as the measurement table of
//! `shared/spec/measurements.md` ([`import_table`]), with lengths in mm and the joints in SI or
//! user units. (The industrial_calibration hand-eye sets are imported by
//! [`crate::handeye::import_ic_handeye`].)

use std::path::Path;

use ferrocal_calib::{MeasurementSet, Split};
use ferrocal_robot::JointKind;

use super::{measurements_to_string, JointUnit, LengthUnit, WriteOptions};
use crate::error::Result;

/// Which recording is read (`ur5`, `ur10`, `table`, `ic_handeye`, `ic_kinematic` by name).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImportSource {
    /// `ur5_tracker/ur5_grid_train.csv`.
    Ur5,
    /// `ur10_tracker/Series_*/measurements_*.csv`.
    Ur10,
    /// A measurement table (re-written in canonical units, checked on the way).
    Table,
    /// An industrial_calibration hand-eye set (`cal_data.yaml`, `poses/`): a hand-eye poses
    /// table, not a measurement table ([`crate::handeye::import_ic_handeye`]).
    IcHandeye,
    /// An industrial_calibration kinematic-calibration set (`measurements.yaml`).
    IcKinematic,
}

/// A recording converted into a measurement table.
#[derive(Clone, Debug)]
pub struct ImportedTable {
    /// The rows.
    pub set: MeasurementSet,
    /// The table's text.
    pub table: String,
    /// The source's nominal robot as URDF (the kinematic-calibration sets, when asked for).
    pub urdf: Option<String>,
    /// What the reader warns about (a measurement table: units that do not fit the header, a
    /// last line without a line end), each naming the file.
    pub warnings: Vec<String>,
}

impl ImportedTable {
    /// Rows marked `test`.
    pub fn n_test(&self) -> usize {
        self.set.rows.iter().filter(|r| r.split == Some(Split::Test)).count()
    }
}

/// Reads the recording `input` of `source` and writes it as a measurement table (for the file
/// `out`, named in an error): lengths in mm, joints in SI units or, with `user_units`, in
/// degrees and mm. `test_every` marks every K-th row `test` (the kinematic-calibration sets);
/// `with_urdf` also writes their nominal positioner as URDF.
pub fn import_table(
    source: ImportSource,
    input: &Path,
    out: &Path,
    test_every: Option<usize>,
    with_urdf: bool,
    user_units: bool,
) -> Result<ImportedTable> {
    let revolute = |s: MeasurementSet| {
        let n = s.n_joints();
        (s, vec![JointKind::Revolute; n])
    };
    let mut urdf = None;
    let mut warnings = Vec::new();
    let (set, kinds) = match source {
        ImportSource::IcKinematic => {
            let s = crate::handeye::read_ic_kinematic(input, test_every)?;
            if with_urdf {
                urdf = Some(crate::handeye::ic_kinematic::ic_positioner_urdf(input)?);
            }
            revolute(s)
        }
        ImportSource::IcHandeye => {
            let why =
                "an industrial_calibration hand-eye set is a poses table for `handeye` (handeye::import_ic_handeye)";
            return Err(crate::error::DatasetError::Input(why.into()));
        }
        ImportSource::Ur5 => revolute(super::import_ur5_grid(input)?),
        ImportSource::Ur10 => revolute(super::import_ur10_measurements(input)?),
        ImportSource::Table => {
            let t = super::read_measurements(input)?;
            warnings = t.warnings.clone();
            let k = t.joint_kinds();
            (t.set, k)
        }
    };
    let mut opts = WriteOptions::si(&kinds);
    if user_units {
        opts.joint_units = kinds
            .iter()
            .map(|k| match k {
                JointKind::Revolute => JointUnit::Deg,
                JointKind::Prismatic => JointUnit::Mm,
            })
            .collect();
    }
    opts.length_unit = LengthUnit::Mm;
    opts.comments = vec![format!("imported by ferrocal {} from {}", env!("CARGO_PKG_VERSION"), input.display())];
    let table = measurements_to_string(&set, &opts).map_err(|e| e.context(format!("writing {}", out.display())))?;
    Ok(ImportedTable { set, table, urdf, warnings })
}
