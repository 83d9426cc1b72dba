//! Which of several redundant candidates the calibration keeps, and what each fixed one trades
//! against.
//!
//! A serial chain's candidates overlap exactly in many places: the last joint's correction
//! translation is the target-to-tool offset, a joint's correction rotation about the next axis
//! is that joint's zero offset, the device frame can swallow the first joint's zero offset and
//! parts of its correction. The data cannot tell them apart, so one of each redundant set is
//! fixed. What a metrologist reads is the physical parameter: the joint zero offsets and the
//! tool (and the effects asked for) are kept first, then the device (base) frame, then the
//! link geometry (lengths, twists), and the per-joint correction terms only for what nothing
//! before them explains ([`priority`], [`ferrocal_lsq::identifiability::analyze_prioritized`]).
//! Parallel robots keep their earlier soft preference (column weights, [`weight`]).

use nalgebra::{DMatrix, Isometry3};
use serde::Serialize;

use super::problem::KinProblem;
use super::{scale_columns, KinematicCalibration, KinematicOptions, StateLayout};
use crate::error::Result;
use crate::frames::exp6;
use crate::identifiability::{analyze, Identifiability};
use crate::lsq::{solve, LmOptions};

/// The selection rank of candidate `name` of a serial chain (lower is kept first).
pub(crate) fn priority(name: &str) -> u32 {
    if name.starts_with("offset.") || name.starts_with("target_tool.") {
        0
    } else if name.starts_with("frame.") {
        1
    } else if (name.starts_with("joint") || name.starts_with("mimic")) && !name.contains(".corr_") {
        // Link geometry, and a mimic joint's coupling multiplier (`mimic<k>.coupling`).
        2
    } else if name.contains(".corr_") {
        3
    } else {
        // Effect parameters: asked for by name, and physical.
        0
    }
}

/// The pivoting weight of candidate `name` of a parallel robot: the robot model's own
/// parameters 1, joint offsets 0.8, the tool 0.7, the device frame 0.5 (a redundant frame is
/// what gets fixed, as in the source's identification "in the measuring device's frame").
/// Serial chains are selected by [`priority`]; their weight is 1.
pub(crate) fn weight(name: &str, serial: bool) -> f64 {
    if serial {
        1.0
    } else {
        parallel_weight(name)
    }
}

/// The pivoting weight by kind of parameter: the robot model's own parameters 1, joint offsets
/// 0.8, the tool 0.7, the device frame 0.5 (parallel robots' selection, and the experiment
/// design's ranking of every robot).
pub(crate) fn parallel_weight(name: &str) -> f64 {
    if name.starts_with("frame.") {
        0.5
    } else if name.starts_with("target_tool.") {
        0.7
    } else if name.starts_with("offset.") {
        0.8
    } else {
        1.0
    }
}

/// The smallest singular value, relative to the largest, that the selection of a serial chain
/// counts as identified (when the options' `rank_tolerance` is smaller). The columns are scaled
/// to 1 mm / 1 mrad, so the largest singular value is about a 1 mm shift of the device frame:
/// a combination below 1e-4 of it moves the measurements by less than 0.1 um per mm or mrad,
/// which no device resolves. With the target close to the last joint's axis (the UR5 tracker
/// table: 0.2 mm off it, 33 mm out) the wrist's correction terms are separated from the zero
/// offsets only by that lever (singular values 4e-5 and 3e-6 of the largest); kept, they made
/// the zero offset of joint 5 a +-0.4 rad parameter.
pub(crate) const SERIAL_MIN_REL_SINGULAR: f64 = 1e-4;

/// Identifiability over the columns `cols` of `a` (names taken from `names`): for a serial chain
/// the prioritized selection ([`priority`]) with a relative tolerance of at least
/// [`SERIAL_MIN_REL_SINGULAR`], for a parallel robot the pivoted QR of the columns weighted by
/// [`weight`].
pub(crate) fn analyze_subset(
    a: &DMatrix<f64>,
    names: &[String],
    cols: &[usize],
    tol: f64,
    serial: bool,
) -> Result<Identifiability> {
    let sub_names: Vec<String> = cols.iter().map(|&c| names[c].clone()).collect();
    let sub = DMatrix::from_fn(a.nrows(), cols.len(), |i, j| a[(i, cols[j])] * weight(&names[cols[j]], serial));
    if serial {
        let prio: Vec<u32> = sub_names.iter().map(|n| priority(n)).collect();
        let tol = tol.max(SERIAL_MIN_REL_SINGULAR);
        Ok(ferrocal_lsq::identifiability::analyze_prioritized(&sub, &sub_names, &prio, tol)?)
    } else {
        analyze(&sub, &sub_names, tol)
    }
}

/// The frames-first fit of a serial chain, before the selection: the device frame, the tool and
/// the joint zero offsets that the options leave free (those of them the Jacobian at the start
/// identifies, by [`analyze_subset`]) fitted alone, the link geometry at its nominal values, by
/// a short Levenberg-Marquardt. `problem`'s registrations `f0` and `tool0` are re-based on the
/// fitted frames (so the frame and tool increments are zero there) and the returned candidate
/// vector carries the fitted zero offsets; the selection is judged on the Jacobian at this
/// point. At the raw start the target sits on the flange (tool = 0), where the last joint's
/// zero offset and the corrections about axes through the flange have no effect and look
/// redundant, and a far-off frame mixes frame and joint columns; once the tool is known they
/// separate. Returns the start unchanged for parallel robots, the closure cost, or when the
/// fit fails or does not lower the cost.
pub(super) fn frames_first(
    problem: &mut KinProblem,
    layout: &StateLayout,
    opts: &KinematicOptions,
) -> Result<Vec<f64>> {
    let start = problem.start.clone();
    if !matches!(problem.base_model, ferrocal_robot::RobotModel::Serial(_))
        || problem.cost != super::Cost::ForwardKinematics
    {
        return Ok(start);
    }
    let mut cols: Vec<usize> = Vec::new();
    if opts.estimate_device_frame && opts.fixed_device_frame.is_none() {
        cols.extend(layout.frame.clone());
    }
    if opts.estimate_tool {
        cols.extend(layout.tool.clone());
    }
    if opts.joint_offsets {
        cols.extend(layout.offsets.clone());
    }
    if cols.is_empty() {
        return Ok(start);
    }
    let j0 = scale_columns(&problem.full_jacobian(&start)?, layout);
    let id = analyze_subset(&j0, &layout.names, &cols, opts.rank_tolerance, true)?;
    let free: Vec<usize> = cols.iter().enumerate().filter(|(k, _)| !id.fixed.contains(k)).map(|(_, &c)| c).collect();
    if free.is_empty() || problem.rows.len() * problem.block() <= free.len() {
        return Ok(start);
    }
    let all_free = std::mem::replace(&mut problem.free, free.clone());
    let x0: Vec<f64> = free.iter().map(|&i| start[i]).collect();
    let lm = LmOptions { max_iterations: 30, loss: opts.loss, ..opts.lm.clone() };
    let fitted = solve(&*problem, &x0, &lm);
    problem.free = all_free;
    let res = match fitted {
        Ok(res) if res.summary.final_cost < res.summary.initial_cost => res,
        _ => return Ok(start),
    };
    let mut at = start.clone();
    for (k, &i) in free.iter().enumerate() {
        at[i] = res.x[k];
    }
    let t = &at[layout.tool.clone()];
    let tool = if t.len() == 6 { exp6(t) } else { Isometry3::translation(t[0], t[1], t[2]) };
    problem.f0 = exp6(&at[layout.frame.clone()]) * problem.f0;
    problem.tool0 *= tool;
    for i in layout.frame.clone().chain(layout.tool.clone()) {
        at[i] = start[i];
    }
    Ok(at)
}

/// The joint torque (N m) below which a `joint_compliance` parameter's scale follows the load:
/// [`StateLayout::scale_compliances`].
pub(crate) const COMPLIANCE_SCALE_TORQUE_NM: f64 = 10.0;

/// The largest joint torque (N m) that counts as no load at all: rounding of the holding torques
/// of any arm (tens to thousands of N m times 1e-16) stays orders of magnitude below it.
pub(crate) const COMPLIANCE_TORQUE_FLOOR_NM: f64 = 1e-6;

impl StateLayout {
    /// [`StateLayout::new`] for `opts`, with the compliance scales of
    /// [`StateLayout::scale_compliances`] for `rows`.
    pub(crate) fn for_rows(
        model: &ferrocal_robot::RobotModel,
        tool_dim: usize,
        opts: &KinematicOptions,
        rows: &[&crate::PoseMeasurement],
    ) -> Result<Self> {
        let mut layout = StateLayout::new(model, tool_dim, &opts.model_params, &opts.effects);
        layout.scale_compliances(model, rows, &opts.effects)?;
        Ok(layout)
    }

    /// Rescales the `joint_compliance` parameters of lightly loaded joints: the fixed scale of
    /// 1e-6 rad/(N m) deflects a joint by 1e-5 rad at 10 N m, but a wrist holding 0.2 N m moves
    /// by 2e-7 rad per scale unit, which the selection takes for an unidentifiable column even
    /// when such a wrist sags by 25 mrad (the simulated coupled arm of `tests/tests/coupled.rs`).
    /// A joint whose largest holding torque over `rows` is below [`COMPLIANCE_SCALE_TORQUE_NM`]
    /// gets the scale `1e-4 rad / max |tau|` instead (0.1 mrad per scale unit at its largest
    /// load); joints carrying more keep 1e-6 (the UR5's shoulder and elbow: its published
    /// numbers are unchanged).
    pub(crate) fn scale_compliances(
        &mut self,
        model: &ferrocal_robot::RobotModel,
        rows: &[&crate::PoseMeasurement],
        effects: &[crate::effects::EffectSpec],
    ) -> Result<()> {
        for (e, range) in effects.iter().zip(self.effects.clone()) {
            let crate::effects::EffectSpec::JointCompliance { joint } = e else { continue };
            let mut peak: f64 = 0.0;
            for r in rows {
                let tau = crate::effects::holding_torques(model, &r.q, r.payload_kg.unwrap_or(0.0))?;
                peak = peak.max(tau.get(joint - 1).copied().unwrap_or(0.0).abs());
            }
            // A joint whose torque is zero but for rounding (a roll axis through its links'
            // centres of mass) keeps 1e-6: its column is empty and the selection fixes it, where
            // a scale of 1e-4 / 1e-15 would step the compliance by 1e8 in the derivatives.
            if peak > COMPLIANCE_TORQUE_FLOOR_NM && peak < COMPLIANCE_SCALE_TORQUE_NM {
                self.scales[range.start] = 1e-4 / peak;
            }
        }
        Ok(())
    }
}

/// One kept parameter a fixed one trades against.
#[derive(Clone, Debug, Serialize)]
pub struct TradePartner {
    /// The kept parameter.
    pub name: String,
    /// The change of the kept parameter (in its unit) that has the same effect on the
    /// measurements as a unit change of the fixed one (in its unit), in the least-squares
    /// sense over the measured poses, where the selection was judged.
    pub per_unit: f64,
}

/// A candidate the calibration fixed because the data cannot separate it from kept ones.
#[derive(Clone, Debug, Serialize)]
pub struct TradeOff {
    /// The fixed parameter.
    pub name: String,
    /// The kept parameters it trades against, strongest first; empty when it has no effect on
    /// the measurements at all.
    pub against: Vec<TradePartner>,
}

impl KinematicCalibration {
    /// For every candidate the structural selection fixed: the kept parameters it
    /// is redundant with (from the least-squares fit of its Jacobian column by the kept ones),
    /// with the exchange rate in the parameters' own units.
    pub fn trade_offs(&self) -> Vec<TradeOff> {
        let id = &self.identifiability_before;
        let serial = matches!(self.calibrated.model, ferrocal_robot::RobotModel::Serial(_));
        let scale = |name: &str| {
            let s = self.layout.names.iter().position(|n| n == name).map_or(1.0, |i| self.layout.scales[i]);
            s * weight(name, serial)
        };
        id.fixed
            .iter()
            .map(|&j| {
                let name = id.names[j].clone();
                let sj = scale(&name);
                let against = id
                    .trades_against
                    .get(j)
                    .map(|t| {
                        t.iter()
                            .map(|&(k, c)| TradePartner {
                                name: id.names[k].clone(),
                                per_unit: c * scale(&id.names[k]) / sj,
                            })
                            .collect()
                    })
                    .unwrap_or_default();
                TradeOff { name, against }
            })
            .collect()
    }
}

/// One line per trade-off for a terminal: `name ~ +1.000 other, ...` or `name: no effect`.
pub fn describe_trade_offs(t: &[TradeOff]) -> Vec<String> {
    t.iter()
        .map(|t| {
            if t.against.is_empty() {
                format!("{}: no effect on the measurements", t.name)
            } else {
                let parts: Vec<String> = t.against.iter().map(|p| format!("{:+.4} {}", p.per_unit, p.name)).collect();
                format!("{} trades against {}", t.name, parts.join(", "))
            }
        })
        .collect()
}
