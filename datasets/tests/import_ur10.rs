//! The UR10 laser-tracker series A and B (data: C. Landgraf et al., "A Hybrid Neural Network
//! Approach for Increasing the Absolute Accuracy of Industrial Robots", IEEE CASE 2021;
//! christianlandgraf/ipa-robot-accuracy, MIT licence).

use std::f64::consts::{FRAC_PI_2, PI};

use ferrocal_datasets::error::DatasetError;
use ferrocal_datasets::import::{
    extrinsic_xyz_from_quat, intrinsic_xyz_from_quat, quat_from_extrinsic_xyz, quat_from_intrinsic_xyz,
    read_measurements, read_tmac_flange_transform, read_ur10_handeye, read_ur10_measurements, register_positions,
    register_with_offset, write_measurements, Ur10Recording, WriteOptions,
};
use ferrocal_robot::Kinematics;
use nalgebra::{Isometry3, Matrix4, Rotation3, UnitQuaternion, Vector3};

const A_DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/ur10_tracker/Series_A");
const B_DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/ur10_tracker/Series_B");

fn series_a() -> Ur10Recording {
    read_ur10_measurements(format!("{A_DIR}/measurements_grid.csv")).unwrap()
}

fn series_b() -> Ur10Recording {
    read_ur10_measurements(format!("{B_DIR}/measurements_joint_configurations.csv")).unwrap()
}

/// Header names and the cells of 1-based line `line`, split and converted independently of the
/// importer (`;` separator, decimal comma).
fn raw_line(path: &str, line: usize) -> (Vec<String>, Vec<String>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(';').map(String::from).collect();
    let cells = text.lines().nth(line - 1).unwrap().split(';').map(String::from).collect();
    (header, cells)
}

fn num(cell: &str) -> f64 {
    cell.replace(',', ".").parse().unwrap()
}

/// Checks every typed field of `rec.rows[i]` against the file text of its line.
fn check_row_against_text(rec: &Ur10Recording, path: &str, i: usize) {
    let r = &rec.rows[i];
    let line = i + 2; // header on line 1, no comment lines
    assert_eq!(r.line, line as u64);
    let (h, c) = raw_line(path, line);
    let get = |name: &str| num(&c[h.iter().position(|x| x == name).unwrap()]);
    assert_eq!(r.timestamp.text, c[0]);
    assert_eq!(r.goal_position_m, Vector3::new(get("Goal x"), get("Goal y"), get("Goal z")));
    assert_eq!(r.goal_rpy_rad, [get("Goal roll"), get("Goal pitch"), get("Goal yaw")]);
    let joints =
        ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"];
    assert_eq!(r.q_rad, joints.map(get));
    assert_eq!(r.temperature_c, get("measurement_temperature"));
    assert_eq!(r.position_mm, Vector3::new(get("measurement_x"), get("measurement_y"), get("measurement_z")));
    assert_eq!(r.euler_xyz_deg, [get("measurement_rx"), get("measurement_ry"), get("measurement_rz")]);
    if let Some(s) = &r.std {
        assert_eq!(
            s.position_mm,
            Vector3::new(get("measurement_std_x"), get("measurement_std_y"), get("measurement_std_z"))
        );
        assert_eq!(s.euler_deg, [get("measurement_std_rx"), get("measurement_std_ry"), get("measurement_std_rz")]);
    }
}

#[test]
#[allow(clippy::approx_constant)] // the file's own rounded values of pi/2
fn row_counts() {
    // Series A: the folder README says 11,910 grid poses; the published file holds 11,911 data
    // rows (11,912 lines with the header). The first row is the start pose (joints
    // -90, -90, 0, -90, 0, 0 deg), not a grid point; the importer keeps every row.
    let a = series_a();
    assert_eq!(a.rows.len(), 11_911);
    // The first row is the start pose; the other 11,910 are the grid the publication counts.
    assert_eq!(a.grid_rows().len(), 11_910);
    assert_eq!(a.rows[0].q_rad, [-1.5708, -1.5708, 0.0, -1.5708, 0.0, 0.0]);
    let b = series_b();
    assert_eq!(b.rows.len(), 1_495);
    assert!(a.rows.iter().all(|r| r.std.is_none()));
    assert!(b.rows.iter().all(|r| r.std.is_some()));
    assert_eq!(read_ur10_handeye(format!("{B_DIR}/calibration_handeye.csv")).unwrap().len(), 25);
}

#[test]
fn spot_checks_series_a_against_the_file_text() {
    let a = series_a();
    let path = format!("{A_DIR}/measurements_grid.csv");
    let n = a.rows.len();
    for i in [0, 1, n / 2, 1358, n - 1] {
        check_row_against_text(&a, &path, i);
    }
    // Literal values as published.
    let first = &a.rows[0];
    assert_eq!(first.timestamp.text, "20200714163904");
    assert_eq!(first.goal_position_m, Vector3::new(0.365141, -0.000212669, 1.4273));
    assert_eq!(first.temperature_c, 23.6800003051758);
    assert_eq!(first.position_mm, Vector3::new(2361.9831, -1368.5474, 119.39713));
    assert_eq!(first.euler_xyz_deg, [-90.409151, -59.885105, -90.887438]);
    let last = &a.rows[n - 1];
    assert_eq!(last.line, 11_912);
    assert_eq!(last.timestamp.text, "20200715050127");
    assert_eq!(last.q_rad, [-3.01086, -1.5202, -2.08208, 0.46137, 1.43858, -0.000155274]);
    assert_eq!(last.position_mm, Vector3::new(2129.2415, -1105.3145, -706.67066));
    assert_eq!(last.euler_xyz_deg[2], -90.793449);
    // A middle row with long decimal expansions (line 1360).
    let mid = &a.rows[1358];
    assert_eq!(mid.timestamp.text, "20200714213820");
    assert_eq!(mid.q_rad[4], 0.5377529999999999);
    assert_eq!(mid.goal_rpy_rad[1], 1.39626);
}

#[test]
#[allow(clippy::approx_constant)] // the file's own rounded values of pi and pi/2
fn spot_checks_series_b_against_the_file_text() {
    let b = series_b();
    let path = format!("{B_DIR}/measurements_joint_configurations.csv");
    let n = b.rows.len();
    for i in [0, n / 2, n - 1] {
        check_row_against_text(&b, &path, i);
    }
    let first = &b.rows[0];
    assert_eq!(first.q_rad, [-3.14159, -1.5708, 0.0, -1.5708, 0.0, 0.0]);
    assert_eq!(first.temperature_c, 21.86750031);
    assert_eq!(first.position_mm, Vector3::new(383.76294, -3240.8734, 201.93157));
    let s = first.std.as_ref().unwrap();
    assert_eq!(s.position_mm, Vector3::new(0.031674, 0.013252, 0.0037622));
    assert_eq!(s.euler_deg, [0.0011832, 0.0013871, 0.0041345]);
    let last = &b.rows[n - 1];
    assert_eq!(last.line, 1_496);
    assert_eq!(last.position_mm, Vector3::new(609.42389, -2695.7813, -23.878262));
    assert_eq!(last.euler_xyz_deg, [-90.078324, -9.9970223, -90.210511]);
    // Series B's time stamps were rounded by a spreadsheet: no usable time.
    assert_eq!(first.timestamp.text, "2,02011E+13");
    assert!(b.rows.iter().all(|r| r.timestamp.civil_s.is_none()));
}

#[test]
fn measurement_sets_of_both_series() {
    let a = series_a();
    let set = a.to_measurement_set();
    assert_eq!(set.rows.len(), 11_911);
    assert!(set.has_orientation());
    let r0 = &set.rows[0];
    assert_eq!(r0.pose_id, "0");
    assert_eq!(r0.position_m, Vector3::new(2361.9831, -1368.5474, 119.39713) / 1000.0);
    assert_eq!(r0.temp_c, Some(23.6800003051758));
    assert_eq!(r0.t_s, Some(0.0));
    assert_eq!(r0.meta["timestamp"], "20200714163904");
    let o = quat_from_intrinsic_xyz(
        (-90.409151f64).to_radians(),
        (-59.885105f64).to_radians(),
        (-90.887438f64).to_radians(),
    );
    assert_eq!(r0.orientation, Some(o));
    // 16:39:04 -> 16:39:24
    assert_eq!(set.rows[1].t_s, Some(20.0));
    // 2020-07-14 16:39:04 -> 2020-07-15 05:01:27
    assert_eq!(set.rows.last().unwrap().t_s, Some((12 * 3600 + 22 * 60 + 23) as f64));
    // 2020-07-18 21:27:57, the latest stamp (line 11903)
    assert_eq!(set.rows[11_901].t_s, Some((4 * 86_400 + 4 * 3600 + 48 * 60 + 53) as f64));
    assert!(set.rows.iter().all(|r| r.t_s.unwrap() >= 0.0 && r.sigma_m.is_none()));

    let b = series_b().to_measurement_set();
    assert_eq!(b.rows.len(), 1_495);
    assert!(b.rows.iter().all(|r| r.t_s.is_none()));
    let s = ((0.031674f64.powi(2) + 0.013252f64.powi(2) + 0.0037622f64.powi(2)) / 3.0).sqrt() / 1000.0;
    assert!((b.rows[0].sigma_m.unwrap() - s).abs() < 1e-18);
    assert!(b.rows[0].sigma_rad.unwrap() > 0.0);
}

/// Distance between two rotations that stays accurate near zero (unlike an angle from acos).
fn dist(p: &UnitQuaternion<f64>, q: &UnitQuaternion<f64>) -> f64 {
    (p.coords - q.coords).norm().min((p.coords + q.coords).norm())
}

fn rot(axis: Vector3<f64>, angle: f64) -> Rotation3<f64> {
    Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle)
}

#[test]
fn euler_conventions_agree_with_each_other_on_constructed_rotations() {
    let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
    let angles = [-3.0, -2.0, -1.2, -0.4, 0.0, 0.3, 1.1, 1.9, 2.9];
    let pitches = [-1.5, -1.0, -0.3, 0.0, 0.2, 0.8, 1.4];
    for &a in &angles {
        for &b in &pitches {
            for &c in &angles {
                // Extrinsic x-y-z (roll a, pitch b, yaw c): R = Rz(c) Ry(b) Rx(a).
                let ext = quat_from_extrinsic_xyz(a, b, c);
                let m_ext = rot(z, c) * rot(y, b) * rot(x, a);
                assert!(dist(&ext, &UnitQuaternion::from_rotation_matrix(&m_ext)) < 1e-12);
                // nalgebra's roll-pitch-yaw is the same convention.
                assert!(dist(&ext, &UnitQuaternion::from_euler_angles(a, b, c)) < 1e-12);
                // Intrinsic X-Y-Z (a, b, c): R = Rx(a) Ry(b) Rz(c).
                let int = quat_from_intrinsic_xyz(a, b, c);
                let m_int = rot(x, a) * rot(y, b) * rot(z, c);
                assert!(dist(&int, &UnitQuaternion::from_rotation_matrix(&m_int)) < 1e-12);
                // The two against each other: Rz(c)Ry(b)Rx(a) = (Rx(-a)Ry(-b)Rz(-c))^-1.
                assert!(dist(&ext, &quat_from_intrinsic_xyz(-a, -b, -c).inverse()) < 1e-12);
                // Extraction inverts each conversion, and converting a rotation's extrinsic
                // angles and its intrinsic angles gives back the same rotation.
                let e = extrinsic_xyz_from_quat(&ext);
                assert!((e[0] - a).abs() < 1e-9 && (e[1] - b).abs() < 1e-9 && (e[2] - c).abs() < 1e-9, "{e:?}");
                let i = intrinsic_xyz_from_quat(&int);
                assert!((i[0] - a).abs() < 1e-9 && (i[1] - b).abs() < 1e-9 && (i[2] - c).abs() < 1e-9, "{i:?}");
                let i2 = intrinsic_xyz_from_quat(&ext);
                assert!(dist(&quat_from_intrinsic_xyz(i2[0], i2[1], i2[2]), &ext) < 1e-9);
                let e2 = extrinsic_xyz_from_quat(&int);
                assert!(dist(&quat_from_extrinsic_xyz(e2[0], e2[1], e2[2]), &int) < 1e-9);
            }
        }
    }
    // Gimbal lock (middle angle +-90 deg) still gives back the rotation.
    for b in [FRAC_PI_2, -FRAC_PI_2] {
        for (a, c) in [(0.3, -0.7), (2.0, 1.0), (-PI + 0.1, 0.5)] {
            let q = quat_from_extrinsic_xyz(a, b, c);
            let e = extrinsic_xyz_from_quat(&q);
            assert!(dist(&quat_from_extrinsic_xyz(e[0], e[1], e[2]), &q) < 1e-6, "{e:?}");
            let q = quat_from_intrinsic_xyz(a, b, c);
            let i = intrinsic_xyz_from_quat(&q);
            assert!(dist(&quat_from_intrinsic_xyz(i[0], i[1], i[2]), &q) < 1e-6, "{i:?}");
        }
    }
    // The two conventions differ: the same numbers give different rotations.
    assert!(quat_from_extrinsic_xyz(0.5, 0.4, 0.3).angle_to(&quat_from_intrinsic_xyz(0.5, 0.4, 0.3)) > 0.1);
}

/// Largest difference between the rotation angle from row 0 to row i of the measured T-Mac
/// orientation and of the commanded orientation. The angle of a relative rotation does not
/// depend on the (unknown) frames, so the two agree only when both Euler conventions are right.
fn relative_angle_mismatch_deg(rec: &Ur10Recording, measured: impl Fn(&[f64; 3]) -> UnitQuaternion<f64>) -> f64 {
    let r0 = &rec.rows[0];
    let m0 = measured(&r0.euler_xyz_deg);
    rec.rows
        .iter()
        .map(|r| {
            let dm = m0.angle_to(&measured(&r.euler_xyz_deg));
            let dg = r0.goal_orientation().angle_to(&r.goal_orientation());
            (dm - dg).abs().to_degrees()
        })
        .fold(0.0, f64::max)
}

#[test]
fn euler_conventions_fit_the_recordings() {
    let intrinsic = |e: &[f64; 3]| {
        let [a, b, c] = e.map(f64::to_radians);
        quat_from_intrinsic_xyz(a, b, c)
    };
    let extrinsic = |e: &[f64; 3]| {
        let [a, b, c] = e.map(f64::to_radians);
        quat_from_extrinsic_xyz(a, b, c)
    };
    for (name, rec) in [("A", series_a()), ("B", series_b())] {
        let good = relative_angle_mismatch_deg(&rec, intrinsic);
        let wrong = relative_angle_mismatch_deg(&rec, extrinsic);
        println!("series {name}: relative-rotation mismatch, tracker read as intrinsic XYZ: {good:.3} deg; as extrinsic xyz: {wrong:.3} deg");
        assert!(good < 0.5, "{good}");
        assert!(wrong > 2.0, "{wrong}");
    }
}

#[test]
fn transform_files() {
    let a = read_tmac_flange_transform(format!("{A_DIR}/Trafo_TM_F_init.txt")).unwrap();
    #[rustfmt::skip]
    let expect = Matrix4::new(
        -0.00079633, 0.99999968, -0.0, -0.0,
        -0.99999937, -0.00079633, -0.00079633, 0.08679961,
        -0.00079633, -0.00000063, 0.99999968, -108.99996544,
        0.0, 0.0, 0.0, 1.0,
    );
    assert_eq!(a.matrix_mm, expect);
    // The file is T_TM_F; its inverse puts the T-Mac 109 mm in front of the flange.
    let t = a.t_flange_tmac().translation.vector * 1000.0;
    assert!((t - Vector3::new(0.0, 0.0, 109.0)).norm() < 0.01, "{t:?}");
    let a_calib = read_tmac_flange_transform(format!("{A_DIR}/Trafo_TM_F_init_calib.txt")).unwrap();
    assert_eq!(a_calib.matrix_mm, expect);
    let b = read_tmac_flange_transform(format!("{B_DIR}/Trafo_TM_F_init.txt")).unwrap();
    assert_eq!(b.matrix_mm, expect);
    // Series B's "calib" file is a pure rotation without translation.
    let b_calib = read_tmac_flange_transform(format!("{B_DIR}/Trafo_TM_F_init_calib.txt")).unwrap();
    #[rustfmt::skip]
    let expect_b = Matrix4::new(
        0.0, 0.0, 1.0, 0.0,
        -1.0, 0.0, 0.0, 0.0,
        0.0, -1.0, 0.0, 0.0,
        0.0, 0.0, 0.0, 1.0,
    );
    assert_eq!(b_calib.matrix_mm, expect_b);
    assert_eq!(b_calib.t_tmac_flange.translation.vector, Vector3::zeros());

    // Bad transform files name file, line and field.
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("Trafo_bad.txt");
    std::fs::write(&p, "1 0 0 0\r\n0 1 0 0,5\r\n0 0 1 0\r\n0 0 0 1\r\n").unwrap();
    let e = read_tmac_flange_transform(&p).unwrap_err().to_string();
    assert!(e.contains(&format!("{}: line 2, column 'field 4'", p.display())) && e.contains("decimal comma"), "{e}");
    std::fs::write(&p, "1 0 0 0\n0 1 0 0\n0 0 1\n0 0 0 1\n").unwrap();
    let e = read_tmac_flange_transform(&p).unwrap_err().to_string();
    assert!(e.contains("line 3"), "{e}");
    std::fs::write(&p, "1 0 0 0\n0 1 0 0\n0 0 1 inf\n0 0 0 1\n").unwrap();
    let e = read_tmac_flange_transform(&p).unwrap_err().to_string();
    assert!(e.contains("line 3, column 'field 4'") && e.contains("non-finite"), "{e}");
    std::fs::write(&p, "2 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n").unwrap();
    assert!(read_tmac_flange_transform(&p).unwrap_err().to_string().contains("not a rotation"));
}

#[test]
fn reproduces_measured_positions_from_the_published_columns() {
    for (name, rec, tf, rms_limit_mm, max_limit_mm) in [
        ("A", series_a(), format!("{A_DIR}/Trafo_TM_F_init.txt"), 3.5, 12.0),
        ("B", series_b(), format!("{B_DIR}/Trafo_TM_F_init.txt"), 3.5, 6.0),
    ] {
        let file = read_tmac_flange_transform(&tf).unwrap();
        // Nominal UR10 FK of the joints, composed with T_F_TM, registered over all rows.
        let reg = rec.reproduce_positions(&file.t_flange_tmac(), |_| true).unwrap();
        let (rms, max) = reg.all_stats_m();
        // Registered over the even rows only, predicting the odd rows.
        let half = rec.reproduce_positions(&file.t_flange_tmac(), |i| i % 2 == 0).unwrap();
        let (h_rms, h_max) = half.stats_m(false).unwrap();
        // The other reading of the file (T_F_TM as written) fits far worse: the file is T_TM_F.
        let other = rec.reproduce_positions(&file.t_tmac_flange, |_| true).unwrap();
        let (o_rms, _) = other.all_stats_m();
        println!(
            "series {name}: {} rows; T-Mac position from nominal FK + T_F_TM + rigid fit: RMS {:.3} mm, max {:.3} mm; \
             held-out odd rows: RMS {:.3} mm, max {:.3} mm; file read the other way: RMS {:.3} mm",
            rec.rows.len(),
            rms * 1e3,
            max * 1e3,
            h_rms * 1e3,
            h_max * 1e3,
            o_rms * 1e3
        );
        assert!(rms * 1e3 < rms_limit_mm && max * 1e3 < max_limit_mm);
        assert!(h_rms * 1e3 < rms_limit_mm && h_max * 1e3 < max_limit_mm);
        assert!(o_rms > 8.0 * rms);

        // With the T-Mac offset identified as well (the file's 109 mm is an initial value).
        let fitted = rec.reproduce_positions_fitting_offset(&file.t_flange_tmac(), |i| i % 2 == 0).unwrap();
        let (f_rms, f_max) = fitted.registration.stats_m(false).unwrap();
        let d_mm = fitted.offset_m * 1000.0;
        println!(
            "series {name}: with the T-Mac offset fitted on the even rows ({} steps): offset {d_mm:.2?} mm; held-out odd rows: RMS {:.3} mm, max {:.3} mm",
            fitted.iterations,
            f_rms * 1e3,
            f_max * 1e3
        );
        assert!(f_rms < 0.6 * rms && f_max * 1e3 < 3.0);
        assert!(d_mm.xy().norm() < 1.0 && (d_mm.z - 93.1).abs() < 0.5, "{d_mm:?}");

        // One row reproduced explicitly: the second row (index 1), held out of the even-row fit.
        let r = &rec.rows[1];
        let mut chain = ferrocal_robot::presets::ur10();
        chain.tool = file.t_flange_tmac();
        let p_base = chain.forward(&r.q_rad).unwrap().translation.vector;
        let p_tracker_mm = (half.t_device_model * nalgebra::Point3::from(p_base)).coords * 1000.0;
        let d = (p_tracker_mm - r.position_mm).norm();
        println!(
            "series {name} line {}: predicted {p_tracker_mm:.2?} mm, measured {:.2?} mm, |d| = {d:.3} mm",
            r.line, r.position_mm
        );
        assert!(d < max_limit_mm);
        // The tracker frame is a rigid transform of the base frame: a proper rotation.
        assert!((half.t_device_model.rotation.to_rotation_matrix().matrix().determinant() - 1.0).abs() < 1e-9);
    }
}

#[test]
fn goal_columns_are_the_tmac_pose_in_the_ros_base_frame() {
    // Goal x/y/z and roll/pitch/yaw (extrinsic xyz) equal Rz(pi) * FK_DH(q) * T_F_TM: the T-Mac
    // pose in the ROS base_link frame (the DH base turned by 180 deg about z), so the Goal columns
    // and the joint columns are consistent.
    let rz = Isometry3::rotation(Vector3::z() * PI);
    for (name, rec, tf) in [
        ("A", series_a(), format!("{A_DIR}/Trafo_TM_F_init.txt")),
        ("B", series_b(), format!("{B_DIR}/Trafo_TM_F_init.txt")),
    ] {
        let t_f_tm = read_tmac_flange_transform(&tf).unwrap().t_flange_tmac();
        let chain = ferrocal_robot::presets::ur10();
        let (mut dp_max, mut da_max) = (0.0f64, 0.0f64);
        for r in &rec.rows {
            let t = rz * chain.forward(&r.q_rad).unwrap() * t_f_tm;
            dp_max = dp_max.max((t.translation.vector - r.goal_position_m).norm());
            da_max = da_max.max(t.rotation.angle_to(&r.goal_orientation()));
        }
        println!("series {name}: Goal vs Rz(pi)*FK*T_F_TM: max {:.3} mm, {:.3} deg", dp_max * 1e3, da_max.to_degrees());
        assert!(dp_max < 1e-3 && da_max.to_degrees() < 0.2);
    }
}

#[test]
fn handeye_table() {
    let path = format!("{B_DIR}/calibration_handeye.csv");
    let rows = read_ur10_handeye(&path).unwrap();
    let r0 = &rows[0];
    assert_eq!(r0.line, 2);
    assert_eq!(r0.flange_position_m, Vector3::new(0.063350018, -0.548357371, 1.248510792));
    // Quaternion columns are x y z w.
    let q = r0.flange_orientation.into_inner();
    let raw = nalgebra::Quaternion::new(0.464994502, -0.271078827, 0.60327616, -0.588518698);
    assert!((q - raw / raw.norm()).norm() < 1e-15);
    assert_eq!(r0.position_mm, Vector3::new(264.90982, -2984.9658, 0.40478541));
    assert_eq!(r0.euler_xyz_deg, [-104.11792, 5.5122913, -171.42391]);
    let last = rows.last().unwrap();
    assert_eq!(last.line, 26);
    assert_eq!(last.euler_xyz_deg, [-121.80093, 0.19293039, -179.13846]);

    // The tracker positions are the flange poses composed with a constant probe offset, up to a
    // rigid motion; the relative rotation angles of flange and T-Mac (read as intrinsic XYZ)
    // agree.
    let poses: Vec<Isometry3<f64>> = rows.iter().map(|r| r.t_base_flange()).collect();
    let meas: Vec<Vector3<f64>> = rows.iter().map(|r| r.position_m()).collect();
    let plain = register_positions(&poses.iter().map(|p| p.translation.vector).collect::<Vec<_>>(), &meas, |_| true)
        .unwrap()
        .all_stats_m();
    let reg = register_with_offset(&poses, &meas, Vector3::zeros(), |_| true).unwrap();
    let (rms, max) = reg.registration.all_stats_m();
    let d_mm = reg.offset_m * 1000.0;
    let mut da: f64 = 0.0;
    for r in &rows {
        let df = r0.flange_orientation.angle_to(&r.flange_orientation);
        let dt = r0.orientation().angle_to(&r.orientation());
        da = da.max((df - dt).abs());
    }
    println!(
        "hand-eye table: {} rows; flange origins vs tracker: RMS {:.3} mm; with a fitted probe offset {d_mm:.2?} mm: RMS {:.3} mm, max {:.3} mm; relative angles agree within {:.3} deg",
        rows.len(),
        plain.0 * 1e3,
        rms * 1e3,
        max * 1e3,
        da.to_degrees()
    );
    // The probe sits about 93 mm along the x axis of this table's flange frame (the ROS `flange`
    // link, x out of the flange), as it sits about 93 mm along z of the DH flange frame.
    assert!((d_mm.x - 93.2).abs() < 0.5 && d_mm.yz().norm() < 1.0, "{d_mm:?}");
    assert!(rms < 1.0e-3 && max < 2.0e-3 && da.to_degrees() < 0.2, "{rms} {da}");
}

#[test]
fn exports_to_the_measurement_csv_and_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    for (rec, name) in [(series_b(), "b.csv"), (series_a(), "a.csv")] {
        let set = rec.to_measurement_set();
        let p = dir.path().join(name);
        write_measurements(&p, &set, &WriteOptions::revolute(6)).unwrap();
        let back = read_measurements(&p).unwrap().set;
        assert_eq!(back.rows.len(), set.rows.len());
        for (a, b) in set.rows.iter().zip(&back.rows) {
            assert_eq!(a.pose_id, b.pose_id);
            assert_eq!(a.q, b.q);
            assert_eq!(a.position_m, b.position_m);
            assert_eq!(a.orientation, b.orientation);
            assert_eq!((a.temp_c, a.t_s, a.sigma_m), (b.temp_c, b.t_s, b.sigma_m));
        }
    }
}

const HEADER: &str = "Timestamp;Goal x;Goal y;Goal z;Goal roll;Goal pitch;Goal yaw;shoulder_pan_joint;shoulder_lift_joint;elbow_joint;wrist_1_joint;wrist_2_joint;wrist_3_joint;measurement_temperature;measurement_x;measurement_y;measurement_z;measurement_rx;measurement_ry;measurement_rz";
const ROW: &str = "20200714163904;0,365141;-0,000212669;1,4273;1,57002;1,57007;1,57073;-1,5708;-1,5708;0,0;-1,5708;0,0;0,0;23,68;2361,9831;-1368,5474;119,39713;-90,409151;-59,885105;-90,887438";

#[test]
fn bad_ur10_input_names_file_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("measurements_bad.csv");
    let check = |text: String, line: u64, column: &str, words: &str| {
        std::fs::write(&p, text).unwrap();
        let e = read_ur10_measurements(&p).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains(&format!("{}: line {line}, column '{column}'", p.display())) && msg.contains(words),
            "{msg}"
        );
        e
    };
    // A missing column.
    let header = HEADER.replace(";Goal yaw", "");
    let row = ROW.replace(";1,57073;", ";");
    let e = check(format!("{header}\r\n{row}\r\n"), 1, "Goal yaw", "required column is missing");
    assert!(matches!(e, DatasetError::MissingColumn { .. }));
    // A decimal point where the file uses a decimal comma.
    let bad = ROW.replace("2361,9831", "2361.9831");
    check(format!("{HEADER}\r\n{ROW}\r\n{bad}\r\n"), 3, "measurement_x", "decimal point");
    // Non-finite and non-numeric values.
    let bad = ROW.replace(";23,68;", ";NaN;");
    check(format!("{HEADER}\r\n{bad}\r\n"), 2, "measurement_temperature", "non-finite");
    let bad = ROW.replace(";-1368,5474;", ";;");
    check(format!("{HEADER}\r\n{bad}\r\n"), 2, "measurement_y", "missing");
    let bad = ROW.replace("20200714163904", "20201314163904");
    check(format!("{HEADER}\r\n{bad}\r\n"), 2, "Timestamp", "time stamp");
}
