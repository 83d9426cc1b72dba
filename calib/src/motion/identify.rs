//! Black-box identification of a sampled single-input single-output system: the output-error
//! model `y(t) = q^-nk B(q) / A(q) u(t) + e(t)` with white `e`, started by Steiglitz-McBride
//! iterations (least squares on data prefiltered by the last `1 / A`) and finished by
//! Levenberg-Marquardt on the simulation error (the prediction-error estimate for output error).
//! The covariance of the coefficients is `s^2 (Psi^T Psi)^-1` with `Psi` the gradient of the
//! simulated output; the modes' standard deviations follow from it to first order.

use nalgebra::{Complex, DMatrix, DVector};

use crate::error::{CalibError, Result};

/// A sampled transfer function `q^-nk (b0 + b1 q^-1 + ...) / (1 + a1 q^-1 + ...)` with the
/// covariance of its coefficients `[a1 .. a_na, b0 .. b_(nb-1)]`.
#[derive(Clone, Debug, PartialEq)]
pub struct DiscreteModel {
    /// Denominator coefficients `a1 .. a_na`.
    pub a: Vec<f64>,
    /// Numerator coefficients `b0 .. b_(nb-1)`.
    pub b: Vec<f64>,
    /// Dead time, samples.
    pub nk: usize,
    /// Sample time, s.
    pub dt_s: f64,
    /// Covariance of `[a; b]`.
    pub covariance: DMatrix<f64>,
    /// Standard deviation of the simulation error on the estimation data, output units.
    pub residual_std: f64,
}

/// An oscillating pole pair of a model, as a continuous-time mode.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mode {
    /// `|s| / 2 pi` with `s = ln(z) / dt`, Hz.
    pub frequency_hz: f64,
    /// Standard deviation of the frequency, Hz.
    pub frequency_std_hz: f64,
    /// Damping ratio `-Re s / |s|`.
    pub damping: f64,
    /// Standard deviation of the damping ratio.
    pub damping_std: f64,
}

fn check_data(u: &[f64], y: &[f64], what: &str) -> Result<()> {
    if u.len() != y.len() {
        return Err(CalibError::Data(format!("{what}: {} input samples but {} output samples", u.len(), y.len())));
    }
    if let Some(i) = u.iter().chain(y).position(|v| !v.is_finite()) {
        let (sig, k) = if i < u.len() { ("input", i) } else { ("output", i - u.len()) };
        return Err(CalibError::Data(format!("{what}: {sig} sample {k} is not finite")));
    }
    Ok(())
}

/// `y = num / den x` from rest, `den[0] = 1`.
fn filter(num: &[f64], den: &[f64], x: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; x.len()];
    for t in 0..x.len() {
        let mut acc = 0.0;
        for (i, c) in num.iter().enumerate() {
            if t >= i {
                acc += c * x[t - i];
            }
        }
        for (i, c) in den.iter().enumerate().skip(1) {
            if t >= i {
                acc -= c * y[t - i];
            }
        }
        y[t] = acc;
    }
    y
}

impl DiscreteModel {
    fn n_params(&self) -> usize {
        self.a.len() + self.b.len()
    }

    fn den(&self) -> Vec<f64> {
        std::iter::once(1.0).chain(self.a.iter().copied()).collect()
    }

    /// Steady-state gain `B(1) / A(1)`.
    pub fn dc_gain(&self) -> f64 {
        self.b.iter().sum::<f64>() / self.den().iter().sum::<f64>()
    }

    /// The output for input `u`, starting at rest at `u[0]` (past inputs equal to `u[0]`, past
    /// outputs at the steady state).
    pub fn simulate(&self, u: &[f64]) -> Vec<f64> {
        let Some(&u0) = u.first() else { return Vec::new() };
        let y0 = self.dc_gain() * u0;
        // Deviations from the initial steady state.
        let du: Vec<f64> = u.iter().map(|v| v - u0).collect();
        let mut num = vec![0.0; self.nk];
        num.extend_from_slice(&self.b);
        filter(&num, &self.den(), &du).into_iter().map(|v| v + y0).collect()
    }

    /// The first `n` samples of the impulse response (input 1 at sample 0).
    pub fn impulse_response(&self, n: usize) -> Vec<f64> {
        let mut x = vec![0.0; n];
        if n > 0 {
            x[0] = 1.0;
        }
        let mut num = vec![0.0; self.nk];
        num.extend_from_slice(&self.b);
        filter(&num, &self.den(), &x)
    }

    /// The frequency response at `f_hz`.
    pub fn frequency_response(&self, f_hz: f64) -> Complex<f64> {
        let w = std::f64::consts::TAU * f_hz * self.dt_s;
        let zinv = |k: usize| Complex::from_polar(1.0, -w * k as f64);
        let num: Complex<f64> = self.b.iter().enumerate().map(|(i, c)| zinv(i + self.nk) * *c).sum();
        let den: Complex<f64> = self.den().iter().enumerate().map(|(i, c)| zinv(i) * *c).sum();
        num / den
    }

    /// The poles: roots of `z^na + a1 z^(na-1) + ... + a_na`.
    pub fn poles(&self) -> Vec<Complex<f64>> {
        poles_of(&self.a)
    }

    /// Whether every pole lies inside the unit circle.
    pub fn is_stable(&self) -> bool {
        self.poles().iter().all(|p| p.norm() < 1.0)
    }

    /// The oscillating pole pairs as continuous-time modes (lowest frequency first) with
    /// first-order standard deviations from the coefficient covariance.
    pub fn modes(&self) -> Vec<Mode> {
        let na = self.a.len();
        let cov = self.covariance.view((0, 0), (na, na)).into_owned();
        let steps: Vec<f64> = self.a.iter().map(|a| 1e-7 * a.abs().max(1e-3)).collect();
        modes_with_std(&modes_of(&self.a, self.dt_s), &cov, &steps, |i, d| {
            let mut a = self.a.clone();
            a[i] += d;
            modes_of(&a, self.dt_s)
        })
    }
}

/// Modes with first-order standard deviations by central differences: `base` the modes
/// `(Hz, damping)` at the estimate, `cov` the covariance of its parameters, `steps[i]` the
/// difference step of parameter `i`, and `modes_at(i, d)` the modes (lowest first, matched to
/// `base` by order) with parameter `i` moved by `d`. A mode lost under a step contributes no
/// derivative in that parameter.
pub(crate) fn modes_with_std(
    base: &[(f64, f64)],
    cov: &DMatrix<f64>,
    steps: &[f64],
    modes_at: impl Fn(usize, f64) -> Vec<(f64, f64)>,
) -> Vec<Mode> {
    let n = steps.len();
    // The modes with each parameter moved up and down: [up_0, down_0, up_1, down_1, ...].
    let shifted: Vec<Vec<(f64, f64)>> =
        steps.iter().enumerate().flat_map(|(i, &h)| [modes_at(i, h), modes_at(i, -h)]).collect();
    base.iter()
        .enumerate()
        .map(|(m, &(f, z))| {
            let mut jf = DVector::zeros(n);
            let mut jz = DVector::zeros(n);
            for (i, pair) in shifted.chunks(2).enumerate() {
                if let (Some(p), Some(q)) = (pair[0].get(m), pair[1].get(m)) {
                    jf[i] = (p.0 - q.0) / (2.0 * steps[i]);
                    jz[i] = (p.1 - q.1) / (2.0 * steps[i]);
                }
            }
            Mode {
                frequency_hz: f,
                frequency_std_hz: (jf.transpose() * cov * &jf)[0].max(0.0).sqrt(),
                damping: z,
                damping_std: (jz.transpose() * cov * &jz)[0].max(0.0).sqrt(),
            }
        })
        .collect()
}

fn poles_of(a: &[f64]) -> Vec<Complex<f64>> {
    let n = a.len();
    if n == 0 {
        return Vec::new();
    }
    let mut c = DMatrix::zeros(n, n);
    for (j, v) in a.iter().enumerate() {
        c[(0, j)] = -v;
    }
    for i in 1..n {
        c[(i, i - 1)] = 1.0;
    }
    c.complex_eigenvalues().iter().copied().collect()
}

fn modes_of(a: &[f64], dt_s: f64) -> Vec<(f64, f64)> {
    let mut m: Vec<(f64, f64)> = poles_of(a)
        .iter()
        .filter(|z| z.im > 1e-12)
        .map(|z| {
            let s = z.ln() / dt_s;
            (s.norm() / std::f64::consts::TAU, -s.re / s.norm())
        })
        .collect();
    m.sort_by(|x, y| x.0.total_cmp(&y.0));
    m
}

/// The least-squares ARX fit `A y = q^-nk B u + e` of orders `na`, `nb` (equation error).
pub fn fit_arx(u: &[f64], y: &[f64], na: usize, nb: usize, nk: usize, dt_s: f64) -> Result<DiscreteModel> {
    check_data(u, y, "ARX fit")?;
    let t0 = na.max(nk + nb.saturating_sub(1));
    let p = na + nb;
    if nb == 0 || u.len() < t0 + 4 * p {
        return Err(CalibError::TooFew(format!(
            "ARX fit: {} samples for {p} coefficients (na {na}, nb {nb}, nk {nk}); at least {} needed",
            u.len(),
            t0 + 4 * p
        )));
    }
    let rows = u.len() - t0;
    let phi = DMatrix::from_fn(rows, p, |r, c| {
        let t = r + t0;
        if c < na {
            -y[t - 1 - c]
        } else {
            u[t - nk - (c - na)]
        }
    });
    let rhs = DVector::from_iterator(rows, (t0..u.len()).map(|t| y[t]));
    let theta =
        phi.clone().svd(true, true).solve(&rhs, 1e-12).map_err(|e| CalibError::Numeric(format!("ARX fit: {e}")))?;
    let res = &rhs - &phi * &theta;
    let s2 = res.norm_squared() / (rows - p) as f64;
    let cov =
        (phi.transpose() * &phi).try_inverse().map(|m| m * s2).unwrap_or_else(|| DMatrix::from_element(p, p, f64::NAN));
    Ok(DiscreteModel {
        a: theta.rows(0, na).iter().copied().collect(),
        b: theta.rows(na, nb).iter().copied().collect(),
        nk,
        dt_s,
        covariance: cov,
        residual_std: s2.sqrt(),
    })
}

/// The dead time (in `0..=max_nk` samples) whose ARX fit of orders `na`, `nb` leaves the
/// smallest residual.
pub fn estimate_delay(u: &[f64], y: &[f64], na: usize, nb: usize, max_nk: usize, dt_s: f64) -> Result<usize> {
    let mut best = (f64::INFINITY, 0);
    for nk in 0..=max_nk {
        let m = fit_arx(u, y, na, nb, nk, dt_s)?;
        if m.residual_std < best.0 {
            best = (m.residual_std, nk);
        }
    }
    Ok(best.1)
}

/// Simulated output and its gradient `Psi` in `[a; b]` (rows from `skip`).
fn simulate_with_gradient(m: &DiscreteModel, u: &[f64], skip: usize) -> (Vec<f64>, DMatrix<f64>) {
    let yhat = m.simulate(u);
    let den = m.den();
    let u0 = u[0];
    let y0 = yhat[0];
    let du: Vec<f64> = u.iter().map(|v| v - u0).collect();
    let dy: Vec<f64> = yhat.iter().map(|v| v - y0).collect();
    let wu = filter(&[1.0], &den, &du);
    let wy = filter(&[1.0], &den, &dy);
    let (na, nb) = (m.a.len(), m.b.len());
    let rows = u.len() - skip;
    // The simulation starts at the steady state of the first input, `y0 = (sum b / sum A) u0`:
    // its derivatives enter every sample.
    let sum_a: f64 = den.iter().sum();
    let (dy0_da, dy0_db) = (-y0 / sum_a, u0 / sum_a);
    let psi = DMatrix::from_fn(rows, na + nb, |r, c| {
        let t = r + skip;
        if c < na {
            let k = c + 1;
            dy0_da - if t >= k { wy[t - k] } else { 0.0 }
        } else {
            let k = m.nk + c - na;
            dy0_db + if t >= k { wu[t - k] } else { 0.0 }
        }
    });
    (yhat, psi)
}

/// The output-error fit of orders `na`, `nb` and dead time `nk`: Steiglitz-McBride from the ARX
/// fit, then Levenberg-Marquardt on the simulation error. Refuses an unstable result.
pub fn fit_output_error(u: &[f64], y: &[f64], na: usize, nb: usize, nk: usize, dt_s: f64) -> Result<DiscreteModel> {
    let arx = fit_arx(u, y, na, nb, nk, dt_s)?;
    let mut m = arx.clone();
    // Steiglitz-McBride on the deviations from the first samples (the record starts at rest, so
    // the filters start at rest too).
    let (u0, y0) = (u[0], y[0]);
    let du: Vec<f64> = u.iter().map(|v| v - u0).collect();
    let dy: Vec<f64> = y.iter().map(|v| v - y0).collect();
    for _ in 0..30 {
        if !m.is_stable() {
            break;
        }
        let den = m.den();
        let uf = filter(&[1.0], &den, &du);
        let yf = filter(&[1.0], &den, &dy);
        let next = fit_arx(&uf, &yf, na, nb, nk, dt_s)?;
        let change = next.a.iter().zip(&m.a).map(|(p, q)| (p - q).abs()).fold(0.0, f64::max);
        m = next;
        if change < 1e-10 {
            break;
        }
    }
    if !m.is_stable() {
        m = fit_arx(u, y, na, nb, nk, dt_s)?;
        if !m.is_stable() {
            return Err(CalibError::Diverged(format!(
                "output-error fit (na {na}, nb {nb}, nk {nk}): the least-squares start is unstable; try other orders"
            )));
        }
    }
    // Levenberg-Marquardt on the simulation error; the first samples (start-up) are skipped.
    let skip = (na.max(nk + nb) + 20).min(u.len() / 4);
    let cost = |m: &DiscreteModel| -> f64 {
        let yhat = m.simulate(u);
        (skip..u.len()).map(|t| (y[t] - yhat[t]).powi(2)).sum()
    };
    // Start from the better of the least-squares and Steiglitz-McBride models.
    if arx.is_stable() && cost(&arx) < cost(&m) {
        m = arx;
    }
    let mut c = cost(&m);
    let mut mu = 1e-3;
    for _ in 0..100 {
        let (yhat, psi) = simulate_with_gradient(&m, u, skip);
        let e = DVector::from_iterator(u.len() - skip, (skip..u.len()).map(|t| y[t] - yhat[t]));
        let jtj = psi.transpose() * &psi;
        let g = psi.transpose() * e;
        let mut improved = false;
        for _ in 0..12 {
            let mut h = jtj.clone();
            for i in 0..h.nrows() {
                h[(i, i)] *= 1.0 + mu;
            }
            let Some(step) = h.cholesky().map(|ch| ch.solve(&g)) else {
                mu *= 10.0;
                continue;
            };
            let mut trial = m.clone();
            let na = trial.a.len();
            for (i, s) in step.iter().enumerate() {
                if i < na {
                    trial.a[i] += s;
                } else {
                    trial.b[i - na] += s;
                }
            }
            let ct = if trial.is_stable() { cost(&trial) } else { f64::INFINITY };
            if ct < c {
                let rel = (c - ct) / c.max(f64::MIN_POSITIVE);
                m = trial;
                c = ct;
                mu = (mu / 10.0).max(1e-12);
                improved = rel > 1e-12;
                break;
            }
            mu *= 10.0;
        }
        if !improved {
            break;
        }
    }
    let (_, psi) = simulate_with_gradient(&m, u, skip);
    let dof = (u.len() - skip).saturating_sub(m.n_params()).max(1);
    let s2 = c / dof as f64;
    m.covariance = (psi.transpose() * &psi)
        .try_inverse()
        .map(|inv| inv * s2)
        .unwrap_or_else(|| DMatrix::from_element(m.n_params(), m.n_params(), f64::NAN));
    m.residual_std = s2.sqrt();
    Ok(m)
}

/// The fit of a simulated output to a measured one, percent: `100 (1 - |y - yhat| / |y - mean y|)`
/// (100 is perfect; 0 is no better than the mean).
pub fn fit_percent(y: &[f64], yhat: &[f64]) -> f64 {
    let mean = y.iter().sum::<f64>() / y.len().max(1) as f64;
    let num: f64 = y.iter().zip(yhat).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
    let den: f64 = y.iter().map(|a| (a - mean).powi(2)).sum::<f64>().sqrt();
    100.0 * (1.0 - num / den)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(seed: u64, n: usize) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
            })
            .collect()
    }

    #[test]
    fn output_error_recovers_a_resonant_system_and_its_mode() {
        // A pole pair at 10 Hz, damping 0.05, at 100 Hz sampling, and a pole at 0.8.
        let dt = 0.01;
        let s = Complex::new(-0.05 * 62.83, 62.83 * (1.0f64 - 0.0025).sqrt());
        let z = (s * dt).exp();
        let (a1, a2) = (-2.0 * z.re, z.norm_sqr());
        // (1 + a1 q^-1 + a2 q^-2)(1 - 0.8 q^-1)
        let a = vec![a1 - 0.8, a2 - 0.8 * a1, -0.8 * a2];
        let truth = DiscreteModel {
            a,
            b: vec![0.02, 0.01, -0.005],
            nk: 2,
            dt_s: dt,
            covariance: DMatrix::zeros(6, 6),
            residual_std: 0.0,
        };
        let u: Vec<f64> = lcg(3, 4000).iter().map(|v| v.signum()).collect();
        let noise = lcg(9, 4000);
        let y: Vec<f64> = truth.simulate(&u).iter().zip(&noise).map(|(v, e)| v + 0.02 * e).collect();
        assert_eq!(estimate_delay(&u, &y, 3, 3, 5, dt).unwrap(), 2);
        let m = fit_output_error(&u, &y, 3, 3, 2, dt).unwrap();
        let modes = m.modes();
        assert_eq!(modes.len(), 1);
        let f_true = s.norm() / std::f64::consts::TAU;
        let mo = modes[0];
        assert!((mo.frequency_hz - f_true).abs() < 4.0 * mo.frequency_std_hz + 1e-3, "{mo:?} vs {f_true}");
        assert!(mo.frequency_std_hz < 0.05 && mo.frequency_std_hz > 0.0, "{mo:?}");
        assert!((mo.damping - 0.05).abs() < 4.0 * mo.damping_std + 1e-4, "{mo:?}");
        assert!(fit_percent(&truth.simulate(&u), &m.simulate(&u)) > 99.0);
        // The noise level is found (uniform on +-0.01: std 0.00577).
        assert!((m.residual_std / 0.005774 - 1.0).abs() < 0.1, "{}", m.residual_std);
    }

    #[test]
    fn bad_data_is_refused_by_sample() {
        let u = vec![0.0, 1.0, f64::NAN, 0.0];
        let e = fit_arx(&u, &[0.0; 4], 1, 1, 0, 0.01).unwrap_err().to_string();
        assert!(e.contains("input sample 2"), "{e}");
        let e = fit_arx(&[0.0; 5], &[0.0; 4], 1, 1, 0, 0.01).unwrap_err().to_string();
        assert!(e.contains("5 input samples but 4"), "{e}");
    }
}
