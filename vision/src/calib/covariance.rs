//! How a camera calibration's covariance is computed.

use serde::{Deserialize, Serialize};

use crate::error::{Result, VisionError};

/// How [`calibrate_camera`](super::calibrate_camera) computes the covariance of the camera parameters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CovarianceMethod {
    /// `s0^2 (J^T J)^-1` with the target poses marginalised: every corner an independent
    /// measurement with the same variance (OpenCV's `stdDeviationsIntrinsics`).
    #[default]
    Independent,
    /// Leave-one-view-out jackknife: the adjustment re-solved without each view in turn
    /// (started from the solution), `(G - 1) / G sum_v (p_v - mean)(p_v - mean)^T` over the
    /// `G` views. Views are the independent units; the corners of a view may be correlated.
    ViewJackknife,
    /// View-clustered sandwich: `S^-1 (sum_v g_v g_v^T) S^-1` with `g_v` a view's score (its
    /// pose marginalised) and a small-sample factor (see the bundle's `view_sandwich`). Views
    /// independent, corners of a view possibly correlated; no re-solves. Optimistic with few
    /// views: the fitted scores are shrunk because every view pulls the fit towards itself
    /// (12 views, 9 parameters, correlated errors: RMS of error / sigma 2.0 against the
    /// jackknife's 1.4; test `the_view_jackknife_covers_errors_correlated_within_views`).
    ViewSandwich,
    /// The jackknife with at least [`MIN_JACKKNIFE_VIEWS`] views, otherwise the independent
    /// covariance with a warning. The summary records the method used.
    Auto,
}

/// Views the [`CovarianceMethod::Auto`] choice needs for the jackknife (its estimate has one
/// degree of freedom fewer than the views).
pub const MIN_JACKKNIFE_VIEWS: usize = 8;

impl CovarianceMethod {
    /// Parses `independent`, `jackknife`, `sandwich` or `auto`.
    pub fn parse(text: &str) -> Result<Self> {
        match text.trim().to_ascii_lowercase().as_str() {
            "independent" => Ok(Self::Independent),
            "jackknife" => Ok(Self::ViewJackknife),
            "sandwich" => Ok(Self::ViewSandwich),
            "auto" => Ok(Self::Auto),
            _ => Err(VisionError::InvalidInput {
                detail: format!("covariance '{text}': expected independent, jackknife, sandwich or auto"),
            }),
        }
    }

    /// The name [`CovarianceMethod::parse`] reads.
    pub fn name(self) -> &'static str {
        match self {
            Self::Independent => "independent",
            Self::ViewJackknife => "jackknife",
            Self::ViewSandwich => "sandwich",
            Self::Auto => "auto",
        }
    }
}
