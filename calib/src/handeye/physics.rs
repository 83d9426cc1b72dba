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

use super::{
    calibrate_hand_eye, HandEyeData, HandEyeOptions, HandEyeResult, IntrinsicsMode, TargetForm, TargetPhysics,
};
use crate::diagnose::camera::{candidate_scores, CameraCandidateScore};
use crate::diagnose::engine::{
    select as engine_select, AllFit, Baseline, Describe, Family, Policy, Screened, StepStart,
};
use crate::diagnose::report::{Decision, Finding, Unit};
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

/// One candidate of one step: the image families' score (effect and variant, cross-validated
/// held-out chain RMS with it in pixels, corrected p-value, verdict, status).
pub type PhysicsCandidate = CameraCandidateScore;

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
    /// A rig's chosen lens model of every camera, camera 0 first (`chosen` is camera 0's);
    /// empty for one camera.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub rig_lenses: Vec<DistortionKind>,
    /// A rig's training images per camera (`n_train` is their sum); empty for one camera.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub n_train_per_camera: Vec<usize>,
}

impl ChainPhysicsReport {
    /// Camera `k`'s chosen variant: the target's physics and its lens model (`chosen` for one
    /// camera).
    pub fn variant_of(&self, k: usize) -> ChainVariant {
        ChainVariant { lens: self.rig_lenses.get(k).copied().unwrap_or(self.chosen.lens), target: self.chosen.target }
    }
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

/// The selection's own variant: the target's physics (one target, shared by every camera) and
/// each camera's lens model, camera 0 first.
#[derive(Clone, Debug, PartialEq)]
struct Variant {
    lens: Vec<DistortionKind>,
    target: TargetPhysics,
}

impl Variant {
    /// Camera `k`'s chain variant.
    fn chain(&self, k: usize) -> ChainVariant {
        ChainVariant { lens: self.lens[k], target: self.target }
    }
}

/// Which effect a variant adds to the current one (a lens: of which camera).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Added {
    Lens(usize),
    Shape,
    PrintScale,
}

fn added(current: &Variant, v: &Variant) -> Added {
    if v.target.shape && !current.target.shape {
        Added::Shape
    } else if v.target.print_x && !current.target.print_x {
        Added::PrintScale
    } else {
        Added::Lens(current.lens.iter().zip(&v.lens).position(|(a, b)| a != b).unwrap_or(0))
    }
}

type Candidate = (String, Variant);

/// One camera's chain: its training images, its whole recording, its options.
struct Chain<'a> {
    train: HandEyeData,
    all: &'a HandEyeData,
    base: &'a HandEyeOptions,
    /// Whether its lens model may change (the camera is calibrated, not given).
    lens_free: bool,
}

struct ChainFamily<'a> {
    chains: Vec<Chain<'a>>,
    opts: &'a PhysicsOptions,
    current: Variant,
    /// The current variant's held-out errors, every camera's training images in camera order.
    current_cv: ImageErrors,
    /// Per accepted effect, its parameters' standard deviations.
    stds: Vec<BTreeMap<String, f64>>,
}

impl ChainFamily<'_> {
    fn fit(&self, v: &Variant) -> Result<Vec<HandEyeResult>> {
        self.chains.iter().enumerate().map(|(k, c)| calibrate_hand_eye(c.all, &v.chain(k).options(c.base))).collect()
    }

    /// Every camera's cross-validated errors of `v`, concatenated in camera order.
    fn cross_validate(&self, v: &Variant) -> Result<ImageErrors> {
        let mut out = Vec::new();
        for (k, c) in self.chains.iter().enumerate() {
            out.extend(cross_validate(&c.train, c.base, v.chain(k), self.opts.folds)?);
        }
        Ok(out)
    }

    /// The camera's name in words, for a rig (empty for one camera).
    fn of_camera(&self, k: usize) -> String {
        if self.chains.len() > 1 {
            format!(" of cam{k}")
        } else {
            String::new()
        }
    }
}

impl Family for ChainFamily<'_> {
    type Candidate = Candidate;
    type Effect = Variant;
    type Screen = ImageErrors;
    type Fit = Vec<HandEyeResult>;

    fn unit(&self) -> Unit {
        Unit::Pixel
    }

    fn begin_step(&mut self, _accepted: &[Variant]) -> Result<StepStart> {
        Ok(StepStart::Baseline(Baseline::of_pooled(&self.current_cv)))
    }

    fn candidates(&self, _accepted: &[Variant], _retired: &[Variant]) -> Vec<Candidate> {
        let c = &self.current;
        let mut out = Vec::new();
        if !c.target.shape {
            let v = Variant { target: TargetPhysics { shape: true, ..c.target }, ..c.clone() };
            out.push(("target_nonflatness (bowl, saddle, twist)".to_string(), v));
        }
        if !c.target.print_x {
            let v = Variant { target: TargetPhysics { print_x: true, ..c.target }, ..c.clone() };
            out.push(("target_print_scale (x spacing against y)".to_string(), v));
        }
        for (k, chain) in self.chains.iter().enumerate() {
            if !chain.lens_free || c.lens[k] != DistortionKind::Brown5 {
                continue;
            }
            let camera = self.of_camera(k);
            for (label, lens) in [
                ("rational radial k4..k6", DistortionKind::Rational8),
                ("Kannala-Brandt fisheye", DistortionKind::KannalaBrandt),
            ] {
                let mut v = c.clone();
                v.lens[k] = lens;
                out.push((format!("lens_distortion{camera} ({label})"), v));
            }
        }
        out
    }

    fn describe(&self, (label, v): &Candidate) -> Describe {
        let (effect, n_params) = match added(&self.current, v) {
            Added::Shape => ("target_nonflatness", 3),
            Added::PrintScale => ("target_print_scale", 1),
            Added::Lens(k) => ("lens_distortion", v.lens[k].coefficient_names().len().saturating_sub(5).max(1)),
        };
        Describe { label: label.clone(), effect: effect.into(), joints: Vec::new(), n_params }
    }

    fn screen(&mut self, (_, v): &Candidate) -> Result<Screened<ImageErrors>> {
        let cv = match self.cross_validate(v) {
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
    ) -> Result<Option<AllFit<Variant, Vec<HandEyeResult>>>> {
        let fits = self.fit(v)?;
        let (parameters, _) = parameters_of(added(&self.current, v), &fits);
        Ok(Some(AllFit { effect: v.clone(), parameters, overlap_sine: None, data: fits }))
    }

    fn plausible(&self, fit: &AllFit<Variant, Vec<HandEyeResult>>) -> std::result::Result<(), String> {
        if fit.parameters.values().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err("the fit has a parameter that is not finite".into())
        }
    }

    fn unusual(&self, fit: &AllFit<Variant, Vec<HandEyeResult>>) -> Option<String> {
        let p = &fit.parameters;
        let big = |names: &[&str], limit: f64| names.iter().filter_map(|n| p.get(*n)).any(|v| v.abs() > limit);
        match added(&self.current, &fit.effect) {
            Added::Shape => big(&["bowl_sag_m", "saddle_sag_m", "twist_sag_m"], self.opts.typical_sag_m)
                .then(|| format!("a sag above {} mm at the target's edge is unusual", self.opts.typical_sag_m * 1e3)),
            Added::PrintScale => big(&["scale_x_minus_y"], self.opts.typical_print_scale)
                .then(|| format!("a print scale error above {} % is unusual", self.opts.typical_print_scale * 100.0)),
            Added::Lens(_) => p
                .values()
                .any(|v| v.abs() > self.opts.typical_rational)
                .then(|| format!("a lens coefficient above {} in size is unusual", self.opts.typical_rational)),
        }
    }

    fn accept(
        &mut self,
        fit: AllFit<Variant, Vec<HandEyeResult>>,
        cv: &ImageErrors,
        decision: &Decision,
    ) -> Result<Finding<Variant>> {
        let kind = added(&self.current, &fit.effect);
        let (effect, statement) = statement(kind, &fit, decision, &self.of_camera_of(kind));
        self.current = fit.effect.clone();
        self.current_cv = cv.clone();
        let std = parameters_of(kind, &fit.data).1;
        let mut finding = Finding::without_evidence(
            fit.effect,
            effect,
            fit.parameters,
            (decision.heldout_before, decision.heldout_after),
            statement,
            decision.clone(),
        );
        finding.std_from_covariance = std.values().next().copied();
        self.stds.push(std);
        Ok(finding)
    }
}

impl ChainFamily<'_> {
    /// [`ChainFamily::of_camera`] of a lens effect; empty for the target's.
    fn of_camera_of(&self, kind: Added) -> String {
        match kind {
            Added::Lens(k) => self.of_camera(k),
            _ => String::new(),
        }
    }
}

/// Inverse-variance mean of `(value, std)` pairs with its standard deviation; the plain mean
/// (no standard deviation) when a pair has none or a zero one; one pair as it is.
fn pooled(pairs: &[(f64, Option<f64>)]) -> (f64, Option<f64>) {
    if let [(v, s)] = pairs {
        return (*v, *s);
    }
    let weights: Option<Vec<f64>> = pairs.iter().map(|(_, s)| s.filter(|s| *s > 0.0).map(|s| 1.0 / (s * s))).collect();
    match weights {
        Some(w) => {
            let sum: f64 = w.iter().sum();
            (pairs.iter().zip(&w).map(|((v, _), w)| v * w).sum::<f64>() / sum, Some(sum.sqrt().recip()))
        }
        None => (pairs.iter().map(|(v, _)| v).sum::<f64>() / pairs.len() as f64, None),
    }
}

/// The target's form pooled over a rig's cameras' fits (each camera's estimate of the one
/// target): every sag and `e_x` the inverse-variance mean of the cameras that fitted it, with its
/// standard deviation (taking the cameras' estimates as independent); `None` when no fit carries
/// a form. One fit's form as it is.
pub fn pooled_target_form(fits: &[&HandEyeResult]) -> Option<TargetForm> {
    let forms: Vec<&TargetForm> = fits.iter().filter_map(|f| f.target_form.as_ref()).collect();
    let first = *forms.first()?;
    let mut out = *first;
    if first.deformation.shape_free {
        let mut std = [0.0; 3];
        for i in 0..3 {
            let pairs: Vec<_> = forms.iter().map(|f| (f.deformation.shape_m[i], f.shape_std_m.map(|s| s[i]))).collect();
            let (v, s) = pooled(&pairs);
            out.deformation.shape_m[i] = v;
            std[i] = s.unwrap_or(f64::NAN);
        }
        out.shape_std_m = first.shape_std_m.map(|_| std);
    }
    if first.deformation.scale_free {
        let pairs: Vec<_> = forms.iter().map(|f| (f.deformation.scale[0], f.scale_x_std)).collect();
        let (v, s) = pooled(&pairs);
        out.deformation.scale[0] = v;
        out.scale_x_std = s;
    }
    Some(out)
}

/// The parameters of the effect `kind` in `fits` (one per camera), and their standard
/// deviations by name: the target's pooled over the cameras ([`pooled`]), a lens's from its
/// camera's fit.
fn parameters_of(kind: Added, fits: &[HandEyeResult]) -> (BTreeMap<String, f64>, BTreeMap<String, f64>) {
    let mut values = BTreeMap::new();
    let mut std = BTreeMap::new();
    let refs: Vec<&HandEyeResult> = fits.iter().collect();
    let form = pooled_target_form(&refs);
    match kind {
        Added::Shape => {
            if let Some(f) = &form {
                for (i, name) in ["bowl_sag_m", "saddle_sag_m", "twist_sag_m"].iter().enumerate() {
                    values.insert(name.to_string(), f.deformation.shape_m[i]);
                    if let Some(s) = f.shape_std_m {
                        std.insert(name.to_string(), s[i]);
                    }
                }
            }
        }
        Added::PrintScale => {
            if let Some(f) = &form {
                values.insert("scale_x_minus_y".into(), f.deformation.scale[0]);
                if let Some(s) = f.scale_x_std {
                    std.insert("scale_x_minus_y".into(), s);
                }
            }
        }
        Added::Lens(k) => {
            let fit = &fits[k];
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

fn statement(
    kind: Added,
    fit: &AllFit<Variant, Vec<HandEyeResult>>,
    d: &Decision,
    camera: &str,
) -> (&'static str, String) {
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
        Added::Lens(k) => (
            "lens_distortion",
            format!("the lens{camera} is better described by the {} model; {tail}.{caution}", fit.effect.lens[k].name()),
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
    select(&[(data, base)], opts)
}

/// [`select_chain_physics`] for a rig: `cameras` are every camera's recording and hand-eye
/// options, camera 0 first. The target is one physical object, so its bending and print scale
/// are candidates shared by every camera, scored on every camera's held-out training images
/// together (each camera's chain is its own hand-eye fit, as the rig's first step fits them);
/// each calibrated camera's lens model is a candidate of its own. The report's
/// [`ChainPhysicsReport::rig_lenses`] holds every camera's chosen lens
/// ([`ChainPhysicsReport::variant_of`]); its parameters of the target are the cameras' estimates
/// pooled by inverse variance ([`pooled_target_form`]). Declines when a camera has fewer than
/// [`MIN_PHYSICS_TRAIN_VIEWS`] training images.
pub fn select_rig_physics(
    cameras: &[(&HandEyeData, &HandEyeOptions)],
    opts: &PhysicsOptions,
) -> Result<ChainPhysicsReport> {
    let mut report = select(cameras, opts)?;
    report.n_train_per_camera = cameras.iter().map(|(d, _)| training(d).views.len()).collect();
    Ok(report)
}

fn select(cameras: &[(&HandEyeData, &HandEyeOptions)], opts: &PhysicsOptions) -> Result<ChainPhysicsReport> {
    let chains: Vec<Chain> = cameras
        .iter()
        .map(|(data, base)| Chain {
            train: training(data),
            all: data,
            base,
            lens_free: matches!(base.intrinsics, IntrinsicsMode::Calibrate(_)),
        })
        .collect();
    let lens_of = |base: &HandEyeOptions| match &base.intrinsics {
        IntrinsicsMode::Calibrate(c) => c.model,
        IntrinsicsMode::Fixed(c) => c.distortion.kind(),
    };
    let nominal =
        Variant { lens: cameras.iter().map(|(_, b)| lens_of(b)).collect(), target: cameras[0].1.target_physics };
    let n_min = chains.iter().map(|c| c.train.views.len()).min().unwrap_or(0);
    let n: usize = chains.iter().map(|c| c.train.views.len()).sum();
    let folds = opts.folds.clamp(2, n_min.max(2));
    let rig = cameras.len() > 1;
    let mut report = ChainPhysicsReport {
        chosen: nominal.chain(0),
        findings: Vec::new(),
        candidates: Vec::new(),
        nominal_cv_rms_px: f64::NAN,
        chosen_cv_rms_px: f64::NAN,
        n_train: n,
        folds,
        declined: None,
        settings: opts.clone(),
        rig_lenses: if rig { nominal.lens.clone() } else { Vec::new() },
        n_train_per_camera: Vec::new(),
    };
    if n_min < MIN_PHYSICS_TRAIN_VIEWS {
        let who = if rig { " (the camera with the fewest)" } else { "" };
        report.declined = Some(format!(
            "{n_min} training images{who}: at least {MIN_PHYSICS_TRAIN_VIEWS} are needed to hold images out and still calibrate; the target is taken flat and the lens model as given"
        ));
        return Ok(report);
    }
    let mut family = ChainFamily { chains, opts, current: nominal.clone(), current_cv: Vec::new(), stds: Vec::new() };
    family.current_cv = family.cross_validate(&nominal)?;
    report.nominal_cv_rms_px = rms(&family.current_cv);
    let policy = Policy::held_out_images(opts.alpha, opts.min_improvement);
    let diagnosis = engine_select(&mut family, &policy)?;
    report.chosen = family.current.chain(0);
    if rig {
        report.rig_lenses = family.current.lens.clone();
    }
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
    report.candidates = candidate_scores(&diagnosis.steps, opts.alpha, opts.min_improvement, "rejected");
    Ok(report)
}
