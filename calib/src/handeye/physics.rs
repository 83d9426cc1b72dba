//! The target's and the lens's physics in the hand-eye chain, decided on the training images.
//!
//! The chain of [`super::calibrate_hand_eye`] takes the target flat and printed to its nominal
//! spacing (up to an overall scale) and the lens as the 5-coefficient Brown model. Real targets
//! bend and are printed with different x and y scales, and some lenses need another model; the
//! camera diagnosis (`ferrocal diagnose --images`) finds these in images alone. Here each is a
//! candidate of the chain itself, kept only when the chain predicts held-out training images
//! better with it:
//! - `target_nonflatness`: sags `[b, s, t]` of a bowl, a saddle and a twist at the target's
//!   edge ([`ferrocal_vision::calib::TargetDeformation`]);
//! - `target_print_scale`: the printed x spacing against the y spacing, `1 + e_x` (the overall
//!   scale is a separate block, [`super::HandEyeOptions::fit_target_scale`]: against the robot's
//!   metric poses both show);
//! - `lens_distortion`: the rational (8-coefficient) or the Kannala-Brandt model in place of
//!   Brown's 5 coefficients, when the camera is calibrated (not with a given camera).
//!
//! Every score comes from the training images alone (the recording's `test` images play no part):
//! K folds over the training images; per fold the whole hand-eye method (camera calibration,
//! closed forms, refinement) runs on the other folds and the held-out fold's images are predicted
//! through the chain with their robot poses as reported. The diagnose engine
//! ([`crate::diagnose::engine`]) tests each candidate's per-image improvement (sign test and t
//! test, Bonferroni over both and the candidates), accepts the best significant one that removes
//! at least [`PhysicsOptions::min_improvement`] of the held-out RMS, and repeats from the
//! enlarged model. Sizes beyond the typical ranges are not vetoed; they need strong evidence
//! ([`crate::diagnose::engine::Family::unusual`]).

use std::collections::BTreeMap;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use ferrocal_vision::camera::DistortionKind;

use super::{calibrate_hand_eye, HandEyeData, HandEyeOptions, HandEyeResult, IntrinsicsMode, TargetPhysics};
use crate::diagnose::engine::{
    select, AllFit, Baseline, Correction, Describe, Family, Improvement, Policy, Screened, Selection, StepStart, Test,
};
use crate::diagnose::report::{best_verdict, Decision, Finding, Unit};
use crate::error::Result;
use crate::measurement::Split;

/// Settings of [`select_chain_physics`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PhysicsOptions {
    /// Folds over the training images (at most their number: leave-one-out then).
    pub folds: usize,
    /// Family-wise significance level of each step.
    pub alpha: f64,
    /// Least relative held-out RMS improvement for a finding.
    pub min_improvement: f64,
    /// Sags above this at the target's edge are unusual (metres): claimed on strong evidence only.
    pub typical_sag_m: f64,
    /// Relative x-against-y print scale errors above this are unusual.
    pub typical_print_scale: f64,
    /// Rational coefficients above this in size are unusual.
    pub typical_rational: f64,
}

impl Default for PhysicsOptions {
    fn default() -> Self {
        Self {
            folds: 5,
            alpha: 0.01,
            min_improvement: 0.02,
            typical_sag_m: 0.005,
            typical_print_scale: 0.01,
            typical_rational: 50.0,
        }
    }
}

/// Fewest training images the selection runs on (every fold must still calibrate the camera and
/// solve the closed forms).
pub const MIN_PHYSICS_TRAIN_VIEWS: usize = 6;

/// A model variant of the chain: its lens model and the target's free physics.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ChainVariant {
    /// The lens model (the given camera's when the camera is given).
    pub lens: DistortionKind,
    /// The target's bending and anisotropic print scale.
    pub target: TargetPhysics,
}

impl ChainVariant {
    /// The hand-eye options of this variant (lens model and target physics over `base`).
    pub fn options(&self, base: &HandEyeOptions) -> HandEyeOptions {
        let mut o = base.clone();
        o.target_physics = self.target;
        if let IntrinsicsMode::Calibrate(c) = &mut o.intrinsics {
            c.model = self.lens;
        }
        o
    }
}

/// One accepted effect.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PhysicsFinding {
    /// `target_nonflatness`, `target_print_scale` or `lens_distortion`.
    pub effect: String,
    /// Its parameters by name (metres, dimensionless, the lens coefficients).
    pub parameters: BTreeMap<String, f64>,
    /// Their standard deviations by name, where the fit computed them.
    pub std: BTreeMap<String, f64>,
    /// Cross-validated held-out chain RMS over the training images before, pixels.
    pub heldout_rms_before_px: f64,
    /// After.
    pub heldout_rms_after_px: f64,
    /// Corrected p-value.
    pub p_value: f64,
    /// Plain words.
    pub statement: String,
}

/// One candidate of one step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PhysicsCandidate {
    /// Effect and variant.
    pub candidate: String,
    /// Cross-validated held-out chain RMS with it, pixels.
    pub heldout_rms_px: f64,
    /// Corrected p-value.
    pub p_value: f64,
    /// Accepted, or why not.
    pub verdict: String,
    /// The outcome in one word.
    pub status: String,
}

/// What the selection decided (JSON `physics` of `handeye`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ChainPhysicsReport {
    /// The variant chosen (the nominal one when nothing was accepted or the analysis declined).
    pub chosen: ChainVariant,
    /// Accepted effects, in order.
    pub findings: Vec<PhysicsFinding>,
    /// Every candidate of every step.
    pub candidates: Vec<Vec<PhysicsCandidate>>,
    /// Cross-validated held-out chain RMS over the training images of the nominal model, pixels.
    pub nominal_cv_rms_px: f64,
    /// Of the chosen one.
    pub chosen_cv_rms_px: f64,
    /// Training images the folds were made of.
    pub n_train: usize,
    /// Folds.
    pub folds: usize,
    /// Why nothing was tried, when the analysis declined.
    pub declined: Option<String>,
    /// Settings.
    pub settings: PhysicsOptions,
}

/// Per training image (in the order of the recording's training images): its held-out chain
/// squared error sum (px^2; infinite when a corner did not project) and its corners.
type ImageErrors = Vec<(f64, usize)>;

fn rms(e: &ImageErrors) -> f64 {
    Baseline::of_pooled(e).heldout
}

/// The recording's training images.
fn training(data: &HandEyeData) -> HandEyeData {
    HandEyeData { views: data.views.iter().filter(|v| v.split == Split::Train).cloned().collect(), ..data.clone() }
}

/// Cross-validates `variant` over the training images `train` (all `Split::Train`).
fn cross_validate(
    train: &HandEyeData,
    base: &HandEyeOptions,
    variant: ChainVariant,
    folds: usize,
) -> Result<ImageErrors> {
    let n = train.views.len();
    let k = folds.clamp(2, n);
    let options = variant.options(base);
    // The folds are independent fits: one per worker.
    let per_fold: Vec<HandEyeResult> = (0..k)
        .into_par_iter()
        .map(|f| {
            let mut fold = train.clone();
            for (i, v) in fold.views.iter_mut().enumerate() {
                v.split = if i % k == f { Split::Test } else { Split::Train };
            }
            calibrate_hand_eye(&fold, &options)
        })
        .collect::<Result<_>>()?;
    let mut errors = vec![(f64::INFINITY, 0); n];
    for (i, v) in train.views.iter().enumerate() {
        // An image the fit skipped (too few corners) stays infinite: it cannot be scored.
        if let Some(fig) = per_fold[i % k].figures.views.iter().find(|g| g.name == v.name) {
            let used = fig.n_corners - fig.n_unprojected;
            errors[i] = if fig.n_unprojected > 0 || used == 0 {
                (f64::INFINITY, fig.n_corners)
            } else {
                (fig.rms_px * fig.rms_px * used as f64, used)
            };
        }
    }
    Ok(errors)
}

/// Which effect a variant adds to the current one.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Added {
    Lens,
    Shape,
    PrintScale,
}

fn added(current: ChainVariant, v: ChainVariant) -> Added {
    if v.target.shape && !current.target.shape {
        Added::Shape
    } else if v.target.print_x && !current.target.print_x {
        Added::PrintScale
    } else {
        Added::Lens
    }
}

type Candidate = (String, ChainVariant);

struct ChainFamily<'a> {
    train: HandEyeData,
    base: &'a HandEyeOptions,
    all: &'a HandEyeData,
    opts: &'a PhysicsOptions,
    lens_free: bool,
    current: ChainVariant,
    current_cv: ImageErrors,
    /// Per accepted effect, its parameters' standard deviations.
    stds: Vec<BTreeMap<String, f64>>,
}

impl ChainFamily<'_> {
    fn fit(&self, v: ChainVariant) -> Result<HandEyeResult> {
        calibrate_hand_eye(self.all, &v.options(self.base))
    }
}

impl Family for ChainFamily<'_> {
    type Candidate = Candidate;
    type Effect = ChainVariant;
    type Screen = ImageErrors;
    type Fit = HandEyeResult;

    fn unit(&self) -> Unit {
        Unit::Pixel
    }

    fn begin_step(&mut self, _accepted: &[ChainVariant]) -> Result<StepStart> {
        Ok(StepStart::Baseline(Baseline::of_pooled(&self.current_cv)))
    }

    fn candidates(&self, _accepted: &[ChainVariant], _retired: &[ChainVariant]) -> Vec<Candidate> {
        let c = self.current;
        let mut out = Vec::new();
        if !c.target.shape {
            let v = ChainVariant { target: TargetPhysics { shape: true, ..c.target }, ..c };
            out.push(("target_nonflatness (bowl, saddle, twist)".to_string(), v));
        }
        if !c.target.print_x {
            let v = ChainVariant { target: TargetPhysics { print_x: true, ..c.target }, ..c };
            out.push(("target_print_scale (x spacing against y)".to_string(), v));
        }
        if self.lens_free && c.lens == DistortionKind::Brown5 {
            for (label, lens) in [
                ("lens_distortion (rational radial k4..k6)", DistortionKind::Rational8),
                ("lens_distortion (Kannala-Brandt fisheye)", DistortionKind::KannalaBrandt),
            ] {
                out.push((label.to_string(), ChainVariant { lens, ..c }));
            }
        }
        out
    }

    fn describe(&self, (label, v): &Candidate) -> Describe {
        let (effect, n_params) = match added(self.current, *v) {
            Added::Shape => ("target_nonflatness", 3),
            Added::PrintScale => ("target_print_scale", 1),
            Added::Lens => ("lens_distortion", v.lens.coefficient_names().len().saturating_sub(5).max(1)),
        };
        Describe { label: label.clone(), effect: effect.into(), joints: Vec::new(), n_params }
    }

    fn screen(&mut self, (_, v): &Candidate) -> Result<Screened<ImageErrors>> {
        let cv = match cross_validate(&self.train, self.base, *v, self.opts.folds) {
            Ok(cv) => cv,
            Err(e) => return Ok(Screened::Unscored { heldout: f64::NAN, why: format!("could not be fitted: {e}") }),
        };
        let d: Vec<f64> = self
            .current_cv
            .iter()
            .zip(&cv)
            .filter(|((a, _), _)| a.is_finite())
            .map(|((a, n), (b, _))| (a - b) / (*n).max(1) as f64)
            .collect();
        if d.iter().any(|v| !v.is_finite()) {
            return Ok(Screened::Unscored {
                heldout: f64::INFINITY,
                why: "fails to predict some held-out training images (corners outside the lens model's field)".into(),
            });
        }
        Ok(Screened::Scored { d, heldout: rms(&cv), data: cv })
    }

    fn fit_all(
        &mut self,
        (_, v): &Candidate,
        _cv: &ImageErrors,
    ) -> Result<Option<AllFit<ChainVariant, HandEyeResult>>> {
        let fit = self.fit(*v)?;
        let (parameters, _) = parameters_of(added(self.current, *v), &fit);
        Ok(Some(AllFit { effect: *v, parameters, overlap_sine: None, data: fit }))
    }

    fn plausible(&self, fit: &AllFit<ChainVariant, HandEyeResult>) -> std::result::Result<(), String> {
        if fit.parameters.values().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err("the fit has a parameter that is not finite".into())
        }
    }

    fn unusual(&self, fit: &AllFit<ChainVariant, HandEyeResult>) -> Option<String> {
        let p = &fit.parameters;
        let big = |names: &[&str], limit: f64| names.iter().filter_map(|n| p.get(*n)).any(|v| v.abs() > limit);
        match added(self.current, fit.effect) {
            Added::Shape => big(&["bowl_sag_m", "saddle_sag_m", "twist_sag_m"], self.opts.typical_sag_m)
                .then(|| format!("a sag above {} mm at the target's edge is unusual", self.opts.typical_sag_m * 1e3)),
            Added::PrintScale => big(&["scale_x_minus_y"], self.opts.typical_print_scale)
                .then(|| format!("a print scale error above {} % is unusual", self.opts.typical_print_scale * 100.0)),
            Added::Lens => p
                .values()
                .any(|v| v.abs() > self.opts.typical_rational)
                .then(|| format!("a lens coefficient above {} in size is unusual", self.opts.typical_rational)),
        }
    }

    fn accept(
        &mut self,
        fit: AllFit<ChainVariant, HandEyeResult>,
        cv: &ImageErrors,
        decision: &Decision,
    ) -> Result<Finding<ChainVariant>> {
        let kind = added(self.current, fit.effect);
        let (effect, statement) = statement(kind, &fit, decision);
        self.current = fit.effect;
        self.current_cv = cv.clone();
        let mut finding = Finding::without_evidence(
            fit.effect,
            effect,
            fit.parameters,
            (decision.heldout_before, decision.heldout_after),
            statement,
            decision.clone(),
        );
        let std = parameters_of(kind, &fit.data).1;
        finding.std_from_covariance = std.values().next().copied();
        self.stds.push(std);
        Ok(finding)
    }
}

/// The parameters of the effect `kind` in `fit`, and their standard deviations by name.
fn parameters_of(kind: Added, fit: &HandEyeResult) -> (BTreeMap<String, f64>, BTreeMap<String, f64>) {
    let mut values = BTreeMap::new();
    let mut std = BTreeMap::new();
    match kind {
        Added::Shape => {
            if let Some(f) = &fit.target_form {
                for (i, name) in ["bowl_sag_m", "saddle_sag_m", "twist_sag_m"].iter().enumerate() {
                    values.insert(name.to_string(), f.deformation.shape_m[i]);
                    if let Some(s) = f.shape_std_m {
                        std.insert(name.to_string(), s[i]);
                    }
                }
            }
        }
        Added::PrintScale => {
            if let Some(f) = &fit.target_form {
                values.insert("scale_x_minus_y".into(), f.deformation.scale[0]);
                if let Some(s) = f.scale_x_std {
                    std.insert("scale_x_minus_y".into(), s);
                }
            }
        }
        Added::Lens => {
            let d = fit.camera.distortion;
            let names = d.kind().coefficient_names();
            for (i, (name, v)) in names.iter().zip(&d.coefficients()).enumerate() {
                values.insert(name.to_string(), *v);
                if let Some(s) = fit.camera_std.as_ref().and_then(|s| s.get(4 + i)) {
                    std.insert(name.to_string(), *s);
                }
            }
        }
    }
    (values, std)
}

fn statement(kind: Added, fit: &AllFit<ChainVariant, HandEyeResult>, d: &Decision) -> (&'static str, String) {
    let (before, after, p, m) = (d.heldout_before, d.heldout_after, d.p_corrected, d.candidates_tried);
    let tail = format!(
        "the chain then predicts held-out training images at {after:.3} px instead of {before:.3} px (p = {p:.1e} after correcting for {m} candidates)"
    );
    let caution = d.caution.as_deref().map(|c| format!(" Note: {c}.")).unwrap_or_default();
    let (_, std) = parameters_of(kind, &fit.data);
    let pm = |name: &str, scale: f64| std.get(name).map(|s| format!(" +- {:.2}", s * scale)).unwrap_or_default();
    let p_ = &fit.parameters;
    match kind {
        Added::Shape => (
            "target_nonflatness",
            format!(
                "the target is not flat: its edge stands {:.3}{} mm out of plane as a bowl, {:.3}{} mm as a saddle and {:.3}{} mm as a twist (1 sigma); {tail}.{caution}",
                p_["bowl_sag_m"] * 1e3,
                pm("bowl_sag_m", 1e3),
                p_["saddle_sag_m"] * 1e3,
                pm("saddle_sag_m", 1e3),
                p_["twist_sag_m"] * 1e3,
                pm("twist_sag_m", 1e3)
            ),
        ),
        Added::PrintScale => (
            "target_print_scale",
            format!(
                "the printed pattern's x spacing differs from its y spacing by {:.0}{} ppm (1 sigma); {tail}.{caution}",
                p_["scale_x_minus_y"] * 1e6,
                pm("scale_x_minus_y", 1e6)
            ),
        ),
        Added::Lens => (
            "lens_distortion",
            format!("the lens is better described by the {} model; {tail}.{caution}", fit.effect.lens.name()),
        ),
    }
}

/// Decides the chain's target physics and lens model on the training images of `data` (see the
/// module documentation); `base` are the hand-eye options the variants start from (their lens
/// model the nominal one). Declines, with the reason, below [`MIN_PHYSICS_TRAIN_VIEWS`] training
/// images. Errors: those of [`calibrate_hand_eye`] for the nominal model.
pub fn select_chain_physics(
    data: &HandEyeData,
    base: &HandEyeOptions,
    opts: &PhysicsOptions,
) -> Result<ChainPhysicsReport> {
    let train = training(data);
    let n = train.views.len();
    let (lens, lens_free) = match &base.intrinsics {
        IntrinsicsMode::Calibrate(c) => (c.model, true),
        IntrinsicsMode::Fixed(c) => (c.distortion.kind(), false),
    };
    let nominal = ChainVariant { lens, target: base.target_physics };
    let folds = opts.folds.clamp(2, n.max(2));
    let mut report = ChainPhysicsReport {
        chosen: nominal,
        findings: Vec::new(),
        candidates: Vec::new(),
        nominal_cv_rms_px: f64::NAN,
        chosen_cv_rms_px: f64::NAN,
        n_train: n,
        folds,
        declined: None,
        settings: opts.clone(),
    };
    if n < MIN_PHYSICS_TRAIN_VIEWS {
        report.declined = Some(format!(
            "{n} training images: at least {MIN_PHYSICS_TRAIN_VIEWS} are needed to hold images out and still calibrate; the target is taken flat and the lens model as given"
        ));
        return Ok(report);
    }
    let current_cv = cross_validate(&train, base, nominal, folds)?;
    report.nominal_cv_rms_px = rms(&current_cv);
    let mut family =
        ChainFamily { train, base, all: data, opts, lens_free, current: nominal, current_cv, stds: Vec::new() };
    let policy = Policy {
        alpha: opts.alpha,
        min_improvement: opts.min_improvement,
        max_effects: usize::MAX,
        min_sin_angle: 0.0,
        test: Test::SignOrT,
        correction: Correction::PerCandidate,
        improvement: Improvement::RmsFraction,
        selection: Selection::SmallestP,
    };
    let diagnosis = select(&mut family, &policy)?;
    report.chosen = family.current;
    report.chosen_cv_rms_px = rms(&family.current_cv);
    report.findings = diagnosis
        .findings
        .iter()
        .zip(&family.stds)
        .map(|(f, std)| PhysicsFinding {
            effect: f.effect.clone(),
            parameters: f.parameters.clone(),
            std: std.clone(),
            heldout_rms_before_px: f.heldout_before,
            heldout_rms_after_px: f.heldout_after,
            p_value: f.decision.p_corrected,
            statement: f.statement.clone(),
        })
        .collect();
    report.candidates = diagnosis
        .steps
        .iter()
        .map(|s| {
            s.rows
                .iter()
                .map(|r| PhysicsCandidate {
                    candidate: r.label.clone(),
                    heldout_rms_px: r.heldout_after,
                    p_value: r.p_corrected,
                    verdict: best_verdict(r, opts.alpha, opts.min_improvement, "rejected"),
                    status: r.verdict.status().to_string(),
                })
                .collect()
        })
        .collect();
    Ok(report)
}
