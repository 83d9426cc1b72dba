//! Runtime of the missing-physics diagnosis on a 400-pose tracker recording of a UR5 with a
//! compliant shoulder (rows generated here with the identification side's own model: this is a
//! timing benchmark, not a check of the physics, which `ferrocal-datasets`' simulator tests).
//! Run single-threaded for the one-core figure: `taskset -c 0 cargo bench -p ferrocal-calib --bench diagnose`.

use criterion::{criterion_group, criterion_main, Criterion};
use ferrocal_calib::diagnose::{diagnose, DiagnoseOptions};
use ferrocal_calib::effects::EffectSpec;
use ferrocal_calib::kinematic::CalibratedModel;
use ferrocal_calib::PoseMeasurement;
use ferrocal_robot::{Parameterized, RobotModel};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

fn recording(n: usize, seed: u64) -> (RobotModel, Vec<PoseMeasurement>) {
    let nominal = RobotModel::load("ur5").expect("preset");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut truth = nominal.clone();
    let params = truth.parameters();
    let mut v = truth.parameter_values();
    let err = Normal::new(0.0, 3e-4).expect("normal");
    for (x, p) in v.iter_mut().zip(&params) {
        if p.name.contains(".corr_") {
            *x += err.sample(&mut rng);
        }
    }
    truth.set_parameter_values(&v).expect("true parameters");
    let cm = CalibratedModel {
        model: truth,
        device_frame: Isometry3::from_parts(
            Translation3::new(2.0, 0.5, 0.2),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 2.8),
        )
        .inverse(),
        tool: Isometry3::translation(0.0, 0.0, 0.05),
        joint_offsets: vec![1e-3, -2e-3, 1e-3, 0.0, 5e-4, 0.0],
        orientation_calibrated: false,
        effects: vec![(EffectSpec::JointCompliance { joint: 2 }, vec![5e-6])],
        load_model: nominal.clone(),
    };
    let ranges = [[-1.5, 1.5], [-2.6, -0.5], [0.3, 2.5], [-2.5, 0.0], [0.5, 2.5], [-1.0, 1.0]];
    let noise = Normal::new(0.0, 1.0).expect("normal");
    let mut prev = vec![0.0; 6];
    let rows = (0..n)
        .map(|k| {
            let q: Vec<f64> = ranges.iter().map(|r| rng.random_range(r[0]..r[1])).collect();
            let dir: Vec<i8> = q.iter().zip(&prev).map(|(a, b)| if a >= b { 1 } else { -1 }).collect();
            prev = q.clone();
            let mut row = PoseMeasurement::new(format!("{k}"), q, Vector3::zeros());
            row.dir = Some(dir);
            row.payload_kg = Some(2.0);
            row.t_s = Some(12.0 * k as f64);
            row.temp_c = Some(20.0 + 4.0 * (1.0 - (-(12.0 * k as f64) / 1500.0).exp()));
            let p = cm.predict_row(&row).expect("prediction").translation.vector;
            let sigma = 15e-6 + 6e-6 * p.norm();
            row.position_m =
                p + Vector3::new(noise.sample(&mut rng), noise.sample(&mut rng), noise.sample(&mut rng)) * sigma;
            row.sigma_m = Some(sigma);
            row
        })
        .collect();
    (nominal, rows)
}

fn bench(c: &mut Criterion) {
    let (model, rows) = recording(400, 7);
    let opts = DiagnoseOptions::default();
    let rep = diagnose(&model, &rows, &opts).expect("diagnose");
    eprintln!(
        "400 poses: findings {:?}",
        rep.findings.iter().map(|f| (f.effect.clone(), f.joints.clone())).collect::<Vec<_>>()
    );
    let mut g = c.benchmark_group("diagnose");
    g.sample_size(10);
    g.bench_function("ur5_400_poses_compliance", |b| b.iter(|| diagnose(std::hint::black_box(&model), &rows, &opts)));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
