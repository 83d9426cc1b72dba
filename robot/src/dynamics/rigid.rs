//! A rigid body's ten inertial parameters and the Newton-Euler wrench linear in them.
//!
//! In the body frame, with `b = a - g` (the origin's acceleration less gravity), angular velocity
//! `w` and acceleration `w'`, the wrench that the supports (sensors, legs) must exert on the body
//! at the frame origin is
//!
//! ```text
//! F = m b + (S(w') + S(w) S(w)) (m c)
//! M = I_P w' + w x (I_P w) - S(b) (m c)
//! ```
//!
//! i.e. `f_Dyn - f_G` with `f_G = m [g; c x g]`, and it is linear in
//! `u = (m, m c, I_xx, I_xy, I_xz, I_yy, I_yz, I_zz)` with `I_P` about the origin.

use nalgebra::{Matrix3, SMatrix, Vector3, Vector6};
use serde::{Deserialize, Serialize};

use super::motion::BodyState;
use crate::error::{Result, RobotError};
use crate::geometry::skew;

/// Names of the ten inertial parameters (inertia about the frame origin).
pub const RIGID_BODY_NAMES: [&str; 10] =
    ["m_kg", "mcx_kgm", "mcy_kgm", "mcz_kgm", "Ixx_kgm2", "Ixy_kgm2", "Ixz_kgm2", "Iyy_kgm2", "Iyz_kgm2", "Izz_kgm2"];

/// Mass, centre of gravity and inertia of a rigid body in its frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RigidBody {
    /// Mass, kg.
    pub mass_kg: f64,
    /// Centre of gravity in the body frame, m.
    pub com_m: Vector3<f64>,
    /// Inertia tensor about the centre of gravity, body axes, kg m^2.
    pub inertia_com_kgm2: Matrix3<f64>,
}

impl RigidBody {
    /// A point mass at `at_m`.
    pub fn point(mass_kg: f64, at_m: Vector3<f64>) -> Self {
        Self { mass_kg, com_m: at_m, inertia_com_kgm2: Matrix3::zeros() }
    }

    /// Checks the numbers: finite, positive mass, symmetric positive semi-definite inertia that
    /// satisfies the triangle inequalities.
    pub fn validate(&self, what: &str) -> Result<()> {
        let bad = |value: f64, reason: &str| RobotError::BadParameter {
            name: what.to_string(),
            value,
            reason: reason.to_string(),
        };
        if !(self.mass_kg.is_finite() && self.mass_kg > 0.0) {
            return Err(bad(self.mass_kg, "the mass must be finite and positive"));
        }
        if self.com_m.iter().chain(self.inertia_com_kgm2.iter()).any(|v| !v.is_finite()) {
            return Err(bad(f64::NAN, "the centre of gravity or the inertia is not finite"));
        }
        let i = &self.inertia_com_kgm2;
        if (i - i.transpose()).abs().max() > 1e-9 * i.abs().max().max(1e-12) {
            return Err(bad(f64::NAN, "the inertia tensor is not symmetric"));
        }
        let e = i.symmetric_eigenvalues();
        let top = e.abs().max();
        if e.iter().any(|l| *l < -1e-9 * top.max(1e-12)) {
            return Err(bad(e.min(), "the inertia tensor has a negative principal moment"));
        }
        let mut l: Vec<f64> = e.iter().copied().collect();
        l.sort_by(|a, b| a.total_cmp(b));
        if l[2] > l[0] + l[1] + 1e-9 * top.max(1e-12) {
            return Err(bad(l[2], "the principal moments break the triangle inequality"));
        }
        Ok(())
    }

    /// Inertia about the frame origin, `I_C + m S(c)^T S(c)`.
    pub fn inertia_origin_kgm2(&self) -> Matrix3<f64> {
        let s = skew(&self.com_m);
        self.inertia_com_kgm2 + s.transpose() * s * self.mass_kg
    }

    /// The ten parameters `(m, m c, I_xx, I_xy, I_xz, I_yy, I_yz, I_zz)`, inertia about the
    /// origin.
    pub fn parameters(&self) -> [f64; 10] {
        let mc = self.com_m * self.mass_kg;
        let i = self.inertia_origin_kgm2();
        [self.mass_kg, mc.x, mc.y, mc.z, i[(0, 0)], i[(0, 1)], i[(0, 2)], i[(1, 1)], i[(1, 2)], i[(2, 2)]]
    }

    /// This body expressed in another frame: `t_new_old` maps this body's frame into the new one.
    pub fn transformed(&self, t_new_old: &nalgebra::Isometry3<f64>) -> Self {
        let r = t_new_old.rotation.to_rotation_matrix().into_inner();
        Self {
            mass_kg: self.mass_kg,
            com_m: t_new_old.transform_point(&self.com_m.into()).coords,
            inertia_com_kgm2: r * self.inertia_com_kgm2 * r.transpose(),
        }
    }

    /// Two bodies rigidly joined, both given in the same frame.
    pub fn combined(&self, other: &RigidBody) -> Self {
        let m = self.mass_kg + other.mass_kg;
        let c = (self.com_m * self.mass_kg + other.com_m * other.mass_kg) / m;
        let shifted = |b: &RigidBody| {
            let s = skew(&(b.com_m - c));
            b.inertia_com_kgm2 + s.transpose() * s * b.mass_kg
        };
        Self { mass_kg: m, com_m: c, inertia_com_kgm2: shifted(self) + shifted(other) }
    }
}

/// `L(v)` with `I v = L(v) (I_xx, I_xy, I_xz, I_yy, I_yz, I_zz)`.
pub fn inertia_regressor(v: &Vector3<f64>) -> SMatrix<f64, 3, 6> {
    SMatrix::<f64, 3, 6>::from_row_slice(&[
        v.x, v.y, v.z, 0.0, 0.0, 0.0, //
        0.0, v.x, 0.0, v.y, v.z, 0.0, //
        0.0, 0.0, v.x, 0.0, v.y, v.z,
    ])
}

/// The 6 x 10 regressor `Y` with `f_Dyn - f_G = Y u` (force rows first, moments about the frame
/// origin; body frame). At rest only the first four columns are non-zero.
pub fn body_regressor(s: &BodyState) -> SMatrix<f64, 6, 10> {
    let b = s.acceleration_m_s2 - s.gravity_m_s2;
    let w = &s.omega_rad_s;
    let sw = skew(w);
    let lin_mc = skew(&s.alpha_rad_s2) + sw * sw;
    let ang_mc = -skew(&b);
    let ang_i = inertia_regressor(&s.alpha_rad_s2) + sw * inertia_regressor(w);
    let mut y = SMatrix::<f64, 6, 10>::zeros();
    for r in 0..3 {
        y[(r, 0)] = b[r];
        for c in 0..3 {
            y[(r, 1 + c)] = lin_mc[(r, c)];
            y[(3 + r, 1 + c)] = ang_mc[(r, c)];
        }
        for c in 0..6 {
            y[(3 + r, 4 + c)] = ang_i[(r, c)];
        }
    }
    y
}

/// The same wrench computed directly from a body about its centre of gravity and moved to the
/// origin (for checks): `F = m (a_C - g)`, `M = I_C w' + w x I_C w + c x F`, body frame.
pub fn newton_euler_wrench(body: &RigidBody, s: &BodyState) -> Vector6<f64> {
    let c = body.com_m;
    let w = s.omega_rad_s;
    let a_c = s.acceleration_m_s2 + s.alpha_rad_s2.cross(&c) + w.cross(&w.cross(&c));
    let f = (a_c - s.gravity_m_s2) * body.mass_kg;
    let i = body.inertia_com_kgm2;
    let m = i * s.alpha_rad_s2 + w.cross(&(i * w)) + c.cross(&f);
    Vector6::new(f.x, f.y, f.z, m.x, m.y, m.z)
}
