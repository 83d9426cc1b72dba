//! The perspective (and distortion) bias of circle centres, and its correction.
//!
//! A circle of radius `R` around `P` on the target images, through a pinhole, as an ellipse
//! whose centre is not the image of `P`: with `H = K [r1 r2 t]` the plane's homography and
//! `C` the circle's conic in plane coordinates, the image conic is `C' = H^-T C H^-1`, and its
//! centre, the pole of the line at infinity, is `H C^-1 H^T (0, 0, 1)^T` (dehomogenised), while
//! `P` images at `H (P_x, P_y, 1)^T` ([`conic_centre_offset_pinhole`]). The offset grows with
//! `R^2` and with the board's tilt. Lens distortion bends the ellipse further; the general
//! route ([`ellipse_centre_offset_px`]) projects points of the circle's rim through the full
//! camera model and fits them with the detector's own ellipse fit, so that what is subtracted
//! is what the detector measures. Both routes agree for a pinhole camera (tests).
//!
//! [`correct_centres`] subtracts the offset from detected centres given a camera and the
//! board's pose (e.g. from a calibration); iterate with a new pose when the correction is
//! large compared with the pose's uncertainty.

use nalgebra::{Isometry3, Matrix2, Matrix3, Point2, Point3, Vector2, Vector3};

use super::ellipse::fit_ellipse_points;
use crate::camera::CameraModel;
use crate::error::{Result, VisionError};

/// Points on the rim used by [`ellipse_centre_offset_px`].
pub const RIM_POINTS: usize = 96;

/// Centre of the fitted ellipse minus the image of the circle's centre, pixels: the circle of
/// `radius_m` around `centre_m` (target frame, `z = 0`) seen by `camera` at `t_cam_target`.
pub fn ellipse_centre_offset_px(
    camera: &CameraModel,
    t_cam_target: &Isometry3<f64>,
    centre_m: &Point3<f64>,
    radius_m: f64,
) -> Result<Vector2<f64>> {
    let c = camera.project(&(t_cam_target * centre_m))?;
    let mut rim = Vec::with_capacity(RIM_POINTS);
    for k in 0..RIM_POINTS {
        let a = 2.0 * std::f64::consts::PI * k as f64 / RIM_POINTS as f64;
        let q = Point3::new(centre_m.x + radius_m * a.cos(), centre_m.y + radius_m * a.sin(), centre_m.z);
        let px = camera.project(&(t_cam_target * q))?;
        rim.push(px.coords);
    }
    // Start from the rim's mean and the moment ellipse of the rim (a ring: moments r^2 / 2).
    let mean = rim.iter().sum::<Vector2<f64>>() / rim.len() as f64;
    let mut m = Matrix2::zeros();
    for p in &rim {
        let d = p - mean;
        m += d * d.transpose() / rim.len() as f64;
    }
    let shape = (m * 2.0)
        .try_inverse()
        .ok_or_else(|| VisionError::InvalidInput { detail: "the circle images as a line (seen edge-on)".into() })?;
    let fit = fit_ellipse_points(&rim, mean, shape)
        .ok_or_else(|| VisionError::InvalidInput { detail: "the circle's image is not an ellipse".into() })?;
    Ok(fit.centre_px.coords - c.coords)
}

/// The same for a pinhole camera (`K` from `camera`'s intrinsics, its distortion ignored), in
/// closed form from the image conic.
pub fn conic_centre_offset_pinhole(
    camera: &CameraModel,
    t_cam_target: &Isometry3<f64>,
    centre_m: &Point3<f64>,
    radius_m: f64,
) -> Result<Vector2<f64>> {
    let k = &camera.intrinsics;
    let kk = Matrix3::new(k.fx_px, 0.0, k.cx_px, 0.0, k.fy_px, k.cy_px, 0.0, 0.0, 1.0);
    let r = t_cam_target.rotation.to_rotation_matrix();
    let t = t_cam_target.translation.vector;
    let h = kk * Matrix3::from_columns(&[r.matrix().column(0).into_owned(), r.matrix().column(1).into_owned(), t]);
    let (x0, y0) = (centre_m.x, centre_m.y);
    // C^-1 of the circle conic [[1, 0, -x0], [0, 1, -y0], [-x0, -y0, x0^2 + y0^2 - R^2]].
    let c = Matrix3::new(1.0, 0.0, -x0, 0.0, 1.0, -y0, -x0, -y0, x0 * x0 + y0 * y0 - radius_m * radius_m);
    let cinv = c.try_inverse().ok_or_else(|| VisionError::InvalidInput { detail: "zero radius".into() })?;
    let e = h * cinv * h.transpose() * Vector3::new(0.0, 0.0, 1.0);
    let p = h * Vector3::new(x0, y0, 1.0);
    if e.z.abs() < 1e-15 || p.z.abs() < 1e-15 {
        return Err(VisionError::InvalidInput { detail: "the circle is not in front of the camera".into() });
    }
    Ok(Vector2::new(e.x / e.z - p.x / p.z, e.y / e.z - p.y / p.z))
}

/// Detected centres corrected for the bias: `centres_px[i]` is the dot `point_ids[i]` of
/// `points_m` with radius `radii_m[i]`; returns the centres minus their offsets.
pub fn correct_centres(
    camera: &CameraModel,
    t_cam_target: &Isometry3<f64>,
    points_m: &[Point3<f64>],
    point_ids: &[usize],
    radii_m: &[f64],
    centres_px: &[Point2<f64>],
) -> Result<Vec<Point2<f64>>> {
    if point_ids.len() != centres_px.len() || radii_m.len() != centres_px.len() {
        return Err(VisionError::InvalidInput {
            detail: format!("{} ids, {} radii, {} centres", point_ids.len(), radii_m.len(), centres_px.len()),
        });
    }
    point_ids
        .iter()
        .zip(radii_m)
        .zip(centres_px)
        .map(|((&id, &r), c)| {
            let p = points_m.get(id).ok_or_else(|| VisionError::InvalidInput {
                detail: format!("point id {id}, the target has {} points", points_m.len()),
            })?;
            Ok(c - ellipse_centre_offset_px(camera, t_cam_target, p, r)?)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Distortion, ImageSize, Intrinsics};
    use nalgebra::{Translation3, UnitQuaternion};

    fn camera(distortion: Distortion) -> CameraModel {
        CameraModel {
            intrinsics: Intrinsics { fx_px: 800.0, fy_px: 790.0, cx_px: 320.0, cy_px: 240.0 },
            distortion,
            image_size: ImageSize { width_px: 640, height_px: 480 },
        }
    }

    #[test]
    fn numeric_route_matches_the_closed_form_for_a_pinhole() {
        let cam = camera(Distortion::None);
        let t = Isometry3::from_parts(
            Translation3::new(0.02, -0.01, 0.5),
            UnitQuaternion::from_euler_angles(0.7, -0.4, 0.2),
        );
        let mut largest = 0.0f64;
        for (x, y) in [(0.0, 0.0), (0.08, 0.05), (-0.1, 0.07)] {
            let p = Point3::new(x, y, 0.0);
            let a = ellipse_centre_offset_px(&cam, &t, &p, 0.01).unwrap();
            let b = conic_centre_offset_pinhole(&cam, &t, &p, 0.01).unwrap();
            assert!((a - b).norm() < 1e-7, "{a} vs {b}");
            largest = largest.max(b.norm());
        }
        // A 40 deg tilt and a 10 mm radius at 0.5 m: a visible bias.
        assert!(largest > 0.05, "{largest}");
        // Facing the camera squarely on its axis, a circle's centre has no bias.
        let facing = Isometry3::translation(0.0, 0.0, 0.5);
        let z = conic_centre_offset_pinhole(&cam, &facing, &Point3::new(0.05, 0.03, 0.0), 0.01).unwrap();
        assert!(z.norm() < 1e-9, "{z}");
    }

    #[test]
    fn distortion_changes_the_offset_and_the_correction_undoes_it() {
        let cam = camera(Distortion::Brown5 { k1: -0.3, k2: 0.1, p1: 0.001, p2: -0.002, k3: 0.0 });
        let t = Isometry3::from_parts(
            Translation3::new(0.05, 0.04, 0.45),
            UnitQuaternion::from_euler_angles(0.6, 0.3, 0.0),
        );
        let p = Point3::new(0.1, 0.08, 0.0);
        let a = ellipse_centre_offset_px(&cam, &t, &p, 0.012).unwrap();
        let b = conic_centre_offset_pinhole(&cam, &t, &p, 0.012).unwrap();
        assert!((a - b).norm() > 1e-3, "distortion should matter here: {a} {b}");
        let truth = cam.project(&(t * p)).unwrap();
        let measured = truth + a;
        let fixed = correct_centres(&cam, &t, &[p], &[0], &[0.012], &[measured]).unwrap();
        assert!((fixed[0] - truth).norm() < 1e-9);
    }
}
