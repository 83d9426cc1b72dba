//! Dynamics identification speed: the force-sensor model 9 (20 parameters) from 20,000 samples
//! (5 periods of a 4 s Fourier excitation at 1 kHz), from motion states and from the raw leg and
//! force streams (forward kinematics, DFT processing, Gauss-Markov with the period covariance);
//! and the optimisation of a 3rd-order Fourier excitation for model 9 (6 DOF, 43 variables).

use criterion::{criterion_group, criterion_main, Criterion as Bench};
use ferrocal_calib::design::criteria::Criterion;
use ferrocal_calib::design::excitation::ExcitationSettings;
use ferrocal_calib::dynamics::design::{optimise_trajectory, reference_scale};
use ferrocal_calib::dynamics::force_sensor::{SensorModel, SensorRegressor};
use ferrocal_calib::dynamics::identify::{identify, identify_from_streams};
use ferrocal_calib::dynamics::{Differentiation, NoiseModel, SensorRows};
use ferrocal_datasets::dynsim::study::{excitation_for, home_coordinates, record_platform, DynamicSetup};
use ferrocal_datasets::dynsim::PlatformSim;

fn bench(c: &mut Bench) {
    let sim = PlatformSim::preset();
    let reg = SensorRegressor::new(sim.sensors.clone(), sim.deformation.reference_xy_m).unwrap();
    let rows = SensorRows { regressor: &reg, model: SensorModel::new(9).unwrap() };
    let setup = DynamicSetup { periods: 5, rate_hz: 1000.0, max_evaluations: 300, ..DynamicSetup::default() };
    let traj = excitation_for(&rows, &sim.hexapod, &setup, Criterion::D, sim.noise.sigma_n).unwrap();
    let rec = record_platform(&sim, &traj, &setup, 1).unwrap();
    assert_eq!(rec.legs.len(), 20_000);
    let d = Differentiation::Frequency { cutoff_hz: setup.cutoff_hz };
    let noise = NoiseModel::Periods { samples_per_period: setup.samples_per_period() };
    let mut g = c.benchmark_group("dynamics");
    g.sample_size(10);
    g.bench_function("model9_20000_samples_from_states", |b| {
        b.iter(|| identify(&rows, &rec.true_states, &rec.forces.values, &noise).unwrap())
    });
    g.bench_function("model9_20000_samples_from_streams", |b| {
        b.iter(|| identify_from_streams(&sim.hexapod, &rows, &rec.legs, &rec.forces, &d, &noise).unwrap())
    });
    let home = home_coordinates(&sim.hexapod.home);
    let bounds = setup.limits.bounds(&home);
    let scale = reference_scale(&rows, &bounds).unwrap();
    let settings = ExcitationSettings { harmonics: 3, period_s: 4.0, samples: 100, ..ExcitationSettings::default() };
    g.bench_function("optimise_3rd_order_excitation_model9", |b| {
        b.iter(|| optimise_trajectory(&rows, &sim.hexapod, &bounds, &settings, &scale, sim.noise.sigma_n).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
