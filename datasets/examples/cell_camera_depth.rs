//! The cell camera's depth error on still frames (no motion blur): the board displaced in depth
//! (and sideways) from its tare, each position the mean of a few noise seeds, for the reduced and
//! the default camera. Measures whether the camera-in-the-loop learning's depth remainder is a
//! scale error (proportional to the travel) or depends on the position.
//!
//! `cargo run --release -p ferrocal-datasets --example cell_camera_depth [-- --frames N]`

use ferrocal_datasets::motion::cell_tracking::reduced_camera;
use ferrocal_datasets::motion::tracking::{Tracker, TrackingSettings};
use nalgebra::Vector3;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let frames: u64 = match args.iter().position(|a| a == "--frames") {
        Some(i) => args.get(i + 1).ok_or("--frames needs a number")?.parse()?,
        None => 6,
    };
    if frames == 0 {
        return Err("--frames must be at least 1".into());
    }
    println!("camera   depth_mm  side_mm  measured_depth_mm  depth_error_um  lateral_error_um");
    for (name, s) in [("reduced", reduced_camera()), ("default", TrackingSettings::default())] {
        let t = Tracker::new(&s)?;
        let mean_at = |d: Vector3<f64>, seed0: u64| -> Result<Vector3<f64>, Box<dyn std::error::Error>> {
            let mut p = Vector3::zeros();
            for i in 0..frames {
                p += t.measure(&t.expose_3d(&[d], seed0 + i)?)?.0 / frames as f64;
            }
            Ok(p)
        };
        let p0 = mean_at(Vector3::zeros(), 100)?;
        for dz_m in [-0.02, -0.01, 0.01, 0.02] {
            for dx_m in [0.0, 0.02] {
                let d = mean_at(Vector3::new(dx_m, 0.0, dz_m), 200)? - p0;
                println!(
                    "{name:8} {:+8.1} {:8.1} {:+18.4} {:+15.1} {:+17.1}",
                    1e3 * dz_m,
                    1e3 * dx_m,
                    1e3 * d.z,
                    1e6 * (d.z - dz_m),
                    1e6 * (d.x - dx_m)
                );
            }
        }
    }
    Ok(())
}
