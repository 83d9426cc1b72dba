//! The light across the board: a smooth illumination field fitted to the segments' levels, and the noise model (variance against level) of the segments' residuals.

use super::*;

/// A smooth illumination field: `ln L(x, y)` as a polynomial (quadratic with at least 12
/// segments, linear with at least 4) fitted to the light levels of the segments.
pub(super) struct IlluminationField {
    centre: Vector2<f64>,
    scale: f64,
    coef: Vec<f64>,
}

impl IlluminationField {
    fn terms(&self, p: Vector2<f64>) -> (Vec<f64>, Vec<Vector2<f64>>) {
        let x = (p.x - self.centre.x) / self.scale;
        let y = (p.y - self.centre.y) / self.scale;
        let k = 1.0 / self.scale;
        let all = [
            (1.0, Vector2::zeros()),
            (x, Vector2::new(k, 0.0)),
            (y, Vector2::new(0.0, k)),
            (x * x, Vector2::new(2.0 * x * k, 0.0)),
            (x * y, Vector2::new(y * k, x * k)),
            (y * y, Vector2::new(0.0, 2.0 * y * k)),
        ];
        let n = self.coef.len();
        (all[..n].iter().map(|t| t.0).collect(), all[..n].iter().map(|t| t.1).collect())
    }

    pub(super) fn fit(lines: &[Option<FittedLine>], min_contrast: f64) -> Option<Self> {
        let mut pts: Vec<(Vector2<f64>, f64)> = Vec::new();
        for l in lines.iter().flatten() {
            for seg in &l.state.segments {
                let level = seg.light_level();
                if seg.b.abs() >= min_contrast && level > 1.0 {
                    pts.push((l.origin + seg.centre(), level.ln()));
                }
            }
        }
        let nterms = if pts.len() >= 12 {
            6
        } else if pts.len() >= 4 {
            3
        } else {
            return None;
        };
        let centre = pts.iter().fold(Vector2::zeros(), |a, p| a + p.0) / pts.len() as f64;
        let scale = pts.iter().map(|p| (p.0 - centre).norm()).fold(0.0, f64::max).max(1.0);
        let mut field = Self { centre, scale, coef: vec![0.0; nterms] };
        let mut ata = nalgebra::DMatrix::<f64>::zeros(nterms, nterms);
        let mut atb = nalgebra::DVector::<f64>::zeros(nterms);
        for (p, v) in &pts {
            let (t, _) = field.terms(*p);
            for i in 0..nterms {
                atb[i] += t[i] * v;
                for j in 0..nterms {
                    ata[(i, j)] += t[i] * t[j];
                }
            }
        }
        let sol = ata.cholesky()?.solve(&atb);
        field.coef = sol.iter().copied().collect();
        Some(field)
    }

    /// Gradient of `ln L` at `p`.
    pub(super) fn gradient(&self, p: Vector2<f64>) -> Vector2<f64> {
        let (_, d) = self.terms(p);
        d.iter().zip(&self.coef).fold(Vector2::zeros(), |a, (di, c)| a + di * *c)
    }
}

/// Least squares `r^2 = offset + slope m` from pooled sums `(1, m, m^2, r^2, m r^2)`.
pub(in crate::subpix) fn estimate_noise(s: &[f64; 5]) -> Option<NoiseModel> {
    if s[0] < 10.0 {
        return None;
    }
    let det = s[0] * s[2] - s[1] * s[1];
    let (mut offset, mut slope) = if det > 1e-9 * s[0] * s[2] {
        ((s[2] * s[3] - s[1] * s[4]) / det, (s[0] * s[4] - s[1] * s[3]) / det)
    } else {
        (s[3] / s[0], 0.0)
    };
    if slope < 0.0 {
        slope = 0.0;
        offset = s[3] / s[0];
    }
    // The variance at the darkest level must stay positive.
    let min_var = 0.02;
    if offset < min_var {
        offset = min_var;
    }
    Some(NoiseModel { offset_dn2: offset, slope_dn: slope })
}
