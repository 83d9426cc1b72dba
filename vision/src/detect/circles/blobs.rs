//! Dot candidates: pixels darker (or lighter) than the mean of a box window around them by
//! more than a threshold, grouped into 8-connected components; a component is a candidate
//! when its area is in range and it fills the ellipse
//! of its own second moments (area within 25 % of `pi a b`, `a, b` twice the square roots of
//! the moments' eigenvalues, axis ratio at least 0.15).

use nalgebra::{Matrix2, Point2};

use super::CircleOptions;
use crate::detect::image::GrayF32;

/// A connected component that looks like a filled ellipse.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Blob {
    /// Pixels in the component.
    pub area_px: f64,
    /// Centroid, pixels.
    pub centroid_px: Point2<f64>,
    /// Second central moments (covariance of the pixel positions), px^2.
    pub moments_px2: Matrix2<f64>,
}

impl Blob {
    /// Semi-axes `(a, b)` (a >= b) and the direction angle of `a`, of the ellipse with these
    /// moments (a filled ellipse has moments `a^2 / 4`, `b^2 / 4` along its axes).
    pub fn ellipse(&self) -> (f64, f64, f64) {
        let m = self.moments_px2;
        let tr = m[(0, 0)] + m[(1, 1)];
        let det = m[(0, 0)] * m[(1, 1)] - m[(0, 1)] * m[(1, 0)];
        let disc = (0.25 * tr * tr - det).max(0.0).sqrt();
        let (l1, l2) = (0.5 * tr + disc, (0.5 * tr - disc).max(0.0));
        let theta = 0.5 * (2.0 * m[(0, 1)]).atan2(m[(0, 0)] - m[(1, 1)]);
        (2.0 * l1.sqrt(), 2.0 * l2.sqrt(), theta)
    }
}

/// Integral image of the values, `(w + 1) x (h + 1)`.
fn integral(img: &GrayF32) -> Vec<f64> {
    let (w, h) = (img.width, img.height);
    let mut s = vec![0.0f64; (w + 1) * (h + 1)];
    for y in 0..h {
        let mut row = 0.0;
        for x in 0..w {
            row += f64::from(img.get(x, y));
            s[(y + 1) * (w + 1) + x + 1] = s[y * (w + 1) + x + 1] + row;
        }
    }
    s
}

/// The candidate dots of one polarity (`dark`: dark dots on a light ground).
pub fn find_blobs(img: &GrayF32, dark: bool, options: &CircleOptions) -> Vec<Blob> {
    let (w, h) = (img.width, img.height);
    let sum = integral(img);
    let half = ((options.window_fraction * w.min(h) as f64) as usize / 2).max(4);
    let mut mask = vec![false; w * h];
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(half), (y + half + 1).min(h));
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(half), (x + half + 1).min(w));
            let n = ((x1 - x0) * (y1 - y0)) as f64;
            let s = sum[y1 * (w + 1) + x1] - sum[y0 * (w + 1) + x1] - sum[y1 * (w + 1) + x0] + sum[y0 * (w + 1) + x0];
            let d = f64::from(img.get(x, y)) - s / n;
            mask[y * w + x] = if dark { d < -options.threshold_dn } else { d > options.threshold_dn };
        }
    }
    let max_area = options.max_area_fraction * (w * h) as f64;
    let mut seen = vec![false; w * h];
    let mut out = Vec::new();
    let mut stack = Vec::new();
    for start in 0..w * h {
        if !mask[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let (mut n, mut sx, mut sy, mut sxx, mut sxy, mut syy) = (0.0f64, 0.0, 0.0, 0.0, 0.0, 0.0);
        while let Some(k) = stack.pop() {
            let (x, y) = (k % w, k / w);
            let (xf, yf) = (x as f64, y as f64);
            n += 1.0;
            sx += xf;
            sy += yf;
            sxx += xf * xf;
            sxy += xf * yf;
            syy += yf * yf;
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                    if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                        continue;
                    }
                    let q = ny as usize * w + nx as usize;
                    if mask[q] && !seen[q] {
                        seen[q] = true;
                        stack.push(q);
                    }
                }
            }
        }
        if n < options.min_area_px || n > max_area {
            continue;
        }
        let (mx, my) = (sx / n, sy / n);
        // Moments of the pixel squares (each pixel adds 1/12 of its own extent).
        let m = Matrix2::new(
            sxx / n - mx * mx + 1.0 / 12.0,
            sxy / n - mx * my,
            sxy / n - mx * my,
            syy / n - my * my + 1.0 / 12.0,
        );
        let blob = Blob { area_px: n, centroid_px: Point2::new(mx, my), moments_px2: m };
        let (a, b, _) = blob.ellipse();
        let fill = n / (std::f64::consts::PI * a * b).max(1e-9);
        if (0.75..=1.25).contains(&fill) && b >= 0.15 * a {
            out.push(blob);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_drawn_disc_is_one_blob_with_its_centre_and_size() {
        let (w, h) = (200usize, 150usize);
        let (cx, cy, r) = (30.3, 27.8, 6.0);
        let mut data = vec![200.0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                // 4 x 4 supersampled coverage.
                let mut cov = 0.0;
                for sy in 0..4 {
                    for sx in 0..4 {
                        let (px, py) = (x as f64 - 0.375 + 0.25 * sx as f64, y as f64 - 0.375 + 0.25 * sy as f64);
                        if (px - cx).hypot(py - cy) <= r {
                            cov += 1.0 / 16.0;
                        }
                    }
                }
                data[y * w + x] = (200.0 - 160.0 * cov) as f32;
            }
        }
        let img = GrayF32::from_vec(w, h, data).unwrap();
        let blobs = find_blobs(&img, true, &CircleOptions::default());
        assert_eq!(blobs.len(), 1);
        let b = blobs[0];
        assert!((b.centroid_px.x - cx).abs() < 0.2 && (b.centroid_px.y - cy).abs() < 0.2, "{b:?}");
        let (a, bb, _) = b.ellipse();
        assert!((a - r).abs() < 1.0 && (bb - r).abs() < 1.0, "{a} {bb}");
        assert!(find_blobs(&img, false, &CircleOptions::default()).is_empty());
    }
}
