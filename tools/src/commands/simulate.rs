//! `ferrocal simulate` and `ferrocal import`: recorded sessions from a simulated cell, and real
//! recordings converted into the measurement table.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use ferrocal_datasets::import::{self, LengthUnit, WriteOptions};
use ferrocal_datasets::sim::{simulate, CellConfig};
use ferrocal_robot::JointKind;

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

pub fn run_simulate(args: &SimulateArgs) -> Result<ExitCode> {
    let mut cfg = CellConfig::from_file(&args.config)?;
    if let Some(s) = args.seed {
        cfg.seed = s;
    }
    let pb = crate::progress::bar(1, "simulating poses");
    let manifest = simulate(&cfg, &args.out, args.force, |k, n| {
        pb.set_length(n as u64);
        pb.set_position(k as u64);
    })?;
    pb.finish_and_clear();
    eprintln!(
        "session written to {}: {} poses, {} camera(s){}{}",
        args.out.display(),
        manifest.n_poses,
        manifest.cameras.len(),
        if manifest.tracker.is_some() { ", laser tracker" } else { "" },
        if manifest.notes.is_empty() {
            String::new()
        } else {
            format!("; {} note(s) in manifest.json", manifest.notes.len())
        }
    );
    Ok(ExitCode::SUCCESS)
}

/// Which recording to import.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum ImportKind {
    /// `ur5_tracker/ur5_grid_train.csv` (measured = target + dif, joints in degrees).
    Ur5,
    /// `ur10_tracker/Series_*/measurements_*.csv` (semicolons, decimal commas; T-Mac positions
    /// and orientations in the tracker frame, temperature, time).
    Ur10,
    /// A measurement table (re-written in canonical units, checked on the way).
    Table,
    /// An industrial_calibration hand-eye set folder (cal_data.yaml, poses/) to a handeye poses CSV.
    IcHandeye,
    /// An industrial_calibration kinematic-calibration set (`measurements.yaml`: the target in a
    /// fixed camera's frame, the target chain's joints) to a measurement table.
    IcKinematic,
}

/// `ferrocal import`.
#[derive(Debug, Args)]
pub struct ImportArgs {
    /// What the input is.
    #[arg(value_enum)]
    pub kind: ImportKind,
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

pub fn run_import(args: &ImportArgs) -> Result<ExitCode> {
    let (set, kinds) = match args.kind {
        ImportKind::IcHandeye => {
            let cam = args.intrinsics_out.as_deref();
            return ferrocal_report::handeye::run_import_ic(&args.input, &args.out, args.test_every, cam);
        }
        ImportKind::IcKinematic => {
            let s = ferrocal_datasets::handeye::read_ic_kinematic(&args.input, args.test_every)?;
            if let Some(p) = &args.robot_out {
                ferrocal_datasets::handeye::ic_kinematic::write_ic_positioner_urdf(p, &args.input)?;
            }
            let n = s.n_joints();
            (s, vec![JointKind::Revolute; n])
        }
        ImportKind::Ur5 => {
            let s = import::import_ur5_grid(&args.input)?;
            let n = s.n_joints();
            (s, vec![JointKind::Revolute; n])
        }
        ImportKind::Ur10 => {
            let s = import::import_ur10_measurements(&args.input)?;
            let n = s.n_joints();
            (s, vec![JointKind::Revolute; n])
        }
        ImportKind::Table => {
            let t = import::read_measurements(&args.input)?;
            let k = t.joint_kinds();
            (t.set, k)
        }
    };
    let mut opts = WriteOptions::si(&kinds);
    if args.user_units {
        opts.joint_units = kinds
            .iter()
            .map(|k| match k {
                JointKind::Revolute => import::JointUnit::Deg,
                JointKind::Prismatic => import::JointUnit::Mm,
            })
            .collect();
    }
    opts.length_unit = LengthUnit::Mm;
    opts.comments = vec![format!("imported by ferrocal {} from {}", env!("CARGO_PKG_VERSION"), args.input.display())];
    import::write_measurements(&args.out, &set, &opts).with_context(|| format!("writing {}", args.out.display()))?;
    eprintln!("{} rows written to {}", set.rows.len(), args.out.display());
    Ok(ExitCode::SUCCESS)
}
