//! `ferrocal handeye` with a rig of cameras: `--images` given once per camera, every camera's
//! images matched to the one poses table's rows by file name ([`RigInput::load`]); each camera's
//! own hand-eye calibration with the rig transforms `T_camk_cam0` combined from them
//! ([`RigInput::fit`], [`rig_transform`]); with a robot model and joint readings the joint
//! adjustment of the robot and every camera in one problem in pixels
//! ([`RigInput::joint_adjustment`], [`ferrocal_calib::handeye::calibrate_joint_rig_with`]).
//!
//! Camera files given with `--intrinsics` that carry OpenCV's stereo `R`, `T` (the files of
//! `--rig-out`, or `stereoCalibrate`'s) give the start of `T_camk_cam0` in the joint adjustment
//! ([`RigInput::file_t_cam_cam0`]) and are checked against the fitted transform
//! ([`rig_file_differences`]: millimetres, degrees, standard deviations).
//!
//! Without the joint adjustment the rig transforms are **not** refined together: each camera's
//! hand-eye fit is its own problem, and `T_camk_cam0 = W_k^-1 W_0` (eye-to-hand) or `X_k^-1
//! X_0` (eye-in-hand) with the covariance propagated to first order from the two fits, taken as
//! independent. They are when the robot poses are taken as exact (the default: the cameras'
//! images are different data); with the poses as measurements the correlation through the poses
//! two cameras share is neglected.

use std::collections::HashSet;
use std::path::PathBuf;

use std::path::Path;

use nalgebra::{Isometry3, Matrix3, Matrix6, Rotation3, Translation3, UnitQuaternion, Vector3, Vector6};
use serde::Serialize;

use ferrocal_calib::handeye::physics::{pooled_target_form, select_rig_physics, ChainPhysicsReport, PhysicsOptions};
use ferrocal_calib::handeye::{
    calibrate_joint_rig_with, rig_transform_from_starts, HandEyeResult, JointOptions, Mount, RigJointCalibration,
    TargetForm, TransformEstimate,
};

use super::workflow::{HandEyeFit, HandEyeInput, HandEyeRunOptions};
use crate::error::{DatasetError, Result};

/// One camera of a rig run.
#[derive(Clone, Debug)]
pub struct RigCameraInput {
    /// Its name (`cam0`, `cam1`, ... in the order of `--images`).
    pub name: String,
    /// Its run options: the shared ones with its own images and camera file.
    pub run: HandEyeRunOptions,
    /// Its recording.
    pub input: HandEyeInput,
    /// `R`, `T` of its camera file (OpenCV stereo FileStorage: `p_k = R p_ref + T`, the
    /// reference's frame into this camera's), when the file carries them.
    pub file_extrinsics: Option<Isometry3<f64>>,
}

impl RigCameraInput {
    /// The camera's name with its image specifications, for messages.
    pub fn label(&self) -> String {
        let specs: Vec<String> = self.run.images.iter().map(|p| p.display().to_string()).collect();
        format!("camera {} ({})", self.name, specs.join(", "))
    }
}

/// A rig's recordings: camera 0 (the reference) first.
#[derive(Clone, Debug)]
pub struct RigInput {
    /// The cameras.
    pub cameras: Vec<RigCameraInput>,
}

/// Every camera's hand-eye fit and the rig transforms combined from them.
#[derive(Clone, Debug)]
pub struct RigFit {
    /// Each camera's hand-eye calibration, camera 0 first.
    pub fits: Vec<HandEyeFit>,
    /// `T_camk_cam0` of cameras 1, 2, ... from the fits ([`rig_transform`]).
    pub t_cam_cam0: Vec<TransformEstimate>,
    /// What the selection of the target's and lenses' physics decided, when it ran.
    pub physics: Option<ChainPhysicsReport>,
}

impl RigInput {
    /// Loads every camera: `cameras[k]` are camera `k`'s image specifications, `intrinsics`
    /// none or one camera file per camera. A camera whose images match no row of the table is
    /// an error naming the camera, its folders and an example of each side's names.
    pub fn load(run: &HandEyeRunOptions, cameras: &[Vec<PathBuf>], intrinsics: &[PathBuf]) -> Result<Self> {
        if !intrinsics.is_empty() && intrinsics.len() != cameras.len() {
            return Err(DatasetError::Input(format!(
                "handeye: {} cameras (--images given {} times) but --intrinsics given {} times: give one camera file per camera, in the order of --images, or none",
                cameras.len(),
                cameras.len(),
                intrinsics.len()
            )));
        }
        let mut out = Vec::with_capacity(cameras.len());
        for (k, images) in cameras.iter().enumerate() {
            let cam_run =
                HandEyeRunOptions { images: images.clone(), intrinsics: intrinsics.get(k).cloned(), ..run.clone() };
            let name = format!("cam{k}");
            let specs: Vec<String> = images.iter().map(|p| p.display().to_string()).collect();
            let label = format!("camera {name} ({})", specs.join(", "));
            let input = HandEyeInput::load(&cam_run).map_err(|e| e.context(label.clone()))?;
            check_matched(&input, &label)?;
            let file_extrinsics = intrinsics.get(k).map(|p| read_rig_extrinsics(p)).transpose()?.flatten();
            out.push(RigCameraInput { name, run: cam_run, input, file_extrinsics });
        }
        Ok(Self { cameras: out })
    }

    /// Camera `k`'s `T_camk_cam0` from the camera files' `R`, `T`: `E_k E_0^-1` with `E` a file's
    /// transform (camera 0's the identity when its file carries none); `None` for camera 0 and
    /// when camera `k`'s file carries no `R`, `T`.
    pub fn file_t_cam_cam0(&self, k: usize) -> Option<Isometry3<f64>> {
        let e_k = self.cameras.get(k).filter(|_| k > 0)?.file_extrinsics?;
        Some(e_k * self.cameras[0].file_extrinsics.unwrap_or_else(Isometry3::identity).inverse())
    }

    /// Each camera's hand-eye calibration (after its motion check, as the single-camera command
    /// runs it) and the rig transforms combined from them.
    pub fn fit(&mut self) -> Result<RigFit> {
        self.fit_with_physics(None)
    }

    /// [`RigInput::fit`] after deciding, when `physics` is given, the target's bending and print
    /// scale (one target: every camera's held-out training images together) and each camera's
    /// lens model on the training images ([`select_rig_physics`]); every camera's fit then runs
    /// with the chosen variant and the rig fit carries the selection's report.
    pub fn fit_with_physics(&mut self, physics: Option<&PhysicsOptions>) -> Result<RigFit> {
        let mut prepared = Vec::with_capacity(self.cameras.len());
        for cam in &mut self.cameras {
            let label = cam.label();
            let options = cam.run.hand_eye_options()?;
            let (_, start) = cam.input.check_motion(&options).map_err(|e| e.context(label.clone()))?;
            prepared.push((options, start));
        }
        let report = match physics {
            Some(p) => {
                let cameras: Vec<_> =
                    self.cameras.iter().zip(&prepared).map(|(c, (o, _))| (&c.input.data, o)).collect();
                Some(select_rig_physics(&cameras, p).map_err(|e| {
                    DatasetError::from(e)
                        .context("handeye: the target's and lenses' physics on the rig's training images")
                })?)
            }
            None => None,
        };
        let mut fits = Vec::with_capacity(self.cameras.len());
        for (k, (cam, (options, start))) in self.cameras.iter().zip(prepared).enumerate() {
            let (options, start) = match &report {
                Some(r) => {
                    let chosen = r.variant_of(k).options(&options);
                    let start = if chosen.intrinsics == options.intrinsics { start } else { None };
                    (chosen, start)
                }
                None => (options, start),
            };
            fits.push(cam.input.fit_from(options, start).map_err(|e| e.context(cam.label()))?);
        }
        let mount = fits[0].result.mount;
        let t_cam_cam0 = fits[1..].iter().map(|f| rig_transform(mount, &fits[0].result, &f.result)).collect();
        Ok(RigFit { fits, t_cam_cam0, physics: report })
    }

    /// The target's form the joint adjustment holds: the cameras' fitted forms pooled by inverse
    /// variance ([`pooled_target_form`]); `None` when the target is taken flat and nominally
    /// printed.
    pub fn target_form(fit: &RigFit) -> Option<TargetForm> {
        let results: Vec<&HandEyeResult> = fit.fits.iter().map(|f| &f.result).collect();
        pooled_target_form(&results)
    }

    /// The joint adjustment of the robot's kinematic parameters with every camera, its
    /// `T_camk_cam0` and the hand-eye transforms, started from each camera's fit in `fit` and
    /// `T_camk_cam0` from the camera files' `R`, `T` where they carry them
    /// ([`RigInput::file_t_cam_cam0`], else combined from the fits), the target held at camera
    /// 0's print scale and, when the physics selection found them, at the cameras' pooled
    /// bending and x print scale ([`RigInput::target_form`]); every image needs joint readings and the input a robot model.
    pub fn joint_adjustment(&self, fit: &RigFit) -> Result<RigJointCalibration> {
        let mut data = Vec::with_capacity(self.cameras.len());
        let mut joints = Vec::with_capacity(self.cameras.len());
        let mut model = None;
        let scale = fit.fits[0].result.target_scale.map(|(s, _)| s);
        let form = Self::target_form(fit);
        for cam in &self.cameras {
            let (m, q) = cam.input.joint_readings().map_err(|e| e.context(cam.label()))?;
            model = Some(m);
            let mut d = cam.input.data.clone();
            if let Some(f) = &form {
                d.target_points_m = f.points(&d.target_points_m);
            }
            if let Some(s) = scale {
                d.target_points_m = ferrocal_calib::handeye::evaluate::scaled_target(&d.target_points_m, s);
            }
            data.push(d);
            joints.push(q);
        }
        let model = model.ok_or_else(|| DatasetError::Input("handeye: a rig needs at least one camera".into()))?;
        let options = JointOptions { hand_eye: fit.fits[0].options.clone(), ..JointOptions::default() };
        let starts = fit.fits.iter().map(|f| f.result.clone()).collect();
        let transforms: Vec<_> = (1..self.cameras.len()).map(|k| self.file_t_cam_cam0(k)).collect();
        calibrate_joint_rig_with(model, &data, &joints, starts, &transforms, &options)
            .map_err(|e| DatasetError::from(e).context("handeye: the joint adjustment of the robot and the rig"))
    }
}

/// `R`, `T` of a camera file, when it is OpenCV FileStorage carrying them (`T` in the file's
/// `translation_unit`, metres by default); `None` for other files. An `R` that is not a rotation
/// is an error naming the file.
pub fn read_rig_extrinsics(path: &Path) -> Result<Option<Isometry3<f64>>> {
    let text = crate::import::table::read_text(path)?;
    let json = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("json")) || text.trim_start().starts_with('{');
    if json || !(text.contains("!!opencv-matrix") || text.starts_with("%YAML")) {
        return Ok(None);
    }
    let (_, ext) = ferrocal_vision::camera::io::from_opencv_rig_yaml(&text)
        .map_err(|e| DatasetError::Input(format!("{}: the rig's R, T: {e}", path.display())))?;
    let Some((r, t_m)) = ext else { return Ok(None) };
    let off = (r.transpose() * r - Matrix3::identity()).abs().max();
    if off > 1e-6 || r.determinant() < 0.0 {
        return Err(DatasetError::Input(format!(
            "{}: R is not a rotation (|R^T R - I| = {off:.2e}, det {:.6})",
            path.display(),
            r.determinant()
        )));
    }
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&r));
    Ok(Some(Isometry3::from_parts(Translation3::from(t_m), rotation)))
}

/// A camera file's `T_camk_cam0` ([`RigInput::file_t_cam_cam0`]) against the fitted one.
#[derive(Clone, Debug, Serialize)]
pub struct RigFileDifference {
    /// The camera (`k >= 1`).
    pub camera: usize,
    /// The file's `T_camk_cam0`.
    pub file: Isometry3<f64>,
    /// The fitted estimate it is compared with: `joint adjustment` or `the cameras' own fits`.
    pub fitted_by: &'static str,
    /// Fitted minus file translation, mm.
    pub translation_mm: Vector3<f64>,
    /// Rotation vector of `R_fitted R_file^-1`, degrees.
    pub rotation_deg: Vector3<f64>,
    /// The largest of the six chart coordinates' differences in the fitted transform's standard
    /// deviations (`[t, r]`, the rotation on the left, as its covariance).
    pub max_sigma: f64,
    /// `sqrt(d^T C^-1 d)` over the six coordinates, `C` the fitted transform's covariance.
    pub mahalanobis: f64,
}

/// Every camera file's `T_camk_cam0` against the fitted one: the joint adjustment's when it ran,
/// else the one combined from the cameras' own fits. Empty when no file carries `R`, `T`.
pub fn rig_file_differences(
    rig: &RigInput,
    fit: &RigFit,
    joint: Option<&RigJointCalibration>,
) -> Vec<RigFileDifference> {
    (1..rig.cameras.len())
        .filter_map(|k| {
            let file = rig.file_t_cam_cam0(k)?;
            let (est, fitted_by) = match joint {
                Some(j) => (&j.cameras[k - 1].t_cam_cam0, "joint adjustment"),
                None => (&fit.t_cam_cam0[k - 1], "the cameras' own fits"),
            };
            let d = chart_diff(&file, &est.transform);
            let max_sigma = (0..6).map(|i| d[i].abs() / est.covariance[(i, i)].max(1e-300).sqrt()).fold(0.0, f64::max);
            let mahalanobis = est.covariance.try_inverse().map_or(f64::NAN, |c| (d.transpose() * c * d)[(0, 0)].sqrt());
            Some(RigFileDifference {
                camera: k,
                file,
                fitted_by,
                translation_mm: Vector3::new(d[0], d[1], d[2]) * 1e3,
                rotation_deg: Vector3::new(d[3], d[4], d[5]).map(f64::to_degrees),
                max_sigma,
                mahalanobis,
            })
        })
        .collect()
}

/// Refuses a camera none of whose images a row of the poses table names.
fn check_matched(input: &HandEyeInput, label: &str) -> Result<()> {
    let file = input.table.file.display();
    if input.paths.is_empty() {
        return Err(DatasetError::Input(format!("handeye: {label}: no image found")));
    }
    let rows: HashSet<&str> = input.table.rows.iter().map(|r| r.image.as_str()).collect();
    let name = |p: &PathBuf| p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    if input.paths.iter().any(|p| rows.contains(name(p).as_str())) {
        return Ok(());
    }
    Err(DatasetError::Input(format!(
        "handeye: {label}: none of its {} image(s) is named by a row of {file} (images e.g. '{}', rows e.g. '{}'); each camera's images are matched to the table's rows by file name",
        input.paths.len(),
        name(&input.paths[0]),
        input.table.rows.first().map_or("", |r| r.image.as_str())
    )))
}

/// `t` moved by the chart increment `d = [dt (m), dr (rad)]`: `t + dt`, `Exp(dr) R` (the
/// convention of [`TransformEstimate`]'s covariance).
fn moved(t: &Isometry3<f64>, d: &Vector6<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(t.translation.vector + Vector3::new(d[0], d[1], d[2])),
        UnitQuaternion::from_scaled_axis(Vector3::new(d[3], d[4], d[5])) * t.rotation,
    )
}

/// The chart increment from `a` to `b` (the inverse of [`moved`]).
fn chart_diff(a: &Isometry3<f64>, b: &Isometry3<f64>) -> Vector6<f64> {
    let dt = b.translation.vector - a.translation.vector;
    let dr = (b.rotation * a.rotation.inverse()).scaled_axis();
    Vector6::new(dt.x, dt.y, dt.z, dr.x, dr.y, dr.z)
}

/// `T_camk_cam0` from camera 0's and camera `k`'s own hand-eye fits
/// ([`rig_transform_from_starts`]: `W_k^-1 W_0` eye-to-hand, `X_k^-1 X_0` eye-in-hand), with its
/// covariance propagated to first order (central differences in the chart) from the two fits'
/// covariances, taken as independent (see the module documentation).
pub fn rig_transform(mount: Mount, cam0: &HandEyeResult, cam_k: &HandEyeResult) -> TransformEstimate {
    let t = rig_transform_from_starts(mount, cam0, cam_k);
    let pick = |r: &HandEyeResult| match mount {
        Mount::EyeToHand => r.world,
        Mount::EyeInHand => r.hand_eye,
    };
    let (a, b) = (pick(cam_k), pick(cam0));
    let f = |da: &Vector6<f64>, db: &Vector6<f64>| moved(&a.transform, da).inverse() * moved(&b.transform, db);
    let h = 1e-7;
    let mut ja = Matrix6::zeros();
    let mut jb = Matrix6::zeros();
    for i in 0..6 {
        let mut d = Vector6::zeros();
        d[i] = h;
        let z = Vector6::zeros();
        let col_a = (chart_diff(&t, &f(&d, &z)) - chart_diff(&t, &f(&-d, &z))) / (2.0 * h);
        let col_b = (chart_diff(&t, &f(&z, &d)) - chart_diff(&t, &f(&z, &-d))) / (2.0 * h);
        ja.set_column(i, &col_a);
        jb.set_column(i, &col_b);
    }
    let covariance = ja * a.covariance * ja.transpose() + jb * b.covariance * jb.transpose();
    TransformEstimate { transform: t, covariance }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rig file's `R`, `T` read back as `[R | T]` (`T` in its unit); a file without them and a
    /// JSON camera give none; an `R` that is not a rotation is refused naming the file.
    #[test]
    fn a_rig_files_r_and_t_are_read_and_checked() {
        use ferrocal_vision::camera::io::to_opencv_rig_yaml;
        use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};
        let camera = CameraModel::new(
            Intrinsics { fx_px: 875.0, fy_px: 875.5, cx_px: 509.0, cy_px: 386.0 },
            Distortion::Brown5 { k1: -0.08, k2: 0.06, p1: -0.0002, p2: 0.0003, k3: -0.01 },
            ImageSize { width_px: 1024, height_px: 768 },
        )
        .unwrap();
        let t = Isometry3::new(Vector3::new(-0.116, 0.001, 0.031), Vector3::new(0.01, 0.26, -0.02));
        let (r, tv) = (t.rotation.to_rotation_matrix().into_inner(), t.translation.vector);
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("cam1.yaml");
        std::fs::write(&good, to_opencv_rig_yaml(&camera, Some((&r, &tv))).unwrap()).unwrap();
        let back = read_rig_extrinsics(&good).unwrap().unwrap();
        assert!((back.translation.vector - tv).norm() < 1e-15);
        assert!(back.rotation.angle_to(&t.rotation) < 1e-12);
        let plain = dir.path().join("cam0.yaml");
        std::fs::write(&plain, to_opencv_rig_yaml(&camera, None).unwrap()).unwrap();
        assert!(read_rig_extrinsics(&plain).unwrap().is_none());
        let json = dir.path().join("camera.json");
        std::fs::write(&json, "{\"fx\": 875.0}").unwrap();
        assert!(read_rig_extrinsics(&json).unwrap().is_none());
        let scaled = dir.path().join("scaled.yaml");
        std::fs::write(&scaled, to_opencv_rig_yaml(&camera, Some((&(r * 1.01), &tv))).unwrap()).unwrap();
        let err = read_rig_extrinsics(&scaled).unwrap_err().to_string();
        assert!(err.contains("scaled.yaml") && err.contains("not a rotation"), "{err}");
    }

    /// The chart Jacobian of `A^-1 B` with respect to `B` is the analytic one in the product
    /// chart (`t_B + dt`, `Exp(dr) R_B`: both map by `R_A^T`), and a rotation-only uncertainty
    /// of `B` moves only the rotation of `A^-1 B`.
    #[test]
    fn the_rig_transform_covariance_follows_the_chart() {
        let a = Isometry3::new(Vector3::new(0.3, -0.2, 1.0), Vector3::new(0.2, -0.4, 0.9));
        let b = Isometry3::new(Vector3::new(-0.5, 0.4, 1.2), Vector3::new(-0.3, 0.1, 0.2));
        let mut cov_b = Matrix6::zeros();
        for i in 3..6 {
            cov_b[(i, i)] = 1e-6;
        }
        let f = |db: &Vector6<f64>| a.inverse() * moved(&b, db);
        let t = f(&Vector6::zeros());
        let h = 1e-7;
        let mut j = Matrix6::zeros();
        for i in 0..6 {
            let mut d = Vector6::zeros();
            d[i] = h;
            j.set_column(i, &((chart_diff(&t, &f(&d)) - chart_diff(&t, &f(&-d))) / (2.0 * h)));
        }
        let ra = a.rotation.to_rotation_matrix().into_inner().transpose();
        let mut expected = Matrix6::zeros();
        expected.fixed_view_mut::<3, 3>(0, 0).copy_from(&ra);
        expected.fixed_view_mut::<3, 3>(3, 3).copy_from(&ra);
        assert!((j - expected).abs().max() < 1e-6, "{j} vs {expected}");
        let cov = j * cov_b * j.transpose();
        assert!((cov - expected * cov_b * expected.transpose()).abs().max() < 1e-12);
    }
}
