//! The Jacobians of SO(3) that exact derivatives of rotation-vector parameters need.
//!
//! With `exp` the rotation of a rotation vector (radians) and `[v]x` the cross-product matrix,
//!
//! ```text
//! exp(w + d) = exp(J_l(w) d) exp(w) = exp(w) exp(J_r(w) d)       (to first order in d)
//! J_l(w) = I + (1 - cos t) / t^2 [w]x + (t - sin t) / t^3 [w]x^2,   t = |w|,   J_r(w) = J_l(-w)
//! log(exp(e) exp(d)) = e + J_r(e)^-1 d                               (to first order in d)
//! ```
//!
//! so `d(exp(w) v)/dw = -[exp(w) v]x J_l(w)`. A parameter that enters a model as a rotation
//! vector `w` has these Jacobians everywhere, not only at `w = 0`.

use nalgebra::{Matrix3, Vector3};

/// The cross-product matrix `[v]x`, `[v]x u = v x u` (nalgebra's `cross_matrix`), the one of
/// every crate above the robot crate.
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    v.cross_matrix()
}

/// The left Jacobian `J_l(w)`: `exp(w + d) = exp(J_l(w) d) exp(w)` to first order.
pub fn left_jacobian(w: &Vector3<f64>) -> Matrix3<f64> {
    let t2 = w.norm_squared();
    let k = skew(w);
    let (c1, c2) = if t2 < 1e-8 {
        // Series to O(t^4): (1 - cos t)/t^2 = 1/2 - t^2/24, (t - sin t)/t^3 = 1/6 - t^2/120.
        (0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0)
    } else {
        let t = t2.sqrt();
        ((1.0 - t.cos()) / t2, (t - t.sin()) / (t2 * t))
    };
    Matrix3::identity() + c1 * k + c2 * k * k
}

/// The right Jacobian `J_r(w) = J_l(-w)`: `exp(w + d) = exp(w) exp(J_r(w) d)` to first order.
pub fn right_jacobian(w: &Vector3<f64>) -> Matrix3<f64> {
    left_jacobian(&-w)
}

/// `J_r(e)^-1`: `log(exp(e) exp(d)) = e + J_r(e)^-1 d` to first order (closed form, valid for
/// `|e| < 2 pi`).
pub fn right_jacobian_inverse(e: &Vector3<f64>) -> Matrix3<f64> {
    let t2 = e.norm_squared();
    let k = skew(e);
    let c = if t2 < 1e-8 {
        // 1/t^2 - (1 + cos t)/(2 t sin t) = 1/12 + t^2/720.
        1.0 / 12.0 + t2 / 720.0
    } else {
        let t = t2.sqrt();
        1.0 / t2 - (1.0 + t.cos()) / (2.0 * t * t.sin())
    };
    Matrix3::identity() + 0.5 * k + c * k * k
}

/// `J_l(w)^-1`: `log(exp(d) exp(w)) = w + J_l(w)^-1 d` to first order (closed form, valid for
/// `|w| < 2 pi`; below `|w|^2 = 1e-10` its series to second order).
pub fn left_jacobian_inverse(w: &Vector3<f64>) -> Matrix3<f64> {
    let t2 = w.norm_squared();
    let k = w.cross_matrix();
    if t2 < 1e-10 {
        return Matrix3::identity() - 0.5 * k + k * k / 12.0;
    }
    let t = t2.sqrt();
    let c = 1.0 / t2 - (1.0 + t.cos()) / (2.0 * t * t.sin());
    Matrix3::identity() - 0.5 * k + c * k * k
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::UnitQuaternion;

    /// A quaternion: its `scaled_axis` keeps full precision at small angles (a rotation matrix's
    /// does not, about 4e-5 relative at 1e-6 rad).
    fn rot(w: &Vector3<f64>) -> UnitQuaternion<f64> {
        UnitQuaternion::from_scaled_axis(*w)
    }

    #[test]
    fn jacobians_match_their_defining_first_order_identities() {
        let d_step = 1e-6;
        for w in [
            Vector3::zeros(),
            Vector3::new(2e-5, -1e-5, 3e-5),
            Vector3::new(0.4, -1.1, 0.8),
            Vector3::new(2.9, 0.1, -0.2),
        ] {
            let (jl, jr, jri) = (left_jacobian(&w), right_jacobian(&w), right_jacobian_inverse(&w));
            for a in 0..3 {
                let d = Vector3::ith(a, d_step);
                // exp(w + d) exp(w)^-1 = exp(J_l d).
                let left = (rot(&(w + d)) * rot(&w).inverse()).scaled_axis() / d_step;
                assert!((left - jl.column(a)).norm() < 1e-6, "J_l at {w:?}: {left:?} vs {:?}", jl.column(a));
                // exp(w)^-1 exp(w + d) = exp(J_r d).
                let right = (rot(&w).inverse() * rot(&(w + d))).scaled_axis() / d_step;
                assert!((right - jr.column(a)).norm() < 1e-6, "J_r at {w:?}");
                // log(exp(w) exp(d)) - w = J_r^-1 d.
                let inv = ((rot(&w) * rot(&d)).scaled_axis() - w) / d_step;
                assert!((inv - jri.column(a)).norm() < 1e-5, "J_r^-1 at {w:?}: {inv:?} vs {:?}", jri.column(a));
                // log(exp(d) exp(w)) - w = J_l^-1 d.
                let inv_l = ((rot(&d) * rot(&w)).scaled_axis() - w) / d_step;
                let jli = left_jacobian_inverse(&w);
                assert!((inv_l - jli.column(a)).norm() < 1e-5, "J_l^-1 at {w:?}: {inv_l:?} vs {:?}", jli.column(a));
            }
            assert!((jr * jri - Matrix3::identity()).norm() < 1e-9);
            assert!((jl * left_jacobian_inverse(&w) - Matrix3::identity()).norm() < 1e-9);
        }
    }
}
