//! Sub-pixel dot centres from edge points.
//!
//! *Edge points.* From the blob's centroid, `N` rays (about one per 1.5 px of perimeter, at
//! least 16) cross the blob's moment ellipse. Along each the image is sampled bilinearly every
//! 0.25 px over `rho +- w` (`rho` the moment ellipse's radius in that direction,
//! `w = max(2, 0.6 rho)` px, shortened outwards at the image border down to `rho + 2`), and the edge point is where the profile crosses the level half-way
//! between the dot (the mean inside half the moment ellipse) and the ground (the ray's outer
//! quarter), interpolated linearly; of several crossings the one nearest `rho`. For a blurred
//! disc the half-way contour of a symmetric point-spread function lies a little inside the
//! true edge, by the same amount all round, so the centre is unaffected to first order.
//!
//! *Ellipse.* The ellipse `(x - c)^T M (x - c) = 1` (`c` and the symmetric `M`, five
//! parameters) is fitted by Gauss-Newton to the radial distances `r_i = |d_i| (1 - Q_i^-1/2)`,
//! `d_i = x_i - c`, `Q_i = d_i^T M d_i` (the distance from the point to the ellipse along the
//! ray from the centre), started from the moment ellipse; points beyond 3 robust standard
//! deviations are dropped once and the fit repeated. The centre's covariance is the 2 x 2 block
//! of `s^2 (J^T J)^-1`, `s^2 = sum r_i^2 / (n - 5)`.

use nalgebra::{Matrix2, Matrix5, Point2, Vector2, Vector5};

use super::blobs::Blob;
use crate::detect::image::GrayF32;

/// A fitted ellipse.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EllipseFit {
    /// Centre, pixels.
    pub centre_px: Point2<f64>,
    /// The shape matrix `M` of `(x - c)^T M (x - c) = 1`, px^-2.
    pub shape: Matrix2<f64>,
    /// Covariance of the centre, px^2.
    pub centre_cov_px2: Matrix2<f64>,
    /// RMS of the radial residuals, pixels.
    pub rms_px: f64,
    /// Points used.
    pub n_points: usize,
}

impl EllipseFit {
    /// Semi-axes `(a, b)`, `a >= b`, pixels.
    pub fn semi_axes_px(&self) -> (f64, f64) {
        let e = self.shape.symmetric_eigenvalues();
        let (l1, l2) = (e[0].max(e[1]), e[0].min(e[1]));
        (1.0 / l2.max(1e-12).sqrt(), 1.0 / l1.max(1e-12).sqrt())
    }
}

/// A dot: its fitted ellipse and the blob it came from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DotFit {
    /// Centre, pixels.
    pub centre_px: Point2<f64>,
    /// Covariance of the centre, px^2.
    pub centre_cov_px2: Matrix2<f64>,
    /// The ellipse.
    pub ellipse: EllipseFit,
    /// Mean radius `sqrt(a b)`, pixels.
    pub radius_px: f64,
}

/// Residuals and Jacobian rows of the radial distances for parameters `(cx, cy, m11, m12, m22)`.
fn residuals(points: &[Vector2<f64>], p: &Vector5<f64>) -> Option<(Vec<f64>, Vec<Vector5<f64>>)> {
    let c = Vector2::new(p[0], p[1]);
    let m = Matrix2::new(p[2], p[3], p[3], p[4]);
    let mut r = Vec::with_capacity(points.len());
    let mut j = Vec::with_capacity(points.len());
    for x in points {
        let d = x - c;
        let len = d.norm();
        let q = d.dot(&(m * d));
        if !(len > 1e-9 && q > 1e-12) {
            return None;
        }
        let qm12 = q.powf(-0.5);
        let qm32 = qm12 / q;
        r.push(len * (1.0 - qm12));
        let dc = -(d / len) * (1.0 - qm12) - (m * d) * (len * qm32);
        let h = 0.5 * len * qm32;
        j.push(Vector5::new(dc.x, dc.y, h * d.x * d.x, 2.0 * h * d.x * d.y, h * d.y * d.y));
    }
    Some((r, j))
}

/// Fits an ellipse to points on (or near) it, started from centre `c0` and shape `m0`.
pub fn fit_ellipse_points(points: &[Vector2<f64>], c0: Vector2<f64>, m0: Matrix2<f64>) -> Option<EllipseFit> {
    let mut pts: Vec<Vector2<f64>> = points.to_vec();
    let mut p = Vector5::new(c0.x, c0.y, m0[(0, 0)], m0[(0, 1)], m0[(1, 1)]);
    for pass in 0..2 {
        if pts.len() < 8 {
            return None;
        }
        let mut lambda = 1e-6;
        let mut cost = residuals(&pts, &p)?.0.iter().map(|v| v * v).sum::<f64>();
        for _ in 0..30 {
            let (r, j) = residuals(&pts, &p)?;
            let mut jtj = Matrix5::zeros();
            let mut jtr = Vector5::zeros();
            for (ri, ji) in r.iter().zip(&j) {
                jtj += ji * ji.transpose();
                jtr += ji * *ri;
            }
            let mut accepted = false;
            for _ in 0..8 {
                let mut a = jtj;
                for k in 0..5 {
                    a[(k, k)] *= 1.0 + lambda;
                }
                let Some(step) = a.cholesky().map(|ch| ch.solve(&(-jtr))) else {
                    lambda *= 10.0;
                    continue;
                };
                let np = p + step;
                let m = Matrix2::new(np[2], np[3], np[3], np[4]);
                if m.determinant() <= 0.0 || m[(0, 0)] <= 0.0 {
                    lambda *= 10.0;
                    continue;
                }
                if let Some((rn, _)) = residuals(&pts, &np) {
                    let c = rn.iter().map(|v| v * v).sum::<f64>();
                    if c <= cost {
                        let done = step.norm() < 1e-10 * (1.0 + p.norm()) || cost - c < 1e-14 * (1.0 + cost);
                        p = np;
                        cost = c;
                        lambda = (lambda * 0.3).max(1e-9);
                        accepted = true;
                        if done {
                            break;
                        }
                        break;
                    }
                }
                lambda *= 10.0;
            }
            if !accepted {
                break;
            }
        }
        let (r, _) = residuals(&pts, &p)?;
        if pass == 0 {
            let mut abs: Vec<f64> = r.iter().map(|v| v.abs()).collect();
            abs.sort_by(f64::total_cmp);
            let sigma = (1.4826 * abs[abs.len() / 2]).max(0.02);
            let keep: Vec<Vector2<f64>> =
                pts.iter().zip(&r).filter(|(_, ri)| ri.abs() <= 3.0 * sigma).map(|(x, _)| *x).collect();
            if keep.len() == pts.len() {
                break;
            }
            pts = keep;
        }
    }
    let (r, j) = residuals(&pts, &p)?;
    let n = pts.len();
    if n < 8 {
        return None;
    }
    let ss: f64 = r.iter().map(|v| v * v).sum();
    let s2 = ss / (n - 5) as f64;
    let mut jtj = Matrix5::zeros();
    for ji in &j {
        jtj += ji * ji.transpose();
    }
    let cov = jtj.try_inverse()? * s2;
    Some(EllipseFit {
        centre_px: Point2::new(p[0], p[1]),
        shape: Matrix2::new(p[2], p[3], p[3], p[4]),
        centre_cov_px2: Matrix2::new(cov[(0, 0)], cov[(0, 1)], cov[(1, 0)], cov[(1, 1)]),
        rms_px: (ss / n as f64).sqrt(),
        n_points: n,
    })
}

/// The sub-pixel ellipse of one blob (`dark`: a dark dot on a light ground), or `None` when
/// the edge points do not make an ellipse.
pub fn fit_dot(img: &GrayF32, blob: &Blob, dark: bool) -> Option<DotFit> {
    let (a, b, theta) = blob.ellipse();
    if b < 1.0 {
        return None;
    }
    let c0 = Vector2::new(blob.centroid_px.x, blob.centroid_px.y);
    let (e1, e2) = (Vector2::new(theta.cos(), theta.sin()), Vector2::new(-theta.sin(), theta.cos()));
    let m0 = (e1 * e1.transpose()) / (a * a) + (e2 * e2.transpose()) / (b * b);
    let (w_img, h_img) = (img.width as f64 - 1.0, img.height as f64 - 1.0);
    let inside = |p: Vector2<f64>| p.x >= 0.0 && p.y >= 0.0 && p.x <= w_img && p.y <= h_img;
    // The dot's level: mean over half the moment ellipse.
    let (mut sum, mut cnt) = (0.0, 0usize);
    let rr = a.ceil() as i64;
    for dy in -rr..=rr {
        for dx in -rr..=rr {
            let p = Vector2::new(c0.x.round() + dx as f64, c0.y.round() + dy as f64);
            let d = p - c0;
            if inside(p) && d.dot(&(m0 * d)) <= 0.25 {
                sum += f64::from(img.get(p.x as usize, p.y as usize));
                cnt += 1;
            }
        }
    }
    let level_in = if cnt > 0 { sum / cnt as f64 } else { img.bilinear(c0.x, c0.y) };
    let perimeter = std::f64::consts::PI * (a + b);
    let n_rays = ((perimeter / 1.5).round() as usize).clamp(16, 360);
    let mut points = Vec::with_capacity(n_rays);
    for k in 0..n_rays {
        let ang = 2.0 * std::f64::consts::PI * k as f64 / n_rays as f64;
        let u = Vector2::new(ang.cos(), ang.sin());
        let rho = 1.0 / u.dot(&(m0 * u)).sqrt();
        let w = (0.6 * rho).max(2.0);
        let t0 = (rho - w).max(0.0);
        // Near the image border the ray stops at the border (it must still pass the edge).
        let mut t1 = rho + w;
        while t1 > rho + 2.0 && !inside(c0 + u * t1) {
            t1 -= 0.25;
        }
        let steps = ((t1 - t0) / 0.25).round() as usize;
        if steps < 4 || !inside(c0 + u * t1) {
            continue;
        }
        let prof: Vec<f64> = (0..=steps)
            .map(|s| t0 + (t1 - t0) * s as f64 / steps as f64)
            .map(|t| img.bilinear(c0.x + u.x * t, c0.y + u.y * t))
            .collect();
        let outer = &prof[(3 * steps) / 4..];
        let level_out = outer.iter().sum::<f64>() / outer.len() as f64;
        let contrast = if dark { level_out - level_in } else { level_in - level_out };
        if contrast < 4.0 {
            continue;
        }
        let level = 0.5 * (level_in + level_out);
        let mut best: Option<f64> = None;
        for s in 0..steps {
            let (v0, v1) = (prof[s] - level, prof[s + 1] - level);
            let crosses = if dark { v0 < 0.0 && v1 >= 0.0 } else { v0 > 0.0 && v1 <= 0.0 };
            if crosses {
                let f = v0 / (v0 - v1);
                let t = t0 + (t1 - t0) * (s as f64 + f) / steps as f64;
                if best.is_none_or(|bt| (t - rho).abs() < (bt - rho).abs()) {
                    best = Some(t);
                }
            }
        }
        if let Some(t) = best {
            points.push(c0 + u * t);
        }
    }
    if points.len() < (n_rays * 3) / 4 {
        return None;
    }
    let fit = fit_ellipse_points(&points, c0, m0)?;
    let (fa, fb) = fit.semi_axes_px();
    // The edge points must describe the blob: centre within half the short axis, similar size.
    let moved = (Vector2::new(fit.centre_px.x, fit.centre_px.y) - c0).norm();
    if moved > 0.5 * b || !(0.5..=2.0).contains(&(fa * fb / (a * b))) || fit.rms_px > 0.25 * fb.max(1.0) {
        return None;
    }
    Some(DotFit {
        centre_px: fit.centre_px,
        centre_cov_px2: fit.centre_cov_px2,
        ellipse: fit,
        radius_px: (fa * fb).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_on_an_ellipse_give_it_back() {
        let (c, a, b, th) = (Vector2::new(10.3, -4.2), 7.0, 3.5, 0.4f64);
        let (e1, e2) = (Vector2::new(th.cos(), th.sin()), Vector2::new(-th.sin(), th.cos()));
        let pts: Vec<Vector2<f64>> = (0..40)
            .map(|k| {
                let t = k as f64 * 0.157 + 0.05 * (k % 3) as f64;
                c + e1 * (a * t.cos()) + e2 * (b * t.sin())
            })
            .collect();
        let fit = fit_ellipse_points(&pts, c + Vector2::new(0.8, -0.5), Matrix2::identity() / 25.0).unwrap();
        assert!((fit.centre_px.coords - c).norm() < 1e-8, "{fit:?}");
        let (fa, fb) = fit.semi_axes_px();
        assert!((fa - a).abs() < 1e-8 && (fb - b).abs() < 1e-8);
        assert!(fit.rms_px < 1e-8);
    }
}
