//! The lens models: one file per model implementing [`LensModel`], listed once in
//! [`lens_models!`] below, which generates [`DistortionKind`], [`Distortion`] and the dispatch
//! from a model's value to its file. Everything else (the command line's `--model`, the
//! parameter vector and its names, every solver and residual, the OpenCV and ROS files, the
//! reports) reads the model through these, so adding a lens model is a file with its
//! equations and one line in the list.
//!
//! Every map works on *normalised* coordinates (metric image plane at unit distance, no focal
//! length, no principal point); the pixel step `u = fx x_d + cx`, `v = fy y_d + cy` lives in
//! [`super::CameraModel`].

mod brown;
mod kannala_brandt;
mod newton;
mod pinhole;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

pub use brown::{Brown5, Rational8};
pub use kannala_brandt::KannalaBrandt;
pub use pinhole::Pinhole;

/// Value and derivatives of a lens map at one camera-frame point.
#[derive(Clone, Copy, Debug, Default)]
pub struct Distorted {
    /// Distorted normalised coordinates `(x_d, y_d)`.
    pub xd: [f64; 2],
    /// `d(x_d, y_d) / d(X, Y, Z)` (row-major, 2 x 3).
    pub d_point: [[f64; 3]; 2],
    /// `d(x_d, y_d) / d(coefficients)`, coefficients in OpenCV order; only the model's first
    /// `n` columns are meaningful.
    pub d_coeffs: [[f64; 8]; 2],
}

/// Why the inverse of a lens map failed at a pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Unprojection {
    /// Newton iterations run.
    pub iterations: usize,
    /// Reprojection residual left, pixels.
    pub residual_px: f64,
    /// Why, in words.
    pub reason: &'static str,
}

/// A lens model: its names, its coefficients (at most 8, in OpenCV order, all dimensionless),
/// the map from a camera-frame point to distorted normalised coordinates with its derivatives,
/// the inverse, and the field over which the map is one-to-one.
pub trait LensModel {
    /// The name on the command line and in the project's files (serde's name of the variant).
    const NAME: &'static str;
    /// Other names read (ROS `distortion_model`, OpenCV's); the first is written to ROS files.
    const ALIASES: &'static [&'static str];
    /// The coefficients' names, in OpenCV order.
    const COEFFICIENTS: &'static [&'static str];
    /// Models of one family share the meaning of equally named coefficients, which carry over
    /// when a fit changes model ([`Distortion::converted`]).
    const FAMILY: &'static str;
    /// Whether a camera can be calibrated with it (`camera calibrate --model`).
    const CALIBRATED: bool;
    /// The largest field angle the model describes, radians (`pi/2` for maps through `X/Z`).
    const FIELD_LIMIT_RAD: f64;

    /// The map of the camera-frame point `p` (metres; finite) with coefficients `c`, or why
    /// the point cannot be projected.
    fn distort(c: &[f64], p: [f64; 3]) -> Result<Distorted, &'static str>;

    /// Whether the map is still one-to-one (radially increasing) at the field angle `theta_rad`.
    fn one_to_one_at(c: &[f64], theta_rad: f64) -> bool;

    /// The normalised point `(X/Z, Y/Z)` whose image is the distorted point `xd`; `f_px` are
    /// the focal lengths, in which the inverse's residual is measured.
    fn unproject_normalized(c: &[f64], xd: [f64; 2], f_px: [f64; 2]) -> Result<[f64; 2], Unprojection>;

    /// The unit ray whose image is the distorted point `xd` (for models that reach beyond 90
    /// degrees, the only form of the inverse that always exists).
    fn unproject_ray(c: &[f64], xd: [f64; 2], f_px: [f64; 2]) -> Result<Vector3<f64>, Unprojection> {
        let n = Self::unproject_normalized(c, xd, f_px)?;
        Ok(Vector3::new(n[0], n[1], 1.0).normalize())
    }
}

/// The names and flags of one model, as [`DistortionKind`] hands them out.
struct LensInfo {
    name: &'static str,
    aliases: &'static [&'static str],
    coefficients: &'static [&'static str],
    family: &'static str,
    calibrated: bool,
    field_limit_rad: f64,
}

impl LensInfo {
    const fn of<M: LensModel>() -> Self {
        Self {
            name: M::NAME,
            aliases: M::ALIASES,
            coefficients: M::COEFFICIENTS,
            family: M::FAMILY,
            calibrated: M::CALIBRATED,
            field_limit_rad: M::FIELD_LIMIT_RAD,
        }
    }
}

/// Declares the lens models: for each, the variant (with its documentation), the type that
/// implements [`LensModel`], and its coefficients' fields in OpenCV order (none for a model
/// without coefficients).
macro_rules! lens_models {
    ($( $(#[$doc:meta])* $variant:ident => $model:ty $({ $( $(#[$fdoc:meta])* $field:ident ),* $(,)? })? ),* $(,)?) => {
        /// Which lens model, without its coefficients.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
        #[serde(rename_all = "snake_case")]
        pub enum DistortionKind {
            $( $(#[$doc])* $variant, )*
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
        /// Kannala-Brandt (OpenCV `fisheye::projectPoints`): with
        /// `theta = atan2(sqrt(X^2+Y^2), Z)`,
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
            $( $(#[$doc])* $variant $({ $( $(#[$fdoc])* $field: f64, )* })?, )*
        }

        impl DistortionKind {
            /// Every lens model, in the order of the list.
            pub const ALL: &'static [DistortionKind] = &[$(DistortionKind::$variant),*];

            fn info(self) -> &'static LensInfo {
                match self {
                    $( DistortionKind::$variant => {
                        const INFO: LensInfo = LensInfo::of::<$model>();
                        &INFO
                    } )*
                }
            }
        }

        impl Distortion {
            /// The model without its coefficients.
            pub fn kind(&self) -> DistortionKind {
                match self {
                    $( Distortion::$variant $({ $( $field: _ ),* })? => DistortionKind::$variant, )*
                }
            }

            /// `f` of the coefficients in OpenCV order (no allocation).
            fn with_coefficients<R>(&self, f: impl FnOnce(&[f64]) -> R) -> R {
                match *self {
                    $( Distortion::$variant $({ $( $field ),* })? => f(&[$($( $field ),*)?]), )*
                }
            }

            /// The model `kind` with the coefficients `c` (OpenCV order, as many as the model
            /// has; checked by the caller).
            fn from_slice(kind: DistortionKind, c: &[f64]) -> Self {
                #[allow(unused_variables, unused_mut)]
                let mut it = c.iter().copied();
                match kind {
                    $( DistortionKind::$variant => Distortion::$variant $({ $( $field: it.next().unwrap_or(0.0) ),* })?, )*
                }
            }

            /// The model's map of the camera-frame point `p`.
            pub(crate) fn distort(&self, p: [f64; 3]) -> Result<Distorted, &'static str> {
                match *self {
                    $( Distortion::$variant $({ $( $field ),* })? => <$model as LensModel>::distort(&[$($( $field ),*)?], p), )*
                }
            }

            /// Whether the map is one-to-one at the field angle `theta_rad`.
            pub(crate) fn one_to_one_at(&self, theta_rad: f64) -> bool {
                match *self {
                    $( Distortion::$variant $({ $( $field ),* })? => <$model as LensModel>::one_to_one_at(&[$($( $field ),*)?], theta_rad), )*
                }
            }

            /// The normalised point of the distorted point `xd` ([`LensModel::unproject_normalized`]).
            pub(crate) fn unproject_normalized(&self, xd: [f64; 2], f_px: [f64; 2]) -> Result<[f64; 2], Unprojection> {
                match *self {
                    $( Distortion::$variant $({ $( $field ),* })? => <$model as LensModel>::unproject_normalized(&[$($( $field ),*)?], xd, f_px), )*
                }
            }

            /// The unit ray of the distorted point `xd` ([`LensModel::unproject_ray`]).
            pub(crate) fn unproject_ray(&self, xd: [f64; 2], f_px: [f64; 2]) -> Result<Vector3<f64>, Unprojection> {
                match *self {
                    $( Distortion::$variant $({ $( $field ),* })? => <$model as LensModel>::unproject_ray(&[$($( $field ),*)?], xd, f_px), )*
                }
            }
        }
    };
}

// The lens models. A new one: a file beside this one with its `LensModel`, and a line here.
lens_models! {
    /// Ideal pinhole: `x_d = x`, `y_d = y`.
    None => Pinhole,
    /// Brown-Conrady, OpenCV's 5 coefficients `k1 k2 p1 p2 k3` (ROS `plumb_bob`).
    Brown5 => Brown5 {
        /// Radial, `r^2`.
        k1,
        /// Radial, `r^4`.
        k2,
        /// Tangential.
        p1,
        /// Tangential.
        p2,
        /// Radial, `r^6`.
        k3,
    },
    /// OpenCV's rational model, 8 coefficients `k1 k2 p1 p2 k3 k4 k5 k6` (ROS
    /// `rational_polynomial`).
    Rational8 => Rational8 {
        /// Radial numerator, `r^2`.
        k1,
        /// Radial numerator, `r^4`.
        k2,
        /// Tangential.
        p1,
        /// Tangential.
        p2,
        /// Radial numerator, `r^6`.
        k3,
        /// Radial denominator, `r^2`.
        k4,
        /// Radial denominator, `r^4`.
        k5,
        /// Radial denominator, `r^6`.
        k6,
    },
    /// Kannala-Brandt, OpenCV's `fisheye` model `k1 k2 k3 k4` (ROS `equidistant`).
    KannalaBrandt => KannalaBrandt {
        /// `theta^3` term.
        k1,
        /// `theta^5` term.
        k2,
        /// `theta^7` term.
        k3,
        /// `theta^9` term.
        k4,
    },
}

impl DistortionKind {
    /// The model's name on the command line and in the project's files (`none`, `brown5`,
    /// `rational8`, `kannala_brandt`; serde's name).
    pub fn name(self) -> &'static str {
        self.info().name
    }

    /// The model's other names (ROS `distortion_model`, OpenCV's): read, never written except
    /// the ROS one, the first ([`DistortionKind::ros_name`]).
    pub fn aliases(self) -> &'static [&'static str] {
        self.info().aliases
    }

    /// The ROS `camera_info` `distortion_model` of the model (`plumb_bob` for the pinhole).
    pub fn ros_name(self) -> &'static str {
        self.aliases().first().copied().unwrap_or("plumb_bob")
    }

    /// Names of the coefficients, in OpenCV order.
    pub fn coefficient_names(self) -> &'static [&'static str] {
        self.info().coefficients
    }

    /// The lens models a camera can be calibrated with (every kind but the ideal pinhole).
    pub fn calibrated_kinds() -> impl Iterator<Item = DistortionKind> {
        DistortionKind::ALL.iter().copied().filter(|k| k.info().calibrated)
    }

    /// A lens model a camera can be calibrated with ([`DistortionKind::calibrated_kinds`]), by
    /// name or alias; anything else (the ideal pinhole included) is refused with the choices.
    pub fn calibrated(s: &str) -> Result<Self, String> {
        match s.parse::<DistortionKind>() {
            Ok(k) if k.info().calibrated => Ok(k),
            _ => {
                let names: Vec<&str> = DistortionKind::calibrated_kinds().map(|k| k.name()).collect();
                Err(format!("'{s}' is not a lens model; use one of {}", names.join(", ")))
            }
        }
    }

    /// The largest field angle the model describes, radians ([`LensModel::FIELD_LIMIT_RAD`]).
    pub(crate) fn field_limit_rad(self) -> f64 {
        self.info().field_limit_rad
    }

    /// Whether coefficients of this model and of `other` with one name mean the same.
    pub(crate) fn same_family(self, other: DistortionKind) -> bool {
        self.info().family == other.info().family
    }
}

impl std::str::FromStr for DistortionKind {
    type Err = crate::error::VisionError;

    /// A model by its name or one of its aliases (see [`DistortionKind::name`]).
    fn from_str(s: &str) -> crate::error::Result<Self> {
        DistortionKind::ALL
            .iter()
            .copied()
            .find(|k| k.name() == s || k.aliases().contains(&s))
            .ok_or_else(|| crate::error::VisionError::UnsupportedDistortion { model: s.to_string(), count: 0 })
    }
}

impl Distortion {
    /// Coefficients in OpenCV order (empty for [`Distortion::None`]).
    pub fn coefficients(&self) -> Vec<f64> {
        self.with_coefficients(|c| c.to_vec())
    }

    /// Builds a model from coefficients in OpenCV order; the count must match the kind.
    pub fn from_coefficients(kind: DistortionKind, c: &[f64]) -> crate::error::Result<Self> {
        use crate::error::VisionError;
        let names = kind.coefficient_names();
        if c.len() != names.len() {
            return Err(VisionError::ParameterCount { expected: names.len(), got: c.len() });
        }
        if let Some((name, v)) = names.iter().zip(c).find(|(_, v)| !v.is_finite()) {
            let reason = "not finite".into();
            return Err(VisionError::BadCameraParameter { name: (*name).to_string(), value: *v, reason });
        }
        Ok(Distortion::from_slice(kind, c))
    }

    /// The starting point of lens model `kind` from this one, for a refit with another model:
    /// the coefficients the two models share carry over (models of one family, e.g. Brown5
    /// and Rational8, share `k1 k2 p1 p2 k3`; a Rational8 model taken to Brown5 loses
    /// `k4 k5 k6`, an approximation), every other coefficient starts at zero (Kannala-Brandt
    /// shares none with the others).
    pub fn converted(&self, kind: DistortionKind) -> Self {
        let from = self.kind();
        if from == kind {
            return *self;
        }
        let (old_names, old) = (from.coefficient_names(), self.coefficients());
        let family = from.same_family(kind);
        let shared = |name: &str| old_names.iter().position(|n| *n == name).map_or(0.0, |i| old[i]);
        let c: Vec<f64> = kind.coefficient_names().iter().map(|n| if family { shared(n) } else { 0.0 }).collect();
        Distortion::from_slice(kind, &c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The names a model declares are serde's names of its variants (files written with one are
    /// read with the other), and every model's coefficients round-trip.
    #[test]
    fn every_model_is_named_as_serde_names_it_and_its_coefficients_round_trip() {
        for &k in DistortionKind::ALL {
            let serde_name = serde_json::to_value(k).unwrap();
            assert_eq!(serde_name, serde_json::Value::String(k.name().into()), "{k:?}");
            assert_eq!(k.name().parse::<DistortionKind>().unwrap(), k);
            let c: Vec<f64> = (0..k.coefficient_names().len()).map(|i| 0.01 * (i as f64 + 1.0)).collect();
            let d = Distortion::from_coefficients(k, &c).unwrap();
            assert_eq!(d.kind(), k);
            assert_eq!(d.coefficients(), c);
            let j = serde_json::to_value(d).unwrap();
            assert_eq!(j["model"], serde_json::Value::String(k.name().into()));
            assert_eq!(serde_json::from_value::<Distortion>(j).unwrap(), d);
        }
        assert!(Distortion::from_coefficients(DistortionKind::Brown5, &[0.0; 4]).is_err());
        assert!(DistortionKind::calibrated("none").is_err() && DistortionKind::calibrated("fisheye").is_ok());
    }

    /// Brown5 and Rational8 share their five coefficients; Kannala-Brandt shares nothing.
    #[test]
    fn a_refit_with_another_model_starts_from_the_coefficients_the_models_share() {
        let b = Distortion::Brown5 { k1: 0.1, k2: 0.2, p1: 0.3, p2: 0.4, k3: 0.5 };
        let r = b.converted(DistortionKind::Rational8);
        assert_eq!(r.coefficients(), vec![0.1, 0.2, 0.3, 0.4, 0.5, 0.0, 0.0, 0.0]);
        assert_eq!(r.converted(DistortionKind::Brown5), b);
        assert_eq!(b.converted(DistortionKind::KannalaBrandt).coefficients(), vec![0.0; 4]);
        assert_eq!(b.converted(DistortionKind::None), Distortion::None);
    }
}
