//! One straight edge line, possibly carrying several segments of either polarity, fitted to the
//! pixels of a band around it with the blurred-step model (Levenberg-Marquardt).

use nalgebra::{DMatrix, DVector, Matrix2, Vector2};

#[cfg(test)]
use super::erf::normal_cdf;
use super::erf::NormalTable;
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

/// Parameters per segment.
const PS: usize = 3;

/// A line `n . x = d`, `n = (cos phi, sin phi)`, `x` relative to the origin, with its segments.
#[derive(Clone, Debug)]
pub(crate) struct LineState {
    pub phi: f64,
    pub d: f64,
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
    fn n_params(&self) -> usize {
        2 + PS * self.segments.len()
    }

    fn params(&self) -> DVector<f64> {
        let mut x = DVector::zeros(self.n_params());
        x[0] = self.phi;
        x[1] = self.d;
        for (k, s) in self.segments.iter().enumerate() {
            x[2 + PS * k] = s.a;
            x[3 + PS * k] = s.b;
            x[4 + PS * k] = s.ln_s;
        }
        x
    }

    fn set_params(&mut self, x: &DVector<f64>) {
        self.phi = x[0];
        self.d = x[1];
        for (k, s) in self.segments.iter_mut().enumerate() {
            s.a = x[2 + PS * k];
            s.b = x[3 + PS * k];
            s.ln_s = x[4 + PS * k].clamp(LN_BLUR_MIN, LN_BLUR_MAX);
        }
    }

    /// Weighted cost, normal matrix and gradient (one pass over the pixels).
    fn evaluate(&self) -> (f64, NormalEquations) {
        let np = self.n_params();
        let table = NormalTable::get();
        let mut h = DMatrix::<f64>::zeros(np, np);
        let mut g = DVector::<f64>::zeros(np);
        let (c, s) = (self.phi.cos(), self.phi.sin());
        let mut cost = 0.0;
        for (k, seg) in self.segments.iter().enumerate() {
            let sig = seg.ln_s.exp();
            let inv_sig = 1.0 / sig;
            let (sa, sb, sg, d) = (seg.a, seg.b, seg.g, self.d);
            // Per-segment accumulation of the upper triangle of the 5x5 normal matrix and the
            // gradient over (phi, d, a, b, ln_s), written out (folded into h afterwards).
            let mut hs = [0.0f64; 15];
            let mut gs = [0.0f64; 5];
            for p in &seg.samples {
                let u = c * p.x + s * p.y - d;
                let z = u * inv_sig;
                let (cdf, pdf) = table.cdf_pdf(z);
                let q = 1.0 + sg * u;
                let base = sa + sb * cdf;
                let r = p.v - base * q;
                cost += p.w * r * r;
                let t = -s * p.x + c * p.y;
                let gu = sb * pdf * inv_sig * q + base * sg;
                let j = [gu * t, -gu, q, cdf * q, -sb * pdf * z * q];
                let wa = [p.w * j[0], p.w * j[1], p.w * j[2], p.w * j[3], p.w * j[4]];
                gs[0] += wa[0] * r;
                gs[1] += wa[1] * r;
                gs[2] += wa[2] * r;
                gs[3] += wa[3] * r;
                gs[4] += wa[4] * r;
                hs[0] += wa[0] * j[0];
                hs[1] += wa[0] * j[1];
                hs[2] += wa[0] * j[2];
                hs[3] += wa[0] * j[3];
                hs[4] += wa[0] * j[4];
                hs[5] += wa[1] * j[1];
                hs[6] += wa[1] * j[2];
                hs[7] += wa[1] * j[3];
                hs[8] += wa[1] * j[4];
                hs[9] += wa[2] * j[2];
                hs[10] += wa[2] * j[3];
                hs[11] += wa[2] * j[4];
                hs[12] += wa[3] * j[3];
                hs[13] += wa[3] * j[4];
                hs[14] += wa[4] * j[4];
            }
            let idx = [0, 1, 2 + PS * k, 3 + PS * k, 4 + PS * k];
            let mut m = 0;
            for a in 0..5 {
                g[idx[a]] += gs[a];
                for b in a..5 {
                    h[(idx[a], idx[b])] += hs[m];
                    if a != b {
                        h[(idx[b], idx[a])] += hs[m];
                    }
                    m += 1;
                }
            }
        }
        (cost, (h, g))
    }

    /// Least-squares intensities `a`, `b` of every segment for the current line and blur.
    pub fn init_intensities(&mut self) {
        let table = NormalTable::get();
        let (c, s) = (self.phi.cos(), self.phi.sin());
        let d = self.d;
        for seg in &mut self.segments {
            let sig = seg.ln_s.exp();
            let (mut s00, mut s01, mut s11, mut t0, mut t1) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for p in &seg.samples {
                let u = c * p.x + s * p.y - d;
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
        let (c, s) = (self.phi.cos(), self.phi.sin());
        let d = self.d;
        for seg in &mut self.segments {
            let sig = seg.ln_s.exp();
            for p in &mut seg.samples {
                p.w = match noise {
                    Some(nm) => {
                        let u = c * p.x + s * p.y - d;
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
    /// for the next step is below 1e-12 of the cost (a step of about 1e-7 px: rounding would
    /// decide whether it is taken), or when no damping gives a decrease.
    pub fn solve(&mut self, max_iterations: usize) -> Option<LineFit> {
        let n: usize = self.segments.iter().map(|s| s.samples.len()).sum();
        let np = self.n_params();
        if n <= np + 2 {
            return None;
        }
        let mut lambda = 1e-3;
        let (mut cost, (mut h, mut g)) = self.evaluate();
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
                for k in 0..self.segments.len() {
                    scale = scale.min(0.5 / delta[4 + PS * k].abs().max(1e-300));
                }
                if scale < 1.0 {
                    delta *= scale;
                }
                // Decrease of the cost the linear model predicts: 2 g.delta - delta' H delta.
                let predicted = 2.0 * g.dot(&delta) - (&h * &delta).dot(&delta);
                if predicted.abs() <= 1e-12 * cost {
                    break 'outer;
                }
                let trial = &x0 + &delta;
                let backup = self.clone_params();
                self.set_params(&trial);
                let (c_new, (h_new, g_new)) = self.evaluate();
                if c_new.is_finite() && c_new <= cost {
                    small_step = delta[1].abs() < 1e-7 && delta[0].abs() < 1e-9 && (cost - c_new) <= 1e-12 * cost;
                    cost = c_new;
                    (h, g) = (h_new, g_new);
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
        let (c, s) = (self.phi.cos(), self.phi.sin());
        let corr = n as f64 / (n - np) as f64;
        let mut out = [0.0; 5];
        for seg in &self.segments {
            let sig = seg.ln_s.exp();
            for p in &seg.samples {
                let u = c * p.x + s * p.y - self.d;
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
mod tests {
    use super::*;

    /// A noiseless synthetic band: the fit recovers the line, the blur and the intensities.
    #[test]
    fn recovers_a_synthetic_edge() {
        let (phi, d, sig, a, b) = (0.3f64, 0.37, 1.3, 40.0, 150.0);
        let mut samples = Vec::new();
        for i in -20..=20 {
            for j in -20..=20 {
                let (x, y) = (i as f64, j as f64);
                let u = phi.cos() * x + phi.sin() * y - d;
                if u.abs() < 5.0 {
                    samples.push(Sample { x, y, v: a + b * normal_cdf(u / sig), w: 1.0 });
                }
            }
        }
        let mut line =
            LineState { phi: 0.25, d: 0.0, segments: vec![Segment { a: 0.0, b: 0.0, ln_s: 0.0, g: 0.0, samples }] };
        line.init_intensities();
        let fit = line.solve(50).unwrap();
        assert!((line.phi - phi).abs() < 1e-7, "{}", line.phi);
        assert!((line.d - d).abs() < 1e-6, "{}", line.d);
        assert!((line.segments[0].ln_s.exp() - sig).abs() < 1e-5);
        assert!((line.segments[0].b - b).abs() < 1e-4);
        assert!(fit.chi2 < 1e-8);
    }
}
