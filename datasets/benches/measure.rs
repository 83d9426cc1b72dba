//! Measuring a 100-image recording (`ferrocal measure --images ... --poses ...`,
//! [`ferrocal_datasets::recording::measure_recording`]) on one worker thread and on all of them:
//! the images are read and searched in parallel, so the time should fall with the cores.
//! The recording (1280 x 960 renders of a 9 x 6 chessboard on the flange, eye-to-hand, the true
//! camera given) is written once into a temporary folder. Run with
//! `cargo bench -p ferrocal-datasets --bench measure`; the medians are in BENCHMARKS.md.

use criterion::{criterion_group, criterion_main, Criterion};
use ferrocal_calib::handeye::Mount;
use ferrocal_datasets::handeye::{read_handeye_poses, write_rendered_recording, HandEyeSimConfig, RobotReading};
use ferrocal_datasets::recording::{measure_recording, RecordingOptions};
use ferrocal_vision::calib::CalibrationOptions;

fn measure(c: &mut Criterion) {
    let tmp = tempfile::tempdir().expect("temporary folder");
    let mut config = HandEyeSimConfig::default_for(Mount::EyeToHand);
    (config.n_train, config.n_test) = (100, 0);
    let rec = write_rendered_recording(&config, tmp.path(), 3).expect("rendered recording");
    let mut table = read_handeye_poses(tmp.path().join("poses.csv")).expect("poses table");
    for r in &mut table.rows {
        r.robot = RobotReading::Joints(vec![0.0; 6]);
    }
    table.joint_units = vec![ferrocal_datasets::import::JointUnit::Rad; 6];
    let mut images: Vec<_> =
        std::fs::read_dir(tmp.path().join("images")).expect("images").map(|e| e.expect("entry").path()).collect();
    images.sort();
    let opts = RecordingOptions {
        mount: Mount::EyeToHand,
        camera: Some(rec.camera),
        calibration: CalibrationOptions::default(),
        corner_sigma_px: 0.1,
    };
    let pattern = rec.pattern.parse().expect("pattern");
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut g = c.benchmark_group(format!("measure_{}_images", images.len()));
    g.sample_size(10);
    for threads in [1, cores] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
        g.bench_function(format!("{threads}_threads"), |b| {
            b.iter(|| pool.install(|| measure_recording(&images, &table, &pattern, &opts).expect("measured")))
        });
    }
    g.finish();
}

criterion_group!(benches, measure);
criterion_main!(benches);
