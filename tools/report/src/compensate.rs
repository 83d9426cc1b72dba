//! What calibration and diagnose find leaves the tool: the demo section that scores the UR5
//! calibration with the diagnosed effects in it against the geometric one, on blocks of poses
//! that no fit and no choice of effect has seen.

use std::path::Path;

use crate::error::Result;
use ferrocal_calib::diagnose::{compensated_calibration, diagnose, DiagnoseOptions};
use ferrocal_calib::kinematic::{calibrate, split_rows_in_blocks, KinematicOptions};
use ferrocal_calib::{PoseMeasurement, Split};
use ferrocal_datasets::checks;
use ferrocal_datasets::correct::CorrectRun;
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

/// The rows of a corrected program beyond the calibrated region (the export limits'
/// `outside_deg_warn` / `outside_mm_warn`): `(pose id, what)`.
fn outside_rows(t: &ferrocal_calib::verdict::Thresholds, run: &CorrectRun) -> Vec<(String, String)> {
    let kinds = ferrocal_robot::Kinematics::joint_kinds(&run.model);
    run.reached()
        .filter_map(|(_, o)| {
            let x = o.outside?;
            let mut what = Vec::new();
            if let Some((j, v)) = x.joint {
                let (shown, limit, unit) = match kinds[j - 1] {
                    ferrocal_robot::JointKind::Revolute => (v.to_degrees(), t.export.outside_deg_warn, "deg"),
                    ferrocal_robot::JointKind::Prismatic => (v * 1e3, t.export.outside_mm_warn, "mm"),
                };
                if shown > limit {
                    what.push(format!("joint {j} {shown:.1} {unit} beyond"));
                }
            }
            if x.position_m * 1e3 > t.export.outside_mm_warn {
                what.push(format!("{:.1} mm outside the positions", x.position_m * 1e3));
            }
            (!what.is_empty()).then(|| (o.pose_id.clone(), what.join(", ")))
        })
        .collect()
}

/// Rows near a singularity (smallest singular value below `singular_m_warn`).
fn singular_rows(t: &ferrocal_calib::verdict::Thresholds, run: &CorrectRun) -> Vec<String> {
    run.rows.iter().filter(|o| o.command.sigma_min < t.export.singular_m_warn).map(|o| o.pose_id.clone()).collect()
}

fn id_list(ids: &[String]) -> String {
    let mut s = ids.iter().take(6).cloned().collect::<Vec<_>>().join(", ");
    if ids.len() > 6 {
        s.push_str(&format!(" and {} more", ids.len() - 6));
    }
    s
}

/// The verdict of `ferrocal correct`: rows that cannot be reached, the largest distance left
/// from a wanted pose and the largest correction (export limits of `t`), rows beyond the
/// calibrated region and near a singularity, whether the commands carry their uncertainty, and
/// linear moves written as joint moves; `out`, `calibration`: the corrected program and the
/// calibration, named in the advice.
pub fn correct_verdict(
    t: &ferrocal_calib::verdict::Thresholds,
    run: &CorrectRun,
    out: &Path,
    calibration: &Path,
    linear_as_joint: &[&Path],
) -> ferrocal_calib::verdict::Verdict {
    use ferrocal_calib::verdict::Check;
    let l = &t.export;
    let largest = run.removed_mm.iter().copied().filter(|v| v.is_finite()).fold(0.0, f64::max);
    let linear: Vec<String> = linear_as_joint.iter().map(|p| p.display().to_string()).collect();
    let unreached: Vec<String> = run.unreached().map(|o| o.pose_id.clone()).collect();
    let outside = outside_rows(t, run);
    let singular = singular_rows(t, run);
    let n = run.rows.len();
    let worst_outside = outside.iter().map(|(id, w)| format!("{id}: {w}")).take(3).collect::<Vec<_>>().join("; ");
    let no_sigma = run.reached().any(|(_, o)| o.landing_sigma_mm.is_none());
    let checks = vec![
        Check::flag(
            "correct.unreached",
            &format!(
                "{} of {n} rows cannot be reached within the joint limits and are not written ({})",
                unreached.len(),
                id_list(&unreached)
            ),
            "every row reached",
            !unreached.is_empty(),
        ),
        Check::at_most(
            "correct.residual_mm",
            "largest distance left from a wanted pose",
            "mm",
            run.worst_residual_mm,
            l.residual_mm_warn,
            l.residual_mm_fail,
        ),
        Check::at_most(
            "correct.correction_mm",
            "largest correction",
            "mm",
            largest,
            l.correction_mm_warn,
            l.correction_mm_fail,
        ),
        Check::flag(
            "correct.outside",
            &format!(
                "{} of {n} rows lie outside the region the calibration's poses cover ({worst_outside})",
                outside.len()
            ),
            "every row inside the calibrated region",
            !outside.is_empty(),
        ),
        Check::flag(
            "correct.near_singularity",
            &format!("{} rows near a singularity ({})", singular.len(), id_list(&singular)),
            "no row near a singularity",
            !singular.is_empty(),
        ),
        Check::flag(
            "correct.uncertainty",
            &format!("{} carries no covariance: the commands have no landing uncertainty", calibration.display()),
            "every command with its landing uncertainty",
            no_sigma,
        ),
        Check::flag(
            "correct.linear_as_joint",
            &format!("linear moves of the program written with joint interpolation in {}", linear.join(", ")),
            "every move written as the program asks",
            !linear.is_empty(),
        ),
    ];
    ferrocal_calib::verdict::Verdict::with_next(checks, |c| {
        match c.map(|c| c.name.as_str()) {
        Some("correct.unreached") => format!(
            "rows {} are not in {}: move them inside the robot's reach{}, or give a start (q columns) on another solution branch",
            id_list(&unreached),
            out.display(),
            if unreached.iter().any(|u| singular.contains(u)) { " and away from the singularity" } else { "" }
        ),
        Some("correct.linear_as_joint") => format!(
            "the end points are corrected, but the path between them is not straight in {}: teach those moves as linear on the controller from the corrected end points, or write --urscript (movel)",
            linear.join(", ")
        ),
        Some("correct.outside") => format!(
            "the calibration was not measured there and its corrections are extrapolated: measure poses around {} and recalibrate, or check those poses on the robot",
            id_list(&outside.iter().map(|(id, _)| id.clone()).collect::<Vec<_>>())
        ),
        Some("correct.near_singularity") => format!(
            "near a singularity a small error of the model moves the joints far: move {} away from it (wrist or elbow stretched), or check them slowly on the robot",
            id_list(&singular)
        ),
        Some("correct.uncertainty") => format!(
            "recalibrate with this version of ferrocal (calibrate, diagnose --out or handeye --out) so that {} carries its covariance",
            calibration.display()
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

/// The JSON report of `ferrocal correct` (the verdict is added by the caller).
pub fn correct_json(run: &CorrectRun, calibration: &Path, input: &Path) -> serde_json::Value {
    let kinds = ferrocal_robot::Kinematics::joint_kinds(&run.model);
    let show = |q: &[f64]| -> Vec<f64> {
        q.iter()
            .zip(&kinds)
            .map(|(v, k)| match k {
                ferrocal_robot::JointKind::Revolute => v.to_degrees(),
                ferrocal_robot::JointKind::Prismatic => v * 1e3,
            })
            .collect()
    };
    let rows: Vec<serde_json::Value> = run
        .rows
        .iter()
        .map(|o| {
            let c = &o.command;
            let p = c.intended.translation.vector * 1e3;
            serde_json::json!({
                "pose_id": o.pose_id,
                "line": o.line,
                "written": o.unreached.is_none(),
                "why_not": o.unreached,
                "q": show(&c.q),
                "wanted_mm": [p.x, p.y, p.z],
                "orientation_matched": o.orientation,
                "removed_error_mm": c.nominal_error_m.is_finite().then_some(c.nominal_error_m * 1e3),
                "residual_mm": c.residual_m * 1e3,
                "landing_sigma_mm": o.landing_sigma_mm,
                "outside_joint": o.outside.and_then(|x| x.joint).map(|(j, _)| j),
                "outside_joint_by": o.outside.and_then(|x| x.joint).map(|(j, v)| match kinds[j - 1] {
                    ferrocal_robot::JointKind::Revolute => v.to_degrees(),
                    ferrocal_robot::JointKind::Prismatic => v * 1e3,
                }),
                "outside_box_mm": o.outside.map(|x| x.position_m * 1e3),
                "sigma_min_m": c.sigma_min,
                "at_limit": c.at_limit,
            })
        })
        .collect();
    let sigmas: Vec<f64> = run.reached().filter_map(|(_, o)| o.landing_sigma_mm).collect();
    serde_json::json!({
        "input": input.display().to_string(),
        "input_kind": if run.targets { "targets" } else { "program" },
        "calibration": calibration.display().to_string(),
        "joint_units": kinds.iter().map(|k| match k {
            ferrocal_robot::JointKind::Revolute => "deg",
            ferrocal_robot::JointKind::Prismatic => "mm",
        }).collect::<Vec<_>>(),
        "n_rows": run.rows.len(),
        "n_written": run.reached().count(),
        "nominal_frames": {
            "source": run.frames.source,
            "n_poses": run.frames.n_poses,
            "rms_mm": run.frames.rms_mm,
        },
        "mean_removed_error_mm": run.mean_removed_mm(),
        "worst_residual_mm": run.worst_residual_mm,
        "median_landing_sigma_mm": median(&sigmas),
        "notes": run.notes,
        "rows": rows,
    })
}

fn median(v: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

/// The terminal lines of `ferrocal correct` before its verdict: what was corrected, the rows
/// not written and the notes.
pub fn correct_lines(run: &CorrectRun, out: &Path) -> Vec<String> {
    let mut lines = vec![run.summary_line(out)];
    let sigmas: Vec<f64> = run.reached().filter_map(|(_, o)| o.landing_sigma_mm).collect();
    if let Some(m) = median(&sigmas) {
        let max = sigmas.iter().copied().fold(0.0, f64::max);
        lines.push(format!(
            "predicted landing error (68 % radius, from the calibration's covariance and unexplained scatter): median {m:.4} mm, largest {max:.4} mm"
        ));
    }
    for o in run.unreached() {
        let line = o.line.map(|l| format!(" (line {l})")).unwrap_or_default();
        lines.push(format!("pose {}{line} not written: {}", o.pose_id, o.unreached.as_deref().unwrap_or("")));
    }
    lines.extend(run.notes.iter().map(|n| format!("note: {n}")));
    lines
}

/// The demo's corrected-program section: the closed loop of `ferrocal correct` on a simulated
/// UR5 whose truth is outside the calibration's model family, calibrated from a tracker and from
/// a camera (`datasets::sim::closed_loop`); its files go under `dir`.
pub fn corrected_section(seed: u64, dir: &Path) -> Result<Section> {
    use ferrocal_datasets::sim::closed_loop::{run_closed_loop, ClosedLoopConfig};
    let mut s = Section::new(
        "corrected-commands",
        "Corrected programs on a robot that is not the model: where the commands land",
    );
    std::fs::create_dir_all(dir)?;
    let config = ClosedLoopConfig::ur5();
    let r = run_closed_loop(&config, 100 + seed, dir)?;
    s.text(format!(
        "A simulated UR5 with geometric errors (0.5 mm, 0.5 mrad) and physics the calibration does not model (upper arm and forearm bending under gravity, eccentric base and shoulder gears, a wobbling elbow axis: {:.4} mm RMS at the program's poses) is calibrated twice: from {} tracker readings, and from {} camera views by the joint adjustment of robot and camera in pixels. A program of {} nominal commands is corrected through each calibration file by `ferrocal correct` (each command on its own, the nominal frames fixed by the calibration) and executed on the simulated truth. The corners are exact projections plus 0.1 px noise, the tracker adds 10 um + 3 um/m; the landed positions are the truth's.",
        r.left_out_rms_mm,
        config.cell.n_train,
        config.cell.n_train,
        config.n_program
    ));
    let row = |name: &str, p: &ferrocal_datasets::sim::closed_loop::PathResult| {
        vec![
            name.to_string(),
            f4(p.held_out_rms_mm),
            f4(p.uncorrected_rms_mm),
            f4(p.landed_rms_mm),
            format!("{:.2}", p.ratio()),
            format!("{}/{}", p.covered, p.rows.len()),
        ]
    };
    s.table(
        "The program on the true robot (RMS distance from the wanted position)",
        &[
            "calibrated from",
            "its held-out RMS [mm]",
            "uncorrected [mm]",
            "corrected [mm]",
            "corrected / held-out",
            "rows within their 1-sigma (68 %) radius",
        ],
        vec![row("laser tracker", &r.tracker), row("camera (joint adjustment)", &r.camera)],
    );
    let pts = |p: &ferrocal_datasets::sim::closed_loop::PathResult| -> Vec<(f64, f64)> {
        p.rows.iter().map(|x| (x.sigma_mm, x.landed_mm)).collect()
    };
    let (pt, pc) = (pts(&r.tracker), pts(&r.camera));
    let top = pt.iter().chain(&pc).map(|(a, b)| a.max(*b)).fold(0.0, f64::max);
    let diagonal = [(0.0, 0.0), (top, top)];
    s.figure(
        "Per command: landed error against its predicted 68 % radius (below the line: covered)",
        plot::xy_plot(
            "Landed error and its prediction",
            "predicted 68 % radius [mm]",
            "landed error [mm]",
            &[
                Series { name: "tracker calibration", points: &pt, line: false },
                Series { name: "camera calibration", points: &pc, line: false },
                Series { name: "equal", points: &diagonal, line: true },
            ],
        ),
    );
    s.data = serde_json::to_value(&r)?;
    s.check(checks::closed_loop(&r));
    Ok(s)
}
