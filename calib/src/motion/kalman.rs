//! A Kalman estimator of the tool position from the encoder, the physical chain and a slower,
//! delayed camera (Dressler ch. 7: the tool-position estimate that learning control uses when the
//! tool itself is not measured at the control rate).
//!
//! State: links and platform positions and velocities `(x1, v1, x2, v2)` and a slowly varying
//! force `f` on the platform (a process force, a cable, a payload the encoder cannot see), a
//! random walk. The carriage position the encoder reads drives the chain; between two samples it
//! is taken as linear (first-order hold), and the transition is the exact exponential of the
//! augmented matrix. A camera frame captured at sample `j` arrives `delay` samples later: the
//! filter runs `delay` samples behind, updates with each frame at its capture time, and predicts
//! forward to the present with the encoder samples already read, so the estimate at `k` uses
//! only what is known at `k`.

use nalgebra::{Matrix1x5, Matrix5, SMatrix, Vector5};

use super::physical::ChainParams;
use crate::error::{CalibError, Result};

/// The tool position at one sample with its standard deviation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolEstimate {
    /// Estimated tool (platform) position, m.
    pub position_m: f64,
    /// Its standard deviation, m.
    pub std_m: f64,
}

/// Noise settings of the estimator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EstimatorNoise {
    /// Acceleration noise on each mass (model error), m/s^2 per sample.
    pub accel_sigma_m_s2: f64,
    /// Random-walk step of the platform force per sample, N.
    pub force_step_n: f64,
    /// Camera measurement standard deviation, m.
    pub camera_sigma_m: f64,
}

/// The estimator for one chain and sample time.
#[derive(Clone, Debug)]
pub struct ToolEstimator {
    phi: Matrix5<f64>,
    gamma_a: Vector5<f64>,
    gamma_v: Vector5<f64>,
    q: Matrix5<f64>,
    r_m2: f64,
    delay: usize,
}

impl ToolEstimator {
    /// The estimator for `chain` sampled at `dt_s`, camera frames arriving `delay_samples` after
    /// their capture.
    pub fn new(chain: &ChainParams, dt_s: f64, noise: EstimatorNoise, delay_samples: usize) -> Result<Self> {
        let v = [chain.m1_kg, chain.m2_kg, chain.k1_n_m, chain.k2_n_m, dt_s, noise.camera_sigma_m];
        if v.iter().any(|x| !(x.is_finite() && *x > 0.0))
            || !(chain.d1_n_s_m >= 0.0 && chain.d2_n_s_m >= 0.0)
            || !(noise.accel_sigma_m_s2 >= 0.0 && noise.force_step_n >= 0.0)
            || !(noise.accel_sigma_m_s2.is_finite() && noise.force_step_n.is_finite())
        {
            return Err(CalibError::Data(format!(
                "tool estimator: masses, stiffnesses, sample time and camera sigma must be finite and positive, \
                 damping and process noise non-negative ({chain:?}, dt {dt_s} s, {noise:?})"
            )));
        }
        let (m1, m2, k1, k2, d1, d2) =
            (chain.m1_kg, chain.m2_kg, chain.k1_n_m, chain.k2_n_m, chain.d1_n_s_m, chain.d2_n_s_m);
        // Augmented continuous system over (x1, v1, x2, v2, f, a, a').
        let mut m = SMatrix::<f64, 7, 7>::zeros();
        m[(0, 1)] = 1.0;
        m[(1, 0)] = -(k1 + k2) / m1;
        m[(1, 1)] = -(d1 + d2) / m1;
        m[(1, 2)] = k2 / m1;
        m[(1, 3)] = d2 / m1;
        m[(1, 5)] = k1 / m1;
        m[(1, 6)] = d1 / m1;
        m[(2, 3)] = 1.0;
        m[(3, 0)] = k2 / m2;
        m[(3, 1)] = d2 / m2;
        m[(3, 2)] = -k2 / m2;
        m[(3, 3)] = -d2 / m2;
        m[(3, 4)] = 1.0 / m2;
        m[(5, 6)] = 1.0;
        let e = (m * dt_s).exp();
        let phi = e.fixed_view::<5, 5>(0, 0).into_owned();
        let gamma_a = e.fixed_view::<5, 1>(0, 5).into_owned();
        let gamma_v = e.fixed_view::<5, 1>(0, 6).into_owned();
        let mut q = Matrix5::zeros();
        let sa = noise.accel_sigma_m_s2 * dt_s;
        q[(1, 1)] = sa * sa;
        q[(3, 3)] = sa * sa;
        q[(4, 4)] = noise.force_step_n * noise.force_step_n;
        Ok(Self { phi, gamma_a, gamma_v, q, r_m2: noise.camera_sigma_m * noise.camera_sigma_m, delay: delay_samples })
    }

    fn predict(&self, x: &mut Vector5<f64>, p: &mut Matrix5<f64>, a_k: f64, a_next: f64, dt_s: f64) {
        let slope = (a_next - a_k) / dt_s;
        *x = self.phi * *x + self.gamma_a * a_k + self.gamma_v * slope;
        *p = self.phi * *p * self.phi.transpose() + self.q;
    }

    /// Estimates the tool position at every encoder sample; `camera[j]` is the tool position
    /// measured in the frame captured at sample `j` (None between frames), usable from sample
    /// `j + delay`. `dt_s` must be the sample time the estimator was built for.
    pub fn estimate(&self, encoder_m: &[f64], camera_m: &[Option<f64>], dt_s: f64) -> Result<Vec<ToolEstimate>> {
        if encoder_m.len() != camera_m.len() {
            return Err(CalibError::Data(format!(
                "tool estimator: {} encoder samples and {} camera slots; one slot per sample needed",
                encoder_m.len(),
                camera_m.len()
            )));
        }
        if let Some(k) = encoder_m.iter().position(|v| !v.is_finite()) {
            return Err(CalibError::Data(format!("tool estimator: encoder sample {k} is not finite")));
        }
        if let Some(k) = camera_m.iter().position(|v| v.is_some_and(|c| !c.is_finite())) {
            return Err(CalibError::Data(format!("tool estimator: camera sample {k} is not finite")));
        }
        let Some(&a0) = encoder_m.first() else { return Ok(Vec::new()) };
        let h = Matrix1x5::new(0.0, 0.0, 1.0, 0.0, 0.0);
        // The lagging filter: at rest at the first encoder reading, the force unknown.
        let mut x = Vector5::new(a0, 0.0, a0, 0.0, 0.0);
        let mut p = Matrix5::zeros();
        p[(4, 4)] = 100.0;
        p[(2, 2)] = self.r_m2;
        p[(0, 0)] = self.r_m2;
        let mut out = Vec::with_capacity(encoder_m.len());
        let mut lag_at = 0usize; // the lagging filter's sample
        for k in 0..encoder_m.len() {
            // Bring the lagging filter to k - delay, updating with every frame on the way.
            let target = k.saturating_sub(self.delay);
            while lag_at < target {
                self.predict(&mut x, &mut p, encoder_m[lag_at], encoder_m[lag_at + 1], dt_s);
                lag_at += 1;
                if let Some(z) = camera_m[lag_at] {
                    update(&mut x, &mut p, &h, z, self.r_m2);
                }
            }
            if k == 0 && self.delay == 0 {
                if let Some(z) = camera_m[0] {
                    update(&mut x, &mut p, &h, z, self.r_m2);
                }
            }
            // Predict to the present with the encoder samples read since.
            let (mut xp, mut pp) = (x, p);
            for j in lag_at..k {
                self.predict(&mut xp, &mut pp, encoder_m[j], encoder_m[j + 1], dt_s);
            }
            out.push(ToolEstimate { position_m: xp[2], std_m: pp[(2, 2)].max(0.0).sqrt() });
        }
        Ok(out)
    }
}

fn update(x: &mut Vector5<f64>, p: &mut Matrix5<f64>, h: &Matrix1x5<f64>, z: f64, r: f64) {
    let s = (h * *p * h.transpose())[0] + r;
    let k = *p * h.transpose() / s;
    *x += k * (z - (h * *x)[0]);
    // Joseph form: stays symmetric and positive.
    let i_kh = Matrix5::identity() - k * h;
    *p = i_kh * *p * i_kh.transpose() + k * k.transpose() * r;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chain() -> ChainParams {
        ChainParams { m1_kg: 2.0, m2_kg: 5.0, k1_n_m: 7.963e5, k2_n_m: 4.07e4, d1_n_s_m: 50.0, d2_n_s_m: 27.0 }
    }

    /// The truth: the chain with a 20 N force step on the platform at 1 s that the encoder does
    /// not see, integrated here by Runge-Kutta (32 substeps; the estimator uses the exact
    /// exponential); a smooth encoder motion.
    fn truth(n: usize, dt: f64) -> (Vec<f64>, Vec<f64>) {
        let c = chain();
        let enc = |t: f64| 0.005 * (1.0 - (t * 3.0).cos());
        let enc_v = |t: f64| 0.015 * (t * 3.0).sin();
        let force = |t: f64| if t >= 1.0 { 20.0 } else { 0.0 };
        let f = |t: f64, x: &nalgebra::Vector4<f64>| {
            let s2 = c.k2_n_m * (x[0] - x[2]) + c.d2_n_s_m * (x[1] - x[3]);
            nalgebra::Vector4::new(
                x[1],
                (c.k1_n_m * (enc(t) - x[0]) + c.d1_n_s_m * (enc_v(t) - x[1]) - s2) / c.m1_kg,
                x[3],
                (s2 + force(t)) / c.m2_kg,
            )
        };
        let mut x = nalgebra::Vector4::zeros();
        let h = dt / 32.0;
        let mut tool = Vec::with_capacity(n);
        for k in 0..n {
            tool.push(x[2]);
            for j in 0..32 {
                let t = k as f64 * dt + j as f64 * h;
                let a = f(t, &x);
                let b = f(t + h / 2.0, &(x + a * (h / 2.0)));
                let cc = f(t + h / 2.0, &(x + b * (h / 2.0)));
                let d = f(t + h, &(x + cc * h));
                x += (a + b * 2.0 + cc * 2.0 + d) * (h / 6.0);
            }
        }
        ((0..n).map(|k| enc(k as f64 * dt)).collect(), tool)
    }

    #[test]
    fn the_delayed_camera_corrects_a_force_the_encoder_cannot_see() {
        let dt = 0.004;
        let n = 1000;
        let (enc, tool) = truth(n, dt);
        // Camera: every 5th sample, 30 µm noise (deterministic pseudo-noise), 3 samples late.
        let noise = |k: usize| 30e-6 * ((k as f64 * 12.9898).sin() * 43758.5453).fract().abs().mul_add(2.0, -1.0) * 1.7;
        let cam: Vec<Option<f64>> = (0..n).map(|k| (k % 5 == 0).then(|| tool[k] + noise(k))).collect();
        let est = ToolEstimator::new(
            &chain(),
            dt,
            EstimatorNoise { accel_sigma_m_s2: 0.05, force_step_n: 0.1, camera_sigma_m: 30e-6 },
            3,
        )
        .unwrap();
        let e = est.estimate(&enc, &cam, dt).unwrap();
        let model_only = chain().simulate(&enc, dt, 8);
        // After the step (last 2 s): the model alone is off by the deflection (0.52 mm) and
        // its ringing; the estimator is within the camera's noise.
        let rms = |f: &dyn Fn(usize) -> f64| ((500..n).map(|k| f(k).powi(2)).sum::<f64>() / (n - 500) as f64).sqrt();
        let e_model = rms(&|k| model_only[k] - tool[k]);
        let e_kf = rms(&|k| e[k].position_m - tool[k]);
        assert!(e_model > 4e-4, "model only {e_model}");
        // Measured: 9.1 µm against the camera's 29 µm per frame.
        assert!(e_kf < 15e-6, "estimator {e_kf}");
        // The stated sigma covers the error (measured RMS of error / sigma 0.46: conservative,
        // the camera's noise here is uniform, not normal).
        let z = rms(&|k| (e[k].position_m - tool[k]) / e[k].std_m);
        assert!(z > 0.3 && z < 2.5, "normalised error RMS {z}");
    }

    #[test]
    fn bad_input_is_refused_by_sample() {
        let est = ToolEstimator::new(
            &chain(),
            0.004,
            EstimatorNoise { accel_sigma_m_s2: 0.1, force_step_n: 0.1, camera_sigma_m: 1e-5 },
            2,
        )
        .unwrap();
        let err = est.estimate(&[0.0, f64::NAN], &[None, None], 0.004).unwrap_err().to_string();
        assert!(err.contains("encoder sample 1"), "{err}");
        assert!(est.estimate(&[0.0], &[None, None], 0.004).is_err());
        let bad = ChainParams { m1_kg: -1.0, ..chain() };
        assert!(ToolEstimator::new(
            &bad,
            0.004,
            EstimatorNoise { accel_sigma_m_s2: 0.1, force_step_n: 0.1, camera_sigma_m: 1e-5 },
            0
        )
        .is_err());
    }
}
