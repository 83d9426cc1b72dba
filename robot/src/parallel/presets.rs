//! The built-in parallel robots (registered by name in [`crate::presets`]).

use std::f64::consts::PI;

use nalgebra::{Isometry3, Vector3};

use super::{Branch, GantryArm, GantryTau3, GantryTau6, GantryTauF1, Guideway, Hexapod, HexapodLeg, Link, RotaryStage};
use crate::geometry::Pose;
use crate::kinematics::JointLimits;

/// Cart travel of the Gantry-Tau presets (the source's guideways: +-1 m).
const CART: JointLimits = JointLimits { lower: -1.0, upper: 1.0 };

fn v3(x: f64, y: f64, z: f64) -> Vector3<f64> {
    Vector3::new(x, y, z)
}

/// `gantry-tau-l1`: the nominal model of the L1 Gantry-Tau from the source (link lengths
/// 2.0613, 2.0662, 2.0632 m; `A^s` as published; `v = (1, 0, 0)` for all arms).
///
/// Choices: every arm on the `minus` branch (cart behind the platform along `+x`) and assembly
/// mode `plus`; with carts at zero that puts the platform at about (-0.021, 2.685, -0.606) m, in
/// front of the guideways, and 97 % of cart positions drawn uniformly within the +-1 m travel
/// assemble in that configuration.
pub fn gantry_tau_l1() -> GantryTau3 {
    let arm = |length_m: f64, a: [f64; 3]| GantryArm {
        length_m,
        a_m: v3(a[0], a[1], a[2]),
        v: v3(1.0, 0.0, 0.0),
        limits: CART,
        branch: Branch::Minus,
        base_axis: None,
        platform_axis: None,
    };
    GantryTau3 {
        name: "gantry-tau-l1".into(),
        arms: [
            arm(2.0613, [-1.8093, 3.5095, 0.0041]),
            arm(2.0662, [-1.8688, 2.2455, 0.2075]),
            arm(2.0632, [-1.8109, 3.2774, -1.4436]),
        ],
        assembly: Branch::Plus,
    }
}

/// Platform-side joint centres of the six-link L1 expansion (platform frame, metres).
const L1_B0: [[f64; 3]; 6] = [
    [0.0, 0.08, 0.06],
    [0.0, -0.008, 0.117],
    [0.0, -0.092, 0.063],
    [0.0, 0.11, -0.03],
    [0.0, 0.01, -0.03],
    [0.0, 0.06, -0.13],
];

/// `gantry-tau-l1-6link`: the L1 nominal geometry expanded into six links.
///
/// Each cluster is a parallelogram: link `j` of arm `i` has `L_ij = L_i`, `A0_ij = A^s_i + B0_ij`,
/// so at nominal values the platform keeps the identity orientation and its reference point moves
/// exactly as the 3-DOF model's `T`. Platform points, about 0.1 m apart, each cluster placed
/// towards its own guideway: arm 1's single link at (0, 0.08, 0.06); arm 2's pair at
/// (0, -0.05, 0.09) +- (0, 0.042, 0.027), separated along `d2 x d3` (the cross product of the link
/// directions of arms 2 and 3 at `q = 0`) so that the pair stops the rotation about arm 3's links
/// that arm 3's cluster leaves free; arm 3's triangle (0, 0.11, -0.03), (0, 0.01, -0.03),
/// (0, 0.06, -0.13) across its links, stopping the two rotations about axes across them. The
/// closure derivative with respect to the pose has condition number 46 at `q = 0`.
pub fn gantry_tau_l1_6link() -> GantryTau6 {
    let l1 = gantry_tau_l1();
    let guideways = [0, 1, 2].map(|i| Guideway { v: l1.arms[i].v, limits: CART, branch: l1.arms[i].branch });
    // A0 = A^s + B0, written out so that the model file holds the same numbers.
    let a0: [[f64; 3]; 6] = [
        [-1.8093, 3.5895, 0.0641],
        [-1.8688, 2.2375, 0.3245],
        [-1.8688, 2.1535, 0.2705],
        [-1.8109, 3.3874, -1.4736],
        [-1.8109, 3.2874, -1.4736],
        [-1.8109, 3.3374, -1.5736],
    ];
    let arms = [0usize, 1, 1, 2, 2, 2];
    let links = (0..6)
        .map(|k| Link {
            arm: arms[k],
            a_m: v3(a0[k][0], a0[k][1], a0[k][2]),
            b0_m: v3(L1_B0[k][0], L1_B0[k][1], L1_B0[k][2]),
            length_m: l1.arms[arms[k]].length_m,
            base_axis: None,
            platform_axis: None,
        })
        .collect();
    GantryTau6 {
        name: "gantry-tau-l1-6link".into(),
        guideways,
        links,
        assembly: l1.assembly,
        tool: Pose::identity(),
        solver: GantryTau6::default_solver(),
    }
}

/// `gantry-tau-f1`: a 6-DOF F1-type Gantry-Tau of our own design (x along the guideways, z up).
///
/// - Guideways along `x` (travel +-1 m, links on the `minus` branch, assembly `minus`) through
///   (y, z) = (0, 1.0) (arm 1, one link), (0.9, -0.4) (arm 2) and (-0.9, -0.4) (arm 3); all links
///   1.8 m. With all actuators at zero the platform is at about (1.554, 0, 0.031) m, level.
/// - Arm 2: a plate (`rot2`, +-0.25 rad) turning about (0.47, 0.88, 0) through the guideway line,
///   carrying two links 0.12 m apart along (-0.19, 0.10, 0.98).
/// - Arm 3: a plate (`rot3`, +-0.25 rad) turning about (0.47, -0.88, 0), carrying a plate (`tilt3`,
///   +-0.25 rad) tilting about (0.19, 0.10, -0.98), with three links in a triangle about 0.1 m
///   across in the plane spanned by the two axes.
/// - Every plate axis is (nearly) perpendicular to its links' direction at `q = 0` (about
///   (0.86, -+0.46, 0.22)): turning a plate then changes the links' lengths as much as possible and
///   no plate motion can turn the link ends about the links' own direction, which would leave an
///   arm's inverse kinematics with several solutions within the limits. The plates' joints sit
///   where the links meet them, mirrored on the platform (parallelogram clusters at zero), so the
///   cluster start of the forward kinematics is exact with the plates at zero.
/// - At `q = 0` the Jacobian is well conditioned: `rot2` and `rot3` give roll and pitch (with
///   opposite pitch), `tilt3` yaw. About 95 % of actuator values drawn within the limits assemble.
pub fn gantry_tau_f1() -> GantryTauF1 {
    let rot = |point: [f64; 3], axis: [f64; 3]| RotaryStage {
        point_m: v3(point[0], point[1], point[2]),
        axis: v3(axis[0], axis[1], axis[2]),
        limits: JointLimits { lower: -0.25, upper: 0.25 },
    };
    let link = |arm: usize, a: [f64; 3], b0: [f64; 3]| Link {
        arm,
        a_m: v3(a[0], a[1], a[2]),
        b0_m: v3(b0[0], b0[1], b0[2]),
        length_m: 1.8,
        base_axis: None,
        platform_axis: None,
    };
    let guideway = Guideway { v: v3(1.0, 0.0, 0.0), limits: CART, branch: Branch::Minus };
    GantryTauF1 {
        name: "gantry-tau-f1".into(),
        guideways: [guideway.clone(), guideway.clone(), guideway],
        rot2: rot([0.0, 0.9, -0.4], [0.47, 0.88, 0.0]),
        rot3: rot([0.0, -0.9, -0.4], [0.47, -0.88, 0.0]),
        tilt3: rot([0.0, 0.0, 0.0], [0.19, 0.1, -0.98]),
        links: vec![
            link(0, [0.0, 0.0, 1.0], [0.0, 0.0, 0.06]),
            link(1, [-0.012, 0.006, 0.059], [-0.012, 0.086, 0.019]),
            link(1, [0.012, -0.006, -0.059], [0.012, 0.074, -0.099]),
            link(2, [0.036, -0.049, -0.039], [0.036, -0.129, -0.079]),
            link(2, [-0.02, 0.057, -0.039], [-0.02, -0.023, -0.079]),
            link(2, [-0.012, -0.006, 0.059], [-0.012, -0.086, 0.019]),
        ],
        assembly: Branch::Minus,
        tool: Pose::identity(),
        solver: GantryTauF1::default_solver(),
    }
}

/// `hexapod`: a symmetric 6-6 Stewart platform.
///
/// Base joints on a circle of radius 0.5 m in the plane z = 0, in pairs at 0, 120 and 240 deg
/// +- 15 deg; platform joints on a circle of radius 0.3 m (platform frame, z = 0) in pairs at 60,
/// 180 and 300 deg +- 15 deg; leg `2k+1` joins base angle `120k - 15` to platform angle
/// `120k - 45`, leg `2k+2` base `120k + 15` to platform `120k + 45` (degrees). Home: platform at
/// (0, 0, 0.8) m with identity orientation, where every leg is 0.8486 m long (`L0`); stroke
/// +-0.15 m.
pub fn hexapod() -> Hexapod {
    let deg = PI / 180.0;
    let on_circle = |r: f64, a_deg: f64| v3(r * (a_deg * deg).cos(), r * (a_deg * deg).sin(), 0.0);
    let home = Isometry3::translation(0.0, 0.0, 0.8);
    let legs = (0..6)
        .map(|i| {
            let k = (i / 2) as f64;
            let s = if i % 2 == 0 { -1.0 } else { 1.0 };
            let a = on_circle(0.5, 120.0 * k + s * 15.0);
            let b0 = on_circle(0.3, 120.0 * k + s * 45.0);
            let length0_m = (a - (home.translation.vector + b0)).norm();
            HexapodLeg {
                a_m: a,
                b0_m: b0,
                length0_m,
                limits: JointLimits { lower: -0.1, upper: 0.1 },
                base_axis: None,
                platform_axis: None,
            }
        })
        .collect();
    Hexapod { name: "hexapod".into(), legs, home, tool: Pose::identity(), solver: Hexapod::default_solver() }
}
