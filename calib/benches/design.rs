//! Pose selection on a pool of 480 Gantry-Tau L1 poses (21 parameters, 3 rows per pose): greedy
//! deletion down to 30 poses (the source's 480 -> 30 reduction; target: well under a second),
//! and the full selection (deletion to the rank limit plus exchange refinement).

use criterion::{criterion_group, criterion_main, Criterion as Bench};
use ferrocal_calib::design::criteria::Criterion;
use ferrocal_calib::design::pool::InformationPool;
use ferrocal_calib::design::selection::{greedy_deletion, select, SelectionSettings};
use ferrocal_calib::kinematic::{design_jacobian, KinematicOptions, ModelParams};
use ferrocal_robot::{Kinematics, RobotModel};
use nalgebra::Isometry3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn l1_pool() -> InformationPool {
    let model = RobotModel::load("gantry-tau-l1").unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut poses = Vec::new();
    while poses.len() < 480 {
        let q: Vec<f64> = (0..3).map(|_| rng.random_range(-0.8..0.8)).collect();
        if model.forward(&q).is_ok() {
            poses.push(q);
        }
    }
    let opts = KinematicOptions {
        model_params: ModelParams::All,
        estimate_device_frame: false,
        fixed_device_frame: Some(Isometry3::identity()),
        joint_offsets: false,
        estimate_tool: false,
        ..KinematicOptions::default()
    };
    let (j, names) = design_jacobian(&model, &poses, 50e-6, false, &opts).unwrap();
    InformationPool::from_grouped_rows(&j, 3, names).unwrap()
}

fn bench(c: &mut Bench) {
    let pool = l1_pool();
    let all: Vec<usize> = (0..pool.len()).collect();
    let mut g = c.benchmark_group("design");
    g.sample_size(10);
    for crit in [Criterion::D, Criterion::A, Criterion::K] {
        g.bench_function(format!("greedy_480_to_30_{}", crit.name()), |b| {
            b.iter(|| greedy_deletion(&pool, &all, 30, crit, 8).unwrap())
        });
    }
    g.bench_function("select_30_of_480_D_with_exchange", |b| {
        b.iter(|| select(&pool, &all, 30, &SelectionSettings::default()).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
