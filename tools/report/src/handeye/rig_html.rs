//! The HTML section of `ferrocal handeye --report` with a rig of cameras: every camera's images,
//! intrinsics and chain figures, and the camera-to-camera transforms `T_camk_cam0` with their
//! standard deviations, from the cameras' own fits and, when it ran, from the joint adjustment.

use ferrocal_calib::handeye::{ChainFigures, RigJointCalibration, TransformEstimate};
use ferrocal_calib::Split;
use ferrocal_datasets::handeye::{rig_file_differences, RigFit, RigInput};
use ferrocal_vision::camera::CameraModel;

use crate::report::Section;

fn opt(v: Option<f64>) -> String {
    v.filter(|x| x.is_finite()).map_or("-".into(), |x| format!("{x:.4}"))
}

fn pm(v: f64, s: Option<f64>, digits: usize) -> String {
    match s {
        Some(s) => format!("{v:.digits$} +- {s:.digits$}"),
        None => format!("{v:.digits$} (held)"),
    }
}

fn camera_row(name: &str, how: &str, c: &CameraModel, std: Option<&[f64]>, f: &ChainFigures) -> Vec<String> {
    let k = c.intrinsics;
    let s = |i: usize| std.and_then(|s| s.get(i).copied());
    vec![
        name.to_string(),
        how.to_string(),
        format!("{} x {}", c.image_size.width_px, c.image_size.height_px),
        pm(k.fx_px, s(0), 3),
        pm(k.fy_px, s(1), 3),
        pm(k.cx_px, s(2), 3),
        pm(k.cy_px, s(3), 3),
        format!("{:.4}", f.train_rms_px),
        opt(f.heldout_rms_px),
    ]
}

fn transform_row(name: &str, how: &str, t: &TransformEstimate) -> Vec<String> {
    let p = t.transform.translation.vector * 1e3;
    let r = t.transform.rotation.scaled_axis() * 1f64.to_degrees();
    let (sp, sr) = (t.translation_std_mm(), t.rotation_std_deg());
    vec![
        format!("T_{name}_cam0"),
        how.to_string(),
        format!("{:.3}, {:.3}, {:.3}", p.x, p.y, p.z),
        format!("{:.3}, {:.3}, {:.3}", sp.x, sp.y, sp.z),
        format!("{:.4}, {:.4}, {:.4}", r.x, r.y, r.z),
        format!("{:.4}, {:.4}, {:.4}", sr.x, sr.y, sr.z),
    ]
}

/// The rig section.
pub fn rig_section(rig: &RigInput, fit: &RigFit, joint: Option<&RigJointCalibration>) -> Section {
    let mut s = Section::new("rig", "Rig: cameras and camera-to-camera transforms");
    let folders: Vec<String> = rig
        .cameras
        .iter()
        .zip(&fit.fits)
        .map(|(c, f)| {
            let n = |split| f.result.figures.views.iter().filter(|v| v.split == split).count();
            format!("{}: {} training, {} held-out images", c.label(), n(Split::Train), n(Split::Test))
        })
        .collect();
    s.text(format!(
        "{} cameras, one poses table, each camera's images matched to its rows by file name: {}. Camera {} is the \
         reference; T_camk_cam0 carries a point from its frame into camera k's (p_k = T_camk_cam0 p_0, OpenCV's R \
         and T of stereoCalibrate). Rotations as rotation vectors in degrees; standard deviations of the \
         translation and of the rotation error about each axis.",
        rig.cameras.len(),
        folders.join("; "),
        rig.cameras[0].name
    ));
    let mut rows = Vec::new();
    for (c, f) in rig.cameras.iter().zip(&fit.fits) {
        let r = &f.result;
        rows.push(camera_row(&c.name, "own hand-eye fit", &r.camera, r.camera_std.as_deref(), &r.figures));
    }
    if let Some(j) = joint {
        let r = &j.reference;
        rows.push(camera_row(&rig.cameras[0].name, "joint adjustment", &r.camera, Some(&r.camera_std), &r.figures));
        for (c, cam) in j.cameras.iter().zip(&rig.cameras[1..]) {
            rows.push(camera_row(&cam.name, "joint adjustment", &c.camera, Some(&c.camera_std), &c.figures));
        }
    }
    s.table(
        "Cameras (px; chain RMS with the robot poses as reported, or through the calibrated robot for the joint adjustment)",
        &["camera", "from", "image", "fx", "fy", "cx", "cy", "train chain RMS", "held-out chain RMS"],
        rows,
    );
    let mut rows: Vec<Vec<String>> = rig.cameras[1..]
        .iter()
        .zip(&fit.t_cam_cam0)
        .map(|(c, t)| transform_row(&c.name, "combined from the cameras' own fits", t))
        .collect();
    if let Some(j) = joint {
        for (c, cam) in j.cameras.iter().zip(&rig.cameras[1..]) {
            rows.push(transform_row(&cam.name, "joint adjustment", &c.t_cam_cam0));
        }
    }
    s.table(
        "Camera-to-camera transforms",
        &["transform", "from", "translation (mm)", "std (mm)", "rotation vector (deg)", "std (deg)"],
        rows,
    );
    let diffs = rig_file_differences(rig, fit, joint);
    if !diffs.is_empty() {
        let rows = diffs
            .iter()
            .map(|d| {
                let cam = &rig.cameras[d.camera];
                let (t, r) = (d.translation_mm, d.rotation_deg);
                vec![
                    format!("T_{}_cam0", cam.name),
                    cam.run.intrinsics.as_ref().map_or(String::new(), |p| p.display().to_string()),
                    d.fitted_by.to_string(),
                    format!("{:.3}, {:.3}, {:.3} ({:.3})", t.x, t.y, t.z, t.norm()),
                    format!("{:.4}, {:.4}, {:.4} ({:.4})", r.x, r.y, r.z, r.norm()),
                    format!("{:.2}", d.max_sigma),
                    format!("{:.2}", d.mahalanobis),
                ]
            })
            .collect();
        s.table(
            "The camera files' R, T against the fit (fitted minus file; the joint adjustment starts from the files' transforms)",
            &["transform", "file", "fitted by", "translation (mm)", "rotation vector (deg)", "largest (sigma)", "Mahalanobis"],
            rows,
        );
    }
    s.text(match joint {
        Some(j) => format!(
            "The joint adjustment poses one problem in pixels over every camera's training corners: the robot's {} \
             kinematic parameters, the device frame and the tool, every camera's intrinsics and T_camk_cam0 (s0 = \
             {:.3}, {} iterations). Its start: the transforms {}.",
            j.reference.free.len(),
            j.reference.s0,
            j.reference.iterations,
            if diffs.is_empty() {
                "combined from the cameras' own fits"
            } else {
                "of the camera files' R, T where they carry them, else combined from the cameras' own fits"
            }
        ),
        None => "Without the joint adjustment (--robot with joint readings and --out) the transforms are not \
                 refined together: each camera's hand-eye fit is its own problem, and T_camk_cam0 = W_k^-1 W_0 \
                 (eye-to-hand) or X_k^-1 X_0 (eye-in-hand), its covariance propagated from the two fits taken as \
                 independent (they are with the robot poses exact, the default)."
            .into(),
    });
    s
}
