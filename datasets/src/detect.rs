//! The `detect` workflow: a pattern found in every image of a batch, with sub-pixel corners
//! ([`detect_images`]), optionally against the static background of the same sequence
//! ([`median_background_of`]). An image that cannot be used never stops the batch: its result
//! says why.

use ferrocal_vision::detect::{load_gray, median_background, DetectOptions, Detector, ImageResult, Pattern};
use image::GrayImage;

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

/// Finds `pattern` in every image of `specs` (files, folders or globs; refused when they name
/// none) with `options`, against `background` when given: one result per image, in order. A
/// failed image's reason is also given to `warn`, naming the image, as it happens. With
/// `timed`, every result carries its per-stage wall times ([`ImageResult::timings`]).
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
    let mut detector = Detector::new(pattern, options, background)?.with_timings(timed);
    let mut results: Vec<ImageResult> = Vec::with_capacity(entries.len());
    for entry in entries {
        let r = match entry {
            Ok(path) => detector.detect_file(&path),
            Err((name, reason)) => ImageResult::failed(name, reason),
        };
        if let Some(e) = &r.error {
            // The vision crate's messages already name the file; list_images' do not.
            if e.contains(&r.image) {
                warn(e);
            } else {
                warn(&format!("{}: {e}", r.image));
            }
        }
        results.push(r);
    }
    Ok(results)
}
