//! Measures a session with the cameras and compares with its tracker:
//! `cargo run --release -p ferrocal-datasets --example measure_session -- SESSION [truth]`.
use ferrocal_calib::kinematic::KinematicOptions;
use ferrocal_datasets::measure::{compare_with_tracker, measure_session, CornerSource, MeasureOptions};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = std::path::Path::new(&args[1]);
    let corners = if args.get(2).map(String::as_str) == Some("truth") {
        CornerSource::TruthWithNoise { sigma_px: 0.05, seed: 5 }
    } else {
        CornerSource::Detector
    };
    let opts = MeasureOptions { corners, corner_sigma_px: 0.05, calibration: Default::default() };
    let t = std::time::Instant::now();
    let m = measure_session(dir, &opts).unwrap();
    println!(
        "measured {} poses in {:.1} s; rig RMS {:.4} px; skipped {:?}",
        m.poses.len(),
        t.elapsed().as_secs_f64(),
        m.rig.rms_px,
        m.skipped
    );
    let tracker = ferrocal_datasets::import::read_measurements(dir.join("tracker.csv")).unwrap().set;
    let truth: ferrocal_datasets::sim::SessionTruth =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth/truth.json")).unwrap()).unwrap();
    for (name, cam) in &truth.t_world_cam {
        let _ = (name, cam);
    }
    let model = ferrocal_robot::RobotModel::load(&truth.cell.robot.model).unwrap();
    let c = compare_with_tracker(&model, &m.rows, &tracker, &m.poses, &KinematicOptions::default()).unwrap();
    println!(
        "camera vs tracker mean {:.4} mm; held out: tracker-cal {:.4}, camera-cal {:.4}, nominal {:.4} mm",
        c.camera_mean_mm, c.tracker_model.mean_mm, c.camera_model.mean_mm, c.nominal_model.mean_mm
    );
    for (k, cal) in m.rig.cameras.iter().enumerate() {
        println!("camera {k}: {:?} rms {:.4}", cal.camera.intrinsics, cal.rms_px);
    }
}
