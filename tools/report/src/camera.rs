//! The JSON of `ferrocal camera calibrate` and `ferrocal camera stereo` (keys per
//! `shared/spec/cli.md`, plus extras) and their terminal summary.

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

/// Prints one camera's calibration on stdout (`label`: `camera`, `left`, `right`) and its
/// warnings on stderr.
pub fn print_camera(label: &str, cal: &CameraCalibration) {
    let k = cal.camera.intrinsics;
    println!(
        "{label}: fx {:.3} +- {:.3}, fy {:.3} +- {:.3}, cx {:.3} +- {:.3}, cy {:.3} +- {:.3} px; distortion {:?}; RMS {:.4} px over {} views",
        k.fx_px,
        cal.std[0],
        k.fy_px,
        cal.std[1],
        k.cx_px,
        cal.std[2],
        k.cy_px,
        cal.std[3],
        cal.camera.distortion.coefficients(),
        cal.rms_px,
        cal.views.iter().filter(|v| v.used).count()
    );
    if cal.summary.covariance_method != ferrocal_vision::calib::CovarianceMethod::Independent {
        let s = &cal.summary.std_independent;
        println!(
            "{label}: standard deviations by {} covariance; with corners independent: fx {:.3}, fy {:.3}, cx {:.3}, cy {:.3} px",
            cal.summary.covariance_method.name(),
            s[0],
            s[1],
            s[2],
            s[3]
        );
    }
    for w in &cal.summary.warnings {
        eprintln!("ferrocal: warning: {w}");
    }
}

/// The rectification in the stereo JSON: OpenCV's matrices row by row (T, P2 and Q in
/// metres), the common focal length, the baseline and the rectified row check.
pub fn rectification_json(pair: &ferrocal_vision::camera::io::StereoPair, row_rms_px: f64, n_corners: usize) -> Value {
    let rc = &pair.rectification;
    let rows = |m: &dyn Fn(usize, usize) -> f64, r: usize, c: usize| -> Vec<Vec<f64>> {
        (0..r).map(|i| (0..c).map(|j| m(i, j)).collect()).collect()
    };
    json!({
        "R1": rows(&|i, j| rc.r1[(i, j)], 3, 3),
        "R2": rows(&|i, j| rc.r2[(i, j)], 3, 3),
        "P1": rows(&|i, j| rc.p1[(i, j)], 3, 4),
        "P2": rows(&|i, j| rc.p2[(i, j)], 3, 4),
        "Q": rows(&|i, j| rc.q[(i, j)], 4, 4),
        "focal_px": rc.focal_px(),
        "baseline_mm": rc.baseline() * 1e3,
        "vertical": rc.vertical(),
        "row_rms_px": row_rms_px,
        "n_corner_pairs": n_corners,
        "method": "Bouguet (OpenCV stereoRectify, alpha = -1, CALIB_ZERO_DISPARITY); T, P2 and Q in metres",
    })
}
