//! Simulated dynamics data: the force-sensing end-effector on a hexapod (Friedrich & Ihlenfeldt
//! 2021) and the hexapod's own actuator forces with friction (Abdellatif & Heimann 2009).
//!
//! Entry points:
//! - [`PlatformSim`]: a body (end-effector and payload) carried by six 1-DOF force sensors on a
//!   hexapod's moving platform, with sensor offsets, the platform's pose-dependent deformation,
//!   cross-correlated sensor noise; quasi-static records (averaged samples per pose,
//!   [`PlatformSim::static_record`]) and sampled trajectories ([`PlatformSim::record`]);
//! - [`HexapodSim`]: the hexapod's actuator forces for a platform body, viscous and Coulomb
//!   friction of the legs and viscous friction of the passive joints;
//! - [`payload_steps`]: the payload validation's steps (five of 19.93 kg);
//! - [`study`]: the sources' experiments run on these simulators (models table, pose
//!   reduction, excitation designs, filtering, payload steps, hexapod dynamics);
//! - [`Sampling`]: the sample clock(s), including deliberately broken ones (a delayed or
//!   differently sampled force stream) for tests of the bad-input messages.
//!
//! # Independence from the identification
//! The identification (`ferrocal_calib::dynamics`) builds regressors linear in the parameters.
//! This simulator computes the same physics in the direct way: the Newton-Euler wrench about the
//! centre of gravity in the base frame, the sensor forces by solving `J_P^-T f = w` with a
//! wrench matrix built here from the strut geometry, the passive joints' friction as the gradient
//! of the dissipation function taken numerically, and the leg positions by the closed-form
//! inverse kinematics. What it shares with the identification are the kinematic conventions
//! ([`MotionState::from_coordinates`]: pose coordinates and their rates to twist and
//! acceleration) and the geometry types.
//!
//! # Conventions
//! SI units. Pose coordinates `(x, y, z, roll, pitch, yaw)` of `T_base_flange` (see
//! `ferrocal_robot::dynamics::motion`). Sensor forces positive in compression. Forces are
//! sampled at the instants of the leg positions unless [`Sampling`] says otherwise.

pub mod checks;
mod hexapod;
pub mod identify;
mod platform;
pub mod study;
pub mod tables;

pub use hexapod::{HexapodFriction, HexapodSim};
pub use platform::{Deformation, PlatformSim, StaticRecord};

use ferrocal_calib::design::excitation::TrajectorySample;
use ferrocal_calib::dynamics::signals::SampledSignal;
use ferrocal_robot::dynamics::{MotionState, RigidBody};
use nalgebra::{DMatrix, Matrix3, Vector3, Vector6};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

use crate::error::{DatasetError, Result};

/// The sample clocks of a dynamic record.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sampling {
    /// Sample rate of the leg positions, Hz.
    pub rate_hz: f64,
    /// Samples recorded.
    pub samples: usize,
    /// Sample rate of the forces (`None`: the legs' rate; anything else makes the streams
    /// unsynchronised, for tests of the checks).
    pub force_rate_hz: Option<f64>,
    /// Delay of the force stream's first sample after the legs' first sample, s (0 for
    /// synchronised streams).
    pub force_delay_s: f64,
}

impl Sampling {
    /// Synchronised streams: `samples` at `rate_hz`.
    pub fn synchronous(rate_hz: f64, samples: usize) -> Self {
        Self { rate_hz, samples, force_rate_hz: None, force_delay_s: 0.0 }
    }

    fn validate(&self) -> Result<()> {
        let fr = self.force_rate_hz.unwrap_or(self.rate_hz);
        if !(self.rate_hz > 0.0 && self.rate_hz.is_finite() && fr > 0.0 && fr.is_finite()) {
            return Err(DatasetError::Config(format!(
                "sampling: rates {} Hz / {fr} Hz must be positive",
                self.rate_hz
            )));
        }
        if self.samples < 2 || !self.force_delay_s.is_finite() {
            return Err(DatasetError::Config("sampling: at least two samples and a finite delay".into()));
        }
        Ok(())
    }
}

/// Noise of the measurements: independent per channel plus a common-mode part shared by the
/// six channels (a shared amplifier or supply), so the channels' covariance is
/// `sigma^2 I + sigma_c^2 1 1^T`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ForceNoise {
    /// Independent noise per channel and sample, N.
    pub sigma_n: f64,
    /// Common-mode noise, N.
    pub common_sigma_n: f64,
    /// Noise of a leg position reading, m.
    pub leg_sigma_m: f64,
}

impl ForceNoise {
    /// No noise at all.
    pub fn none() -> Self {
        Self { sigma_n: 0.0, common_sigma_n: 0.0, leg_sigma_m: 0.0 }
    }

    /// The 6 x 6 covariance of one sample's forces.
    pub fn covariance(&self) -> DMatrix<f64> {
        let c = self.common_sigma_n * self.common_sigma_n;
        DMatrix::from_fn(6, 6, |i, j| c + if i == j { self.sigma_n * self.sigma_n } else { 0.0 })
    }

    fn draw(&self, rng: &mut ChaCha8Rng) -> Vector6<f64> {
        let common: f64 = rng.sample::<f64, _>(StandardNormal) * self.common_sigma_n;
        Vector6::from_fn(|_, _| rng.sample::<f64, _>(StandardNormal) * self.sigma_n + common)
    }

    fn validate(&self) -> Result<()> {
        for (name, v) in
            [("sigma_n", self.sigma_n), ("common_sigma_n", self.common_sigma_n), ("leg_sigma_m", self.leg_sigma_m)]
        {
            if !(v >= 0.0 && v.is_finite()) {
                return Err(DatasetError::Config(format!("noise: {name} = {v} must be finite and >= 0")));
            }
        }
        Ok(())
    }
}

/// A sampled dynamic record: leg positions and forces (sensor or actuator), and the true
/// motion at the leg samples for checks.
#[derive(Clone, Debug)]
pub struct DynamicRecord {
    /// Measured leg extensions (6 channels), m.
    pub legs: SampledSignal,
    /// Measured forces (6 channels), N.
    pub forces: SampledSignal,
    /// The true motion at the leg samples.
    pub true_states: Vec<MotionState>,
    /// The noise-free forces at the force samples.
    pub true_forces: DMatrix<f64>,
}

/// A motion in pose coordinates: position, velocity, acceleration at a time.
pub type Motion<'a> = &'a dyn Fn(f64) -> TrajectorySample;

/// The true state of a motion at `t_s`.
pub fn state_at(motion: Motion<'_>, t_s: f64) -> Result<MotionState> {
    let s = motion(t_s);
    if s.x.len() != 6 || s.xd.len() != 6 || s.xdd.len() != 6 {
        return Err(DatasetError::Config(format!("a platform motion has 6 pose coordinates, this one {}", s.x.len())));
    }
    let a = |v: &[f64]| -> [f64; 6] { std::array::from_fn(|i| v[i]) };
    MotionState::from_coordinates(&a(&s.x), &a(&s.xd), &a(&s.xdd))
        .map_err(|e| DatasetError::Input(format!("t = {t_s:.4} s: {e}")))
}

/// The wrench `(F, M)` the supports must exert on `body` (given in the flange frame) at the
/// flange origin, base frame, computed directly about the centre of gravity:
/// `F = m (a_C - g)`, `M = I_C,w alpha + w x I_C,w w + (R c) x F`.
pub(crate) fn support_wrench_base(
    body: &RigidBody,
    s: &MotionState,
    gravity_m_s2: &Vector3<f64>,
) -> (Vector3<f64>, Vector3<f64>) {
    let r: Matrix3<f64> = s.pose.rotation.to_rotation_matrix().into_inner();
    let c = r * body.com_m;
    let w = s.omega_rad_s;
    let a_c = s.acceleration_m_s2 + s.alpha_rad_s2.cross(&c) + w.cross(&w.cross(&c));
    let f = (a_c - gravity_m_s2) * body.mass_kg;
    let i_w = r * body.inertia_com_kgm2 * r.transpose();
    let m = i_w * s.alpha_rad_s2 + w.cross(&(i_w * w)) + c.cross(&f);
    (f, m)
}

/// The payload validation's bodies: `steps` payloads of `step_kg` each (the source: five steps
/// of 19.93 kg, up to 99.65 kg), stacked as steel discs of radius 0.15 m on the end-effector,
/// the first centred at `(0.01, -0.005, 0.16)` m in the flange frame, each disc 0.036 m high per
/// 19.93 kg. Element `k` is the total payload of step `k + 1`.
pub fn payload_steps(steps: usize, step_kg: f64) -> Vec<RigidBody> {
    let radius_m: f64 = 0.15;
    let height_per_kg_m = 0.036 / 19.93;
    (1..=steps)
        .map(|k| {
            let m = step_kg * k as f64;
            let h = height_per_kg_m * m;
            let ixx = m * (3.0 * radius_m * radius_m + h * h) / 12.0;
            let izz = 0.5 * m * radius_m * radius_m;
            RigidBody {
                mass_kg: m,
                com_m: Vector3::new(0.01, -0.005, 0.16 + 0.5 * h),
                inertia_com_kgm2: Matrix3::from_diagonal(&Vector3::new(ixx, ixx, izz)),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrocal_robot::dynamics::{newton_euler_wrench, BodyState};

    #[test]
    fn base_frame_wrench_matches_the_body_frame_one() {
        let body = RigidBody {
            mass_kg: 12.0,
            com_m: Vector3::new(0.02, -0.01, 0.1),
            inertia_com_kgm2: Matrix3::new(0.3, 0.01, 0.0, 0.01, 0.25, 0.02, 0.0, 0.02, 0.2),
        };
        let s = MotionState::from_coordinates(
            &[0.01, 0.02, 0.8, 0.1, -0.05, 0.2],
            &[0.1, -0.05, 0.02, 0.3, 0.2, -0.4],
            &[1.0, 0.5, -0.3, 2.0, -1.0, 0.5],
        )
        .unwrap();
        let g = ferrocal_robot::dynamics::GRAVITY_M_S2;
        let (f, m) = support_wrench_base(&body, &s, &g);
        let b: BodyState = s.body(&g);
        let w = newton_euler_wrench(&body, &b);
        let r = s.pose.rotation;
        let fb = r * Vector3::new(w[0], w[1], w[2]);
        let mb = r * Vector3::new(w[3], w[4], w[5]);
        assert!((f - fb).norm() < 1e-9 && (m - mb).norm() < 1e-9);
    }

    #[test]
    fn payload_steps_add_up() {
        let p = payload_steps(5, 19.93);
        assert_eq!(p.len(), 5);
        assert!((p[4].mass_kg - 99.65).abs() < 1e-9);
        p.iter().for_each(|b| b.validate("payload").unwrap());
    }
}
