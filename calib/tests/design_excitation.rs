//! Fourier-series excitation: analytic derivatives, bounds on a fine grid, and optimisation of
//! a linear regressor's information by the design criteria.

use ferrocal_calib::design::criteria::Criterion;
use ferrocal_calib::design::excitation::{
    check_bounds, information, optimise_excitation, ExcitationBounds, ExcitationSettings, FourierTrajectory,
    TrajectorySample,
};
use nalgebra::DMatrix;

fn sample_traj() -> FourierTrajectory {
    let mut t = FourierTrajectory::zero(2, 3, std::f64::consts::TAU / 8.0);
    t.set_coefficients(&[0.1, -0.05, 0.02, 0.03, 0.04, -0.01, 0.2, -0.08, 0.05, 0.01, 0.0, 0.06, 0.02, -0.1]).unwrap();
    t
}

#[test]
fn derivatives_are_analytic() {
    let t = sample_traj();
    let h = 1e-5;
    for &time in &[0.0, 0.7, 3.1, 7.9] {
        let s = t.eval(time);
        let (p, m) = (t.eval(time + h), t.eval(time - h));
        for i in 0..2 {
            let v = (p.x[i] - m.x[i]) / (2.0 * h);
            let a = (p.xd[i] - m.xd[i]) / (2.0 * h);
            assert!((v - s.xd[i]).abs() < 1e-8, "velocity {v} vs {}", s.xd[i]);
            assert!((a - s.xdd[i]).abs() < 1e-7, "acceleration {a} vs {}", s.xdd[i]);
        }
    }
    // Periodic.
    let (a, b) = (t.eval(0.3), t.eval(0.3 + t.period_s()));
    assert!((a.x[0] - b.x[0]).abs() < 1e-12 && (a.xd[1] - b.xd[1]).abs() < 1e-12);
}

#[test]
fn bounds_are_checked_on_the_time_grid() {
    let t = sample_traj();
    let ok = ExcitationBounds { position: vec![[-1.0, 1.0]; 2], velocity: vec![1.0; 2], acceleration: vec![5.0; 2] };
    assert!(check_bounds(&t, &ok, 1000).is_ok());
    let tight = ExcitationBounds { velocity: vec![0.05, 1.0], ..ok.clone() };
    let v = check_bounds(&t, &tight, 1000).unwrap_err();
    assert_eq!((v.dof, v.quantity.as_str()), (1, "velocity"));
}

/// Two joints with inertia, viscous and Coulomb friction and a gravity term: a linear
/// regressor `tau = Y(q, q', q'') u` with 7 parameters.
fn regressor(s: &TrajectorySample) -> ferrocal_calib::Result<DMatrix<f64>> {
    let (q, qd, qdd) = (&s.x, &s.xd, &s.xdd);
    Ok(DMatrix::from_row_slice(
        2,
        7,
        &[
            qdd[0],
            qdd[0] + qdd[1],
            qd[0],
            qd[0].signum(),
            0.0,
            0.0,
            q[0].cos(),
            0.0,
            qdd[0] * q[1].cos() + qdd[1],
            0.0,
            0.0,
            qd[1],
            qd[1].signum(),
            (q[0] + q[1]).cos(),
        ],
    ))
}

#[test]
fn optimised_excitation_stays_within_bounds_and_improves_the_criterion() {
    let bounds = ExcitationBounds {
        position: vec![[-1.5, 1.5], [-1.0, 1.0]],
        velocity: vec![1.5, 2.0],
        acceleration: vec![4.0, 6.0],
    };
    for c in [Criterion::D, Criterion::N] {
        let settings = ExcitationSettings {
            harmonics: 3,
            period_s: 8.0,
            samples: 80,
            check_samples: 800,
            criterion: c,
            max_evaluations: 600,
            ..Default::default()
        };
        let r = optimise_excitation(&bounds, &settings, &regressor).unwrap();
        assert!(check_bounds(&r.trajectory, &bounds, 5000).is_ok(), "{c}: bounds broken on a finer grid");
        assert!(r.loss < r.start_loss, "{c}: {} -> {}", r.start_loss, r.loss);
        let f = information(&r.trajectory, 80, &regressor).unwrap();
        assert!((c.loss(&f) - r.loss).abs() < 1e-9 * r.loss.abs().max(1.0));
        eprintln!("{c}: {:.4} -> {:.4} in {} evaluations", c.value(r.start_loss), r.value, r.evaluations);
    }
}
