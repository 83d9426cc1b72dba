//! Kannala-Brandt (OpenCV `fisheye`, `k1..k4`): `rho = sqrt(X^2 + Y^2)`,
//! `theta = atan2(rho, Z)` (the angle from the optical axis),
//!
//! ```text
//! theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)
//! x_d = (theta_d / rho) X,   y_d = (theta_d / rho) Y
//! ```
//!
//! which equals OpenCV's `fisheye::projectPoints` for `Z > 0` and continues it to
//! `theta < pi`. The inverse is Newton's method on `theta_d(theta)`.

use std::f64::consts::PI;

use nalgebra::Vector3;

use super::newton::{damped_newton, Solved};
use super::{Distorted, LensModel, Unprojection};

/// OpenCV's fisheye model (ROS `equidistant`).
#[derive(Clone, Copy, Debug)]
pub struct KannalaBrandt;

fn four(c: &[f64]) -> [f64; 4] {
    [c[0], c[1], c[2], c[3]]
}

impl LensModel for KannalaBrandt {
    const NAME: &'static str = "kannala_brandt";
    const ALIASES: &'static [&'static str] = &["equidistant", "fisheye", "kannala-brandt"];
    const COEFFICIENTS: &'static [&'static str] = &["k1", "k2", "k3", "k4"];
    const FAMILY: &'static str = "kannala_brandt";
    const CALIBRATED: bool = true;
    const FIELD_LIMIT_RAD: f64 = PI;

    fn distort(c: &[f64], p: [f64; 3]) -> Result<Distorted, &'static str> {
        point(&four(c), p).ok_or("at the centre of projection or on the negative optical axis")
    }

    fn one_to_one_at(c: &[f64], theta_rad: f64) -> bool {
        theta_d(&four(c), theta_rad).1 > 0.0
    }

    fn unproject_ray(c: &[f64], xd: [f64; 2], f_px: [f64; 2]) -> Result<Vector3<f64>, Unprojection> {
        let t_d = xd[0].hypot(xd[1]);
        if t_d == 0.0 {
            return Ok(Vector3::new(0.0, 0.0, 1.0));
        }
        let theta = invert(&four(c), xd, t_d, f_px)?;
        let s = theta.sin() / t_d;
        Ok(Vector3::new(s * xd[0], s * xd[1], theta.cos()))
    }

    fn unproject_normalized(c: &[f64], xd: [f64; 2], f_px: [f64; 2]) -> Result<[f64; 2], Unprojection> {
        let ray = Self::unproject_ray(c, xd, f_px)?;
        if ray.z <= 0.0 {
            let reason = "the ray points at or behind the image plane (theta >= 90 deg)";
            return Err(Unprojection { iterations: 0, residual_px: 0.0, reason });
        }
        Ok([ray.x / ray.z, ray.y / ray.z])
    }
}

/// `theta (1 + k1 theta^2 + ... + k4 theta^8)` and its derivative in `theta`.
fn theta_d(k: &[f64; 4], theta: f64) -> (f64, f64) {
    let t2 = theta * theta;
    let poly = 1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3])));
    let dpoly = 1.0 + t2 * (3.0 * k[0] + t2 * (5.0 * k[1] + t2 * (7.0 * k[2] + t2 * 9.0 * k[3])));
    (theta * poly, dpoly)
}

/// Kannala-Brandt map of a 3D point. `None` at the centre of projection or on the negative
/// optical axis (direction undefined).
fn point(k: &[f64; 4], p: [f64; 3]) -> Option<Distorted> {
    let [px, py, pz] = p;
    let rho2 = px * px + py * py;
    let rho = rho2.sqrt();
    let norm2 = rho2 + pz * pz;
    if norm2 == 0.0 || !norm2.is_finite() {
        return None;
    }
    // s = theta_d / rho and its partial derivatives ds/dX, ds/dY, ds/dZ;
    // q = theta / rho (needed for the coefficient derivatives).
    let (s, ds_dx, ds_dy, ds_dz, theta, q);
    if pz > 0.0 && rho < 1e-7 * pz {
        // Near the axis: t = rho / Z, theta = t - t^3/3 + O(t^5),
        // theta_d = t + (k1 - 1/3) t^3 + O(t^5), s = (1 + c t^2) / Z with c = k1 - 1/3.
        let c = k[0] - 1.0 / 3.0;
        let inv_z = 1.0 / pz;
        let t2 = rho2 * inv_z * inv_z;
        s = (1.0 + c * t2) * inv_z;
        let inv_z3 = inv_z * inv_z * inv_z;
        ds_dx = 2.0 * c * px * inv_z3;
        ds_dy = 2.0 * c * py * inv_z3;
        ds_dz = -(1.0 + 3.0 * c * t2) * inv_z * inv_z;
        theta = rho * inv_z;
        q = (1.0 - t2 / 3.0) * inv_z;
    } else {
        if rho == 0.0 {
            // On the negative optical axis: theta = pi, direction undefined.
            return None;
        }
        let th = rho.atan2(pz);
        let (thd, dthd) = theta_d(k, th);
        let inv_rho = 1.0 / rho;
        s = thd * inv_rho;
        // dtheta/drho = Z / (rho^2 + Z^2), dtheta/dZ = -rho / (rho^2 + Z^2)
        let dth_drho = pz / norm2;
        let dth_dz = -rho / norm2;
        let ds_drho = (dthd * dth_drho * rho - thd) * inv_rho * inv_rho;
        ds_dx = ds_drho * px * inv_rho;
        ds_dy = ds_drho * py * inv_rho;
        ds_dz = dthd * dth_dz * inv_rho;
        theta = th;
        q = th * inv_rho;
    }
    let xd = [s * px, s * py];
    let d_point = [[s + px * ds_dx, px * ds_dy, px * ds_dz], [py * ds_dx, s + py * ds_dy, py * ds_dz]];
    // d theta_d / d k_i = theta^(2i+1); d x_d / d k_i = X theta^(2i+1) / rho = X q theta^(2i).
    let t2 = theta * theta;
    let t4 = t2 * t2;
    let powers = [t2, t4, t4 * t2, t4 * t4];
    let mut d_coeffs = [[0.0; 8]; 2];
    for (i, pw) in powers.iter().enumerate() {
        d_coeffs[0][i] = px * q * pw;
        d_coeffs[1][i] = py * q * pw;
    }
    Some(Distorted { xd, d_point, d_coeffs })
}

/// The field angle `theta` whose `theta_d` is `t_d` (the distorted point `xd`), by Newton's
/// method; the residual is measured in pixels through the focal lengths `f_px`.
fn invert(k: &[f64; 4], xd: [f64; 2], t_d: f64, f_px: [f64; 2]) -> Result<f64, Unprojection> {
    let fail = |iterations, residual_px, reason| Unprojection { iterations, residual_px, reason };
    let target = t_d;
    // Pixel length of a unit change of theta_d along the pixel's direction.
    let scale = (f_px[0] * xd[0] / t_d).hypot(f_px[1] * xd[1] / t_d);
    // The state at an angle: `theta_d` and its derivative.
    let eval = |theta: f64| {
        let (f, df) = theta_d(k, theta);
        Some(((f, df), (f - target).abs() * scale))
    };
    let theta0 = target.min(3.0);
    let (start, res_px) = eval(theta0).expect("theta_d is always evaluated");
    let direction = |&(f, df): &(f64, f64)| {
        if df <= 0.0 || !df.is_finite() {
            return Err("theta_d(theta) is not increasing (beyond a fold of the fisheye model)");
        }
        Ok((f - target) / df)
    };
    let Solved { x: theta, res_px, iterations, .. } = damped_newton(
        (theta0, start, res_px),
        eval,
        direction,
        |theta, delta, step| (theta - step * delta).clamp(0.0, PI),
        "Newton iteration did not reach 1e-10 px",
    )?;
    let on_branch = (1..=64).all(|i| theta_d(k, theta * i as f64 / 64.0).1 > 0.0);
    if !on_branch || theta >= PI {
        return Err(fail(iterations, res_px, "solution lies beyond a fold of the fisheye model"));
    }
    Ok(theta)
}
