//! The UR5 preset against the targets of the real UR5 recording (../shared/data/ur5_tracker):
//! nominal forward kinematics of the commanded joints plus a tool offset of about
//! (0, 0.09, 31.0) mm in the flange frame must give x_t, y_t, z_t within 0.05 mm on all rows.
//! Data: P. Jacobi, MSc thesis, Tsinghua University, 2025 (MIT licence).

use std::path::PathBuf;

use ferrocal_robot::{presets, Kinematics, Pose};

fn data_file() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/ur5_tracker/ur5_grid_train.csv")
}

#[test]
fn ur5_preset_reproduces_recorded_targets() {
    let path = data_file();
    let mut rdr = csv::Reader::from_path(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (../shared/data/ur5_tracker must be beside the checkout)", path.display()));
    let mut robot = presets::ur5();
    robot.tool = Pose::translation(0.0, 0.09e-3, 31.0e-3);
    let mut n = 0;
    let mut worst_mm: f64 = 0.0;
    for rec in rdr.records() {
        let rec = rec.unwrap();
        let v: Vec<f64> = rec.iter().map(|s| s.parse().unwrap()).collect();
        let target_mm = [v[1], v[2], v[3]];
        let q: Vec<f64> = v[7..13].iter().map(|d| d.to_radians()).collect();
        let t = robot.forward(&q).unwrap();
        let p = t.translation.vector * 1e3;
        let err = ((p.x - target_mm[0]).powi(2) + (p.y - target_mm[1]).powi(2) + (p.z - target_mm[2]).powi(2)).sqrt();
        worst_mm = worst_mm.max(err);
        n += 1;
    }
    assert_eq!(n, 1000, "the recording has 1000 rows");
    assert!(worst_mm < 0.05, "worst target mismatch {worst_mm:.4} mm (limit 0.05 mm)");
    eprintln!("UR5 preset vs recorded targets: worst {worst_mm:.5} mm over {n} rows");
}
