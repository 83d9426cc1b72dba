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
