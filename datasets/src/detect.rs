//! The `detect` workflow: a pattern found in every image of a batch, with sub-pixel corners
//! ([`detect_images`], the images in parallel on the current rayon pool, the results in input
//! order), optionally against the static background of the same sequence
//! ([`median_background_of`]). An image that cannot be used never stops the batch: its result
//! says why.

use ferrocal_vision::detect::{load_gray, median_background, DetectOptions, Detector, ImageResult, Pattern};
use image::GrayImage;
use rayon::prelude::*;

use crate::error::{DatasetError, Result};
use crate::import::images::image_entries;

/// The per-pixel median of the images of `specs` (files, folders or globs), the static
/// background of a sequence; `None` without specifications. Every image must be readable.
pub fn median_background_of(specs: &[String]) -> Result<Option<GrayImage>> {
    if specs.is_empty() {
        return Ok(None);
    }
    let mut frames = Vec::new();
    for entry in image_entries(specs) {
        match entry {
            Ok(p) => frames.push(load_gray(&p)?),
            Err((name, reason)) => return Err(DatasetError::Input(format!("background image {name}: {reason}"))),
        }
    }
    Ok(Some(median_background(&frames).map_err(|e| DatasetError::from(e).context("background median"))?))
}

/// One line per image with its per-stage wall times (the results that carry them), for the
/// terminal: `<image>: read ... ms / candidates ... / total ... ms`.
pub fn timing_lines(results: &[ImageResult]) -> Vec<String> {
    results.iter().filter_map(|r| r.timings.as_ref().map(|t| format!("{}: {t}", r.image))).collect()
}

/// The terminal line of a batch's results written to `json`: in how many images the pattern
/// was found, how many failed.
pub fn summary_line(results: &[ImageResult], json: &std::path::Path) -> String {
    let failed = results.iter().filter(|r| r.error.is_some()).count();
    format!(
        "{} images: pattern found in {}, {} failed; wrote {}",
        results.len(),
        results.len() - failed,
        failed,
        json.display()
    )
}

/// Runs `work` on a rayon pool of `threads` workers (`None`: the global pool, every core
/// unless `RAYON_NUM_THREADS` says otherwise), with OpenCV limited to as many threads; refused
/// for 0 threads. Every parallel loop inside `work` (the images of [`detect_images`] and each
/// image's own) runs on that pool.
pub fn with_threads<R: Send>(threads: Option<usize>, work: impl FnOnce() -> R + Send) -> Result<R> {
    let Some(n) = threads else { return Ok(work()) };
    if n == 0 {
        return Err(DatasetError::Input("--threads must be at least 1".into()));
    }
    ferrocal_vision::backends::set_opencv_threads(n)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .map_err(|e| DatasetError::Input(format!("cannot start {n} worker threads: {e}")))?;
    Ok(pool.install(work))
}

/// Finds `pattern` in every image of `specs` (files, folders or globs; refused when they name
/// none) with `options`, against `background` when given: one result per image, in order. The
/// images are read and detected in parallel on the current rayon pool (one [`Detector`] per
/// worker; run inside `ThreadPool::install` to choose the threads); the results, and so the
/// JSON written from them, are the same, in the same order, on any number of threads. A failed
/// image's reason is given to `warn`, naming the image, in input order once the batch is
/// done. With `timed`, every result carries its per-stage wall times
/// ([`ImageResult::timings`]).
pub fn detect_images(
    specs: &[String],
    pattern: Pattern,
    options: DetectOptions,
    background: Option<GrayImage>,
    timed: bool,
    warn: &dyn Fn(&str),
) -> Result<Vec<ImageResult>> {
    let entries = image_entries(specs);
    if entries.is_empty() {
        return Err(DatasetError::Input("no images given".into()));
    }
    // Globs or folders that match no image file at all: no images (exit 1 as documented), not
    // a batch of failed images (exit 2).
    let unmatched: Vec<&str> = entries
        .iter()
        .filter_map(|e| match e {
            Err((name, reason)) if reason == "no image files match" => Some(name.as_str()),
            _ => None,
        })
        .collect();
    if unmatched.len() == entries.len() {
        return Err(DatasetError::Input(format!(
            "no images given: no image file matches {}; check the path (and quote a glob)",
            unmatched.join(", ")
        )));
    }
    // Checks the options once; every worker then builds its own detector (the AprilTag
    // decoder it may hold is not shared between threads).
    Detector::new(pattern, options.clone(), None)?;
    let new_detector = || {
        Detector::new(pattern, options.clone(), background.clone())
            .expect("the options were checked above")
            .with_timings(timed)
    };
    // One detector per rayon job (a run of images on one worker), not per image.
    let results: Vec<ImageResult> = entries
        .into_par_iter()
        .map_init(new_detector, |detector, entry| match entry {
            Ok(path) => detector.detect_file(&path),
            Err((name, reason)) => ImageResult::failed(name, reason),
        })
        .collect();
    for r in &results {
        if let Some(e) = &r.error {
            // The vision crate's messages already name the file; list_images' do not.
            if e.contains(&r.image) {
                warn(e);
            } else {
                warn(&format!("{}: {e}", r.image));
            }
        }
    }
    Ok(results)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    /// Four of the real ChArUco images (`../shared/data/industrial_calibration`, Apache-2.0)
    /// and a file that is no image, on 1 and on 3 worker threads: the same results, serialised
    /// to the same bytes, in the input order; the broken file is reported by name, once, and
    /// the images after it are still detected.
    #[test]
    fn parallel_batch_gives_the_serial_results_in_order() {
        let dir =
            concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/industrial_calibration/test_set_charuco/images");
        let tmp = tempfile::tempdir().unwrap();
        let bad = tmp.path().join("broken.png");
        std::fs::write(&bad, b"not a png").unwrap();
        let specs = vec![
            format!("{dir}/2.png"),
            bad.display().to_string(),
            format!("{dir}/10.png"),
            format!("{dir}/15.png"),
            format!("{dir}/4.png"),
        ];
        let pattern: Pattern = "charuco:5x7:36.195mm:18.256mm:DICT_6X6_250".parse().unwrap();
        let run = |threads: usize| {
            let warned = Mutex::new(Vec::new());
            let results = with_threads(Some(threads), || {
                detect_images(&specs, pattern, DetectOptions::default(), None, false, &|e| {
                    warned.lock().unwrap().push(e.to_string())
                })
            })
            .unwrap()
            .unwrap();
            (results, warned.into_inner().unwrap())
        };
        let (serial, warned_serial) = run(1);
        let (parallel, warned_parallel) = run(3);
        let names: Vec<&str> = serial.iter().map(|r| r.image.as_str()).collect();
        assert_eq!(names.len(), 5, "{names:?}");
        for (name, spec) in names.iter().zip(&specs) {
            assert!(name.ends_with(spec.rsplit('/').next().unwrap()), "{names:?} against {specs:?}");
        }
        assert_eq!(serde_json::to_string(&serial).unwrap(), serde_json::to_string(&parallel).unwrap());
        assert_eq!(warned_serial, warned_parallel);
        assert_eq!(warned_serial.len(), 1, "{warned_serial:?}");
        assert!(warned_serial[0].contains("broken.png"), "{warned_serial:?}");
        assert!(serial[1].error.as_deref().is_some_and(|e| !e.is_empty()));
        for k in [0, 2, 3, 4] {
            assert!(serial[k].error.is_none() && serial[k].detections[0].corners_px.len() >= 10, "{}", serial[k].image);
        }
        assert!(with_threads(Some(0), || ()).is_err());
    }
}
