//! The joint adjustment of robot and camera against the tracker-calibrated model on the
//! simulated UR5 cell of `ferrocal_datasets::handeye::joint_study`, in a small seeded version
//! (the 20-seed study is `cargo run --release -p ferrocal-datasets --example joint_study`).
//!
//! The corners come from the estimator's own model family (exact projections of the true chain
//! through a Brown-5 camera plus Gaussian noise with the covariance the estimator is given).

use ferrocal_datasets::handeye::joint_study::{run_joint_study, JointStudyConfig};

/// 30 training images and tracker readings, 30 held-out tracker readings, one seed. Asserted:
/// the joint adjustment's held-out RMS within 1.5 times the tracker-calibrated model's (the
/// issue's must-hold), at least 90 % of its free robot parameters within 3 standard deviations
/// of the truth in its gauge (all of them on this seed at the time of writing; with 26
/// parameters and correct standard deviations about 7 % of seeds have one outside), and a
/// held-out RMS below a third of the nominal model's.
#[test]
fn joint_adjustment_is_within_1_5x_of_the_tracker_model_with_parameters_within_3_sigma() {
    let mut config = JointStudyConfig::ur5();
    (config.n_train, config.n_test) = (30, 30);
    let seed = 3;
    let r = run_joint_study(&config, seed).unwrap();
    eprintln!(
        "seed {seed}: held-out RMS tracker {:.4}, two-step {:.4} (true camera {:.4}), joint {:.4}, nominal {:.4} mm; joint parameters within 3 sigma {}/{} (max z {:.2}), s0 {:.3}",
        r.tracker.rms_mm,
        r.two_step.rms_mm,
        r.two_step_true_camera.rms_mm,
        r.joint.rms_mm,
        r.nominal.rms_mm,
        r.joint_coverage.within_3sigma,
        r.joint_coverage.n,
        r.joint_coverage.max_z,
        r.joint_s0
    );
    // The selection keeps the tool (the plate on the flange) and the joint zero offsets before
    // per-joint corrections, so fewer robot parameters are free than the 26 of the earlier
    // selection (20 on this seed, 19 with a standard deviation in the joint adjustment).
    assert!(r.joint_coverage.n >= 15, "{} free robot parameters", r.joint_coverage.n);
    assert!(
        r.joint.rms_mm <= 1.5 * r.tracker.rms_mm,
        "joint {:.4} mm against the tracker model's {:.4} mm",
        r.joint.rms_mm,
        r.tracker.rms_mm
    );
    assert!(
        r.joint_coverage.fraction() >= 0.9,
        "{}/{} parameters within 3 sigma",
        r.joint_coverage.within_3sigma,
        r.joint_coverage.n
    );
    assert!(r.joint.rms_mm < r.nominal.rms_mm / 3.0, "joint {:.4} vs nominal {:.4}", r.joint.rms_mm, r.nominal.rms_mm);
    assert!((0.8..1.25).contains(&r.joint_s0), "s0 {}", r.joint_s0);
}
