//! Iterative learning control in lifted form (Dressler ch. 7): over a trial of `N` samples the
//! plant is the lower-triangular Toeplitz matrix `G` of its impulse response, and the update
//! `u_(k+1) = u_k + L e_k` with the norm-optimal learning matrix
//! `L = (G^T G + w I)^-1 G^T` (the minimiser of `|e_(k+1)|^2 + w |u_(k+1) - u_k|^2` for the model),
//! `G` from an identified model. With `w > 0` the update is a contraction for the model and
//! stays one for plants close to it; `w` trades speed against robustness and noise.

use nalgebra::{DMatrix, DVector};

use crate::error::{CalibError, Result};

/// A learning matrix for trials of a fixed length.
#[derive(Clone, Debug)]
pub struct Ilc {
    l: DMatrix<f64>,
}

impl Ilc {
    /// The norm-optimal learning matrix for the impulse response `h` (`h[0]` the response at the
    /// input's own sample) over trials of `h.len()` samples, with input weight `w` (> 0).
    pub fn norm_optimal(h: &[f64], w: f64) -> Result<Self> {
        let n = h.len();
        if n == 0 || !(w > 0.0 && w.is_finite()) || h.iter().any(|v| !v.is_finite()) {
            return Err(CalibError::Data(format!(
                "ILC: {n} impulse-response samples and weight {w}: need some, finite, w > 0"
            )));
        }
        let g = DMatrix::from_fn(n, n, |i, j| if i >= j { h[i - j] } else { 0.0 });
        let mut a = g.transpose() * &g;
        for i in 0..n {
            a[(i, i)] += w;
        }
        let ch = a.cholesky().ok_or_else(|| CalibError::Numeric("ILC: G^T G + w I is not positive definite".into()))?;
        Ok(Self { l: ch.solve(&g.transpose()) })
    }

    /// Trial length, samples.
    pub fn len(&self) -> usize {
        self.l.nrows()
    }

    /// Whether the trial is empty (never: constructors refuse it).
    pub fn is_empty(&self) -> bool {
        self.l.nrows() == 0
    }

    /// The next trial's input from this trial's input and error (desired minus measured).
    pub fn update(&self, u: &[f64], e: &[f64]) -> Result<Vec<f64>> {
        if u.len() != self.len() || e.len() != self.len() {
            return Err(CalibError::Data(format!(
                "ILC: trial of {} samples, got {} inputs and {} errors",
                self.len(),
                u.len(),
                e.len()
            )));
        }
        let du = &self.l * DVector::from_column_slice(e);
        Ok(u.iter().zip(du.iter()).map(|(a, b)| a + b).collect())
    }
}

/// Root mean square of a signal.
pub fn rms(x: &[f64]) -> f64 {
    (x.iter().map(|v| v * v).sum::<f64>() / x.len().max(1) as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn norm_optimal_ilc_converges_on_its_own_model_and_on_a_perturbed_one() {
        // A lightly damped second-order plant with a dead time of 2 samples.
        let n = 200;
        let plant = |gain: f64, pole: f64| -> Vec<f64> {
            let mut h = vec![0.0; n];
            let (mut y1, mut y2) = (0.0, 0.0);
            for (k, hk) in h.iter_mut().enumerate() {
                let x = if k == 2 { gain } else { 0.0 };
                let y = x + 2.0 * pole * 0.95 * y1 - pole * pole * y2;
                *hk = y;
                y2 = y1;
                y1 = y;
            }
            h
        };
        let (model, truth) = (plant(0.02, 0.97), plant(0.023, 0.968));
        let conv =
            |h: &[f64], u: &[f64]| -> Vec<f64> { (0..n).map(|i| (0..=i).map(|j| h[i - j] * u[j]).sum()).collect() };
        let yd: Vec<f64> = (0..n).map(|k| ((k as f64 - 20.0) / 60.0).clamp(0.0, 1.0)).collect();
        let ilc = Ilc::norm_optimal(&model, 1e-4).unwrap();
        let mut u = vec![0.0; n];
        let mut first = 0.0;
        let mut last = 0.0;
        for k in 0..10 {
            let y = conv(&truth, &u);
            let e: Vec<f64> = yd.iter().zip(&y).map(|(a, b)| a - b).collect();
            let r = rms(&e[..n - 10]);
            if k == 0 {
                first = r;
            }
            last = r;
            u = ilc.update(&u, &e).unwrap();
        }
        assert!(last < first / 20.0, "{first} -> {last}");
        assert!(Ilc::norm_optimal(&model, 0.0).is_err());
        assert!(ilc.update(&u[..5], &u[..5]).is_err());
    }
}
