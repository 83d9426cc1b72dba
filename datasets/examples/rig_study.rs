//! The joint adjustment with a two-camera rig on a simulated UR5 eye-to-hand cell
//! (`ferrocal_datasets::handeye::rig_study`): per seed and over all seeds, the held-out RMS
//! (mm, tracker-measured held-out poses after the frame refit) of the rig's joint adjustment,
//! of each camera's own joint adjustment on the same data and of the tracker-calibrated robot,
//! and the rig's robot parameters against the truth in standard deviations.
//!
//! `cargo run --offline -p ferrocal-datasets --example rig_study -- --seeds 20 [--first 0]
//! [--train 60] [--test 40] [--corner-sigma-px 0.1] [--json out.json]`

use ferrocal_datasets::handeye::rig_study::{run_rig_study, summarise_rig_study, RigStudyConfig};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let get = |name: &str| args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).cloned();
    let seeds: u64 = get("--seeds").map_or(20, |v| v.parse().expect("--seeds N"));
    let first: u64 = get("--first").map_or(0, |v| v.parse().expect("--first N"));
    let mut config = RigStudyConfig::ur5_two_cameras();
    if let Some(v) = get("--train") {
        config.base.n_train = v.parse().expect("--train N");
    }
    if let Some(v) = get("--test") {
        config.base.n_test = v.parse().expect("--test N");
    }
    if let Some(v) = get("--corner-sigma-px") {
        config.base.corner_sigma_px = v.parse().expect("--corner-sigma-px S");
    }
    let b = &config.base;
    println!(
        "UR5 two-camera eye-to-hand cell: {} training / {} held-out poses, {:.2} px corner noise, errors {} mm / {} mrad; held-out RMS in mm (tracker, frame refitted)",
        b.n_train, b.n_test, b.corner_sigma_px, b.length_sigma_mm, b.angle_sigma_mrad
    );
    println!(
        "{:>4} | {:>9} | {:>8} {:>8} {:>8} {:>8} {:>8} | {:>6} {:>6} | {:>9} {:>6} | {:>6}",
        "seed", "images", "tracker", "rig", "cam0", "cam1", "nominal", "r/best", "r/trk", "rig3s", "max z", "s0"
    );
    let mut runs = Vec::new();
    let mut failed = Vec::new();
    for seed in first..first + seeds {
        let t0 = std::time::Instant::now();
        match run_rig_study(&config, seed) {
            Ok(r) => {
                let single = |k: usize| r.single.get(k).copied().flatten().map_or(f64::NAN, |s| s.rms_mm);
                let images: Vec<String> = r.n_images.iter().map(|n| n.to_string()).collect();
                let transform: Vec<String> = r
                    .rig_transform_error
                    .iter()
                    .map(|(mm, deg, z)| format!("{mm:.3} mm {deg:.4} deg ({z:.2} sigma)"))
                    .collect();
                println!(
                    "{:>4} | {:>9} | {:>8.4} {:>8.4} {:>8.4} {:>8.4} {:>8.4} | {:>6.2} {:>6.2} | {:>4}/{:<4} {:>6.2} | {:>6.3}  ({:.1} s; {} shared; model error tracker {:.4}, rig {:.4} (noise-free {:.4}), best single {:.4} mm; T_cam1_cam0 error {})",
                    r.seed,
                    images.join("/"),
                    r.tracker.rms_mm,
                    r.rig.rms_mm,
                    single(0),
                    single(1),
                    r.nominal.rms_mm,
                    r.rig_to_best_single(),
                    r.rig_to_tracker(),
                    r.rig_coverage.within_3sigma,
                    r.rig_coverage.n,
                    r.rig_coverage.max_z,
                    r.rig_s0,
                    t0.elapsed().as_secs_f64(),
                    r.n_shared,
                    r.tracker_model_rms_mm,
                    r.rig_model_rms_mm,
                    r.rig_noise_free_model_rms_mm,
                    r.best_single_model_rms_mm(),
                    transform.join(", "),
                );
                runs.push(r);
            }
            Err(e) => {
                println!("{seed:>4} | failed: {e}");
                failed.push((seed, e.to_string()));
            }
        }
    }
    let s = summarise_rig_study(&runs, failed);
    println!(
        "median held-out RMS (mm): tracker {:.4}, rig {:.4}, best single camera {:.4}, camera 0 alone {:.4}, nominal {:.4}",
        s.median_rms_mm[0], s.median_rms_mm[1], s.median_rms_mm[2], s.median_rms_mm[3], s.median_rms_mm[4]
    );
    println!(
        "rig below the best single camera on {}/{} seeds (rig / best single: median {:.3}, largest {:.3})",
        s.rig_beats_best_single_seeds, s.n_runs, s.rig_to_best_single.0, s.rig_to_best_single.1
    );
    println!(
        "rig within 1.2x of the tracker-calibrated robot on {}/{} seeds (rig / tracker: median {:.3}, largest {:.3})",
        s.rig_within_1_2_tracker_seeds, s.n_runs, s.rig_to_tracker.0, s.rig_to_tracker.1
    );
    println!(
        "model error (against the true held-out positions, mm): median tracker {:.4}, rig {:.4}, best single {:.4}; rig below the best single camera on {}/{} seeds (median ratio {:.3}, largest {:.3}); rig / tracker median {:.3}, largest {:.3}",
        s.median_model_rms_mm[0],
        s.median_model_rms_mm[1],
        s.median_model_rms_mm[2],
        s.rig_beats_best_single_model_seeds,
        s.n_runs,
        s.rig_to_best_single_model.0,
        s.rig_to_best_single_model.1,
        s.rig_to_tracker_model.0,
        s.rig_to_tracker_model.1
    );
    println!(
        "rig robot parameters within 3 sigma of the truth (its gauge): {}/{} ({:.1} %), largest z {:.2}, all within on {}/{} seeds; {} failed",
        s.rig_params_compared - s.rig_params_outside,
        s.rig_params_compared,
        100.0 * s.rig_within_3sigma,
        s.rig_max_z,
        s.rig_all_within_seeds,
        s.n_runs,
        s.failed.len()
    );
    if let Some(path) = get("--json") {
        let json = serde_json::json!({ "config": config, "runs": runs, "summary": s });
        std::fs::write(&path, serde_json::to_string_pretty(&json).unwrap()).expect("write the JSON");
    }
}
