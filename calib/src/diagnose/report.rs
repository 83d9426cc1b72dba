//! The one report of a diagnosis: the candidate rows of every step with their verdicts, the
//! accepted effects with their held-out figures before and after and their evidence, in the
//! family's unit. Each variant's JSON (`shared/spec/diagnose.md`: `_mm` for arms, `_px` for
//! cameras, `_n` for force sensors) is a thin view built from it.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

/// The unit of a diagnosis's held-out figures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Unit {
    /// Position errors of arms and machines, millimetres (`_mm`).
    Millimetre,
    /// Reprojection errors of cameras, pixels (`_px`).
    Pixel,
    /// Force residuals of force sensors, newtons (`_n`).
    Newton,
}

impl Unit {
    /// The suffix of JSON keys in this unit (`mm`, `px`, `n`).
    pub fn suffix(self) -> &'static str {
        match self {
            Unit::Millimetre => "mm",
            Unit::Pixel => "px",
            Unit::Newton => "n",
        }
    }

    /// The unit's symbol in words (`mm`, `px`, `N`).
    pub fn symbol(self) -> &'static str {
        match self {
            Unit::Millimetre => "mm",
            Unit::Pixel => "px",
            Unit::Newton => "N",
        }
    }
}

/// What happened to a candidate in its step.
#[derive(Clone, Debug, PartialEq)]
pub enum Verdict {
    /// Not decided (e.g. not applicable at the all-data fit).
    Pending,
    /// Could not be scored, with the family's reason.
    Unscored(String),
    /// The held-out improvement is below the threshold.
    TooSmall,
    /// The improvement is not significant after the correction.
    NotSignificant,
    /// Not the candidate examined this step (smallest-p selection).
    NotBest,
    /// Significant, but not examined (the step's limit, or another one was accepted).
    NotExamined,
    /// Nearly a combination of the base model's parameters (sine of the angle).
    Overlap(f64),
    /// Physically implausible sign or size.
    Implausible(String),
    /// Unstable across the folds.
    Unstable(String),
    /// The confirming full refit failed.
    RefitFailed(String),
    /// The confirming full refits do not support it.
    NotConfirmed {
        /// Held-out improvement of the full refits (fraction of the mean squared error).
        improvement: f64,
        /// Their corrected p-value.
        p_corrected: f64,
    },
    /// A look-alike candidate explains it: fitted together, the look-alike adds a significant
    /// improvement to it while it adds none to the look-alike.
    Explained {
        /// Label of the look-alike.
        by: String,
        /// p-value of adding this candidate to the look-alike (not significant).
        p_added: f64,
        /// p-value of adding the look-alike to this candidate (significant).
        p_rival_added: f64,
    },
    /// The held-out data cannot tell it from a look-alike: neither adds a significant
    /// improvement to the other when the two are fitted together. Neither is claimed.
    NotSeparable {
        /// Label of the look-alike.
        with: String,
        /// p-value of adding this candidate to the look-alike.
        p_added: f64,
        /// p-value of adding the look-alike to this candidate.
        p_rival_added: f64,
    },
    /// Accepted, with the corrected p-value that decided it.
    Accepted {
        /// Corrected p-value.
        p_corrected: f64,
    },
}

impl Verdict {
    /// The outcome as one machine-readable word, written beside the words in every report's
    /// JSON (`status`): `accepted`, `rejected` (significant, then refused: overlap, implausible,
    /// unstable, refit failed, not confirmed, explained by a look-alike), `not_separable`,
    /// `not_significant`, `too_small`, `not_best`, `not_examined`, `unscored`, `pending`.
    pub fn status(&self) -> &'static str {
        match self {
            Verdict::Pending => "pending",
            Verdict::Unscored(_) => "unscored",
            Verdict::TooSmall => "too_small",
            Verdict::NotSignificant => "not_significant",
            Verdict::NotBest => "not_best",
            Verdict::NotExamined => "not_examined",
            Verdict::Overlap(_)
            | Verdict::Implausible(_)
            | Verdict::Unstable(_)
            | Verdict::RefitFailed(_)
            | Verdict::NotConfirmed { .. }
            | Verdict::Explained { .. } => "rejected",
            Verdict::NotSeparable { .. } => "not_separable",
            Verdict::Accepted { .. } => "accepted",
        }
    }
}

/// One candidate of one step.
#[derive(Clone, Debug, PartialEq)]
pub struct CandidateRow {
    /// Readable label.
    pub label: String,
    /// Effect name.
    pub effect: String,
    /// 1-based joints.
    pub joints: Vec<usize>,
    /// Held-out figure of the current model.
    pub heldout_before: f64,
    /// Held-out figure with the candidate (screening).
    pub heldout_after: f64,
    /// Improvement measure of the engine's policy.
    pub improvement: f64,
    /// Uncorrected p-value of the screening test.
    pub p_value: f64,
    /// Corrected p-value.
    pub p_corrected: f64,
    /// Parameters of the all-data fit (when examined).
    pub parameters: BTreeMap<String, f64>,
    /// Sine of the angle to the base model (when examined and measured).
    pub overlap_sine: Option<f64>,
    /// What happened to it.
    pub verdict: Verdict,
}

/// The rows of one step.
#[derive(Clone, Debug, PartialEq)]
pub struct StepRows {
    /// The candidates (in the order of the selection).
    pub rows: Vec<CandidateRow>,
    /// Label of the accepted one.
    pub accepted: Option<String>,
    /// Candidates open in the step (also those left out as not applicable).
    pub candidates_tried: usize,
}

/// The statistics behind an accepted candidate.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Decision {
    /// Label of the candidate.
    pub label: String,
    /// Corrected p-value (of the confirmation when there is one).
    pub p_corrected: f64,
    /// Uncorrected p-value.
    pub p_uncorrected: f64,
    /// Candidates tried in the step.
    pub candidates_tried: usize,
    /// Cross-validated held-out figure before.
    pub heldout_before: f64,
    /// After.
    pub heldout_after: f64,
    /// Relative standard deviation of the main parameter over the folds.
    pub relative_std: f64,
    /// Sine of the angle to the base model, when measured.
    pub overlap_sine: Option<f64>,
    /// Other candidates the held-out data cannot tell from it.
    pub alternatives: Vec<String>,
    /// Why the effect is unusual for its kind (outside the typical range of the family's
    /// machines, or of the sign that is unusual), when it was claimed on strong held-out
    /// evidence all the same; the family puts it into the statement.
    pub caution: Option<String>,
}

impl Decision {
    /// The decision to accept the candidate of `row` (its label, p-values and held-out figures),
    /// before the engine counts the candidates tried and lists the alternatives.
    pub(crate) fn of_row(
        row: &CandidateRow,
        relative_std: f64,
        overlap_sine: Option<f64>,
        caution: Option<String>,
    ) -> Self {
        Decision {
            label: row.label.clone(),
            p_corrected: row.p_corrected,
            p_uncorrected: row.p_value,
            candidates_tried: 0,
            heldout_before: row.heldout_before,
            heldout_after: row.heldout_after,
            relative_std,
            overlap_sine,
            alternatives: Vec::new(),
            caution,
        }
    }
}

/// Residuals against the telling input before and after an accepted effect (for plots).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Evidence {
    /// Index of the finding.
    pub finding: usize,
    /// Input label (x axis).
    pub x_label: String,
    /// Residual quantity label (y axis).
    pub y_label: String,
    /// Input value per analysis pose.
    pub x: Vec<f64>,
    /// Held-out residual quantity before.
    pub before: Vec<f64>,
    /// After.
    pub after: Vec<f64>,
}

/// One accepted effect.
#[derive(Clone, Debug)]
pub struct Finding<E> {
    /// The effect as the family describes it.
    pub accepted: E,
    /// Effect name (`shared/spec/diagnose.md`).
    pub effect: String,
    /// 1-based joints.
    pub joints: Vec<usize>,
    /// Identified parameters (names with units).
    pub parameters: BTreeMap<String, f64>,
    /// Reported held-out figure before (validation data when there is some).
    pub heldout_before: f64,
    /// After.
    pub heldout_after: f64,
    /// Fraction of the held-out mean squared error it removes.
    pub explained_fraction: f64,
    /// Plain words.
    pub statement: String,
    /// Standard deviation of the main parameter from the fit's covariance.
    pub std_from_covariance: Option<f64>,
    /// The input against which it shows (empty when the family names none).
    pub telling_input: String,
    /// Residuals against that input (`finding` is set by the views).
    pub evidence: Option<Evidence>,
    /// The statistics.
    pub decision: Decision,
}

impl<E> Finding<E> {
    /// A finding of a family whose effects name no joints, no telling input and no evidence
    /// (the camera and force families); the explained fraction follows from `before` / `after`.
    pub fn without_evidence(
        accepted: E,
        effect: &str,
        parameters: BTreeMap<String, f64>,
        (heldout_before, heldout_after): (f64, f64),
        statement: String,
        decision: Decision,
    ) -> Self {
        Self {
            accepted,
            effect: effect.into(),
            joints: Vec::new(),
            parameters,
            heldout_before,
            heldout_after,
            explained_fraction: explained(heldout_before, heldout_after),
            statement,
            std_from_covariance: None,
            telling_input: String::new(),
            evidence: None,
            decision,
        }
    }
}

/// The result of a selection: every step's candidates and the accepted effects.
#[derive(Clone, Debug)]
pub struct Diagnosis<E> {
    /// Unit of the held-out figures.
    pub unit: Unit,
    /// Every step.
    pub steps: Vec<StepRows>,
    /// Accepted effects, in order of acceptance.
    pub findings: Vec<Finding<E>>,
    /// Effects accepted and later dropped.
    pub retired: Vec<E>,
    /// Whether the search stopped at the most effects with candidates left.
    pub capped: bool,
    /// Remarks of the selection (dropped effects).
    pub notes: Vec<String>,
}

/// Explained fraction of the mean squared error from RMS figures before and after.
pub fn explained(before: f64, after: f64) -> f64 {
    let b = before * before;
    ((b - after * after) / b).max(0.0)
}

/// `x` with `digits` significant digits.
pub fn sig(x: f64, digits: usize) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let mag = x.abs().log10().floor() as i32;
    if (-3..4).contains(&mag) {
        let dec = (digits as i32 - 1 - mag).max(0) as usize;
        format!("{x:.dec$}")
    } else {
        format!("{x:.prec$e}", prec = digits.saturating_sub(1))
    }
}

/// A p-value in words.
pub fn fmt_p(p: f64) -> String {
    if p < 1e-15 {
        "p < 1e-15".into()
    } else {
        format!("p = {}", sig(p, 2))
    }
}

/// The verdict in words of a smallest-p selection (camera, force sensor): every verdict names
/// its reason (never an empty string); `implausible` prefixes the family's reason for an
/// implausible candidate (e.g. `rejected: implausible size`).
pub fn best_verdict(row: &CandidateRow, alpha: f64, min_improvement: f64, implausible: &str) -> String {
    match &row.verdict {
        Verdict::Pending => "not decided (not applicable when fitted on all the data)".into(),
        Verdict::Unscored(why) if why.is_empty() => "could not be scored".into(),
        Verdict::Unscored(why) => why.clone(),
        Verdict::Accepted { p_corrected } => format!("accepted ({} corrected)", fmt_p(*p_corrected)),
        Verdict::Implausible(why) => {
            let lead = if implausible.is_empty() { "rejected as physically implausible" } else { implausible };
            format!("{lead}: {why}")
        }
        Verdict::NotSignificant => format!("not significant (p = {:.2e} >= {alpha})", row.p_corrected),
        Verdict::TooSmall => {
            format!("improvement {:.1} % below {:.1} %", row.improvement * 100.0, min_improvement * 100.0)
        }
        Verdict::NotBest => "not the best candidate".into(),
        Verdict::NotExamined => "significant, not examined further this step".into(),
        Verdict::Overlap(sa) => {
            format!("rejected: nearly a combination of the base model's parameters (sine of the angle {sa:.3})")
        }
        Verdict::Unstable(why) => format!("rejected as unstable across the folds: {why}"),
        Verdict::RefitFailed(e) => format!("rejected: the full refit failed ({e})"),
        Verdict::NotConfirmed { improvement, p_corrected } => format!(
            "rejected by the full refits: held-out improvement {:.2} %, {}",
            improvement * 100.0,
            fmt_p(*p_corrected)
        ),
        Verdict::Explained { by, p_added, p_rival_added } => format!(
            "rejected: {by} explains it ({} for it added to {by}, {} the other way)",
            fmt_p(*p_added),
            fmt_p(*p_rival_added)
        ),
        Verdict::NotSeparable { with, p_added, p_rival_added } => format!(
            "not claimed: the held-out data cannot tell it from {with} ({} and {})",
            fmt_p(*p_added),
            fmt_p(*p_rival_added)
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_in_words() {
        assert_eq!(sig(0.1134, 2), "0.11");
        assert_eq!(sig(7.04e-6, 2), "7.0e-6");
        assert_eq!(fmt_p(1e-20), "p < 1e-15");
    }

    #[test]
    fn units_name_their_keys() {
        assert_eq!(Unit::Millimetre.suffix(), "mm");
        assert_eq!(Unit::Pixel.suffix(), "px");
        assert_eq!(Unit::Newton.suffix(), "n");
    }
}
