//! Norm-optimal iterative learning control for a plant with three inputs and three outputs, in
//! lifted form (the multivariable form of [`super::ilc`]): over a trial of `N` samples the plant
//! is the block lower-triangular Toeplitz matrix `G` (3N x 3N, sample-major) of its 3 x 3
//! impulse response, and the update is `u_(k+1) = u_k + L e_k` with
//! `L = (G^T G + w I)^-1 G^T`. The factorisation and solve run in faer (the lifted matrix of a
//! 2 s trial at 4 ms is 1500 x 1500).

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};

use crate::error::{CalibError, Result};

/// A learning matrix for three-channel trials of a fixed length.
#[derive(Clone, Debug)]
pub struct MimoIlc {
    l: Mat<f64>,
}

impl MimoIlc {
    /// The norm-optimal learning matrix for the impulse response `h` (`h[k][r][c]`: output `r`'s
    /// response `k` samples after a unit impulse on input `c`) over trials of `h.len()` samples,
    /// with input weight `w` (> 0).
    pub fn norm_optimal(h: &[[[f64; 3]; 3]], w: f64) -> Result<Self> {
        Self::build(h, w, None)
    }

    /// The norm-optimal learning matrix when only the samples `measured` of a trial carry an
    /// error (a sensor slower than the trial's sampling, e.g. a camera every few samples): it
    /// minimises the error at those samples plus `w` times the input change,
    /// `L = (G^T S^T S G + w I)^-1 G^T S^T S` with `S` selecting the measured samples, so
    /// [`Self::update`] ignores the errors at the other samples.
    pub fn norm_optimal_sampled(h: &[[[f64; 3]; 3]], w: f64, measured: &[usize]) -> Result<Self> {
        if let Some(k) = measured.iter().find(|&&k| k >= h.len()) {
            return Err(CalibError::Data(format!("MIMO ILC: measured sample {k} beyond the trial of {}", h.len())));
        }
        let mut mask = vec![false; h.len()];
        measured.iter().for_each(|&k| mask[k] = true);
        Self::build(h, w, Some(&mask))
    }

    fn build(h: &[[[f64; 3]; 3]], w: f64, mask: Option<&[bool]>) -> Result<Self> {
        let n = h.len();
        if n == 0 || !(w > 0.0 && w.is_finite()) || h.iter().flatten().flatten().any(|v| !v.is_finite()) {
            return Err(CalibError::Data(format!(
                "MIMO ILC: {n} impulse-response samples and weight {w}: need some, finite, w > 0"
            )));
        }
        let g = Mat::from_fn(3 * n, 3 * n, |i, j| {
            let (ki, r) = (i / 3, i % 3);
            let (kj, c) = (j / 3, j % 3);
            if ki >= kj && mask.is_none_or(|m| m[ki]) {
                h[ki - kj][r][c]
            } else {
                0.0
            }
        });
        let gt = g.transpose().to_owned();
        let mut a = &gt * &g;
        for i in 0..3 * n {
            a[(i, i)] += w;
        }
        let llt = a
            .llt(Side::Lower)
            .map_err(|e| CalibError::Numeric(format!("MIMO ILC: G^T G + w I is not positive definite ({e:?})")))?;
        Ok(Self { l: llt.solve(&gt) })
    }

    /// Trial length, samples.
    pub fn len(&self) -> usize {
        self.l.nrows() / 3
    }

    /// Whether the trial is empty (never: the constructor refuses it).
    pub fn is_empty(&self) -> bool {
        self.l.nrows() == 0
    }

    /// The next trial's inputs from this trial's inputs and errors (desired minus measured).
    pub fn update(&self, u: &[[f64; 3]], e: &[[f64; 3]]) -> Result<Vec<[f64; 3]>> {
        let n = self.len();
        if u.len() != n || e.len() != n {
            return Err(CalibError::Data(format!(
                "MIMO ILC: trial of {n} samples, got {} inputs and {} errors",
                u.len(),
                e.len()
            )));
        }
        let ev = Mat::from_fn(3 * n, 1, |i, _| e[i / 3][i % 3]);
        let du = &self.l * &ev;
        Ok(u.iter().enumerate().map(|(k, uk)| [0, 1, 2].map(|c| uk[c] + du[(3 * k + c, 0)])).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A coupled plant: a one-sample delay, a first-order lag per channel and a fixed mixing.
    fn simulate(u: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let mix = [[1.0, 0.3, -0.2], [0.1, 0.8, 0.25], [-0.15, 0.2, 1.1]];
        let mut s = [0.0f64; 3];
        let mut y = Vec::with_capacity(u.len());
        for uk in u {
            y.push([0, 1, 2].map(|r| (0..3).map(|c| mix[r][c] * s[c]).sum::<f64>()));
            for c in 0..3 {
                s[c] = 0.8 * s[c] + 0.2 * uk[c];
            }
        }
        y
    }

    /// The plant's `n`-sample impulse response, `h[k][r][c]`.
    fn impulse_response(n: usize) -> Vec<[[f64; 3]; 3]> {
        let per_input: Vec<Vec<[f64; 3]>> = (0..3)
            .map(|c| {
                let mut u = vec![[0.0; 3]; n];
                u[0][c] = 1.0;
                simulate(&u)
            })
            .collect();
        (0..n).map(|k| [0, 1, 2].map(|r| [0, 1, 2].map(|c| per_input[c][k][r]))).collect()
    }

    #[test]
    fn learning_on_the_exact_model_drives_a_coupled_error_down() {
        let n = 120;
        let h = impulse_response(n);
        let ilc = MimoIlc::norm_optimal(&h, 1e-4).unwrap();
        let target: Vec<[f64; 3]> = (0..n)
            .map(|k| {
                let t = k as f64 / n as f64;
                [(6.0 * t).sin() * t, (1.0 - (4.0 * t).cos()) * t, t * t]
            })
            .collect();
        let mut u = vec![[0.0; 3]; n];
        let rms = |y: &[[f64; 3]]| {
            (y.iter()
                .zip(&target)
                .skip(5)
                .map(|(a, b)| (0..3).map(|j| (a[j] - b[j]).powi(2)).sum::<f64>())
                .sum::<f64>()
                / n as f64)
                .sqrt()
        };
        let first = rms(&simulate(&u));
        for _ in 0..5 {
            let y = simulate(&u);
            let e: Vec<[f64; 3]> = y.iter().zip(&target).map(|(a, b)| [0, 1, 2].map(|j| b[j] - a[j])).collect();
            u = ilc.update(&u, &e).unwrap();
        }
        let last = rms(&simulate(&u));
        assert!(last < 0.01 * first, "{first} -> {last}");
        assert!(ilc.update(&u[1..], &u[1..]).is_err());
    }

    #[test]
    fn the_sampled_form_ignores_unmeasured_samples_and_equals_the_full_form_when_all_are_measured() {
        let n = 40;
        let h = impulse_response(n);
        let u = vec![[0.0; 3]; n];
        let e: Vec<[f64; 3]> = (0..n).map(|k| [0.01 * k as f64, 0.5, -0.2]).collect();
        let all: Vec<usize> = (0..n).collect();
        let full = MimoIlc::norm_optimal(&h, 1e-3).unwrap().update(&u, &e).unwrap();
        let same = MimoIlc::norm_optimal_sampled(&h, 1e-3, &all).unwrap().update(&u, &e).unwrap();
        let diff =
            full.iter().zip(&same).flat_map(|(a, b)| (0..3).map(move |j| (a[j] - b[j]).abs())).fold(0.0, f64::max);
        assert!(diff < 1e-9, "full and all-sampled differ by {diff}");
        // Every 5th sample measured: changing the errors elsewhere changes nothing.
        let every5: Vec<usize> = (0..n).step_by(5).collect();
        let l = MimoIlc::norm_optimal_sampled(&h, 1e-3, &every5).unwrap();
        let mut e2 = e.clone();
        e2.iter_mut().enumerate().filter(|(k, _)| k % 5 != 0).for_each(|(_, v)| *v = [9.0, -9.0, 9.0]);
        assert_eq!(l.update(&u, &e).unwrap(), l.update(&u, &e2).unwrap());
        assert!(MimoIlc::norm_optimal_sampled(&h, 1e-3, &[n]).is_err());
    }
}
