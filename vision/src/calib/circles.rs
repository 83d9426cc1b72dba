//! Calibration from circle grids with the perspective bias of the dot centres corrected.
//!
//! The detector measures the centre of each dot's image, an ellipse whose centre is not the
//! image of the dot's centre ([`crate::detect::circles::bias`]). The calibration is solved on
//! the measured centres; then, with that camera and every view's pose, each centre is
//! corrected by its predicted offset (always from the measured centre, never cumulatively) and
//! the calibration solved again, until the corrections change by less than
//! [`BIAS_TOLERANCE_PX`] (at most [`BIAS_ROUNDS`] rounds). The dots' radii are those the
//! detector measured (ellipse area over the local lattice cell), so an unknown print size is
//! not a problem; the offset scales with the radius squared.

use serde::{Deserialize, Serialize};

use super::{calibrate_camera, CalibrationOptions, CameraCalibration, PlanarTarget, View};
use crate::detect::circles::bias::ellipse_centre_offset_px;
use crate::detect::CircleGrid;
use crate::error::{Result, VisionError};

/// Largest number of correction rounds.
pub const BIAS_ROUNDS: usize = 5;
/// The rounds stop when no correction changes by more than this, pixels.
pub const BIAS_TOLERANCE_PX: f64 = 1e-4;

/// What the bias correction did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CircleBiasReport {
    /// The dots' radii used, `[small, large]`, millimetres.
    pub radii_mm: [f64; 2],
    /// Correction rounds run.
    pub rounds: usize,
    /// RMS reprojection error on the measured (ellipse) centres, pixels.
    pub rms_before_px: f64,
    /// RMS reprojection error on the corrected centres, pixels.
    pub rms_after_px: f64,
    /// RMS length of the corrections, pixels.
    pub shift_rms_px: f64,
    /// Largest correction, pixels.
    pub shift_max_px: f64,
    /// Corrected minus uncorrected `fx, fy, cx, cy`, pixels.
    pub intrinsics_change_px: [f64; 4],
}

impl std::fmt::Display for CircleBiasReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let d = self.intrinsics_change_px;
        write!(
            f,
            "circle centres corrected for perspective ({} round(s), dot radii {:.2} / {:.2} mm as measured): \
             corrections RMS {:.4} px, max {:.4} px; RMS {:.4} -> {:.4} px; fx {:+.3}, fy {:+.3}, cx {:+.3}, cy {:+.3} px",
            self.rounds,
            self.radii_mm[0],
            self.radii_mm[1],
            self.shift_rms_px,
            self.shift_max_px,
            self.rms_before_px,
            self.rms_after_px,
            d[0],
            d[1],
            d[2],
            d[3]
        )
    }
}

/// Calibrates from views of a circle grid, correcting the centres' perspective bias (see the
/// module documentation). `radii_m` are the dots' radii `[small, large]` in metres (the large
/// one is dot 0 of a modified grid).
pub fn calibrate_circle_grid(
    views: &[View],
    grid: &CircleGrid,
    radii_m: [f64; 2],
    options: &CalibrationOptions,
) -> Result<(CameraCalibration, CircleBiasReport)> {
    if !(radii_m.iter().all(|r| r.is_finite() && *r > 0.0)) {
        return Err(VisionError::InvalidInput { detail: format!("circle radii {radii_m:?} m must be positive") });
    }
    let target = PlanarTarget { points_m: grid.target_points_m(), reversible: false };
    let first = calibrate_camera(views, &target, options)?;
    let radius = |id: usize| if grid.modified && id == 0 { radii_m[1] } else { radii_m[0] };
    let mut cal = first.clone();
    let mut offsets: Vec<Vec<nalgebra::Vector2<f64>>> =
        views.iter().map(|v| vec![Default::default(); v.corners_px.len()]).collect();
    let mut rounds = 0;
    for _ in 0..BIAS_ROUNDS {
        rounds += 1;
        let mut change = 0.0f64;
        let mut corrected = Vec::with_capacity(views.len());
        for ((v, rep), off) in views.iter().zip(&cal.views).zip(offsets.iter_mut()) {
            let mut w = v.clone();
            if rep.rms_px.is_finite() {
                for ((id, px), o) in v.point_ids.iter().zip(&mut w.corners_px).zip(off.iter_mut()) {
                    let new =
                        ellipse_centre_offset_px(&cal.camera, &rep.t_cam_target, &target.points_m[*id], radius(*id))?;
                    change = change.max((new - *o).norm());
                    *o = new;
                    *px -= new;
                }
            }
            corrected.push(w);
        }
        cal = calibrate_camera(&corrected, &target, options)?;
        if change < BIAS_TOLERANCE_PX {
            break;
        }
    }
    let shifts: Vec<f64> = offsets.iter().flatten().map(|o| o.norm()).collect();
    let k0 = first.camera.intrinsics;
    let k1 = cal.camera.intrinsics;
    let report = CircleBiasReport {
        radii_mm: [radii_m[0] * 1e3, radii_m[1] * 1e3],
        rounds,
        rms_before_px: first.rms_px,
        rms_after_px: cal.rms_px,
        shift_rms_px: (shifts.iter().map(|s| s * s).sum::<f64>() / shifts.len().max(1) as f64).sqrt(),
        shift_max_px: shifts.iter().copied().fold(0.0, f64::max),
        intrinsics_change_px: [k1.fx_px - k0.fx_px, k1.fy_px - k0.fy_px, k1.cx_px - k0.cx_px, k1.cy_px - k0.cy_px],
    };
    Ok((cal, report))
}
