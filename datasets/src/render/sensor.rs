//! The image sensor: photo-electrons, noise, saturation, 8-bit quantisation and JPEG.

use image::GrayImage;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Poisson, StandardNormal};
use serde::{Deserialize, Serialize};

use super::optics::config_error;
use super::LinearImage;
use crate::error::{DatasetError, Result};

/// How photon shot noise is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ShotNoise {
    /// No shot noise: the collected charge equals its expectation `S`.
    Off,
    /// Gaussian approximation: `N(S, S)` electrons (accurate for `S` above a few dozen).
    Gaussian,
    /// Exact: `Poisson(S)` electrons (slower).
    Poisson,
}

/// The sensor model. For a pixel with expected charge `S` electrons (from the optics):
///
/// ```text
/// e  = min(shot(S), full_well_e) + N(0, read_noise_e^2)      electrons
/// DN = clamp(round(e / gain_e_per_dn + black_level_dn), 0, 255)
/// ```
///
/// so that, away from clipping, `E[DN] = S / g + b` and
/// `Var[DN] = (S + read_noise_e^2) / g^2 + 1/12` (the last term from rounding). With
/// Gaussian shot noise and `S + 6 sqrt(S) < full_well_e`, shot and read noise are drawn as one
/// normal deviate of variance `S + read_noise_e^2`. An optional JPEG round trip (the `image`
/// crate's encoder and decoder) follows quantisation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorConfig {
    /// Exposure: electrons collected by a pixel that sees reflectance 1 under unit
    /// illumination with no vignetting. `S = exposure_e * E * V * reflectance`.
    pub exposure_e: f64,
    /// Full-well capacity, electrons (saturation).
    pub full_well_e: f64,
    /// Conversion gain, electrons per digital number.
    pub gain_e_per_dn: f64,
    /// Offset added to every pixel, digital numbers.
    pub black_level_dn: f64,
    /// Standard deviation of the read noise, electrons (0 = off).
    pub read_noise_e: f64,
    /// Shot-noise model.
    pub shot_noise: ShotNoise,
    /// JPEG quality 1..=100, or `None` for no compression.
    pub jpeg_quality: Option<u8>,
}

impl Default for SensorConfig {
    /// A machine-vision sensor: 10 500 e- full well, 40 e-/DN, white paper (0.85) at about
    /// 7 650 e- (195 DN), 6 e- read noise, Gaussian shot noise, no JPEG.
    fn default() -> Self {
        Self {
            exposure_e: 9000.0,
            full_well_e: 10500.0,
            gain_e_per_dn: 40.0,
            black_level_dn: 4.0,
            read_noise_e: 6.0,
            shot_noise: ShotNoise::Gaussian,
            jpeg_quality: None,
        }
    }
}

impl SensorConfig {
    /// The same sensor with shot and read noise off (quantisation and JPEG unchanged).
    pub fn noiseless(mut self) -> Self {
        self.shot_noise = ShotNoise::Off;
        self.read_noise_e = 0.0;
        self
    }

    /// Checks every field.
    pub fn validate(&self) -> Result<()> {
        let positive = [("sensor.full_well_e", self.full_well_e), ("sensor.gain_e_per_dn", self.gain_e_per_dn)];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(config_error(name, v, "must be finite and > 0"));
            }
        }
        let non_negative = [
            ("sensor.exposure_e", self.exposure_e),
            ("sensor.black_level_dn", self.black_level_dn),
            ("sensor.read_noise_e", self.read_noise_e),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(config_error(name, v, "must be finite and >= 0"));
            }
        }
        if let Some(q) = self.jpeg_quality {
            if !(1..=100).contains(&q) {
                return Err(config_error("sensor.jpeg_quality", q, "must lie in 1..=100"));
            }
        }
        Ok(())
    }

    /// Turns expected charges into an 8-bit image, deterministically for a seed (ChaCha8,
    /// pixels drawn in row-major order).
    pub fn expose(&self, expected: &LinearImage, seed: u64) -> Result<GrayImage> {
        self.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let inv_gain = 1.0 / self.gain_e_per_dn;
        let read_var = self.read_noise_e * self.read_noise_e;
        let mut out = Vec::with_capacity(expected.electrons.len());
        for &s in &expected.electrons {
            let s = f64::from(s).max(0.0);
            let e = match self.shot_noise {
                ShotNoise::Off => s.min(self.full_well_e) + self.read(&mut rng),
                ShotNoise::Gaussian => {
                    if s + 6.0 * s.sqrt() < self.full_well_e {
                        let n: f64 = rng.sample(StandardNormal);
                        s + (s + read_var).sqrt() * n
                    } else {
                        let n: f64 = rng.sample(StandardNormal);
                        (s + s.sqrt() * n).min(self.full_well_e) + self.read(&mut rng)
                    }
                }
                ShotNoise::Poisson => {
                    let shot = if s > 0.0 { Poisson::new(s).map(|p| p.sample(&mut rng)).unwrap_or(s) } else { 0.0 };
                    shot.min(self.full_well_e) + self.read(&mut rng)
                }
            };
            let dn = (e * inv_gain + self.black_level_dn).round().clamp(0.0, 255.0);
            out.push(dn as u8);
        }
        let img = GrayImage::from_raw(expected.width_px, expected.height_px, out)
            .ok_or_else(|| DatasetError::Render("image buffer size does not match its dimensions".into()))?;
        match self.jpeg_quality {
            Some(q) => jpeg_round_trip(&img, q),
            None => Ok(img),
        }
    }

    fn read(&self, rng: &mut ChaCha8Rng) -> f64 {
        if self.read_noise_e > 0.0 {
            let n: f64 = rng.sample(StandardNormal);
            self.read_noise_e * n
        } else {
            0.0
        }
    }
}

/// Encodes as baseline JPEG at `quality` and decodes again.
pub fn jpeg_round_trip(img: &GrayImage, quality: u8) -> Result<GrayImage> {
    let mut buf = Vec::new();
    let encoder = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut buf, quality);
    img.write_with_encoder(encoder).map_err(|e| DatasetError::Render(format!("JPEG encoding failed: {e}")))?;
    let decoded = image::load_from_memory_with_format(&buf, image::ImageFormat::Jpeg)
        .map_err(|e| DatasetError::Render(format!("JPEG decoding failed: {e}")))?;
    Ok(decoded.to_luma8())
}
