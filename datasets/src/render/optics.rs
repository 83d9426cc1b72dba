//! Point-spread functions, illumination and vignetting.

use serde::{Deserialize, Serialize};

use crate::error::{DatasetError, Result};

/// The optics' point-spread function (defocus and lens blur), applied to the pixel-integrated
/// image as a discrete convolution with a normalised kernel `w`: `I'(i, j) = sum w(k, l) I(i-k, j-l)`,
/// borders replicated.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Psf {
    /// No blur.
    None,
    /// Gaussian, separable: `w(k) = exp(-k^2 / (2 sigma^2)) / sum`, `|k| <= ceil(4 sigma)`.
    Gaussian {
        /// Standard deviation, pixels (0.3 to 20).
        sigma_px: f64,
    },
    /// Uniform disc (geometric defocus): `w(k, l)` = area of the disc of radius `radius_px`
    /// inside pixel `(k, l)` (16 x 16 sub-samples per pixel), normalised.
    Disc {
        /// Radius, pixels (0.5 to 20).
        radius_px: f64,
    },
}

/// Vignetting: the relative illumination of the image plane.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Vignetting {
    /// Uniform.
    None,
    /// Natural cos^4 falloff: `V = cos^4(theta) = 1 / (1 + r^2 / f^2)^2` with `r` the distance
    /// (pixels) from the principal point and `f` = `focal_px`, or the camera's mean focal
    /// length when absent. A smaller `focal_px` gives stronger falloff.
    Cos4 {
        /// Focal length of the falloff, pixels.
        #[serde(default)]
        focal_px: Option<f64>,
    },
}

/// Uneven illumination over the image:
/// `E(u, v) = max(0, 1 + gradient_x x + gradient_y y + quadratic (x^2 + y^2))` with
/// `x = (u - (W - 1)/2) / (W/2)`, `y = (v - (H - 1)/2) / (H/2)` in `[-1, 1]`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Illumination {
    /// Relative change from the image centre to the right edge.
    pub gradient_x: f64,
    /// Relative change from the image centre to the bottom edge.
    pub gradient_y: f64,
    /// Relative change from the centre to the edge midpoints (negative: darker border).
    pub quadratic: f64,
}

pub(crate) fn config_error(field: &str, value: impl ToString, reason: &str) -> DatasetError {
    DatasetError::RenderConfig { field: field.into(), value: value.to_string(), reason: reason.into() }
}

impl Psf {
    pub(crate) fn validate(&self) -> Result<()> {
        match *self {
            Psf::None => Ok(()),
            Psf::Gaussian { sigma_px } => {
                if sigma_px.is_finite() && (0.3..=20.0).contains(&sigma_px) {
                    Ok(())
                } else {
                    Err(config_error(
                        "optics.psf.sigma_px",
                        sigma_px,
                        "must lie in 0.3..=20 (use kind = \"none\" for no blur)",
                    ))
                }
            }
            Psf::Disc { radius_px } => {
                if radius_px.is_finite() && (0.5..=20.0).contains(&radius_px) {
                    Ok(())
                } else {
                    Err(config_error("optics.psf.radius_px", radius_px, "must lie in 0.5..=20"))
                }
            }
        }
    }

    /// Applies the PSF in place to a `width x height` image.
    pub(crate) fn apply(&self, img: &mut [f32], width: usize, height: usize) {
        match *self {
            Psf::None => {}
            Psf::Gaussian { sigma_px } => blur_separable(img, width, height, &gaussian_kernel(sigma_px)),
            Psf::Disc { radius_px } => {
                let (kernel, r) = disc_kernel(radius_px);
                blur_2d(img, width, height, &kernel, r);
            }
        }
    }
}

impl Vignetting {
    pub(crate) fn validate(&self) -> Result<()> {
        match *self {
            Vignetting::Cos4 { focal_px: Some(f) } if !(f.is_finite() && f > 0.0) => {
                Err(config_error("optics.vignetting.focal_px", f, "must be finite and > 0"))
            }
            _ => Ok(()),
        }
    }
}

impl Illumination {
    pub(crate) fn validate(&self) -> Result<()> {
        for (name, v) in
            [("gradient_x", self.gradient_x), ("gradient_y", self.gradient_y), ("quadratic", self.quadratic)]
        {
            if !(v.is_finite() && v.abs() <= 10.0) {
                return Err(config_error(&format!("scene.illumination.{name}"), v, "must be finite, |value| <= 10"));
            }
        }
        Ok(())
    }
}

/// Normalised Gaussian taps `w[k + R]`, `R = ceil(4 sigma)`.
pub(crate) fn gaussian_kernel(sigma_px: f64) -> Vec<f32> {
    let r = (4.0 * sigma_px).ceil() as i64;
    let w: Vec<f64> = (-r..=r).map(|k| (-(k * k) as f64 / (2.0 * sigma_px * sigma_px)).exp()).collect();
    let s: f64 = w.iter().sum();
    w.iter().map(|v| (v / s) as f32).collect()
}

/// Normalised disc kernel, `(2R+1)^2` taps row-major, and `R`.
pub(crate) fn disc_kernel(radius_px: f64) -> (Vec<f32>, usize) {
    let r = (radius_px + 0.5).ceil() as usize;
    let n = 2 * r + 1;
    let sub = 16;
    let mut w = vec![0.0f64; n * n];
    for (j, row) in w.chunks_exact_mut(n).enumerate() {
        for (i, cell) in row.iter_mut().enumerate() {
            let mut k = 0;
            for sy in 0..sub {
                for sx in 0..sub {
                    let x = i as f64 - r as f64 - 0.5 + (sx as f64 + 0.5) / sub as f64;
                    let y = j as f64 - r as f64 - 0.5 + (sy as f64 + 0.5) / sub as f64;
                    if x * x + y * y <= radius_px * radius_px {
                        k += 1;
                    }
                }
            }
            *cell = k as f64;
        }
    }
    let s: f64 = w.iter().sum();
    (w.iter().map(|v| (v / s) as f32).collect(), r)
}

/// Separable convolution (rows then columns) with replicated borders.
pub(crate) fn blur_separable(img: &mut [f32], width: usize, height: usize, kernel: &[f32]) {
    let r = kernel.len() / 2;
    // Rows.
    let mut pad = vec![0.0f32; width + 2 * r];
    for row in img.chunks_exact_mut(width) {
        let (first, last) = (row[0], row[width - 1]);
        pad[..r].fill(first);
        pad[r..r + width].copy_from_slice(row);
        pad[r + width..].fill(last);
        for (i, o) in row.iter_mut().enumerate() {
            let window = &pad[i..i + kernel.len()];
            *o = window.iter().zip(kernel).map(|(a, b)| a * b).sum();
        }
    }
    // Columns: out row j = sum_k w_k in_row[clamp(j + k - R)].
    let src = img.to_vec();
    for (j, out) in img.chunks_exact_mut(width).enumerate() {
        out.fill(0.0);
        for (k, wk) in kernel.iter().enumerate() {
            let jj = (j + k).saturating_sub(r).min(height - 1);
            let in_row = &src[jj * width..(jj + 1) * width];
            for (o, v) in out.iter_mut().zip(in_row) {
                *o += wk * v;
            }
        }
    }
}

/// Direct 2D convolution with replicated borders.
pub(crate) fn blur_2d(img: &mut [f32], width: usize, height: usize, kernel: &[f32], r: usize) {
    let n = 2 * r + 1;
    let src = img.to_vec();
    let mut row_buf = vec![0.0f32; width + 2 * r];
    for (j, out) in img.chunks_exact_mut(width).enumerate() {
        out.fill(0.0);
        for kj in 0..n {
            let jj = (j + kj).saturating_sub(r).min(height - 1);
            let in_row = &src[jj * width..(jj + 1) * width];
            row_buf[..r].fill(in_row[0]);
            row_buf[r..r + width].copy_from_slice(in_row);
            row_buf[r + width..].fill(in_row[width - 1]);
            for ki in 0..n {
                let wk = kernel[kj * n + ki];
                if wk == 0.0 {
                    continue;
                }
                for (o, v) in out.iter_mut().zip(&row_buf[ki..ki + width]) {
                    *o += wk * v;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernels_are_normalised_and_blur_preserves_the_mean() {
        let g = gaussian_kernel(1.3);
        assert!((g.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        let (d, r) = disc_kernel(2.5);
        assert_eq!(d.len(), (2 * r + 1).pow(2));
        assert!((d.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        let (w, h) = (40, 30);
        let mut img: Vec<f32> = (0..w * h).map(|i| if (i % w) > 20 { 1.0 } else { 0.0 }).collect();
        let before: f32 = img[10 * w..11 * w].iter().sum();
        blur_separable(&mut img, w, h, &g);
        let after: f32 = img[10 * w..11 * w].iter().sum();
        assert!((before - after).abs() < 1e-4);
        let mut flat = vec![0.25f32; w * h];
        blur_2d(&mut flat, w, h, &d, r);
        assert!(flat.iter().all(|v| (v - 0.25).abs() < 1e-6));
    }
}
