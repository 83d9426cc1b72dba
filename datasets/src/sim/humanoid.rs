//! A lightweight humanoid-class robot for the diagnosis of real-robot physics (issue
//! [physics-real]): a torso with a passively coupled pitch joint carrying two arms, the left hand
//! measured by a motion-capture system, the arms and torso sagging under gravity.
//!
//! Simulated by [`super::tree`], written apart from the analysis. The robot: torso yaw, torso
//! pitch, a second torso pitch coupled to the first (`q = 0.5 q_pitch`, a belt; the truth's
//! multiplier is 1 % off), torso roll, then a 7-joint left arm (shoulder pitch, roll, yaw, elbow,
//! wrist yaw, pitch, roll): 11 revolute joints from the base to the hand, 10 actuated. The right
//! arm (7 joints, the same masses) hangs on the torso and stands still at zero. Links of 0.4-6 kg
//! (31 kg in all). Truth geometry: origins within 1 mm, origin rotations within 1.5 mrad, zero
//! offsets within 3 mrad, a motion-capture frame anywhere. With sag, the torso pitch, shoulder
//! pitch, shoulder roll and elbow drives deflect 25 mrad at their largest holding torque over the
//! recording (the hand moves tens of mm). Each pose's measurement has its own noise level, drawn
//! between 0.5 and 1 mm per axis; the recording has no sigma column; every fourth pose is held
//! out.

use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::tree::{rot, Tf, TreeJoint, TreeRobot};
use crate::error::DatasetError;
use ferrocal_calib::{PoseMeasurement, Split};

/// The actuated joints (1-based, the recording's `q` numbering) that sag in the truth.
pub const SAGGING_JOINTS: [usize; 4] = [2, 4, 5, 7];

/// Deflection of each sagging drive at its largest holding torque over the recording (rad).
pub const SAG_RAD: f64 = 25e-3;

/// A simulated recording of the humanoid-class robot.
#[derive(Clone, Debug)]
pub struct HumanoidRecording {
    /// The nominal robot as URDF (both arms; the chain to the left hand is the longest, first).
    pub urdf: String,
    /// The recorded poses: commanded joints, measured hand position, `split`.
    pub rows: Vec<PoseMeasurement>,
    /// The true model's held-out RMS: the noise on the held-out rows (mm).
    pub truth_held_out_mm: f64,
    /// The largest displacement of the hand by the sag over the recording (mm; 0 without sag).
    pub max_sag_mm: f64,
    /// The true compliances of the actuated joints (rad/(N m)).
    pub compliance_rad_per_nm: Vec<f64>,
}

/// The nominal tree: torso (yaw, pitch, coupled pitch, roll), left arm (7), right arm (7).
pub fn nominal() -> TreeRobot {
    let j = |name: &str,
             parent: Option<usize>,
             xyz: [f64; 3],
             axis: [f64; 3],
             mass_kg: f64,
             com: [f64; 3],
             lim: (f64, f64)| {
        TreeJoint {
            name: name.into(),
            parent,
            xyz_m: Vector3::from(xyz),
            rpy_rad: Vector3::zeros(),
            axis: Vector3::from(axis),
            mass_kg,
            com_m: Vector3::from(com),
            mimic: None,
            limits_rad: lim,
        }
    };
    let mut joints = vec![
        j("torso_yaw", None, [0.0, 0.0, 0.35], [0.0, 0.0, 1.0], 4.0, [0.0, 0.0, 0.05], (-1.0, 1.0)),
        j("torso_pitch", Some(0), [0.0, 0.0, 0.10], [0.0, 1.0, 0.0], 6.0, [0.02, 0.0, 0.15], (-0.15, 0.45)),
        j("torso_pitch2", Some(1), [0.0, 0.0, 0.20], [0.0, 1.0, 0.0], 4.0, [0.02, 0.0, 0.12], (-0.1, 0.25)),
        j("torso_roll", Some(2), [0.0, 0.0, 0.20], [1.0, 0.0, 0.0], 3.0, [0.0, 0.0, 0.10], (-0.3, 0.3)),
    ];
    joints[2].mimic = Some((1, 0.5, 0.0));
    for (side, s) in [("l", 1.0), ("r", -1.0)] {
        let base = joints.len();
        let arm = [
            ("shoulder_pitch", 3, [0.0, s * 0.18, 0.20], [0.0, 1.0, 0.0], 1.5, [0.0, s * 0.05, 0.0], (-2.2, 1.0)),
            ("shoulder_roll", base, [0.0, s * 0.08, 0.0], [s, 0.0, 0.0], 1.2, [0.0, 0.0, -0.10], (-0.2, 1.6)),
            ("shoulder_yaw", base + 1, [0.0, 0.0, -0.12], [0.0, 0.0, 1.0], 1.3, [0.0, 0.0, -0.10], (-1.2, 1.2)),
            ("elbow", base + 2, [0.0, 0.0, -0.15], [0.0, 1.0, 0.0], 1.0, [0.0, 0.0, -0.10], (-2.0, 0.0)),
            ("wrist_yaw", base + 3, [0.0, 0.0, -0.12], [0.0, 0.0, 1.0], 0.8, [0.0, 0.0, -0.08], (-1.5, 1.5)),
            ("wrist_pitch", base + 4, [0.0, 0.0, -0.12], [0.0, 1.0, 0.0], 0.5, [0.0, 0.0, -0.03], (-1.2, 1.2)),
            ("wrist_roll", base + 5, [0.0, 0.0, -0.05], [0.0, 0.0, 1.0], 0.4, [0.0, 0.0, -0.04], (-2.0, 2.0)),
        ];
        for (name, parent, xyz, axis, m, com, lim) in arm {
            joints.push(j(&format!("{side}_{name}"), Some(parent), xyz, axis, m, com, lim));
        }
    }
    let n_act = 10;
    TreeRobot {
        joints,
        tip: 10,
        tool_m: Vector3::new(0.02, 0.0, -0.09),
        offsets_rad: vec![0.0; n_act],
        compliance_rad_per_nm: vec![0.0; n_act],
    }
}

/// A recording of `n_poses` random poses (seeded), with or without the sag.
pub fn recording(seed: u64, n_poses: usize, with_sag: bool) -> Result<HumanoidRecording, DatasetError> {
    let nominal = nominal();
    let urdf = nominal.urdf("humanoid_torso", &Vector3::new(0.02, 0.0, -0.09));
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut truth = nominal.clone();
    for j in &mut truth.joints {
        j.xyz_m += Vector3::from_fn(|_, _| rng.random_range(-1.0e-3..1.0e-3));
        j.rpy_rad += Vector3::from_fn(|_, _| rng.random_range(-1.5e-3..1.5e-3));
    }
    if let Some((_, m, _)) = truth.joints[2].mimic.as_mut() {
        *m *= 1.01;
    }
    truth.tool_m += Vector3::new(0.4e-3, -0.3e-3, 0.5e-3);
    let actuated = truth.actuated();
    truth.offsets_rad = actuated.iter().map(|_| rng.random_range(-3e-3..3e-3)).collect();
    let device = Tf { r: rot(&Vector3::new(0.1, 0.2, 0.97).normalize(), 0.5), t: Vector3::new(1.8, -0.6, 0.4) };
    let qs: Vec<Vec<f64>> = (0..n_poses)
        .map(|_| {
            actuated
                .iter()
                .map(|&j| {
                    let (lo, hi) = truth.joints[j].limits_rad;
                    rng.random_range(lo..hi)
                })
                .collect()
        })
        .collect();
    if with_sag {
        let mut peak = vec![0.0f64; actuated.len()];
        for q in &qs {
            for (p, t) in peak.iter_mut().zip(truth.torques_nm(q)) {
                *p = p.max(t.abs());
            }
        }
        for &k in &SAGGING_JOINTS {
            truth.compliance_rad_per_nm[k - 1] = SAG_RAD / peak[k - 1];
        }
    }
    let rigid = {
        let mut r = truth.clone();
        r.compliance_rad_per_nm = vec![0.0; actuated.len()];
        r
    };
    let mut rows = Vec::with_capacity(n_poses);
    let (mut noise_sq, mut n_test, mut max_sag_mm) = (0.0, 0usize, 0.0f64);
    for (i, q) in qs.iter().enumerate() {
        let q_eff = truth
            .equilibrium(q)
            .ok_or_else(|| DatasetError::Input(format!("humanoid pose {}: the equilibrium did not settle", i + 1)))?;
        let p_true = truth.tool_point(&q_eff);
        let q_rigid: Vec<f64> = q.iter().zip(&truth.offsets_rad).map(|(q, o)| q + o).collect();
        max_sag_mm = max_sag_mm.max((p_true - rigid.tool_point(&q_rigid)).norm() * 1e3);
        let sigma_m = rng.random_range(0.5e-3..1.0e-3);
        let normal = Normal::new(0.0, sigma_m).map_err(|e| DatasetError::Input(e.to_string()))?;
        let noise = Vector3::from_fn(|_, _| normal.sample(&mut rng));
        let test = i % 4 == 3;
        if test {
            noise_sq += noise.norm_squared();
            n_test += 1;
        }
        let mut m = PoseMeasurement::new(format!("p{}", i + 1), q.clone(), device.apply(&p_true) + noise);
        m.split = Some(if test { Split::Test } else { Split::Train });
        m.source_line = Some(i as u64 + 2);
        rows.push(m);
    }
    Ok(HumanoidRecording {
        urdf,
        rows,
        truth_held_out_mm: (noise_sq / n_test.max(1) as f64).sqrt() * 1e3,
        max_sag_mm,
        compliance_rad_per_nm: truth.compliance_rad_per_nm,
    })
}
