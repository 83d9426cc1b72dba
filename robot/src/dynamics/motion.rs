//! Platform motion: six pose coordinates and their rates, the twist and acceleration they give,
//! the same quantities in the body frame, and the Gibbs vector of an orientation.
//!
//! Pose coordinates are `x = (p_x, p_y, p_z, roll, pitch, yaw)` of `T_base_flange`, metres and
//! radians, with `R = Rz(yaw) Ry(pitch) Rx(roll)` (the URDF convention of
//! [`crate::geometry::rpy`]). With `e_1 = z`, `e_2 = Rz(yaw) y`, `e_3 = Rz(yaw) Ry(pitch) x` the
//! angular velocity is `w = yaw' e_1 + pitch' e_2 + roll' e_3`, and the angular acceleration adds
//! `pitch' (yaw' z) x e_2 + roll' (yaw' z + pitch' e_2) x e_3` to the same sum over the second
//! derivatives.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3, Vector6};

use crate::error::{Result, RobotError};
use crate::geometry::Pose;

/// The platform's pose, twist and acceleration, base frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionState {
    /// `T_base_flange`.
    pub pose: Pose,
    /// Velocity of the flange origin, m/s.
    pub velocity_m_s: Vector3<f64>,
    /// Angular velocity, rad/s.
    pub omega_rad_s: Vector3<f64>,
    /// Acceleration of the flange origin, m/s^2.
    pub acceleration_m_s2: Vector3<f64>,
    /// Angular acceleration, rad/s^2.
    pub alpha_rad_s2: Vector3<f64>,
}

/// The quantities of the Newton-Euler equations in the body (flange) frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyState {
    /// Gravity `R^T g`, m/s^2.
    pub gravity_m_s2: Vector3<f64>,
    /// Acceleration of the frame origin `R^T a`, m/s^2.
    pub acceleration_m_s2: Vector3<f64>,
    /// Angular velocity `R^T w`, rad/s.
    pub omega_rad_s: Vector3<f64>,
    /// Angular acceleration `R^T w'`, rad/s^2.
    pub alpha_rad_s2: Vector3<f64>,
}

/// `T_base_flange` from pose coordinates `(p, roll, pitch, yaw)`.
pub fn pose_from_coordinates(x: &[f64; 6]) -> Pose {
    Isometry3::from_parts(Translation3::new(x[0], x[1], x[2]), UnitQuaternion::from_euler_angles(x[3], x[4], x[5]))
}

/// Pose coordinates of `T_base_flange` (roll, pitch, yaw from the rotation; pitch within
/// `[-pi/2, pi/2]`).
pub fn coordinates_from_pose(pose: &Pose) -> [f64; 6] {
    let t = pose.translation.vector;
    let (r, p, y) = pose.rotation.euler_angles();
    [t.x, t.y, t.z, r, p, y]
}

/// The Gibbs (Rodrigues) vector `tan(theta / 2) * axis` of a rotation; `None` at half a turn,
/// where it is infinite.
pub fn gibbs_vector(rotation: &UnitQuaternion<f64>) -> Option<Vector3<f64>> {
    let w = rotation.w;
    if w.abs() < 1e-9 {
        return None;
    }
    Some(rotation.imag() / w)
}

impl MotionState {
    /// The twist `[v, w]`: the flange origin's velocity, then the angular velocity (base frame).
    pub fn twist(&self) -> Vector6<f64> {
        let (v, w) = (self.velocity_m_s, self.omega_rad_s);
        Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z)
    }

    /// A platform at rest.
    pub fn at_rest(pose: Pose) -> Self {
        Self {
            pose,
            velocity_m_s: Vector3::zeros(),
            omega_rad_s: Vector3::zeros(),
            acceleration_m_s2: Vector3::zeros(),
            alpha_rad_s2: Vector3::zeros(),
        }
    }

    /// The state from pose coordinates and their first and second time derivatives. Fails on
    /// non-finite input.
    pub fn from_coordinates(x: &[f64; 6], xd: &[f64; 6], xdd: &[f64; 6]) -> Result<Self> {
        if x.iter().chain(xd).chain(xdd).any(|v| !v.is_finite()) {
            return Err(RobotError::BadParameter {
                name: "pose coordinates".into(),
                value: f64::NAN,
                reason: "a pose coordinate or one of its rates is not finite".into(),
            });
        }
        let pose = pose_from_coordinates(x);
        let (roll_d, pitch_d, yaw_d) = (xd[3], xd[4], xd[5]);
        let rz = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), x[5]);
        let ry = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), x[4]);
        let e1 = Vector3::z();
        let e2 = rz * Vector3::y();
        let e3 = rz * (ry * Vector3::x());
        let omega = e1 * yaw_d + e2 * pitch_d + e3 * roll_d;
        let e2_dot = (e1 * yaw_d).cross(&e2);
        let e3_dot = (e1 * yaw_d + e2 * pitch_d).cross(&e3);
        let alpha = e1 * xdd[5] + e2 * xdd[4] + e3 * xdd[3] + e2_dot * pitch_d + e3_dot * roll_d;
        Ok(Self {
            pose,
            velocity_m_s: Vector3::new(xd[0], xd[1], xd[2]),
            omega_rad_s: omega,
            acceleration_m_s2: Vector3::new(xdd[0], xdd[1], xdd[2]),
            alpha_rad_s2: alpha,
        })
    }

    /// The body-frame quantities under `gravity_m_s2` (base frame).
    pub fn body(&self, gravity_m_s2: &Vector3<f64>) -> BodyState {
        let rt = self.pose.rotation.inverse();
        BodyState {
            gravity_m_s2: rt * gravity_m_s2,
            acceleration_m_s2: rt * self.acceleration_m_s2,
            omega_rad_s: rt * self.omega_rad_s,
            alpha_rad_s2: rt * self.alpha_rad_s2,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angular_rates_match_finite_differences() {
        let path = |t: f64| -> [f64; 6] {
            [0.1 * t, -0.02 * t * t, 0.8, 0.2 * (1.3 * t).sin(), 0.15 * (0.7 * t).cos(), 0.3 * t - 0.1 * t * t]
        };
        let rates = |t: f64, h: f64| -> ([f64; 6], [f64; 6]) {
            let (p, m, c) = (path(t + h), path(t - h), path(t));
            let mut d = [0.0; 6];
            let mut dd = [0.0; 6];
            for i in 0..6 {
                d[i] = (p[i] - m[i]) / (2.0 * h);
                dd[i] = (p[i] - 2.0 * c[i] + m[i]) / (h * h);
            }
            (d, dd)
        };
        let t = 0.9;
        let h = 1e-4;
        let (d, dd) = rates(t, h);
        let s = MotionState::from_coordinates(&path(t), &d, &dd).unwrap();
        // Angular velocity from the rotation's finite difference: R(t+h) R(t-h)^T = exp(2 h w).
        let rp = pose_from_coordinates(&path(t + h)).rotation;
        let rm = pose_from_coordinates(&path(t - h)).rotation;
        let w = (rp * rm.inverse()).scaled_axis() / (2.0 * h);
        assert!((w - s.omega_rad_s).norm() < 1e-6, "{w} vs {}", s.omega_rad_s);
        let omega_at = |tt: f64| {
            let (d, dd) = rates(tt, h);
            MotionState::from_coordinates(&path(tt), &d, &dd).unwrap().omega_rad_s
        };
        let a = (omega_at(t + 1e-3) - omega_at(t - 1e-3)) / 2e-3;
        assert!((a - s.alpha_rad_s2).norm() < 1e-4, "{a} vs {}", s.alpha_rad_s2);
        let back = coordinates_from_pose(&s.pose);
        for (x, y) in back.iter().zip(path(t)) {
            assert!((x - y).abs() < 1e-12);
        }
    }

    #[test]
    fn gibbs_vector_is_tan_half_angle() {
        let q = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.4);
        let g = gibbs_vector(&q).unwrap();
        assert!((g - Vector3::new(0.0, (0.2f64).tan(), 0.0)).norm() < 1e-14);
        assert!(gibbs_vector(&UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)).is_none());
    }
}
