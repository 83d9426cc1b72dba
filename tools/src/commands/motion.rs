//! `ferrocal motion`: compliance dynamics and learning control on the simulated compliant axis
//! (Dressler ch. 6-7; docs/motion.md).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use ferrocal_report::motion::study_report;

/// `ferrocal motion`.
#[derive(Debug, clap::Args)]
pub struct MotionArgs {
    /// What to run.
    #[command(subcommand)]
    pub command: MotionCommand,
}

/// The subcommands of `ferrocal motion`.
#[derive(Debug, clap::Subcommand)]
pub enum MotionCommand {
    /// Identify the simulated compliant axis (black-box and physical models, validation on
    /// another record) and run learning control on actuator-side, tool-estimated, measured and
    /// Kalman-estimated tool errors; writes index.html and report.json. Exits 0 when every
    /// check passes, 2 when the report was written but a check failed.
    Study(StudyArgs),
    /// Identify the simulated compliant 3-DOF Gantry-Tau cell (all three drives excited at once;
    /// the physical model fitted and validated on another record) and run learning control on
    /// actuator-side, tool-estimated and measured errors; writes index.html and report.json.
    /// Exits 0 when every check passes, 2 when the report was written but a check failed.
    Cell(CellArgs),
}

/// `ferrocal motion cell`.
#[derive(Debug, clap::Args)]
pub struct CellArgs {
    /// Folder for index.html and report.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Seed of the excitation and the sensor noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Shorter identification records (20 s to fit, 10 s to validate, instead of 60 s and 30 s).
    #[arg(long)]
    pub quick: bool,
}

/// `ferrocal motion study`.
#[derive(Debug, clap::Args)]
pub struct StudyArgs {
    /// Folder for index.html and report.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Seed of the excitation and the sensor noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Also run learning control with a contact force of this size (N) that the encoder cannot
    /// see (0: skip).
    #[arg(long, default_value_t = 20.0)]
    pub contact_force_n: f64,
    /// Shorter records (20 s to fit, 10 s to validate, instead of 60 s and 30 s).
    #[arg(long)]
    pub quick: bool,
}

/// Runs `ferrocal motion`.
pub fn run(a: &MotionArgs) -> Result<ExitCode> {
    match &a.command {
        MotionCommand::Study(s) => run_study(s),
        MotionCommand::Cell(c) => run_cell(c),
    }
}

fn run_cell(a: &CellArgs) -> Result<ExitCode> {
    let t0 = std::time::Instant::now();
    let report = ferrocal_report::motion_cell::cell_report(a.seed, a.quick, &|s| {
        eprintln!("[{:6.1} s] {s}", t0.elapsed().as_secs_f64())
    })?;
    let html = report.write(&a.out)?;
    println!("wrote {} ({:.1} s)", html.display(), t0.elapsed().as_secs_f64());
    Ok(if report.failed() { ExitCode::from(2) } else { ExitCode::SUCCESS })
}

fn run_study(a: &StudyArgs) -> Result<ExitCode> {
    if !(a.contact_force_n >= 0.0 && a.contact_force_n <= 1000.0) {
        anyhow::bail!("--contact-force-n {} N: give a force from 0 to 1000 N", a.contact_force_n);
    }
    let t0 = std::time::Instant::now();
    let report =
        study_report(a.seed, a.quick, a.contact_force_n, &|s| eprintln!("[{:6.1} s] {s}", t0.elapsed().as_secs_f64()))?;
    let html = report.write(&a.out)?;
    println!("wrote {} ({:.1} s)", html.display(), t0.elapsed().as_secs_f64());
    Ok(if report.failed() { ExitCode::from(2) } else { ExitCode::SUCCESS })
}
