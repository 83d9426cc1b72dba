//! The simulated laser tracker.
//!
//! It measures the reflector (a point fixed in the tool frame) in its own frame, placed somewhere
//! in the cell. Noise model: each coordinate gets independent Gaussian noise with standard
//! deviation `sigma = sigma_const + sigma_per_m * d`, `d` the distance from the tracker (the
//! usual volumetric specification, e.g. 15 um + 6 um/m, read as one standard deviation). A 6-DoF
//! probe also reports the tool orientation, perturbed by a rotation vector with independent
//! Gaussian components of `sigma_angle`.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

/// Tracker placement and noise (TOML table `[tracker]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackerConfig {
    /// Tracker position in the cell (world) frame.
    pub position_m: [f64; 3],
    /// Tracker orientation in the world frame, roll-pitch-yaw (`Rz Ry Rx`), degrees.
    #[serde(default)]
    pub rpy_deg: [f64; 3],
    /// Constant part of the noise, micrometres (one standard deviation per axis).
    #[serde(default = "default_const")]
    pub sigma_const_um: f64,
    /// Distance-proportional part of the noise, micrometres per metre.
    #[serde(default = "default_per_m")]
    pub sigma_per_m_um: f64,
    /// Whether a 6-DoF probe reports orientation too.
    #[serde(default)]
    pub six_dof: bool,
    /// Orientation noise of the 6-DoF probe, milliradians per axis.
    #[serde(default = "default_angle")]
    pub sigma_angle_mrad: f64,
    /// Reflector position in the tool frame.
    #[serde(default)]
    pub reflector_in_tool_m: [f64; 3],
}

fn default_const() -> f64 {
    15.0
}
fn default_per_m() -> f64 {
    6.0
}
fn default_angle() -> f64 {
    0.02
}

/// One tracker reading.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrackerReading {
    /// Measured reflector position in the tracker frame.
    pub position_m: Vector3<f64>,
    /// Measured orientation of the tool in the tracker frame (6-DoF probe only).
    pub orientation: Option<UnitQuaternion<f64>>,
    /// Standard deviation used for this reading, per axis.
    pub sigma_m: f64,
}

impl TrackerConfig {
    /// `T_world_tracker`.
    pub fn t_world_tracker(&self) -> Isometry3<f64> {
        let r = self.rpy_deg.map(f64::to_radians);
        Isometry3::from_parts(
            Translation3::new(self.position_m[0], self.position_m[1], self.position_m[2]),
            UnitQuaternion::from_euler_angles(r[0], r[1], r[2]),
        )
    }

    /// Checks the settings: finite placement, noise standard deviations finite and not negative
    /// (a negative one would be written into the tracker table, which the table's reader then
    /// refuses).
    pub fn validate(&self) -> Result<(), String> {
        for (name, v) in [
            ("sigma_const_um", self.sigma_const_um),
            ("sigma_per_m_um", self.sigma_per_m_um),
            ("sigma_angle_mrad", self.sigma_angle_mrad),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("[tracker] {name} = {v}: a standard deviation must be a finite number >= 0"));
            }
        }
        let placement = self.position_m.iter().chain(&self.rpy_deg).chain(&self.reflector_in_tool_m);
        if placement.copied().any(|v| !(v.is_finite() && v.abs() < 1e4)) {
            return Err(
                "[tracker] position_m, rpy_deg and reflector_in_tool_m must be finite numbers of plausible size".into(),
            );
        }
        Ok(())
    }

    /// A noisy reading of the tool at `t_world_tool`.
    pub fn measure(&self, t_world_tool: &Isometry3<f64>, rng: &mut impl Rng) -> TrackerReading {
        let t_tracker_tool = self.t_world_tracker().inverse() * t_world_tool;
        let p = t_tracker_tool * Point3::from(Vector3::from(self.reflector_in_tool_m));
        let d = p.coords.norm();
        let sigma = (self.sigma_const_um + self.sigma_per_m_um * d) * 1e-6;
        let mut noise = || -> f64 { StandardNormal.sample(rng) };
        let n = Vector3::new(noise(), noise(), noise()) * sigma;
        let orientation = self.six_dof.then(|| {
            let s = self.sigma_angle_mrad * 1e-3;
            let w = Vector3::new(noise(), noise(), noise()) * s;
            UnitQuaternion::from_scaled_axis(w) * t_tracker_tool.rotation
        });
        TrackerReading { position_m: p.coords + n, orientation, sigma_m: sigma }
    }
}

#[cfg(test)]
mod validate_tests {
    use super::*;

    #[test]
    fn simulate_tracker_with_negative_sigma_is_refused() {
        let mut t: TrackerConfig = toml::from_str("position_m = [2.0, 0.0, 0.5]").unwrap();
        assert!(t.validate().is_ok());
        t.sigma_const_um = -15.0;
        assert!(t.validate().unwrap_err().contains("sigma_const_um = -15"));
        t.sigma_const_um = 15.0;
        t.sigma_per_m_um = f64::NAN;
        assert!(t.validate().unwrap_err().contains("sigma_per_m_um"));
    }
}
