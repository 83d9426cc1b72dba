//! `ferrocal measure --images ... --poses P.csv --pattern P`: a user's own recording measured
//! by one camera into a measurement table with each pose's covariance
//! ([`ferrocal_datasets::recording`]); its JSON and verdict by [`ferrocal_report::recording`].

use ferrocal_report::{say, tell};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::Args;
use ferrocal_datasets::recording::{RecordingInput, RecordingOptions};
use ferrocal_report::recording::{print_summary, recording_json, recording_verdict};
use ferrocal_report::verdict::VerdictSettings;
use ferrocal_report::Outputs;

use ferrocal_calib::handeye::Mount;

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
    #[arg(long, default_value = "eye-to-hand")]
    pub mount: Mount,
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
    let input = RecordingInput::load(&a.images, poses, pattern_text, out.is_some())?;
    let outputs: Vec<&Path> = out.iter().chain(json_out.iter()).map(|p| p.as_path()).collect();
    input.refuse_overwrite(&outputs)?;
    ferrocal_report::check_outputs(&outputs, &input.inputs())?;
    let mount = a.mount;
    let opts = RecordingOptions::new(mount, a.intrinsics.as_deref(), corner_sigma_px)?;
    tell!("measuring {} image(s) of {} ...", input.paths.len(), poses.display());
    let m = input.measure(&opts).with_context(|| format!("measure: {}", poses.display()))?;
    for s in input.skipped_lines(&m) {
        eprintln!("ferrocal measure: skipped {s}");
    }
    print_summary(&m);
    // The table and the JSON are composed first and written together at the end.
    let mut files = Outputs::default();
    if let (Some(out), Some(rows)) = (out, &m.rows) {
        let text = input.table_text(rows, mount, m.source.as_deref());
        files.text(out, text.with_context(|| format!("writing {}", out.display()))?);
        say!("table {} ({} rows)", out.display(), rows.rows.len());
    }
    let total = m.poses.len() + m.skipped.len() + input.skipped_images.len();
    let verdict = recording_verdict(&vs.thresholds, &m, total, out.map(PathBuf::as_path));
    if let Some(j) = json_out {
        files.json_with_verdict(j, recording_json(&m, poses, pattern_text, mount, &input.skipped_images), &verdict)?;
    }
    files.write()?;
    Ok(vs.conclude(&verdict))
}
