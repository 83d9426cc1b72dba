//! Exact-area rasterisation of polygons seen through a lens model.
//!
//! A polygon's coverage of pixel `(i, j)` (the unit square centred on `(i, j)`) is computed in
//! closed form from its boundary: every directed boundary segment adds, row by row, the signed
//! area between itself and the row's right end (Green's theorem); a running sum along each row
//! turns these into the covered area of every pixel. The result is exact for polygons with
//! straight sides, costs time proportional to the number of pixels the boundary crosses plus one
//! addition per pixel, and handles any number of weighted polygons in one pass.
//!
//! Target edges are straight in space; through a distorting lens they become curves. Each edge
//! is clipped in the normalised image plane to a region where the lens is one-to-one, then
//! projected through the exact lens model and subdivided recursively until the projected
//! midpoint of every piece lies within `tolerance_px` of the chord (and pieces are at most
//! [`MAX_PIECE_PX`] long); the area error per unit edge length is then below the tolerance.

use nalgebra::{Isometry3, Point2, Point3};

use ferrocal_vision::camera::{CameraModel, Distortion};

use crate::error::{DatasetError, Result};

/// Longest projected piece of a curved edge, pixels.
pub(crate) const MAX_PIECE_PX: f64 = 4.0;
/// Recursion limit of the edge subdivision.
const MAX_DEPTH: u32 = 24;
/// Vertices of the convex clip polygon in the normalised plane.
const CLIP_VERTICES: usize = 64;
/// Near plane (metres) against which polygons are clipped before the perspective division.
const Z_NEAR_M: f64 = 1e-6;

/// Signed-area accumulator for one image.
pub(crate) struct Coverage {
    width: usize,
    height: usize,
    stride: usize,
    acc: Vec<f64>,
}

impl Coverage {
    /// An empty accumulator for a `width x height` image.
    pub(crate) fn new(width: usize, height: usize) -> Self {
        let stride = width + 2;
        Self { width, height, stride, acc: vec![0.0; stride * height] }
    }

    /// Adds a directed boundary segment between two pixel positions (pixel-centre convention)
    /// with a weight. A closed polygon traversed with the image-plane signed area
    /// `sum(u_i v_{i+1} - u_{i+1} v_i) / 2 < 0` (counter-clockwise as seen on screen) adds
    /// `weight * covered area` to every pixel.
    pub(crate) fn add_segment(&mut self, p0: [f64; 2], p1: [f64; 2], weight: f64) {
        // Shift so that pixel (i, j) covers [i, i+1] x [j, j+1].
        let (x0, y0, x1, y1) = (p0[0] + 0.5, p0[1] + 0.5, p1[0] + 0.5, p1[1] + 0.5);
        if y0 == y1 || !(x0.is_finite() && y0.is_finite() && x1.is_finite() && y1.is_finite()) {
            return;
        }
        let (dir, xa, ya, xb, yb) = if y0 < y1 { (weight, x0, y0, x1, y1) } else { (-weight, x1, y1, x0, y0) };
        let h = self.height as f64;
        if yb <= 0.0 || ya >= h {
            return;
        }
        let dxdy = (xb - xa) / (yb - ya);
        let ys = ya.max(0.0);
        let ye = yb.min(h);
        let first = ys.floor() as usize;
        let last = (ye.ceil() as usize).min(self.height);
        for row in first..last {
            let r0 = ys.max(row as f64);
            let r1 = ye.min(row as f64 + 1.0);
            if r1 <= r0 {
                continue;
            }
            let xs = xa + (r0 - ya) * dxdy;
            let xe = xa + (r1 - ya) * dxdy;
            self.add_row_piece(row, xs, xe, dir * (r1 - r0));
        }
    }

    /// Distributes a piece of boundary inside one pixel row (vertical extent `dy`, signed and
    /// weighted) over the columns it crosses.
    fn add_row_piece(&mut self, row: usize, xs: f64, xe: f64, dy: f64) {
        let base = row * self.stride;
        let w = self.width as f64;
        let (xl, xr) = if xs <= xe { (xs, xe) } else { (xe, xs) };
        let span = xr - xl;
        if span <= 1e-12 {
            // (Nearly) vertical: one cell.
            let x = xl;
            if x >= w {
                return;
            }
            if x <= 0.0 {
                self.acc[base] += dy;
                return;
            }
            let c = x.floor();
            let ci = c as usize;
            self.acc[base + ci] += dy * (c + 1.0 - x);
            self.acc[base + ci + 1] += dy * (x - c);
            return;
        }
        // Part left of the image: acts as a boundary at x = 0.
        if xl < 0.0 {
            let f = ((0.0f64).min(xr) - xl) / span;
            self.acc[base] += dy * f;
        }
        let ml = xl.max(0.0);
        let mr = xr.min(w);
        if mr <= ml {
            return;
        }
        let mut c = ml.floor();
        while c < mr {
            let cl = ml.max(c);
            let cr = mr.min(c + 1.0);
            if cr > cl {
                let d = dy * (cr - cl) / span;
                let xm = 0.5 * (cl + cr);
                let ci = c as usize;
                self.acc[base + ci] += d * (c + 1.0 - xm);
                self.acc[base + ci + 1] += d * (xm - c);
            }
            c += 1.0;
        }
    }

    /// Running sums along each row: `out[j * width + i] = base + sum of weighted coverages`.
    pub(crate) fn resolve(&self, base: f64, out: &mut [f32]) {
        for (row, dst) in self.acc.chunks_exact(self.stride).zip(out.chunks_exact_mut(self.width)) {
            let mut s = base;
            for (a, o) in row[..self.width].iter().zip(dst.iter_mut()) {
                s += a;
                *o = s as f32;
            }
        }
    }
}

/// Projects target polygons through a lens model into a [`Coverage`].
pub(crate) struct LensRaster {
    camera: CameraModel,
    /// Convex clip polygon in the normalised plane, vertices at increasing angle.
    clip: Vec<[f64; 2]>,
    tolerance_px: f64,
    pinhole: bool,
}

fn cross(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

fn lerp2(a: [f64; 2], b: [f64; 2], t: f64) -> [f64; 2] {
    [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
}

impl LensRaster {
    /// Prepares the clip region of `camera`: a 64-gon in the normalised plane that contains the
    /// preimage of the whole image and lies inside the field over which the lens model is
    /// one-to-one. Fails when no such region exists (the model folds inside the image, or the
    /// image reaches 90 degrees from the optical axis).
    pub(crate) fn new(camera: &CameraModel, tolerance_px: f64) -> Result<Self> {
        let w = camera.image_size.width_px as f64;
        let h = camera.image_size.height_px as f64;
        let mut border = Vec::new();
        let step = 4.0;
        let nu = (w / step).ceil() as usize;
        let nv = (h / step).ceil() as usize;
        for k in 0..=nu {
            let u = (-0.5 + k as f64 * step).min(w - 0.5);
            border.push(Point2::new(u, -0.5));
            border.push(Point2::new(u, h - 0.5));
        }
        for k in 0..=nv {
            let v = (-0.5 + k as f64 * step).min(h - 0.5);
            border.push(Point2::new(-0.5, v));
            border.push(Point2::new(w - 0.5, v));
        }
        let mut r_img: f64 = 0.0;
        for px in &border {
            let n = camera.unproject_normalized(px).map_err(|e| {
                DatasetError::Render(format!(
                    "the lens model cannot be inverted at image pixel ({:.1}, {:.1}): {e}; the renderer needs a \
                     model that is one-to-one over the whole image within 90 degrees of the axis",
                    px.x, px.y
                ))
            })?;
            r_img = r_img.max(n.coords.norm());
        }
        let r_img = r_img * 1.01 + 1e-9;
        let theta_max = camera.max_field_angle_rad().min(89.9f64.to_radians());
        let r_valid = theta_max.tan() * 0.999;
        let r_clip = r_valid.min(2.0 * r_img);
        let inscribed = r_clip * (std::f64::consts::PI / CLIP_VERTICES as f64).cos();
        if inscribed <= r_img {
            return Err(DatasetError::Render(format!(
                "the lens model is one-to-one only up to {:.2} deg from the axis, but the image reaches {:.2} deg",
                theta_max.to_degrees(),
                r_img.atan().to_degrees()
            )));
        }
        let clip = (0..CLIP_VERTICES)
            .map(|k| {
                let a = 2.0 * std::f64::consts::PI * k as f64 / CLIP_VERTICES as f64;
                [r_clip * a.cos(), r_clip * a.sin()]
            })
            .collect();
        Ok(Self { camera: *camera, clip, tolerance_px, pinhole: matches!(camera.distortion, Distortion::None) })
    }

    fn project(&self, n: [f64; 2]) -> Result<[f64; 2]> {
        let p = self.camera.project_normalized(&Point2::new(n[0], n[1]))?;
        Ok([p.x, p.y])
    }

    /// Adds `weight * coverage` of a polygon given in the target plane (z = 0, metres).
    pub(crate) fn add_polygon(
        &self,
        cov: &mut Coverage,
        t_cam_target: &Isometry3<f64>,
        polygon_m: &[Point2<f64>],
        weight: f64,
    ) -> Result<()> {
        // 1. Camera frame, clipped against the near plane.
        let pts: Vec<Point3<f64>> =
            polygon_m.iter().map(|p| t_cam_target.transform_point(&Point3::new(p.x, p.y, 0.0))).collect();
        let mut clipped: Vec<Point3<f64>> = Vec::with_capacity(pts.len() + 4);
        for i in 0..pts.len() {
            let a = pts[i];
            let b = pts[(i + 1) % pts.len()];
            let a_in = a.z >= Z_NEAR_M;
            let b_in = b.z >= Z_NEAR_M;
            if a_in {
                clipped.push(a);
            }
            if a_in != b_in {
                let t = (Z_NEAR_M - a.z) / (b.z - a.z);
                clipped.push(a + (b - a) * t);
            }
        }
        if clipped.len() < 3 {
            return Ok(());
        }
        // 2. Normalised plane, clipped against the lens's one-to-one region.
        let mut poly: Vec<[f64; 2]> = clipped.iter().map(|p| [p.x / p.z, p.y / p.z]).collect();
        for k in 0..self.clip.len() {
            let a = self.clip[k];
            let b = self.clip[(k + 1) % self.clip.len()];
            let input = std::mem::take(&mut poly);
            for i in 0..input.len() {
                let p = input[i];
                let q = input[(i + 1) % input.len()];
                let dp = cross(a, b, p);
                let dq = cross(a, b, q);
                if dp >= 0.0 {
                    poly.push(p);
                }
                if (dp >= 0.0) != (dq >= 0.0) {
                    poly.push(lerp2(p, q, dp / (dp - dq)));
                }
            }
            if poly.len() < 3 {
                return Ok(());
            }
        }
        // 3. Orientation: normalised and pixel coordinates have the same handedness
        // (fx, fy > 0). The accumulator adds positive coverage for negative signed area.
        let area2: f64 = (0..poly.len())
            .map(|i| {
                let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
                p[0] * q[1] - q[0] * p[1]
            })
            .sum();
        let weight = if area2 > 0.0 { -weight } else { weight };
        // 4. Edges through the lens.
        let projected: Vec<[f64; 2]> = poly.iter().map(|n| self.project(*n)).collect::<Result<_>>()?;
        for i in 0..poly.len() {
            let j = (i + 1) % poly.len();
            self.trace(cov, poly[i], poly[j], projected[i], projected[j], 0, weight)?;
        }
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    fn trace(
        &self,
        cov: &mut Coverage,
        a: [f64; 2],
        b: [f64; 2],
        pa: [f64; 2],
        pb: [f64; 2],
        depth: u32,
        weight: f64,
    ) -> Result<()> {
        if self.pinhole {
            cov.add_segment(pa, pb, weight);
            return Ok(());
        }
        let m = lerp2(a, b, 0.5);
        let pm = self.project(m)?;
        let chord = lerp2(pa, pb, 0.5);
        let dev = (pm[0] - chord[0]).hypot(pm[1] - chord[1]);
        let len = (pb[0] - pa[0]).hypot(pb[1] - pa[1]);
        // Pieces wholly left of the image only contribute through their end rows, wholly
        // above, below or right of it nothing: their shape does not matter.
        let w = cov.width as f64;
        let h = cov.height as f64;
        let margin = 1.0 + 2.0 * dev;
        let (xmin, xmax) = (pa[0].min(pb[0]).min(pm[0]), pa[0].max(pb[0]).max(pm[0]));
        let (ymin, ymax) = (pa[1].min(pb[1]).min(pm[1]), pa[1].max(pb[1]).max(pm[1]));
        let outside =
            xmax < -0.5 - margin || xmin > w - 0.5 + margin || ymax < -0.5 - margin || ymin > h - 0.5 + margin;
        if outside && xmax < -0.5 - margin {
            cov.add_segment(pa, pb, weight);
            return Ok(());
        }
        if outside {
            return Ok(());
        }
        if depth >= MAX_DEPTH || (dev <= self.tolerance_px && len <= MAX_PIECE_PX) {
            cov.add_segment(pa, pm, weight);
            cov.add_segment(pm, pb, weight);
            return Ok(());
        }
        self.trace(cov, a, m, pa, pm, depth + 1, weight)?;
        self.trace(cov, m, b, pm, pb, depth + 1, weight)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shoelace(p: &[[f64; 2]]) -> f64 {
        (0..p.len())
            .map(|i| {
                let (a, b) = (p[i], p[(i + 1) % p.len()]);
                a[0] * b[1] - b[0] * a[1]
            })
            .sum::<f64>()
            / 2.0
    }

    fn coverage_of(poly: &[[f64; 2]], w: usize, h: usize) -> Vec<f32> {
        let mut cov = Coverage::new(w, h);
        let weight = if shoelace(poly) < 0.0 { 1.0 } else { -1.0 };
        for i in 0..poly.len() {
            cov.add_segment(poly[i], poly[(i + 1) % poly.len()], weight);
        }
        let mut out = vec![0.0; w * h];
        cov.resolve(0.0, &mut out);
        out
    }

    /// Monte-Carlo-free check: a triangle's total coverage equals its area, and each pixel's
    /// coverage matches a fine point-sampling estimate.
    #[test]
    fn coverage_is_exact_area() {
        let tri = [[1.3, 0.2], [7.9, 3.7], [2.2, 6.4]];
        let out = coverage_of(&tri, 10, 8);
        let total: f64 = out.iter().map(|v| *v as f64).sum();
        assert!((total - shoelace(&tri).abs()).abs() < 1e-5, "{total}");
        let inside = |x: f64, y: f64| {
            (0..3).all(|i| {
                let (a, b) = (tri[i], tri[(i + 1) % 3]);
                cross(a, b, [x, y]) >= 0.0
            })
        };
        let n = 200;
        for j in 0..8 {
            for i in 0..10 {
                let mut k = 0;
                for sy in 0..n {
                    for sx in 0..n {
                        let x = i as f64 - 0.5 + (sx as f64 + 0.5) / n as f64;
                        let y = j as f64 - 0.5 + (sy as f64 + 0.5) / n as f64;
                        k += usize::from(inside(x, y));
                    }
                }
                let est = k as f64 / (n * n) as f64;
                assert!((est - out[j * 10 + i] as f64).abs() < 0.01, "pixel ({i},{j}): {est} vs {}", out[j * 10 + i]);
            }
        }
    }

    #[test]
    fn polygons_beyond_the_image_edges_still_cover_correctly() {
        // A rectangle from far left of the image to its middle, and beyond top and bottom.
        let rect = [[-50.0, -9.0], [-50.0, 20.0], [3.25, 20.0], [3.25, -9.0]];
        let out = coverage_of(&rect, 8, 6);
        for j in 0..6 {
            let row = &out[j * 8..j * 8 + 8];
            assert_eq!(&row[..3], &[1.0, 1.0, 1.0]);
            assert!((row[3] - 0.75).abs() < 1e-6);
            assert!(row[4..].iter().all(|v| v.abs() < 1e-6));
        }
    }
}
