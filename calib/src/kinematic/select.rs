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

use nalgebra::DMatrix;
use serde::Serialize;

use super::KinematicCalibration;
use crate::error::Result;
use crate::identifiability::{analyze, Identifiability};

/// The selection rank of candidate `name` of a serial chain (lower is kept first).
pub(crate) fn priority(name: &str) -> u32 {
    if name.starts_with("offset.") || name.starts_with("target_tool.") {
        0
    } else if name.starts_with("frame.") {
        1
    } else if name.starts_with("joint") && !name.contains(".corr_") {
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
    } else if name.starts_with("frame.") {
        0.5
    } else if name.starts_with("target_tool.") {
        0.7
    } else if name.starts_with("offset.") {
        0.8
    } else {
        1.0
    }
}

/// Identifiability over the columns `cols` of `a` (names taken from `names`): for a serial chain
/// the prioritized selection ([`priority`]), for a parallel robot the pivoted QR of the columns
/// weighted by [`weight`].
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
        Ok(ferrocal_lsq::identifiability::analyze_prioritized(&sub, &sub_names, &prio, tol)?)
    } else {
        analyze(&sub, &sub_names, tol)
    }
}

/// One kept parameter a fixed one trades against.
#[derive(Clone, Debug, Serialize)]
pub struct TradePartner {
    /// The kept parameter.
    pub name: String,
    /// The change of the kept parameter (in its unit) that has the same effect on the
    /// measurements as a unit change of the fixed one (in its unit), in the least-squares
    /// sense over the measured poses, at the start values.
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
    /// For every candidate the structural analysis at the start fixed: the kept parameters it
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
