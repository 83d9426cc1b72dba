//! The HTML sections of `ferrocal handeye --report`: the two transforms with their standard
//! deviations, the per-image chain residuals (train and test), the closed-form starts, OpenCV on
//! the same corners and split, the camera, and the data's source.

use ferrocal_calib::handeye::opencv::{best_baseline, BaselineReport};
use ferrocal_calib::handeye::{ChainFigures, HandEyeResult, TransformEstimate};
use ferrocal_calib::Split;

use crate::plot::bar_chart;
use crate::report::Section;

fn f(v: Option<f64>, digits: usize) -> String {
    match v {
        Some(x) if x.is_finite() => format!("{x:.digits$}"),
        _ => "-".into(),
    }
}

fn transform_row(name: &str, t: &TransformEstimate) -> Vec<String> {
    let p = t.transform.translation.vector * 1e3;
    let q = t.transform.rotation;
    let s = t.translation_std_mm();
    let r = t.rotation_std_deg();
    vec![
        name.to_string(),
        format!("{:.3}, {:.3}, {:.3}", p.x, p.y, p.z),
        format!("{:.3}, {:.3}, {:.3}", s.x, s.y, s.z),
        format!("{:.6}, {:.6}, {:.6}, {:.6}", q.w, q.i, q.j, q.k),
        format!("{:.4}, {:.4}, {:.4}", r.x, r.y, r.z),
    ]
}

fn figures_row(who: &str, fig: &ChainFigures) -> Vec<String> {
    vec![
        who.to_string(),
        f(Some(fig.train_rms_px), 4),
        f(fig.heldout_rms_px, 4),
        f(fig.train_pnp_position_mm, 3),
        f(fig.train_pnp_rotation_deg, 4),
        f(fig.heldout_pnp_position_mm, 3),
        f(fig.heldout_pnp_rotation_deg, 4),
    ]
}

const FIGURE_HEADER: [&str; 7] = [
    "estimate",
    "train chain RMS (px)",
    "held-out chain RMS (px)",
    "train PnP diff (mm)",
    "train PnP diff (deg)",
    "held-out PnP diff (mm)",
    "held-out PnP diff (deg)",
];

/// Every section of the report.
pub fn handeye_sections(r: &HandEyeResult, baselines: &[BaselineReport], source: Option<&str>) -> Vec<Section> {
    let attribute = |s: &mut Section| {
        if let Some(src) = source {
            s.attribution(&format!("Data: {src}"));
        }
    };
    let mut out = Vec::new();

    let mut s = Section::new("result", "Hand-eye and world transforms");
    s.text(format!(
        "Mount {}: the hand-eye transform is {}, the world transform {}. Refined in pixels over every training \
         corner (s0 = {:.3}, {} iterations, {}); standard deviations from s0^2 (J^T J)^-1 with the robot-pose \
         blocks marginalised; rotations in the frame of the transform's first index.",
        r.mount.name(),
        r.mount.hand_eye_name(),
        r.mount.world_name(),
        r.s0,
        r.iterations,
        r.termination
    ));
    for w in &r.warnings {
        s.text(format!("Warning: {w}."));
    }
    s.text(format!(
        "Flange rotation over the training images: largest relative rotation {:.3} deg, {:.3} deg about a second axis.",
        r.motion.max_rotation_deg, r.motion.second_axis_rotation_deg
    ));
    s.table(
        "Transforms",
        &["transform", "translation (mm)", "std (mm)", "rotation (w, x, y, z)", "std (deg)"],
        vec![transform_row(r.mount.hand_eye_name(), &r.hand_eye), transform_row(r.mount.world_name(), &r.world)],
    );
    let n = &r.noise;
    s.text(format!(
        "Noise levels {}: corner covariances x {:.3} (the detector's, scaled), robot {:.4} mm and {:.5} deg per axis{}.",
        if n.estimated { "estimated by variance components" } else { "as given" },
        n.corner_variance_factor,
        n.robot_sigma_m * 1e3,
        n.robot_sigma_rad.to_degrees(),
        if n.robot_sigma_m == 0.0 { " (robot poses taken as exact)" } else { "" }
    ));
    if let Some((v, sd)) = r.target_scale {
        s.text(format!(
            "Target print scale {v:.6} +- {sd:.6} (1 = nominal spacing). The per-image PnP poses the chain is \
             compared with use the same scaled target."
        ));
    }
    s.table("Chain figures (robot poses as reported)", &FIGURE_HEADER, vec![figures_row("ferrocal", &r.figures)]);
    attribute(&mut s);
    out.push(s);

    let mut s = Section::new("per-image", "Chain residual per image");
    let bars: Vec<(String, String, f64)> = r
        .figures
        .views
        .iter()
        .map(|v| (v.name.clone(), if v.split == Split::Test { "test" } else { "train" }.to_string(), v.rms_px))
        .collect();
    s.figure(
        "Chain reprojection RMS of each image: train images were fitted, test images only predicted.",
        bar_chart("Chain RMS per image", "RMS (px)", &bars),
    );
    let rows = r
        .figures
        .views
        .iter()
        .map(|v| {
            vec![
                v.name.clone(),
                if v.split == Split::Test { "test" } else { "train" }.into(),
                v.n_corners.to_string(),
                f(Some(v.rms_px), 4),
                f(v.pnp_position_mm, 3),
                f(v.pnp_rotation_deg, 4),
            ]
        })
        .collect();
    s.table("Per image", &["image", "split", "corners", "chain RMS (px)", "PnP diff (mm)", "PnP diff (deg)"], rows);
    attribute(&mut s);
    out.push(s);

    let mut s = Section::new("opencv", "OpenCV on the same corners and split");
    s.text(
        "OpenCV's closed forms on the same PnP poses of the same training images; their figures are computed by \
         the same code as ours. calibrateHandEye gives one transform; the other is the mean of what each \
         training image implies.",
    );
    let mut rows = vec![figures_row("ferrocal (refined in pixels)", &r.figures)];
    for b in baselines {
        let who = format!("{} {}", b.function, b.method);
        match &b.figures {
            Some(fig) => rows.push(figures_row(&who, fig)),
            None => rows.push(vec![
                who,
                b.error.clone().unwrap_or_default(),
                "".into(),
                "".into(),
                "".into(),
                "".into(),
                "".into(),
            ]),
        }
    }
    s.table("Chain figures", &FIGURE_HEADER, rows);
    match (best_baseline(baselines).and_then(|b| b.figures.as_ref().map(|f| (b, f))), r.figures.heldout_rms_px) {
        (Some((b, bf)), Some(ours)) => {
            let theirs = bf.heldout_rms_px.unwrap_or(f64::NAN);
            s.status(
                ours < theirs,
                format!("held-out chain RMS {ours:.4} px vs OpenCV's best ({}) {theirs:.4} px", b.method),
            );
        }
        _ => {
            s.reported("no test images: no held-out comparison");
        }
    }
    attribute(&mut s);
    out.push(s);

    let mut s = Section::new("starts", "Closed-form starts");
    let rows = r
        .starts
        .iter()
        .map(|st| {
            vec![
                st.method.name().to_string(),
                f(st.train_rms_px, 4),
                if st.chosen { "yes".into() } else { "".into() },
                st.error.clone().unwrap_or_default(),
            ]
        })
        .collect();
    s.table("Starts (training chain RMS)", &["method", "train chain RMS (px)", "chosen", "error"], rows);
    out.push(s);

    let mut s = Section::new("camera", "Camera");
    let k = r.camera.intrinsics;
    let std = r.camera_std.clone().unwrap_or_default();
    let sd = |i: usize| std.get(i).map(|v| format!(" +- {v:.3}")).unwrap_or_default();
    s.text(format!(
        "{}: fx {:.3}{}, fy {:.3}{}, cx {:.3}{}, cy {:.3}{} px; distortion {:?}.",
        if r.camera_std.is_some() {
            "Calibrated from the training images and refined with the chain"
        } else {
            "Given (held fixed)"
        },
        k.fx_px,
        sd(0),
        k.fy_px,
        sd(1),
        k.cx_px,
        sd(2),
        k.cy_px,
        sd(3),
        r.camera.distortion.coefficients()
    ));
    out.push(s);
    out
}
