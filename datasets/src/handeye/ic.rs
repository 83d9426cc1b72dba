//! The importer of ROS-Industrial industrial_calibration hand-eye sets (`cal_data.yaml` and
//! `poses/N.yaml`, as in `shared/data/industrial_calibration/test_set_*`) into the poses table
//! of [`super::poses`].
//!
//! `cal_data.yaml`: `data` (a list of `{pose, image}` file pairs), `intrinsics` (`fx fy cx cy`,
//! pixels), `static_camera` (true: the camera is fixed, eye-to-hand), `target_finder` (the
//! target's description). `poses/N.yaml`: `x y z` (metres) and `qx qy qz qw` of
//! `T_base_flange` as the controller reported it. Rows are written in the natural order of the
//! image names; with `test_every = K`, every K-th row (the K-th, 2K-th, ...; for K = 2 every
//! second image) is marked `test`.

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::Deserialize;

use ferrocal_calib::handeye::Mount;
use ferrocal_calib::Split;
use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};

use crate::error::{DatasetError, Location, Result};
use crate::import::natural_cmp;

#[derive(Deserialize)]
struct CalData {
    data: Vec<Entry>,
    #[serde(default)]
    intrinsics: Option<IcIntrinsics>,
    #[serde(default)]
    static_camera: bool,
    #[serde(default)]
    target_finder: Option<TargetFinder>,
}

#[derive(Deserialize)]
struct Entry {
    pose: String,
    image: String,
}

#[derive(Deserialize)]
struct IcIntrinsics {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
}

#[derive(Deserialize)]
struct TargetFinder {
    #[serde(rename = "type")]
    kind: String,
    rows: u32,
    cols: u32,
    #[serde(default)]
    spacing: Option<f64>,
    #[serde(default)]
    chessboard_dim: Option<f64>,
    #[serde(default)]
    aruco_marker_dim: Option<f64>,
    #[serde(default)]
    dictionary: Option<u32>,
}

#[derive(Deserialize)]
pub(super) struct IcPose {
    pub(super) x: f64,
    pub(super) y: f64,
    pub(super) z: f64,
    pub(super) qx: f64,
    pub(super) qy: f64,
    pub(super) qz: f64,
    pub(super) qw: f64,
}

/// An imported set.
#[derive(Clone, Debug, PartialEq)]
pub struct IcSet {
    /// Rows: image file name, `T_base_flange`, split.
    pub rows: Vec<(String, Isometry3<f64>, Split)>,
    /// The mount (`static_camera: true` is eye-to-hand).
    pub mount: Mount,
    /// The camera of `intrinsics` (pinhole; the source gives no distortion) with the size of the
    /// first image, when both are there.
    pub camera: Option<CameraModel>,
    /// The target as a ferrocal pattern string, when the finder type is known.
    pub pattern: Option<String>,
}

pub(super) fn yaml_error(path: &Path, e: &serde_norway::Error) -> DatasetError {
    let (line, column) = e.location().map_or((1, None), |l| (l.line() as u64, Some(l.column().to_string())));
    DatasetError::Invalid {
        location: Location { file: path.to_path_buf(), line, column },
        message: e.to_string().split(" at line ").next().unwrap_or_default().to_string(),
    }
}

fn read_yaml<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T> {
    let text = crate::import::table::read_text(path)?;
    serde_norway::from_str(&text).map_err(|e| yaml_error(path, &e))
}

/// OpenCV's ArUco dictionary name by its enum value (the dictionaries ferrocal decodes).
fn dictionary_name(k: u32) -> Option<&'static str> {
    ferrocal_vision::detect::ArucoDictionary::ALL.get(k as usize).map(|d| d.name())
}

fn mm(v_m: f64) -> String {
    format!("{}mm", (v_m * 1e6).round() / 1e3)
}

fn pattern_string(t: &TargetFinder) -> Option<String> {
    match t.kind.as_str() {
        "ModifiedCircleGridTargetFinder" => {
            Some(format!("circlegrid:{}x{}:{}:modified", t.cols, t.rows, mm(t.spacing?)))
        }
        "CircleGridTargetFinder" => Some(format!("circlegrid:{}x{}:{}", t.cols, t.rows, mm(t.spacing?))),
        "CharucoGridTargetFinder" => Some(format!(
            "charuco:{}x{}:{}:{}:{}",
            t.cols,
            t.rows,
            mm(t.chessboard_dim?),
            mm(t.aruco_marker_dim?),
            dictionary_name(t.dictionary?)?
        )),
        _ => None,
    }
}

/// Reads an industrial_calibration set folder (see the module documentation).
pub fn read_ic_set(dir: &Path, test_every: Option<usize>) -> Result<IcSet> {
    if test_every == Some(0) {
        return Err(DatasetError::Input("test_every must be at least 1".into()));
    }
    let cal_path = dir.join("cal_data.yaml");
    let cal: CalData = read_yaml(&cal_path)?;
    if cal.data.is_empty() {
        return Err(DatasetError::Invalid {
            location: Location::line(&cal_path, 1),
            message: "'data' is empty".into(),
        });
    }
    let mut entries: Vec<(String, PathBuf, PathBuf)> = cal
        .data
        .iter()
        .map(|e| {
            let name = Path::new(&e.image).file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
            (name, dir.join(&e.image), dir.join(&e.pose))
        })
        .collect();
    entries.sort_by(|a, b| natural_cmp(&a.0, &b.0));
    let mut rows = Vec::with_capacity(entries.len());
    for (k, (name, _, pose_path)) in entries.iter().enumerate() {
        let p: IcPose = read_yaml(pose_path)?;
        let q = Quaternion::new(p.qw, p.qx, p.qy, p.qz);
        let norm = q.norm();
        if (norm - 1.0).abs() > super::poses::QUATERNION_NORM_TOLERANCE {
            return Err(DatasetError::Invalid {
                location: Location::line(pose_path, 1),
                message: format!("the quaternion (qx, qy, qz, qw) has norm {norm:.6}, not 1"),
            });
        }
        let t =
            Isometry3::from_parts(Translation3::from(Vector3::new(p.x, p.y, p.z)), UnitQuaternion::from_quaternion(q));
        let split = match test_every {
            Some(n) if k % n == n - 1 => Split::Test,
            _ => Split::Train,
        };
        rows.push((name.clone(), t, split));
    }
    let size = image::image_dimensions(&entries[0].1)
        .map(|(w, h)| ImageSize { width_px: w, height_px: h })
        .map_err(|e| DatasetError::Image { path: entries[0].1.clone(), reason: e.to_string() })?;
    let camera = match cal.intrinsics {
        Some(k) => Some(
            CameraModel::new(Intrinsics { fx_px: k.fx, fy_px: k.fy, cx_px: k.cx, cy_px: k.cy }, Distortion::None, size)
                .map_err(|e| DatasetError::Invalid {
                    location: Location::line(&cal_path, 1),
                    message: e.to_string(),
                })?,
        ),
        None => None,
    };
    let mount = if cal.static_camera { Mount::EyeToHand } else { Mount::EyeInHand };
    Ok(IcSet { rows, mount, camera, pattern: cal.target_finder.as_ref().and_then(pattern_string) })
}

/// Reads a set and writes its poses table to `out` (atomically, never onto an input), and, when
/// asked, its camera as OpenCV YAML to `intrinsics_out`.
pub fn import_ic_handeye(
    dir: &Path,
    out: &Path,
    test_every: Option<usize>,
    intrinsics_out: Option<&Path>,
) -> Result<IcSet> {
    let set = read_ic_set(dir, test_every)?;
    let mut comments = vec![
        format!("imported by ferrocal {} from {}", env!("CARGO_PKG_VERSION"), dir.display()),
        "source: ROS-Industrial industrial_calibration example data, Apache-2.0".to_string(),
        format!("mount: {}", set.mount.name()),
    ];
    if let Some(p) = &set.pattern {
        comments.push(format!("pattern: {p}"));
    }
    let text = super::poses::flange_poses_to_string(&set.rows, &comments);
    let cal = dir.join("cal_data.yaml");
    // The table and the camera are composed first and written as one commit.
    let yaml = match intrinsics_out {
        Some(_) => {
            let camera = set.camera.ok_or_else(|| DatasetError::Invalid {
                location: Location::line(&cal, 1),
                message: "no 'intrinsics' to write".into(),
            })?;
            Some(ferrocal_vision::camera::io::to_opencv_yaml(&camera)?)
        }
        None => None,
    };
    let mut files: Vec<(&Path, &[u8])> = vec![(out, text.as_bytes())];
    if let (Some(path), Some(yaml)) = (intrinsics_out, &yaml) {
        files.push((path, yaml.as_bytes()));
    }
    super::poses::write_all_atomic(&files, &[cal.as_path()])?;
    Ok(set)
}
