//! `ferrocal detect`: find a pattern in images and write the corners as JSON
//! (`shared/spec/cli.md`).
//!
//! Glue only: the batch is detected by `ferrocal_datasets::detect` (image lists from
//! `ferrocal_datasets::import::list_images`, the per-image results from
//! `ferrocal_vision::detect::Detector`).

use ferrocal_report::say;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::Args;
use ferrocal_datasets::detect::{detect_images, median_background_of, summary_line, timing_lines, with_threads};
use ferrocal_vision::detect::{AprilTagOptions, DetectOptions, Pattern, TagBackend, TagRefine};

use ferrocal_calib::verdict::commands as verdict;
use ferrocal_report::verdict::VerdictSettings;

use crate::report::write_atomic;

/// `ferrocal detect`.
#[derive(Debug, Args)]
#[command(
    after_help = "Output: [{\"image\": \"<path>\", \"detections\": [{\"id\": <int|null>, \"corners_px\": [[x, y], ...], ...}], \
\"error\": \"<why>\" (only when the image failed)}]. Pixel (0, 0) is the centre of the top-left pixel. A chessboard is one \
detection whose corners run row by row from the top-left as printed; the plate is one detection of 20 corners (squares \
top-left, top-right, centre, bottom-left, bottom-right; corners top-left, top-right, bottom-right, bottom-left); tags are \
one detection each, corners in the AprilTag library's order; a ChArUco board is one detection of the corners seen, \
with their ids in `corner_ids` (OpenCV's numbering); a circle grid one detection of the dot centres (ellipse centres, \
not corrected for perspective) from the origin dot.\n\n\
An image that cannot be read, is empty, or does not show the pattern is reported on stderr and in its JSON entry; the \
batch goes on.\n\n\
Exit status: 0 when the pattern was found in every image; 2 when at least one image failed (the JSON is still written; \
the last stdout line, the verdict, fails below `detect.found_fraction_fail`, docs/verdicts.md); \
1 when the command itself fails (a pattern that does not parse, no images at all, the JSON cannot be written)."
)]
pub struct DetectArgs {
    /// Images: files, directories or glob patterns (quote globs); several may follow.
    #[arg(long, required = true, num_args = 1..)]
    pub images: Vec<String>,
    /// The pattern: `chessboard:<cols>x<rows>:<square>mm` (inner corners),
    /// `apriltag:<family>[:<tag size>mm]`, `plate:<square>mm` (the Gantry-Tau plate),
    /// `aprilboard:<cols>x<rows>:<tag>mm:<spacing>mm[:first_id]`,
    /// `charuco:<cols>x<rows>:<square>mm:<marker>mm:<dictionary>`, `circlegrid:<cols>x<rows>:<spacing>mm[:modified]`,
    /// `acircles:<cols>x<rows>:<spacing>mm`, `aprilgrid:<cols>x<rows>:<tag>mm:<spacing>[:first_id]`.
    #[arg(long)]
    pub pattern: String,
    /// Write the detections here (JSON).
    #[arg(long)]
    pub json: PathBuf,
    /// Accept chessboards of which only a part is visible (extra fields `grid_index`, `complete`,
    /// `anchored` say which corners they are).
    #[arg(long)]
    pub partial: bool,
    /// Report the detector's coarse corners, without the sub-pixel edge fit.
    #[arg(long)]
    pub no_refine: bool,
    /// Plate only: images of the same sequence whose per-pixel median is the static background
    /// (files, directories or globs).
    #[arg(long, num_args = 1..)]
    pub background: Vec<String>,
    /// AprilTags: refit the tag borders with the edge model and report covariances.
    #[arg(long)]
    pub tag_edge_refine: bool,
    /// Print the wall time of every stage per image (reading, candidate search, grid growth,
    /// refinement, covariance) and add it to each image's JSON entry as `timings`
    /// (milliseconds).
    #[arg(long)]
    pub timings: bool,
    /// AprilTags: the decoder, `c` (the AprilTag C library) or `kornia` (kornia-apriltag).
    #[arg(long, default_value = "c", value_parser = ["c", "kornia"])]
    pub tag_backend: String,
    /// Worker threads: the images are detected in parallel, this many at a time (and OpenCV
    /// uses as many); default every core (or `RAYON_NUM_THREADS`). The JSON is the same on any
    /// number of threads.
    #[arg(long)]
    pub threads: Option<usize>,
}

/// Runs `ferrocal detect`.
pub fn run(args: &DetectArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let pattern: Pattern = args.pattern.parse()?;
    let mut options = DetectOptions { refine: !args.no_refine, partial: args.partial, ..DetectOptions::default() };
    options.apriltag = AprilTagOptions {
        backend: if args.tag_backend == "kornia" { TagBackend::Kornia } else { TagBackend::CLibrary },
        refine: if args.tag_edge_refine && !args.no_refine { TagRefine::EdgeModel } else { TagRefine::Backend },
        ..AprilTagOptions::default()
    };
    let background = median_background_of(&args.background)?;
    let results = with_threads(args.threads, || {
        detect_images(&args.images, pattern, options, background, args.timings, &|e| eprintln!("ferrocal: {e}"))
    })??;
    for line in timing_lines(&results) {
        say!("{line}");
    }
    let failed = results.iter().filter(|r| r.error.is_some()).count();
    let json = serde_json::to_vec_pretty(&results)?;
    write_atomic(&args.json, &json).with_context(|| format!("cannot write {}", args.json.display()))?;
    say!("{}", summary_line(&results, &args.json));
    let verdict = verdict::detect(&vs.thresholds, results.len(), failed);
    // The JSON is an array per the spec: the verdict is on the terminal only. Failed images keep
    // their documented exit status 2; a failed verdict has at least one failed image.
    let ok = if failed == 0 { ExitCode::SUCCESS } else { ExitCode::from(2) };
    Ok(vs.conclude_with(&verdict, ok, 2))
}
