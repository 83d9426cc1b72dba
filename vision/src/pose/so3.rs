//! Rotations as rotation vectors (axis times angle, radians), the parameterisation of every
//! optimisation in `calib` and `pose`.
//!
//! Optimisers never add to a rotation vector directly: they estimate a small *left increment*
//! `delta` around a reference rotation, `R = exp(delta) R_ref`, and fold it into `R_ref` after
//! each solve (a local parameterisation, the role of a Ceres manifold). The derivative of a
//! rotated point with respect to the increment is exact for any `delta` (not only at zero),
//!
//! ```text
//! d(exp(delta) v) / d(delta) = -[exp(delta) v]_x J_l(delta),
//! J_l(w) = I + (1 - cos t) / t^2 [w]_x + (t - sin t) / t^3 [w]_x^2,   t = |w|,
//! ```
//!
//! so an increment that grows during a solve does not slow convergence; it is only kept away
//! from `pi` by rebasing.

use nalgebra::{Matrix3, Rotation3, Vector3};

pub use ferrocal_lsq::so3::skew;

/// The rotation of a rotation vector (radians).
pub fn exp(w: &Vector3<f64>) -> Rotation3<f64> {
    Rotation3::new(*w)
}

/// The rotation vector (radians, angle in `[0, pi]`) of a rotation.
pub fn log(r: &Rotation3<f64>) -> Vector3<f64> {
    r.scaled_axis()
}

/// The left Jacobian `J_l(w)` of SO(3): `exp(w + d) = exp(J_l(w) d) exp(w)` to first order.
pub fn left_jacobian(w: &Vector3<f64>) -> Matrix3<f64> {
    let t2 = w.norm_squared();
    let k = skew(w);
    if t2 < 1e-10 {
        // Series: I + K/2 + K^2/6 (error O(t^3)).
        return Matrix3::identity() + 0.5 * k + k * k / 6.0;
    }
    let t = t2.sqrt();
    Matrix3::identity() + (1.0 - t.cos()) / t2 * k + (t - t.sin()) / (t2 * t) * k * k
}

/// `d(exp(w) v) / dw` for a left increment `w` (see the module documentation).
pub fn d_rotated_d_increment(w: &Vector3<f64>, rotated: &Vector3<f64>) -> Matrix3<f64> {
    -skew(rotated) * left_jacobian(w)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn increment_derivative_matches_finite_differences() {
        let r_ref = exp(&Vector3::new(0.3, -1.2, 0.7));
        let v = Vector3::new(0.4, -0.1, 2.0);
        for w in [Vector3::zeros(), Vector3::new(1e-7, 0.0, -2e-7), Vector3::new(0.5, -0.9, 1.7)] {
            let rotated = exp(&w) * r_ref * v;
            let analytic = d_rotated_d_increment(&w, &rotated);
            let h = 1e-6;
            for c in 0..3 {
                let mut wp = w;
                wp[c] += h;
                let mut wm = w;
                wm[c] -= h;
                let num = (exp(&wp) * r_ref * v - exp(&wm) * r_ref * v) / (2.0 * h);
                for r in 0..3 {
                    assert!(
                        (num[r] - analytic[(r, c)]).abs() < 1e-8,
                        "w {w:?} ({r},{c}): {} vs {}",
                        num[r],
                        analytic[(r, c)]
                    );
                }
            }
        }
    }

    #[test]
    fn log_inverts_exp_up_to_pi() {
        for w in [Vector3::new(0.1, 0.2, -0.3), Vector3::new(0.0, 3.1, 0.0), Vector3::new(1e-12, 0.0, 0.0)] {
            assert!((log(&exp(&w)) - w).norm() < 1e-9);
        }
    }
}
