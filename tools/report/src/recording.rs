//! `ferrocal measure --images ... --poses P.csv --pattern P`'s presentation: a user's own
//! recording (a folder of images and the poses table of `handeye`, no session manifest, no
//! truth) measured by one camera (`ferrocal_datasets::recording`) into its JSON, its verdict and
//! its summary; `ferrocal measure --session`'s JSON, verdict and summary lines
//! ([`session_json`]); and the demo's section on the real recordings.

use std::path::Path;

use ferrocal_calib::handeye::Mount;
use ferrocal_datasets::handeye::read_handeye_poses;
use ferrocal_datasets::import::images::expand_image_specs;
use ferrocal_datasets::measure::{SessionMeasurement, TrackerComparison};
use ferrocal_datasets::recording::{frame_note, measure_recording, RecordingMeasurement, RecordingOptions};
use ferrocal_vision::calib::corners::SkippedImage;
use ferrocal_vision::calib::CalibrationOptions;
use serde_json::json;

use crate::error::{Context, Result};

/// The JSON of `ferrocal measure --images ... --json` (without its verdict): the recording
/// `m` of the poses table `poses`, with every image left out (`skipped_images`: named by the
/// specifications but not found; `m.skipped`: not usable).
pub fn recording_json(
    m: &RecordingMeasurement,
    poses: &Path,
    pattern_text: &str,
    mount: Mount,
    skipped_images: &[SkippedImage],
) -> serde_json::Value {
    let mut skipped: Vec<serde_json::Value> =
        skipped_images.iter().map(|s| json!({"image": s.image.display().to_string(), "reason": s.reason})).collect();
    skipped.extend(m.skipped.iter().map(|s| json!({"image": s.what, "reason": s.reason})));
    json!({
        "poses_table": poses.display().to_string(),
        "pattern": pattern_text,
        "mount": mount.name(),
        "frame": frame_note(mount),
        "source": m.source,
        "camera": m.camera,
        "n_measured": m.poses.len(),
        "skipped": skipped,
        "reprojection_outliers": m.reprojection,
        "poses": m.poses.iter().map(|p| json!({
            "image": p.image,
            "split": p.split,
            "rms_px": p.estimate.rms_px,
            "s0": p.estimate.s0,
            "n_corners": p.estimate.n_corners,
            "t_cam_target": crate::handeye::json::transform_json(&p.estimate.t_cam_target),
            "measured": crate::handeye::json::transform_json(&p.measured),
            "sigma_position_mm": p.sigma_position_mm(),
            "sigma_rotation_deg": p.sigma_rotation_deg(),
        })).collect::<Vec<_>>(),
    })
}

/// The verdict of `ferrocal measure --images`: how many of the `total` images were measured,
/// and the camera's calibration RMS (or, with a given camera, the poses' median reprojection
/// RMS); `out`: the table written, if any.
pub fn recording_verdict(
    t: &ferrocal_calib::verdict::Thresholds,
    m: &RecordingMeasurement,
    total: usize,
    out: Option<&Path>,
) -> ferrocal_calib::verdict::Verdict {
    let (label, rms) = match m.camera.calibration_rms_px {
        Some(r) => ("camera calibration RMS", r),
        None => {
            let mut r: Vec<f64> = m.poses.iter().map(|p| p.estimate.rms_px).collect();
            r.sort_by(f64::total_cmp);
            ("median reprojection RMS of the poses", r.get(r.len() / 2).copied().unwrap_or(f64::NAN))
        }
    };
    crate::verdict::measure_verdict(t, m.poses.len(), total, label, rms, &m.reprojection, out)
}

/// Prints the summary of a recording's measurement: the camera and the poses' precision.
pub fn print_summary(m: &RecordingMeasurement) {
    let c = &m.camera;
    match (c.calibration_rms_px, &c.std) {
        (Some(rms), Some(std)) => crate::say!(
            "camera calibrated from {} views: fx {:.2} +- {:.2}, fy {:.2} +- {:.2}, cx {:.2} +- {:.2}, cy {:.2} +- {:.2} px, RMS {rms:.4} px",
            c.calibration_views,
            c.camera.intrinsics.fx_px,
            std[0],
            c.camera.intrinsics.fy_px,
            std[1],
            c.camera.intrinsics.cx_px,
            std[2],
            c.camera.intrinsics.cy_px,
            std[3]
        ),
        _ => crate::say!("camera given: fx {:.2}, fy {:.2} px", c.camera.intrinsics.fx_px, c.camera.intrinsics.fy_px),
    }
    let mut sig: Vec<f64> = m.poses.iter().map(|p| p.sigma_position_rms_mm()).collect();
    sig.sort_by(f64::total_cmp);
    let rms: Vec<f64> = m.poses.iter().map(|p| p.estimate.rms_px).collect();
    crate::say!(
        "{} image(s) measured, {} left out; median position sigma {:.4} mm; median reprojection RMS {:.4} px",
        m.poses.len(),
        m.skipped.len(),
        sig[sig.len() / 2],
        {
            let mut r = rms;
            r.sort_by(f64::total_cmp);
            r[r.len() / 2]
        }
    );
}

/// The JSON of `ferrocal measure --session ... --json`: the session `m` measured from the
/// folder `session`, its comparison with a tracker when there is one, and its verdict.
pub fn session_json(
    m: &SessionMeasurement,
    session: &Path,
    comparison: Option<&TrackerComparison>,
    verdict: &ferrocal_calib::verdict::Verdict,
) -> serde_json::Value {
    let mut v = json!({
        "tracker_comparison": comparison,
        "session": session.display().to_string(),
        "n_measured": m.rows.rows.len(),
        "skipped": m.skipped,
        "reprojection_outliers": m.reprojection,
        "rig_rms_px": m.rig.rms_px,
        "median_position_sigma_mm": m.median_sigma_mm(),
        "camera_agreement": m.agreement.poses,
        "poses": m.poses.iter().map(|p| json!({
            "pose_id": p.pose_id,
            "cameras": p.cameras,
            "sigma_position_mm": p.estimate.sigma_position_mm().as_slice(),
            "sigma_rotation_deg": p.estimate.sigma_rotation_deg().as_slice(),
        })).collect::<Vec<_>>(),
    });
    crate::verdict::add_verdict(&mut v, verdict);
    v
}

/// The verdict of `ferrocal measure --session`: how many poses were measured and the rig
/// calibration's RMS; `out`: the table written.
pub fn session_verdict(
    t: &ferrocal_calib::verdict::Thresholds,
    m: &SessionMeasurement,
    out: &Path,
) -> ferrocal_calib::verdict::Verdict {
    let n = m.rows.rows.len();
    let mut v = crate::verdict::measure_verdict(
        t,
        n,
        n + m.skipped.len(),
        "rig calibration RMS",
        m.rig.rms_px,
        &m.reprojection,
        Some(out),
    );
    // The cameras' agreement pose by pose (a larger disagreeing fraction was refused before).
    let l = &t.measure;
    let a = &m.agreement;
    if !a.poses.is_empty() {
        let bad = a.disagreeing(l.cameras_disagree_sigmas, l.cameras_disagree_relative);
        let named = bad
            .iter()
            .map(|p| format!("{} (camera {}: {:.2} mm, {:.0} sigma)", p.pose_id, p.camera, p.difference_mm, p.sigmas))
            .collect::<Vec<_>>()
            .join(", ");
        let label = if bad.is_empty() {
            format!("cameras agree on all {} poses, fraction disagreeing", a.poses.len())
        } else {
            format!("cameras disagree on {} of {} poses: {named}; fraction", bad.len(), a.poses.len())
        };
        let check = ferrocal_calib::verdict::Check::at_most(
            "measure.cameras_disagree_fraction",
            &label,
            "",
            bad.len() as f64 / a.poses.len() as f64,
            l.cameras_disagree_fraction_warn,
            l.cameras_disagree_fraction_fail,
        );
        let next = if bad.is_empty() || v.status != ferrocal_calib::verdict::Status::Pass {
            v.next.clone()
        } else {
            "look at the named poses' images (blur, a reflection, a partly covered target) and drop or retake them"
                .into()
        };
        v = ferrocal_calib::verdict::Verdict::new(v.checks.into_iter().chain([check]).collect(), next);
    }
    v
}

/// The terminal line of a session's measurement written to the table `out`.
pub fn session_line(m: &SessionMeasurement, out: &Path) -> String {
    format!(
        "{} poses measured, {} skipped; rig calibration RMS {:.4} px; median position sigma {:.4} mm; table {}",
        m.rows.rows.len(),
        m.skipped.len(),
        m.rig.rms_px,
        m.median_sigma_mm(),
        out.display()
    )
}

/// The terminal line of the cameras against a laser tracker.
pub fn tracker_line(c: &TrackerComparison) -> String {
    format!(
        "against the tracker ({} common poses): cameras {:.4} mm mean after registration; held-out tracker error of the model calibrated from the cameras {:.4} mm, from the tracker {:.4} mm, nominal {:.4} mm",
        c.n_common, c.camera_mean_mm, c.camera_model.mean_mm, c.tracker_model.mean_mm, c.nominal_model.mean_mm
    )
}

/// The demo's section: both real recordings of the ROS-Industrial industrial_calibration example
/// data (Apache-2.0) measured image by image as `ferrocal measure --images ... --poses ...` does,
/// the camera calibrated from the recording's own images and set beside the source's.
pub fn demo_section(data: &std::path::Path, work: &std::path::Path) -> Result<crate::report::Section> {
    use crate::handeye::demo::ic_section;
    use ferrocal_calib::check::Check;
    use ferrocal_datasets::handeye::import_ic_handeye;
    let (mut s, root) = ic_section(
        "measure-real",
        "Real recordings measured image by image (`ferrocal measure --images`)",
        data,
        work,
    )?;
    let Some(root) = root else { return Ok(s) };
    let mut rows = Vec::new();
    let mut bars = Vec::new();
    let mut verdicts = Vec::new();
    let mut data_json = Vec::new();
    for folder in ["test_set_charuco", "test_set_10x10"] {
        let dir = root.join(folder);
        let csv = work.join(format!("{folder}.poses.csv"));
        let ic = import_ic_handeye(&dir, &csv, None, None)?;
        let pattern_text = ic.pattern.clone().with_context(|| format!("{}: no target", dir.display()))?;
        let table = read_handeye_poses(&csv)?;
        let mut skipped_images = Vec::new();
        let paths = expand_image_specs(&[dir.join("images")], &mut skipped_images);
        let opts = RecordingOptions {
            mount: ic.mount,
            camera: None,
            calibration: CalibrationOptions::default(),
            corner_sigma_px: 0.1,
        };
        let m = measure_recording(&paths, &table, &pattern_text.parse()?, &opts)?;
        let k = m.camera.camera.intrinsics;
        let sd = m.camera.std.clone().unwrap_or_default();
        let sd = |i: usize| sd.get(i).copied().unwrap_or(f64::NAN);
        let source = ic.camera.map(|c| c.intrinsics);
        let rms: Vec<f64> = m.poses.iter().map(|p| p.estimate.rms_px).collect();
        let max_rms = rms.iter().cloned().fold(0.0, f64::max);
        let mut sig: Vec<f64> = m.poses.iter().map(|p| p.sigma_position_rms_mm()).collect();
        sig.sort_by(f64::total_cmp);
        for p in &m.poses {
            bars.push((p.image.clone(), folder.to_string(), p.estimate.rms_px));
        }
        rows.push(vec![
            folder.to_string(),
            ic.mount.name().to_string(),
            format!("{} / {}", m.poses.len(), table.rows.len()),
            format!("{:.1} +- {:.1}, {:.1} +- {:.1}", k.fx_px, sd(0), k.fy_px, sd(1)),
            format!("{:.1} +- {:.1}, {:.1} +- {:.1}", k.cx_px, sd(2), k.cy_px, sd(3)),
            source.map_or("-".into(), |c| format!("{:.1}, {:.1} / {:.1}, {:.1}", c.fx_px, c.fy_px, c.cx_px, c.cy_px)),
            format!("{max_rms:.3}"),
            format!("{:.3}", sig[sig.len() / 2]),
        ]);
        verdicts.push(Check::from_bool(
            format!("{folder}: every image measured within the source's 1.5 px"),
            m.poses.len() == table.rows.len() && max_rms < 1.5,
            format!(
                "{folder}: {} of {} images measured, worst reprojection RMS {max_rms:.3} px",
                m.poses.len(),
                table.rows.len()
            ),
        ));
        data_json.push(json!({"set": folder, "pattern": pattern_text, "camera": m.camera, "skipped": m.skipped,
            "per_image": m.poses.iter().map(|p| json!({"image": p.image, "rms_px": p.estimate.rms_px,
            "s0": p.estimate.s0, "measured": crate::handeye::json::transform_json(&p.measured),
            "sigma_position_mm": p.sigma_position_mm()})).collect::<Vec<_>>()}));
    }
    s.text("Each set is a folder of images and the robot's flange poses (imported with `ferrocal import ic-handeye`), measured as `ferrocal measure --images DIR --poses P.csv --pattern P --json R` does: the project's detector on every image (in parallel), the camera calibrated from the same images, each image's target pose weighted by the corners' covariances, with the camera's uncertainty propagated and the corners' part scaled by s0^2 where they scatter more than stated. Rows are T_camera_target (eye-to-hand) or T_target_camera (eye-in-hand). These sets report flange poses, not joints, so the poses go to the JSON; with joints the same command writes a measurement table (docs/session-format.md).");
    s.table(
        "Per set (source's camera: fx, fy / cx, cy)",
        &[
            "set",
            "mount",
            "measured",
            "fx, fy [px]",
            "cx, cy [px]",
            "source's camera",
            "worst RMS [px]",
            "median position sigma [mm]",
        ],
        rows,
    );
    s.figure(
        "Reprojection RMS of each image's pose fit",
        crate::plot::bar_chart("Per-image reprojection RMS", "RMS [px]", &bars),
    );
    s.data = json!({"sets": data_json});
    s.check(Check::all("real recordings measured", &verdicts));
    Ok(s)
}
