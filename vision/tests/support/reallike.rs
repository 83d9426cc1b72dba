//! Renders made to look like real shop photographs of large chessboards, with exact truth: an
//! image-degradation stage on top of the procedural renderer of `synth.rs` (which must be a
//! module named `synth` at the crate root).
//!
//! What a real photograph has and a clean render lacks, in the order it happens:
//! 1. *Background clutter*: outside the board's margin, a texture of random rotated
//!    rectangles, small checker patches and stripes (corner-like texture, coloured).
//! 2. *Light*: uneven illumination (a linear ramp plus a broad bump), vignetting
//!    (`1 - v r^2`), a warm light colour, and *glare* (a broad veiling highlight on part of
//!    the board, lowering the contrast there without hiding any corner).
//! 3. *Defocus that varies across the board*: a Gaussian PSF whose width changes linearly
//!    across the frame (from `blur_min_px` to `blur_max_px`), made by blending three blurred
//!    copies per pixel.
//! 4. *Colour sensor*: an RGGB Bayer mosaic with shot and read noise, 8 bits, gamma, then
//!    bilinear demosaicing (with its zipper artefacts at the edges).
//! 5. *File*: PNG or JPEG (quality 88); the detectors read the file's BT.601 grey level.
//!
//! The board's area is rendered exactly by `synth::render_linear` (area-sampled edges), so
//! the inner corners' truth is `synth::chessboard_truth`. Every symmetric PSF and the
//! bilinear demosaicing keep the corners in place; gamma, glare and the varying blur bend the
//! edge profiles slightly, as they do in real photographs.
#![allow(dead_code)]

use image::{GrayImage, RgbImage};
use nalgebra::{Matrix3, Point2, Vector3};

use crate::synth::{self, Layout, Scene};

/// The file format of a rendered view.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Lossless PNG.
    Png,
    /// JPEG, quality 88.
    Jpeg,
}

/// One view of the set: the geometry and what degrades it.
#[derive(Clone, Debug)]
pub struct View {
    /// Short name (also the file stem).
    pub name: String,
    /// The procedural scene (board geometry, levels); its blur and noise are not used.
    pub scene: Scene,
    /// Inner corners (`cols`, `rows`).
    pub cols: usize,
    pub rows: usize,
    /// PSF width at the left and right edge of the frame, pixels.
    pub blur_min_px: f64,
    pub blur_max_px: f64,
    /// Vignetting: relative loss at the frame corners.
    pub vignetting: f64,
    /// Glare: centre (fraction of the frame), radius (fraction of the width), strength (DN).
    pub glare: (f64, f64, f64, f64),
    /// File format.
    pub format: Format,
    /// Tilt of the board against the image plane, degrees (for the record).
    pub tilt_deg: f64,
}

/// Statistics of a view: squares' size range, board coverage of the frame.
#[derive(Clone, Copy, Debug)]
pub struct ViewStats {
    pub min_square_px: f64,
    pub max_square_px: f64,
    /// Fraction of the frame inside the board's squares.
    pub coverage: f64,
}

/// The benchmark set: 2.3 to 5 MP, boards of 418 to 570 inner corners, squares 25-60 px,
/// tilts up to 60 degrees, PNG and JPEG.
pub fn views() -> Vec<View> {
    // (name, width, height, cols, rows, square_px at the centre, roll, tilt_x, tilt_y,
    //  shift (fraction of the distance), blur range, glare (cx, cy, r, DN), format)
    type Row = (
        &'static str,
        u32,
        u32,
        usize,
        usize,
        f64,
        f64,
        f64,
        f64,
        (f64, f64),
        (f64, f64),
        (f64, f64, f64, f64),
        Format,
    );
    let rows: [Row; 8] = [
        (
            "r00_1928x1208_28x17_png",
            1928,
            1208,
            28,
            17,
            46.0,
            2.0,
            6.0,
            -14.0,
            (0.01, 0.02),
            (0.8, 1.6),
            (0.35, 0.4, 0.12, 45.0),
            Format::Png,
        ),
        (
            "r01_1928x1208_28x17_jpg",
            1928,
            1208,
            28,
            17,
            46.0,
            -4.0,
            -22.0,
            28.0,
            (-0.02, 0.0),
            (1.0, 2.2),
            (0.6, 0.55, 0.10, 60.0),
            Format::Jpeg,
        ),
        (
            "r02_2448x2048_24x18_png",
            2448,
            2048,
            24,
            18,
            56.0,
            8.0,
            12.0,
            44.0,
            (0.03, -0.02),
            (0.9, 2.4),
            (0.45, 0.35, 0.14, 50.0),
            Format::Png,
        ),
        (
            "r03_2448x2048_30x19_jpg",
            2448,
            2048,
            30,
            19,
            54.0,
            24.0,
            -10.0,
            -20.0,
            (0.0, 0.02),
            (0.7, 1.8),
            (0.55, 0.6, 0.12, 55.0),
            Format::Jpeg,
        ),
        (
            "r04_2592x1944_28x17_png",
            2592,
            1944,
            28,
            17,
            58.0,
            -3.0,
            8.0,
            58.0,
            (0.06, 0.0),
            (0.8, 2.0),
            (0.3, 0.5, 0.10, 40.0),
            Format::Png,
        ),
        (
            "r05_1928x1208_25x17_jpg",
            1928,
            1208,
            25,
            17,
            46.0,
            1.0,
            40.0,
            4.0,
            (0.0, 0.0),
            (0.9, 1.7),
            (0.5, 0.3, 0.10, 50.0),
            Format::Jpeg,
        ),
        (
            "r06_2048x1536_26x20_png",
            2048,
            1536,
            26,
            20,
            50.0,
            -12.0,
            -35.0,
            -30.0,
            (-0.03, 0.02),
            (1.0, 2.4),
            (0.65, 0.45, 0.12, 55.0),
            Format::Png,
        ),
        (
            "r07_2592x1944_22x19_jpg",
            2592,
            1944,
            22,
            19,
            58.0,
            6.0,
            15.0,
            -8.0,
            (0.0, 0.01),
            (0.8, 1.5),
            (0.4, 0.6, 0.15, 45.0),
            Format::Jpeg,
        ),
    ];
    rows.iter()
        .map(|&(name, w, h, cols, rows, square_px, roll, tx, ty, shift, blur, glare, format)| {
            let f = 1.1 * w as f64;
            let square_m = 0.02;
            let dist = f * square_m / square_px;
            let hm = synth::homography(
                f,
                0.5 * w as f64 - 0.5,
                0.5 * h as f64 - 0.5,
                (rows + 1, cols + 1),
                square_m,
                dist,
                roll,
                tx,
                ty,
                (shift.0 * dist, shift.1 * dist),
            );
            let scene = Scene {
                width: w,
                height: h,
                h: hm,
                layout: Layout::Chessboard { cols, rows, margin: 0.7 },
                dark_dn: 28.0,
                light_dn: 175.0,
                background_dn: 0.0,
                blur_px: 0.0,
                noise_dn: 0.0,
                seed: name.bytes().fold(17u64, |a, b| a.wrapping_mul(31).wrapping_add(u64::from(b))),
                lens: None,
            };
            let tilt = (tx * tx + ty * ty).sqrt();
            View {
                name: name.to_string(),
                scene,
                cols,
                rows,
                blur_min_px: blur.0,
                blur_max_px: blur.1,
                vignetting: 0.35,
                glare,
                format,
                tilt_deg: tilt,
            }
        })
        .collect()
}

impl View {
    /// The inner corners' exact positions, row by row from the top-left as rendered.
    pub fn truth(&self) -> Vec<Point2<f64>> {
        synth::chessboard_truth(&self.scene)
    }

    /// Pattern string for the detectors.
    pub fn pattern(&self) -> String {
        format!("chessboard:{}x{}:20mm", self.cols, self.rows)
    }

    /// Square sizes and coverage (from the truth and the board's outline).
    pub fn stats(&self) -> ViewStats {
        let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
        let p = |i: usize, j: usize| synth::grid_point(&self.scene, i, j);
        for i in 0..=self.rows + 1 {
            for j in 0..=self.cols {
                let d = (p(i, j + 1) - p(i, j)).norm();
                lo = lo.min(d);
                hi = hi.max(d);
            }
        }
        let c = [p(0, 0), p(0, self.cols + 1), p(self.rows + 1, self.cols + 1), p(self.rows + 1, 0)];
        let mut area = 0.0;
        for k in 0..4 {
            let (a, b) = (c[k], c[(k + 1) % 4]);
            area += a.x * b.y - a.y * b.x;
        }
        let coverage = 0.5 * area.abs() / (self.scene.width as f64 * self.scene.height as f64);
        ViewStats { min_square_px: lo, max_square_px: hi, coverage }
    }
}

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn uniform(&mut self) -> f64 {
        ((self.next() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.uniform()
    }
    fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

/// One clutter shape: a rotated rectangle, optionally filled with a checker or stripes.
struct Shape {
    centre: (f64, f64),
    half: (f64, f64),
    cos_sin: (f64, f64),
    rgb: [f64; 3],
    /// 0 plain, 1 checker of this cell, 2 stripes.
    kind: u8,
    cell_px: f64,
}

impl Shape {
    fn value(&self, x: f64, y: f64) -> Option<[f64; 3]> {
        let (dx, dy) = (x - self.centre.0, y - self.centre.1);
        let (c, s) = self.cos_sin;
        let (u, v) = (c * dx + s * dy, -s * dx + c * dy);
        if u.abs() > self.half.0 || v.abs() > self.half.1 {
            return None;
        }
        let dark = match self.kind {
            1 => ((u / self.cell_px).floor() as i64 + (v / self.cell_px).floor() as i64).rem_euclid(2) == 0,
            2 => (u / self.cell_px).floor() as i64 % 2 == 0,
            _ => false,
        };
        Some(if dark { self.rgb.map(|k| 0.25 * k) } else { self.rgb })
    }
}

/// Whether pixel `(x, y)` sees the board (its squares or its light margin).
fn on_board(hinv: &Matrix3<f64>, scene: &Scene, x: f64, y: f64) -> bool {
    let v = hinv * Vector3::new(x, y, 1.0);
    if v.z <= 0.0 {
        return false;
    }
    let (bx, by) = (v.x / v.z, v.y / v.z);
    let Layout::Chessboard { cols, rows, margin } = scene.layout else { return false };
    bx >= -margin && by >= -margin && bx <= (cols + 1) as f64 + margin && by <= (rows + 1) as f64 + margin
}

fn blur_plane(img: &[f64], w: usize, h: usize, sigma: f64) -> Vec<f64> {
    let r = (3.0 * sigma).ceil() as isize;
    let k: Vec<f64> = (-r..=r).map(|x| (-(x * x) as f64 / (2.0 * sigma * sigma)).exp()).collect();
    let sum: f64 = k.iter().sum();
    let k: Vec<f64> = k.iter().map(|v| v / sum).collect();
    let mut tmp = vec![0.0; w * h];
    for y in 0..h {
        let row = &img[y * w..(y + 1) * w];
        for x in 0..w {
            let mut s = 0.0;
            for (o, kv) in k.iter().enumerate() {
                let xx = (x as isize + o as isize - r).clamp(0, w as isize - 1) as usize;
                s += kv * row[xx];
            }
            tmp[y * w + x] = s;
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for (o, kv) in k.iter().enumerate() {
            let yy = (y as isize + o as isize - r).clamp(0, h as isize - 1) as usize;
            let src = &tmp[yy * w..(yy + 1) * w];
            let dst = &mut out[y * w..(y + 1) * w];
            for (d, s) in dst.iter_mut().zip(src) {
                *d += kv * s;
            }
        }
    }
    out
}

/// Renders the view as the camera's colour image (after demosaicing, before the file).
pub fn render_rgb(view: &View) -> RgbImage {
    let scene = &view.scene;
    let (w, h) = (scene.width as usize, scene.height as usize);
    let mut rng = Rng(scene.seed);
    // 1. The board, exactly (area-sampled, no blur, no noise); background 0.
    let board = synth::render_linear(scene);
    let hinv = scene.h.try_inverse().expect("invertible homography");
    let mut shapes = Vec::new();
    let n_shapes = (w * h) / 9000;
    for _ in 0..n_shapes {
        let big = rng.uniform() < 0.15;
        let size = if big { rng.range(80.0, 300.0) } else { rng.range(6.0, 60.0) };
        let base = rng.range(20.0, 230.0);
        let tint = [rng.range(0.6, 1.3), rng.range(0.6, 1.3), rng.range(0.6, 1.3)];
        let kind = match rng.next() % 5 {
            0 => 1,
            1 => 2,
            _ => 0,
        };
        let a = rng.range(0.0, std::f64::consts::PI);
        shapes.push(Shape {
            centre: (rng.range(0.0, w as f64), rng.range(0.0, h as f64)),
            half: (size, size * rng.range(0.3, 1.0)),
            cos_sin: (a.cos(), a.sin()),
            rgb: tint.map(|t| (base * t).min(250.0)),
            kind,
            cell_px: rng.range(4.0, 20.0),
        });
    }
    // Grid buckets of shapes for speed.
    let cell = 64usize;
    let (gw, gh) = (w.div_ceil(cell), h.div_ceil(cell));
    let mut buckets: Vec<Vec<usize>> = vec![Vec::new(); gw * gh];
    for (k, s) in shapes.iter().enumerate() {
        let r = s.half.0.max(s.half.1) * std::f64::consts::SQRT_2;
        let x0 = ((s.centre.0 - r).max(0.0) as usize / cell).min(gw - 1);
        let x1 = ((s.centre.0 + r).max(0.0) as usize / cell).min(gw - 1);
        let y0 = ((s.centre.1 - r).max(0.0) as usize / cell).min(gh - 1);
        let y1 = ((s.centre.1 + r).max(0.0) as usize / cell).min(gh - 1);
        for gy in y0..=y1 {
            for gx in x0..=x1 {
                buckets[gy * gw + gx].push(k);
            }
        }
    }
    // 2. Scene radiance per channel: board (neutral) or clutter (coloured, 2 x 2 supersampled).
    let mut planes = [vec![0.0f64; w * h], vec![0.0f64; w * h], vec![0.0f64; w * h]];
    let floor_rgb = [70.0, 66.0, 60.0];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if on_board(&hinv, scene, x as f64, y as f64) {
                for p in planes.iter_mut() {
                    p[i] = board[i];
                }
                continue;
            }
            let b = &buckets[(y / cell) * gw + x / cell];
            let mut acc = [0.0; 3];
            for (sx, sy) in [(-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)] {
                let (px, py) = (x as f64 + sx, y as f64 + sy);
                let mut v = floor_rgb;
                for &k in b.iter().rev() {
                    if let Some(c) = shapes[k].value(px, py) {
                        v = c;
                        break;
                    }
                }
                for c in 0..3 {
                    acc[c] += 0.25 * v[c];
                }
            }
            for c in 0..3 {
                planes[c][i] = acc[c];
            }
        }
    }
    // 3. Light: warm colour, ramp + bump, vignetting, glare.
    let light = [1.0, 0.93, 0.78];
    let (cx, cy) = (0.5 * w as f64, 0.5 * h as f64);
    let rmax2 = cx * cx + cy * cy;
    let ramp = (rng.range(-0.25, 0.25), rng.range(-0.2, 0.2));
    let bump = (rng.range(0.2, 0.8) * w as f64, rng.range(0.2, 0.8) * h as f64, 0.5 * w as f64);
    let (gx, gy, gr, gdn) = view.glare;
    let (gx, gy, gr) = (gx * w as f64, gy * h as f64, gr * w as f64);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let (fx, fy) = (x as f64, y as f64);
            let r2 = ((fx - cx).powi(2) + (fy - cy).powi(2)) / rmax2;
            let mut l = 1.0 - view.vignetting * r2;
            l *= 1.0 + ramp.0 * (fx - cx) / cx + ramp.1 * (fy - cy) / cy;
            l *= 1.0 + 0.2 * (-((fx - bump.0).powi(2) + (fy - bump.1).powi(2)) / (2.0 * bump.2 * bump.2)).exp();
            let glare = gdn * (-((fx - gx).powi(2) + (fy - gy).powi(2)) / (2.0 * gr * gr)).exp();
            for c in 0..3 {
                planes[c][i] = planes[c][i] * l * light[c] + glare;
            }
        }
    }
    // 4. Defocus varying across the frame: three blurred copies blended per pixel.
    let sig = [view.blur_min_px, 0.5 * (view.blur_min_px + view.blur_max_px), view.blur_max_px];
    for plane in planes.iter_mut() {
        let b: Vec<Vec<f64>> = sig.iter().map(|&s| blur_plane(plane, w, h, s)).collect();
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                // Blur grows along a diagonal of the frame.
                let t = (0.7 * x as f64 / w as f64 + 0.3 * y as f64 / h as f64).clamp(0.0, 1.0) * 2.0;
                let (k, f) = if t < 1.0 { (0, t) } else { (1, t - 1.0) };
                plane[i] = b[k][i] * (1.0 - f) + b[k + 1][i] * f;
            }
        }
    }
    // 5. Bayer RGGB, noise (shot + read, electrons at gain 0.25 DN/e), gamma, 8 bits.
    let gain = 0.25;
    let read_e = 6.0;
    let mut raw = vec![0.0f64; w * h];
    for y in 0..h {
        for x in 0..w {
            let c = match (y % 2, x % 2) {
                (0, 0) => 0,
                (1, 1) => 2,
                _ => 1,
            };
            let lin = planes[c][y * w + x].max(0.0);
            let e = lin / gain;
            let noisy = (e + (e + read_e * read_e).sqrt() * rng.normal()) * gain;
            // Display gamma on the 0..255 scale (a mild 1/1.6 curve), 8 bits.
            let g = 255.0 * (noisy.max(0.0) / 255.0).powf(1.0 / 1.6);
            raw[y * w + x] = g.round().clamp(0.0, 255.0);
        }
    }
    // Bilinear demosaicing.
    let at = |x: isize, y: isize| raw[(y.clamp(0, h as isize - 1) as usize) * w + x.clamp(0, w as isize - 1) as usize];
    let mut out = RgbImage::new(w as u32, h as u32);
    for y in 0..h as isize {
        for x in 0..w as isize {
            let v = at(x, y);
            let cross = 0.25 * (at(x - 1, y) + at(x + 1, y) + at(x, y - 1) + at(x, y + 1));
            let diag = 0.25 * (at(x - 1, y - 1) + at(x + 1, y - 1) + at(x - 1, y + 1) + at(x + 1, y + 1));
            let horiz = 0.5 * (at(x - 1, y) + at(x + 1, y));
            let vert = 0.5 * (at(x, y - 1) + at(x, y + 1));
            let rgb = match (y % 2, x % 2) {
                (0, 0) => [v, cross, diag],
                (1, 1) => [diag, cross, v],
                (0, _) => [horiz, v, vert],
                _ => [vert, v, horiz],
            };
            out.put_pixel(x as u32, y as u32, image::Rgb(rgb.map(|c| c.round().clamp(0.0, 255.0) as u8)));
        }
    }
    out
}

/// Encodes the view's colour image in its file format.
pub fn encode(view: &View, rgb: &RgbImage) -> Vec<u8> {
    let mut buf = Vec::new();
    match view.format {
        Format::Png => {
            image::codecs::png::PngEncoder::new(&mut buf)
                .write_image(rgb.as_raw(), rgb.width(), rgb.height(), image::ExtendedColorType::Rgb8)
                .expect("PNG encoding");
        }
        Format::Jpeg => {
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut buf, 88).encode_image(rgb).expect("JPEG encoding");
        }
    }
    buf
}

use image::ImageEncoder;

/// The grey image the detectors see: the encoded file decoded and converted (BT.601 luma,
/// as `load_gray` does).
pub fn render_gray(view: &View) -> GrayImage {
    let bytes = encode(view, &render_rgb(view));
    let img = image::load_from_memory(&bytes).expect("decoding the rendered file");
    ferrocal_vision::detect::to_gray(&img)
}

/// File extension of the view's format.
pub fn extension(view: &View) -> &'static str {
    match view.format {
        Format::Png => "png",
        Format::Jpeg => "jpg",
    }
}
