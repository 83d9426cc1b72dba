//! The target's departure from its nominal geometry, shared by every view of one physical
//! target: a bent plate (bowl, saddle, twist) and a printed pattern whose spacing is scaled
//! differently along the target's x and y axes.
//!
//! With `(x0, y0)` the centroid of the nominal points, `(dx, dy) = (x - x0, y - y0)` a nominal
//! point's in-plane offset and `h` the target's half-size (the largest `|dx|` or `|dy|` over its
//! points), `u = dx / h`, `v = dy / h`, the point that the camera sees is
//!
//! ```text
//! x' = x0 + (1 + e_x) dx
//! y' = y0 + (1 + e_y) dy
//! z' = z  + b (u^2 + v^2) + s (u^2 - v^2) + t u v
//! ```
//!
//! `b`, `s`, `t` are the sags (metres) of a bowl, a saddle and a twist at the target's edge;
//! `e_x`, `e_y` the relative errors of the printed spacing. The bending is a function of the
//! nominal position (the difference from the printed one is of second order). Scaling about the
//! centroid keeps the scale from trading with a pose's translation; the in-plane position over
//! the half-size keeps the bending from trading with a pose's tilt only approximately (a pose
//! absorbs a plane, the bending terms are quadratic).
//!
//! Only the ratio `(1 + e_x) / (1 + e_y)` shows in images: an overall scale of the target trades
//! exactly with the distance of every view. The bundle adjustment therefore estimates `e_x` with
//! `e_y` held at its given value (zero unless the caller knows better): the estimated `e_x` is the
//! printed x spacing relative to the y spacing, `e_x - e_y` to first order.

use nalgebra::{Matrix3, Point3, Vector3};

use crate::error::{Result, VisionError};

/// The deformation of one target (see the module documentation), with which of its parameters
/// the adjustment estimates.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TargetDeformation {
    /// Centroid `(x0, y0)` of the nominal points, metres.
    pub centre_m: [f64; 2],
    /// Half-size `h`, metres.
    pub half_m: f64,
    /// `[b, s, t]`, metres.
    pub shape_m: [f64; 3],
    /// `[e_x, e_y]`, dimensionless.
    pub scale: [f64; 2],
    /// Whether `[b, s, t]` is a free block.
    pub shape_free: bool,
    /// Whether `e_x` is a free block (`e_y` is always held).
    pub scale_free: bool,
}

/// A deformed point with its derivatives.
#[derive(Clone, Copy, Debug)]
pub struct Deformed {
    /// The point in the target frame, metres.
    pub point: Point3<f64>,
    /// `d point / d [b, s, t]`.
    pub d_shape: Matrix3<f64>,
    /// `d point / d e_x`.
    pub d_scale_x: Vector3<f64>,
}

impl TargetDeformation {
    /// The centroid and half-size of a target's nominal points, with no deformation; an error
    /// unless every point lies in the target's `z = 0` plane (the axes the deformation is
    /// defined on).
    pub fn of_points(points_m: &[Point3<f64>]) -> Result<Self> {
        if points_m.is_empty() {
            return Err(VisionError::InvalidInput { detail: "a target needs points".into() });
        }
        if let Some((i, p)) = points_m.iter().enumerate().find(|(_, p)| p.z != 0.0) {
            return Err(VisionError::InvalidInput {
                detail: format!(
                    "target point {i} lies at z = {} m: the target-shape and print-scale blocks are defined on a \
                     target whose points lie in its z = 0 plane",
                    p.z
                ),
            });
        }
        let n = points_m.len() as f64;
        let (sx, sy) = points_m.iter().fold((0.0, 0.0), |(a, b), p| (a + p.x, b + p.y));
        let centre_m = [sx / n, sy / n];
        let half_m =
            points_m.iter().map(|p| (p.x - centre_m[0]).abs().max((p.y - centre_m[1]).abs())).fold(1e-9, f64::max);
        Ok(Self { centre_m, half_m, shape_m: [0.0; 3], scale: [0.0; 2], shape_free: false, scale_free: false })
    }

    /// The deformed point of the nominal point `p` with shape `[b, s, t]` and `e_x` (the held
    /// `e_y` from `self`).
    pub fn apply(&self, p: &Point3<f64>, shape_m: &[f64], scale_x: f64) -> Deformed {
        let (dx, dy) = (p.x - self.centre_m[0], p.y - self.centre_m[1]);
        let (u, v) = (dx / self.half_m, dy / self.half_m);
        let basis = [u * u + v * v, u * u - v * v, u * v];
        let z = p.z + shape_m[0] * basis[0] + shape_m[1] * basis[1] + shape_m[2] * basis[2];
        let point =
            Point3::new(self.centre_m[0] + (1.0 + scale_x) * dx, self.centre_m[1] + (1.0 + self.scale[1]) * dy, z);
        let mut d_shape = Matrix3::zeros();
        for (c, b) in basis.iter().enumerate() {
            d_shape[(2, c)] = *b;
        }
        Deformed { point, d_shape, d_scale_x: Vector3::new(dx, 0.0, 0.0) }
    }

    /// The deformed point at the current values.
    pub fn point(&self, p: &Point3<f64>) -> Point3<f64> {
        self.apply(p, &self.shape_m, self.scale[0]).point
    }

    /// Number of free coordinates.
    pub fn n_free(&self) -> usize {
        3 * usize::from(self.shape_free) + usize::from(self.scale_free)
    }
}
