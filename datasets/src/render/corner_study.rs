//! The corner study of `ferrocal corner-study`: sub-pixel corner accuracy on rendered images
//! with exact truth.
//!
//! Chessboards (9 x 6 inner corners) and Gantry-Tau plates are rendered by
//! [`crate::render`] (pinhole camera, exact area coverage, Gaussian PSF, sensor noise)
//! at every combination of blur (PSF sigma 0.5, 1.0, 1.5, 2.5 px) and noise (off: quantisation
//! only; low: the default sensor, shot noise and 6 e- read noise; high: shot noise and 120 e-
//! = 3 DN read noise). For each level the RMS corner error against the truth is reported for
//! this project's edge-model refinement, OpenCV's `cornerSubPix` (11 x 11 window, started from
//! the same coarse corners), OpenCV's `findChessboardCornersSB` (accurate mode) and OpenCV's
//! classic recipe (`findChessboardCorners` + `cornerSubPix` 11 x 11), beside the Cramer-Rao
//! bound of the edge model under the true noise model. The rows leave as CSV
//! ([`rows_csv`]); the Markdown table is `ferrocal_report::corner_study`.

use nalgebra::{Isometry3, Point2, Translation3, UnitQuaternion, Vector3};
use serde::Serialize;

use super::{Psf, RenderConfig, Renderer, SensorConfig, ShotNoise, TargetConfig, Vignetting};
use crate::error::{DatasetError, Result};
use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};
use ferrocal_vision::detect::baseline::{opencv_corner_subpix, opencv_find_chessboard, opencv_find_chessboard_sb};
use ferrocal_vision::detect::{detect, DetectOptions, Pattern};
use ferrocal_vision::subpix::{LineSupport, NoiseModel, NoiseSpec};

/// The study's settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CornerStudySettings {
    /// Rendered images per target and level.
    pub images: usize,
    /// Seed of the sensor noise.
    pub seed: u64,
    /// Image width, pixels (height is 3/4 of it; at least 320).
    pub width: u32,
}

/// One row of the table.
#[derive(Clone, Debug, Serialize)]
pub struct StudyRow {
    /// `chessboard` or `plate`.
    pub target: String,
    /// PSF standard deviation, pixels.
    pub psf_sigma_px: f64,
    /// `off`, `low` or `high`.
    pub noise: String,
    /// Images rendered.
    pub images: usize,
    /// Corners compared (this project).
    pub corners: usize,
    /// RMS error of this project's corners, px.
    pub ours_rms_px: f64,
    /// RMS of the Cramer-Rao bound (sqrt of the mean trace), px.
    pub crb_rms_px: f64,
    /// RMS of the reported standard deviation (sqrt of the mean trace of the covariance), px.
    pub reported_rms_px: f64,
    /// RMS error with whole grid lines (`LineSupport::Global`, valid here: pinhole camera), px.
    pub ours_global_rms_px: f64,
    /// Cramer-Rao bound of the whole-line fit, px.
    pub crb_global_rms_px: f64,
    /// RMS error of cornerSubPix 11 x 11 from the same coarse corners, px.
    pub subpix_rms_px: f64,
    /// RMS error of findChessboardCornersSB (accurate mode), px (NaN for the plate).
    pub sb_rms_px: f64,
    /// Images where SB found the board.
    pub sb_found: usize,
    /// RMS error of findChessboardCornersSB with its default flags (no CALIB_CB_ACCURACY), px.
    pub sb_default_rms_px: f64,
    /// RMS error of findChessboardCorners + cornerSubPix 11 x 11, px (NaN for the plate).
    pub classic_rms_px: f64,
    /// Images where the classic detector found the board.
    pub classic_found: usize,
    /// Images where this project found the target.
    pub ours_found: usize,
}

fn pose(x: f64, y: f64, z: f64, roll_deg: f64, tilt_x_deg: f64, tilt_y_deg: f64) -> Isometry3<f64> {
    let face = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    let roll = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), roll_deg.to_radians());
    let tx = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), tilt_x_deg.to_radians());
    let ty = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), tilt_y_deg.to_radians());
    Isometry3::from_parts(Translation3::new(x, y, z), ty * tx * roll * face)
}

/// Squared error of each found point to its nearest truth point (ordering-agnostic).
fn nearest_sq(found: &[Point2<f64>], truth: &[Point2<f64>]) -> Vec<f64> {
    found.iter().map(|p| truth.iter().map(|t| (p - t).norm_squared()).fold(f64::INFINITY, f64::min)).collect()
}

fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        f64::NAN
    } else {
        (v.iter().sum::<f64>() / v.len() as f64).sqrt()
    }
}

/// Runs the study: every target, blur and noise level; `log` receives one line per level.
/// Returns the rows and the image size.
pub fn corner_study(args: &CornerStudySettings, log: &dyn Fn(&str)) -> Result<(Vec<StudyRow>, u32, u32)> {
    let (w, h) = (args.width.max(320), args.width.max(320) * 3 / 4);
    let f = 1.1 * w as f64;
    let camera = CameraModel::new(
        Intrinsics { fx_px: f, fy_px: f, cx_px: 0.5 * w as f64 - 0.5, cy_px: 0.5 * h as f64 - 0.5 },
        Distortion::None,
        ImageSize { width_px: w, height_px: h },
    )?;
    let chessboard = TargetConfig::Chessboard { inner_cols: 9, inner_rows: 6, square_m: 0.025, margin_m: 0.02 };
    let plate = TargetConfig::Plate { square_m: 0.04, margin_m: 0.015 };
    // Squares of about 3.5 % of the image width.
    let z_board = f * 0.025 / (0.035 * w as f64);
    let z_plate = f * 0.04 / (0.045 * w as f64);
    let noises: [(&str, SensorConfig); 3] = [
        ("off", SensorConfig::default().noiseless()),
        ("low", SensorConfig::default()),
        ("high", SensorConfig { read_noise_e: 120.0, shot_noise: ShotNoise::Gaussian, ..SensorConfig::default() }),
    ];
    let mut rows = Vec::new();
    for (name, target, z, pattern) in
        [("chessboard", &chessboard, z_board, "chessboard:9x6:25mm"), ("plate", &plate, z_plate, "plate:40mm")]
    {
        let pattern: Pattern = pattern.parse()?;
        for sigma in [0.5, 1.0, 1.5, 2.5] {
            for (noise_name, sensor) in &noises {
                let mut config = RenderConfig::default();
                config.optics.psf = Psf::Gaussian { sigma_px: sigma };
                config.optics.vignetting = Vignetting::Cos4 { focal_px: None };
                config.sensor = sensor.clone();
                let renderer = Renderer::new(camera, target, config)?;
                let s = &renderer.config().sensor;
                let truth_noise = NoiseModel::from_sensor(
                    s.gain_e_per_dn,
                    s.read_noise_e,
                    s.black_level_dn,
                    s.shot_noise != ShotNoise::Off,
                );
                let mut row = StudyRow {
                    target: name.into(),
                    psf_sigma_px: sigma,
                    noise: (*noise_name).into(),
                    images: 0,
                    corners: 0,
                    ours_rms_px: f64::NAN,
                    crb_rms_px: f64::NAN,
                    reported_rms_px: f64::NAN,
                    ours_global_rms_px: f64::NAN,
                    crb_global_rms_px: f64::NAN,
                    subpix_rms_px: f64::NAN,
                    sb_rms_px: f64::NAN,
                    sb_found: 0,
                    sb_default_rms_px: f64::NAN,
                    classic_rms_px: f64::NAN,
                    classic_found: 0,
                    ours_found: 0,
                };
                let (mut ours, mut crb, mut rep, mut sub, mut sb, mut classic) =
                    (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
                let (mut glob, mut glob_crb, mut sb_default) = (Vec::new(), Vec::new(), Vec::new());
                for k in 0..args.images {
                    let a = k as f64;
                    let t = pose(
                        0.06 * z * (1.3 * a + 0.4).sin(),
                        0.05 * z * (1.7 * a + 1.1).cos(),
                        z * (1.0 + 0.08 * (0.9 * a).sin()),
                        7.0 + 11.0 * a,
                        15.0 * (0.8 * a + 0.3).sin(),
                        18.0 * (1.1 * a + 0.7).cos(),
                    );
                    let seed = args.seed.wrapping_mul(1_000_003).wrapping_add(k as u64);
                    let out = renderer.render(&t, seed)?;
                    row.images += 1;
                    let truth: Vec<Point2<f64>> = out.truth.corners.iter().filter_map(|c| c.pixel).collect();
                    let img = &out.image;
                    let default = DetectOptions::default();
                    let Ok(found) = detect(img, &pattern, &default, None) else { continue };
                    row.ours_found += 1;
                    let d = &found[0];
                    let pts = d.corners_px();
                    ours.extend(nearest_sq(&pts, &truth));
                    rep.extend(d.corners.iter().map(|c| c.covariance_px2.map_or(f64::NAN, |m| m.trace())));
                    // The bound under the true noise model.
                    let mut known = default.clone();
                    known.refine_options.noise = NoiseSpec::Known(truth_noise);
                    if let Ok(kf) = detect(img, &pattern, &known, None) {
                        crb.extend(kf[0].corners.iter().map(|c| c.crb_px2.map_or(f64::NAN, |m| m.trace())));
                    }
                    // Whole grid lines (the camera is a pinhole: lines are straight).
                    let mut global = default.clone();
                    global.refine_options.support = LineSupport::Global;
                    if let Ok(gf) = detect(img, &pattern, &global, None) {
                        glob.extend(nearest_sq(&gf[0].corners_px(), &truth));
                    }
                    global.refine_options.noise = NoiseSpec::Known(truth_noise);
                    if let Ok(gf) = detect(img, &pattern, &global, None) {
                        glob_crb.extend(gf[0].corners.iter().map(|c| c.crb_px2.map_or(f64::NAN, |m| m.trace())));
                    }
                    // cornerSubPix from the same coarse corners.
                    let coarse = detect(img, &pattern, &DetectOptions { refine: false, ..default.clone() }, None)?;
                    let cs = opencv_corner_subpix(img, &coarse[0].corners_px(), 5, 0.001)?;
                    sub.extend(nearest_sq(&cs, &truth));
                    if name == "chessboard" {
                        if let Some(p) = opencv_find_chessboard_sb(img, 9, 6, true)? {
                            row.sb_found += 1;
                            sb.extend(nearest_sq(&p, &truth));
                        }
                        if let Some(p) = opencv_find_chessboard_sb(img, 9, 6, false)? {
                            sb_default.extend(nearest_sq(&p, &truth));
                        }
                        if let Some(p) = opencv_find_chessboard(img, 9, 6, Some(5))? {
                            row.classic_found += 1;
                            classic.extend(nearest_sq(&p, &truth));
                        }
                    }
                }
                row.corners = ours.len();
                row.ours_rms_px = rms(&ours);
                row.crb_rms_px = rms(&crb);
                row.reported_rms_px = rms(&rep);
                row.subpix_rms_px = rms(&sub);
                row.ours_global_rms_px = rms(&glob);
                row.crb_global_rms_px = rms(&glob_crb);
                row.sb_rms_px = rms(&sb);
                row.sb_default_rms_px = rms(&sb_default);
                row.classic_rms_px = rms(&classic);
                log(&format!(
                    "{name:10} psf {sigma:.1} noise {noise_name:4}: ours {:.4} px, CRB {:.4}, whole lines {:.4} (CRB {:.4}), cornerSubPix {:.4}, SB {:.4}, classic {:.4}",
                    row.ours_rms_px, row.crb_rms_px, row.ours_global_rms_px, row.crb_global_rms_px, row.subpix_rms_px, row.sb_rms_px, row.classic_rms_px
                ));
                rows.push(row);
            }
        }
    }
    Ok((rows, w, h))
}

/// The rows as CSV (one header line, one line per row).
pub fn rows_csv(rows: &[StudyRow]) -> Result<String> {
    let mut csv = csv::Writer::from_writer(Vec::new());
    for r in rows {
        csv.serialize(r).map_err(|e| DatasetError::Input(format!("corner study CSV: {e}")))?;
    }
    let bytes = csv.into_inner().map_err(|e| DatasetError::Input(format!("corner study CSV: {e}")))?;
    String::from_utf8(bytes).map_err(|e| DatasetError::Input(format!("corner study CSV: {e}")))
}

/// The worst ratio of the project's corner RMS error to the Cramer-Rao bound over the rows with
/// noise (NaN without any).
pub fn worst_crb_ratio(rows: &[StudyRow]) -> f64 {
    rows.iter()
        .filter(|r| r.crb_rms_px > 0.0 && r.crb_rms_px.is_finite() && r.ours_rms_px.is_finite())
        .map(|r| r.ours_rms_px / r.crb_rms_px)
        .fold(f64::NAN, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_squared_errors_ignore_the_order() {
        let truth = [Point2::new(0.0, 0.0), Point2::new(10.0, 0.0)];
        let found = [Point2::new(10.0, 0.5), Point2::new(0.3, 0.4)];
        let d = nearest_sq(&found, &truth);
        assert!((d[0] - 0.25).abs() < 1e-12 && (d[1] - 0.25).abs() < 1e-12, "{d:?}");
        assert!((rms(&d) - 0.5).abs() < 1e-12);
        assert!(rms(&[]).is_nan());
    }
}
