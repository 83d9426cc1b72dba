//! The real-like benchmark set (`tests/support/reallike.rs`: renders degraded like shop
//! photographs, exact truth) and the shared real images, side by side with OpenCV in one
//! process: per image, interleaved runs, medians; per-stage times of ferrocal; corner RMS on
//! truth (renders) for both; found / not found with the reason.
//!
//! ```text
//! cargo run --release -p ferrocal-vision --example realistic -- time [runs] [--threads N]
//! cargo run --release -p ferrocal-vision --example realistic -- write <dir>
//! cargo run --release -p ferrocal-vision --example realistic -- charuco [runs] [--threads N]
//! ```
//!
//! `charuco` runs only the ChArUco part: per image, ferrocal with the markers decoded at
//! full resolution (the detector before the coarse-to-fine marker search), ferrocal as it is
//! (half resolution first) and OpenCV, interleaved.
//!
//! `--threads 1` runs ferrocal (rayon) and OpenCV on one thread each. The shared real images
//! are the ROS-Industrial industrial_calibration example data (Apache-2.0,
//! `test_set_charuco`, 16 images 1600x1200) and OpenCV's stereo sample (`opencv_stereo`, 26
//! images 640x480, Apache-2.0).

#[path = "../tests/support/reallike.rs"]
mod reallike;
#[path = "../tests/support/synth.rs"]
mod synth;

use std::time::Instant;

use ferrocal_vision::detect::aruco::{opencv_charuco_corners, MarkerParams};
use ferrocal_vision::detect::baseline::opencv_find_chessboard_sb;
use ferrocal_vision::detect::{detect, detect_timed, load_gray, DetectOptions, Pattern, StageTimings};
use nalgebra::Point2;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// RMS distance of each found point to its nearest truth point (within `max_px`), and the
/// number matched.
fn rms_to_truth(found: &[Point2<f64>], truth: &[Point2<f64>], max_px: f64) -> (f64, usize) {
    let mut s = 0.0;
    let mut n = 0;
    for p in found {
        let d = truth.iter().map(|t| (t - p).norm()).fold(f64::INFINITY, f64::min);
        if d < max_px {
            s += d * d;
            n += 1;
        }
    }
    ((s / n.max(1) as f64).sqrt(), n)
}

fn stages_line(t: &StageTimings) -> String {
    format!(
        "convert {:.1} / candidates {:.1} ({}) / grid {:.1} / refine {:.1} ({} passes, {} lines, {} px) / covariance {:.1} / total {:.1} ms",
        t.convert_ms,
        t.candidates_ms,
        t.candidates,
        t.grid_ms,
        t.refine_ms,
        t.refine_passes,
        t.lines,
        t.band_pixels,
        t.covariance_ms,
        t.total_ms
    )
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let threads = args.iter().position(|a| a == "--threads").and_then(|k| args.get(k + 1)).and_then(|v| v.parse().ok());
    if let Some(n) = threads {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().expect("rayon pool");
        opencv::core::set_num_threads(n as i32).expect("OpenCV threads");
    }
    match args.first().map(String::as_str) {
        Some("write") => write(args.get(1).expect("write <dir>")),
        Some("markers") => markers(),
        Some("charuco") => charuco(args.get(1).and_then(|a| a.parse().ok()).unwrap_or(3)),
        _ => {
            let runs: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(3);
            time(runs, threads);
        }
    }
}

fn write(dir: &str) {
    std::fs::create_dir_all(dir).expect("output folder");
    for v in reallike::views() {
        let rgb = reallike::render_rgb(&v);
        let path = format!("{dir}/{}.{}", v.name, reallike::extension(&v));
        std::fs::write(&path, reallike::encode(&v, &rgb)).expect("write image");
        let truth: Vec<[f64; 2]> = v.truth().iter().map(|p| [p.x, p.y]).collect();
        let json = format!(
            "{{\"pattern\": \"{}\", \"corners_px\": {}}}",
            v.pattern(),
            serde_json::to_string(&truth).expect("json")
        );
        std::fs::write(format!("{dir}/{}.truth.json", v.name), json).expect("write truth");
        let s = v.stats();
        println!(
            "{path}: {}x{} {} corners, squares {:.0}-{:.0} px, coverage {:.0} %, tilt {:.0} deg",
            v.scene.width,
            v.scene.height,
            v.cols * v.rows,
            s.min_square_px,
            s.max_square_px,
            100.0 * s.coverage,
            v.tilt_deg
        );
    }
}

fn time(runs: usize, threads: Option<usize>) {
    println!(
        "{runs} interleaved runs per method and image, median wall time; threads: {}",
        threads.map_or("ferrocal one per core, OpenCV default".to_string(), |n| format!("{n} (ferrocal and OpenCV)"))
    );
    println!("\n### Real-like renders (tests/support/reallike.rs), ferrocal detect + refinement against findChessboardCornersSB\n");
    println!("| image | corners | squares px | coverage | tilt | ferrocal ms | SB ms | ratio | ferrocal RMS px | SB RMS px | found (ours / SB) |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let (mut sum_ours, mut sum_sb) = (0.0, 0.0);
    let (mut e_ours, mut n_ours, mut e_sb, mut n_sb) = (0.0, 0usize, 0.0, 0usize);
    let mut stage_lines = Vec::new();
    for v in reallike::views() {
        let img = reallike::render_gray(&v);
        let truth = v.truth();
        let stats = v.stats();
        let pattern: Pattern = v.pattern().parse().unwrap();
        let options = DetectOptions::default();
        let (first, timings) = detect_timed(&img, &pattern, &options, None);
        let ours_found = first.as_ref().map(|d| d[0].corners_px()).map_err(|e| e.to_string());
        let sb_found = opencv_find_chessboard_sb(&img, v.cols as u32, v.rows as u32, false).unwrap();
        let (mut t_ours, mut t_sb) = (Vec::new(), Vec::new());
        for _ in 0..runs {
            let t0 = Instant::now();
            let _ = detect(&img, &pattern, &options, None);
            t_ours.push(t0.elapsed().as_secs_f64() * 1e3);
            let t0 = Instant::now();
            let _ = opencv_find_chessboard_sb(&img, v.cols as u32, v.rows as u32, false);
            t_sb.push(t0.elapsed().as_secs_f64() * 1e3);
        }
        let (mo, ms) = (median(t_ours), median(t_sb));
        sum_ours += mo;
        sum_sb += ms;
        let half_square = 0.5 * stats.min_square_px;
        let fmt_rms = |f: &Result<Vec<Point2<f64>>, String>| match f {
            Ok(p) => {
                let (r, n) = rms_to_truth(p, &truth, half_square);
                format!("{r:.3} ({n})")
            }
            Err(_) => "-".into(),
        };
        if let Ok(p) = &ours_found {
            let (r, n) = rms_to_truth(p, &truth, half_square);
            e_ours += r * r * n as f64;
            n_ours += n;
        }
        if let Some(p) = &sb_found {
            let (r, n) = rms_to_truth(p, &truth, half_square);
            e_sb += r * r * n as f64;
            n_sb += n;
        }
        let sb_res: Result<Vec<Point2<f64>>, String> = sb_found.clone().ok_or_else(|| "not found".into());
        println!(
            "| {} | {} | {:.0}-{:.0} | {:.0} % | {:.0} deg | {mo:.0} | {ms:.0} | {:.2} | {} | {} | {} / {} |",
            v.name,
            v.cols * v.rows,
            stats.min_square_px,
            stats.max_square_px,
            100.0 * stats.coverage,
            v.tilt_deg,
            mo / ms,
            fmt_rms(&ours_found),
            fmt_rms(&sb_res),
            match &ours_found {
                Ok(p) => format!("{}", p.len()),
                Err(e) => format!("no: {e}"),
            },
            sb_found.as_ref().map_or("no".to_string(), |p| p.len().to_string()),
        );
        stage_lines.push(format!("- {}: {}", v.name, stages_line(&timings)));
    }
    println!(
        "| **all** | | | | | **{sum_ours:.0}** | **{sum_sb:.0}** | **{:.2}** | {:.3} | {:.3} | |",
        sum_ours / sum_sb,
        (e_ours / n_ours.max(1) as f64).sqrt(),
        (e_sb / n_sb.max(1) as f64).sqrt()
    );
    println!("\nferrocal per stage (first run of each image):\n");
    for l in stage_lines {
        println!("{l}");
    }
    charuco(runs);
    // Chessboard 9x6 on OpenCV's stereo sample.
    let pattern: Pattern = "chessboard:9x6:25mm".parse().unwrap();
    let (mut sum_ours, mut sum_sb, mut f_ours, mut f_sb) = (0.0, 0.0, 0, 0);
    let mut n = 0;
    for side in ["left", "right"] {
        for k in [1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 12, 13, 14] {
            let path = format!("{}/../../shared/data/opencv_stereo/{side}{k:02}.jpg", env!("CARGO_MANIFEST_DIR"));
            let img = load_gray(&path).unwrap();
            n += 1;
            f_ours += detect(&img, &pattern, &DetectOptions::default(), None).is_ok() as usize;
            f_sb += opencv_find_chessboard_sb(&img, 9, 6, false).unwrap().is_some() as usize;
            let (mut t_ours, mut t_sb) = (Vec::new(), Vec::new());
            for _ in 0..runs {
                let t0 = Instant::now();
                let _ = detect(&img, &pattern, &DetectOptions::default(), None);
                t_ours.push(t0.elapsed().as_secs_f64() * 1e3);
                let t0 = Instant::now();
                let _ = opencv_find_chessboard_sb(&img, 9, 6, false);
                t_sb.push(t0.elapsed().as_secs_f64() * 1e3);
            }
            sum_ours += median(t_ours);
            sum_sb += median(t_sb);
        }
    }
    println!("\n### Chessboard 9x6, real 640x480 (OpenCV stereo sample, opencv_stereo/left01..right14, {n} images)\n");
    println!("| method | sum of medians ms | ratio | found |\n|---|---|---|---|");
    println!("| ferrocal detect + refinement | {sum_ours:.0} | {:.2} | {f_ours}/{n} |", sum_ours / sum_sb);
    println!("| OpenCV findChessboardCornersSB | {sum_sb:.0} | 1.00 | {f_sb}/{n} |");
}

/// ChArUco on the shared real images: per image, ferrocal with the markers decoded at full
/// resolution, ferrocal coarse to fine (the default) and OpenCV's detectMarkers +
/// interpolateCornersCharuco, interleaved, medians; corners found by each; the largest shift
/// of a corner found by both ferrocal variants.
fn charuco(runs: usize) {
    println!("\n### ChArUco 5x7, real 1600x1200 images (ROS-Industrial industrial_calibration example data, Apache-2.0, test_set_charuco/images/0..15.png)\n");
    let pattern: Pattern = "charuco:5x7:36.195mm:18.256mm:DICT_6X6_250".parse().unwrap();
    let Pattern::Charuco(board) = pattern else { unreachable!() };
    let fine = DetectOptions::default();
    let mut full = DetectOptions::default();
    full.charuco.half_resolution_first = false;
    let (mut sums, mut found, mut corners) = ([0.0; 3], [0usize; 3], [0usize; 3]);
    let mut stage_lines = Vec::new();
    println!("| image | ms full-res markers | ms coarse-to-fine | ms OpenCV | ratio coarse-to-fine / OpenCV | corners full-res / coarse-to-fine / OpenCV | largest shift px |");
    println!("|---|---|---|---|---|---|---|");
    for k in 0..16 {
        let path = format!(
            "{}/../../shared/data/industrial_calibration/test_set_charuco/images/{k}.png",
            env!("CARGO_MANIFEST_DIR")
        );
        let img = load_gray(&path).unwrap();
        let (d_full, t_full) = detect_timed(&img, &pattern, &full, None);
        let (d_fine, t_fine) = detect_timed(&img, &pattern, &fine, None);
        let cv = opencv_charuco_corners(&img, &board, MarkerParams::OpenCv, 2).unwrap();
        let count = |d: &ferrocal_vision::Result<Vec<ferrocal_vision::detect::Detection>>| {
            d.as_ref().map_or(0, |d| d[0].corners.len())
        };
        let n = [count(&d_full), count(&d_fine), cv.len()];
        for (j, nj) in n.iter().enumerate() {
            corners[j] += nj;
            found[j] += usize::from(*nj > 0);
        }
        let mut shift: f64 = 0.0;
        if let (Ok(a), Ok(b)) = (&d_full, &d_fine) {
            for c in &a[0].corners {
                if let Some(q) = b[0].corners.iter().find(|q| q.point_id == c.point_id) {
                    shift = shift.max((q.position_px - c.position_px).norm());
                }
            }
        }
        let mut t: [Vec<f64>; 3] = Default::default();
        for _ in 0..runs {
            let t0 = Instant::now();
            let _ = detect(&img, &pattern, &full, None);
            t[0].push(t0.elapsed().as_secs_f64() * 1e3);
            let t0 = Instant::now();
            let _ = detect(&img, &pattern, &fine, None);
            t[1].push(t0.elapsed().as_secs_f64() * 1e3);
            let t0 = Instant::now();
            let _ = opencv_charuco_corners(&img, &board, MarkerParams::OpenCv, 2);
            t[2].push(t0.elapsed().as_secs_f64() * 1e3);
        }
        let m = t.map(median);
        for j in 0..3 {
            sums[j] += m[j];
        }
        println!(
            "| {k}.png | {:.0} | {:.0} | {:.0} | {:.2} | {} / {} / {} | {shift:.1e} |",
            m[0],
            m[1],
            m[2],
            m[1] / m[2],
            n[0],
            n[1],
            n[2]
        );
        stage_lines.push(format!("- {k}.png full-res markers: {}", stages_line(&t_full)));
        stage_lines.push(format!("- {k}.png coarse-to-fine: {}", stages_line(&t_fine)));
    }
    println!(
        "| **all 16** (sum of medians) | **{:.0}** | **{:.0}** | **{:.0}** | **{:.2}** | {} / {} / {} | |",
        sums[0],
        sums[1],
        sums[2],
        sums[1] / sums[2],
        corners[0],
        corners[1],
        corners[2]
    );
    println!(
        "\nper image: full-res markers {:.1} ms ({:.2} x OpenCV), coarse-to-fine {:.1} ms ({:.2} x OpenCV), OpenCV {:.1} ms; boards found {} / {} / {} of 16",
        sums[0] / 16.0,
        sums[0] / sums[2],
        sums[1] / 16.0,
        sums[1] / sums[2],
        sums[2] / 16.0,
        found[0],
        found[1],
        found[2]
    );
    println!("\nferrocal per stage (first run):\n");
    for l in stage_lines {
        println!("{l}");
    }
}

/// Marker decoding on the shared ChArUco images under several OpenCV parameter sets: markers
/// of the board decoded and time (sum of medians of 3 runs).
fn markers() {
    use opencv::core::{Mat, Point2f, Vector};
    use opencv::prelude::*;
    let dict = opencv::aruco::get_predefined_dictionary_i32(10).unwrap();
    let imgs: Vec<image::GrayImage> = (0..16)
        .map(|k| {
            load_gray(format!(
                "{}/../../shared/data/industrial_calibration/test_set_charuco/images/{k}.png",
                env!("CARGO_MANIFEST_DIR")
            ))
            .unwrap()
        })
        .collect();
    type Cfg = (&'static str, bool, bool, f32, i32);
    let cfgs: [Cfg; 6] = [
        ("opencv default", false, false, 0.0, 10),
        ("tolerant", true, false, 0.0, 10),
        ("tolerant, aruco3 ratio 0.02", true, true, 0.02, 10),
        ("tolerant, aruco3 ratio 0.03", true, true, 0.03, 10),
        ("tolerant, aruco3 ratio 0.0", true, true, 0.0, 10),
        ("tolerant, window step 20", true, false, 0.0, 20),
    ];
    for (name, tolerant, a3, ratio, step) in cfgs {
        let mut p = opencv::aruco::DetectorParameters::create().unwrap();
        if tolerant {
            p.set_perspective_remove_pixel_per_cell(8);
            p.set_perspective_remove_ignored_margin_per_cell(0.3);
            p.set_error_correction_rate(0.8);
        }
        if a3 {
            p.set_use_aruco3_detection(true);
            p.set_min_marker_length_ratio_original_img(ratio);
        }
        p.set_adaptive_thresh_win_size_step(step);
        let (mut n, mut total) = (0, 0.0);
        for img in &imgs {
            let flat = Mat::from_slice(img.as_raw()).unwrap();
            let mat = flat.reshape(1, img.height() as i32).unwrap().try_clone().unwrap();
            let mut t = Vec::new();
            for run in 0..3 {
                let mut corners: Vector<Vector<Point2f>> = Vector::new();
                let mut ids: Vector<i32> = Vector::new();
                let mut rejected: Vector<Vector<Point2f>> = Vector::new();
                let t0 = Instant::now();
                opencv::aruco::detect_markers(&mat, &dict, &mut corners, &mut ids, &p, &mut rejected).unwrap();
                t.push(t0.elapsed().as_secs_f64() * 1e3);
                if run == 0 {
                    n += ids.iter().filter(|&i| (0..17).contains(&i)).count();
                }
            }
            total += median(t);
        }
        println!("{name}: {n} of 272 markers, {total:.0} ms for 16 images");
    }
}
