//! The kinematic candidates a recording can test, and those it cannot (with the reason).

use ferrocal_robot::JointKind;
use nalgebra::Vector3;

use super::family::{Cand, Ctx};
use super::{DiagnoseOptions, Untestable};
use crate::effects::{CustomEffect, EffectSpec};
use crate::error::Result;
use crate::kinematic::KinematicCalibration;
use crate::measurement::PoseMeasurement;

/// The least range of a joint's angle over which an axis wobble is a candidate.
const MIN_WOBBLE_RANGE_RAD: f64 = 0.5;

/// Frequency grids (cycles per joint unit) of the periodic candidates per joint.
pub(super) fn period_grids(rows: &[&PoseMeasurement], kinds: &[JointKind], opts: &DiagnoseOptions) -> Vec<Vec<f64>> {
    kinds
        .iter()
        .enumerate()
        .map(|(j, kind)| {
            let (lo, hi) =
                rows.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), r| (l.min(r.q[j]), h.max(r.q[j])));
            let range = (hi - lo).max(1e-9);
            let (f_min, f_max) = match kind {
                JointKind::Revolute => (1.0 / opts.longest_period_rad, 1.0 / opts.shortest_period_rad),
                JointKind::Prismatic => (1.0 / range, 1.0 / opts.shortest_period_m),
            };
            let step = 1.0 / (4.0 * range);
            let n = (((f_max - f_min) / step).ceil() as usize).min(20_000);
            (0..=n).map(|k| f_min + k as f64 * step).filter(|f| *f <= f_max * 1.000_001).collect()
        })
        .collect()
}

/// The candidates that can be tested on this recording, and those that cannot (with why).
pub(super) fn enumerate_candidates(
    ctx: &Ctx,
    all_rows: &[PoseMeasurement],
    geo: &KinematicCalibration,
) -> Result<(Vec<Cand>, Vec<Untestable>)> {
    let mut cands = Vec::new();
    let mut un = Vec::new();
    let n = ctx.rows.len();
    // Loads from the nominal link frames (see `CalibratedModel::load_model`).
    let model = &geo.calibrated.load_model;
    let mut tau = Vec::with_capacity(n);
    for r in &ctx.rows {
        tau.push(crate::effects::holding_torques(model, &r.q, r.payload_kg.unwrap_or(0.0))?);
    }
    let tau_max = tau.iter().flatten().fold(0.0f64, |a, b| a.max(b.abs()));
    for (j, kind) in ctx.kinds.iter().enumerate() {
        let jn = j + 1;
        let q = ctx.q(j);
        let (lo, hi) = q.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| (l.min(*v), h.max(*v)));
        let moved = match kind {
            JointKind::Revolute => hi - lo > 0.05,
            JointKind::Prismatic => hi - lo > 0.01,
        };
        // Compliance: the load torque must vary.
        let tj: Vec<f64> = tau.iter().map(|t| t[j]).collect();
        let mean = tj.iter().sum::<f64>() / n as f64;
        let sd = (tj.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        if tau_max == 0.0 {
            un.push(Untestable {
                effect: "joint_compliance".into(),
                joints: vec![jn],
                reason: "the model carries no masses (no link inertials, no payload): load torques are unknown".into(),
            });
        } else if sd <= 1e-3 * tau_max.max(1.0) {
            un.push(Untestable {
                effect: "joint_compliance".into(),
                joints: vec![jn],
                reason: format!("joint {jn}'s gravity torque does not vary over the poses (its axis is vertical or it carries no load)"),
            });
        } else {
            cands.push(Cand::Fixed(EffectSpec::JointCompliance { joint: jn }));
        }
        // Backlash: directions on every row, both signs seen.
        let spec = EffectSpec::Backlash { joint: jn };
        let missing = all_rows.iter().any(|r| r.dir.as_ref().and_then(|d| d.get(j)).is_none());
        if missing {
            un.push(Untestable {
                effect: "backlash".into(),
                joints: vec![jn],
                reason: "the recording has no approach directions (dir columns)".into(),
            });
        } else {
            let plus = ctx.rows.iter().filter(|r| r.dir.as_ref().is_some_and(|d| d[j] > 0)).count();
            let minus = ctx.rows.iter().filter(|r| r.dir.as_ref().is_some_and(|d| d[j] < 0)).count();
            let zero = n - plus - minus;
            if zero > 0 {
                un.push(Untestable {
                    effect: "backlash".into(),
                    joints: vec![jn],
                    reason: format!("joint {jn}'s approach direction is unknown (0) on {zero} poses"),
                });
            } else if plus < 5 || minus < 5 {
                un.push(Untestable {
                    effect: "backlash".into(),
                    joints: vec![jn],
                    reason: format!(
                        "joint {jn} was approached from one side only ({plus} positive, {minus} negative approaches)"
                    ),
                });
            } else {
                cands.push(Cand::Fixed(spec));
            }
        }
        if moved {
            cands.push(Cand::Fixed(EffectSpec::JointScaleError { joint: jn }));
            cands.push(Cand::Periodic { joint: jn });
            if *kind == JointKind::Revolute {
                // Once and twice per revolution (eccentricity, ovality), with the period fixed.
                for k in [1.0, 2.0] {
                    cands.push(Cand::Fixed(EffectSpec::PeriodicJointError {
                        joint: jn,
                        period_si: std::f64::consts::TAU / k,
                    }));
                }
            }
        } else {
            for e in ["joint_scale_error", "periodic_joint_error"] {
                un.push(Untestable {
                    effect: e.into(),
                    joints: vec![jn],
                    reason: format!("joint {jn} barely moved over the poses"),
                });
            }
        }
    }
    // Axis misalignment: a revolute joint of a serial chain that turned far enough for a wobble
    // at twice its angle to differ from a fixed axis placement.
    if let ferrocal_robot::RobotModel::Serial(_) = model {
        for (j, kind) in ctx.kinds.iter().enumerate() {
            if *kind != JointKind::Revolute {
                continue;
            }
            let q = ctx.q(j);
            let (lo, hi) = q.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| (l.min(*v), h.max(*v)));
            if hi - lo >= MIN_WOBBLE_RANGE_RAD {
                cands.push(Cand::Fixed(EffectSpec::AxisMisalignment { joint: j + 1 }));
            } else {
                un.push(Untestable {
                    effect: "axis_misalignment".into(),
                    joints: vec![j + 1],
                    reason: format!(
                        "joint {} turned through {:.0} deg only: a wobble with its angle needs at least {:.0} deg",
                        j + 1,
                        (hi - lo).to_degrees(),
                        MIN_WOBBLE_RANGE_RAD.to_degrees()
                    ),
                });
            }
        }
    }
    // Coupled transmissions: joint J's error in proportion to joint K's angle, for every pair of
    // joints that both moved.
    let moved: Vec<bool> = ctx
        .kinds
        .iter()
        .enumerate()
        .map(|(j, kind)| {
            let q = ctx.q(j);
            let (lo, hi) = q.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| (l.min(*v), h.max(*v)));
            match kind {
                JointKind::Revolute => hi - lo > 0.05,
                JointKind::Prismatic => hi - lo > 0.01,
            }
        })
        .collect();
    for joint in 1..=ctx.kinds.len() {
        for driver in (1..=ctx.kinds.len()).filter(|&k| k != joint) {
            if moved[joint - 1] && moved[driver - 1] {
                cands.push(Cand::Fixed(EffectSpec::CoupledTransmission { joint, driver }));
            }
        }
    }
    // Length changes.
    if all_rows.iter().any(|r| r.temp_c.is_none()) {
        un.push(Untestable {
            effect: "thermal_expansion".into(),
            joints: vec![],
            reason: "no temperature (temp_c) on every row: expansion with temperature cannot be tested".into(),
        });
    } else {
        let (lo, hi) = ctx.rows.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), r| {
            let t = r.temp_c.unwrap_or(0.0);
            (l.min(t), h.max(t))
        });
        if hi - lo < 0.2 {
            un.push(Untestable {
                effect: "thermal_expansion".into(),
                joints: vec![],
                reason: format!("the temperature varied by only {:.2} K", hi - lo),
            });
        } else {
            cands.push(Cand::Fixed(EffectSpec::ThermalExpansion { reference_temp_c: ctx.ref_temp_c }));
        }
    }
    if all_rows.iter().any(|r| r.t_s.is_none()) {
        un.push(Untestable {
            effect: "thermal_expansion".into(),
            joints: vec![],
            reason: "no time (t_s) on every row: a drift with time cannot be tested".into(),
        });
    } else {
        let (lo, hi) = ctx.rows.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), r| {
            let t = r.t_s.unwrap_or(0.0);
            (l.min(t), h.max(t))
        });
        if hi - lo < 60.0 {
            un.push(Untestable {
                effect: "thermal_expansion".into(),
                joints: vec![],
                reason: format!("the recording spans only {:.0} s", hi - lo),
            });
        } else {
            cands.push(Cand::Fixed(EffectSpec::TimeDrift));
        }
    }
    // The registry's effects: the candidates each kind finds on the recording.
    for kind in crate::effect_registry::effect_kinds() {
        let found = kind.candidates(model, &ctx.rows);
        cands.extend(found.into_iter().map(|e| Cand::Fixed(EffectSpec::Custom(CustomEffect(e)))));
    }
    // Link compliance: serial chains with masses, per link that carries a further joint, when
    // the load moment across the next joint's axis varies over the poses.
    if let ferrocal_robot::RobotModel::Serial(chain) = model {
        if chain.has_mimic_joints() {
            un.push(Untestable {
                effect: "link_compliance".into(),
                joints: Vec::new(),
                reason: "the link bending model does not yet carry coupled (mimic) joints: not tested on this robot"
                    .into(),
            });
            return Ok((cands, un));
        }
        let mut per_row = Vec::with_capacity(n);
        for r in &ctx.rows {
            per_row.push(crate::effects::link_bendings(model, &r.q, r.payload_kg.unwrap_or(0.0))?);
        }
        for link in 1..ctx.kinds.len() {
            let moments: Vec<Vector3<f64>> = per_row.iter().map(|b| b[link - 1].0).collect();
            let mean = moments.iter().fold(Vector3::zeros(), |a, v| a + v) / n as f64;
            let sd = (moments.iter().map(|v| (v - mean).norm_squared()).sum::<f64>() / n as f64).sqrt();
            if tau_max == 0.0 {
                un.push(Untestable {
                    effect: "link_compliance".into(),
                    joints: vec![link, link + 1],
                    reason: "the model carries no masses (no link inertials, no payload): load moments are unknown"
                        .into(),
                });
            } else if sd <= 1e-3 * tau_max.max(1.0) {
                un.push(Untestable {
                    effect: "link_compliance".into(),
                    joints: vec![link, link + 1],
                    reason: format!(
                        "the load moment link {link} carries across joint {}'s axis does not vary over the poses",
                        link + 1
                    ),
                });
            } else {
                cands.push(Cand::Fixed(EffectSpec::LinkCompliance { link }));
            }
        }
    }
    Ok((cands, un))
}
