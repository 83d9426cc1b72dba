//! Side-by-side timing (one process, interleaved runs, medians) of this project's detectors
//! against OpenCV and the AprilTag libraries; prints a markdown table with ratios.
//!
//! `cargo run --release -p ferrocal-vision --example speed [-- runs]`

#[path = "../tests/support/synth.rs"]
mod synth;

use std::time::Instant;

use ferrocal_vision::detect::apriltag::{AprilTagDetector, AprilTagOptions, TagBackend, TagRefine};
use ferrocal_vision::detect::baseline::{opencv_find_chessboard, opencv_find_chessboard_sb};
use ferrocal_vision::detect::{detect, load_gray, DetectOptions, Pattern, TagFamily};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

type Job<'a> = (&'a str, Box<dyn FnMut() + 'a>);

/// Runs every job `runs` times, interleaved (job 1, job 2, ..., job 1, ...), and returns the
/// median wall time of each, milliseconds.
fn race(jobs: &mut [Job], runs: usize) -> Vec<f64> {
    let mut t = vec![Vec::new(); jobs.len()];
    for (_, f) in jobs.iter_mut() {
        f(); // warm-up
    }
    for _ in 0..runs {
        for (k, (_, f)) in jobs.iter_mut().enumerate() {
            let t0 = Instant::now();
            f();
            t[k].push(t0.elapsed().as_secs_f64() * 1e3);
        }
    }
    t.into_iter().map(median).collect()
}

fn table(title: &str, names: &[&str], ms: &[f64], reference: usize) {
    println!("\n### {title}\n\n| method | median ms | ratio to {} |\n|---|---|---|", names[reference]);
    for (n, m) in names.iter().zip(ms) {
        println!("| {n} | {m:.1} | {:.2} |", m / ms[reference]);
    }
}

fn main() {
    let runs: usize = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(7);
    println!(
        "{runs} interleaved runs per method, median wall time; threads: OpenCV default, ferrocal one per \
         core ({}), AprilTag C 1 thread.",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    // Chessboard 25x17 (425 corners), 2 MP, tilted, JPEG quality 90.
    let (_, img) = synth::chessboard_2mp_jpeg();
    let pattern: Pattern = "chessboard:25x17:25mm".parse().unwrap();
    let mut jobs: Vec<Job> = vec![
        (
            "ferrocal detect + edge refinement",
            Box::new(|| drop(detect(&img, &pattern, &DetectOptions::default(), None).unwrap())),
        ),
        (
            "ferrocal detect (coarse)",
            Box::new(|| {
                drop(detect(&img, &pattern, &DetectOptions { refine: false, ..Default::default() }, None).unwrap())
            }),
        ),
        (
            "OpenCV findChessboardCornersSB",
            Box::new(|| drop(opencv_find_chessboard_sb(&img, 25, 17, false).unwrap().unwrap())),
        ),
        (
            "OpenCV findChessboardCorners + cornerSubPix 11x11",
            Box::new(|| drop(opencv_find_chessboard(&img, 25, 17, Some(5)).unwrap().unwrap())),
        ),
    ];
    let names: Vec<&str> = jobs.iter().map(|j| j.0).collect();
    let ms = race(&mut jobs, runs);
    table("Chessboard 25x17 (425 corners), 1920x1080 (2 MP), tilted, squares ~42-56 px, JPEG q90", &names, &ms, 2);
    // Chessboard, 5 MP.
    let img = synth::render(&synth::chessboard_scene(2592, 1944, 9, 6, 120.0, 0, 1.0, 2.0));
    let pattern: Pattern = "chessboard:9x6:25mm".parse().unwrap();
    let mut jobs: Vec<Job> = vec![
        (
            "ferrocal detect + edge refinement",
            Box::new(|| drop(detect(&img, &pattern, &DetectOptions::default(), None).unwrap())),
        ),
        (
            "ferrocal detect (coarse)",
            Box::new(|| {
                drop(detect(&img, &pattern, &DetectOptions { refine: false, ..Default::default() }, None).unwrap())
            }),
        ),
        (
            "OpenCV findChessboardCornersSB",
            Box::new(|| drop(opencv_find_chessboard_sb(&img, 9, 6, false).unwrap().unwrap())),
        ),
        (
            "OpenCV findChessboardCornersSB (ACCURACY)",
            Box::new(|| drop(opencv_find_chessboard_sb(&img, 9, 6, true).unwrap().unwrap())),
        ),
        (
            "OpenCV findChessboardCorners + cornerSubPix 11x11",
            Box::new(|| drop(opencv_find_chessboard(&img, 9, 6, Some(5)).unwrap().unwrap())),
        ),
    ];
    let names: Vec<&str> = jobs.iter().map(|j| j.0).collect();
    let ms = race(&mut jobs, runs);
    table("Chessboard 9x6, 2592x1944 (5 MP), squares ~120 px", &names, &ms, 2);
    // Plate, 5 MP.
    let img = synth::render(&synth::plate_scene(2592, 1944, 200.0, 1, 1.0, 2.0));
    let pattern: Pattern = "plate:40mm".parse().unwrap();
    let mut jobs: Vec<Job> = vec![
        (
            "ferrocal plate detect + edge refinement",
            Box::new(|| drop(detect(&img, &pattern, &DetectOptions::default(), None).unwrap())),
        ),
        (
            "ferrocal plate detect (coarse)",
            Box::new(|| {
                drop(detect(&img, &pattern, &DetectOptions { refine: false, ..Default::default() }, None).unwrap())
            }),
        ),
    ];
    let names: Vec<&str> = jobs.iter().map(|j| j.0).collect();
    let ms = race(&mut jobs, runs);
    table("Gantry-Tau plate, 2592x1944 (5 MP), squares ~200 px", &names, &ms, 0);
    // AprilTags, NASA photo (799x533, 25 tags).
    let img =
        load_gray(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/apriltag_nasa/34085369442_304b6bafd9_c.jpg"))
            .unwrap();
    let mk = |o: AprilTagOptions| AprilTagDetector::new(TagFamily::Tag36h11, o).unwrap();
    let mut c1 = mk(AprilTagOptions::default());
    let mut c2 = mk(AprilTagOptions { decimation: 2.0, ..Default::default() });
    let mut k1 = mk(AprilTagOptions { backend: TagBackend::Kornia, ..Default::default() });
    let mut k2 = mk(AprilTagOptions { backend: TagBackend::Kornia, decimation: 2.0, ..Default::default() });
    let mut e1 = mk(AprilTagOptions { refine: TagRefine::EdgeModel, ..Default::default() });
    let mut jobs: Vec<Job> = vec![
        ("AprilTag C, decimation 1 (ferrocal default)", Box::new(|| drop(c1.detect(&img).unwrap()))),
        ("AprilTag C, decimation 2", Box::new(|| drop(c2.detect(&img).unwrap()))),
        ("kornia-apriltag, decimation 1", Box::new(|| drop(k1.detect(&img).unwrap()))),
        ("kornia-apriltag, decimation 2", Box::new(|| drop(k2.detect(&img).unwrap()))),
        ("AprilTag C + ferrocal edge-model refinement", Box::new(|| drop(e1.detect(&img).unwrap()))),
    ];
    let names: Vec<&str> = jobs.iter().map(|j| j.0).collect();
    let ms = race(&mut jobs, runs * 3);
    table("AprilTag photo 34085369442 (799x533, 25 tags)", &names, &ms, 0);
}
