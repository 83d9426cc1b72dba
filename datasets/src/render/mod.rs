//! The synthetic camera renderer: what a real camera sees of a planar target on a robot's
//! end-effector, with exact ground truth.
//!
//! Entry points:
//! - [`TargetConfig`] (plate, chessboard, AprilTag board, ChArUco board, circle grid) and its
//!   [`TargetGeometry`];
//! - [`Renderer`] (of a [`TargetConfig`], or of any [`TargetGeometry`], e.g. one printed to a
//!   wrong scale by [`TargetGeometry::printed`]): [`Renderer::render`] (8-bit image and [`GroundTruth`]),
//!   [`Renderer::render_expected`] (noise-free expected charge per pixel),
//!   [`Renderer::ground_truth`];
//! - configuration: [`RenderConfig`] = [`SceneConfig`] + [`OpticsConfig`] + [`SensorConfig`],
//!   all serde structs with defaults, ready to be embedded in a TOML cell file.
//!
//! # The image model
//! For a camera pose `T_cam_target`, pixel `(i, j)` (pixel-centre convention: pixel `(0, 0)` is
//! centred on `(0, 0)` and covers `[-0.5, 0.5]^2`) is produced in these steps:
//!
//! 1. **Reflectance, exactly area-averaged.** The scene is a background of reflectance
//!    `rho_bg`, the plate (white, `rho_w`) and the black polygons (`rho_b`). Every polygon edge
//!    is projected through the camera model (pinhole, Brown 5/8 or Kannala-Brandt), curved edges
//!    subdivided until the chord error is below `edge_tolerance_px`, and the exact covered area
//!    `A_p(i, j)` of each polygon in each pixel is accumulated (see `raster`):
//!    `rho(i, j) = rho_bg + (rho_w - rho_bg) A_plate(i, j) + (rho_b - rho_w) sum A_black(i, j)`.
//! 2. **Blur** by the point-spread function ([`Psf`]): `rho' = w * rho`.
//! 3. **Irradiance**: `S(i, j) = exposure_e * E(i, j) * V(i, j) * rho'(i, j)` electrons, with
//!    uneven illumination `E` ([`Illumination`]) and vignetting `V` ([`Vignetting`]); both are
//!    smooth, so applying them after the blur differs from before by `O(sigma^2 grad^2 E)`.
//! 4. **Sensor** ([`SensorConfig`]): shot noise, full-well clipping, read noise, conversion
//!    gain, black level, rounding and clipping to 8 bits, optional JPEG.
//!
//! Ground truth ([`GroundTruth`]): the camera model, `T_cam_target`, and every target corner
//! projected through the same camera model (pixel-centre convention).
//!
//! # Conventions
//! Target frame: x right, y up as the printed face is read, z out of the face; the camera must
//! see the printed face. Camera frame: z forward, x right, y down. Everything is deterministic
//! for a seed (ChaCha8).

pub mod apriltag;
mod boards;
pub mod calibration_errors;
pub mod calibration_study;
pub mod corner_study;
mod optics;
pub mod printed_targets;
mod raster;
mod sensor;
pub mod supersampled;
pub mod target;

#[cfg(test)]
mod tests;

use image::GrayImage;
use nalgebra::{Isometry3, Point2, Point3};
use serde::{Deserialize, Serialize};

use ferrocal_vision::camera::CameraModel;

pub use apriltag::TagFamily;
pub use optics::{Illumination, Psf, Vignetting};
pub use sensor::{jpeg_round_trip, SensorConfig, ShotNoise};
pub use target::{TargetConfig, TargetCorner, TargetGeometry};

use crate::error::{DatasetError, Result};
use optics::config_error;

/// Largest image the renderer accepts (256 MP).
const MAX_PIXELS: u64 = 1 << 28;

/// Reflectances of the scene and its illumination.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SceneConfig {
    /// Reflectance of the white plate, 0..=1.
    pub white_reflectance: f64,
    /// Reflectance of the black print, 0..=1.
    pub black_reflectance: f64,
    /// Reflectance of everything behind the plate, 0..=1.
    pub background_reflectance: f64,
    /// Uneven illumination over the image.
    pub illumination: Illumination,
}

impl Default for SceneConfig {
    /// White 0.85, black 0.04, background 0.15, uniform illumination.
    fn default() -> Self {
        Self {
            white_reflectance: 0.85,
            black_reflectance: 0.04,
            background_reflectance: 0.15,
            illumination: Illumination::default(),
        }
    }
}

/// The lens beyond its geometric model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OpticsConfig {
    /// Point-spread function.
    pub psf: Psf,
    /// Vignetting.
    pub vignetting: Vignetting,
}

impl Default for OpticsConfig {
    /// Gaussian blur with `sigma_px = 0.7` and natural cos^4 vignetting.
    fn default() -> Self {
        Self { psf: Psf::Gaussian { sigma_px: 0.7 }, vignetting: Vignetting::Cos4 { focal_px: None } }
    }
}

/// Everything the renderer needs besides the camera and the target.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RenderConfig {
    /// Reflectances and illumination.
    pub scene: SceneConfig,
    /// Blur and vignetting.
    pub optics: OpticsConfig,
    /// Noise, gain, quantisation, JPEG.
    pub sensor: SensorConfig,
    /// Largest distance (pixels) between a projected curved edge and the chords that stand for
    /// it; 1e-6..=0.1, default 1e-4.
    pub edge_tolerance_px: f64,
}

impl Default for RenderConfig {
    fn default() -> Self {
        Self {
            scene: SceneConfig::default(),
            optics: OpticsConfig::default(),
            sensor: SensorConfig::default(),
            edge_tolerance_px: 1e-4,
        }
    }
}

impl RenderConfig {
    /// An ideal configuration: no blur, no vignetting, uniform light, no noise, no JPEG.
    pub fn ideal() -> Self {
        Self {
            optics: OpticsConfig { psf: Psf::None, vignetting: Vignetting::None },
            sensor: SensorConfig::default().noiseless(),
            ..Self::default()
        }
    }

    /// Checks every field.
    pub fn validate(&self) -> Result<()> {
        let s = &self.scene;
        for (name, v) in [
            ("scene.white_reflectance", s.white_reflectance),
            ("scene.black_reflectance", s.black_reflectance),
            ("scene.background_reflectance", s.background_reflectance),
        ] {
            if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
                return Err(config_error(name, v, "must lie in 0..=1"));
            }
        }
        s.illumination.validate()?;
        self.optics.psf.validate()?;
        self.optics.vignetting.validate()?;
        self.sensor.validate()?;
        if !(self.edge_tolerance_px.is_finite() && (1e-6..=0.1).contains(&self.edge_tolerance_px)) {
            return Err(config_error("edge_tolerance_px", self.edge_tolerance_px, "must lie in 1e-6..=0.1"));
        }
        Ok(())
    }
}

/// Expected charge per pixel before noise (row-major).
#[derive(Clone, Debug, PartialEq)]
pub struct LinearImage {
    /// Columns.
    pub width_px: u32,
    /// Rows.
    pub height_px: u32,
    /// Expected photo-electrons `S(i, j)` at `j * width + i`.
    pub electrons: Vec<f32>,
}

impl LinearImage {
    /// The value at column `u`, row `v`, if inside.
    pub fn get(&self, u: u32, v: u32) -> Option<f32> {
        if u < self.width_px && v < self.height_px {
            self.electrons.get(v as usize * self.width_px as usize + u as usize).copied()
        } else {
            None
        }
    }
}

/// One target corner in one image.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CornerTruth {
    /// The corner on the target (feature, index, position).
    pub corner: TargetCorner,
    /// Its position in the camera frame, metres.
    pub p_cam_m: Point3<f64>,
    /// Its exact image position (pixel-centre convention), when the camera model can project it.
    pub pixel: Option<Point2<f64>>,
    /// Whether `pixel` lies inside the image.
    pub in_image: bool,
}

/// The ground truth of one rendered image.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GroundTruth {
    /// The camera model used.
    pub camera: CameraModel,
    /// Pose of the target in the camera frame.
    pub t_cam_target: Isometry3<f64>,
    /// Every target corner, in the target's documented order.
    pub corners: Vec<CornerTruth>,
}

/// A rendered image with its ground truth.
#[derive(Clone, Debug)]
pub struct RenderedImage {
    /// The 8-bit image.
    pub image: GrayImage,
    /// What it shows.
    pub truth: GroundTruth,
}

/// Renders one camera's view of one target.
pub struct Renderer {
    camera: CameraModel,
    target: TargetGeometry,
    config: RenderConfig,
    raster: raster::LensRaster,
}

impl Renderer {
    /// Validates the inputs and prepares the lens clipping region.
    pub fn new(camera: CameraModel, target: &TargetConfig, config: RenderConfig) -> Result<Self> {
        Self::with_geometry(camera, target.build()?, config)
    }

    /// A renderer of a target geometry built elsewhere, e.g. a pattern printed to a wrong scale
    /// ([`TargetGeometry::printed`]).
    pub fn with_geometry(camera: CameraModel, target: TargetGeometry, config: RenderConfig) -> Result<Self> {
        camera.validate()?;
        config.validate()?;
        let pixels = u64::from(camera.image_size.width_px) * u64::from(camera.image_size.height_px);
        if pixels > MAX_PIXELS {
            return Err(config_error(
                "camera.image_size",
                format!("{}x{}", camera.image_size.width_px, camera.image_size.height_px),
                "the renderer handles at most 256 megapixels",
            ));
        }
        let raster = raster::LensRaster::new(&camera, config.edge_tolerance_px)?;
        Ok(Self { camera, target, config, raster })
    }

    /// The camera model.
    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }

    /// The target geometry.
    pub fn target(&self) -> &TargetGeometry {
        &self.target
    }

    /// The configuration.
    pub fn config(&self) -> &RenderConfig {
        &self.config
    }

    fn check_pose(&self, t_cam_target: &Isometry3<f64>) -> Result<()> {
        let t = t_cam_target.translation.vector;
        let q = t_cam_target.rotation.coords;
        if !(t.iter().all(|v| v.is_finite()) && q.iter().all(|v| v.is_finite())) {
            return Err(DatasetError::Render("T_cam_target has non-finite entries".into()));
        }
        // The camera centre, seen from the target, must lie in front of the printed face.
        let t_target_cam = t_cam_target.inverse();
        let face = if self.target.face_minus_z { -1.0 } else { 1.0 };
        if face * t_target_cam.translation.vector.z <= 0.0 {
            return Err(DatasetError::Render(format!(
                "the camera sees the back of the target (camera at z = {:.4} m in the target frame); \
                 the target's z axis must point {} the camera",
                t_target_cam.translation.vector.z,
                if self.target.face_minus_z { "away from" } else { "towards" }
            )));
        }
        Ok(())
    }

    /// The exact image positions of all target corners.
    pub fn ground_truth(&self, t_cam_target: &Isometry3<f64>) -> Result<GroundTruth> {
        self.check_pose(t_cam_target)?;
        let corners = self
            .target
            .corners
            .iter()
            .map(|c| {
                let p_cam_m = t_cam_target.transform_point(&c.p_target_m);
                let pixel = self.camera.project(&p_cam_m).ok();
                let in_image = pixel.is_some_and(|p| self.camera.contains_pixel(&p));
                CornerTruth { corner: *c, p_cam_m, pixel, in_image }
            })
            .collect();
        Ok(GroundTruth { camera: self.camera, t_cam_target: *t_cam_target, corners })
    }

    /// Area-averaged reflectance per pixel after the PSF (steps 1 and 2 of the model).
    pub fn render_reflectance(&self, t_cam_target: &Isometry3<f64>) -> Result<Vec<f32>> {
        self.check_pose(t_cam_target)?;
        let w = self.camera.image_size.width_px as usize;
        let h = self.camera.image_size.height_px as usize;
        let s = &self.config.scene;
        let mut cov = raster::Coverage::new(w, h);
        self.raster.add_polygon(
            &mut cov,
            t_cam_target,
            &self.target.outline_m,
            s.white_reflectance - s.background_reflectance,
        )?;
        let dark = s.black_reflectance - s.white_reflectance;
        for poly in &self.target.dark_m {
            self.raster.add_polygon(&mut cov, t_cam_target, poly, dark)?;
        }
        let mut img = vec![0.0f32; w * h];
        cov.resolve(s.background_reflectance, &mut img);
        self.config.optics.psf.apply(&mut img, w, h);
        Ok(img)
    }

    /// Noise-free expected charge per pixel (steps 1 to 3 of the model).
    pub fn render_expected(&self, t_cam_target: &Isometry3<f64>) -> Result<LinearImage> {
        let mut img = self.render_reflectance(t_cam_target)?;
        let w = self.camera.image_size.width_px as usize;
        let h = self.camera.image_size.height_px as usize;
        let k = &self.camera.intrinsics;
        let ill = self.config.scene.illumination;
        let vig_f = match self.config.optics.vignetting {
            Vignetting::None => None,
            Vignetting::Cos4 { focal_px } => Some(focal_px.unwrap_or(0.5 * (k.fx_px + k.fy_px))),
        };
        let exposure = self.config.sensor.exposure_e;
        let (hw, hh) = (0.5 * w as f64, 0.5 * h as f64);
        let (mu, mv) = (0.5 * (w as f64 - 1.0), 0.5 * (h as f64 - 1.0));
        let uniform = ill == Illumination::default() && vig_f.is_none();
        for (j, row) in img.chunks_exact_mut(w).enumerate() {
            if uniform {
                for v in row.iter_mut() {
                    *v = (exposure * f64::from(*v)) as f32;
                }
                continue;
            }
            let y = (j as f64 - mv) / hh;
            let dv = j as f64 - k.cy_px;
            for (i, v) in row.iter_mut().enumerate() {
                let x = (i as f64 - mu) / hw;
                let e = (1.0 + ill.gradient_x * x + ill.gradient_y * y + ill.quadratic * (x * x + y * y)).max(0.0);
                let vig = match vig_f {
                    Some(f) => {
                        let du = i as f64 - k.cx_px;
                        let c2 = 1.0 / (1.0 + (du * du + dv * dv) / (f * f));
                        c2 * c2
                    }
                    None => 1.0,
                };
                *v = (exposure * e * vig * f64::from(*v)) as f32;
            }
        }
        Ok(LinearImage { width_px: w as u32, height_px: h as u32, electrons: img })
    }

    /// Renders the 8-bit image for a pose, deterministically for `seed`, with its ground truth.
    pub fn render(&self, t_cam_target: &Isometry3<f64>, seed: u64) -> Result<RenderedImage> {
        let truth = self.ground_truth(t_cam_target)?;
        let expected = self.render_expected(t_cam_target)?;
        let image = self.config.sensor.expose(&expected, seed)?;
        Ok(RenderedImage { image, truth })
    }
}
