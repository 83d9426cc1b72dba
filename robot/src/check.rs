//! Self-checks of any model: forward/inverse round trips and Jacobians against central finite
//! differences, on random configurations. Used by the tests and shown in `ferrocal demo`.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::geometry::{pose_error, wrap_angle};
use crate::kinematics::{JointKind, Kinematics, Mobility};

/// Results of [`self_check`].
#[derive(Clone, Debug, Default, Serialize)]
pub struct SelfCheck {
    /// Configurations tried.
    pub tried: usize,
    /// Configurations whose forward kinematics failed (outside the assembly or unreachable).
    pub fk_failed: usize,
    /// Configurations skipped as near-singular (smallest Jacobian singular value below 0.05).
    pub near_singular: usize,
    /// Round trips made.
    pub round_trips: usize,
    /// Inverse kinematics failures among them.
    pub ik_failed: usize,
    /// Worst position error of `FK(IK(FK(q)))` against `FK(q)`.
    pub worst_position_m: f64,
    /// Worst orientation error (only for models that control the orientation).
    pub worst_orientation_rad: f64,
    /// Worst joint difference between `IK(FK(q))` and `q`.
    pub worst_joint: f64,
    /// Worst relative mismatch of a Jacobian column against central differences.
    pub worst_jacobian_rel: f64,
}

/// Samples `n` random configurations within the joint limits (unbounded revolute joints in
/// `[-pi, pi]`, unbounded prismatic joints in `[-1, 1]` m) and checks the round trip and the
/// Jacobian at each. Deterministic for `seed`.
pub fn self_check<K: Kinematics + ?Sized>(model: &K, n: usize, seed: u64, mut progress: impl FnMut()) -> SelfCheck {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let limits = model.joint_limits();
    let kinds = model.joint_kinds();
    let mobility = model.mobility();
    let mut out = SelfCheck::default();
    for _ in 0..n {
        progress();
        out.tried += 1;
        let q: Vec<f64> = limits
            .iter()
            .zip(&kinds)
            .map(|(l, k)| {
                let (dlo, dhi) = match k {
                    JointKind::Revolute => (-std::f64::consts::PI, std::f64::consts::PI),
                    JointKind::Prismatic => (-1.0, 1.0),
                };
                let lo = if l.lower.is_finite() { l.lower } else { dlo };
                let hi = if l.upper.is_finite() { l.upper } else { dhi };
                lo + (hi - lo) * rng.random::<f64>()
            })
            .collect();
        let Ok(target) = model.forward(&q) else {
            out.fk_failed += 1;
            continue;
        };
        let Ok(jac) = model.jacobian(&q) else {
            out.fk_failed += 1;
            continue;
        };
        let rows = if mobility == Mobility::Full6 { 6 } else { 3 };
        let sv = jac.rows(0, rows).into_owned().svd(false, false).singular_values;
        if sv.iter().copied().fold(f64::INFINITY, f64::min) < 0.05 {
            out.near_singular += 1;
            continue;
        }
        // Jacobian against central differences.
        let h = 1e-6;
        for i in 0..q.len() {
            let mut qp = q.clone();
            let mut qm = q.clone();
            qp[i] += h;
            qm[i] -= h;
            let (Ok(tp), Ok(tm)) = (model.forward(&qp), model.forward(&qm)) else {
                continue;
            };
            let dp = (tp.translation.vector - tm.translation.vector) / (2.0 * h);
            let dr = (tp.rotation * tm.rotation.inverse()).scaled_axis() / (2.0 * h);
            let col = jac.column(i);
            let scale = col.norm().max(1.0);
            let e = ((dp - col.fixed_rows::<3>(0)).norm() + (dr - col.fixed_rows::<3>(3)).norm()) / scale;
            out.worst_jacobian_rel = out.worst_jacobian_rel.max(e);
        }
        // Round trip from a seed near q.
        let seed_q: Vec<f64> =
            q.iter().zip(&limits).map(|(v, l)| (v + rng.random_range(-0.02..0.02)).clamp(l.lower, l.upper)).collect();
        out.round_trips += 1;
        match model.inverse(&target, &seed_q) {
            Ok(sol) => {
                if let Ok(back) = model.forward(&sol) {
                    let e = pose_error(&target, &back);
                    out.worst_position_m = out.worst_position_m.max(e.fixed_rows::<3>(0).norm());
                    if mobility == Mobility::Full6 {
                        out.worst_orientation_rad = out.worst_orientation_rad.max(e.fixed_rows::<3>(3).norm());
                    }
                }
                for ((a, b), k) in sol.iter().zip(&q).zip(&kinds) {
                    let d = match k {
                        JointKind::Revolute => wrap_angle(a - b).abs(),
                        JointKind::Prismatic => (a - b).abs(),
                    };
                    out.worst_joint = out.worst_joint.max(d);
                }
            }
            Err(_) => out.ik_failed += 1,
        }
    }
    out
}
