//! The Markdown table of `ferrocal corner-study` (`corner_study.md`); the study is
//! `ferrocal_datasets::render::corner_study`.

use std::fmt::Write as _;

use ferrocal_datasets::render::corner_study::StudyRow;

fn fmt(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.4}")
    } else {
        "n/a".into()
    }
}

/// The study's Markdown table (`corner_study.md`) for `rows` of a study of `images` per level
/// with `seed` at `w` x `h` pixels.
pub fn markdown(rows: &[StudyRow], images: usize, seed: u64, w: u32, h: u32) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Corner accuracy on rendered images\n");
    let _ = writeln!(
        s,
        "{} images per row ({w}x{h}, pinhole, cos^4 vignetting), seed {}. RMS corner error against the renderer's exact \
         truth, px. Noise: off = quantisation only; low = shot noise + 6 e- read noise (default sensor, 40 e-/DN); \
         high = shot noise + 120 e- (3 DN) read noise. cornerSubPix: 11x11 window, eps 0.001, started from this \
         project's coarse corners. SB: findChessboardCornersSB with CALIB_CB_ACCURACY (SB default: without it). Classic: findChessboardCorners + \
         cornerSubPix 11x11. CRB: Cramer-Rao bound of the edge model under the true noise model (sqrt of the mean \
         trace). \"ours\" is the default (each corner from the segments that end at it, valid with lens distortion); \
         \"whole lines\" fits every grid line over its full length (valid for straight lines: undistorted images or a \
         camera model). Noise \"off\" is deterministic 8-bit rounding, correlated along an edge, not white noise: \
         the white-noise CRB (1/12 DN^2) is not a bound there. Reproduce: `ferrocal corner-study --images {} --seed {}`.\n",
        images, seed, images, seed
    );
    let _ = writeln!(
        s,
        "| target | PSF sigma px | noise | ours | CRB | ours/CRB | whole lines | CRB | ratio | cornerSubPix 11x11 | ours/subpix | SB | SB default | classic | found ours/SB/classic |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {:.1} | {} | {} | {} | {:.2} | {} | {} | {:.2} | {} | {:.2} | {} | {} | {} | {}/{}/{} of {} |",
            r.target,
            r.psf_sigma_px,
            r.noise,
            fmt(r.ours_rms_px),
            fmt(r.crb_rms_px),
            r.ours_rms_px / r.crb_rms_px,
            fmt(r.ours_global_rms_px),
            fmt(r.crb_global_rms_px),
            r.ours_global_rms_px / r.crb_global_rms_px,
            fmt(r.subpix_rms_px),
            r.ours_rms_px / r.subpix_rms_px,
            fmt(r.sb_rms_px),
            fmt(r.sb_default_rms_px),
            fmt(r.classic_rms_px),
            r.ours_found,
            r.sb_found,
            r.classic_found,
            r.images
        );
    }
    s
}
