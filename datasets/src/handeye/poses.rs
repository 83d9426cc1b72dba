//! The hand-eye poses table (`ferrocal handeye --poses`, `shared/spec/cli.md`): one row per
//! image, `image`, then either the flange pose the controller reported (`x_mm, y_mm, z_mm, qw,
//! qx, qy, qz`: `T_base_flange`, Hamilton unit quaternion, scalar first; `x_m, y_m, z_m` in
//! metres also accepted) or joint readings `q1_<unit>, q2_<unit>, ...` (`rad`, `deg`, `m`, `mm`)
//! for a robot model, and an optional `split` column (`train` / `test`, empty = train).
//!
//! Comment lines start with `#`. Every error names the file, the line and the column.
//! Quaternions are normalised when their norm is within [`QUATERNION_NORM_TOLERANCE`] of 1
//! (controllers print rounded values) and rejected otherwise.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};

use ferrocal_calib::Split;
use ferrocal_robot::{Kinematics, RobotModel};

use crate::error::{DatasetError, Location, Result};
use crate::import::table::{Table, TableFormat};
use crate::import::units::{JointUnit, LengthUnit};

/// How far from 1 a quaternion's norm may be before the row is rejected.
pub const QUATERNION_NORM_TOLERANCE: f64 = 1e-3;

/// What the robot reported for one image.
#[derive(Clone, Debug, PartialEq)]
pub enum RobotReading {
    /// `T_base_flange` (metres).
    Flange(Isometry3<f64>),
    /// Joint values in SI units (rad, m), in the model's order.
    Joints(Vec<f64>),
}

/// One row of the table.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseRow {
    /// The image's file name.
    pub image: String,
    /// 1-based line of the row in the file.
    pub line: u64,
    /// Train or test.
    pub split: Split,
    /// The robot's reading.
    pub robot: RobotReading,
}

/// A parsed poses table.
#[derive(Clone, Debug, PartialEq)]
pub struct PosesTable {
    /// The file (for messages).
    pub file: PathBuf,
    /// The rows, in file order.
    pub rows: Vec<PoseRow>,
    /// The joint columns' units (empty for flange poses).
    pub joint_units: Vec<JointUnit>,
    /// The data's source and licence, from a `# source: ...` comment line (the importers write
    /// one), to be shown wherever results on the data are.
    pub source: Option<String>,
}

const POSE_COLUMNS: [&str; 4] = ["qw", "qx", "qy", "qz"];

fn is_numeric_column(h: &str) -> bool {
    h != "image" && h != "split"
}

/// Reads a poses table.
pub fn read_handeye_poses(path: impl AsRef<Path>) -> Result<PosesTable> {
    let path = path.as_ref();
    let text = crate::import::table::read_text(path)?;
    parse_handeye_poses(&text, path)
}

/// What an importer wrote into a poses table's leading comment lines (`# mount: eye-in-hand`,
/// `# pattern: chessboard:9x6:25mm`): the defaults of `handeye`'s `--mount` and `--pattern`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PosesHeader {
    /// `# mount:`, if present.
    pub mount: Option<ferrocal_calib::handeye::Mount>,
    /// `# pattern:`, if present (the pattern's text, as `--pattern` takes it).
    pub pattern: Option<String>,
}

impl PosesHeader {
    /// `--pattern` and `--mount` of `handeye`: each flag's value, else what the header of the
    /// poses table `file` holds (`# pattern:`, `# mount:`). A flag that differs from the header
    /// is used, and `warn` says so; neither given is an error naming the flag and the file.
    pub fn resolve(
        &self,
        pattern: Option<String>,
        mount: Option<ferrocal_calib::handeye::Mount>,
        file: &Path,
        warn: &dyn Fn(&str),
    ) -> Result<(String, ferrocal_calib::handeye::Mount)> {
        let pattern = flag_or_header("pattern", pattern, self.pattern.clone(), file, warn, |p| p.clone())?;
        let mount = flag_or_header("mount", mount, self.mount, file, warn, |m| m.name().to_string())?;
        Ok((pattern, mount))
    }
}

/// A flag's value, else the header's ([`PosesHeader::resolve`]).
fn flag_or_header<T: PartialEq>(
    flag: &str,
    given: Option<T>,
    written: Option<T>,
    file: &Path,
    warn: &dyn Fn(&str),
    show: impl Fn(&T) -> String,
) -> Result<T> {
    match (given, written) {
        (Some(g), Some(w)) if g != w => {
            let (g_text, w_text, f) = (show(&g), show(&w), file.display());
            warn(&format!(
                "--{flag} {g_text} differs from the '# {flag}: {w_text}' that {f} was written with; using --{flag}"
            ));
            Ok(g)
        }
        (Some(g), _) | (None, Some(g)) => Ok(g),
        (None, None) => Err(DatasetError::Input(format!(
            "handeye: --{flag} is required ({} has no '# {flag}:' line)",
            file.display()
        ))),
    }
}

/// Reads the leading comment lines of the poses table at `path` ([`PosesHeader`]); a mount
/// other than `eye-in-hand` or `eye-to-hand` is refused naming the file and line.
pub fn read_poses_header(path: impl AsRef<Path>) -> Result<PosesHeader> {
    use ferrocal_calib::handeye::Mount;
    let path = path.as_ref();
    let text = crate::import::table::read_text(path)?;
    let mut header = PosesHeader::default();
    for (i, line) in text.lines().enumerate().take_while(|(_, l)| l.trim_start().starts_with('#')) {
        let body = line.trim_start().trim_start_matches('#').trim();
        if let Some(m) = body.strip_prefix("mount:").map(str::trim) {
            header.mount = Some(match m {
                "eye-in-hand" => Mount::EyeInHand,
                "eye-to-hand" => Mount::EyeToHand,
                _ => {
                    return Err(DatasetError::Invalid {
                        location: Location::line(path, i as u64 + 1),
                        message: format!("'# mount: {m}' is not a mount; use eye-in-hand or eye-to-hand"),
                    })
                }
            });
        } else if let Some(p) = body.strip_prefix("pattern:").map(str::trim).filter(|p| !p.is_empty()) {
            header.pattern = Some(p.to_string());
        }
    }
    Ok(header)
}

/// The joint columns `q1_<u>, q2_<u>, ...` of a header, in order, with their units.
fn joint_columns(t: &Table) -> Result<Vec<(usize, JointUnit)>> {
    let mut found: Vec<(usize, usize, JointUnit)> = Vec::new();
    for (c, h) in t.headers.iter().enumerate() {
        let Some(rest) = h.strip_prefix('q') else { continue };
        let Some((num, unit)) = rest.split_once('_') else { continue };
        let Ok(k) = num.parse::<usize>() else { continue };
        let unit = JointUnit::from_suffix(unit).ok_or_else(|| DatasetError::Invalid {
            location: t.header_loc(c),
            message: format!("unknown joint unit '{unit}': use rad, deg, m or mm"),
        })?;
        found.push((k, c, unit));
    }
    found.sort_by_key(|f| f.0);
    for (i, f) in found.iter().enumerate() {
        if f.0 != i + 1 {
            return Err(DatasetError::Invalid {
                location: t.header_loc(f.1),
                message: format!("joint columns must be numbered q1, q2, ... without gaps; expected q{}", i + 1),
            });
        }
    }
    Ok(found.into_iter().map(|f| (f.1, f.2)).collect())
}

/// Parses a poses table from text; `file` names it in messages.
pub fn parse_handeye_poses(text: &str, file: &Path) -> Result<PosesTable> {
    let t = Table::parse(text, file, TableFormat::CSV, &is_numeric_column)?;
    let image = t.require("image")?;
    let split = t.col("split");
    let joints = joint_columns(&t)?;
    let unit = ["mm", "m"].into_iter().find(|u| t.col(&format!("x_{u}")).is_some());
    let position = match unit {
        Some(u) => {
            let lu = LengthUnit::from_suffix(u).expect("mm or m");
            let cols: Vec<usize> =
                ["x", "y", "z"].iter().map(|a| t.require(&format!("{a}_{u}"))).collect::<Result<_>>()?;
            let q: Vec<usize> = POSE_COLUMNS.iter().map(|c| t.require(c)).collect::<Result<_>>()?;
            Some((lu, cols, q))
        }
        None => None,
    };
    if position.is_some() && !joints.is_empty() {
        return Err(DatasetError::Invalid {
            location: t.header_loc(joints[0].0),
            message: "the table has both flange-pose columns (x_mm ... qz) and joint columns; give one of them".into(),
        });
    }
    if position.is_none() && joints.is_empty() {
        return Err(t.missing_column_of(&["x_mm", "q1_deg", "q1_rad"]));
    }
    let mut rows = Vec::with_capacity(t.rows.len());
    let mut seen: HashMap<String, u64> = HashMap::new();
    for row in &t.rows {
        let name = t.text(row, image)?.to_string();
        if let Some(first) = seen.insert(name.clone(), row.line) {
            return Err(DatasetError::Invalid {
                location: t.loc(row, image),
                message: format!("image '{name}' occurs twice (first on line {first})"),
            });
        }
        let split = match split.map(|c| row.cells[c].to_ascii_lowercase()) {
            None => Split::Train,
            Some(s) if s.is_empty() || s == "train" => Split::Train,
            Some(s) if s == "test" => Split::Test,
            Some(s) => {
                return Err(DatasetError::Invalid {
                    location: t.loc(row, split.expect("present")),
                    message: format!("split '{s}': expected train or test"),
                })
            }
        };
        let robot = match &position {
            Some((lu, cols, qc)) => {
                let p: Vec<f64> = cols.iter().map(|&c| t.number(row, c).map(|v| lu.to_m(v))).collect::<Result<_>>()?;
                let q: Vec<f64> = qc.iter().map(|&c| t.number(row, c)).collect::<Result<_>>()?;
                let quat = Quaternion::new(q[0], q[1], q[2], q[3]);
                let norm = quat.norm();
                if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
                    return Err(DatasetError::Invalid {
                        location: t.loc(row, qc[0]),
                        message: format!(
                            "the quaternion (qw, qx, qy, qz) has norm {norm:.6}; a unit quaternion is expected \
                             (scalar first, Hamilton)"
                        ),
                    });
                }
                RobotReading::Flange(Isometry3::from_parts(
                    Translation3::from(Vector3::new(p[0], p[1], p[2])),
                    UnitQuaternion::from_quaternion(quat),
                ))
            }
            None => RobotReading::Joints(
                joints.iter().map(|&(c, u)| t.number(row, c).map(|v| u.to_si(v))).collect::<Result<_>>()?,
            ),
        };
        rows.push(PoseRow { image: name, line: row.line, split, robot });
    }
    if rows.is_empty() {
        return Err(DatasetError::Invalid { location: Location::line(file, t.header_line), message: "no rows".into() });
    }
    check_units(&t, &rows, &position, &joints)?;
    let source = text.lines().find_map(|l| l.strip_prefix("# source:").map(|s| s.trim().to_string()));
    Ok(PosesTable { file: file.to_path_buf(), rows, joint_units: joints.iter().map(|j| j.1).collect(), source })
}

/// Refuses values that cannot be in the unit their header names, naming the column and the
/// likely unit: flange positions in metres under `_mm` (every coordinate within 10 mm: no
/// hand-eye recording moves the flange so little), millimetres under `_m` (a flange 100 m or
/// more from the base), joints in radians under `_deg` (every reading within 2 pi degrees while
/// they vary) and degrees under `_rad` (a reading beyond 4 pi, two turns). Tables of fewer than
/// [`crate::import::plausible::MIN_POSES_FOR_UNIT_CHECK`] rows are not judged.
fn check_units(
    t: &Table,
    rows: &[PoseRow],
    position: &Option<(LengthUnit, Vec<usize>, Vec<usize>)>,
    joints: &[(usize, JointUnit)],
) -> Result<()> {
    if rows.len() < crate::import::plausible::MIN_POSES_FOR_UNIT_CHECK {
        return Ok(());
    }
    let bad = |col: usize, message: String| Err(DatasetError::Invalid { location: t.header_loc(col), message });
    if let Some((unit, cols, _)) = position {
        let p: Vec<f64> = rows
            .iter()
            .filter_map(|r| match &r.robot {
                RobotReading::Flange(f) => Some(f.translation.vector),
                RobotReading::Joints(_) => None,
            })
            .flat_map(|v| [v.x, v.y, v.z])
            .collect();
        let largest_m = p.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let varies = p.iter().any(|v| (v - p[0]).abs() > 1e-9);
        if *unit == LengthUnit::Mm && largest_m <= 10e-3 && varies {
            return bad(
                cols[0],
                format!(
                    "every flange position lies within +-{:.3} mm of the base: the values look like metres; if so, name the columns x_m, y_m, z_m",
                    largest_m * 1e3
                ),
            );
        }
        if *unit == LengthUnit::M && largest_m >= 100.0 {
            return bad(
                cols[0],
                format!("a flange position lies {largest_m:.1} m from the base: the values look like millimetres; if so, name the columns x_mm, y_mm, z_mm"),
            );
        }
    }
    for (j, &(col, unit)) in joints.iter().enumerate() {
        let q: Vec<f64> = rows
            .iter()
            .filter_map(|r| match &r.robot {
                RobotReading::Joints(q) => q.get(j).copied(),
                RobotReading::Flange(_) => None,
            })
            .collect();
        let largest = q.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        if unit == JointUnit::Rad && largest > 2.0 * std::f64::consts::TAU {
            return bad(
                col,
                format!(
                    "a reading of {largest:.1} rad ({:.1} turns): the values look like degrees; if so, name the column q{}_deg",
                    largest / std::f64::consts::TAU,
                    j + 1
                ),
            );
        }
    }
    // Radians under `_deg`: judged over all joint columns together (a single joint may well
    // stay within a few degrees).
    let deg_cols: Vec<usize> =
        joints.iter().enumerate().filter(|(_, j)| j.1 == JointUnit::Deg).map(|(k, _)| k).collect();
    if !deg_cols.is_empty() {
        let values: Vec<f64> = rows
            .iter()
            .filter_map(|r| match &r.robot {
                RobotReading::Joints(q) => Some(deg_cols.iter().filter_map(|&k| q.get(k).copied()).collect::<Vec<_>>()),
                RobotReading::Flange(_) => None,
            })
            .flatten()
            .collect();
        let largest_deg = values.iter().fold(0.0f64, |a, v| a.max(v.abs().to_degrees()));
        let spread = values.iter().fold(0.0f64, |a, v| a.max((v - values[0]).abs().to_degrees()));
        if largest_deg <= std::f64::consts::TAU + 1e-3 && spread > 1e-3 {
            return bad(
                joints[deg_cols[0]].0,
                format!(
                    "every joint reading in degrees stays within +-{largest_deg:.2}: the values look like radians; if so, name the columns q<i>_rad"
                ),
            );
        }
    }
    Ok(())
}

impl PosesTable {
    /// Every row's `T_base_flange`: as written, or from the joints by the model's forward
    /// kinematics. Errors name the file, the line and the joint.
    pub fn flange_poses(&self, robot: Option<&RobotModel>) -> Result<Vec<Isometry3<f64>>> {
        self.rows
            .iter()
            .map(|r| match (&r.robot, robot) {
                (RobotReading::Flange(t), _) => Ok(*t),
                (RobotReading::Joints(_), None) => Err(DatasetError::Invalid {
                    location: Location::line(&self.file, r.line),
                    message: "the table holds joint readings: give the robot model (--robot)".into(),
                }),
                (RobotReading::Joints(q), Some(m)) => {
                    if q.len() != m.dof() {
                        return Err(DatasetError::JointCount {
                            location: Location::line(&self.file, r.line),
                            message: format!(
                                "{} joint columns, the robot '{}' has {} joints",
                                q.len(),
                                m.name(),
                                m.dof()
                            ),
                        });
                    }
                    m.forward(q).map_err(|e| DatasetError::Invalid {
                        location: Location::line(&self.file, r.line),
                        message: format!("forward kinematics of the robot '{}': {e}", m.name()),
                    })
                }
            })
            .collect()
    }
}

/// The table's text for flange poses (`x_mm ... qz`, `split`), numbers written so that they
/// read back to the same `f64`.
pub fn flange_poses_to_string(rows: &[(String, Isometry3<f64>, Split)], comments: &[String]) -> String {
    let mut out = String::new();
    for c in comments {
        out.push_str(&format!("# {c}\n"));
    }
    out.push_str("image,x_mm,y_mm,z_mm,qw,qx,qy,qz,split\n");
    for (name, t, split) in rows {
        let p = t.translation.vector * 1e3;
        let q = t.rotation;
        let s = match split {
            Split::Train => "train",
            Split::Test => "test",
        };
        out.push_str(&format!("{name},{},{},{},{},{},{},{},{s}\n", p.x, p.y, p.z, q.w, q.i, q.j, q.k));
    }
    out
}

pub use crate::atomic::{write_all_atomic, write_atomic};

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<PosesTable> {
        parse_handeye_poses(text, Path::new("poses.csv"))
    }

    #[test]
    fn flange_rows_with_split_read_back() {
        let t = Isometry3::new(Vector3::new(0.71, 0.0033, 0.853), Vector3::new(0.1, 3.0, -0.2));
        let text = flange_poses_to_string(
            &[("0.png".into(), t, Split::Train), ("1.png".into(), t.inverse(), Split::Test)],
            &["source: somebody's data, CC0".into()],
        );
        let p = parse(&text).unwrap();
        assert_eq!(p.source.as_deref(), Some("somebody's data, CC0"));
        assert_eq!(p.rows.len(), 2);
        assert_eq!(p.rows[1].split, Split::Test);
        assert_eq!(p.rows[0].line, 3);
        let f = p.flange_poses(None).unwrap();
        assert!((f[0].to_homogeneous() - t.to_homogeneous()).norm() < 1e-12);
    }

    #[test]
    fn joint_rows_need_a_robot_and_the_right_count() {
        let p = parse("image,q1_deg,q2_deg,split\na.png,10,20,train\n").unwrap();
        assert_eq!(p.rows[0].robot, RobotReading::Joints(vec![10f64.to_radians(), 20f64.to_radians()]));
        let e = p.flange_poses(None).unwrap_err().to_string();
        assert!(e.contains("poses.csv: line 2") && e.contains("--robot"), "{e}");
        let ur5 = RobotModel::load("ur5").unwrap();
        let e = p.flange_poses(Some(&ur5)).unwrap_err().to_string();
        assert!(e.contains("line 2") && e.contains("2 joint columns") && e.contains("6 joints"), "{e}");
    }

    #[test]
    fn bad_cells_are_located() {
        let head = "image,x_mm,y_mm,z_mm,qw,qx,qy,qz,split\n";
        let cases = [
            (format!("{head}a.png,1,2,3,0.5,0,0,0,train\n"), "line 2, column 'qw'", "norm 0.5"),
            (format!("{head}a.png,1,2,x,1,0,0,0,train\n"), "line 2, column 'z_mm'", "not a number"),
            (format!("{head}a.png,1,2,3,1,0,0,0,maybe\n"), "line 2, column 'split'", "train or test"),
            (format!("{head}a.png,1,2,3,1,0,0,0,\na.png,1,2,3,1,0,0,0,\n"), "line 3, column 'image'", "twice"),
            ("image,x_mm,y_mm,z_mm,qw,qx,qy\n".to_string(), "column 'qz'", "missing"),
            ("image,split\na.png,train\n".to_string(), "column 'x_mm'", "missing"),
            ("image,q1_deg,q3_deg\na,1,2\n".to_string(), "column 'q3_deg'", "expected q2"),
        ];
        for (text, at, what) in cases {
            let e = parse(&text).unwrap_err().to_string();
            assert!(e.contains(at) && e.contains(what), "{text}: {e}");
        }
    }

    #[test]
    fn values_in_another_unit_than_the_header_names_are_refused_with_the_likely_unit() {
        let rows = |f: &dyn Fn(usize) -> String| (0..8).map(|k| format!("i{k}.png,{}\n", f(k))).collect::<String>();
        // Flange positions in metres under `_mm`.
        let head = "image,x_mm,y_mm,z_mm,qw,qx,qy,qz\n";
        let metres = format!("{head}{}", rows(&|k| format!("0.{}1,-0.2,0.4{k},1,0,0,0", k % 3)));
        let e = parse(&metres).unwrap_err().to_string();
        assert!(e.contains("column 'x_mm'") && e.contains("look like metres") && e.contains("x_m, y_m, z_m"), "{e}");
        // The same numbers in mm are a real recording (a flange 400 mm away).
        let mm = format!("{head}{}", rows(&|k| format!("{}1,-200,40{k},1,0,0,0", k % 3)));
        assert!(parse(&mm).is_ok());
        // Millimetres under `_m`.
        let m_head = "image,x_m,y_m,z_m,qw,qx,qy,qz\n";
        let e = parse(&format!("{m_head}{}", rows(&|k| format!("{}1,-200,40{k},1,0,0,0", k % 3)))).unwrap_err();
        assert!(e.to_string().contains("look like millimetres"), "{e}");
        // Radians under `_deg`: every joint within 2 pi degrees while they move.
        let q_head = "image,q1_deg,q2_deg,q3_deg\n";
        let e = parse(&format!("{q_head}{}", rows(&|k| format!("0.{k},-1.2,2.{k}")))).unwrap_err().to_string();
        assert!(e.contains("column 'q1_deg'") && e.contains("look like radians"), "{e}");
        assert!(parse(&format!("{q_head}{}", rows(&|k| format!("{k}0,-72,12{k}")))).is_ok());
        // Degrees under `_rad`: a reading of more than two turns.
        let r_head = "image,q1_rad,q2_rad,q3_rad\n";
        let e = parse(&format!("{r_head}{}", rows(&|k| format!("0.{k},-1.2,9{k}")))).unwrap_err().to_string();
        assert!(e.contains("column 'q3_rad'") && e.contains("look like degrees") && e.contains("q3_deg"), "{e}");
        // Too few rows to judge.
        let few = "image,x_mm,y_mm,z_mm,qw,qx,qy,qz\na,0.1,0.2,0.3,1,0,0,0\nb,0.2,0.1,0.3,1,0,0,0\n";
        assert!(parse(few).is_ok());
    }
}
