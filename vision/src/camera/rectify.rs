//! Rectification of a calibrated stereo pair (Bouguet's method, as OpenCV's `stereoRectify`):
//! both cameras are turned so that their image planes coincide and their rows are the epipolar
//! lines, and given one common pinhole camera matrix.
//!
//! Method, for `p_right = R p_left + T` (OpenCV's `R`, `T` of `stereoCalibrate`):
//! 1. the rotation is split between the cameras: `r_half = exp(-log(R) / 2)`, so that
//!    `r_half R = r_half^T` and both cameras, turned by `r_half^T` (left) and `r_half` (right),
//!    look the same way; the baseline in that common frame is `t = r_half T`;
//! 2. a second rotation `w` (about `t x e`, by the angle between `t` and `e`) turns the baseline
//!    onto the new x axis `e = (sign t_x, 0, 0)` (onto the y axis when `|t_y| >= |t_x|`: vertical
//!    stereo); `R1 = w r_half^T`, `R2 = w r_half`;
//! 3. the new focal length is the mean of the two cameras' `fy` (`fx` for vertical stereo); each
//!    camera's new principal point is chosen so that its four image corners, undistorted and
//!    turned by `R1` / `R2`, are centred on the image (OpenCV with `alpha = -1`: no scaling,
//!    `newImageSize` = the image size); both principal points are then replaced by their mean
//!    (OpenCV's default `CALIB_ZERO_DISPARITY`: a point at infinity has zero disparity);
//! 4. `P1 = [K' | 0]`, `P2 = [K' | K' (t', 0, 0)]` with `t' = (R2 T)_x` (so `P2[0][3] = -f' B`
//!    with `B` the baseline, in the unit of `T`), and the disparity-to-depth matrix `Q`.
//!
//! Differences from OpenCV (documented, measured in the tests): OpenCV undistorts the four
//! image corners in single precision with a fixed number of iterations (5) of its fixed-point
//! inverse, this module with the model's exact inverse ([`CameraModel::unproject_normalized`]);
//! the principal points therefore differ by a small fraction of a pixel where the distortion at
//! the image corners is strong. The rotations and the focal length are the same to rounding.
//! `alpha` in `[0, 1]` (OpenCV's scaling to the valid pixels) is not implemented. Any lens model
//! is rectified the same way (through its exact inverse); for Kannala-Brandt this is not
//! OpenCV's `fisheye::stereoRectify`, which chooses the new camera matrix differently, and it
//! fails when an image corner turns to 90 degrees or more from the new optical axis.

use nalgebra::{Matrix3, Matrix3x4, Matrix4, Point2, Point3, Rotation3, Vector3, Vector4};
use serde::{Deserialize, Serialize};

use super::CameraModel;
use crate::error::{Result, VisionError};

/// The rectification of a stereo pair: rotations, new projection matrices and the
/// disparity-to-depth matrix, with OpenCV's names and conventions.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct StereoRectification {
    /// `R1`: rotation from the left camera frame to the rectified left frame.
    pub r1: Matrix3<f64>,
    /// `R2`: rotation from the right camera frame to the rectified right frame.
    pub r2: Matrix3<f64>,
    /// `P1 = [K' | 0]`: projection of the rectified left frame, pixels.
    pub p1: Matrix3x4<f64>,
    /// `P2 = [K' | K' (t', 0, 0)^T]`: projection of the rectified left frame into the rectified
    /// right image; `P2[0][3] = t' f'` with `t' = (R2 T)_x` (negative for a right camera on the
    /// left camera's `+x` side), in the unit of `T` times pixels.
    pub p2: Matrix3x4<f64>,
    /// `Q`: `(u, v, disparity, 1)` of the rectified left image to homogeneous coordinates of
    /// the point in the rectified left frame (the unit of `T`).
    pub q: Matrix4<f64>,
}

impl StereoRectification {
    /// The common focal length `f'`, pixels.
    pub fn focal_px(&self) -> f64 {
        self.p1[(0, 0)]
    }

    /// True when the cameras are stacked vertically (the baseline along the rectified y axis).
    pub fn vertical(&self) -> bool {
        self.p2[(1, 3)] != 0.0
    }

    /// The baseline, in the unit of `T`: `-P2[0][3] / f'` (or `-P2[1][3] / f'` for vertical
    /// stereo); positive when the second camera sits on the first one's `+x` (`+y`) side.
    pub fn baseline(&self) -> f64 {
        let i = usize::from(self.vertical());
        -self.p2[(i, 3)] / self.focal_px()
    }

    /// The rectified pixel of a raw pixel of the left (`right = false`) or right camera.
    pub fn rectify_pixel(&self, camera: &CameraModel, right: bool, pixel: &Point2<f64>) -> Result<Point2<f64>> {
        let n = camera.unproject_normalized(pixel)?;
        let (r, p) = if right { (&self.r2, &self.p2) } else { (&self.r1, &self.p1) };
        let x = r * Vector3::new(n.x, n.y, 1.0);
        if x.z <= 0.0 {
            return Err(VisionError::InvalidInput {
                detail: format!("pixel ({}, {}) is turned behind the rectified image plane", pixel.x, pixel.y),
            });
        }
        let k = p.fixed_view::<3, 3>(0, 0);
        let h = k * x;
        Ok(Point2::new(h.x / h.z, h.y / h.z))
    }

    /// The point (rectified left frame, unit of `T`) of a rectified left pixel and its
    /// disparity `u_left - u_right` (`v_left - v_right` for vertical stereo), through `Q`.
    pub fn reproject(&self, pixel: &Point2<f64>, disparity_px: f64) -> Point3<f64> {
        let h = self.q * Vector4::new(pixel.x, pixel.y, disparity_px, 1.0);
        Point3::new(h.x / h.w, h.y / h.w, h.z / h.w)
    }
}

/// Rectifies a calibrated stereo pair; `r`, `t`: `p_right = r p_left + t` (OpenCV's `R`, `T`;
/// any length unit, which `P2` and `Q` then carry). Both cameras must have the same image size.
/// See the module documentation for the method.
pub fn stereo_rectify(
    left: &CameraModel,
    right: &CameraModel,
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
) -> Result<StereoRectification> {
    if left.image_size != right.image_size {
        return Err(VisionError::InvalidInput {
            detail: format!(
                "rectification needs two images of one size; left is {}x{}, right {}x{}",
                left.image_size.width_px,
                left.image_size.height_px,
                right.image_size.width_px,
                right.image_size.height_px
            ),
        });
    }
    let nt = t.norm();
    if !(nt.is_finite() && nt > 0.0 && r.iter().all(|v| v.is_finite())) {
        return Err(VisionError::InvalidInput {
            detail: format!("rectification needs a finite rotation and a non-zero baseline; |T| = {nt}"),
        });
    }
    // 1. Half rotations.
    let om = Rotation3::from_matrix_unchecked(*r).scaled_axis();
    let r_half = Rotation3::new(-0.5 * om).into_inner();
    let th = r_half * t;
    // 2. Baseline onto the x (or y) axis.
    let idx = if th.x.abs() > th.y.abs() { 0 } else { 1 };
    let c = th[idx];
    let mut e = Vector3::zeros();
    e[idx] = if c > 0.0 { 1.0 } else { -1.0 };
    let mut w = th.cross(&e);
    let nw = w.norm();
    if nw > 0.0 {
        w *= (c.abs() / nt).clamp(-1.0, 1.0).acos() / nw;
    }
    let wr = Rotation3::new(w).into_inner();
    let r1 = wr * r_half.transpose();
    let r2 = wr * r_half;
    let t_new = r2 * t;
    // 3. Focal length and principal points.
    let other = 1 - idx;
    let f_of = |cam: &CameraModel| if other == 1 { cam.intrinsics.fy_px } else { cam.intrinsics.fx_px };
    let f = 0.5 * (f_of(left) + f_of(right));
    let (w_px, h_px) = (left.image_size.width_px as f64, left.image_size.height_px as f64);
    let mut cc = [Point2::origin(); 2];
    for (k, (cam, rk)) in [(left, &r1), (right, &r2)].into_iter().enumerate() {
        let mut sum = Vector3::zeros();
        for (u, v) in [(0.0, 0.0), (w_px - 1.0, 0.0), (0.0, h_px - 1.0), (w_px - 1.0, h_px - 1.0)] {
            let n = cam.unproject_normalized(&Point2::new(u, v))?;
            let x = rk * Vector3::new(n.x, n.y, 1.0);
            sum += Vector3::new(f * x.x / x.z, f * x.y / x.z, 0.0);
        }
        cc[k] = Point2::new(0.5 * (w_px - 1.0) - sum.x / 4.0, 0.5 * (h_px - 1.0) - sum.y / 4.0);
    }
    let mean = Point2::new(0.5 * (cc[0].x + cc[1].x), 0.5 * (cc[0].y + cc[1].y));
    let (cx1, cy1, cx2, cy2) = (mean.x, mean.y, mean.x, mean.y);
    // 4. Projections and Q.
    let p1 = Matrix3x4::new(f, 0.0, cx1, 0.0, 0.0, f, cy1, 0.0, 0.0, 0.0, 1.0, 0.0);
    let mut p2 = Matrix3x4::new(f, 0.0, cx2, 0.0, 0.0, f, cy2, 0.0, 0.0, 0.0, 1.0, 0.0);
    let tb = t_new[idx];
    p2[(idx, 3)] = tb * f;
    let d_c = if idx == 0 { cx1 - cx2 } else { cy1 - cy2 };
    // `+ 0.0`: no negative zero in the file when the principal points coincide.
    let q =
        Matrix4::new(1.0, 0.0, 0.0, -cx1, 0.0, 1.0, 0.0, -cy1, 0.0, 0.0, 0.0, f, 0.0, 0.0, -1.0 / tb, d_c / tb + 0.0);
    Ok(StereoRectification { r1, r2, p1, p2, q })
}

/// The essential matrix `E = [T]x R` of a pair (`p_right = R p_left + T`).
pub fn essential_matrix(r: &Matrix3<f64>, t: &Vector3<f64>) -> Matrix3<f64> {
    crate::pose::so3::skew(t) * r
}

/// The fundamental matrix `F = K2^-T E K1^-1` of a pair (pinhole part only: it holds for
/// undistorted pixels), normalised as OpenCV's `stereoCalibrate` does (`F[2][2] = 1` when that
/// entry is not zero).
pub fn fundamental_matrix(left: &CameraModel, right: &CameraModel, r: &Matrix3<f64>, t: &Vector3<f64>) -> Matrix3<f64> {
    let k = |c: &CameraModel| {
        let i = c.intrinsics;
        Matrix3::new(i.fx_px, 0.0, i.cx_px, 0.0, i.fy_px, i.cy_px, 0.0, 0.0, 1.0)
    };
    let k1i = k(left).try_inverse().unwrap_or_else(Matrix3::identity);
    let k2i = k(right).try_inverse().unwrap_or_else(Matrix3::identity);
    let f = k2i.transpose() * essential_matrix(r, t) * k1i;
    if f[(2, 2)].abs() > 0.0 {
        f / f[(2, 2)]
    } else {
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Distortion, ImageSize, Intrinsics};

    fn pair() -> (CameraModel, CameraModel, Matrix3<f64>, Vector3<f64>) {
        let size = ImageSize { width_px: 640, height_px: 480 };
        let left = CameraModel::new(
            Intrinsics { fx_px: 534.1, fy_px: 534.1, cx_px: 341.9, cy_px: 233.1 },
            Distortion::Brown5 { k1: -0.28, k2: 0.09, p1: 0.0012, p2: -0.0002, k3: 0.0 },
            size,
        )
        .unwrap();
        let right = CameraModel::new(
            Intrinsics { fx_px: 537.6, fy_px: 537.9, cx_px: 326.4, cy_px: 249.3 },
            Distortion::Brown5 { k1: -0.27, k2: 0.05, p1: -0.0006, p2: 0.0005, k3: 0.02 },
            size,
        )
        .unwrap();
        let r = Rotation3::new(Vector3::new(0.0061, -0.0082, -0.0034)).into_inner();
        let t = Vector3::new(-0.0832, 0.0011, 0.0005);
        (left, right, r, t)
    }

    /// A point seen by both cameras lands on the same rectified row, and its disparity
    /// reconstructs it through `Q` (in the rectified left frame, `R1 X`).
    #[test]
    fn rectified_rows_agree_and_q_reconstructs_depth() {
        let (left, right, r, t) = pair();
        let rect = stereo_rectify(&left, &right, &r, &t).unwrap();
        assert!((rect.r1 * rect.r1.transpose() - Matrix3::identity()).norm() < 1e-14);
        assert!((rect.r2 * r - rect.r1).norm() < 1e-14, "R2 R = R1");
        assert!((rect.baseline() - t.norm()).abs() < 1e-15, "baseline {} vs |T| {}", rect.baseline(), t.norm());
        assert!(!rect.vertical());
        for (x, y, z) in [(0.1, -0.05, 0.7), (-0.2, 0.12, 1.3), (0.0, 0.0, 3.0), (0.25, 0.18, 0.9)] {
            let p = Point3::new(x, y, z);
            let pl = left.project(&p).unwrap();
            let pr = right.project(&Point3::from(r * p.coords + t)).unwrap();
            let ql = rect.rectify_pixel(&left, false, &pl).unwrap();
            let qr = rect.rectify_pixel(&right, true, &pr).unwrap();
            assert!((ql.y - qr.y).abs() < 1e-9, "rows {} vs {}", ql.y, qr.y);
            let back = rect.reproject(&ql, ql.x - qr.x);
            let want = rect.r1 * p.coords;
            assert!((back.coords - want).norm() < 1e-9 * z, "{back} vs {want}");
        }
    }

    /// Cameras stacked vertically rectify along y, and a pure translation along x gives the
    /// identity rotations.
    #[test]
    fn vertical_and_ideal_pairs() {
        let (left, right, r, _) = pair();
        let t = Vector3::new(0.001, -0.1, 0.002);
        let rect = stereo_rectify(&left, &right, &r, &t).unwrap();
        assert!(rect.vertical());
        let p = Point3::new(0.05, 0.02, 1.1);
        let ql = rect.rectify_pixel(&left, false, &left.project(&p).unwrap()).unwrap();
        let qr = rect.rectify_pixel(&right, true, &right.project(&Point3::from(r * p.coords + t)).unwrap()).unwrap();
        assert!((ql.x - qr.x).abs() < 1e-9);
        let back = rect.reproject(&ql, ql.y - qr.y);
        assert!((back.coords - rect.r1 * p.coords).norm() < 1e-9);
        let ideal = stereo_rectify(&left, &left, &Matrix3::identity(), &Vector3::new(-0.1, 0.0, 0.0)).unwrap();
        assert!((ideal.r1 - Matrix3::identity()).norm() < 1e-15 && (ideal.r2 - Matrix3::identity()).norm() < 1e-15);
        assert!(stereo_rectify(&left, &right, &r, &Vector3::zeros()).is_err());
    }

    #[test]
    fn epipolar_constraint_holds_for_e_and_f() {
        let (left, right, r, t) = pair();
        let e = essential_matrix(&r, &t);
        let f = fundamental_matrix(&left, &right, &r, &t);
        let p = Point3::new(0.1, -0.05, 0.9);
        let pr = r * p.coords + t;
        assert!((pr.transpose() * e * p.coords)[(0, 0)].abs() < 1e-15);
        let ideal = |cam: &CameraModel, x: &Vector3<f64>| {
            let i = cam.intrinsics;
            Vector3::new(i.fx_px * x.x / x.z + i.cx_px, i.fy_px * x.y / x.z + i.cy_px, 1.0)
        };
        let (ul, ur) = (ideal(&left, &p.coords), ideal(&right, &pr));
        assert!((ur.transpose() * f * ul)[(0, 0)].abs() < 1e-9);
    }
}
