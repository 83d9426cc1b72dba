//! Rows that disagree with every calibration: a residual test after the fit, the rows beyond it
//! named and dropped, the fit repeated without them.
//!
//! A typo in one row of a tracker table (a coordinate 50 mm off, x and y swapped) pulls a
//! least-squares fit towards it and raises s0 for every row; the user is told neither which row
//! nor why. The test: each row's position residual over its effective standard deviation,
//! `z_i = |e_i| / sqrt(sigma_i^2 + tau^2)` (3-D, so `z` follows a chi distribution with 3 degrees
//! of freedom times a common scale when the noise model is right up to a factor), against a
//! robust estimate of that scale, `s = median(z) / 1.5382` (the median of chi with 3 degrees of
//! freedom); `tau` is the error the model leaves in every row when the stated sigmas are smaller
//! than the residuals ([`ratios`]). A row with `z_i > threshold * s` is an outlier: its error is
//! `threshold` times what the other rows say the noise is, whatever the stated sigma. The median
//! is not moved by a few wrong rows, so the test
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
    /// of all rows' normalised residuals. The default, 12, is far beyond any Gaussian tail (a 3-D
    /// Gaussian error reaches 4.2 times the scale once in 1000 rows) and beyond the heavier tails
    /// real tables have: the largest row of the shared clean tables stands at 4.3 (UR5), 4.7
    /// (UR10 series A), 9.1 (UR10 series B) and POSITIONER times the scale (`docs/reliability.md`).
    /// A 50 mm typo in the UR5 table stands at about 800.
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
        Self { threshold: 12.0, max_fraction: 0.05, max_rounds: 10 }
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
/// threshold, refit, for up to `max_rounds` rounds (rows still beyond after them: too many, as
/// with `max_fraction`). The result's `dropped_rows` names them (empty when
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
    let mut largest = None;
    let mut cal = calibrate(model, &kept, &plain)?;
    for round in 0..=screen.max_rounds {
        let (errors, _) = cal.calibrated.errors(&kept)?;
        let norms: Vec<f64> = errors.iter().map(|e| e.norm()).collect();
        let sigmas: Vec<f64> = kept.iter().map(|r| r.sigma_m.unwrap_or(opts.sigma_position_m)).collect();
        let Some(z) = ratios(&norms, &sigmas) else { break };
        largest = z.iter().copied().max_by(f64::total_cmp);
        let beyond: Vec<usize> = (0..z.len()).filter(|&i| z[i] > screen.threshold).collect();
        if beyond.is_empty() {
            break;
        }
        let total = rows.len() as f64;
        let count = dropped.len() + beyond.len();
        if count as f64 > screen.max_fraction * total || round == screen.max_rounds {
            note = Some(format!(
                "{count} of {} rows have residuals beyond {} times the others' scale (more than {} rows or {:.0} % of them): too many to be typos; the model, the units or the noise level is off, so no row was dropped",
                rows.len(),
                screen.threshold,
                screen.max_rounds,
                100.0 * screen.max_fraction
            ));
            break;
        }
        // The worst row only: a wrong row pulls the fit towards it, so that a repeated
        // measurement of the same pose can look wrong too until the wrong one is gone.
        let worst = beyond.iter().copied().max_by(|a, b| z[*a].total_cmp(&z[*b])).expect("non-empty");
        dropped.push(DroppedRow {
            pose_id: kept[worst].pose_id.clone(),
            line: kept[worst].source_line,
            residual_mm: norms[worst] * 1e3,
            ratio: z[worst],
        });
        kept.remove(worst);
        cal = calibrate(model, &kept, &plain)?;
    }
    if note.is_some() && !dropped.is_empty() {
        // A later round found too many: keep every row, as the note says.
        cal = calibrate(model, rows, &plain)?;
        dropped.clear();
    }
    cal.largest_residual_ratio = largest;
    cal.dropped_rows = dropped;
    cal.outlier_note = note;
    Ok(cal)
}

/// The test's statistic per row: its position residual `e_i` (m) over its effective standard
/// deviation `sqrt(sigma_i^2 + tau^2)`, over the robust scale of all rows, `median / 1.5382`.
/// The noise floor `tau` (m) is zero when the stated sigmas `sigma_i` (m) explain the residuals
/// (the scale is at most 1); otherwise it is the common error the model leaves in every row
/// (chosen so that the scale is 1). Without it a row whose stated sigma is far below that common
/// error (the UR10 series B tracker states 0.002-0.057 mm against 0.36 mm median residual)
/// would stand out for its sigma, not its error. With one sigma for every row the statistic is
/// `e_i / median(e) * 1.5382` either way. `None` when the scale is zero or not finite.
pub(super) fn ratios(errors_m: &[f64], sigmas_m: &[f64]) -> Option<Vec<f64>> {
    let median = |v: &[f64]| -> f64 {
        let mut s = v.to_vec();
        s.sort_by(f64::total_cmp);
        s.get(s.len() / 2).copied().unwrap_or(f64::NAN)
    };
    let normalised = |tau_m: f64| -> Vec<f64> {
        errors_m.iter().zip(sigmas_m).map(|(e, s)| e / (s * s + tau_m * tau_m).sqrt().max(f64::MIN_POSITIVE)).collect()
    };
    let mut tau_m = 0.0;
    if median(&normalised(0.0)) > CHI3_MEDIAN {
        // median(z(tau)) falls with tau; at tau = median(e) / 1.5382 it is at most 1.5382.
        let (mut lo, mut hi) = (0.0, median(errors_m) / CHI3_MEDIAN);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if median(&normalised(mid)) > CHI3_MEDIAN {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        tau_m = hi;
    }
    let z = normalised(tau_m);
    let scale = median(&z) / CHI3_MEDIAN;
    (scale.is_finite() && scale > 0.0).then(|| z.iter().map(|v| v / scale).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic sequence in [0, 1).
    fn unit(k: usize) -> f64 {
        ((k as f64 * 12.9898).sin() * 43758.5453).fract().abs()
    }

    /// Residuals of 0.1-0.5 mm on 1000 rows with one row at 5 mm.
    fn errors_m() -> Vec<f64> {
        let mut e: Vec<f64> = (0..1000).map(|k| (0.1 + 0.4 * unit(k)) * 1e-3).collect();
        e[17] = 5e-3;
        e
    }

    #[test]
    fn one_sigma_for_every_row_gives_the_residual_over_the_median() {
        let e = errors_m();
        let mut sorted = e.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[500];
        // Stated sigmas above and below the residuals: the same statistic.
        for sigma_m in [1e-5, 3e-4, 1e-2] {
            let z = ratios(&e, &vec![sigma_m; e.len()]).unwrap();
            for (zi, ei) in z.iter().zip(&e) {
                assert!((zi - ei / median * CHI3_MEDIAN).abs() < 1e-9 * zi.max(1.0), "{sigma_m}: {zi}");
            }
        }
    }

    /// The UR10 series B case: stated sigmas spread over a factor 30 and far below the residuals.
    /// Over the stated sigma, rows with a small one stand out (beyond 12); with the noise floor
    /// only the 5 mm row does.
    #[test]
    fn a_row_with_a_small_stated_sigma_does_not_stand_out_for_it() {
        let e = errors_m();
        let sigmas: Vec<f64> = (0..e.len()).map(|k| (0.002 + 0.055 * unit(k + 5000)) * 1e-3).collect();
        let naive: Vec<f64> = e.iter().zip(&sigmas).map(|(e, s)| e / s).collect();
        let mut sorted = naive.clone();
        sorted.sort_by(f64::total_cmp);
        let naive_scale = sorted[500] / CHI3_MEDIAN;
        let naive_beyond = naive.iter().filter(|z| **z > 12.0 * naive_scale).count();
        assert!(naive_beyond > 10, "{naive_beyond}");
        let z = ratios(&e, &sigmas).unwrap();
        let beyond: Vec<usize> = (0..z.len()).filter(|&i| z[i] > 12.0).collect();
        assert_eq!(beyond, vec![17], "{:?}", beyond.iter().map(|&i| z[i]).collect::<Vec<_>>());
        let mut zs = z.clone();
        zs.sort_by(f64::total_cmp);
        assert!((zs[500] - CHI3_MEDIAN).abs() < 1e-6, "scale 1 at the median: {}", zs[500]);
    }

    #[test]
    fn zero_residuals_give_no_statistic() {
        assert!(ratios(&[0.0; 5], &[1e-4; 5]).is_none());
    }
}
