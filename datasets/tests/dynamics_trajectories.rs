//! Dynamic identification from simulated trajectories: frequency- against time-domain
//! processing, the hexapod's rigid-body and friction parameters, payload steps, noise
//! covariances from repeated periods, and streams that do not fit together.

use ferrocal_calib::design::criteria::Criterion;
use ferrocal_calib::dynamics::identify::identify_from_streams;
use ferrocal_calib::dynamics::signals::{period_statistics, SampledSignal};
use ferrocal_calib::dynamics::{Differentiation, NoiseModel};
use ferrocal_datasets::dynsim::study::{
    excitation_for, filtering_study, hexapod_study, ml_study, payload_study, record_hexapod, DynamicSetup,
};
use ferrocal_datasets::dynsim::{HexapodSim, PlatformSim, Sampling};
use ferrocal_robot::dynamics::HexapodDynamics;
use nalgebra::DMatrix;
use rand::SeedableRng;

fn setup() -> DynamicSetup {
    DynamicSetup { max_evaluations: 300, ..DynamicSetup::default() }
}

#[test]
fn frequency_domain_processing_predicts_a_validation_trajectory_better() {
    let sim = HexapodSim::preset();
    let f = filtering_study(&sim, &setup(), 5).unwrap();
    let (fd, td) = (&f.rows[0], &f.rows[1]);
    assert!(fd.label.starts_with("frequency") && td.label.starts_with("time"));
    assert!(fd.validation_rms_n < td.validation_rms_n, "{} vs {}", fd.validation_rms_n, td.validation_rms_n);
    // The frequency domain reaches the noise floor (within 2 %), and its accelerations are far
    // more accurate.
    assert!(fd.validation_rms_n < 1.02 * f.noise_floor_n, "{} vs floor {}", fd.validation_rms_n, f.noise_floor_n);
    assert!(fd.acceleration_rms_m_s2 * 10.0 < td.acceleration_rms_m_s2);
}

#[test]
fn hexapod_rigid_body_and_friction_parameters_from_actuator_forces() {
    let sim = HexapodSim::preset();
    let h = hexapod_study(&sim, &setup(), 5).unwrap();
    assert_eq!(h.names.len(), 24);
    assert_eq!(h.names, HexapodDynamics::parameter_names());
    let mut worst: (f64, &str) = (0.0, "");
    for i in 0..24 {
        let z = (h.fit.values[i] - h.truth[i]).abs() / h.fit.std[i];
        if z > worst.0 {
            worst = (z, &h.names[i]);
        }
    }
    assert!(worst.0 < 4.5, "worst parameter {} at {:.1} sigma", worst.1, worst.0);
    assert!((h.fit.values[0] - h.truth[0]).abs() < 0.01 * h.truth[0], "mass {}", h.fit.values[0]);
    for i in 10..22 {
        assert!((h.fit.values[i] - h.truth[i]).abs() < 0.05 * h.truth[i], "{} {}", h.names[i], h.fit.values[i]);
    }
}

#[test]
fn payload_steps_are_reidentified_within_one_percent() {
    let sim = PlatformSim::preset();
    let rows = payload_study(&sim, 5, 19.93, 480, 200, &setup(), 11).unwrap();
    assert_eq!(rows.len(), 6);
    assert!((rows[5].payload_kg - 99.65).abs() < 1e-9);
    for r in &rows {
        let total = sim.body.mass_kg + r.payload_kg;
        for (what, m) in [("quasi-static", r.static_mass_kg), ("dynamic", r.dynamic_mass_kg)] {
            assert!((m - total).abs() < 0.01 * total, "{what}: {m} for {total} kg");
        }
        if r.payload_kg > 0.0 {
            for (what, p) in [("quasi-static", r.static_payload_kg), ("dynamic", r.dynamic_payload_kg)] {
                assert!((p - r.payload_kg).abs() < 0.01 * r.payload_kg, "{what} payload: {p} for {}", r.payload_kg);
            }
        }
    }
}

#[test]
fn noise_covariance_from_repeated_periods_matches_the_simulated_one() {
    let sim = HexapodSim::preset();
    let s = DynamicSetup { periods: 6, ..setup() };
    let dynm = HexapodDynamics::new(&sim.hexapod).unwrap();
    let traj = excitation_for(&dynm, &sim.hexapod, &s, Criterion::D, 3.0).unwrap();
    let rec = record_hexapod(&sim, &traj, &s, 3).unwrap();
    let st = period_statistics("actuator forces", &rec.forces.values, s.samples_per_period()).unwrap();
    let truth = sim.noise.covariance();
    // 800 samples x 5 degrees of freedom per entry: a few percent.
    for i in 0..6 {
        for j in 0..6 {
            assert!((st.covariance[(i, j)] - truth[(i, j)]).abs() < 0.08 * truth[(i, i)], "({i}, {j})");
        }
    }
    // Gauss-Markov with that covariance.
    let f = identify_from_streams(
        &sim.hexapod,
        &dynm,
        &rec.legs,
        &rec.forces,
        &Differentiation::Frequency { cutoff_hz: s.cutoff_hz },
        &NoiseModel::Periods { samples_per_period: s.samples_per_period() },
    )
    .unwrap();
    assert!((f.fit.s0 - 1.0).abs() < 0.05, "s0 {}", f.fit.s0);
}

#[test]
fn unsynchronised_or_differently_sampled_streams_are_refused() {
    let sim = HexapodSim::preset();
    let s = setup();
    let dynm = HexapodDynamics::new(&sim.hexapod).unwrap();
    let traj = excitation_for(&dynm, &sim.hexapod, &s, Criterion::D, 3.0).unwrap();
    let d = Differentiation::Frequency { cutoff_hz: s.cutoff_hz };
    let noise = NoiseModel::Unit;
    let record = |sampling: Sampling| {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        sim.record(&|t| traj.eval(t), &sampling, &mut rng).unwrap()
    };
    let n = s.samples_per_period() * 2;
    let delayed = record(Sampling { force_delay_s: 0.013, ..Sampling::synchronous(s.rate_hz, n) });
    let e =
        identify_from_streams(&sim.hexapod, &dynm, &delayed.legs, &delayed.forces, &d, &noise).unwrap_err().to_string();
    assert!(e.contains("not synchronised") && e.contains("leg positions") && e.contains("actuator forces"), "{e}");
    let other_rate = record(Sampling { force_rate_hz: Some(250.0), ..Sampling::synchronous(s.rate_hz, n) });
    let e = identify_from_streams(&sim.hexapod, &dynm, &other_rate.legs, &other_rate.forces, &d, &noise)
        .unwrap_err()
        .to_string();
    assert!(e.contains("250.000000 Hz") && e.contains("200.000000 Hz") && e.contains("one sample clock"), "{e}");
    // Different lengths.
    let ok = record(Sampling::synchronous(s.rate_hz, n));
    let short = SampledSignal::uniform("actuator forces", 0.0, s.rate_hz, ok.forces.values.rows(0, n - 5).into_owned())
        .unwrap();
    let e = identify_from_streams(&sim.hexapod, &dynm, &ok.legs, &short, &d, &noise).unwrap_err().to_string();
    assert!(e.contains("do not cover the same time"), "{e}");
    // Time stamps off a uniform grid.
    let mut t: Vec<f64> = (0..100).map(|k| k as f64 / 200.0).collect();
    t[40] += 0.003;
    let e = SampledSignal::from_timestamps("sensor forces", &t, DMatrix::zeros(100, 6)).unwrap_err().to_string();
    assert!(e.contains("sample 41") && e.contains("off the uniform"), "{e}");
}

/// The maximum-likelihood estimate with the cutoff as its one extra parameter: with noisy leg
/// readings (50 um) the cutoff lands above the excitation's highest harmonic and well below the
/// Nyquist frequency, and the estimate at it is the Gauss-Markov one.
#[test]
fn maximum_likelihood_cutoff_with_noisy_leg_readings() {
    let m = ml_study(&HexapodSim::preset(), &setup(), 5e-5, 9).unwrap();
    assert!(m.cutoff_hz > m.highest_harmonic_hz && m.cutoff_hz < 20.0, "cutoff {} Hz", m.cutoff_hz);
    assert!(m.curve.iter().all(|(f, _)| *f <= 40.0 + 0.5), "searched beyond the range");
    assert!((m.mass_kg - 45.0).abs() < 0.01 * 45.0, "mass {}", m.mass_kg);
}
