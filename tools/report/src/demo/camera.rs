//! The demo's real-camera sections, built from the JSON of `ferrocal camera` and `ferrocal diagnose --images` runs.

use super::*;

/// The real-camera section from `ferrocal camera calibrate --json` of each camera and `ferrocal
/// camera stereo --json`: the left camera against its published calibration, the right against
/// OpenCV's recomputation with the same recipe (no published calibration exists for it).
pub fn camera_real(left: &Value, right: &Value, stereo: &Value) -> Section {
    let mut s = Section::new("camera-real", "Real images: the OpenCV stereo sample calibrated");
    s.attribution(OPENCV_ATTRIBUTION);
    let f = |v: &Value, k: &str| v[k].as_f64().unwrap_or(f64::NAN);
    let mut rows = Vec::new();
    let mut verdicts = Vec::new();
    for (v, reference) in [(left, &OPENCV_LEFT_PUBLISHED), (right, &OPENCV_RIGHT_RECOMPUTED)] {
        let p = reference.values;
        let ours = [f(v, "fx"), f(v, "cx"), f(v, "cy"), f(v, "rms_px")];
        let rel = (ours[0] - p[0]).abs() / p[0];
        verdicts.push(checks::intrinsics(ours, reference));
        rows.push(vec![
            reference.camera.to_string(),
            reference.source.to_string(),
            format!("{:.3} ({:.3})", ours[0], p[0]),
            format!("{:.3} ({:.3})", ours[1], p[1]),
            format!("{:.3} ({:.3})", ours[2], p[2]),
            format!("{:.4} ({:.4})", ours[3], p[3]),
            format!("{:.3} %", rel * 100.0),
        ]);
    }
    s.text("`ferrocal camera calibrate --fix-aspect --corners opencv` (OpenCV's corner recipe, our bundle adjustment) on the 13 views of each camera; the reference values in brackets. Only the left camera has a published calibration (OpenCV samples/data/left_intrinsics.yml, fx 535.9157 px); the right camera's reference is OpenCV's own result with the same recipe, recomputed for shared/data/opencv_stereo/README.md: a check against OpenCV, not against a published number.");
    s.table(
        "Intrinsics against the reference values",
        &["camera", "reference", "fx [px]", "cx [px]", "cy [px]", "RMS [px]", "fx difference"],
        rows,
    );
    let baseline = f(stereo, "baseline_mm");
    let baseline_std = f(stereo, "baseline_std_mm");
    s.text(format!(
        "Stereo (`ferrocal camera stereo`, own corners, the default; OpenCV's recipe gives 83.44 +- 0.09 mm): baseline {baseline:.2} +- {baseline_std:.2} mm with 25 mm squares. OpenCV's own stereo sample reports about 83 mm; the Caltech toolbox's 99.8 mm corresponds to 30 mm squares (83.4 x 30 / 25 = 100.1 mm): an open check, not a truth."
    ));
    s.data = json!({"left": left, "right": right, "stereo": stereo, "references": [OPENCV_LEFT_PUBLISHED, OPENCV_RIGHT_RECOMPUTED]});
    s.check(Check::all("OpenCV stereo sample", &verdicts));
    s
}

/// The default corners (the project's detector) against OpenCV's recipe on the OpenCV sample,
/// every second image held out (`ferrocal camera calibrate --test-every 2 --corners own|opencv`
/// per camera, `(side, own, opencv)`): the held-out reprojection error, which free parameters
/// cannot lower, judges the corners.
pub fn camera_own_corners(runs: &[(&str, Value, Value)]) -> Section {
    let mut s = Section::new("camera-own-corners", "Real images: own corners against OpenCV's recipe, held out");
    s.attribution(OPENCV_ATTRIBUTION);
    let f = |v: &Value, k: &str| v[k].as_f64().unwrap_or(f64::NAN);
    let held = |v: &Value| v["held_out"]["rms_px"].as_f64().unwrap_or(f64::NAN);
    let mut rows = Vec::new();
    let mut verdicts = Vec::new();
    for (side, own, cv) in runs {
        for (name, v) in [("own (default)", own), ("OpenCV recipe", cv)] {
            rows.push(vec![
                side.to_string(),
                name.to_string(),
                format!("{:.3} +- {:.3}", f(v, "fx"), v["std"]["fx"].as_f64().unwrap_or(f64::NAN)),
                format!("{:.4}", f(v, "rms_px")),
                format!("{:.4}", held(v)),
            ]);
        }
        verdicts.push(checks::held_out_corners(side, held(own), held(cv)));
    }
    s.text("Every second image of each camera is held out of the calibration; each held-out view's pose is fitted with the camera fixed and its reprojection error reported. The project's corners (X-corners and the edge-model refinement) against OpenCV's findChessboardCorners + cornerSubPix recipe (11 x 11 window), same images, same bundle adjustment. On left02 the recipe's 23 px window reaches the neighbouring corners of the 20 px squares (docs/targets.md).");
    s.table(
        "Held-out reprojection error",
        &["camera", "corners", "fx [px]", "fit RMS [px]", "held-out RMS [px]"],
        rows,
    );
    // Per held-out view: both corner sources side by side (bars by view, coloured by source).
    let mut bars = Vec::new();
    for (_, own, cv) in runs {
        for (name, v) in [("own corners", own), ("OpenCV recipe", cv)] {
            for view in v["held_out"]["views"].as_array().into_iter().flatten() {
                let rms = view["rms_px"].as_f64().unwrap_or(f64::NAN);
                let image = view["name"].as_str().unwrap_or("?");
                let stem = Path::new(image).file_stem().map_or(image.into(), |s| s.to_string_lossy());
                bars.push((stem.to_string(), name.to_string(), rms));
            }
        }
    }
    bars.sort_by(|a, b| a.0.cmp(&b.0));
    s.figure(
        "Reprojection error of each held-out view (its pose fitted, the camera fixed): the project's corners against OpenCV's recipe on the same images.",
        crate::plot::bar_chart("Held-out views", "RMS [px]", &bars),
    );
    s.data = json!({"runs": runs.iter().map(|(side, own, cv)| json!({"camera": side, "own": own, "opencv": cv})).collect::<Vec<_>>()});
    s.check(Check::all("own corners on held-out views", &verdicts));
    s
}

/// Detections made elsewhere: the same corners given as images and as an observations file
/// (`camera calibrate --save-observations`, then `--observations`) give the same camera.
pub fn camera_observations(images: &Value, observations: &Value) -> Section {
    let mut s = Section::new("camera-observations", "Real images: the same corners as an observations file");
    s.attribution(OPENCV_ATTRIBUTION);
    s.text("The left camera's corners found by the project's detector are saved with --save-observations (image, camera, point_id, u_px, v_px; numbers in their shortest exact form) and the camera is calibrated again from that file alone, as a user whose corners come from another detector would (mrcal's corners files are read too). Both calibrations must agree to the last digit.");
    let keys = ["fx", "fy", "cx", "cy", "rms_px", "std", "per_view"];
    let rows =
        keys[..5].iter().map(|k| vec![k.to_string(), images[k].to_string(), observations[k].to_string()]).collect();
    s.table("The left camera from its images and from its observations", &["value", "images", "observations"], rows);
    s.data = json!({"images": images, "observations": observations});
    let differ: Vec<&str> = keys.iter().copied().filter(|k| images[*k] != observations[*k]).collect();
    s.check(checks::same_from_observations(&differ));
    s
}

/// The real-camera section when the images under `dir` are absent.
pub fn camera_real_skipped(dir: &Path) -> Section {
    let mut s = Section::new("camera-real", "Real images: the OpenCV stereo sample calibrated");
    s.attribution(OPENCV_ATTRIBUTION);
    s.skipped(format!("{} is not present", dir.display()));
    s
}

/// What the default camera model leaves out, from `ferrocal diagnose --images --json` of each
/// camera (`(side, report)`); numbers without a pass/fail criterion.
pub fn camera_diagnose(reports: &[(&str, Value)]) -> Section {
    let mut d = Section::new("camera-diagnose", "Real images: what the default camera model leaves out");
    d.attribution(OPENCV_ATTRIBUTION);
    let f = |v: &Value, k: &str| v[k].as_f64().unwrap_or(f64::NAN);
    let mut rows = Vec::new();
    let mut data = serde_json::Map::new();
    for (side, rep) in reports {
        let findings: Vec<String> = rep["findings"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(|f| f["statement"].as_str().map(String::from))
            .collect();
        let best_bend = rep["candidates"][0]
            .as_array()
            .into_iter()
            .flatten()
            .find(|c| c["candidate"].as_str().is_some_and(|n| n.starts_with("target_nonflatness")))
            .map(|c| format!("{:.4} px (p = {:.1e})", f(c, "heldout_rms_px"), f(c, "p_value")))
            .unwrap_or_else(|| "-".into());
        rows.push(vec![
            side.to_string(),
            format!("{:.4}", f(&rep["nominal"], "heldout_rms_px")),
            best_bend,
            format!("{:.4}", f(&rep["final"], "heldout_rms_px")),
            if findings.is_empty() { "none".into() } else { findings.join("; ") },
            if rep["unexplained"]["structure_found"].as_bool() == Some(true) { "yes".into() } else { "no".into() },
        ]);
        data.insert(side.to_string(), rep.clone());
    }
    d.text("`ferrocal diagnose --images ... --pattern chessboard:9x6:25mm`, our sub-pixel detector, each view held out once (5 folds): the lens candidates (rational radial, Kannala-Brandt) and a bent target (bowl, saddle, twist, one shape for all views) are refitted and kept only when the held-out reprojection improves significantly. Both cameras see the same board at the same instants, so a bent board must show in both.");
    d.table(
        "Held-out reprojection RMS",
        &["camera", "default model [px]", "with a bent target [px]", "final [px]", "findings", "unexplained structure"],
        rows,
    );
    d.data = Value::Object(data);
    d.reported("findings shown; no pass/fail criterion");
    d
}

/// The boards people print calibrated side by side on renders of one known camera
/// (`ferrocal_datasets::render::printed_targets`).
pub fn printed_targets_section(seed: u64) -> Result<Section> {
    let mut s = Section::new(
        "printed-targets",
        "Printed targets: chessboard, OpenCV's asymmetric circle grid, Kalibr's Aprilgrid",
    );
    let rows = ferrocal_datasets::render::printed_targets::printed_targets(seed, 12)?;
    s.text("Twelve random views (20 to 50 degrees of tilt, the last two cut by the image border) of each board, rendered with one known 1280 x 960 camera (Brown 5); `camera calibrate` on each (the circle grid's centres corrected for the perspective bias, the Aprilgrid's tag corners refined by the edge model and used with their ids, so partial views count). The same lens family renders and calibrates: this checks the targets' detection, numbering and frames. Pattern strings: `chessboard:9x6:25mm`, `acircles:4x11:20mm`, `aprilgrid:6x4:30mm:0.3`.");
    let fmt4 = |v: &[f64; 4]| v.iter().map(|x| format!("{x:+.3}")).collect::<Vec<_>>().join(" / ");
    s.table(
        "Intrinsics against the truth",
        &["target", "views found", "points", "RMS [px]", "error fx / fy / cx / cy [px]", "std [px]", "error norm [px]"],
        rows.iter()
            .map(|r| {
                vec![
                    r.target.clone(),
                    format!("{} of {}", r.views_found, r.views),
                    r.corners.to_string(),
                    format!("{:.4}", r.rms_px),
                    fmt4(&r.error_px),
                    r.std_px.iter().map(|x| format!("{x:.3}")).collect::<Vec<_>>().join(" / "),
                    format!("{:.3}", r.error_norm_px),
                ]
            })
            .collect(),
    );
    s.data = serde_json::to_value(&rows)?;
    s.check(checks::printed_targets(&rows));
    Ok(s)
}
