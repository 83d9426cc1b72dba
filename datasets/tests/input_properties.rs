//! The bounded property-based pass over the public input readers (issue #16; the CI twin of the
//! fuzz targets in `tests/fuzz`): measurement table, URDF, model, plan and cell TOML, calibration
//! JSON, recordings (hand-eye poses table, camera files) and the checked image loader.
//!
//! - crash-free: arbitrary and mutated bytes give `Ok` or `Err`, never a panic;
//! - error-or-correct: a valid table with one cell replaced is read with exactly that value or
//!   refused naming that line and column; a calibration file written and read back is the same
//!   file and applies to the same parameter values (within 1e-14).
//!
//! Cases are kept small (64 to 128 per property) so the pass takes seconds. The inputs the
//! fuzzers found are kept at the end, as regression tests named after what they test.

use std::path::{Path, PathBuf};

use ferrocal_calib::file::CalibrationFile;
use ferrocal_calib::kinematic::CalibratedModel;
use ferrocal_datasets::formats::plan_file::PlanFile;
use ferrocal_datasets::handeye::poses::parse_handeye_poses;
use ferrocal_datasets::handeye::read_camera_file;
use ferrocal_datasets::import::parse_measurements;
use ferrocal_datasets::sim::CellConfig;
use ferrocal_robot::params::Parameterized;
use ferrocal_robot::serial::{parse_urdf_str, UrdfOptions};
use ferrocal_robot::RobotModel;
use proptest::prelude::*;

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel)
}

fn read(rel: &str) -> Vec<u8> {
    std::fs::read(repo(rel)).unwrap()
}

/// A valid table: six revolute joints (rad) and a position (mm), five rows.
const HEADER: [&str; 10] =
    ["pose_id", "q1_rad", "q2_rad", "q3_rad", "q4_rad", "q5_rad", "q6_rad", "x_mm", "y_mm", "z_mm"];

fn table_cells() -> Vec<Vec<String>> {
    (0..5)
        .map(|r| {
            let mut row = vec![format!("p{r}")];
            row.extend((0..6).map(|j| format!("{}", 0.1 * (r as f64) - 0.05 * (j as f64))));
            row.extend((0..3).map(|a| format!("{}", 400.0 + 10.0 * (r as f64) + (a as f64))));
            row
        })
        .collect()
}

fn table_text(cells: &[Vec<String>]) -> String {
    let mut s = HEADER.join(",");
    s.push('\n');
    for row in cells {
        s.push_str(&row.join(","));
        s.push('\n');
    }
    s
}

/// `bytes` with the byte at `at` (modulo the length) replaced by `with`, and `cut` bytes removed
/// after it.
fn mutate(bytes: &[u8], at: usize, with: u8, cut: usize) -> Vec<u8> {
    let mut b = bytes.to_vec();
    if b.is_empty() {
        return vec![with];
    }
    let i = at % b.len();
    b[i] = with;
    let end = (i + 1 + cut).min(b.len());
    b.drain(i + 1..end);
    b
}

/// A scratch file of this test process.
fn scratch(name: &str, bytes: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ferrocal-input-properties-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(format!("{:?}-{name}", std::thread::current().id()).replace(['(', ')'], ""));
    std::fs::write(&p, bytes).unwrap();
    p
}

/// A cell: a plain number, or text that may or may not be one.
fn cell_strategy() -> impl Strategy<Value = String> {
    prop_oneof![
        (-1.0e3..1.0e3f64).prop_map(|v| format!("{v}")),
        "[-+.eE0-9naif ]{0,10}",
        Just(String::new()),
        Just("1e400".to_string()),
        Just("NaN".to_string()),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn measurement_table_reader_is_crash_free(
        bytes in proptest::collection::vec(any::<u8>(), 0..300),
        at in any::<usize>(), with in any::<u8>(), cut in 0usize..20,
    ) {
        let _ = parse_measurements(&String::from_utf8_lossy(&bytes), "t.csv");
        let valid = table_text(&table_cells());
        let m = mutate(valid.as_bytes(), at, with, cut);
        let _ = parse_measurements(&String::from_utf8_lossy(&m), "t.csv");
    }

    #[test]
    fn measurement_table_cell_is_read_exactly_or_refused_by_line_and_column(
        row in 0usize..5, col in 1usize..10, cell in cell_strategy(),
    ) {
        let mut cells = table_cells();
        cells[row][col] = cell.clone();
        match parse_measurements(&table_text(&cells), "t.csv") {
            Ok(t) => {
                let v: f64 = cell.trim().parse().unwrap_or_else(|_| panic!("'{cell}' was read as a number"));
                let r = &t.set.rows[row];
                let got = if col <= 6 { r.q[col - 1] } else { r.position_m[col - 7] * 1e3 };
                prop_assert!((got - v).abs() <= 1e-12 * v.abs().max(1.0), "'{cell}' read as {got}");
            }
            Err(e) => {
                let msg = e.to_string();
                let line = row + 2;
                prop_assert!(
                    msg.contains(&format!("line {line}")) && msg.contains(&format!("'{}'", HEADER[col])),
                    "'{cell}' in line {line}, column {}: {msg}", HEADER[col]
                );
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn urdf_and_model_toml_readers_are_crash_free(at in any::<usize>(), with in any::<u8>(), cut in 0usize..40) {
        let urdf = mutate(&read("robot/models/example_arm6.urdf"), at, with, cut);
        let _ = parse_urdf_str(&String::from_utf8_lossy(&urdf), &UrdfOptions::default());
        for m in ["hexapod.toml", "gantry-tau-f1.toml", "gantry-tau-l1-6link.toml"] {
            let text = mutate(&read(&format!("robot/models/{m}")), at, with, cut);
            let _ = ferrocal_robot::parallel::file::parse_str(&String::from_utf8_lossy(&text), Path::new(m));
        }
    }

    #[test]
    fn plan_and_cell_readers_are_crash_free(at in any::<usize>(), with in any::<u8>(), cut in 0usize..40) {
        let plan = mutate(&read("datasets/cells/plan_gantry_tau_l1.toml"), at, with, cut);
        let _ = PlanFile::from_file(&scratch("plan.toml", &plan));
        let cell = mutate(&read("datasets/cells/gantry_tau_l1.toml"), at, with, cut);
        if let Ok(c) = CellConfig::from_toml_str(&String::from_utf8_lossy(&cell), Path::new("cell.toml")) {
            for cam in &c.cameras {
                let _ = cam.t_world_cam();
            }
        }
    }

    #[test]
    fn recording_readers_are_crash_free(at in any::<usize>(), with in any::<u8>(), cut in 0usize..20) {
        let poses = "# mount: eye-in-hand\nimage,x_mm,y_mm,z_mm,qw,qx,qy,qz,split\n\
                     0.png,100,200,300,1,0,0,0,train\n1.png,110,190,310,0.7071067811865476,0.7071067811865476,0,0,test\n";
        let m = mutate(poses.as_bytes(), at, with, cut);
        let _ = parse_handeye_poses(&String::from_utf8_lossy(&m), Path::new("poses.csv"));
        let cam = r#"{"image_size":[640,480],"fx":550.0,"fy":551.0,"cx":320.0,"cy":240.0,"model":"brown5","distortion":[0.1,-0.05,0.001,0.0005,0.01]}"#;
        let _ = read_camera_file(&scratch("camera.json", &mutate(cam.as_bytes(), at, with, cut)));
        let yaml = "image_width: 640\nimage_height: 480\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [550.0, 0.0, 320.0, 0.0, 550.0, 240.0, 0.0, 0.0, 1.0]\ndistortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0.1, -0.05, 0.0, 0.0, 0.0]\n";
        let _ = read_camera_file(&scratch("camera.yaml", &mutate(yaml.as_bytes(), at, with, cut)));
    }

    #[test]
    fn image_loader_is_crash_free(at in any::<usize>(), with in any::<u8>(), cut in 0usize..64, jpeg in any::<bool>()) {
        let img = image::GrayImage::from_fn(24, 16, |x, y| image::Luma([(x * 10 + y * 7) as u8]));
        let mut bytes = Vec::new();
        let format = if jpeg { image::ImageFormat::Jpeg } else { image::ImageFormat::Png };
        img.write_to(&mut std::io::Cursor::new(&mut bytes), format).unwrap();
        let path = scratch("image", &mutate(&bytes, at, with, cut));
        let _ = ferrocal_vision::detect::check_image_file(&path);
        if let Ok(g) = ferrocal_vision::detect::load_gray(&path) {
            prop_assert!(g.width() > 0 && g.height() > 0);
        }
    }

    #[test]
    fn calibration_file_written_and_read_is_the_same(
        scale in proptest::collection::vec(-1e-3..1e-3f64, 64), offsets in proptest::collection::vec(-0.01..0.01f64, 6),
    ) {
        let ur5 = RobotModel::load("ur5").unwrap();
        let mut cm = CalibratedModel::nominal(ur5.clone());
        let mut values = cm.model.parameter_values();
        for (v, s) in values.iter_mut().zip(scale.iter().cycle()) {
            *v += s;
        }
        cm.model.set_parameter_values(&values).unwrap();
        cm.joint_offsets = offsets;
        let file = CalibrationFile::new("ur5", &cm);
        let path = scratch("cal.json", serde_json::to_string_pretty(&file).unwrap().as_bytes());
        let back = CalibrationFile::read(&path).unwrap();
        prop_assert_eq!(&back, &file);
        let applied = back.apply(&ur5).unwrap();
        // The file is exact (above); applying it sets the model's frames from their angles, and
        // reading the angles back from a rotation may move them by an ulp: 1e-14 (rad or m).
        let diff = applied.model.parameter_values().iter().zip(cm.model.parameter_values()).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        prop_assert!(diff <= 1e-14, "applied parameters differ by {diff}");
        prop_assert_eq!(applied.joint_offsets, cm.joint_offsets);
        // and any mutation of the text is read or refused, never a panic
        let text = std::fs::read(&path).unwrap();
        let m = mutate(&text, (scale[0].to_bits() as usize) % text.len(), b'9', 3);
        if let Ok(f) = CalibrationFile::read(&scratch("cal-mutated.json", &m)) {
            let _ = f.apply(&ur5);
        }
    }
}

// Inputs the fuzzers found (tests/fuzz), inlined.

#[test]
fn header_naming_a_huge_joint_number_is_refused_without_allocating() {
    // measurements fuzz target: `q0000000000000004843587262305_m` made the reader reserve room
    // for 4.8e12 joints (a 77 TB allocation) before it found that q1 is missing.
    let text = "# \npose_id,q2_m,x_mm,y_mm,\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0osp _id,q0000000000000004843587262305_m";
    let err = parse_measurements(text, "t.csv").unwrap_err().to_string();
    assert!(err.contains("no q1"), "{err}");
    let err = parse_measurements("pose_id,q1_rad,q99999999999999_rad,x_m,y_m,z_m\n0,0,0,0,0,0\n", "t.csv")
        .unwrap_err()
        .to_string();
    assert!(err.contains("no q2"), "{err}");
}

#[test]
fn opencv_yaml_matrix_whose_rows_times_cols_overflows_is_refused() {
    // recording fuzz target: `rows: 777...773` (19 digits) times `cols: 3` overflowed usize (a panic in the
    // dev profile, a wrapped product in release).
    let text = "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n   \
                rows: 7777777777777777773\n   cols: 3\n   dt: d\n   \
                data: [ 550.0, 0.0, 320.0, 0.0, 550.0, 240.0, 0.0, 0.0, 1.0 ]\n";
    let err = ferrocal_vision::camera::io::from_opencv_yaml(text).unwrap_err().to_string();
    assert!(err.contains("camera_matrix"), "{err}");
    let path = scratch("overflow.yaml", text.replace("7777777777777777773", "6148914691236517206").as_bytes());
    let err = read_camera_file(&path).unwrap_err().to_string();
    assert!(err.contains("camera_matrix"), "{err}");
}
