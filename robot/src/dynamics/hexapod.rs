//! The hexapod's actuator forces, linear in 10 rigid-body and 14 friction parameters
//! (Abdellatif & Heimann 2009, written for the [`Hexapod`] model).
//!
//! Leg `i` joins the base point `A_i` to the platform point `B_i = p + R b_i`; `L_i = |B_i - A_i|`,
//! `u_i = (B_i - A_i) / L_i`, `r_i = R b_i`; the actuator extends the leg by `q_i = L_i - L0_i`
//! with `q_i' = u_i . (v + w x r_i)`, i.e. `q' = J^-1 t` with rows `[u_i^T, (r_i x u_i)^T]` and
//! the twist `t = (v, w)`. An actuator force `Q_i` (positive: the leg pushes the platform along
//! `u_i`) gives the platform the wrench `J^-T Q`, so
//!
//! ```text
//! Q_a = J^T [ diag(R, R) Y(x, t, t') p_rb + (sum_i J_b,i^T J_b,i t) d_b + (sum_i J_p,i^T J_p,i t) d_p ]
//!       + diag(q') f_v + diag(sign q') f_c
//! ```
//!
//! - `p_rb` (10): the moving platform's inertial parameters in the flange frame (whatever rides
//!   on it: end-effector, payload, the point masses of the legs' moving parts at `B_i`, all
//!   merge into these ten);
//! - `f_v`, `f_c` (6 + 6): viscous and Coulomb friction of each leg's prismatic actuator;
//! - `d_b`, `d_p` (2): viscous friction of the passive joints, common to the six base (universal)
//!   joints and to the six platform (spherical) joints. A leg does not spin about its axis, so
//!   its angular velocity is `w_L,i = u_i x (v + w x r_i) / L_i = J_b,i t`; the base joint turns
//!   by `w_L,i`, the platform joint by `w_L,i - w = J_p,i t`. The dissipated power
//!   `d_b |w_L|^2 + d_p |w_L - w|^2` gives the generalised forces `J^T J t d` above.
//!
//! Total: 24 parameters (the PaLiDA's 10 + 14, with this choice of the two extra ones).

use nalgebra::{Matrix6, SMatrix, Vector3, Vector6};

use super::motion::MotionState;
use super::rigid::{body_regressor, RIGID_BODY_NAMES};
use super::GRAVITY_M_S2;
use crate::error::{Result, RobotError};
use crate::geometry::skew;
use crate::parallel::Hexapod;

/// Names of the 14 friction parameters.
pub const HEXAPOD_FRICTION_NAMES: [&str; 14] = [
    "fv1_Ns_m",
    "fv2_Ns_m",
    "fv3_Ns_m",
    "fv4_Ns_m",
    "fv5_Ns_m",
    "fv6_Ns_m",
    "fc1_N",
    "fc2_N",
    "fc3_N",
    "fc4_N",
    "fc5_N",
    "fc6_N",
    "db_Nms_rad",
    "dp_Nms_rad",
];

/// Number of parameters of [`HexapodDynamics::regressor`].
pub const HEXAPOD_PARAMETERS: usize = 24;

/// Leg quantities at one state, base frame.
#[derive(Clone, Debug, PartialEq)]
pub struct LegKinematics {
    /// Leg extensions `q_i = L_i - L0_i`, m.
    pub q_m: [f64; 6],
    /// Extension rates, m/s.
    pub qd_m_s: [f64; 6],
    /// Leg lengths, m.
    pub length_m: [f64; 6],
    /// Unit leg directions `u_i` (base to platform).
    pub direction: [Vector3<f64>; 6],
    /// `r_i = R b_i`, m.
    pub arm_m: [Vector3<f64>; 6],
    /// Leg angular velocities (no spin about the leg axis), rad/s.
    pub leg_omega_rad_s: [Vector3<f64>; 6],
    /// `J^-1` (rows `[u_i^T, (r_i x u_i)^T]`): extension rates per twist.
    pub inverse_jacobian: Matrix6<f64>,
}

/// The hexapod's inverse dynamics in regressor form.
#[derive(Clone, Debug, PartialEq)]
pub struct HexapodDynamics {
    base_m: [Vector3<f64>; 6],
    platform_m: [Vector3<f64>; 6],
    length0_m: [f64; 6],
    /// Speeds below this count as standstill for the Coulomb columns (`sign(0) = 0`), m/s.
    pub coulomb_deadband_m_s: f64,
}

impl HexapodDynamics {
    /// The dynamics of a hexapod model (its `home` and `tool` do not matter here: states are
    /// flange poses).
    pub fn new(model: &Hexapod) -> Result<Self> {
        model.validate()?;
        let mut base_m = [Vector3::zeros(); 6];
        let mut platform_m = [Vector3::zeros(); 6];
        let mut length0_m = [0.0; 6];
        for (i, l) in model.legs.iter().enumerate() {
            base_m[i] = l.a_m;
            platform_m[i] = l.b0_m;
            length0_m[i] = l.length0_m;
        }
        Ok(Self { base_m, platform_m, length0_m, coulomb_deadband_m_s: 1e-9 })
    }

    /// Every parameter name: the ten rigid-body ones, then the fourteen friction ones.
    pub fn parameter_names() -> Vec<String> {
        RIGID_BODY_NAMES.iter().chain(HEXAPOD_FRICTION_NAMES.iter()).map(|s| s.to_string()).collect()
    }

    /// Leg quantities at a state; fails at a singular configuration.
    pub fn legs(&self, s: &MotionState) -> Result<LegKinematics> {
        let rot = s.pose.rotation;
        let p = s.pose.translation.vector;
        let mut out = LegKinematics {
            q_m: [0.0; 6],
            qd_m_s: [0.0; 6],
            length_m: [0.0; 6],
            direction: [Vector3::zeros(); 6],
            arm_m: [Vector3::zeros(); 6],
            leg_omega_rad_s: [Vector3::zeros(); 6],
            inverse_jacobian: Matrix6::zeros(),
        };
        for i in 0..6 {
            let r = rot * self.platform_m[i];
            let d = p + r - self.base_m[i];
            let l = d.norm();
            if l.is_nan() || l <= 1e-9 || l.is_infinite() {
                return Err(RobotError::Singular { reason: format!("leg {} has zero or non-finite length", i + 1) });
            }
            let u = d / l;
            let vb = s.velocity_m_s + s.omega_rad_s.cross(&r);
            let ru = r.cross(&u);
            out.q_m[i] = l - self.length0_m[i];
            out.qd_m_s[i] = u.dot(&vb);
            out.length_m[i] = l;
            out.direction[i] = u;
            out.arm_m[i] = r;
            out.leg_omega_rad_s[i] = u.cross(&vb) / l;
            out.inverse_jacobian.set_row(i, &Vector6::new(u.x, u.y, u.z, ru.x, ru.y, ru.z).transpose());
        }
        Ok(out)
    }

    /// The 6 x 24 regressor under standard gravity: actuator forces `Q_a = Y p`.
    pub fn regressor(&self, s: &MotionState) -> Result<SMatrix<f64, 6, 24>> {
        self.regressor_with_gravity(s, &GRAVITY_M_S2)
    }

    /// The 6 x 24 regressor under `gravity_m_s2` (base frame).
    pub fn regressor_with_gravity(&self, s: &MotionState, gravity_m_s2: &Vector3<f64>) -> Result<SMatrix<f64, 6, 24>> {
        let legs = self.legs(s)?;
        let jt = legs.inverse_jacobian.transpose();
        let lu = jt.lu();
        let rot = s.pose.rotation.to_rotation_matrix().into_inner();
        let yb = body_regressor(&s.body(gravity_m_s2));
        // Platform-side wrench columns, base frame.
        let mut wrench = SMatrix::<f64, 6, 12>::zeros();
        for c in 0..10 {
            let f = rot * Vector3::new(yb[(0, c)], yb[(1, c)], yb[(2, c)]);
            let m = rot * Vector3::new(yb[(3, c)], yb[(4, c)], yb[(5, c)]);
            wrench.set_column(c, &Vector6::new(f.x, f.y, f.z, m.x, m.y, m.z));
        }
        let twist = s.twist();
        let mut gb = Vector6::zeros();
        let mut gp = Vector6::zeros();
        for i in 0..6 {
            let jb = leg_rate_map(&legs.direction[i], &legs.arm_m[i], legs.length_m[i]);
            let mut jp = jb;
            for k in 0..3 {
                jp[(k, 3 + k)] -= 1.0;
            }
            gb += jb.transpose() * (jb * twist);
            gp += jp.transpose() * (jp * twist);
        }
        wrench.set_column(10, &gb);
        wrench.set_column(11, &gp);
        let mapped = lu
            .solve(&wrench)
            .ok_or_else(|| RobotError::Singular { reason: "the hexapod's Jacobian is singular at this pose".into() })?;
        if mapped.iter().any(|v| !v.is_finite()) {
            return Err(RobotError::Singular { reason: "the hexapod's Jacobian is singular at this pose".into() });
        }
        let mut y = SMatrix::<f64, 6, 24>::zeros();
        for r in 0..6 {
            for c in 0..10 {
                y[(r, c)] = mapped[(r, c)];
            }
            y[(r, 10 + r)] = legs.qd_m_s[r];
            let qd = legs.qd_m_s[r];
            y[(r, 16 + r)] = if qd.abs() <= self.coulomb_deadband_m_s { 0.0 } else { qd.signum() };
            y[(r, 22)] = mapped[(r, 10)];
            y[(r, 23)] = mapped[(r, 11)];
        }
        Ok(y)
    }

    /// Actuator forces for parameters `p` (24 values).
    pub fn actuator_forces(&self, s: &MotionState, p: &[f64]) -> Result<Vector6<f64>> {
        if p.len() != HEXAPOD_PARAMETERS {
            return Err(RobotError::ParameterCount { expected: HEXAPOD_PARAMETERS, got: p.len() });
        }
        Ok(self.regressor(s)? * nalgebra::SVector::<f64, 24>::from_row_slice(p))
    }
}

/// `J_b`: twist to the angular velocity of a leg with direction `u`, arm `r` and length `L`:
/// `u x (v + w x r) / L`.
fn leg_rate_map(u: &Vector3<f64>, r: &Vector3<f64>, l: f64) -> SMatrix<f64, 3, 6> {
    let su = skew(u) / l;
    let right = -su * skew(r);
    let mut j = SMatrix::<f64, 3, 6>::zeros();
    j.fixed_view_mut::<3, 3>(0, 0).copy_from(&su);
    j.fixed_view_mut::<3, 3>(0, 3).copy_from(&right);
    j
}
