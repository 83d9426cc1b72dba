//! The lens-distortion maps and their analytic derivatives.
//!
//! Everything here works on *normalised* coordinates (metric image plane at unit distance, no
//! focal length, no principal point). The pixel step `u = fx x_d + cx`, `v = fy y_d + cy` lives in
//! [`super::CameraModel`].
//!
//! ## Brown-Conrady with the rational radial term (OpenCV `k1 k2 p1 p2 k3 k4 k5 k6`)
//! For a point `(X, Y, Z)` with `Z > 0`: `x = X / Z`, `y = Y / Z`, `r^2 = x^2 + y^2`,
//!
//! ```text
//! R   = (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)
//! x_d = x R + 2 p1 x y + p2 (r^2 + 2 x^2)
//! y_d = y R + p1 (r^2 + 2 y^2) + 2 p2 x y
//! ```
//!
//! The five-coefficient model is the same with `k4 = k5 = k6 = 0`.
//!
//! ## Kannala-Brandt (OpenCV `fisheye`, `k1..k4`)
//! `rho = sqrt(X^2 + Y^2)`, `theta = atan2(rho, Z)` (the angle from the optical axis),
//!
//! ```text
//! theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)
//! x_d = (theta_d / rho) X,   y_d = (theta_d / rho) Y
//! ```
//!
//! which equals OpenCV's `fisheye::projectPoints` for `Z > 0` and continues it to
//! `theta < pi`.

/// Value and derivatives of a distortion map at one point.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Distorted {
    /// Distorted normalised coordinates `(x_d, y_d)`.
    pub xd: [f64; 2],
    /// `d(x_d, y_d) / d(X, Y, Z)` (row-major, 2 x 3).
    pub d_point: [[f64; 3]; 2],
    /// `d(x_d, y_d) / d(coefficients)`, coefficients in OpenCV order; only the model's first
    /// `n` columns are meaningful.
    pub d_coeffs: [[f64; 8]; 2],
}

/// Brown-Conrady / rational map of the undistorted normalised point `(x, y)`.
/// `c` holds `k1 k2 p1 p2 k3 k4 k5 k6`. Returns `(x_d, y_d)`, `d(x_d,y_d)/d(x,y)` and
/// `d(x_d,y_d)/d(c)`. `None` when the rational denominator is not positive.
pub(crate) fn brown_normalized(c: &[f64; 8], x: f64, y: f64) -> Option<BrownResult> {
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

/// Result of [`brown_normalized`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct BrownResult {
    /// Distorted normalised point.
    pub xd: [f64; 2],
    /// `d(x_d, y_d)/d(x, y)`.
    pub j_xy: [[f64; 2]; 2],
    /// `d(x_d, y_d)/d(k1 k2 p1 p2 k3 k4 k5 k6)`.
    pub j_c: [[f64; 8]; 2],
}

/// Brown-Conrady / rational map of a 3D point (requires `Z > 0`, checked by the caller).
pub(crate) fn brown_point(c: &[f64; 8], p: [f64; 3]) -> Option<Distorted> {
    let inv_z = 1.0 / p[2];
    let x = p[0] * inv_z;
    let y = p[1] * inv_z;
    let b = brown_normalized(c, x, y)?;
    // d(x, y)/d(X, Y, Z) = [[1/Z, 0, -x/Z], [0, 1/Z, -y/Z]]
    let mut d_point = [[0.0; 3]; 2];
    for (row, j) in d_point.iter_mut().zip(b.j_xy.iter()) {
        row[0] = j[0] * inv_z;
        row[1] = j[1] * inv_z;
        row[2] = -(j[0] * x + j[1] * y) * inv_z;
    }
    Some(Distorted { xd: b.xd, d_point, d_coeffs: b.j_c })
}

/// `theta (1 + k1 theta^2 + ... + k4 theta^8)` and its derivative in `theta`.
pub(crate) fn kb_theta_d(k: &[f64; 4], theta: f64) -> (f64, f64) {
    let t2 = theta * theta;
    let poly = 1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3])));
    let dpoly = 1.0 + t2 * (3.0 * k[0] + t2 * (5.0 * k[1] + t2 * (7.0 * k[2] + t2 * 9.0 * k[3])));
    (theta * poly, dpoly)
}

/// Kannala-Brandt map of a 3D point. `None` at the centre of projection or on the negative
/// optical axis (direction undefined).
pub(crate) fn kb_point(k: &[f64; 4], p: [f64; 3]) -> Option<Distorted> {
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
        let (thd, dthd) = kb_theta_d(k, th);
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
