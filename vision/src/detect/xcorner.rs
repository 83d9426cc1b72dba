//! X-corner (saddle) candidates: the points where two dark and two light fields meet.
//!
//! 1. Smooth with a Gaussian of `sigma` (kornia-rs kernel); on images above 2 MP work on a 2 x 2
//!    average first.
//! 2. Saddle response from the second derivatives, `R = Ixy^2 - Ixx Iyy` (positive at saddles,
//!    near zero on straight edges, negative on blobs). An ideal X-corner of step `b` and total
//!    blur `s` has `R = (b / (pi s^2))^2` at its centre, which sets the threshold from the least
//!    contrast wanted.
//! 3. Non-maximum suppression in a 7 x 7 window, sub-pixel saddle position from the local
//!    quadratic.
//! 4. Validation on circles of two radii around each candidate: the smoothed intensity must
//!    cross its mid level exactly four times, the crossings must pair into two straight lines
//!    (opposite rays within 23 degrees of each other), the second angular harmonic must carry at
//!    least half the energy, and opposite sectors must have the same shade. The two crossing
//!    lines give the candidate's two edge directions.

use nalgebra::Vector2;
use rayon::prelude::*;

use super::image::GrayF32;
use crate::error::Result;

/// One validated candidate.
#[derive(Clone, Copy, Debug)]
pub(crate) struct XCorner {
    /// Position (full-resolution pixels, pixel-centre convention).
    pub p: Vector2<f64>,
    /// The two edge-line directions (unit vectors, defined up to sign).
    pub dirs: [Vector2<f64>; 2],
    /// Light minus dark level on the validation circle, DN.
    pub contrast: f64,
}

/// Options of [`find_xcorners`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct XCornerOptions {
    /// Smoothing before the second derivatives, pixels of the working image.
    pub sigma_px: f64,
    /// Least step between dark and light fields, DN (raised to 8 % of the image's range).
    pub min_contrast_dn: f64,
    /// Work on a 2 x 2 average above this many pixels.
    pub downsample_above_px: usize,
    /// Keep at most this many candidates (strongest first).
    pub max_candidates: usize,
}

impl Default for XCornerOptions {
    fn default() -> Self {
        Self { sigma_px: 1.5, min_contrast_dn: 12.0, downsample_above_px: 2_000_000, max_candidates: 4000 }
    }
}

/// Robust range of an image: 2nd and 98th percentiles.
fn percentiles(img: &GrayF32) -> (f64, f64) {
    let mut hist = [0usize; 256];
    for v in &img.data {
        hist[v.clamp(0.0, 255.0) as usize] += 1;
    }
    let n = img.data.len();
    let q = |frac: f64| {
        let target = (frac * n as f64) as usize;
        let mut acc = 0;
        for (k, h) in hist.iter().enumerate() {
            acc += h;
            if acc > target {
                return k as f64;
            }
        }
        255.0
    };
    (q(0.02), q(0.98))
}

fn wrap(a: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    let mut x = a % tau;
    if x > std::f64::consts::PI {
        x -= tau;
    }
    if x < -std::f64::consts::PI {
        x += tau;
    }
    x
}

/// Samples on a validation circle.
const N: usize = 48;

/// Angle, cosine, sine, and cosine and sine of the doubled angle of the circle's samples.
struct CircleTrig {
    th: [f64; N],
    cos: [f64; N],
    sin: [f64; N],
    cos2: [f64; N],
    sin2: [f64; N],
}

impl CircleTrig {
    fn new() -> Self {
        let mut t = Self { th: [0.0; N], cos: [0.0; N], sin: [0.0; N], cos2: [0.0; N], sin2: [0.0; N] };
        for k in 0..N {
            let th = std::f64::consts::TAU * k as f64 / N as f64;
            let th2 = 2.0 * std::f64::consts::TAU * k as f64 / N as f64;
            (t.th[k], t.cos[k], t.sin[k], t.cos2[k], t.sin2[k]) = (th, th.cos(), th.sin(), th2.cos(), th2.sin());
        }
        t
    }
}

/// The circle test at radius `r`: edge-line angles and contrast, or `None`.
fn circle_test(sm: &GrayF32, trig: &CircleTrig, p: Vector2<f64>, r: f64, min_contrast: f64) -> Option<([f64; 2], f64)> {
    let mut v = [0.0f64; N];
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for (k, val) in v.iter_mut().enumerate() {
        *val = sm.bilinear(p.x + r * trig.cos[k], p.y + r * trig.sin[k]);
        lo = lo.min(*val);
        hi = hi.max(*val);
    }
    if hi - lo < 0.5 * min_contrast {
        return None;
    }
    let mid = 0.5 * (lo + hi);
    // Crossings of the mid level.
    let mut cross = Vec::with_capacity(8);
    for k in 0..N {
        let (a, b) = (v[k] - mid, v[(k + 1) % N] - mid);
        if (a > 0.0) != (b > 0.0) {
            let f = a / (a - b);
            cross.push(std::f64::consts::TAU * (k as f64 + f) / N as f64);
        }
        if cross.len() > 4 {
            return None;
        }
    }
    if cross.len() != 4 {
        return None;
    }
    // Opposite rays.
    let tol = 0.4;
    if wrap(cross[2] - cross[0] - std::f64::consts::PI).abs() > tol
        || wrap(cross[3] - cross[1] - std::f64::consts::PI).abs() > tol
    {
        return None;
    }
    // Second harmonic energy.
    let mean = v.iter().sum::<f64>() / N as f64;
    let (mut re, mut im, mut e) = (0.0, 0.0, 0.0);
    for (k, val) in v.iter().enumerate() {
        let d = val - mean;
        re += d * trig.cos2[k];
        im += d * trig.sin2[k];
        e += d * d;
    }
    if e <= 0.0 || 2.0 * (re * re + im * im) / (N as f64 * e) < 0.5 {
        return None;
    }
    // Sector shades: opposite sectors alike, neighbours different.
    let sector_mean = |a: f64, b: f64| {
        let (mut s, mut n) = (0.0, 0.0);
        for (k, val) in v.iter().enumerate() {
            let rel = (trig.th[k] - a).rem_euclid(std::f64::consts::TAU);
            let span = (b - a).rem_euclid(std::f64::consts::TAU);
            if rel > 0.15 * span && rel < 0.85 * span {
                s += val;
                n += 1.0;
            }
        }
        if n > 0.0 {
            s / n
        } else {
            mid
        }
    };
    let m: Vec<f64> = (0..4).map(|k| sector_mean(cross[k], cross[(k + 1) % 4])).collect();
    let contrast = ((m[0] + m[2]) - (m[1] + m[3])).abs() * 0.5;
    if contrast < 0.5 * min_contrast || (m[0] - m[2]).abs() > 0.35 * contrast || (m[1] - m[3]).abs() > 0.35 * contrast {
        return None;
    }
    // Line angles (mod pi) by the doubled-angle mean.
    let line = |a: f64, b: f64| {
        let (s, c) = ((2.0 * a).sin() + (2.0 * b).sin(), (2.0 * a).cos() + (2.0 * b).cos());
        0.5 * s.atan2(c)
    };
    let l1 = line(cross[0], cross[2]);
    let l2 = line(cross[1], cross[3]);
    if wrap(2.0 * (l1 - l2)).abs() < 2.0 * 0.35 {
        return None;
    }
    Some(([l1, l2], contrast))
}

/// Finds and validates X-corner candidates. `keep(x, y)` (full-resolution pixels) may restrict
/// them to a region (e.g. the foreground of a background-subtracted image).
///
/// The response and the search for maxima run on bands of rows in parallel; the candidates
/// come out in the same order as from a single thread.
pub(crate) fn find_xcorners(
    img: &GrayF32,
    options: &XCornerOptions,
    keep: Option<&(dyn Fn(f64, f64) -> bool + Sync)>,
) -> Result<Vec<XCorner>> {
    let half;
    let (work, factor) = if img.width * img.height > options.downsample_above_px {
        half = img.downsample2();
        (&half, 2.0)
    } else {
        (img, 1.0)
    };
    let (w, h) = (work.width, work.height);
    let sigma = options.sigma_px;
    let sm = work.gaussian(sigma)?;
    let (p_lo, p_hi) = percentiles(work);
    let min_contrast = options.min_contrast_dn.max(0.08 * (p_hi - p_lo));
    let st2 = sigma * sigma + 1.0;
    let tau = (0.4 * min_contrast / (std::f64::consts::PI * st2)).powi(2);
    let margin = (4.0 * sigma).ceil() as usize + 8;
    if w <= 2 * margin + 2 || h <= 2 * margin + 2 {
        return Ok(Vec::new());
    }
    let at = |x: usize, y: usize| f64::from(sm.data[y * w + x]);
    let mut resp = vec![0.0f32; w * h];
    resp.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        if y < margin - 2 || y >= h - margin + 2 {
            return;
        }
        for (x, out) in row.iter_mut().enumerate().take(w - margin + 2).skip(margin - 2) {
            let c = at(x, y);
            let ixx = at(x + 1, y) - 2.0 * c + at(x - 1, y);
            let iyy = at(x, y + 1) - 2.0 * c + at(x, y - 1);
            let ixy = 0.25 * (at(x + 1, y + 1) - at(x + 1, y - 1) - at(x - 1, y + 1) + at(x - 1, y - 1));
            *out = (ixy * ixy - ixx * iyy) as f32;
        }
    });
    let trig = CircleTrig::new();
    let rad = 3isize;
    // Non-maximum suppression, nearest neighbours first (most pixels fail there).
    let mut offsets: Vec<(isize, isize)> =
        (-rad..=rad).flat_map(|dy| (-rad..=rad).map(move |dx| (dx, dy))).filter(|&o| o != (0, 0)).collect();
    offsets.sort_by_key(|&(dx, dy)| dx.abs().max(dy.abs()));
    let rows: Vec<Vec<XCorner>> = (margin..h - margin)
        .into_par_iter()
        .map(|y| {
            let mut found = Vec::new();
            'px: for x in margin..w - margin {
                let r0 = resp[y * w + x];
                if f64::from(r0) < tau {
                    continue;
                }
                for &(dx, dy) in &offsets {
                    let v = resp[(y as isize + dy) as usize * w + (x as isize + dx) as usize];
                    // Ties broken towards the first in raster order.
                    if v > r0 || (v == r0 && (dy < 0 || (dy == 0 && dx < 0))) {
                        continue 'px;
                    }
                }
                // Sub-pixel saddle of the quadratic model.
                let c = at(x, y);
                let gx = 0.5 * (at(x + 1, y) - at(x - 1, y));
                let gy = 0.5 * (at(x, y + 1) - at(x, y - 1));
                let ixx = at(x + 1, y) - 2.0 * c + at(x - 1, y);
                let iyy = at(x, y + 1) - 2.0 * c + at(x, y - 1);
                let ixy = 0.25 * (at(x + 1, y + 1) - at(x + 1, y - 1) - at(x - 1, y + 1) + at(x - 1, y - 1));
                let det = ixx * iyy - ixy * ixy;
                let mut p = Vector2::new(x as f64, y as f64);
                if det.abs() > 1e-12 {
                    let dx = -(iyy * gx - ixy * gy) / det;
                    let dy = -(-ixy * gx + ixx * gy) / det;
                    if dx.abs() <= 1.0 && dy.abs() <= 1.0 {
                        p += Vector2::new(dx, dy);
                    }
                }
                let full = p * factor + Vector2::repeat(0.5 * (factor - 1.0));
                if let Some(k) = keep {
                    if !k(full.x, full.y) {
                        continue;
                    }
                }
                let mut best = None;
                for r in [3.5, 5.5] {
                    if let Some(t) = circle_test(&sm, &trig, p, r, min_contrast) {
                        best = Some(t);
                    }
                }
                if let Some((angles, contrast)) = best {
                    let dirs = angles.map(|a| Vector2::new(a.cos(), a.sin()));
                    found.push(XCorner { p: full, dirs, contrast });
                }
            }
            found
        })
        .collect();
    let mut out: Vec<XCorner> = rows.into_iter().flatten().collect();
    out.sort_by(|a, b| b.contrast.total_cmp(&a.contrast));
    out.truncate(options.max_candidates);
    Ok(out)
}
