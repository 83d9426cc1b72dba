//! The line fits and intersections behind [`refine_grid`]: segments and lines of a
//! [`CheckerGrid`], the blurred-step fits, corner covariances and the noise estimate.

use nalgebra::{Matrix2, Point2, Vector2};
use rayon::prelude::*;

use super::line::{LineFit, LineState, Sample, Segment};
use super::{CheckerGrid, LineSupport, NoiseModel, NoiseSpec, RefineOptions, RefineSummary, RefinedCorner};
use crate::camera::CameraModel;
use crate::detect::{GrayF32, StageTimings};
use crate::error::{Result, VisionError};
use std::time::Instant;

mod light;
pub(super) use light::estimate_noise;
use light::IlluminationField;

mod points;
use points::{intersect, segment_job, Points};

mod snap;
use snap::snap_line;

mod band;
use band::row_span;

/// Maps between image pixels and the coordinates in which lines are straight.
enum Coords<'a> {
    Pixel,
    Undistorted(&'a CameraModel),
}

impl Coords<'_> {
    fn to_fit(&self, p: Vector2<f64>) -> Option<Vector2<f64>> {
        match self {
            Coords::Pixel => Some(p),
            Coords::Undistorted(cam) => {
                let n = cam.unproject_normalized(&Point2::new(p.x, p.y)).ok()?;
                let k = &cam.intrinsics;
                Some(Vector2::new(k.fx_px * n.x + k.cx_px, k.fy_px * n.y + k.cy_px))
            }
        }
    }

    fn to_pixel(&self, q: Vector2<f64>) -> Option<Vector2<f64>> {
        match self {
            Coords::Pixel => Some(q),
            Coords::Undistorted(cam) => {
                let k = &cam.intrinsics;
                let p =
                    cam.project_normalized(&Point2::new((q.x - k.cx_px) / k.fx_px, (q.y - k.cy_px) / k.fy_px)).ok()?;
                Some(Vector2::new(p.x, p.y))
            }
        }
    }

    /// d(pixel)/d(fit coordinates) by central differences.
    fn jacobian(&self, q: Vector2<f64>) -> Option<Matrix2<f64>> {
        match self {
            Coords::Pixel => Some(Matrix2::identity()),
            Coords::Undistorted(_) => {
                let h = 1e-3;
                let dx =
                    (self.to_pixel(q + Vector2::new(h, 0.0))? - self.to_pixel(q - Vector2::new(h, 0.0))?) / (2.0 * h);
                let dy =
                    (self.to_pixel(q + Vector2::new(0.0, h))? - self.to_pixel(q - Vector2::new(0.0, h))?) / (2.0 * h);
                Some(Matrix2::from_columns(&[dx, dy]))
            }
        }
    }
}

/// One segment of a line job, in fit coordinates.
#[derive(Clone, Debug)]
struct SegJob {
    a: Vector2<f64>,
    b: Vector2<f64>,
    /// Directions of the crossing lines at `a` and `b` (unit).
    cross_a: Vector2<f64>,
    cross_b: Vector2<f64>,
    /// Room on either side of the edge before the next parallel edge, pixels.
    room_px: f64,
}

/// A line to fit: origin, initial tangent, segments, and (local support) the largest `|t|`.
#[derive(Clone, Debug)]
struct LineJob {
    origin: Vector2<f64>,
    tangent: Vector2<f64>,
    segments: Vec<SegJob>,
    t_limit: Option<f64>,
    /// Fit a parabola with its vertex at the origin instead of a straight line (the two
    /// segments on either side of a corner, [`LineSupport::Local`]).
    curved: bool,
}

/// A line job's identity: the bits of everything its fit depends on.
type JobKey = Vec<u64>;

/// Unweighted fits of the previous pass by job ([`refine_grid`]).
type FitCache = std::collections::HashMap<JobKey, Option<FittedLine>>;

impl LineJob {
    fn key(&self) -> JobKey {
        let mut k = Vec::with_capacity(6 + 9 * self.segments.len());
        k.extend([self.origin.x, self.origin.y, self.tangent.x, self.tangent.y].map(f64::to_bits));
        k.push(self.t_limit.map_or(u64::MAX, f64::to_bits));
        k.push(u64::from(self.curved));
        for s in &self.segments {
            k.extend(
                [s.a.x, s.a.y, s.b.x, s.b.y, s.cross_a.x, s.cross_a.y, s.cross_b.x, s.cross_b.y, s.room_px]
                    .map(f64::to_bits),
            );
        }
        k
    }
}

/// A fitted line in fit coordinates.
#[derive(Clone, Debug)]
struct FittedLine {
    origin: Vector2<f64>,
    state: LineState,
    fit: LineFit,
    pixels: usize,
}

impl FittedLine {
    fn reduced_chi2(&self) -> f64 {
        self.fit.chi2 / (self.fit.n - self.fit.p) as f64
    }
}

/// Collects the band pixels of every segment for the line's current state.
fn gather(
    img: &GrayF32,
    coords: &Coords,
    job: &LineJob,
    state: &LineState,
    blur: f64,
    options: &RefineOptions,
) -> Vec<Option<Vec<Sample>>> {
    let n = state.normal();
    let t = state.tangent();
    let (w_img, h_img) = (img.width as f64, img.height as f64);
    job.segments
        .iter()
        .map(|seg| {
            let mut w = 2.5 * blur + 2.0;
            w = w.min(seg.room_px - 2.5 * blur - 0.5);
            if let Some(m) = options.max_band_px {
                w = w.min(m);
            }
            if w < 1.5 {
                w = w.max(1.0);
                if seg.room_px < 2.0 {
                    return None;
                }
            }
            let ex = |cross: Vector2<f64>| {
                let sin = (t.x * cross.y - t.y * cross.x).abs().max(0.25);
                let cos = t.dot(&cross).abs();
                (3.0 * blur + 1.0 + w * cos) / sin
            };
            let ta = t.dot(&(seg.a - job.origin));
            let tb = t.dot(&(seg.b - job.origin));
            let (mut lo, mut hi) = if ta <= tb {
                (ta + ex(seg.cross_a), tb - ex(seg.cross_b))
            } else {
                (tb + ex(seg.cross_b), ta - ex(seg.cross_a))
            };
            if let Some(l) = job.t_limit {
                lo = lo.max(-l);
                hi = hi.min(l);
            }
            if hi - lo < 3.0 {
                return None;
            }
            // Bounding box of the band in pixels.
            let mut bb = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
            let steps = if matches!(coords, Coords::Pixel) { 1 } else { 8 };
            for k in 0..=steps {
                let tt = lo + (hi - lo) * k as f64 / steps as f64;
                for uu in [-w, w] {
                    let q = job.origin + t * tt + n * (state.d + uu);
                    let p = coords.to_pixel(q)?;
                    bb[0] = bb[0].min(p.x);
                    bb[1] = bb[1].min(p.y);
                    bb[2] = bb[2].max(p.x);
                    bb[3] = bb[3].max(p.y);
                }
            }
            let margin = if matches!(coords, Coords::Pixel) { 1.0 } else { 3.0 };
            let x0 = (bb[0] - margin).floor().max(0.0);
            let y0 = (bb[1] - margin).floor().max(0.0);
            let x1 = (bb[2] + margin).ceil().min(w_img - 1.0);
            let y1 = (bb[3] + margin).ceil().min(h_img - 1.0);
            if x1 < x0 || y1 < y0 {
                return None;
            }
            let mut out = Vec::new();
            for yi in y0 as usize..=y1 as usize {
                let (xa, xb) = match coords {
                    Coords::Pixel => row_span(job.origin, t, n, state.d, (lo, hi), w, yi as f64, (x0, x1)),
                    Coords::Undistorted(_) => (x0, x1),
                };
                if xb < xa {
                    continue;
                }
                for xi in xa as usize..=xb as usize {
                    let Some(q) = coords.to_fit(Vector2::new(xi as f64, yi as f64)) else { continue };
                    let x = q - job.origin;
                    let tt = t.dot(&x);
                    let u = n.dot(&x) - state.d;
                    if tt >= lo && tt <= hi && u.abs() <= w {
                        out.push(Sample { x: x.x, y: x.y, v: f64::from(img.get(xi, yi)), w: 1.0 });
                    }
                }
            }
            if out.len() < 8 {
                None
            } else {
                Some(out)
            }
        })
        .collect()
}

/// A job's line is bent only while it keeps a segment on either side of its corner.
fn set_curved(state: &mut LineState, job: &LineJob) {
    state.curved = job.curved && state.segments.len() == 2;
    if !state.curved {
        state.kappa = 0.0;
    }
}

/// Fits one line job: band selection, fit, dropping segments without an edge, reselection
/// when the line moved. Unweighted (pass 1).
fn fit_job(img: &GrayF32, coords: &Coords, job: &LineJob, options: &RefineOptions) -> Option<FittedLine> {
    let phi0 = job.tangent.y.atan2(job.tangent.x) - std::f64::consts::FRAC_PI_2;
    let mut state = LineState::straight(phi0, 0.0, Vec::new());
    snap_line(img, coords, job, &mut state, options);
    let phi0 = state.phi;
    let mut blur = options.initial_blur_px;
    let mut prev = (phi0, state.d);
    let mut fitted: Option<LineFit> = None;
    let mut kept: Vec<bool> = vec![true; job.segments.len()];
    for round in 0..4 {
        let gathered = gather(img, coords, job, &state, blur, options);
        let old: Vec<Segment> = std::mem::take(&mut state.segments);
        let mut idx = 0;
        for (k, g) in gathered.into_iter().enumerate() {
            // The previous round's parameters of the segment (its pixels are replaced).
            let prior = if round > 0 && kept[k] {
                let s = old.get(idx).map(|s| (s.a, s.b, s.ln_s, s.g));
                idx += 1;
                s
            } else {
                None
            };
            match g {
                Some(samples) if kept[k] => {
                    let (a, b, ln_s, g) = prior.unwrap_or((0.0, 0.0, blur.ln(), 0.0));
                    state.segments.push(Segment { a, b, ln_s, g, samples });
                }
                _ => kept[k] = false,
            }
        }
        if state.segments.is_empty() {
            return None;
        }
        set_curved(&mut state, job);
        if round == 0 {
            state.init_intensities();
        }
        let mut fit = state.solve_intermediate(options.max_iterations)?;
        // Drop segments without a clear step and refit.
        let max_b = state.segments.iter().map(|s| s.b.abs()).fold(0.0, f64::max);
        let thresh = options.min_contrast_dn.max(0.25 * max_b);
        if state.segments.iter().any(|s| s.b.abs() < thresh) {
            let mut j = 0;
            for keep in kept.iter_mut() {
                if *keep {
                    if state.segments[j].b.abs() < thresh {
                        *keep = false;
                    }
                    j += 1;
                }
            }
            state.segments.retain(|s| s.b.abs() >= thresh);
            if state.segments.is_empty() {
                return None;
            }
            set_curved(&mut state, job);
            fit = state.solve_intermediate(options.max_iterations)?;
        }
        let new_blur = state.segments.iter().map(|s| s.ln_s.exp()).fold(0.0, f64::max);
        let reach = job.t_limit.unwrap_or(200.0);
        let moved = (state.d - prev.1).abs() + (state.phi - prev.0).abs() * reach;
        let blur_changed = (new_blur / blur - 1.0).abs() > 0.25;
        prev = (state.phi, state.d);
        fitted = Some(fit);
        if moved < 0.3 && !blur_changed {
            // The band the pixels came from is the band of the fitted line.
            break;
        }
        blur = new_blur.clamp(0.3, 8.0);
    }
    let fit = fitted?;
    // A bend that lens distortion cannot give (a sagitta above MAX_SAGITTA_PX over the
    // segments' reach: small, blurred squares where the curvature is not determined) falls
    // back to the straight line.
    if state.curved {
        let reach = state
            .segments
            .iter()
            .flat_map(|s| s.samples.iter())
            .map(|p| state.tangent().dot(&Vector2::new(p.x, p.y)).abs())
            .fold(0.0, f64::max);
        if 0.5 * state.kappa.abs() * reach * reach > MAX_SAGITTA_PX {
            return fit_job(img, coords, &LineJob { curved: false, ..job.clone() }, options);
        }
    }
    let pixels = state.segments.iter().map(|s| s.samples.len()).sum();
    Some(FittedLine { origin: job.origin, state, fit, pixels })
}

/// Largest sagitta (pixels) of a bent line over its segments' reach that is taken as lens
/// distortion (see [`fit_job`]). 0.5 px fell back to the straight chord in the image corners of
/// a strong barrel lens (k1 = -0.195 at 1280 x 960, calibration study seed 15: outer-third
/// radial corner bias -0.038 px, fx off by 0.19 px); 1.0 px keeps those bends and still
/// rejects the spurious ones of small blurred squares (OpenCV's stereo sample).
const MAX_SAGITTA_PX: f64 = 1.0;

/// Refines grid points of a [`CheckerGrid`] from the edges that meet there.
///
/// `wanted` lists the grid points `(row, col)` to return (in that order); each needs an
/// initial position within about one blur width plus one pixel, and at least one edge along
/// each of its two grid lines. Points that cannot be refined come back as `None`.
pub fn refine_grid(
    image: &GrayF32,
    grid: &CheckerGrid,
    wanted: &[(usize, usize)],
    options: &RefineOptions,
) -> Result<(Vec<Option<RefinedCorner>>, RefineSummary)> {
    refine_grid_timed(image, grid, wanted, options, None)
}

/// [`refine_grid`] adding the time of its stages to `timings`.
pub(crate) fn refine_grid_timed(
    image: &GrayF32,
    grid: &CheckerGrid,
    wanted: &[(usize, usize)],
    options: &RefineOptions,
    mut timings: Option<&mut StageTimings>,
) -> Result<(Vec<Option<RefinedCorner>>, RefineSummary)> {
    grid.check()?;
    options.validate()?;
    let coords = match &options.camera {
        Some(c) => Coords::Undistorted(c),
        None => Coords::Pixel,
    };
    // The bands and the excluded corner neighbourhoods are placed from the grid points: when a
    // corner of the unweighted fit lies more than 0.5 px from its start, every wanted point
    // starts again from its unweighted corner (at most twice; a line whose grid points did
    // not move comes from the cache, bit for bit). The noise estimate and the weighted fit
    // run once, on the last unweighted pass.
    let mut current = grid.clone();
    let mut pass = unweighted_pass(image, &coords, &current, wanted, options, FitCache::new(), timings.as_deref_mut())?;
    for _ in 0..2 {
        let mut moved = false;
        for (&(i, j), q) in wanted.iter().zip(pass.corners_px(&coords)) {
            let k = i * (grid.field_cols + 1) + j;
            if let Some(q) = q {
                if let Some(p) = current.points_px[k] {
                    moved |= (p - q).norm() > 0.5;
                }
                current.points_px[k] = Some(q);
            }
        }
        if !moved {
            break;
        }
        // The fits of this pass move into the next pass's cache (no copy of their pixels).
        let cache: FitCache = pass.keys.into_iter().zip(pass.fitted).collect();
        pass = unweighted_pass(image, &coords, &current, wanted, options, cache, timings.as_deref_mut())?;
    }
    Ok(weighted_pass(pass, &coords, options, timings))
}

/// The unweighted fits of one pass: the line jobs' fits and, per wanted point, its two lines.
struct UnweightedPass {
    fitted: Vec<Option<FittedLine>>,
    corner_jobs: Vec<Option<(usize, usize)>>,
    /// The job of each fit (the next pass's cache).
    keys: Vec<JobKey>,
}

impl UnweightedPass {
    /// The wanted points where their two unweighted lines cross (pixels), in order.
    fn corners_px(&self, coords: &Coords) -> Vec<Option<Point2<f64>>> {
        self.corner_jobs
            .iter()
            .map(|cj| {
                let (a, b) = (*cj)?;
                let (q, _) = intersect(self.fitted[a].as_ref()?, self.fitted[b].as_ref()?)?;
                coords.to_pixel(q).map(|p| Point2::new(p.x, p.y))
            })
            .collect()
    }
}

/// One pass of unweighted line fits from the grid points of `grid` (see [`refine_grid`]); a
/// line whose job is in `cache` (the previous pass's) is moved from there.
fn unweighted_pass(
    image: &GrayF32,
    coords: &Coords,
    grid: &CheckerGrid,
    wanted: &[(usize, usize)],
    options: &RefineOptions,
    mut cache: FitCache,
    timings: Option<&mut StageTimings>,
) -> Result<UnweightedPass> {
    let t0 = Instant::now();
    let pts = Points {
        grid,
        fit: grid.points_px.iter().map(|p| p.and_then(|p| coords.to_fit(Vector2::new(p.x, p.y)))).collect(),
    };
    for &(i, j) in wanted {
        if i > grid.field_rows || j > grid.field_cols {
            return Err(VisionError::BadOption {
                name: "wanted",
                value: format!("({i}, {j})"),
                reason: format!("grid points run to ({}, {})", grid.field_rows, grid.field_cols),
            });
        }
    }
    // Line jobs: per wanted point (local) or per grid line (global). key: (dir, index, point).
    let mut jobs: Vec<LineJob> = Vec::new();
    let mut corner_jobs: Vec<Option<(usize, usize)>> = Vec::with_capacity(wanted.len());
    let mut global_index: std::collections::HashMap<(usize, usize), Option<usize>> = std::collections::HashMap::new();
    for &(i, j) in wanted {
        let (ii, jj) = (i as isize, j as isize);
        let Some(c) = pts.get(ii, jj) else {
            corner_jobs.push(None);
            continue;
        };
        let mut pair = [None, None];
        for (dir, slot) in pair.iter_mut().enumerate() {
            match options.support {
                LineSupport::Local => {
                    let mut segs = Vec::new();
                    // The two segments of this line that end at (i, j).
                    let (si, sj) = if dir == 0 { (0, 1) } else { (1, 0) };
                    for (pi, pj) in [(ii - si, jj - sj), (ii, jj)] {
                        if grid.is_edge(pi, pj, dir) {
                            if let Some(s) = segment_job(&pts, pi, pj, dir) {
                                segs.push(s);
                            }
                        }
                    }
                    if segs.is_empty() {
                        continue;
                    }
                    let t = pts.direction(ii, jj, si, sj);
                    let Some(t) = t else { continue };
                    // A corner between two segments of a line bent by an unknown lens
                    // distortion: its tangent through the corner, not the chord (see `line`).
                    // With a camera model the lines are straight in the fit coordinates.
                    let curved = segs.len() == 2 && options.camera.is_none();
                    jobs.push(LineJob {
                        origin: c,
                        tangent: t,
                        segments: segs,
                        t_limit: Some(options.max_segment_px),
                        curved,
                    });
                    *slot = Some(jobs.len() - 1);
                }
                LineSupport::Global => {
                    let key = (dir, if dir == 0 { i } else { j });
                    let entry = global_index.entry(key).or_insert_with(|| {
                        let n = if dir == 0 { grid.field_cols } else { grid.field_rows };
                        let mut segs = Vec::new();
                        let mut members = Vec::new();
                        for k in 0..=n as isize {
                            let (pi, pj) = if dir == 0 { (ii, k) } else { (k, jj) };
                            if let Some(p) = pts.get(pi, pj) {
                                members.push(p);
                            }
                            if k < n as isize && grid.is_edge(pi, pj, dir) {
                                if let Some(s) = segment_job(&pts, pi, pj, dir) {
                                    segs.push(s);
                                }
                            }
                        }
                        if segs.is_empty() || members.len() < 2 {
                            return None;
                        }
                        let origin = members.iter().sum::<Vector2<f64>>() / members.len() as f64;
                        let v = members[members.len() - 1] - members[0];
                        let tangent = v / v.norm().max(1e-12);
                        jobs.push(LineJob { origin, tangent, segments: segs, t_limit: None, curved: false });
                        Some(jobs.len() - 1)
                    });
                    *slot = *entry;
                }
            }
        }
        corner_jobs.push(match pair {
            [Some(a), Some(b)] => Some((a, b)),
            _ => None,
        });
    }
    // Pass 1: unweighted. The lines are independent: fitted in parallel, collected in order
    // (every sum over lines below runs in the same order as on one thread).
    // A line whose job is the same as in the previous pass (its grid points did not move) has
    // the same unweighted fit: taken from the cache, bit for bit.
    // (A job that appears twice is taken from the cache once and fitted again the second
    // time: the same fit.)
    let keys: Vec<JobKey> = jobs.iter().map(LineJob::key).collect();
    let hits: Vec<Option<Option<FittedLine>>> = keys.iter().map(|k| cache.remove(k)).collect();
    let fitted: Vec<Option<FittedLine>> =
        jobs.par_iter().zip(hits).map(|(j, hit)| hit.unwrap_or_else(|| fit_job(image, coords, j, options))).collect();
    if let Some(t) = timings {
        StageTimings::add_since(&mut t.refine_ms, t0);
        t.refine_passes += 1;
        t.lines += jobs.len();
        t.band_pixels += fitted.iter().flatten().map(|f| f.pixels).sum::<usize>();
    }
    Ok(UnweightedPass { fitted, corner_jobs, keys })
}

/// The noise estimate and the weighted fits on the lines of the last unweighted pass, the
/// corners and their covariances.
fn weighted_pass(
    pass: UnweightedPass,
    coords: &Coords,
    options: &RefineOptions,
    timings: Option<&mut StageTimings>,
) -> (Vec<Option<RefinedCorner>>, RefineSummary) {
    let t1 = Instant::now();
    let UnweightedPass { mut fitted, corner_jobs, .. } = pass;
    // Illumination (vignetting, uneven light): a smooth field fitted to the segments' light
    // levels gives each segment its fixed gradient across the edge, used from here on (the
    // noise statistics at the unweighted fit, then the final fit below: the gradient moves
    // a line by far less than its uncertainty, so the noise estimate does not need a refit
    // in between).
    if let Some(field) = IlluminationField::fit(&fitted, options.min_contrast_dn) {
        fitted.par_iter_mut().for_each(|f| {
            let Some(line) = f.as_mut() else { return };
            let n = line.state.normal();
            let origin = line.origin;
            for seg in &mut line.state.segments {
                seg.g = field.gradient(origin + seg.centre()).dot(&n);
            }
        });
    }
    // Noise model.
    let noise = match options.noise {
        NoiseSpec::Unweighted => None,
        NoiseSpec::Known(m) => Some(m),
        NoiseSpec::Estimate => {
            // Per line in parallel, summed in line order.
            let per_line: Vec<[f64; 5]> =
                fitted.par_iter().flatten().map(|f| f.state.noise_sums(f.fit.n, f.fit.p)).collect();
            let mut s = [0.0f64; 5];
            for sums in per_line {
                for (a, b) in s.iter_mut().zip(sums) {
                    *a += b;
                }
            }
            estimate_noise(&s)
        }
    };
    // Pass 2: weighted (or, without a noise model, the unweighted fits to the tight
    // tolerance: the fits above only place bands and start this one): one Gauss-Newton step
    // from the unweighted fit (`LineState::solve_from_near`, Levenberg-Marquardt when the
    // step is large or does not lower the cost).
    fitted.par_iter_mut().for_each(|f| {
        let Some(line) = f.as_mut() else { return };
        if let Some(nm) = &noise {
            line.state.set_weights(Some(nm));
        }
        match line.state.solve_from_near(options.max_iterations) {
            Some(fit) => line.fit = fit,
            None => *f = None,
        }
    });
    let lines_fitted = fitted.iter().filter(|f| f.is_some()).count();
    let (mut chi_sum, mut chi_n) = (0.0, 0.0);
    for f in fitted.iter().flatten() {
        chi_sum += f.fit.chi2;
        chi_n += (f.fit.n - f.fit.p) as f64;
    }
    let summary = RefineSummary {
        noise,
        lines_fitted,
        lines_failed: fitted.len() - lines_fitted,
        reduced_chi2: if chi_n > 0.0 { chi_sum / chi_n } else { f64::NAN },
    };
    let corners = corner_jobs
        .iter()
        .map(|cj| {
            let (a, b) = (*cj)?;
            let (l1, l2) = (fitted[a].as_ref()?, fitted[b].as_ref()?);
            let (q, blocks) = intersect(l1, l2)?;
            // The refined corner must stay near its start.
            let jac = coords.jacobian(q)?;
            let p = coords.to_pixel(q)?;
            let mut cov = Matrix2::zeros();
            let mut crb = Matrix2::zeros();
            for (blk, l) in blocks.iter().zip([l1, l2]) {
                let j = jac * blk;
                cov += j * (l.state_h_inv() * l.reduced_chi2()) * j.transpose();
                crb += j * l.state_h_inv() * j.transpose();
            }
            let segs: Vec<&Segment> = l1.state.segments.iter().chain(&l2.state.segments).collect();
            let blur = segs.iter().map(|s| s.ln_s.exp()).sum::<f64>() / segs.len() as f64;
            let contrast = segs.iter().map(|s| s.b.abs()).sum::<f64>() / segs.len() as f64;
            Some(RefinedCorner {
                position_px: Point2::new(p.x, p.y),
                covariance_px2: cov,
                crb_px2: noise.map(|_| crb),
                blur_px: blur,
                contrast_dn: contrast,
                pixels: l1.pixels + l2.pixels,
            })
        })
        .collect();
    if let Some(t) = timings {
        StageTimings::add_since(&mut t.covariance_ms, t1);
    }
    (corners, summary)
}
