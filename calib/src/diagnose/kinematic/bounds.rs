//! The sizes the kinematic diagnosis compares its candidate effects with: typical ranges and
//! limits ([`Bounds`]).

use serde::{Deserialize, Serialize};

/// Sizes of the candidate effects: the typical ranges of industrial arms (`max_*`, `thermal_alpha_per_k`;
/// beyond them an effect is *unusual*: claimed only on strong held-out evidence and then
/// reported as unusually large, never silently discarded) and the limits past which the
/// effect's linear model no longer describes a machine (`limit_*`: vetoed, with the reason).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Bounds {
    /// Largest joint deflection under load a compliance may cause, revolute joints.
    pub max_deflection_rad: f64,
    /// Largest deflection of a prismatic joint.
    pub max_deflection_m: f64,
    /// Largest backlash (dead band) of a revolute joint.
    pub max_backlash_rad: f64,
    /// Largest backlash of a prismatic joint.
    pub max_backlash_m: f64,
    /// Largest relative scale error of a joint reading.
    pub max_scale_error: f64,
    /// Largest amplitude of a periodic error, revolute joints.
    pub max_periodic_rad: f64,
    /// Largest amplitude of a periodic error, prismatic joints.
    pub max_periodic_m: f64,
    /// Range of thermal expansion coefficients accepted (metals: Invar about 1.2e-6 to zinc
    /// about 30e-6 per K).
    pub thermal_alpha_per_k: [f64; 2],
    /// Largest relative length drift per hour (a warm-up without a temperature reading).
    pub max_drift_per_hour: f64,
    /// Largest tilt amplitude of a wobbling joint axis (axis misalignment): bearings and
    /// housings of arms hold their axes to well under a milliradian; 2 mrad is generous.
    #[serde(default = "default_max_axis_wobble_rad")]
    pub max_axis_wobble_rad: f64,
    /// Deflection of a revolute joint or a link past which a linear compliance means nothing
    /// (0.25 rad, 14 deg: a lightweight arm's gravity sag is tens of milliradians).
    #[serde(default = "limits::deflection_rad")]
    pub limit_deflection_rad: f64,
    /// The same for a prismatic joint.
    #[serde(default = "limits::deflection_m")]
    pub limit_deflection_m: f64,
    /// Direction-dependent error of a revolute joint past which it is not a drive train's.
    #[serde(default = "limits::backlash_rad")]
    pub limit_backlash_rad: f64,
    /// The same for a prismatic joint.
    #[serde(default = "limits::backlash_m")]
    pub limit_backlash_m: f64,
    /// Scale error or coupling past which the joint's model is wrong, not its scale.
    #[serde(default = "limits::scale_error")]
    pub limit_scale_error: f64,
    /// Periodic amplitude limit, revolute joints.
    #[serde(default = "limits::periodic_rad")]
    pub limit_periodic_rad: f64,
    /// Periodic amplitude limit, prismatic joints.
    #[serde(default = "limits::periodic_m")]
    pub limit_periodic_m: f64,
    /// Largest magnitude of a thermal expansion coefficient (per K) of any structure.
    #[serde(default = "limits::thermal_alpha_per_k")]
    pub limit_thermal_alpha_per_k: f64,
    /// Largest relative length drift per hour.
    #[serde(default = "limits::drift_per_hour")]
    pub limit_drift_per_hour: f64,
    /// Largest axis tilt amplitude.
    #[serde(default = "limits::axis_wobble_rad")]
    pub limit_axis_wobble_rad: f64,
}

pub(super) fn default_true() -> bool {
    true
}

fn default_max_axis_wobble_rad() -> f64 {
    0.002
}

/// The default limits of [`Bounds`] (past them an effect's linear model means nothing).
mod limits {
    pub(super) fn deflection_rad() -> f64 {
        0.25
    }
    pub(super) fn deflection_m() -> f64 {
        0.05
    }
    pub(super) fn backlash_rad() -> f64 {
        0.1
    }
    pub(super) fn backlash_m() -> f64 {
        0.02
    }
    pub(super) fn scale_error() -> f64 {
        0.1
    }
    pub(super) fn periodic_rad() -> f64 {
        0.1
    }
    pub(super) fn periodic_m() -> f64 {
        0.02
    }
    pub(super) fn thermal_alpha_per_k() -> f64 {
        2e-4
    }
    pub(super) fn drift_per_hour() -> f64 {
        1e-2
    }
    pub(super) fn axis_wobble_rad() -> f64 {
        0.02
    }
}

impl Default for Bounds {
    fn default() -> Self {
        Self {
            max_deflection_rad: 0.01,
            max_deflection_m: 0.002,
            max_backlash_rad: 0.01,
            max_backlash_m: 0.002,
            max_scale_error: 0.01,
            max_periodic_rad: 0.01,
            max_periodic_m: 0.002,
            thermal_alpha_per_k: [0.5e-6, 35e-6],
            max_drift_per_hour: 2e-4,
            max_axis_wobble_rad: default_max_axis_wobble_rad(),
            limit_deflection_rad: limits::deflection_rad(),
            limit_deflection_m: limits::deflection_m(),
            limit_backlash_rad: limits::backlash_rad(),
            limit_backlash_m: limits::backlash_m(),
            limit_scale_error: limits::scale_error(),
            limit_periodic_rad: limits::periodic_rad(),
            limit_periodic_m: limits::periodic_m(),
            limit_thermal_alpha_per_k: limits::thermal_alpha_per_k(),
            limit_drift_per_hour: limits::drift_per_hour(),
            limit_axis_wobble_rad: limits::axis_wobble_rad(),
        }
    }
}
