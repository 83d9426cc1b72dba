//! The measurement CSV of `shared/spec/measurements.md`: reader, writer, errors.

use std::path::{Path, PathBuf};

use ferrocal_calib::{MeasurementSet, PoseMeasurement, Split};
use ferrocal_datasets::error::DatasetError;
use ferrocal_datasets::import::{
    measurements_to_string, parse_measurements, read_measurements, write_measurements, JointUnit, LengthUnit,
    WriteOptions,
};
use ferrocal_robot::JointKind;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

fn write(dir: &tempfile::TempDir, name: &str, text: &str) -> PathBuf {
    let p = dir.path().join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Reads `text` from a temp file and returns the error message (the test fails if it parses).
fn error_of(name: &str, text: &str) -> (PathBuf, String, DatasetError) {
    let dir = tempfile::tempdir().unwrap();
    let p = write(&dir, name, text);
    let e = read_measurements(&p).expect_err("the table should be rejected");
    let msg = e.to_string();
    (p, msg, e)
}

fn assert_names(msg: &str, file: &Path, line: u64, column: &str) {
    assert!(msg.contains(&file.display().to_string()), "message does not name the file: {msg}");
    assert!(msg.contains(&format!("line {line}")), "message does not name line {line}: {msg}");
    assert!(msg.contains(&format!("column '{column}'")), "message does not name column {column}: {msg}");
}

const FULL: &str = "\
# a comment line, counted as line 1
# another one
temp_c,pose_id,q2_deg,q1_rad,q3_mm,x_mm,y_m,z_mm,qx,qy,qz,qw,t_s,payload_kg,dir1,dir2,dir3,sigma_mm,split,operator
21.5,p-1,90,0.5,250,1000.5,0.25,-3,0,0,0,2,0.0,1.5,1,-1,0,0.02,train,anna
,p-2,-45,-0.25,0,1,2,3,,,,,12.5,,,,,,test,
# a comment between rows
22,7,0,0,1.5,0,0,0,0.5,0.5,0.5,0.5,,,0,,1,,,bob
";

#[test]
fn reads_every_column_in_free_order_and_converts_to_si() {
    let t = parse_measurements(FULL, "full.csv").unwrap();
    assert_eq!(t.joint_units, vec![JointUnit::Rad, JointUnit::Deg, JointUnit::Mm]);
    assert_eq!(t.joint_kinds(), vec![JointKind::Revolute, JointKind::Revolute, JointKind::Prismatic]);
    assert_eq!(t.position_units, [LengthUnit::Mm, LengthUnit::M, LengthUnit::Mm]);
    assert_eq!(t.sigma_unit, Some(LengthUnit::Mm));
    assert_eq!(t.header_line, 3);
    let s = &t.set;
    assert_eq!(s.rows.len(), 3);
    assert_eq!(s.n_joints(), 3);

    let r = &s.rows[0];
    assert_eq!(r.pose_id, "p-1");
    assert_eq!(r.source_line, Some(4));
    assert_eq!(r.q, vec![0.5, 90f64.to_radians(), 0.25]);
    assert_eq!(r.position_m, Vector3::new(1.0005, 0.25, -0.003));
    // (0,0,0,2) normalises to the identity.
    assert_eq!(r.orientation, Some(UnitQuaternion::identity()));
    assert_eq!(r.t_s, Some(0.0));
    assert_eq!(r.temp_c, Some(21.5));
    assert_eq!(r.payload_kg, Some(1.5));
    assert_eq!(r.dir, Some(vec![1, -1, 0]));
    assert_eq!(r.sigma_m, Some(0.02 / 1000.0));
    assert_eq!(r.split, Some(Split::Train));
    assert_eq!(r.meta.get("operator").map(String::as_str), Some("anna"));

    // Empty optional cells mean "not measured".
    let r = &s.rows[1];
    assert_eq!(r.source_line, Some(5));
    assert_eq!(r.orientation, None);
    assert_eq!(r.temp_c, None);
    assert_eq!(r.payload_kg, None);
    assert_eq!(r.dir, None);
    assert_eq!(r.sigma_m, None);
    assert_eq!(r.split, Some(Split::Test));
    assert!(r.meta.is_empty());

    // Line numbers count comment lines; an integer pose_id is text; a partly given dir is 0 where empty.
    let r = &s.rows[2];
    assert_eq!(r.pose_id, "7");
    assert_eq!(r.source_line, Some(7));
    assert_eq!(r.dir, Some(vec![0, 0, 1]));
    let q = r.orientation.unwrap();
    assert!((q.into_inner() - Quaternion::new(0.5, 0.5, 0.5, 0.5)).norm() < 1e-15);
    assert_eq!(s.split(Split::Test).len(), 1);
    assert_eq!(s.split(Split::Train).len(), 2);
}

#[test]
fn joint_units_are_checked_against_a_robot_model() {
    let t = parse_measurements(FULL, "full.csv").unwrap();
    t.check_joint_kinds(&[JointKind::Revolute, JointKind::Revolute, JointKind::Prismatic]).unwrap();
    let e =
        t.check_joint_kinds(&[JointKind::Revolute, JointKind::Revolute, JointKind::Revolute]).unwrap_err().to_string();
    assert!(e.contains("full.csv: line 3, column 'q3_mm'") && e.contains("rad or deg"), "{e}");
    let e = t.check_joint_kinds(&[JointKind::Revolute; 6]).unwrap_err().to_string();
    assert!(e.contains("inconsistent joint count") && e.contains("6 joints"), "{e}");
}

#[test]
fn missing_required_column_names_file_line_and_column() {
    let (p, msg, e) = error_of("no_y.csv", "# comment\npose_id,q1_rad,x_m,z_m\n1,0,0,0\n");
    assert!(matches!(e, DatasetError::MissingColumn { .. }));
    assert_names(&msg, &p, 2, "y_m");
    assert!(msg.contains("required column is missing") && msg.contains("y_mm"), "{msg}");

    let (p, msg, _) = error_of("no_id.csv", "q1_rad,x_m,y_m,z_m\n0,0,0,0\n");
    assert_names(&msg, &p, 1, "pose_id");

    // Names are case-sensitive; the message says so.
    let (p, msg, _) = error_of("case.csv", "pose_id,q1_rad,X_mm,y_mm,z_mm\n1,0,0,0,0\n");
    assert_names(&msg, &p, 1, "x_m");
    assert!(msg.contains("case-sensitive") && msg.contains("X_mm"), "{msg}");

    // A quaternion comes complete.
    let (p, msg, _) = error_of("quat.csv", "pose_id,q1_rad,x_m,y_m,z_m,qw,qx,qy\n1,0,0,0,0,1,0,0\n");
    assert_names(&msg, &p, 1, "qz");

    // No joint columns at all.
    let (p, msg, _) = error_of("nojoints.csv", "pose_id,x_m,y_m,z_m\n1,0,0,0\n");
    assert_names(&msg, &p, 1, "q1_rad");
}

#[test]
fn decimal_comma_is_reported_explicitly() {
    // Quoted, so the comma stays inside the cell.
    let (p, msg, e) = error_of("comma_quoted.csv", "pose_id,q1_rad,x_mm,y_mm,z_mm\n# c\n1,0.5,\"12,5\",0,0\n");
    assert!(matches!(e, DatasetError::DecimalComma { .. }), "{e:?}");
    assert_names(&msg, &p, 3, "x_mm");
    assert!(msg.contains("decimal comma") && msg.contains("12,5"), "{msg}");

    // Unquoted, the comma splits the number into two cells: still recognised and located.
    let (p, msg, _) = error_of("comma_split.csv", "pose_id,q1_rad,x_mm,y_mm,z_mm\n1,0.5,1,0,0\n2,0.5,2.5,0.1,0,25\n");
    assert_names(&msg, &p, 3, "z_mm");
    assert!(msg.contains("decimal comma") && msg.contains("0,25"), "{msg}");
    let (p, msg, _) = error_of("comma_split2.csv", "pose_id,q1_deg,x_mm,y_mm,z_mm\n17,0,5,1,0,0\n");
    assert_names(&msg, &p, 2, "q1_deg");
    assert!(msg.contains("decimal comma"), "{msg}");
}

#[test]
fn non_finite_and_non_numeric_values_are_rejected() {
    for bad in ["NaN", "inf", "-infinity", "1e999"] {
        let (p, msg, e) = error_of("nonfinite.csv", &format!("pose_id,q1_rad,x_m,y_m,z_m\n1,0,0,{bad},0\n"));
        assert!(matches!(e, DatasetError::NonFinite { .. }), "{e:?}");
        assert_names(&msg, &p, 2, "y_m");
        assert!(msg.contains("non-finite") && msg.contains(bad), "{msg}");
    }
    // Optional columns too.
    let (p, msg, _) = error_of("nonfinite_t.csv", "pose_id,q1_rad,x_m,y_m,z_m,t_s\n1,0,0,0,0,nan\n");
    assert_names(&msg, &p, 2, "t_s");

    let (p, msg, e) = error_of("text.csv", "pose_id,q1_rad,q2_rad,x_m,y_m,z_m\n1,0,zero,0,0,0\n");
    assert!(matches!(e, DatasetError::NotANumber { .. }));
    assert_names(&msg, &p, 2, "q2_rad");
    assert!(msg.contains("'zero' is not a number"), "{msg}");
}

#[test]
fn missing_required_value_is_an_error_not_a_dropped_row() {
    let (p, msg, e) = error_of("empty.csv", "pose_id,q1_rad,x_m,y_m,z_m\n1,0,0,0,0\n2,,0,0,0\n");
    assert!(matches!(e, DatasetError::MissingValue { .. }));
    assert_names(&msg, &p, 3, "q1_rad");
    let (p, msg, _) = error_of("empty_id.csv", "pose_id,q1_rad,x_m,y_m,z_m\n,0,0,0,0\n");
    assert_names(&msg, &p, 2, "pose_id");
    // A short row names the first missing column.
    let (p, msg, _) = error_of("short.csv", "pose_id,q1_rad,x_m,y_m,z_m\n1,0,0,0\n");
    assert_names(&msg, &p, 2, "z_m");
}

#[test]
fn duplicate_pose_id_and_inconsistent_joints_are_rejected() {
    let (p, msg, e) = error_of("dup.csv", "pose_id,q1_rad,x_m,y_m,z_m\na,0,0,0,0\n#\nb,0,0,0,0\na,1,0,0,0\n");
    assert!(matches!(e, DatasetError::DuplicateId { first_line: 2, .. }), "{e:?}");
    assert_names(&msg, &p, 5, "pose_id");
    assert!(msg.contains("duplicate pose_id 'a'"), "{msg}");

    let (p, msg, e) = error_of("gap.csv", "pose_id,q1_rad,q3_rad,x_m,y_m,z_m\n1,0,0,0,0,0\n");
    assert!(matches!(e, DatasetError::JointCount { .. }));
    assert_names(&msg, &p, 1, "q2_<unit>");
    assert!(msg.contains("inconsistent joint count"), "{msg}");

    let (p, msg, _) = error_of("dirs.csv", "pose_id,q1_rad,q2_rad,x_m,y_m,z_m,dir1\n1,0,0,0,0,0,1\n");
    assert_names(&msg, &p, 1, "dir2");
    assert!(msg.contains("inconsistent joint count"), "{msg}");

    let (p, msg, _) = error_of("twice.csv", "pose_id,q1_rad,q1_deg,x_m,y_m,z_m\n1,0,0,0,0,0\n");
    assert_names(&msg, &p, 1, "q1_deg");
}

#[test]
fn bad_units_quaternions_and_codes_are_rejected() {
    let (p, msg, _) = error_of("unit.csv", "pose_id,q1_grad,x_m,y_m,z_m\n1,0,0,0,0\n");
    assert_names(&msg, &p, 1, "q1_grad");
    let (p, msg, _) = error_of("unit2.csv", "pose_id,q1_rad,x_cm,y_m,z_m\n1,0,0,0,0\n");
    assert_names(&msg, &p, 1, "x_cm");
    let (p, msg, _) =
        error_of("zeroquat.csv", "pose_id,q1_rad,x_m,y_m,z_m,qw,qx,qy,qz\n1,0,0,0,0,1,0,0,0\n2,0,0,0,0,0,0,0,0\n");
    assert_names(&msg, &p, 3, "qw");
    assert!(msg.contains("zero length"), "{msg}");
    let (p, msg, _) = error_of("halfquat.csv", "pose_id,q1_rad,x_m,y_m,z_m,qw,qx,qy,qz\n1,0,0,0,0,1,,0,0\n");
    assert_names(&msg, &p, 2, "qx");
    let (p, msg, _) = error_of("split.csv", "pose_id,q1_rad,x_m,y_m,z_m,split\n1,0,0,0,0,validation\n");
    assert_names(&msg, &p, 2, "split");
    let (p, msg, _) = error_of("dir.csv", "pose_id,q1_rad,x_m,y_m,z_m,dir1\n1,0,0,0,0,2\n");
    assert_names(&msg, &p, 2, "dir1");
    let (p, msg, _) = error_of("sigma.csv", "pose_id,q1_rad,x_m,y_m,z_m,sigma_m\n1,0,0,0,0,-1\n");
    assert_names(&msg, &p, 2, "sigma_m");
}

/// A set exercising every field, with values that do not survive a careless format.
fn tricky_set() -> MeasurementSet {
    let mut rows = Vec::new();
    for i in 0..50u32 {
        let f = i as f64;
        let mut r = PoseMeasurement::new(
            format!("pose {i}"),
            vec![0.1 * f - 2.0, (f * 0.7).sin(), 1.0 / 3.0 + f, -f * 1e-7],
            Vector3::new(1.0 / (f + 7.0), -2.5e-9 * f, (1234.0 + 1.0 / 7.0) / (f + 1.0)),
        );
        if i % 3 != 0 {
            r.orientation = Some(UnitQuaternion::from_euler_angles(0.3 * f, -0.2, f.sqrt()));
        }
        if i % 2 == 0 {
            r.sigma_m = Some(1e-5 * (f + 1.0) / 3.0);
            r.t_s = Some(f * 0.1);
            r.temp_c = Some(20.0 + f / 7.0);
        }
        if i % 5 == 0 {
            r.payload_kg = Some(2.0 / 3.0);
            r.dir = Some(vec![1, -1, 0, 1]);
            r.split = Some(if i % 10 == 0 { Split::Test } else { Split::Train });
        }
        rows.push(r);
    }
    rows[3].pose_id = "#hash, \"quoted\"".into();
    rows[4].q[0] = 0.0;
    rows[5].position_m.x = -0.0;
    // The largest plausible coordinate (docs/reliability.md), at full precision.
    rows[6].position_m.y = 9999.999999999998;
    MeasurementSet { source: "tricky".into(), rows }
}

/// Rows equal except the line they were read from.
fn assert_same_rows(a: &MeasurementSet, b: &MeasurementSet, tol: f64) {
    assert_eq!(a.rows.len(), b.rows.len());
    for (x, y) in a.rows.iter().zip(&b.rows) {
        assert_eq!(x.pose_id, y.pose_id);
        let close = |u: f64, v: f64| {
            if tol == 0.0 {
                u == v
            } else {
                (u - v).abs() <= tol * u.abs().max(v.abs()).max(1e-300)
            }
        };
        assert_eq!(x.q.len(), y.q.len());
        for (u, v) in x.q.iter().zip(&y.q) {
            assert!(close(*u, *v), "{}: q {u} != {v}", x.pose_id);
        }
        for k in 0..3 {
            assert!(close(x.position_m[k], y.position_m[k]), "{}: position", x.pose_id);
        }
        assert_eq!(x.orientation.is_some(), y.orientation.is_some());
        if let (Some(p), Some(q)) = (x.orientation, y.orientation) {
            if tol == 0.0 {
                assert_eq!(p, q);
            } else {
                assert!(p.angle_to(&q) < 1e-12);
            }
        }
        for (u, v) in [(x.sigma_m, y.sigma_m), (x.t_s, y.t_s), (x.temp_c, y.temp_c), (x.payload_kg, y.payload_kg)] {
            assert_eq!(u.is_some(), v.is_some());
            if let (Some(u), Some(v)) = (u, v) {
                assert!(close(u, v), "{}: {u} != {v}", x.pose_id);
            }
        }
        assert_eq!(x.dir, y.dir);
        assert_eq!(x.split, y.split);
        assert_eq!(x.meta, y.meta);
    }
}

#[test]
fn writer_round_trips_at_full_precision() {
    let set = tricky_set();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("round.csv");
    let mut opts =
        WriteOptions::si(&[JointKind::Revolute, JointKind::Revolute, JointKind::Revolute, JointKind::Prismatic]);
    opts.comments = vec!["written by the round-trip test".into()];
    write_measurements(&p, &set, &opts).unwrap();
    let back = read_measurements(&p).unwrap();
    assert_eq!(back.joint_units, vec![JointUnit::Rad, JointUnit::Rad, JointUnit::Rad, JointUnit::M]);
    // What the reader refuses (a position of 1e300 m) is not written either.
    let mut huge = set.clone();
    huge.rows[6].position_m.y = 1e300;
    assert!(measurements_to_string(&huge, &opts).unwrap_err().to_string().contains("plausible"));
    // Bit-exact with SI columns.
    assert_same_rows(&set, &back.set, 0.0);
    // The first data row is on line 3, after the comment and the header.
    assert_eq!(back.set.rows[0].source_line, Some(3));

    // Writing what was read gives the same text again.
    let again = measurements_to_string(&back.set, &opts).unwrap();
    assert_eq!(again, std::fs::read_to_string(&p).unwrap());

    // Edge units (deg, mm) round-trip to the last bits.
    let edge = WriteOptions {
        joint_units: vec![JointUnit::Deg, JointUnit::Deg, JointUnit::Deg, JointUnit::Mm],
        length_unit: LengthUnit::Mm,
        include_meta: false,
        comments: vec![],
    };
    let text = measurements_to_string(&set, &edge).unwrap();
    assert!(text.starts_with("pose_id,q1_deg,q2_deg,q3_deg,q4_mm,x_mm,y_mm,z_mm,qw,qx,qy,qz,sigma_mm,"), "{text}");
    let back = parse_measurements(&text, "edge.csv").unwrap();
    assert_same_rows(&set, &back.set, 8.0 * f64::EPSILON);
}

#[test]
fn writer_keeps_metadata_when_asked_and_rejects_what_the_reader_would() {
    let t = parse_measurements(FULL, "full.csv").unwrap();
    let mut opts = WriteOptions::si_like(&t);
    opts.include_meta = true;
    let text = measurements_to_string(&t.set, &opts).unwrap();
    let back = parse_measurements(&text, "again.csv").unwrap();
    assert_same_rows(&t.set, &back.set, 0.0);
    assert_eq!(back.set.rows[0].meta["operator"], "anna");

    let mut bad = t.set.clone();
    bad.rows[1].q.pop();
    let e = measurements_to_string(&bad, &opts).unwrap_err().to_string();
    assert!(e.contains("p-2") && e.contains("2 joint values"), "{e}");
    let mut bad = t.set.clone();
    bad.rows[1].pose_id = "p-1".into();
    assert!(measurements_to_string(&bad, &opts).unwrap_err().to_string().contains("duplicate pose_id"));
    let mut bad = t.set.clone();
    bad.rows[0].temp_c = Some(f64::NAN);
    assert!(measurements_to_string(&bad, &opts).unwrap_err().to_string().contains("non-finite"));
    let mut bad = t.set.clone();
    bad.rows[0].meta.insert("x_mm".into(), "1".into());
    assert!(measurements_to_string(&bad, &opts).is_err());
}

#[test]
fn header_only_and_missing_file() {
    let t = parse_measurements("pose_id,q1_rad,x_m,y_m,z_m\n", "h.csv").unwrap();
    assert!(t.set.rows.is_empty());
    let e = read_measurements("/nonexistent/dir/m.csv").unwrap_err().to_string();
    assert!(e.contains("/nonexistent/dir/m.csv"), "{e}");
    let e = parse_measurements("", "empty.csv").unwrap_err().to_string();
    assert!(e.contains("empty.csv: line 1") && e.contains("no header"), "{e}");
    // A semicolon file gets a hint.
    let e = parse_measurements("pose_id;q1_rad;x_m;y_m;z_m\n1;0;0;0;0\n", "semi.csv").unwrap_err().to_string();
    assert!(e.contains("separated by ';'") && e.contains("decimal point"), "{e}");
}

/// A measured pose's covariance (`cov_<a>_<b>_<unit>` columns): the 6 x 6 of a camera pose and
/// the 3 x 3 of a tracker reflector in one table round-trip in SI bit for bit and in mm to
/// rounding; an incomplete or indefinite covariance is an error at its row and column.
#[test]
fn pose_covariances_round_trip_and_bad_ones_are_located() {
    use ferrocal_calib::PoseCovariance;
    use nalgebra::{Matrix3, Matrix6};
    let a = Matrix6::from_fn(|i, j| ((i + 1) * (j + 2)) as f64 * 1e-3 + if i == j { 1.0 } else { 0.0 });
    let si6 = (a * a.transpose()).component_mul(&Matrix6::from_fn(|i, j| {
        let s = |k: usize| if k < 3 { 1e-4 } else { 1e-3 };
        s(i) * s(j)
    }));
    let m2 = Matrix3::new(4e-8, 1e-9, 0.0, 1e-9, 9e-8, -2e-9, 0.0, -2e-9, 1e-8);
    let mut cam = PoseMeasurement::new("cam", vec![0.1, 0.2], Vector3::new(0.5, 0.25, 1.0));
    cam.orientation = Some(UnitQuaternion::identity());
    cam.covariance = Some(PoseCovariance::Pose { si: si6 });
    let mut tracker = PoseMeasurement::new("tracker", vec![0.3, 0.4], Vector3::new(0.5, 0.25, 1.5));
    tracker.covariance = Some(PoseCovariance::Position { m2 });
    let plain = PoseMeasurement::new("plain", vec![0.5, 0.6], Vector3::new(0.1, 0.2, 0.3));
    let set = MeasurementSet { source: "test".into(), rows: vec![cam, tracker, plain] };
    for (unit, tol) in [(LengthUnit::M, 0.0), (LengthUnit::Mm, 1e-15)] {
        let opts = WriteOptions { length_unit: unit, ..WriteOptions::si(&[JointKind::Revolute; 2]) };
        let text = measurements_to_string(&set, &opts).unwrap();
        let header = text.lines().next().unwrap();
        assert_eq!(header.matches("cov_").count(), 21, "{header}");
        let u = unit.suffix();
        assert!(header.contains(&format!("cov_x_x_{u}2")) && header.contains(&format!("cov_z_rx_{u}_rad")));
        assert!(header.contains("cov_rz_rz_rad2"));
        let back = parse_measurements(&text, "cov.csv").unwrap().set;
        let (c0, c1) = (back.rows[0].covariance.as_ref().unwrap(), back.rows[1].covariance.as_ref().unwrap());
        let rel = |x: f64, y: f64| (x - y).abs() / y.abs().max(1e-300);
        assert!(si6.iter().zip(c0.pose().unwrap().iter()).all(|(x, y)| rel(*y, *x) <= tol), "{unit:?}");
        assert!(c1.pose().is_none(), "the tracker row stays position-only");
        assert!(m2.iter().zip(c1.position_m2().iter()).all(|(x, y)| *x == 0.0 && *y == 0.0 || rel(*y, *x) <= tol));
        assert!(back.rows[2].covariance.is_none());
    }
    // A missing entry and a negative variance.
    let text = measurements_to_string(&set, &WriteOptions::si(&[JointKind::Revolute; 2])).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let col = header.iter().position(|h| *h == "cov_x_ry_m_rad").unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let mut cells: Vec<String> = lines[1].split(',').map(String::from).collect();
    cells[col] = String::new();
    lines[1] = cells.join(",");
    let (p, msg, _) = error_of("cov_missing.csv", &(lines.join("\n") + "\n"));
    assert!(msg.contains(&p.display().to_string()) && msg.contains("line 2") && msg.contains("(x, ry)"), "{msg}");
    let col = header.iter().position(|h| *h == "cov_y_y_m2").unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let mut cells: Vec<String> = lines[2].split(',').map(String::from).collect();
    cells[col] = "-1e-8".into();
    lines[2] = cells.join(",");
    let (_, msg, _) = error_of("cov_negative.csv", &(lines.join("\n") + "\n"));
    assert!(msg.contains("line 3"), "{msg}");
    let (_, msg, _) = error_of("cov_name.csv", "pose_id,q1_rad,x_m,y_m,z_m,cov_rx_x_m_rad\np,0,0,0,0,1\n");
    assert!(msg.contains("cov_rx_x_m_rad") && msg.contains("a first"), "{msg}");
}
