//! `ferrocal handeye`: the command's arguments, turned into the workflow's options
//! ([`ferrocal_datasets::handeye::workflow`]); the results go to JSON and HTML through
//! [`ferrocal_report::handeye`]. Also `handeye study` (the Monte Carlo check of the covariance)
//! and `handeye simulate`.

use ferrocal_report::{say, tell};
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::{Args, Subcommand};
use ferrocal_calib::handeye::physics::PhysicsOptions;
use ferrocal_calib::handeye::Mount;
use ferrocal_datasets::handeye::RigInput;
use ferrocal_datasets::handeye::{
    check_simulated_images, coverage_study, huber_sigmas_of_loss, read_poses_header, run_inputs,
    write_simulated_recording, HandEyeInput, HandEyeRunOptions,
};
use ferrocal_report::handeye::rig::{present_rig, rig_file_paths, rig_outputs, RigFiles};
use ferrocal_report::handeye::{handeye_outputs, present_run, study_json, verdict, HandeyeFiles};
use ferrocal_report::verdict::VerdictSettings;

/// `ferrocal handeye`.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct HandeyeArgs {
    /// The Monte Carlo study instead of a calibration.
    #[command(subcommand)]
    pub command: Option<HandeyeCommand>,
    /// Images: files, directories or quoted globs. Given once per camera for a rig (two or more
    /// cameras, camera 0 the reference): `--images cam0/ --images cam1/`; each camera's images
    /// are matched to the poses table's rows by file name.
    #[arg(long, required_unless_present = "observations", num_args = 1..)]
    pub images: Vec<PathBuf>,
    /// Detections made elsewhere instead of images (one camera): a CSV of `image, camera,
    /// point_id, u_px, v_px` (optionally `sigma_px`), the point ids those of `--pattern`'s points,
    /// or mrcal's corners file; each image matched to the poses table's rows by file name.
    #[arg(long, conflicts_with = "images")]
    pub observations: Option<PathBuf>,
    /// The size of the observed images, `<width>x<height>` pixels (read from the image files
    /// when they exist beside the observations file).
    #[arg(long, value_name = "WxH", requires = "observations")]
    pub image_size: Option<String>,
    /// `--images` grouped by occurrence, one group per camera (filled by
    /// [`crate::cli::Cli::try_parse_grouped`]; empty: one camera, `images`).
    #[arg(skip)]
    pub image_groups: Vec<Vec<PathBuf>>,
    /// Poses CSV: `image`, then `x_mm,y_mm,z_mm,qw,qx,qy,qz` (T_base_flange) or joints `q1_<unit>...`
    /// (with --robot), optional `split` (train/test).
    #[arg(long, required = true)]
    pub poses: Option<PathBuf>,
    /// The target, e.g. `chessboard:9x6:25mm`; default: the `# pattern:` line that `ferrocal
    /// import` wrote into the poses table.
    #[arg(long)]
    pub pattern: Option<String>,
    /// Where the camera is: `eye-in-hand` or `eye-to-hand`; default: the poses table's
    /// `# mount:` line (written by `import`).
    #[arg(long)]
    pub mount: Option<Mount>,
    /// Robot model (preset, URDF or TOML) for joint readings.
    #[arg(long)]
    pub robot: Option<String>,
    /// Camera file to hold fixed (camera calibrate JSON, OpenCV or ROS YAML); without it the
    /// camera is calibrated from the training images and refined with the chain. With a rig:
    /// once per camera, in the order of --images, or not at all; OpenCV files' R, T (those of
    /// --rig-out) start the joint adjustment's T_camk_cam0 and are compared with the fit.
    #[arg(long)]
    pub intrinsics: Vec<PathBuf>,
    /// Write the JSON result here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write an HTML report here.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Write the fit's inputs here as JSON: the target points, and per image its split, the
    /// robot pose and the detected corners with their point ids (for running other tools on
    /// the same corners and split, e.g. scripts/handeye_peers.py).
    #[arg(long, value_name = "FILE.json")]
    pub corners_out: Option<PathBuf>,
    /// Fit the printed target's overall scale against the robot's metric poses: the default
    /// without --out; with --out (the joint adjustment) only when given.
    #[arg(long, conflicts_with = "nominal_target_scale")]
    pub target_scale: bool,
    /// Hold the target at its nominal spacing instead of fitting its print scale.
    #[arg(long)]
    pub nominal_target_scale: bool,
    /// Take the target flat and the lens model as given, without trying its bending, its
    /// x-against-y print scale and other lens models (each rig camera's) on the training images
    /// (docs/handeye.md).
    #[arg(long)]
    pub no_physics: bool,
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
    /// Write every camera's file into this folder: `cam<k>.yaml` (OpenCV FileStorage:
    /// camera_matrix, distortion_coefficients and, for camera k > 0, R and T of T_camk_cam0 as
    /// OpenCV's stereoCalibrate names them, T in metres) and `cam<k>_camera_info.yaml` (ROS).
    #[arg(long, value_name = "DIR")]
    pub rig_out: Option<PathBuf>,
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
    /// Where the camera is: `eye-in-hand` or `eye-to-hand`.
    #[arg(long)]
    pub mount: Mount,
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
    /// Cameras: 2 writes a rig recording of the ur5 cell: eye-to-hand the rig study's two fixed
    /// cameras, eye-in-hand a stereo head on the flange; each camera's images in cam<k>/images
    /// named after the poses table's rows, its true camera in cam<k>/camera.yaml, the true
    /// T_camk_cam0 in truth.json.
    #[arg(long, default_value_t = 1)]
    pub cameras: usize,
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

/// Runs `ferrocal handeye` (or its study).
pub fn run(a: &HandeyeArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    match &a.command {
        Some(HandeyeCommand::Study(s)) => return run_study(s, vs),
        Some(HandeyeCommand::Simulate(s)) => return run_simulate(s, vs),
        None => {}
    }
    let Some(poses_path) = &a.poses else { bail!("handeye: --poses is required") };
    // --pattern and --mount default to what `import` wrote into the table's header.
    let warn = |w: &str| eprintln!("ferrocal handeye: warning: {w}");
    let (pattern_text, mount) =
        read_poses_header(poses_path)?.resolve(a.pattern.clone(), a.mount, poses_path, &warn)?;
    let files = HandeyeFiles {
        json: a.json.as_deref(),
        report: a.report.as_deref(),
        out: a.out.as_deref(),
        corners: a.corners_out.as_deref(),
    };
    let groups = if a.image_groups.is_empty() { vec![a.images.clone()] } else { a.image_groups.clone() };
    let flat: Vec<PathBuf> = groups.iter().flatten().cloned().collect();
    let mut inputs = run_inputs(poses_path, None, a.robot.as_deref(), &flat);
    inputs.extend(a.observations.as_deref());
    inputs.extend(a.intrinsics.iter().map(PathBuf::as_path));
    let rig_paths = a.rig_out.as_deref().map(|d| rig_file_paths(d, groups.len())).unwrap_or_default();
    let mut outputs = files.all();
    outputs.extend(rig_paths.iter().map(PathBuf::as_path));
    ferrocal_report::check_outputs(&outputs, &inputs)?;
    if groups.len() == 1 && a.intrinsics.len() > 1 {
        bail!("handeye: --intrinsics given {} times for one camera (one --images)", a.intrinsics.len());
    }
    let run = HandEyeRunOptions {
        images: groups[0].clone(),
        poses: poses_path.clone(),
        pattern: pattern_text,
        mount,
        robot: a.robot.clone(),
        intrinsics: a.intrinsics.first().cloned(),
        // The print scale is fitted unless asked not to: printed targets are rarely at their
        // nominal spacing and the robot's metric poses determine it (docs/handeye.md). Not with
        // the joint adjustment (--out) unless asked: there the flange poses come from the nominal
        // robot, whose length errors a free scale would take up, and the adjustment holds the
        // scale of its start.
        fit_target_scale: a.target_scale || (!a.nominal_target_scale && a.out.is_none()),
        huber_sigmas: a.loss.as_deref().map_or(Ok(a.huber), huber_sigmas_of_loss)?,
        robot_poses_as_measurements: a.robot_poses_as_measurements,
        robot_sigma_mm_deg: a.robot_sigma_mm.zip(a.robot_sigma_deg),
        exact_robot_poses: a.exact_robot_poses,
        physics: !a.no_physics,
        observations: match &a.observations {
            Some(f) => Some((
                f.clone(),
                a.image_size.as_deref().map(ferrocal_datasets::import::observations::parse_image_size).transpose()?,
            )),
            None => None,
        },
    };
    if a.observations.is_some() && a.rig_out.is_some() {
        bail!("handeye: --observations takes one camera's detections; a rig (--rig-out) needs --images per camera");
    }
    if groups.len() > 1 || a.rig_out.is_some() {
        return run_rig(a, vs, &run, &groups, &RigFiles { handeye: files, rig_out: a.rig_out.as_deref() });
    }
    let mut input = HandEyeInput::load(&run)?;
    let options = run.hand_eye_options()?;
    // The robot's motions against the camera's before the fit: a recording that disagrees is
    // refused with the likely cause; an image far off is named (and left out when clearly so).
    let (motion, start) = input.check_motion(&options)?;
    for w in &motion.warnings {
        eprintln!("ferrocal handeye: warning: {w}");
    }
    let motion_check = verdict::motion_check(motion);
    for s in input.skipped_lines() {
        eprintln!("ferrocal: skipped {s}");
    }
    let physics = run.physics.then(PhysicsOptions::default);
    if physics.is_some() {
        tell!("handeye: trying the target's bending, print scale and lens models on the training images (--no-physics skips)");
    }
    let fit = input.fit_with_physics(options, start, physics.as_ref())?;
    let joint = (a.out.is_some() && a.robot.is_some()).then(|| input.joint_adjustment(&fit)).transpose()?;
    let flags = verdict::RunFlags::of(&run);
    let verdict = present_run(&vs.thresholds, &input, &fit, joint.as_ref(), motion_check, a.out.as_deref(), flags);
    // Every output is composed first and all are written together at the end: a failing joint
    // adjustment leaves no summary or report of half a run.
    handeye_outputs(&run, &input, &fit, joint.as_ref(), &verdict, &files)?.write()?;
    Ok(vs.conclude(&verdict))
}

/// `ferrocal handeye` with a rig of cameras (`--images` given once per camera), or one camera
/// with `--rig-out`: each camera's hand-eye fit, the rig transforms, with `--robot` and `--out`
/// the joint adjustment of the robot and every camera ([`RigInput`]).
fn run_rig(
    a: &HandeyeArgs,
    vs: &VerdictSettings,
    run: &HandEyeRunOptions,
    cameras: &[Vec<PathBuf>],
    files: &RigFiles,
) -> Result<ExitCode> {
    let mut rig = RigInput::load(run, cameras, &a.intrinsics)?;
    let fit = rig.fit_with_physics(run.physics.then(PhysicsOptions::default).as_ref())?;
    let joint = (a.out.is_some() && a.robot.is_some()).then(|| rig.joint_adjustment(&fit)).transpose()?;
    let verdict = present_rig(&vs.thresholds, &rig, &fit, joint.as_ref(), a.out.as_deref());
    // Composed first, written together: a failing joint adjustment leaves no half of a run.
    rig_outputs(&rig, &fit, joint.as_ref(), &verdict, files)?.write()?;
    Ok(vs.conclude(&verdict))
}

fn run_simulate(s: &SimulateArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    check_simulated_images(s.train, s.test)?;
    // Written aside and moved into place: a run that is stopped leaves no folder of images
    // without its poses.csv.
    ferrocal_report::StagedFolder::check(&s.out, false)?;
    let staged = ferrocal_report::StagedFolder::create(&s.out)?;
    let counts = (s.train, s.test, s.seed);
    let written = write_simulated_recording(s.mount, s.robot.as_deref(), s.cameras, counts, staged.path(), &s.out)?;
    tell!("{written}");
    staged.commit()?;
    if s.cameras > 1 {
        let counts = [("poses", s.train + s.test)];
        let next = format!(
            "calibrate the rig with its robot: ferrocal handeye --images {dir}/cam0/images --images {dir}/cam1/images --poses {dir}/poses.csv --robot ur5 --pattern <truth.json's pattern> --mount {mount} --out <calibration.json> --rig-out <folder>",
            dir = s.out.display(),
            mount = s.mount.name()
        );
        return Ok(vs.conclude(&ferrocal_calib::verdict::commands::simulated("handeye", &counts, &next)));
    }
    let counts = [("images", s.train + s.test)];
    let next = format!(
        "calibrate from it: ferrocal handeye --images {dir}/images --poses {dir}/poses.csv --pattern <truth.json's pattern> --mount {mount} --intrinsics {dir}/camera.yaml",
        dir = s.out.display(),
        mount = s.mount.name()
    );
    Ok(vs.conclude(&ferrocal_calib::verdict::commands::simulated("handeye", &counts, &next)))
}

fn run_study(s: &StudyArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    if s.simulations == 0 {
        bail!("handeye study: --simulations must be at least 1");
    }
    let mode =
        ferrocal_datasets::handeye::StudyMode { free_intrinsics: s.free_intrinsics, estimate_noise: s.estimate_noise };
    let rows = coverage_study(s.simulations, s.seed, mode, &|k, n| {
        if k % 20 == 0 || k == n {
            tell!("handeye study: {k}/{n} simulations");
        }
    });
    for r in &rows {
        say!("{}", ferrocal_report::handeye::coverage_line(r));
    }
    let v = ferrocal_report::handeye::study_verdict(&vs.thresholds, &rows);
    let json = || study_json(s.simulations, s.seed, mode, &rows);
    ferrocal_report::Outputs::verdict_json(s.json.as_deref(), json, &v)?.write()?;
    // A failed check exits 2, the studies' documented status (0 with --keep).
    Ok(vs.conclude_with(&v, ExitCode::SUCCESS, 2))
}
