//! Outlier views and corners of a bundle: per-view RMS against the median, corners beyond a number of robust sigmas.

use super::*;

/// An outlier corner found in a bundle's residuals.
pub(crate) struct FlaggedCorner {
    /// Index into the list of observations that was checked.
    pub obs: usize,
    /// The bundle's view index.
    pub view: usize,
    pub point_id: usize,
    pub residual_px: f64,
}

/// Per-view RMS and outlier flags.
pub(crate) struct Flags {
    pub view_rms: Vec<f64>,
    pub view_outlier: Vec<bool>,
    pub median_rms: f64,
    pub corners: Vec<FlaggedCorner>,
    pub removed_obs: std::collections::HashSet<usize>,
    pub dropped_views: bool,
}

impl Flags {
    pub(crate) fn any_view(&self) -> bool {
        self.view_outlier.iter().any(|o| *o)
    }
}

/// Per-view RMS over `all_obs` (evaluated with the bundle's current state, whether or not an
/// observation is still in the bundle), outlier views (RMS above the factor times the median)
/// and outlier corners (beyond the given number of robust sigmas).
pub(crate) fn flag_outliers(bundle: &Bundle, all_obs: &[Obs], options: &CalibrationOptions) -> Result<Flags> {
    let res = bundle.residuals_of(all_obs)?;
    let nv = bundle.views.len();
    let mut sq = vec![0.0; nv];
    let mut cnt = vec![0usize; nv];
    let mut comps = Vec::new();
    for (o, r) in all_obs.iter().zip(&res) {
        if let Some(r) = r {
            sq[o.view] += r.norm_squared();
            cnt[o.view] += 1;
            comps.push(r.x.abs());
            comps.push(r.y.abs());
        }
    }
    let view_rms: Vec<f64> =
        (0..nv).map(|k| if cnt[k] > 0 { (sq[k] / cnt[k] as f64).sqrt() } else { f64::NAN }).collect();
    // A view is an outlier when most of its corners are off, not when one corner is: compare
    // the views' median corner errors (one bad corner is an outlier corner instead).
    let mut lens: Vec<Vec<f64>> = vec![Vec::new(); nv];
    for (o, r) in all_obs.iter().zip(&res) {
        if let Some(r) = r {
            lens[o.view].push(r.norm());
        }
    }
    let view_median: Vec<f64> = lens.iter().map(|l| if l.is_empty() { f64::NAN } else { median(l) }).collect();
    let finite: Vec<f64> = view_median.iter().copied().filter(|x| x.is_finite()).collect();
    let median_all = median(&finite);
    let finite_rms: Vec<f64> = view_rms.iter().copied().filter(|x| x.is_finite()).collect();
    let median_rms = median(&finite_rms);
    let view_outlier: Vec<bool> = view_median
        .iter()
        .zip(&view_rms)
        .map(|(m, r)| {
            m.is_finite()
                && *m > options.outlier_view_factor * median_all
                && *r > options.outlier_view_factor * median_rms
        })
        .collect();
    let sigma = 1.4826 * median(&comps);
    let mut corners = Vec::new();
    for (oi, (o, r)) in all_obs.iter().zip(&res).enumerate() {
        if let Some(r) = r {
            let len = r.norm();
            if sigma > 0.0 && len > options.outlier_corner_sigmas * sigma {
                corners.push(FlaggedCorner { obs: oi, view: o.view, point_id: o.point_id, residual_px: len });
            }
        }
    }
    Ok(Flags { view_rms, view_outlier, median_rms, corners, removed_obs: Default::default(), dropped_views: false })
}
