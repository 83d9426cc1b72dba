//! Synchronisation of a camera's clock with the encoder stream, estimated from the data
//! (Dressler ch. 6: the camera's positions are only useful to control and estimation once their
//! time stamps are on the encoder's clock).
//!
//! The camera stamps a frame captured at encoder time `t` (s from the record's first sample) with
//! `stamp = (1 + rate_ppm 1e-6) t + offset`. Given a predicted tool track at the encoder samples
//! (the tool position a model computes from the encoder: the identified chain, or the encoder
//! itself where the structure is stiff at the motion's frequencies) and the camera's stamped
//! positions with their standard deviations, the estimator
//!
//! 1. interpolates the predicted track by a natural cubic spline (the frame measures the track's
//!    mean over its exposure: the spline's exact integral over the window);
//! 2. searches the offset on a grid over a stated range, the weighted residual of the frames
//!    against the track at `stamp - offset` (with a free position bias, solved in closed form at
//!    each candidate), and keeps the smallest;
//! 3. refines offset (rate, bias) by Gauss-Newton on the continuous residual, the derivative of
//!    the predicted track at each frame's time being the spline's;
//! 4. states the offset's standard deviation from the residual and the slope of the track:
//!    `(J^T W J)^-1` scaled by the reduced chi-square of the fit.
//!
//! Only motion fixes the offset: a record whose predicted track does not move by more than the
//! frames' noise, or whose motion fixes the offset only to worse than a stated limit, is refused
//! with an error instead of a number. A rate is assumed small enough that the drift over the
//! record is well below the motion's time scale (ppm over minutes), as the grid searches the
//! offset only.

use nalgebra::{DMatrix, DVector};

use crate::error::{CalibError, Result};

/// One camera position with its time stamp on the camera's clock.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StampedPosition {
    /// Time stamp on the camera's clock (the middle of the exposure), s.
    pub stamp_s: f64,
    /// Measured tool position, m.
    pub position_m: f64,
    /// Its standard deviation, m.
    pub std_m: f64,
}

/// Settings of the estimator.
#[derive(Clone, Debug, PartialEq)]
pub struct SyncSettings {
    /// Smallest offset searched, s.
    pub search_min_s: f64,
    /// Largest offset searched, s.
    pub search_max_s: f64,
    /// Grid step of the coarse search, s (a fraction of the motion's shortest time scale).
    pub search_step_s: f64,
    /// Estimate the clock rate as well (needs a record long enough for the drift to show).
    pub estimate_rate: bool,
    /// Estimate a constant position bias between camera and model (a tare or zero mismatch).
    pub estimate_bias: bool,
    /// Exposure time of a frame, s: the frame measures the track's mean over it (0: a point).
    pub exposure_s: f64,
    /// Fewest frames inside the record for every searched offset.
    pub min_frames: usize,
    /// The record is refused as motionless if its motion fixes the offset (from the frames'
    /// stated standard deviations) only to worse than this, s.
    pub max_offset_std_s: f64,
    /// A stated timing uncertainty of the predicted track and of the measurement that the
    /// residual cannot show (the model's discretisation of the encoder, a camera error that grows
    /// with the speed): added in quadrature to the offset's standard deviation, s.
    pub model_timing_std_s: f64,
}

impl Default for SyncSettings {
    /// Offsets from -50 ms to 100 ms on a 1 ms grid, offset and bias (no rate), point frames, at
    /// least 8 frames, refused beyond 1 ms of standard deviation, no stated model timing
    /// uncertainty.
    fn default() -> Self {
        Self {
            search_min_s: -0.05,
            search_max_s: 0.1,
            search_step_s: 0.001,
            estimate_rate: false,
            estimate_bias: true,
            exposure_s: 0.0,
            min_frames: 8,
            max_offset_std_s: 0.001,
            model_timing_std_s: 0.0,
        }
    }
}

/// The estimated clock relation.
#[derive(Clone, Debug, PartialEq)]
pub struct ClockSync {
    /// Camera clock minus encoder clock at the record's first sample, s.
    pub offset_s: f64,
    /// Its standard deviation, s: the fit's and the stated model timing uncertainty in
    /// quadrature.
    pub offset_std_s: f64,
    /// The fit's part: from the residual and the slope of the track, s.
    pub offset_std_fit_s: f64,
    /// The camera clock's rate error, ppm (0 when not estimated).
    pub rate_ppm: f64,
    /// Its standard deviation, ppm (0 when not estimated).
    pub rate_std_ppm: f64,
    /// Correlation of offset and rate (0 when the rate is not estimated).
    pub offset_rate_correlation: f64,
    /// Camera position minus model position, m (0 when not estimated).
    pub bias_m: f64,
    /// Its standard deviation, m.
    pub bias_std_m: f64,
    /// The offset the coarse search found, s.
    pub coarse_offset_s: f64,
    /// Frames used.
    pub frames_used: usize,
    /// Weighted residual sum of squares over its degrees of freedom (1 when the stated standard
    /// deviations describe the residual).
    pub reduced_chi2: f64,
    /// RMS of the residuals, m.
    pub residual_rms_m: f64,
    /// RMS of the predicted track's slope at the frames, m/s.
    pub slope_rms_m_s: f64,
    /// The offset's standard deviation from the stated standard deviations alone (not scaled by
    /// the residual), s.
    pub offset_std_stated_s: f64,
}

impl ClockSync {
    /// The encoder time (s from the record's first sample) of a camera stamp.
    pub fn encoder_time_s(&self, stamp_s: f64) -> f64 {
        (stamp_s - self.offset_s) / (1.0 + 1e-6 * self.rate_ppm)
    }
}

/// A natural cubic spline through samples at a uniform spacing (the first at 0), with its exact
/// integral; outside the samples the end values are held.
#[derive(Clone, Debug)]
pub struct Spline {
    y: Vec<f64>,
    /// Second derivatives at the knots.
    m: Vec<f64>,
    /// Integral from the first knot to each knot.
    cum: Vec<f64>,
    h: f64,
}

impl Spline {
    /// The spline through `y` sampled `h` apart (`y` not empty, `h` > 0).
    pub fn new(y: &[f64], h: f64) -> Self {
        let n = y.len();
        let mut m = vec![0.0; n];
        if n > 2 {
            // Tridiagonal system for the interior second derivatives (Thomas algorithm):
            // m[i-1] + 4 m[i] + m[i+1] = 6 (y[i+1] - 2 y[i] + y[i-1]) / h^2.
            let k = n - 2;
            let mut c = vec![0.0; k];
            let mut d = vec![0.0; k];
            for i in 0..k {
                let rhs = 6.0 * (y[i + 2] - 2.0 * y[i + 1] + y[i]) / (h * h);
                let (prev_c, prev_d) = if i == 0 { (0.0, 0.0) } else { (c[i - 1], d[i - 1]) };
                let denom = 4.0 - prev_c;
                c[i] = 1.0 / denom;
                d[i] = (rhs - prev_d) / denom;
            }
            for i in (0..k).rev() {
                let next = if i + 1 < k { m[i + 2] } else { 0.0 };
                m[i + 1] = d[i] - c[i] * next;
            }
        }
        let mut s = Self { y: y.to_vec(), m, cum: vec![0.0; n], h };
        for i in 1..n {
            s.cum[i] = s.cum[i - 1] + s.piece_integral(i - 1, h);
        }
        s
    }

    fn end_s(&self) -> f64 {
        (self.y.len().saturating_sub(1)) as f64 * self.h
    }

    /// Coefficients `a + b s + c s^2 + d s^3` of the piece starting at knot `i`.
    fn coeffs(&self, i: usize) -> [f64; 4] {
        let h = self.h;
        let (y0, y1, m0, m1) = (self.y[i], self.y[i + 1], self.m[i], self.m[i + 1]);
        [y0, (y1 - y0) / h - h * (2.0 * m0 + m1) / 6.0, 0.5 * m0, (m1 - m0) / (6.0 * h)]
    }

    fn piece_integral(&self, i: usize, s: f64) -> f64 {
        let [a, b, c, d] = self.coeffs(i);
        s * (a + s * (b / 2.0 + s * (c / 3.0 + s * d / 4.0)))
    }

    /// The piece and the local coordinate of `t` (inside the record).
    fn locate(&self, t: f64) -> (usize, f64) {
        let i = ((t / self.h).floor() as usize).min(self.y.len() - 2);
        (i, t - i as f64 * self.h)
    }

    /// Value and slope at `t`; outside the record the end values held (slope 0).
    pub fn eval(&self, t: f64) -> (f64, f64) {
        if self.y.len() < 2 || t <= 0.0 {
            return (self.y[0], 0.0);
        }
        if t >= self.end_s() {
            return (self.y[self.y.len() - 1], 0.0);
        }
        let (i, s) = self.locate(t);
        let [a, b, c, d] = self.coeffs(i);
        (a + s * (b + s * (c + s * d)), b + s * (2.0 * c + 3.0 * s * d))
    }

    /// The integral from 0 to `t` (the end values held outside the record).
    fn integral(&self, t: f64) -> f64 {
        if self.y.len() < 2 || t <= 0.0 {
            return self.y[0] * t;
        }
        let end = self.end_s();
        if t >= end {
            return self.cum[self.y.len() - 1] + self.y[self.y.len() - 1] * (t - end);
        }
        let (i, s) = self.locate(t);
        self.cum[i] + self.piece_integral(i, s)
    }

    /// The track's mean over `[t - e/2, t + e/2]` and its derivative with respect to `t`.
    pub fn window(&self, t: f64, e: f64) -> (f64, f64) {
        if e <= 0.0 {
            return self.eval(t);
        }
        let (lo, hi) = (t - 0.5 * e, t + 0.5 * e);
        ((self.integral(hi) - self.integral(lo)) / e, (self.eval(hi).0 - self.eval(lo).0) / e)
    }
}

fn validate(track_m: &[f64], dt_s: f64, frames: &[StampedPosition], s: &SyncSettings) -> Result<()> {
    let field = |name: &str, why: &str| Err(CalibError::Data(format!("clock sync: {name} {why}")));
    if !(dt_s > 0.0 && dt_s.is_finite()) {
        return field("dt_s", &format!("must be finite and positive, got {dt_s}"));
    }
    if let Some(k) = track_m.iter().position(|v| !v.is_finite()) {
        return field("track_m", &format!("sample {k} is not finite"));
    }
    if let Some(k) =
        frames.iter().position(|f| !(f.stamp_s.is_finite() && f.position_m.is_finite() && f.std_m.is_finite()))
    {
        return field("frames", &format!("frame {k} has a value that is not finite"));
    }
    if let Some(k) = frames.iter().position(|f| f.std_m <= 0.0) {
        return field("frames", &format!("frame {k} has a standard deviation <= 0"));
    }
    if !(s.search_min_s.is_finite() && s.search_max_s.is_finite() && s.search_min_s <= s.search_max_s) {
        return field(
            "search_min_s / search_max_s",
            &format!("must be finite with min <= max, got {} / {}", s.search_min_s, s.search_max_s),
        );
    }
    if !(s.search_step_s > 0.0 && s.search_step_s.is_finite()) {
        return field("search_step_s", &format!("must be finite and positive, got {}", s.search_step_s));
    }
    if (s.search_max_s - s.search_min_s) / s.search_step_s > 1e7 {
        return field("search_step_s", "gives more than 1e7 grid points over the search range");
    }
    if !(s.exposure_s >= 0.0 && s.exposure_s.is_finite()) {
        return field("exposure_s", &format!("must be finite and non-negative, got {}", s.exposure_s));
    }
    if !(s.model_timing_std_s >= 0.0 && s.model_timing_std_s.is_finite()) {
        return field("model_timing_std_s", &format!("must be finite and non-negative, got {}", s.model_timing_std_s));
    }
    if !(s.max_offset_std_s > 0.0 && s.max_offset_std_s.is_finite()) {
        return field("max_offset_std_s", &format!("must be finite and positive, got {}", s.max_offset_std_s));
    }
    Ok(())
}

/// Estimates the camera clock's offset (and rate, and a position bias, as `s` asks) against the
/// encoder clock: `track_m` is the predicted tool position at the encoder samples (`dt_s`
/// apart, the first at time 0), `frames` the camera's stamped positions.
pub fn estimate_clock(track_m: &[f64], dt_s: f64, frames: &[StampedPosition], s: &SyncSettings) -> Result<ClockSync> {
    validate(track_m, dt_s, frames, s)?;
    if track_m.len() < 4 {
        return Err(CalibError::TooFew(format!(
            "clock sync: the record is too short: {} encoder samples, at least 4 needed",
            track_m.len()
        )));
    }
    let spline = Spline::new(track_m, dt_s);
    let end = spline.end_s();
    let half_e = 0.5 * s.exposure_s;
    // Frames whose exposure lies inside the record for every searched offset.
    let used: Vec<StampedPosition> = frames
        .iter()
        .filter(|f| f.stamp_s - s.search_max_s - half_e >= 0.0 && f.stamp_s - s.search_min_s + half_e <= end)
        .copied()
        .collect();
    let n_params = 1 + usize::from(s.estimate_rate) + usize::from(s.estimate_bias);
    let need = s.min_frames.max(n_params + 2);
    if used.len() < need {
        return Err(CalibError::TooFew(format!(
            "clock sync: the record is too short: {} of {} frames lie inside the {:.3} s encoder record for every \
             offset from {:.1} to {:.1} ms, at least {need} needed (lengthen the record or narrow the search range)",
            used.len(),
            frames.len(),
            end,
            1e3 * s.search_min_s,
            1e3 * s.search_max_s
        )));
    }
    // No motion, no offset: the predicted track's span over the frames' window against their
    // noise.
    let t_lo = (used.iter().map(|f| f.stamp_s).fold(f64::INFINITY, f64::min) - s.search_max_s - half_e).max(0.0);
    let t_hi = (used.iter().map(|f| f.stamp_s).fold(f64::NEG_INFINITY, f64::max) - s.search_min_s + half_e).min(end);
    let (k_lo, k_hi) = ((t_lo / dt_s).floor() as usize, ((t_hi / dt_s).ceil() as usize).min(track_m.len() - 1));
    let span = track_m[k_lo..=k_hi].iter().fold(f64::NEG_INFINITY, |a, v| a.max(*v))
        - track_m[k_lo..=k_hi].iter().fold(f64::INFINITY, |a, v| a.min(*v));
    let mut stds: Vec<f64> = used.iter().map(|f| f.std_m).collect();
    stds.sort_by(f64::total_cmp);
    let median_std = stds[stds.len() / 2];
    if span <= 5.0 * median_std {
        return Err(CalibError::Data(format!(
            "clock sync: the record has no motion that fixes the offset: the predicted track moves {:.3e} m over \
             the frames, not more than 5 times their noise ({:.3e} m); record a move",
            span, median_std
        )));
    }
    let weights: Vec<f64> = used.iter().map(|f| 1.0 / (f.std_m * f.std_m)).collect();
    let w_sum: f64 = weights.iter().sum();

    // Coarse search over the offset (rate 0), the bias solved in closed form.
    let cost_at = |offset: f64| -> f64 {
        let r: Vec<f64> =
            used.iter().map(|f| f.position_m - spline.window(f.stamp_s - offset, s.exposure_s).0).collect();
        let bias = if s.estimate_bias { r.iter().zip(&weights).map(|(r, w)| r * w).sum::<f64>() / w_sum } else { 0.0 };
        r.iter().zip(&weights).map(|(r, w)| w * (r - bias) * (r - bias)).sum()
    };
    let steps = ((s.search_max_s - s.search_min_s) / s.search_step_s).floor() as usize;
    let (mut coarse, mut best) = (s.search_min_s, f64::INFINITY);
    for i in 0..=steps {
        let offset = s.search_min_s + i as f64 * s.search_step_s;
        let c = cost_at(offset);
        if c < best {
            (coarse, best) = (offset, c);
        }
    }

    // Gauss-Newton over (offset, [rate ppm], [bias]).
    let eval = |p: &[f64]| -> (DVector<f64>, DMatrix<f64>) {
        let (offset, rate_ppm) = (p[0], if s.estimate_rate { p[1] } else { 0.0 });
        let bias = if s.estimate_bias { p[n_params - 1] } else { 0.0 };
        let scale = 1.0 + 1e-6 * rate_ppm;
        let mut r = DVector::zeros(used.len());
        let mut j = DMatrix::zeros(used.len(), n_params);
        for (i, f) in used.iter().enumerate() {
            let t = (f.stamp_s - offset) / scale;
            let (pred, slope) = spline.window(t, s.exposure_s);
            let sw = weights[i].sqrt();
            r[i] = sw * (f.position_m - pred - bias);
            // d r / d p = -slope d t / d p (and -1 for the bias), weighted.
            j[(i, 0)] = sw * slope / scale;
            if s.estimate_rate {
                j[(i, 1)] = sw * slope * (f.stamp_s - offset) * 1e-6 / (scale * scale);
            }
            if s.estimate_bias {
                j[(i, n_params - 1)] = -sw;
            }
        }
        (r, j)
    };
    let mut p = vec![0.0; n_params];
    p[0] = coarse;
    let (mut r, mut j) = eval(&p);
    let mut cost = r.norm_squared();
    for _ in 0..50 {
        let jtj = j.transpose() * &j;
        let Some(step) = jtj.clone().cholesky().map(|c| c.solve(&(-(j.transpose() * &r)))) else {
            return Err(CalibError::Data(
                "clock sync: the record's motion does not fix the offset (the normal matrix is singular: no motion, \
                 or a constant velocity, where a time shift looks like a position bias)"
                    .into(),
            ));
        };
        let mut lambda = 1.0;
        let mut improved = false;
        while lambda > 1e-6 {
            let trial: Vec<f64> = p.iter().zip(step.iter()).map(|(a, d)| a + lambda * d).collect();
            let (rt, jt) = eval(&trial);
            let ct = rt.norm_squared();
            if ct <= cost {
                (p, r, j, cost, improved) = (trial, rt, jt, ct, true);
                break;
            }
            lambda *= 0.5;
        }
        if !improved || (lambda * step[0]).abs() < 1e-10 {
            break;
        }
    }
    let dof = (used.len() - n_params) as f64;
    let reduced_chi2 = cost / dof;
    let inv = (j.transpose() * &j)
        .try_inverse()
        .ok_or_else(|| CalibError::Numeric("clock sync: the normal matrix is singular at the solution".into()))?;
    let offset_std_stated_s = inv[(0, 0)].max(0.0).sqrt();
    if offset_std_stated_s > s.max_offset_std_s {
        return Err(CalibError::Data(format!(
            "clock sync: the record's motion fixes the offset only to {:.3} ms (more than the limit {:.3} ms): too \
             little motion against the frames' noise; record a faster or longer move",
            1e3 * offset_std_stated_s,
            1e3 * s.max_offset_std_s
        )));
    }
    let cov = inv * reduced_chi2;
    let sd = |i: usize| cov[(i, i)].max(0.0).sqrt();
    let scale = 1.0 + 1e-6 * if s.estimate_rate { p[1] } else { 0.0 };
    let slopes: Vec<f64> = used.iter().map(|f| spline.window((f.stamp_s - p[0]) / scale, s.exposure_s).1).collect();
    let residual_rms_m = (r.iter().zip(&weights).map(|(ri, w)| ri * ri / w).sum::<f64>() / used.len() as f64).sqrt();
    Ok(ClockSync {
        offset_s: p[0],
        offset_std_s: sd(0).hypot(s.model_timing_std_s),
        offset_std_fit_s: sd(0),
        rate_ppm: if s.estimate_rate { p[1] } else { 0.0 },
        rate_std_ppm: if s.estimate_rate { sd(1) } else { 0.0 },
        offset_rate_correlation: if s.estimate_rate {
            cov[(0, 1)] / (sd(0) * sd(1)).max(f64::MIN_POSITIVE)
        } else {
            0.0
        },
        bias_m: if s.estimate_bias { p[n_params - 1] } else { 0.0 },
        bias_std_m: if s.estimate_bias { sd(n_params - 1) } else { 0.0 },
        coarse_offset_s: coarse,
        frames_used: used.len(),
        reduced_chi2,
        residual_rms_m,
        slope_rms_m_s: (slopes.iter().map(|v| v * v).sum::<f64>() / slopes.len() as f64).sqrt(),
        offset_std_stated_s,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    use std::f64::consts::TAU;

    /// A smooth track: quintic moves of +-10 mm every 0.5 s, and its value at any time.
    fn track_at(t: f64) -> f64 {
        let period = 0.5;
        let k = (t / period).floor();
        let u = ((t - k * period) / 0.3).clamp(0.0, 1.0);
        let from = if (k as i64) % 2 == 0 { 0.0 } else { 0.01 };
        from + (0.01 - 2.0 * from) * u * u * u * (10.0 - 15.0 * u + 6.0 * u * u)
    }

    fn frames(
        duration_s: f64,
        offset_s: f64,
        rate_ppm: f64,
        sigma_m: f64,
        seed: u64,
    ) -> (Vec<f64>, Vec<StampedPosition>) {
        let dt = 0.004;
        let n = (duration_s / dt).round() as usize;
        let track: Vec<f64> = (0..n).map(|k| track_at(k as f64 * dt)).collect();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let noise = Normal::new(0.0, sigma_m).unwrap();
        // A 50 Hz camera whose frames fall between encoder samples (started 1.3 ms after one).
        let frames = (0..)
            .map(|i| 0.0013 + 0.02 * i as f64)
            .take_while(|t| *t < duration_s)
            .map(|t| StampedPosition {
                stamp_s: (1.0 + 1e-6 * rate_ppm) * t + offset_s,
                position_m: track_at(t) + noise.sample(&mut rng),
                std_m: sigma_m,
            })
            .collect();
        (track, frames)
    }

    #[test]
    fn a_known_offset_and_rate_are_recovered_within_their_sigma() {
        // 20 s, 13.7 ms and 80 ppm (1.6 ms of drift over the record), 5 µm noise.
        let (track, fr) = frames(20.0, 0.0137, 80.0, 5e-6, 3);
        let s = SyncSettings { estimate_rate: true, ..SyncSettings::default() };
        let c = estimate_clock(&track, 0.004, &fr, &s).unwrap();
        let (e_off, e_rate) = (c.offset_s - 0.0137, c.rate_ppm - 80.0);
        // Measured: offset error 10.4 µs against sigma 10.0 µs, rate error -0.37 ppm against
        // sigma 0.87 ppm (correlation -0.87).
        assert!(c.offset_std_s < 3e-5 && c.rate_std_ppm < 2.0, "{c:?}");
        assert!(e_off.abs() < 3.0 * c.offset_std_s, "offset error {e_off} s, {c:?}");
        assert!(e_rate.abs() < 3.0 * c.rate_std_ppm, "rate error {e_rate} ppm, {c:?}");
        assert!((c.reduced_chi2 - 1.0).abs() < 0.2, "{c:?}");
        assert!(c.bias_m.abs() < 3.0 * c.bias_std_m, "{c:?}");
        // Without the rate the offset is the drift's mean, and the residual shows the rate (measured:
        // reduced chi-square 9.0 against 0.96).
        let c0 = estimate_clock(&track, 0.004, &fr, &SyncSettings::default()).unwrap();
        assert!(c0.reduced_chi2 > 5.0 * c.reduced_chi2, "{c0:?}");
    }

    #[test]
    fn the_offset_alone_is_recovered_and_its_sigma_is_honest_over_seeds() {
        let mut z2 = 0.0;
        let n = 20;
        for seed in 0..n {
            let (track, fr) = frames(3.0, 0.0137, 0.0, 20e-6, 100 + seed);
            let c = estimate_clock(&track, 0.004, &fr, &SyncSettings::default()).unwrap();
            let e = c.offset_s - 0.0137;
            assert!(e.abs() < 5.0 * c.offset_std_s && c.offset_std_s < 1e-4, "seed {seed}: {e} s, {c:?}");
            assert!((c.coarse_offset_s - 0.0137).abs() <= 0.001, "{c:?}");
            z2 += (e / c.offset_std_s).powi(2);
        }
        // Measured: 1.03.
        let z = (z2 / n as f64).sqrt();
        assert!(z > 0.6 && z < 1.5, "RMS of error / sigma over {n} seeds: {z}");
    }

    #[test]
    fn a_motionless_or_short_record_is_refused() {
        let still = vec![0.01; 1000];
        let fr: Vec<StampedPosition> = (0..40)
            .map(|i| StampedPosition { stamp_s: 0.06 + 0.02 * i as f64, position_m: 0.01, std_m: 1e-5 })
            .collect();
        let e = estimate_clock(&still, 0.004, &fr, &SyncSettings::default()).unwrap_err().to_string();
        assert!(e.contains("no motion"), "{e}");
        // A slow sway of +-0.1 mm at 0.25 Hz: more than the noise, but it fixes the offset only to
        // about 20 ms.
        let creep: Vec<f64> = (0..1000).map(|k| 0.01 + 1e-4 * (k as f64 * 0.004 * 0.25 * TAU).sin()).collect();
        let e = estimate_clock(&creep, 0.004, &fr, &SyncSettings::default()).unwrap_err().to_string();
        assert!(e.contains("fixes the offset only to"), "{e}");
        // A constant velocity: a time shift is a position bias.
        let ramp: Vec<f64> = (0..1000).map(|k| 1e-4 * k as f64).collect();
        let e = estimate_clock(&ramp, 0.004, &fr, &SyncSettings::default()).unwrap_err().to_string();
        assert!(e.contains("does not fix the offset"), "{e}");
        let (track, fr) = frames(0.25, 0.0137, 0.0, 5e-6, 1);
        let e = estimate_clock(&track, 0.004, &fr, &SyncSettings::default()).unwrap_err();
        assert!(matches!(e, CalibError::TooFew(_)) && e.to_string().contains("too short"), "{e}");
        let bad = SyncSettings { search_step_s: 0.0, ..SyncSettings::default() };
        let e = estimate_clock(&track, 0.004, &fr, &bad).unwrap_err().to_string();
        assert!(e.contains("search_step_s"), "{e}");
    }

    #[test]
    fn the_spline_window_is_the_exact_mean_of_a_cubic() {
        let f = |t: f64| 1.0 + 2.0 * t - 3.0 * t * t + 0.5 * t * t * t;
        let h = 0.01;
        let y: Vec<f64> = (0..200).map(|k| f(k as f64 * h)).collect();
        let sp = Spline::new(&y, h);
        // Away from the natural ends the spline reproduces the cubic closely.
        let t = 1.0037;
        let e = 0.0023;
        let exact = {
            let big_f = |t: f64| t + t * t - t * t * t + 0.125 * t * t * t * t;
            (big_f(t + 0.5 * e) - big_f(t - 0.5 * e)) / e
        };
        let (m, slope) = sp.window(t, e);
        assert!((m - exact).abs() < 1e-9, "{m} {exact}");
        assert!((slope - (2.0 - 6.0 * t + 1.5 * t * t)).abs() < 1e-6, "{slope}");
    }
}
