//! `ferrocal handeye`: the command's arguments and its run (images and poses in, the JSON of
//! `shared/spec/cli.md` and an HTML report out), `ferrocal handeye study` (the Monte Carlo
//! check of the covariance) and the industrial_calibration importer's wiring. The method lives in
//! `ferrocal_calib::handeye`, the formats in `ferrocal_datasets::handeye`.

pub mod demo;
pub mod html;
pub mod joint_demo;
pub mod json;
pub mod verdict;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use ferrocal_calib::handeye::opencv::{best_baseline, opencv_baselines};
use ferrocal_calib::handeye::{
    calibrate_hand_eye, calibrate_joint_from, HandEyeOptions, IntrinsicsMode, JointOptions, Mount,
};
use ferrocal_datasets::handeye::{coverage_study, load_recording, read_camera_file, read_handeye_poses};
use ferrocal_datasets::import::images::expand_image_specs;
use ferrocal_robot::RobotModel;
use ferrocal_vision::calib::CalibrationOptions;
use serde_json::{json, Value};

use crate::report::{write_atomic, Provenance, Report};

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
    /// Huber threshold in robust standard deviations (0: plain least squares).
    #[arg(long, default_value_t = 3.0)]
    pub huber: f64,
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

fn write_json(path: &Path, v: &Value) -> Result<()> {
    write_atomic(path, serde_json::to_string_pretty(v)?.as_bytes())
        .with_context(|| format!("writing {}", path.display()))
}

/// Runs `ferrocal handeye` (or its study).
pub fn run(a: &HandeyeArgs, vs: &crate::verdict::VerdictSettings) -> Result<ExitCode> {
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
    crate::report::check_outputs(&outputs, &inputs)?;
    // Every output is composed first and all are written together at the end: a failing joint
    // adjustment leaves no summary or report of half a run.
    let mut files: Vec<(&Path, Vec<u8>)> = Vec::new();
    let mount = mount_of(mount);
    let pattern: ferrocal_vision::detect::Pattern = pattern_text.parse()?;
    let table = read_handeye_poses(poses_path)?;
    let robot = a.robot.as_deref().map(RobotModel::load).transpose()?;
    let flange = table.flange_poses(robot.as_ref())?;
    let mut skipped_images = Vec::new();
    let paths = expand_image_specs(&a.images, &mut skipped_images);
    let (data, skipped) = load_recording(&paths, &table, &flange, &pattern, mount)?;
    for s in &skipped_images {
        eprintln!("ferrocal: skipped {s}");
    }
    for s in &skipped {
        eprintln!("ferrocal: skipped {}: {}", s.what, s.reason);
    }
    let intrinsics = match &a.intrinsics {
        Some(p) => IntrinsicsMode::Fixed(read_camera_file(p)?),
        None => IntrinsicsMode::Calibrate(CalibrationOptions::default()),
    };
    let mut options = HandEyeOptions {
        intrinsics,
        // The print scale is fitted unless asked not to: printed targets are rarely at their
        // nominal spacing and the robot's metric poses determine it (docs/handeye.md). Not with
        // the joint adjustment (--out) unless asked: there the flange poses come from the nominal
        // robot, whose length errors a free scale would take up, and the adjustment holds the
        // scale of its start.
        fit_target_scale: a.target_scale || (!a.nominal_target_scale && a.out.is_none()),
        huber_sigmas: a.huber,
        ..HandEyeOptions::default()
    };
    if a.robot_poses_as_measurements {
        (options.robot_sigma_m, options.robot_sigma_rad) = HandEyeOptions::MEASURED_POSE_SIGMAS;
    }
    if let (Some(mm), Some(deg)) = (a.robot_sigma_mm, a.robot_sigma_deg) {
        (options.robot_sigma_m, options.robot_sigma_rad, options.estimate_noise) = (mm * 1e-3, deg.to_radians(), false);
    }
    if a.exact_robot_poses {
        (options.robot_sigma_m, options.robot_sigma_rad) = (0.0, 0.0);
    }
    let result = calibrate_hand_eye(&data, &options)
        .with_context(|| format!("handeye: {} usable image(s) of {}", data.views.len(), paths.len()))?;
    let opencv_camera = result.initial_camera.as_ref().map_or(result.camera, |c| c.camera);
    let baselines = opencv_baselines(&data, &options, &opencv_camera);
    let mut skipped_json: Vec<Value> =
        skipped_images.iter().map(|s| json!({"image": s.image.display().to_string(), "reason": s.reason})).collect();
    skipped_json.extend(skipped.iter().map(|s| json!({"image": s.what, "reason": s.reason})));
    skipped_json.extend(result.skipped.iter().map(|s| json!({"image": s.name, "reason": s.reason})));
    let source = table.source.as_deref();
    if let Some(h) = &a.report {
        let mut prov =
            Provenance::new(json!({"pattern": pattern_text, "mount": mount.name(), "options": format!("{options:?}")}));
        prov.add_input(poses_path);
        let mut rep = Report::new(&format!("Hand-eye calibration ({}, {})", mount.name(), pattern_text), prov);
        rep.sections.extend(html::handeye_sections(&result, &baselines, source));
        files.push((h, rep.to_html().into_bytes()));
    }
    print_summary(&result, best_baseline(&baselines), source);
    let has_heldout = result.figures.heldout_rms_px.is_some();
    let split = if has_heldout { ferrocal_calib::Split::Test } else { ferrocal_calib::Split::Train };
    let mut checks =
        verdict::chain_checks(&vs.thresholds, &result.figures, verdict::pnp_rms_px(&data, &result, split), "handeye");
    if let (Some(out), Some(model), Some(spec)) = (&a.out, &robot, &a.robot) {
        let rows: std::collections::HashMap<&str, &ferrocal_datasets::handeye::PoseRow> =
            table.rows.iter().map(|r| (r.image.as_str(), r)).collect();
        let joints = data
            .views
            .iter()
            .map(|v| match rows.get(v.name.as_str()).map(|r| &r.robot) {
                Some(ferrocal_datasets::handeye::RobotReading::Joints(q)) => Ok(q.clone()),
                _ => bail!("handeye --out: image {} has no joint readings in the poses table", v.name),
            })
            .collect::<Result<Vec<_>>>()?;
        let joint_options = JointOptions { hand_eye: options.clone(), ..JointOptions::default() };
        // The joint adjustment holds the target at the print scale the hand-eye fit found.
        let mut scaled = data.clone();
        if let Some((scale, _)) = result.target_scale {
            scaled.target_points_m = ferrocal_calib::handeye::evaluate::scaled_target(&data.target_points_m, scale);
        }
        let joint = calibrate_joint_from(model, &scaled, &joints, result.clone(), &joint_options)
            .context("handeye: the joint adjustment of robot and camera")?;
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
    if let Some(p) = &a.json {
        let mut v = json::handeye_json(&result, &baselines, Value::Array(skipped_json), source);
        crate::verdict::add_verdict(&mut v, &verdict);
        files.insert(0, (p, serde_json::to_string_pretty(&v)?.into_bytes()));
    }
    crate::report::write_all_atomic(&files.iter().map(|(p, b)| (*p, b.as_slice())).collect::<Vec<_>>())?;
    Ok(vs.conclude(&verdict))
}

fn print_summary(
    r: &ferrocal_calib::handeye::HandEyeResult,
    best: Option<&ferrocal_calib::handeye::opencv::BaselineReport>,
    source: Option<&str>,
) {
    let p = r.hand_eye.transform.translation.vector * 1e3;
    let s = r.hand_eye.translation_std_mm();
    println!(
        "{} {}: translation [{:.3}, {:.3}, {:.3}] +- [{:.3}, {:.3}, {:.3}] mm, rotation std {:.4?} deg",
        r.mount.name(),
        r.mount.hand_eye_name(),
        p.x,
        p.y,
        p.z,
        s.x,
        s.y,
        s.z,
        r.hand_eye.rotation_std_deg().as_slice()
    );
    let f = &r.figures;
    let opt = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{x:.4}"));
    println!(
        "chain RMS: train {:.4} px, held-out {} px; PnP agreement: train {} mm / {} deg, held-out {} mm / {} deg",
        f.train_rms_px,
        opt(f.heldout_rms_px),
        opt(f.train_pnp_position_mm),
        opt(f.train_pnp_rotation_deg),
        opt(f.heldout_pnp_position_mm),
        opt(f.heldout_pnp_rotation_deg)
    );
    if let Some(b) = best.and_then(|b| b.figures.as_ref().map(|f| (b, f))) {
        println!(
            "OpenCV best ({} {}): train {:.4} px, held-out {} px",
            b.0.function,
            b.0.method,
            b.1.train_rms_px,
            opt(b.1.heldout_rms_px)
        );
    }
    if let Some(src) = source {
        println!("data: {src}");
    }
    for w in &r.warnings {
        eprintln!("ferrocal handeye: warning: {w}");
    }
}

/// The mount of a command-line value.
pub fn mount_of(m: MountArg) -> Mount {
    match m {
        MountArg::EyeInHand => Mount::EyeInHand,
        MountArg::EyeToHand => Mount::EyeToHand,
    }
}

fn run_simulate(s: &SimulateArgs) -> Result<ExitCode> {
    if let Some(robot) = &s.robot {
        if robot != "ur5" || s.mount != MountArg::EyeToHand {
            bail!("handeye simulate --robot: only the ur5 cell, eye-to-hand, is simulated (got {robot})");
        }
        let config = ferrocal_datasets::handeye::joint_record::rendered_ur5_cell(s.train, s.test);
        let r = ferrocal_datasets::handeye::joint_record::write_joint_recording(&config, &s.out, s.seed)?;
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
    let r = ferrocal_datasets::handeye::write_rendered_recording(&config, &s.out, s.seed)?;
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
        println!(
            "{}: {} runs ({} failed); 3-sigma coverage translation {:.1} %, rotation {:.1} %; RMS error {:.4} mm \
             (stated std {:.4} mm), {:.5} deg (stated {:.5} deg); held-out chain RMS {:.4} px",
            r.mount.name(),
            r.n_runs,
            r.n_failed,
            100.0 * r.translation_coverage_3sigma,
            100.0 * r.rotation_coverage_3sigma,
            r.translation_rms_error_mm,
            r.translation_rms_std_mm,
            r.rotation_rms_error_deg,
            r.rotation_rms_std_deg,
            r.mean_heldout_rms_px
        );
    }
    if let Some(p) = &s.json {
        write_json(p, &json!({"simulations": s.simulations, "seed": s.seed, "mode": mode, "mounts": rows}))?;
    }
    Ok(ExitCode::SUCCESS)
}

/// `ferrocal import ic-handeye`: an industrial_calibration set folder to the poses table (and its
/// camera to OpenCV YAML when asked).
pub fn run_import_ic(
    input: &Path,
    out: &Path,
    test_every: Option<usize>,
    intrinsics_out: Option<&Path>,
    vs: &crate::verdict::VerdictSettings,
) -> Result<ExitCode> {
    let set = ferrocal_datasets::handeye::import_ic_handeye(input, out, test_every, intrinsics_out)?;
    let n_test = set.rows.iter().filter(|r| r.2 == ferrocal_calib::Split::Test).count();
    println!(
        "{} rows ({n_test} test) written to {}; mount {}{}",
        set.rows.len(),
        out.display(),
        set.mount.name(),
        set.pattern.as_ref().map(|p| format!(", pattern {p}")).unwrap_or_default()
    );
    let l = &vs.thresholds.import;
    let checks = vec![ferrocal_calib::verdict::Check::at_least(
        "import.rows",
        "rows written",
        "",
        set.rows.len() as f64,
        l.rows_warn,
        l.rows_fail,
    )];
    let mount_name = set.mount.name();
    let pattern = set.pattern.clone().unwrap_or_else(|| "<pattern>".into());
    let verdict = ferrocal_calib::verdict::Verdict::with_next(checks, |c| {
        match c {
        None => format!(
            "calibrate ({n_test} rows marked test are held out): ferrocal handeye --images {}/images --poses {} --pattern {pattern} --mount {mount_name} --json <result.json>",
            input.display(),
            out.display()
        ),
        Some(_) => "the set holds too few images for a hand-eye calibration: record more poses".into(),
    }
    });
    Ok(vs.conclude(&verdict))
}
