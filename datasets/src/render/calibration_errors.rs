//! Where the calibration study's intrinsic errors come from
//! ([`super::calibration_study`]): the corner errors of a seed's views against the truth
//! (the renders' true corner positions), their structure (correlation between neighbouring
//! corners of a view, per-view mean, radial component, the board's outer corners against
//! its inner ones), and what they do to the intrinsics, measured by calibrating
//! ([`calibrate_camera`], Brown-5, corners as independent) on the true corners plus
//! **parts or rearrangements of the measured errors**:
//!
//! - the measured errors (the study's result);
//! - the errors shuffled among the corners of each view (keeps every view's error
//!   distribution, destroys its spatial pattern): the spread of the intrinsics if the same
//!   errors were independent;
//! - each view's errors multiplied by a random sign (keeps every view's pattern, makes the
//!   views independent of each other; a wild bootstrap over views): the spread of the
//!   intrinsics when views are independent but corners within a view are not;
//! - only the radial component (about the true principal point), only the outer ring of
//!   corners, only each view's mean error, only each view's smooth part (a quadratic in the
//!   corner's grid position fitted per view and component) and the rest.
//!
//! `cargo run --release -p ferrocal-datasets --example calibration_errors -- --seeds 4,1`.

use nalgebra::{DMatrix, DVector, Point2, Vector2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::calibration_study::{RenderedSeed, StudySettings};
use crate::error::Result;
use ferrocal_vision::calib::{calibrate_camera, CalibrationOptions, CovarianceMethod, PlanarTarget, View};

/// One corner's error.
#[derive(Clone, Copy, Debug)]
struct CornerError {
    row: u32,
    col: u32,
    truth_px: Point2<f64>,
    error_px: Vector2<f64>,
}

/// The matched corners of one view.
#[derive(Clone, Debug)]
struct ViewErrors {
    view: View,
    corners: Vec<CornerError>,
}

/// Statistics of one side's corner errors and their effect on `fx fy cx cy`.
#[derive(Clone, Debug, Serialize)]
pub struct ErrorAnalysis {
    /// Views.
    pub views: usize,
    /// RMS corner error length, pixels.
    pub rms_px: f64,
    /// RMS over views of the length of the view's mean error vector, pixels.
    pub view_mean_rms_px: f64,
    /// What that would be for independent errors: `rms / sqrt(corners per view)`, pixels.
    pub view_mean_rms_independent_px: f64,
    /// Correlation of the error vectors of horizontally / vertically adjacent corners
    /// (`sum e_i . e_j / sum |e|^2`), and of corners two apart along a row.
    pub neighbour_correlation: [f64; 3],
    /// The same after removing each view's mean error.
    pub neighbour_correlation_centred: [f64; 3],
    /// Mean radial error (positive: away from the true principal point) in three bins of the
    /// radius (inner, middle, outer third of the largest radius), pixels.
    pub radial_mean_px: [f64; 3],
    /// RMS corner error of the board's outer ring of corners and of the inner ones, pixels.
    pub ring_rms_px: [f64; 2],
    /// `estimate - truth` of `fx fy cx cy` from the measured errors, pixels.
    pub actual_error_px: [f64; 4],
    /// From the true corners alone (the solver's floor), pixels.
    pub truth_only_error_px: [f64; 4],
    /// Standard deviations of `fx fy cx cy` with corners taken as independent, as reported.
    pub reported_std_px: [f64; 4],
    /// Standard deviation over the shuffles (errors independent within a view), pixels.
    pub shuffled_std_px: [f64; 4],
    /// Standard deviation over the per-view sign flips (views independent), pixels.
    pub flipped_std_px: [f64; 4],
    /// The errors from the radial components alone, pixels.
    pub radial_only_error_px: [f64; 4],
    /// From the outer ring of corners' errors alone.
    pub ring_only_error_px: [f64; 4],
    /// From each view's mean error alone.
    pub view_mean_only_error_px: [f64; 4],
    /// From each view's smooth part (quadratic in the grid position) alone.
    pub smooth_only_error_px: [f64; 4],
    /// From the rest (measured minus smooth part).
    pub rough_only_error_px: [f64; 4],
}

/// Matches every found corner to its nearest true corner.
fn match_views(rendered: &RenderedSeed, views: &[View], cols: u32) -> Vec<ViewErrors> {
    let mut out = Vec::new();
    for v in views {
        let Some(i) = rendered.view_index(&v.name) else { continue };
        let truth = &rendered.truth_px[i];
        let corners = v
            .corners_px
            .iter()
            .map(|p| {
                let (j, t) = truth
                    .iter()
                    .enumerate()
                    .min_by(|a, b| (p - a.1).norm_squared().total_cmp(&(p - b.1).norm_squared()))
                    .expect("true corners");
                CornerError { row: j as u32 / cols, col: j as u32 % cols, truth_px: *t, error_px: p - t }
            })
            .collect();
        out.push(ViewErrors { view: v.clone(), corners });
    }
    out
}

/// `fx fy cx cy` errors of a calibration on the true corners plus `error(view, corner)`.
fn calibrate_with(
    matched: &[ViewErrors],
    target: &PlanarTarget,
    truth: &[f64; 4],
    error: &mut dyn FnMut(usize, usize) -> Vector2<f64>,
) -> Result<([f64; 4], [f64; 4])> {
    let views: Vec<View> = matched
        .iter()
        .enumerate()
        .map(|(k, m)| {
            let mut v = m.view.clone();
            v.corners_px = m.corners.iter().enumerate().map(|(i, c)| c.truth_px + error(k, i)).collect();
            v
        })
        .collect();
    let options = CalibrationOptions { covariance: CovarianceMethod::Independent, ..CalibrationOptions::default() };
    let c = calibrate_camera(&views, target, &options)?;
    let k = c.camera.intrinsics;
    let est = [k.fx_px, k.fy_px, k.cx_px, k.cy_px];
    Ok((std::array::from_fn(|i| est[i] - truth[i]), std::array::from_fn(|i| c.std[i])))
}

/// Per view and component, the least-squares quadratic in the grid position `(col, row)`.
fn smooth_part(m: &ViewErrors) -> Vec<Vector2<f64>> {
    let basis = |c: &CornerError| {
        let (x, y) = (f64::from(c.col), f64::from(c.row));
        [1.0, x, y, x * x, x * y, y * y]
    };
    let n = m.corners.len();
    let a = DMatrix::from_fn(n, 6, |i, j| basis(&m.corners[i])[j]);
    let svd = a.clone().svd(true, true);
    let fit = |f: &dyn Fn(&CornerError) -> f64| -> DVector<f64> {
        let b = DVector::from_iterator(n, m.corners.iter().map(f));
        let x = svd.solve(&b, 1e-10).expect("svd solve");
        &a * x
    };
    let fx = fit(&|c| c.error_px.x);
    let fy = fit(&|c| c.error_px.y);
    (0..n).map(|i| Vector2::new(fx[i], fy[i])).collect()
}

/// Correlation of the error vectors of corner pairs `(r, c)`, `(r + dr, c + dc)` within views.
fn pair_correlation(matched: &[ViewErrors], dr: u32, dc: u32, centred: bool) -> f64 {
    let (mut num, mut den_a, mut den_b) = (0.0, 0.0, 0.0);
    for m in matched {
        let mean = if centred {
            m.corners.iter().map(|c| c.error_px).sum::<Vector2<f64>>() / m.corners.len() as f64
        } else {
            Vector2::zeros()
        };
        for a in &m.corners {
            if let Some(b) = m.corners.iter().find(|b| b.row == a.row + dr && b.col == a.col + dc) {
                let (ea, eb) = (a.error_px - mean, b.error_px - mean);
                num += ea.dot(&eb);
                den_a += ea.norm_squared();
                den_b += eb.norm_squared();
            }
        }
    }
    num / (den_a * den_b).sqrt()
}

fn std_of(samples: &[[f64; 4]]) -> [f64; 4] {
    let n = samples.len() as f64;
    std::array::from_fn(|i| {
        let mean = samples.iter().map(|s| s[i]).sum::<f64>() / n;
        (samples.iter().map(|s| (s[i] - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    })
}

/// The analysis of `views` (corners found in `rendered`'s images) with `draws` shuffles and
/// sign flips, seeded.
pub fn analyze(
    settings: &StudySettings,
    rendered: &RenderedSeed,
    views: &[View],
    draws: usize,
) -> Result<ErrorAnalysis> {
    let b = &settings.board;
    let target = PlanarTarget::chessboard(b.inner_cols, b.inner_rows, b.square_m);
    let matched = match_views(rendered, views, b.inner_cols);
    let t = rendered.truth.intrinsics;
    let truth = [t.fx_px, t.fy_px, t.cx_px, t.cy_px];
    let all: Vec<&CornerError> = matched.iter().flat_map(|m| &m.corners).collect();
    let rms_px = (all.iter().map(|c| c.error_px.norm_squared()).sum::<f64>() / all.len() as f64).sqrt();
    let means: Vec<Vector2<f64>> = matched
        .iter()
        .map(|m| m.corners.iter().map(|c| c.error_px).sum::<Vector2<f64>>() / m.corners.len() as f64)
        .collect();
    let view_mean_rms_px = (means.iter().map(|m| m.norm_squared()).sum::<f64>() / means.len() as f64).sqrt();
    let per_view = all.len() as f64 / matched.len() as f64;
    let pp = Point2::new(t.cx_px, t.cy_px);
    let r_max = all.iter().map(|c| (c.truth_px - pp).norm()).fold(0.0, f64::max);
    let mut radial = [(0.0, 0usize); 3];
    for c in &all {
        let d = c.truth_px - pp;
        let bin = ((3.0 * d.norm() / r_max) as usize).min(2);
        radial[bin].0 += c.error_px.dot(&d) / d.norm().max(1e-9);
        radial[bin].1 += 1;
    }
    let on_ring = |c: &CornerError| c.row == 0 || c.col == 0 || c.row + 1 == b.inner_rows || c.col + 1 == b.inner_cols;
    let ring_rms = |ring: bool| {
        let sel: Vec<f64> = all.iter().filter(|c| on_ring(c) == ring).map(|c| c.error_px.norm_squared()).collect();
        (sel.iter().sum::<f64>() / sel.len().max(1) as f64).sqrt()
    };

    let (actual, reported) = calibrate_with(&matched, &target, &truth, &mut |k, i| matched[k].corners[i].error_px)?;
    let (truth_only, _) = calibrate_with(&matched, &target, &truth, &mut |_, _| Vector2::zeros())?;
    let mut rng = ChaCha8Rng::seed_from_u64(rendered.seed.wrapping_add(77));
    let (mut shuffled, mut flipped) = (Vec::new(), Vec::new());
    for _ in 0..draws {
        let perms: Vec<Vec<usize>> = matched
            .iter()
            .map(|m| {
                let mut p: Vec<usize> = (0..m.corners.len()).collect();
                for i in (1..p.len()).rev() {
                    p.swap(i, rng.random_range(0..=i));
                }
                p
            })
            .collect();
        shuffled
            .push(calibrate_with(&matched, &target, &truth, &mut |k, i| matched[k].corners[perms[k][i]].error_px)?.0);
        let signs: Vec<f64> = matched.iter().map(|_| if rng.random_bool(0.5) { 1.0 } else { -1.0 }).collect();
        flipped
            .push(calibrate_with(&matched, &target, &truth, &mut |k, i| signs[k] * matched[k].corners[i].error_px)?.0);
    }
    let radial_only = calibrate_with(&matched, &target, &truth, &mut |k, i| {
        let c = &matched[k].corners[i];
        let d = (c.truth_px - pp).normalize();
        d * c.error_px.dot(&d)
    })?
    .0;
    let ring_only = calibrate_with(&matched, &target, &truth, &mut |k, i| {
        let c = &matched[k].corners[i];
        if on_ring(c) {
            c.error_px
        } else {
            Vector2::zeros()
        }
    })?
    .0;
    let mean_only = calibrate_with(&matched, &target, &truth, &mut |k, _| means[k])?.0;
    let smooth: Vec<Vec<Vector2<f64>>> = matched.iter().map(smooth_part).collect();
    let smooth_only = calibrate_with(&matched, &target, &truth, &mut |k, i| smooth[k][i])?.0;
    let rough_only =
        calibrate_with(&matched, &target, &truth, &mut |k, i| matched[k].corners[i].error_px - smooth[k][i])?.0;
    Ok(ErrorAnalysis {
        views: matched.len(),
        rms_px,
        view_mean_rms_px,
        view_mean_rms_independent_px: rms_px / per_view.sqrt(),
        neighbour_correlation: [
            pair_correlation(&matched, 0, 1, false),
            pair_correlation(&matched, 1, 0, false),
            pair_correlation(&matched, 0, 2, false),
        ],
        neighbour_correlation_centred: [
            pair_correlation(&matched, 0, 1, true),
            pair_correlation(&matched, 1, 0, true),
            pair_correlation(&matched, 0, 2, true),
        ],
        radial_mean_px: radial.map(|(s, n)| s / n.max(1) as f64),
        ring_rms_px: [ring_rms(true), ring_rms(false)],
        actual_error_px: actual,
        truth_only_error_px: truth_only,
        reported_std_px: reported,
        shuffled_std_px: std_of(&shuffled),
        flipped_std_px: std_of(&flipped),
        radial_only_error_px: radial_only,
        ring_only_error_px: ring_only,
        view_mean_only_error_px: mean_only,
        smooth_only_error_px: smooth_only,
        rough_only_error_px: rough_only,
    })
}

impl ErrorAnalysis {
    /// A readable report.
    pub fn report(&self) -> String {
        let f = |v: [f64; 4]| format!("{:+.3} {:+.3} {:+.3} {:+.3}", v[0], v[1], v[2], v[3]);
        let z = |v: [f64; 4], s: [f64; 4]| {
            format!("{:+.1} {:+.1} {:+.1} {:+.1}", v[0] / s[0], v[1] / s[1], v[2] / s[2], v[3] / s[3])
        };
        format!(
            "views {}, corner RMS {:.4} px; view-mean RMS {:.4} px (independent: {:.4} px)\n\
             neighbour correlation h / v / h2: {:.2} {:.2} {:.2}; per-view mean removed: {:.2} {:.2} {:.2}\n\
             mean radial error inner / middle / outer radius: {:+.4} {:+.4} {:+.4} px; RMS outer ring / inner: {:.4} / {:.4} px\n\
             fx fy cx cy errors (px):\n  actual        {}  (z vs reported {}; vs flips {})\n  truth only    {}\n\
             \x20 radial only   {}\n  ring only     {}\n  view means    {}\n  smooth part   {}\n  rough part    {}\n\
             spreads (px): reported {}  shuffled {}  sign-flipped views {}\n",
            self.views,
            self.rms_px,
            self.view_mean_rms_px,
            self.view_mean_rms_independent_px,
            self.neighbour_correlation[0],
            self.neighbour_correlation[1],
            self.neighbour_correlation[2],
            self.neighbour_correlation_centred[0],
            self.neighbour_correlation_centred[1],
            self.neighbour_correlation_centred[2],
            self.radial_mean_px[0],
            self.radial_mean_px[1],
            self.radial_mean_px[2],
            self.ring_rms_px[0],
            self.ring_rms_px[1],
            f(self.actual_error_px),
            z(self.actual_error_px, self.reported_std_px),
            z(self.actual_error_px, self.flipped_std_px),
            f(self.truth_only_error_px),
            f(self.radial_only_error_px),
            f(self.ring_only_error_px),
            f(self.view_mean_only_error_px),
            f(self.smooth_only_error_px),
            f(self.rough_only_error_px),
            f(self.reported_std_px),
            f(self.shuffled_std_px),
            f(self.flipped_std_px),
        )
    }
}
