//! `ferrocal simulate` and `ferrocal import`: recorded sessions from a simulated cell, and real
//! recordings converted into the measurement table.

use ferrocal_report::{say, tell};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::Args;
use ferrocal_calib::verdict::commands as verdict;
use ferrocal_datasets::import::convert::{import_table, ImportSource};
use ferrocal_datasets::sim::session::{cell_for_session, session_summary};
use ferrocal_datasets::sim::simulate;
use ferrocal_report::recording::{session_json, session_line, session_verdict, tracker_line};
use ferrocal_report::verdict::VerdictSettings;
use ferrocal_report::Outputs;

/// `ferrocal simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Cell file (TOML): robot with its errors and effects, plan, tracker, cameras, target.
    /// `datasets/cells/gantry_tau_l1.toml` is the built-in example.
    #[arg(long)]
    pub config: PathBuf,
    /// Folder for the session (images, joints.csv, tracker.csv, manifest.json, truth/).
    #[arg(long)]
    pub out: PathBuf,
    /// Replace the folder when it exists.
    #[arg(long)]
    pub force: bool,
    /// Override the cell's seed.
    #[arg(long)]
    pub seed: Option<u64>,
}

pub fn run_simulate(args: &SimulateArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let cfg = cell_for_session(&args.config, &args.out, args.seed)?;
    let bars = crate::progress::Bars::default();
    let manifest = simulate(&cfg, &args.out, args.force, |k, n| bars.tick("simulating poses", k as u64, n as u64))?;
    tell!("{}", session_summary(&manifest, &args.out));
    let counts = [("poses", manifest.n_poses)];
    let next = if manifest.cameras.is_empty() {
        format!(
            "calibrate from the tracker's table: ferrocal calibrate --robot <model> --measurements {} --out <cal.json>",
            args.out.join("tracker.csv").display()
        )
    } else {
        format!("measure the session: ferrocal measure --session {} --out <table.csv>", args.out.display())
    };
    Ok(vs.conclude(&verdict::simulated("simulate", &counts, &next)))
}

/// `ferrocal import`.
#[derive(Debug, Args)]
pub struct ImportArgs {
    /// What the input is: `ur5` (`ur5_tracker/ur5_grid_train.csv`: measured = target + dif,
    /// joints in degrees), `ur10` (`ur10_tracker/Series_*/measurements_*.csv`: semicolons,
    /// decimal commas; T-Mac positions and orientations in the tracker frame, temperature,
    /// time), `table` (a measurement table, re-written in canonical units, checked on the way),
    /// `ic-handeye` (an industrial_calibration hand-eye set folder, cal_data.yaml and poses/, to
    /// a handeye poses CSV) or `ic-kinematic` (an industrial_calibration kinematic-calibration
    /// set, `measurements.yaml`: the target in a fixed camera's frame, the target chain's
    /// joints, to a measurement table).
    #[arg(value_parser = crate::cli::choice::<ImportSource>)]
    pub kind: ImportSource,
    /// The recording's file.
    #[arg(long)]
    pub input: PathBuf,
    /// The measurement table to write (shared/spec/measurements.md).
    #[arg(long)]
    pub out: PathBuf,
    /// Write joints in degrees (revolute) and lengths in mm instead of SI.
    #[arg(long)]
    pub user_units: bool,
    /// ic-handeye, ic-kinematic: mark every K-th row `test` (2: every second one).
    #[arg(long)]
    pub test_every: Option<usize>,
    /// ic-handeye: write the set's camera as OpenCV YAML here.
    #[arg(long)]
    pub intrinsics_out: Option<PathBuf>,
    /// ic-kinematic: write the source's nominal two-axis positioner model as URDF here.
    #[arg(long)]
    pub robot_out: Option<PathBuf>,
}

pub fn run_import(args: &ImportArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let mut outputs = vec![args.out.as_path()];
    outputs.extend(args.robot_out.as_deref());
    outputs.extend(args.intrinsics_out.as_deref());
    ferrocal_report::check_outputs(&outputs, &[&args.input])?;
    if args.kind == ImportSource::IcHandeye {
        let cam = args.intrinsics_out.as_deref();
        let set = ferrocal_datasets::handeye::import_ic_handeye(&args.input, &args.out, args.test_every, cam)?;
        return Ok(ferrocal_report::handeye::import_ic_summary(&set, &args.input, &args.out, vs));
    }
    let (robot_out, units) = (args.robot_out.is_some(), args.user_units);
    let t = import_table(args.kind, &args.input, &args.out, args.test_every, robot_out, units)?;
    for w in &t.warnings {
        eprintln!("warning: {w}");
    }
    // Every output is composed first and all are written as one commit at the end.
    let mut out = Outputs::default();
    out.text(&args.out, t.table.as_str());
    if let (Some(p), Some(urdf)) = (&args.robot_out, &t.urdf) {
        out.text(p, urdf.as_str());
    }
    let (n, n_test) = (t.set.rows.len(), t.n_test());
    let has_split = t.set.rows.iter().any(|r| r.split.is_some());
    say!("imported {n} rows ({n_test} marked test; {})", verdict::held_out_words(n, n_test, has_split));
    out.write()?;
    let doubts: Vec<&str> =
        t.warnings.iter().filter_map(|w| ferrocal_datasets::import::plausible::unit_advice(w)).collect();
    let v = verdict::import(&vs.thresholds, n, n_test, has_split, &args.out);
    Ok(vs.conclude(&ferrocal_calib::verdict::with_unit_doubts(v, &doubts)))
}

/// `ferrocal measure`.
#[derive(Debug, Args)]
pub struct MeasureArgs {
    /// The session folder (docs/session-format.md; `ferrocal simulate` writes one).
    #[arg(long, required_unless_present = "images")]
    pub session: Option<PathBuf>,
    /// A recording of images and a poses table instead of a session.
    #[command(flatten)]
    pub recording: super::recording::RecordingArgs,
    /// The measurement table to write (shared/spec/measurements.md with the `cov_*` columns of
    /// docs/session-format.md), lengths in mm; required with --session.
    #[arg(long, required_unless_present = "images")]
    pub out: Option<PathBuf>,
    /// Write a JSON summary here (rig calibration, per-pose standard deviations, skipped images).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Corner standard deviation for corners the detector gives no covariance for, pixels.
    #[arg(long, default_value_t = 0.02)]
    pub corner_sigma_px: f64,
    /// A laser tracker's measurement table of the same poses (matched by pose id): the camera
    /// system is compared with it, and the robot calibrated from each on held-out tracker poses.
    #[arg(long, requires = "robot")]
    pub tracker: Option<PathBuf>,
    /// The robot model for the comparison (preset, URDF or TOML).
    #[arg(long)]
    pub robot: Option<String>,
}

/// Runs `ferrocal measure`: every image that cannot be used is named on stderr and in the JSON,
/// and the batch goes on; the table is written only when at least one pose was measured.
pub fn run_measure(args: &MeasureArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    use ferrocal_datasets::measure::{check_out_of_session, measure_session_checked, MeasureOptions};
    let opts = MeasureOptions::detector(args.corner_sigma_px)?;
    let (Some(session), Some(out)) = (&args.session, &args.out) else {
        return super::recording::run(&args.recording, args.out.as_ref(), args.json.as_ref(), args.corner_sigma_px, vs);
    };
    check_out_of_session(out, session)?;
    let outputs: Vec<&Path> = [Some(out.as_path()), args.json.as_deref()].into_iter().flatten().collect();
    let inputs: Vec<&Path> =
        [args.tracker.as_deref(), args.robot.as_deref().map(Path::new)].into_iter().flatten().collect();
    ferrocal_report::check_outputs(&outputs, &inputs)?;
    tell!("measuring {} ...", session.display());
    // Data that contradict themselves are refused before anything is written.
    let tracker = args.tracker.as_deref().zip(args.robot.as_deref());
    let skipped = |s: &str| eprintln!("ferrocal measure: skipped {s}");
    let (m, comparison) = measure_session_checked(session, &opts, &vs.thresholds.measure, tracker, &skipped)
        .with_context(|| format!("measure: {}", session.display()))?;
    // The table and the summary are composed first and written together at the end.
    let mut files = Outputs::default();
    files.text(out, m.table_text(session).with_context(|| format!("writing {}", out.display()))?);
    say!("{}", session_line(&m, out));
    comparison.iter().for_each(|c| say!("{}", tracker_line(c)));
    let verdict = session_verdict(&vs.thresholds, &m, out);
    if let Some(j) = &args.json {
        files.json(j, &session_json(&m, session, comparison.as_ref(), &verdict))?;
    }
    files.write()?;
    Ok(vs.conclude(&verdict))
}
