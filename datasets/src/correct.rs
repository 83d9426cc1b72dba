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
    let opts = CorrectOptions { use_orientation: !positions_only, ..CorrectOptions::default() };
    let units = &program.joint_units;
    let mut csv = format!("# corrected by ferrocal {} with {}\n", env!("CARGO_PKG_VERSION"), calibration.display());
    csv.push_str("pose_id");
    for (i, u) in units.iter().enumerate() {
        csv.push_str(&format!(",q{}_{}", i + 1, u.suffix()));
    }
    csv.push_str(",removed_error_mm,residual_mm\n");
    let mut removed_mm = Vec::new();
    let mut worst_residual_mm = 0.0f64;
    let corrected = correct_program(&cm, &program.set.rows, &opts)
        .map_err(|e| DatasetError::from(e).context(format!("correcting {}", program_path.display())))?;
    for (row, c) in program.set.rows.iter().zip(&corrected) {
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
        csv.push_str(&format!(",{:.6},{:.6}\n", c.nominal_error_m * 1e3, c.residual_m * 1e3));
        removed_mm.push(c.nominal_error_m * 1e3);
        worst_residual_mm = worst_residual_mm.max(c.residual_m * 1e3);
    }
    Ok(CorrectRun { model, program, corrected, csv, removed_mm, worst_residual_mm })
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

impl CorrectRun {
    /// The corrected commands as the robot programs `outputs` asks for (path, text), one measure
    /// step per command in the program's order with its approach directions when the program
    /// has them, waiting `dwell_s` at each; `header`: the programs' comment lines. Each
    /// program's name is its file's stem.
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
            .enumerate()
            .map(|(k, (r, c))| PathStep {
                q: c.q.clone(),
                kind: StepKind::Measure,
                pose: Some(k),
                dir: r.dir.clone().unwrap_or_else(|| vec![0; c.q.len()]),
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
