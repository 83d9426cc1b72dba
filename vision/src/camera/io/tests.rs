use super::*;

fn cameras() -> Vec<CameraModel> {
    let k = Intrinsics { fx_px: 535.9157, fy_px: 535.9157 + 1.0 / 3.0e9, cx_px: 342.2832 + 0.1 + 0.2, cy_px: 235.5708 };
    let size = ImageSize { width_px: 640, height_px: 480 };
    [
        Distortion::None,
        Distortion::Brown5 { k1: -0.26637, k2: -0.038589, p1: 0.0017832, p2: -0.00028122 / 3.0, k3: 0.23839 },
        Distortion::Rational8 { k1: 1.9, k2: 0.4, p1: 3e-4, p2: -1e-20, k3: 0.01, k4: 2.2, k5: 0.9, k6: 0.05 },
        Distortion::KannalaBrandt { k1: -0.00371, k2: 0.0406, k3: -0.0392, k4: 0.0072 },
    ]
    .into_iter()
    .map(|d| CameraModel::new(k, d, size).unwrap())
    .collect()
}

fn stereo_pair(kind: usize) -> StereoPair {
    let cams = cameras();
    let mut right = cams[kind];
    right.intrinsics.fx_px += 3.7;
    right.intrinsics.cx_px -= 15.3;
    let r = nalgebra::Rotation3::new(Vector3::new(0.0061, -0.0082, -0.0034)).into_inner();
    StereoPair::new(cams[kind], right, r, Vector3::new(-0.0832, 0.0011 / 3.0, 0.0005)).unwrap()
}

#[test]
fn opencv_stereo_yaml_round_trips_exactly() {
    for kind in [0, 1, 2] {
        let pair = stereo_pair(kind);
        let text = to_opencv_stereo_yaml(&pair).unwrap();
        for key in ["M1:", "D1:", "M2:", "D2:", "R:", "T:", "E:", "F:", "R1:", "R2:", "P1:", "P2:", "Q:"] {
            assert!(text.lines().any(|l| l.starts_with(key)), "{key} missing:\n{text}");
        }
        let back = from_opencv_stereo_yaml(&text).unwrap();
        assert_eq!(back, pair, "{text}");
        // Without the rectification the reader computes the same one.
        let cut = text.find("R1:").unwrap();
        assert_eq!(from_opencv_stereo_yaml(&text[..cut]).unwrap(), pair);
    }
    // T in millimetres (as OpenCV's stereoCalibrate gives it with the board in mm).
    let pair = stereo_pair(1);
    let text = to_opencv_stereo_yaml(&pair).unwrap();
    let t_line = text.lines().skip_while(|l| !l.starts_with("T:")).nth(4).unwrap().to_string();
    let mm: Vec<String> = pair.t_m.iter().map(|v| fmt_f64(v * 1e3)).collect();
    let text_mm = text[..text.find("R1:").unwrap()]
        .replace(&t_line, &format!("   data: [ {} ]", mm.join(", ")))
        .replace("translation_unit: m", "translation_unit: mm");
    let back = from_opencv_stereo_yaml(&text_mm).unwrap();
    assert!((back.t_m - pair.t_m).norm() < 1e-15);
    assert!((back.rectification.p2 - pair.rectification.p2).norm() < 1e-12);
    let bad = text.replace("translation_unit: m", "translation_unit: furlong");
    assert!(from_opencv_stereo_yaml(&bad).unwrap_err().to_string().contains("furlong"));
}

#[test]
fn ros_stereo_yaml_round_trips_exactly_with_the_rectification() {
    let pair = stereo_pair(1);
    let (l, r) = to_ros_stereo_yaml(&pair, "stereo/left", "stereo/right").unwrap();
    let li = from_ros_camera_info(&l).unwrap();
    let ri = from_ros_camera_info(&r).unwrap();
    assert_eq!((li.camera, li.name.as_str()), (pair.left, "stereo/left"));
    assert_eq!((ri.camera, ri.name.as_str()), (pair.right, "stereo/right"));
    assert_eq!(li.rectification, pair.rectification.r1);
    assert_eq!(ri.rectification, pair.rectification.r2);
    assert_eq!(li.projection, pair.rectification.p1);
    assert_eq!(ri.projection, pair.rectification.p2);
    // ROS: P2[0][3] = -fx' B, B in metres.
    let b = pair.rectification.baseline();
    assert!((b - pair.t_m.norm()).abs() < 1e-15);
    assert!((ri.projection[(0, 3)] + ri.projection[(0, 0)] * b).abs() < 1e-12);
    // A mono file reads with identity and [K | 0].
    let mono = from_ros_camera_info(&to_ros_yaml(&pair.left, "left").unwrap()).unwrap();
    assert_eq!(mono.rectification, Matrix3::identity());
    assert_eq!(mono.projection[(0, 2)], pair.left.intrinsics.cx_px);
}

#[test]
fn stereo_files_round_trip_and_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let pair = stereo_pair(1);
    let p = dir.path().join("stereo.yml");
    write_opencv_stereo_yaml(&pair, &p).unwrap();
    assert_eq!(read_opencv_stereo_yaml(&p).unwrap(), pair);
    let text = std::fs::read_to_string(&p).unwrap().replace("   rows: 3\n   cols: 1\n", "   rows: 2\n   cols: 1\n");
    std::fs::write(&p, text).unwrap();
    let err = read_opencv_stereo_yaml(&p).unwrap_err().to_string();
    assert!(err.contains("stereo.yml") && err.contains("'T'"), "{err}");
    let err = read_ros_camera_info(&dir.path().join("none.yaml")).unwrap_err().to_string();
    assert!(err.contains("none.yaml"), "{err}");
}

#[test]
fn opencv_yaml_round_trips_exactly() {
    for cam in cameras() {
        let text = to_opencv_yaml(&cam).unwrap();
        let back = from_opencv_yaml(&text).unwrap();
        assert_eq!(back, cam, "{text}");
    }
}

#[test]
fn ros_yaml_round_trips_exactly() {
    for (i, cam) in cameras().into_iter().enumerate() {
        let name = if i == 0 { "narrow_stereo/left" } else { "cam \"1\"" };
        let text = to_ros_yaml(&cam, name).unwrap();
        let (back, back_name) = from_ros_yaml(&text).unwrap();
        assert_eq!(back, cam, "{text}");
        assert_eq!(back_name, name);
    }
}

#[test]
fn files_round_trip_and_io_errors_name_the_file() {
    let dir = std::env::temp_dir().join(format!("ferrocal-camera-io-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cam = cameras()[1];
    let p = dir.join("left.yml");
    write_opencv_yaml(&cam, &p).unwrap();
    assert_eq!(read_opencv_yaml(&p).unwrap(), cam);
    let q = dir.join("left_ros.yaml");
    write_ros_yaml(&cam, "left", &q).unwrap();
    assert_eq!(read_ros_yaml(&q).unwrap(), (cam, "left".to_string()));
    let missing = dir.join("missing.yml");
    let err = read_opencv_yaml(&missing).unwrap_err();
    assert!(err.to_string().contains("missing.yml"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A file in the layout OpenCV's `FileStorage` writes (OpenCV's number style, 5x1 and 1x5
/// vectors, no ferrocal keys).
#[test]
fn reads_opencv_style_files() {
    let text = "%YAML:1.0\n---\ncalibration_time: \"Mon Jan  1 00:00:00 2024\"\nimage_width: 640\nimage_height: 480\nflags: 0\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 5.3591573396163199e+02, 0., 3.4228315473308373e+02, 0.,\n       5.3591573396163199e+02, 2.3557082909788173e+02, 0., 0., 1. ]\ndistortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: [ -2.6637260909660682e-01, -3.8588898922304653e-02,\n       1.7831947042852964e-03, -2.8122100441115472e-04,\n       2.3839153080878486e-01 ]\navg_reprojection_error: 3.9e-01\n";
    let cam = from_opencv_yaml(text).unwrap();
    let num = |s: &str| s.parse::<f64>().unwrap();
    assert_eq!(cam.intrinsics.fx_px, num("5.3591573396163199e+02"));
    assert_eq!(cam.intrinsics.cy_px, num("2.3557082909788173e+02"));
    assert_eq!(
        cam.distortion.coefficients(),
        [
            "-2.6637260909660682e-01",
            "-3.8588898922304653e-02",
            "1.7831947042852964e-03",
            "-2.8122100441115472e-04",
            "2.3839153080878486e-01"
        ]
        .map(num)
    );
    // Four coefficients: k1 k2 p1 p2, k3 = 0; with fisheye_model: 1, Kannala-Brandt.
    let four = text.replace("cols: 5", "cols: 4").replace(",\n       2.3839153080878486e-01 ]", " ]");
    assert_eq!(from_opencv_yaml(&four).unwrap().distortion.kind(), DistortionKind::Brown5);
    let fish = format!("{four}fisheye_model: 1\n");
    assert_eq!(from_opencv_yaml(&fish).unwrap().distortion.kind(), DistortionKind::KannalaBrandt);
}

#[test]
fn malformed_files_are_reported_with_line_numbers() {
    let good = to_opencv_yaml(&cameras()[1]).unwrap();
    let bad_count = good.replace("rows: 5", "rows: 6");
    let err = from_opencv_yaml(&bad_count).unwrap_err();
    assert!(matches!(err, VisionError::Parse { line, .. } if line > 0), "{err}");
    let bad_number = good.replace("0.23839", "abc");
    assert!(from_opencv_yaml(&bad_number).is_err());
    let missing = good.replace("image_width", "width");
    assert!(from_opencv_yaml(&missing).unwrap_err().to_string().contains("image_width"));
    let skew = good.replacen(", 0.0,", ", 0.5,", 1);
    assert!(from_opencv_yaml(&skew).is_err());
    let model = good.replace("plumb_bob", "unknown_model");
    assert!(matches!(from_opencv_yaml(&model).unwrap_err(), VisionError::UnsupportedDistortion { .. }));
}

/// One camera of a rig: the camera file with `R` and `T` (OpenCV's stereoCalibrate names)
/// reads back to the same numbers; the reference camera's file has neither and is a plain
/// camera file ([`from_opencv_yaml`] reads both).
#[test]
fn rig_camera_files_round_trip_with_r_and_t() {
    let cam = cameras()[1];
    let r = nalgebra::Rotation3::from_euler_angles(0.1, -0.4, 0.05).into_inner();
    let t = nalgebra::Vector3::new(-0.41, 0.02, 0.135);
    let text = to_opencv_rig_yaml(&cam, Some((&r, &t))).unwrap();
    let (back, ext) = from_opencv_rig_yaml(&text).unwrap();
    assert_eq!(back, cam);
    let (r2, t2) = ext.unwrap();
    assert_eq!((r2, t2), (r, t));
    assert_eq!(from_opencv_yaml(&text).unwrap(), cam);
    let mm = text.replace("translation_unit: m", "translation_unit: mm");
    assert!((from_opencv_rig_yaml(&mm).unwrap().1.unwrap().1 - t * 1e-3).norm() < 1e-15);
    let reference = to_opencv_rig_yaml(&cam, None).unwrap();
    assert_eq!(reference, to_opencv_yaml(&cam).unwrap());
    assert!(from_opencv_rig_yaml(&reference).unwrap().1.is_none());
}
