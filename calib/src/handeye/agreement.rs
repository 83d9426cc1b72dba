//! The robot's motion against the camera's, before any fit: between two images the flange moves
//! by `A = F_i^-1 F_j` and the camera sees the target move by `B = C_i C_j^-1` (the closed forms'
//! `C`, [`super::Mount::closed_form_c`]), and `A X = X B` whatever the hand-eye transform `X`.
//! So, model-free:
//! - the rotation angles agree: `angle(A) = angle(B)` (a joint in degrees read as radians, a row
//!   paired with the wrong image or a wrong robot model break it);
//! - the travels along the screw axes agree up to the target's print scale: `d_A = s d_B`, `d = t
//!   . axis` (quaternions in another order, a wrong robot model or mount break it; the angle of a
//!   relative rotation does not depend on the order of a quaternion's four numbers, the axis does).
//!
//! And per image, from a robust closed-form `X` (rotation by a weighted Kabsch fit of the motions'
//! rotation vectors, translation and scale by iteratively re-weighted least squares): each pair's
//! residual of `A X = X B` in rotation (deg) and translation (mm); an image whose robot pose is off
//! has large residuals with every other image. The decisions are the caller's
//! (`ferrocal_datasets::handeye::motion_check`): this module only measures.

use nalgebra::{Isometry3, Matrix3, Matrix3x4, Matrix4, Rotation3, Translation3, UnitQuaternion, Vector3, Vector4};
use serde::{Deserialize, Serialize};

use super::Mount;

/// Relative motions that rotate less than this (degrees) have no screw axis to compare
/// travels along: their pitches are left out.
pub const MIN_SCREW_ROTATION_DEG: f64 = 5.0;

/// The smallest median rotation (degrees) and travel (millimetres) the disagreements are taken
/// relative to: below them the motions are mostly noise (the real recordings: 27 to 103 deg,
/// 95 to 400 mm).
pub const MIN_RELATIVE_TO_DEG_MM: (f64, f64) = (10.0, 100.0);

/// Fewest images the comparison needs (three pairs at least).
pub const MIN_VIEWS: usize = 4;

/// Up to this many images every pair is compared; beyond, each image with its
/// [`NEIGHBOUR_PAIRS`] next ones.
pub const MAX_ALL_PAIRS_VIEWS: usize = 200;

/// Pairs per image beyond [`MAX_ALL_PAIRS_VIEWS`] images.
pub const NEIGHBOUR_PAIRS: usize = 100;

/// Re-weighting passes of the robust closed-form fit.
const IRLS_PASSES: usize = 8;

/// The Cauchy weight's scale, in median residuals: a pair at this many times the median
/// weighs one half.
const IRLS_CLIP: f64 = 3.0;

/// Floors of the median residuals in the weights: degrees, millimetres.
const RESIDUAL_FLOOR_DEG_MM: (f64, f64) = (1e-4, 1e-3);

/// How one image's motions agree with the others'.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewAgreement {
    /// Index of the image in the lists given.
    pub index: usize,
    /// Median over its pairs of `|angle(A) - angle(B)|`, degrees.
    pub angle_deg: f64,
    /// Median over its pairs of the rotation residual of `A X = X B`, degrees.
    pub residual_rotation_deg: f64,
    /// Median over its pairs of the translation residual of `A X = X B`, millimetres.
    pub residual_translation_mm: f64,
}

/// The agreement of the robot's and the camera's relative motions over all pairs of images.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MotionAgreement {
    /// Images compared.
    pub n_views: usize,
    /// Pairs compared.
    pub n_pairs: usize,
    /// Median rotation angle of the robot's relative motions, degrees.
    pub median_rotation_deg: f64,
    /// Median over pairs of `|angle(A) - angle(B)|`, degrees.
    pub rotation_disagreement_deg: f64,
    /// Pairs whose rotation exceeds [`MIN_SCREW_ROTATION_DEG`] (their travels are compared).
    pub n_screw_pairs: usize,
    /// The robot's travel along the screw axis over the camera's (least absolute deviations
    /// through the origin): the target's print scale; 1 when the target is as printed.
    pub scale: f64,
    /// Median over the screw pairs of `|d_A|`, millimetres.
    pub median_travel_mm: f64,
    /// Median over the screw pairs of `|d_A - scale d_B|`, millimetres.
    pub travel_disagreement_mm: f64,
    /// Median over pairs of the rotation residual of `A X = X B` with the robust `X`, degrees.
    pub residual_rotation_deg: f64,
    /// Median over pairs of the translation residual, millimetres.
    pub residual_translation_mm: f64,
    /// The robust closed form's `X` (the module's conventions; the camera's travels scaled).
    pub closed_form_x: Isometry3<f64>,
    /// The robust closed form's scale of the camera's travels.
    pub closed_form_scale: f64,
    /// Per image.
    pub views: Vec<ViewAgreement>,
}

impl MotionAgreement {
    /// The median residuals (deg, mm) of image `k`'s pairs with every other image with the
    /// closed form of these figures, for the robot poses `flange` and the PnP poses
    /// `t_camera_target` (e.g. image `k` given another row's pose): how well the image would fit.
    pub fn view_residuals(
        &self,
        mount: Mount,
        k: usize,
        flange: &[Isometry3<f64>],
        t_camera_target: &[Isometry3<f64>],
    ) -> (f64, f64) {
        let c = |i: usize| mount.closed_form_c(&t_camera_target[i]);
        let (rot, trans): (Vec<f64>, Vec<f64>) = (0..flange.len().min(t_camera_target.len()))
            .filter(|&j| j != k)
            .map(|j| {
                let (i, j) = (k.min(j), k.max(j));
                let (a, b) = (flange[i].inverse() * flange[j], c(i) * c(j).inverse());
                residual(&a, &b, &self.closed_form_x, self.closed_form_scale)
            })
            .unzip();
        (median(&rot), median(&trans))
    }

    /// `rotation_disagreement_deg` over `median_rotation_deg` (at least
    /// [`MIN_RELATIVE_TO_DEG_MM`]`.0`, so that a recording that hardly rotates is not judged
    /// by its noise): scale-free, 0.002 to 0.07 on the real recordings.
    pub fn relative_rotation(&self) -> f64 {
        self.rotation_disagreement_deg / self.median_rotation_deg.max(MIN_RELATIVE_TO_DEG_MM.0)
    }

    /// `travel_disagreement_mm` over `median_travel_mm` (at least [`MIN_RELATIVE_TO_DEG_MM`]`.1`;
    /// 0 without screw pairs).
    pub fn relative_travel(&self) -> f64 {
        if self.n_screw_pairs == 0 {
            0.0
        } else {
            self.travel_disagreement_mm / self.median_travel_mm.max(MIN_RELATIVE_TO_DEG_MM.1)
        }
    }
}

/// The median of `v`'s finite values (NaN when there are none).
pub fn median(v: &[f64]) -> f64 {
    let s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if s.is_empty() {
        return f64::NAN;
    }
    ferrocal_vision::calib::median(&s)
}

/// The rotation angle of `q`, radians in [0, pi] (exact near zero, unlike an arc cosine).
fn angle(q: &UnitQuaternion<f64>) -> f64 {
    2.0 * q.imag().norm().atan2(q.w.abs())
}

/// The rotation vector of `q` (axis times angle in [0, pi]; zero for the identity).
fn log(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    let v = q.imag();
    let n = v.norm();
    if n < 1e-15 {
        return Vector3::zeros();
    }
    v * (angle(q) / n) * if q.w >= 0.0 { 1.0 } else { -1.0 }
}

/// Angle (rad, in [0, pi]) and travel along the axis (m) of a relative motion.
fn screw(m: &Isometry3<f64>) -> (f64, f64) {
    let q = m.rotation;
    let v = q.imag();
    let angle = angle(&q);
    if v.norm() < 1e-15 {
        return (0.0, 0.0);
    }
    // The axis with the angle in [0, pi]: along the imaginary part when w >= 0.
    let axis = v.normalize() * if q.w >= 0.0 { 1.0 } else { -1.0 };
    (angle, m.translation.vector.dot(&axis))
}

/// The weighted median of `values` (weights >= 0): the `s` minimising `sum w |v - s|`.
fn weighted_median(values: &[f64], weights: &[f64]) -> f64 {
    let mut p: Vec<(f64, f64)> = values.iter().copied().zip(weights.iter().copied()).filter(|p| p.1 > 0.0).collect();
    if p.is_empty() {
        return f64::NAN;
    }
    p.sort_by(|a, b| a.0.total_cmp(&b.0));
    let half = 0.5 * p.iter().map(|x| x.1).sum::<f64>();
    let mut acc = 0.0;
    for (v, w) in &p {
        acc += w;
        if acc >= half {
            return *v;
        }
    }
    p[p.len() - 1].0
}

/// One pair of images.
struct Pair {
    i: usize,
    j: usize,
    a: Isometry3<f64>,
    b: Isometry3<f64>,
}

/// The rotation (deg) and translation (mm) residuals of `A X = X B` for the closed form `X =
/// (q_x, t_x)` with the camera's travels scaled by `s`.
fn residual(a: &Isometry3<f64>, b: &Isometry3<f64>, x: &Isometry3<f64>, s: f64) -> (f64, f64) {
    let q_x = x.rotation;
    let rot = angle(&(a.rotation * q_x * b.rotation.inverse() * q_x.inverse())).to_degrees();
    let ra = a.rotation.to_rotation_matrix().into_inner();
    let e = (ra - Matrix3::identity()) * x.translation.vector - s * (q_x * b.translation.vector) + a.translation.vector;
    (rot, e.norm() * 1e3)
}

/// The robust closed form's `X` and scale, and every pair's final residuals (deg, mm).
struct ClosedFit {
    x: Isometry3<f64>,
    scale: f64,
    rotation_deg: Vec<f64>,
    translation_mm: Vec<f64>,
}

/// The robust closed form: `X` and the scale `s` from the pairs with weights re-computed from
/// the residuals, and the final residuals (deg, mm) of every pair.
fn robust_closed_form(pairs: &[Pair]) -> Option<ClosedFit> {
    let n = pairs.len();
    let mut w = vec![1.0; n];
    let mut res = (vec![0.0; n], vec![0.0; n]);
    let mut fit = (Isometry3::identity(), 1.0);
    for _ in 0..IRLS_PASSES {
        // Rotation: R_X maps B's rotation vectors onto A's (weighted Kabsch).
        let mut h = Matrix3::zeros();
        for (p, wk) in pairs.iter().zip(&w) {
            h += *wk * log(&p.b.rotation) * log(&p.a.rotation).transpose();
        }
        let svd = h.svd(true, true);
        let (u, vt) = (svd.u?, svd.v_t?);
        let d = (vt.transpose() * u.transpose()).determinant().signum();
        let r_x = vt.transpose() * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
        let r_x = Rotation3::from_matrix_unchecked(r_x);
        // Translation and scale: (R_A - I) t_X - s R_X t_B = -t_A, by weighted normal equations.
        let mut normal = Matrix4::zeros();
        let mut rhs = Vector4::zeros();
        for (p, wk) in pairs.iter().zip(&w) {
            let ra = p.a.rotation.to_rotation_matrix().into_inner() - Matrix3::identity();
            let mut m = Matrix3x4::zeros();
            m.fixed_view_mut::<3, 3>(0, 0).copy_from(&ra);
            m.set_column(3, &-(r_x * p.b.translation.vector));
            normal += *wk * m.transpose() * m;
            rhs += *wk * m.transpose() * -p.a.translation.vector;
        }
        let sol = normal.try_inverse()? * rhs;
        let x = Isometry3::from_parts(
            Translation3::new(sol[0], sol[1], sol[2]),
            UnitQuaternion::from_rotation_matrix(&r_x),
        );
        fit = (x, sol[3]);
        for (k, p) in pairs.iter().enumerate() {
            (res.0[k], res.1[k]) = residual(&p.a, &p.b, &fit.0, fit.1);
        }
        // Cauchy weights on the residuals over their medians (floored far below any real noise,
        // so that an exact recording's rounding does not weigh).
        let (mr, mt) = (median(&res.0).max(RESIDUAL_FLOOR_DEG_MM.0), median(&res.1).max(RESIDUAL_FLOOR_DEG_MM.1));
        for (wk, (r, t)) in w.iter_mut().zip(res.0.iter().zip(&res.1)) {
            let z = (r / mr).max(t / mt) / IRLS_CLIP;
            *wk = 1.0 / (1.0 + z * z);
        }
    }
    let finite = res.0.iter().chain(&res.1).all(|v| v.is_finite()) && fit.1.is_finite();
    finite.then_some(ClosedFit { x: fit.0, scale: fit.1, rotation_deg: res.0, translation_mm: res.1 })
}

/// The pairs compared among `n` images: all of them up to [`MAX_ALL_PAIRS_VIEWS`] images, else
/// each image with the next [`NEIGHBOUR_PAIRS`] (cyclically), so that the work grows linearly.
fn pair_indices(n: usize) -> Vec<(usize, usize)> {
    if n <= MAX_ALL_PAIRS_VIEWS {
        (0..n).flat_map(|i| (i + 1..n).map(move |j| (i, j))).collect()
    } else {
        (0..n)
            .flat_map(|i| (1..=NEIGHBOUR_PAIRS).map(move |d| (i, (i + d) % n)))
            .map(|(i, j)| (i.min(j), i.max(j)))
            .collect()
    }
}

/// Compares the robot's relative motions (`flange[i]` = `T_base_flange` of image `i`) with the
/// camera's (`t_camera_target[i]`, its PnP pose) over every pair of images. `None` with fewer
/// than [`MIN_VIEWS`] images or when the closed form cannot be solved.
pub fn motion_agreement(
    mount: Mount,
    flange: &[Isometry3<f64>],
    t_camera_target: &[Isometry3<f64>],
) -> Option<MotionAgreement> {
    let n = flange.len().min(t_camera_target.len());
    if n < MIN_VIEWS {
        return None;
    }
    let c: Vec<Isometry3<f64>> = t_camera_target.iter().map(|t| mount.closed_form_c(t)).collect();
    let pairs: Vec<Pair> = pair_indices(n)
        .into_iter()
        .map(|(i, j)| Pair { i, j, a: flange[i].inverse() * flange[j], b: c[i] * c[j].inverse() })
        .collect();
    let screws: Vec<((f64, f64), (f64, f64))> = pairs.iter().map(|p| (screw(&p.a), screw(&p.b))).collect();
    let angle_diff: Vec<f64> = screws.iter().map(|(a, b)| (a.0 - b.0).abs().to_degrees()).collect();
    let angles: Vec<f64> = screws.iter().map(|(a, _)| a.0.to_degrees()).collect();
    let min_rad = MIN_SCREW_ROTATION_DEG.to_radians();
    let screw_pairs: Vec<usize> =
        (0..pairs.len()).filter(|&k| screws[k].0 .0 > min_rad && screws[k].1 .0 > min_rad).collect();
    // The print scale by least absolute deviations through the origin: the weighted median of
    // the ratios d_A / d_B with weights |d_B|.
    let ratios: Vec<f64> = screw_pairs.iter().map(|&k| screws[k].0 .1 / screws[k].1 .1).collect();
    let weights: Vec<f64> = screw_pairs.iter().map(|&k| screws[k].1 .1.abs()).collect();
    let scale = if screw_pairs.is_empty() { 1.0 } else { weighted_median(&ratios, &weights) };
    let travel: Vec<f64> = screw_pairs.iter().map(|&k| screws[k].0 .1.abs() * 1e3).collect();
    let travel_diff: Vec<f64> =
        screw_pairs.iter().map(|&k| (screws[k].0 .1 - scale * screws[k].1 .1).abs() * 1e3).collect();
    let ClosedFit { x: closed_form_x, scale: closed_form_scale, rotation_deg: res_rot, translation_mm: res_trans } =
        robust_closed_form(&pairs)?;
    let views = (0..n)
        .map(|v| {
            let of = |x: &[f64]| {
                median(&pairs.iter().zip(x).filter(|(p, _)| p.i == v || p.j == v).map(|(_, r)| *r).collect::<Vec<_>>())
            };
            ViewAgreement {
                index: v,
                angle_deg: of(&angle_diff),
                residual_rotation_deg: of(&res_rot),
                residual_translation_mm: of(&res_trans),
            }
        })
        .collect();
    Some(MotionAgreement {
        n_views: n,
        n_pairs: pairs.len(),
        median_rotation_deg: median(&angles),
        rotation_disagreement_deg: median(&angle_diff),
        n_screw_pairs: screw_pairs.len(),
        scale: if scale.is_finite() { scale } else { 1.0 },
        median_travel_mm: if travel.is_empty() { 0.0 } else { median(&travel) },
        travel_disagreement_mm: if travel_diff.is_empty() { 0.0 } else { median(&travel_diff) },
        residual_rotation_deg: median(&res_rot),
        residual_translation_mm: median(&res_trans),
        closed_form_x,
        closed_form_scale,
        views,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(t: [f64; 3], r: [f64; 3]) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::new(t[0], t[1], t[2]), UnitQuaternion::from_scaled_axis(Vector3::from(r)))
    }

    /// Exact eye-in-hand motions agree to rounding; the print scale is found; one image's robot
    /// pose 50 mm off stands out in its own residuals only; quaternions read in another order
    /// keep every rotation angle but not the travels.
    #[test]
    fn exact_motions_agree_and_an_offset_pose_stands_out() {
        let x = pose([0.03, -0.02, 0.1], [0.1, -0.2, 1.5]);
        let w = pose([0.8, 0.1, -0.2], [3.0, 0.1, 0.2]);
        let flange: Vec<Isometry3<f64>> = (0..8)
            .map(|k| {
                let f = k as f64;
                pose(
                    [0.5 + 0.05 * f, -0.1 * (f * 0.7).sin(), 0.6 + 0.03 * f],
                    [0.4 * (f * 1.3).sin(), 0.3 * f.cos(), 0.5 * f],
                )
            })
            .collect();
        let scale = 1.02;
        let cams: Vec<Isometry3<f64>> = flange
            .iter()
            .map(|f| {
                let t = Mount::EyeInHand.t_camera_target(&x, &w, f);
                Isometry3::from_parts(Translation3::from(t.translation.vector / scale), t.rotation)
            })
            .collect();
        let a = motion_agreement(Mount::EyeInHand, &flange, &cams).unwrap();
        assert_eq!((a.n_views, a.n_pairs), (8, 28));
        assert!(a.rotation_disagreement_deg < 1e-9 && a.travel_disagreement_mm < 1e-6, "{a:?}");
        assert!((a.scale - scale).abs() < 1e-9 && a.residual_translation_mm < 1e-6, "{a:?}");
        let mut off = flange.clone();
        off[3].translation.vector.x += 0.05;
        let b = motion_agreement(Mount::EyeInHand, &off, &cams).unwrap();
        let worst =
            b.views.iter().max_by(|p, q| p.residual_translation_mm.total_cmp(&q.residual_translation_mm)).unwrap();
        assert_eq!(worst.index, 3);
        assert!(worst.residual_translation_mm > 30.0 && b.residual_translation_mm < 5.0, "{b:?}");
        let permuted: Vec<Isometry3<f64>> = flange
            .iter()
            .map(|f| {
                let q = f.rotation;
                let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q.i, q.j, q.k, q.w));
                Isometry3::from_parts(f.translation, q)
            })
            .collect();
        let c = motion_agreement(Mount::EyeInHand, &permuted, &cams).unwrap();
        assert!(c.rotation_disagreement_deg < 1e-6, "{c:?}");
        assert!(c.relative_travel() > 0.2, "{c:?}");
        assert!(motion_agreement(Mount::EyeInHand, &flange[..3], &cams[..3]).is_none());
    }
}
