//! The must-hold of the default `camera calibrate` on independent renders
//! (`ferrocal_datasets::render::calibration_study`, supersampled renderer, not the one the
//! detector was tuned on): at least 1.5 times closer to the true fx, fy, cx, cy than OpenCV's
//! calibrateCamera on its own corners (RMS over the four errors), and the truth within 3
//! reported sigmas. A small version (800 x 600, 4 x 4 sub-samples, 12 views) of
//! `cargo run --release -p ferrocal-datasets --example calibration_study`.

use ferrocal_datasets::render::calibration_study::{run_seed, StudySettings};
use ferrocal_datasets::render::supersampled::SupersampledConfig;

#[test]
fn own_corners_calibrate_closer_than_opencv_and_within_three_sigma() {
    let settings = StudySettings {
        views: 12,
        width: 800,
        height: 600,
        render: SupersampledConfig { subsamples: 4, ..SupersampledConfig::default() },
        ..StudySettings::default()
    };
    let dir = tempfile::tempdir().unwrap();
    for seed in [3u64, 5] {
        let r = run_seed(&settings, seed, dir.path()).unwrap();
        let (o, c) = (&r.ours, &r.opencv);
        eprintln!(
            "seed {seed}: ours err {:?} std {:?} (jackknife {:?}, sandwich {:?}; {} views, corners {:.4} px); OpenCV err {:?} ({} views, corners {:.4} px); ratio {:.2}",
            o.abs_error_px, o.std_px, o.std_jackknife_px, o.std_sandwich_px, o.views, o.corner_rms_px, c.abs_error_px, c.views, c.corner_rms_px, r.ratio
        );
        // Every view is found by both sides (the whole board is always in view).
        assert_eq!((o.views, c.views), (12, 12), "seed {seed}");
        assert!(o.rms_error_px.is_finite() && c.rms_error_px.is_finite() && o.rms_error_px > 0.0);
        assert!(r.ratio >= 1.5, "seed {seed}: OpenCV / ours = {:.2} (< 1.5)", r.ratio);
        assert!(
            o.within_3_sigma.iter().all(|w| *w),
            "seed {seed}: errors {:?} px against 3 sigma {:?} px",
            o.abs_error_px,
            o.std_px.map(|s| 3.0 * s)
        );
        // The view-clustered covariances (views independent, corners of a view possibly
        // correlated) cover the truth too, and stay within a factor of 3 of the
        // independent-corner sigmas (not absurdly pessimistic or optimistic).
        for (name, std) in [("jackknife", o.std_jackknife_px), ("sandwich", o.std_sandwich_px)] {
            for (i, ((err, s), s_ind)) in o.abs_error_px.iter().zip(std).zip(o.std_independent_px).enumerate() {
                assert!(
                    *err <= 3.0 * s,
                    "seed {seed} {name}: error {err:.4} px beyond 3 sigma ({s:.4} px), parameter {i}"
                );
                let r = s / s_ind;
                assert!((1.0 / 3.0..3.0).contains(&r), "seed {seed} {name}: sigma {r:.2} x independent, parameter {i}");
            }
        }
    }
}
