//! The force-sensing end-effector's strut framework: six 1-DOF force sensors between the
//! hexapod's moving platform and the end-effector body.
//!
//! Sensor `i` is a strut from `base_i` (on the platform) to `head_i` (on the end-effector body),
//! both in the platform frame `P` (the hexapod's flange frame; the framework is stiff, so the
//! body frame is `P`). Its force `f_i` (positive in compression: it pushes the body along
//! `n_i = (head_i - base_i) / |head_i - base_i|`) acts at `h_i = head_i`, so the sensors exert
//! the wrench `J_P^-T f_q` on the body, with the columns `[n_i; h_i x n_i]` of `J_P^-T`
//! ([`SensorFrame::wrench_matrix`]). Its inverse `J_P^T` ([`SensorFrame::force_map`]) turns a
//! wrench at the origin of `P` into sensor forces.

use std::f64::consts::PI;

use nalgebra::{Matrix6, Vector3, Vector6};
use serde::{Deserialize, Serialize};

use crate::error::{Result, RobotError};

/// One force-sensing strut, platform frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SensorStrut {
    /// End on the hexapod's platform, m.
    pub base_m: Vector3<f64>,
    /// End on the end-effector body (the force's point of application `h_i`), m.
    pub head_m: Vector3<f64>,
}

/// Six sensors in a strut framework.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SensorFrame {
    /// The struts in sensor order.
    pub struts: Vec<SensorStrut>,
}

/// Largest condition number of `J_P^-T` accepted by [`SensorFrame::validate`].
pub const MAX_CONDITION: f64 = 1e8;

impl SensorFrame {
    /// The framework this project uses (our choice; the source does not publish its geometry):
    /// a small 6-6 Stewart arrangement. Strut `2k+1` runs from the platform at angle
    /// `120k - 15` deg on a circle of radius 0.16 m at `z = 0.03` m to the body at `120k - 45` deg
    /// on a circle of radius 0.11 m at `z = 0.13` m; strut `2k+2` from `120k + 15` deg to
    /// `120k + 45` deg. The struts are 0.131 m long, 40 deg from the platform normal;
    /// `cond(J_P^-T)` is about 11 (forces in N, moments in N m).
    pub fn preset() -> Self {
        let deg = PI / 180.0;
        let at = |r: f64, a_deg: f64, z: f64| Vector3::new(r * (a_deg * deg).cos(), r * (a_deg * deg).sin(), z);
        let struts = (0..6)
            .map(|i| {
                let k = (i / 2) as f64;
                let s = if i % 2 == 0 { -1.0 } else { 1.0 };
                SensorStrut {
                    base_m: at(0.16, 120.0 * k + s * 15.0, 0.03),
                    head_m: at(0.11, 120.0 * k + s * 45.0, 0.13),
                }
            })
            .collect();
        Self { struts }
    }

    /// Checks the numbers: six struts, finite points, non-zero lengths and a framework that can
    /// carry every wrench (`cond(J_P^-T)` below [`MAX_CONDITION`]).
    pub fn validate(&self) -> Result<()> {
        if self.struts.len() != 6 {
            return Err(RobotError::BadParameter {
                name: "sensor struts".into(),
                value: self.struts.len() as f64,
                reason: "the force-sensing framework needs exactly 6 struts".into(),
            });
        }
        for (i, s) in self.struts.iter().enumerate() {
            if s.base_m.iter().chain(s.head_m.iter()).any(|v| !v.is_finite()) {
                return Err(RobotError::BadParameter {
                    name: format!("sensor {}", i + 1),
                    value: f64::NAN,
                    reason: "a strut end is not finite".into(),
                });
            }
            let l = (s.head_m - s.base_m).norm();
            if l < 1e-6 {
                return Err(RobotError::BadParameter {
                    name: format!("sensor {}", i + 1),
                    value: l,
                    reason: "the strut has no length".into(),
                });
            }
        }
        let c = self.condition_number();
        if c.is_nan() || c >= MAX_CONDITION {
            return Err(RobotError::Singular {
                reason: format!(
                    "the sensor framework cannot carry every wrench: cond(J_P^-T) = {c:.3e}; move the struts apart"
                ),
            });
        }
        Ok(())
    }

    /// Unit strut directions `n_i`.
    pub fn directions(&self) -> Vec<Vector3<f64>> {
        self.struts.iter().map(|s| (s.head_m - s.base_m).normalize()).collect()
    }

    /// `J_P^-T`: column `i` is the wrench `[n_i; h_i x n_i]` of a unit force of sensor `i`.
    pub fn wrench_matrix(&self) -> Matrix6<f64> {
        let mut w = Matrix6::zeros();
        for (i, (s, n)) in self.struts.iter().zip(self.directions()).enumerate() {
            let m = s.head_m.cross(&n);
            w.set_column(i, &Vector6::new(n.x, n.y, n.z, m.x, m.y, m.z));
        }
        w
    }

    /// `J_P^T = (J_P^-T)^-1`: sensor forces that carry a wrench at the origin of `P`.
    pub fn force_map(&self) -> Result<Matrix6<f64>> {
        self.validate()?;
        self.wrench_matrix().try_inverse().ok_or_else(|| RobotError::Singular {
            reason: "the sensor framework's wrench matrix J_P^-T is singular".into(),
        })
    }

    /// `cond(J_P^-T)` (ratio of extreme singular values; infinite when singular).
    pub fn condition_number(&self) -> f64 {
        let s = self.wrench_matrix().singular_values();
        let (lo, hi) = (s.min(), s.max());
        if lo > 0.0 {
            hi / lo
        } else {
            f64::INFINITY
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preset_is_well_conditioned_and_inverts() {
        let f = SensorFrame::preset();
        f.validate().unwrap();
        let c = f.condition_number();
        assert!(c < 30.0, "cond {c}");
        let w = f.wrench_matrix();
        let j = f.force_map().unwrap();
        assert!((w * j - Matrix6::identity()).norm() < 1e-10);
        let len = (f.struts[0].head_m - f.struts[0].base_m).norm();
        assert!((len - 0.131).abs() < 2e-3, "{len}");
    }

    #[test]
    fn degenerate_frames_are_refused() {
        let mut f = SensorFrame::preset();
        f.struts.pop();
        assert!(f.validate().unwrap_err().to_string().contains("exactly 6"));
        let mut g = SensorFrame::preset();
        for s in &mut g.struts {
            s.head_m = s.base_m + Vector3::z() * 0.1;
        }
        assert!(g.validate().unwrap_err().to_string().contains("cannot carry"));
    }
}
