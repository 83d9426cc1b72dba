//! `ferrocal corner-study`: sub-pixel corner accuracy on rendered images with exact truth (the
//! study is `ferrocal_datasets::render::corner_study`, the table `ferrocal_report::corner_study`).
//! Writes `corner_study.md`, `.csv` and `.json`.

use ferrocal_report::{say, tell};
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::Args;
use ferrocal_calib::verdict::commands as verdict;
use ferrocal_datasets::render::corner_study::{corner_study, rows_csv, worst_crb_ratio, CornerStudySettings};
use ferrocal_report::corner_study::markdown;
use ferrocal_report::verdict::VerdictSettings;
use ferrocal_report::write_atomic;

/// `ferrocal corner-study`.
#[derive(Debug, Args)]
pub struct CornerStudyArgs {
    /// Folder for corner_study.md, corner_study.csv and corner_study.json.
    #[arg(long, default_value = "out/corner_study")]
    pub out: PathBuf,
    /// Rendered images per target and level.
    #[arg(long, default_value_t = 4)]
    pub images: usize,
    /// Seed of the sensor noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Image width, pixels (height is 3/4 of it).
    #[arg(long, default_value_t = 1280)]
    pub width: u32,
}

/// Runs the study.
pub fn run(args: &CornerStudyArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let settings = CornerStudySettings { images: args.images, seed: args.seed, width: args.width };
    let (rows, w, h) = corner_study(&settings, &|s| tell!("{s}"))?;
    let md = markdown(&rows, args.images, args.seed, w, h);
    std::fs::create_dir_all(&args.out).with_context(|| format!("cannot create {}", args.out.display()))?;
    write_atomic(&args.out.join("corner_study.md"), md.as_bytes())?;
    // The worst ratio of the project's corner error to the Cramer-Rao bound where there is noise.
    let verdict = verdict::corner_study(&vs.thresholds, worst_crb_ratio(&rows), &args.out.join("corner_study.md"));
    // The study's JSON is an array of rows (its format since it was written): the verdict is
    // written beside it.
    write_atomic(&args.out.join("corner_study.json"), &serde_json::to_vec_pretty(&rows)?)?;
    write_atomic(&args.out.join("verdict.json"), &serde_json::to_vec_pretty(&verdict.to_json())?)?;
    write_atomic(&args.out.join("corner_study.csv"), rows_csv(&rows)?.as_bytes())?;
    say!("{md}");
    Ok(vs.conclude(&verdict))
}
