//! Images (or a session's poses) whose pose fit leaves a reprojection residual far above the
//! others': the corners do not fit one rigid view of the target through the camera model (a
//! wrong detection, motion blur, a reflection, a partly covered target, or in a rig one camera's
//! image of another pose). `ferrocal measure` names them and leaves them out of the table, up to
//! a cap; beyond the cap the images are not the problem (the camera model is), so every image is
//! kept and the verdict says so.
//!
//! The rule: an image's reprojection RMS over the median image's, at least
//! [`ReprojectionScreen::ratio`] times and at least [`ReprojectionScreen::min_rms_px`] (an image
//! at 0.4 px beside a median of 0.05 px on a rendered recording is not wrong). The real
//! recordings of industrial_calibration reach 2.23 (ChArUco, 0.42 px median) and 1.45 (10 x 10
//! circle grid, 0.18 px median) times the median; the rendered sessions stay below 1 px.

use serde::Serialize;

/// The limits of the screen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReprojectionScreen {
    /// An image is flagged at this many times the median image's reprojection RMS.
    pub ratio: f64,
    /// ... and at least this reprojection RMS (px).
    pub min_rms_px: f64,
    /// At most this fraction of the images is left out; more flagged: none is.
    pub max_fraction: f64,
}

impl Default for ReprojectionScreen {
    fn default() -> Self {
        Self { ratio: 5.0, min_rms_px: 1.0, max_fraction: 0.2 }
    }
}

/// An image (or pose) whose reprojection residual is far above the others'.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReprojectionOutlier {
    /// The image or pose, as the user knows it.
    pub what: String,
    /// Its reprojection RMS (px).
    pub rms_px: f64,
    /// Its RMS over the median image's.
    pub ratio: f64,
    /// Left out of the table (false: too many flagged to leave out).
    pub left_out: bool,
}

impl ReprojectionOutlier {
    /// One line: which image, how far off, what was done.
    pub fn describe(&self, median_px: f64) -> String {
        format!(
            "{}: reprojection RMS {:.3} px, {:.1} times the median image's {median_px:.3} px (a wrong detection, blur, a reflection, or another pose's image){}",
            self.what,
            self.rms_px,
            self.ratio,
            if self.left_out { "; left out of the table" } else { "" }
        )
    }
}

/// What [`screen_reprojection`] found: the flagged images (in the input's order), the median
/// RMS (px), and a note when too many were flagged to leave any out.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ReprojectionScreening {
    /// The flagged images.
    pub flagged: Vec<ReprojectionOutlier>,
    /// The median image's reprojection RMS (px).
    pub median_rms_px: f64,
    /// Why the flagged images were kept, when they were.
    pub note: Option<String>,
}

impl ReprojectionScreening {
    /// The lines for stderr and the verdict.
    pub fn lines(&self) -> Vec<String> {
        self.flagged.iter().map(|o| o.describe(self.median_rms_px)).chain(self.note.clone()).collect()
    }

    /// Whether the image `what` is left out.
    pub fn left_out(&self, what: &str) -> bool {
        self.flagged.iter().any(|o| o.left_out && o.what == what)
    }
}

/// Screens the reprojection RMS (px) of each image, `rms_px[i]` for the image `names[i]`.
pub fn screen_reprojection(names: &[String], rms_px: &[f64], screen: &ReprojectionScreen) -> ReprojectionScreening {
    let mut sorted: Vec<f64> = rms_px.iter().copied().filter(|r| r.is_finite()).collect();
    sorted.sort_by(f64::total_cmp);
    let Some(&median) = sorted.get(sorted.len() / 2) else { return ReprojectionScreening::default() };
    if sorted.len() < 3 || median <= 0.0 {
        return ReprojectionScreening { median_rms_px: median, ..Default::default() };
    }
    let mut flagged: Vec<ReprojectionOutlier> = names
        .iter()
        .zip(rms_px)
        .filter(|(_, r)| !r.is_finite() || (**r >= screen.ratio * median && **r >= screen.min_rms_px))
        .map(|(n, r)| ReprojectionOutlier { what: n.clone(), rms_px: *r, ratio: r / median, left_out: true })
        .collect();
    let cap = (screen.max_fraction * rms_px.len() as f64).floor() as usize;
    let mut note = None;
    if flagged.len() > cap {
        flagged.iter_mut().for_each(|o| o.left_out = false);
        note = Some(format!(
            "{} of {} images have a reprojection RMS of {} times the median image's or more: too many to leave out (at most {:.0} %); the camera model or the target's description is off, so every image was kept",
            flagged.len(),
            rms_px.len(),
            screen.ratio,
            100.0 * screen.max_fraction
        ));
    }
    ReprojectionScreening { flagged, median_rms_px: median, note }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(n: usize) -> Vec<String> {
        (0..n).map(|i| format!("{i}.png")).collect()
    }

    #[test]
    fn one_image_far_above_the_others_is_left_out_and_a_spread_like_the_real_sets_is_not() {
        // The ChArUco set's spread (0.47-2.23 times the median of 0.42 px) with one image at 12 px.
        let mut rms: Vec<f64> =
            [0.47, 0.87, 0.87, 0.92, 0.94, 0.96, 1.0, 1.0, 1.01, 1.06, 1.22, 1.27, 1.46, 1.56, 2.23]
                .iter()
                .map(|r| r * 0.42)
                .collect();
        let clean = screen_reprojection(&names(rms.len()), &rms, &ReprojectionScreen::default());
        assert!(clean.flagged.is_empty() && clean.note.is_none(), "{clean:?}");
        rms.push(12.0);
        let s = screen_reprojection(&names(rms.len()), &rms, &ReprojectionScreen::default());
        assert_eq!(s.flagged.len(), 1);
        assert!(s.left_out("15.png") && !s.left_out("14.png"));
        assert!(s.lines()[0].starts_with("15.png: reprojection RMS 12.000 px"), "{:?}", s.lines());
    }

    #[test]
    fn small_residuals_and_too_many_flagged_images_leave_everything_in() {
        // 0.4 px beside 0.05 px: below the 1 px floor.
        let rms = vec![0.05, 0.05, 0.06, 0.04, 0.4];
        assert!(screen_reprojection(&names(5), &rms, &ReprojectionScreen::default()).flagged.is_empty());
        // Two of five far above: beyond 20 %, kept with a note.
        let rms = vec![0.3, 0.3, 0.3, 9.0, 9.0];
        let s = screen_reprojection(&names(5), &rms, &ReprojectionScreen::default());
        assert_eq!(s.flagged.len(), 2);
        assert!(!s.left_out("3.png") && s.note.as_deref().is_some_and(|n| n.contains("too many")), "{s:?}");
    }
}
