//! `ferrocal handeye` with a rig of cameras: the terminal lines, the verdict's checks, the JSON
//! part `rig` and every output file ([`rig_outputs`]), camera 0 (the reference) reported at the
//! top level exactly as a one-camera run reports its camera. The workflow lives in
//! `ferrocal_datasets::handeye::rig_run`.

use std::path::{Path, PathBuf};

use ferrocal_calib::handeye::{HandEyeResult, RigJointCalibration, TransformEstimate};
use ferrocal_calib::verdict::{Check, Thresholds, Verdict};
use ferrocal_calib::Split;
use ferrocal_datasets::handeye::{rig_file_differences, RigFileDifference, RigFit, RigInput};
use ferrocal_vision::camera::{io, CameraModel};
use nalgebra::Isometry3;
use serde_json::{json, Value};

use super::json::{figures_json, matrix_rows, std_json, transform_json};
use super::{handeye_outputs, result_json, HandeyeFiles};
use crate::camera::with_camera_fields;
use crate::error::Result;
use crate::outputs::Outputs;
use crate::report::{Provenance, Report};

/// Where `ferrocal handeye` writes with a rig: the one-camera files (the JSON and the report
/// with every camera; `--out` the robot; `--corners-out` camera 0's corners) and the rig's
/// camera files.
#[derive(Clone, Copy, Debug, Default)]
pub struct RigFiles<'a> {
    /// The one-camera files.
    pub handeye: HandeyeFiles<'a>,
    /// The folder of the rig's camera files ([`rig_file_paths`]).
    pub rig_out: Option<&'a Path>,
}

/// The rig's camera files in `dir` for `n` cameras: per camera `cam<k>.yaml` (OpenCV
/// FileStorage: `camera_matrix`, `distortion_coefficients` and, for `k > 0`, `R` and `T` of
/// `T_camk_cam0` as OpenCV's stereoCalibrate names them) and `cam<k>_camera_info.yaml` (ROS).
pub fn rig_file_paths(dir: &Path, n: usize) -> Vec<PathBuf> {
    (0..n).flat_map(|k| [dir.join(format!("cam{k}.yaml")), dir.join(format!("cam{k}_camera_info.yaml"))]).collect()
}

/// The rig transform as a JSON object: the transform, its standard deviations and covariance.
fn rig_transform_json(t: &TransformEstimate) -> Value {
    let mut v = transform_json(&t.transform);
    let r = t.transform.rotation.scaled_axis() * 1f64.to_degrees();
    v["rotation_vector_deg"] = json!([r.x, r.y, r.z]);
    v["std"] = std_json(t);
    v["covariance"] = json!(matrix_rows(&t.covariance));
    v
}

/// A camera with the standard deviations of its parameters (the order of
/// [`CameraModel::parameters`]).
fn camera_std_json(c: &CameraModel, s: &[f64]) -> Value {
    let sd = |i: usize| s.get(i).copied();
    with_camera_fields(
        c,
        json!({
            "std": {"fx": sd(0), "fy": sd(1), "cx": sd(2), "cy": sd(3), "distortion": s.get(4..).unwrap_or(&[]).to_vec()},
        }),
    )
}

/// A camera file's `T_camk_cam0` and its difference from the fitted one, as JSON.
fn file_difference_json(d: &RigFileDifference, file: &Path) -> Value {
    let mut v = transform_json(&d.file);
    v["file"] = json!(file.display().to_string());
    let (t, r) = (d.translation_mm, d.rotation_deg);
    v["difference"] = json!({
        "compared_with": d.fitted_by,
        "is": "fitted minus the file's: translation (mm), rotation vector of R_fitted R_file^-1 (deg); in the fitted transform's standard deviations",
        "translation_mm": [t.x, t.y, t.z],
        "translation_norm_mm": t.norm(),
        "rotation_deg": [r.x, r.y, r.z],
        "rotation_norm_deg": r.norm(),
        "max_sigma": d.max_sigma,
        "mahalanobis": d.mahalanobis,
    });
    v
}

/// The terminal line of a camera file's `T_camk_cam0` against the fitted one.
pub fn file_difference_line(name: &str, file: &Path, d: &RigFileDifference) -> String {
    let (t, r) = (d.translation_mm, d.rotation_deg);
    format!(
        "T_{name}_cam0 of {} (R, T) against the {}: [{:.3}, {:.3}, {:.3}] mm ({:.3} mm), [{:.4}, {:.4}, {:.4}] deg ({:.4} deg); largest {:.2} sigma (Mahalanobis {:.2})",
        file.display(),
        d.fitted_by,
        t.x,
        t.y,
        t.z,
        t.norm(),
        r.x,
        r.y,
        r.z,
        r.norm(),
        d.max_sigma,
        d.mahalanobis
    )
}

fn count(r: &HandEyeResult, split: Split) -> usize {
    r.figures.views.iter().filter(|v| v.split == split).count()
}

/// The `rig` part of the JSON: per camera its images, its own hand-eye result (the one-camera
/// JSON without OpenCV's solvers) and `T_camk_cam0` combined from the fits; with the joint
/// adjustment, per camera its camera, `T_camk_cam0` and chain figures from it.
pub fn rig_json(rig: &RigInput, fit: &RigFit, joint: Option<&RigJointCalibration>) -> Value {
    let diffs = rig_file_differences(rig, fit, joint);
    let file_json = |k: usize| {
        let d = diffs.iter().find(|d| d.camera == k)?;
        Some(file_difference_json(d, rig.cameras[k].run.intrinsics.as_deref()?))
    };
    let cameras: Vec<Value> = rig
        .cameras
        .iter()
        .zip(&fit.fits)
        .enumerate()
        .map(|(k, (cam, f))| {
            let mut own = result_json(&cam.input, f);
            if let Some(o) = own.as_object_mut() {
                o.remove("opencv");
            }
            json!({
                "name": cam.name,
                "images": cam.run.images.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
                "intrinsics_given": cam.run.intrinsics.as_ref().map(|p| p.display().to_string()),
                "train_images": count(&f.result, Split::Train),
                "test_images": count(&f.result, Split::Test),
                "t_cam_cam0": if k == 0 { Value::Null } else { rig_transform_json(&fit.t_cam_cam0[k - 1]) },
                "t_cam_cam0_file": file_json(k),
                "hand_eye_fit": own,
            })
        })
        .collect();
    let joint = joint.map(|j| {
        let mut cams = vec![json!({
            "name": rig.cameras[0].name,
            "camera": camera_std_json(&j.reference.camera, &j.reference.camera_std),
            "t_cam_cam0": Value::Null,
            "figures": figures_json(&j.reference.figures),
        })];
        for (k, (c, cam)) in j.cameras.iter().zip(&rig.cameras[1..]).enumerate() {
            let start = match rig.file_t_cam_cam0(k + 1) {
                Some(_) => "the camera files' R, T (--intrinsics)",
                None => "combined from the cameras' own fits",
            };
            cams.push(json!({
                "name": cam.name,
                "camera": camera_std_json(&c.camera, &c.camera_std),
                "t_cam_cam0": rig_transform_json(&c.t_cam_cam0),
                "t_cam_cam0_start": start,
                "figures": figures_json(&c.figures),
            }));
        }
        json!({
            "robot_parameters": j.reference.free.len(),
            "s0": j.reference.s0,
            "iterations": j.reference.iterations,
            "termination": j.reference.termination,
            "hand_eye": transform_json(&j.reference.hand_eye.transform),
            "world": transform_json(&j.reference.world.transform),
            "std": {"hand_eye": std_json(&j.reference.hand_eye), "world": std_json(&j.reference.world)},
            "cameras": cams,
        })
    });
    json!({
        "reference": rig.cameras[0].name,
        "t_cam_cam0_is": "the reference camera's frame into camera k's: p_k = T_camk_cam0 p_0 (OpenCV's R, T of stereoCalibrate)",
        "method": "each camera's own hand-eye fit; T_camk_cam0 = W_k^-1 W_0 (eye-to-hand) or X_k^-1 X_0 (eye-in-hand) with the covariance propagated from the two fits taken as independent; with --robot and --out the joint adjustment of the robot and every camera in one problem (joint)",
        "cameras": cameras,
        "joint": joint,
    })
}

/// The terminal lines of the rig: per further camera `T_camk_cam0` from the fits.
pub fn rig_lines(rig: &RigInput, fit: &RigFit) -> Vec<String> {
    rig.cameras[1..]
        .iter()
        .zip(&fit.t_cam_cam0)
        .map(|(c, t)| transform_line(&c.name, "the cameras' own fits", t))
        .collect()
}

fn transform_line(name: &str, from: &str, t: &TransformEstimate) -> String {
    let p = t.transform.translation.vector * 1e3;
    let r = t.transform.rotation.scaled_axis() * 1f64.to_degrees();
    let (sp, sr) = (t.translation_std_mm(), t.rotation_std_deg());
    format!(
        "T_{name}_cam0 ({from}): translation [{:.3}, {:.3}, {:.3}] +- [{:.3}, {:.3}, {:.3}] mm, rotation vector [{:.4}, {:.4}, {:.4}] +- [{:.4}, {:.4}, {:.4}] deg",
        p.x, p.y, p.z, sp.x, sp.y, sp.z, r.x, r.y, r.z, sr.x, sr.y, sr.z
    )
}

/// The terminal lines of the rig's joint adjustment (after [`super::joint_line`]): per further
/// camera its focal length, `T_camk_cam0` and chain figures.
pub fn rig_joint_lines(rig: &RigInput, joint: &RigJointCalibration) -> Vec<String> {
    let opt = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{x:.4}"));
    let mut out = Vec::new();
    let cam_line = |name: &str, c: &CameraModel, s: &[f64], f: &ferrocal_calib::handeye::ChainFigures| {
        format!(
            "joint adjustment {name}: fx {:.3} +- {:.3} px, fy {:.3} +- {:.3} px; chain RMS train {:.4} px, held-out {} px",
            c.intrinsics.fx_px,
            s.first().copied().unwrap_or(f64::NAN),
            c.intrinsics.fy_px,
            s.get(1).copied().unwrap_or(f64::NAN),
            f.train_rms_px,
            opt(f.heldout_rms_px)
        )
    };
    let r = &joint.reference;
    out.push(cam_line(&rig.cameras[0].name, &r.camera, &r.camera_std, &r.figures));
    for (c, cam) in joint.cameras.iter().zip(&rig.cameras[1..]) {
        out.push(cam_line(&cam.name, &c.camera, &c.camera_std, &c.figures));
        out.push(transform_line(&cam.name, "joint adjustment", &c.t_cam_cam0));
    }
    out
}

fn named(mut c: Check, camera: &str) -> Check {
    c.what = format!("{camera}: {}", c.what);
    c
}

/// The checks of every camera's hand-eye fit and motion check (camera 0's named as in a
/// one-camera run, camera `k`'s `handeye.cam<k>...`).
pub fn rig_checks(t: &Thresholds, rig: &RigInput, fit: &RigFit) -> Vec<Check> {
    let mut out = Vec::new();
    for (k, (cam, f)) in rig.cameras.iter().zip(&fit.fits).enumerate() {
        let r = &f.result;
        let split = if r.figures.heldout_rms_px.is_some() { Split::Test } else { Split::Train };
        let prefix = if k == 0 { "handeye".to_string() } else { format!("handeye.{}", cam.name) };
        let pnp = super::verdict::pnp_rms_px(&cam.input.data, r, split);
        out.extend(super::verdict::chain_checks(t, &r.figures, pnp, &prefix).into_iter().map(|c| named(c, &cam.name)));
        if let Some(m) = &cam.input.motion {
            let mut c = named(super::verdict::motion_check(m), &cam.name);
            c.name = format!("{prefix}.motion_check");
            out.push(c);
        }
    }
    out
}

/// The checks of the rig's joint adjustment: every camera's chain RMS.
pub fn rig_joint_checks(t: &Thresholds, rig: &RigInput, joint: &RigJointCalibration) -> Vec<Check> {
    let mut out: Vec<Check> =
        super::verdict::joint_checks(t, &joint.reference).into_iter().map(|c| named(c, &rig.cameras[0].name)).collect();
    for (c, cam) in joint.cameras.iter().zip(&rig.cameras[1..]) {
        let prefix = format!("handeye.joint.{}", cam.name);
        out.extend(
            super::verdict::chain_checks(t, &c.figures, None, &prefix)
                .into_iter()
                .filter(|c| c.name.ends_with("chain_rms_px"))
                .map(|c| named(c, &cam.name)),
        );
    }
    out
}

/// The rig's camera files ([`rig_file_paths`]): the joint adjustment's cameras and transforms
/// when it ran, else each camera's own fit and the combined transforms.
fn rig_camera_files(
    out: &mut Outputs,
    dir: &Path,
    rig: &RigInput,
    fit: &RigFit,
    joint: Option<&RigJointCalibration>,
) -> Result<()> {
    let mut cams: Vec<(CameraModel, Option<Isometry3<f64>>)> = Vec::new();
    match joint {
        Some(j) => {
            cams.push((j.reference.camera, None));
            cams.extend(j.cameras.iter().map(|c| (c.camera, Some(c.t_cam_cam0.transform))));
        }
        None => {
            cams.push((fit.fits[0].result.camera, None));
            for (f, t) in fit.fits[1..].iter().zip(&fit.t_cam_cam0) {
                cams.push((f.result.camera, Some(t.transform)));
            }
        }
    }
    let paths = rig_file_paths(dir, cams.len());
    for ((camera, t), (paths, cam)) in cams.iter().zip(paths.chunks(2).zip(&rig.cameras)) {
        let r = t.map(|t| t.rotation.to_rotation_matrix().into_inner());
        let tv = t.map(|t| t.translation.vector);
        let ext = r.as_ref().zip(tv.as_ref());
        out.text(&paths[0], io::to_opencv_rig_yaml(camera, ext)?);
        out.text(&paths[1], io::to_ros_yaml(camera, &cam.name)?);
    }
    Ok(())
}

/// The files of `ferrocal handeye` with a rig, composed (not written): the JSON (camera 0 at the
/// top level as a one-camera run writes it, `rig` with every camera, the verdict), `--out` (the
/// robot of the joint adjustment), `--corners-out` (camera 0's corners), the HTML report
/// (camera 0's sections and the rig's) and the rig's camera files.
pub fn rig_outputs(
    rig: &RigInput,
    fit: &RigFit,
    joint: Option<&RigJointCalibration>,
    verdict: &Verdict,
    files: &RigFiles,
) -> Result<Outputs> {
    let cam0 = &rig.cameras[0];
    let only = HandeyeFiles { json: None, report: None, ..files.handeye };
    let mut out = handeye_outputs(&cam0.run, &cam0.input, &fit.fits[0], joint.map(|j| &j.reference), verdict, &only)?;
    if let Some(dir) = files.rig_out {
        rig_camera_files(&mut out, dir, rig, fit, joint)?;
    }
    if let Some(h) = files.handeye.report {
        let run = &cam0.run;
        let (mount, pattern) = (run.mount.name(), &run.pattern);
        let images: Vec<Vec<String>> =
            rig.cameras.iter().map(|c| c.run.images.iter().map(|p| p.display().to_string()).collect()).collect();
        let settings = json!({"pattern": pattern, "mount": mount, "cameras": images, "options": format!("{:?}", fit.fits[0].options)});
        let mut prov = Provenance::new(settings);
        prov.add_input(&run.poses);
        let f0 = &fit.fits[0];
        let source = cam0.input.table.source.as_deref();
        let mut sections = super::html::handeye_sections(&f0.result, &f0.baselines, source);
        sections.insert(1.min(sections.len()), super::rig_html::rig_section(rig, fit, joint));
        if let Some(p) = &fit.physics {
            let form = RigInput::target_form(fit);
            sections.insert(2.min(sections.len()), super::physics::physics_section_with(p, form.as_ref()));
        }
        let title = format!("Hand-eye calibration of a rig of {} cameras ({mount}, {pattern})", rig.cameras.len());
        out.html(h, Report::of(&title, prov, sections), verdict);
    }
    if let Some(p) = files.handeye.json {
        let mut v = result_json(&cam0.input, &fit.fits[0]);
        v["rig"] = rig_json(rig, fit, joint);
        if let Some(p) = &fit.physics {
            v["rig"]["physics"] = serde_json::to_value(p).unwrap_or(Value::Null);
            v["rig"]["target_form"] = serde_json::to_value(RigInput::target_form(fit)).unwrap_or(Value::Null);
        }
        crate::verdict::add_verdict(&mut v, verdict);
        out.json_first(p, &v)?;
    }
    Ok(out)
}

/// The lines `ferrocal handeye` prints on stderr for a rig: every camera's motion-check
/// warnings and the images it left out, naming the camera; the table rows a camera has no
/// image of (a pose it did not see) are counted, not listed.
pub fn rig_warning_lines(rig: &RigInput) -> Vec<String> {
    let mut out = Vec::new();
    for cam in &rig.cameras {
        let input = &cam.input;
        if let Some(m) = &input.motion {
            out.extend(m.warnings.iter().map(|w| format!("ferrocal handeye: warning: {}: {w}", cam.name)));
        }
        let no_image = |s: &&ferrocal_datasets::handeye::Skipped| s.reason.starts_with("no image named");
        let unseen = input.skipped.iter().filter(no_image).count();
        out.extend(input.skipped_images.iter().map(|s| format!("ferrocal: skipped ({}) {s}", cam.name)));
        out.extend(
            input
                .skipped
                .iter()
                .filter(|s| !no_image(s))
                .map(|s| format!("ferrocal: skipped ({}) {}: {}", cam.name, s.what, s.reason)),
        );
        if unseen > 0 {
            out.push(format!(
                "ferrocal: {}: {unseen} row(s) of {} have no image of this camera (poses it did not see)",
                cam.label(),
                input.table.file.display()
            ));
        }
    }
    out
}

/// Presents a rig run on the terminal (every camera's summary, the rig transforms, the joint
/// adjustment's lines when it ran) and returns its verdict: every camera's checks and the joint
/// adjustment's (`joint`, whose calibration went to `joint_out`).
pub fn present_rig(
    t: &Thresholds,
    rig: &RigInput,
    fit: &RigFit,
    joint: Option<&RigJointCalibration>,
    joint_out: Option<&Path>,
) -> Verdict {
    use ferrocal_calib::handeye::opencv::best_baseline;
    rig_warning_lines(rig).iter().for_each(|l| eprintln!("{l}"));
    for (cam, f) in rig.cameras.iter().zip(&fit.fits) {
        crate::say!("{}:", cam.label());
        super::print_summary(&f.result, best_baseline(&f.baselines), None);
    }
    if let Some(src) = rig.cameras[0].input.table.source.as_deref() {
        crate::say!("data: {src}");
    }
    rig_lines(rig, fit).iter().for_each(|l| crate::say!("{l}"));
    if let Some(p) = &fit.physics {
        crate::say!("{}", super::physics::physics_line(p));
    }
    let mut checks = rig_checks(t, rig, fit);
    if joint.is_none() && rig.cameras.len() > 1 {
        // A robot's reported flange poses come from its nominal model: combined from the
        // cameras' own fits, the transforms carry the robot's errors outside their uncertainty
        // (36.5 mm at 15 sigma in the rig simulation, docs/handeye.md).
        checks.push(Check::flag(
            "handeye.rig.own_fits",
            "camera-to-camera transforms combined from each camera's own fit on the reported flange poses: the robot's errors are not in their uncertainty (joint readings, --robot and --out adjust the robot with the cameras)",
            "camera-to-camera transforms from the joint adjustment",
            true,
        ));
    }
    if let (Some(joint), Some(out)) = (joint, joint_out) {
        checks.extend(rig_joint_checks(t, rig, joint));
        crate::say!("{}", super::joint_line(&joint.reference, out));
        rig_joint_lines(rig, joint).iter().for_each(|l| crate::say!("{l}"));
    }
    for d in rig_file_differences(rig, fit, joint) {
        let cam = &rig.cameras[d.camera];
        if let Some(file) = cam.run.intrinsics.as_deref() {
            crate::say!("{}", file_difference_line(&cam.name, file, &d));
            let label =
                format!("T_{}_cam0 of {} against the {} (largest coordinate)", cam.name, file.display(), d.fitted_by);
            let name = format!("handeye.rig.{}.file_sigma", cam.name);
            checks.push(Check::at_most(
                &name,
                &label,
                "sigma",
                d.max_sigma,
                t.handeye.rig_file_sigma_warn,
                f64::INFINITY,
            ));
        }
    }
    let flags = rig.cameras.first().map(|c| super::verdict::RunFlags::of(&c.run)).unwrap_or_default();
    super::verdict::run_verdict(checks, &fit.fits[0].result, joint_out, flags)
}
