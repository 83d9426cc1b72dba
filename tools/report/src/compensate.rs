//! What calibration and diagnose find leaves the tool: the demo section that scores the UR5
//! calibration with the diagnosed effects in it against the geometric one, on blocks of poses
//! that no fit and no choice of effect has seen.

use std::path::Path;

use crate::error::Result;
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
        crate::bail!("the block split needs a block size and at least two blocks per group");
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

/// The verdict of `ferrocal correct`: the largest distance left from an intended pose and the
/// largest correction, against the export limits of `t`; `out`, `calibration`: the corrected
/// program and the calibration, named in the advice.
pub fn correct_verdict(
    t: &ferrocal_calib::verdict::Thresholds,
    run: &ferrocal_datasets::correct::CorrectRun,
    out: &Path,
    calibration: &Path,
    linear_as_joint: &[&Path],
) -> ferrocal_calib::verdict::Verdict {
    let l = &t.export;
    let largest = run.removed_mm.iter().copied().fold(0.0, f64::max);
    let linear: Vec<String> = linear_as_joint.iter().map(|p| p.display().to_string()).collect();
    let checks = vec![
        ferrocal_calib::verdict::Check::at_most(
            "correct.residual_mm",
            "largest distance left from an intended pose",
            "mm",
            run.worst_residual_mm,
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
        ferrocal_calib::verdict::Check::flag(
            "correct.linear_as_joint",
            &format!("linear moves of the program written with joint interpolation in {}", linear.join(", ")),
            "every move written as the program asks",
            !linear.is_empty(),
        ),
    ];
    ferrocal_calib::verdict::Verdict::with_next(checks, |c| {
        match c.map(|c| c.name.as_str()) {
        Some("correct.linear_as_joint") => format!(
            "the end points are corrected, but the path between them is not straight in {}: teach those moves as linear on the controller from the corrected end points, or write --urscript (movel)",
            linear.join(", ")
        ),
        None => format!("run {} on the robot and measure a few of its poses to confirm", out.display()),
        Some("correct.correction_mm") => format!(
            "the corrections are large: check that {} was made for this robot and frame (ferrocal evaluate on a recent table) before running the program",
            calibration.display()
        ),
        _ => "some commands cannot reach their pose exactly: move them away from singularities and joint limits".into(),
    }
    })
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
