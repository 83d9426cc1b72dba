//! The tables of `ferrocal dynamics` (`docs/dynamics.md`): streams (`t_s` and six channels on a
//! uniform time grid: leg positions `q1_m..q6_m`, forces `f1_n..f6_n`) and quasi-static pose
//! tables (`x_m,y_m,z_m,roll_rad,pitch_rad,yaw_rad` and six averaged forces). Comma-separated, a
//! header line first, `#` lines and blank lines skipped; errors name the file, line and column.

use std::path::{Path, PathBuf};

use ferrocal_calib::dynamics::signals::SampledSignal;
use ferrocal_robot::dynamics::motion::{coordinates_from_pose, pose_from_coordinates};
use ferrocal_robot::Pose;
use nalgebra::DMatrix;

use crate::error::{DatasetError, Result};

fn input(message: String) -> DatasetError {
    DatasetError::Input(message)
}

/// A numeric table read from a CSV file, with the line of every row.
pub struct Table {
    /// The file.
    pub path: PathBuf,
    /// The required columns, row by row.
    pub values: DMatrix<f64>,
    /// The 1-based line of every row.
    pub lines: Vec<usize>,
}

/// Reads the `required` columns of a comma-separated file (header line first; `#` lines and
/// blank lines are skipped). Errors carry `file:line` and the column.
pub fn read_table(path: &Path, required: &[&str]) -> Result<Table> {
    let text = std::fs::read_to_string(path).map_err(|source| DatasetError::Io { path: path.to_path_buf(), source })?;
    let mut header: Option<(usize, Vec<String>)> = None;
    let mut rows: Vec<Vec<f64>> = Vec::new();
    let mut lines = Vec::new();
    let mut index = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let l = raw.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let cells: Vec<&str> = l.split(',').map(str::trim).collect();
        match &header {
            None => {
                let names: Vec<String> = cells.iter().map(|s| s.to_string()).collect();
                for r in required {
                    match names.iter().position(|n| n == r) {
                        Some(k) => index.push(k),
                        None => {
                            return Err(input(format!(
                                "{}:{line}: required column '{r}' is missing (the header has: {})",
                                path.display(),
                                names.join(", ")
                            )))
                        }
                    }
                }
                header = Some((line, names));
            }
            Some((_, names)) => {
                if cells.len() != names.len() {
                    return Err(input(format!(
                        "{}:{line}: the row has {} fields, the header {}",
                        path.display(),
                        cells.len(),
                        names.len()
                    )));
                }
                let mut row = Vec::with_capacity(required.len());
                for (r, &k) in required.iter().zip(&index) {
                    let v: f64 = cells[k].parse().map_err(|_| {
                        input(format!("{}:{line}, column '{r}': '{}' is not a number", path.display(), cells[k]))
                    })?;
                    if !v.is_finite() {
                        return Err(input(format!(
                            "{}:{line}, column '{r}': '{}' is not finite",
                            path.display(),
                            cells[k]
                        )));
                    }
                    row.push(v);
                }
                rows.push(row);
                lines.push(line);
            }
        }
    }
    if header.is_none() {
        return Err(input(format!(
            "{}: the file is empty (a header line is expected: {})",
            path.display(),
            required.join(",")
        )));
    }
    let values = DMatrix::from_fn(rows.len(), required.len(), |r, c| rows[r][c]);
    Ok(Table { path: path.to_path_buf(), values, lines })
}

/// A stream (`t_s` and six channels) as a sampled signal; the time stamps must increase on a
/// uniform grid, errors name the file and line.
pub fn read_stream(path: &Path, name: &str, channels: &[&str]) -> Result<SampledSignal> {
    let mut cols = vec!["t_s"];
    cols.extend_from_slice(channels);
    let t = read_table(path, &cols)?;
    let n = t.values.nrows();
    if n < 2 {
        return Err(input(format!("{}: {n} samples; a stream needs at least two", path.display())));
    }
    let ts: Vec<f64> = t.values.column(0).iter().copied().collect();
    for k in 1..n {
        if ts[k] <= ts[k - 1] {
            return Err(input(format!(
                "{}:{}: t_s = {} does not increase (previous {})",
                path.display(),
                t.lines[k],
                ts[k],
                ts[k - 1]
            )));
        }
    }
    let dt = (ts[n - 1] - ts[0]) / (n - 1) as f64;
    for k in 0..n {
        let dev = ts[k] - (ts[0] + dt * k as f64);
        if dev.abs() > 0.1 * dt {
            return Err(input(format!(
                "{}:{}: t_s = {} is {:.3} ms off the uniform {:.3} Hz grid: resample the stream to a constant rate",
                path.display(),
                t.lines[k],
                ts[k],
                dev * 1e3,
                1.0 / dt
            )));
        }
    }
    let values = t.values.columns(1, channels.len()).into_owned();
    SampledSignal::uniform(name, ts[0], 1.0 / dt, values).map_err(|e| input(format!("{}: {e}", t.path.display())))
}

/// A stream as CSV text: `t_s` and one column per name (the format [`read_stream`] reads).
pub fn stream_csv(names: &[&str], signal: &SampledSignal) -> String {
    let mut s = format!("t_s,{}\n", names.join(","));
    for k in 0..signal.len() {
        s.push_str(&format!("{:.6}", signal.time(k)));
        for c in 0..signal.values.ncols() {
            s.push_str(&format!(",{:.9}", signal.values[(k, c)]));
        }
        s.push('\n');
    }
    s
}

/// Leg-position columns of a stream, m.
pub const LEG_COLUMNS: [&str; 6] = ["q1_m", "q2_m", "q3_m", "q4_m", "q5_m", "q6_m"];
/// Force columns of a stream or a pose table, N.
pub const FORCE_COLUMNS: [&str; 6] = ["f1_n", "f2_n", "f3_n", "f4_n", "f5_n", "f6_n"];
/// Pose columns of a quasi-static table (`coordinates_from_pose`), m and rad.
pub const POSE_COLUMNS: [&str; 6] = ["x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad"];

/// Reads a quasi-static table (`ferrocal dynamics simulate`'s static.csv: the pose coordinates
/// and six averaged sensor forces per row): the poses and the forces (poses x 6, N).
pub fn read_static_table(path: &Path) -> Result<(Vec<Pose>, DMatrix<f64>)> {
    let mut cols: Vec<&str> = POSE_COLUMNS.to_vec();
    cols.extend_from_slice(&FORCE_COLUMNS);
    let t = read_table(path, &cols)?;
    check_pose_units(&t)?;
    let poses: Vec<Pose> =
        (0..t.values.nrows()).map(|k| pose_from_coordinates(&std::array::from_fn(|i| t.values[(k, i)]))).collect();
    Ok((poses, t.values.columns(6, 6).into_owned()))
}

/// Largest plausible platform coordinate of a quasi-static table, metres: beyond it the values
/// are millimetres under a `_m` header (the largest parallel machines move a few metres; a
/// hexapod's platform stays within a metre of its home).
pub const MAX_PLATFORM_COORDINATE_M: f64 = 50.0;

/// Refuses a quasi-static table whose pose columns cannot be in their stated units: a position
/// beyond [`MAX_PLATFORM_COORDINATE_M`] (millimetres under `_m`) or an angle beyond a full turn
/// (degrees under `_rad`); the error names the file, line, column and the likely unit.
fn check_pose_units(t: &Table) -> Result<()> {
    for (c, name) in POSE_COLUMNS.iter().enumerate() {
        let angle = c >= 3;
        let limit = if angle { std::f64::consts::TAU } else { MAX_PLATFORM_COORDINATE_M };
        let Some(r) = (0..t.values.nrows()).find(|&r| t.values[(r, c)].abs() > limit) else { continue };
        let v = t.values[(r, c)];
        let n = (0..t.values.nrows()).filter(|&k| t.values[(k, c)].abs() > limit).count();
        let why = if angle {
            format!("beyond a full turn ({limit:.4} rad): the angles look like degrees; convert them to radians")
        } else {
            format!("more than {limit} m from the platform's origin: the positions look like millimetres; convert them to metres")
        };
        return Err(input(format!(
            "{}:{}, column '{name}': {v} is {why} ({n} of {} rows)",
            t.path.display(),
            t.lines[r],
            t.values.nrows()
        )));
    }
    Ok(())
}

/// A quasi-static table as CSV text: the pose coordinates (9 decimals) and the six forces (6
/// decimals) per row (the format [`read_static_table`] reads).
pub fn static_csv(poses: &[Pose], forces_n: &DMatrix<f64>) -> String {
    let mut s = format!("{},{}\n", POSE_COLUMNS.join(","), FORCE_COLUMNS.join(","));
    for (k, p) in poses.iter().enumerate() {
        let c = coordinates_from_pose(p);
        let cells: Vec<String> =
            c.iter().map(|v| format!("{v:.9}")).chain((0..6).map(|i| format!("{:.6}", forces_n[(k, i)]))).collect();
        s.push_str(&cells.join(","));
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_report_file_and_line() {
        let dir = std::env::temp_dir().join(format!("ferrocal-dyn-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("legs.csv");
        std::fs::write(&p, "# comment\nt_s,q1_m,q2_m,q3_m,q4_m,q5_m,q6_m\n0,0,0,0,0,0,0\n0.01,0,0,x,0,0,0\n").unwrap();
        let e = read_stream(&p, "leg positions", &LEG_COLUMNS).unwrap_err().to_string();
        assert!(e.contains("legs.csv:4, column 'q3_m': 'x' is not a number"), "{e}");
        std::fs::write(&p, "t_s,q1_m,q2_m\n0,0,0\n").unwrap();
        let e = read_stream(&p, "leg positions", &LEG_COLUMNS).unwrap_err().to_string();
        assert!(e.contains("legs.csv:1: required column 'q3_m' is missing"), "{e}");
        let mut s = String::from("t_s,q1_m,q2_m,q3_m,q4_m,q5_m,q6_m\n");
        for k in 0..20 {
            let t = k as f64 * 0.01 + if k == 7 { 0.004 } else { 0.0 };
            s.push_str(&format!("{t},0,0,0,0,0,0\n"));
        }
        std::fs::write(&p, s).unwrap();
        let e = read_stream(&p, "leg positions", &LEG_COLUMNS).unwrap_err().to_string();
        assert!(e.contains("legs.csv:9: t_s = 0.074") && e.contains("off the uniform"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn static_tables_in_degrees_or_millimetres_are_refused_naming_the_column() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("static.csv");
        let head = format!("{},{}\n", POSE_COLUMNS.join(","), FORCE_COLUMNS.join(","));
        std::fs::write(&p, format!("{head}0.01,0,0.8,0.05,0,0,1,2,3,4,5,6\n0.02,0,0.8,12.5,0,0,1,2,3,4,5,6\n"))
            .unwrap();
        let e = read_static_table(&p).unwrap_err().to_string();
        assert!(e.contains("static.csv:3, column 'roll_rad': 12.5") && e.contains("look like degrees"), "{e}");
        std::fs::write(&p, format!("{head}10,0,800,0,0,0,1,2,3,4,5,6\n")).unwrap();
        let e = read_static_table(&p).unwrap_err().to_string();
        assert!(e.contains("column 'z_m': 800") && e.contains("look like millimetres"), "{e}");
        std::fs::write(&p, format!("{head}0.01,0,0.8,0.05,-0.1,3.0,1,2,3,4,5,6\n")).unwrap();
        assert!(read_static_table(&p).is_ok());
    }

    #[test]
    fn streams_and_static_tables_round_trip() {
        let dir = std::env::temp_dir().join(format!("ferrocal-dyn-rt-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let values = DMatrix::from_fn(5, 6, |r, c| 0.001 * (r * 6 + c) as f64);
        let signal = SampledSignal::uniform("legs", 0.5, 100.0, values.clone()).unwrap();
        let p = dir.join("legs.csv");
        std::fs::write(&p, stream_csv(&LEG_COLUMNS, &signal)).unwrap();
        let back = read_stream(&p, "legs", &LEG_COLUMNS).unwrap();
        assert_eq!(back.len(), 5);
        assert!((back.time(4) - 0.54).abs() < 1e-9);
        assert!((back.values.clone() - values).abs().max() < 1e-9);
        let poses: Vec<Pose> =
            (0..3).map(|k| pose_from_coordinates(&[0.01 * k as f64, 0.0, 1.0, 0.0, 0.02 * k as f64, 0.0])).collect();
        let forces = DMatrix::from_fn(3, 6, |r, c| (r + c) as f64 - 2.5);
        let p = dir.join("static.csv");
        std::fs::write(&p, static_csv(&poses, &forces)).unwrap();
        let (pb, fb) = read_static_table(&p).unwrap();
        assert_eq!(pb.len(), 3);
        assert!((fb - forces).abs().max() < 1e-6);
        let c = coordinates_from_pose(&pb[2]);
        assert!((c[0] - 0.02).abs() < 1e-9 && (c[4] - 0.04).abs() < 1e-9, "{c:?}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
