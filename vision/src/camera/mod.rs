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

mod distortion;
pub mod io;
pub mod rectify;
mod unproject;
mod yaml;

use nalgebra::{Matrix2x3, Matrix2xX, Point2, Point3};
use serde::{Deserialize, Serialize};

use crate::error::{Result, VisionError};

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

/// Which lens model, without its coefficients.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DistortionKind {
    /// Ideal pinhole.
    None,
    /// Brown-Conrady, OpenCV's 5 coefficients `k1 k2 p1 p2 k3` (ROS `plumb_bob`).
    Brown5,
    /// OpenCV's rational model, 8 coefficients `k1 k2 p1 p2 k3 k4 k5 k6` (ROS
    /// `rational_polynomial`).
    Rational8,
    /// Kannala-Brandt, OpenCV's `fisheye` model `k1 k2 k3 k4` (ROS `equidistant`).
    KannalaBrandt,
}

impl DistortionKind {
    /// The lens models a camera can be calibrated with (every kind but the ideal pinhole).
    pub const CALIBRATED: [DistortionKind; 3] =
        [DistortionKind::Brown5, DistortionKind::Rational8, DistortionKind::KannalaBrandt];

    /// The model's name on the command line and in the project's files (`none`, `brown5`,
    /// `rational8`, `kannala_brandt`; serde's name).
    pub fn name(self) -> &'static str {
        match self {
            DistortionKind::None => "none",
            DistortionKind::Brown5 => "brown5",
            DistortionKind::Rational8 => "rational8",
            DistortionKind::KannalaBrandt => "kannala_brandt",
        }
    }

    /// The model's other names (ROS `distortion_model`, OpenCV's): read, never written except
    /// the ROS one, the first ([`DistortionKind::ros_name`]).
    pub fn aliases(self) -> &'static [&'static str] {
        match self {
            DistortionKind::None => &[],
            DistortionKind::Brown5 => &["plumb_bob"],
            DistortionKind::Rational8 => &["rational_polynomial"],
            DistortionKind::KannalaBrandt => &["equidistant", "fisheye", "kannala-brandt"],
        }
    }

    /// The ROS `camera_info` `distortion_model` of the model (`plumb_bob` for the pinhole).
    pub fn ros_name(self) -> &'static str {
        self.aliases().first().copied().unwrap_or("plumb_bob")
    }

    /// Names of the coefficients, in OpenCV order.
    pub fn coefficient_names(self) -> &'static [&'static str] {
        match self {
            DistortionKind::None => &[],
            DistortionKind::Brown5 => &["k1", "k2", "p1", "p2", "k3"],
            DistortionKind::Rational8 => &["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"],
            DistortionKind::KannalaBrandt => &["k1", "k2", "k3", "k4"],
        }
    }
}

impl std::str::FromStr for DistortionKind {
    type Err = VisionError;

    /// A model by its name or one of its aliases (see [`DistortionKind::name`]).
    fn from_str(s: &str) -> Result<Self> {
        let all =
            [DistortionKind::None, DistortionKind::Brown5, DistortionKind::Rational8, DistortionKind::KannalaBrandt];
        all.into_iter()
            .find(|k| k.name() == s || k.aliases().contains(&s))
            .ok_or_else(|| VisionError::UnsupportedDistortion { model: s.to_string(), count: 0 })
    }
}

/// A lens-distortion model with its coefficients (all dimensionless).
///
/// Brown-Conrady / rational (OpenCV `projectPoints`): with `x = X/Z`, `y = Y/Z`,
/// `r^2 = x^2 + y^2`,
///
/// ```text
/// R   = (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)
/// x_d = x R + 2 p1 x y + p2 (r^2 + 2 x^2)
/// y_d = y R + p1 (r^2 + 2 y^2) + 2 p2 x y
/// ```
///
/// (`k4 = k5 = k6 = 0` for [`Distortion::Brown5`]). Points need `Z > 0`.
///
/// Kannala-Brandt (OpenCV `fisheye::projectPoints`): with `theta = atan2(sqrt(X^2+Y^2), Z)`,
///
/// ```text
/// theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)
/// (x_d, y_d) = theta_d (X, Y) / sqrt(X^2 + Y^2)
/// ```
///
/// valid for `theta < pi`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "snake_case")]
pub enum Distortion {
    /// Ideal pinhole: `x_d = x`, `y_d = y`.
    None,
    /// Brown-Conrady with 5 coefficients.
    Brown5 {
        /// Radial, `r^2`.
        k1: f64,
        /// Radial, `r^4`.
        k2: f64,
        /// Tangential.
        p1: f64,
        /// Tangential.
        p2: f64,
        /// Radial, `r^6`.
        k3: f64,
    },
    /// Brown-Conrady with OpenCV's rational radial term, 8 coefficients.
    Rational8 {
        /// Radial numerator, `r^2`.
        k1: f64,
        /// Radial numerator, `r^4`.
        k2: f64,
        /// Tangential.
        p1: f64,
        /// Tangential.
        p2: f64,
        /// Radial numerator, `r^6`.
        k3: f64,
        /// Radial denominator, `r^2`.
        k4: f64,
        /// Radial denominator, `r^4`.
        k5: f64,
        /// Radial denominator, `r^6`.
        k6: f64,
    },
    /// Kannala-Brandt (equidistant fisheye) with 4 coefficients.
    KannalaBrandt {
        /// `theta^3` term.
        k1: f64,
        /// `theta^5` term.
        k2: f64,
        /// `theta^7` term.
        k3: f64,
        /// `theta^9` term.
        k4: f64,
    },
}

impl Distortion {
    /// The model without its coefficients.
    pub fn kind(&self) -> DistortionKind {
        match self {
            Distortion::None => DistortionKind::None,
            Distortion::Brown5 { .. } => DistortionKind::Brown5,
            Distortion::Rational8 { .. } => DistortionKind::Rational8,
            Distortion::KannalaBrandt { .. } => DistortionKind::KannalaBrandt,
        }
    }

    /// Coefficients in OpenCV order (empty for [`Distortion::None`]).
    pub fn coefficients(&self) -> Vec<f64> {
        match *self {
            Distortion::None => Vec::new(),
            Distortion::Brown5 { k1, k2, p1, p2, k3 } => vec![k1, k2, p1, p2, k3],
            Distortion::Rational8 { k1, k2, p1, p2, k3, k4, k5, k6 } => vec![k1, k2, p1, p2, k3, k4, k5, k6],
            Distortion::KannalaBrandt { k1, k2, k3, k4 } => vec![k1, k2, k3, k4],
        }
    }

    /// Builds a model from coefficients in OpenCV order; the count must match the kind.
    pub fn from_coefficients(kind: DistortionKind, c: &[f64]) -> Result<Self> {
        let n = kind.coefficient_names().len();
        if c.len() != n {
            return Err(VisionError::ParameterCount { expected: n, got: c.len() });
        }
        for (name, v) in kind.coefficient_names().iter().zip(c) {
            if !v.is_finite() {
                return Err(VisionError::BadCameraParameter {
                    name: (*name).to_string(),
                    value: *v,
                    reason: "not finite".into(),
                });
            }
        }
        Ok(match kind {
            DistortionKind::None => Distortion::None,
            DistortionKind::Brown5 => Distortion::Brown5 { k1: c[0], k2: c[1], p1: c[2], p2: c[3], k3: c[4] },
            DistortionKind::Rational8 => {
                Distortion::Rational8 { k1: c[0], k2: c[1], p1: c[2], p2: c[3], k3: c[4], k4: c[5], k5: c[6], k6: c[7] }
            }
            DistortionKind::KannalaBrandt => Distortion::KannalaBrandt { k1: c[0], k2: c[1], k3: c[2], k4: c[3] },
        })
    }

    /// The starting point of lens model `kind` from this one, for a refit with another model:
    /// the coefficients the two models share carry over (Brown5 and Rational8 share
    /// `k1 k2 p1 p2 k3`; a Rational8 model taken to Brown5 loses `k4 k5 k6`, an approximation),
    /// every other coefficient starts at zero (Kannala-Brandt shares none with the others).
    pub fn converted(&self, kind: DistortionKind) -> Self {
        if self.kind() == kind {
            return *self;
        }
        let b = self.brown_array();
        let shares = matches!(self.kind(), DistortionKind::Brown5 | DistortionKind::Rational8);
        match (kind, shares) {
            (DistortionKind::Brown5, true) => Distortion::Brown5 { k1: b[0], k2: b[1], p1: b[2], p2: b[3], k3: b[4] },
            (DistortionKind::Rational8, true) => {
                Distortion::Rational8 { k1: b[0], k2: b[1], p1: b[2], p2: b[3], k3: b[4], k4: 0.0, k5: 0.0, k6: 0.0 }
            }
            (DistortionKind::None, _) => Distortion::None,
            (DistortionKind::Brown5, false) => Distortion::Brown5 { k1: 0.0, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0 },
            (DistortionKind::Rational8, false) => {
                Distortion::Rational8 { k1: 0.0, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0, k4: 0.0, k5: 0.0, k6: 0.0 }
            }
            (DistortionKind::KannalaBrandt, _) => Distortion::KannalaBrandt { k1: 0.0, k2: 0.0, k3: 0.0, k4: 0.0 },
        }
    }

    /// Brown / rational coefficients padded to `k1 k2 p1 p2 k3 k4 k5 k6`.
    fn brown_array(&self) -> [f64; 8] {
        match *self {
            Distortion::Brown5 { k1, k2, p1, p2, k3 } => [k1, k2, p1, p2, k3, 0.0, 0.0, 0.0],
            Distortion::Rational8 { k1, k2, p1, p2, k3, k4, k5, k6 } => [k1, k2, p1, p2, k3, k4, k5, k6],
            _ => [0.0; 8],
        }
    }
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
    fn distort_point(&self, p: &Point3<f64>) -> Result<distortion::Distorted> {
        if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
            return Err(Self::not_projectable(p, "non-finite coordinates"));
        }
        match self.distortion {
            Distortion::KannalaBrandt { k1, k2, k3, k4 } => distortion::kb_point(&[k1, k2, k3, k4], [p.x, p.y, p.z])
                .ok_or_else(|| Self::not_projectable(p, "at the centre of projection or on the negative optical axis")),
            _ => {
                if p.z <= 0.0 {
                    return Err(Self::not_projectable(p, "behind the camera (z <= 0); this model needs z > 0"));
                }
                distortion::brown_point(&self.distortion.brown_array(), [p.x, p.y, p.z])
                    .ok_or_else(|| Self::not_projectable(p, "rational distortion denominator is not positive"))
            }
        }
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
    /// Brown and rational models are capped at `pi/2`; Kannala-Brandt at `pi`. Found by a scan
    /// in 0.01 degree steps refined by bisection.
    pub fn max_field_angle_rad(&self) -> f64 {
        use std::f64::consts::{FRAC_PI_2, PI};
        let (limit, ok): (f64, Box<dyn Fn(f64) -> bool>) = match self.distortion {
            Distortion::None => return FRAC_PI_2,
            Distortion::KannalaBrandt { k1, k2, k3, k4 } => {
                (PI, Box::new(move |theta: f64| distortion::kb_theta_d(&[k1, k2, k3, k4], theta).1 > 0.0))
            }
            _ => {
                let c = self.distortion.brown_array();
                (
                    FRAC_PI_2,
                    Box::new(move |theta: f64| {
                        let r = theta.tan();
                        brown_radial_increasing(&c, r * r)
                    }),
                )
            }
        };
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

/// Whether the radial part `r R(r^2)` of a Brown / rational model is increasing at `a = r^2`
/// (with a positive rational denominator): `d(r R)/dr = R + 2 a dR/da > 0`.
fn brown_radial_increasing(c: &[f64; 8], a: f64) -> bool {
    let num = 1.0 + c[0] * a + c[1] * a * a + c[4] * a * a * a;
    let den = 1.0 + c[5] * a + c[6] * a * a + c[7] * a * a * a;
    if den <= 0.0 || !den.is_finite() {
        return false;
    }
    let dnum = c[0] + 2.0 * c[1] * a + 3.0 * c[4] * a * a;
    let dden = c[5] + 2.0 * c[6] * a + 3.0 * c[7] * a * a;
    let radial = num / den;
    let dr_da = (dnum * den - num * dden) / (den * den);
    radial > 0.0 && radial + 2.0 * a * dr_da > 0.0
}

#[cfg(test)]
mod tests;
