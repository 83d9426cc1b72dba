//! The `correct` workflow: a program's joint commands corrected through a calibration, so that
//! the calibrated robot reaches the poses the nominal model meant
//! ([`ferrocal_calib::kinematic::correct`]), as the corrected CSV and as robot programs.

use std::path::{Path, PathBuf};

use ferrocal_calib::kinematic::correct::{
    command_for_target, correct_program_row, effective_options, radius_68, CorrectOptions, CorrectedCommand,
    NominalFrames, Outside,
};
use ferrocal_calib::kinematic::CalibratedModel;
use ferrocal_calib::PoseMeasurement;
use ferrocal_robot::program::{gcode, krl, rapid_module, urscript, PathStep, PlannedPath, ProgramSettings, StepKind};
use ferrocal_robot::{JointKind, Kinematics, RobotModel};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use rayon::prelude::*;

use crate::error::{DatasetError, Result};
use crate::import::{read_joint_program, read_targets, JointUnit, MeasurementTable};

pub use ferrocal_calib::kinematic::correct::REACHED_M;

/// How a program moves to a command: the optional `motion` column of a joint program.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    /// Joint interpolation (`joint`, `j`, `movej`, `ptp`, `moveabsj`, `movej`): the default.
    Joint,
    /// Linear in the tool (`linear`, `l`, `movel`, `lin`).
    Linear,
}

impl Motion {
    /// The word written in the corrected CSV's `motion` column.
    pub fn word(self) -> &'static str {
        match self {
            Motion::Joint => "joint",
            Motion::Linear => "linear",
        }
    }

    /// Reads a `motion` cell (case-insensitive); `None` for a word it does not know.
    pub fn parse(cell: &str) -> Option<Self> {
        match cell.trim().to_ascii_lowercase().as_str() {
            "" | "joint" | "j" | "movej" | "ptp" | "moveabsj" | "movabsj" => Some(Motion::Joint),
            "linear" | "l" | "movel" | "lin" => Some(Motion::Linear),
            _ => None,
        }
    }
}

/// The motion of every row of a joint program (its `motion` column; joint without one), or an
/// error naming the file, line and word.
fn read_motions(program: &MeasurementTable, path: &Path) -> Result<Vec<Motion>> {
    program
        .set
        .rows
        .iter()
        .map(|r| match r.meta.get("motion") {
            None => Ok(Motion::Joint),
            Some(cell) => Motion::parse(cell).ok_or_else(|| {
                DatasetError::Input(format!(
                    "{}: line {}, column motion: '{}' is not a motion; use joint (movej, ptp) or linear (movel, lin)",
                    path.display(),
                    r.source_line.unwrap_or(0),
                    cell.trim()
                ))
            }),
        })
        .collect()
}

/// What `ferrocal correct` is asked to reach.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wanted<'a> {
    /// Nominal joint commands (`--program`): each means the pose the nominal model gives it.
    Program(&'a Path),
    /// Wanted poses of the measured point in the calibration's device frame (`--targets`).
    Targets(&'a Path),
}

impl Wanted<'_> {
    /// The file.
    pub fn path(&self) -> &Path {
        match self {
            Wanted::Program(p) | Wanted::Targets(p) => p,
        }
    }
}

/// One row of a corrected program.
#[derive(Clone, Debug)]
pub struct RowOutcome {
    /// The row's id.
    pub pose_id: String,
    /// Its line in the input file.
    pub line: Option<u64>,
    /// The command and what remains under the calibrated model.
    pub command: CorrectedCommand,
    /// Whether the row's orientation was matched (else its position only).
    pub orientation: bool,
    /// The radius that holds 68 % of the landing error (one standard deviation), mm, from the
    /// calibration's covariance and unexplained scatter; `None` when the file carries none.
    pub landing_sigma_mm: Option<f64>,
    /// How far the row lies outside the region the calibration's poses cover; `None` when the
    /// file does not say what it covers.
    pub outside: Option<Outside>,
    /// Why the row was not written, when it was not.
    pub unreached: Option<String>,
}

/// A corrected program.
#[derive(Clone, Debug)]
pub struct CorrectRun {
    /// The nominal robot model.
    pub model: RobotModel,
    /// The input as read (its rows with their conditions).
    pub program: MeasurementTable,
    /// Whether the input was a program or a list of targets.
    pub targets: bool,
    /// Per row, the outcome (in the input's order).
    pub rows: Vec<RowOutcome>,
    /// The corrected commands of the reached rows as CSV (`q<i>_deg` for revolute joints,
    /// `q<i>_mm` for prismatic ones), with per pose the error the correction removes, what
    /// remains under the calibrated model, the landing uncertainty and the extrapolation.
    pub csv: String,
    /// Per reached command, the error the correction removes, mm.
    pub removed_mm: Vec<f64>,
    /// The largest distance left from a wanted pose over the reached commands, mm.
    pub worst_residual_mm: f64,
    /// Per row, the motion the input asked for (its `motion` column; joint without one).
    pub motions: Vec<Motion>,
    /// The frames the nominal model's commands are read in.
    pub frames: NominalFrames,
    /// What the user should know about the inputs (a file without frames or covariance, an
    /// orientation the calibration cannot match).
    pub notes: Vec<String>,
}

impl CorrectRun {
    /// The rows that were written.
    pub fn reached(&self) -> impl Iterator<Item = (usize, &RowOutcome)> {
        self.rows.iter().enumerate().filter(|(_, r)| r.unreached.is_none())
    }

    /// The rows that were not written.
    pub fn unreached(&self) -> impl Iterator<Item = &RowOutcome> {
        self.rows.iter().filter(|r| r.unreached.is_some())
    }
}

/// Corrects every row of `wanted` for the robot `robot` (preset, URDF or TOML) through the
/// calibration file `calibration`, each row on its own: positions and orientations, or
/// positions only. A row that no command within the joint limits brings to its pose is named
/// and left out; the others are written.
pub fn correct_run(robot: &str, calibration: &Path, wanted: Wanted, positions_only: bool) -> Result<CorrectRun> {
    let model = RobotModel::load(robot)?;
    let (file, cm) = crate::calibration::read_calibration(robot, &model, calibration)?;
    let path = wanted.path();
    let program = match wanted {
        Wanted::Program(p) => read_joint_program(p)?,
        Wanted::Targets(p) => read_targets(p)?,
    };
    let targets = matches!(wanted, Wanted::Targets(_));
    let dof = Kinematics::dof(&model);
    if !targets || !program.joint_units.is_empty() {
        if program.joint_units.len() != dof {
            return Err(DatasetError::Input(format!(
                "{}: {} joint columns, but the robot model '{}' has {dof} joints",
                path.display(),
                program.joint_units.len(),
                model.name()
            )));
        }
        program.check_joint_kinds(&model.joint_kinds())?;
        // Readings in another unit (degrees under `_rad`) or beyond the limits are refused by row.
        let with_q: Vec<PoseMeasurement> = program.set.rows.iter().filter(|r| r.q.len() == dof).cloned().collect();
        let mut only = program.clone();
        only.set.rows = with_q;
        only.check_joint_values(&Kinematics::joint_limits(&model), model.name())?;
    }
    let motions = read_motions(&program, path)?;
    let mut notes = Vec::new();
    let frames = file.nominal_frames(&cm).map_err(|e| DatasetError::from(e).context("the nominal frames"))?;
    if file.nominal_frames.is_none() && !targets {
        notes.push(format!(
            "{} predates stored nominal frames: the program is read through frames fitted over a fixed sample of the joint space; recalibrate with this version to read it through the calibration's own poses",
            calibration.display()
        ));
    }
    if file.uncertainty.is_none() {
        notes.push(format!(
            "{} carries no covariance: the commands have no landing uncertainty; recalibrate with this version to get one",
            calibration.display()
        ));
    }
    if targets && !cm.orientation_calibrated && program.set.rows.iter().any(|r| r.orientation.is_some()) {
        notes.push(format!(
            "{} was calibrated from positions only: the targets' orientations are not matched, only their positions",
            calibration.display()
        ));
    }
    let base = CorrectOptions { use_orientation: !positions_only, ..CorrectOptions::default() };
    let rows: Vec<RowOutcome> = program
        .set
        .rows
        .par_iter()
        .map(|r| correct_row(&cm, &file, &frames, r, &base, targets))
        .collect::<Result<_>>()
        .map_err(|e| e.context(format!("correcting {}", path.display())))?;
    let units: Vec<JointUnit> = model
        .joint_kinds()
        .iter()
        .map(|k| match k {
            JointKind::Revolute => JointUnit::Deg,
            JointKind::Prismatic => JointUnit::Mm,
        })
        .collect();
    let has_motion = program.set.rows.iter().any(|r| r.meta.contains_key("motion"));
    let mut csv = format!("# corrected by ferrocal {} with {}\n", env!("CARGO_PKG_VERSION"), calibration.display());
    csv.push_str("pose_id");
    for (i, u) in units.iter().enumerate() {
        csv.push_str(&format!(",q{}_{}", i + 1, u.suffix()));
    }
    if has_motion {
        csv.push_str(",motion");
    }
    csv.push_str(
        ",removed_error_mm,residual_mm,landing_sigma_mm,outside_joint,outside_joint_by,outside_box_mm,sigma_min_m\n",
    );
    let mut removed_mm = Vec::new();
    let mut worst_residual_mm = 0.0f64;
    for (k, o) in rows.iter().enumerate().filter(|(_, o)| o.unreached.is_none()) {
        let c = &o.command;
        csv.push_str(&o.pose_id);
        for (v, u) in c.q.iter().zip(&units) {
            csv.push_str(&format!(",{}", u.from_si(*v)));
        }
        if has_motion {
            csv.push_str(&format!(",{}", motions[k].word()));
        }
        let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6}"));
        let (joint, by) = match o.outside.and_then(|x| x.joint) {
            Some((j, v)) => (j.to_string(), format!("{:.4}", units[j - 1].from_si(v))),
            None => ("0".into(), "0".into()),
        };
        csv.push_str(&format!(
            ",{},{:.6},{},{joint},{by},{},{:.6}\n",
            opt(c.nominal_error_m.is_finite().then_some(c.nominal_error_m * 1e3)),
            c.residual_m * 1e3,
            opt(o.landing_sigma_mm),
            opt(o.outside.map(|x| x.position_m * 1e3)),
            c.sigma_min
        ));
        removed_mm.push(c.nominal_error_m * 1e3);
        worst_residual_mm = worst_residual_mm.max(c.residual_m * 1e3);
    }
    Ok(CorrectRun { model, program, targets, rows, csv, removed_mm, worst_residual_mm, motions, frames, notes })
}

/// One row corrected: its wanted pose (the nominal model's for a program row, the row's own
/// for a target), its command, landing uncertainty and extrapolation.
fn correct_row(
    cm: &CalibratedModel,
    file: &ferrocal_calib::file::CalibrationFile,
    frames: &NominalFrames,
    r: &PoseMeasurement,
    base: &CorrectOptions,
    targets: bool,
) -> Result<RowOutcome> {
    let (command, orientation) = if targets {
        let opts = CorrectOptions {
            use_orientation: base.use_orientation && cm.orientation_calibrated && r.orientation.is_some(),
            ..*base
        };
        let want = Isometry3::from_parts(
            Translation3::from(r.position_m),
            r.orientation.unwrap_or_else(UnitQuaternion::identity),
        );
        (command_for_target(cm, frames, r, &want, &opts)?, opts.use_orientation)
    } else {
        let opts = effective_options(cm, base);
        (correct_program_row(cm, frames, r, &opts)?, opts.use_orientation)
    };
    let mut at = r.clone();
    at.q = command.q.clone();
    let landing_sigma_mm = match &file.uncertainty {
        Some(u) => Some(radius_68(&u.landing_covariance(cm, &at)?) * 1e3),
        None => None,
    };
    let outside = file.coverage.as_ref().map(|c| c.outside(&command.q, &command.intended.translation.vector));
    let unreached = (!command.reached()).then(|| {
        let limits = if command.at_limit.is_empty() {
            String::new()
        } else {
            format!(
                " with joint{} {} held at {} limit",
                if command.at_limit.len() > 1 { "s" } else { "" },
                command.at_limit.iter().map(|j| j.to_string()).collect::<Vec<_>>().join(", "),
                if command.at_limit.len() > 1 { "their" } else { "its" }
            )
        };
        format!(
            "no command within the joint limits reaches it ({:.4} mm remain{limits}; the search ends where the task Jacobian's smallest singular value is {:.2e} m)",
            command.residual_m * 1e3,
            command.sigma_min
        )
    });
    Ok(RowOutcome {
        pose_id: r.pose_id.clone(),
        line: r.source_line,
        command,
        orientation,
        landing_sigma_mm,
        outside,
        unreached,
    })
}

/// A robot program format the corrected commands can be written in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProgramFormat {
    /// ABB RAPID module (`MoveAbsJ` per command).
    Rapid,
    /// G-code (one axis letter per joint, `G1` per command).
    Gcode,
    /// Universal Robots URScript (`movej` per command).
    Urscript,
    /// KUKA KRL (`PTP {AXIS: ..}` per command).
    Krl,
}

impl ProgramFormat {
    /// The programs asked for, each with its file, in the order RAPID, G-code, URScript, KRL.
    pub fn asked<'a>(
        rapid: Option<&'a Path>,
        gcode: Option<&'a Path>,
        urscript: Option<&'a Path>,
        krl: Option<&'a Path>,
    ) -> Vec<(ProgramFormat, &'a Path)> {
        [(Self::Rapid, rapid), (Self::Gcode, gcode), (Self::Urscript, urscript), (Self::Krl, krl)]
            .into_iter()
            .filter_map(|(k, p)| p.map(|p| (k, p)))
            .collect()
    }
}

impl CorrectRun {
    /// The corrected commands as the robot programs `outputs` asks for (path, text): a motion
    /// program, one move per command in the program's order named by its pose id, joint or
    /// linear as the program's `motion` column asks (linear moves with joint interpolation where
    /// the language needs a Cartesian target for a linear move: RAPID, KRL; said in the line's
    /// comment), with its approach directions when the program has them, waiting `dwell_s` at
    /// each when it is above zero; `header`: the programs' comment lines. Each program's name is
    /// its file's stem.
    pub fn programs(
        &self,
        outputs: &[(ProgramFormat, &Path)],
        dwell_s: f64,
        header: &[String],
    ) -> Result<Vec<(PathBuf, String)>> {
        let rows = &self.program.set.rows;
        let steps: Vec<PathStep> = self
            .reached()
            .map(|(k, o)| PathStep {
                q: o.command.q.clone(),
                kind: match self.motions[k] {
                    Motion::Joint => StepKind::Move,
                    Motion::Linear => StepKind::MoveLinear,
                },
                pose: Some(k),
                dir: rows[k].dir.clone().unwrap_or_else(|| vec![0; o.command.q.len()]),
                label: Some(o.pose_id.clone()),
            })
            .collect();
        let steps_len = steps.len();
        let path = PlannedPath {
            order: (0..steps.len()).collect(),
            steps,
            dwell_s: dwell_s * steps_len as f64,
            ..PlannedPath::default()
        };
        let model = &self.model;
        let mut out = Vec::new();
        for &(kind, p) in outputs {
            let stem =
                p.file_stem().and_then(|s| s.to_str()).unwrap_or("ferrocal_corrected").replace(['-', '.', ' '], "_");
            let settings = ProgramSettings {
                rapid_module: stem.clone(),
                urscript_name: stem.clone(),
                krl_name: stem.clone(),
                ..ProgramSettings::default()
            };
            let text = match kind {
                ProgramFormat::Rapid => rapid_module(model, &path, dwell_s, &settings, header),
                ProgramFormat::Gcode => gcode(model, &path, dwell_s, &settings, header).map(|g| g.text),
                ProgramFormat::Urscript => urscript(model, &path, dwell_s, &settings, header),
                ProgramFormat::Krl => krl(model, &path, dwell_s, &settings, header),
            }
            .map_err(|e| DatasetError::from(e).context(format!("writing the corrected program {}", p.display())))?;
            out.push((p.to_path_buf(), text));
        }
        Ok(out)
    }
}

/// The comments that open the written programs: what corrected them and when (`now`), from
/// which program, calibration and robot, and what the commands are for.
pub fn program_header(program: &Path, calibration: &Path, robot: &str, now: &str) -> Vec<String> {
    vec![
        format!("corrected by ferrocal {} ({now})", env!("CARGO_PKG_VERSION")),
        format!("program {}; calibration {}; robot {robot}", program.display(), calibration.display()),
        "joint commands for the calibrated robot to reach the poses the nominal model meant; the path between them is not checked against safety zones".into(),
    ]
}

impl CorrectRun {
    /// The terminal line of the run written to `out`: the commands corrected and how far off the
    /// calibrated model predicts the uncorrected ones on average.
    pub fn summary_line(&self, out: &Path) -> String {
        format!(
            "{} commands corrected; the calibrated model predicts the uncorrected ones {:.4} mm off on average; written to {}",
            self.removed_mm.len(),
            self.mean_removed_mm(),
            out.display()
        )
    }

    /// The files of `outputs` whose language writes this program's linear moves with joint
    /// interpolation (RAPID, KRL; empty when the program has no linear move).
    pub fn linear_as_joint<'a>(&self, outputs: &[(ProgramFormat, &'a Path)]) -> Vec<&'a Path> {
        if !self.motions.contains(&Motion::Linear) {
            return Vec::new();
        }
        outputs
            .iter()
            .filter(|(k, _)| matches!(k, ProgramFormat::Rapid | ProgramFormat::Krl))
            .map(|(_, p)| *p)
            .collect()
    }

    /// The mean of the errors the correction removes, mm (0 without commands).
    pub fn mean_removed_mm(&self) -> f64 {
        let finite: Vec<f64> = self.removed_mm.iter().copied().filter(|v| v.is_finite()).collect();
        finite.iter().sum::<f64>() / finite.len().max(1) as f64
    }
}
