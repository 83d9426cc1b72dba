//! Whether the robot's motions determine the hand-eye transform at all. Hand-eye calibration
//! needs the flange to rotate between images, about at least two axes that are not parallel
//! (Tsai and Lenz): without any rotation the translation of `X` is confounded with that of `W`
//! (only their combination moves the image), and with rotations about one axis only, `X`'s
//! translation along that axis is. The solvers still return numbers in both cases, so the
//! result says so in words.

use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use super::HandEyeView;
use crate::measurement::Split;

/// Below this relative rotation (degrees) between any two training poses, the flange is taken as
/// not rotating: a rotation this small moves a point 100 mm from the axis by less than 3.5 mm.
pub const MIN_ROTATION_DEG: f64 = 2.0;

/// The spread of the flange orientations over the training images.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MotionGeometry {
    /// The largest relative rotation between two training poses, degrees.
    pub max_rotation_deg: f64,
    /// The largest rotation component of any pair perpendicular to the dominant rotation axis,
    /// degrees: how much the motions rotate about a second axis.
    pub second_axis_rotation_deg: f64,
}

impl MotionGeometry {
    /// The geometry of the training views' flange poses.
    pub fn of(views: &[HandEyeView]) -> Self {
        let rotations: Vec<UnitQuaternion<f64>> =
            views.iter().filter(|v| v.split == Split::Train).map(|v| v.t_base_flange.rotation).collect();
        let mut axes: Vec<Vector3<f64>> = Vec::new();
        for (i, a) in rotations.iter().enumerate() {
            for b in &rotations[i + 1..] {
                axes.push((a.inverse() * b).scaled_axis());
            }
        }
        let max_rotation_deg = axes.iter().map(|w| w.norm()).fold(0.0, f64::max).to_degrees();
        let scatter: Matrix3<f64> = axes.iter().map(|w| w * w.transpose()).sum();
        let eigen = scatter.symmetric_eigen();
        let k = eigen.eigenvalues.imax();
        let dominant = eigen.eigenvectors.column(k).into_owned();
        let second_axis_rotation_deg =
            axes.iter().map(|w| (w - dominant * dominant.dot(w)).norm()).fold(0.0, f64::max).to_degrees();
        Self { max_rotation_deg, second_axis_rotation_deg }
    }

    /// What the geometry leaves undetermined, in words (empty when the motions suffice).
    pub fn warnings(&self) -> Vec<String> {
        if self.max_rotation_deg < MIN_ROTATION_DEG {
            vec![format!(
                "the flange hardly rotates between the training images (largest relative rotation {:.3} deg): \
                 the hand-eye translation is not determined apart from the fixed transform's, only their \
                 combination is, and its stated standard deviations rest on that tiny rotation; rotate the \
                 flange between images, by 20 deg or more about at least two axes",
                self.max_rotation_deg
            )]
        } else if self.second_axis_rotation_deg < MIN_ROTATION_DEG {
            vec![format!(
                "the flange rotates about one axis only (at most {:.3} deg about any other): the hand-eye \
                 translation along that axis is not determined; rotate about a second axis too",
                self.second_axis_rotation_deg
            )]
        } else {
            Vec::new()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrocal_vision::camera::ImageSize;
    use nalgebra::{Isometry3, Translation3};

    fn view(t: Vector3<f64>, r: Vector3<f64>) -> HandEyeView {
        HandEyeView {
            name: "v".into(),
            split: Split::Train,
            t_base_flange: Isometry3::from_parts(Translation3::from(t), UnitQuaternion::from_scaled_axis(r)),
            image_size: ImageSize { width_px: 640, height_px: 480 },
            point_ids: Vec::new(),
            corners_px: Vec::new(),
            covariances_px2: Vec::new(),
        }
    }

    #[test]
    fn pure_translations_one_axis_and_two_axes_are_told_apart() {
        let z = Vector3::zeros();
        let translations: Vec<HandEyeView> = (0..5).map(|k| view(Vector3::new(0.1 * k as f64, 0.0, 0.5), z)).collect();
        let g = MotionGeometry::of(&translations);
        assert!(g.max_rotation_deg < 1e-9);
        assert!(g.warnings()[0].contains("hardly rotates"));

        let one_axis: Vec<HandEyeView> = (0..5).map(|k| view(z, Vector3::new(0.0, 0.0, 0.2 * k as f64))).collect();
        let g = MotionGeometry::of(&one_axis);
        assert!((g.max_rotation_deg - 0.8f64.to_degrees()).abs() < 1e-9, "{g:?}");
        assert!(g.second_axis_rotation_deg < 1e-9, "{g:?}");
        assert!(g.warnings()[0].contains("one axis only"));

        let mut two_axes = one_axis.clone();
        two_axes.push(view(z, Vector3::new(0.3, 0.0, 0.0)));
        let g = MotionGeometry::of(&two_axes);
        assert!(g.second_axis_rotation_deg > 10.0, "{g:?}");
        assert!(g.warnings().is_empty());

        let mut held_out = translations.clone();
        held_out.push(view(z, Vector3::new(0.3, 0.2, 0.0)));
        held_out.last_mut().unwrap().split = Split::Test;
        assert!(MotionGeometry::of(&held_out).max_rotation_deg < 1e-9, "test images do not count");
    }
}
