//! Detection speed: this project's detectors against OpenCV and the AprilTag libraries on the
//! same images. Run with `cargo bench -p ferrocal-vision --bench detect`; the side-by-side
//! medians and ratios come from `cargo run --release -p ferrocal-vision --example speed`
//! (see BENCHMARKS.md).

#[path = "../tests/support/synth.rs"]
mod synth;

use criterion::{criterion_group, criterion_main, Criterion};
use ferrocal_vision::detect::apriltag::{AprilTagDetector, AprilTagOptions, TagBackend, TagRefine};
use ferrocal_vision::detect::baseline::{opencv_find_chessboard, opencv_find_chessboard_sb};
use ferrocal_vision::detect::{detect, load_gray, DetectOptions, Pattern, TagFamily};

/// A 5 MP (2592 x 1944) view of a 9 x 6 chessboard with squares of about 120 px, blur 1 px,
/// noise 2 DN.
fn chessboard_5mp() -> image::GrayImage {
    synth::render(&synth::chessboard_scene(2592, 1944, 9, 6, 120.0, 0, 1.0, 2.0))
}

fn plate_5mp() -> image::GrayImage {
    synth::render(&synth::plate_scene(2592, 1944, 200.0, 1, 1.0, 2.0))
}

fn nasa() -> image::GrayImage {
    load_gray(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/apriltag_nasa/34085369442_304b6bafd9_c.jpg"))
        .unwrap()
}

fn chessboard(c: &mut Criterion) {
    let img = chessboard_5mp();
    let pattern: Pattern = "chessboard:9x6:25mm".parse().unwrap();
    let mut g = c.benchmark_group("chessboard_5mp");
    g.sample_size(10);
    g.bench_function("ferrocal_detect_refine", |b| {
        b.iter(|| detect(&img, &pattern, &DetectOptions::default(), None).unwrap())
    });
    g.bench_function("ferrocal_detect_coarse", |b| {
        b.iter(|| detect(&img, &pattern, &DetectOptions { refine: false, ..Default::default() }, None).unwrap())
    });
    g.bench_function("opencv_sb", |b| b.iter(|| opencv_find_chessboard_sb(&img, 9, 6, false).unwrap().unwrap()));
    g.bench_function("opencv_sb_accuracy", |b| {
        b.iter(|| opencv_find_chessboard_sb(&img, 9, 6, true).unwrap().unwrap())
    });
    g.bench_function("opencv_classic_subpix11", |b| {
        b.iter(|| opencv_find_chessboard(&img, 9, 6, Some(5)).unwrap().unwrap())
    });
    g.finish();
}

fn plate(c: &mut Criterion) {
    let img = plate_5mp();
    let pattern: Pattern = "plate:40mm".parse().unwrap();
    let mut g = c.benchmark_group("plate_5mp");
    g.sample_size(10);
    g.bench_function("ferrocal_detect_refine", |b| {
        b.iter(|| detect(&img, &pattern, &DetectOptions::default(), None).unwrap())
    });
    g.finish();
}

fn apriltag(c: &mut Criterion) {
    let img = nasa();
    let mut g = c.benchmark_group("apriltag_nasa_photo");
    g.sample_size(20);
    for (name, opts) in [
        ("c_library_decimate1", AprilTagOptions::default()),
        ("c_library_decimate2", AprilTagOptions { decimation: 2.0, ..Default::default() }),
        ("kornia_decimate1", AprilTagOptions { backend: TagBackend::Kornia, ..Default::default() }),
        ("c_library_edge_model", AprilTagOptions { refine: TagRefine::EdgeModel, ..Default::default() }),
    ] {
        let mut det = AprilTagDetector::new(TagFamily::Tag36h11, opts).unwrap();
        g.bench_function(name, |b| b.iter(|| det.detect(&img).unwrap()));
    }
    g.finish();
}

criterion_group!(benches, chessboard, plate, apriltag);
criterion_main!(benches);
