//! `ferrocal correct`: the arguments of the `correct` workflow
//! ([`ferrocal_datasets::correct`]), its outputs and its verdict
//! ([`ferrocal_report::compensate::correct_verdict`]).

use ferrocal_report::say;
use std::path::Path;
use std::process::ExitCode;

use anyhow::Result;
use ferrocal_datasets::correct::{correct_run, program_header, ProgramFormat};
use ferrocal_report::verdict::VerdictSettings;

/// `ferrocal correct`.
#[derive(Debug, clap::Args)]
pub struct CorrectArgs {
    /// Robot model (preset, URDF or TOML): the nominal model the program was written for.
    #[arg(long)]
    pub robot: String,
    /// The calibration (`ferrocal calibrate --out`, `diagnose --out`).
    #[arg(long)]
    pub calibration: std::path::PathBuf,
    /// The program's joint commands: `pose_id`, `q1_<u>` ... (rad, deg, m, mm), optionally the
    /// conditions the effects see (`dir<i>`, `temp_c`, `payload_kg`, `t_s`) and `motion` (`joint`
    /// or `linear` per command; joint without the column).
    #[arg(long)]
    pub program: std::path::PathBuf,
    /// The corrected commands (CSV, the program's joint units), with per pose the error the
    /// correction removes and what remains under the calibrated model.
    #[arg(long)]
    pub out: std::path::PathBuf,
    /// Match positions only (the smallest joint change that does), not orientations.
    #[arg(long)]
    pub positions_only: bool,
    /// Also write the corrected program as an ABB RAPID module (`MoveAbsJ` per command, named by
    /// its pose id).
    #[arg(long, value_name = "FILE.mod")]
    pub rapid: Option<std::path::PathBuf>,
    /// Also write it as G-code (one axis letter per joint, `G1` per command).
    #[arg(long, value_name = "FILE.ngc")]
    pub gcode: Option<std::path::PathBuf>,
    /// Also write it as a Universal Robots URScript (`movej` per command, `movel` where the
    /// program asks for a linear move; six revolute joints).
    #[arg(long, value_name = "FILE.script")]
    pub urscript: Option<std::path::PathBuf>,
    /// Also write it as a KUKA KRL program (`PTP {AXIS: ..}` per command); the `DEF` name is the
    /// file's stem.
    #[arg(long, value_name = "FILE.src")]
    pub krl: Option<std::path::PathBuf>,
    /// Wait at every command of the written programs, seconds (0: move on once in position).
    #[arg(long, default_value_t = 0.0)]
    pub dwell_s: f64,
}

/// Runs `ferrocal correct`: every command is corrected through the calibrated model so that it
/// reaches the pose the nominal model meant; a command that cannot be corrected is an error
/// naming its pose id and line, and nothing is written.
pub fn run(a: &CorrectArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    // The robot programs asked for; every output is checked before any work (two outputs on
    // one path, or an output that names an input, are refused), all are composed, then written
    // together.
    let outputs = ProgramFormat::asked(a.rapid.as_deref(), a.gcode.as_deref(), a.urscript.as_deref(), a.krl.as_deref());
    let all_outputs: Vec<&Path> = std::iter::once(a.out.as_path()).chain(outputs.iter().map(|(_, p)| *p)).collect();
    ferrocal_report::check_outputs(&all_outputs, &[a.program.as_path(), a.calibration.as_path(), Path::new(&a.robot)])?;
    let run = correct_run(&a.robot, &a.calibration, &a.program, a.positions_only)?;
    let header = program_header(&a.program, &a.calibration, &a.robot, &ferrocal_report::report::now_rfc3339());
    let programs = run.programs(&outputs, a.dwell_s, &header)?;
    let mut files = ferrocal_report::Outputs::default();
    files.text(&a.out, run.csv.as_str());
    programs.iter().for_each(|(p, t)| files.text(p, t.as_str()));
    say!("{}", run.summary_line(&a.out));
    files.write()?;
    let linear_as_joint = run.linear_as_joint(&outputs);
    let verdict =
        ferrocal_report::compensate::correct_verdict(&vs.thresholds, &run, &a.out, &a.calibration, &linear_as_joint);
    Ok(vs.conclude(&verdict))
}
