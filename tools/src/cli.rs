//! Argument definitions (help text, man page and completions come from here).

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

/// ferrocal: cameras and a printed pattern in place of a laser tracker. Measures end-effector
/// poses, plans safe measurement poses, calibrates robot models and explains what they miss.
#[derive(Debug, Parser)]
#[command(name = "ferrocal", version, about, long_about = None, propagate_version = true, after_help = VERDICT_HELP)]
pub struct Cli {
    /// Limits of the verdict line every command ends with, from this TOML file (only the keys
    /// to change; docs/verdicts.md lists every key and its default). An unknown key is refused.
    #[arg(long, global = true, value_name = "FILE.toml")]
    pub thresholds: Option<PathBuf>,
    /// Keep a result whose verdict is `fail`: exit 0 instead of 1 (its outputs are written either
    /// way, and stderr says that it failed its checks).
    #[arg(long, global = true)]
    pub keep: bool,
    /// Print only the verdict line on stdout (warnings and errors still go to stderr; no
    /// progress bars). The results are in the files written.
    #[arg(long, short = 'q', global = true, conflicts_with = "verbose")]
    pub quiet: bool,
    /// Print the internals behind a result as well (e.g. which parameters a calibration fixed
    /// and what each trades against, every identified parameter with its standard deviation).
    #[arg(long, short = 'v', global = true)]
    pub verbose: bool,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

impl Cli {
    /// Parses `args` as [`clap::Parser::try_parse_from`] does, and keeps `handeye --images` and
    /// `diagnose --images` grouped by occurrence (`--images cam0/ --images cam1/`: one group per
    /// camera of a rig or stereo pair),
    /// which the derived parser flattens.
    pub fn try_parse_grouped<I, T>(args: I) -> Result<Self, clap::Error>
    where
        I: IntoIterator<Item = T>,
        T: Into<std::ffi::OsString> + Clone,
    {
        use clap::{CommandFactory, FromArgMatches};
        let matches = Self::command().try_get_matches_from(args)?;
        let mut cli = Self::from_arg_matches(&matches).map_err(|e| e.format(&mut Self::command()))?;
        match (&mut cli.command, matches.subcommand()) {
            (Command::Handeye(h), Some(("handeye", m))) => h.image_groups = grouped(m),
            (Command::Diagnose(d), Some(("diagnose", m))) => d.image_groups = grouped(m),
            _ => {}
        }
        Ok(cli)
    }
}

/// A subcommand's `--images` grouped by occurrence (empty without any).
fn grouped<T: Clone + Send + Sync + 'static>(m: &clap::ArgMatches) -> Vec<Vec<T>> {
    let groups = m.try_get_occurrences::<T>("images").ok().flatten();
    groups.map(|g| g.map(|g| g.cloned().collect()).collect()).unwrap_or_default()
}

/// The verdict and the exit status, in `--help`.
const VERDICT_HELP: &str = "Every command that computes a result ends its output on stdout with one line \
`verdict: pass|warning|fail: <what was checked>; next: <the next step>` and writes the same as `verdict` \
in its JSON. Exit status: 0 on success (and on a `warning`); 1 when the command fails or its result's \
verdict is `fail` (the outputs are still written; `--keep` exits 0); 2 where a command documents it \
(`detect`: an image failed; `plan`, `demo`, `handeye study` and the studies: a check failed; `stiffness \
identify`: the estimate is not physical); 3 when `robot check` finds the joint values not safe (also with \
`--keep`). Limits: docs/verdicts.md, \
overridden with --thresholds FILE.toml.";

/// The commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run the whole pipeline on the built-in example and write an HTML report.
    Demo(DemoArgs),
    /// Check that every external library (OpenCV, AprilTag, kornia-rs, Ceres) is built and answers.
    Doctor,
    /// Robot models: information, forward and inverse kinematics, safety checks.
    #[command(subcommand)]
    Robot(RobotCommand),
    /// Detect chessboards, the Gantry-Tau plate, AprilTags and tag boards, with sub-pixel corners.
    Detect(crate::commands::detect::DetectArgs),
    /// Corner accuracy study on rendered images: this project, OpenCV cornerSubPix and
    /// findChessboardCornersSB, and the Cramer-Rao bound, at several blur and noise levels.
    CornerStudy(crate::commands::corner_study::CornerStudyArgs),
    /// Cameras: calibrate one camera or a stereo pair from images of a chessboard.
    #[command(subcommand)]
    Camera(crate::commands::camera::CameraCommand),
    /// Write a recorded session from a simulated cell (TOML): images, joints, tracker, truth.
    Simulate(crate::commands::simulate::SimulateArgs),
    /// Convert a real recording (UR5, UR10 laser-tracker sets) into the measurement table.
    Import(crate::commands::simulate::ImportArgs),
    /// Measure a recorded session with its cameras: the rig calibrated from its board views,
    /// one target pose with its 6 x 6 covariance per robot pose, written as a measurement table.
    Measure(crate::commands::simulate::MeasureArgs),
    /// Correct a program's joint commands through a calibration, so that the robot reaches the
    /// poses the nominal model meant.
    Correct(crate::commands::correct::CorrectArgs),
    /// Plan measurement poses: safe and measurable workspace, pose selection (A/D/K/N), predicted
    /// and simulated calibration, a checked path and robot programs (RAPID, CSV, G-code).
    Plan(crate::commands::plan::PlanArgs),
    /// Kinematic calibration from a measurement table (laser tracker, cameras, CMM).
    Calibrate(crate::commands::calibrate::CalibrateArgs),
    /// Find the physics a model leaves out: screen the residuals, test candidate effects
    /// (joint and link compliance, one joint at a time and on every loaded joint together,
    /// direction-dependent errors of either sign, scale, periodic, thermal; for cameras lens and
    /// target shape) on held-out data, report what passes.
    ///
    /// Sizes are evidence, not vetoes: an effect beyond the typical range of industrial arms
    /// (e.g. a 25 mrad sag) is claimed on strong held-out support and reported as UNUSUAL; only
    /// sizes where the effect's model means nothing are refused. A rejected candidate never
    /// explains another away, and the report's first line says why nothing was claimed when the
    /// residuals show strong structure (docs/diagnose.md).
    Diagnose(crate::commands::diagnose::DiagnoseArgs),
    /// Hand-eye calibration (camera on the flange or fixed), refined in pixels, with OpenCV beside.
    Handeye(crate::commands::handeye::HandeyeArgs),
    /// Predict a measurement table with a calibrated model and report the position errors.
    Evaluate(crate::commands::calibrate::EvaluateArgs),
    /// Export a calibration for other tools: the calibrated serial robot as a URDF and as a
    /// modified DH table.
    Export(crate::commands::calibrate::ExportArgs),
    /// Force-sensor models and dynamics of parallel machines: identification from quasi-static
    /// poses and excitation trajectories, experiment design, studies.
    Dynamics(crate::commands::dynamics::DynamicsArgs),
    /// Elastostatic (compliance) identification with practical identifiability and compensation.
    Stiffness(crate::commands::stiffness::StiffnessArgs),
    /// Compliance dynamics, tool estimation and learning control on a simulated compliant axis and
    /// 3-DOF Gantry-Tau cell (identification with validation, Bode plot, pole map, ILC over trials).
    Motion(crate::commands::motion::MotionArgs),
}

/// `ferrocal demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Folder for the report (index.html, report.json and data files).
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    /// Folder of the shared real recordings (parts of the demo use them when present).
    #[arg(long, default_value = "../shared/data")]
    pub data: PathBuf,
    /// Random configurations per model in the kinematics self-check.
    #[arg(long, default_value_t = 2000)]
    pub samples: usize,
    /// Seed of every random choice in the demo.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// A smaller simulated cell (fewer poses and board views): for tests and a first look.
    #[arg(long)]
    pub quick: bool,
}

/// `ferrocal robot ...`.
#[derive(Debug, Subcommand)]
pub enum RobotCommand {
    /// Joints, limits and the named parameter vector of a model.
    Info {
        /// A preset name (ur5, ur10, gantry-tau-l1, ...), a URDF file or a TOML model file.
        #[arg(long)]
        robot: String,
        /// Write the information as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Forward kinematics: the tool pose for joint values.
    Fk {
        /// A preset name, a URDF file or a TOML model file.
        #[arg(long)]
        robot: String,
        /// Joint values, comma-separated (degrees for revolute joints, mm for prismatic ones).
        #[arg(long, allow_hyphen_values = true)]
        joints: String,
        /// The link whose pose to report, of a URDF with several chains: the joint values are
        /// then every moving joint of the tree, in the URDF's order.
        #[arg(long)]
        tip: Option<String>,
    },
    /// Inverse kinematics: joint values for a tool pose.
    Ik {
        /// A preset name, a URDF file or a TOML model file.
        #[arg(long)]
        robot: String,
        /// Target `x,y,z` in mm, optionally followed by a rotation vector `rx,ry,rz` in degrees.
        #[arg(long, allow_hyphen_values = true)]
        pose: String,
        /// Start (and configuration choice), comma-separated joint values (deg / mm).
        #[arg(long, allow_hyphen_values = true)]
        seed: Option<String>,
    },
    /// Check joint values (and optionally a move to a second set) against a safety configuration.
    Check {
        /// A preset name, a URDF file or a TOML model file.
        #[arg(long)]
        robot: String,
        /// Safety configuration (TOML, the `[safety]` table or a bare file of its keys).
        #[arg(long)]
        safety: PathBuf,
        /// Joint values (deg / mm).
        #[arg(long, allow_hyphen_values = true)]
        joints: String,
        /// Joint values of the end of a straight joint-space move to check as well.
        #[arg(long, allow_hyphen_values = true)]
        to: Option<String>,
    },
}

/// A flag's value read by the library type's own (serde) name, `-` read as `_`
/// (`carriage-compensated`); the error lists the names it accepts, spelt with `-`.
pub fn choice<T: serde::de::DeserializeOwned>(s: &str) -> Result<T, String> {
    serde_json::from_value(serde_json::Value::String(s.replace('-', "_"))).map_err(|e| e.to_string().replace('_', "-"))
}

#[cfg(test)]
mod tests {
    use ferrocal_datasets::motion::leadthrough::SensorPlacement;

    #[test]
    fn flag_values_are_the_library_names_spelt_with_dashes() {
        let placement = super::choice::<SensorPlacement>("carriage-compensated");
        assert_eq!(placement, Ok(SensorPlacement::CarriageCompensated));
        assert_eq!(super::choice::<SensorPlacement>("carriage_compensated"), placement);
        let e = super::choice::<SensorPlacement>("hand").unwrap_err();
        assert!(e.contains("`hand`") && e.contains("`carriage-compensated`"), "{e}");
    }
}
