//! The compliant actuator axis of a Gantry-Tau-like machine, for the motion experiments of
//! Dressler ch. 6-7 in simulation.
//!
//! One actuator axis: a position-controlled drive (the source's closed-loop actuator model, a
//! first-order lag with a dead time, `q^-5 0.03527 / (1 - 0.9647 q^-1)` at 4 ms) moves a carriage
//! whose position the encoder reads; the links (mass `m1`) hang on the carriage through a stiff
//! spring-damper `k1, d1`, the platform with the tool (mass `m2`) on the links through a softer
//! `k2, d2`. The drive imposes its position (a stiff servo rejects the reaction forces), so the
//! structure is excited at its base:
//!
//! ```text
//! a' = (r(t - delay) - a) / tau
//! m1 x1'' = k1 (a - x1) + d1 (a' - x1') - k2 (x1 - x2) - d2 (x1' - x2')
//! m2 x2'' = k2 (x1 - x2) + d2 (x1' - x2')
//! ```
//!
//! The reference `r` is held over each sample (zero-order hold), so the sampled record is exact:
//! the state is advanced by the matrix exponential of the continuous system over one sample. The
//! encoder reads `a` (quantised); a tracker or camera reads the tool `x2` with Gaussian noise.
//!
//! Model family: the truth is linear and time-invariant of order five with a dead time, so a
//! black-box discrete model of that order fits it exactly (the same family); the physical fit in
//! `ferrocal_calib::motion::physical` integrates the chain by its own Runge-Kutta code driven by
//! the recorded encoder, a different discretisation of the same structure.

pub mod cell;
pub mod cell_ilc;
pub mod cell_study;
pub mod cell_tracking;
pub mod leadthrough;
pub mod study;
pub mod tracking;

use ferrocal_calib::motion::physical::ChainParams;
use nalgebra::{SMatrix, SVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::error::{DatasetError, Result};

/// The true compliant axis: the structure (the chain of the physical model) and the actuator
/// loop that drives its base.
#[derive(Clone, Debug, PartialEq)]
pub struct CompliantAxis {
    /// Masses, stiffnesses and dampers of the links-and-platform chain.
    pub chain: ChainParams,
    /// Time constant of the closed actuator loop, s.
    pub servo_tau_s: f64,
    /// Dead time of the actuator loop, samples.
    pub servo_delay_samples: usize,
    /// Sample time, s.
    pub dt_s: f64,
}

/// Sensor noise of a record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorNoise {
    /// Encoder resolution, m (the reading is rounded to it).
    pub encoder_resolution_m: f64,
    /// Standard deviation of the tool measurement, m.
    pub tool_sigma_m: f64,
}

impl Default for SensorNoise {
    /// A 1 µm encoder and a tracker at 10 µm.
    fn default() -> Self {
        Self { encoder_resolution_m: 1e-6, tool_sigma_m: 10e-6 }
    }
}

/// One simulated record.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisRecord {
    /// The reference given to the drive, m.
    pub reference_m: Vec<f64>,
    /// The encoder reading, m.
    pub encoder_m: Vec<f64>,
    /// The true tool position, m.
    pub tool_true_m: Vec<f64>,
    /// The measured tool position, m.
    pub tool_measured_m: Vec<f64>,
}

/// A mode of the undamped structure: natural frequency and modal damping ratio.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrueMode {
    /// Damped natural frequency `|s| / 2 pi` of the pole pair, Hz.
    pub frequency_hz: f64,
    /// Damping ratio `-Re s / |s|`.
    pub damping: f64,
}

impl TrueMode {
    /// The oscillating modes among a continuous state matrix's eigenvalues, lowest first.
    pub fn of(eigenvalues: impl IntoIterator<Item = nalgebra::Complex<f64>>) -> Vec<Self> {
        ferrocal_calib::motion::continuous_modes(eigenvalues)
            .into_iter()
            .map(|(frequency_hz, damping)| Self { frequency_hz, damping })
            .collect()
    }
}

impl CompliantAxis {
    /// The L1-like axis: the source's actuator loop at 4 ms (pole 0.9647, five samples of dead
    /// time) and a structure with modes near 14 Hz and 103 Hz (the source's physical fit).
    pub fn l1_like() -> Self {
        let dt_s = 0.004;
        Self {
            chain: ChainParams {
                m1_kg: 2.0,
                m2_kg: 5.0,
                k1_n_m: 7.963e5,
                k2_n_m: 4.070e4,
                d1_n_s_m: 50.0,
                d2_n_s_m: 27.0,
            },
            servo_tau_s: -dt_s / 0.9647f64.ln(),
            servo_delay_samples: 5,
            dt_s,
        }
    }

    fn validate(&self) -> Result<()> {
        let c = &self.chain;
        let v = [c.m1_kg, c.m2_kg, c.k1_n_m, c.k2_n_m, self.servo_tau_s, self.dt_s];
        if v.iter().any(|x| !x.is_finite() || *x <= 0.0)
            || !(c.d1_n_s_m >= 0.0 && c.d2_n_s_m >= 0.0 && c.d1_n_s_m.is_finite() && c.d2_n_s_m.is_finite())
        {
            return Err(DatasetError::Input(format!(
                "compliant axis: masses, stiffnesses, damping, tau and dt must be finite and positive: {self:?}"
            )));
        }
        Ok(())
    }

    /// Continuous state matrix over `[a, x1, v1, x2, v2]` and input vector of `r`.
    fn continuous(&self) -> (SMatrix<f64, 5, 5>, SVector<f64, 5>) {
        let c = &self.chain;
        let (m1, m2, k1, k2, d1, d2, tau) =
            (c.m1_kg, c.m2_kg, c.k1_n_m, c.k2_n_m, c.d1_n_s_m, c.d2_n_s_m, self.servo_tau_s);
        let mut a = SMatrix::<f64, 5, 5>::zeros();
        let mut b = SVector::<f64, 5>::zeros();
        // a' = (r - a) / tau
        a[(0, 0)] = -1.0 / tau;
        b[0] = 1.0 / tau;
        // x1' = v1
        a[(1, 2)] = 1.0;
        // m1 v1' = k1 (a - x1) + d1 (a' - v1) - k2 (x1 - x2) - d2 (v1 - v2), a' = (r - a) / tau
        a[(2, 0)] = (k1 - d1 / tau) / m1;
        b[2] = d1 / tau / m1;
        a[(2, 1)] = -(k1 + k2) / m1;
        a[(2, 2)] = -(d1 + d2) / m1;
        a[(2, 3)] = k2 / m1;
        a[(2, 4)] = d2 / m1;
        // x2' = v2
        a[(3, 4)] = 1.0;
        // m2 v2' = k2 (x1 - x2) + d2 (v1 - v2)
        a[(4, 1)] = k2 / m2;
        a[(4, 2)] = d2 / m2;
        a[(4, 3)] = -k2 / m2;
        a[(4, 4)] = -d2 / m2;
        (a, b)
    }

    /// The exact sampled system over `[a, x1, v1, x2, v2]` (zero-order hold on the delayed
    /// reference and on a platform force): transition, reference input, force input.
    pub(crate) fn discrete(&self) -> (SMatrix<f64, 5, 5>, SVector<f64, 5>, SVector<f64, 5>) {
        let (ac, bc) = self.continuous();
        let mut aug = SMatrix::<f64, 7, 7>::zeros();
        aug.fixed_view_mut::<5, 5>(0, 0).copy_from(&(ac * self.dt_s));
        aug.fixed_view_mut::<5, 1>(0, 5).copy_from(&(bc * self.dt_s));
        aug[(4, 6)] = self.dt_s / self.chain.m2_kg;
        let e = aug.exp();
        (
            e.fixed_view::<5, 5>(0, 0).into_owned(),
            e.fixed_view::<5, 1>(0, 5).into_owned(),
            e.fixed_view::<5, 1>(0, 6).into_owned(),
        )
    }

    /// The structure's two modes (the pole pairs of the links-and-platform chain with the
    /// carriage held), lowest first.
    pub fn modes(&self) -> Result<Vec<TrueMode>> {
        self.validate()?;
        let (a, _) = self.continuous();
        let chain = a.fixed_view::<4, 4>(1, 1).into_owned();
        let modes = TrueMode::of(chain.complex_eigenvalues().iter().copied());
        if modes.len() != 2 {
            return Err(DatasetError::Input(format!(
                "compliant axis: {} oscillating modes, expected 2 (overdamped?)",
                modes.len()
            )));
        }
        Ok(modes)
    }

    /// Runs the axis from rest at the first reference value over the whole reference, sampled
    /// at `dt_s`: encoder, true and measured tool.
    pub fn run(&self, reference_m: &[f64], noise: SensorNoise, seed: u64) -> Result<AxisRecord> {
        self.run_with_force(reference_m, &[], noise, seed)
    }

    /// As [`Self::run`], with a force on the platform (N per sample, held over the sample; a
    /// process or contact force the encoder does not see). An empty slice means no force.
    pub fn run_with_force(
        &self,
        reference_m: &[f64],
        platform_force_n: &[f64],
        noise: SensorNoise,
        seed: u64,
    ) -> Result<AxisRecord> {
        self.validate()?;
        if reference_m.iter().any(|r| !r.is_finite()) {
            return Err(DatasetError::Input("compliant axis: a reference value is not finite".into()));
        }
        if !platform_force_n.is_empty() && platform_force_n.len() != reference_m.len() {
            return Err(DatasetError::Input(format!(
                "compliant axis: {} force samples for {} reference samples",
                platform_force_n.len(),
                reference_m.len()
            )));
        }
        if let Some(k) = platform_force_n.iter().position(|f| !f.is_finite()) {
            return Err(DatasetError::Input(format!("compliant axis: force sample {k} is not finite")));
        }
        if !(noise.encoder_resolution_m >= 0.0 && noise.tool_sigma_m >= 0.0) {
            return Err(DatasetError::Input(format!("compliant axis: negative or NaN sensor noise {noise:?}")));
        }
        let (ad, bd, bf) = self.discrete();
        let r0 = reference_m.first().copied().unwrap_or(0.0);
        let mut x = SVector::<f64, 5>::new(r0, r0, 0.0, r0, 0.0);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let normal = Normal::new(0.0, noise.tool_sigma_m.max(f64::MIN_POSITIVE)).expect("finite sigma");
        let n = reference_m.len();
        let mut rec = AxisRecord {
            reference_m: reference_m.to_vec(),
            encoder_m: Vec::with_capacity(n),
            tool_true_m: Vec::with_capacity(n),
            tool_measured_m: Vec::with_capacity(n),
        };
        for k in 0..n {
            let q = noise.encoder_resolution_m;
            rec.encoder_m.push(if q > 0.0 { (x[0] / q).round() * q } else { x[0] });
            rec.tool_true_m.push(x[3]);
            let eps = if noise.tool_sigma_m > 0.0 { normal.sample(&mut rng) } else { 0.0 };
            rec.tool_measured_m.push(x[3] + eps);
            let delayed = if k >= self.servo_delay_samples { reference_m[k - self.servo_delay_samples] } else { r0 };
            x = ad * x + bd * delayed + bf * platform_force_n.get(k).copied().unwrap_or(0.0);
        }
        Ok(rec)
    }
}

/// A reference of `n` samples: a random binary signal of +-`amplitude_m` around zero whose level
/// changes with probability 1/2 every `hold` samples (an excitation whose spectrum is flat to about
/// `1 / (2 hold dt)`), from the seeded generator.
pub fn random_binary_reference(n: usize, hold: usize, amplitude_m: f64, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let hold = hold.max(1);
    let mut level = amplitude_m;
    (0..n)
        .map(|k| {
            if k % hold == 0 && rng.random_bool(0.5) {
                level = -level;
            }
            level
        })
        .collect()
}

/// A smooth point-to-point move: rest at 0 for `rest_s`, a quintic move of `distance_m` over
/// `move_s`, then rest at `distance_m`; `n` samples at `dt_s`.
pub fn quintic_move(n: usize, dt_s: f64, rest_s: f64, move_s: f64, distance_m: f64) -> Vec<f64> {
    (0..n)
        .map(|k| {
            let s = ((k as f64 * dt_s - rest_s) / move_s).clamp(0.0, 1.0);
            distance_m * s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_l1_like_axis_has_modes_near_14_and_103_hz_and_the_sources_actuator_pole() {
        let axis = CompliantAxis::l1_like();
        let m = axis.modes().unwrap();
        assert!((m[0].frequency_hz - 14.0).abs() < 0.5, "{m:?}");
        assert!((m[1].frequency_hz - 103.0).abs() < 2.0, "{m:?}");
        assert!(m.iter().all(|m| m.damping > 0.005 && m.damping < 0.1), "{m:?}");
        let pole = (-axis.dt_s / axis.servo_tau_s).exp();
        assert!((pole - 0.9647).abs() < 1e-12);
    }

    #[test]
    fn a_step_settles_at_the_reference_after_the_dead_time() {
        let axis = CompliantAxis::l1_like();
        let mut r = vec![0.0; 2000];
        r[10..].iter_mut().for_each(|v| *v = 0.01);
        let rec = axis.run(&r, SensorNoise { encoder_resolution_m: 0.0, tool_sigma_m: 0.0 }, 1).unwrap();
        // Dead time: nothing moves before sample 10 + 5 + 1.
        assert_eq!(rec.encoder_m[15], 0.0);
        assert!(rec.encoder_m[17] > 0.0);
        // First order: after one time constant 63 %.
        let k_tau = 16 + (axis.servo_tau_s / axis.dt_s).round() as usize;
        assert!((rec.encoder_m[k_tau] / 0.01 - 0.632).abs() < 0.02, "{}", rec.encoder_m[k_tau]);
        assert!((rec.tool_true_m[1999] - 0.01).abs() < 1e-7);
    }
}
