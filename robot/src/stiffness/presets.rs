//! Built-in stiffness models: a KUKA KR 270-like heavy arm with a gravity compensator, and the
//! compliance matrix of Klimchik's one-link Orthoglide example.
//!
//! # KR 270-like arm
//! Standard DH (`a`, `alpha`, `d`, `theta offset`), the commonly quoted KR 270 values
//! `a1 = 350, a2 = 1150, a3 = 41 mm, d1 = 675, d4 = 1200, d6 = 215 mm` with the twists and offsets
//! chosen here so that at `q = 0` the upper arm is vertical and the forearm points along +x:
//!
//! | joint | a (m) | alpha | d (m) | theta offset |
//! | --- | --- | --- | --- | --- |
//! | 1 | 0.350 | -pi/2 | 0.675 | 0 |
//! | 2 | 1.150 | 0 | 0 | -pi/2 |
//! | 3 | -0.041 | -pi/2 | 0 | 0 |
//! | 4 | 0 | pi/2 | 1.200 | 0 |
//! | 5 | 0 | -pi/2 | 0 | 0 |
//! | 6 | 0 | 0 | 0.215 | 0 |
//!
//! The tool point is 0.25 m ahead of the flange. Link masses (kg) 450, 220, 180, 90, 40, 10
//! (about 1 t, as the real arm) with estimated centres of mass; joint limits are a plausible
//! subset of the real ones in this convention. The compliances are design estimates ("CAD
//! values") from beam models of the links and typical gearbox stiffnesses: they are the
//! identification's priors, not the truth of any simulation. A compression-spring gravity
//! compensator acts on joint 2 between a point 0.5 m below the shoulder axis on the rotating
//! column and a point 0.25 m up the upper arm (60 kN/m, free length 1.2 m).

use std::f64::consts::{FRAC_PI_2, PI};

use nalgebra::Matrix6;

use crate::kinematics::JointLimits;
use crate::serial::{Inertial, SerialChain};
use crate::stiffness::beam::BeamStiffness;
use crate::stiffness::compensator::GravityCompensator;
use crate::stiffness::error::Result;
use crate::stiffness::model::VjmModel;

/// Names of the built-in stiffness models.
pub const STIFFNESS_PRESETS: &[&str] = &["kr270-like"];

/// The KR 270-like kinematics with link inertials and limits (no compliance).
pub fn kr270_like_chain() -> SerialChain {
    let a = [0.350, 1.150, -0.041, 0.0, 0.0, 0.0];
    let alpha = [-FRAC_PI_2, 0.0, -FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, 0.0];
    let d = [0.675, 0.0, 0.0, 1.200, 0.0, 0.215];
    let off = [0.0, -FRAC_PI_2, 0.0, 0.0, 0.0, 0.0];
    let mut chain = SerialChain::from_dh("kr270-like", &a, &alpha, &d, &off);
    let masses = [450.0, 220.0, 180.0, 90.0, 40.0, 10.0];
    let coms = [
        [-0.20, 0.35, 0.0],
        [-0.55, 0.0, 0.05],
        [0.05, 0.0, -0.10],
        [0.0, -0.60, 0.0],
        [0.0, 0.0, 0.0],
        [0.0, 0.0, -0.03],
    ];
    let limits_deg = [[-170.0, 170.0], [-45.0, 85.0], [-70.0, 80.0], [-180.0, 180.0], [-120.0, 120.0], [-180.0, 180.0]];
    let names = ["a1", "a2", "a3", "a4", "a5", "a6"];
    for (i, j) in chain.joints.iter_mut().enumerate() {
        j.name = names[i].to_string();
        j.inertial = Some(Inertial { mass_kg: masses[i], com_m: coms[i], inertia_kgm2: [0.0; 9] });
        j.limits = JointLimits { lower: limits_deg[i][0] * PI / 180.0, upper: limits_deg[i][1] * PI / 180.0 };
    }
    chain.tool = nalgebra::Isometry3::translation(0.0, 0.0, 0.25);
    chain
}

/// Design-estimate joint compliances of the KR 270-like arm, rad/(N m).
pub const KR270_JOINT_COMPLIANCE: [f64; 6] = [0.30e-6, 0.20e-6, 0.35e-6, 2.5e-6, 2.5e-6, 4.0e-6];

/// Design-estimate beam models of the KR 270-like links 0 (pedestal) to 6 (flange and tool
/// mount), each along its spring's beam axis.
pub fn kr270_link_beams() -> [BeamStiffness; 7] {
    let b = |length_m, axial_n, b1, b2, torsion_nm2| BeamStiffness {
        length_m,
        axial_n,
        bending_1_nm2: b1,
        bending_2_nm2: b2,
        torsion_nm2,
    };
    [
        b(0.50, 5e9, 2e8, 2e8, 1.5e8),
        b(0.76, 3e9, 5e7, 5e7, 4e7),
        b(1.15, 2e9, 1.2e7, 8e6, 6e6),
        b(0.20, 3e9, 3e7, 3e7, 2e7),
        b(1.20, 1.5e9, 5e6, 5e6, 4e6),
        b(0.15, 1e9, 3e6, 3e6, 2e6),
        b(0.215, 1e9, 2e6, 2e6, 1.5e6),
    ]
}

/// The KR 270-like arm's gravity compensator (on joint 2).
pub fn kr270_compensator() -> GravityCompensator {
    GravityCompensator {
        joint: 2,
        anchor_m: [0.0, 0.5, 0.3],
        attach_m: [-0.9, 0.0, 0.3],
        stiffness_n_per_m: 6e4,
        free_length_m: 1.2,
    }
}

/// The KR 270-like virtual joint model with its design-estimate compliances and compensator.
pub fn kr270_like() -> Result<VjmModel> {
    let chain = kr270_like_chain();
    let mut springs = VjmModel::auto_springs(&chain)?;
    for (s, beam) in springs.iter_mut().zip(kr270_link_beams()) {
        s.compliance = beam.compliance(s.beam_axis.unwrap_or(2), &s.name)?;
    }
    VjmModel::new(chain, KR270_JOINT_COMPLIANCE.to_vec(), springs, Some(kr270_compensator()))
}

/// A built-in stiffness model by name.
pub fn stiffness_preset(name: &str) -> Option<Result<VjmModel>> {
    match name.to_ascii_lowercase().as_str() {
        "kr270-like" | "kr270_like" | "kr270" => Some(kr270_like()),
        _ => None,
    }
}

/// The compliance matrix of one Orthoglide link (Klimchik et al. 2015), N, m, rad: diagonal
/// 4.50e-8, 8.01e-5, 3.64e-5, 3.76e-3, 1.09e-3, 2.65e-3; `k26 = k62 = 3.98e-4`,
/// `k35 = k53 = -1.71e-4`.
pub fn orthoglide_link_compliance() -> Matrix6<f64> {
    let mut k = Matrix6::zeros();
    for (i, v) in [4.50e-8, 8.01e-5, 3.64e-5, 3.76e-3, 1.09e-3, 2.65e-3].iter().enumerate() {
        k[(i, i)] = *v;
    }
    k[(1, 5)] = 3.98e-4;
    k[(5, 1)] = 3.98e-4;
    k[(2, 4)] = -1.71e-4;
    k[(4, 2)] = -1.71e-4;
    k
}
