//! Exploration: does any physical effect improve the UR5's held-out fit?
use ferrocal_calib::effects::EffectSpec;
use ferrocal_calib::kinematic::{calibrate, split_rows, KinematicOptions};
use ferrocal_robot::RobotModel;
fn main() {
    let set = ferrocal_datasets::import::import_ur5_grid(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/data/ur5_tracker/ur5_grid_train.csv"
    ))
    .unwrap();
    let model = RobotModel::load("ur5").unwrap();
    let (train, test) = split_rows(&set.rows, true);
    let mut cands: Vec<(String, Vec<EffectSpec>)> = vec![("none".into(), vec![])];
    for j in 1..=6 {
        cands.push((format!("compliance j{j}"), vec![EffectSpec::JointCompliance { joint: j }]));
        cands.push((format!("scale j{j}"), vec![EffectSpec::JointScaleError { joint: j }]));
    }
    cands.push((
        "compliance j2+j3".into(),
        vec![EffectSpec::JointCompliance { joint: 2 }, EffectSpec::JointCompliance { joint: 3 }],
    ));
    for (name, effects) in cands {
        let opts = KinematicOptions { effects, ..KinematicOptions::default() };
        let cal = calibrate(&model, &train, &opts).unwrap();
        let e = cal.calibrated.evaluate(&test).unwrap();
        let extra: Vec<String> = cal
            .params
            .iter()
            .filter(|p| p.name.contains("compliance") || p.name.contains("scale"))
            .map(|p| format!("{}={:.3e}+-{:.1e}", p.name, p.value, p.std.unwrap_or(0.0)))
            .collect();
        println!("{name:20} held-out mean {:.4} rms {:.4} {:?}", e.mean_mm, e.rms_mm, extra);
    }
}
