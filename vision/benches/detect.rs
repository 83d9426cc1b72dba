//! Detection speed: this project's detectors against OpenCV and the AprilTag libraries on the
//! same images (real-like renders of large chessboards, procedural chessboards at 5 MP and
//! 2 MP, ChArUco boards and circle grids on the
//! ROS-Industrial industrial_calibration example data, Apache-2.0). Run with `cargo bench --workspace --bench detect`; the side-by-side
//! medians and ratios come from `cargo run --release -p ferrocal-vision --example speed`
//! (see BENCHMARKS.md).

#[path = "../tests/support/reallike.rs"]
mod reallike;
#[path = "../tests/support/synth.rs"]
mod synth;

use criterion::{criterion_group, criterion_main, Criterion};
use ferrocal_vision::detect::apriltag::{AprilTagDetector, AprilTagOptions, TagBackend, TagRefine};
use ferrocal_vision::detect::aruco::{opencv_charuco_corners, MarkerParams};
use ferrocal_vision::detect::baseline::{opencv_find_chessboard, opencv_find_chessboard_sb, opencv_find_circles_grid};
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

/// A 2 MP (1920 x 1080) tilted view of a 25 x 17 chessboard (425 corners, squares of about
/// 42 to 56 px), blur 1 px, noise 2 DN, JPEG quality 90.
fn chessboard_2mp(c: &mut Criterion) {
    let (_, img) = synth::chessboard_2mp_jpeg();
    let pattern: Pattern = "chessboard:25x17:25mm".parse().unwrap();
    let mut g = c.benchmark_group("chessboard_2mp_425");
    g.sample_size(10);
    g.bench_function("ferrocal_detect_refine", |b| {
        b.iter(|| detect(&img, &pattern, &DetectOptions::default(), None).unwrap())
    });
    g.bench_function("ferrocal_detect_coarse", |b| {
        b.iter(|| detect(&img, &pattern, &DetectOptions { refine: false, ..Default::default() }, None).unwrap())
    });
    g.bench_function("opencv_sb", |b| b.iter(|| opencv_find_chessboard_sb(&img, 25, 17, false).unwrap().unwrap()));
    g.bench_function("opencv_classic_subpix11", |b| {
        b.iter(|| opencv_find_chessboard(&img, 25, 17, Some(5)).unwrap().unwrap())
    });
    g.finish();
}

/// The real-like set (`tests/support/reallike.rs`: colour sensor with bilinear demosaicing,
/// defocus varying across the frame, vignetting, uneven light, glare, background clutter,
/// PNG or JPEG): a 1928 x 1208 PNG of a 28 x 17 board (476 corners, squares 33-40 px) and a
/// 2448 x 2048 JPEG of a 30 x 19 board (570 corners, rolled 24 degrees); ferrocal's detection
/// and refinement against `findChessboardCornersSB`, side by side in one group.
fn chessboard_reallike(c: &mut Criterion) {
    for name in ["r00_1928x1208_28x17_png", "r03_2448x2048_30x19_jpg"] {
        let view = reallike::views().into_iter().find(|v| v.name == name).expect("view");
        let img = reallike::render_gray(&view);
        let pattern: Pattern = view.pattern().parse().unwrap();
        let (cols, rows) = (view.cols as u32, view.rows as u32);
        let mut g = c.benchmark_group(format!("reallike_{name}"));
        g.sample_size(10);
        g.bench_function("ferrocal_detect_refine", |b| {
            b.iter(|| detect(&img, &pattern, &DetectOptions::default(), None).unwrap())
        });
        // SB does not find the board in every view of the set (r03): timed all the same.
        g.bench_function("opencv_sb", |b| b.iter(|| opencv_find_chessboard_sb(&img, cols, rows, false).unwrap()));
        g.finish();
    }
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

/// An image of the ROS-Industrial industrial_calibration example data (Apache-2.0).
fn industrial(set: &str, image: &str) -> image::GrayImage {
    load_gray(format!("{}/../../shared/data/industrial_calibration/{set}/images/{image}", env!("CARGO_MANIFEST_DIR")))
        .unwrap()
}

/// ChArUco, 1600 x 1200, the whole 5 x 7 board (24 corners): ours (OpenCV's marker decoding,
/// own corner refinement with covariances) against OpenCV's `interpolateCornersCharuco`.
fn charuco(c: &mut Criterion) {
    let img = industrial("test_set_charuco", "10.png");
    let pattern: Pattern = "charuco:5x7:36.195mm:18.256mm:DICT_6X6_250".parse().unwrap();
    let Pattern::Charuco(board) = pattern else { unreachable!() };
    let mut g = c.benchmark_group("charuco_1600x1200");
    g.sample_size(10);
    g.bench_function("ferrocal_detect_refine", |b| {
        b.iter(|| detect(&img, &pattern, &DetectOptions::default(), None).unwrap())
    });
    g.bench_function("opencv_interpolate_corners_charuco", |b| {
        b.iter(|| opencv_charuco_corners(&img, &board, MarkerParams::OpenCv, 2).unwrap())
    });
    g.finish();
}

/// A modified 10 x 10 circle grid, 640 x 480 (Kinect): ours against `findCirclesGrid`.
fn circle_grid(c: &mut Criterion) {
    let img = industrial("test_set_10x10", "0.png");
    let pattern: Pattern = "circlegrid:10x10:25.4mm:modified".parse().unwrap();
    let mut g = c.benchmark_group("circlegrid_640x480");
    g.sample_size(20);
    g.bench_function("ferrocal_detect", |b| {
        b.iter(|| detect(&img, &pattern, &DetectOptions::default(), None).unwrap())
    });
    g.bench_function("opencv_find_circles_grid", |b| {
        b.iter(|| opencv_find_circles_grid(&img, 10, 10).unwrap().unwrap())
    });
    g.finish();
}

criterion_group!(benches, chessboard_reallike, chessboard, chessboard_2mp, plate, apriltag, charuco, circle_grid);
criterion_main!(benches);
