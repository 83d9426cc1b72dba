//! The joint adjustment with a two-camera rig on the simulated UR5 eye-to-hand cell of
//! `ferrocal_datasets::handeye::rig_study`, in a small seeded version (the 20-seed study is
//! `cargo run --offline -p ferrocal-datasets --example rig_study -- --seeds 20`).
//!
//! The corners come from the estimators' own model family (exact projections of the true
//! chain through Brown-5 cameras plus Gaussian noise with the covariance the estimators are
//! given). Held-out errors are millimetres at tracker-measured held-out poses (frame refitted),
//! and the models' own error against the true positions at those poses.

use ferrocal_datasets::handeye::rig_study::{run_rig_study, RigStudyConfig, RigStudyRun};

/// Seeds 2 and 3 (run side by side), 24 training poses (each camera sees 13 to 15 of them) and
/// 15 held-out tracker poses. Asserted per seed: both cameras take part; the rig's held-out RMS
/// at most 0.9 times the best single camera's joint adjustment on the same images, in both
/// measures (0.79 to 0.80 at the time of writing; a rig whose second camera did nothing would
/// equal camera 0 alone, one with a wrong rig transform would be worse); every free robot
/// parameter within 3 standard deviations of the truth in its gauge, at least 15 compared;
/// `T_cam1_cam0` within 3 standard deviations of the true one in every coordinate; the rig within
/// 1.5 times the tracker-calibrated robot (1.22 and 1.00; the 1.2 of the issue is the 20-seed
/// study's, on 60 poses); held-out RMS below a third of the nominal robot's; s0 near 1.
#[test]
fn rig_joint_adjustment_beats_the_best_single_camera_with_parameters_within_3_sigma() {
    let mut config = RigStudyConfig::ur5_two_cameras();
    (config.base.n_train, config.base.n_test) = (24, 15);
    let config = &config;
    let runs: Vec<(u64, RigStudyRun)> = std::thread::scope(|s| {
        let handles: Vec<_> =
            [2u64, 3].into_iter().map(|seed| (seed, s.spawn(move || run_rig_study(config, seed)))).collect();
        handles.into_iter().map(|(seed, h)| (seed, h.join().unwrap().unwrap())).collect()
    });
    for (seed, r) in runs {
        eprintln!(
            "seed {seed}: images {:?} ({} shared); held-out RMS tracker {:.4}, rig {:.4}, single {:?}, nominal {:.4} mm; model error tracker {:.4}, rig {:.4}, best single {:.4} mm; rig parameters within 3 sigma {}/{} (max z {:.2}); T_cam1_cam0 error {:?}; s0 {:.3}",
            r.n_images,
            r.n_shared,
            r.tracker.rms_mm,
            r.rig.rms_mm,
            r.single.iter().map(|s| s.map(|s| s.rms_mm)).collect::<Vec<_>>(),
            r.nominal.rms_mm,
            r.tracker_model_rms_mm,
            r.rig_model_rms_mm,
            r.best_single_model_rms_mm(),
            r.rig_coverage.within_3sigma,
            r.rig_coverage.n,
            r.rig_coverage.max_z,
            r.rig_transform_error,
            r.rig_s0
        );
        assert!(r.n_images.iter().all(|&n| n >= 8), "seed {seed}: images per camera {:?}", r.n_images);
        let best = r.best_single_rms_mm();
        assert!(best.is_finite() && r.single.iter().all(|s| s.is_some()), "seed {seed}: a single camera failed");
        assert!(r.rig.rms_mm <= 0.9 * best, "seed {seed}: rig {:.4} mm, best single camera {best:.4} mm", r.rig.rms_mm);
        let best_model = r.best_single_model_rms_mm();
        assert!(
            r.rig_model_rms_mm <= 0.9 * best_model,
            "seed {seed}: rig model error {:.4} mm, best single camera {best_model:.4} mm",
            r.rig_model_rms_mm
        );
        assert!(r.rig_coverage.n >= 15, "seed {seed}: {} free robot parameters", r.rig_coverage.n);
        assert_eq!(
            r.rig_coverage.within_3sigma, r.rig_coverage.n,
            "seed {seed}: largest z {:.2}",
            r.rig_coverage.max_z
        );
        let (_, _, z) = r.rig_transform_error[0];
        assert!(z <= 3.0, "seed {seed}: T_cam1_cam0 {z:.2} sigma off");
        assert!(r.rig_to_tracker() <= 1.5, "seed {seed}: rig / tracker {:.3}", r.rig_to_tracker());
        assert!(
            r.rig.rms_mm < r.nominal.rms_mm / 3.0,
            "seed {seed}: rig {:.4}, nominal {:.4}",
            r.rig.rms_mm,
            r.nominal.rms_mm
        );
        assert!((0.8..1.25).contains(&r.rig_s0), "seed {seed}: s0 {}", r.rig_s0);
    }
}
