//! The camera-based robot calibration against the tracker's on a simulated UR5 cell
//! (`ferrocal_datasets::handeye::joint_study`): per seed and over all seeds, the held-out RMS of
//! the tracker-calibrated model, the two-step camera path, the joint adjustment and the nominal
//! model, their ratios to the tracker's, and the robot parameters within 3 sigma of the truth.
//!
//! `cargo run --release -p ferrocal-datasets --example joint_study -- --seeds 20 [--first 0]
//! [--train 60] [--test 40] [--corner-sigma-px 0.1] [--mount eye-in-hand] [--json out.json]`

use ferrocal_datasets::handeye::joint_study::{run_joint_study, summarise_joint_study, JointStudyConfig};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let get = |name: &str| args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).cloned();
    let seeds: u64 = get("--seeds").map_or(20, |v| v.parse().expect("--seeds N"));
    let first: u64 = get("--first").map_or(0, |v| v.parse().expect("--first N"));
    let mut config = match get("--mount").as_deref() {
        None | Some("eye-to-hand") => JointStudyConfig::ur5(),
        Some("eye-in-hand") => JointStudyConfig::ur5_eye_in_hand(),
        Some(m) => panic!("--mount {m}: eye-to-hand or eye-in-hand"),
    };
    if let Some(v) = get("--train") {
        config.n_train = v.parse().expect("--train N");
    }
    if let Some(v) = get("--test") {
        config.n_test = v.parse().expect("--test N");
    }
    if let Some(v) = get("--corner-sigma-px") {
        config.corner_sigma_px = v.parse().expect("--corner-sigma-px S");
    }
    println!(
        "UR5 cell: {} training / {} held-out poses, {:.2} px corner noise, errors {} mm / {} mrad",
        config.n_train, config.n_test, config.corner_sigma_px, config.length_sigma_mm, config.angle_sigma_mrad
    );
    println!(
        "{:>4} | {:>8} {:>8} {:>8} {:>8} | {:>6} {:>6} | {:>9} {:>9} {:>9} | {:>6} {:>5}",
        "seed",
        "tracker",
        "2-step",
        "joint",
        "nominal",
        "r2step",
        "rjoint",
        "joint3s",
        "2step3s",
        "track3s",
        "s0",
        "px"
    );
    let mut runs = Vec::new();
    let mut failed = Vec::new();
    for seed in first..first + seeds {
        let t0 = std::time::Instant::now();
        match run_joint_study(&config, seed) {
            Ok(r) => {
                println!(
                    "{:>4} | {:>8.4} {:>8.4} {:>8.4} {:>8.4} | {:>6.2} {:>6.2} | {:>4}/{:<4} {:>4}/{:<4} {:>4}/{:<4} | {:>6.3} {:>5.3}  ({:.1} s; floor {:.4} mm; max z joint {:.2}; 2-step true camera {:.4}; fx error joint {:+.2} +- {:.2} px, 2-step {:+.2} +- {:.2} px)",
                    r.seed,
                    r.tracker.rms_mm,
                    r.two_step.rms_mm,
                    r.joint.rms_mm,
                    r.nominal.rms_mm,
                    r.two_step_ratio(),
                    r.joint_ratio(),
                    r.joint_coverage.within_3sigma,
                    r.joint_coverage.n,
                    r.two_step_coverage.within_3sigma,
                    r.two_step_coverage.n,
                    r.tracker_coverage.within_3sigma,
                    r.tracker_coverage.n,
                    r.joint_s0,
                    r.joint_train_rms_px,
                    t0.elapsed().as_secs_f64(),
                    r.noise_floor_mm,
                    r.joint_coverage.max_z,
                    r.two_step_true_camera.rms_mm,
                    r.joint_fx_error_px,
                    r.joint_fx_std_px,
                    r.two_step_fx_error_px,
                    r.two_step_fx_std_px,
                );
                runs.push(r);
            }
            Err(e) => {
                println!("{seed:>4} | failed: {e}");
                failed.push((seed, e.to_string()));
            }
        }
    }
    let s = summarise_joint_study(&runs, failed);
    println!(
        "median held-out RMS (mm): tracker {:.4}, two-step {:.4} (true camera given: {:.4}), joint {:.4}, nominal {:.4}",
        s.median_rms_mm[0], s.median_rms_mm[1], s.median_rms_mm[4], s.median_rms_mm[2], s.median_rms_mm[3]
    );
    println!(
        "median ratio to the tracker model: two-step {:.2}, joint {:.2} (largest joint {:.2})",
        s.median_two_step_ratio, s.median_joint_ratio, s.max_joint_ratio
    );
    println!(
        "robot parameters within 3 sigma of the truth: joint {:.1} % in its gauge ({:.1} % against the drawn values); gauge ignored: two-step {:.1} %, tracker {:.1} %; all within on {}/{} seeds (joint); {} failed",
        100.0 * s.joint_within_3sigma,
        100.0 * s.joint_raw_within_3sigma,
        100.0 * s.two_step_within_3sigma,
        100.0 * s.tracker_within_3sigma,
        s.joint_all_within_seeds,
        s.n_runs,
        s.failed.len()
    );
    if let Some(path) = get("--json") {
        let json = serde_json::json!({ "config": config, "runs": runs, "summary": s });
        std::fs::write(&path, serde_json::to_string_pretty(&json).unwrap()).expect("write the JSON");
    }
}
