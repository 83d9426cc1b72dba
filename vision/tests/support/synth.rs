//! Procedural images with exact ground truth for the vision tests and benchmarks (the vision
//! crate cannot use the renderer of `ferrocal-datasets`, which depends on it).
//!
//! A planar pattern of square fields (board units: one field = 1) is mapped to the image by a
//! homography; each pixel is the exact-enough area average of the reflectance (16 x 16
//! sub-samples where the pixel straddles an edge), then blurred by a Gaussian PSF (borders
//! replicated), then Gaussian noise is added and the result is rounded to 8 bits.
#![allow(dead_code)]

use image::GrayImage;
use nalgebra::{Matrix3, Point2, Rotation3, Vector3};

/// What the fields are.
#[derive(Clone, Debug)]
pub enum Layout {
    /// A chessboard with `cols x rows` inner corners (`(rows+1) x (cols+1)` fields, the top-left
    /// dark) and a light margin of `margin` fields.
    Chessboard { cols: usize, rows: usize, margin: f64 },
    /// The Gantry-Tau plate: 3 x 3 fields, the five with even `row + col` dark, light margin.
    Plate { margin: f64 },
    /// Any grid of `cols x rows` cells (`true` = dark, row by row), light margin.
    Cells { cols: usize, rows: usize, dark: Vec<bool>, margin: f64 },
}

/// Scene parameters.
#[derive(Clone, Debug)]
pub struct Scene {
    pub width: u32,
    pub height: u32,
    /// Board units (fields) to pixels.
    pub h: Matrix3<f64>,
    pub layout: Layout,
    pub dark_dn: f64,
    pub light_dn: f64,
    pub background_dn: f64,
    pub blur_px: f64,
    pub noise_dn: f64,
    pub seed: u64,
    /// Radial lens distortion `(f, cx, cy, k1)`: an ideal pixel `q` is seen at
    /// `c + (q - c) (1 + k1 |(q - c) / f|^2)` (OpenCV's Brown model with only `k1`).
    pub lens: Option<(f64, f64, f64, f64)>,
}

impl Scene {
    /// Ideal (pinhole) pixel -> observed pixel.
    pub fn distort(&self, q: Point2<f64>) -> Point2<f64> {
        match self.lens {
            None => q,
            Some((f, cx, cy, k1)) => {
                let (x, y) = ((q.x - cx) / f, (q.y - cy) / f);
                let s = 1.0 + k1 * (x * x + y * y);
                Point2::new(cx + f * x * s, cy + f * y * s)
            }
        }
    }

    /// Observed pixel -> ideal pixel (fixed-point iteration).
    pub fn undistort(&self, p: Point2<f64>) -> Point2<f64> {
        match self.lens {
            None => p,
            Some((f, cx, cy, k1)) => {
                let (xd, yd) = ((p.x - cx) / f, (p.y - cy) / f);
                let (mut x, mut y) = (xd, yd);
                for _ in 0..30 {
                    let s = 1.0 + k1 * (x * x + y * y);
                    x = xd / s;
                    y = yd / s;
                }
                Point2::new(cx + f * x, cy + f * y)
            }
        }
    }
}

impl Layout {
    fn fields(&self) -> (usize, usize) {
        match self {
            Layout::Chessboard { cols, rows, .. } => (rows + 1, cols + 1),
            Layout::Plate { .. } => (3, 3),
            Layout::Cells { cols, rows, .. } => (*rows, *cols),
        }
    }
    fn margin(&self) -> f64 {
        match self {
            Layout::Chessboard { margin, .. } | Layout::Plate { margin } | Layout::Cells { margin, .. } => *margin,
        }
    }
    /// 0 background, 1 light, 2 dark at board point (x, y).
    fn class(&self, x: f64, y: f64) -> u8 {
        let (fr, fc) = self.fields();
        let m = self.margin();
        if x < -m || y < -m || x > fc as f64 + m || y > fr as f64 + m {
            return 0;
        }
        if x < 0.0 || y < 0.0 || x >= fc as f64 || y >= fr as f64 {
            return 1;
        }
        let (r, c) = (y.floor() as usize, x.floor() as usize);
        let dark = match self {
            Layout::Cells { cols, dark, .. } => dark[r * cols + c],
            _ => (r + c) % 2 == 0,
        };
        if dark {
            2
        } else {
            1
        }
    }
}

/// Homography of a board seen by a pinhole camera: board units of `square_m` metres, board
/// centre at distance `dist_m`, rotated by `roll_deg` about the optical axis and tilted by
/// `tilt_x_deg`, `tilt_y_deg`, shifted by `(shift_x_m, shift_y_m)`.
#[allow(clippy::too_many_arguments)]
pub fn homography(
    f_px: f64,
    cx: f64,
    cy: f64,
    fields: (usize, usize),
    square_m: f64,
    dist_m: f64,
    roll_deg: f64,
    tilt_x_deg: f64,
    tilt_y_deg: f64,
    shift: (f64, f64),
) -> Matrix3<f64> {
    let r = Rotation3::from_euler_angles(tilt_x_deg.to_radians(), tilt_y_deg.to_radians(), roll_deg.to_radians());
    let k = Matrix3::new(f_px, 0.0, cx, 0.0, f_px, cy, 0.0, 0.0, 1.0);
    // Board point (x, y) in fields -> metres about the centre, y down like the image.
    let (fr, fc) = fields;
    let s = Matrix3::new(
        square_m,
        0.0,
        -0.5 * fc as f64 * square_m,
        0.0,
        square_m,
        -0.5 * fr as f64 * square_m,
        0.0,
        0.0,
        1.0,
    );
    let rm = r.matrix();
    let t = Vector3::new(shift.0, shift.1, dist_m);
    let m = Matrix3::from_columns(&[rm.column(0).into_owned(), rm.column(1).into_owned(), t]);
    k * m * s
}

pub fn apply(h: &Matrix3<f64>, x: f64, y: f64) -> Point2<f64> {
    let v = h * Vector3::new(x, y, 1.0);
    Point2::new(v.x / v.z, v.y / v.z)
}

/// Grid point `(i, j)` (board point `(j, i)`) in the image.
pub fn grid_point(scene: &Scene, i: usize, j: usize) -> Point2<f64> {
    scene.distort(apply(&scene.h, j as f64, i as f64))
}

/// Chessboard inner corners row by row (exact truth).
pub fn chessboard_truth(scene: &Scene) -> Vec<Point2<f64>> {
    let Layout::Chessboard { cols, rows, .. } = scene.layout else { return Vec::new() };
    let mut out = Vec::new();
    for i in 1..=rows {
        for j in 1..=cols {
            out.push(grid_point(scene, i, j));
        }
    }
    out
}

/// Plate corners in the renderer's order: squares TL, TR, centre, BL, BR; corners TL, TR, BR,
/// BL (image-upright board).
pub fn plate_truth(scene: &Scene) -> Vec<Point2<f64>> {
    let mut out = Vec::new();
    for (r, c) in [(0usize, 0usize), (0, 2), (1, 1), (2, 0), (2, 2)] {
        for (di, dj) in [(0, 0), (0, 1), (1, 1), (1, 0)] {
            out.push(grid_point(scene, r + di, c + dj));
        }
    }
    out
}

struct SplitMix(u64);
impl SplitMix {
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
    fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

/// Renders the scene as floating-point intensities before noise.
pub fn render_linear(scene: &Scene) -> Vec<f64> {
    let (w, h) = (scene.width as usize, scene.height as usize);
    let hinv = scene.h.try_inverse().expect("invertible homography");
    let level = |c: u8| match c {
        0 => scene.background_dn,
        1 => scene.light_dn,
        _ => scene.dark_dn,
    };
    let class_at = |x: f64, y: f64| {
        let q = scene.undistort(Point2::new(x, y));
        let v = hinv * Vector3::new(q.x, q.y, 1.0);
        if v.z <= 0.0 {
            return 0;
        }
        scene.layout.class(v.x / v.z, v.y / v.z)
    };
    let mut img = vec![0.0f64; w * h];
    // Classes at pixel corners (x - 0.5, y - 0.5).
    let mut corners = vec![0u8; (w + 1) * (h + 1)];
    for j in 0..=h {
        for i in 0..=w {
            corners[j * (w + 1) + i] = class_at(i as f64 - 0.5, j as f64 - 0.5);
        }
    }
    const N: usize = 16;
    for j in 0..h {
        for i in 0..w {
            let c = [
                corners[j * (w + 1) + i],
                corners[j * (w + 1) + i + 1],
                corners[(j + 1) * (w + 1) + i],
                corners[(j + 1) * (w + 1) + i + 1],
            ];
            let centre = class_at(i as f64, j as f64);
            img[j * w + i] = if c.iter().all(|&k| k == centre) {
                level(centre)
            } else {
                let mut s = 0.0;
                for a in 0..N {
                    for b in 0..N {
                        let x = i as f64 - 0.5 + (b as f64 + 0.5) / N as f64;
                        let y = j as f64 - 0.5 + (a as f64 + 0.5) / N as f64;
                        s += level(class_at(x, y));
                    }
                }
                s / (N * N) as f64
            };
        }
    }
    if scene.blur_px > 0.0 {
        blur(&mut img, w, h, scene.blur_px);
    }
    img
}

fn blur(img: &mut [f64], w: usize, h: usize, sigma: f64) {
    let r = (4.0 * sigma).ceil() as isize;
    let k: Vec<f64> = (-r..=r).map(|x| (-(x * x) as f64 / (2.0 * sigma * sigma)).exp()).collect();
    let sum: f64 = k.iter().sum();
    let k: Vec<f64> = k.iter().map(|v| v / sum).collect();
    let mut tmp = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for (o, kv) in k.iter().enumerate() {
                let xx = (x as isize + o as isize - r).clamp(0, w as isize - 1) as usize;
                s += kv * img[y * w + xx];
            }
            tmp[y * w + x] = s;
        }
    }
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for (o, kv) in k.iter().enumerate() {
                let yy = (y as isize + o as isize - r).clamp(0, h as isize - 1) as usize;
                s += kv * tmp[yy * w + x];
            }
            img[y * w + x] = s;
        }
    }
}

/// Adds noise to a linear rendering and quantises it.
pub fn quantise(scene: &Scene, linear: &[f64]) -> GrayImage {
    let mut rng = SplitMix(scene.seed ^ 0x5EED);
    let data: Vec<u8> =
        linear.iter().map(|v| (v + scene.noise_dn * rng.normal()).round().clamp(0.0, 255.0) as u8).collect();
    GrayImage::from_raw(scene.width, scene.height, data).expect("size")
}

/// Renders the 8-bit image.
pub fn render(scene: &Scene) -> GrayImage {
    quantise(scene, &render_linear(scene))
}

#[allow(clippy::too_many_arguments)]
/// A typical chessboard scene: `cols x rows` inner corners, squares of about `square_px`
/// pixels, a moderate perspective.
pub fn chessboard_scene(
    width: u32,
    height: u32,
    cols: usize,
    rows: usize,
    square_px: f64,
    pose: u64,
    blur_px: f64,
    noise_dn: f64,
) -> Scene {
    let f = 1.2 * width as f64;
    let square_m = 0.025;
    let dist = f * square_m / square_px;
    let (roll, tx, ty) = match pose % 4 {
        0 => (3.0, 12.0, -8.0),
        1 => (-7.0, -18.0, 10.0),
        2 => (11.0, 5.0, 22.0),
        _ => (-2.0, 25.0, 4.0),
    };
    let shift = (0.03 * dist * ((pose as f64 * 1.7).sin()), 0.03 * dist * ((pose as f64 * 2.3).cos()));
    let h = homography(
        f,
        0.5 * width as f64 - 0.5,
        0.5 * height as f64 - 0.5,
        (rows + 1, cols + 1),
        square_m,
        dist,
        roll,
        tx,
        ty,
        shift,
    );
    Scene {
        width,
        height,
        h,
        layout: Layout::Chessboard { cols, rows, margin: 0.6 },
        dark_dn: 20.0,
        light_dn: 200.0,
        background_dn: 90.0,
        blur_px,
        noise_dn,
        seed: pose.wrapping_mul(7919).wrapping_add(17),
        lens: None,
    }
}

/// A plate scene with squares of about `square_px` pixels.
pub fn plate_scene(width: u32, height: u32, square_px: f64, pose: u64, blur_px: f64, noise_dn: f64) -> Scene {
    let mut s = chessboard_scene(width, height, 2, 2, square_px, pose, blur_px, noise_dn);
    s.layout = Layout::Plate { margin: 0.5 };
    s
}

/// Encodes an 8-bit image as JPEG of `quality` (1..=100) with the `image` crate and decodes it
/// again: the block artefacts and ringing of a camera's compressed output.
pub fn jpeg_roundtrip(img: &GrayImage, quality: u8) -> GrayImage {
    let mut buf = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut buf, quality).encode_image(img).expect("JPEG encoding");
    image::load_from_memory_with_format(&buf, image::ImageFormat::Jpeg).expect("JPEG decoding").to_luma8()
}

/// A 2 MP (1920 x 1080) tilted view of a 25 x 17 chessboard (425 inner corners, squares of
/// about 42 to 56 px), blur 1 px, noise 2 DN.
pub fn chessboard_2mp_scene() -> Scene {
    let mut s = chessboard_scene(1920, 1080, 25, 17, 50.0, 0, 1.0, 2.0);
    // Tilted by 18 degrees about the vertical axis and 6 about the horizontal, rolled by 4,
    // board centred (the board's 18 field rows fill most of the 1080 lines).
    let f = 1.2 * 1920.0;
    let square_m = 0.025;
    let dist = f * square_m / 50.0;
    s.h = homography(f, 959.5, 539.5, (18, 26), square_m, dist, 4.0, 6.0, -18.0, (0.0, 0.0));
    s
}

/// The 2 MP 425-corner scene rendered and passed through JPEG at quality 90.
pub fn chessboard_2mp_jpeg() -> (Scene, GrayImage) {
    let scene = chessboard_2mp_scene();
    let img = jpeg_roundtrip(&render(&scene), 90);
    (scene, img)
}
