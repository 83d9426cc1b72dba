//! The source's end-to-end experiment, simulated: the L1 with two cameras and a laser tracker,
//! poses on a grid; the camera system against the tracker, and the model calibrated from the
//! cameras against the one calibrated from the tracker on held-out tracker poses. Corners are
//! the exact ones plus noise of the size the project's detector reaches (the detector itself is
//! tested on rendered images elsewhere), so this checks everything after detection.

use std::path::Path;

use ferrocal_calib::kinematic::KinematicOptions;
use ferrocal_datasets::import::read_measurements;
use ferrocal_datasets::measure::{compare_with_tracker, measure_session, CornerSource, MeasureOptions};
use ferrocal_datasets::sim::{simulate, CellConfig};
use ferrocal_robot::RobotModel;
use ferrocal_vision::calib::CalibrationOptions;

#[test]
fn l1_cameras_against_the_tracker() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("cells/gantry_tau_l1.toml");
    let mut cfg = CellConfig::from_file(&path).unwrap();
    cfg.render_images = false;
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("s");
    simulate(&cfg, &dir, false, |_, _| {}).unwrap();
    let opts = MeasureOptions {
        corners: CornerSource::TruthWithNoise { sigma_px: 0.05, seed: 5 },
        corner_sigma_px: 0.05,
        calibration: CalibrationOptions::default(),
    };
    let m = measure_session(&dir, &opts).unwrap();
    assert!(m.skipped.is_empty(), "{:?}", m.skipped);
    let tracker = read_measurements(dir.join("tracker.csv")).unwrap().set;
    let model = RobotModel::load(&cfg.robot.model).unwrap();
    let c = compare_with_tracker(&model, &m.rows, &tracker, &m.poses, &KinematicOptions::default()).unwrap();
    eprintln!(
        "rig RMS {:.4} px; camera vs tracker: mean {:.4} mm over {} poses; held out: tracker-calibrated {:.4} mm, camera-calibrated {:.4} mm, nominal {:.4} mm (means)",
        m.rig.rms_px, c.camera_mean_mm, c.n_common, c.tracker_model.mean_mm, c.camera_model.mean_mm, c.nominal_model.mean_mm
    );
    assert!(c.camera_mean_mm < 0.10, "camera system {:.4} mm from the tracker", c.camera_mean_mm);
    assert!(
        c.camera_model.mean_mm < 1.5 * c.tracker_model.mean_mm,
        "camera-calibrated {:.4} mm vs tracker-calibrated {:.4} mm",
        c.camera_model.mean_mm,
        c.tracker_model.mean_mm
    );
}
