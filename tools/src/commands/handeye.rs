//! `ferrocal handeye`: the command's arguments, turned into the workflow's options
//! ([`ferrocal_datasets::handeye::workflow`]); the results go to JSON and HTML through
//! [`ferrocal_report::handeye`]. Also `handeye study` (the Monte Carlo check of the covariance)
//! and `handeye simulate`.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::{Args, Subcommand, ValueEnum};
use ferrocal_calib::handeye::opencv::best_baseline;
use ferrocal_calib::handeye::Mount;
use ferrocal_datasets::handeye::{coverage_study, HandEyeInput, HandEyeRunOptions};
use ferrocal_report::handeye::{html, json, print_summary, verdict};
use ferrocal_report::report::{Provenance, Report};
use ferrocal_report::verdict::VerdictSettings;
use serde_json::{json, Value};

/// The mount on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum MountArg {
    /// Camera on the flange, target fixed.
    #[value(name = "eye-in-hand")]
    EyeInHand,
    /// Camera fixed, target on the flange.
    #[value(name = "eye-to-hand")]
    EyeToHand,
}

/// `ferrocal handeye`.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct HandeyeArgs {
    /// The Monte Carlo study instead of a calibration.
    #[command(subcommand)]
    pub command: Option<HandeyeCommand>,
    /// Images: files, directories or quoted globs.
    #[arg(long, required = true, num_args = 1..)]
    pub images: Vec<PathBuf>,
    /// Poses CSV: `image`, then `x_mm,y_mm,z_mm,qw,qx,qy,qz` (T_base_flange) or joints `q1_<unit>...`
    /// (with --robot), optional `split` (train/test).
    #[arg(long, required = true)]
    pub poses: Option<PathBuf>,
    /// The target, e.g. `chessboard:9x6:25mm`.
    #[arg(long, required = true)]
    pub pattern: Option<String>,
    /// Where the camera is.
    #[arg(long, value_enum, required = true)]
    pub mount: Option<MountArg>,
    /// Robot model (preset, URDF or TOML) for joint readings.
    #[arg(long)]
    pub robot: Option<String>,
    /// Camera file to hold fixed (camera calibrate JSON, OpenCV or ROS YAML); without it the
    /// camera is calibrated from the training images and refined with the chain.
    #[arg(long)]
    pub intrinsics: Option<PathBuf>,
    /// Write the JSON result here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write an HTML report here.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Fit the printed target's overall scale against the robot's metric poses: the default
    /// without --out; with --out (the joint adjustment) only when given.
    #[arg(long, conflicts_with = "nominal_target_scale")]
    pub target_scale: bool,
    /// Hold the target at its nominal spacing instead of fitting its print scale.
    #[arg(long)]
    pub nominal_target_scale: bool,
    /// Noise of the reported flange positions, mm per coordinate; with --robot-sigma-deg the
    /// poses are measurements with this fixed noise.
    #[arg(long, requires = "robot_sigma_deg")]
    pub robot_sigma_mm: Option<f64>,
    /// Noise of the reported flange orientations, degrees per axis.
    #[arg(long, requires = "robot_sigma_mm")]
    pub robot_sigma_deg: Option<f64>,
    /// Take the reported flange poses as exact (no robot-pose noise): the default.
    #[arg(long, conflicts_with_all = ["robot_sigma_mm", "robot_poses_as_measurements"])]
    pub exact_robot_poses: bool,
    /// Take the reported flange poses as measurements with their own noise, estimated from the
    /// data (for controllers whose poses scatter from pose to pose).
    #[arg(long)]
    pub robot_poses_as_measurements: bool,
    /// Huber threshold in robust standard deviations (0: plain least squares); the same as
    /// `--loss huber:<sigmas>`.
    #[arg(long, default_value_t = 3.0, conflicts_with = "loss")]
    pub huber: f64,
    /// Robust loss of the second solve, as in `calibrate` and `camera calibrate`: `none` or
    /// `huber:<sigmas>` (robust standard deviations of the first solve); default `huber:3`.
    #[arg(long)]
    pub loss: Option<String>,
    /// With --robot and joint readings: adjust the robot's kinematic parameters together with
    /// the camera, W and X (the joint adjustment) and write the calibrated robot here, in the
    /// format `evaluate` reads (device frame: W^-1, the camera's frame for eye-to-hand; tool: X).
    #[arg(long, requires = "robot")]
    pub out: Option<PathBuf>,
}

/// `ferrocal handeye <command>`.
#[derive(Debug, Subcommand)]
pub enum HandeyeCommand {
    /// Monte Carlo check of the hand-eye covariance on simulated recordings with known truth
    /// (both mounts): the 3-sigma coverage of the hand-eye translation and rotation.
    Study(StudyArgs),
    /// Write a simulated recording with rendered chessboard images, the poses CSV, the true
    /// camera (camera.yaml) and the truth (truth.json), to try the command on.
    Simulate(SimulateArgs),
}

/// `ferrocal handeye simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Where the camera is.
    #[arg(long, value_enum)]
    pub mount: MountArg,
    /// Folder to write (images/, poses.csv, camera.yaml, truth.json).
    #[arg(long)]
    pub out: PathBuf,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Training images.
    #[arg(long, default_value_t = 10)]
    pub train: usize,
    /// Held-out images.
    #[arg(long, default_value_t = 6)]
    pub test: usize,
    /// A robot cell instead (eye-to-hand only; `ur5`): the joint study's UR5 with true
    /// kinematic errors, the joint readings in poses.csv, and heldout.csv, a simulated tracker's
    /// readings of the held-out poses for `evaluate --refit-frame` (the joint adjustment's check).
    #[arg(long)]
    pub robot: Option<String>,
}

/// `ferrocal handeye study`.
#[derive(Debug, Args)]
pub struct StudyArgs {
    /// Simulations per mount.
    #[arg(long, default_value_t = 200)]
    pub simulations: usize,
    /// Seed of the first simulation (the others follow).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Calibrate the intrinsics from the training images (else held at the truth).
    #[arg(long)]
    pub free_intrinsics: bool,
    /// Estimate the noise levels by variance components (else the true ones are given).
    #[arg(long)]
    pub estimate_noise: bool,
    /// Write the summary as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// The mount of a command-line value.
pub fn mount_of(m: MountArg) -> Mount {
    match m {
        MountArg::EyeInHand => Mount::EyeInHand,
        MountArg::EyeToHand => Mount::EyeToHand,
    }
}

/// Runs `ferrocal handeye` (or its study).
pub fn run(a: &HandeyeArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    match &a.command {
        Some(HandeyeCommand::Study(s)) => return run_study(s),
        Some(HandeyeCommand::Simulate(s)) => return run_simulate(s),
        None => {}
    }
    let (Some(poses_path), Some(pattern_text), Some(mount)) = (&a.poses, &a.pattern, a.mount) else {
        bail!("handeye: --poses, --pattern and --mount are required");
    };
    let outputs: Vec<&Path> = [&a.json, &a.report, &a.out].into_iter().flatten().map(PathBuf::as_path).collect();
    let mut inputs: Vec<&Path> = vec![poses_path.as_path()];
    inputs.extend(a.intrinsics.as_deref());
    inputs.extend(a.robot.as_deref().map(Path::new));
    inputs.extend(a.images.iter().map(PathBuf::as_path));
    ferrocal_report::check_outputs(&outputs, &inputs)?;
    // Every output is composed first and all are written together at the end: a failing joint
    // adjustment leaves no summary or report of half a run.
    let mut files: Vec<(&Path, Vec<u8>)> = Vec::new();
    let mount = mount_of(mount);
    let run = HandEyeRunOptions {
        images: a.images.clone(),
        poses: poses_path.clone(),
        pattern: pattern_text.clone(),
        mount,
        robot: a.robot.clone(),
        intrinsics: a.intrinsics.clone(),
        // The print scale is fitted unless asked not to: printed targets are rarely at their
        // nominal spacing and the robot's metric poses determine it (docs/handeye.md). Not with
        // the joint adjustment (--out) unless asked: there the flange poses come from the nominal
        // robot, whose length errors a free scale would take up, and the adjustment holds the
        // scale of its start.
        fit_target_scale: a.target_scale || (!a.nominal_target_scale && a.out.is_none()),
        huber_sigmas: match a.loss.as_deref() {
            None => a.huber,
            Some(l) => match ferrocal_datasets::calibration::parse_loss(l)? {
                ferrocal_lsq::Loss::Squared => 0.0,
                ferrocal_lsq::Loss::Huber { delta } => delta,
                _ => anyhow::bail!("--loss {l}: the hand-eye fit takes none or huber:<sigmas>"),
            },
        },
        robot_poses_as_measurements: a.robot_poses_as_measurements,
        robot_sigma_mm_deg: a.robot_sigma_mm.zip(a.robot_sigma_deg),
        exact_robot_poses: a.exact_robot_poses,
    };
    let input = HandEyeInput::load(&run)?;
    for s in &input.skipped_images {
        eprintln!("ferrocal: skipped {s}");
    }
    for s in &input.skipped {
        eprintln!("ferrocal: skipped {}: {}", s.what, s.reason);
    }
    let fit = input.fit(run.hand_eye_options()?)?;
    let (result, baselines, options) = (&fit.result, &fit.baselines, &fit.options);
    let mut skipped_json: Vec<Value> = input
        .skipped_images
        .iter()
        .map(|s| json!({"image": s.image.display().to_string(), "reason": s.reason}))
        .collect();
    skipped_json.extend(input.skipped.iter().map(|s| json!({"image": s.what, "reason": s.reason})));
    skipped_json.extend(result.skipped.iter().map(|s| json!({"image": s.name, "reason": s.reason})));
    let source = input.table.source.as_deref();
    print_summary(result, best_baseline(baselines), source);
    let has_heldout = result.figures.heldout_rms_px.is_some();
    let split = if has_heldout { ferrocal_calib::Split::Test } else { ferrocal_calib::Split::Train };
    let pnp = verdict::pnp_rms_px(&input.data, result, split);
    let mut checks = verdict::chain_checks(&vs.thresholds, &result.figures, pnp, "handeye");
    if let (Some(out), Some(spec)) = (&a.out, &a.robot) {
        let joint = input.joint_adjustment(&fit)?;
        files.push((out, serde_json::to_string_pretty(&joint.file(spec))?.into_bytes()));
        // The joint adjustment's chain, scored as the hand-eye fit's (no PnP floor: its camera
        // is the adjustment's own).
        checks.extend(
            verdict::chain_checks(&vs.thresholds, &joint.figures, None, "handeye.joint")
                .into_iter()
                .filter(|c| c.name.ends_with("chain_rms_px")),
        );
        let opt = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{x:.4}"));
        println!(
            "joint adjustment: {} robot parameters, chain RMS train {:.4} px, held-out {} px, s0 {:.3}; calibration written to {}",
            joint.free.len(),
            joint.figures.train_rms_px,
            opt(joint.figures.heldout_rms_px),
            joint.s0,
            out.display()
        );
    }
    let out_text = a.out.as_ref().map(|p| p.display().to_string());
    let verdict = verdict::handeye_verdict(checks, mount, has_heldout, out_text.as_deref());
    if let Some(h) = &a.report {
        let mut prov =
            Provenance::new(json!({"pattern": pattern_text, "mount": mount.name(), "options": format!("{options:?}")}));
        prov.add_input(poses_path);
        let mut rep = Report::new(&format!("Hand-eye calibration ({}, {})", mount.name(), pattern_text), prov);
        rep.sections.extend(html::handeye_sections(result, baselines, source));
        rep.verdict = Some(verdict.clone());
        files.push((h, rep.to_html().into_bytes()));
    }
    if let Some(p) = &a.json {
        let mut v = json::handeye_json(result, baselines, Value::Array(skipped_json), source);
        ferrocal_report::verdict::add_verdict(&mut v, &verdict);
        files.insert(0, (p, serde_json::to_string_pretty(&v)?.into_bytes()));
    }
    ferrocal_report::write_all_atomic(&files.iter().map(|(p, b)| (*p, b.as_slice())).collect::<Vec<_>>())?;
    Ok(vs.conclude(&verdict))
}

/// The most images one `handeye simulate` renders (about 1 MB each).
const MAX_SIMULATED_IMAGES: usize = 2000;

fn run_simulate(s: &SimulateArgs) -> Result<ExitCode> {
    if s.train + s.test > MAX_SIMULATED_IMAGES {
        bail!(
            "handeye simulate: --train {} and --test {} ask for {} images; at most {MAX_SIMULATED_IMAGES} are rendered",
            s.train,
            s.test,
            s.train + s.test
        );
    }
    // Written aside and moved into place: a run that is stopped leaves no folder of images
    // without its poses.csv.
    ferrocal_report::StagedFolder::check(&s.out, false)?;
    let staged = ferrocal_report::StagedFolder::create(&s.out)?;
    let code = simulate_into(s, staged.path())?;
    staged.commit()?;
    Ok(code)
}

fn simulate_into(s: &SimulateArgs, dir: &std::path::Path) -> Result<ExitCode> {
    if let Some(robot) = &s.robot {
        if robot != "ur5" || s.mount != MountArg::EyeToHand {
            bail!("handeye simulate --robot: only the ur5 cell, eye-to-hand, is simulated (got {robot})");
        }
        let config = ferrocal_datasets::handeye::joint_record::rendered_ur5_cell(s.train, s.test);
        let r = ferrocal_datasets::handeye::joint_record::write_joint_recording(&config, dir, s.seed)?;
        eprintln!(
            "{} + {} images written to {} (pattern {}); nominal {} held out: mean {:.4} mm after the frame refit",
            r.n_train,
            r.n_test,
            s.out.display(),
            r.pattern,
            r.robot,
            r.nominal_heldout.mean_mm
        );
        return Ok(ExitCode::SUCCESS);
    }
    let mut config = ferrocal_datasets::handeye::HandEyeSimConfig::default_for(mount_of(s.mount));
    config.n_train = s.train;
    config.n_test = s.test;
    let r = ferrocal_datasets::handeye::write_rendered_recording(&config, dir, s.seed)?;
    eprintln!("{} images written to {} (pattern {})", r.n_images, s.out.display(), r.pattern);
    Ok(ExitCode::SUCCESS)
}

fn run_study(s: &StudyArgs) -> Result<ExitCode> {
    if s.simulations == 0 {
        bail!("handeye study: --simulations must be at least 1");
    }
    let mode =
        ferrocal_datasets::handeye::StudyMode { free_intrinsics: s.free_intrinsics, estimate_noise: s.estimate_noise };
    let rows = coverage_study(s.simulations, s.seed, mode, &|k, n| {
        if k % 20 == 0 || k == n {
            eprintln!("handeye study: {k}/{n} simulations");
        }
    });
    for r in &rows {
        println!("{}", ferrocal_report::handeye::coverage_line(r));
    }
    if let Some(p) = &s.json {
        let v = json!({"simulations": s.simulations, "seed": s.seed, "mode": mode, "mounts": rows});
        ferrocal_report::write_atomic(p, serde_json::to_string_pretty(&v)?.as_bytes())
            .map_err(|e| anyhow::Error::new(e).context(format!("writing {}", p.display())))?;
    }
    Ok(ExitCode::SUCCESS)
}
