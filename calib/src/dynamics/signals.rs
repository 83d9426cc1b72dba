//! Sampled signals for dynamic identification: stream checks, DFT filtering and
//! differentiation, a zero-phase Butterworth filter with central differences for comparison,
//! and statistics over repeated periods.
//!
//! # Frequency domain (Abdellatif & Heimann)
//! The record (an integer number of periods of a periodic excitation) is transformed, every bin
//! above the cutoff `f_c` is set to zero (a rectangular window in frequency), and the first and
//! second derivatives are formed as `j w X` and `-w^2 X` before transforming back. Nothing is
//! assumed about where the signal's energy lies below `f_c` (the pose from numerical forward
//! kinematics is not exactly on the nominal harmonics), and the pass band is neither attenuated
//! nor delayed.
//!
//! # Time domain
//! A Butterworth low-pass of even order run forwards and backwards (zero phase; odd reflection
//! at the ends), then central differences.
//!
//! The transform is our own: a radix-2 FFT, with Bluestein's chirp-z algorithm for lengths that
//! are not powers of two.

use std::f64::consts::PI;

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use crate::error::{CalibError, Result};

/// A uniformly sampled multi-channel signal.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SampledSignal {
    /// What it is (used in messages: `leg positions`, `sensor forces`).
    pub name: String,
    /// Time of the first sample, s.
    pub start_s: f64,
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Samples (rows) by channels (columns).
    pub values: DMatrix<f64>,
}

impl SampledSignal {
    /// A signal from time stamps and rows of values; checks that the stamps are increasing and
    /// on a uniform grid (deviations below 10 % of the interval) and that every value is finite.
    pub fn from_timestamps(name: &str, t_s: &[f64], values: DMatrix<f64>) -> Result<Self> {
        if t_s.len() != values.nrows() {
            return Err(CalibError::Data(format!("{name}: {} time stamps for {} samples", t_s.len(), values.nrows())));
        }
        if t_s.len() < 2 {
            return Err(CalibError::TooFew(format!("{name}: at least two samples are needed")));
        }
        if let Some(k) = t_s.iter().position(|t| !t.is_finite()) {
            return Err(CalibError::Data(format!("{name}: time stamp of sample {} is not finite", k + 1)));
        }
        let n = t_s.len();
        let dt = (t_s[n - 1] - t_s[0]) / (n - 1) as f64;
        if dt.is_nan() || dt <= 0.0 {
            return Err(CalibError::Data(format!("{name}: time stamps do not increase")));
        }
        for (k, t) in t_s.iter().enumerate() {
            let dev = t - (t_s[0] + dt * k as f64);
            if dev.abs() > 0.1 * dt {
                return Err(CalibError::Data(format!(
                    "{name}: sample {} at t = {t:.6} s is {:.3} ms off the uniform {:.3} Hz grid: resample the stream to a constant rate first",
                    k + 1,
                    dev * 1e3,
                    1.0 / dt
                )));
            }
        }
        Self::uniform(name, t_s[0], 1.0 / dt, values)
    }

    /// A signal on a known grid; checks the rate and the values.
    pub fn uniform(name: &str, start_s: f64, rate_hz: f64, values: DMatrix<f64>) -> Result<Self> {
        if !rate_hz.is_finite() || rate_hz <= 0.0 || !start_s.is_finite() {
            return Err(CalibError::Data(format!(
                "{name}: sample rate {rate_hz} Hz / start {start_s} s is not usable"
            )));
        }
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            let rows = values.nrows().max(1);
            return Err(CalibError::Data(format!(
                "{name}: sample {}, channel {} is not finite",
                k % rows + 1,
                k / rows + 1
            )));
        }
        Ok(Self { name: name.to_string(), start_s, rate_hz, values })
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.values.nrows()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.values.nrows() == 0
    }

    /// Time of sample `k`, s.
    pub fn time(&self, k: usize) -> f64 {
        self.start_s + k as f64 / self.rate_hz
    }

    /// One channel as a vector.
    pub fn channel(&self, c: usize) -> Vec<f64> {
        self.values.column(c).iter().copied().collect()
    }
}

/// Checks that two streams were sampled together: same rate (within 1e-6), same start (within a
/// tenth of a sample) and the same number of samples. The message names both streams and what
/// differs.
pub fn check_synchronised(a: &SampledSignal, b: &SampledSignal) -> Result<()> {
    if ((a.rate_hz - b.rate_hz) / a.rate_hz).abs() > 1e-6 {
        return Err(CalibError::Data(format!(
            "the {} are sampled at {:.6} Hz but the {} at {:.6} Hz: the streams must share one sample clock (resample one of them)",
            a.name, a.rate_hz, b.name, b.rate_hz
        )));
    }
    let offset = b.start_s - a.start_s;
    if offset.abs() > 0.1 / a.rate_hz {
        return Err(CalibError::Data(format!(
            "the {} start at t = {:.6} s but the {} at t = {:.6} s ({:.3} ms, {:.2} samples apart): the streams are not synchronised",
            a.name,
            a.start_s,
            b.name,
            b.start_s,
            offset * 1e3,
            offset * a.rate_hz
        )));
    }
    if a.len() != b.len() {
        return Err(CalibError::Data(format!(
            "the {} have {} samples but the {} {}: the streams do not cover the same time",
            a.name,
            a.len(),
            b.name,
            b.len()
        )));
    }
    Ok(())
}

/// In-place radix-2 FFT of `re + j im` (length a power of two); `inverse` uses `e^{+j}` and does
/// not divide by the length.
fn fft_pow2(re: &mut [f64], im: &mut [f64], inverse: bool) {
    let n = re.len();
    let mut j = 0usize;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            re.swap(i, j);
            im.swap(i, j);
        }
    }
    let sign = if inverse { 1.0 } else { -1.0 };
    let mut len = 2;
    while len <= n {
        let ang = sign * 2.0 * PI / len as f64;
        let (ws, wc) = ang.sin_cos();
        for start in (0..n).step_by(len) {
            let (mut cr, mut ci) = (1.0, 0.0);
            for k in 0..len / 2 {
                let (a, b) = (start + k, start + k + len / 2);
                let tr = re[b] * cr - im[b] * ci;
                let ti = re[b] * ci + im[b] * cr;
                re[b] = re[a] - tr;
                im[b] = im[a] - ti;
                re[a] += tr;
                im[a] += ti;
                let nr = cr * wc - ci * ws;
                ci = cr * ws + ci * wc;
                cr = nr;
            }
        }
        len <<= 1;
    }
}

/// The discrete Fourier transform of `re + j im` (any length; `inverse` without the `1/n`).
pub fn dft(re: &[f64], im: &[f64], inverse: bool) -> (Vec<f64>, Vec<f64>) {
    let n = re.len();
    if n <= 1 {
        return (re.to_vec(), im.to_vec());
    }
    if n.is_power_of_two() {
        let (mut r, mut i) = (re.to_vec(), im.to_vec());
        fft_pow2(&mut r, &mut i, inverse);
        return (r, i);
    }
    // Bluestein: X_k = w_k sum_j (x_j w_j) conj(w_{k-j}), w_k = exp(-+ j pi k^2 / n).
    let sign = if inverse { 1.0 } else { -1.0 };
    let m = (2 * n - 1).next_power_of_two();
    let chirp: Vec<(f64, f64)> = (0..n)
        .map(|k| {
            let k2 = ((k as u128 * k as u128) % (2 * n as u128)) as f64;
            let a = sign * PI * k2 / n as f64;
            (a.cos(), a.sin())
        })
        .collect();
    let (mut ar, mut ai) = (vec![0.0; m], vec![0.0; m]);
    for k in 0..n {
        let (c, s) = chirp[k];
        ar[k] = re[k] * c - im[k] * s;
        ai[k] = re[k] * s + im[k] * c;
    }
    let (mut br, mut bi) = (vec![0.0; m], vec![0.0; m]);
    br[0] = chirp[0].0;
    bi[0] = -chirp[0].1;
    for k in 1..n {
        br[k] = chirp[k].0;
        bi[k] = -chirp[k].1;
        br[m - k] = chirp[k].0;
        bi[m - k] = -chirp[k].1;
    }
    fft_pow2(&mut ar, &mut ai, false);
    fft_pow2(&mut br, &mut bi, false);
    for k in 0..m {
        let r = ar[k] * br[k] - ai[k] * bi[k];
        let i = ar[k] * bi[k] + ai[k] * br[k];
        ar[k] = r;
        ai[k] = i;
    }
    fft_pow2(&mut ar, &mut ai, true);
    let (mut or, mut oi) = (vec![0.0; n], vec![0.0; n]);
    for k in 0..n {
        let (r, i) = (ar[k] / m as f64, ai[k] / m as f64);
        let (c, s) = chirp[k];
        or[k] = r * c - i * s;
        oi[k] = r * s + i * c;
    }
    (or, oi)
}

/// The spectrum of a real signal, for repeated filtering at different cutoffs.
#[derive(Clone, Debug)]
pub struct Spectrum {
    re: Vec<f64>,
    im: Vec<f64>,
    rate_hz: f64,
}

impl Spectrum {
    /// The DFT of `x` sampled at `rate_hz`.
    pub fn of(x: &[f64], rate_hz: f64) -> Self {
        let (re, im) = dft(x, &vec![0.0; x.len()], false);
        Self { re, im, rate_hz }
    }

    /// Frequency of bin `k` (signed), Hz.
    pub fn frequency(&self, k: usize) -> f64 {
        let n = self.re.len();
        let kk = if k <= n / 2 { k as f64 } else { k as f64 - n as f64 };
        kk * self.rate_hz / n as f64
    }

    /// The bin spacing `rate / n`, Hz.
    pub fn resolution_hz(&self) -> f64 {
        self.rate_hz / self.re.len().max(1) as f64
    }

    /// The signal and its first two derivatives, band-limited to `|f| <= cutoff_hz` (see the
    /// module documentation).
    pub fn derivatives(&self, cutoff_hz: f64) -> [Vec<f64>; 3] {
        let n = self.re.len();
        let mut out: [Vec<f64>; 3] = [Vec::new(), Vec::new(), Vec::new()];
        for (order, o) in out.iter_mut().enumerate() {
            let (mut r, mut i) = (vec![0.0; n], vec![0.0; n]);
            for k in 0..n {
                let f = self.frequency(k);
                let nyquist = n.is_multiple_of(2) && k == n / 2;
                if f.abs() > cutoff_hz || (nyquist && order > 0) {
                    continue;
                }
                let w = 2.0 * PI * f;
                let (a, b) = (self.re[k], self.im[k]);
                match order {
                    0 => {
                        r[k] = a;
                        i[k] = b;
                    }
                    1 => {
                        r[k] = -w * b;
                        i[k] = w * a;
                    }
                    _ => {
                        r[k] = -w * w * a;
                        i[k] = -w * w * b;
                    }
                }
            }
            let (xr, _) = dft(&r, &i, true);
            *o = xr.into_iter().map(|v| v / n as f64).collect();
        }
        out
    }
}

/// The signal and its derivatives by frequency-domain filtering at `cutoff_hz`.
pub fn frequency_domain(x: &[f64], rate_hz: f64, cutoff_hz: f64) -> [Vec<f64>; 3] {
    Spectrum::of(x, rate_hz).derivatives(cutoff_hz)
}

/// Zero-phase Butterworth low-pass of even `order` (2, 4, ...) at `cutoff_hz`, run forwards and
/// backwards with odd reflection of `3 rate / cutoff` samples at both ends.
pub fn butterworth_filtfilt(x: &[f64], rate_hz: f64, cutoff_hz: f64, order: usize) -> Result<Vec<f64>> {
    if order == 0 || !order.is_multiple_of(2) {
        return Err(CalibError::Data(format!("Butterworth order {order}: use an even order (2, 4, 6)")));
    }
    if !(cutoff_hz > 0.0 && cutoff_hz < 0.5 * rate_hz) {
        return Err(CalibError::Data(format!(
            "cutoff {cutoff_hz} Hz must lie between 0 and the Nyquist frequency {} Hz",
            0.5 * rate_hz
        )));
    }
    let n = x.len();
    if n < 3 {
        return Ok(x.to_vec());
    }
    let k = (PI * cutoff_hz / rate_hz).tan();
    let sections: Vec<[f64; 5]> = (0..order / 2)
        .map(|i| {
            let q = 1.0 / (2.0 * (PI * (2 * i + 1) as f64 / (2 * order) as f64).sin());
            let norm = 1.0 / (1.0 + k / q + k * k);
            let b0 = k * k * norm;
            [b0, 2.0 * b0, b0, 2.0 * (k * k - 1.0) * norm, (1.0 - k / q + k * k) * norm]
        })
        .collect();
    let pad = ((3.0 * rate_hz / cutoff_hz) as usize).min(n - 1);
    let mut ext = Vec::with_capacity(n + 2 * pad);
    for i in (1..=pad).rev() {
        ext.push(2.0 * x[0] - x[i]);
    }
    ext.extend_from_slice(x);
    for i in 1..=pad {
        ext.push(2.0 * x[n - 1] - x[n - 1 - i]);
    }
    let run = |v: &mut Vec<f64>| {
        for s in &sections {
            let x0 = v[0];
            let (mut x1, mut x2, mut y1, mut y2) = (x0, x0, x0, x0);
            for item in v.iter_mut() {
                let xi = *item;
                let yi = s[0] * xi + s[1] * x1 + s[2] * x2 - s[3] * y1 - s[4] * y2;
                x2 = x1;
                x1 = xi;
                y2 = y1;
                y1 = yi;
                *item = yi;
            }
        }
    };
    run(&mut ext);
    ext.reverse();
    run(&mut ext);
    ext.reverse();
    Ok(ext[pad..pad + n].to_vec())
}

/// First and second derivatives by central differences (one-sided at the ends).
pub fn central_differences(x: &[f64], rate_hz: f64) -> [Vec<f64>; 2] {
    let n = x.len();
    let h = 1.0 / rate_hz;
    let mut v = vec![0.0; n];
    let mut a = vec![0.0; n];
    if n < 3 {
        return [v, a];
    }
    for i in 1..n - 1 {
        v[i] = (x[i + 1] - x[i - 1]) / (2.0 * h);
        a[i] = (x[i + 1] - 2.0 * x[i] + x[i - 1]) / (h * h);
    }
    v[0] = (x[1] - x[0]) / h;
    v[n - 1] = (x[n - 1] - x[n - 2]) / h;
    a[0] = a[1];
    a[n - 1] = a[n - 2];
    [v, a]
}

/// The signal and its derivatives by time-domain filtering: zero-phase Butterworth of `order`
/// at `cutoff_hz`, then central differences.
pub fn time_domain(x: &[f64], rate_hz: f64, cutoff_hz: f64, order: usize) -> Result<[Vec<f64>; 3]> {
    let f = butterworth_filtfilt(x, rate_hz, cutoff_hz, order)?;
    let [v, a] = central_differences(&f, rate_hz);
    Ok([f, v, a])
}

/// Mean and noise covariance over repeated periods.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PeriodStatistics {
    /// Number of periods.
    pub periods: usize,
    /// The mean period (samples per period x channels).
    pub mean: DMatrix<f64>,
    /// Covariance of one sample's noise across channels (full, cross-correlated), from the
    /// deviations of every period from the mean period.
    pub covariance: DMatrix<f64>,
}

/// Splits `values` (samples x channels) into periods of `samples_per_period` and returns the
/// mean period and the channels' noise covariance. Needs at least two whole periods; samples
/// beyond the last whole period are an error (the record must hold whole periods).
pub fn period_statistics(name: &str, values: &DMatrix<f64>, samples_per_period: usize) -> Result<PeriodStatistics> {
    let (n, k) = values.shape();
    if samples_per_period == 0 || !n.is_multiple_of(samples_per_period) {
        return Err(CalibError::Data(format!(
            "{name}: {n} samples are not a whole number of periods of {samples_per_period} samples"
        )));
    }
    let periods = n / samples_per_period;
    if periods < 2 {
        return Err(CalibError::TooFew(format!(
            "{name}: noise covariances need at least two repeated periods, the record holds {periods}"
        )));
    }
    let mut mean = DMatrix::zeros(samples_per_period, k);
    for p in 0..periods {
        mean += values.rows(p * samples_per_period, samples_per_period);
    }
    mean /= periods as f64;
    let mut cov = DMatrix::zeros(k, k);
    for p in 0..periods {
        let d = values.rows(p * samples_per_period, samples_per_period) - &mean;
        cov += d.transpose() * d;
    }
    cov /= (samples_per_period * (periods - 1)) as f64;
    Ok(PeriodStatistics { periods, mean, covariance: cov })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dft_matches_the_definition_for_any_length() {
        for n in [1usize, 2, 5, 8, 12, 17] {
            let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.7).sin() + 0.1 * i as f64).collect();
            let y: Vec<f64> = (0..n).map(|i| (i as f64 * 1.3).cos()).collect();
            let (r, i) = dft(&x, &y, false);
            for k in 0..n {
                let (mut sr, mut si) = (0.0, 0.0);
                for j in 0..n {
                    let a = -2.0 * PI * (k * j) as f64 / n as f64;
                    sr += x[j] * a.cos() - y[j] * a.sin();
                    si += x[j] * a.sin() + y[j] * a.cos();
                }
                assert!((sr - r[k]).abs() < 1e-9 && (si - i[k]).abs() < 1e-9, "n {n} k {k}");
            }
            let (br, bi) = dft(&r, &i, true);
            for j in 0..n {
                assert!((br[j] / n as f64 - x[j]).abs() < 1e-9 && (bi[j] / n as f64 - y[j]).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn spectral_derivatives_of_a_periodic_signal_are_exact() {
        let rate = 100.0;
        let n = 1000; // 10 s, base 0.1 Hz
        let w = 2.0 * PI * 0.3;
        let x: Vec<f64> = (0..n).map(|i| (w * i as f64 / rate).sin()).collect();
        let [f, v, a] = frequency_domain(&x, rate, 1.0);
        for i in 0..n {
            let t = i as f64 / rate;
            assert!((f[i] - (w * t).sin()).abs() < 1e-9);
            assert!((v[i] - w * (w * t).cos()).abs() < 1e-9);
            assert!((a[i] + w * w * (w * t).sin()).abs() < 1e-9);
        }
    }

    #[test]
    fn butterworth_passes_low_and_stops_high_frequencies() {
        let rate = 1000.0;
        let n = 4000;
        let low: Vec<f64> = (0..n).map(|i| (2.0 * PI * 0.5 * i as f64 / rate).sin()).collect();
        let high: Vec<f64> = (0..n).map(|i| (2.0 * PI * 50.0 * i as f64 / rate).sin()).collect();
        let fl = butterworth_filtfilt(&low, rate, 5.0, 4).unwrap();
        let fh = butterworth_filtfilt(&high, rate, 5.0, 4).unwrap();
        let mid = n / 4..3 * n / 4;
        assert!(mid.clone().all(|i| (fl[i] - low[i]).abs() < 1e-3));
        assert!(mid.clone().all(|i| fh[i].abs() < 1e-6));
        assert!(butterworth_filtfilt(&low, rate, 600.0, 4).is_err());
    }
}
