//! Where the calibration study's intrinsic errors come from
//! ([`ferrocal_datasets::render::calibration_errors`]): the structure of the corner errors of
//! the project's own corners and of OpenCV's on a seed's renders, and what parts of them do to
//! `fx fy cx cy`.
//!
//! `cargo run --release -p ferrocal-datasets --example calibration_errors -- --seeds 4,1`
//! options: `--seeds A,B,..` (4,1), `--draws N` (40 shuffles and sign flips), `--keep DIR`
//! (render into DIR and reuse the PNG files found there; they must come from the study's
//! default settings).

use ferrocal_datasets::render::calibration_errors::analyze;
use ferrocal_datasets::render::calibration_study::{opencv_views, own_views, render_seed, StudySettings};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |name: &str| args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).cloned();
    let seeds: Vec<u64> = value("--seeds")
        .unwrap_or_else(|| "4,1".into())
        .split(',')
        .map(|s| s.trim().parse().expect("--seeds"))
        .collect();
    let draws: usize = value("--draws").map_or(40, |v| v.parse().expect("--draws"));
    let tmp = tempfile::tempdir().expect("temporary folder");
    let keep = value("--keep");
    let dir = keep.clone().map_or_else(|| tmp.path().to_path_buf(), std::path::PathBuf::from);
    let settings = StudySettings { reuse_renders: keep.is_some(), ..StudySettings::default() };
    for seed in seeds {
        let rendered = render_seed(&settings, seed, &dir).expect("render");
        let k = rendered.truth.intrinsics;
        println!(
            "seed {seed}: truth fx {:.2} fy {:.2} cx {:.2} cy {:.2}, {:?}",
            k.fx_px, k.fy_px, k.cx_px, k.cy_px, rendered.truth.distortion
        );
        for (label, views) in
            [("own corners", own_views(&settings, &rendered)), ("OpenCV corners", opencv_views(&settings, &rendered))]
        {
            match analyze(&settings, &rendered, &views, draws) {
                Ok(a) => println!("-- {label}:\n{}", a.report()),
                Err(e) => println!("-- {label}: failed: {e}"),
            }
        }
    }
}
