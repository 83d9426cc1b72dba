//! Parameter manifolds: how a block's stored values (its *ambient* coordinates) move by a small
//! step in its *tangent* space.
//!
//! Every manifold here uses a left increment, `x ⊞ δ = Exp(δ) · x`, so a step is expressed in the
//! frame the block's value is expressed in (for a pose `T_a_b`: in frame `a`). Residual blocks give
//! their Jacobians with respect to that tangent step at the current point, `∂r(x ⊞ δ)/∂δ` at
//! `δ = 0`; [`crate::check`] verifies both the manifolds and those Jacobians numerically.
//!
//! | manifold | ambient (stored) | tangent (step) |
//! | --- | --- | --- |
//! | [`Euclidean`] | `n` values | the same `n` values |
//! | [`So3`] | unit quaternion `qw qx qy qz` (Hamilton, scalar first) | rotation vector `rx ry rz`, rad |
//! | [`Se3`] | `tx ty tz qw qx qy qz` (metres; quaternion as above) | `tx ty tz rx ry rz` (m, rad) |
//! | [`UnitVector3`] | unit 3-vector | 2 coordinates in a tangent basis, rad |
//!
//! [`Se3`] is the product chart R³ × SO(3): `t' = t + δt`, `R' = Exp(δr) R`; its 6-vector order
//! (translation first, then rotation) is the one documented in `docs/conventions.md` for every
//! pose increment of the project.

use nalgebra::{DMatrix, Quaternion, UnitQuaternion, Vector3};

/// A smooth manifold on which a parameter block lives.
pub trait Manifold: Send + Sync + std::fmt::Debug {
    /// A short name ("euclidean", "so3", ...), for error messages and indexes.
    fn name(&self) -> &'static str;
    /// Number of stored (ambient) values.
    fn ambient_size(&self) -> usize;
    /// Number of degrees of freedom (tangent size).
    fn tangent_size(&self) -> usize;
    /// `x ⊞ δ`, written to `out` (ambient size).
    fn plus(&self, x: &[f64], delta: &[f64], out: &mut [f64]);
    /// `y ⊟ x`: the step `δ` with `x ⊞ δ = y`, written to `out` (tangent size).
    fn minus(&self, y: &[f64], x: &[f64], out: &mut [f64]);
    /// `∂(x ⊞ δ)/∂δ` at `δ = 0` (ambient x tangent).
    fn plus_jacobian(&self, x: &[f64]) -> DMatrix<f64>;
    /// Whether `x` lies on the manifold (to `1e-9`).
    fn contains(&self, x: &[f64]) -> bool;
    /// Names of the tangent coordinates (`"x"`, `"rx"`, ...).
    fn tangent_names(&self) -> Vec<String>;
}

/// Ordinary vectors: `x ⊞ δ = x + δ`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Euclidean {
    /// Dimension.
    pub n: usize,
}

impl Manifold for Euclidean {
    fn name(&self) -> &'static str {
        "euclidean"
    }
    fn ambient_size(&self) -> usize {
        self.n
    }
    fn tangent_size(&self) -> usize {
        self.n
    }
    fn plus(&self, x: &[f64], delta: &[f64], out: &mut [f64]) {
        for ((o, a), d) in out.iter_mut().zip(x).zip(delta) {
            *o = a + d;
        }
    }
    fn minus(&self, y: &[f64], x: &[f64], out: &mut [f64]) {
        for ((o, a), b) in out.iter_mut().zip(y).zip(x) {
            *o = a - b;
        }
    }
    fn plus_jacobian(&self, _x: &[f64]) -> DMatrix<f64> {
        DMatrix::identity(self.n, self.n)
    }
    fn contains(&self, x: &[f64]) -> bool {
        x.len() == self.n && x.iter().all(|v| v.is_finite())
    }
    fn tangent_names(&self) -> Vec<String> {
        (0..self.n).map(|i| i.to_string()).collect()
    }
}

fn quat(x: &[f64]) -> UnitQuaternion<f64> {
    UnitQuaternion::new_unchecked(Quaternion::new(x[0], x[1], x[2], x[3]))
}

fn put_quat(q: &UnitQuaternion<f64>, out: &mut [f64]) {
    out[0] = q.w;
    out[1] = q.i;
    out[2] = q.j;
    out[3] = q.k;
}

fn unit_ok(x: &[f64]) -> bool {
    x.iter().all(|v| v.is_finite()) && (x.iter().map(|v| v * v).sum::<f64>() - 1.0).abs() < 1e-9
}

/// `∂(Exp(δ) q)/∂δ` at `δ = 0` for a quaternion `q` (4 x 3): `½ [-v^T; w I - [v]x]`.
fn quat_left_jacobian(x: &[f64]) -> DMatrix<f64> {
    let (w, v) = (x[0], Vector3::new(x[1], x[2], x[3]));
    let mut j = DMatrix::zeros(4, 3);
    for c in 0..3 {
        j[(0, c)] = -0.5 * v[c];
    }
    let skew = v.cross_matrix();
    for r in 0..3 {
        for c in 0..3 {
            let id = if r == c { w } else { 0.0 };
            j[(1 + r, c)] = 0.5 * (id - skew[(r, c)]);
        }
    }
    j
}

/// Rotations stored as unit quaternions, stepped by a rotation vector on the left.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct So3;

impl Manifold for So3 {
    fn name(&self) -> &'static str {
        "so3"
    }
    fn ambient_size(&self) -> usize {
        4
    }
    fn tangent_size(&self) -> usize {
        3
    }
    fn plus(&self, x: &[f64], delta: &[f64], out: &mut [f64]) {
        let q = UnitQuaternion::from_scaled_axis(Vector3::new(delta[0], delta[1], delta[2])) * quat(x);
        put_quat(&UnitQuaternion::new_normalize(*q.quaternion()), out);
    }
    fn minus(&self, y: &[f64], x: &[f64], out: &mut [f64]) {
        let d = (quat(y) * quat(x).inverse()).scaled_axis();
        out.copy_from_slice(d.as_slice());
    }
    fn plus_jacobian(&self, x: &[f64]) -> DMatrix<f64> {
        quat_left_jacobian(x)
    }
    fn contains(&self, x: &[f64]) -> bool {
        x.len() == 4 && unit_ok(x)
    }
    fn tangent_names(&self) -> Vec<String> {
        ["rx", "ry", "rz"].map(String::from).to_vec()
    }
}

/// Rigid transforms stored as `tx ty tz qw qx qy qz`, stepped in the product chart
/// `t' = t + δt`, `R' = Exp(δr) R` with the tangent `[δt, δr]`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Se3;

impl Se3 {
    /// The stored values of a pose.
    pub fn from_isometry(t: &nalgebra::Isometry3<f64>) -> [f64; 7] {
        let v = t.translation.vector;
        let q = t.rotation;
        [v.x, v.y, v.z, q.w, q.i, q.j, q.k]
    }

    /// The pose of stored values `x` (7 values; the quaternion is normalised).
    pub fn to_isometry(x: &[f64]) -> nalgebra::Isometry3<f64> {
        nalgebra::Isometry3::from_parts(
            nalgebra::Translation3::new(x[0], x[1], x[2]),
            UnitQuaternion::new_normalize(Quaternion::new(x[3], x[4], x[5], x[6])),
        )
    }
}

impl Manifold for Se3 {
    fn name(&self) -> &'static str {
        "se3"
    }
    fn ambient_size(&self) -> usize {
        7
    }
    fn tangent_size(&self) -> usize {
        6
    }
    fn plus(&self, x: &[f64], delta: &[f64], out: &mut [f64]) {
        for i in 0..3 {
            out[i] = x[i] + delta[i];
        }
        So3.plus(&x[3..7], &delta[3..6], &mut out[3..7]);
    }
    fn minus(&self, y: &[f64], x: &[f64], out: &mut [f64]) {
        for i in 0..3 {
            out[i] = y[i] - x[i];
        }
        So3.minus(&y[3..7], &x[3..7], &mut out[3..6]);
    }
    fn plus_jacobian(&self, x: &[f64]) -> DMatrix<f64> {
        let mut j = DMatrix::zeros(7, 6);
        for i in 0..3 {
            j[(i, i)] = 1.0;
        }
        j.view_mut((3, 3), (4, 3)).copy_from(&quat_left_jacobian(&x[3..7]));
        j
    }
    fn contains(&self, x: &[f64]) -> bool {
        x.len() == 7 && x[..3].iter().all(|v| v.is_finite()) && unit_ok(&x[3..7])
    }
    fn tangent_names(&self) -> Vec<String> {
        ["tx", "ty", "tz", "rx", "ry", "rz"].map(String::from).to_vec()
    }
}

/// Unit 3-vectors (axis directions), stepped along great circles:
/// `x ⊞ δ = cos|v| x + sin|v| v/|v|` with `v = B(x) δ`, `B(x)` an orthonormal tangent basis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UnitVector3;

impl UnitVector3 {
    /// The tangent basis at `x` (3 x 2, orthonormal, perpendicular to `x`): the axis least aligned
    /// with `x`, made perpendicular, and its cross product with `x`.
    pub fn basis(x: &[f64]) -> nalgebra::Matrix3x2<f64> {
        let v = Vector3::new(x[0], x[1], x[2]);
        let k = (0..3).min_by(|&a, &b| v[a].abs().total_cmp(&v[b].abs())).unwrap_or(0);
        let e = Vector3::ith(k, 1.0);
        let b1 = (e - v * v.dot(&e)).normalize();
        let b2 = v.cross(&b1);
        nalgebra::Matrix3x2::from_columns(&[b1, b2])
    }
}

impl Manifold for UnitVector3 {
    fn name(&self) -> &'static str {
        "unit_vector3"
    }
    fn ambient_size(&self) -> usize {
        3
    }
    fn tangent_size(&self) -> usize {
        2
    }
    fn plus(&self, x: &[f64], delta: &[f64], out: &mut [f64]) {
        let v = Self::basis(x) * nalgebra::Vector2::new(delta[0], delta[1]);
        let a = v.norm();
        let p = Vector3::new(x[0], x[1], x[2]);
        let y = if a < 1e-300 { p } else { p * a.cos() + v * (a.sin() / a) };
        let y = y.normalize();
        out.copy_from_slice(y.as_slice());
    }
    fn minus(&self, y: &[f64], x: &[f64], out: &mut [f64]) {
        let p = Vector3::new(x[0], x[1], x[2]);
        let q = Vector3::new(y[0], y[1], y[2]);
        let perp = q - p * p.dot(&q);
        let s = perp.norm();
        let angle = s.atan2(p.dot(&q));
        let v = if s < 1e-300 { Vector3::zeros() } else { perp * (angle / s) };
        let d = Self::basis(x).transpose() * v;
        out[0] = d[0];
        out[1] = d[1];
    }
    fn plus_jacobian(&self, x: &[f64]) -> DMatrix<f64> {
        let b = Self::basis(x);
        DMatrix::from_fn(3, 2, |r, c| b[(r, c)])
    }
    fn contains(&self, x: &[f64]) -> bool {
        x.len() == 3 && unit_ok(x)
    }
    fn tangent_names(&self) -> Vec<String> {
        ["u", "v"].map(String::from).to_vec()
    }
}
