//! Missing physics in a camera calibration: calibrate with the default lens model (5-coefficient
//! Brown) and a rigid, flat target, then test what the images show that this model leaves out.
//!
//! Candidates (JSON `effect` names of `shared/spec/diagnose.md`):
//! - `lens_distortion`: the rational radial model (`k4, k5, k6`, OpenCV's 8 coefficients) in
//!   place of the 5-coefficient one;
//! - `target_nonflatness`: the target is bent: its points move out of plane by
//!   `z = b (u^2 + v^2) + s (u^2 - v^2) + t u v`, with `(u, v)` the in-plane position divided by
//!   the target's half-size, so `b`, `s`, `t` are the sags (metres) at the target's edge of a bowl,
//!   a saddle and a twist, the same for every view (one physical target).
//!
//! A family of the diagnose engine ([`super::engine`]). Held-out figures come from whole views
//! held out (K-fold over views): the model is fitted on the other views, then only the held-out
//! view's pose is fitted to its corners (intrinsics, distortion and target shape fixed) and its
//! reprojection RMS is the score. The engine examines the candidate with the smallest corrected
//! p-value (the smaller of a sign test and a t test over the held-out views, Bonferroni over both
//! tests and the candidates) and accepts it when significant, at least `min_improvement` of the
//! held-out RMS, and physically plausible; then the search repeats from the enlarged model.

use ferrocal_vision::calib::{calibrate_camera, CalibrationOptions, PlanarTarget, View};
use ferrocal_vision::camera::{CameraModel, Distortion, DistortionKind};
use nalgebra::{DVector, Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use super::engine::{
    select, AllFit, Baseline, Correction, Describe, Family, Improvement, Policy, Screened, Selection, StepStart, Test,
};
use super::report::{best_verdict, Decision, Finding, Unit};
use super::stats::{bonferroni, paired_test};
use crate::error::{CalibError, Result};
use crate::lsq::{solve, LmOptions, Problem};

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
}

impl Default for CameraDiagnoseOptions {
    fn default() -> Self {
        Self { folds: 5, alpha: 0.01, min_improvement: 0.02, max_sag_m: 0.01, max_rational: 50.0 }
    }
}

/// One accepted effect.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CameraFinding {
    /// `lens_distortion` or `target_nonflatness`.
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
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CameraCandidateScore {
    /// Effect name and variant.
    pub candidate: String,
    /// Held-out RMS with it, pixels.
    pub heldout_rms_px: f64,
    /// Corrected p-value.
    pub p_value: f64,
    /// Accepted or why not.
    pub verdict: String,
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

/// A model variant: lens model and whether the target may bend.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Variant {
    lens: Lens,
    bent: bool,
}

/// Lens model of a variant.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Lens {
    Brown5,
    Rational8,
    KannalaBrandt,
}

/// A fitted variant.
#[derive(Clone, Debug)]
struct Fit {
    camera: CameraModel,
    bend: [f64; 3],
    poses: Vec<Isometry3<f64>>,
    rms_px: f64,
}

fn bent_points(points: &[Point3<f64>], bend: &[f64; 3], half: f64) -> Vec<Point3<f64>> {
    points
        .iter()
        .map(|p| {
            let (u, v) = (p.x / half, p.y / half);
            Point3::new(p.x, p.y, p.z + bend[0] * (u * u + v * v) + bend[1] * (u * u - v * v) + bend[2] * u * v)
        })
        .collect()
}

/// Target centred on its centroid (so the bending terms do not trade with the pose).
fn centred(target: &PlanarTarget) -> (Vec<Point3<f64>>, f64) {
    let n = target.points_m.len() as f64;
    let c = target.points_m.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / n;
    let pts: Vec<Point3<f64>> = target.points_m.iter().map(|p| Point3::from(p.coords - c)).collect();
    let half = pts.iter().map(|p| p.x.abs().max(p.y.abs())).fold(1e-9, f64::max);
    (pts, half)
}

struct BundleProblem<'a> {
    views: &'a [&'a View],
    points: &'a [Point3<f64>],
    half: f64,
    base_camera: CameraModel,
    n_cam: usize,
    bent: bool,
    poses0: Vec<Isometry3<f64>>,
    /// Fixed camera and bend (pose-only problem) when set.
    fixed: Option<(CameraModel, [f64; 3])>,
}

impl BundleProblem<'_> {
    fn n_shape(&self) -> usize {
        if self.fixed.is_some() {
            0
        } else {
            self.n_cam + if self.bent { 3 } else { 0 }
        }
    }

    fn unpack(&self, x: &[f64]) -> Result<(CameraModel, [f64; 3], Vec<Isometry3<f64>>)> {
        let (camera, bend) = match &self.fixed {
            Some((c, b)) => (*c, *b),
            None => {
                let mut c = self.base_camera;
                c.set_parameter_values(&x[..self.n_cam]).map_err(|e| CalibError::Numeric(e.to_string()))?;
                let b = if self.bent { [x[self.n_cam], x[self.n_cam + 1], x[self.n_cam + 2]] } else { [0.0; 3] };
                (c, b)
            }
        };
        let s = self.n_shape();
        let poses = self
            .poses0
            .iter()
            .enumerate()
            .map(|(k, p0)| {
                let d = &x[s + 6 * k..s + 6 * k + 6];
                Isometry3::from_parts(
                    Translation3::new(d[3], d[4], d[5]),
                    UnitQuaternion::from_scaled_axis(Vector3::new(d[0], d[1], d[2])),
                ) * p0
            })
            .collect();
        Ok((camera, bend, poses))
    }
}

impl Problem for BundleProblem<'_> {
    fn n_params(&self) -> usize {
        self.n_shape() + 6 * self.views.len()
    }
    fn n_residuals(&self) -> usize {
        self.views.iter().map(|v| 2 * v.corners_px.len()).sum()
    }
    fn block_size(&self) -> usize {
        2
    }
    fn residuals(&self, x: &[f64]) -> Result<DVector<f64>> {
        let (camera, bend, poses) = self.unpack(x)?;
        let pts = bent_points(self.points, &bend, self.half);
        let mut r = DVector::zeros(self.n_residuals());
        let mut k = 0;
        for (v, pose) in self.views.iter().zip(&poses) {
            for (id, obs) in v.point_ids.iter().zip(&v.corners_px) {
                let p = camera.project(&(pose * pts[*id])).map_err(|e| CalibError::Numeric(e.to_string()))?;
                r[k] = p.x - obs.x;
                r[k + 1] = p.y - obs.y;
                k += 2;
            }
        }
        Ok(r)
    }
    fn scales(&self) -> Vec<f64> {
        let mut s = Vec::with_capacity(self.n_params());
        if self.fixed.is_none() {
            for p in self.base_camera.parameters() {
                s.push(match p.name {
                    "fx_px" | "fy_px" | "cx_px" | "cy_px" => 1.0,
                    _ => 1e-3,
                });
            }
            if self.bent {
                s.extend([1e-4; 3]);
            }
        }
        for _ in self.views {
            s.extend([1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3]);
        }
        s
    }
}

fn lm() -> LmOptions {
    LmOptions { max_iterations: 100, ..LmOptions::default() }
}

/// Fits a variant on `views`, starting from a default-model calibration.
fn fit_variant(views: &[&View], target: &PlanarTarget, variant: Variant, start: Option<&Fit>) -> Result<Fit> {
    let (points, half) = centred(target);
    let (camera0, poses0) = match start {
        Some(f) => (f.camera, f.poses.clone()),
        None => {
            let owned: Vec<View> = views.iter().map(|v| (*v).clone()).collect();
            let centred_target = PlanarTarget { points_m: points.clone(), reversible: target.reversible };
            let cal = calibrate_camera(&owned, &centred_target, &CalibrationOptions::default())
                .map_err(|e| CalibError::Data(format!("camera calibration: {e}")))?;
            (cal.camera, cal.views.iter().map(|v| v.t_cam_target).collect())
        }
    };
    let mut camera = camera0;
    let to_numeric = |e: ferrocal_vision::VisionError| CalibError::Numeric(e.to_string());
    match (variant.lens, camera.distortion.kind()) {
        (Lens::Rational8, DistortionKind::Brown5) => {
            let c = camera.distortion.coefficients();
            camera.distortion = Distortion::from_coefficients(
                DistortionKind::Rational8,
                &[c[0], c[1], c[2], c[3], c[4], 0.0, 0.0, 0.0],
            )
            .map_err(to_numeric)?;
        }
        (Lens::KannalaBrandt, DistortionKind::Brown5) => {
            camera.distortion =
                Distortion::from_coefficients(DistortionKind::KannalaBrandt, &[0.0; 4]).map_err(to_numeric)?;
        }
        _ => {}
    }
    let n_cam = camera.n_parameters();
    let problem = BundleProblem {
        views,
        points: &points,
        half,
        base_camera: camera,
        n_cam,
        bent: variant.bent,
        poses0,
        fixed: None,
    };
    let mut x0 = camera.parameter_values();
    if variant.bent {
        x0.extend(start.map_or([0.0; 3], |f| f.bend));
    }
    x0.extend(std::iter::repeat_n(0.0, 6 * views.len()));
    let res = solve(&problem, &x0, &lm())?;
    let (camera, bend, poses) = problem.unpack(&res.x)?;
    let rms_px = (res.residuals.norm_squared() / (res.residuals.len() / 2).max(1) as f64).sqrt();
    Ok(Fit { camera, bend, poses, rms_px })
}

/// Reprojection residuals (projected - observed, x and y per corner) of a held-out view with its
/// pose alone fitted; `None` when the model cannot place the view.
fn heldout_residuals(view: &View, target: &PlanarTarget, fit: &Fit) -> Result<Option<DVector<f64>>> {
    let (points, half) = centred(target);
    let flat = PlanarTarget { points_m: points.clone(), reversible: false };
    let pts_flat: Vec<Point3<f64>> = flat.points_m.clone();
    // A model that cannot even place the held-out view predicts it infinitely badly.
    let Ok(est) = ferrocal_vision::pose::estimate_pose(
        &fit.camera,
        &pts_flat,
        &view.point_ids,
        &view.corners_px,
        &ferrocal_vision::pose::CornerNoise::Isotropic { sigma_px: 0.1 },
    ) else {
        return Ok(None);
    };
    let views = [view];
    let problem = BundleProblem {
        views: &views,
        points: &points,
        half,
        base_camera: fit.camera,
        n_cam: 0,
        bent: false,
        poses0: vec![est.t_cam_target],
        fixed: Some((fit.camera, fit.bend)),
    };
    Ok(solve(&problem, &[0.0; 6], &lm()).ok().map(|res| res.residuals))
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
        let train: Vec<&View> = views.iter().enumerate().filter(|(i, _)| i % k != f).map(|(_, v)| v).collect();
        let base = fit_variant(&train, target, Variant { lens: Lens::Brown5, bent: false }, None)?;
        let fit = if variant == (Variant { lens: Lens::Brown5, bent: false }) {
            base
        } else {
            fit_variant(&train, target, variant, Some(&base))?
        };
        for (i, v) in views.iter().enumerate().filter(|(i, _)| i % k == f) {
            let r = heldout_residuals(v, target, &fit)?;
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
fn unexplained_structure(
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
    let (s, n) = sq.iter().fold((0.0, 0usize), |(a, b), (s, n)| (a + s, b + n));
    (s / n.max(1) as f64).sqrt()
}

/// A candidate: its label and the model variant it leads to.
type CameraCandidate = (&'static str, Variant);

/// The camera's model variants as a candidate family of the diagnose engine.
struct CameraFamily<'a> {
    views: &'a [View],
    all: Vec<&'a View>,
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
        let (s, n) = self.current_cv.errors.iter().fold((0.0, 0usize), |(a, b), (s, n)| (a + s, b + n));
        Ok(StepStart::Baseline(Baseline { heldout: rms(&self.current_cv.errors), mse: s / n.max(1) as f64 }))
    }

    fn candidates(&self, _accepted: &[Variant], _retired: &[Variant]) -> Vec<CameraCandidate> {
        let current = self.current;
        let mut cands = Vec::new();
        if current.lens == Lens::Brown5 {
            cands.push(("lens_distortion (rational radial k4..k6)", Variant { lens: Lens::Rational8, ..current }));
            cands.push(("lens_distortion (Kannala-Brandt fisheye)", Variant { lens: Lens::KannalaBrandt, ..current }));
        }
        if !current.bent {
            cands.push(("target_nonflatness (bowl, saddle, twist)", Variant { bent: true, ..current }));
        }
        cands
    }

    fn describe(&self, (label, variant): &CameraCandidate) -> Describe {
        let bends = variant.bent && !self.current.bent;
        Describe {
            label: label.to_string(),
            effect: if bends { "target_nonflatness" } else { "lens_distortion" }.into(),
            joints: Vec::new(),
            n_params: match (bends, variant.lens) {
                (false, Lens::KannalaBrandt) => 4,
                _ => 3,
            },
        }
    }

    fn screen(&mut self, (_, variant): &CameraCandidate) -> Result<Screened<CrossValidation>> {
        let cv = match cross_validate(self.views, self.target, *variant, self.opts.folds) {
            Ok(cv) => cv,
            Err(e) => return Ok(Screened::Unscored { heldout: f64::NAN, why: format!("could not be fitted: {e}") }),
        };
        // Per-view differences of mean squared error (before - after).
        let d: Vec<f64> = self
            .current_cv
            .errors
            .iter()
            .zip(&cv.errors)
            .map(|((a, na), (b, _))| (a - b) / (*na).max(1) as f64)
            .collect();
        if d.iter().any(|v| !v.is_finite()) {
            return Ok(Screened::Unscored {
                heldout: f64::INFINITY,
                why: "fails to predict some held-out views (their corners leave the fitted lens model's valid field)"
                    .into(),
            });
        }
        // Views differ widely in how much a lens or target effect shows (the image border against
        // the centre), so the heavy-tailed per-view differences are tested with the sign test and
        // with the t test (the engine's `Test::SignOrT`).
        Ok(Screened::Scored { d, heldout: rms(&cv.errors), data: cv })
    }

    fn fit_all(
        &mut self,
        (_, variant): &CameraCandidate,
        _cv: &CrossValidation,
    ) -> Result<Option<AllFit<Variant, Fit>>> {
        let fit = fit_variant(&self.all, self.target, *variant, Some(&self.current_fit))?;
        let mut parameters = std::collections::BTreeMap::new();
        if variant.bent && !self.current.bent {
            for (k, name) in ["bowl_sag_m", "saddle_sag_m", "twist_sag_m"].iter().enumerate() {
                parameters.insert(name.to_string(), fit.bend[k]);
            }
        } else {
            let c = fit.camera.distortion.coefficients();
            let names = fit.camera.distortion.kind().coefficient_names();
            for (name, v) in names.iter().zip(&c) {
                parameters.insert(name.to_string(), *v);
            }
        }
        Ok(Some(AllFit { effect: *variant, parameters, overlap_sine: None, data: fit }))
    }

    fn plausible(&self, fit: &AllFit<Variant, Fit>) -> std::result::Result<(), String> {
        let ok = if fit.effect.bent && !self.current.bent {
            fit.data.bend.iter().all(|b| b.abs() <= self.opts.max_sag_m)
        } else {
            fit.data.camera.distortion.coefficients().iter().all(|c| c.abs() <= self.opts.max_rational)
        };
        if ok {
            Ok(())
        } else {
            Err("implausible size".into())
        }
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
        let statement;
        let effect;
        if variant.bent && !self.current.bent {
            effect = "target_nonflatness";
            statement = format!(
                "the target is not flat: its edge stands {:.2} mm out of plane as a bowl, {:.2} mm as a saddle and {:.2} mm as a twist; modelling it lowers the held-out reprojection RMS from {:.3} to {:.3} px (p = {:.1e} after correcting for {m} candidates)",
                fit.bend[0] * 1e3, fit.bend[1] * 1e3, fit.bend[2] * 1e3, before, after, p
            );
        } else {
            effect = "lens_distortion";
            let c = fit.camera.distortion.coefficients();
            let model = match variant.lens {
                Lens::KannalaBrandt => "the Kannala-Brandt (fisheye) model".to_string(),
                _ => format!("the rational radial terms (k4 = {:.3}, k5 = {:.3}, k6 = {:.3})", c[5], c[6], c[7]),
            };
            statement = format!(
                "the 5-coefficient lens model leaves systematic image residuals: {model}: the held-out reprojection RMS drops from {before:.3} to {after:.3} px (p = {p:.1e} after correcting for {m} candidates)"
            );
        }
        self.current = variant;
        self.current_cv = CrossValidation { errors: cv.errors.clone(), residuals: cv.residuals.clone() };
        self.current_fit = fit;
        Ok(Finding::without_evidence(variant, effect, parameters, (before, after), statement, decision.clone()))
    }
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
    let all: Vec<&View> = views.iter().collect();
    let current = Variant { lens: Lens::Brown5, bent: false };
    let nominal_fit = fit_variant(&all, target, current, None)?;
    let current_cv = cross_validate(views, target, current, opts.folds)?;
    let nominal = CameraFit {
        n_train: n - n.div_ceil(opts.folds.clamp(2, n)),
        n_heldout: n,
        train_rms_px: nominal_fit.rms_px,
        heldout_rms_px: rms(&current_cv.errors),
    };
    let mut family = CameraFamily { views, all, target, opts, current, current_cv, current_fit: nominal_fit };
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
        candidates: diagnosis
            .steps
            .iter()
            .map(|s| {
                s.rows
                    .iter()
                    .map(|r| CameraCandidateScore {
                        candidate: r.label.clone(),
                        heldout_rms_px: r.heldout_after,
                        p_value: r.p_corrected,
                        verdict: best_verdict(r, opts.alpha, opts.min_improvement, "rejected: implausible size"),
                    })
                    .collect()
            })
            .collect(),
        settings: opts.clone(),
        n_views: n,
    })
}
