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
        "seed {seed}: held-out RMS tracker {:.4} (floor {:.4}), two-step {:.4} (true camera {:.4}), joint {:.4}, nominal {:.4} mm; joint parameters within 3 sigma {}/{} (max z {:.2}), s0 {:.3}",
        r.tracker.rms_mm,
        r.noise_floor_mm,
        r.two_step.rms_mm,
        r.two_step_true_camera.rms_mm,
        r.joint.rms_mm,
        r.nominal.rms_mm,
        r.joint_coverage.within_3sigma,
        r.joint_coverage.n,
        r.joint_coverage.max_z,
        r.joint_s0
    );
    // The selection keeps the plate's pose on the flange as the tool (not a robot parameter)
    // and the joint zero offsets before per-joint corrections: the 26 robot parameters of the
    // earlier selection counted joint 6's corrections, which are that pose. On this seed 19
    // are free: the zero offsets of joints 1-5 and 14 corrections of joints 1-5 (joint 6's zero
    // offset is the plate's rotation about the flange axis).
    assert!(r.joint_coverage.n >= 19, "{} free robot parameters", r.joint_coverage.n);
    // The tracker calibration itself reaches the held-out table's noise floor (it was 0.249 mm
    // against a floor of about 0.03 mm when the selection was judged with the target on the
    // flange, which fixed joint 5's corrections and joint 6's zero offset).
    assert!(
        r.tracker.rms_mm <= 1.5 * r.noise_floor_mm,
        "tracker model {:.4} mm, noise floor {:.4} mm",
        r.tracker.rms_mm,
        r.noise_floor_mm
    );
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
