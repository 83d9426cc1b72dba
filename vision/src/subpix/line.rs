//! One edge line, possibly carrying several segments of either polarity, fitted to the pixels
//! of a band around it with the blurred-step model (Levenberg-Marquardt). The line is straight,
//! or, when [`LineState::curved`], a parabola with its vertex at the origin: the signed
//! distance of `x` (relative to the origin) is `u = n . x - d - kappa (t . x)^2 / 2`. Lens
//! distortion bends the image of a straight grid line; a straight line fitted to the two
//! segments on either side of a corner then passes the corner at the mean sagitta (about
//! `kappa L^2 / 6` for segments reaching `L` from it), a bias towards the centre of curvature
//! that does not average out. The parabola is the second-order expansion of the bent line
//! about the corner, so `(phi, d)` describe its tangent there without that bias.

use nalgebra::{DMatrix, DVector, Matrix2, Vector2};

#[cfg(test)]
use super::erf::normal_cdf;
use super::erf::{madd, NormalTable};
use super::NoiseModel;

/// Lower and upper bounds of `ln(blur)` (blur from 0.1 px to 15 px).
const LN_BLUR_MIN: f64 = -std::f64::consts::LN_10;
const LN_BLUR_MAX: f64 = 2.708_050_201_102_21;

/// One pixel of a band: its position relative to the line's origin (fit coordinates), its value
/// and its weight (inverse variance, 1 when unweighted).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sample {
    pub x: f64,
    pub y: f64,
    pub v: f64,
    pub w: f64,
}

/// One segment of the line: its own intensities `a` (the side where `u < 0`), `b` (the step,
/// signed) and blur `exp(ln_s)`, a fixed relative illumination gradient `g` across the edge
/// (`I = (a + b Phi(u / s)) (1 + g u)`, from the smooth illumination field; not fitted, as it
/// would trade against the edge position), and its pixels.
#[derive(Clone, Debug)]
pub(crate) struct Segment {
    pub a: f64,
    pub b: f64,
    pub ln_s: f64,
    pub g: f64,
    pub samples: Vec<Sample>,
}

/// Normal matrix and gradient of a weighted least-squares problem.
type NormalEquations = (DMatrix<f64>, DVector<f64>);

/// One segment's cost, normal matrix (upper triangle, padded to 6) and gradient.
type SegmentSums = (f64, [[f64; 6]; 6], [f64; 6]);

/// Whether the CPU has AVX2 and FMA (the pixel loops are then compiled for them).
#[cfg(target_arch = "x86_64")]
#[inline]
fn avx2_fma() -> bool {
    std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
}

/// Parameters per segment.
const PS: usize = 3;

/// Relative tolerance of a fit whose result is reported ([`LineState::solve_to`]).
pub(crate) const TIGHT: f64 = 1e-10;

/// Relative tolerance of an intermediate fit (its line places a band or starts the next fit):
/// a step of about 1e-4 px, far below the corners' uncertainty.
pub(crate) const LOOSE: f64 = 1e-6;

/// A line `n . x = d`, `n = (cos phi, sin phi)`, `x` relative to the origin, with its segments;
/// when `curved`, bent by `kappa` (see the module documentation).
#[derive(Clone, Debug)]
pub(crate) struct LineState {
    pub phi: f64,
    pub d: f64,
    /// Curvature, 1/px (fitted only when `curved`, else 0).
    pub kappa: f64,
    /// Whether `kappa` is a parameter of the fit.
    pub curved: bool,
    pub segments: Vec<Segment>,
}

/// What a converged fit leaves behind.
#[derive(Clone, Debug)]
pub(crate) struct LineFit {
    /// Weighted sum of squared residuals.
    pub chi2: f64,
    /// Number of pixels.
    pub n: usize,
    /// Number of parameters.
    pub p: usize,
    /// Inverse of the weighted normal matrix, the `(phi, d)` block.
    pub h_inv_line: Matrix2<f64>,
}

impl LineState {
    /// A straight line.
    pub fn straight(phi: f64, d: f64, segments: Vec<Segment>) -> Self {
        Self { phi, d, kappa: 0.0, curved: false, segments }
    }

    /// Parameters of the line itself: `phi, d` and, when curved, `kappa`.
    fn line_params(&self) -> usize {
        if self.curved {
            3
        } else {
            2
        }
    }

    fn n_params(&self) -> usize {
        self.line_params() + PS * self.segments.len()
    }

    /// The signed distance `u` of a point (relative to the origin) and `t . x`.
    fn u_t(&self, cs: (f64, f64), x: f64, y: f64) -> (f64, f64) {
        let (c, s) = cs;
        let t = -s * x + c * y;
        (c * x + s * y - self.d - 0.5 * self.kappa * t * t, t)
    }

    fn params(&self) -> DVector<f64> {
        let mut x = DVector::zeros(self.n_params());
        x[0] = self.phi;
        x[1] = self.d;
        if self.curved {
            x[2] = self.kappa;
        }
        let l = self.line_params();
        for (k, s) in self.segments.iter().enumerate() {
            x[l + PS * k] = s.a;
            x[l + 1 + PS * k] = s.b;
            x[l + 2 + PS * k] = s.ln_s;
        }
        x
    }

    fn set_params(&mut self, x: &DVector<f64>) {
        self.phi = x[0];
        self.d = x[1];
        if self.curved {
            self.kappa = x[2];
        }
        let l = self.line_params();
        for (k, s) in self.segments.iter_mut().enumerate() {
            s.a = x[l + PS * k];
            s.b = x[l + 1 + PS * k];
            s.ln_s = x[l + 2 + PS * k].clamp(LN_BLUR_MIN, LN_BLUR_MAX);
        }
    }

    /// Weighted cost, normal matrix and gradient (one pass over the pixels).
    fn evaluate(&self) -> (f64, NormalEquations) {
        #[cfg(test)]
        tests::EVALUATIONS.with(|c| c.set(c.get() + 1));
        let np = self.n_params();
        let mut h = DMatrix::<f64>::zeros(np, np);
        let mut g = DVector::<f64>::zeros(np);
        let l = self.line_params();
        let mut cost = 0.0;
        for (k, seg) in self.segments.iter().enumerate() {
            // Per-segment accumulation ((phi, d[, kappa], a, b, ln_s)), folded into h afterwards;
            // the number of parameters is a constant of each loop, which the compiler unrolls.
            // Unit weights (the unweighted fits) skip the multiplications by 1 (the same sums).
            let unit = seg.samples.iter().all(|p| p.w == 1.0);
            let (c, hs, gs) = match (self.curved, unit) {
                (true, true) => self.segment_sums::<6, true>(seg),
                (true, false) => self.segment_sums::<6, false>(seg),
                (false, true) => self.segment_sums::<5, true>(seg),
                (false, false) => self.segment_sums::<5, false>(seg),
            };
            cost += c;
            let m = l + 3;
            let idx = if self.curved {
                [0, 1, 2, l + PS * k, l + 1 + PS * k, l + 2 + PS * k]
            } else {
                [0, 1, l + PS * k, l + 1 + PS * k, l + 2 + PS * k, 0]
            };
            for a in 0..m {
                g[idx[a]] += gs[a];
                for b in a..m {
                    h[(idx[a], idx[b])] += hs[a][b];
                    if a != b {
                        h[(idx[b], idx[a])] += hs[a][b];
                    }
                }
            }
        }
        (cost, (h, g))
    }

    /// One segment's weighted cost, normal matrix (upper triangle) and gradient over its
    /// `M` parameters: `phi, d, [kappa,] a, b, ln_s` (`M` = 6 when curved, else 5); with
    /// `UNIT`, every weight is 1 and is not multiplied. On a CPU with AVX2 and FMA (checked at
    /// run time), the same sums compiled for it, with fused multiply-adds.
    #[inline(always)]
    fn segment_sums<const M: usize, const UNIT: bool>(&self, seg: &Segment) -> SegmentSums {
        #[cfg(target_arch = "x86_64")]
        if avx2_fma() {
            // SAFETY: the CPU has the features the function is compiled for (checked above).
            return unsafe { self.segment_sums_avx2::<M, UNIT>(seg) };
        }
        self.segment_sums_with::<M, UNIT, false>(seg)
    }

    /// [`Self::segment_sums_with`] compiled for AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn segment_sums_avx2<const M: usize, const UNIT: bool>(&self, seg: &Segment) -> SegmentSums {
        self.segment_sums_with::<M, UNIT, true>(seg)
    }

    /// [`Self::segment_sums`]; with `FMA`, products are accumulated by fused multiply-adds
    /// (only inside a function compiled for FMA).
    #[inline(always)]
    fn segment_sums_with<const M: usize, const UNIT: bool, const FMA: bool>(&self, seg: &Segment) -> SegmentSums {
        let table = NormalTable::get();
        let (c, s) = (self.phi.cos(), self.phi.sin());
        let sig = seg.ln_s.exp();
        let inv_sig = 1.0 / sig;
        // Rows padded to 8 columns: with FMA (AVX2), a whole row is two vector multiply-adds
        // (the entries below the diagonal are summed too, and not used).
        let mut hs = [[0.0f64; 8]; M];
        let mut gs = [0.0f64; 8];
        let mut cost = 0.0;
        for p in &seg.samples {
            let (u, t) = self.u_t((c, s), p.x, p.y);
            let z = u * inv_sig;
            let (cdf, pdf) = table.cdf_pdf_with::<FMA>(z);
            let q = madd::<FMA>(seg.g, u, 1.0);
            let base = madd::<FMA>(seg.b, cdf, seg.a);
            let r = p.v - base * q;
            cost = madd::<FMA>(if UNIT { r } else { p.w * r }, r, cost);
            let gu = madd::<FMA>(seg.b * pdf * inv_sig, q, base * seg.g);
            // du/dphi = t + kappa t (n . x), du/dd = -1, du/dkappa = -t^2 / 2.
            let du_dphi = madd::<FMA>(self.kappa * t, c * p.x + s * p.y, t);
            let (ja, jb, js) = (q, cdf * q, -seg.b * pdf * z * q);
            let mut j = [0.0f64; 8];
            j[0] = gu * du_dphi;
            j[1] = -gu;
            if M == 6 {
                j[2] = -0.5 * gu * t * t;
            }
            j[M - 3] = ja;
            j[M - 2] = jb;
            j[M - 1] = js;
            let wr = if UNIT { r } else { p.w * r };
            for (a, row) in hs.iter_mut().enumerate() {
                let wa = if UNIT { j[a] } else { p.w * j[a] };
                if FMA {
                    for b in 0..8 {
                        row[b] = madd::<FMA>(wa, j[b], row[b]);
                    }
                } else {
                    for b in a..M {
                        row[b] = madd::<FMA>(wa, j[b], row[b]);
                    }
                }
            }
            for (g, jb) in gs.iter_mut().zip(j) {
                *g = madd::<FMA>(wr, jb, *g);
            }
        }
        let mut h6 = [[0.0f64; 6]; 6];
        let mut g6 = [0.0f64; 6];
        for a in 0..M {
            g6[a] = gs[a];
            h6[a][a..M].copy_from_slice(&hs[a][a..M]);
        }
        (cost, h6, g6)
    }

    /// Least-squares intensities `a`, `b` of every segment for the current line and blur.
    pub fn init_intensities(&mut self) {
        let table = NormalTable::get();
        let cs = (self.phi.cos(), self.phi.sin());
        let line = Self::straight(self.phi, self.d, Vec::new());
        let line = Self { kappa: self.kappa, ..line };
        for seg in &mut self.segments {
            let sig = seg.ln_s.exp();
            let (mut s00, mut s01, mut s11, mut t0, mut t1) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for p in &seg.samples {
                let (u, _) = line.u_t(cs, p.x, p.y);
                let q = 1.0 + seg.g * u;
                let (e, f) = (q, table.cdf(u / sig) * q);
                s00 += p.w * e * e;
                s01 += p.w * e * f;
                s11 += p.w * f * f;
                t0 += p.w * p.v * e;
                t1 += p.w * p.v * f;
            }
            let det = s00 * s11 - s01 * s01;
            if det.abs() > 1e-12 * (s00 * s11).max(1e-300) {
                seg.a = (s11 * t0 - s01 * t1) / det;
                seg.b = (s00 * t1 - s01 * t0) / det;
            } else {
                seg.a = if s00 > 0.0 { t0 / s00 } else { 0.0 };
                seg.b = 0.0;
            }
        }
    }

    /// Replaces every weight by the inverse variance of the noise model at the current model
    /// value (or 1 without a model).
    pub fn set_weights(&mut self, noise: Option<&NoiseModel>) {
        let table = NormalTable::get();
        let cs = (self.phi.cos(), self.phi.sin());
        let line = Self { kappa: self.kappa, ..Self::straight(self.phi, self.d, Vec::new()) };
        for seg in &mut self.segments {
            let sig = seg.ln_s.exp();
            for p in &mut seg.samples {
                p.w = match noise {
                    Some(nm) => {
                        let (u, _) = line.u_t(cs, p.x, p.y);
                        let m = (seg.a + seg.b * table.cdf(u / sig)) * (1.0 + seg.g * u);
                        1.0 / nm.variance_dn2(m)
                    }
                    None => 1.0,
                };
            }
        }
    }

    /// Levenberg-Marquardt; `None` when the normal matrix is singular or the fit diverges.
    ///
    /// Every trial point is evaluated with its normal equations (one pass over the pixels), so
    /// an accepted step already holds the next iteration's system and, at the end, the one the
    /// covariance comes from. The fit stops when a step is negligible (below 1e-7 px in `d`
    /// and 1e-9 rad in `phi` with no real decrease), when the decrease the linear model predicts
    /// for the next step is below [`TIGHT`] of the cost (a step of about 1e-6 px: rounding would
    /// decide whether it is taken), or when no damping gives a decrease.
    #[cfg(test)]
    pub fn solve(&mut self, max_iterations: usize) -> Option<LineFit> {
        self.solve_to(max_iterations, TIGHT)
    }

    /// [`Self::solve`] stopping when the predicted decrease is below `rel_tol` of the cost
    /// (and a step below `1e-7 sqrt(rel_tol / 1e-12)` px is negligible): [`TIGHT`] for a
    /// result, [`LOOSE`] (a step of about 1e-4 px) for a fit that only places the next band
    /// or starts another fit (but see [`Self::solve_intermediate`]).
    pub fn solve_to(&mut self, max_iterations: usize, rel_tol: f64) -> Option<LineFit> {
        self.solve_with(max_iterations, rel_tol, false)
    }

    /// [`Self::solve_to`] with [`LOOSE`] for a fit that only places the next band or starts
    /// another fit, ending one pass over the pixels earlier where it converges fast: when the
    /// decrease a step predicts, times its ratio to the previous step's prediction (the
    /// contraction per step), is below a tenth of [`LOOSE`] of the cost, the step after it
    /// would not be taken; the step is then checked by its cost alone (a pass without
    /// derivatives) and the fit ends on it. The point is the one [`Self::solve_to`] ends on
    /// whenever that prediction holds; the returned [`LineFit::h_inv_line`] is the normal
    /// matrix's before the last step (a fit whose covariance is reported is not intermediate).
    pub fn solve_intermediate(&mut self, max_iterations: usize) -> Option<LineFit> {
        self.solve_with(max_iterations, LOOSE, true)
    }

    /// [`Self::solve_to`]; with `finish_by_prediction`, as [`Self::solve_intermediate`].
    fn solve_with(&mut self, max_iterations: usize, rel_tol: f64, finish_by_prediction: bool) -> Option<LineFit> {
        let step_scale = (rel_tol / 1e-12).sqrt();
        let n: usize = self.segments.iter().map(|s| s.samples.len()).sum();
        let np = self.n_params();
        if n <= np + 2 {
            return None;
        }
        let mut lambda = 1e-3;
        let (mut cost, (mut h, mut g)) = self.evaluate();
        // Predicted relative decrease of the last accepted step.
        let mut last_predicted: Option<f64> = None;
        'outer: for _ in 0..max_iterations {
            let x0 = self.params();
            let mut improved = false;
            let mut small_step = false;
            for _ in 0..12 {
                let mut a = h.clone();
                for i in 0..np {
                    a[(i, i)] += lambda * h[(i, i)].max(1e-12);
                }
                let Some(ch) = a.cholesky() else {
                    lambda *= 10.0;
                    continue;
                };
                let mut delta = ch.solve(&g);
                // Trust region on the line and blur parameters.
                let mut scale: f64 = 1.0;
                scale = scale.min(0.05 / delta[0].abs().max(1e-300));
                scale = scale.min(1.0 / delta[1].abs().max(1e-300));
                if self.curved {
                    // At most 1e-3 / px per step (a sagitta of 0.5 px over 32 px).
                    scale = scale.min(1e-3 / delta[2].abs().max(1e-300));
                }
                let l = self.line_params();
                for k in 0..self.segments.len() {
                    scale = scale.min(0.5 / delta[l + 2 + PS * k].abs().max(1e-300));
                }
                if scale < 1.0 {
                    delta *= scale;
                }
                // Decrease of the cost the linear model predicts: 2 g.delta - delta' H delta.
                let predicted = 2.0 * g.dot(&delta) - (&h * &delta).dot(&delta);
                if predicted.abs() <= rel_tol * cost {
                    break 'outer;
                }
                let relative = predicted / cost;
                let finish = finish_by_prediction
                    && scale == 1.0
                    && last_predicted.is_some_and(|p| p > relative && relative * (relative / p) <= 0.1 * rel_tol);
                let trial = &x0 + &delta;
                let backup = self.clone_params();
                self.set_params(&trial);
                if finish {
                    let c_new = self.cost();
                    if c_new.is_finite() && c_new <= cost {
                        cost = c_new;
                        break 'outer;
                    }
                    self.restore_params(&backup);
                    lambda *= 4.0;
                    continue;
                }
                let (c_new, (h_new, g_new)) = self.evaluate();
                if c_new.is_finite() && c_new <= cost {
                    small_step = delta[1].abs() < 1e-7 * step_scale
                        && delta[0].abs() < 1e-9 * step_scale
                        && (cost - c_new) <= rel_tol * cost;
                    cost = c_new;
                    (h, g) = (h_new, g_new);
                    last_predicted = Some(relative);
                    lambda = (lambda / 3.0).max(1e-9);
                    improved = true;
                    break;
                }
                self.restore_params(&backup);
                lambda *= 4.0;
            }
            if !improved || small_step {
                break;
            }
        }
        if !cost.is_finite() {
            return None;
        }
        let inv = h.cholesky()?.inverse();
        let h_inv_line = Matrix2::new(inv[(0, 0)], inv[(0, 1)], inv[(1, 0)], inv[(1, 1)]);
        if !(h_inv_line[(0, 0)] > 0.0 && h_inv_line[(1, 1)] > 0.0) {
            return None;
        }
        Some(LineFit { chi2: cost, n, p: np, h_inv_line })
    }

    /// The weighted fit from the unweighted one (or any nearby start): one Gauss-Newton step
    /// on the weighted normal equations, kept when it lowers the cost (one more pass over the
    /// pixels, without derivatives); the covariance comes from the normal matrix at the start
    /// of the step. The weights move the optimum by a fraction of the parameters' standard
    /// deviation, where the model is linear to far better than that, so the step lands on the
    /// weighted optimum to second order (a few 1e-4 px). A step that the trust region would
    /// cut, or that does not lower the cost, falls back to [`Self::solve_to`] with [`TIGHT`].
    pub fn solve_from_near(&mut self, max_iterations: usize) -> Option<LineFit> {
        let n: usize = self.segments.iter().map(|s| s.samples.len()).sum();
        let np = self.n_params();
        if n <= np + 2 {
            return None;
        }
        let (cost, (h, g)) = self.evaluate();
        let Some(ch) = h.cholesky() else { return self.solve_to(max_iterations, TIGHT) };
        let delta = ch.solve(&g);
        let l = self.line_params();
        let mut big = delta[0].abs() > 0.05 || delta[1].abs() > 1.0 || (self.curved && delta[2].abs() > 1e-3);
        for k in 0..self.segments.len() {
            big |= delta[l + 2 + PS * k].abs() > 0.5;
        }
        if !cost.is_finite() || big {
            return self.solve_to(max_iterations, TIGHT);
        }
        let x0 = self.params();
        self.set_params(&(&x0 + &delta));
        let c_new = self.cost();
        if !(c_new.is_finite() && c_new <= cost) {
            self.set_params(&x0);
            return self.solve_to(max_iterations, TIGHT);
        }
        let inv = ch.inverse();
        let h_inv_line = Matrix2::new(inv[(0, 0)], inv[(0, 1)], inv[(1, 0)], inv[(1, 1)]);
        if !(h_inv_line[(0, 0)] > 0.0 && h_inv_line[(1, 1)] > 0.0) {
            return None;
        }
        Some(LineFit { chi2: c_new, n, p: np, h_inv_line })
    }

    /// The weighted cost alone (one pass over the pixels, no derivatives); compiled for AVX2
    /// and FMA where the CPU has them, as [`Self::segment_sums`].
    fn cost(&self) -> f64 {
        #[cfg(target_arch = "x86_64")]
        if avx2_fma() {
            // SAFETY: the CPU has the features the function is compiled for (checked above).
            return unsafe { self.cost_avx2() };
        }
        self.cost_with::<false>()
    }

    /// [`Self::cost_with`] compiled for AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn cost_avx2(&self) -> f64 {
        self.cost_with::<true>()
    }

    /// [`Self::cost`]; with `FMA`, fused multiply-adds (only inside a function compiled for
    /// FMA).
    #[inline(always)]
    fn cost_with<const FMA: bool>(&self) -> f64 {
        let table = NormalTable::get();
        let cs = (self.phi.cos(), self.phi.sin());
        let mut cost = 0.0;
        for seg in &self.segments {
            let inv_sig = 1.0 / seg.ln_s.exp();
            for p in &seg.samples {
                let (u, _) = self.u_t(cs, p.x, p.y);
                let cdf = table.cdf_pdf_with::<FMA>(u * inv_sig).0;
                let r = p.v - madd::<FMA>(seg.b, cdf, seg.a) * madd::<FMA>(seg.g, u, 1.0);
                cost = madd::<FMA>(p.w * r, r, cost);
            }
        }
        cost
    }

    fn clone_params(&self) -> DVector<f64> {
        self.params()
    }

    fn restore_params(&mut self, x: &DVector<f64>) {
        self.set_params(x);
    }

    /// Unweighted residual statistics for the noise model at the current parameters: sums over
    /// pixels of `1, m, m^2, r^2, m r^2` (model value `m`, residual `r`), scaled by
    /// `n / (n - p)` for a fit with `n` pixels and `p` parameters.
    pub fn noise_sums(&self, n: usize, np: usize) -> [f64; 5] {
        let table = NormalTable::get();
        let cs = (self.phi.cos(), self.phi.sin());
        let corr = n as f64 / (n - np) as f64;
        let mut out = [0.0; 5];
        for seg in &self.segments {
            let sig = seg.ln_s.exp();
            for p in &seg.samples {
                let (u, _) = self.u_t(cs, p.x, p.y);
                let m = (seg.a + seg.b * table.cdf(u / sig)) * (1.0 + seg.g * u);
                let r2 = (p.v - m).powi(2) * corr;
                out[0] += 1.0;
                out[1] += m;
                out[2] += m * m;
                out[3] += r2;
                out[4] += m * r2;
            }
        }
        out
    }

    /// Unit normal.
    pub fn normal(&self) -> Vector2<f64> {
        Vector2::new(self.phi.cos(), self.phi.sin())
    }

    /// Unit tangent (the normal turned by +90 degrees).
    pub fn tangent(&self) -> Vector2<f64> {
        Vector2::new(-self.phi.sin(), self.phi.cos())
    }
}

impl Segment {
    /// Mean position of the segment's pixels (relative to the line's origin).
    pub fn centre(&self) -> Vector2<f64> {
        let n = self.samples.len().max(1) as f64;
        self.samples.iter().fold(Vector2::zeros(), |a, p| a + Vector2::new(p.x, p.y)) / n
    }

    /// The light level of the segment (the brighter side).
    pub fn light_level(&self) -> f64 {
        self.a.max(self.a + self.b)
    }
}

#[cfg(test)]
mod tests;
