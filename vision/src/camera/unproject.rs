//! Unprojection: the ray of a pixel, the lens map inverted by the model's own method
//! ([`super::LensModel::unproject_ray`], [`super::LensModel::unproject_normalized`]).

use nalgebra::{Point2, Vector3};

use super::lens::Unprojection;
use super::CameraModel;
use crate::error::{Result, VisionError};

impl CameraModel {
    /// Distorted normalised coordinates of a pixel (inverse of the pixel step).
    fn pixel_to_distorted(&self, pixel: &Point2<f64>) -> [f64; 2] {
        let k = &self.intrinsics;
        [(pixel.x - k.cx_px) / k.fx_px, (pixel.y - k.cy_px) / k.fy_px]
    }

    /// The error of a failed inverse at `pixel`.
    fn unprojection_failed(pixel: &Point2<f64>, u: Unprojection) -> VisionError {
        VisionError::UnprojectionFailed {
            u_px: pixel.x,
            v_px: pixel.y,
            iterations: u.iterations,
            residual_px: u.residual_px,
            reason: u.reason.to_string(),
        }
    }

    /// The distorted normalised point of a finite pixel, and the focal lengths.
    fn distorted_of(&self, pixel: &Point2<f64>) -> Result<([f64; 2], [f64; 2])> {
        if !(pixel.x.is_finite() && pixel.y.is_finite()) {
            let u = Unprojection { iterations: 0, residual_px: f64::NAN, reason: "non-finite pixel" };
            return Err(Self::unprojection_failed(pixel, u));
        }
        Ok((self.pixel_to_distorted(pixel), [self.intrinsics.fx_px, self.intrinsics.fy_px]))
    }

    /// The unit ray (camera frame) that projects to `pixel`.
    ///
    /// The distortion is inverted by Newton's method on the analytic 2 x 2 Jacobian (Brown,
    /// rational) or on `theta_d(theta)` (Kannala-Brandt), started at the distorted point, with
    /// step halving when the residual grows. It fails with
    /// [`VisionError::UnprojectionFailed`] when the reprojection residual stays above 1e-10 px
    /// or the solution lies beyond a fold of the distortion (where the map is not invertible).
    pub fn unproject(&self, pixel: &Point2<f64>) -> Result<Vector3<f64>> {
        let (xd, f_px) = self.distorted_of(pixel)?;
        self.distortion.unproject_ray(xd, f_px).map_err(|u| Self::unprojection_failed(pixel, u))
    }

    /// The normalised point `(X/Z, Y/Z)` that projects to `pixel`; fails when the ray does not
    /// point forward (`Z <= 0`, possible only with Kannala-Brandt). See
    /// [`CameraModel::unproject`] for the method.
    pub fn unproject_normalized(&self, pixel: &Point2<f64>) -> Result<Point2<f64>> {
        let (xd, f_px) = self.distorted_of(pixel)?;
        let n = self.distortion.unproject_normalized(xd, f_px).map_err(|u| Self::unprojection_failed(pixel, u))?;
        Ok(Point2::new(n[0], n[1]))
    }
}
