//! Unprojection: the ray of a pixel, the distortion inverted by Newton's method.

use nalgebra::{Point2, Vector3};

use super::{brown_radial_increasing, distortion, CameraModel, Distortion};
use crate::error::{Result, VisionError};

/// Pixel residual below which the iterative inverse stops.
const UNPROJECT_STOP_PX: f64 = 1e-12;
/// Pixel residual above which the iterative inverse reports failure.
const UNPROJECT_ACCEPT_PX: f64 = 1e-10;
/// Maximum Newton iterations of the inverse.
const UNPROJECT_MAX_ITERATIONS: usize = 60;

impl CameraModel {
    /// Distorted normalised coordinates of a pixel (inverse of the pixel step).
    fn pixel_to_distorted(&self, pixel: &Point2<f64>) -> [f64; 2] {
        let k = &self.intrinsics;
        [(pixel.x - k.cx_px) / k.fx_px, (pixel.y - k.cy_px) / k.fy_px]
    }

    /// The unit ray (camera frame) that projects to `pixel`.
    ///
    /// The distortion is inverted by Newton's method on the analytic 2 x 2 Jacobian (Brown,
    /// rational) or on `theta_d(theta)` (Kannala-Brandt), started at the distorted point, with
    /// step halving when the residual grows. It fails with
    /// [`VisionError::UnprojectionFailed`] when the reprojection residual stays above 1e-10 px
    /// or the solution lies beyond a fold of the distortion (where the map is not invertible).
    pub fn unproject(&self, pixel: &Point2<f64>) -> Result<Vector3<f64>> {
        let fail = |iterations, residual_px, reason: &str| VisionError::UnprojectionFailed {
            u_px: pixel.x,
            v_px: pixel.y,
            iterations,
            residual_px,
            reason: reason.to_string(),
        };
        if !(pixel.x.is_finite() && pixel.y.is_finite()) {
            return Err(fail(0, f64::NAN, "non-finite pixel"));
        }
        match self.distortion {
            Distortion::KannalaBrandt { k1, k2, k3, k4 } => {
                let xd = self.pixel_to_distorted(pixel);
                let theta_d = xd[0].hypot(xd[1]);
                if theta_d == 0.0 {
                    return Ok(Vector3::new(0.0, 0.0, 1.0));
                }
                let theta = self.invert_kb(&[k1, k2, k3, k4], xd, theta_d, &fail)?;
                let s = theta.sin() / theta_d;
                Ok(Vector3::new(s * xd[0], s * xd[1], theta.cos()))
            }
            _ => {
                let n = self.unproject_brown(pixel, &fail)?;
                Ok(Vector3::new(n[0], n[1], 1.0).normalize())
            }
        }
    }

    /// The normalised point `(X/Z, Y/Z)` that projects to `pixel`; fails when the ray does not
    /// point forward (`Z <= 0`, possible only with Kannala-Brandt). See
    /// [`CameraModel::unproject`] for the method.
    pub fn unproject_normalized(&self, pixel: &Point2<f64>) -> Result<Point2<f64>> {
        match self.distortion {
            Distortion::KannalaBrandt { .. } => {
                let ray = self.unproject(pixel)?;
                if ray.z <= 0.0 {
                    return Err(VisionError::UnprojectionFailed {
                        u_px: pixel.x,
                        v_px: pixel.y,
                        iterations: 0,
                        residual_px: 0.0,
                        reason: "the ray points at or behind the image plane (theta >= 90 deg)".into(),
                    });
                }
                Ok(Point2::new(ray.x / ray.z, ray.y / ray.z))
            }
            _ => {
                let fail = |iterations, residual_px, reason: &str| VisionError::UnprojectionFailed {
                    u_px: pixel.x,
                    v_px: pixel.y,
                    iterations,
                    residual_px,
                    reason: reason.to_string(),
                };
                if !(pixel.x.is_finite() && pixel.y.is_finite()) {
                    return Err(fail(0, f64::NAN, "non-finite pixel"));
                }
                let n = self.unproject_brown(pixel, &fail)?;
                Ok(Point2::new(n[0], n[1]))
            }
        }
    }

    fn unproject_brown(&self, pixel: &Point2<f64>, fail: &dyn Fn(usize, f64, &str) -> VisionError) -> Result<[f64; 2]> {
        let target = self.pixel_to_distorted(pixel);
        if let Distortion::None = self.distortion {
            return Ok(target);
        }
        let c = self.distortion.brown_array();
        let (fx, fy) = (self.intrinsics.fx_px, self.intrinsics.fy_px);
        let eval = |x: f64, y: f64| -> Option<(distortion::BrownResult, f64, [f64; 2])> {
            let b = distortion::brown_normalized(&c, x, y)?;
            let r = [b.xd[0] - target[0], b.xd[1] - target[1]];
            let res_px = (fx * r[0]).hypot(fy * r[1]);
            Some((b, res_px, r))
        };
        let mut x = target;
        let (mut b, mut res_px, mut r) =
            eval(x[0], x[1]).ok_or_else(|| fail(0, f64::NAN, "rational denominator <= 0"))?;
        let mut iterations = 0;
        while res_px > UNPROJECT_STOP_PX && iterations < UNPROJECT_MAX_ITERATIONS {
            iterations += 1;
            let j = b.j_xy;
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            if det.abs() < 1e-300 || !det.is_finite() {
                return Err(fail(iterations, res_px, "singular distortion Jacobian"));
            }
            let dx = (j[1][1] * r[0] - j[0][1] * r[1]) / det;
            let dy = (-j[1][0] * r[0] + j[0][0] * r[1]) / det;
            let mut step = 1.0;
            let mut accepted = false;
            for _ in 0..40 {
                let cand = [x[0] - step * dx, x[1] - step * dy];
                if let Some((nb, nres, nr)) = eval(cand[0], cand[1]) {
                    if nres < res_px || nres <= UNPROJECT_STOP_PX {
                        x = cand;
                        b = nb;
                        res_px = nres;
                        r = nr;
                        accepted = true;
                        break;
                    }
                }
                step *= 0.5;
            }
            if !accepted {
                break;
            }
        }
        if res_px > UNPROJECT_ACCEPT_PX || !res_px.is_finite() {
            return Err(fail(
                iterations,
                res_px,
                "Newton iteration did not reach 1e-10 px (pixel outside the model's invertible region?)",
            ));
        }
        // The solution must lie on the branch that contains the principal point: the radial
        // map must increase all the way from the centre to it (checked at 64 radii).
        let a = x[0] * x[0] + x[1] * x[1];
        let on_branch = (1..=64).all(|i| brown_radial_increasing(&c, a * i as f64 / 64.0));
        let j = b.j_xy;
        if !on_branch || j[0][0] * j[1][1] - j[0][1] * j[1][0] <= 0.0 {
            return Err(fail(
                iterations,
                res_px,
                "solution lies beyond a fold of the distortion (not invertible there)",
            ));
        }
        Ok(x)
    }

    fn invert_kb(
        &self,
        k: &[f64; 4],
        xd: [f64; 2],
        theta_d: f64,
        fail: &dyn Fn(usize, f64, &str) -> VisionError,
    ) -> Result<f64> {
        // Pixel length of a unit change of theta_d along the pixel's direction.
        let scale = (self.intrinsics.fx_px * xd[0] / theta_d).hypot(self.intrinsics.fy_px * xd[1] / theta_d);
        let mut theta = theta_d.min(3.0);
        let (mut f, mut df) = distortion::kb_theta_d(k, theta);
        let mut res_px = (f - theta_d).abs() * scale;
        let mut iterations = 0;
        while res_px > UNPROJECT_STOP_PX && iterations < UNPROJECT_MAX_ITERATIONS {
            iterations += 1;
            if df <= 0.0 || !df.is_finite() {
                return Err(fail(
                    iterations,
                    res_px,
                    "theta_d(theta) is not increasing (beyond a fold of the fisheye model)",
                ));
            }
            let delta = (f - theta_d) / df;
            let mut step = 1.0;
            let mut accepted = false;
            for _ in 0..40 {
                let cand = (theta - step * delta).clamp(0.0, std::f64::consts::PI);
                let (nf, ndf) = distortion::kb_theta_d(k, cand);
                let nres = (nf - theta_d).abs() * scale;
                if nres < res_px || nres <= UNPROJECT_STOP_PX {
                    theta = cand;
                    f = nf;
                    df = ndf;
                    res_px = nres;
                    accepted = true;
                    break;
                }
                step *= 0.5;
            }
            if !accepted {
                break;
            }
        }
        if res_px > UNPROJECT_ACCEPT_PX || !res_px.is_finite() {
            return Err(fail(iterations, res_px, "Newton iteration did not reach 1e-10 px"));
        }
        let on_branch = (1..=64).all(|i| distortion::kb_theta_d(k, theta * i as f64 / 64.0).1 > 0.0);
        if !on_branch || theta >= std::f64::consts::PI {
            return Err(fail(iterations, res_px, "solution lies beyond a fold of the fisheye model"));
        }
        Ok(theta)
    }
}
