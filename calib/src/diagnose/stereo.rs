//! Missing physics in a stereo calibration: both cameras with the default lens model
//! (5-coefficient Brown), a flat, nominally printed target and one rigid `T_cam1_cam0`, fitted
//! together over both cameras' corners; then test what the images of both cameras show that this
//! model leaves out.
//!
//! Candidates (JSON `effect` names of `shared/spec/diagnose.md`):
//! - `target_nonflatness` and `target_print_scale`: the one-camera diagnosis's target models
//!   ([`super::camera`]), **one for both cameras** (one physical target: the evidence of both
//!   images of every pair pools);
//! - `lens_distortion` **per camera**: the rational radial model (`k4, k5, k6`) or the
//!   Kannala-Brandt model in place of camera 0's, or camera 1's, 5-coefficient one (the finding
//!   names its camera).
//!
//! Every fit is vision's rig bundle adjustment ([`ferrocal_vision::calib::adjust_rig`]: the two
//! cameras, `T_cam1_cam0`, the target's shape and print scale shared by all views, one target
//! pose per pair). The start is the stereo calibration ([`ferrocal_vision::calib::calibrate_stereo`]),
//! which also makes the right views' corner numbering that of the left ones (a chessboard may be
//! numbered from either end). Held-out figures come from whole pairs held out (K-fold over the
//! pairs in which both images show the target): the model is fitted on the other pairs (and on
//! every view only one camera saw, with that camera alone), then only the held-out pair's target
//! pose is fitted to both images' corners (cameras, `T_cam1_cam0`, shape and print scale held)
//! and the score is that pair's reprojection RMS over both images. Acceptance is the one-camera
//! family's, through the same engine ([`super::engine::select`]: sign test and t test over the
//! held-out pairs, Bonferroni over both tests and the candidates, a least relative improvement,
//! a plausible size).

use std::collections::BTreeMap;

use ferrocal_vision::calib::{
    adjust_rig, calibrate_stereo, BundleMode, CalibrationOptions, PlanarTarget, RigBundleFit, RigBundleModel,
    RigBundleSpec, View,
};
use nalgebra::{DVector, Isometry3};

use super::camera::{
    board_width_m, candidate_scores, centred, effect_parameters, plausible_size, print_scale_statement, screened,
    unexplained_structure, vision_error, Added, CameraDiagnoseOptions, CameraFinalFit, CameraFit, CameraUnexplained,
};
use super::engine::{select, AllFit, Baseline, Describe, Family, Policy, Screened, StepStart};
use super::report::{Decision, Finding, Unit};
use crate::error::{CalibError, Result};

mod types;
pub use types::*;

/// Camera names in statements.
const CAMERA_NAMES: [&str; 2] = ["camera 0 (left)", "camera 1 (right)"];

/// A model variant: each camera's lens model, whether the target bends, whether its print is
/// scaled.
type Variant = super::camera::variant::Variant<2>;

const NOMINAL: Variant = Variant::NOMINAL;

/// The views of a pair: `views[k][i]` is camera `k`'s view of target pose `i`; `pairs` the
/// poses both cameras saw (the held-out units), in order.
struct Rig {
    views: Vec<Vec<Option<View>>>,
    pairs: Vec<usize>,
}

impl Rig {
    /// The views of the poses `keep`, camera-major.
    fn subset(&self, keep: &[usize]) -> Vec<Vec<Option<View>>> {
        self.views.iter().map(|cam| keep.iter().map(|&i| cam[i].clone()).collect()).collect()
    }

    /// Training poses of fold `f` of `k`: every pose but the held-out pairs of the fold.
    fn train(&self, f: usize, k: usize) -> Vec<usize> {
        let held: Vec<usize> = self.pairs.iter().enumerate().filter(|(j, _)| j % k == f).map(|(_, &i)| i).collect();
        (0..self.views[0].len()).filter(|i| !held.contains(i)).collect()
    }
}

/// Fits `variant` to the poses `keep` from `start` (model and, when the poses are the same,
/// their fitted poses).
fn fit_variant(
    rig: &Rig,
    keep: &[usize],
    target: &PlanarTarget,
    variant: Variant,
    start: (&RigBundleModel, Option<&[Isometry3<f64>]>),
    covariance: bool,
) -> Result<RigBundleFit> {
    let mut model = start.0.clone();
    if !variant.bent {
        model.shape = Default::default();
    }
    if !variant.scaled {
        model.print_scale = Default::default();
    }
    let spec = RigBundleSpec {
        lenses: variant.lens.iter().map(|l| Some(*l)).collect(),
        estimate_shape: variant.bent,
        estimate_print_scale: variant.scaled,
        mode: BundleMode::Full,
        max_iterations: 100,
        covariance,
    };
    adjust_rig(&rig.subset(keep), target, &model, start.1, &spec).map_err(vision_error("rig bundle adjustment"))
}

/// One cross-validation of a variant over the pairs.
#[derive(Clone)]
struct CrossValidation {
    /// Per pair: sum of squared held-out reprojection errors over both images (infinite when the
    /// fitted model cannot place the pair) and the number of corners.
    errors: Vec<(f64, usize)>,
    /// Per pair and camera: the held-out residuals (x and y per corner), when placed.
    residuals: Vec<[Option<DVector<f64>>; 2]>,
    /// Per fold: the variant's fit on the training poses (the start of the next variant's).
    fits: Vec<RigBundleFit>,
}

/// Cross-validates `variant`, each fold's fit started from `from`'s fit of that fold (the
/// current model's) or, without it, from `nominal`.
fn cross_validate(
    rig: &Rig,
    target: &PlanarTarget,
    variant: Variant,
    folds: usize,
    nominal: &RigBundleModel,
    from: Option<&CrossValidation>,
) -> Result<CrossValidation> {
    let n = rig.pairs.len();
    let k = folds.clamp(2, n);
    let mut cv = CrossValidation { errors: vec![(0.0, 0); n], residuals: vec![[None, None]; n], fits: Vec::new() };
    for f in 0..k {
        let train = rig.train(f, k);
        let start = match from {
            Some(c) => (&c.fits[f].model, Some(c.fits[f].t_cam0_target.as_slice())),
            None => (nominal, None),
        };
        let fit = fit_variant(rig, &train, target, variant, start, false)?;
        for (j, &i) in rig.pairs.iter().enumerate().filter(|(j, _)| j % k == f) {
            let spec = RigBundleSpec { mode: BundleMode::PosesOnly, max_iterations: 100, ..Default::default() };
            let placed = adjust_rig(&rig.subset(&[i]), target, &fit.model, None, &spec).ok();
            let per_cam: [Option<DVector<f64>>; 2] = std::array::from_fn(|c| {
                placed.as_ref().map(|p| {
                    let r = &p.residuals_px[0][c];
                    DVector::from_iterator(2 * r.len(), r.iter().flat_map(|r| [r.x, r.y]))
                })
            });
            let sq = match &placed {
                Some(_) => per_cam.iter().flatten().map(|r| r.norm_squared()).sum(),
                None => f64::INFINITY,
            };
            let n_corners = rig.views.iter().map(|c| c[i].as_ref().map_or(0, |v| v.corners_px.len())).sum::<usize>();
            cv.errors[j] = (sq, n_corners);
            cv.residuals[j] = per_cam;
        }
        cv.fits.push(fit);
    }
    Ok(cv)
}

/// The candidate family: a label and the variant it leads to.
type StereoCandidate = (String, Variant);

struct StereoFamily<'a> {
    rig: &'a Rig,
    target: &'a PlanarTarget,
    opts: &'a CameraDiagnoseOptions,
    nominal_start: RigBundleModel,
    current: Variant,
    current_cv: CrossValidation,
    current_fit: RigBundleFit,
    all: Vec<usize>,
    /// Per accepted effect, in order: its camera (lens effects) and its parameters' standard
    /// deviations.
    accepted: Vec<(Option<usize>, BTreeMap<String, f64>)>,
}

/// The effect's parameters (and their standard deviations) in the fit of all poses.
fn fit_parameters(fit: &RigBundleFit, kind: Added) -> (BTreeMap<String, f64>, BTreeMap<String, f64>) {
    let std: BTreeMap<String, f64> =
        fit.parameter_names.iter().cloned().zip(fit.std.iter().copied()).filter(|(_, s)| s.is_finite()).collect();
    let m = &fit.model;
    effect_parameters(kind, (m.shape, m.print_scale.x), |c| m.cameras[c].distortion, &std, |c| format!("cam{c}."))
}

impl Family for StereoFamily<'_> {
    type Candidate = StereoCandidate;
    type Effect = Variant;
    type Screen = CrossValidation;
    type Fit = RigBundleFit;

    fn unit(&self) -> Unit {
        Unit::Pixel
    }

    fn begin_step(&mut self, _accepted: &[Variant]) -> Result<StepStart> {
        Ok(StepStart::Baseline(Baseline::of_pooled(&self.current_cv.errors)))
    }

    fn candidates(&self, _accepted: &[Variant], _retired: &[Variant]) -> Vec<StereoCandidate> {
        self.current.candidates(|c, what| format!("lens_distortion of {} ({what})", CAMERA_NAMES[c]), "; both cameras")
    }

    fn describe(&self, (label, variant): &StereoCandidate) -> Describe {
        variant.describe(self.current, label)
    }

    fn screen(&mut self, (_, variant): &StereoCandidate) -> Result<Screened<CrossValidation>> {
        // Per pair: difference of mean squared error (before - after) over both images.
        let (rig, start) = (self.rig, &self.nominal_start);
        let cv = cross_validate(rig, self.target, *variant, self.opts.folds, start, Some(&self.current_cv));
        Ok(screened(cv, |cv| &cv.errors, &self.current_cv.errors, "pairs"))
    }

    fn fit_all(
        &mut self,
        (_, variant): &StereoCandidate,
        _cv: &CrossValidation,
    ) -> Result<Option<AllFit<Variant, RigBundleFit>>> {
        let start = (&self.current_fit.model, Some(self.current_fit.t_cam0_target.as_slice()));
        let fit = fit_variant(self.rig, &self.all, self.target, *variant, start, true)?;
        let (parameters, _) = fit_parameters(&fit, variant.added_to(self.current));
        Ok(Some(AllFit { effect: *variant, parameters, overlap_sine: None, data: fit }))
    }

    fn plausible(&self, fit: &AllFit<Variant, RigBundleFit>) -> std::result::Result<(), String> {
        let m = &fit.data.model;
        plausible_size(
            fit.effect.added_to(self.current),
            (m.shape, m.print_scale.x),
            |c| m.cameras[c].distortion,
            self.opts,
        )
    }

    fn accept(
        &mut self,
        fit: AllFit<Variant, RigBundleFit>,
        cv: &CrossValidation,
        decision: &Decision,
    ) -> Result<Finding<Variant>> {
        let (variant, parameters, fit) = (fit.effect, fit.parameters, fit.data);
        let (before, after, p, m) =
            (decision.heldout_before, decision.heldout_after, decision.p_corrected, decision.candidates_tried);
        let kind = variant.added_to(self.current);
        let (_, stds) = fit_parameters(&fit, kind);
        self.accepted.push((if let Added::Lens(c) = kind { Some(c) } else { None }, stds.clone()));
        let sd = |name: &str| stds.get(name).copied().unwrap_or(f64::NAN);
        let gain = format!(
            "the held-out reprojection RMS over both images of a pair drops from {before:.3} to {after:.3} px (p = {p:.1e} after correcting for {m} candidates)"
        );
        let mut main_std = None;
        let (effect, statement) = match kind {
            Added::Shape => {
                let s = fit.model.shape;
                main_std = Some(sd("bowl_sag_m"));
                ("target_nonflatness", format!(
                    "the target is not flat (seen by both cameras): its edge stands {:.3} +- {:.3} mm out of plane as a bowl, {:.3} +- {:.3} mm as a saddle and {:.3} +- {:.3} mm as a twist (1 sigma); {gain}",
                    s.bowl_m * 1e3, sd("bowl_sag_m") * 1e3, s.saddle_m * 1e3, sd("saddle_sag_m") * 1e3,
                    s.twist_m * 1e3, sd("twist_sag_m") * 1e3
                ))
            }
            Added::PrintScale => {
                let e = fit.model.print_scale.x;
                main_std = Some(sd("scale_x_minus_y"));
                let words =
                    print_scale_statement(e, sd("scale_x_minus_y"), board_width_m(self.target), (before, after, p, m));
                ("target_print_scale", format!("{words} (both cameras)"))
            }
            Added::Lens(c) => {
                let d = fit.model.cameras[c].distortion.coefficients();
                let model = match variant.lens[c] {
                    ferrocal_vision::camera::DistortionKind::KannalaBrandt => {
                        "the Kannala-Brandt (fisheye) model".to_string()
                    }
                    _ => format!("the rational radial terms (k4 = {:.3}, k5 = {:.3}, k6 = {:.3})", d[5], d[6], d[7]),
                };
                (
                    "lens_distortion",
                    format!(
                        "{}: the 5-coefficient lens model leaves systematic image residuals; with {model} {gain}",
                        CAMERA_NAMES[c]
                    ),
                )
            }
        };
        self.current = variant;
        self.current_cv = cv.clone();
        self.current_fit = fit;
        let mut finding =
            Finding::without_evidence(variant, effect, parameters, (before, after), statement, decision.clone());
        finding.std_from_covariance = main_std;
        Ok(finding)
    }
}

/// The right views renumbered where the stereo calibration found them reversed.
fn renumbered(right: &[Option<View>], reversed: &[(usize, String)], n_points: usize) -> Vec<Option<View>> {
    right
        .iter()
        .map(|v| {
            v.as_ref().map(|v| {
                let mut v = v.clone();
                if reversed.iter().any(|(k, name)| *k == 1 && *name == v.name) {
                    v.point_ids = v.point_ids.iter().map(|p| n_points - 1 - p).collect();
                }
                v
            })
        })
        .collect()
}

/// The residual structure left on the held-out pairs, per camera.
fn unexplained(rig: &Rig, cv: &CrossValidation, opts: &CameraDiagnoseOptions) -> CameraUnexplained {
    let mut out = CameraUnexplained::default();
    for (c, name) in CAMERA_NAMES.iter().enumerate() {
        let views: Vec<View> = rig.pairs.iter().map(|&i| rig.views[c][i].clone().expect("a pair")).collect();
        let residuals: Vec<Option<DVector<f64>>> = cv.residuals.iter().map(|r| r[c].clone()).collect();
        let u = unexplained_structure(&views, &residuals, opts);
        out.structure_found |= u.structure_found;
        out.depends_on.extend(u.depends_on.iter().map(|d| format!("{name}: {d}")));
        out.evidence.extend(u.evidence.iter().map(|e| format!("{name}: {e}")));
    }
    out
}

/// Runs the analysis on the views of a stereo pair: `left[i]` and `right[i]` see the same target
/// pose (`None` where the target was not found in that image), paired as
/// [`calibrate_stereo`] pairs them. Declines (says why, claims nothing) with fewer than 6 pairs
/// in which both images show the target.
pub fn diagnose_stereo(
    left: &[Option<View>],
    right: &[Option<View>],
    target: &PlanarTarget,
    opts: &CameraDiagnoseOptions,
) -> Result<StereoDiagnoseReport> {
    if left.len() != right.len() {
        return Err(CalibError::Data(format!(
            "{} left and {} right images: the pairs are formed by order, give as many of each",
            left.len(),
            right.len()
        )));
    }
    let seen: Vec<usize> = (0..left.len()).filter(|&i| left[i].is_some() || right[i].is_some()).collect();
    let pairs: Vec<usize> = (0..left.len()).filter(|&i| left[i].is_some() && right[i].is_some()).collect();
    let n_single_views =
        [seen.iter().filter(|&&i| right[i].is_none()).count(), seen.iter().filter(|&&i| left[i].is_none()).count()];
    let mut report = StereoDiagnoseReport {
        nominal: CameraFit::default(),
        findings: Vec::new(),
        final_fit: CameraFinalFit::default(),
        unexplained: CameraUnexplained::default(),
        declined: None,
        candidates: Vec::new(),
        settings: opts.clone(),
        n_pairs: pairs.len(),
        n_single_views,
        n_reversed_views: 0,
        baseline_mm: f64::NAN,
    };
    if pairs.len() < 6 {
        report.declined = Some(format!(
            "{} pairs in which both images show the target: at least 6 are needed to hold pairs out and still calibrate; nothing is claimed",
            pairs.len()
        ));
        return Ok(report);
    }
    let cal = calibrate_stereo(left, right, target, &CalibrationOptions::default())
        .map_err(vision_error("stereo calibration"))?
        .calibration;
    report.n_reversed_views = cal.reversed_views.len();
    // The target centred on its centroid (so the bending and scale terms do not trade with the
    // pose); the reversal of a chessboard's numbering is a point reflection about the centroid,
    // so it is the same on the centred target.
    let target = &centred(target);
    let right = renumbered(right, &cal.reversed_views, target.points_m.len());
    let keep = |side: &[Option<View>]| seen.iter().map(|&i| side[i].clone()).collect::<Vec<_>>();
    let rig = Rig {
        views: vec![keep(left), keep(&right)],
        pairs: (0..seen.len()).filter(|&j| pairs.contains(&seen[j])).collect(),
    };
    let nominal_start = RigBundleModel {
        cameras: cal.cameras.iter().map(|c| c.camera).collect(),
        t_cam_cam0: cal.t_cam_cam0.clone(),
        shape: Default::default(),
        print_scale: Default::default(),
    };
    let all: Vec<usize> = (0..seen.len()).collect();
    let nominal_fit = fit_variant(&rig, &all, target, NOMINAL, (&nominal_start, None), false)?;
    let current_cv = cross_validate(&rig, target, NOMINAL, opts.folds, &nominal_fit.model, None)?;
    let n = rig.pairs.len();
    report.nominal = CameraFit {
        n_train: n - n.div_ceil(opts.folds.clamp(2, n)),
        n_heldout: n,
        train_rms_px: nominal_fit.rms_px,
        heldout_rms_px: Baseline::of_pooled(&current_cv.errors).heldout,
    };
    let mut family = StereoFamily {
        rig: &rig,
        target,
        opts,
        nominal_start: nominal_fit.model.clone(),
        current: NOMINAL,
        current_cv,
        current_fit: nominal_fit,
        all,
        accepted: Vec::new(),
    };
    let policy = Policy::held_out_images(opts.alpha, opts.min_improvement);
    let diagnosis = select(&mut family, &policy)?;
    report.findings = diagnosis
        .findings
        .iter()
        .zip(&family.accepted)
        .map(|(f, (camera, stds))| StereoFinding {
            effect: f.effect.clone(),
            joints: f.joints.clone(),
            camera: *camera,
            parameters: f.parameters.clone(),
            parameters_std: stds.clone(),
            heldout_rms_before_px: f.heldout_before,
            heldout_rms_after_px: f.heldout_after,
            explained_fraction: f.explained_fraction,
            p_value: f.decision.p_corrected,
            statement: f.statement.clone(),
        })
        .collect();
    report.final_fit = CameraFinalFit {
        train_rms_px: family.current_fit.rms_px,
        heldout_rms_px: Baseline::of_pooled(&family.current_cv.errors).heldout,
    };
    report.unexplained = unexplained(&rig, &family.current_cv, opts);
    report.baseline_mm = family.current_fit.model.t_cam_cam0[1].inverse().translation.vector.norm() * 1e3;
    report.candidates =
        candidate_scores(&diagnosis.steps, opts.alpha, opts.min_improvement, "rejected: implausible size");
    Ok(report)
}
