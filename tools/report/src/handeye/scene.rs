//! The hand-eye cell in 3-D for `ferrocal handeye --report`: the robot's base, the flange at
//! every image, the camera and the target where the fit puts them.

use nalgebra::{Isometry3, Point3, Translation3};

use ferrocal_calib::handeye::{HandEyeData, HandEyeResult, Mount};
use ferrocal_calib::Split;

use crate::plot::Scene3d;
use crate::report::Section;

/// At most this many cameras (eye-in-hand) or target outlines (eye-to-hand) are drawn; the
/// flange positions are drawn for every image.
const MAX_DRAWN: usize = 40;

/// `t` with its translation in mm.
fn in_mm(t: &Isometry3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::from(t.translation.vector * 1e3), t.rotation)
}

/// The cell in the robot's base frame (mm, +z up): the base, the flange path over the images
/// (training and held-out in two colours), and the fitted camera and target: for eye-in-hand
/// the camera at every drawn image and the target where `W` puts it; for eye-to-hand the fixed
/// camera and the target outline at every drawn image.
pub fn cell_section(r: &HandEyeResult, data: &HandEyeData) -> Section {
    let mut s = Section::new("cell-3d", "The cell in 3-D");
    let (caption, svg) = cell_figure(r, data);
    s.figure(&caption, svg);
    s
}

/// The figure of [`cell_section`]: its caption and SVG.
pub fn cell_figure(r: &HandEyeResult, data: &HandEyeData) -> (String, String) {
    let outline = crate::plot::scene3d::target_outline(&data.target_points_m, 1e3);
    let (x, w) = (in_mm(&r.hand_eye.transform), in_mm(&r.world.transform));
    let flanges: Vec<(Isometry3<f64>, Split)> = data.views.iter().map(|v| (in_mm(&v.t_base_flange), v.split)).collect();
    let extent = flanges
        .iter()
        .map(|(t, _)| t.translation.vector.norm())
        .chain(std::iter::once(w.translation.vector.norm()))
        .fold(0.0, f64::max)
        .max(1.0);
    let mut sc = Scene3d::new("The cell in the robot's base frame", "mm");
    sc.frame(&Isometry3::identity(), 0.12 * extent, "base");
    for (split, k, name) in [(Split::Train, 0, "flange, training images"), (Split::Test, 3, "flange, held-out images")]
    {
        let pts: Vec<Point3<f64>> =
            flanges.iter().filter(|(_, s)| *s == split).map(|(t, _)| t * Point3::origin()).collect();
        if !pts.is_empty() {
            sc.dots(&pts, k, 2.5);
            sc.legend(k, name);
        }
    }
    let step = flanges.len().div_ceil(MAX_DRAWN).max(1);
    let size = 0.06 * extent;
    match r.mount {
        Mount::EyeInHand => {
            for (t, _) in flanges.iter().step_by(step) {
                sc.camera(&(t * x), size, 1, "");
            }
            sc.outline(&outline.map(|p| w * p), 2, 2.5);
            sc.dots(&[w * outline[0]], 2, 3.5);
            sc.label(w * outline[0], "target");
            sc.legend(1, "camera at the drawn images (T_base_flange X)");
            sc.legend(2, "target (W = T_base_target)");
        }
        Mount::EyeToHand => {
            for (t, _) in flanges.iter().step_by(step) {
                sc.outline(&outline.map(|p| t * x * p), 2, 1.0);
            }
            sc.camera(&w, 2.0 * size, 1, "camera");
            sc.legend(1, "camera (W = T_base_camera)");
            sc.legend(2, "target on the flange at the drawn images (T_base_flange X)");
        }
    }
    let drawn = flanges.len().div_ceil(step);
    let caption = format!(
        "The fitted cell, in mm in the robot's base frame (drag to turn): the flange at each of the {} images, the {} at {drawn} of them{}.",
        flanges.len(),
        if r.mount == Mount::EyeInHand { "camera" } else { "target" },
        if step > 1 { format!(" (every {step}th)") } else { String::new() }
    );
    (caption, sc.to_svg())
}
