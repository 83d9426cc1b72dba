//! `ferrocal demo`: the whole pipeline on the built-in example, as one HTML report.
//!
//! Each stage of the project adds a section (`ferrocal_report::demo`, with the checks of
//! `ferrocal_datasets::checks`): the external libraries, the robot models' self-checks, the UR5
//! preset against a real laser-tracker recording, the safety zones, the simulated cell (rendered
//! images measured by the real detector), calibration from the tracker and from the cameras, the
//! UR5 and UR10 calibrated from real tracker data, the OpenCV sample cameras calibrated and
//! diagnosed, the pose planner, the UR5's missing physics found by `diagnose`, the force-sensor
//! and hexapod dynamics identification, and the elastostatic identification with compensation.
//! The sections that are commands of their own (camera, plan, diagnose) run here in-process, as
//! a user would call them. The report opens with a summary of every section's status; skipped
//! and reported sections are not counted as passing, and a failed check exits 2.

use ferrocal_report::{say, tell};
use std::process::ExitCode;

use anyhow::Result;
use ferrocal_report::demo::pipeline::{demo_report, written_line, DemoSettings};
use ferrocal_report::error::ReportError;
use ferrocal_report::verdict::VerdictSettings;
use ferrocal_report::Provenance;
use serde_json::json;

use crate::cli::DemoArgs;
use crate::progress::Bars;

/// Runs `ferrocal demo`.
pub fn run(args: &DemoArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let bars = Bars::default();
    let tick = |label: &str, pos: u64, len: u64| bars.tick(label, pos, len);
    let settings = json!({"samples": args.samples, "seed": args.seed, "data": args.data.display().to_string()});
    let prov = Provenance::new(settings);
    tell!("ferrocal demo -> {}", args.out.display());
    let d =
        DemoSettings { out: &args.out, data: &args.data, samples: args.samples, seed: args.seed, quick: args.quick };
    // The commands of their own run in-process; their error reaches the demo's as it reads.
    let run = |argv: &[String]| run_command(argv).map_err(|e| ReportError::msg(format!("{e:#}")));
    let report = demo_report(&d, prov, &tick, &run)?;
    say!("{}", written_line(&report, &args.out.join("index.html")));
    Ok(ferrocal_report::verdict::conclude_report(vs, report, &args.out, "demo")?)
}

/// Runs a `ferrocal` command in-process, as a user would call it.
fn run_command(argv: &[String]) -> Result<ExitCode> {
    let mut full = vec!["ferrocal".to_string()];
    full.extend(argv.iter().cloned());
    let cli = crate::cli::Cli::try_parse_grouped(&full).map_err(|e| anyhow::anyhow!("{e}"))?;
    super::run(cli)
}
