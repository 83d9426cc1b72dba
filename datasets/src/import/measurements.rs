//! The measurement table of `shared/spec/measurements.md`: reader and writer.
//!
//! The reader accepts every required and optional column of the specification in any order,
//! converts to SI (metres, radians) and reports each problem with the file, the 1-based line
//! (comment lines count) and the column name. Columns the specification does not define are kept
//! per row in [`PoseMeasurement::meta`].
//!
//! The writer produces a table the reader reads back to the same values. With the default SI
//! columns (`q<i>_rad` / `q<i>_m`, `x_m`, `sigma_m`) the round trip is bit-exact; with `deg` or
//! `mm` columns it is exact to the last bit or two of each value (one multiplication and one
//! division by the unit factor).

use std::collections::{BTreeSet, HashMap};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use ferrocal_calib::{MeasurementSet, PoseCovariance, PoseMeasurement, Split};
use ferrocal_robot::JointKind;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

use super::plausible::{cut_cell, MAX_JOINT_SI, MAX_POSITION_M};
use super::table::{Row, Table, TableFormat};
use super::units::{JointUnit, LengthUnit};
use crate::error::{DatasetError, Location, Result};

mod write;

pub(crate) use write::fmt_f64;
pub use write::{measurements_to_string, write_measurements};

/// A measurement table as read from a file: the rows in SI units plus the units the columns used.
#[derive(Clone, Debug, PartialEq)]
pub struct MeasurementTable {
    /// The rows, in SI units; `source` is the file, `source_line` the line of each row.
    pub set: MeasurementSet,
    /// Unit of each joint column, in joint order (`q1` first). Its [`JointUnit::kind`] tells
    /// whether the table treats the joint as revolute or prismatic.
    pub joint_units: Vec<JointUnit>,
    /// Units of the `x`, `y`, `z` columns.
    pub position_units: [LengthUnit; 3],
    /// Unit of the `sigma` column, when present.
    pub sigma_unit: Option<LengthUnit>,
    /// The file (for messages).
    pub file: PathBuf,
    /// 1-based line of the header row.
    pub header_line: u64,
    /// Doubts that are not errors (a last line without a line end), for the caller to print.
    pub warnings: Vec<String>,
}

impl MeasurementTable {
    /// The joint kinds implied by the unit suffixes, in joint order.
    pub fn joint_kinds(&self) -> Vec<JointKind> {
        self.joint_units.iter().map(|u| u.kind()).collect()
    }

    /// Checks the table's joint columns against a robot model's joint kinds: the same number of
    /// joints, `rad`/`deg` for revolute joints and `m`/`mm` for prismatic ones. The error names
    /// the file, the header line and the offending column.
    pub fn check_joint_kinds(&self, kinds: &[JointKind]) -> Result<()> {
        if kinds.len() != self.joint_units.len() {
            return Err(DatasetError::JointCount {
                location: Location::new(
                    &self.file,
                    self.header_line,
                    format!("q{}_{}", self.joint_units.len(), self.joint_units.last().map_or("rad", |u| u.suffix())),
                ),
                message: format!(
                    "the table has {} joint columns, the robot model {} joints",
                    self.joint_units.len(),
                    kinds.len()
                ),
            });
        }
        for (i, (u, k)) in self.joint_units.iter().zip(kinds).enumerate() {
            if u.kind() != *k {
                let want = match k {
                    JointKind::Revolute => "rad or deg",
                    JointKind::Prismatic => "m or mm",
                };
                return Err(DatasetError::Invalid {
                    location: Location::new(&self.file, self.header_line, format!("q{}_{}", i + 1, u.suffix())),
                    message: format!("joint {} of the robot model is {:?}; its column needs the unit {want}", i + 1, k),
                });
            }
        }
        Ok(())
    }
}

/// How [`write_measurements`] writes a table.
#[derive(Clone, Debug, PartialEq)]
pub struct WriteOptions {
    /// Unit of each joint column, in joint order; its length must equal the rows' joint count.
    pub joint_units: Vec<JointUnit>,
    /// Unit of the `x`, `y`, `z` and `sigma` columns.
    pub length_unit: LengthUnit,
    /// Whether to write [`PoseMeasurement::meta`] entries as extra columns (the specification's
    /// readers ignore columns they do not know; keys must not be names of specified columns).
    pub include_meta: bool,
    /// Comment lines written before the header (without the leading `#`).
    pub comments: Vec<String>,
}

impl WriteOptions {
    /// SI columns (`rad` or `m` per joint kind, lengths in `m`): a bit-exact round trip.
    pub fn si(kinds: &[JointKind]) -> Self {
        Self {
            joint_units: kinds.iter().map(|k| JointUnit::si(*k)).collect(),
            length_unit: LengthUnit::M,
            include_meta: false,
            comments: Vec::new(),
        }
    }

    /// SI columns for `n` revolute joints (serial arms such as the UR presets).
    pub fn revolute(n: usize) -> Self {
        Self::si(&vec![JointKind::Revolute; n])
    }

    /// SI columns matching the kinds of a table read earlier.
    pub fn si_like(table: &MeasurementTable) -> Self {
        Self::si(&table.joint_kinds())
    }
}

/// Reads a measurement table.
pub fn read_measurements(path: impl AsRef<Path>) -> Result<MeasurementTable> {
    let path = path.as_ref();
    let text = super::table::read_text(path)?;
    parse_measurements(&text, path)
}

/// Parses a measurement table from text; `source` names it in messages and in the set.
pub fn parse_measurements(text: &str, source: impl AsRef<Path>) -> Result<MeasurementTable> {
    parse_table(text, source.as_ref(), true)
}

/// Reads a joint program: the measurement table's columns without the measured ones (`x`, `y`,
/// `z` may be absent; when absent the rows' positions are zero and mean nothing): `pose_id`,
/// `q1_<u>` ... `qN_<u>`, and the conditions the effects see (`dir<i>`, `temp_c`, `payload_kg`,
/// `t_s`). Errors name the file, line and column as for measurement tables.
pub fn read_joint_program(path: impl AsRef<Path>) -> Result<MeasurementTable> {
    let path = path.as_ref();
    let text = super::table::read_text(path)?;
    parse_table(&text, path, false)
}

/// Reads a table of wanted poses (`ferrocal correct --targets`): `pose_id`, `x_<u>`, `y_<u>`,
/// `z_<u>`, optionally `qw, qx, qy, qz`, joint columns `q1_<u>` ... as the start of the search
/// (a row whose joint cells are all empty has none; without joint columns the rows' `q` are
/// empty), and the conditions the effects see. Errors name the file, line and column.
pub fn read_targets(path: impl AsRef<Path>) -> Result<MeasurementTable> {
    let path = path.as_ref();
    let text = super::table::read_text(path)?;
    parse_with(&text, path, true, false)
}

fn parse_table(text: &str, source: &Path, require_positions: bool) -> Result<MeasurementTable> {
    parse_with(text, source, require_positions, true)
}

fn parse_with(text: &str, source: &Path, require_positions: bool, require_joints: bool) -> Result<MeasurementTable> {
    let table = Table::parse(text, source, TableFormat::CSV, &|name| {
        matches!(
            classify(name),
            Ok(Column::Joint(..)
                | Column::Position(..)
                | Column::Quat(_)
                | Column::Sigma(_)
                | Column::TS
                | Column::TempC
                | Column::PayloadKg)
        )
    })?;
    let mut layout = Layout::from_table(&table, require_positions, require_joints)?;
    layout.joints_optional = !require_joints;
    let warnings = super::plausible::check_not_cut(text, &table)?;
    let mut rows = Vec::with_capacity(table.rows.len());
    let mut seen: HashMap<String, u64> = HashMap::new();
    for row in &table.rows {
        let m = layout.read_row(&table, row)?;
        if let Some(first) = seen.get(&m.pose_id) {
            return Err(DatasetError::DuplicateId {
                location: table.loc(row, layout.pose_id),
                id: cut_cell(&m.pose_id),
                first_line: *first,
            });
        }
        seen.insert(m.pose_id.clone(), row.line);
        rows.push(m);
    }
    let mut table = MeasurementTable {
        set: MeasurementSet { source: source.display().to_string(), rows },
        joint_units: layout.joints.iter().map(|(_, u)| *u).collect(),
        position_units: [layout.xyz[0].1, layout.xyz[1].1, layout.xyz[2].1],

        sigma_unit: layout.sigma.map(|(_, u)| u),
        file: source.to_path_buf(),
        header_line: table.header_line,
        warnings,
    };
    let units = super::plausible::unit_warnings(&table);
    table.warnings.extend(units);
    Ok(table)
}

/// What a header name means.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Column {
    PoseId,
    /// 1-based joint number and unit.
    Joint(usize, JointUnit),
    /// Axis 0..3 and unit.
    Position(usize, LengthUnit),
    /// 0..4 = w, x, y, z.
    Quat(usize),
    Sigma(LengthUnit),
    TS,
    TempC,
    PayloadKg,
    /// 1-based joint number.
    Dir(usize),
    Split,
    /// Covariance entry (row, column of the 6 x 6 over `[x, y, z, rx, ry, rz]`, row <= column)
    /// and the factor from the column's unit to SI.
    Cov(usize, usize, f64),
    Meta,
}

/// The coordinates of a pose covariance, in the order of [`PoseCovariance`]'s chart.
const COV_AXES: [&str; 6] = ["x", "y", "z", "rx", "ry", "rz"];

/// The covariance column of entry `(i, j)` (`i <= j`) with lengths in `unit`.
fn cov_column(i: usize, j: usize, unit: LengthUnit) -> String {
    let lu = unit.suffix();
    let u = match (i < 3, j < 3) {
        (true, true) => format!("{lu}2"),
        (true, false) => format!("{lu}_rad"),
        _ => "rad2".to_string(),
    };
    format!("cov_{}_{}_{u}", COV_AXES[i], COV_AXES[j])
}

/// A `cov_<a>_<b>_<unit>` name, or `None` when `name` is not one.
fn classify_cov(name: &str) -> Option<std::result::Result<Column, String>> {
    let rest = name.strip_prefix("cov_")?;
    let axis = |s: &str| -> Option<(usize, usize)> {
        COV_AXES
            .iter()
            .enumerate()
            .filter(|(_, a)| s.starts_with(*a) && s[a.len()..].starts_with('_'))
            .map(|(k, a)| (k, a.len()))
            .max_by_key(|x| x.1)
    };
    let bad = || {
        Some(Err(format!("'{name}': a covariance column is cov_<a>_<b>_<unit> with <a>, <b> in x, y, z, rx, ry, rz (a first) and <unit> m2 or mm2, m_rad or mm_rad, rad2")))
    };
    let Some((i, la)) = axis(rest) else { return bad() };
    let rest = &rest[la + 1..];
    let Some((j, lb)) = axis(rest) else { return bad() };
    let unit = &rest[lb + 1..];
    if i > j {
        return bad();
    }
    let scale = match ((i < 3, j < 3), unit) {
        ((true, true), "m2") => 1.0,
        ((true, true), "mm2") => 1e-6,
        ((true, false), "m_rad") => 1.0,
        ((true, false), "mm_rad") => 1e-3,
        ((false, false), "rad2") => 1.0,
        _ => return bad(),
    };
    Some(Ok(Column::Cov(i, j, scale)))
}

fn classify(name: &str) -> std::result::Result<Column, String> {
    match name {
        "pose_id" => return Ok(Column::PoseId),
        "qw" => return Ok(Column::Quat(0)),
        "qx" => return Ok(Column::Quat(1)),
        "qy" => return Ok(Column::Quat(2)),
        "qz" => return Ok(Column::Quat(3)),
        "t_s" => return Ok(Column::TS),
        "temp_c" => return Ok(Column::TempC),
        "payload_kg" => return Ok(Column::PayloadKg),
        "split" => return Ok(Column::Split),
        _ => {}
    }
    if let Some(c) = classify_cov(name) {
        return c;
    }
    if let Some(rest) = name.strip_prefix('q') {
        let digits: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
        if !digits.is_empty() {
            let idx: usize = digits.parse().map_err(|_| "joint number too large".to_string())?;
            if idx == 0 {
                return Err("joints are numbered from 1 (q1, q2, ...)".into());
            }
            let suffix = &rest[digits.len()..];
            return match suffix.strip_prefix('_').and_then(JointUnit::from_suffix) {
                Some(u) => Ok(Column::Joint(idx, u)),
                None => Err(format!(
                    "a joint column needs a unit suffix: q{idx}_rad, q{idx}_deg (revolute), q{idx}_m or q{idx}_mm (prismatic)"
                )),
            };
        }
    }
    if let Some(rest) = name.strip_prefix("dir") {
        if !rest.is_empty() && rest.bytes().all(|b| b.is_ascii_digit()) {
            return match rest.parse::<usize>() {
                Ok(0) | Err(_) => Err("dir columns are numbered from 1 (dir1, dir2, ...)".into()),
                Ok(i) => Ok(Column::Dir(i)),
            };
        }
    }
    for (axis, p) in ["x_", "y_", "z_"].iter().enumerate() {
        if let Some(s) = name.strip_prefix(p) {
            return match LengthUnit::from_suffix(s) {
                Some(u) => Ok(Column::Position(axis, u)),
                None => Err(format!("unknown unit '{s}' of a position column (use {p}m or {p}mm)")),
            };
        }
    }
    if let Some(s) = name.strip_prefix("sigma_") {
        return match LengthUnit::from_suffix(s) {
            Some(u) => Ok(Column::Sigma(u)),
            None => Err(format!("unknown unit '{s}' of the sigma column (use sigma_m or sigma_mm)")),
        };
    }
    Ok(Column::Meta)
}

/// Column indices of a parsed header.
struct Layout {
    pose_id: usize,
    /// (column, unit) per joint, joint order.
    joints: Vec<(usize, JointUnit)>,
    xyz: [(usize, LengthUnit); 3],
    quat: Option<[usize; 4]>,
    sigma: Option<(usize, LengthUnit)>,
    t_s: Option<usize>,
    temp_c: Option<usize>,
    payload_kg: Option<usize>,
    dir: Option<Vec<usize>>,
    split: Option<usize>,
    /// (row, column, factor to SI, table column) of every covariance entry given.
    cov: Vec<(usize, usize, f64, usize)>,
    meta: Vec<usize>,
    /// A row whose joint cells are all empty has no joints (a table of wanted poses).
    joints_optional: bool,
}

impl Layout {
    fn from_table(t: &Table, require_positions: bool, require_joints: bool) -> Result<Layout> {
        let mut pose_id = None;
        let mut joints: HashMap<usize, (usize, JointUnit)> = HashMap::new();
        let mut xyz: [Option<(usize, LengthUnit)>; 3] = [None; 3];
        let mut quat: [Option<usize>; 4] = [None; 4];
        let mut sigma = None;
        let (mut t_s, mut temp_c, mut payload_kg, mut split) = (None, None, None, None);
        let mut dirs: HashMap<usize, usize> = HashMap::new();
        let mut meta = Vec::new();
        let mut cov: Vec<(usize, usize, f64, usize)> = Vec::new();
        let twice = |col: usize, other: usize| DatasetError::Invalid {
            location: t.header_loc(col),
            message: format!("the same quantity as column '{}'", t.headers[other]),
        };
        for (col, name) in t.headers.iter().enumerate() {
            let kind =
                classify(name).map_err(|message| DatasetError::Invalid { location: t.header_loc(col), message })?;
            match kind {
                Column::PoseId => pose_id = Some(col),
                Column::Joint(i, u) => {
                    if let Some((other, _)) = joints.insert(i, (col, u)) {
                        return Err(twice(col, other));
                    }
                }
                Column::Position(a, u) => {
                    if let Some((other, _)) = xyz[a].replace((col, u)) {
                        return Err(twice(col, other));
                    }
                }
                Column::Quat(i) => quat[i] = Some(col),
                Column::Sigma(u) => {
                    if let Some((other, _)) = sigma.replace((col, u)) {
                        return Err(twice(col, other));
                    }
                }
                Column::TS => t_s = Some(col),
                Column::TempC => temp_c = Some(col),
                Column::PayloadKg => payload_kg = Some(col),
                Column::Dir(i) => {
                    dirs.insert(i, col);
                }
                Column::Split => split = Some(col),
                Column::Cov(i, j, f) => {
                    if let Some(other) = cov.iter().find(|c| c.0 == i && c.1 == j) {
                        return Err(twice(col, other.3));
                    }
                    cov.push((i, j, f, col));
                }
                Column::Meta => meta.push(col),
            }
        }
        let pose_id = pose_id.ok_or_else(|| t.missing_column("pose_id"))?;
        let n = joints.keys().copied().max().unwrap_or(0);
        if n == 0 && require_joints {
            let mut e = t.missing_column("q1_rad");
            if let DatasetError::MissingColumn { hint, .. } = &mut e {
                if hint.is_empty() {
                    *hint = "; joint columns are q1_<u> ... qN_<u> with <u> = rad, deg, m or mm".into();
                }
            }
            return Err(e);
        }
        // n comes from a header name (`q99999999_rad`): the columns present bound the allocation.
        let mut joint_cols = Vec::with_capacity(joints.len());
        for i in 1..=n {
            match joints.get(&i) {
                Some(j) => joint_cols.push(*j),
                None => {
                    return Err(DatasetError::JointCount {
                        location: Location::new(&t.file, t.header_line, format!("q{i}_<unit>")),
                        message: format!("the header has joint columns up to q{n} but no q{i}"),
                    })
                }
            }
        }
        let mut xyz_cols = [(0, LengthUnit::M); 3];
        for (a, slot) in xyz.iter().enumerate() {
            let axis = ["x", "y", "z"][a];
            match slot {
                Some(c) => xyz_cols[a] = *c,
                None if !require_positions => xyz_cols[a] = (usize::MAX, LengthUnit::M),
                None => return Err(t.missing_column_of(&[&format!("{axis}_m"), &format!("{axis}_mm")])),
            }
        }
        let quat = if quat.iter().any(Option::is_some) {
            let mut cols = [0; 4];
            for (i, c) in quat.iter().enumerate() {
                match c {
                    Some(c) => cols[i] = *c,
                    None => {
                        let name = ["qw", "qx", "qy", "qz"][i];
                        let mut e = t.missing_column(name);
                        if let DatasetError::MissingColumn { hint, .. } = &mut e {
                            *hint = format!("; qw, qx, qy, qz come together{hint}");
                        }
                        return Err(e);
                    }
                }
            }
            Some(cols)
        } else {
            None
        };
        let dir = if dirs.is_empty() {
            None
        } else {
            let m = dirs.keys().copied().max().unwrap_or(0);
            if m != n || dirs.len() != n {
                let missing = (1..=n).find(|i| !dirs.contains_key(i));
                let column = match missing {
                    Some(i) => format!("dir{i}"),
                    None => format!("dir{m}"),
                };
                return Err(DatasetError::JointCount {
                    location: Location::new(&t.file, t.header_line, column),
                    message: format!(
                        "the header has {n} joint columns and dir columns {}; dir1 ... dir{n} must all be present",
                        {
                            let mut k: Vec<usize> = dirs.keys().copied().collect();
                            k.sort_unstable();
                            k.iter().map(|i| format!("dir{i}")).collect::<Vec<_>>().join(", ")
                        }
                    ),
                });
            }
            Some((1..=n).map(|i| dirs[&i]).collect())
        };
        Ok(Layout {
            pose_id,
            joints: joint_cols,
            xyz: xyz_cols,
            quat,
            sigma,
            t_s,
            temp_c,
            payload_kg,
            dir,
            split,
            cov,
            meta,
            joints_optional: false,
        })
    }

    /// The row's covariance from the `cov_*` cells: the position block alone when no entry
    /// involves an orientation, else the whole 6 x 6 (every entry it needs present).
    fn read_covariance(&self, t: &Table, row: &Row, m: &mut PoseMeasurement) -> Result<()> {
        let mut given = Vec::new();
        for &(i, j, f, col) in &self.cov {
            if let Some(v) = t.opt_number(row, col)? {
                given.push((i, j, v * f, col));
            }
        }
        let Some(first) = given.first().map(|g| g.3) else { return Ok(()) };
        let size = if given.iter().any(|g| g.1 >= 3) { 6 } else { 3 };
        let mut c = nalgebra::Matrix6::<f64>::zeros();
        let mut seen = [[false; 6]; 6];
        for (i, j, v, _) in given {
            (c[(i, j)], c[(j, i)]) = (v, v);
            seen[i][j] = true;
        }
        if let Some((i, j)) = (0..size).flat_map(|i| (i..size).map(move |j| (i, j))).find(|&(i, j)| !seen[i][j]) {
            return Err(DatasetError::Invalid {
                location: t.loc(row, first),
                message: format!(
                    "the covariance lacks entry ({}, {}): a {size} x {size} covariance needs all {} upper-triangle entries",
                    COV_AXES[i],
                    COV_AXES[j],
                    size * (size + 1) / 2
                ),
            });
        }
        let cov = if size == 3 {
            PoseCovariance::Position { m2: c.fixed_view::<3, 3>(0, 0).into_owned() }
        } else {
            PoseCovariance::Pose { si: c }
        };
        cov.validate().map_err(|message| DatasetError::Invalid { location: t.loc(row, first), message })?;
        m.covariance = Some(cov);
        Ok(())
    }

    fn read_row(&self, t: &Table, row: &Row) -> Result<PoseMeasurement> {
        let pose_id = t.text(row, self.pose_id)?.to_string();
        let mut q = Vec::with_capacity(self.joints.len());
        let no_joints = self.joints_optional && self.joints.iter().all(|(c, _)| row.cells[*c].trim().is_empty());
        for (col, unit) in self.joints.iter().filter(|_| !no_joints) {
            let v = unit.to_si(t.number(row, *col)?);
            if v.abs() > MAX_JOINT_SI {
                return Err(DatasetError::Invalid {
                    location: t.loc(row, *col),
                    message: format!(
                        "{} is not a plausible joint value (at most {MAX_JOINT_SI:e} rad or m)",
                        cut_cell(&row.cells[*col])
                    ),
                });
            }
            q.push(v);
        }
        let mut p = Vector3::zeros();
        for (a, (col, unit)) in self.xyz.iter().enumerate().filter(|(_, (col, _))| *col != usize::MAX) {
            p[a] = unit.to_m(t.number(row, *col)?);
            if p[a].abs() > MAX_POSITION_M {
                return Err(DatasetError::Invalid {
                    location: t.loc(row, *col),
                    message: format!(
                        "{} is not a plausible position (at most {MAX_POSITION_M:e} m from the device)",
                        cut_cell(&row.cells[*col])
                    ),
                });
            }
        }
        let mut m = PoseMeasurement::new(pose_id, q, p);
        m.source_line = Some(row.line);
        if let Some(cols) = self.quat {
            let vals = cols.iter().map(|c| t.opt_number(row, *c)).collect::<Result<Vec<_>>>()?;
            if vals.iter().any(Option::is_some) {
                let mut v = [0.0; 4];
                for (i, x) in vals.iter().enumerate() {
                    v[i] = x.ok_or_else(|| DatasetError::Invalid {
                        location: t.loc(row, cols[i]),
                        message: "empty quaternion component while the others are given; qw, qx, qy, qz are given together or not at all".into(),
                    })?;
                }
                let raw = Quaternion::new(v[0], v[1], v[2], v[3]);
                let norm = raw.norm();
                if !norm.is_finite() || norm < 1e-6 {
                    return Err(DatasetError::Invalid {
                        location: t.loc(row, cols[0]),
                        message: format!(
                            "quaternion (qw, qx, qy, qz) = ({}, {}, {}, {}) has zero length",
                            v[0], v[1], v[2], v[3]
                        ),
                    });
                }
                // A quaternion that is unit to rounding is kept bit for bit, so that written tables
                // read back unchanged; anything else is normalised.
                m.orientation = Some(if (norm - 1.0).abs() <= 8.0 * f64::EPSILON {
                    UnitQuaternion::new_unchecked(raw)
                } else {
                    UnitQuaternion::from_quaternion(raw)
                });
            }
        }
        if let Some((col, unit)) = self.sigma {
            if let Some(s) = t.opt_number(row, col)? {
                if s < 0.0 {
                    return Err(DatasetError::Invalid {
                        location: t.loc(row, col),
                        message: format!("a standard deviation cannot be negative ({s})"),
                    });
                }
                m.sigma_m = Some(unit.to_m(s));
            }
        }
        if let Some(col) = self.t_s {
            m.t_s = t.opt_number(row, col)?;
        }
        if let Some(col) = self.temp_c {
            m.temp_c = t.opt_number(row, col)?;
        }
        if let Some(col) = self.payload_kg {
            m.payload_kg = t.opt_number(row, col)?;
            if let Some(v) = m.payload_kg.filter(|v| *v < 0.0) {
                return Err(DatasetError::Invalid {
                    location: t.loc(row, col),
                    message: format!("a payload mass cannot be negative ({v})"),
                });
            }
        }
        if let Some(cols) = &self.dir {
            if cols.iter().any(|c| !row.cells[*c].is_empty()) {
                let mut d = Vec::with_capacity(cols.len());
                for c in cols {
                    d.push(match row.cells[*c].as_str() {
                        "" | "0" | "+0" | "-0" => 0,
                        "1" | "+1" => 1,
                        "-1" => -1,
                        other => {
                            return Err(DatasetError::Invalid {
                                location: t.loc(row, *c),
                                message: format!(
                                    "'{}' is not a motion direction (1, -1, or 0 for unknown)",
                                    cut_cell(other)
                                ),
                            })
                        }
                    });
                }
                m.dir = Some(d);
            }
        }
        if let Some(col) = self.split {
            m.split = match row.cells[col].as_str() {
                "" => None,
                "train" => Some(Split::Train),
                "test" => Some(Split::Test),
                other => {
                    return Err(DatasetError::Invalid {
                        location: t.loc(row, col),
                        message: format!("'{}' is not a split (train or test)", cut_cell(other)),
                    })
                }
            };
        }
        self.read_covariance(t, row, &mut m)?;
        for col in &self.meta {
            let v = &row.cells[*col];
            if !v.is_empty() {
                m.meta.insert(t.headers[*col].clone(), v.clone());
            }
        }
        Ok(m)
    }
}
