//! Rigid frames on a proper manifold, and the registration that starts them.
//!
//! A frame is held as `T = Exp(delta) T0`: a fixed reference `T0` and a 6-vector `delta`
//! (translation in metres, rotation vector in radians) that stays small during a fit, so the
//! chart never comes near its singularity whatever the rotation of `T0` (the source's free
//! quaternions drifted to norms 0.974-1.003: this cannot happen here).

use nalgebra::{Isometry3, Matrix3, Point3, Translation3, Vector3};

use crate::error::{CalibError, Result};

pub use ferrocal_robot::geometry::{exp6, log6};

/// Least-squares rigid transform `T` with `to_i ~ T from_i` (Horn/Kabsch via SVD).
pub fn fit_rigid(from: &[Point3<f64>], to: &[Point3<f64>]) -> Result<Isometry3<f64>> {
    if from.len() != to.len() || from.len() < 3 {
        return Err(CalibError::TooFew(format!(
            "a rigid registration needs at least 3 point pairs, got {}",
            from.len().min(to.len())
        )));
    }
    if let Some(k) = from
        .iter()
        .zip(to)
        .position(|(a, b)| !(a.coords.iter().chain(b.coords.iter()).all(|v| v.is_finite() && v.abs() < 1e12)))
    {
        return Err(CalibError::Numeric(format!(
            "a rigid registration got a point that is not a finite number of plausible size (pair {}: {:?} -> {:?})",
            k + 1,
            from[k].coords.as_slice(),
            to[k].coords.as_slice()
        )));
    }
    let n = from.len() as f64;
    let ca = from.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / n;
    let cb = to.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / n;
    let mut h = Matrix3::zeros();
    for (a, b) in from.iter().zip(to) {
        h += (a.coords - ca) * (b.coords - cb).transpose();
    }
    let svd = h.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Err(CalibError::Numeric("SVD of the registration failed".into()));
    };
    let mut d = Matrix3::identity();
    if (vt.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = vt.transpose() * d * u.transpose();
    // `r` is orthonormal (from the SVD): converted directly, never iteratively.
    let rot = ferrocal_robot::geometry::rotation_from_orthonormal(&r)
        .ok_or_else(|| CalibError::Numeric("the rigid registration's rotation is not finite".into()))?;
    let t = cb - rot * ca;
    Ok(Isometry3::from_parts(Translation3::from(t), rot))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::UnitQuaternion;

    #[test]
    fn registration_recovers_a_transform_near_pi() {
        let t = Isometry3::from_parts(
            Translation3::new(1.0, -2.0, 0.5),
            UnitQuaternion::from_scaled_axis(Vector3::new(0.1, 3.1, -0.2)),
        );
        let pts: Vec<Point3<f64>> =
            (0..20).map(|k| Point3::new((k as f64 * 0.7).sin(), (k as f64 * 1.3).cos(), k as f64 * 0.05)).collect();
        let moved: Vec<Point3<f64>> = pts.iter().map(|p| t * p).collect();
        let est = fit_rigid(&pts, &moved).unwrap();
        assert!((est.translation.vector - t.translation.vector).norm() < 1e-12);
        assert!(est.rotation.angle_to(&t.rotation) < 1e-12);
        let back = exp6(log6(&t).as_slice());
        assert!(back.rotation.angle_to(&t.rotation) < 1e-12);
        // A huge or non-finite coordinate is an error, not an endless iteration.
        let mut bad = moved.clone();
        bad[3].x = 1e300;
        assert!(fit_rigid(&pts, &bad).unwrap_err().to_string().contains("pair 4"));
        bad[3].x = f64::NAN;
        assert!(fit_rigid(&pts, &bad).is_err());
    }
}
