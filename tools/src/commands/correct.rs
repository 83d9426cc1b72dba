//! `ferrocal correct`: the arguments of the `correct` workflow
//! ([`ferrocal_datasets::correct`]), its outputs and its verdict
//! ([`ferrocal_report::compensate::correct_verdict`]).

use ferrocal_report::say;
use std::path::Path;
use std::process::ExitCode;

use anyhow::Result;
use ferrocal_datasets::correct::{correct_run, program_header, ProgramFormat, Wanted};
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
    /// The program's nominal joint commands: `pose_id`, `q1_<u>` ... (rad, deg, m, mm), each
    /// meaning the pose the nominal model gives it (read through the nominal frames stored in
    /// the calibration, the same for every program); optionally the conditions the effects see
    /// (`dir<i>`, `temp_c`, `payload_kg`, `t_s`) and `motion` (`joint` or `linear` per command;
    /// joint without the column).
    #[arg(long, required_unless_present = "targets", conflicts_with = "targets")]
    pub program: Option<std::path::PathBuf>,
    /// Wanted poses of the calibration's measured point in its device frame: `pose_id`, `x_<u>`,
    /// `y_<u>`, `z_<u>` (m or mm), optionally `qw, qx, qy, qz` (matched when the calibration
    /// measured orientations), joint columns `q1_<u>` ... as the start of the search (the
    /// solution branch), the conditions the effects see and `motion`.
    #[arg(long)]
    pub targets: Option<std::path::PathBuf>,
    /// The corrected commands (CSV: `pose_id`, `q<i>_deg` or `q<i>_mm`, the program's `motion`,
    /// the error the correction removes, what remains under the calibrated model, the landing
    /// uncertainty and how far the row lies outside the calibrated region). Rows that cannot be
    /// reached are left out and named.
    #[arg(long)]
    pub out: std::path::PathBuf,
    /// Also write a JSON report: every row with its command, landing uncertainty, extrapolation
    /// and singularity measure, the frames used and the verdict.
    #[arg(long)]
    pub json: Option<std::path::PathBuf>,
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

/// Runs `ferrocal correct`: every row is corrected on its own through the calibrated model so
/// that it reaches its wanted pose; a row that cannot be reached is named and left out, the
/// others are written.
pub fn run(a: &CorrectArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let wanted = match (&a.program, &a.targets) {
        (Some(p), None) => Wanted::Program(p),
        (None, Some(t)) => Wanted::Targets(t),
        _ => anyhow::bail!("give either --program (nominal joint commands) or --targets (wanted poses)"),
    };
    // The robot programs asked for; every output is checked before any work (two outputs on
    // one path, or an output that names an input, are refused), all are composed, then written
    // together.
    let outputs = ProgramFormat::asked(a.rapid.as_deref(), a.gcode.as_deref(), a.urscript.as_deref(), a.krl.as_deref());
    let all_outputs: Vec<&Path> =
        std::iter::once(a.out.as_path()).chain(a.json.as_deref()).chain(outputs.iter().map(|(_, p)| *p)).collect();
    ferrocal_report::check_outputs(&all_outputs, &[wanted.path(), a.calibration.as_path(), Path::new(&a.robot)])?;
    let run = correct_run(&a.robot, &a.calibration, wanted, a.positions_only)?;
    let header = program_header(wanted.path(), &a.calibration, &a.robot, &ferrocal_report::report::now_rfc3339());
    let programs = run.programs(&outputs, a.dwell_s, &header)?;
    let linear_as_joint = run.linear_as_joint(&outputs);
    let verdict =
        ferrocal_report::compensate::correct_verdict(&vs.thresholds, &run, &a.out, &a.calibration, &linear_as_joint);
    let mut files = ferrocal_report::Outputs::default();
    files.text(&a.out, run.csv.as_str());
    programs.iter().for_each(|(p, t)| files.text(p, t.as_str()));
    if let Some(j) = &a.json {
        files.json_with_verdict(
            j,
            ferrocal_report::compensate::correct_json(&run, &a.calibration, wanted.path()),
            &verdict,
        )?;
    }
    for line in ferrocal_report::compensate::correct_lines(&run, &a.out) {
        say!("{line}");
    }
    files.write()?;
    Ok(vs.conclude(&verdict))
}
