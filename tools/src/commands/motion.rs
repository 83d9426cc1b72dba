//! `ferrocal motion`: compliance dynamics, learning control and lead-through on the simulated
//! compliant axis (Dressler ch. 6-8; docs/motion.md). `study` runs every experiment; `identify`,
//! `ilc`, `track` and `leadthrough` one each, with the same code and the same sections; `cell`
//! the compliant 3-DOF Gantry-Tau cell.

use ferrocal_report::tell;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use ferrocal_datasets::motion::leadthrough::{LeadSettings, SensorPlacement};
use ferrocal_datasets::motion::study::{check_contact_force, check_iterations};
use ferrocal_report::motion::{
    identify_report, ilc_report, leadthrough_report, study_report, track_report, IlcOptions,
};
use ferrocal_report::motion_cell::cell_report;
use ferrocal_report::verdict::VerdictSettings;

/// `ferrocal motion`.
#[derive(Debug, clap::Args)]
pub struct MotionArgs {
    /// What to run.
    #[command(subcommand)]
    pub command: MotionCommand,
}

/// The subcommands of `ferrocal motion`. Each writes index.html and report.json into `--out` and
/// exits 0 when every check passes, 2 when the report was written but a check failed.
#[derive(Debug, clap::Subcommand)]
pub enum MotionCommand {
    /// Every experiment: identification (black-box and physical models, validation on another
    /// record), vision tracking, learning control on actuator-side, tool-estimated, measured and
    /// Kalman-estimated tool errors, with and without a contact force, and lead-through.
    Study(StudyArgs),
    /// Chapter 6: identification of the axis (Bode plot, pole map, validation fits).
    Identify(IdentifyArgs),
    /// Chapter 7: learning control over trials, the four measurement cases, without and with a
    /// contact force the encoder cannot see.
    Ilc(IlcArgs),
    /// The camera tracking of the moving tool in rendered, motion-blurred frames.
    Track(TrackArgs),
    /// Chapter 8: lead-through with tool force feedback, a guided move and the stability map.
    Leadthrough(LeadthroughArgs),
    /// The compliant 3-DOF Gantry-Tau cell: all three drives excited at once, the physical model
    /// fitted and validated on another record, and learning control on actuator-side,
    /// tool-estimated and measured errors and on rendered, motion-blurred camera frames.
    Cell(CellArgs),
}

/// Options every experiment has.
#[derive(Debug, clap::Args)]
pub struct CommonArgs {
    /// Folder for index.html and report.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Seed of the excitation and the sensor noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// `ferrocal motion study`.
#[derive(Debug, clap::Args)]
pub struct StudyArgs {
    #[command(flatten)]
    pub common: CommonArgs,
    /// Also run learning control with a contact force of this size (N) that the encoder cannot
    /// see (0: skip).
    #[arg(long, default_value_t = 20.0)]
    pub contact_force_n: f64,
    /// Shorter records (20 s to fit, 10 s to validate, instead of 60 s and 30 s) and a smaller
    /// camera.
    #[arg(long)]
    pub quick: bool,
}

/// `ferrocal motion identify`.
#[derive(Debug, clap::Args)]
pub struct IdentifyArgs {
    #[command(flatten)]
    pub common: CommonArgs,
    /// Shorter records (20 s to fit, 10 s to validate, instead of 60 s and 30 s).
    #[arg(long)]
    pub quick: bool,
}

/// `ferrocal motion ilc`.
#[derive(Debug, clap::Args)]
pub struct IlcArgs {
    #[command(flatten)]
    pub common: CommonArgs,
    /// Also run learning control with a contact force of this size (N) that the encoder cannot
    /// see (0: skip).
    #[arg(long, default_value_t = 20.0)]
    pub contact_force_n: f64,
    /// Trials after the first (1 to 50).
    #[arg(long, default_value_t = 10)]
    pub iterations: usize,
    /// Identify the learning matrices' models from shorter records (20 s and 10 s).
    #[arg(long)]
    pub quick: bool,
}

/// `ferrocal motion cell`.
#[derive(Debug, clap::Args)]
pub struct CellArgs {
    #[command(flatten)]
    pub common: CommonArgs,
    /// Shorter identification records (20 s to fit, 10 s to validate, instead of 60 s and 30 s).
    #[arg(long)]
    pub quick: bool,
}

/// `ferrocal motion track`.
#[derive(Debug, clap::Args)]
pub struct TrackArgs {
    #[command(flatten)]
    pub common: CommonArgs,
    /// A 640 x 400 camera 0.6 m from the board instead of the 1280 x 800 one at 0.9 m.
    #[arg(long)]
    pub quick: bool,
}

/// `ferrocal motion leadthrough`.
#[derive(Debug, clap::Args)]
pub struct LeadthroughArgs {
    #[command(flatten)]
    pub common: CommonArgs,
    /// Admittance damping of the guided move, N s/m (1 N moves the axis at 1 / D_a m/s).
    #[arg(long, default_value_t = LeadSettings::default().admittance_n_s_m)]
    pub admittance_n_s_m: f64,
    /// Cut-off of the force low-pass, Hz (0: no filter).
    #[arg(long, default_value_t = LeadSettings::default().force_cutoff_hz)]
    pub force_cutoff_hz: f64,
    /// Force-sensor noise, N.
    #[arg(long, default_value_t = LeadSettings::default().sensor_sigma_n)]
    pub sensor_sigma_n: f64,
    /// Where the force sensor of the guided move and the stability map sits (the report
    /// compares all three either way): `tool` (between the hand and the tool), `carriage` (between the carriage and the links;
    /// it also reads the structure's inertial forces) or `carriage-compensated` (at the
    /// carriage, the rigid-body inertia added back from the encoder).
    #[arg(long, default_value = "tool", value_parser = crate::cli::choice::<SensorPlacement>)]
    pub sensor: SensorPlacement,
}

/// Runs `ferrocal motion`.
pub fn run(a: &MotionArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let t0 = std::time::Instant::now();
    let progress = |s: &str| tell!("[{:6.1} s] {s}", t0.elapsed().as_secs_f64());
    let (report, common) = match &a.command {
        MotionCommand::Study(s) => {
            check_contact_force(s.contact_force_n)?;
            (study_report(s.common.seed, s.quick, s.contact_force_n, &progress)?, &s.common)
        }
        MotionCommand::Identify(s) => (identify_report(s.common.seed, s.quick, &progress)?, &s.common),
        MotionCommand::Ilc(s) => {
            check_contact_force(s.contact_force_n)?;
            check_iterations(s.iterations)?;
            let o = IlcOptions { contact_force_n: s.contact_force_n, iterations: s.iterations };
            (ilc_report(s.common.seed, s.quick, &o, &progress)?, &s.common)
        }
        MotionCommand::Track(s) => (track_report(s.common.seed, s.quick, &progress)?, &s.common),
        MotionCommand::Leadthrough(s) => {
            // Each flag checked by name.
            let (damping, cutoff, noise) = (s.admittance_n_s_m, s.force_cutoff_hz, s.sensor_sigma_n);
            let l = LeadSettings::from_flags(damping, cutoff, noise, s.common.seed, s.sensor)?;
            (leadthrough_report(&l, &progress)?, &s.common)
        }
        MotionCommand::Cell(s) => (cell_report(s.common.seed, s.quick, &progress)?, &s.common),
    };
    super::finish_study(report, &common.out, t0, vs)
}
