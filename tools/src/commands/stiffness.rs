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

use ferrocal_report::say;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use ferrocal_calib::verdict::commands as verdict;
use ferrocal_datasets::stiffsim::identify::identify_deflections;
use ferrocal_datasets::stiffsim::tables::simulated_deflections;
use ferrocal_report::stiffness::{
    complete_parameters, identify_lines, identify_report, study_report, trusted_parameters,
};
use ferrocal_report::verdict::VerdictSettings;
use ferrocal_report::Outputs;

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
    /// is not physical (its verdict fails; 0 with --keep) or the loads leave parameters
    /// unexcited (no estimate; 2 also with --keep).
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
        StiffnessCommand::Simulate(a) => run_simulate(a, vs),
        StiffnessCommand::Identify(a) => run_identify(a, vs),
    }
}

fn run_study(a: &StudyArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let t0 = std::time::Instant::now();
    let report = study_report(a.seed, a.trials, a.quick)?;
    super::finish_study(report, &a.out, t0, vs)
}

fn run_simulate(a: &SimulateArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let sim = simulated_deflections(a.seed, a.configurations)?;
    let (table, mut files) = (a.out.join("deflections.csv"), Outputs::default());
    files.text(&table, sim.csv.as_str());
    files.json(&a.out.join("truth.json"), &sim.truth)?;
    files.write()?;
    let next = format!("identify from it: ferrocal stiffness identify --measurements {}", table.display());
    Ok(vs.conclude(&verdict::simulated("stiffness", &[("measurements", sim.measurements)], &next)))
}

fn run_identify(a: &IdentifyArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let id = match identify_deflections(&a.model, &a.measurements, a.nu_threshold)? {
        Ok(id) => id,
        Err(e) => {
            // No estimate at all: exit status 2 with or without --keep (there is nothing to keep).
            eprintln!("error: {e}");
            println!("{}", verdict::stiffness_unexcited(&e.to_string()).line());
            return Ok(ExitCode::from(2));
        }
    };
    let (red, prior_red) = (&id.reduction, &id.prior);
    identify_lines(red, prior_red).iter().for_each(|l| say!("{l}"));
    if !red.physical_problems.is_empty() {
        eprintln!("error: the estimate is not physical: {}", red.physical_problems.join("; "));
        eprintln!("parameters that can be trusted: {}", trusted_parameters(red).join(", "));
    }
    let s0 = red.steps.last().map_or(red.fit.s0, |s| s.s0);
    let verdict = verdict::stiffness_identify(&vs.thresholds, &red.physical_problems, s0, red.param.len());
    if let Some(out) = &a.out {
        // The report, its JSON and the parameters are composed first and written together.
        let mut files = Outputs::default();
        let report = identify_report(&a.model, a.nu_threshold, &a.measurements, red, prior_red);
        files.report_folder(out, report, &verdict)?;
        files.json(&out.join("parameters.json"), &complete_parameters(&id.problem, red))?;
        files.write()?;
    }
    // A physical estimate exits 0; one that is not exits 2 (0 with --keep), as before.
    Ok(vs.conclude_with(&verdict, ExitCode::SUCCESS, 2))
}
