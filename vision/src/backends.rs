//! The external libraries behind the vision chain, and a probe that each one is built, linked
//! and answering: OpenCV (the baseline), the AprilTag C library, kornia-rs and Ceres.

use serde::Serialize;

/// Whether the third-party libraries' own log lines (OpenCV's `[ WARN:0@...]`, Ceres' glog
/// warnings such as "Linear solver failure") reach stderr: off by default, a command's
/// `--verbose` shows them. What they report is in the results (a solver's termination, a
/// detection's failure); on their own they alarm on runs that are fine. Set once at start.
pub fn show_library_logs(shown: bool) {
    use opencv::core::LogLevel;
    ferrocal_lsq::show_ceres_log(shown);
    let level = if shown { LogLevel::LOG_LEVEL_INFO } else { LogLevel::LOG_LEVEL_ERROR };
    // Setting a level cannot fail in a build with logging; a build without it has nothing to hide.
    let _ = opencv::core::set_log_level(level);
}

/// What one backend answered.
#[derive(Clone, Debug, Serialize)]
pub struct BackendStatus {
    /// Library name.
    pub name: &'static str,
    /// Its role in ferrocal.
    pub role: &'static str,
    /// Version or a short description of what the probe saw.
    pub detail: String,
    /// Whether the probe succeeded.
    pub ok: bool,
}

/// Runs a small real call in every backend: OpenCV reports its version and finds no chessboard
/// in a blank image, the AprilTag C library and kornia-apriltag run on a blank image, Ceres
/// solves `min (x - 2)^2`.
pub fn probe_backends() -> Vec<BackendStatus> {
    vec![probe_opencv(), probe_apriltag(), probe_kornia(), probe_ceres()]
}

fn probe_opencv() -> BackendStatus {
    use opencv::core::{Mat, Scalar, Size, Vector, CV_8UC1};
    let result = (|| -> opencv::Result<String> {
        let version = opencv::core::get_version_string()?;
        let img = Mat::new_rows_cols_with_default(120, 160, CV_8UC1, Scalar::all(128.0))?;
        let mut corners: Vector<opencv::core::Point2f> = Vector::new();
        let found = opencv::calib3d::find_chessboard_corners(
            &img,
            Size::new(9, 6),
            &mut corners,
            opencv::calib3d::CALIB_CB_ADAPTIVE_THRESH,
        )?;
        Ok(format!("OpenCV {version} (blank image: chessboard found = {found})"))
    })();
    match result {
        Ok(detail) => BackendStatus { name: "opencv", role: "baseline for every vision result", detail, ok: true },
        Err(e) => {
            BackendStatus { name: "opencv", role: "baseline for every vision result", detail: e.to_string(), ok: false }
        }
    }
}

fn probe_apriltag() -> BackendStatus {
    let role = "reference AprilTag detector (C library)";
    let detector = apriltag::DetectorBuilder::new().add_family_bits(apriltag::Family::tag_36h11(), 1).build();
    match detector {
        Ok(mut d) => match apriltag::Image::zeros_with_stride(64, 48, 64) {
            Ok(img) => {
                let n = d.detect(&img).len();
                BackendStatus {
                    name: "apriltag",
                    role,
                    detail: format!("tag36h11 detector built; blank image: {n} detections"),
                    ok: true,
                }
            }
            Err(e) => BackendStatus { name: "apriltag", role, detail: e.to_string(), ok: false },
        },
        Err(e) => BackendStatus { name: "apriltag", role, detail: e.to_string(), ok: false },
    }
}

fn probe_kornia() -> BackendStatus {
    use kornia_apriltag::{family::TagFamilyKind, AprilTagDecoder, DecodeTagsConfig};
    use kornia_image::{Image, ImageSize};
    let role = "image primitives and the pure-Rust AprilTag detector";
    let size = ImageSize { width: 64, height: 48 };
    let result = (|| -> Result<usize, String> {
        let img = Image::<u8, 1>::from_size_val(size, 255).map_err(|e| e.to_string())?;
        let cfg = DecodeTagsConfig::new(vec![TagFamilyKind::Tag36H11]).map_err(|e| e.to_string())?;
        let mut dec = AprilTagDecoder::new(cfg, size).map_err(|e| e.to_string())?;
        Ok(dec.decode(&img).map_err(|e| e.to_string())?.len())
    })();
    match result {
        Ok(n) => BackendStatus {
            name: "kornia-rs",
            role,
            detail: format!("kornia-apriltag 0.2 on a blank image: {n} detections"),
            ok: true,
        },
        Err(e) => BackendStatus { name: "kornia-rs", role, detail: e, ok: false },
    }
}

fn probe_ceres() -> BackendStatus {
    use ceres_solver::{CostFunctionType, NllsProblem, SolverOptions};
    let role = "large non-linear least squares (bundle adjustment)";
    let cost: CostFunctionType =
        Box::new(move |p: &[&[f64]], r: &mut [f64], jac: Option<&mut [Option<&mut [&mut [f64]]>]>| {
            r[0] = p[0][0] - 2.0;
            if let Some(j) = jac {
                if let Some(d) = &mut j[0] {
                    d[0][0] = 1.0;
                }
            }
            true
        });
    let solved = NllsProblem::new()
        .residual_block_builder()
        .set_cost(cost, 1)
        .set_parameters(vec![vec![0.0]])
        .build_into_problem()
        .map_err(|e| e.to_string())
        .and_then(|(p, _)| p.solve(&SolverOptions::default()).map_err(|e| e.to_string()));
    match solved {
        Ok(s) => BackendStatus {
            name: "ceres-solver",
            role,
            detail: format!("Ceres 2.2 solved min (x-2)^2: x = {:.9}", s.parameters[0][0]),
            ok: (s.parameters[0][0] - 2.0).abs() < 1e-6,
        },
        Err(e) => BackendStatus { name: "ceres-solver", role, detail: e, ok: false },
    }
}

/// Limits OpenCV's own worker threads (its `parallel_for_`, e.g. inside the marker decoding)
/// to `threads` for the rest of the process; 1 runs it on the calling thread.
pub fn set_opencv_threads(threads: usize) -> crate::Result<()> {
    let n = i32::try_from(threads.max(1)).unwrap_or(i32::MAX);
    opencv::core::set_num_threads(n)
        .map_err(|e| crate::VisionError::Backend { library: "opencv", message: e.to_string() })
}

#[cfg(test)]
mod tests {
    #[test]
    fn every_backend_answers() {
        for b in super::probe_backends() {
            assert!(b.ok, "{}: {}", b.name, b.detail);
        }
    }
}
