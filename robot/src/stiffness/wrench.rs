//! Wrenches: a force and a moment acting on the robot, checked for plausible magnitudes and
//! resolved from a named frame into the base frame at the tool point.

use nalgebra::{Point3, Vector3, Vector6};
use serde::{Deserialize, Serialize};

use crate::stiffness::error::{Result, StiffnessError};

/// A wrench in base-frame axes: a force and the moment about a reference point (for a tool
/// wrench, the tool point).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Wrench {
    /// Force.
    pub force_n: Vector3<f64>,
    /// Moment about the reference point.
    pub torque_nm: Vector3<f64>,
}

impl Wrench {
    /// A wrench from its parts.
    pub fn new(force_n: Vector3<f64>, torque_nm: Vector3<f64>) -> Self {
        Self { force_n, torque_nm }
    }

    /// The weight of a point mass `mass_kg` at `com` under `gravity_m_s2`, as a wrench about
    /// `reference` (all base frame).
    pub fn gravity(mass_kg: f64, com: &Point3<f64>, reference: &Point3<f64>, gravity_m_s2: &Vector3<f64>) -> Self {
        let f = gravity_m_s2 * mass_kg;
        Self { force_n: f, torque_nm: (com - reference).cross(&f) }
    }

    /// `(force, moment)` as one 6-vector.
    pub fn as_vector(&self) -> Vector6<f64> {
        Vector6::new(
            self.force_n.x,
            self.force_n.y,
            self.force_n.z,
            self.torque_nm.x,
            self.torque_nm.y,
            self.torque_nm.z,
        )
    }

    /// The same wrench about another reference point: `M' = M + (p_old - p_new) x F`.
    pub fn moved(&self, from: &Point3<f64>, to: &Point3<f64>) -> Self {
        Self { force_n: self.force_n, torque_nm: self.torque_nm + (from - to).cross(&self.force_n) }
    }

    /// Sum of two wrenches about the same point.
    pub fn plus(&self, other: &Wrench) -> Self {
        Self { force_n: self.force_n + other.force_n, torque_nm: self.torque_nm + other.torque_nm }
    }

    /// Checks the wrench against `limits`: finite values, force and moment below their largest
    /// plausible sizes, and a lever arm `|M| / |F|` no longer than `limits.max_lever_m` (a moment
    /// given in N mm instead of N m is 1000 times too large and shows here).
    pub fn check(&self, limits: &WrenchLimits) -> Result<()> {
        let f = self.force_n.norm();
        let m = self.torque_nm.norm();
        if !(f.is_finite() && m.is_finite()) {
            return Err(StiffnessError::ImplausibleWrench { reason: "force or moment is not finite".into() });
        }
        if f > limits.max_force_n {
            return Err(StiffnessError::ImplausibleWrench {
                reason: format!(
                    "a force of {f:.4e} N exceeds the plausible {:.4e} N: forces are in newtons (a mass in kg times 9.81), not mN or in grams",
                    limits.max_force_n
                ),
            });
        }
        if m > limits.max_torque_nm {
            return Err(StiffnessError::ImplausibleWrench {
                reason: format!(
                    "a moment of {m:.4e} N m exceeds the plausible {:.4e} N m: moments are in N m, not N mm",
                    limits.max_torque_nm
                ),
            });
        }
        if f > 0.0 && m / f > limits.max_lever_m {
            return Err(StiffnessError::ImplausibleWrench {
                reason: format!(
                    "a moment of {m:.4e} N m with a force of {f:.4e} N implies a lever arm of {:.1} m (more than {} m): are the moments in N mm instead of N m, or the forces in kN instead of N?",
                    m / f,
                    limits.max_lever_m
                ),
            });
        }
        Ok(())
    }
}

/// Largest plausible wrench on a robot (for input checks).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct WrenchLimits {
    /// Largest force.
    pub max_force_n: f64,
    /// Largest moment.
    pub max_torque_nm: f64,
    /// Longest lever arm `|M| / |F|` between a force and its moment.
    pub max_lever_m: f64,
}

impl Default for WrenchLimits {
    /// Ten tonnes of force, 100 kN m of moment, a 20 m lever arm: beyond any industrial arm.
    fn default() -> Self {
        Self { max_force_n: 1e5, max_torque_nm: 1e5, max_lever_m: 20.0 }
    }
}

/// A wrench as a user gives it: components in a named frame, applied at a point of that frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WrenchSpec {
    /// Frame of the components and the point: `base` (or `world`), `flange`, `tool`, `link0`
    /// to `link<n>`, or a joint's name (the frame of the link that joint moves).
    pub frame: String,
    /// Force components in `frame`.
    pub force_n: [f64; 3],
    /// Moment components in `frame`, about `point_m`.
    pub torque_nm: [f64; 3],
    /// Point of application in `frame`.
    #[serde(default)]
    pub point_m: [f64; 3],
}
