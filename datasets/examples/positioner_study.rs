//! The real positioner of industrial_calibration's kinematic example (a fixed camera measuring
//! a target on a two-axis positioner, every fourth pose held out): the weighting of the camera's
//! pose measurements and the effects beside the geometry chosen by cross-validation on the
//! training poses alone, every candidate scored on the held-out quarter for the record, and both
//! nominal baselines.
//!
//! `cargo run -p ferrocal-datasets --example positioner_study -- [--data ../shared/data] [--folds 5]`

use std::path::PathBuf;

use ferrocal_calib::kinematic::{calibrate, KinematicOptions, ModelParams};
use ferrocal_calib::{PoseMeasurement, Split};
use ferrocal_datasets::handeye::positioner::{
    choose_by_cross_validation, diagnose_effects, estimate_pose_covariance, read_initial_guesses,
    source_guess_baseline, with_effects,
};
use ferrocal_datasets::handeye::{ic_positioner_nominal, read_ic_kinematic};
use ferrocal_robot::RobotModel;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let arg = |name: &str| args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).cloned();
    let data = PathBuf::from(arg("--data").unwrap_or_else(|| "../shared/data".into()));
    let folds: usize = arg("--folds").map_or(Ok(5), |v| v.parse())?;
    let dir = data.join("industrial_calibration/kinematic_calibration");
    let set = read_ic_kinematic(&dir, Some(4))?;
    let train: Vec<&PoseMeasurement> = set.rows.iter().filter(|r| r.split == Some(Split::Train)).collect();
    let test: Vec<&PoseMeasurement> = set.rows.iter().filter(|r| r.split == Some(Split::Test)).collect();
    let model = RobotModel::Serial(ic_positioner_nominal());
    let opts = KinematicOptions {
        sigma_position_m: 0.3e-3,
        sigma_orientation_rad: 0.03f64.to_radians(),
        ..Default::default()
    };
    println!(
        "{} training, {} held-out poses; {folds}-fold cross-validation on the training poses",
        train.len(),
        test.len()
    );
    let choice = choose_by_cross_validation(&model, &train, &opts, folds)?;
    for s in &choice.scores {
        let o = with_effects(&opts, &s.effects)?;
        let (cal, cov) = estimate_pose_covariance(&model, &train, &o, s.shape)?;
        let st = cal.calibrated.evaluate(&test)?;
        let sd = cov.map(|c| {
            let d = c.diagonal().map(|v| v.sqrt());
            format!(
                "; sigmas {:.3} {:.3} {:.3} mm, {:.4} {:.4} {:.4} deg",
                d[0] * 1e3,
                d[1] * 1e3,
                d[2] * 1e3,
                d[3].to_degrees(),
                d[4].to_degrees(),
                d[5].to_degrees()
            )
        });
        let chosen = s.shape == choice.shape && s.effects == choice.effects;
        println!(
            "{:<8} effects '{}': cv {:.4} mm, {:.4} deg; held-out {:.4} mm (max {:.4}), {:.4} deg{}{}",
            s.shape.name(),
            s.effects,
            s.cv_mean_mm,
            s.cv_mean_deg,
            st.mean_mm,
            st.max_mm,
            st.mean_deg.unwrap_or(f64::NAN),
            sd.unwrap_or_default(),
            if chosen { "  <- chosen" } else { "" }
        );
    }
    // `ferrocal diagnose` on the training poses (the frames placed in the model first).
    let chain = ic_positioner_nominal();
    let (list, report) = diagnose_effects(&chain, &train, &opts)?;
    for f in &report.findings {
        println!("diagnose finding: {}", f.statement);
    }
    let o = with_effects(&opts, &list)?;
    let cal = calibrate(&model, &train, &o)?;
    let st = cal.calibrated.evaluate(&test)?;
    println!(
        "held-out with diagnose's effects '{list}': mean {:.4} mm (max {:.4}), {:.4} deg",
        st.mean_mm,
        st.max_mm,
        st.mean_deg.unwrap_or(f64::NAN)
    );
    for (label, params, offsets) in [
        ("nominal DH, frames fitted on the training poses", ModelParams::None, false),
        ("nominal DH, frames and joint offsets fitted", ModelParams::None, true),
    ] {
        let cal = calibrate(
            &model,
            &train,
            &KinematicOptions { model_params: params, joint_offsets: offsets, ..opts.clone() },
        )?;
        let st = cal.calibrated.evaluate(&test)?;
        println!("held-out {label}: mean {:.4} mm, {:.4} deg", st.mean_mm, st.mean_deg.unwrap_or(f64::NAN));
    }
    let (cam, tgt) = read_initial_guesses(&dir)?;
    let st = source_guess_baseline(&model, &test, &cam, &tgt)?;
    println!(
        "held-out nominal DH with the source's initial mount guesses: mean {:.4} mm, {:.4} deg",
        st.mean_mm,
        st.mean_deg.unwrap_or(f64::NAN)
    );
    Ok(())
}
