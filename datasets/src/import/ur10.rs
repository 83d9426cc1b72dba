//! The UR10 laser-tracker recordings (`shared/data/ur10_tracker`, series A and B).
//!
//! The measurement files are semicolon-separated with a decimal comma. Columns (names as in the
//! files): `Timestamp`; `Goal x`, `Goal y`, `Goal z` (m) and `Goal roll`, `Goal pitch`,
//! `Goal yaw` (rad, extrinsic x-y-z) of the commanded pose; the six joints
//! `shoulder_pan_joint` ... `wrist_3_joint` (rad); `measurement_temperature` (deg C);
//! `measurement_x/y/z` (mm) and `measurement_rx/ry/rz` (deg, intrinsic X-Y-Z) of the T-Mac probe
//! in the tracker frame; series B adds `measurement_std_<x|y|z|rx|ry|rz>` after each value.
//!
//! Frames and transforms, as determined from the data (tests in `datasets/tests/import_ur10.rs`):
//! - `Trafo_TM_F_init*.txt` hold `T_TM_F`, the transform that maps flange coordinates into the
//!   T-Mac frame, in mm, as the name says in this project's `T_a_b` convention. Its inverse,
//!   `T_F_TM` ([`TmacFlangeFile::t_flange_tmac`]), puts the T-Mac origin 109 mm in front of the
//!   flange along the flange z axis. Nominal UR10 kinematics with `T_F_TM`, registered to the
//!   tracker by a rigid fit, reproduce the measured positions to about 3 mm RMS (series A and B);
//!   the file read the other way round (T-Mac 109 mm behind the flange) gives 34-37 mm RMS.
//! - The 109 mm is an initial value: identified from the data, the measured point sits about
//!   93.2 mm in front of the flange (then about 0.8-1.4 mm RMS remain, the nominal model's
//!   own error). Series B's `Trafo_TM_F_init_calib.txt` is a pure rotation without translation.
//! - The flange frame is the last frame of the standard UR DH table
//!   ([`ferrocal_robot::presets::ur10`]).
//! - The `Goal` columns are the T-Mac pose in the ROS `base_link` frame (the DH base turned by
//!   180 degrees about z): `Rz(pi) * FK(q) * T_F_TM` matches them to 0.6 mm and 0.12 degrees.
//! - `calibration_handeye.csv`'s flange frame has x pointing out of the flange (the ROS `flange`
//!   link): the probe sits about 93 mm along its x axis.
//! - `Timestamp` is local civil time `YYYYMMDDhhmmss` in series A; in series B the published
//!   file holds a spreadsheet-rounded `2,02011E+13` in every row, so series B has no usable time.

use std::path::{Path, PathBuf};

use ferrocal_calib::{MeasurementSet, PoseMeasurement};
use ferrocal_robot::Kinematics;
use nalgebra::{Isometry3, Matrix3, Matrix4, Quaternion, Translation3, UnitQuaternion, Vector3};

use super::geometry::{
    quat_from_extrinsic_xyz, quat_from_intrinsic_xyz, register_positions, register_with_offset, OffsetRegistration,
    PositionRegistration,
};
use super::table::{parse_number, read_text, Decimal, Table, TableFormat};
use crate::error::{DatasetError, Location, Result};

/// Joint column names of the UR10 files, in joint order.
pub const UR10_JOINT_COLUMNS: [&str; 6] =
    ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"];

/// The `Timestamp` cell of a UR10 row.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Ur10Timestamp {
    /// The cell as written.
    pub text: String,
    /// Seconds since 1970-01-01 00:00:00 of the civil time the cell names (time zone unknown,
    /// so only differences are meaningful); `None` when the cell is a rounded number rather than
    /// a `YYYYMMDDhhmmss` stamp (series B).
    pub civil_s: Option<i64>,
}

/// Standard deviations the tracker reported for one row (series B).
#[derive(Clone, Debug, PartialEq)]
pub struct Ur10Std {
    /// Of `measurement_x/y/z`, mm.
    pub position_mm: Vector3<f64>,
    /// Of `measurement_rx/ry/rz`, degrees.
    pub euler_deg: [f64; 3],
}

/// One row of a UR10 measurement file, in the file's units.
#[derive(Clone, Debug, PartialEq)]
pub struct Ur10Row {
    /// 1-based line in the file.
    pub line: u64,
    /// `Timestamp`.
    pub timestamp: Ur10Timestamp,
    /// `Goal x/y/z`, metres: the commanded T-Mac position in the ROS `base_link` frame (see the
    /// module documentation).
    pub goal_position_m: Vector3<f64>,
    /// `Goal roll/pitch/yaw`, radians, extrinsic x-y-z: the commanded T-Mac orientation in the
    /// ROS `base_link` frame.
    pub goal_rpy_rad: [f64; 3],
    /// The six joint angles, radians, in UR joint order.
    pub q_rad: [f64; 6],
    /// `measurement_temperature`, degrees Celsius.
    pub temperature_c: f64,
    /// `measurement_x/y/z`: T-Mac position in the tracker frame, mm.
    pub position_mm: Vector3<f64>,
    /// `measurement_rx/ry/rz`: T-Mac orientation in the tracker frame, degrees, intrinsic X-Y-Z.
    pub euler_xyz_deg: [f64; 3],
    /// `measurement_std_*`, when the file has them (series B).
    pub std: Option<Ur10Std>,
}

impl Ur10Row {
    /// Commanded orientation from `Goal roll/pitch/yaw` (extrinsic x-y-z).
    pub fn goal_orientation(&self) -> UnitQuaternion<f64> {
        let [r, p, y] = self.goal_rpy_rad;
        quat_from_extrinsic_xyz(r, p, y)
    }

    /// Measured T-Mac orientation in the tracker frame (intrinsic X-Y-Z degrees converted).
    pub fn orientation(&self) -> UnitQuaternion<f64> {
        let [a, b, c] = self.euler_xyz_deg.map(f64::to_radians);
        quat_from_intrinsic_xyz(a, b, c)
    }

    /// Measured T-Mac position in the tracker frame, metres.
    pub fn position_m(&self) -> Vector3<f64> {
        self.position_mm / 1000.0
    }
}

/// A UR10 measurement file.
#[derive(Clone, Debug, PartialEq)]
pub struct Ur10Recording {
    /// The file read.
    pub file: PathBuf,
    /// Rows in file order.
    pub rows: Vec<Ur10Row>,
}

impl Ur10Recording {
    /// The grid poses only: the rows after a leading start pose. Series A's file holds 11,911
    /// data rows; its first is the robot's start configuration (joints -90, -90, 0, -90, 0, 0
    /// degrees), not a grid point, which leaves the 11,910 grid poses the publication counts.
    /// A row is a start pose when all its joints are within 1e-3 rad of that configuration.
    pub fn grid_rows(&self) -> &[Ur10Row] {
        let start = [-90f64, -90.0, 0.0, -90.0, 0.0, 0.0].map(f64::to_radians);
        let is_start = |r: &Ur10Row| r.q_rad.iter().zip(&start).all(|(a, b)| (a - b).abs() < 1e-3);
        match self.rows.first() {
            Some(r) if is_start(r) => &self.rows[1..],
            _ => &self.rows,
        }
    }

    /// The rows as measurements: `pose_id` = the 0-based data row index, `q` in radians,
    /// `position_m` and `orientation` of the T-Mac in the tracker frame, `temp_c`, `t_s` = seconds
    /// since the first row's timestamp (series A; `None` when the timestamps are not usable),
    /// `sigma_m` / `sigma_rad` = RMS over the three axes of the reported standard deviations
    /// (series B), and `meta["timestamp"]` = the timestamp as written.
    pub fn to_measurement_set(&self) -> MeasurementSet {
        let t0 = self.rows.first().and_then(|r| r.timestamp.civil_s);
        let rms3 = |v: [f64; 3]| ((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) / 3.0).sqrt();
        let rows = self
            .rows
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let mut m = PoseMeasurement::new(i.to_string(), r.q_rad.to_vec(), r.position_m());
                m.orientation = Some(r.orientation());
                m.temp_c = Some(r.temperature_c);
                m.t_s = match (t0, r.timestamp.civil_s) {
                    (Some(a), Some(b)) => Some((b - a) as f64),
                    _ => None,
                };
                if let Some(s) = &r.std {
                    m.sigma_m = Some(rms3([s.position_mm.x, s.position_mm.y, s.position_mm.z]) / 1000.0);
                    m.sigma_rad = Some(rms3(s.euler_deg).to_radians());
                }
                m.source_line = Some(r.line);
                m.meta.insert("timestamp".into(), r.timestamp.text.clone());
                m
            })
            .collect();
        MeasurementSet { source: self.file.display().to_string(), rows }
    }

    /// Nominal flange poses `T_base_flange` of the rows: the standard UR10 DH forward kinematics
    /// ([`ferrocal_robot::presets::ur10`]) of each row's joints, metres.
    pub fn nominal_flange_poses(&self) -> Result<Vec<Isometry3<f64>>> {
        let chain = ferrocal_robot::presets::ur10();
        self.rows
            .iter()
            .map(|r| {
                chain.forward(&r.q_rad).map_err(|e| DatasetError::Invalid {
                    location: Location::line(&self.file, r.line),
                    message: format!("forward kinematics of the joints failed: {e}"),
                })
            })
            .collect()
    }

    /// Nominal T-Mac positions in the robot base frame, metres: the nominal flange poses
    /// composed with `t_flange_tmac`.
    pub fn nominal_tmac_positions_m(&self, t_flange_tmac: &Isometry3<f64>) -> Result<Vec<Vector3<f64>>> {
        Ok(self.nominal_flange_poses()?.iter().map(|t| (t * t_flange_tmac).translation.vector).collect())
    }

    /// Reproduces the measured T-Mac positions from the published columns: nominal UR10 forward
    /// kinematics of the joints, composed with `t_flange_tmac`, registered to the tracker frame by
    /// a rigid fit over the rows where `fit_row(i)` is true. The result's `t_device_model` is
    /// `T_tracker_base`.
    pub fn reproduce_positions(
        &self,
        t_flange_tmac: &Isometry3<f64>,
        fit_row: impl Fn(usize) -> bool,
    ) -> Result<PositionRegistration> {
        let model = self.nominal_tmac_positions_m(t_flange_tmac)?;
        let measured: Vec<Vector3<f64>> = self.rows.iter().map(Ur10Row::position_m).collect();
        register_positions(&model, &measured, fit_row)
    }

    /// Like [`Ur10Recording::reproduce_positions`], but identifies the T-Mac's position in the
    /// flange frame together with `T_tracker_base` (starting from `t_flange_tmac`'s
    /// translation), so that an inexact probe offset in the transform file does not dominate the
    /// residual.
    pub fn reproduce_positions_fitting_offset(
        &self,
        t_flange_tmac: &Isometry3<f64>,
        fit_row: impl Fn(usize) -> bool,
    ) -> Result<OffsetRegistration> {
        let poses = self.nominal_flange_poses()?;
        let measured: Vec<Vector3<f64>> = self.rows.iter().map(Ur10Row::position_m).collect();
        register_with_offset(&poses, &measured, t_flange_tmac.translation.vector, fit_row)
    }
}

fn numeric_ur10(_: &str) -> bool {
    true
}

/// Reads a UR10 measurement file (series A `measurements_grid.csv` or series B
/// `measurements_joint_configurations.csv`); the `measurement_std_*` columns are read when all
/// six are present.
pub fn read_ur10_measurements(path: impl AsRef<Path>) -> Result<Ur10Recording> {
    let path = path.as_ref();
    let table = Table::read(path, TableFormat::SEMICOLON_DECIMAL_COMMA, &numeric_ur10)?;
    let ts = table.require("Timestamp")?;
    let goal = ["Goal x", "Goal y", "Goal z", "Goal roll", "Goal pitch", "Goal yaw"]
        .map(|c| table.require(c))
        .into_iter()
        .collect::<Result<Vec<_>>>()?;
    let joints = UR10_JOINT_COLUMNS.map(|c| table.require(c)).into_iter().collect::<Result<Vec<_>>>()?;
    let temp = table.require("measurement_temperature")?;
    let meas =
        ["measurement_x", "measurement_y", "measurement_z", "measurement_rx", "measurement_ry", "measurement_rz"]
            .map(|c| table.require(c))
            .into_iter()
            .collect::<Result<Vec<_>>>()?;
    let std_names = [
        "measurement_std_x",
        "measurement_std_y",
        "measurement_std_z",
        "measurement_std_rx",
        "measurement_std_ry",
        "measurement_std_rz",
    ];
    let std_cols = if std_names.iter().any(|c| table.col(c).is_some()) {
        Some(std_names.map(|c| table.require(c)).into_iter().collect::<Result<Vec<_>>>()?)
    } else {
        None
    };

    let mut rows = Vec::with_capacity(table.rows.len());
    for row in &table.rows {
        let num = |c: usize| table.number(row, c);
        let text = table.text(row, ts)?;
        let timestamp = parse_timestamp(text, || table.loc(row, ts))?;
        let std = match &std_cols {
            Some(c) => Some(Ur10Std {
                position_mm: Vector3::new(num(c[0])?, num(c[1])?, num(c[2])?),
                euler_deg: [num(c[3])?, num(c[4])?, num(c[5])?],
            }),
            None => None,
        };
        rows.push(Ur10Row {
            line: row.line,
            timestamp,
            goal_position_m: Vector3::new(num(goal[0])?, num(goal[1])?, num(goal[2])?),
            goal_rpy_rad: [num(goal[3])?, num(goal[4])?, num(goal[5])?],
            q_rad: [
                num(joints[0])?,
                num(joints[1])?,
                num(joints[2])?,
                num(joints[3])?,
                num(joints[4])?,
                num(joints[5])?,
            ],
            temperature_c: num(temp)?,
            position_mm: Vector3::new(num(meas[0])?, num(meas[1])?, num(meas[2])?),
            euler_xyz_deg: [num(meas[3])?, num(meas[4])?, num(meas[5])?],
            std,
        });
    }
    Ok(Ur10Recording { file: path.to_path_buf(), rows })
}

/// Reads a UR10 measurement file straight into a measurement set
/// (see [`Ur10Recording::to_measurement_set`]).
pub fn import_ur10_measurements(path: impl AsRef<Path>) -> Result<MeasurementSet> {
    Ok(read_ur10_measurements(path)?.to_measurement_set())
}

fn parse_timestamp(text: &str, loc: impl Fn() -> Location) -> Result<Ur10Timestamp> {
    if text.len() == 14 && text.bytes().all(|b| b.is_ascii_digit()) {
        let f = |a: usize, b: usize| text[a..b].parse::<i64>().unwrap_or(-1);
        let (y, mo, d, h, mi, s) = (f(0, 4), f(4, 6), f(6, 8), f(8, 10), f(10, 12), f(12, 14));
        let leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
        let dim = match mo {
            1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
            4 | 6 | 9 | 11 => 30,
            2 if leap => 29,
            2 => 28,
            _ => 0,
        };
        if !(1..=dim).contains(&d) || !(0..24).contains(&h) || !(0..60).contains(&mi) || !(0..=60).contains(&s) {
            return Err(DatasetError::Invalid {
                location: loc(),
                message: format!("'{text}' is not a valid YYYYMMDDhhmmss time stamp"),
            });
        }
        let days = days_from_civil(y, mo, d);
        return Ok(Ur10Timestamp { text: text.to_string(), civil_s: Some(days * 86_400 + h * 3600 + mi * 60 + s) });
    }
    // Otherwise the spreadsheet turned the stamp into a rounded number: keep the text only.
    parse_number(text, Decimal::Comma, &loc)?;
    Ok(Ur10Timestamp { text: text.to_string(), civil_s: None })
}

/// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's algorithm).
fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// A `Trafo_TM_F_*.txt` file: a 4x4 homogeneous transform, rows on lines, values separated by
/// spaces, lengths in mm.
#[derive(Clone, Debug, PartialEq)]
pub struct TmacFlangeFile {
    /// The file read.
    pub file: PathBuf,
    /// The matrix exactly as written (mm).
    pub matrix_mm: Matrix4<f64>,
    /// The same transform with the rotation orthonormalised and the translation in metres:
    /// `T_TM_F`, mapping flange coordinates into the T-Mac frame.
    pub t_tmac_flange: Isometry3<f64>,
}

impl TmacFlangeFile {
    /// `T_F_TM`: the T-Mac frame in the flange frame (the inverse of the file's transform). Use it
    /// as the tool of the UR10 model.
    pub fn t_flange_tmac(&self) -> Isometry3<f64> {
        self.t_tmac_flange.inverse()
    }
}

/// Reads a `Trafo_TM_F_*.txt` transform file. Errors name the file, line and field; the
/// rotation part must be orthonormal to 1e-4 and the last row `0 0 0 1`.
pub fn read_tmac_flange_transform(path: impl AsRef<Path>) -> Result<TmacFlangeFile> {
    let path = path.as_ref();
    let text = read_text(path)?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let mut m = Matrix4::zeros();
    let mut r = 0;
    let mut last_line = 1;
    for (i, line) in text.lines().enumerate() {
        let line_no = i as u64 + 1;
        last_line = line_no;
        let fields: Vec<&str> = line.split_whitespace().collect();
        if fields.is_empty() {
            continue;
        }
        if r == 4 {
            return Err(DatasetError::Invalid {
                location: Location::line(path, line_no),
                message: "more than four rows; a 4x4 matrix was expected".into(),
            });
        }
        if fields.len() != 4 {
            return Err(DatasetError::FieldCount {
                location: Location::new(path, line_no, format!("field {}", fields.len().min(4) + 1)),
                found: fields.len(),
                expected: 4,
            });
        }
        for (c, f) in fields.iter().enumerate() {
            m[(r, c)] = parse_number(f, Decimal::Point, || Location::new(path, line_no, format!("field {}", c + 1)))?;
        }
        r += 1;
    }
    if r < 4 {
        return Err(DatasetError::Invalid {
            location: Location::line(path, last_line),
            message: format!("only {r} rows; a 4x4 matrix was expected"),
        });
    }
    let bottom = [m[(3, 0)], m[(3, 1)], m[(3, 2)], m[(3, 3)]];
    if bottom != [0.0, 0.0, 0.0, 1.0] {
        return Err(DatasetError::Invalid {
            location: Location::line(path, last_line),
            message: format!("the last row is {bottom:?}, expected [0, 0, 0, 1]"),
        });
    }
    let rot: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    let dev = (rot.transpose() * rot - Matrix3::identity()).abs().max();
    if dev > 1e-4 || rot.determinant() < 0.0 {
        return Err(DatasetError::Invalid {
            location: Location::line(path, 1),
            message: format!(
                "the upper-left 3x3 block is not a rotation (|R^T R - I| = {dev:.2e}, det = {:.4})",
                rot.determinant()
            ),
        });
    }
    // Orthonormal to the file's digits (checked above): the nearest rotation, computed directly.
    let q = ferrocal_robot::geometry::nearest_rotation(&rot).ok_or_else(|| DatasetError::Invalid {
        location: Location::line(path, 1),
        message: "the upper-left 3x3 block has no nearest rotation (SVD failed)".into(),
    })?;
    let t = Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]) / 1000.0;
    Ok(TmacFlangeFile {
        file: path.to_path_buf(),
        matrix_mm: m,
        t_tmac_flange: Isometry3::from_parts(Translation3::from(t), q),
    })
}

/// One row of series B's `calibration_handeye.csv`.
#[derive(Clone, Debug, PartialEq)]
pub struct HandEyeRow {
    /// 1-based line in the file.
    pub line: u64,
    /// `flange_x/y/z`: flange position in the robot base frame, metres.
    pub flange_position_m: Vector3<f64>,
    /// `flange_qx/qy/qz/qw`: flange orientation in the base frame (normalised).
    pub flange_orientation: UnitQuaternion<f64>,
    /// `measurement_x/y/z`: T-Mac position in the tracker frame, mm.
    pub position_mm: Vector3<f64>,
    /// `measurement_rx/ry/rz`: T-Mac orientation in the tracker frame, degrees, intrinsic X-Y-Z.
    pub euler_xyz_deg: [f64; 3],
}

impl HandEyeRow {
    /// `T_base_flange`, metres.
    pub fn t_base_flange(&self) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::from(self.flange_position_m), self.flange_orientation)
    }

    /// Measured T-Mac orientation in the tracker frame.
    pub fn orientation(&self) -> UnitQuaternion<f64> {
        let [a, b, c] = self.euler_xyz_deg.map(f64::to_radians);
        quat_from_intrinsic_xyz(a, b, c)
    }

    /// Measured T-Mac position in the tracker frame, metres.
    pub fn position_m(&self) -> Vector3<f64> {
        self.position_mm / 1000.0
    }
}

/// Reads series B's `calibration_handeye.csv` (semicolon-separated, decimal comma).
pub fn read_ur10_handeye(path: impl AsRef<Path>) -> Result<Vec<HandEyeRow>> {
    let path = path.as_ref();
    let table = Table::read(path, TableFormat::SEMICOLON_DECIMAL_COMMA, &numeric_ur10)?;
    let names = [
        "flange_x",
        "flange_y",
        "flange_z",
        "flange_qx",
        "flange_qy",
        "flange_qz",
        "flange_qw",
        "measurement_x",
        "measurement_y",
        "measurement_z",
        "measurement_rx",
        "measurement_ry",
        "measurement_rz",
    ];
    let cols = names.map(|c| table.require(c)).into_iter().collect::<Result<Vec<_>>>()?;
    let mut rows = Vec::with_capacity(table.rows.len());
    for row in &table.rows {
        let mut v = [0.0; 13];
        for (k, c) in cols.iter().enumerate() {
            v[k] = table.number(row, *c)?;
        }
        let raw = Quaternion::new(v[6], v[3], v[4], v[5]);
        if raw.norm() < 1e-6 {
            return Err(DatasetError::Invalid {
                location: table.loc(row, cols[6]),
                message: "flange quaternion has zero length".into(),
            });
        }
        rows.push(HandEyeRow {
            line: row.line,
            flange_position_m: Vector3::new(v[0], v[1], v[2]),
            flange_orientation: UnitQuaternion::from_quaternion(raw),
            position_mm: Vector3::new(v[7], v[8], v[9]),
            euler_xyz_deg: [v[10], v[11], v[12]],
        });
    }
    Ok(rows)
}
