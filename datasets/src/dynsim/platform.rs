//! The force-sensing end-effector: a body on six 1-DOF force sensors on a hexapod's platform.
//!
//! Sensor forces of one sample (positive in compression):
//!
//! ```text
//! f_q = f_q0 + J_P^T (w_support + w_K) + noise
//! ```
//!
//! with `w_support` the wrench the sensors must exert on the body (Newton-Euler about the centre
//! of gravity, moved to the flange origin, flange axes) and `w_K` the platform's deformation,
//! linear in the platform's position `(x, y)` relative to the reference and in the Gibbs vector
//! `phi` of its orientation:
//!
//! ```text
//! w_K = [ k0 (x, y, 0) + k2 (-phi_y, phi_x, 0) ;  k1 (-y, x, 0) + k3 (phi_x, phi_y, 0) ]
//! ```
//!
//! (forces N, moments N m). `J_P^T` is applied by solving `J_P^-T f = w` with the wrench matrix
//! of the strut geometry, built here.

use ferrocal_calib::dynamics::force_sensor::{SensorRegressor, SensorTruth};
use ferrocal_calib::dynamics::signals::SampledSignal;
use ferrocal_robot::dynamics::{MotionState, RigidBody, SensorFrame, GRAVITY_M_S2};
use ferrocal_robot::parallel::{presets, Hexapod};
use ferrocal_robot::{Kinematics, Pose};
use nalgebra::{DMatrix, Matrix3, Matrix6, Vector3, Vector6};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

use super::{state_at, support_wrench_base, DynamicRecord, ForceNoise, Motion, Sampling};
use crate::error::{DatasetError, Result};

/// The platform's pose-dependent deformation, as a wrench on the sensors (see the module
/// documentation).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Deformation {
    /// Force per position, N/m.
    pub k0_n_m: f64,
    /// Moment per position, N m/m.
    pub k1_nm_m: f64,
    /// Force per Gibbs-vector unit, N.
    pub k2_n: f64,
    /// Moment per Gibbs-vector unit, N m.
    pub k3_nm: f64,
    /// Position the deformation is measured from (the hexapod's home), base frame, m.
    pub reference_xy_m: [f64; 2],
}

impl Deformation {
    /// No deformation.
    pub fn none() -> Self {
        Self { k0_n_m: 0.0, k1_nm_m: 0.0, k2_n: 0.0, k3_nm: 0.0, reference_xy_m: [0.0, 0.0] }
    }

    /// The deformation wrench at a pose, flange axes.
    pub fn wrench(&self, pose: &Pose) -> Result<Vector6<f64>> {
        let q = pose.rotation;
        if q.w.abs() < 1e-9 {
            return Err(DatasetError::Input(
                "the platform is turned by half a turn: its Gibbs vector is infinite".into(),
            ));
        }
        let phi = q.imag() / q.w;
        let p = pose.translation.vector;
        let (x, y) = (p.x - self.reference_xy_m[0], p.y - self.reference_xy_m[1]);
        Ok(Vector6::new(
            self.k0_n_m * x - self.k2_n * phi.y,
            self.k0_n_m * y + self.k2_n * phi.x,
            0.0,
            -self.k1_nm_m * y + self.k3_nm * phi.x,
            self.k1_nm_m * x + self.k3_nm * phi.y,
            0.0,
        ))
    }
}

/// The force-sensing end-effector on its hexapod.
#[derive(Clone, Debug, PartialEq)]
pub struct PlatformSim {
    /// The hexapod that moves the platform (leg positions, reachability).
    pub hexapod: Hexapod,
    /// The sensor framework.
    pub sensors: SensorFrame,
    /// The carried body (end-effector, tool, payload), flange frame.
    pub body: RigidBody,
    /// Sensor offsets, N.
    pub offsets_n: [f64; 6],
    /// The platform's deformation.
    pub deformation: Deformation,
    /// Measurement noise.
    pub noise: ForceNoise,
    /// Gravity, base frame, m/s^2.
    pub gravity_m_s2: Vector3<f64>,
    /// Sensor cross-talk: `crosstalk[i][j]` is the fraction of sensor `j + 1`'s load that sensor
    /// `i + 1` also reads (the diagonal is ignored; all zero: none). The offsets are not loads
    /// and are not passed on.
    pub crosstalk: [[f64; 6]; 6],
}

/// A quasi-static record: the mean of `samples_per_pose` sensor readings at each pose.
#[derive(Clone, Debug)]
pub struct StaticRecord {
    /// The poses (`T_base_flange`).
    pub poses: Vec<Pose>,
    /// Mean sensor forces per pose (poses x 6), N.
    pub forces_n: DMatrix<f64>,
    /// Standard deviation of one sample per pose and sensor, from the samples (poses x 6), N.
    pub sample_std_n: DMatrix<f64>,
    /// Samples averaged per pose.
    pub samples_per_pose: usize,
}

/// The source's end-effector mass, kg (Friedrich & Ihlenfeldt 2021).
pub const SOURCE_MASS_KG: f64 = 33.78;
/// The source's centre-of-gravity height, m.
pub const SOURCE_COG_Z_M: f64 = 0.1089;
/// The source's "empirical" mass without orientation terms, kg.
pub const SOURCE_EMPIRICAL_MASS_KG: f64 = 30.36;
/// The source's "empirical" centre-of-gravity height, m.
pub const SOURCE_EMPIRICAL_COG_Z_M: f64 = 0.0749;

impl PlatformSim {
    /// The project's test rig (our choice; the source publishes only the mass, centre of gravity
    /// and the size of the effects): the `hexapod` preset, [`SensorFrame::preset`], an
    /// end-effector of the source's 33.78 kg with its centre of gravity 108.9 mm above the
    /// flange, offsets of up to 15 N, and a deformation of up to 13 N (RMS 5 N) per sensor over
    /// the quasi-static pose box (the source saw +-20 N). Its orientation terms are sized so
    /// that, to first order in the tilt, a model without them absorbs them into the source's
    /// empirical mass and centre of gravity: `k2 = 2 g (m_emp - m)` and
    /// `k3 = 2 g (m c - m_emp c_emp)` (the sensors carry a lateral force `2 g m phi` and a moment
    /// `-2 g m c_z phi` from gravity under a tilt with Gibbs vector `phi`; a model without
    /// orientation terms reads `k2 phi` and `k3 phi` as more of them). Noise: 1.5 N per sensor
    /// and sample plus 0.8 N common mode, 1 um per leg reading.
    pub fn preset() -> Self {
        let g = -GRAVITY_M_S2.z;
        let k2_n = 2.0 * g * (SOURCE_EMPIRICAL_MASS_KG - SOURCE_MASS_KG);
        let k3_nm = 2.0 * g * (SOURCE_MASS_KG * SOURCE_COG_Z_M - SOURCE_EMPIRICAL_MASS_KG * SOURCE_EMPIRICAL_COG_Z_M);
        let hexapod = presets::hexapod();
        let home = hexapod.home.translation.vector;
        Self {
            hexapod,
            sensors: SensorFrame::preset(),
            body: RigidBody {
                mass_kg: SOURCE_MASS_KG,
                com_m: Vector3::new(0.0021, -0.0034, SOURCE_COG_Z_M),
                inertia_com_kgm2: Matrix3::new(0.42, 0.012, -0.004, 0.012, 0.40, 0.006, -0.004, 0.006, 0.28),
            },
            offsets_n: [12.5, -8.0, 3.2, -15.1, 6.7, 9.9],
            deformation: Deformation { k0_n_m: 150.0, k1_nm_m: 40.0, k2_n, k3_nm, reference_xy_m: [home.x, home.y] },
            noise: ForceNoise { sigma_n: 1.5, common_sigma_n: 0.8, leg_sigma_m: 1e-6 },
            gravity_m_s2: GRAVITY_M_S2,
            crosstalk: [[0.0; 6]; 6],
        }
    }

    /// The same rig carrying an extra rigidly mounted payload (flange frame).
    pub fn with_payload(&self, payload: &RigidBody) -> Self {
        Self { body: self.body.combined(payload), ..self.clone() }
    }

    /// The regressor of the rig's sensor framework (its sensors and the deformation's reference
    /// point).
    pub fn sensor_regressor(&self) -> ferrocal_calib::Result<SensorRegressor> {
        SensorRegressor::new(self.sensors.clone(), self.deformation.reference_xy_m)
    }

    /// The true values for comparison with an identification.
    pub fn truth(&self) -> SensorTruth {
        let d = &self.deformation;
        SensorTruth { body: self.body, offsets_n: self.offsets_n, deformation: [d.k0_n_m, d.k1_nm_m, d.k2_n, d.k3_nm] }
    }

    /// Checks the rig.
    pub fn validate(&self) -> Result<()> {
        self.hexapod.validate().map_err(|e| DatasetError::Config(format!("hexapod: {e}")))?;
        self.sensors.validate().map_err(|e| DatasetError::Config(format!("sensor framework: {e}")))?;
        self.body.validate("end-effector body").map_err(|e| DatasetError::Config(e.to_string()))?;
        self.noise.validate()?;
        if self.crosstalk.iter().flatten().any(|v| !v.is_finite() || v.abs() > 0.5) {
            return Err(DatasetError::Config("sensor cross-talk fractions must be finite and below 0.5".into()));
        }
        if self.offsets_n.iter().any(|v| !v.is_finite()) {
            return Err(DatasetError::Config("sensor offsets must be finite".into()));
        }
        Ok(())
    }

    /// `J_P^-T` built from the strut geometry: column `i` is `[n_i; h_i x n_i]`.
    fn wrench_matrix(&self) -> Matrix6<f64> {
        let mut w = Matrix6::zeros();
        for (i, s) in self.sensors.struts.iter().enumerate() {
            let d = s.head_m - s.base_m;
            let n = d / d.norm();
            let m = s.head_m.cross(&n);
            for r in 0..3 {
                w[(r, i)] = n[r];
                w[(3 + r, i)] = m[r];
            }
        }
        w
    }

    /// Noise-free sensor forces at a state.
    pub fn sensor_forces(&self, s: &MotionState) -> Result<Vector6<f64>> {
        let (f, m) = support_wrench_base(&self.body, s, &self.gravity_m_s2);
        let rt = s.pose.rotation.inverse();
        let (fb, mb) = (rt * f, rt * m);
        let w = Vector6::new(fb.x, fb.y, fb.z, mb.x, mb.y, mb.z) + self.deformation.wrench(&s.pose)?;
        let forces = self
            .wrench_matrix()
            .lu()
            .solve(&w)
            .ok_or_else(|| DatasetError::Config("the sensor framework cannot carry every wrench".into()))?;
        // What each sensor reads: its own load and the fractions of the others' it picks up.
        let read = Vector6::from_fn(|i, _| {
            forces[i] + (0..6).filter(|&j| j != i).map(|j| self.crosstalk[i][j] * forces[j]).sum::<f64>()
        });
        Ok(read + Vector6::from_column_slice(&self.offsets_n))
    }

    /// Leg extensions at a flange pose; fails outside the legs' limits, naming the leg.
    pub fn leg_positions(&self, flange: &Pose, t_s: f64) -> Result<[f64; 6]> {
        leg_positions(&self.hexapod, flange, t_s)
    }

    /// [`static_record`](Self::static_record) with the noise drawn from a ChaCha8 generator
    /// seeded with `seed`.
    pub fn static_record_seeded(&self, poses: &[Pose], samples_per_pose: usize, seed: u64) -> Result<StaticRecord> {
        use rand::SeedableRng;
        self.static_record(poses, samples_per_pose, &mut ChaCha8Rng::seed_from_u64(seed))
    }

    /// Quasi-static record: at each pose, `samples_per_pose` noisy readings at rest, averaged.
    pub fn static_record(&self, poses: &[Pose], samples_per_pose: usize, rng: &mut ChaCha8Rng) -> Result<StaticRecord> {
        self.validate()?;
        if samples_per_pose == 0 {
            return Err(DatasetError::Config("at least one sample per pose".into()));
        }
        let mut forces = DMatrix::zeros(poses.len(), 6);
        let mut sd = DMatrix::zeros(poses.len(), 6);
        for (k, p) in poses.iter().enumerate() {
            leg_positions(&self.hexapod, p, 0.0).map_err(|e| DatasetError::Input(format!("pose {}: {e}", k + 1)))?;
            let f0 = self.sensor_forces(&MotionState::at_rest(*p))?;
            let mut sum = Vector6::zeros();
            let mut sq = Vector6::zeros();
            for _ in 0..samples_per_pose {
                let v = f0 + self.noise.draw(rng);
                sum += v;
                sq += v.component_mul(&v);
            }
            let n = samples_per_pose as f64;
            let mean = sum / n;
            for c in 0..6 {
                forces[(k, c)] = mean[c];
                sd[(k, c)] = if samples_per_pose > 1 {
                    ((sq[c] - n * mean[c] * mean[c]) / (n - 1.0)).max(0.0).sqrt()
                } else {
                    0.0
                };
            }
        }
        Ok(StaticRecord { poses: poses.to_vec(), forces_n: forces, sample_std_n: sd, samples_per_pose })
    }

    /// A sampled trajectory: leg positions at the legs' clock, sensor forces at the forces'
    /// clock (see [`Sampling`]). Fails when the motion drives a leg beyond its limits.
    pub fn record(&self, motion: Motion<'_>, sampling: &Sampling, rng: &mut ChaCha8Rng) -> Result<DynamicRecord> {
        self.validate()?;
        record(&self.hexapod, &self.noise, motion, sampling, rng, "sensor forces", &|s| self.sensor_forces(s))
    }
}

/// Leg extensions of `hexapod` at a flange pose; fails outside the limits, naming the leg.
pub(crate) fn leg_positions(hexapod: &Hexapod, flange: &Pose, t_s: f64) -> Result<[f64; 6]> {
    let q = hexapod
        .inverse_unchecked(&(flange * hexapod.tool))
        .map_err(|e| DatasetError::Input(format!("t = {t_s:.4} s: the pose is not reachable: {e}")))?;
    let limits = hexapod.joint_limits();
    for (i, (v, l)) in q.iter().zip(&limits).enumerate() {
        if !l.contains(*v, 0.0) {
            return Err(DatasetError::Input(format!(
                "t = {t_s:.4} s: the motion drives leg {} to {:.4} m, outside its stroke [{:.4}, {:.4}] m",
                i + 1,
                v,
                l.lower,
                l.upper
            )));
        }
    }
    Ok(std::array::from_fn(|i| q[i]))
}

/// The shared sampling loop of both simulators.
pub(crate) fn record(
    hexapod: &Hexapod,
    noise: &ForceNoise,
    motion: Motion<'_>,
    sampling: &Sampling,
    rng: &mut ChaCha8Rng,
    force_name: &str,
    forces_at: &dyn Fn(&MotionState) -> Result<Vector6<f64>>,
) -> Result<DynamicRecord> {
    sampling.validate()?;
    let n = sampling.samples;
    let force_rate = sampling.force_rate_hz.unwrap_or(sampling.rate_hz);
    let mut legs = DMatrix::zeros(n, 6);
    let mut forces = DMatrix::zeros(n, 6);
    let mut true_forces = DMatrix::zeros(n, 6);
    let mut true_states = Vec::with_capacity(n);
    for k in 0..n {
        let t = k as f64 / sampling.rate_hz;
        let s = state_at(motion, t)?;
        let q = leg_positions(hexapod, &s.pose, t)?;
        for i in 0..6 {
            legs[(k, i)] = q[i] + rng.sample::<f64, _>(StandardNormal) * noise.leg_sigma_m;
        }
        true_states.push(s);
        let tf = sampling.force_delay_s + k as f64 / force_rate;
        let sf = if tf == t { s } else { state_at(motion, tf)? };
        let f = forces_at(&sf)?;
        let e = noise.draw(rng);
        for i in 0..6 {
            true_forces[(k, i)] = f[i];
            forces[(k, i)] = f[i] + e[i];
        }
    }
    let to_err = |e: ferrocal_calib::CalibError| DatasetError::Input(e.to_string());
    Ok(DynamicRecord {
        legs: SampledSignal::uniform("leg positions", 0.0, sampling.rate_hz, legs).map_err(to_err)?,
        forces: SampledSignal::uniform(force_name, sampling.force_delay_s, force_rate, forces).map_err(to_err)?,
        true_states,
        true_forces,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrocal_calib::dynamics::force_sensor::{SensorModel, SensorRegressor};
    use nalgebra::DVector;

    /// The simulator and the identification's regressor, written independently, agree on
    /// noise-free data when the regressor gets the true parameters.
    #[test]
    fn simulator_agrees_with_the_regressor_at_the_true_parameters() {
        let sim = PlatformSim::preset();
        let reg = SensorRegressor::new(sim.sensors.clone(), sim.deformation.reference_xy_m).unwrap();
        let truth = sim.truth();
        let s = MotionState::from_coordinates(
            &[0.03, -0.02, 0.82, 0.08, -0.06, 0.1],
            &[0.05, 0.02, -0.01, 0.2, -0.3, 0.1],
            &[0.4, -0.2, 0.3, 1.5, 0.7, -1.1],
        )
        .unwrap();
        let f = sim.sensor_forces(&s).unwrap();
        for model in [4u8, 5, 8, 9] {
            let m = SensorModel::new(model).unwrap();
            let u: Vec<f64> = reg.true_values(m, &truth).into_iter().map(|v| v.unwrap()).collect();
            let state = if m.is_dynamic() { s } else { MotionState::at_rest(s.pose) };
            let fm = if m.is_dynamic() { f } else { sim.sensor_forces(&state).unwrap() };
            let pred = reg.rows(m, &state).unwrap() * DVector::from_column_slice(&u);
            for i in 0..6 {
                assert!((pred[i] - fm[i]).abs() < 1e-8, "{m}: sensor {} {} vs {}", i + 1, pred[i], fm[i]);
            }
        }
    }
}
