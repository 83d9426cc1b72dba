//! The hexapod's actuator forces: a rigid platform body, friction in the legs and in the passive
//! joints.
//!
//! The actuators must exert on the platform (through the legs, `J^-T Q`) the Newton-Euler wrench
//! of the platform body plus the wrench that overcomes the passive joints' viscous friction.
//! That friction is given by its dissipation function (leg angular velocities
//! `w_L,i = u_i x (v + w x r_i) / L_i`, no spin about the leg axis):
//!
//! ```text
//! D(t) = 1/2 sum_i ( d_b |w_L,i|^2 + d_p |w_L,i - w|^2 )
//! ```
//!
//! whose gradient with respect to the twist `t = (v, w)` is taken here by central differences
//! (exact for a quadratic). Each leg adds its own viscous and Coulomb friction:
//! `Q_i += f_v,i q_i' + f_c,i sign(q_i')`.

use ferrocal_robot::dynamics::{MotionState, RigidBody, GRAVITY_M_S2};
use ferrocal_robot::parallel::{presets, Hexapod};
use nalgebra::{Matrix3, Matrix6, Point3, Vector3, Vector6};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::platform::record;
use super::{support_wrench_base, DynamicRecord, ForceNoise, Motion, Sampling};
use crate::error::{DatasetError, Result};

/// Unit leg directions, arms `R b_i` and lengths at one pose.
type LegGeometry = ([Vector3<f64>; 6], [Vector3<f64>; 6], [f64; 6]);

/// Friction of the hexapod's joints.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct HexapodFriction {
    /// Viscous friction of each leg's actuator, N s/m.
    pub viscous_ns_m: [f64; 6],
    /// Coulomb friction of each leg's actuator, N.
    pub coulomb_n: [f64; 6],
    /// Viscous friction of each base (universal) joint, N m s/rad.
    pub base_joint_nms_rad: f64,
    /// Viscous friction of each platform (spherical) joint, N m s/rad.
    pub platform_joint_nms_rad: f64,
}

/// The hexapod with its platform body and friction.
#[derive(Clone, Debug, PartialEq)]
pub struct HexapodSim {
    /// The hexapod.
    pub hexapod: Hexapod,
    /// Everything the platform carries, flange frame.
    pub platform: RigidBody,
    /// Friction.
    pub friction: HexapodFriction,
    /// Measurement noise (forces: the actuators' force readings).
    pub noise: ForceNoise,
    /// Gravity, base frame, m/s^2.
    pub gravity_m_s2: Vector3<f64>,
}

impl HexapodSim {
    /// The project's test rig: the `hexapod` preset carrying a 45 kg platform (our choice, in the
    /// range of the PaLiDA's), leg friction 200 to 300 N s/m and 15 to 25 N, passive joints
    /// 0.8 and 0.5 N m s/rad; actuator force noise 3 N per leg plus 1 N common mode, leg
    /// readings 1 um.
    pub fn preset() -> Self {
        Self {
            hexapod: presets::hexapod(),
            platform: RigidBody {
                mass_kg: 45.0,
                com_m: Vector3::new(0.004, -0.003, 0.06),
                inertia_com_kgm2: Matrix3::new(1.1, 0.02, -0.01, 0.02, 1.05, 0.015, -0.01, 0.015, 1.9),
            },
            friction: HexapodFriction {
                viscous_ns_m: [220.0, 260.0, 240.0, 300.0, 210.0, 280.0],
                coulomb_n: [18.0, 22.0, 15.0, 25.0, 20.0, 17.0],
                base_joint_nms_rad: 0.8,
                platform_joint_nms_rad: 0.5,
            },
            noise: ForceNoise { sigma_n: 3.0, common_sigma_n: 1.0, leg_sigma_m: 1e-6 },
            gravity_m_s2: GRAVITY_M_S2,
        }
    }

    /// The true parameters in the order of `ferrocal_robot::dynamics::HexapodDynamics`: the
    /// platform's ten inertial parameters (flange frame, inertia about the flange origin), six
    /// viscous and six Coulomb leg frictions, base and platform joint friction.
    pub fn truth(&self) -> Vec<f64> {
        let mut p = self.platform.parameters().to_vec();
        p.extend(self.friction.viscous_ns_m);
        p.extend(self.friction.coulomb_n);
        p.push(self.friction.base_joint_nms_rad);
        p.push(self.friction.platform_joint_nms_rad);
        p
    }

    /// Checks the rig.
    pub fn validate(&self) -> Result<()> {
        self.hexapod.validate().map_err(|e| DatasetError::Config(format!("hexapod: {e}")))?;
        self.platform.validate("platform body").map_err(|e| DatasetError::Config(e.to_string()))?;
        self.noise.validate()
    }

    /// Leg geometry at a pose: unit directions `u_i`, arms `r_i = R b_i`, lengths.
    fn legs(&self, s: &MotionState) -> Result<LegGeometry> {
        let mut u = [Vector3::zeros(); 6];
        let mut r = [Vector3::zeros(); 6];
        let mut l = [0.0; 6];
        for (i, leg) in self.hexapod.legs.iter().enumerate() {
            let b = s.pose.transform_point(&Point3::from(leg.b0_m)).coords;
            let d = b - leg.a_m;
            l[i] = d.norm();
            if l[i].is_nan() || l[i] <= 1e-9 {
                return Err(DatasetError::Input(format!("leg {} has no length", i + 1)));
            }
            u[i] = d / l[i];
            r[i] = b - s.pose.translation.vector;
        }
        Ok((u, r, l))
    }

    /// The passive joints' dissipation at a twist `(v, w)`.
    fn dissipation(&self, u: &[Vector3<f64>; 6], r: &[Vector3<f64>; 6], l: &[f64; 6], t: &Vector6<f64>) -> f64 {
        let v = Vector3::new(t[0], t[1], t[2]);
        let w = Vector3::new(t[3], t[4], t[5]);
        (0..6)
            .map(|i| {
                let wl = u[i].cross(&(v + w.cross(&r[i]))) / l[i];
                0.5 * (self.friction.base_joint_nms_rad * wl.norm_squared()
                    + self.friction.platform_joint_nms_rad * (wl - w).norm_squared())
            })
            .sum()
    }

    /// Noise-free actuator forces at a state (positive: the leg pushes the platform).
    pub fn actuator_forces(&self, s: &MotionState) -> Result<Vector6<f64>> {
        let (u, r, l) = self.legs(s)?;
        let (f, m) = support_wrench_base(&self.platform, s, &self.gravity_m_s2);
        let twist = s.twist();
        let h = 1e-3;
        let grad = Vector6::from_fn(|k, _| {
            let mut tp = twist;
            let mut tm = twist;
            tp[k] += h;
            tm[k] -= h;
            (self.dissipation(&u, &r, &l, &tp) - self.dissipation(&u, &r, &l, &tm)) / (2.0 * h)
        });
        let wrench = Vector6::new(f.x, f.y, f.z, m.x, m.y, m.z) + grad;
        // Column i of J^-T: the wrench of a unit push of leg i.
        let mut jit = Matrix6::zeros();
        for i in 0..6 {
            let mo = r[i].cross(&u[i]);
            jit.set_column(i, &Vector6::new(u[i].x, u[i].y, u[i].z, mo.x, mo.y, mo.z));
        }
        let mut q = jit
            .lu()
            .solve(&wrench)
            .ok_or_else(|| DatasetError::Input("the hexapod is singular at this pose".into()))?;
        for i in 0..6 {
            let qd = u[i].dot(&(s.velocity_m_s + s.omega_rad_s.cross(&r[i])));
            let sign = if qd > 0.0 {
                1.0
            } else if qd < 0.0 {
                -1.0
            } else {
                0.0
            };
            q[i] += self.friction.viscous_ns_m[i] * qd + self.friction.coulomb_n[i] * sign;
        }
        Ok(q)
    }

    /// A sampled trajectory: leg positions and actuator forces (see [`Sampling`]). Fails when the
    /// motion drives a leg beyond its limits.
    pub fn record(&self, motion: Motion<'_>, sampling: &Sampling, rng: &mut ChaCha8Rng) -> Result<DynamicRecord> {
        self.validate()?;
        record(&self.hexapod, &self.noise, motion, sampling, rng, "actuator forces", &|s| self.actuator_forces(s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrocal_robot::dynamics::HexapodDynamics;

    #[test]
    fn simulator_agrees_with_the_regressor_at_the_true_parameters() {
        let sim = HexapodSim::preset();
        let dynm = HexapodDynamics::new(&sim.hexapod).unwrap();
        let p = sim.truth();
        for (x, xd, xdd) in [
            (
                [0.02, -0.01, 0.82, 0.05, -0.04, 0.1],
                [0.05, 0.02, -0.03, 0.2, -0.3, 0.1],
                [0.4, -0.2, 0.3, 1.5, 0.7, -1.1],
            ),
            (
                [-0.03, 0.02, 0.78, -0.06, 0.03, -0.08],
                [-0.02, -0.06, 0.01, -0.1, 0.25, -0.2],
                [-0.3, 0.6, -0.1, -0.5, 1.2, 0.9],
            ),
        ] {
            let s = MotionState::from_coordinates(&x, &xd, &xdd).unwrap();
            let q = sim.actuator_forces(&s).unwrap();
            let y = dynm.actuator_forces(&s, &p).unwrap();
            assert!((q - y).norm() < 1e-6 * q.norm().max(1.0), "{q} vs {y}");
        }
    }
}
