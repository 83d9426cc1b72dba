//! From a folder of images and a poses table to a hand-eye recording
//! ([`ferrocal_calib::handeye::HandEyeData`]): each image matched to its row by file name, the
//! pattern detected with per-corner covariances, every corner numbered by its position on the
//! target (so that any detector that reports target positions works, partial views included).
//! Also the camera files `--intrinsics` accepts.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point3};

use ferrocal_calib::handeye::{HandEyeData, HandEyeView, Mount};
use ferrocal_vision::camera::{CameraModel, Distortion, DistortionKind, ImageSize, Intrinsics};
use ferrocal_vision::detect::{DetectOptions, Detection, Detector, Pattern};

use super::poses::PosesTable;
use crate::error::{DatasetError, Location, Result};

/// An image or a row left out, and why.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Skipped {
    /// The image (or the table row, `file:line`).
    pub what: String,
    /// Why.
    pub reason: String,
}

/// Key of a target position, to 0.1 µm.
fn key(p: &Point3<f64>) -> [i64; 3] {
    [p.x, p.y, p.z].map(|v| (v * 1e7).round() as i64)
}

/// Detects `pattern` in every image and pairs it with its row of `table` (`flange[i]` is row
/// `i`'s `T_base_flange`). Images without a row, rows without an image, unreadable images and
/// images where the pattern is not found are listed in the second result; the batch goes on.
pub fn load_recording(
    images: &[PathBuf],
    table: &PosesTable,
    flange: &[Isometry3<f64>],
    pattern: &Pattern,
    mount: Mount,
) -> Result<(HandEyeData, Vec<Skipped>)> {
    // Fail early on a pattern the detector refuses, before any image is read. The calibration
    // targets' options (an AprilTag board's corners refined by the edge model).
    let options = ferrocal_vision::calib::CalibrationPattern::of(pattern)
        .map(|c| c.detect_options())
        .unwrap_or_else(|_| DetectOptions::default());
    Detector::new(*pattern, options.clone(), None)?;
    let by_name: HashMap<&str, usize> = table.rows.iter().enumerate().map(|(i, r)| (r.image.as_str(), i)).collect();
    let mut used = vec![false; table.rows.len()];
    let mut skipped = Vec::new();
    let mut ids: HashMap<[i64; 3], usize> = HashMap::new();
    let mut points: Vec<Point3<f64>> = Vec::new();
    let mut views = Vec::new();
    // Images matched to rows, then read and searched in parallel (one detector per worker
    // thread), then numbered in input order so that the result does not depend on the threads.
    let mut matched = Vec::new();
    for path in images {
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let Some(&row) = by_name.get(name.as_str()) else {
            skipped.push(Skipped {
                what: path.display().to_string(),
                reason: format!("no row of {} names it", table.file.display()),
            });
            continue;
        };
        used[row] = true;
        matched.push((path, name, row));
    }
    let found: Vec<std::result::Result<(ImageSize, Vec<Detection>), String>> = {
        use rayon::prelude::*;
        matched
            .par_iter()
            .map_init(
                || Detector::new(*pattern, options.clone(), None),
                |det, (path, _, _)| {
                    let det = det.as_mut().map_err(|e| e.to_string())?;
                    let img = ferrocal_vision::detect::load_gray(path).map_err(|e| e.to_string())?;
                    let size = ImageSize { width_px: img.width(), height_px: img.height() };
                    det.detect(&img).map(|d| (size, d)).map_err(|e| e.to_string())
                },
            )
            .collect()
    };
    for ((path, name, row), found) in matched.into_iter().zip(found) {
        let (image_size, detections) = match found {
            Ok(f) => f,
            Err(reason) => {
                skipped.push(Skipped { what: path.display().to_string(), reason });
                continue;
            }
        };
        if detections.iter().all(|d| d.corners.is_empty()) {
            skipped.push(Skipped { what: path.display().to_string(), reason: format!("'{pattern}' not found") });
            continue;
        }
        let mut view = HandEyeView {
            name: name.clone(),
            split: table.rows[row].split,
            t_base_flange: flange[row],
            image_size,
            point_ids: Vec::new(),
            corners_px: Vec::new(),
            covariances_px2: Vec::new(),
        };
        for c in detections.iter().flat_map(|d| &d.corners) {
            let Some(t) = c.target_m else { continue };
            let id = *ids.entry(key(&t)).or_insert_with(|| {
                points.push(t);
                points.len() - 1
            });
            if view.point_ids.contains(&id) {
                continue;
            }
            view.point_ids.push(id);
            view.corners_px.push(c.position_px);
            view.covariances_px2.push(c.covariance_px2);
        }
        if view.point_ids.is_empty() {
            skipped.push(Skipped {
                what: path.display().to_string(),
                reason: format!("the pattern '{pattern}' gives no target positions (its size is needed)"),
            });
            continue;
        }
        views.push(view);
    }
    for (r, u) in table.rows.iter().zip(&used) {
        if !u {
            skipped.push(Skipped {
                what: format!("{}:{}", table.file.display(), r.line),
                reason: format!("no image named '{}' among the images given", r.image),
            });
        }
    }
    Ok((HandEyeData { mount, target_points_m: points, views }, skipped))
}

/// A recording from detections made elsewhere (`handeye --observations`): each observed image
/// paired with its row of `table` by file name, its points numbered as `pattern`'s calibration
/// target numbers them, each with the covariance `sigma_px^2 I` when the file gives one. Images
/// without a row, rows without an image and images without points are listed in the second
/// result; a point id the target does not have is an error naming the file, line and image.
pub fn load_observed(
    obs: &crate::import::observations::Observations,
    file: &Path,
    image_size: ImageSize,
    table: &PosesTable,
    flange: &[Isometry3<f64>],
    pattern: &Pattern,
    mount: Mount,
) -> Result<(HandEyeData, Vec<Skipped>)> {
    // Numbered as the calibration target numbers its points, placed in the detector's frame (the
    // frame the image route's hand-eye transform is in).
    let points_m = ferrocal_vision::calib::CalibrationPattern::of(pattern)?.detector_points_m();
    let cameras = obs.cameras();
    if cameras.len() > 1 {
        return Err(DatasetError::Input(format!(
            "{}: observations of {} cameras ({}); handeye --observations takes one camera's",
            file.display(),
            cameras.len(),
            cameras.join(", ")
        )));
    }
    let by_name: HashMap<&str, usize> = table.rows.iter().enumerate().map(|(i, r)| (r.image.as_str(), i)).collect();
    let mut used = vec![false; table.rows.len()];
    let mut skipped = Vec::new();
    let mut views = Vec::new();
    for i in &obs.images {
        let name = Path::new(&i.image).file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let Some(&row) = by_name.get(name.as_str()) else {
            skipped.push(Skipped {
                what: i.image.clone(),
                reason: format!("no row of {} names it", table.file.display()),
            });
            continue;
        };
        used[row] = true;
        if let Some(id) = i.point_ids.iter().find(|&&id| id >= points_m.len()) {
            return Err(DatasetError::Input(format!(
                "{} (line {}): image '{}' names point {id}, but the pattern {pattern} has points 0 to {}",
                file.display(),
                i.line,
                i.image,
                points_m.len().saturating_sub(1)
            )));
        }
        if i.point_ids.is_empty() {
            skipped.push(Skipped { what: i.image.clone(), reason: "no points observed".into() });
            continue;
        }
        views.push(HandEyeView {
            name,
            split: table.rows[row].split,
            t_base_flange: flange[row],
            image_size,
            point_ids: i.point_ids.clone(),
            corners_px: i.corners_px.clone(),
            covariances_px2: i.sigma_px.iter().map(|s| s.map(|s| nalgebra::Matrix2::identity() * (s * s))).collect(),
        });
    }
    for (r, u) in table.rows.iter().zip(&used) {
        if !u {
            skipped.push(Skipped {
                what: format!("{}:{}", table.file.display(), r.line),
                reason: format!("no image named '{}' among the observations", r.image),
            });
        }
    }
    Ok((HandEyeData { mount, target_points_m: points_m, views }, skipped))
}

fn json_number(v: &serde_json::Value, key: &str, path: &Path) -> Result<f64> {
    v.get(key).and_then(serde_json::Value::as_f64).ok_or_else(|| DatasetError::Invalid {
        location: Location::new(path, 1, key),
        message: format!("'{key}' is missing or not a number"),
    })
}

/// A camera from the JSON of `ferrocal camera calibrate` (or the `camera` part of
/// `ferrocal handeye`'s JSON).
fn camera_from_json(text: &str, path: &Path) -> Result<CameraModel> {
    let root: serde_json::Value = serde_json::from_str(text).map_err(|e| DatasetError::Invalid {
        location: Location {
            file: path.to_path_buf(),
            line: e.line() as u64,
            column: Some(format!("column {}", e.column())),
        },
        message: e.to_string(),
    })?;
    let v = root.get("camera").filter(|c| c.get("fx").is_some()).unwrap_or(&root);
    let size = v.get("image_size").and_then(|s| s.as_array()).filter(|s| s.len() == 2);
    let size = size.and_then(|s| Some(ImageSize { width_px: s[0].as_u64()? as u32, height_px: s[1].as_u64()? as u32 }));
    let size = size.ok_or_else(|| DatasetError::Invalid {
        location: Location::new(path, 1, "image_size"),
        message: "'image_size' must be [width, height]".into(),
    })?;
    let coefficients: Vec<f64> = v
        .get("distortion")
        .and_then(|d| d.as_array())
        .map(|d| d.iter().filter_map(serde_json::Value::as_f64).collect())
        .unwrap_or_default();
    // Every lens model by its name or alias (`DistortionKind::from_str`); `pinhole` is the JSON's
    // name of the ideal pinhole.
    let kind = match v.get("model").and_then(|m| m.as_str()).unwrap_or("brown5") {
        "pinhole" => DistortionKind::None,
        other => other.parse::<DistortionKind>().map_err(|_| DatasetError::Invalid {
            location: Location::new(path, 1, "model"),
            message: format!("unknown lens model '{other}'"),
        })?,
    };
    let intrinsics = Intrinsics {
        fx_px: json_number(v, "fx", path)?,
        fy_px: json_number(v, "fy", path)?,
        cx_px: json_number(v, "cx", path)?,
        cy_px: json_number(v, "cy", path)?,
    };
    let distortion = if kind == DistortionKind::None {
        Distortion::None
    } else {
        Distortion::from_coefficients(kind, &coefficients)?
    };
    Ok(CameraModel::new(intrinsics, distortion, size)?)
}

/// Reads a camera file: the JSON of `ferrocal camera calibrate`, OpenCV FileStorage YAML or ROS
/// `camera_info` YAML (told apart by extension and content).
pub fn read_camera_file(path: &Path) -> Result<CameraModel> {
    let text = crate::import::table::read_text(path)?;
    let located = |e: ferrocal_vision::VisionError| DatasetError::Invalid {
        location: Location::line(path, 1),
        message: format!("not a camera file ferrocal reads (camera calibrate JSON, OpenCV or ROS YAML): {e}"),
    };
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("json")) || text.trim_start().starts_with('{') {
        return camera_from_json(&text, path);
    }
    if text.contains("!!opencv-matrix") || text.starts_with("%YAML") {
        return ferrocal_vision::camera::io::from_opencv_yaml(&text).map_err(located);
    }
    ferrocal_vision::camera::io::from_ros_yaml(&text).map(|(c, _)| c).map_err(located)
}
