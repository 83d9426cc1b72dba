//! Corrected joint commands on a simulated UR5 with known geometric errors (the [compensate]
//! check, `datasets::sim::corrected_commands_study`): the robot is calibrated from 6-DoF tracker
//! poses, a program of other commands is corrected through the calibration and run through the
//! true robot. The truth is the calibration's own model family (see the study's docs).

use ferrocal_datasets::checks::corrected_commands;
use ferrocal_datasets::sim::corrected_commands_study;

#[test]
fn corrected_commands_land_within_1_5x_of_the_held_out_calibration_error() {
    for seed in [31, 32, 33] {
        let s = corrected_commands_study(seed).unwrap();
        eprintln!(
            "seed {seed}: program of {} commands on the true robot: uncorrected {:.4} mm, corrected {:.4} mm; calibration held-out {:.4} mm",
            s.n_program, s.uncorrected_mm, s.corrected_mm, s.held_out_mm
        );
        assert!(s.max_model_residual_mm < 1e-4, "{s:?}");
        let c = corrected_commands(&s);
        assert!(!c.failed(), "{}", c.detail);
        assert!(s.corrected_mm < 0.2 * s.uncorrected_mm, "the correction must remove most of the error: {s:?}");
    }
}
