//! The JSON of `ferrocal camera calibrate` and `ferrocal camera stereo` (keys per
//! `shared/spec/cli.md`, plus extras).

use ferrocal_vision::calib::corners::SkippedImage;
use ferrocal_vision::calib::{CameraCalibration, StereoCalibration};
use ferrocal_vision::camera::DistortionKind;
use ferrocal_vision::detect::Pattern;
use serde_json::{json, Value};

/// The skipped images with their reasons.
pub fn skipped_json(skipped: &[SkippedImage]) -> Value {
    Value::Array(skipped.iter().map(|s| json!({"image": s.image.display().to_string(), "reason": s.reason})).collect())
}

/// The lens model's name in the JSON.
pub fn model_name(kind: DistortionKind) -> &'static str {
    match kind {
        DistortionKind::None => "pinhole",
        DistortionKind::Brown5 => "brown5",
        DistortionKind::Rational8 => "rational8",
        DistortionKind::KannalaBrandt => "kannala_brandt",
    }
}

/// The camera part of the JSON report (`shared/spec/cli.md`) plus extras.
pub fn camera_json(cal: &CameraCalibration) -> Value {
    let c = &cal.camera;
    let k = c.intrinsics;
    let per_view: Vec<Value> = cal
        .views
        .iter()
        .map(|v| {
            json!({
                "image": v.name, "rms_px": v.rms_px, "n_corners": v.n_corners, "outlier": v.outlier,
                "used": v.used, "n_outlier_corners": v.n_outlier_corners,
            })
        })
        .collect();
    let outliers: Vec<Value> = cal
        .outlier_corners
        .iter()
        .map(|o| json!({"image": o.view, "corner": o.point_id, "residual_px": o.residual_px, "removed": o.removed}))
        .collect();
    json!({
        "image_size": [c.image_size.width_px, c.image_size.height_px],
        "model": model_name(c.distortion.kind()),
        "fx": k.fx_px, "fy": k.fy_px, "cx": k.cx_px, "cy": k.cy_px,
        "distortion": c.distortion.coefficients(),
        "rms_px": cal.rms_px,
        "per_view": per_view,
        "std": {
            "fx": cal.std[0], "fy": cal.std[1], "cx": cal.std[2], "cy": cal.std[3],
            "distortion": cal.std[4..].to_vec(),
            "method": cal.summary.covariance_method.name(),
        },
        "std_independent": cal.summary.std_independent,
        "outlier_corners": outliers,
        "summary": {
            "n_views_used": cal.views.iter().filter(|v| v.used).count(),
            "n_corners": cal.summary.n_corners,
            "s0_px": cal.summary.s0_px,
            "zhang_condition": cal.summary.zhang_condition,
            "normal_condition": cal.summary.normal_condition,
            "max_board_angle_deg": cal.summary.max_board_angle_deg,
            "removed_views": cal.summary.removed_views,
            "warnings": cal.summary.warnings,
            "solver_report": cal.summary.solver_report,
        },
    })
}

/// The stereo JSON of `ferrocal camera stereo --json`.
pub fn stereo_json(
    st: &StereoCalibration,
    n_pairs: usize,
    pattern: &Pattern,
    fix_aspect: bool,
    skipped: &[SkippedImage],
) -> Value {
    json!({
        "left": camera_json(st.left()),
        "right": camera_json(st.right()),
        "rotation_deg": st.rotation_deg.as_slice(),
        "translation_mm": st.translation_mm.as_slice(),
        "rms_px": st.calibration.rms_px,
        "rotation_std_deg": st.rotation_std_deg.as_slice(),
        "translation_std_mm": st.translation_std_mm.as_slice(),
        "baseline_mm": st.baseline_mm,
        "baseline_std_mm": st.baseline_std_mm,
        "rms_left_px": st.left().rms_px,
        "rms_right_px": st.right().rms_px,
        "convention": "T_right_left (OpenCV stereoCalibrate R, T): p_right = R p_left + T; rotation as a rotation vector",
        "n_pairs": n_pairs,
        "n_views": st.calibration.n_views,
        "s0_px": st.calibration.s0_px,
        "reversed_views": st.calibration.reversed_views.iter().map(|(k, n)| json!({"camera": k, "image": n})).collect::<Vec<_>>(),
        "pattern": pattern.to_string(),
        "fix_aspect": fix_aspect,
        "skipped": skipped_json(skipped),
        "solver_report": st.calibration.solver_report,
    })
}
