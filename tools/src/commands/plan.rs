//! `ferrocal plan`: the arguments, and the flow of `ferrocal_report::plan` (plan file, workspace,
//! selection, predicted and simulated calibration, path, programs, report).

use ferrocal_report::{say, tell};
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use ferrocal_calib::design::criteria::Criterion;
use ferrocal_calib::verdict::commands as verdict;
use ferrocal_datasets::plan::{run_plan, PlanRequest};
use ferrocal_report::plan::{plan_line, plan_report, write_plan};
use ferrocal_report::verdict::failed_sections;

/// `ferrocal plan`.
#[derive(Debug, clap::Args)]
#[command(
    about = "Plan measurement poses: safe, measurable workspace, pose selection, predicted and simulated calibration, path and robot programs",
    long_about = "Runs the source's automated calibration flow on a plan file (TOML; see docs/plan-format.md and datasets/cells/plan_gantry_tau_l1.toml):\n\n  1. the workspace by grid search, cut by joint limits, spherical-joint limits, the workspace-edge margin and every obstacle box with its margin;\n  2. the measurable region: the whole target inside every image with large enough features and an acceptable viewing angle, line of sight free (or a tracker's range and line of sight);\n  3. the regular grid for the wanted count (spacing = (volume / wanted)^(1/3)) and a denser pool;\n  4. selection by the A, D, K or N criterion (greedy deletion, exchange), the sigma_max^2/sigma_min check and the predicted accuracy, adding poses while a check fails;\n  5. simulated calibrations (Monte Carlo) against the predicted parameter deviations;\n  6. a short, checked path through joint space and the programs.\n\nWrites into --out: poses.csv (the measurement poses in visiting order), path.csv (every step), grid_poses.csv (the source's regular grid), program.mod (ABB RAPID), program.ngc (G-code), session_plan.toml (a [plan] table for `ferrocal simulate`), index.html and report.json, written aside and moved into place together (an existing non-empty folder needs --force). Exits 0 when the plan passes its checks, 2 when it was written but a check failed (0 with --keep); the last stdout line is the verdict, also in report.json."
)]
pub struct PlanArgs {
    /// The plan file (TOML).
    #[arg(long)]
    pub plan: PathBuf,
    /// Folder for the poses, programs and report.
    #[arg(long)]
    pub out: PathBuf,
    /// Simulated calibrations of the Monte Carlo check (0: skip; the plan file's
    /// `[simulation] runs` by default). The study of the prediction uses 200.
    #[arg(long)]
    pub simulations: Option<usize>,
    /// Override the selection criterion (a, d, k, n, dressler).
    #[arg(long)]
    pub criterion: Option<Criterion>,
    /// Override the wanted number of poses.
    #[arg(long)]
    pub wanted: Option<usize>,
    /// Random subsets of the chosen size compared with the selection.
    #[arg(long, default_value_t = 1000)]
    pub random_subsets: usize,
    /// Override the seed of the random pool, subsets and simulations.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Replace --out when it exists and is not empty (the new folder is written aside and moved
    /// into place; without --force a non-empty folder is refused).
    #[arg(long)]
    pub force: bool,
}

/// Runs `ferrocal plan`.
pub fn run(args: &PlanArgs, vs: &ferrocal_report::verdict::VerdictSettings) -> Result<ExitCode> {
    let t0 = std::time::Instant::now();
    let log = |s: &str| tell!("[{:6.1} s] {s}", t0.elapsed().as_secs_f64());
    let request = PlanRequest {
        plan: args.plan.clone(),
        out: args.out.clone(),
        simulations: args.simulations,
        criterion: args.criterion,
        wanted: args.wanted,
        random_subsets: args.random_subsets,
        seed: args.seed,
        force: args.force,
    };
    // The run folder is written aside and moved into place at the end (a killed or failed plan
    // leaves no new file beside old ones): check it can be, before any work.
    ferrocal_report::StagedFolder::check(&args.out, args.force)?;
    let bars = crate::progress::Bars::default();
    let run = run_plan(&request, &log, &|k, n| bars.tick("simulated calibrations", k as u64, n as u64))?;
    say!("{}", plan_line(&run));
    // The plan's own checks (selection, sigma ratio, predicted accuracy, path) decide, as its
    // exit status always did; another failed section of the report (the Monte Carlo check of the
    // prediction on few runs) is a warning.
    let report = plan_report(&run);
    let html = args.out.join("index.html").display().to_string();
    let verdict = verdict::plan(&vs.thresholds, run.design.passed, &failed_sections(&report.to_json()), &html);
    write_plan(&run, report, &verdict)?;
    Ok(vs.conclude_with(&verdict, ExitCode::SUCCESS, 2))
}
