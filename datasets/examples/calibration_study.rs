//! The calibration study ([`ferrocal_datasets::render::calibration_study`]): `camera
//! calibrate`'s default (own corners) against OpenCV's calibrateCamera on its own corners, on
//! independent supersampled renders with known truth.
//!
//! `cargo run --release -p ferrocal-datasets --example calibration_study -- --seeds 10`
//! options: `--seeds N` (10), `--first-seed S` (0), `--views N` (18), `--size WxH` (1280x960),
//! `--subsamples S` (8), `--psf SIGMA` (0.8), `--jpeg Q` (off), `--keep DIR` (keep the PNG files;
//! with `--reuse` files already there are used instead of rendering them again),
//! `--json FILE` (the per-seed results).

use ferrocal_datasets::render::calibration_study::{markdown, run_seed, summarize, StudySettings};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |name: &str| args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).cloned();
    let num = |name: &str, default: f64| value(name).map_or(default, |v| v.parse().expect(name));
    let seeds = num("--seeds", 10.0) as u64;
    let first = num("--first-seed", 0.0) as u64;
    let mut settings = StudySettings { views: num("--views", 18.0) as usize, ..StudySettings::default() };
    if let Some(size) = value("--size") {
        let (w, h) = size.split_once('x').expect("--size WxH");
        settings.width = w.parse().expect("--size");
        settings.height = h.parse().expect("--size");
    }
    settings.render.subsamples = num("--subsamples", 8.0) as u32;
    settings.render.psf_sigma_px = num("--psf", settings.render.psf_sigma_px);
    settings.render.jpeg_quality = value("--jpeg").map(|q| q.parse().expect("--jpeg"));
    settings.reuse_renders = args.iter().any(|a| a == "--reuse");
    let tmp = tempfile::tempdir().expect("temporary folder");
    let dir = value("--keep").map_or_else(|| tmp.path().to_path_buf(), std::path::PathBuf::from);
    println!("{settings:?}");
    let mut results = Vec::new();
    for seed in first..first + seeds {
        let start = std::time::Instant::now();
        match run_seed(&settings, seed, &dir) {
            Ok(r) => {
                println!(
                    "seed {seed}: ratio {:.2}, RMS error ours {:.3} px / OpenCV {:.3} px, ours within 3 sigma {:?} ({:.0} s)",
                    r.ratio,
                    r.ours.rms_error_px,
                    r.opencv.rms_error_px,
                    r.ours.within_3_sigma,
                    start.elapsed().as_secs_f64()
                );
                results.push(r);
            }
            Err(e) => println!("seed {seed}: failed: {e}"),
        }
    }
    let summary = summarize(&results);
    println!("\n{}", markdown(&results, &summary));
    if let Some(path) = value("--json") {
        let json = serde_json::json!({ "results": results, "summary": summary });
        std::fs::write(&path, serde_json::to_string_pretty(&json).unwrap()).expect("--json");
    }
}
