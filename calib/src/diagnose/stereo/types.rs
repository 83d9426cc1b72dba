//! The stereo diagnosis's report types (its options are the camera diagnosis's).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::super::camera::{CameraCandidateScore, CameraDiagnoseOptions, CameraFinalFit, CameraFit, CameraUnexplained};

/// One accepted effect of a stereo pair.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct StereoFinding {
    /// `lens_distortion`, `target_nonflatness` or `target_print_scale`.
    pub effect: String,
    /// Always empty (no joints).
    pub joints: Vec<usize>,
    /// The camera the effect belongs to (0 = left, 1 = right); absent for the target's effects,
    /// which both cameras share.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<usize>,
    /// The effect's parameters by name.
    pub parameters: BTreeMap<String, f64>,
    /// Standard deviation (1 sigma, from the fit's covariance) of each parameter by name, where
    /// the fit determined it.
    #[serde(default)]
    pub parameters_std: BTreeMap<String, f64>,
    /// Held-out reprojection RMS over both images of the held-out pairs before, pixels.
    pub heldout_rms_before_px: f64,
    /// Held-out reprojection RMS after, pixels.
    pub heldout_rms_after_px: f64,
    /// Share of the held-out mean squared error explained.
    pub explained_fraction: f64,
    /// Corrected p-value.
    pub p_value: f64,
    /// Plain words.
    pub statement: String,
}

/// The stereo report (`ferrocal diagnose --images left/ --images right/`), the JSON of
/// `shared/spec/diagnose.md` with `_px`; the held-out unit is a pair of images.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct StereoDiagnoseReport {
    /// The default model's fit (`n_train`, `n_heldout` count pairs).
    pub nominal: CameraFit,
    /// Accepted effects.
    pub findings: Vec<StereoFinding>,
    /// With every accepted effect.
    #[serde(rename = "final")]
    pub final_fit: CameraFinalFit,
    /// Structure left on the held-out pairs, per camera (`depends_on` entries name the camera).
    pub unexplained: CameraUnexplained,
    /// Why nothing was claimed, when the analysis declined.
    pub declined: Option<String>,
    /// Every candidate of every round.
    pub candidates: Vec<Vec<CameraCandidateScore>>,
    /// Settings.
    pub settings: CameraDiagnoseOptions,
    /// Pairs in which both images show the target (the held-out units).
    pub n_pairs: usize,
    /// Per camera: views of target poses the other camera did not see (used in every training
    /// fit with that camera alone, never held out).
    pub n_single_views: [usize; 2],
    /// Right views whose corner numbering was reversed to match the left view (a chessboard
    /// seen from either end).
    pub n_reversed_views: usize,
    /// Baseline of the final fit (distance between the projection centres), millimetres.
    pub baseline_mm: f64,
}
