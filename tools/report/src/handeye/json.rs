//! The JSON of `ferrocal handeye` (`shared/spec/cli.md`: `mount`, `camera`, `hand_eye`, `world`,
//! `train_rms_px`, `heldout_rms_px`, `per_image`, `std`), plus extras: covariances, the
//! camera-to-target agreement with PnP, the closed-form starts, OpenCV's results on the same
//! corners, skipped images and the data's source.

use ferrocal_calib::handeye::opencv::BaselineReport;
use ferrocal_calib::handeye::{ChainFigures, HandEyeData, HandEyeResult, TransformEstimate};
use ferrocal_calib::Split;
use nalgebra::Isometry3;
use serde_json::{json, Value};

use crate::camera::{camera_json, with_camera_fields};

/// `{"translation_mm": [x, y, z], "rotation_wxyz": [w, x, y, z]}`.
pub fn transform_json(t: &Isometry3<f64>) -> Value {
    let p = t.translation.vector * 1e3;
    let q = t.rotation;
    json!({"translation_mm": [p.x, p.y, p.z], "rotation_wxyz": [q.w, q.i, q.j, q.k]})
}

/// A transform's standard deviations: `translation_mm` and `rotation_deg` (about each axis).
pub fn std_json(t: &TransformEstimate) -> Value {
    json!({
        "translation_mm": t.translation_std_mm().as_slice(),
        "rotation_deg": t.rotation_std_deg().as_slice(),
    })
}

fn split_name(s: Split) -> &'static str {
    match s {
        Split::Train => "train",
        Split::Test => "test",
    }
}

/// The inputs of a fit as `handeye --corners-out` writes them, for running other tools on the
/// same corners and split: the mount, the pattern, the target's nominal points (metres), and per
/// image its split, the robot's `T_base_flange` as read, the detected corners (pixels, `(0, 0)`
/// the centre of the top-left pixel) with their point ids (indices into `target_points_m`), and
/// `used`: false for an image the fit `result` left out (too few corners, no PnP pose).
pub fn corners_json(data: &HandEyeData, pattern: &str, result: &HandEyeResult, source: Option<&str>) -> Value {
    let views: Vec<Value> = data
        .views
        .iter()
        .map(|v| {
            json!({
                "image": v.name,
                "split": split_name(v.split),
                "used": !result.skipped.iter().any(|s| s.name == v.name),
                "image_size": [v.image_size.width_px, v.image_size.height_px],
                "t_base_flange": transform_json(&v.t_base_flange),
                "point_ids": v.point_ids,
                "corners_px": v.corners_px.iter().map(|p| [p.x, p.y]).collect::<Vec<_>>(),
            })
        })
        .collect();
    json!({
        "mount": data.mount.name(),
        "pattern": pattern,
        "target_points_m": data.target_points_m.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
        // The points as the chain predicts through them: bent and printed as fitted (before the
        // overall `target_scale`); the nominal ones when no form was fitted.
        "chain_target_points_m": result
            .target_form
            .map_or_else(|| data.target_points_m.clone(), |f| f.points(&data.target_points_m))
            .iter()
            .map(|p| [p.x, p.y, p.z])
            .collect::<Vec<_>>(),
        "pixel_convention": "(0, 0) is the centre of the top-left pixel (OpenCV's)",
        "views": views,
        "data_source": source,
    })
}

/// The chain figures' overall numbers.
pub fn figures_json(f: &ChainFigures) -> Value {
    json!({
        "train_rms_px": f.train_rms_px,
        "heldout_rms_px": f.heldout_rms_px,
        "train_pnp_position_mm": f.train_pnp_position_mm,
        "train_pnp_rotation_deg": f.train_pnp_rotation_deg,
        "heldout_pnp_position_mm": f.heldout_pnp_position_mm,
        "heldout_pnp_rotation_deg": f.heldout_pnp_rotation_deg,
        "pnp_target_scale": f.pnp_target_scale,
    })
}

/// The camera part: the fields of `camera calibrate` for the camera the chain used.
pub fn camera_part(r: &HandEyeResult) -> Value {
    let c = &r.camera;
    let zeros = vec![0.0; c.n_parameters()];
    let s = r.camera_std.as_ref().unwrap_or(&zeros);
    let per_view: Vec<Value> = r
        .figures
        .views
        .iter()
        .filter(|v| v.split == Split::Train)
        .map(|v| json!({"image": v.name, "rms_px": v.rms_px}))
        .collect();
    with_camera_fields(
        c,
        json!({
            "rms_px": r.figures.train_rms_px,
            "per_view": per_view,
            "std": {"fx": s[0], "fy": s[1], "cx": s[2], "cy": s[3], "distortion": s[4..].to_vec()},
            "fixed": r.camera_std.is_none(),
            "initial_calibration": r.initial_camera.as_ref().map(camera_json),
        }),
    )
}

/// A 6 x 6 matrix as rows.
pub fn matrix_rows(m: &nalgebra::Matrix6<f64>) -> Vec<Vec<f64>> {
    (0..6).map(|i| (0..6).map(|j| m[(i, j)]).collect()).collect()
}

/// OpenCV's results, each with its chain figures.
pub fn baselines_json(b: &[BaselineReport]) -> Value {
    Value::Array(
        b.iter()
            .map(|r| {
                json!({
                    "function": r.function,
                    "method": r.method,
                    "hand_eye": r.chain.map(|c| transform_json(&c.x)),
                    "world": r.chain.map(|c| transform_json(&c.w)),
                    "figures": r.figures.as_ref().map(figures_json),
                    "error": r.error,
                })
            })
            .collect(),
    )
}

/// The target's fitted bending (sags in mm) and x-against-y print scale, with their standard
/// deviations.
fn target_form_json(f: &ferrocal_calib::handeye::TargetForm) -> Value {
    let d = &f.deformation;
    let shape = d.shape_free.then(|| {
        let std = f.shape_std_m.unwrap_or([f64::NAN; 3]);
        json!({
            "bowl_sag_mm": d.shape_m[0] * 1e3, "saddle_sag_mm": d.shape_m[1] * 1e3, "twist_sag_mm": d.shape_m[2] * 1e3,
            "std_mm": [std[0] * 1e3, std[1] * 1e3, std[2] * 1e3],
            "centre_m": d.centre_m, "half_size_m": d.half_m,
        })
    });
    let print = d.scale_free.then(|| json!({"scale_x_minus_y": d.scale[0], "std": f.scale_x_std}));
    json!({"shape": shape, "print_scale_x": print})
}

/// The whole JSON of `ferrocal handeye`.
pub fn handeye_json(r: &HandEyeResult, baselines: &[BaselineReport], skipped: Value, source: Option<&str>) -> Value {
    let per_image: Vec<Value> = r
        .figures
        .views
        .iter()
        .map(|v| {
            json!({
                "image": v.name, "split": split_name(v.split), "rms_px": v.rms_px, "n_corners": v.n_corners,
                "pnp_position_mm": v.pnp_position_mm, "pnp_rotation_deg": v.pnp_rotation_deg,
            })
        })
        .collect();
    let scale = r.target_scale.map(|(v, s)| json!({"value": v, "std": s}));
    json!({
        "mount": r.mount.name(),
        "camera": camera_part(r),
        "hand_eye": transform_json(&r.hand_eye.transform),
        "world": transform_json(&r.world.transform),
        "hand_eye_is": r.mount.hand_eye_name(),
        "world_is": r.mount.world_name(),
        "train_rms_px": r.figures.train_rms_px,
        "heldout_rms_px": r.figures.heldout_rms_px,
        "per_image": per_image,
        "std": {
            "hand_eye": std_json(&r.hand_eye),
            "world": std_json(&r.world),
            "target_scale": r.target_scale.map(|s| s.1),
        },
        "covariance": {
            "chart": "[tx_m, ty_m, tz_m, rx_rad, ry_rad, rz_rad], rotation error on the left",
            "hand_eye": matrix_rows(&r.hand_eye.covariance),
            "world": matrix_rows(&r.world.covariance),
        },
        "target_scale": scale,
        "target_form": r.target_form.map(|f| target_form_json(&f)),
        "pnp_agreement": figures_json(&r.figures),
        "motion": r.motion,
        "warnings": r.warnings,
        "starts": r.starts,
        "opencv": baselines_json(baselines),
        "skipped": skipped,
        "noise": {
            "estimated": r.noise.estimated,
            "corner_variance_factor": r.noise.corner_variance_factor,
            "robot_sigma_mm": r.noise.robot_sigma_m * 1e3,
            "robot_sigma_deg": r.noise.robot_sigma_rad.to_degrees(),
            "iterations": r.noise.iterations,
        },
        "solver": {
            "s0": r.s0, "iterations": r.iterations, "termination": r.termination,
            "downweighted_corners": r.n_downweighted,
        },
        "data_source": source,
    })
}
