//! What calibration and diagnose find leaves the tool: the demo section that scores the UR5
//! calibration with the diagnosed effects in it against the geometric one, on blocks of poses
//! that no fit and no choice of effect has seen.

use std::path::Path;

use anyhow::Result;
use ferrocal_calib::diagnose::{compensated_calibration, diagnose, DiagnoseOptions};
use ferrocal_calib::kinematic::{calibrate, split_rows_in_blocks, KinematicOptions};
use ferrocal_calib::{PoseMeasurement, Split};
use ferrocal_datasets::checks;
use ferrocal_robot::RobotModel;

use crate::plot::{self, Series};
use crate::report::Section;

/// Consecutive poses per block of the non-interleaved split.
pub const BLOCK: usize = 50;
/// Every this many blocks, one is held out.
pub const EVERY: usize = 4;

/// The UR5 compensation section (`attribution`: the recording's source and licence).
pub fn demo_section(ur5_csv: &Path, attribution: &str, tick: crate::demo::Tick) -> Result<Section> {
    let mut s = Section::new("ur5-compensation", "UR5: the calibration with the diagnosed physics in it");
    s.attribution(attribution);
    if !ur5_csv.exists() {
        s.skipped(format!("{} is not present", ur5_csv.display()));
        return Ok(s);
    }
    let set = ferrocal_datasets::import::import_ur5_grid(ur5_csv)?;
    let model = RobotModel::load("ur5")?;
    let Some((train, test)) = split_rows_in_blocks(&set.rows, BLOCK, EVERY) else {
        anyhow::bail!("the block split needs a block size and at least two blocks per group");
    };
    let test_ids: std::collections::HashSet<&str> = test.iter().map(|r| r.pose_id.as_str()).collect();
    // The recording with its split written in, as a user's table would carry it.
    let rows: Vec<PoseMeasurement> = set
        .rows
        .iter()
        .map(|r| {
            let mut r = r.clone();
            r.split = Some(if test_ids.contains(r.pose_id.as_str()) { Split::Test } else { Split::Train });
            r
        })
        .collect();
    tick("UR5 compensation", 0, 3);
    let geometric = calibrate(&model, &train, &KinematicOptions::default())?;
    tick("UR5 compensation", 1, 3);
    let rep = diagnose(&model, &rows, &DiagnoseOptions::default())?;
    tick("UR5 compensation", 2, 3);
    let compensated = compensated_calibration(&model, &rows, &rep)?;
    tick("UR5 compensation", 3, 3);
    let e_geo = geometric.calibrated.evaluate(&test)?;
    let e_comp = compensated.calibrated.evaluate(&test)?;
    s.text(format!(
        "Blocks of {BLOCK} consecutive poses, every {EVERY}th block held out ({} training, {} held-out poses): the held-out blocks are used by no fit and by no choice of effect. `diagnose --out` refits the geometry with the {} accepted effect(s) on the training poses and writes the calibration file that `evaluate` predicts with; `calibrate --effects <diagnose json>` fits the same model from scratch.",
        train.len(),
        test.len(),
        rep.findings.len()
    ));
    s.table(
        "Held-out blocks, position errors",
        &["model", "mean [mm]", "RMS [mm]", "max [mm]"],
        vec![
            vec!["geometric calibration".into(), f4(e_geo.mean_mm), f4(e_geo.rms_mm), f4(e_geo.max_mm)],
            vec!["with the diagnosed effects".into(), f4(e_comp.mean_mm), f4(e_comp.rms_mm), f4(e_comp.max_mm)],
        ],
    );
    s.table(
        "Effects in the delivered calibration",
        &["effect", "joints", "statement"],
        rep.findings.iter().map(|f| vec![f.effect.clone(), format!("{:?}", f.joints), f.statement.clone()]).collect(),
    );
    let (p_geo, _) = geometric.calibrated.errors(&test)?;
    let (p_comp, _) = compensated.calibrated.errors(&test)?;
    let pairs: Vec<(f64, f64)> = p_geo.iter().zip(&p_comp).map(|(a, b)| (a.norm() * 1e3, b.norm() * 1e3)).collect();
    let diagonal = [(0.0, 0.0), (e_geo.max_mm, e_geo.max_mm)];
    s.figure(
        "Per held-out pose: error of the compensated model against the geometric one (below the line: better)",
        plot::xy_plot(
            "Held-out pose errors",
            "geometric calibration [mm]",
            "with the diagnosed effects [mm]",
            &[
                Series { name: "held-out pose", points: &pairs, line: false },
                Series { name: "equal", points: &diagonal, line: true },
            ],
        ),
    );
    s.data = serde_json::json!({
        "block": BLOCK, "every": EVERY, "n_train": train.len(), "n_test": test.len(),
        "geometric": e_geo, "compensated": e_comp,
        "effects": rep.findings.iter().map(|f| &f.spec).collect::<Vec<_>>(),
    });
    s.check(checks::ur5_compensation(&e_geo, &e_comp));
    Ok(s)
}

fn f4(v: f64) -> String {
    format!("{v:.4}")
}

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
    /// conditions the effects see (`dir<i>`, `temp_c`, `payload_kg`, `t_s`).
    #[arg(long)]
    pub program: std::path::PathBuf,
    /// The corrected commands (CSV, the program's joint units), with per pose the error the
    /// correction removes and what remains under the calibrated model.
    #[arg(long)]
    pub out: std::path::PathBuf,
    /// Match positions only (the smallest joint change that does), not orientations.
    #[arg(long)]
    pub positions_only: bool,
    /// Also write the corrected program as an ABB RAPID module (`MoveAbsJ` per command).
    #[arg(long, value_name = "FILE.mod")]
    pub rapid: Option<std::path::PathBuf>,
    /// Also write it as G-code (one axis letter per joint, `G1` per command).
    #[arg(long, value_name = "FILE.ngc")]
    pub gcode: Option<std::path::PathBuf>,
    /// Also write it as a Universal Robots URScript (`movej` per command; six revolute joints).
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
pub fn run_correct(a: &CorrectArgs, vs: &crate::verdict::VerdictSettings) -> Result<std::process::ExitCode> {
    use anyhow::Context;
    use ferrocal_calib::kinematic::correct::{correct_program, CorrectOptions};
    for input in [&a.program, &a.calibration] {
        if crate::report::same_file(input, &a.out) {
            anyhow::bail!(
                "--out {} would overwrite the input {}; choose another file",
                a.out.display(),
                input.display()
            );
        }
    }
    let model = RobotModel::load(&a.robot)?;
    let file = ferrocal_calib::file::CalibrationFile::read(&a.calibration)?;
    file.check_robot(&a.robot, &model).with_context(|| format!("{}", a.calibration.display()))?;
    let cm = file.apply(&model).with_context(|| format!("applying {}", a.calibration.display()))?;
    let program = ferrocal_datasets::import::read_joint_program(&a.program)?;
    // Readings in another unit (degrees under `_rad`) or beyond the limits are refused by row.
    if program.joint_units.len() == ferrocal_robot::Kinematics::dof(&model) {
        program.check_joint_values(&ferrocal_robot::Kinematics::joint_limits(&model), model.name())?;
    }
    let opts = CorrectOptions { use_orientation: !a.positions_only, ..CorrectOptions::default() };
    let units = &program.joint_units;
    let mut out = format!("# corrected by ferrocal {} with {}\n", env!("CARGO_PKG_VERSION"), a.calibration.display());
    out.push_str("pose_id");
    for (i, u) in units.iter().enumerate() {
        out.push_str(&format!(",q{}_{}", i + 1, u.suffix()));
    }
    out.push_str(",removed_error_mm,residual_mm\n");
    let mut removed = Vec::new();
    let mut worst_residual_mm = 0.0f64;
    let corrected = correct_program(&cm, &program.set.rows, &opts)
        .with_context(|| format!("correcting {}", a.program.display()))?;
    for (row, c) in program.set.rows.iter().zip(&corrected) {
        if c.residual_m > 1e-6 {
            anyhow::bail!(
                "{}: pose {} (line {}): the calibrated model cannot reach the intended pose ({:.4} mm remain)",
                a.program.display(),
                row.pose_id,
                row.source_line.unwrap_or(0),
                c.residual_m * 1e3
            );
        }
        out.push_str(&row.pose_id);
        for (v, u) in c.q.iter().zip(units) {
            out.push_str(&format!(",{}", u.from_si(*v)));
        }
        out.push_str(&format!(",{:.6},{:.6}\n", c.nominal_error_m * 1e3, c.residual_m * 1e3));
        removed.push(c.nominal_error_m * 1e3);
        worst_residual_mm = worst_residual_mm.max(c.residual_m * 1e3);
    }
    let programs = corrected_programs(a, &model, &program.set.rows, &corrected)?;
    crate::report::write_atomic(&a.out, out.as_bytes())?;
    for (path, text) in &programs {
        crate::report::write_atomic(path, text.as_bytes())?;
        println!("corrected program written to {}", path.display());
    }
    let mean = removed.iter().sum::<f64>() / removed.len().max(1) as f64;
    println!(
        "{} commands corrected; the calibrated model predicts the uncorrected ones {mean:.4} mm off on average; written to {}",
        removed.len(),
        a.out.display()
    );
    let l = &vs.thresholds.export;
    let largest = removed.iter().copied().fold(0.0, f64::max);
    let checks = vec![
        ferrocal_calib::verdict::Check::at_most(
            "correct.residual_mm",
            "largest distance left from an intended pose",
            "mm",
            worst_residual_mm,
            l.residual_mm_warn,
            l.residual_mm_fail,
        ),
        ferrocal_calib::verdict::Check::at_most(
            "correct.correction_mm",
            "largest correction",
            "mm",
            largest,
            l.correction_mm_warn,
            l.correction_mm_fail,
        ),
    ];
    let verdict = ferrocal_calib::verdict::Verdict::with_next(checks, |c| {
        match c.map(|c| c.name.as_str()) {
        None => format!("run {} on the robot and measure a few of its poses to confirm", a.out.display()),
        Some("correct.correction_mm") => format!(
            "the corrections are large: check that {} was made for this robot and frame (ferrocal evaluate on a recent table) before running the program",
            a.calibration.display()
        ),
        _ => "some commands cannot reach their pose exactly: move them away from singularities and joint limits".into(),
    }
    });
    Ok(vs.conclude(&verdict))
}

/// The corrected commands as the robot programs `a` asks for (path, text), all composed before
/// anything is written: one measure step per command, in the program's order, with its approach
/// directions when the program has them. An output that names an input is refused.
fn corrected_programs(
    a: &CorrectArgs,
    model: &RobotModel,
    rows: &[ferrocal_calib::measurement::PoseMeasurement],
    corrected: &[ferrocal_calib::kinematic::correct::CorrectedCommand],
) -> Result<Vec<(std::path::PathBuf, String)>> {
    use anyhow::Context;
    use ferrocal_robot::program::{
        gcode, krl, rapid_module, urscript, PathStep, PlannedPath, ProgramSettings, StepKind,
    };
    let outputs: Vec<(&str, &std::path::PathBuf)> =
        [("rapid", &a.rapid), ("gcode", &a.gcode), ("urscript", &a.urscript), ("krl", &a.krl)]
            .into_iter()
            .filter_map(|(k, p)| p.as_ref().map(|p| (k, p)))
            .collect();
    let inputs = [&a.program, &a.calibration, &a.out];
    for (_, p) in &outputs {
        if let Some(i) = inputs.iter().find(|i| crate::report::same_file(i, p)) {
            anyhow::bail!("output {} would overwrite {}; choose another file", p.display(), i.display());
        }
    }
    let steps: Vec<PathStep> = rows
        .iter()
        .zip(corrected)
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
        dwell_s: a.dwell_s * rows.len() as f64,
        nearest_neighbour_s: 0.0,
        ordered_s: 0.0,
        detours: 0,
        checked_segments: 0,
    };
    let header = vec![
        format!("corrected by ferrocal {} ({})", env!("CARGO_PKG_VERSION"), chrono::Utc::now().to_rfc3339()),
        format!("program {}; calibration {}; robot {}", a.program.display(), a.calibration.display(), a.robot),
        "joint commands for the calibrated robot to reach the poses the nominal model meant; the path between them is not checked against safety zones".into(),
    ];
    let mut out = Vec::new();
    for (kind, p) in outputs {
        let stem = p.file_stem().and_then(|s| s.to_str()).unwrap_or("ferrocal_corrected").replace(['-', '.', ' '], "_");
        let settings = ProgramSettings {
            rapid_module: stem.clone(),
            urscript_name: stem.clone(),
            krl_name: stem.clone(),
            ..ProgramSettings::default()
        };
        let text = match kind {
            "rapid" => rapid_module(model, &path, a.dwell_s, &settings, &header),
            "gcode" => gcode(model, &path, a.dwell_s, &settings, &header).map(|g| g.text),
            "urscript" => urscript(model, &path, a.dwell_s, &settings, &header),
            _ => krl(model, &path, a.dwell_s, &settings, &header),
        }
        .with_context(|| format!("writing the corrected program {}", p.display()))?;
        out.push((p.clone(), text));
    }
    Ok(out)
}

/// The demo's corrected-program section: the simulated check of `ferrocal correct`.
pub fn corrected_section(seed: u64) -> Result<Section> {
    let mut s =
        Section::new("corrected-commands", "Corrected programs: commands through the calibration, on the true robot");
    let r = ferrocal_datasets::sim::corrected_commands_study(30 + seed)?;
    s.text(format!(
        "A simulated UR5 with random geometric errors (0.5 mm, 1 mrad per joint) is calibrated from {} six-DoF tracker poses; {} further poses check the calibration; a program of {} other commands is corrected with `ferrocal correct` (the nominal model's frames fitted to the calibrated one, then each command solved on the calibrated model) and both programs run on the true robot. The truth is the calibration's own model family: this shows that the correction delivers what the calibration knows.",
        r.n_train, r.n_test, r.n_program
    ));
    s.table(
        "Program on the true robot (mean distance from the intended pose)",
        &["commands", "mean [mm]"],
        vec![
            vec!["as written (nominal model)".into(), f4(r.uncorrected_mm)],
            vec!["corrected through the calibration".into(), f4(r.corrected_mm)],
            vec!["for scale: the calibration's held-out error (tracker noise included)".into(), f4(r.held_out_mm)],
        ],
    );
    s.data = serde_json::to_value(&r)?;
    s.check(checks::corrected_commands(&r));
    Ok(s)
}
