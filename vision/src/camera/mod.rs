//! Camera models: pinhole with Brown-Conrady distortion (OpenCV's 5 and 8 coefficients) and
//! Kannala-Brandt (OpenCV's `fisheye`), with analytic Jacobians, an iterative inverse, a named
//! parameter vector for calibration, and OpenCV / ROS YAML files.
//!
//! Entry points:
//! - [`CameraModel`]: [`CameraModel::project`], [`CameraModel::project_with_jacobians`],
//!   [`CameraModel::unproject`], [`CameraModel::unproject_normalized`], the parameter vector
//!   ([`CameraModel::parameters`], [`CameraModel::set_parameter_values`]);
//! - [`Distortion`]: the lens models and their coefficients in OpenCV order;
//! - [`io`]: OpenCV FileStorage YAML and ROS `camera_info` YAML, written and read exactly, for one
//!   camera and for a stereo pair ([`io::StereoPair`]: `M1 D1 M2 D2 R T E F R1 R2 P1 P2 Q`, and
//!   the two ROS files with the rectification);
//! - [`rectify`]: Bouguet's rectification of a stereo pair ([`rectify::stereo_rectify`]).
//!
//! # Conventions
//! Camera frame: z forward, x right, y down. Pixel `(0, 0)` is the centre of the top-left pixel,
//! so the image spans `[-0.5, width - 0.5] x [-0.5, height - 0.5]`; OpenCV and ROS use the same
//! convention, so `cx_px`, `cy_px` are exchanged with them unchanged. Pixels are
//! `u = fx_px x_d + cx_px`, `v = fy_px y_d + cy_px` where `(x_d, y_d)` are the distorted
//! normalised coordinates of the model (equations in the documentation of [`Distortion`]).

pub mod io;
pub mod lens;
pub mod rectify;
mod unproject;
mod yaml;

use nalgebra::{Matrix2x3, Matrix2xX, Point2, Point3};
use serde::{Deserialize, Serialize};

use crate::error::{Result, VisionError};
pub use lens::{Distortion, DistortionKind, LensModel};

/// Focal lengths and principal point, in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// Focal length along x (columns), pixels.
    pub fx_px: f64,
    /// Focal length along y (rows), pixels.
    pub fy_px: f64,
    /// Principal point column, pixel-centre convention (pixel (0, 0) is the top-left centre).
    pub cx_px: f64,
    /// Principal point row, pixel-centre convention.
    pub cy_px: f64,
}

/// Image size in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct ImageSize {
    /// Number of columns.
    pub width_px: u32,
    /// Number of rows.
    pub height_px: u32,
}

/// Unit of a camera parameter.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CameraParamUnit {
    /// Pixels (focal lengths, principal point).
    Pixel,
    /// A pure number (distortion coefficients).
    Dimensionless,
}

/// One entry of a camera's parameter vector.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraParameter {
    /// Stable name: `fx_px`, `fy_px`, `cx_px`, `cy_px`, then the distortion coefficients
    /// (`k1`, `k2`, `p1`, ...) in OpenCV order.
    pub name: &'static str,
    /// Unit of `value`.
    pub unit: CameraParamUnit,
    /// Current value.
    pub value: f64,
}

/// A projection with its analytic Jacobians.
#[derive(Clone, Debug, PartialEq)]
pub struct Projection {
    /// The pixel, pixel-centre convention.
    pub pixel: Point2<f64>,
    /// `d(u, v) / d(X, Y, Z)` of the point in the camera frame, px per metre.
    pub d_pixel_d_point: Matrix2x3<f64>,
    /// `d(u, v) / d(parameters)`, columns in the order of [`CameraModel::parameters`].
    pub d_pixel_d_params: Matrix2xX<f64>,
}

/// A calibrated camera: intrinsics, lens distortion and image size.
///
/// Fields are public for reading and for serde; models built by hand should pass through
/// [`CameraModel::new`] or [`CameraModel::validate`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraModel {
    /// Focal lengths and principal point.
    pub intrinsics: Intrinsics,
    /// Lens distortion.
    pub distortion: Distortion,
    /// Image size.
    pub image_size: ImageSize,
}

fn bad(name: &str, value: f64, reason: &str) -> VisionError {
    VisionError::BadCameraParameter { name: name.to_string(), value, reason: reason.to_string() }
}

impl CameraModel {
    /// Builds and validates a model.
    pub fn new(intrinsics: Intrinsics, distortion: Distortion, image_size: ImageSize) -> Result<Self> {
        let m = Self { intrinsics, distortion, image_size };
        m.validate()?;
        Ok(m)
    }

    /// Checks that focal lengths are positive and finite, the principal point and coefficients
    /// finite and the image non-empty.
    pub fn validate(&self) -> Result<()> {
        let k = &self.intrinsics;
        for (name, v) in [("fx_px", k.fx_px), ("fy_px", k.fy_px)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(bad(name, v, "focal lengths must be positive and finite"));
            }
        }
        for (name, v) in [("cx_px", k.cx_px), ("cy_px", k.cy_px)] {
            if !v.is_finite() {
                return Err(bad(name, v, "not finite"));
            }
        }
        let kind = self.distortion.kind();
        for (name, v) in kind.coefficient_names().iter().zip(self.distortion.coefficients()) {
            if !v.is_finite() {
                return Err(bad(name, v, "not finite"));
            }
        }
        if self.image_size.width_px == 0 || self.image_size.height_px == 0 {
            return Err(bad("image_size", 0.0, "width and height must be at least one pixel"));
        }
        Ok(())
    }

    /// Number of entries of the parameter vector (4 intrinsics plus the distortion coefficients).
    pub fn n_parameters(&self) -> usize {
        4 + self.distortion.kind().coefficient_names().len()
    }

    /// Names, units and values of the parameter vector, in a fixed order:
    /// `fx_px, fy_px, cx_px, cy_px`, then the distortion coefficients in OpenCV order.
    pub fn parameters(&self) -> Vec<CameraParameter> {
        let k = &self.intrinsics;
        let mut out = vec![
            CameraParameter { name: "fx_px", unit: CameraParamUnit::Pixel, value: k.fx_px },
            CameraParameter { name: "fy_px", unit: CameraParamUnit::Pixel, value: k.fy_px },
            CameraParameter { name: "cx_px", unit: CameraParamUnit::Pixel, value: k.cx_px },
            CameraParameter { name: "cy_px", unit: CameraParamUnit::Pixel, value: k.cy_px },
        ];
        let kind = self.distortion.kind();
        for (name, value) in kind.coefficient_names().iter().zip(self.distortion.coefficients()) {
            out.push(CameraParameter { name, unit: CameraParamUnit::Dimensionless, value });
        }
        out
    }

    /// Values of the parameter vector.
    pub fn parameter_values(&self) -> Vec<f64> {
        self.parameters().into_iter().map(|p| p.value).collect()
    }

    /// Index of the parameter called `name` (e.g. `"cx_px"`, `"k2"`).
    pub fn parameter_index(&self, name: &str) -> Option<usize> {
        self.parameters().iter().position(|p| p.name == name)
    }

    /// Replaces every parameter value (order of [`CameraModel::parameters`]); the model is left
    /// unchanged when the values are rejected.
    pub fn set_parameter_values(&mut self, values: &[f64]) -> Result<()> {
        let n = self.n_parameters();
        if values.len() != n {
            return Err(VisionError::ParameterCount { expected: n, got: values.len() });
        }
        let candidate = Self {
            intrinsics: Intrinsics { fx_px: values[0], fy_px: values[1], cx_px: values[2], cy_px: values[3] },
            distortion: Distortion::from_coefficients(self.distortion.kind(), &values[4..])?,
            image_size: self.image_size,
        };
        candidate.validate()?;
        *self = candidate;
        Ok(())
    }

    fn not_projectable(p: &Point3<f64>, reason: &str) -> VisionError {
        VisionError::NotProjectable { x_m: p.x, y_m: p.y, z_m: p.z, reason: reason.to_string() }
    }

    /// Distorted normalised coordinates and their derivatives for a camera-frame point.
    fn distort_point(&self, p: &Point3<f64>) -> Result<lens::Distorted> {
        if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
            return Err(Self::not_projectable(p, "non-finite coordinates"));
        }
        self.distortion.distort([p.x, p.y, p.z]).map_err(|why| Self::not_projectable(p, why))
    }

    /// Projects a point given in the camera frame (metres) to a pixel.
    pub fn project(&self, p_cam: &Point3<f64>) -> Result<Point2<f64>> {
        let d = self.distort_point(p_cam)?;
        let k = &self.intrinsics;
        Ok(Point2::new(k.fx_px * d.xd[0] + k.cx_px, k.fy_px * d.xd[1] + k.cy_px))
    }

    /// Projects the normalised point `(x, y, 1)` (i.e. `X/Z`, `Y/Z`) to a pixel.
    pub fn project_normalized(&self, xn: &Point2<f64>) -> Result<Point2<f64>> {
        self.project(&Point3::new(xn.x, xn.y, 1.0))
    }

    /// Projects a point and returns the analytic Jacobians with respect to the point and to the
    /// parameter vector:
    ///
    /// ```text
    /// d(u,v)/d(X,Y,Z)    = diag(fx, fy) d(x_d, y_d)/d(X, Y, Z)
    /// d(u,v)/d(fx,fy)    = diag(x_d, y_d),   d(u,v)/d(cx,cy) = I
    /// d(u,v)/d(k)        = diag(fx, fy) d(x_d, y_d)/d(k)
    /// ```
    pub fn project_with_jacobians(&self, p_cam: &Point3<f64>) -> Result<Projection> {
        let d = self.distort_point(p_cam)?;
        let k = &self.intrinsics;
        let pixel = Point2::new(k.fx_px * d.xd[0] + k.cx_px, k.fy_px * d.xd[1] + k.cy_px);
        let f = [k.fx_px, k.fy_px];
        let mut j_p = Matrix2x3::zeros();
        for r in 0..2 {
            for c in 0..3 {
                j_p[(r, c)] = f[r] * d.d_point[r][c];
            }
        }
        let n = self.n_parameters();
        let mut j_k = Matrix2xX::zeros(n);
        j_k[(0, 0)] = d.xd[0];
        j_k[(1, 1)] = d.xd[1];
        j_k[(0, 2)] = 1.0;
        j_k[(1, 3)] = 1.0;
        for i in 0..n - 4 {
            j_k[(0, 4 + i)] = f[0] * d.d_coeffs[0][i];
            j_k[(1, 4 + i)] = f[1] * d.d_coeffs[1][i];
        }
        Ok(Projection { pixel, d_pixel_d_point: j_p, d_pixel_d_params: j_k })
    }

    /// The largest angle from the optical axis (radians) up to which the radial part of the
    /// model is strictly increasing (and, for the rational model, its denominator positive),
    /// i.e. the field of view over which projection is one-to-one. [`Distortion::None`],
    /// Brown and rational models are capped at `pi/2`; Kannala-Brandt at `pi`
    /// ([`LensModel::FIELD_LIMIT_RAD`]). Found by a scan in 0.01 degree steps refined by
    /// bisection.
    pub fn max_field_angle_rad(&self) -> f64 {
        let limit = self.distortion.kind().field_limit_rad();
        let ok = |theta: f64| self.distortion.one_to_one_at(theta);
        let step = 0.01f64.to_radians();
        let n = (limit / step).floor() as usize;
        let mut lo = 0.0;
        for i in 1..=n {
            let theta = i as f64 * step;
            if theta >= limit {
                break;
            }
            if !ok(theta) {
                let mut hi = theta;
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if ok(mid) {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                return lo;
            }
            lo = theta;
        }
        limit
    }

    /// Whether a pixel lies inside the image area `[-0.5, w - 0.5] x [-0.5, h - 0.5]`.
    pub fn contains_pixel(&self, pixel: &Point2<f64>) -> bool {
        let w = self.image_size.width_px as f64;
        let h = self.image_size.height_px as f64;
        pixel.x >= -0.5 && pixel.x <= w - 0.5 && pixel.y >= -0.5 && pixel.y <= h - 0.5
    }
}

#[cfg(test)]
mod tests;
