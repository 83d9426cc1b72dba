//! An independent chessboard renderer by supersampled area coverage, for checks that must not
//! use the renderer the corner detector was tuned on (the exact-area polygon rasteriser of the
//! rest of [`crate::render`]). It shares no code with that renderer: only the camera model
//! *types* of [`ferrocal_vision::camera`] describe the truth lens.
//!
//! # The image model
//! Pixel `(i, j)` (pixel-centre convention: it covers `[i - 0.5, i + 0.5] x [j - 0.5, j + 0.5]`)
//! is produced in these steps:
//!
//! 1. **Supersampled reflectance.** `S x S` stratified sub-samples per pixel: sample `(a, b)`
//!    lies at `(i - 0.5 + (a + xi) / S, j - 0.5 + (b + eta) / S)` with `xi, eta` uniform in
//!    `[0, 1)`, drawn from a hash of `(seed, pixel, sample)` (deterministic, independent of the
//!    number of threads). Each sample is back-projected through the *inverse* of the lens:
//!    the distorted normalised point `((u - cx) / fx, (v - cy) / fy)` is undistorted by
//!    Newton's method on the Brown-5 model (OpenCV's `k1 k2 p1 p2 k3`, written here
//!    independently), iterated until the distorted point is matched to `1e-12` (normalised,
//!    about `1e-9` px) and refused when the Jacobian is not positive (beyond a fold) or 30
//!    iterations do not converge. The ray `(x, y, 1)` is intersected with the board plane; the
//!    reflectance there is looked up: the board is a chessboard of `(cols + 1) x (rows + 1)`
//!    squares (top-left square dark, as the project's chessboards), surrounded by a white
//!    margin, printed on a plane in front of a uniform mid-grey background (rays that miss the
//!    board, or meet its plane behind the camera, see the background). The pixel's value is
//!    the mean over its `S^2` samples: area coverage with a stratified-sampling error of at
//!    most about `1 / S` of the contrast for a pixel cut by an edge (typically far less).
//! 2. **Optical blur**: separable Gaussian point-spread function of standard deviation
//!    `psf_sigma_px` (kernel radius `ceil(4 sigma)`, borders replicated).
//! 3. **Vignetting**: `V = 1 - vignetting (r / r_corner)^2`, `r` the distance from the image
//!    centre, `r_corner` that of an image corner.
//! 4. **Sensor**: expected charge `N = exposure_e V rho` electrons; the collected charge is
//!    `Poisson(N)` (photon shot noise) plus Gaussian read noise of `read_noise_e`;
//!    `DN = clamp(round(e / gain_e_per_dn + black_level_dn), 0, 255)` (ChaCha8, seeded).
//! 5. Optionally a **JPEG** round trip (the `image` crate's encoder at `jpeg_quality`).
//!
//! # Frames
//! Board frame: origin at the outer corner of the top-left square, `x` to the right and `y`
//! downwards as the print is read, `z` into the printed face (right-handed). A board at the
//! identity rotation in front of the camera (camera frame: z forward, x right, y down) is
//! therefore seen upright. Inner corner `(r, c)` (row `r` from the top, column `c` from the
//! left) lies at `((c + 1) s, (r + 1) s, 0)`.

use image::GrayImage;
use nalgebra::{Isometry3, Point2, Point3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, Poisson};

use crate::error::{DatasetError, Result};
use ferrocal_vision::camera::{CameraModel, Distortion};

/// Convergence threshold of the lens inversion (normalised image units).
const UNDISTORT_TOL: f64 = 1e-12;
/// Iteration limit of the lens inversion.
const UNDISTORT_MAX_ITER: usize = 30;

/// A chessboard printed with a white margin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrintedChessboard {
    /// Inner corners per row.
    pub inner_cols: u32,
    /// Inner corners per column.
    pub inner_rows: u32,
    /// Side of a square, metres.
    pub square_m: f64,
    /// White margin around the squares, metres.
    pub margin_m: f64,
}

/// What a ray meets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Surface {
    /// A dark square.
    Dark,
    /// A light square or the margin.
    White,
    /// Beyond the board.
    Background,
}

impl PrintedChessboard {
    /// Width and height of the printed sheet's squares region, metres.
    pub fn squares_size_m(&self) -> (f64, f64) {
        (f64::from(self.inner_cols + 1) * self.square_m, f64::from(self.inner_rows + 1) * self.square_m)
    }

    /// The surface at board coordinates `(x, y)` (metres, board frame).
    pub fn surface(&self, x: f64, y: f64) -> Surface {
        let (w, h) = self.squares_size_m();
        let m = self.margin_m;
        if !(x >= -m && x < w + m && y >= -m && y < h + m) {
            return Surface::Background;
        }
        if x < 0.0 || y < 0.0 || x >= w || y >= h {
            return Surface::White;
        }
        let c = (x / self.square_m).floor() as i64;
        let r = (y / self.square_m).floor() as i64;
        if (r + c) % 2 == 0 {
            Surface::Dark
        } else {
            Surface::White
        }
    }

    /// Inner corner `(r, c)` in the board frame.
    pub fn inner_corner(&self, r: u32, c: u32) -> Point3<f64> {
        Point3::new(f64::from(c + 1) * self.square_m, f64::from(r + 1) * self.square_m, 0.0)
    }

    /// All inner corners, row by row from the top-left.
    pub fn inner_corners(&self) -> Vec<Point3<f64>> {
        (0..self.inner_rows).flat_map(|r| (0..self.inner_cols).map(move |c| self.inner_corner(r, c))).collect()
    }

    /// The four outer corners of the printed sheet (margin included), board frame.
    pub fn sheet_corners(&self) -> [Point3<f64>; 4] {
        let (w, h) = self.squares_size_m();
        let m = self.margin_m;
        [
            Point3::new(-m, -m, 0.0),
            Point3::new(w + m, -m, 0.0),
            Point3::new(w + m, h + m, 0.0),
            Point3::new(-m, h + m, 0.0),
        ]
    }
}

/// Everything the supersampled renderer needs besides the camera, board and pose.
#[derive(Clone, Debug, PartialEq)]
pub struct SupersampledConfig {
    /// Sub-samples per pixel side (`S`, 1..=32).
    pub subsamples: u32,
    /// Reflectance of the dark squares.
    pub dark: f64,
    /// Reflectance of the light squares and the margin.
    pub white: f64,
    /// Reflectance of the background.
    pub background: f64,
    /// Standard deviation of the Gaussian PSF, pixels (0 = none).
    pub psf_sigma_px: f64,
    /// Relative fall-off of the light at the image corners (0 = none).
    pub vignetting: f64,
    /// Electrons for reflectance 1 at the image centre.
    pub exposure_e: f64,
    /// Read noise, electrons (0 = none).
    pub read_noise_e: f64,
    /// Whether photon shot noise is drawn.
    pub shot_noise: bool,
    /// Conversion gain, electrons per digital number.
    pub gain_e_per_dn: f64,
    /// Offset, digital numbers.
    pub black_level_dn: f64,
    /// JPEG quality 1..=100, or `None`.
    pub jpeg_quality: Option<u8>,
}

impl Default for SupersampledConfig {
    /// `S = 8`; reflectances 0.05 / 0.85 / 0.45; PSF sigma 0.8 px; 12 % vignetting; 20 000 e-
    /// for reflectance 1 (white at about 174 DN), 100 e-/DN, black level 4 DN, 10 e- read noise,
    /// shot noise on; no JPEG.
    fn default() -> Self {
        Self {
            subsamples: 8,
            dark: 0.05,
            white: 0.85,
            background: 0.45,
            psf_sigma_px: 0.8,
            vignetting: 0.12,
            exposure_e: 20_000.0,
            read_noise_e: 10.0,
            shot_noise: true,
            gain_e_per_dn: 100.0,
            black_level_dn: 4.0,
            jpeg_quality: None,
        }
    }
}

impl SupersampledConfig {
    /// The same without noise (quantisation and JPEG kept).
    pub fn noiseless(mut self) -> Self {
        self.shot_noise = false;
        self.read_noise_e = 0.0;
        self
    }

    fn validate(&self) -> Result<()> {
        let bad = |what: &str| Err(DatasetError::Render(format!("supersampled renderer: {what}")));
        if !(1..=32).contains(&self.subsamples) {
            return bad("subsamples must lie in 1..=32");
        }
        for v in [self.dark, self.white, self.background] {
            if !(0.0..=1.0).contains(&v) {
                return bad("reflectances must lie in 0..=1");
            }
        }
        if !(self.psf_sigma_px.is_finite() && (0.0..=20.0).contains(&self.psf_sigma_px)) {
            return bad("psf_sigma_px must lie in 0..=20");
        }
        if !(0.0..1.0).contains(&self.vignetting) {
            return bad("vignetting must lie in 0..1");
        }
        if !(self.exposure_e > 0.0 && self.gain_e_per_dn > 0.0 && self.read_noise_e >= 0.0) {
            return bad("exposure and gain must be > 0, read noise >= 0");
        }
        if self.jpeg_quality.is_some_and(|q| !(1..=100).contains(&q)) {
            return bad("jpeg_quality must lie in 1..=100");
        }
        Ok(())
    }
}

/// Brown-5 coefficients `k1 k2 p1 p2 k3`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Brown {
    k1: f64,
    k2: f64,
    p1: f64,
    p2: f64,
    k3: f64,
}

impl Brown {
    /// The distorted point and the Jacobian `d(xd, yd)/d(x, y)` (row-major).
    fn distort(&self, x: f64, y: f64) -> ([f64; 2], [f64; 4]) {
        let Brown { k1, k2, p1, p2, k3 } = *self;
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        let dradial = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3); // d(radial)/d(r2)
        let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
        let j00 = radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x;
        let j01 = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
        let j10 = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
        let j11 = radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x;
        ([xd, yd], [j00, j01, j10, j11])
    }

    /// The undistorted point whose distortion is `target`, by Newton's method from `start`.
    fn undistort(&self, target: [f64; 2], start: [f64; 2]) -> Option<[f64; 2]> {
        let mut p = start;
        for _ in 0..UNDISTORT_MAX_ITER {
            let (d, j) = self.distort(p[0], p[1]);
            let (rx, ry) = (d[0] - target[0], d[1] - target[1]);
            let det = j[0] * j[3] - j[1] * j[2];
            if !(det > 0.0 && det.is_finite()) {
                return None;
            }
            if rx.abs().max(ry.abs()) < UNDISTORT_TOL {
                return Some(p);
            }
            p[0] -= (j[3] * rx - j[1] * ry) / det;
            p[1] -= (-j[2] * rx + j[0] * ry) / det;
        }
        None
    }
}

/// The supersampled renderer of one camera and one chessboard.
#[derive(Clone, Debug)]
pub struct SupersampledRenderer {
    camera: CameraModel,
    lens: Brown,
    board: PrintedChessboard,
    config: SupersampledConfig,
}

/// `splitmix64`: a well-mixed 64-bit hash step.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Two uniform numbers in `[0, 1)` from a hash.
fn unit_pair(h: u64) -> (f64, f64) {
    let a = (h >> 40) as f64 / (1u64 << 24) as f64;
    let b = ((h >> 16) & 0xFF_FFFF) as f64 / (1u64 << 24) as f64;
    (a, b)
}

impl SupersampledRenderer {
    /// A renderer of `board` seen by `camera` (pinhole or Brown-5 only).
    pub fn new(camera: CameraModel, board: PrintedChessboard, config: SupersampledConfig) -> Result<Self> {
        camera.validate()?;
        config.validate()?;
        let lens = match camera.distortion {
            Distortion::None => Brown { k1: 0.0, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0 },
            Distortion::Brown5 { k1, k2, p1, p2, k3 } => Brown { k1, k2, p1, p2, k3 },
            other => {
                return Err(DatasetError::Render(format!(
                    "supersampled renderer: lens model {:?} is not supported (pinhole or Brown-5)",
                    other.kind()
                )))
            }
        };
        if !(board.inner_cols >= 2 && board.inner_rows >= 2 && board.square_m > 0.0 && board.margin_m >= 0.0) {
            return Err(DatasetError::Render("supersampled renderer: bad chessboard".into()));
        }
        Ok(Self { camera, lens, board, config })
    }

    /// The camera.
    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }

    /// The board.
    pub fn board(&self) -> &PrintedChessboard {
        &self.board
    }

    /// The undistorted normalised point `(X/Z, Y/Z)` of the ray through `pixel`, by this
    /// module's own Newton iteration; `None` beyond a fold of the lens or without convergence.
    pub fn back_project(&self, pixel: &Point2<f64>) -> Option<Point2<f64>> {
        let k = &self.camera.intrinsics;
        let t = [(pixel.x - k.cx_px) / k.fx_px, (pixel.y - k.cy_px) / k.fy_px];
        self.lens.undistort(t, t).map(|p| Point2::new(p[0], p[1]))
    }

    /// The exact image position of a board point (forward Brown-5 model of this module).
    pub fn project(&self, t_cam_board: &Isometry3<f64>, p_board: &Point3<f64>) -> Option<Point2<f64>> {
        let p = t_cam_board.transform_point(p_board);
        if p.z <= 0.0 {
            return None;
        }
        let (d, _) = self.lens.distort(p.x / p.z, p.y / p.z);
        let k = &self.camera.intrinsics;
        Some(Point2::new(k.fx_px * d[0] + k.cx_px, k.fy_px * d[1] + k.cy_px))
    }

    /// Step 1 of the model: the mean reflectance over each pixel's sub-samples, row-major.
    pub fn render_reflectance(&self, t_cam_board: &Isometry3<f64>, seed: u64) -> Result<Vec<f64>> {
        let w = self.camera.image_size.width_px as usize;
        let h = self.camera.image_size.height_px as usize;
        // The board plane in the camera frame: normal n (board z axis), through t.
        let rot = t_cam_board.rotation.to_rotation_matrix();
        let t = t_cam_board.translation.vector;
        let n: Vector3<f64> = rot.matrix().column(2).into_owned();
        let ex: Vector3<f64> = rot.matrix().column(0).into_owned();
        let ey: Vector3<f64> = rot.matrix().column(1).into_owned();
        let nt = n.dot(&t);
        // The printed face looks along -z of the board: the camera must be on that side.
        if nt <= 0.0 {
            return Err(DatasetError::Render("supersampled renderer: the camera sees the back of the board".into()));
        }
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).clamp(1, 8);
        let rows_per = h.div_ceil(threads);
        let mut out = vec![0.0f64; w * h];
        let failed = std::sync::atomic::AtomicBool::new(false);
        std::thread::scope(|scope| {
            for (chunk_index, chunk) in out.chunks_mut(rows_per * w).enumerate() {
                let failed = &failed;
                scope.spawn(move || {
                    let j0 = chunk_index * rows_per;
                    for (dj, row) in chunk.chunks_mut(w).enumerate() {
                        if !self.render_row(j0 + dj, row, seed, (&n, &ex, &ey, &t, nt)) {
                            failed.store(true, std::sync::atomic::Ordering::Relaxed);
                            return;
                        }
                    }
                });
            }
        });
        if failed.into_inner() {
            return Err(DatasetError::Render(
                "supersampled renderer: the lens cannot be inverted at some pixel (beyond a fold of the distortion)"
                    .into(),
            ));
        }
        Ok(out)
    }

    /// One row of step 1; false when the lens could not be inverted.
    fn render_row(
        &self,
        j: usize,
        row: &mut [f64],
        seed: u64,
        plane: (&Vector3<f64>, &Vector3<f64>, &Vector3<f64>, &Vector3<f64>, f64),
    ) -> bool {
        let (n, ex, ey, t, nt) = plane;
        let k = &self.camera.intrinsics;
        let c = &self.config;
        let s = c.subsamples as usize;
        let inv_s = 1.0 / s as f64;
        let inv_n = 1.0 / (s * s) as f64;
        let w = row.len();
        let mut start = [(0.0 - k.cx_px) / k.fx_px, (j as f64 - k.cy_px) / k.fy_px];
        for (i, value) in row.iter_mut().enumerate() {
            let centre = [(i as f64 - k.cx_px) / k.fx_px, (j as f64 - k.cy_px) / k.fy_px];
            let Some(pc) = self.lens.undistort(centre, start) else { return false };
            start = pc;
            let pixel_hash = mix(seed ^ mix((j * w + i) as u64));
            let mut sum = 0.0;
            for b in 0..s {
                for a in 0..s {
                    let (xi, eta) = unit_pair(mix(pixel_hash.wrapping_add((b * s + a) as u64)));
                    let u = i as f64 - 0.5 + (a as f64 + xi) * inv_s;
                    let v = j as f64 - 0.5 + (b as f64 + eta) * inv_s;
                    let target = [(u - k.cx_px) / k.fx_px, (v - k.cy_px) / k.fy_px];
                    let Some(p) = self.lens.undistort(target, pc) else { return false };
                    let d = Vector3::new(p[0], p[1], 1.0);
                    let nd = n.dot(&d);
                    let rho = if nd <= 0.0 {
                        c.background
                    } else {
                        let q = d * (nt / nd) - t;
                        match self.board.surface(ex.dot(&q), ey.dot(&q)) {
                            Surface::Dark => c.dark,
                            Surface::White => c.white,
                            Surface::Background => c.background,
                        }
                    };
                    sum += rho;
                }
            }
            *value = sum * inv_n;
        }
        true
    }

    /// Steps 1 to 3: the expected charge per pixel (electrons), row-major.
    pub fn render_expected(&self, t_cam_board: &Isometry3<f64>, seed: u64) -> Result<Vec<f64>> {
        let w = self.camera.image_size.width_px as usize;
        let h = self.camera.image_size.height_px as usize;
        let mut img = self.render_reflectance(t_cam_board, seed)?;
        if self.config.psf_sigma_px > 0.0 {
            gaussian_blur(&mut img, w, h, self.config.psf_sigma_px);
        }
        let (uc, vc) = (0.5 * (w as f64 - 1.0), 0.5 * (h as f64 - 1.0));
        let r2_corner = uc * uc + vc * vc;
        for (j, row) in img.chunks_mut(w).enumerate() {
            let dv = j as f64 - vc;
            for (i, v) in row.iter_mut().enumerate() {
                let du = i as f64 - uc;
                let vig = 1.0 - self.config.vignetting * (du * du + dv * dv) / r2_corner;
                *v *= self.config.exposure_e * vig;
            }
        }
        Ok(img)
    }

    /// The 8-bit image of the board at `t_cam_board` (board frame to camera frame),
    /// deterministic for `seed` (sub-sample jitter and sensor noise).
    pub fn render(&self, t_cam_board: &Isometry3<f64>, seed: u64) -> Result<GrayImage> {
        let w = self.camera.image_size.width_px;
        let h = self.camera.image_size.height_px;
        let expected = self.render_expected(t_cam_board, seed)?;
        let c = &self.config;
        let mut rng = ChaCha8Rng::seed_from_u64(mix(seed ^ 0x005E_ED0F_5E45_0125));
        let read = Normal::new(0.0, c.read_noise_e.max(0.0)).map_err(|e| DatasetError::Render(e.to_string()))?;
        let mut bytes = Vec::with_capacity(expected.len());
        for &e in &expected {
            let mut q = e;
            if c.shot_noise && e > 0.0 {
                q = Poisson::new(e).map_err(|err| DatasetError::Render(err.to_string()))?.sample(&mut rng);
            }
            if c.read_noise_e > 0.0 {
                q += read.sample(&mut rng);
            }
            let dn = (q / c.gain_e_per_dn + c.black_level_dn).round().clamp(0.0, 255.0);
            bytes.push(dn as u8);
        }
        let img = GrayImage::from_raw(w, h, bytes)
            .ok_or_else(|| DatasetError::Render("supersampled renderer: image buffer size".into()))?;
        match c.jpeg_quality {
            None => Ok(img),
            Some(q) => jpeg(&img, q),
        }
    }
}

/// A JPEG round trip at quality `q`.
fn jpeg(img: &GrayImage, q: u8) -> Result<GrayImage> {
    let mut buf = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut buf, q)
        .encode_image(img)
        .map_err(|e| DatasetError::Render(format!("JPEG encoding: {e}")))?;
    let decoded = image::load_from_memory_with_format(&buf, image::ImageFormat::Jpeg)
        .map_err(|e| DatasetError::Render(format!("JPEG decoding: {e}")))?;
    Ok(decoded.to_luma8())
}

/// Separable Gaussian blur in place, kernel radius `ceil(4 sigma)`, borders replicated.
fn gaussian_blur(img: &mut [f64], w: usize, h: usize, sigma: f64) {
    let r = (4.0 * sigma).ceil() as isize;
    let mut kernel: Vec<f64> = (-r..=r).map(|k| (-(k * k) as f64 / (2.0 * sigma * sigma)).exp()).collect();
    let total: f64 = kernel.iter().sum();
    kernel.iter_mut().for_each(|k| *k /= total);
    let mut tmp = vec![0.0; img.len()];
    for j in 0..h {
        for i in 0..w {
            let mut acc = 0.0;
            for (m, kv) in kernel.iter().enumerate() {
                let ii = (i as isize + m as isize - r).clamp(0, w as isize - 1) as usize;
                acc += kv * img[j * w + ii];
            }
            tmp[j * w + i] = acc;
        }
    }
    for j in 0..h {
        for i in 0..w {
            let mut acc = 0.0;
            for (m, kv) in kernel.iter().enumerate() {
                let jj = (j as isize + m as isize - r).clamp(0, h as isize - 1) as usize;
                acc += kv * tmp[jj * w + i];
            }
            img[j * w + i] = acc;
        }
    }
}

#[cfg(test)]
#[path = "supersampled_tests.rs"]
mod tests;
