//! Brown-Conrady with the rational radial term (OpenCV `k1 k2 p1 p2 k3 k4 k5 k6`; the
//! five-coefficient model is the same with `k4 = k5 = k6 = 0`). For a point `(X, Y, Z)` with
//! `Z > 0`: `x = X / Z`, `y = Y / Z`, `r^2 = x^2 + y^2`,
//!
//! ```text
//! R   = (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)
//! x_d = x R + 2 p1 x y + p2 (r^2 + 2 x^2)
//! y_d = y R + p1 (r^2 + 2 y^2) + 2 p2 x y
//! ```
//!
//! The inverse is Newton's method on the analytic 2 x 2 Jacobian, started at the distorted
//! point, with step halving when the residual grows.

use std::f64::consts::FRAC_PI_2;

use super::newton::{damped_newton, Solved};
use super::{Distorted, LensModel, Unprojection};

/// OpenCV's five coefficients `k1 k2 p1 p2 k3` (ROS `plumb_bob`).
#[derive(Clone, Copy, Debug)]
pub struct Brown5;

/// OpenCV's rational model, `k1 k2 p1 p2 k3 k4 k5 k6` (ROS `rational_polynomial`).
#[derive(Clone, Copy, Debug)]
pub struct Rational8;

/// Coefficients padded to `k1 k2 p1 p2 k3 k4 k5 k6`.
pub(super) fn padded(c: &[f64]) -> [f64; 8] {
    let mut a = [0.0; 8];
    a[..c.len()].copy_from_slice(c);
    a
}

/// The [`LensModel`] of a model of the Brown family: its names; the maps are the rational one
/// with the coefficients it lacks at zero.
macro_rules! brown_model {
    ($model:ident, $name:literal, $ros:literal, [$($coefficient:literal),*]) => {
        impl LensModel for $model {
            const NAME: &'static str = $name;
            const ALIASES: &'static [&'static str] = &[$ros];
            const COEFFICIENTS: &'static [&'static str] = &[$($coefficient),*];
            const FAMILY: &'static str = "brown";
            const CALIBRATED: bool = true;
            const FIELD_LIMIT_RAD: f64 = FRAC_PI_2;

            fn distort(c: &[f64], p: [f64; 3]) -> Result<Distorted, &'static str> {
                distort(&padded(c), p)
            }

            fn one_to_one_at(c: &[f64], theta_rad: f64) -> bool {
                let r = theta_rad.tan();
                radial_increasing(&padded(c), r * r)
            }

            fn unproject_normalized(c: &[f64], xd: [f64; 2], f_px: [f64; 2]) -> Result<[f64; 2], Unprojection> {
                invert(&padded(c), xd, f_px)
            }
        }
    };
}

brown_model!(Brown5, "brown5", "plumb_bob", ["k1", "k2", "p1", "p2", "k3"]);
brown_model!(Rational8, "rational8", "rational_polynomial", ["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"]);

/// The map of a camera-frame point through `X/Z` (needs `Z > 0`).
pub(super) fn distort(c: &[f64; 8], p: [f64; 3]) -> Result<Distorted, &'static str> {
    if p[2] <= 0.0 {
        return Err("behind the camera (z <= 0); this model needs z > 0");
    }
    point(c, p).ok_or("rational distortion denominator is not positive")
}

/// Result of [`normalized`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct BrownResult {
    /// Distorted normalised point.
    pub xd: [f64; 2],
    /// `d(x_d, y_d)/d(x, y)`.
    pub j_xy: [[f64; 2]; 2],
    /// `d(x_d, y_d)/d(k1 k2 p1 p2 k3 k4 k5 k6)`.
    pub j_c: [[f64; 8]; 2],
}

/// Brown-Conrady / rational map of the undistorted normalised point `(x, y)`.
/// `c` holds `k1 k2 p1 p2 k3 k4 k5 k6`. Returns `(x_d, y_d)`, `d(x_d,y_d)/d(x,y)` and
/// `d(x_d,y_d)/d(c)`. `None` when the rational denominator is not positive.
pub(crate) fn normalized(c: &[f64; 8], x: f64, y: f64) -> Option<BrownResult> {
    let [k1, k2, p1, p2, k3, k4, k5, k6] = *c;
    let a = x * x + y * y;
    let a2 = a * a;
    let a3 = a2 * a;
    let num = 1.0 + k1 * a + k2 * a2 + k3 * a3;
    let den = 1.0 + k4 * a + k5 * a2 + k6 * a3;
    if den <= 0.0 || !den.is_finite() {
        return None;
    }
    let inv_den = 1.0 / den;
    let radial = num * inv_den;
    // dR/da = (N' D - N D') / D^2
    let dnum = k1 + 2.0 * k2 * a + 3.0 * k3 * a2;
    let dden = k4 + 2.0 * k5 * a + 3.0 * k6 * a2;
    let dr_da = (dnum * den - num * dden) * inv_den * inv_den;
    let xy = x * y;
    let xd = x * radial + 2.0 * p1 * xy + p2 * (a + 2.0 * x * x);
    let yd = y * radial + p1 * (a + 2.0 * y * y) + 2.0 * p2 * xy;

    let j_xy = [
        [radial + 2.0 * x * x * dr_da + 2.0 * p1 * y + 6.0 * p2 * x, 2.0 * xy * dr_da + 2.0 * p1 * x + 2.0 * p2 * y],
        [2.0 * xy * dr_da + 2.0 * p1 * x + 2.0 * p2 * y, radial + 2.0 * y * y * dr_da + 6.0 * p1 * y + 2.0 * p2 * x],
    ];
    // dR/dk: numerator coefficients a^i / D, denominator coefficients -N a^i / D^2.
    let dr_dk1 = a * inv_den;
    let dr_dk2 = a2 * inv_den;
    let dr_dk3 = a3 * inv_den;
    let nd2 = num * inv_den * inv_den;
    let dr_dk4 = -a * nd2;
    let dr_dk5 = -a2 * nd2;
    let dr_dk6 = -a3 * nd2;
    let j_c = [
        [x * dr_dk1, x * dr_dk2, 2.0 * xy, a + 2.0 * x * x, x * dr_dk3, x * dr_dk4, x * dr_dk5, x * dr_dk6],
        [y * dr_dk1, y * dr_dk2, a + 2.0 * y * y, 2.0 * xy, y * dr_dk3, y * dr_dk4, y * dr_dk5, y * dr_dk6],
    ];
    Some(BrownResult { xd: [xd, yd], j_xy, j_c })
}

/// Brown-Conrady / rational map of a 3D point (requires `Z > 0`, checked by the caller).
fn point(c: &[f64; 8], p: [f64; 3]) -> Option<Distorted> {
    let inv_z = 1.0 / p[2];
    let x = p[0] * inv_z;
    let y = p[1] * inv_z;
    let b = normalized(c, x, y)?;
    // d(x, y)/d(X, Y, Z) = [[1/Z, 0, -x/Z], [0, 1/Z, -y/Z]]
    let mut d_point = [[0.0; 3]; 2];
    for (row, j) in d_point.iter_mut().zip(b.j_xy.iter()) {
        row[0] = j[0] * inv_z;
        row[1] = j[1] * inv_z;
        row[2] = -(j[0] * x + j[1] * y) * inv_z;
    }
    Some(Distorted { xd: b.xd, d_point, d_coeffs: b.j_c })
}

/// Whether the radial part `r R(r^2)` of a Brown / rational model is increasing at `a = r^2`
/// (with a positive rational denominator): `d(r R)/dr = R + 2 a dR/da > 0`.
pub(super) fn radial_increasing(c: &[f64; 8], a: f64) -> bool {
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

/// The normalised point whose image is `target` (distorted normalised coordinates), by Newton's
/// method; the residual is measured in pixels through the focal lengths `f_px`. Fails when the
/// residual stays above 1e-10 px or the solution lies beyond a fold of the map.
fn invert(c: &[f64; 8], target: [f64; 2], f_px: [f64; 2]) -> Result<[f64; 2], Unprojection> {
    let fail = |iterations, residual_px, reason| Unprojection { iterations, residual_px, reason };
    let [fx, fy] = f_px;
    // The state at a point: the model there and the residual in normalised coordinates.
    let eval = |x: [f64; 2]| -> Option<((BrownResult, [f64; 2]), f64)> {
        let b = normalized(c, x[0], x[1])?;
        let r = [b.xd[0] - target[0], b.xd[1] - target[1]];
        let res_px = (fx * r[0]).hypot(fy * r[1]);
        Some(((b, r), res_px))
    };
    let (start, res_px) = eval(target).ok_or_else(|| fail(0, f64::NAN, "rational denominator <= 0"))?;
    let direction = |(b, r): &(BrownResult, [f64; 2])| {
        let j = b.j_xy;
        let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
        if det.abs() < 1e-300 || !det.is_finite() {
            return Err("singular distortion Jacobian");
        }
        Ok([(j[1][1] * r[0] - j[0][1] * r[1]) / det, (-j[1][0] * r[0] + j[0][0] * r[1]) / det])
    };
    let Solved { x, state: (b, _), res_px, iterations } = damped_newton(
        (target, start, res_px),
        eval,
        direction,
        |x, d, step| [x[0] - step * d[0], x[1] - step * d[1]],
        "Newton iteration did not reach 1e-10 px (pixel outside the model's invertible region?)",
    )?;
    // The solution must lie on the branch that contains the principal point: the radial
    // map must increase all the way from the centre to it (checked at 64 radii).
    let a = x[0] * x[0] + x[1] * x[1];
    let on_branch = (1..=64).all(|i| radial_increasing(c, a * i as f64 / 64.0));
    let j = b.j_xy;
    if !on_branch || j[0][0] * j[1][1] - j[0][1] * j[1][0] <= 0.0 {
        return Err(fail(iterations, res_px, "solution lies beyond a fold of the distortion (not invertible there)"));
    }
    Ok(x)
}
