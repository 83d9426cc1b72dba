//! The camera diagnosis's options and report types.

use super::*;

/// Options of [`diagnose_camera`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraDiagnoseOptions {
    /// Folds over views (at most the number of views: leave-one-out then).
    pub folds: usize,
    /// Family-wise significance level.
    pub alpha: f64,
    /// Least relative held-out RMS improvement for a finding.
    pub min_improvement: f64,
    /// Largest plausible sag of a target at its edge, metres.
    pub max_sag_m: f64,
    /// Largest plausible size of a rational coefficient.
    pub max_rational: f64,
    /// Largest plausible relative difference of the printed x and y spacings (0.02: 2 %).
    #[serde(default = "default_max_print_scale")]
    pub max_print_scale: f64,
}

fn default_max_print_scale() -> f64 {
    0.02
}

impl Default for CameraDiagnoseOptions {
    fn default() -> Self {
        Self {
            folds: 5,
            alpha: 0.01,
            min_improvement: 0.02,
            max_sag_m: 0.01,
            max_rational: 50.0,
            max_print_scale: default_max_print_scale(),
        }
    }
}

/// One accepted effect.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CameraFinding {
    /// `lens_distortion`, `target_nonflatness` or `target_print_scale`.
    pub effect: String,
    /// Always empty for a camera (no joints).
    pub joints: Vec<usize>,
    /// The effect's parameters by name.
    pub parameters: std::collections::BTreeMap<String, f64>,
    /// Held-out reprojection RMS before, pixels.
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

/// RMS figures of a fit.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct CameraFit {
    /// Views used for fitting (per fold: all but the held-out ones).
    pub n_train: usize,
    /// Views held out (over all folds: every view once).
    pub n_heldout: usize,
    /// Reprojection RMS on all views fitted together, pixels.
    pub train_rms_px: f64,
    /// Held-out reprojection RMS, pixels.
    pub heldout_rms_px: f64,
}

/// The final fit.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct CameraFinalFit {
    /// Reprojection RMS on all views, pixels.
    pub train_rms_px: f64,
    /// Held-out reprojection RMS, pixels.
    pub heldout_rms_px: f64,
}

/// What is left.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct CameraUnexplained {
    /// Whether residual structure remains that no candidate explains.
    pub structure_found: bool,
    /// What it depends on (`image position`, ...).
    pub depends_on: Vec<String>,
    /// Where it shows: one plain-words line per significant image cell or ring.
    #[serde(default)]
    pub evidence: Vec<String>,
}

/// One candidate tried in a round.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraCandidateScore {
    /// Effect name and variant.
    pub candidate: String,
    /// Held-out RMS with it, pixels.
    pub heldout_rms_px: f64,
    /// Corrected p-value.
    pub p_value: f64,
    /// Accepted or why not.
    pub verdict: String,
    /// The outcome in one word (`accepted`, `rejected`, `not_significant`, ...; see
    /// `diagnose::report::Verdict::status`).
    #[serde(default)]
    pub status: String,
}

/// The report (`ferrocal diagnose --images`), the JSON of `shared/spec/diagnose.md` with `_px`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CameraDiagnoseReport {
    /// The default model's fit.
    pub nominal: CameraFit,
    /// Accepted effects.
    pub findings: Vec<CameraFinding>,
    /// With every accepted effect.
    #[serde(rename = "final")]
    pub final_fit: CameraFinalFit,
    /// Structure left.
    pub unexplained: CameraUnexplained,
    /// Why nothing was claimed, when the analysis declined.
    pub declined: Option<String>,
    /// Every candidate of every round.
    pub candidates: Vec<Vec<CameraCandidateScore>>,
    /// Settings.
    pub settings: CameraDiagnoseOptions,
    /// Views used.
    pub n_views: usize,
}
