//! The JSON of `ferrocal camera calibrate` and `ferrocal camera stereo` (keys per
//! `shared/spec/cli.md`, plus extras), all their output files ([`camera_outputs`],
//! [`stereo_outputs`]) and their terminal summary.

use std::path::Path;

use ferrocal_calib::verdict::Verdict;
use ferrocal_datasets::camera::{CameraRun, Rectified, StereoRun};
use ferrocal_vision::calib::corners::SkippedImage;
use ferrocal_vision::calib::heldout::HeldOut;
use ferrocal_vision::calib::{CameraCalibration, StereoCalibration};
use ferrocal_vision::camera::io;
use ferrocal_vision::camera::{CameraModel, DistortionKind};
use ferrocal_vision::detect::Pattern;
use serde_json::{json, Value};

use crate::camera_report::{camera_report, stereo_report, CameraReportInput, StereoReportInput};
use crate::error::Result;
use crate::outputs::Outputs;
use crate::report::Provenance;
use crate::verdict::add_verdict;

/// The skipped images with their reasons.
pub fn skipped_json(skipped: &[SkippedImage]) -> Value {
    Value::Array(skipped.iter().map(|s| json!({"image": s.image.display().to_string(), "reason": s.reason})).collect())
}

/// The lens model's name in the JSON (`pinhole` for the ideal pinhole, else the model's name).
pub fn model_name(kind: DistortionKind) -> &'static str {
    match kind {
        DistortionKind::None => "pinhole",
        other => other.name(),
    }
}

/// The camera part of the JSON report (`shared/spec/cli.md`) plus extras.
pub fn camera_json(cal: &CameraCalibration) -> Value {
    let c = &cal.camera;
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
    with_camera_fields(
        c,
        json!({
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
        }),
    )
}

/// A camera's own fields, the same in every camera JSON (image size, lens model, intrinsics,
/// distortion coefficients), with the object `rest` (the calling command's fields) added.
pub fn with_camera_fields(c: &CameraModel, rest: Value) -> Value {
    let k = c.intrinsics;
    let mut v = json!({
        "image_size": [c.image_size.width_px, c.image_size.height_px],
        "model": model_name(c.distortion.kind()),
        "fx": k.fx_px, "fy": k.fy_px, "cx": k.cx_px, "cy": k.cy_px,
        "distortion": c.distortion.coefficients(),
    });
    if let (Value::Object(m), Value::Object(r)) = (&mut v, rest) {
        m.extend(r);
    }
    v
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
    crate::say!(
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
        crate::say!(
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
pub fn rectification_json(pair: &io::StereoPair, row_rms_px: f64, n_corners: usize) -> Value {
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

/// Where `ferrocal camera calibrate` writes (each file only when asked for).
#[derive(Clone, Copy, Debug, Default)]
pub struct CameraFiles<'a> {
    /// The JSON report.
    pub json: Option<&'a Path>,
    /// The camera as OpenCV FileStorage YAML.
    pub opencv_yaml: Option<&'a Path>,
    /// The camera as ROS camera_info YAML.
    pub ros_yaml: Option<&'a Path>,
    /// The HTML report.
    pub report: Option<&'a Path>,
    /// The camera's name in the ROS file.
    pub camera_name: &'a str,
}

impl CameraFiles<'_> {
    /// Every output asked for, in the order of the arguments.
    pub fn all(&self) -> Vec<&Path> {
        [self.json, self.opencv_yaml, self.ros_yaml, self.report].into_iter().flatten().collect()
    }
}

/// The files of `ferrocal camera calibrate`, composed (not written): the JSON with the verdict,
/// the pattern, the corner method, the held-out scores and the skipped images; the OpenCV and
/// ROS camera files; the HTML report opening with the verdict. `test_every` is recorded in the
/// report's provenance.
pub fn camera_outputs(
    run: &CameraRun,
    held_out: Option<&HeldOut>,
    test_every: Option<usize>,
    verdict: &Verdict,
    files: &CameraFiles,
) -> Result<Outputs> {
    let (cal, mut out) = (&run.fit.calibration, Outputs::default());
    if let Some(p) = files.json {
        let mut v = camera_json(cal);
        add_verdict(&mut v, verdict);
        v["circle_bias"] = json!(run.fit.circle_bias);
        v["pattern"] = json!(run.pattern.to_string());
        v["fix_aspect"] = json!(run.options.fix_aspect);
        v["corners"] = json!(run.method);
        v["held_out"] = json!(held_out);
        v["skipped"] = skipped_json(&run.skipped);
        out.json(p, &v)?;
    }
    if let Some(p) = files.opencv_yaml {
        out.text(p, io::to_opencv_yaml(&cal.camera)?);
    }
    if let Some(p) = files.ros_yaml {
        out.text(p, io::to_ros_yaml(&cal.camera, files.camera_name)?);
    }
    if let Some(p) = files.report {
        let mut prov = Provenance::new(json!({"pattern": run.pattern.to_string(), "corners": run.method,
            "fix_aspect": run.options.fix_aspect, "model": format!("{:?}", run.options.model), "test_every": test_every}));
        run.paths.iter().for_each(|i| prov.add_input(i));
        let target = run.pattern.target();
        let pattern = run.pattern.to_string();
        let input =
            CameraReportInput { pattern: &pattern, views: &run.views, target: &target, held_out, provenance: prov };
        out.html(p, camera_report(cal, input), verdict);
    }
    Ok(out)
}

/// Where `ferrocal camera stereo` writes (each file only when asked for).
#[derive(Clone, Copy, Debug, Default)]
pub struct StereoFiles<'a> {
    /// The JSON report.
    pub json: Option<&'a Path>,
    /// The left camera as OpenCV FileStorage YAML.
    pub left_opencv_yaml: Option<&'a Path>,
    /// The right camera as OpenCV FileStorage YAML.
    pub right_opencv_yaml: Option<&'a Path>,
    /// The left camera as ROS camera_info YAML with the rectification.
    pub left_ros_yaml: Option<&'a Path>,
    /// The right camera as ROS camera_info YAML with the rectification.
    pub right_ros_yaml: Option<&'a Path>,
    /// The pair as one OpenCV FileStorage YAML file (the stereo_calib sample's names).
    pub opencv_stereo_yaml: Option<&'a Path>,
    /// The HTML report.
    pub report: Option<&'a Path>,
}

impl StereoFiles<'_> {
    /// Every output asked for, in the order of the arguments.
    pub fn all(&self) -> Vec<&Path> {
        [
            self.json,
            self.left_opencv_yaml,
            self.right_opencv_yaml,
            self.left_ros_yaml,
            self.right_ros_yaml,
            self.opencv_stereo_yaml,
            self.report,
        ]
        .into_iter()
        .flatten()
        .collect()
    }

    /// True when an output needs the rectification (the ROS files, the OpenCV stereo file, the
    /// report).
    pub fn need_rectification(&self) -> bool {
        self.left_ros_yaml.is_some()
            || self.right_ros_yaml.is_some()
            || self.opencv_stereo_yaml.is_some()
            || self.report.is_some()
    }
}

/// The files of `ferrocal camera stereo`, composed (not written): the JSON with the verdict and
/// the rectification, both cameras' OpenCV files and, when the pair could be rectified, the ROS
/// files, the OpenCV stereo file and the HTML report opening with the verdict.
pub fn stereo_outputs(
    run: &StereoRun,
    rectified: Option<&Rectified>,
    verdict: &Verdict,
    files: &StereoFiles,
) -> Result<Outputs> {
    let (st, mut out) = (&run.calibration, Outputs::default());
    if let Some(p) = files.json {
        let pattern = run.pattern.pattern();
        let mut v = stereo_json(st, run.n_pairs, &pattern, run.options.fix_aspect, &run.views.skipped);
        add_verdict(&mut v, verdict);
        v["rectification"] =
            rectified.map_or(Value::Null, |r| rectification_json(&r.pair, r.row_rms_px, r.corners.len()));
        // The pairs' agreement on the cameras' relative pose before the joint fit (issue #44).
        v["pairing"] = serde_json::to_value(&run.pairing)?;
        out.json(p, &v)?;
    }
    for (cal, path) in [(st.left(), files.left_opencv_yaml), (st.right(), files.right_opencv_yaml)] {
        if let Some(p) = path {
            out.text(p, io::to_opencv_yaml(&cal.camera)?);
        }
    }
    let Some(Rectified { pair, corners, .. }) = rectified else {
        return Ok(out);
    };
    if files.left_ros_yaml.is_some() || files.right_ros_yaml.is_some() {
        let (l, r) = io::to_ros_stereo_yaml(pair, "left", "right")?;
        for (text, path) in [(l, files.left_ros_yaml), (r, files.right_ros_yaml)] {
            if let Some(p) = path {
                out.text(p, text);
            }
        }
    }
    if let Some(p) = files.opencv_stereo_yaml {
        out.text(p, io::to_opencv_stereo_yaml(pair)?);
    }
    if let Some(p) = files.report {
        let mut prov = Provenance::new(json!({"pattern": run.pattern.to_string(), "corners": run.views.method,
            "fix_aspect": run.options.fix_aspect, "model": format!("{:?}", run.options.model)}));
        run.inputs().iter().for_each(|i| prov.add_input(i));
        let pattern = run.pattern.to_string();
        let (left, right, target) = (&run.views.left, &run.views.right, &run.target);
        let input = StereoReportInput { pattern: &pattern, left, right, target, pair, corners, provenance: prov };
        out.html(p, stereo_report(st, input), verdict);
    }
    Ok(out)
}

/// The terminal line of a stereo calibration: `T_right_left` with its standard deviations, the
/// baseline and the RMS over the pairs.
pub fn stereo_line(st: &StereoCalibration, n_pairs: usize) -> String {
    format!(
        "T_right_left: rotation {:.4?} deg (std {:.4?}), translation {:.3?} mm (std {:.3?}), baseline {:.3} +- {:.3} mm; RMS {:.4} px ({n_pairs} pairs)",
        st.rotation_deg.as_slice(),
        st.rotation_std_deg.as_slice(),
        st.translation_mm.as_slice(),
        st.translation_std_mm.as_slice(),
        st.baseline_mm,
        st.baseline_std_mm,
        st.calibration.rms_px
    )
}

/// The terminal line of the rectification check: the common focal length, the baseline and the
/// row difference RMS over the corner pairs.
pub fn rectified_line(r: &Rectified) -> String {
    let rect = &r.pair.rectification;
    format!(
        "rectified: f' {:.3} px, baseline {:.3} mm, row difference RMS {:.4} px over {} corner pairs",
        rect.focal_px(),
        rect.baseline() * 1e3,
        r.row_rms_px,
        r.corners.len()
    )
}

/// The verdict of `ferrocal camera calibrate` ([`ferrocal_calib::verdict::commands::camera`]):
/// the fit's RMS, the views it used and the held-out RMS when views were held out.
pub fn camera_verdict(t: &ferrocal_calib::verdict::Thresholds, run: &CameraRun, held_out: Option<&HeldOut>) -> Verdict {
    let heldout_rms = held_out.and_then(|h| h.rms_px);
    ferrocal_calib::verdict::commands::camera(&t.camera, run.fit.calibration.rms_px, run.n_used(), heldout_rms)
}

/// The terminal line of the held-out scoring of `n_views` views.
pub fn held_out_line(h: &HeldOut, n_views: usize) -> String {
    match h.rms_px {
        Some(r) => format!("held out: RMS {r:.4} px over {n_views} views"),
        None => format!("held out: no view usable ({n_views} held out)"),
    }
}

/// Prints the held-out line of a calibration's test views on stdout and, on stderr, every
/// held-out view whose pose could not be fitted, with why.
pub fn print_held_out(h: &HeldOut, n_views: usize) {
    crate::say!("{}", held_out_line(h, n_views));
    for v in h.views.iter().filter(|v| v.error.is_some()) {
        eprintln!("ferrocal: held-out view {}: {}", v.name, v.error.as_deref().unwrap_or(""));
    }
}

/// The stereo pair's rectification when it exists, its line printed; a pair that cannot be
/// rectified (a wide fisheye whose image corners lie beyond 90 degrees) is a warning when no
/// output needs the rectification (`needed`), an error when one does.
pub fn rectification(run: &ferrocal_datasets::camera::StereoRun, needed: bool) -> Result<Option<Rectified>> {
    match run.rectify(needed)? {
        Ok(r) => {
            crate::say!("{}", rectified_line(&r));
            Ok(Some(r))
        }
        Err(why) => {
            eprintln!("ferrocal: warning: the pair cannot be rectified: {why}");
            Ok(None)
        }
    }
}
