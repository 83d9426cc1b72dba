//! `ferrocal measure --images ... --poses P.csv --pattern P`: a user's own recording measured
//! by one camera into a measurement table with each pose's covariance
//! ([`ferrocal_datasets::recording`]); its JSON and verdict by [`ferrocal_report::recording`].

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::Args;
use ferrocal_datasets::handeye::{read_camera_file, read_handeye_poses};
use ferrocal_datasets::import::images::expand_image_specs;
use ferrocal_datasets::recording::{measure_recording, recording_table_text, RecordingOptions};
use ferrocal_report::recording::{print_summary, recording_json, recording_verdict};
use ferrocal_report::verdict::VerdictSettings;
use ferrocal_vision::calib::CalibrationOptions;

use super::handeye::{mount_of, MountArg};

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
    vs: &VerdictSettings,
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
    ferrocal_report::check_outputs(&outputs, &inputs)?;
    // The table and the JSON are composed first and written together at the end.
    let mut files: Vec<(&Path, Vec<u8>)> = Vec::new();
    let mount = mount_of(a.mount);
    let opts = RecordingOptions {
        mount,
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
        let text = recording_table_text(rows, &table, mount, poses, m.source.as_deref())
            .with_context(|| format!("writing {}", out.display()))?;
        files.push((out.as_path(), text.into_bytes()));
        println!("table {} ({} rows)", out.display(), rows.rows.len());
    }
    let total = m.poses.len() + m.skipped.len() + skipped_images.len();
    let verdict = recording_verdict(&vs.thresholds, &m, total, out.map(PathBuf::as_path));
    if let Some(j) = json_out {
        let mut v = recording_json(&m, poses, pattern_text, mount, &skipped_images);
        ferrocal_report::verdict::add_verdict(&mut v, &verdict);
        files.push((j.as_path(), serde_json::to_string_pretty(&v)?.into_bytes()));
    }
    ferrocal_report::write_all_atomic(&files.iter().map(|(p, b)| (*p, b.as_slice())).collect::<Vec<_>>())?;
    Ok(vs.conclude(&verdict))
}
