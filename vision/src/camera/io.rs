//! Camera calibration files: OpenCV FileStorage YAML and ROS `camera_info` YAML.
//!
//! Both are written by hand and read with a small tolerant reader (no YAML crate). Numbers are
//! written in the shortest form that parses back to the same `f64`, so write-then-read returns
//! the identical model.
//!
//! OpenCV FileStorage (as the calibration samples write it):
//!
//! ```text
//! %YAML:1.0
//! ---
//! image_width: 640
//! image_height: 480
//! camera_matrix: !!opencv-matrix
//!    rows: 3
//!    cols: 3
//!    dt: d
//!    data: [ fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0 ]
//! distortion_coefficients: !!opencv-matrix
//!    rows: 5
//!    cols: 1
//!    dt: d
//!    data: [ k1, k2, p1, p2, k3 ]
//! distortion_model: plumb_bob
//! ```
//!
//! `distortion_model` (ROS names; `none` for an ideal pinhole) is ferrocal's addition that
//! OpenCV ignores. Without it, 4 coefficients mean `k1 k2 p1 p2` (Brown with `k3 = 0`) unless
//! `fisheye_model: 1` (OpenCV's calibration tutorial) says fisheye; 5 mean Brown, 8 rational;
//! 12 or 14 are accepted when the thin-prism and tilt terms are zero.
//!
//! ROS `camera_info` (as `camera_calibration_parsers` writes it): `image_width`,
//! `image_height`, `camera_name`, `camera_matrix`, `distortion_model` (`plumb_bob`,
//! `rational_polynomial`, `equidistant`), `distortion_coefficients` (empty for an ideal
//! pinhole), `rectification_matrix` and `projection_matrix`: for one camera written as identity
//! and `[K | 0]`; for a stereo pair ([`to_ros_stereo_yaml`]) `R1`/`R2` and `P1`/`P2` of the
//! rectification, `P2[0][3] = -fx' B` with the baseline `B` in metres (ROS' convention); read
//! back by [`from_ros_camera_info`] ([`from_ros_yaml`] reads the camera only). ROS, OpenCV and
//! ferrocal all put pixel centres at integer coordinates, so no offset is applied.
//!
//! A stereo pair in OpenCV FileStorage ([`to_opencv_stereo_yaml`]): the names of OpenCV's
//! `stereo_calib` sample, `M1 D1 M2 D2` (its `intrinsics.yml`) and `R T R1 R2 P1 P2 Q` (its
//! `extrinsics.yml`) in one file, plus `E`, `F`; `T` in metres (`translation_unit: m`).

use std::path::Path;

use nalgebra::{Matrix3, Matrix3x4, Matrix4, Vector3};

use super::rectify::{essential_matrix, fundamental_matrix, stereo_rectify, StereoRectification};
use super::yaml::{self, fmt_f64, Entry, Node};
use super::{CameraModel, Distortion, DistortionKind, ImageSize, Intrinsics};
use crate::error::{Result, VisionError};

fn perr(source_name: &str, line: usize, message: impl Into<String>) -> VisionError {
    VisionError::Parse { source_name: source_name.to_string(), line, message: message.into() }
}

fn fmt_list(values: &[f64]) -> String {
    values.iter().map(|v| fmt_f64(*v)).collect::<Vec<_>>().join(", ")
}

fn k_matrix(camera: &CameraModel) -> [f64; 9] {
    let k = &camera.intrinsics;
    [k.fx_px, 0.0, k.cx_px, 0.0, k.fy_px, k.cy_px, 0.0, 0.0, 1.0]
}

/// The OpenCV FileStorage YAML text of a camera.
pub fn to_opencv_yaml(camera: &CameraModel) -> Result<String> {
    camera.validate()?;
    let kind = camera.distortion.kind();
    let coeffs = match kind {
        DistortionKind::None => vec![0.0; 5],
        _ => camera.distortion.coefficients(),
    };
    let model = match kind {
        DistortionKind::None => "none",
        other => other.ros_name(),
    };
    let mut s = String::new();
    s.push_str("%YAML:1.0\n---\n");
    s.push_str(&format!("image_width: {}\n", camera.image_size.width_px));
    s.push_str(&format!("image_height: {}\n", camera.image_size.height_px));
    s.push_str("camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n");
    s.push_str(&format!("   data: [ {} ]\n", fmt_list(&k_matrix(camera))));
    s.push_str(&format!("distortion_coefficients: !!opencv-matrix\n   rows: {}\n   cols: 1\n   dt: d\n", coeffs.len()));
    s.push_str(&format!("   data: [ {} ]\n", fmt_list(&coeffs)));
    s.push_str(&format!("distortion_model: {model}\n"));
    if kind == DistortionKind::KannalaBrandt {
        s.push_str("fisheye_model: 1\n");
    }
    Ok(s)
}

/// The ROS `camera_info` YAML text of a camera (rectification identity, projection `[K | 0]`).
pub fn to_ros_yaml(camera: &CameraModel, camera_name: &str) -> Result<String> {
    let k = k_matrix(camera);
    let p = [k[0], k[1], k[2], 0.0, k[3], k[4], k[5], 0.0, k[6], k[7], k[8], 0.0];
    ros_text(camera, camera_name, &IDENTITY3, &p)
}

const IDENTITY3: [f64; 9] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];

/// The ROS `camera_info` text with the given rectification (3 x 3) and projection (3 x 4)
/// matrices, row by row.
fn ros_text(camera: &CameraModel, camera_name: &str, r: &[f64; 9], p: &[f64; 12]) -> Result<String> {
    camera.validate()?;
    let kind = camera.distortion.kind();
    let coeffs = camera.distortion.coefficients();
    let k = k_matrix(camera);
    let name = if camera_name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '/')
        && !camera_name.is_empty()
    {
        camera_name.to_string()
    } else {
        format!("\"{}\"", camera_name.replace('\\', "\\\\").replace('"', "\\\""))
    };
    let mut s = String::new();
    s.push_str(&format!("image_width: {}\n", camera.image_size.width_px));
    s.push_str(&format!("image_height: {}\n", camera.image_size.height_px));
    s.push_str(&format!("camera_name: {name}\n"));
    s.push_str("camera_matrix:\n  rows: 3\n  cols: 3\n");
    s.push_str(&format!("  data: [{}]\n", fmt_list(&k)));
    s.push_str(&format!("distortion_model: {}\n", kind.ros_name()));
    s.push_str(&format!("distortion_coefficients:\n  rows: 1\n  cols: {}\n", coeffs.len()));
    s.push_str(&format!("  data: [{}]\n", fmt_list(&coeffs)));
    s.push_str("rectification_matrix:\n  rows: 3\n  cols: 3\n");
    s.push_str(&format!("  data: [{}]\n", fmt_list(r)));
    s.push_str("projection_matrix:\n  rows: 3\n  cols: 4\n");
    s.push_str(&format!("  data: [{}]\n", fmt_list(p)));
    Ok(s)
}

struct Doc<'a> {
    entries: Vec<Entry>,
    source_name: &'a str,
}

impl<'a> Doc<'a> {
    fn parse(text: &str, source_name: &'a str) -> Result<Self> {
        Ok(Self { entries: yaml::parse(text, source_name)?, source_name })
    }

    fn get(&self, key: &str) -> Option<&Entry> {
        self.entries.iter().find(|e| e.key == key)
    }

    fn require(&self, key: &str) -> Result<&Entry> {
        self.get(key).ok_or_else(|| perr(self.source_name, 0, format!("missing key '{key}'")))
    }

    fn scalar<'e>(&self, e: &'e Entry) -> Result<&'e str> {
        match &e.value {
            Node::Scalar(s) => Ok(s),
            _ => Err(perr(self.source_name, e.line, format!("'{}' must be a single value", e.key))),
        }
    }

    fn u32_value(&self, key: &str) -> Result<u32> {
        let e = self.require(key)?;
        let s = self.scalar(e)?;
        s.parse::<u32>()
            .map_err(|_| perr(self.source_name, e.line, format!("'{key}' must be a non-negative integer, found '{s}'")))
    }

    /// A matrix written as a mapping with `rows`, `cols` and `data`.
    fn matrix(&self, key: &str) -> Result<(usize, usize, Vec<f64>, usize)> {
        let e = self.require(key)?;
        let Node::Map(m) = &e.value else {
            return Err(perr(self.source_name, e.line, format!("'{key}' must be a matrix with rows, cols and data")));
        };
        let field = |name: &str| -> Result<&Entry> {
            m.iter()
                .find(|f| f.key == name)
                .ok_or_else(|| perr(self.source_name, e.line, format!("matrix '{key}' has no '{name}'")))
        };
        let dim = |name: &str| -> Result<usize> {
            let f = field(name)?;
            let s = self.scalar(f)?;
            s.parse::<usize>().map_err(|_| {
                perr(self.source_name, f.line, format!("'{key}.{name}' must be a non-negative integer, found '{s}'"))
            })
        };
        let rows = dim("rows")?;
        let cols = dim("cols")?;
        let data_entry = field("data")?;
        let items: Vec<String> = match &data_entry.value {
            Node::Seq(items) => items.clone(),
            Node::Scalar(s) if s.is_empty() => Vec::new(),
            _ => {
                return Err(perr(
                    self.source_name,
                    data_entry.line,
                    format!("'{key}.data' must be a sequence of numbers"),
                ))
            }
        };
        let mut data = Vec::with_capacity(items.len());
        for item in &items {
            data.push(yaml::parse_f64(item).ok_or_else(|| {
                perr(self.source_name, data_entry.line, format!("'{key}.data' holds '{item}', not a finite number"))
            })?);
        }
        // rows and cols come from the file: their product may overflow.
        if rows.checked_mul(cols) != Some(data.len()) {
            return Err(perr(
                self.source_name,
                data_entry.line,
                format!("'{key}' is {rows}x{cols} but its data has {} values", data.len()),
            ));
        }
        Ok((rows, cols, data, e.line))
    }

    /// What the OpenCV and ROS files of one camera share: the intrinsics, the image size and
    /// the distortion coefficients (a vector) with the line they stand on.
    fn camera_entries(&self) -> Result<(Intrinsics, ImageSize, Vec<f64>, usize)> {
        let intrinsics = self.intrinsics()?;
        let image_size = self.image_size()?;
        let (rows, cols, coeffs, line) = self.matrix("distortion_coefficients")?;
        if rows != 1 && cols != 1 && rows * cols != 0 {
            return Err(perr(
                self.source_name,
                line,
                format!("distortion_coefficients must be a vector, found {rows}x{cols}"),
            ));
        }
        Ok((intrinsics, image_size, coeffs, line))
    }

    fn intrinsics(&self) -> Result<Intrinsics> {
        let (rows, cols, k, line) = self.matrix("camera_matrix")?;
        if rows != 3 || cols != 3 {
            return Err(perr(self.source_name, line, format!("camera_matrix must be 3x3, found {rows}x{cols}")));
        }
        if k[1] != 0.0 || k[3] != 0.0 || k[6] != 0.0 || k[7] != 0.0 || k[8] != 1.0 {
            return Err(perr(
                self.source_name,
                line,
                "camera_matrix must be [fx 0 cx; 0 fy cy; 0 0 1] (skew is not supported)",
            ));
        }
        Ok(Intrinsics { fx_px: k[0], fy_px: k[4], cx_px: k[2], cy_px: k[5] })
    }

    fn image_size(&self) -> Result<ImageSize> {
        Ok(ImageSize { width_px: self.u32_value("image_width")?, height_px: self.u32_value("image_height")? })
    }

    fn model_name(&self) -> Result<Option<String>> {
        match self.get("distortion_model") {
            Some(e) => Ok(Some(self.scalar(e)?.to_string())),
            None => Ok(None),
        }
    }
}

/// Chooses the distortion model from a model name (may be absent), a fisheye flag and the
/// coefficients.
fn distortion_from(
    model: Option<&str>,
    fisheye: bool,
    coeffs: &[f64],
    source_name: &str,
    line: usize,
) -> Result<Distortion> {
    let unsupported =
        || VisionError::UnsupportedDistortion { model: model.unwrap_or("").to_string(), count: coeffs.len() };
    let n = coeffs.len();
    let kind = match model {
        Some("none") => {
            if coeffs.iter().any(|c| *c != 0.0) {
                return Err(perr(source_name, line, "distortion_model 'none' with non-zero coefficients"));
            }
            return Ok(Distortion::None);
        }
        // Every other model by its name or alias (`DistortionKind::name`, `aliases`); plumb_bob
        // without coefficients is the pinhole.
        Some(name) => match name.parse::<DistortionKind>() {
            Ok(DistortionKind::Brown5) if n == 0 => return Ok(Distortion::None),
            Ok(kind) => kind,
            Err(_) => return Err(unsupported()),
        },
        None if fisheye => DistortionKind::KannalaBrandt,
        None => match n {
            0 => return Ok(Distortion::None),
            4 | 5 => DistortionKind::Brown5,
            8 | 12 | 14 => DistortionKind::Rational8,
            _ => return Err(unsupported()),
        },
    };
    let want = kind.coefficient_names().len();
    let mut c = coeffs.to_vec();
    match kind {
        DistortionKind::Brown5 if n == 4 => c.push(0.0),
        DistortionKind::Rational8 if n == 12 || n == 14 => {
            if c[8..].iter().any(|v| *v != 0.0) {
                return Err(perr(
                    source_name,
                    line,
                    "thin-prism (s1..s4) and tilt (tau_x, tau_y) coefficients are not supported; \
                     they must be zero",
                ));
            }
            c.truncate(8);
        }
        DistortionKind::Rational8 if n == 5 => c.extend_from_slice(&[0.0, 0.0, 0.0]),
        _ => {}
    }
    if c.len() != want {
        return Err(unsupported());
    }
    Distortion::from_coefficients(kind, &c)
}

fn opencv_from_doc(doc: &Doc<'_>) -> Result<CameraModel> {
    let (intrinsics, image_size, coeffs, line) = doc.camera_entries()?;
    let fisheye = match doc.get("fisheye_model") {
        Some(e) => {
            let s = doc.scalar(e)?;
            !(s == "0" || s.eq_ignore_ascii_case("false"))
        }
        None => false,
    };
    let model = doc.model_name()?;
    let distortion = distortion_from(model.as_deref(), fisheye, &coeffs, doc.source_name, line)?;
    CameraModel::new(intrinsics, distortion, image_size)
}

/// Reads a camera from OpenCV FileStorage YAML text.
pub fn from_opencv_yaml(text: &str) -> Result<CameraModel> {
    opencv_from_doc(&Doc::parse(text, "<string>")?)
}

/// Reads a camera and its name from ROS `camera_info` YAML text (the name is empty when the
/// file has none).
pub fn from_ros_yaml(text: &str) -> Result<(CameraModel, String)> {
    ros_from_doc(&Doc::parse(text, "<string>")?)
}

fn ros_from_doc(doc: &Doc<'_>) -> Result<(CameraModel, String)> {
    let (intrinsics, image_size, coeffs, line) = doc.camera_entries()?;
    let model = doc.model_name()?;
    let distortion =
        distortion_from(Some(model.as_deref().unwrap_or("plumb_bob")), false, &coeffs, doc.source_name, line)?;
    let name = match doc.get("camera_name") {
        Some(e) => doc.scalar(e)?.replace("\\\"", "\"").replace("\\\\", "\\"),
        None => String::new(),
    };
    Ok((CameraModel::new(intrinsics, distortion, image_size)?, name))
}

/// Reads the YAML file `path` and hands its entries (named by the path in errors) to `from_doc`.
fn read_doc<T>(path: &Path, from_doc: impl Fn(&Doc) -> Result<T>) -> Result<T> {
    let text = std::fs::read_to_string(path).map_err(|source| VisionError::Io { path: path.to_path_buf(), source })?;
    let name = path.display().to_string();
    from_doc(&Doc::parse(&text, &name)?)
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).map_err(|source| VisionError::Io { path: path.to_path_buf(), source })
}

/// Writes a camera as OpenCV FileStorage YAML.
pub fn write_opencv_yaml(camera: &CameraModel, path: &Path) -> Result<()> {
    write_text(path, &to_opencv_yaml(camera)?)
}

/// Reads a camera from an OpenCV FileStorage YAML file.
pub fn read_opencv_yaml(path: &Path) -> Result<CameraModel> {
    read_doc(path, opencv_from_doc)
}

/// Writes a camera as ROS `camera_info` YAML.
pub fn write_ros_yaml(camera: &CameraModel, camera_name: &str, path: &Path) -> Result<()> {
    write_text(path, &to_ros_yaml(camera, camera_name)?)
}

/// Reads a camera and its name from a ROS `camera_info` YAML file.
pub fn read_ros_yaml(path: &Path) -> Result<(CameraModel, String)> {
    read_doc(path, ros_from_doc)
}

/// A calibrated stereo pair as the stereo files hold it: both cameras, `p_right = r p_left +
/// t_m` (OpenCV's `R`, `T`; metres) and the rectification computed from them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StereoPair {
    /// The left (first) camera.
    pub left: CameraModel,
    /// The right (second) camera.
    pub right: CameraModel,
    /// `R` of `T_right_left`.
    pub r: Matrix3<f64>,
    /// `T` of `T_right_left`, metres.
    pub t_m: Vector3<f64>,
    /// `R1 R2 P1 P2 Q` ([`stereo_rectify`]; `P2` and `Q` in metres).
    pub rectification: StereoRectification,
}

impl StereoPair {
    /// A pair with its rectification computed by [`stereo_rectify`].
    pub fn new(left: CameraModel, right: CameraModel, r: Matrix3<f64>, t_m: Vector3<f64>) -> Result<Self> {
        let rectification = stereo_rectify(&left, &right, &r, &t_m)?;
        Ok(Self { left, right, r, t_m, rectification })
    }
}

/// One OpenCV FileStorage matrix block, row by row.
fn cv_matrix(s: &mut String, name: &str, rows: usize, cols: usize, data: &[f64]) {
    s.push_str(&format!("{name}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n"));
    s.push_str(&format!("   data: [ {} ]\n", fmt_list(data)));
}

fn row_major<const R: usize, const C: usize>(m: &nalgebra::SMatrix<f64, R, C>) -> Vec<f64> {
    (0..R).flat_map(|i| (0..C).map(move |j| m[(i, j)])).collect()
}

/// The OpenCV FileStorage YAML text of a stereo pair, with the names of OpenCV's `stereo_calib`
/// sample (its `intrinsics.yml` and `extrinsics.yml` in one file): `M1 D1 M2 D2 R T E F R1 R2
/// P1 P2 Q`, plus `image_width`, `image_height`, and ferrocal's `distortion_model_1`,
/// `distortion_model_2` (ROS names, `none` for an ideal pinhole) and `translation_unit: m`
/// (OpenCV ignores them). `T`, `E`, `P2` and `Q` are in metres.
pub fn to_opencv_stereo_yaml(pair: &StereoPair) -> Result<String> {
    let mut s = String::from("%YAML:1.0\n---\n");
    if pair.left.image_size != pair.right.image_size {
        return Err(VisionError::InvalidInput { detail: "a stereo file needs two cameras of one image size".into() });
    }
    s.push_str(&format!("image_width: {}\n", pair.left.image_size.width_px));
    s.push_str(&format!("image_height: {}\n", pair.left.image_size.height_px));
    for (i, cam) in [(1, &pair.left), (2, &pair.right)] {
        cam.validate()?;
        let kind = cam.distortion.kind();
        let coeffs = match kind {
            DistortionKind::None => vec![0.0; 5],
            _ => cam.distortion.coefficients(),
        };
        cv_matrix(&mut s, &format!("M{i}"), 3, 3, &k_matrix(cam));
        cv_matrix(&mut s, &format!("D{i}"), 1, coeffs.len(), &coeffs);
        let model = match kind {
            DistortionKind::None => "none",
            other => other.ros_name(),
        };
        s.push_str(&format!("distortion_model_{i}: {model}\n"));
    }
    let rc = &pair.rectification;
    cv_matrix(&mut s, "R", 3, 3, &row_major(&pair.r));
    cv_matrix(&mut s, "T", 3, 1, pair.t_m.as_slice());
    s.push_str("translation_unit: m\n");
    cv_matrix(&mut s, "E", 3, 3, &row_major(&essential_matrix(&pair.r, &pair.t_m)));
    cv_matrix(&mut s, "F", 3, 3, &row_major(&fundamental_matrix(&pair.left, &pair.right, &pair.r, &pair.t_m)));
    cv_matrix(&mut s, "R1", 3, 3, &row_major(&rc.r1));
    cv_matrix(&mut s, "R2", 3, 3, &row_major(&rc.r2));
    cv_matrix(&mut s, "P1", 3, 4, &row_major(&rc.p1));
    cv_matrix(&mut s, "P2", 3, 4, &row_major(&rc.p2));
    cv_matrix(&mut s, "Q", 4, 4, &row_major(&rc.q));
    Ok(s)
}

impl Doc<'_> {
    /// A matrix of the given shape (a vector may be written as a row or a column).
    fn fixed(&self, key: &str, rows: usize, cols: usize) -> Result<Vec<f64>> {
        let (r, c, data, line) = self.matrix(key)?;
        let vector_ok = (rows == 1 || cols == 1) && r * c == rows * cols && (r == 1 || c == 1);
        if (r, c) != (rows, cols) && !vector_ok {
            return Err(perr(self.source_name, line, format!("'{key}' must be {rows}x{cols}, found {r}x{c}")));
        }
        Ok(data)
    }

    /// A camera from `M{i}`, `D{i}` and `distortion_model_{i}` with the file's image size.
    fn stereo_camera(&self, i: usize, image_size: ImageSize) -> Result<CameraModel> {
        let k = self.fixed(&format!("M{i}"), 3, 3)?;
        let (_, _, _, line) = self.matrix(&format!("M{i}"))?;
        if k[1] != 0.0 || k[3] != 0.0 || k[6] != 0.0 || k[7] != 0.0 || k[8] != 1.0 {
            return Err(perr(self.source_name, line, format!("M{i} must be [fx 0 cx; 0 fy cy; 0 0 1] (no skew)")));
        }
        let (rows, cols, coeffs, dline) = self.matrix(&format!("D{i}"))?;
        if rows != 1 && cols != 1 && rows * cols != 0 {
            return Err(perr(self.source_name, dline, format!("D{i} must be a vector, found {rows}x{cols}")));
        }
        let model = match self.get(&format!("distortion_model_{i}")) {
            Some(e) => Some(self.scalar(e)?.to_string()),
            None => None,
        };
        let distortion = distortion_from(model.as_deref(), false, &coeffs, self.source_name, dline)?;
        CameraModel::new(Intrinsics { fx_px: k[0], fy_px: k[4], cx_px: k[2], cy_px: k[5] }, distortion, image_size)
    }
}

fn mat3(v: &[f64]) -> Matrix3<f64> {
    Matrix3::from_row_slice(v)
}

fn opencv_stereo_from_doc(doc: &Doc<'_>) -> Result<StereoPair> {
    let image_size = doc.image_size()?;
    let left = doc.stereo_camera(1, image_size)?;
    let right = doc.stereo_camera(2, image_size)?;
    let r = mat3(&doc.fixed("R", 3, 3)?);
    let scale = match doc.get("translation_unit") {
        None => 1.0,
        Some(e) => match doc.scalar(e)? {
            "m" => 1.0,
            "cm" => 1e-2,
            "mm" => 1e-3,
            other => return Err(perr(doc.source_name, e.line, format!("translation_unit '{other}': use m, cm or mm"))),
        },
    };
    let t_m = Vector3::from_column_slice(&doc.fixed("T", 3, 1)?) * scale;
    let mut pair = StereoPair::new(left, right, r, t_m)?;
    // The file's own rectification when it has one (all five matrices), else the computed one.
    if ["R1", "R2", "P1", "P2", "Q"].iter().all(|k| doc.get(k).is_some()) {
        let rc = &mut pair.rectification;
        rc.r1 = mat3(&doc.fixed("R1", 3, 3)?);
        rc.r2 = mat3(&doc.fixed("R2", 3, 3)?);
        rc.p1 = Matrix3x4::from_row_slice(&doc.fixed("P1", 3, 4)?);
        rc.p2 = Matrix3x4::from_row_slice(&doc.fixed("P2", 3, 4)?);
        rc.q = Matrix4::from_row_slice(&doc.fixed("Q", 4, 4)?);
        if scale != 1.0 {
            for i in 0..3 {
                rc.p2[(i, 3)] *= scale;
            }
            rc.q[(3, 2)] /= scale;
            rc.q[(3, 3)] /= scale;
        }
    }
    Ok(pair)
}

/// Reads a stereo pair from OpenCV FileStorage YAML text (see [`to_opencv_stereo_yaml`]; `T` in
/// `translation_unit` (`m`, `cm`, `mm`; metres when absent), `E` and `F` ignored, the
/// rectification computed when `R1 R2 P1 P2 Q` are not all present).
pub fn from_opencv_stereo_yaml(text: &str) -> Result<StereoPair> {
    opencv_stereo_from_doc(&Doc::parse(text, "<string>")?)
}

/// Writes a stereo pair as OpenCV FileStorage YAML.
pub fn write_opencv_stereo_yaml(pair: &StereoPair, path: &Path) -> Result<()> {
    write_text(path, &to_opencv_stereo_yaml(pair)?)
}

/// Reads a stereo pair from an OpenCV FileStorage YAML file.
pub fn read_opencv_stereo_yaml(path: &Path) -> Result<StereoPair> {
    read_doc(path, opencv_stereo_from_doc)
}

/// The OpenCV FileStorage YAML text of one camera of a rig: [`to_opencv_yaml`]'s keys and, for
/// a camera other than the reference, `R` and `T` of `T_camk_cam0` with OpenCV's
/// `stereoCalibrate` meaning (`p_k = R p_0 + T`; `T` in metres, `translation_unit: m`).
pub fn to_opencv_rig_yaml(camera: &CameraModel, extrinsics: Option<(&Matrix3<f64>, &Vector3<f64>)>) -> Result<String> {
    let mut s = to_opencv_yaml(camera)?;
    if let Some((r, t_m)) = extrinsics {
        cv_matrix(&mut s, "R", 3, 3, &row_major(r));
        cv_matrix(&mut s, "T", 3, 1, t_m.as_slice());
        s.push_str("translation_unit: m\n");
    }
    Ok(s)
}

/// `R` and `T` of a rig camera's file: `p_k = R p_0 + T`, `T` in metres.
pub type RigExtrinsics = (Matrix3<f64>, Vector3<f64>);

/// Reads one camera of a rig ([`to_opencv_rig_yaml`]): the camera and, when the file has them,
/// `R` and `T` (metres; `translation_unit` `m`, `cm` or `mm`, metres when absent).
pub fn from_opencv_rig_yaml(text: &str) -> Result<(CameraModel, Option<RigExtrinsics>)> {
    let doc = Doc::parse(text, "<string>")?;
    let camera = opencv_from_doc(&doc)?;
    if doc.get("R").is_none() && doc.get("T").is_none() {
        return Ok((camera, None));
    }
    let scale = match doc.get("translation_unit").map(|e| doc.scalar(e).map(|v| (v, e.line))).transpose()? {
        None | Some(("m", _)) => 1.0,
        Some(("cm", _)) => 1e-2,
        Some(("mm", _)) => 1e-3,
        Some((other, line)) => {
            return Err(perr("<string>", line, format!("translation_unit '{other}': use m, cm or mm")))
        }
    };
    let r = mat3(&doc.fixed("R", 3, 3)?);
    let t_m = Vector3::from_column_slice(&doc.fixed("T", 3, 1)?) * scale;
    Ok((camera, Some((r, t_m))))
}

/// A ROS `camera_info` file with its rectification and projection matrices.
#[derive(Clone, Debug, PartialEq)]
pub struct RosCameraInfo {
    /// The camera.
    pub camera: CameraModel,
    /// `camera_name` (empty when absent).
    pub name: String,
    /// `rectification_matrix` (`R`; identity when absent).
    pub rectification: Matrix3<f64>,
    /// `projection_matrix` (`P`; `[K | 0]` when absent).
    pub projection: Matrix3x4<f64>,
}

/// The ROS `camera_info` YAML texts of the left and right camera of a stereo pair, as ROS'
/// stereo calibrator writes them: `rectification_matrix` = `R1` / `R2`, `projection_matrix` =
/// `P1` / `P2` with `P2[0][3] = -fx' B`, `B` the baseline in metres.
pub fn to_ros_stereo_yaml(pair: &StereoPair, left_name: &str, right_name: &str) -> Result<(String, String)> {
    let rc = &pair.rectification;
    let arr9 = |m: &Matrix3<f64>| -> [f64; 9] { std::array::from_fn(|i| m[(i / 3, i % 3)]) };
    let arr12 = |m: &Matrix3x4<f64>| -> [f64; 12] { std::array::from_fn(|i| m[(i / 4, i % 4)]) };
    Ok((
        ros_text(&pair.left, left_name, &arr9(&rc.r1), &arr12(&rc.p1))?,
        ros_text(&pair.right, right_name, &arr9(&rc.r2), &arr12(&rc.p2))?,
    ))
}

fn ros_info_from_doc(doc: &Doc<'_>) -> Result<RosCameraInfo> {
    let (camera, name) = ros_from_doc(doc)?;
    let rectification = if doc.get("rectification_matrix").is_some() {
        mat3(&doc.fixed("rectification_matrix", 3, 3)?)
    } else {
        Matrix3::identity()
    };
    let projection = if doc.get("projection_matrix").is_some() {
        Matrix3x4::from_row_slice(&doc.fixed("projection_matrix", 3, 4)?)
    } else {
        let k = k_matrix(&camera);
        Matrix3x4::new(k[0], k[1], k[2], 0.0, k[3], k[4], k[5], 0.0, k[6], k[7], k[8], 0.0)
    };
    Ok(RosCameraInfo { camera, name, rectification, projection })
}

/// Reads a ROS `camera_info` YAML text with its rectification and projection matrices.
pub fn from_ros_camera_info(text: &str) -> Result<RosCameraInfo> {
    ros_info_from_doc(&Doc::parse(text, "<string>")?)
}

/// Reads a ROS `camera_info` YAML file with its rectification and projection matrices.
pub fn read_ros_camera_info(path: &Path) -> Result<RosCameraInfo> {
    read_doc(path, ros_info_from_doc)
}

#[cfg(test)]
mod tests;
