//! `ferrocal dynamics`: force-sensor model calibration of a hexapod end-effector (Friedrich &
//! Ihlenfeldt 2021) and dynamics identification of the hexapod (Abdellatif & Heimann 2009).
//!
//! - `study`: the sources' experiments on the simulator (`ferrocal_report::dynamics`);
//! - `simulate`: writes simulated leg, force and pose tables (`ferrocal_datasets::dynsim::tables`);
//! - `identify`: a model from synchronised leg-position and force streams (CSV);
//! - `identify-static`: a quasi-static model from averaged forces at poses (CSV).
//!
//! File formats: `docs/dynamics.md`, `ferrocal_datasets::formats::dynamics_tables`.

use ferrocal_report::{say, tell};
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use ferrocal_calib::verdict::commands::{self as verdict, LinearFitFigures};
use ferrocal_datasets::dynsim::identify::{identify_static, identify_streams, StreamIdentifyOptions};
use ferrocal_datasets::dynsim::tables::{simulated_tables, Rig, TableSettings};
use ferrocal_report::dynamics::{fit_json, print_fit, study_report};
use ferrocal_report::verdict::VerdictSettings;
use ferrocal_report::Outputs;
use serde_json::json;

/// `ferrocal dynamics`.
#[derive(Debug, clap::Args)]
#[command(
    about = "Force-sensor model calibration of a hexapod end-effector and hexapod dynamics identification",
    long_about = "Identification of the force-sensing end-effector's models 0 to 9 (mass, centre of gravity, inertia, sensor offsets, deformation terms) and of the hexapod's 10 rigid-body + 14 friction parameters, from quasi-static poses or from excitation trajectories.\n\nThe geometry is the project's: the `hexapod` preset and its force-sensor framework (docs/dynamics.md). File formats: docs/dynamics.md."
)]
pub struct DynamicsArgs {
    /// What to do.
    #[command(subcommand)]
    pub command: DynamicsCommand,
}

/// The subcommands of `ferrocal dynamics`.
#[derive(Debug, clap::Subcommand)]
pub enum DynamicsCommand {
    /// Run the sources' experiments on the simulator and write an HTML report beside the
    /// sources' numbers. Exits 0 when every check passes, 2 when the report was written but a
    /// check failed.
    Study(StudyArgs),
    /// Write simulated streams and pose tables (legs.csv, forces.csv, static.csv, truth.json).
    Simulate(SimulateArgs),
    /// Identify a dynamic model (6 to 9, or the hexapod) from leg-position and force streams.
    Identify(IdentifyArgs),
    /// Identify a quasi-static model (0 to 5) from averaged sensor forces at poses.
    IdentifyStatic(IdentifyStaticArgs),
}

/// `ferrocal dynamics study`.
#[derive(Debug, clap::Args)]
pub struct StudyArgs {
    /// Folder for index.html and report.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Repeated identifications of the D-optimal against the condition-number design (the
    /// source: 100).
    #[arg(long, default_value_t = 100)]
    pub repeats: usize,
    /// Seed of every simulation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Criterion evaluations of each trajectory optimisation.
    #[arg(long, default_value_t = 3000)]
    pub evaluations: usize,
    /// Smaller experiments (about 5 s instead of 35 s in release): 20 repeats, 500
    /// evaluations, one maximum-likelihood search.
    #[arg(long)]
    pub quick: bool,
}

/// `ferrocal dynamics simulate`.
#[derive(Debug, clap::Args)]
pub struct SimulateArgs {
    /// Folder for the tables.
    #[arg(long)]
    pub out: PathBuf,
    /// Which rig: `platform` (the force-sensing end-effector: sensor forces) or `hexapod`
    /// (actuator forces).
    #[arg(long, default_value = "platform", value_parser = crate::cli::choice::<Rig>)]
    pub rig: Rig,
    /// Extra payload on the end-effector (platform rig), kg, as the payload steps mount it.
    #[arg(long, default_value_t = 0.0)]
    pub payload_kg: f64,
    /// Periods of the 4 s excitation recorded.
    #[arg(long, default_value_t = 2)]
    pub periods: usize,
    /// Sample rate, Hz.
    #[arg(long, default_value_t = 200.0)]
    pub rate_hz: f64,
    /// Poses of the quasi-static table (platform rig).
    #[arg(long, default_value_t = 120)]
    pub poses: usize,
    /// Sensor cross-talk (platform rig), a fraction (e.g. 0.015): each sensor also reads this
    /// fraction of the next sensor's load and minus half of it of the previous one's.
    #[arg(long, default_value_t = 0.0)]
    pub crosstalk: f64,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// `ferrocal dynamics identify`.
#[derive(Debug, clap::Args)]
pub struct IdentifyArgs {
    /// Leg positions: `t_s,q1_m,...,q6_m`.
    #[arg(long)]
    pub legs: PathBuf,
    /// Forces: `t_s,f1_n,...,f6_n` (sensor forces for models 6 to 9, actuator forces for the
    /// hexapod), sampled with the legs.
    #[arg(long)]
    pub forces: PathBuf,
    /// The model: 6, 7, 8, 9 (force sensors) or `hexapod` (10 rigid-body + 14 friction).
    #[arg(long, default_value = "9")]
    pub model: String,
    /// Cutoff of the processing, Hz.
    #[arg(long, default_value_t = 2.5)]
    pub cutoff_hz: f64,
    /// Use time-domain processing (4th-order zero-phase Butterworth, central differences)
    /// instead of the DFT.
    #[arg(long)]
    pub time_domain: bool,
    /// Samples per excitation period: weights by the force covariance from the repeated
    /// periods (Gauss-Markov). Without it: unit weights.
    #[arg(long)]
    pub period_samples: Option<usize>,
    /// Write the result as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// `ferrocal dynamics identify-static`.
#[derive(Debug, clap::Args)]
pub struct IdentifyStaticArgs {
    /// Poses and averaged forces: `x_m,y_m,z_m,roll_rad,pitch_rad,yaw_rad,f1_n,...,f6_n`.
    #[arg(long)]
    pub poses: PathBuf,
    /// The model (0 to 5).
    #[arg(long, default_value_t = 5)]
    pub model: u8,
    /// Write the result as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Runs `ferrocal dynamics`.
pub fn run(args: &DynamicsArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    match &args.command {
        DynamicsCommand::Study(a) => run_study(a, vs),
        DynamicsCommand::Simulate(a) => run_simulate(a, vs),
        DynamicsCommand::Identify(a) => run_identify(a, vs),
        DynamicsCommand::IdentifyStatic(a) => run_identify_static(a, vs),
    }
}

fn run_identify(a: &IdentifyArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let (f, d) = identify_streams(&StreamIdentifyOptions {
        model: a.model.clone(),
        legs: a.legs.clone(),
        forces: a.forces.clone(),
        time_domain: a.time_domain,
        cutoff_hz: a.cutoff_hz,
        period_samples: a.period_samples,
    })?;
    say!("{} samples, {}", f.samples, d.label());
    print_fit(&f.fit);
    // With --period-samples the weights are the noise measured from the repeated periods, and
    // s0 is held against 1.
    let figures = LinearFitFigures::of(&f.fit, a.period_samples.is_some());
    let verdict = verdict::dynamics_identify(&vs.thresholds, &figures);
    let settings = json!({"model": a.model, "processing": d.label(), "samples": f.samples});
    Outputs::verdict_json(a.json.as_deref(), || fit_json(&f.fit, settings), &verdict)?.write()?;
    Ok(vs.conclude(&verdict))
}

fn run_identify_static(a: &IdentifyStaticArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let (m, n_poses, f) = identify_static(a.model, &a.poses)?;
    say!("{m}: {} from {n_poses} poses", m.description());
    print_fit(&f);
    let verdict = verdict::dynamics_identify(&vs.thresholds, &LinearFitFigures::of(&f, false));
    Outputs::verdict_json(a.json.as_deref(), || fit_json(&f, json!({"model": a.model, "poses": n_poses})), &verdict)?
        .write()?;
    Ok(vs.conclude(&verdict))
}

fn run_simulate(a: &SimulateArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let settings = TableSettings {
        rig: a.rig,
        payload_kg: a.payload_kg,
        periods: a.periods,
        rate_hz: a.rate_hz,
        poses: a.poses,
        seed: a.seed,
        crosstalk: a.crosstalk,
    };
    // Composed first (bounds checked before any allocation), then written together.
    let tables = simulated_tables(&settings)?;
    let mut files = Outputs::default();
    tables.iter().for_each(|(name, text)| files.text(&a.out.join(name), text.as_str()));
    files.write()?;
    let hexapod = a.rig == Rig::Hexapod;
    Ok(vs.conclude(&ferrocal_report::dynamics::simulate_verdict(&tables, &a.out, hexapod, a.periods, a.rate_hz)))
}

fn run_study(a: &StudyArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let (repeats, evaluations) =
        if a.quick { (a.repeats.min(20), a.evaluations.min(500)) } else { (a.repeats, a.evaluations) };
    let t0 = std::time::Instant::now();
    let report =
        study_report(a.seed, a.quick, repeats, evaluations, &|s| tell!("[{:6.1} s] {s}", t0.elapsed().as_secs_f64()))?;
    super::finish_study(report, &a.out, t0, vs)
}
