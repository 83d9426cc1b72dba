//! The force-sensor diagnosis's options and report types.

use super::*;

/// Options of [`diagnose_force_sensor`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ForceDiagnoseOptions {
    /// Folds over poses.
    pub folds: usize,
    /// Family-wise significance level per step.
    pub alpha: f64,
    /// Least relative held-out RMS improvement for a finding.
    pub min_improvement: f64,
}

impl Default for ForceDiagnoseOptions {
    fn default() -> Self {
        Self { folds: 5, alpha: 0.01, min_improvement: 0.02 }
    }
}

/// Fit figures (sensor forces, newtons).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct ForceFit {
    /// Poses per training fold.
    pub n_train: usize,
    /// Poses held out over all folds (each once).
    pub n_heldout: usize,
    /// RMS force residual of the fit on all poses, N.
    pub train_rms_n: f64,
    /// Held-out RMS force residual, N.
    pub heldout_rms_n: f64,
}

/// One accepted effect.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ForceFinding {
    /// `platform_deformation` or `sensor_crosstalk`.
    pub effect: String,
    /// Empty (no joints).
    pub joints: Vec<usize>,
    /// The added terms' parameters, and the mass and centre of gravity before and after.
    pub parameters: BTreeMap<String, f64>,
    /// Held-out RMS before, N.
    pub heldout_rms_before_n: f64,
    /// Held-out RMS after, N.
    pub heldout_rms_after_n: f64,
    /// Share of the held-out mean squared error explained.
    pub explained_fraction: f64,
    /// Corrected p-value.
    pub p_value: f64,
    /// Plain words.
    pub statement: String,
}

/// The final model's figures.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct ForceFinalFit {
    /// The identification model reached (0 to 5).
    pub model: u8,
    /// RMS on all poses, N.
    pub train_rms_n: f64,
    /// Held-out RMS, N.
    pub heldout_rms_n: f64,
}

/// Structure left.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct ForceUnexplained {
    /// Whether the held-out residuals still depend on a platform coordinate.
    pub structure_found: bool,
    /// Those coordinates (`x`, `y`, `z`, `phi_x`, `phi_y`, `phi_z`).
    pub depends_on: Vec<String>,
}

/// A candidate's score in a step.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ForceCandidateScore {
    /// The candidate model and what it adds.
    pub candidate: String,
    /// Held-out RMS with it, N.
    pub heldout_rms_n: f64,
    /// Corrected p-value.
    pub p_value: f64,
    /// Accepted or why not.
    pub verdict: String,
    /// The outcome in one word (`accepted`, `rejected`, `not_significant`, ...; see
    /// `diagnose::report::Verdict::status`).
    #[serde(default)]
    pub status: String,
}

/// The report (`ferrocal diagnose --forces`): the JSON of `shared/spec/diagnose.md` with `_n`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ForceDiagnoseReport {
    /// Model 0's fit.
    pub nominal: ForceFit,
    /// Accepted effects.
    pub findings: Vec<ForceFinding>,
    /// With every accepted effect.
    #[serde(rename = "final")]
    pub final_fit: ForceFinalFit,
    /// Structure left.
    pub unexplained: ForceUnexplained,
    /// Why nothing was claimed, when the analysis declined.
    pub declined: Option<String>,
    /// The candidates of every step.
    pub candidates: Vec<Vec<ForceCandidateScore>>,
    /// Mass (kg) and centre-of-gravity height (m) of model 0 and of the final model.
    pub mass_kg: [f64; 2],
    /// Centre-of-gravity height above the flange, model 0 and final, metres.
    pub cog_z_m: [f64; 2],
    /// Settings.
    pub settings: ForceDiagnoseOptions,
}
