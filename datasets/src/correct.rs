//! The `correct` workflow: a program's joint commands corrected through a calibration, so that
//! the calibrated robot reaches the poses the nominal model meant
//! ([`ferrocal_calib::kinematic::correct`]), as the corrected CSV and as robot programs.

use std::path::{Path, PathBuf};

use ferrocal_calib::kinematic::correct::{correct_program, CorrectOptions, CorrectedCommand};
use ferrocal_robot::program::{gcode, krl, rapid_module, urscript, PathStep, PlannedPath, ProgramSettings, StepKind};
use ferrocal_robot::{Kinematics, RobotModel};

use crate::error::{DatasetError, Result};
use crate::import::{read_joint_program, MeasurementTable};

/// A command is corrected when the calibrated model reaches its intended pose within this, m.
pub const REACHED_M: f64 = 1e-6;

/// A corrected program.
#[derive(Clone, Debug)]
pub struct CorrectRun {
    /// The nominal robot model.
    pub model: RobotModel,
    /// The program as read (its joint units, its rows with their conditions).
    pub program: MeasurementTable,
    /// Per command, the corrected joints with the error removed and what remains.
    pub corrected: Vec<CorrectedCommand>,
    /// The corrected commands as CSV (the program's joint units), with per pose the error the
    /// correction removes and what remains under the calibrated model, mm.
    pub csv: String,
    /// Per command, the error the correction removes, mm.
    pub removed_mm: Vec<f64>,
    /// The largest distance left from an intended pose, mm.
    pub worst_residual_mm: f64,
    /// Per command, the motion the program asked for (its `motion` column; joint without one).
    pub motions: Vec<Motion>,
}

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

/// Corrects every command of the joint program `program` for the robot `robot` (preset, URDF or
/// TOML) through the calibration file `calibration`: positions and orientations, or positions
/// only. A command the calibrated model cannot reach is an error naming its pose id and line.
pub fn correct_run(robot: &str, calibration: &Path, program_path: &Path, positions_only: bool) -> Result<CorrectRun> {
    let model = RobotModel::load(robot)?;
    let cm = crate::calibration::apply_calibration(robot, &model, calibration)?;
    let program = read_joint_program(program_path)?;
    // Readings in another unit (degrees under `_rad`) or beyond the limits are refused by row.
    if program.joint_units.len() == Kinematics::dof(&model) {
        program.check_joint_values(&Kinematics::joint_limits(&model), model.name())?;
    }
    let motions = read_motions(&program, program_path)?;
    let has_motion = program.set.rows.iter().any(|r| r.meta.contains_key("motion"));
    let opts = CorrectOptions { use_orientation: !positions_only, ..CorrectOptions::default() };
    let units = &program.joint_units;
    let mut csv = format!("# corrected by ferrocal {} with {}\n", env!("CARGO_PKG_VERSION"), calibration.display());
    csv.push_str("pose_id");
    for (i, u) in units.iter().enumerate() {
        csv.push_str(&format!(",q{}_{}", i + 1, u.suffix()));
    }
    if has_motion {
        csv.push_str(",motion");
    }
    csv.push_str(",removed_error_mm,residual_mm\n");
    let mut removed_mm = Vec::new();
    let mut worst_residual_mm = 0.0f64;
    let corrected = correct_program(&cm, &program.set.rows, &opts)
        .map_err(|e| DatasetError::from(e).context(format!("correcting {}", program_path.display())))?;
    for (k, (row, c)) in program.set.rows.iter().zip(&corrected).enumerate() {
        if c.residual_m > REACHED_M {
            return Err(DatasetError::Input(format!(
                "{}: pose {} (line {}): the calibrated model cannot reach the intended pose ({:.4} mm remain)",
                program_path.display(),
                row.pose_id,
                row.source_line.unwrap_or(0),
                c.residual_m * 1e3
            )));
        }
        csv.push_str(&row.pose_id);
        for (v, u) in c.q.iter().zip(units) {
            csv.push_str(&format!(",{}", u.from_si(*v)));
        }
        if has_motion {
            csv.push_str(&format!(",{}", motions[k].word()));
        }
        csv.push_str(&format!(",{:.6},{:.6}\n", c.nominal_error_m * 1e3, c.residual_m * 1e3));
        removed_mm.push(c.nominal_error_m * 1e3);
        worst_residual_mm = worst_residual_mm.max(c.residual_m * 1e3);
    }
    Ok(CorrectRun { model, program, corrected, csv, removed_mm, worst_residual_mm, motions })
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
        let steps: Vec<PathStep> = rows
            .iter()
            .zip(&self.corrected)
            .zip(&self.motions)
            .enumerate()
            .map(|(k, ((r, c), m))| PathStep {
                q: c.q.clone(),
                kind: match m {
                    Motion::Joint => StepKind::Move,
                    Motion::Linear => StepKind::MoveLinear,
                },
                pose: Some(k),
                dir: r.dir.clone().unwrap_or_else(|| vec![0; c.q.len()]),
                label: Some(r.pose_id.clone()),
            })
            .collect();
        let path = PlannedPath {
            order: (0..steps.len()).collect(),
            steps,
            travel_s: 0.0,
            dwell_s: dwell_s * rows.len() as f64,
            nearest_neighbour_s: 0.0,
            ordered_s: 0.0,
            detours: 0,
            checked_segments: 0,
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
        self.removed_mm.iter().sum::<f64>() / self.removed_mm.len().max(1) as f64
    }
}
