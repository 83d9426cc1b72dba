//! Rows that disagree with every calibration: a residual test after the fit, the rows beyond it
//! named and dropped, the fit repeated without them.
//!
//! A typo in one row of a tracker table (a coordinate 50 mm off, x and y swapped) pulls a
//! least-squares fit towards it and raises s0 for every row; the user is told neither which row
//! nor why. The test: each row's position residual over its standard deviation, `z_i = |e_i| /
//! sigma_i` (3-D, so `z` follows a chi distribution with 3 degrees of freedom times the common
//! scale when the noise model is right up to a factor), against a robust estimate of that common
//! scale, `s = median(z) / 1.5382` (the median of chi with 3 degrees of freedom). A row with
//! `z_i > threshold * s` is an outlier: its error is `threshold` times what the other rows say the
//! noise is, whatever the stated sigma. The median is not moved by a few wrong rows, so the test
//! sees them even though the first fit leaned towards them. When more than `max_fraction` of the
//! rows are beyond the threshold the rows are not the problem (the model is): nothing is dropped,
//! and the result says so.

use serde::{Deserialize, Serialize};

use super::{calibrate, KinematicCalibration, KinematicOptions};
use crate::error::Result;
use crate::measurement::PoseMeasurement;

/// Median of the chi distribution with 3 degrees of freedom.
const CHI3_MEDIAN: f64 = 1.538_2;

/// Settings of the residual test ([`KinematicOptions::outliers`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct OutlierScreen {
    /// A row is an outlier when its normalised residual exceeds this many times the robust scale
    /// of all rows' normalised residuals. The default, 8, is far in the tail of a 3-D Gaussian
    /// error (chi with 3 degrees of freedom exceeds 8 with probability 1e-13) and of the
    /// heavier-tailed residuals unmodelled physics leaves (the shared UR5, UR10 and positioner
    /// tables, whose largest rows stand at 3-5 times the scale: `tests/tests/reliability.rs`).
    pub threshold: f64,
    /// Drop nothing when more than this fraction of the rows is beyond the threshold.
    pub max_fraction: f64,
    /// Rounds of test-and-refit; each drops the one worst row beyond the threshold (a wrong row
    /// pulls the fit towards it, so that its neighbours and a repeated measurement of its pose can
    /// look wrong until it is gone), so this is also the most rows it drops.
    pub max_rounds: usize,
}

impl Default for OutlierScreen {
    fn default() -> Self {
        Self { threshold: 8.0, max_fraction: 0.05, max_rounds: 10 }
    }
}

/// A row the residual test dropped.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DroppedRow {
    /// The row's `pose_id`.
    pub pose_id: String,
    /// Its line in the table, when known.
    pub line: Option<u64>,
    /// Its position residual in the fit that found it (mm).
    pub residual_mm: f64,
    /// Its normalised residual over the robust scale of all rows (the test's statistic).
    pub ratio: f64,
}

impl DroppedRow {
    /// One line for the terminal: which row, how far off, why.
    pub fn describe(&self) -> String {
        let line = self.line.map(|l| format!(" (line {l})")).unwrap_or_default();
        format!(
            "row '{}'{line} dropped: its residual of {:.3} mm is {:.1} times what the other rows' residuals say the noise is; check it for a typo (a wrong digit, swapped columns, another unit)",
            self.pose_id, self.residual_mm, self.ratio
        )
    }
}

/// [`calibrate`] with the residual test of `screen`: fit, drop the worst row beyond the
/// threshold, refit, for up to `max_rounds` rounds. The result's `dropped_rows` names them (empty when
/// nothing was dropped); `outlier_note` says why nothing was dropped when many rows were beyond
/// the threshold.
pub(super) fn screened(
    model: &ferrocal_robot::RobotModel,
    rows: &[&PoseMeasurement],
    opts: &KinematicOptions,
    screen: &OutlierScreen,
) -> Result<KinematicCalibration> {
    let plain = KinematicOptions { outliers: None, ..opts.clone() };
    let mut kept: Vec<&PoseMeasurement> = rows.to_vec();
    let mut dropped: Vec<DroppedRow> = Vec::new();
    let mut note = None;
    let mut cal = calibrate(model, &kept, &plain)?;
    for _ in 0..screen.max_rounds {
        let (errors, _) = cal.calibrated.errors(&kept)?;
        let z: Vec<f64> = errors
            .iter()
            .zip(&kept)
            .map(|(e, r)| e.norm() / r.sigma_m.unwrap_or(opts.sigma_position_m).max(f64::MIN_POSITIVE))
            .collect();
        let mut sorted = z.clone();
        sorted.sort_by(f64::total_cmp);
        let scale = sorted[sorted.len() / 2] / CHI3_MEDIAN;
        if scale.is_nan() || scale <= 0.0 {
            break;
        }
        let beyond: Vec<usize> = (0..z.len()).filter(|&i| z[i] > screen.threshold * scale).collect();
        if beyond.is_empty() {
            break;
        }
        let total = rows.len() as f64;
        if (dropped.len() + beyond.len()) as f64 > screen.max_fraction * total {
            note = Some(format!(
                "{} of {} rows have residuals beyond {} times the others' scale: too many to be typos; the model, the units or the noise level is off, so no row was dropped",
                dropped.len() + beyond.len(),
                rows.len(),
                screen.threshold
            ));
            break;
        }
        // The worst row only: a wrong row pulls the fit towards it, so that a repeated
        // measurement of the same pose can look wrong too until the wrong one is gone.
        let worst = beyond.iter().copied().max_by(|a, b| z[*a].total_cmp(&z[*b])).expect("non-empty");
        dropped.push(DroppedRow {
            pose_id: kept[worst].pose_id.clone(),
            line: kept[worst].source_line,
            residual_mm: errors[worst].norm() * 1e3,
            ratio: z[worst] / scale,
        });
        kept.remove(worst);
        cal = calibrate(model, &kept, &plain)?;
    }
    if note.is_some() && !dropped.is_empty() {
        // A later round found too many: keep every row, as the note says.
        cal = calibrate(model, rows, &plain)?;
        dropped.clear();
    }
    cal.dropped_rows = dropped;
    cal.outlier_note = note;
    Ok(cal)
}
