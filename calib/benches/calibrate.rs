//! Calibrating the UR5 on the 1000 poses of the real recording (target: under one second).
//! Data: ../shared/data/ur5_tracker (P. Jacobi, MSc thesis, Tsinghua University, 2025, MIT).

use criterion::{criterion_group, criterion_main, Criterion};
use ferrocal_calib::kinematic::{calibrate, KinematicOptions};
use ferrocal_calib::PoseMeasurement;
use ferrocal_robot::RobotModel;
use nalgebra::Vector3;

fn ur5_rows() -> Vec<PoseMeasurement> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/ur5_tracker/ur5_grid_train.csv");
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{path}: {e} (../shared/data/ur5_tracker must be beside the checkout)"));
    text.lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            let p = Vector3::new(v[1] + v[4], v[2] + v[5], v[3] + v[6]) * 1e-3;
            PoseMeasurement::new(format!("{}", v[0]), v[7..13].iter().map(|d| d.to_radians()).collect(), p)
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let rows = ur5_rows();
    let refs: Vec<&PoseMeasurement> = rows.iter().collect();
    let model = RobotModel::load("ur5").unwrap();
    let opts = KinematicOptions::default();
    let mut g = c.benchmark_group("calibrate");
    g.sample_size(10);
    g.bench_function("ur5_1000_poses", |b| b.iter(|| calibrate(&model, &refs, &opts).unwrap()));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
