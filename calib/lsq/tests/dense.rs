//! The dense back end on a problem with a known answer: an exponential fit whose covariance
//! matches Monte Carlo, and a robust loss that ignores outliers.

use ferrocal_lsq::dense::{solve, DenseProblem, LmOptions};
use ferrocal_lsq::{covariance, Loss, Result};
use nalgebra::DVector;

/// Fit y = a exp(b t) + c.
struct Exp {
    t: Vec<f64>,
    y: Vec<f64>,
}

impl DenseProblem for Exp {
    fn n_params(&self) -> usize {
        3
    }
    fn n_residuals(&self) -> usize {
        self.t.len()
    }
    fn residuals(&self, x: &[f64]) -> Result<DVector<f64>> {
        Ok(DVector::from_iterator(
            self.t.len(),
            self.t.iter().zip(&self.y).map(|(t, y)| x[0] * (x[1] * t).exp() + x[2] - y),
        ))
    }
    fn scales(&self) -> Vec<f64> {
        vec![1.0, 0.1, 1.0]
    }
}

#[test]
fn fits_an_exponential_and_its_covariance_matches_monte_carlo() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let truth = [2.0, -0.7, 0.5];
    let t: Vec<f64> = (0..60).map(|k| k as f64 * 0.1).collect();
    let noise = Normal::new(0.0, 0.01).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let mut estimates = Vec::new();
    let mut predicted_sd = [0.0; 3];
    for trial in 0..200 {
        let y: Vec<f64> =
            t.iter().map(|t| truth[0] * (truth[1] * t).exp() + truth[2] + noise.sample(&mut rng)).collect();
        // Whitened problem: residuals divided by sigma.
        let p = Exp { t: t.clone(), y: y.iter().map(|v| v / 0.01).collect() };
        struct Scaled<'a>(&'a Exp);
        impl DenseProblem for Scaled<'_> {
            fn n_params(&self) -> usize {
                3
            }
            fn n_residuals(&self) -> usize {
                self.0.t.len()
            }
            fn residuals(&self, x: &[f64]) -> Result<DVector<f64>> {
                Ok(DVector::from_iterator(
                    self.0.t.len(),
                    self.0.t.iter().zip(&self.0.y).map(|(t, y)| (x[0] * (x[1] * t).exp() + x[2]) / 0.01 - y),
                ))
            }
            fn scales(&self) -> Vec<f64> {
                vec![1.0, 0.1, 1.0]
            }
        }
        let res = solve(&Scaled(&p), &[1.0, -0.3, 0.0], &LmOptions::default()).unwrap();
        assert!(res.summary.converged, "{:?}", res.summary);
        if trial == 0 {
            let (cov, s0) = covariance(&res.jacobian, &res.residuals).unwrap();
            assert!((s0 - 1.0).abs() < 0.3, "s0 = {s0}");
            for i in 0..3 {
                predicted_sd[i] = cov[(i, i)].sqrt() / s0;
            }
        }
        estimates.push(res.x);
    }
    for i in 0..3 {
        let mean = estimates.iter().map(|e| e[i]).sum::<f64>() / 200.0;
        let sd = (estimates.iter().map(|e| (e[i] - mean).powi(2)).sum::<f64>() / 199.0).sqrt();
        assert!((mean - truth[i]).abs() < 4.0 * sd / 200f64.sqrt() + 1e-9, "param {i}: mean {mean}");
        assert!((sd / predicted_sd[i] - 1.0).abs() < 0.2, "param {i}: sd {sd} vs predicted {}", predicted_sd[i]);
    }
}

#[test]
fn huber_down_weights_outliers() {
    let t: Vec<f64> = (0..40).map(|k| k as f64 * 0.1).collect();
    let mut y: Vec<f64> = t.iter().map(|t| 2.0 * (-0.7 * t).exp() + 0.5).collect();
    y[10] += 5.0;
    y[30] -= 3.0;
    let p = Exp { t, y };
    let plain = solve(&p, &[1.0, -0.3, 0.0], &LmOptions::default()).unwrap();
    let robust =
        solve(&p, &[1.0, -0.3, 0.0], &LmOptions { loss: Loss::Huber { delta: 0.05 }, ..LmOptions::default() }).unwrap();
    let err = |x: &[f64]| (x[0] - 2.0).abs() + (x[1] + 0.7).abs() + (x[2] - 0.5).abs();
    assert!(err(&robust.x) < 0.1 * err(&plain.x), "robust {:?} plain {:?}", robust.x, plain.x);
    assert!(robust.summary.downweighted_blocks >= 2);
}
