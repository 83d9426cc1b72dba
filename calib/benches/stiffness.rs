//! Elastostatic identification of the KR 270-like arm (the source's 6-DOF study): building the
//! weighted problem of 45 tracker measurements (3 reflectors each) over the 260 complete
//! parameters, the model reduction M0 to M6 with a fit per step, and the final fit of the reduced
//! parameters (target: well under a second each).

use criterion::{criterion_group, criterion_main, Criterion};
use ferrocal_calib::stiffness::problem::{LinearProblem, Measured, Observation};
use ferrocal_calib::stiffness::reduce::{fit_with_fixed, fixed_vector, reduce, ReductionSettings};
use ferrocal_calib::stiffness::LoadCase;
use ferrocal_robot::stiffness::presets::kr270_like;
use ferrocal_robot::stiffness::{VjmModel, WrenchLimits};
use ferrocal_robot::Kinematics;
use nalgebra::{DVector, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

const MARKERS: [[f64; 3]; 3] = [[0.2, 0.0, 0.0], [-0.1, 0.17, 0.0], [-0.1, -0.17, 0.05]];

/// 45 measurements under 0, 150 and 270 kg: linear-model deflections of the design estimates
/// scaled by 1.2, plus 30 um noise.
fn observations(model: &VjmModel) -> Vec<Observation> {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let lim = model.chain.joint_limits();
    let truth = DVector::from_vec(model.complete_values()) * 1.2;
    let loads = [
        LoadCase::payload(0.0, [0.0; 3]),
        LoadCase::payload(150.0, [0.25, 0.0, 0.15]),
        LoadCase::payload(270.0, [0.0, 0.25, 0.3]),
    ];
    let markers: Vec<Vector3<f64>> = MARKERS.iter().map(|m| Vector3::from(*m)).collect();
    (0..45)
        .map(|k| {
            let q: Vec<f64> =
                lim.iter().map(|l| rng.random_range(0.8 * l.lower.max(-3.0)..0.8 * l.upper.min(3.0))).collect();
            let load = loads[k % 3];
            let loading = load.loading(model, &q).unwrap();
            let a = model.marker_matrix(&q, &loading, &markers).unwrap();
            let d = a * &truth;
            let dp = (0..3)
                .map(|m| {
                    std::array::from_fn(|r| {
                        let e: f64 = StandardNormal.sample(&mut rng);
                        d[3 * m + r] + 30e-6 * e
                    })
                })
                .collect();
            Observation {
                id: format!("o{k}"),
                q,
                loading,
                measured: Measured::Markers { markers_in_tool_m: MARKERS.to_vec(), dp_m: dp, sigma_m: 30e-6 },
                truth: None,
            }
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let model = kr270_like().unwrap();
    let obs = observations(&model);
    let limits = WrenchLimits::default();
    let prior = model.complete_values();
    let settings = ReductionSettings::default();
    c.bench_function("stiffness/problem_45x3_markers_260_params", |b| {
        b.iter(|| LinearProblem::from_observations(&model, &obs, &limits).unwrap())
    });
    let problem = LinearProblem::from_observations(&model, &obs, &limits).unwrap();
    c.bench_function("stiffness/reduce_m0_to_m6", |b| {
        b.iter(|| reduce(&problem, None, Some(&prior), &settings).unwrap())
    });
    let red = reduce(&problem, None, Some(&prior), &settings).unwrap();
    let fixed = fixed_vector(problem.layout.len(), &red.fixed);
    c.bench_function("stiffness/fit_reduced", |b| {
        b.iter(|| fit_with_fixed(&problem, &red.param, &fixed, settings.rank_tol).unwrap())
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
