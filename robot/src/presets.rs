//! Built-in robot models, by name.

use std::f64::consts::FRAC_PI_2;

use crate::error::{Result, RobotError};
use crate::model::RobotModel;
use crate::parallel::presets as parallel_presets;
use crate::serial::{Inertial, SerialChain};

/// Every preset name [`preset`] accepts.
pub const PRESET_NAMES: &[&str] = &["ur5", "ur10", "gantry-tau-l1", "gantry-tau-l1-6link", "gantry-tau-f1", "hexapod"];

/// The model called `name`.
pub fn preset(name: &str) -> Result<RobotModel> {
    match name.to_ascii_lowercase().as_str() {
        "ur5" => Ok(RobotModel::Serial(ur5())),
        "ur10" => Ok(RobotModel::Serial(ur10())),
        "gantry-tau-l1" => Ok(RobotModel::GantryTau3(parallel_presets::gantry_tau_l1())),
        "gantry-tau-l1-6link" => Ok(RobotModel::GantryTau6(parallel_presets::gantry_tau_l1_6link())),
        "gantry-tau-f1" => Ok(RobotModel::GantryTauF1(parallel_presets::gantry_tau_f1())),
        "hexapod" => Ok(RobotModel::Hexapod(parallel_presets::hexapod())),
        _ => Err(RobotError::UnknownPreset(name.to_string())),
    }
}

fn ur_chain(name: &str, a: [f64; 6], d: [f64; 6], masses: [f64; 6], coms: [[f64; 3]; 6]) -> SerialChain {
    let alpha = [FRAC_PI_2, 0.0, 0.0, FRAC_PI_2, -FRAC_PI_2, 0.0];
    let mut chain = SerialChain::from_dh(name, &a, &alpha, &d, &[0.0; 6])
        .with_limits(-2.0 * std::f64::consts::PI, 2.0 * std::f64::consts::PI)
        .expect("valid preset limits");
    for (i, j) in chain.joints.iter_mut().enumerate() {
        j.name = ["shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"][i].to_string();
        // The maker publishes masses and centres of mass; inertia tensors are not needed for
        // gravity torques and are approximated as zero here.
        j.inertial = Some(Inertial { mass_kg: masses[i], com_m: coms[i], inertia_kgm2: [0.0; 9] });
    }
    chain
}

/// Universal Robots UR5 with the maker's standard DH table (metres, radians) and published link
/// masses and centres of mass (in the DH link frames).
pub fn ur5() -> SerialChain {
    ur_chain(
        "ur5",
        [0.0, -0.425, -0.39225, 0.0, 0.0, 0.0],
        [0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823],
        [3.7, 8.393, 2.275, 1.219, 1.219, 0.1879],
        [
            [0.0, -0.02561, 0.00193],
            [0.2125, 0.0, 0.11336],
            [0.15, 0.0, 0.0265],
            [0.0, -0.0018, 0.01634],
            [0.0, 0.0018, 0.01634],
            [0.0, 0.0, -0.001159],
        ],
    )
}

/// Universal Robots UR10 with the maker's standard DH table and published link masses and centres
/// of mass.
pub fn ur10() -> SerialChain {
    ur_chain(
        "ur10",
        [0.0, -0.612, -0.5723, 0.0, 0.0, 0.0],
        [0.1273, 0.0, 0.0, 0.163941, 0.1157, 0.0922],
        [7.1, 12.7, 4.27, 2.0, 2.0, 0.365],
        [
            [0.021, 0.0, 0.027],
            [0.38, 0.0, 0.158],
            [0.24, 0.0, 0.068],
            [0.0, 0.007, 0.018],
            [0.0, 0.007, 0.018],
            [0.0, 0.0, -0.026],
        ],
    )
}
