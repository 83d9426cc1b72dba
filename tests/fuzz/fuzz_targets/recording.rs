//! Recording manifests: the hand-eye pose table (`handeye --poses`), a simulated session's
//! `manifest.json` with its `joints.csv`, and a camera file (`--camera`: JSON, OpenCV or ROS
//! YAML). The first byte chooses the reader; any rest gives Ok or an error.
#![no_main]

use std::path::Path;

use ferrocal_datasets::handeye::poses::parse_handeye_poses;
use ferrocal_datasets::handeye::read_camera_file;
use ferrocal_datasets::measure::{read_session_joints, target_points};
use ferrocal_datasets::sim::SessionManifest;
use libfuzzer_sys::fuzz_target;

mod common;

fuzz_target!(|data: &[u8]| {
    let Some((&which, rest)) = data.split_first() else { return };
    match which % 4 {
        0 => {
            let Ok(text) = std::str::from_utf8(rest) else { return };
            let _ = parse_handeye_poses(text, Path::new("poses.csv"));
        }
        1 => {
            // manifest, a line `----`, then joints.csv
            let Ok(text) = std::str::from_utf8(rest) else { return };
            let (manifest, joints) = text.split_once("\n----\n").unwrap_or((text, ""));
            let Ok(mut m) = serde_json::from_str::<SessionManifest>(manifest) else { return };
            let _ = target_points(&m);
            let path = common::temp_file("joints.csv", joints.as_bytes());
            m.joints = "joints.csv".into();
            let _ = read_session_joints(path.parent().expect("folder"), &m);
        }
        2 => {
            let path = common::temp_file("camera.json", rest);
            let _ = read_camera_file(&path);
        }
        _ => {
            let path = common::temp_file("camera.yaml", rest);
            let _ = read_camera_file(&path);
        }
    }
});
