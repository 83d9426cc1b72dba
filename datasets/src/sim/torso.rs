//! A two-armed torso with every joint moving and either hand (or both) measured (issue #46):
//! the evaluation of trees of chains and whole-body gravity, generated apart from the estimator.
//!
//! The robot is [`super::humanoid::nominal`]'s: torso yaw, pitch, a belt-coupled second pitch
//! (`q = 0.5 q_pitch`, the truth's multiplier 1 % off) and roll, then a 7-joint left arm and a
//! 7-joint right arm; 18 revolute joints, 17 actuated, commanded at random in every pose (the
//! table's `q1..q17` in the URDF's order). The simulator is this file's own code over
//! [`super::tree`]'s transforms: forward kinematics of the whole tree from the URDF-style
//! origins, holding torques as central differences of the potential energy of every link of both
//! arms, each placed by its own joints' commanded-and-sagged angles, and the equilibrium
//! `q = q_cmd + offset - C tau(q)` iterated to 1e-11 rad. The truth is of the estimator's
//! family (a linear compliance per drive at the torque equilibrium, rigid links): the check is of
//! the tree reading, the shared parameters of several tips and the whole-body loads, not of a
//! physics the analysis lacks. Truth geometry: origins within 1 mm, origin rotations within
//! 1.5 mrad, zero offsets within 3 mrad, each hand's marker off by up to 0.5 mm, a
//! motion-capture frame anywhere. Each measured point has its own noise level between 0.5 and
//! 1 mm per axis; every fourth pose is held out (both hands' rows of a pose together).

use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::tree::{rot, rpy, Tf, TreeRobot};
use crate::error::DatasetError;
use ferrocal_calib::{PoseMeasurement, Split};

/// The measured links (the URDF's marker links on the two hands).
pub const TIPS: [&str; 2] = ["l_wrist_roll_marker", "r_wrist_roll_marker"];

/// The actuated joints (1-based, the table's numbering) that sag in the truth: the torso pitch,
/// each arm's shoulder pitch and elbow.
pub const SAGGING_JOINTS: [usize; 5] = [2, 4, 7, 11, 14];

/// Deflection of each sagging drive at its largest holding torque over the recording (rad).
pub const SAG_RAD: f64 = 25e-3;

/// Which hands each pose measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Hands {
    /// The left hand only (the right arm moves unmeasured).
    Left,
    /// The right hand only.
    Right,
    /// Both hands: two rows per pose.
    Both,
}

/// A simulated recording of the two-armed torso.
#[derive(Clone, Debug)]
pub struct TorsoRecording {
    /// The nominal robot as URDF (markers `l_wrist_roll_marker` and `r_wrist_roll_marker`).
    pub urdf: String,
    /// The rows: every actuated joint, the measured point, `tip` (in `meta`) and `split`.
    pub rows: Vec<PoseMeasurement>,
    /// Per tip of [`TIPS`], the true model's held-out RMS: the noise on its held-out rows (mm).
    pub truth_held_out_mm: [f64; 2],
    /// The largest displacement of a measured hand by the sag (mm; 0 without sag).
    pub max_sag_mm: f64,
    /// The true compliances of the actuated joints (rad/(N m)).
    pub compliance_rad_per_nm: Vec<f64>,
}

/// The truth: the tree, the hands' points, per actuated joint its offset and compliance.
struct Truth {
    tree: TreeRobot,
    hands: [(usize, Vector3<f64>); 2],
    offsets_rad: Vec<f64>,
    compliance: Vec<f64>,
}

impl Truth {
    fn actuated(&self) -> Vec<usize> {
        (0..self.tree.joints.len()).filter(|&j| self.tree.joints[j].mimic.is_none()).collect()
    }

    fn links(&self, q_act: &[f64]) -> Vec<Tf> {
        let mut a = vec![0.0; self.tree.joints.len()];
        for (k, &j) in self.actuated().iter().enumerate() {
            a[j] = q_act[k];
        }
        for (j, joint) in self.tree.joints.iter().enumerate() {
            if let Some((leader, m, o)) = joint.mimic {
                a[j] = m * a[leader] + o;
            }
        }
        let mut out: Vec<Tf> = Vec::with_capacity(a.len());
        for (j, joint) in self.tree.joints.iter().enumerate() {
            let parent = joint.parent.map_or_else(Tf::identity, |p| out[p]);
            let origin = Tf { r: rpy(&joint.rpy_rad), t: joint.xyz_m };
            out.push(parent.then(&origin).then(&Tf { r: rot(&joint.axis, a[j]), t: Vector3::zeros() }));
        }
        out
    }

    fn energy_j(&self, q: &[f64]) -> f64 {
        let links = self.links(q);
        self.tree.joints.iter().zip(&links).map(|(j, l)| j.mass_kg * 9.80665 * l.apply(&j.com_m).z).sum()
    }

    fn torques_nm(&self, q: &[f64]) -> Vec<f64> {
        super::tree::energy_gradient(q, |x| self.energy_j(x))
    }

    fn equilibrium(&self, q_cmd: &[f64]) -> Option<Vec<f64>> {
        let q0: Vec<f64> = q_cmd.iter().zip(&self.offsets_rad).map(|(q, o)| q + o).collect();
        let mut q = q0.clone();
        for _ in 0..500 {
            let tau = self.torques_nm(&q);
            let next: Vec<f64> = q0.iter().zip(&self.compliance).zip(&tau).map(|((q0, c), t)| q0 - c * t).collect();
            let d = next.iter().zip(&q).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            q = next;
            if d < 1e-11 {
                return Some(q);
            }
        }
        None
    }

    fn hand(&self, q: &[f64], h: usize) -> Vector3<f64> {
        let (j, p) = self.hands[h];
        self.links(q)[j].apply(&p)
    }
}

/// A recording of `n_poses` random poses (seeded) measuring `hands`, with or without the sag.
pub fn recording(seed: u64, n_poses: usize, hands: Hands, with_sag: bool) -> Result<TorsoRecording, DatasetError> {
    let nominal = super::humanoid::nominal();
    let hand_m = Vector3::new(0.02, 0.0, -0.09);
    let urdf = nominal.urdf("two_arm_torso", &hand_m);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut tree = nominal.clone();
    for j in &mut tree.joints {
        j.xyz_m += Vector3::from_fn(|_, _| rng.random_range(-1.0e-3..1.0e-3));
        j.rpy_rad += Vector3::from_fn(|_, _| rng.random_range(-1.5e-3..1.5e-3));
    }
    if let Some((_, m, _)) = tree.joints[2].mimic.as_mut() {
        *m *= 1.01;
    }
    let mut marker = || hand_m + Vector3::from_fn(|_, _| rng.random_range(-0.5e-3..0.5e-3));
    let hands_truth = [(10, marker()), (17, marker())];
    let n_act = tree.joints.iter().filter(|j| j.mimic.is_none()).count();
    let mut truth = Truth { tree, hands: hands_truth, offsets_rad: vec![0.0; n_act], compliance: vec![0.0; n_act] };
    truth.offsets_rad = (0..n_act).map(|_| rng.random_range(-3e-3..3e-3)).collect();
    let device = Tf { r: rot(&Vector3::new(0.1, 0.2, 0.97).normalize(), 0.5), t: Vector3::new(1.8, -0.6, 0.4) };
    let actuated = truth.actuated();
    let qs: Vec<Vec<f64>> = (0..n_poses)
        .map(|_| {
            actuated
                .iter()
                .map(|&j| {
                    let (lo, hi) = truth.tree.joints[j].limits_rad;
                    rng.random_range(lo..hi)
                })
                .collect()
        })
        .collect();
    if with_sag {
        let mut peak = vec![0.0f64; n_act];
        for q in &qs {
            for (p, t) in peak.iter_mut().zip(truth.torques_nm(q)) {
                *p = p.max(t.abs());
            }
        }
        for &k in &SAGGING_JOINTS {
            truth.compliance[k - 1] = SAG_RAD / peak[k - 1];
        }
    }
    let measured: Vec<usize> = match hands {
        Hands::Left => vec![0],
        Hands::Right => vec![1],
        Hands::Both => vec![0, 1],
    };
    let mut rows = Vec::with_capacity(n_poses * measured.len());
    let (mut noise_sq, mut n_test, mut max_sag_mm) = ([0.0; 2], [0usize; 2], 0.0f64);
    for (i, q) in qs.iter().enumerate() {
        let q_eff = truth
            .equilibrium(q)
            .ok_or_else(|| DatasetError::Input(format!("torso pose {}: the equilibrium did not settle", i + 1)))?;
        let q_rigid: Vec<f64> = q.iter().zip(&truth.offsets_rad).map(|(q, o)| q + o).collect();
        let test = i % 4 == 3;
        for &h in &measured {
            let p_true = truth.hand(&q_eff, h);
            max_sag_mm = max_sag_mm.max((p_true - truth.hand(&q_rigid, h)).norm() * 1e3);
            let sigma_m = rng.random_range(0.5e-3..1.0e-3);
            let normal = Normal::new(0.0, sigma_m).map_err(|e| DatasetError::Input(e.to_string()))?;
            let noise = Vector3::from_fn(|_, _| normal.sample(&mut rng));
            if test {
                noise_sq[h] += noise.norm_squared();
                n_test[h] += 1;
            }
            let mut m =
                PoseMeasurement::new(format!("p{}{}", i + 1, ["l", "r"][h]), q.clone(), device.apply(&p_true) + noise);
            m.split = Some(if test { Split::Test } else { Split::Train });
            m.source_line = Some(rows.len() as u64 + 2);
            m.meta.insert("tip".into(), TIPS[h].into());
            rows.push(m);
        }
    }
    let held = |h: usize| (noise_sq[h] / n_test[h].max(1) as f64).sqrt() * 1e3;
    Ok(TorsoRecording {
        urdf,
        rows,
        truth_held_out_mm: [held(0), held(1)],
        max_sag_mm,
        compliance_rad_per_nm: truth.compliance,
    })
}
