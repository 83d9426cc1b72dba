//! `ferrocal stiffness`: elastostatic identification of serial robots by the virtual joint
//! method with practical identifiability (Klimchik et al. 2015).
//!
//! - `study`: the source's one-link and 6-DOF studies on the simulator
//!   (`ferrocal_report::stiffness`);
//! - `simulate`: writes a deflection table of the simulated KR 270-like arm
//!   (`ferrocal_datasets::stiffsim::tables`);
//! - `identify`: the reduced compliance model from a table of joint angles, wrenches and measured
//!   deflections (`ferrocal_datasets::formats::deflections`), with the reduction table and the
//!   parameters that can be trusted.
//!
//! File format: `docs/stiffness.md`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use ferrocal_calib::stiffness::problem::LinearProblem;
use ferrocal_calib::stiffness::reduce::{reduce, ReductionSettings};
use ferrocal_calib::stiffness::StiffnessIdError;
use ferrocal_datasets::formats::deflections::{read_deflections, stiffness_model};
use ferrocal_datasets::stiffsim::tables::simulated_deflections;
use ferrocal_report::stiffness::{
    complete_parameters, identify_lines, identify_report, study_report, trusted_parameters,
};
use ferrocal_report::verdict::VerdictSettings;
use ferrocal_report::write_atomic;
use ferrocal_robot::stiffness::WrenchLimits;

/// `ferrocal stiffness`.
#[derive(Debug, clap::Args)]
#[command(
    about = "Elastostatic (compliance) identification with practical identifiability and compliance compensation",
    long_about = "The virtual joint model of a serial arm (compliant joints, a 6x6 compliance matrix per link, a gravity compensator), its identification from deflections measured under loads, the source's model reduction (symmetry, sparsity templates, aggregation, SVD partition, coupled groups, parameter-to-noise threshold) and compensation of a task load by the mirror method.\n\nFile format and method: docs/stiffness.md."
)]
pub struct StiffnessArgs {
    /// What to do.
    #[command(subcommand)]
    pub command: StiffnessCommand,
}

/// The subcommands of `ferrocal stiffness`.
#[derive(Debug, clap::Subcommand)]
pub enum StiffnessCommand {
    /// Run the source's one-link and 6-DOF studies on the simulator and write an HTML report
    /// beside the source's numbers. Exits 0 when every check passes, 2 when the report was
    /// written but a check failed.
    Study(StudyArgs),
    /// Write a simulated deflection table of the KR 270-like arm (deflections.csv) and its true
    /// compliances (truth.json).
    Simulate(SimulateArgs),
    /// Identify the reduced compliance model from a deflection table. Exits 2 when the estimate
    /// is not physical or the loads leave parameters unexcited.
    Identify(IdentifyArgs),
}

/// `ferrocal stiffness study`.
#[derive(Debug, clap::Args)]
pub struct StudyArgs {
    /// Folder for index.html and report.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Seed of every simulation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulated one-link experiments.
    #[arg(long, default_value_t = 100)]
    pub trials: usize,
    /// Smaller 6-DOF experiment.
    #[arg(long)]
    pub quick: bool,
}

/// `ferrocal stiffness simulate`.
#[derive(Debug, clap::Args)]
pub struct SimulateArgs {
    /// Folder for deflections.csv and truth.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Configurations (each measured without payload, with 150 kg and with 270 kg).
    #[arg(long, default_value_t = 30)]
    pub configurations: usize,
}

/// `ferrocal stiffness identify`.
#[derive(Debug, clap::Args)]
pub struct IdentifyArgs {
    /// The deflection table (CSV, docs/stiffness.md).
    #[arg(long)]
    pub measurements: PathBuf,
    /// The stiffness model: a stiffness preset with design estimates (kr270-like), or any serial
    /// robot (preset name, URDF, model file) with one spring per link and no design estimates.
    #[arg(long, default_value = "kr270-like")]
    pub model: String,
    /// Smallest parameter-to-noise ratio kept.
    #[arg(long, default_value_t = 2.0)]
    pub nu_threshold: f64,
    /// Folder for a report (index.html, report.json) and parameters.json.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Runs `ferrocal stiffness`.
pub fn run(args: &StiffnessArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    match &args.command {
        StiffnessCommand::Study(a) => run_study(a, vs),
        StiffnessCommand::Simulate(a) => run_simulate(a),
        StiffnessCommand::Identify(a) => run_identify(a),
    }
}

fn run_study(a: &StudyArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let t0 = std::time::Instant::now();
    let report = study_report(a.seed, a.trials, a.quick)?;
    let html = report.write(&a.out)?;
    println!("wrote {} ({:.1} s)", html.display(), t0.elapsed().as_secs_f64());
    Ok(ferrocal_report::verdict::conclude_report(vs, &a.out, "study")?)
}

fn run_simulate(a: &SimulateArgs) -> Result<ExitCode> {
    let sim = simulated_deflections(a.seed, a.configurations)?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("cannot create {}", a.out.display()))?;
    write_atomic(&a.out.join("deflections.csv"), sim.csv.as_bytes())?;
    write_atomic(&a.out.join("truth.json"), serde_json::to_string_pretty(&sim.truth)?.as_bytes())?;
    println!("wrote {} ({} measurements)", a.out.join("deflections.csv").display(), sim.measurements);
    Ok(ExitCode::SUCCESS)
}

fn run_identify(a: &IdentifyArgs) -> Result<ExitCode> {
    let (model, prior) = stiffness_model(&a.model)?;
    let limits = WrenchLimits::default();
    let obs = read_deflections(&a.measurements, &model, &limits)?;
    let problem = LinearProblem::from_observations(&model, &obs, &limits)?;
    let settings = ReductionSettings { nu_threshold: a.nu_threshold, ..ReductionSettings::default() };
    let red = match reduce(&problem, None, prior.as_deref(), &settings) {
        Ok(r) => r,
        Err(e @ StiffnessIdError::Unexcited { .. }) => {
            eprintln!("error: {e}");
            return Ok(ExitCode::from(2));
        }
        Err(e) => return Err(e.into()),
    };
    let prior_red = red.param.project(prior.as_deref().unwrap_or(&vec![0.0; problem.layout.len()]));
    identify_lines(&red, &prior_red).iter().for_each(|l| println!("{l}"));
    let ok = red.physical_problems.is_empty();
    if !ok {
        eprintln!("error: the estimate is not physical: {}", red.physical_problems.join("; "));
        eprintln!("parameters that can be trusted: {}", trusted_parameters(&red).join(", "));
    }
    if let Some(out) = &a.out {
        let html = identify_report(&a.model, a.nu_threshold, &a.measurements, &red, &prior_red).write(out)?;
        let params = complete_parameters(&problem, &red);
        write_atomic(&out.join("parameters.json"), serde_json::to_string_pretty(&params)?.as_bytes())?;
        println!("wrote {}", html.display());
    }
    Ok(if ok { ExitCode::SUCCESS } else { ExitCode::from(2) })
}
