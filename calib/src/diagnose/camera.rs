//! Missing physics in a camera calibration: calibrate with the default lens model (5-coefficient
//! Brown) and a rigid, flat target, then test what the images show that this model leaves out.
//!
//! Candidates (JSON `effect` names of `shared/spec/diagnose.md`):
//! - `lens_distortion`: the rational radial model (`k4, k5, k6`, OpenCV's 8 coefficients) in
//!   place of the 5-coefficient one;
//! - `target_nonflatness`: the target is bent: its points move out of plane by
//!   `z = b (u^2 + v^2) + s (u^2 - v^2) + t u v`, with `(u, v)` the in-plane position divided by
//!   the target's half-size, so `b`, `s`, `t` are the sags (metres) at the target's edge of a bowl,
//!   a saddle and a twist, the same for every view (one physical target);
//! - `target_print_scale`: the printed spacing along the target's x axis differs from the one
//!   along its y axis by the factor `1 + e` (`scale_x_minus_y` = `e`; printers scale x and y
//!   differently). Only this anisotropic part shows in images: an overall scale trades with the
//!   views' distances, so the y spacing is taken as nominal. It also trades with the camera's
//!   `fy / fx` unless the board is turned in its plane between views (e.g. by 90 deg).
//!
//! Every fit is vision's bundle adjustment ([`ferrocal_vision::calib::adjust_bundle`]: Ceres,
//! analytic Jacobians, the target's shape and print scale as blocks shared by all views) on the
//! target centred on its centroid. A family of the diagnose engine ([`super::engine`]). Held-out
//! figures come from whole views held out (K-fold over views): the model is fitted on the other
//! views, then only the held-out view's pose is fitted to its corners (intrinsics, distortion,
//! target shape and print scale held: [`ferrocal_vision::calib::BundleMode::PosesOnly`]) and its
//! reprojection RMS is the score. The engine examines the candidate with the smallest corrected
//! p-value (the smaller of a sign test and a t test over the held-out views, Bonferroni over both
//! tests and the candidates) and accepts it when significant, at least `min_improvement` of the
//! held-out RMS, and physically plausible; then the search repeats from the enlarged model.

use ferrocal_vision::calib::{
    adjust_bundle, calibrate_camera, BundleMode, BundleModel, BundleSpec, CalibrationOptions, PlanarTarget, PrintScale,
    TargetShape, View,
};
use nalgebra::{DVector, Isometry3, Point3, Vector3};
use serde::{Deserialize, Serialize};

use super::engine::{select, AllFit, Baseline, Describe, Family, Policy, Screened, StepStart};
use super::report::{best_verdict, Decision, Finding, StepRows, Unit};
use super::stats::{bonferroni, paired_test};
use crate::error::{CalibError, Result};

mod types;
pub(super) mod variant;
pub use types::*;
pub(super) use variant::{effect_parameters, plausible_size, screened, Added};

/// A model variant of the one camera.
type Variant = variant::Variant<1>;

/// The default model: 5-coefficient Brown, a flat and nominally printed target.
const NOMINAL: Variant = Variant::NOMINAL;

/// A fitted variant.
#[derive(Clone, Debug)]
struct Fit {
    model: BundleModel,
    poses: Vec<Isometry3<f64>>,
    rms_px: f64,
    /// Standard deviations of the free parameters by name, when the fit computed them.
    std: std::collections::BTreeMap<String, f64>,
}

/// Target centred on its centroid (so the bending and scale terms do not trade with the pose).
pub(super) fn centred(target: &PlanarTarget) -> PlanarTarget {
    let n = target.points_m.len() as f64;
    let c = target.points_m.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / n;
    PlanarTarget {
        points_m: target.points_m.iter().map(|p| Point3::from(p.coords - c)).collect(),
        reversible: target.reversible,
    }
}

pub(super) fn vision_error(what: &str) -> impl Fn(ferrocal_vision::VisionError) -> CalibError + '_ {
    move |e| CalibError::Data(format!("{what}: {e}"))
}

/// Fits a variant on `views` of the centred target with vision's bundle adjustment, starting
/// from `start` or, without one, from a default-model calibration. With `covariance` the fit
/// carries the standard deviations of its parameters.
fn fit_variant(
    views: &[View],
    target: &PlanarTarget,
    variant: Variant,
    start: Option<&Fit>,
    covariance: bool,
) -> Result<Fit> {
    let (mut model, poses) = match start {
        Some(f) => (f.model, f.poses.clone()),
        None => {
            let cal = calibrate_camera(views, target, &CalibrationOptions::default())
                .map_err(vision_error("camera calibration"))?;
            (BundleModel::new(cal.camera), cal.views.iter().map(|v| v.t_cam_target).collect())
        }
    };
    // A variant without a block starts (and stays) without it.
    if !variant.bent {
        model.shape = TargetShape::default();
    }
    if !variant.scaled {
        model.print_scale = PrintScale::default();
    }
    let spec = BundleSpec {
        lens: Some(variant.lens[0]),
        estimate_shape: variant.bent,
        estimate_print_scale: variant.scaled,
        mode: BundleMode::Full,
        max_iterations: 100,
        covariance,
        ..BundleSpec::default()
    };
    let fit = adjust_bundle(views, target, &model, Some(&poses), &spec).map_err(vision_error("bundle adjustment"))?;
    Ok(Fit {
        model: fit.model,
        poses: fit.views.iter().map(|v| v.t_cam_target).collect(),
        rms_px: fit.rms_px,
        std: fit.parameter_names.iter().cloned().zip(fit.std.iter().copied()).collect(),
    })
}

/// Reprojection residuals (projected - observed, x and y per corner) of a held-out view with its
/// pose alone fitted (camera, shape and print scale held); `None` when the model cannot place
/// the view (no closed-form start, or the refit fails).
fn heldout_residuals(view: &View, target: &PlanarTarget, fit: &Fit) -> Option<DVector<f64>> {
    let spec = BundleSpec { mode: BundleMode::PosesOnly, max_iterations: 100, ..BundleSpec::default() };
    let placed = adjust_bundle(std::slice::from_ref(view), target, &fit.model, None, &spec).ok()?;
    Some(DVector::from_iterator(
        2 * view.corners_px.len(),
        placed.views[0].residuals_px.iter().flat_map(|r| [r.x, r.y]),
    ))
}

/// One cross-validation of a variant over views (each view held out once).
struct CrossValidation {
    /// Per view: sum of squared held-out reprojection errors (infinite when the fitted model
    /// cannot place the view) and its number of corners.
    errors: ViewErrors,
    /// Per view: the held-out residuals (projected - observed, x and y per corner), when placed.
    residuals: Vec<Option<DVector<f64>>>,
}

/// Cross-validates `variant`: per fold the default model and then the variant are fitted on the
/// other views, and each held-out view's pose alone is fitted to its corners.
fn cross_validate(views: &[View], target: &PlanarTarget, variant: Variant, folds: usize) -> Result<CrossValidation> {
    let n = views.len();
    let k = folds.clamp(2, n);
    let mut errors = vec![(0.0, 0); n];
    let mut residuals = vec![None; n];
    for f in 0..k {
        let train: Vec<View> = views.iter().enumerate().filter(|(i, _)| i % k != f).map(|(_, v)| v.clone()).collect();
        let base = fit_variant(&train, target, NOMINAL, None, false)?;
        let fit = if variant == NOMINAL { base } else { fit_variant(&train, target, variant, Some(&base), false)? };
        for (i, v) in views.iter().enumerate().filter(|(i, _)| i % k == f) {
            let r = heldout_residuals(v, target, &fit);
            errors[i] = (r.as_ref().map_or(f64::INFINITY, |r| r.norm_squared()), v.corners_px.len());
            residuals[i] = r;
        }
    }
    Ok(CrossValidation { errors, residuals })
}

/// Residual structure of the final model on held-out views: does the mean residual depend on
/// where a corner lies in the image (a 4 x 4 grid of cells) or on its distance from the image
/// centre (five rings, radial component)? Per cell that at least three views reach, the corners'
/// residuals are tested against zero with a t test, Bonferroni-corrected over all cells; a
/// dependence counts when significant at `alpha` and larger than a third of the held-out RMS
/// (per corner, both axes).
pub(super) fn unexplained_structure(
    views: &[View],
    residuals: &[Option<DVector<f64>>],
    opts: &CameraDiagnoseOptions,
) -> CameraUnexplained {
    let n = views.len();
    // Per view: (corner position, residual).
    let per_view: Vec<Vec<(nalgebra::Point2<f64>, nalgebra::Vector2<f64>)>> = views
        .iter()
        .zip(residuals)
        .map(|(v, r)| match r {
            Some(r) => v
                .corners_px
                .iter()
                .enumerate()
                .map(|(c, p)| (*p, nalgebra::Vector2::new(r[2 * c], r[2 * c + 1])))
                .collect(),
            None => Vec::new(),
        })
        .collect();
    let all: Vec<f64> = per_view.iter().flatten().map(|(_, r)| r.norm_squared()).collect();
    if all.is_empty() {
        return CameraUnexplained::default();
    }
    let rms_px = (all.iter().sum::<f64>() / all.len() as f64).sqrt();
    let size = views[0].image_size;
    let (w, h) = (size.width_px as f64, size.height_px as f64);
    let centre = nalgebra::Point2::new(w / 2.0, h / 2.0);
    let r_max = (centre.x * centre.x + centre.y * centre.y).sqrt();
    const GRID: usize = 4;
    const RINGS: usize = 5;
    let grid = |p: &nalgebra::Point2<f64>| {
        let gx = ((p.x / w * GRID as f64) as usize).min(GRID - 1);
        let gy = ((p.y / h * GRID as f64) as usize).min(GRID - 1);
        gy * GRID + gx
    };
    let mut depends_on = Vec::new();
    let mut evidence = Vec::new();
    // Grid: x and y components per cell.
    let mut grid_units: Vec<Vec<Vec<f64>>> = vec![vec![Vec::new(); n]; 2 * GRID * GRID];
    let mut ring_units: Vec<Vec<Vec<f64>>> = vec![vec![Vec::new(); n]; RINGS];
    for (vi, corners) in per_view.iter().enumerate() {
        for (p, r) in corners {
            let g = grid(p);
            grid_units[2 * g][vi].push(r.x);
            grid_units[2 * g + 1][vi].push(r.y);
            let d = p - centre;
            let rad = d.norm();
            let ring = ((rad / r_max * RINGS as f64) as usize).min(RINGS - 1);
            if rad > 1e-9 {
                ring_units[ring][vi].push(r.dot(&(d / rad)));
            }
        }
    }
    for (label, units) in [("image position", &grid_units), ("image radius", &ring_units)] {
        // Corners are the units of the test (the held-out view's own pose is refitted, which
        // removes what a view's corners share); a cell counts only when at least three views
        // put corners in it, so one odd view cannot make a finding.
        let results: Vec<(usize, Vec<f64>)> = units
            .iter()
            .enumerate()
            .filter(|(_, group)| group.iter().filter(|v| !v.is_empty()).count() >= 3)
            .map(|(k, group)| (k, group.iter().flatten().copied().collect()))
            .collect();
        let m = results.len();
        let mut found = false;
        for (k, values) in &results {
            let mean = values.iter().sum::<f64>() / values.len() as f64;
            // Two-sided: the one-sided test of the mean's own sign, doubled.
            let signed: Vec<f64> = values.iter().map(|v| v * mean.signum()).collect();
            let p_two = (2.0 * paired_test(&signed).p_value).min(1.0);
            let p = bonferroni(p_two, m);
            if p < opts.alpha && mean.abs() > rms_px / 3.0 {
                found = true;
                let place = if label == "image position" {
                    let (cell, axis) = (k / 2, if k % 2 == 0 { "x" } else { "y" });
                    let (gx, gy) = ((cell % GRID) as f64, (cell / GRID) as f64);
                    let (cw, ch) = (w / GRID as f64, h / GRID as f64);
                    format!(
                        "image cell x {:.0}..{:.0} px, y {:.0}..{:.0} px: mean {axis} residual",
                        gx * cw,
                        (gx + 1.0) * cw,
                        gy * ch,
                        (gy + 1.0) * ch
                    )
                } else {
                    let rw = r_max / RINGS as f64;
                    format!(
                        "radius {:.0}..{:.0} px from the image centre: mean radial residual",
                        *k as f64 * rw,
                        (*k as f64 + 1.0) * rw
                    )
                };
                evidence.push(format!(
                    "{place} {mean:+.3} px over {} corners (p = {p:.1e}; held-out RMS {rms_px:.3} px)",
                    values.len()
                ));
            }
        }
        if found {
            depends_on.push(label.to_string());
        }
    }
    CameraUnexplained { structure_found: !depends_on.is_empty(), depends_on, evidence }
}

/// Per view: the sum of squared held-out reprojection errors and the number of corners.
type ViewErrors = Vec<(f64, usize)>;

fn rms(sq: &[(f64, usize)]) -> f64 {
    Baseline::of_pooled(sq).heldout
}

/// A candidate: its label and the model variant it leads to.
type CameraCandidate = (String, Variant);

/// The camera's model variants as a candidate family of the diagnose engine.
struct CameraFamily<'a> {
    views: &'a [View],
    /// The centred target.
    target: &'a PlanarTarget,
    opts: &'a CameraDiagnoseOptions,
    current: Variant,
    current_cv: CrossValidation,
    current_fit: Fit,
}

impl Family for CameraFamily<'_> {
    type Candidate = CameraCandidate;
    type Effect = Variant;
    type Screen = CrossValidation;
    type Fit = Fit;

    fn unit(&self) -> Unit {
        Unit::Pixel
    }

    fn begin_step(&mut self, _accepted: &[Variant]) -> Result<StepStart> {
        Ok(StepStart::Baseline(Baseline::of_pooled(&self.current_cv.errors)))
    }

    fn candidates(&self, _accepted: &[Variant], _retired: &[Variant]) -> Vec<CameraCandidate> {
        self.current.candidates(|_, what| format!("lens_distortion ({what})"), "")
    }

    fn describe(&self, (label, variant): &CameraCandidate) -> Describe {
        variant.describe(self.current, label)
    }

    fn screen(&mut self, (_, variant): &CameraCandidate) -> Result<Screened<CrossValidation>> {
        // Per-view differences of mean squared error (before - after). Views differ widely in
        // how much a lens or target effect shows (the image border against the centre), so the
        // heavy-tailed per-view differences are tested with the sign test and with the t test
        // (the engine's `Test::SignOrT`).
        let cv = cross_validate(self.views, self.target, *variant, self.opts.folds);
        Ok(screened(cv, |cv| &cv.errors, &self.current_cv.errors, "views"))
    }

    fn fit_all(
        &mut self,
        (_, variant): &CameraCandidate,
        _cv: &CrossValidation,
    ) -> Result<Option<AllFit<Variant, Fit>>> {
        let fit = fit_variant(self.views, self.target, *variant, Some(&self.current_fit), true)?;
        let m = &fit.model;
        let (parameters, _) = effect_parameters(
            variant.added_to(self.current),
            (m.shape, m.print_scale.x),
            |_| m.camera.distortion,
            &Default::default(),
            |_| String::new(),
        );
        Ok(Some(AllFit { effect: *variant, parameters, overlap_sine: None, data: fit }))
    }

    fn plausible(&self, fit: &AllFit<Variant, Fit>) -> std::result::Result<(), String> {
        let m = &fit.data.model;
        plausible_size(
            fit.effect.added_to(self.current),
            (m.shape, m.print_scale.x),
            |_| m.camera.distortion,
            self.opts,
        )
    }

    fn accept(
        &mut self,
        fit: AllFit<Variant, Fit>,
        cv: &CrossValidation,
        decision: &Decision,
    ) -> Result<Finding<Variant>> {
        let (variant, parameters, fit) = (fit.effect, fit.parameters, fit.data);
        let (before, after, p, m) =
            (decision.heldout_before, decision.heldout_after, decision.p_corrected, decision.candidates_tried);
        let kind = variant.added_to(self.current);
        let mut main_std = None;
        let (effect, statement) = match kind {
            Added::Shape => {
                let s = fit.model.shape;
                ("target_nonflatness", format!(
                    "the target is not flat: its edge stands {:.2} mm out of plane as a bowl, {:.2} mm as a saddle and {:.2} mm as a twist; modelling it lowers the held-out reprojection RMS from {:.3} to {:.3} px (p = {:.1e} after correcting for {m} candidates)",
                    s.bowl_m * 1e3, s.saddle_m * 1e3, s.twist_m * 1e3, before, after, p
                ))
            }
            Added::PrintScale => {
                let e = fit.model.print_scale.x;
                let std = fit.std.get("print_scale_x").copied().unwrap_or(f64::NAN);
                main_std = Some(std);
                ("target_print_scale", print_scale_statement(e, std, board_width_m(self.target), (before, after, p, m)))
            }
            Added::Lens(_) => {
                let c = fit.model.camera.distortion.coefficients();
                let model = match variant.lens[0] {
                    ferrocal_vision::camera::DistortionKind::KannalaBrandt => {
                        "the Kannala-Brandt (fisheye) model".to_string()
                    }
                    _ => format!("the rational radial terms (k4 = {:.3}, k5 = {:.3}, k6 = {:.3})", c[5], c[6], c[7]),
                };
                ("lens_distortion", format!(
                    "the 5-coefficient lens model leaves systematic image residuals: {model}: the held-out reprojection RMS drops from {before:.3} to {after:.3} px (p = {p:.1e} after correcting for {m} candidates)"
                ))
            }
        };
        self.current = variant;
        self.current_cv = CrossValidation { errors: cv.errors.clone(), residuals: cv.residuals.clone() };
        self.current_fit = fit;
        let mut finding =
            Finding::without_evidence(variant, effect, parameters, (before, after), statement, decision.clone());
        finding.std_from_covariance = main_std;
        Ok(finding)
    }
}

/// Extent of the target's points along its x axis, metres.
pub(super) fn board_width_m(target: &PlanarTarget) -> f64 {
    let (lo, hi) =
        target.points_m.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.x), b.max(p.x)));
    hi - lo
}

/// The print-scale finding in words: which axis, how large (ppm, and millimetres over the
/// board's width), how sure.
pub(super) fn print_scale_statement(
    e: f64,
    std: f64,
    width_m: f64,
    (before, after, p, m): (f64, f64, f64, usize),
) -> String {
    let (ppm, std_ppm) = (e * 1e6, std * 1e6);
    let sense = if e >= 0.0 { "longer" } else { "shorter" };
    format!(
        "the printed pattern is not to scale: its spacing along the target's x axis is {:.0} ppm ({:.3} %) {sense} than along its y axis (+- {:.0} ppm, 1 sigma), {:.2} mm over the board's {:.0} mm; modelling it lowers the held-out reprojection RMS from {before:.3} to {after:.3} px (p = {p:.1e} after correcting for {m} candidates); the overall scale is not visible in images alone",
        ppm.abs(),
        (e * 100.0).abs(),
        std_ppm,
        (e * width_m * 1e3).abs(),
        width_m * 1e3
    )
}

/// Runs the analysis on detected views of a planar target.
pub fn diagnose_camera(
    views: &[View],
    target: &PlanarTarget,
    opts: &CameraDiagnoseOptions,
) -> Result<CameraDiagnoseReport> {
    let n = views.len();
    if n < 6 {
        return Ok(CameraDiagnoseReport {
            nominal: CameraFit::default(),
            findings: Vec::new(),
            final_fit: CameraFinalFit::default(),
            unexplained: CameraUnexplained::default(),
            declined: Some(format!(
                "{n} usable views: at least 6 are needed to hold views out and still calibrate; nothing is claimed"
            )),
            candidates: Vec::new(),
            settings: opts.clone(),
            n_views: n,
        });
    }
    let target = &centred(target);
    let current = NOMINAL;
    let nominal_fit = fit_variant(views, target, current, None, false)?;
    let current_cv = cross_validate(views, target, current, opts.folds)?;
    let nominal = CameraFit {
        n_train: n - n.div_ceil(opts.folds.clamp(2, n)),
        n_heldout: n,
        train_rms_px: nominal_fit.rms_px,
        heldout_rms_px: rms(&current_cv.errors),
    };
    let mut family = CameraFamily { views, target, opts, current, current_cv, current_fit: nominal_fit };
    let policy = Policy::held_out_images(opts.alpha, opts.min_improvement);
    let diagnosis = select(&mut family, &policy)?;
    Ok(CameraDiagnoseReport {
        nominal,
        findings: diagnosis
            .findings
            .iter()
            .map(|f| CameraFinding {
                effect: f.effect.clone(),
                joints: f.joints.clone(),
                parameters: f.parameters.clone(),
                heldout_rms_before_px: f.heldout_before,
                heldout_rms_after_px: f.heldout_after,
                explained_fraction: f.explained_fraction,
                p_value: f.decision.p_corrected,
                statement: f.statement.clone(),
            })
            .collect(),
        final_fit: CameraFinalFit {
            train_rms_px: family.current_fit.rms_px,
            heldout_rms_px: rms(&family.current_cv.errors),
        },
        unexplained: unexplained_structure(views, &family.current_cv.residuals, opts),
        declined: None,
        candidates: candidate_scores(&diagnosis.steps, opts.alpha, opts.min_improvement, "rejected: implausible size"),
        settings: opts.clone(),
        n_views: n,
    })
}

/// Every candidate of every step of a selection as the image families report it; `vetoed` is
/// the words of a candidate its family vetoed (see [`best_verdict`]).
pub fn candidate_scores(
    steps: &[StepRows],
    alpha: f64,
    min_improvement: f64,
    vetoed: &str,
) -> Vec<Vec<CameraCandidateScore>> {
    steps
        .iter()
        .map(|s| {
            s.rows
                .iter()
                .map(|r| CameraCandidateScore {
                    candidate: r.label.clone(),
                    heldout_rms_px: r.heldout_after,
                    p_value: r.p_corrected,
                    verdict: best_verdict(r, alpha, min_improvement, vetoed),
                    status: r.verdict.status().to_string(),
                })
                .collect()
        })
        .collect()
}
