//! The UR5 laser-tracker grid (data: P. Jacobi, MSc thesis, Tsinghua University 2025, MIT licence).

use ferrocal_calib::MeasurementSet;
use ferrocal_datasets::import::{import_ur5_grid, read_measurements, read_ur5_grid, write_measurements, WriteOptions};
use ferrocal_robot::Kinematics;
use nalgebra::{Isometry3, Vector3};

const UR5: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/ur5_tracker/ur5_grid_train.csv");

/// The cells of 1-based line `line` of the raw file, parsed independently of the importer.
fn raw_line(line: usize) -> Vec<f64> {
    let text = std::fs::read_to_string(UR5).unwrap_or_else(|e| panic!("{UR5}: {e}"));
    let l = text.lines().nth(line - 1).unwrap();
    l.split(',').map(|c| c.trim().parse::<f64>().unwrap()).collect()
}

#[test]
fn reads_all_1000_rows() {
    let grid = read_ur5_grid(UR5).unwrap();
    assert_eq!(grid.rows.len(), 1000);
    assert!(grid.rows.iter().enumerate().all(|(i, r)| r.step_order == i as u64 && r.line == i as u64 + 2));
    let set = grid.to_measurement_set();
    assert_eq!(set.rows.len(), 1000);
    assert_eq!(set.n_joints(), 6);
    assert!(!set.has_orientation());
}

#[test]
fn spot_checks_first_middle_last_rows_against_the_file_text() {
    let grid = read_ur5_grid(UR5).unwrap();
    let set = grid.to_measurement_set();
    // Data row i is on line i + 2 (header on line 1).
    for i in [0usize, 500, 999] {
        let raw = raw_line(i + 2);
        let r = &grid.rows[i];
        assert_eq!(r.step_order as f64, raw[0]);
        assert_eq!(r.target_mm, Vector3::new(raw[1], raw[2], raw[3]));
        assert_eq!(r.dif_mm, Vector3::new(raw[4], raw[5], raw[6]));
        assert_eq!(r.joints_deg.to_vec(), raw[7..13].to_vec());
        let m = &set.rows[i];
        assert_eq!(m.pose_id, format!("{i}"));
        assert_eq!(m.source_line, Some(i as u64 + 2));
        for k in 0..3 {
            // measured = target + dif, mm -> m
            assert_eq!(m.position_m[k], (raw[1 + k] + raw[4 + k]) / 1000.0);
        }
        for j in 0..6 {
            assert_eq!(m.q[j], raw[7 + j].to_radians());
        }
    }
    // Literal values of the first and last rows as published.
    let r0 = &grid.rows[0];
    assert_eq!(r0.target_mm.x, -430.32784075885013);
    assert_eq!(r0.dif_mm.z, 0.8144149428075877);
    assert_eq!(r0.joints_deg[0], -22.933297010882566);
    let r999 = &grid.rows[999];
    assert_eq!(r999.step_order, 999);
    assert_eq!(r999.target_mm.z, -107.12873485530581);
    assert_eq!(r999.joints_deg[5], 2.482360161206326);
    let r500 = &grid.rows[500];
    assert_eq!(r500.target_mm.y, -262.94288707090203);
    assert_eq!(r500.joints_deg[2], 135.44679877909277);
}

#[test]
fn targets_are_nominal_ur5_kinematics_of_the_joints() {
    // The folder README: target = standard UR5 DH forward kinematics plus a tool offset of about
    // (0, 0.09, 31.0) mm in the flange frame, to within 0.05 mm.
    let grid = read_ur5_grid(UR5).unwrap();
    let mut chain = ferrocal_robot::presets::ur5();
    chain.tool = Isometry3::translation(0.0, 0.09e-3, 31.0e-3);
    let mut max_mm: f64 = 0.0;
    for r in &grid.rows {
        let p = chain.forward(&r.q_rad()).unwrap().translation.vector * 1000.0;
        max_mm = max_mm.max((p - r.target_mm).norm());
    }
    println!("UR5 targets vs nominal FK + tool: max {max_mm:.4} mm");
    assert!(max_mm < 0.05, "max {max_mm} mm");
}

#[test]
fn exports_to_the_measurement_csv_and_reads_back() {
    let set: MeasurementSet = import_ur5_grid(UR5).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("ur5.csv");
    write_measurements(&p, &set, &WriteOptions::revolute(6)).unwrap();
    let back = read_measurements(&p).unwrap();
    assert_eq!(back.set.rows.len(), 1000);
    for (a, b) in set.rows.iter().zip(&back.set.rows) {
        assert_eq!((&a.pose_id, &a.q, &a.position_m), (&b.pose_id, &b.q, &b.position_m));
    }
}
