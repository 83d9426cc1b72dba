//! Studies of ferrocal's camera calibration on simulated data (exact projections plus Gaussian
//! corner noise), more seeds than the tests run:
//!
//! 1. coverage: how often the true intrinsics lie within 1, 2 and 3 reported sigmas (expected
//!    68.3, 95.4, 99.7 %), per parameter, for the VGA camera of the tests (12 views, 0.2 px);
//! 2. the stereo cell: two 5 MP cameras 2.5 m from a 1 m workspace, calibrated from 20 views of
//!    a large board, then 60 target poses measured: absolute error in cam0, error after rigid
//!    alignment, distance errors, and the covariance's consistency (NEES).
//!
//! `cargo run -p ferrocal-datasets --example vision_calibration_study -- [coverage seeds] [cell seeds]`
//! (defaults 200 and 10).

#[path = "../../vision/tests/calib_support/mod.rs"]
mod calib_support;

use calib_support as sim;
use ferrocal_vision::calib::{calibrate_camera, CalibrationOptions, PlanarTarget};

fn coverage(label: &str, options: &CalibrationOptions, fix: bool, seeds: u64) {
    let mut camera = sim::vga_camera();
    if fix {
        camera.intrinsics.fy_px = camera.intrinsics.fx_px;
    }
    let board = PlanarTarget::chessboard(9, 6, 0.025);
    let truth: Vec<f64> = camera.parameters().iter().map(|p| p.value).collect();
    let mut within = vec![[0usize; 3]; truth.len()];
    for seed in 0..seeds {
        let mut rng = sim::rng(50_000 + seed);
        let views = sim::calibration_views(&mut rng, &camera, &board, 12, (0.25, 0.6), 0.2);
        let cal = calibrate_camera(&views, &board, options).unwrap();
        for (i, p) in cal.camera.parameters().iter().enumerate() {
            let z = (p.value - truth[i]).abs() / cal.std[i];
            for (k, w) in within[i].iter_mut().enumerate() {
                if z <= (k + 1) as f64 {
                    *w += 1;
                }
            }
        }
    }
    println!("coverage, {label}, {seeds} seeds (expected 68.3 / 95.4 / 99.7 %):");
    for (p, w) in camera.parameters().iter().zip(&within) {
        let pct = |k: usize| 100.0 * w[k] as f64 / seeds as f64;
        println!("  {:>6}: {:5.1} {:5.1} {:5.1} %", p.name, pct(0), pct(1), pct(2));
    }
}

fn main() {
    let args: Vec<u64> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let seeds = args.first().copied().unwrap_or(200);
    let cell_seeds = args.get(1).copied().unwrap_or(10);
    coverage("Brown 5, free aspect", &CalibrationOptions::default(), false, seeds);
    coverage("Brown 5, fx = fy", &CalibrationOptions { fix_aspect: true, ..Default::default() }, true, seeds);

    println!("stereo cell (2 x 5 MP, 2.5 m, 1 m workspace, 0.1 px corners, 20 calibration views, 60 poses):");
    println!(
        "  seed  baseline err  |  abs mean  abs max  | aligned mean  max | dist mean | NEES | sigma corners / total"
    );
    let cell = sim::cell::Cell::new();
    let t_true = cell.t_cam_world(1) * cell.t_world_cam[0];
    let (mut abs, mut ali, mut nees) = (Vec::new(), Vec::new(), Vec::new());
    for seed in 0..cell_seeds {
        let st = sim::cell::calibrate(&cell, 1000 + seed, 20, 0.1);
        let m = sim::cell::measure(&cell, &st.rig(), 2000 + seed, 60, 0.1);
        println!(
            "  {seed:4}  {:+.4} mm    |  {:.4}   {:.4}  |   {:.4}   {:.4} |  {:.4}   | {:.2} | {:.4} / {:.4} mm",
            st.baseline_mm - t_true.translation.vector.norm() * 1e3,
            m.mean_mm,
            m.max_mm,
            m.aligned_mean_mm,
            m.aligned_max_mm,
            m.distance_mean_mm,
            m.mean_nees,
            m.sigma_corners_mm,
            m.sigma_total_mm
        );
        abs.push(m.mean_mm);
        ali.push(m.aligned_mean_mm);
        nees.push(m.mean_nees);
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    println!(
        "  over {cell_seeds} calibrations: absolute mean error {:.4} mm, after rigid alignment {:.4} mm, mean NEES {:.2} (3 expected)",
        mean(&abs),
        mean(&ali),
        mean(&nees)
    );
}
