//! Experiment design for the force-sensor and hexapod models: pose reduction by the N criterion
//! (Friedrich & Ihlenfeldt), D-optimal against condition-number excitation (Abdellatif &
//! Heimann), and trajectories that leave their bounds.

use ferrocal_calib::design::criteria::Criterion;
use ferrocal_calib::design::excitation::ExcitationSettings;
use ferrocal_calib::dynamics::design::{check_trajectory, optimise_trajectory, reference_scale};
use ferrocal_calib::dynamics::force_sensor::{SensorModel, SensorRegressor};
use ferrocal_calib::dynamics::SensorRows;
use ferrocal_datasets::dynsim::study::{excitation_study, home_coordinates, reduction_study, DynamicSetup};
use ferrocal_datasets::dynsim::{HexapodSim, PlatformSim, Sampling};
use rand::SeedableRng;

#[test]
fn pose_reduction_480_to_30_on_n_and_on_to_the_rank_limit() {
    let sim = PlatformSim::preset();
    let r = reduction_study(&sim, SensorModel::new(5).unwrap(), 480, 30, Criterion::N, 3).unwrap();
    assert_eq!(r.pool, 480);
    assert_eq!(r.reduction.chosen.len(), 30);
    // Deviations grow, but by less than thinning the pool uniformly would give (sqrt(16) = 4):
    // the criterion keeps the informative poses.
    let med = r.reduction.median_ratio;
    assert!(med > 1.5 && med < 4.0, "median ratio {med}");
    assert!(r.ratios.iter().all(|(_, v)| *v > 1.0), "{:?}", r.ratios);
    // Running on: 14 parameters, 6 equations per pose: the theoretical minimum is 3 poses.
    assert_eq!(r.reduction.history.minimum_count, 3);
    assert!(r.reduction.history.reached_rank_limit);
    // Actual fits on simulated data agree with the predicted growth (within a factor of 1.5).
    let (full, reduced) = r.fitted_mass_std_kg;
    let ratio = reduced / full;
    let predicted = r.ratios[0].1;
    assert!(ratio > predicted / 1.5 && ratio < predicted * 1.5, "fitted {ratio} vs predicted {predicted}");
}

#[test]
fn d_optimal_excitation_beats_the_condition_number_design() {
    let sim = HexapodSim::preset();
    let setup = DynamicSetup { max_evaluations: 1500, harmonics: 3, ..DynamicSetup::default() };
    let e = excitation_study(&sim, &setup, 8, 5).unwrap();
    assert_eq!(e.names.len(), 24);
    // Predicted deviations (mean of each fit's own) are stable with few repeats.
    assert!(e.d_better_predicted >= 16, "D better for {} of 24 (predicted)", e.d_better_predicted);
    // Monte-Carlo deviations over the repeats: noisy with 8 repeats, the majority still holds.
    assert!(e.d_better >= 13, "D better for {} of 24 (repeats)", e.d_better);
    // Both trajectories stay within their bounds.
    let home = home_coordinates(&sim.hexapod.home);
    for t in &e.trajectories {
        check_trajectory(t, &setup.limits.bounds(&home), 2000).unwrap();
    }
}

#[test]
fn a_trajectory_that_leaves_its_bounds_is_refused_with_the_coordinate_named() {
    let sim = PlatformSim::preset();
    let reg = SensorRegressor::new(sim.sensors.clone(), sim.deformation.reference_xy_m).unwrap();
    let rows = SensorRows { regressor: &reg, model: SensorModel::new(9).unwrap() };
    let home = home_coordinates(&sim.hexapod.home);
    let setup = DynamicSetup::default();
    let bounds = setup.limits.bounds(&home);
    let scale = reference_scale(&rows, &bounds).unwrap();
    let settings =
        ExcitationSettings { harmonics: 3, period_s: 4.0, samples: 60, max_evaluations: 50, ..Default::default() };
    let r = optimise_trajectory(&rows, &sim.hexapod, &bounds, &settings, &scale, 1.5).unwrap();
    check_trajectory(&r.trajectory, &bounds, 2000).unwrap();
    // Triple every velocity coefficient: the motion now leaves its bounds.
    let mut fast = r.trajectory.clone();
    for d in &mut fast.dofs {
        d.a.iter_mut().chain(d.b.iter_mut()).for_each(|c| *c *= 3.0);
    }
    let e = check_trajectory(&fast, &bounds, 2000).unwrap_err().to_string();
    assert!(e.contains("leaves its bounds") && e.contains("coordinate") && e.contains(" at t = "), "{e}");
    // The simulator refuses a motion beyond the legs' stroke, naming the leg.
    let far = |_: f64| ferrocal_calib::design::excitation::TrajectorySample {
        x: vec![home[0], home[1], home[2] + 0.3, 0.0, 0.0, 0.0],
        xd: vec![0.0; 6],
        xdd: vec![0.0; 6],
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let e = sim.record(&far, &Sampling::synchronous(100.0, 10), &mut rng).unwrap_err().to_string();
    assert!(e.contains("leg 1") && e.contains("stroke"), "{e}");
}

/// The point-to-point alternative: smooth moves between waypoints within the speed and
/// acceleration bounds, usable for the identification of model 9.
#[test]
fn point_to_point_excitation_stays_in_bounds_and_identifies_model_9() {
    use ferrocal_calib::dynamics::design::PointToPoint;
    use ferrocal_calib::dynamics::identify::identify_from_streams;
    use ferrocal_calib::dynamics::{Differentiation, NoiseModel};
    let sim = PlatformSim::preset();
    let home = home_coordinates(&sim.hexapod.home);
    let setup = DynamicSetup::default();
    let bounds = setup.limits.bounds(&home);
    let h = setup.limits.half_range;
    // Corners of the pose box, alternating signs per coordinate.
    let waypoints: Vec<[f64; 6]> = (0..8)
        .map(|k| {
            std::array::from_fn(|i| {
                home[i]
                    + 0.9 * h[i] * if (k >> (i % 3)) & 1 == 0 { 1.0 } else { -1.0 } * if i >= 3 { -1.0 } else { 1.0 }
            })
        })
        .collect();
    let ptp = PointToPoint::new(waypoints.clone(), &bounds).unwrap();
    let period = ptp.period_s();
    for k in 0..4000 {
        let s = ptp.eval(period * k as f64 / 4000.0);
        for i in 0..6 {
            assert!(s.xd[i].abs() <= bounds.velocity[i] * (1.0 + 1e-9), "speed {i}");
            assert!(s.xdd[i].abs() <= bounds.acceleration[i] * (1.0 + 1e-9), "acceleration {i}");
            assert!(s.x[i] >= bounds.position[i][0] - 1e-12 && s.x[i] <= bounds.position[i][1] + 1e-12);
        }
    }
    let reg = SensorRegressor::new(sim.sensors.clone(), sim.deformation.reference_xy_m).unwrap();
    let rows = SensorRows { regressor: &reg, model: SensorModel::new(9).unwrap() };
    let samples = (2.0 * period * 200.0) as usize;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    let rec = sim.record(&|t| ptp.eval(t), &Sampling::synchronous(200.0, samples), &mut rng).unwrap();
    let f = identify_from_streams(
        &sim.hexapod,
        &rows,
        &rec.legs,
        &rec.forces,
        &Differentiation::TimeDomain { cutoff_hz: 5.0, order: 4 },
        &NoiseModel::Known(sim.noise.covariance()),
    )
    .unwrap();
    let (m, sd) = f.fit.get("m_kg").unwrap();
    assert!((m - sim.body.mass_kg).abs() < 4.0 * sd && sd < 0.02 * sim.body.mass_kg, "{m} +- {sd}");
    // A waypoint outside the bounds is refused, naming it and the coordinate.
    let mut bad = waypoints;
    bad[2][4] = home[4] + 2.0 * h[4];
    let e = PointToPoint::new(bad, &bounds).unwrap_err().to_string();
    assert!(e.contains("waypoint 3") && e.contains("(pitch)"), "{e}");
}
