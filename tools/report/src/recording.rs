//! `ferrocal measure --images ... --poses P.csv --pattern P`: a user's own recording (a folder of
//! images and the poses table of `handeye`, no session manifest, no truth) measured by one camera
//! into a measurement table with each pose's covariance (`ferrocal_datasets::recording`).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::Args;
use ferrocal_datasets::handeye::{read_camera_file, read_handeye_poses};
use ferrocal_datasets::import::images::expand_image_specs;
use ferrocal_datasets::import::{self, JointUnit, LengthUnit, WriteOptions};
use ferrocal_datasets::recording::{measure_recording, RecordingMeasurement, RecordingOptions};
use ferrocal_vision::calib::CalibrationOptions;
use serde_json::json;

use crate::handeye::MountArg;
use crate::report::write_all_atomic;

/// The recording half of `ferrocal measure` (without `--session`).
#[derive(Debug, Args)]
pub struct RecordingArgs {
    /// Images of a recording: files, directories or quoted globs (instead of --session).
    #[arg(long, num_args = 1.., conflicts_with = "session", requires_all = ["poses", "pattern"])]
    pub images: Vec<PathBuf>,
    /// The poses table naming the images (the `handeye` format: `image`, joints `q1_<unit>...` or
    /// a flange pose, optional `split`). A measurement table needs joints.
    #[arg(long)]
    pub poses: Option<PathBuf>,
    /// The target: chessboard, ChArUco, circle grid, AprilTag board (docs/targets.md).
    #[arg(long)]
    pub pattern: Option<String>,
    /// Where the camera is: fixed, measuring the target on the flange (eye-to-hand, the
    /// default), or on the flange, looking at a fixed target (eye-in-hand: rows are the camera's
    /// pose in the target's frame).
    #[arg(long, value_enum, default_value = "eye-to-hand")]
    pub mount: MountArg,
    /// The camera (camera calibrate JSON, OpenCV or ROS YAML); without it the camera is
    /// calibrated from the recording's own views, which then need varied orientations.
    #[arg(long)]
    pub intrinsics: Option<PathBuf>,
}

/// Runs the recording measurement: every image that cannot be used is named on stderr and in
/// the JSON, and the batch goes on; the table is written only when at least one pose was
/// measured, never onto an input.
pub fn run(
    a: &RecordingArgs,
    out: Option<&PathBuf>,
    json_out: Option<&PathBuf>,
    corner_sigma_px: f64,
    vs: &crate::verdict::VerdictSettings,
) -> Result<ExitCode> {
    let (Some(poses), Some(pattern_text)) = (&a.poses, &a.pattern) else {
        bail!("measure: --images needs --poses and --pattern (or give --session)");
    };
    let pattern: ferrocal_vision::detect::Pattern = pattern_text.parse()?;
    let table = read_handeye_poses(poses)?;
    if out.is_some() && table.joint_units.is_empty() {
        bail!(
            "measure: {} gives flange poses, but a measurement table needs joint readings (q1_<unit>, ...); \
             leave out --out to get the per-image poses in --json, or use `ferrocal handeye` for the hand-eye transform",
            poses.display()
        );
    }
    let mut skipped_images = Vec::new();
    let paths = expand_image_specs(&a.images, &mut skipped_images);
    for o in out.iter().chain(json_out.iter()) {
        if let Ok(o) = o.canonicalize() {
            if paths.iter().chain(std::iter::once(poses)).any(|p| p.canonicalize().is_ok_and(|p| p == o)) {
                bail!("measure: refusing to overwrite {}, an input", o.display());
            }
        }
    }
    let outputs: Vec<&Path> = out.iter().chain(json_out.iter()).map(|p| p.as_path()).collect();
    let inputs: Vec<&Path> = paths.iter().map(PathBuf::as_path).chain([poses.as_path()]).collect();
    crate::report::check_outputs(&outputs, &inputs)?;
    // The table and the JSON are composed first and written together at the end.
    let mut files: Vec<(&Path, Vec<u8>)> = Vec::new();
    let opts = RecordingOptions {
        mount: crate::handeye::mount_of(a.mount),
        camera: a.intrinsics.as_deref().map(read_camera_file).transpose()?,
        calibration: CalibrationOptions::default(),
        corner_sigma_px,
    };
    eprintln!("measuring {} image(s) of {} ...", paths.len(), poses.display());
    let m =
        measure_recording(&paths, &table, &pattern, &opts).with_context(|| format!("measure: {}", poses.display()))?;
    for s in &skipped_images {
        eprintln!("ferrocal measure: skipped {s}");
    }
    for s in &m.skipped {
        eprintln!("ferrocal measure: skipped {}: {}", s.what, s.reason);
    }
    print_summary(&m);
    if let (Some(out), Some(rows)) = (out, &m.rows) {
        // Joints in SI (rad, m) whatever the poses table used: the values are SI inside.
        let mut wopts = WriteOptions::revolute(table.joint_units.len());
        wopts.joint_units = table
            .joint_units
            .iter()
            .map(|u| match u {
                JointUnit::Rad | JointUnit::Deg => JointUnit::Rad,
                JointUnit::M | JointUnit::Mm => JointUnit::M,
            })
            .collect();
        wopts.length_unit = LengthUnit::Mm;
        wopts.comments = vec![
            format!("measured by ferrocal {} from the images of {}", env!("CARGO_PKG_VERSION"), poses.display()),
            format!("{}; cov_*: each pose's covariance", frame_note(a.mount)),
        ];
        if let Some(s) = &m.source {
            wopts.comments.push(format!("source: {s}"));
        }
        let text =
            import::measurements_to_string(rows, &wopts).with_context(|| format!("writing {}", out.display()))?;
        files.push((out.as_path(), text.into_bytes()));
        println!("table {} ({} rows)", out.display(), rows.rows.len());
    }
    let verdict = {
        let total = m.poses.len() + m.skipped.len() + skipped_images.len();
        let (label, rms) = match m.camera.calibration_rms_px {
            Some(r) => ("camera calibration RMS", r),
            None => {
                let mut r: Vec<f64> = m.poses.iter().map(|p| p.estimate.rms_px).collect();
                r.sort_by(f64::total_cmp);
                ("median reprojection RMS of the poses", r.get(r.len() / 2).copied().unwrap_or(f64::NAN))
            }
        };
        crate::verdict::measure_verdict(&vs.thresholds, m.poses.len(), total, label, rms, out.map(PathBuf::as_path))
    };
    if let Some(j) = json_out {
        let mut skipped: Vec<serde_json::Value> = skipped_images
            .iter()
            .map(|s| json!({"image": s.image.display().to_string(), "reason": s.reason}))
            .collect();
        skipped.extend(m.skipped.iter().map(|s| json!({"image": s.what, "reason": s.reason})));
        let v = json!({
            "poses_table": poses.display().to_string(),
            "pattern": pattern_text,
            "mount": crate::handeye::mount_of(a.mount).name(),
            "frame": frame_note(a.mount),
            "source": m.source,
            "camera": m.camera,
            "n_measured": m.poses.len(),
            "skipped": skipped,
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
        });
        let mut v = v;
        crate::verdict::add_verdict(&mut v, &verdict);
        files.push((j.as_path(), serde_json::to_string_pretty(&v)?.into_bytes()));
    }
    write_all_atomic(&files.iter().map(|(p, b)| (*p, b.as_slice())).collect::<Vec<_>>())?;
    Ok(vs.conclude(&verdict))
}

fn frame_note(mount: MountArg) -> &'static str {
    match mount {
        MountArg::EyeToHand => "positions and orientations of the target in the camera's frame",
        MountArg::EyeInHand => "positions and orientations of the camera in the fixed target's frame",
    }
}

fn print_summary(m: &RecordingMeasurement) {
    let c = &m.camera;
    match (c.calibration_rms_px, &c.std) {
        (Some(rms), Some(std)) => println!(
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
        _ => println!("camera given: fx {:.2}, fy {:.2} px", c.camera.intrinsics.fx_px, c.camera.intrinsics.fy_px),
    }
    let mut sig: Vec<f64> = m.poses.iter().map(|p| p.sigma_position_rms_mm()).collect();
    sig.sort_by(f64::total_cmp);
    let rms: Vec<f64> = m.poses.iter().map(|p| p.estimate.rms_px).collect();
    println!(
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

/// The demo's section: both real recordings of the ROS-Industrial industrial_calibration example
/// data (Apache-2.0) measured image by image as `ferrocal measure --images ... --poses ...` does,
/// the camera calibrated from the recording's own images and set beside the source's.
pub fn demo_section(data: &std::path::Path, work: &std::path::Path) -> Result<crate::report::Section> {
    use crate::handeye::demo::IC_ATTRIBUTION;
    use crate::report::Section;
    use ferrocal_calib::check::Check;
    use ferrocal_datasets::handeye::import_ic_handeye;
    let mut s = Section::new("measure-real", "Real recordings measured image by image (`ferrocal measure --images`)");
    s.attribution(IC_ATTRIBUTION);
    let root = data.join("industrial_calibration");
    if !root.exists() {
        s.skipped(format!("{} is not present", root.display()));
        return Ok(s);
    }
    std::fs::create_dir_all(work).with_context(|| format!("creating {}", work.display()))?;
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
