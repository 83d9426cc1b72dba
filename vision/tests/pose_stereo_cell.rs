//! Metric target poses from a calibrated stereo pair in a robot cell: two 5 MP cameras
//! (2448 x 2048 px, fx about 4640 px) 2.5 m from a 1 m workspace, 1 m apart. The pair is first
//! calibrated from simulated views of a large board (so calibration errors propagate into the
//! poses), then a smaller target is measured all over the workspace. Exact projections plus
//! Gaussian corner noise.

use crate::calib_support;

use calib_support::cell::{calibrate, measure, Cell};
use nalgebra::Isometry3;

#[test]
fn with_the_true_rig_target_positions_are_within_50_um_mean() {
    let cell = Cell::new();
    let rig = ferrocal_vision::pose::CameraRig {
        cameras: cell.cams.to_vec(),
        t_cam_cam0: vec![Isometry3::identity(), cell.t_cam_world(1) * cell.t_world_cam[0]],
        covariance: None,
    };
    let m = measure(&cell, &rig, 5, 60, 0.1);
    println!(
        "true rig, 0.1 px: mean {:.4} mm, max {:.4} mm, NEES {:.2}, predicted sigma {:.4} mm",
        m.mean_mm, m.max_mm, m.mean_nees, m.sigma_corners_mm
    );
    assert!(m.mean_mm < 0.05, "mean position error {} mm", m.mean_mm);
    assert!(m.mean_nees > 1.5 && m.mean_nees < 4.5, "mean NEES {}", m.mean_nees);
}

#[test]
fn calibrated_pair_measures_within_50_um_mean_up_to_the_camera_frame() {
    let cell = Cell::new();
    let sigma_px = 0.1;
    let st = calibrate(&cell, 21, 20, sigma_px);
    let t_true = cell.t_cam_world(1) * cell.t_world_cam[0];
    println!(
        "calibration (20 views, 0.1 px): baseline {:.4} +- {:.4} mm (true {:.4}), rms {:.4} px; fx0 {:.3} +- {:.3} (true {:.3}); \
         cx0 {:.3} +- {:.3} (true {:.3})",
        st.baseline_mm,
        st.baseline_std_mm,
        t_true.translation.vector.norm() * 1e3,
        st.calibration.rms_px,
        st.left().camera.intrinsics.fx_px,
        st.left().std[0],
        cell.cams[0].intrinsics.fx_px,
        st.left().camera.intrinsics.cx_px,
        st.left().std[2],
        cell.cams[0].intrinsics.cx_px,
    );
    let m = measure(&cell, &st.rig(), 77, 60, sigma_px);
    println!(
        "calibrated rig: absolute mean {:.4} mm (max {:.4}); after rigid alignment mean {:.4} mm (max {:.4}); \
         distance errors mean {:.4} mm; NEES {:.2}; predicted sigma corners {:.4} mm, with calibration {:.4} mm",
        m.mean_mm,
        m.max_mm,
        m.aligned_mean_mm,
        m.aligned_max_mm,
        m.distance_mean_mm,
        m.mean_nees,
        m.sigma_corners_mm,
        m.sigma_total_mm
    );
    // Up to the camera frame (which kinematic calibration identifies with the base frame), the
    // positions are within 50 um on average; so are the distances between them.
    assert!(m.aligned_mean_mm < 0.05, "aligned mean {} mm", m.aligned_mean_mm);
    assert!(m.distance_mean_mm < 0.05, "distance error mean {} mm", m.distance_mean_mm);
    // The absolute error is the calibration's uncertainty of the camera frame itself (principal
    // point, focal length: a shared rotation and scale of all positions), and the reported
    // covariance says so: normalised errors average about 3 (one draw of a shared error, so a
    // wide band).
    assert!(m.mean_mm < 1.0, "absolute mean {} mm", m.mean_mm);
    assert!(m.mean_nees < 12.0, "mean NEES {}", m.mean_nees);
    assert!(m.sigma_total_mm > 3.0 * m.sigma_corners_mm);
}

/// The rectification of a calibrated pair whose right camera numbered some boards from the
/// other end (as a chessboard detector may): the calibration finds those views reversed, and
/// `rectified_corners` pairs the corners through the same flip, so every corner lands on the
/// same rectified row up to the corner noise (0.1 px per coordinate: a row difference of about
/// 0.14 px RMS); pairing by the raw numbering would put them hundreds of pixels apart.
/// Simulated with the same pinhole + Brown model family that estimates it.
#[test]
fn rectified_rows_agree_with_reversed_corner_numbering() {
    use ferrocal_vision::calib::{calibrate_stereo, rectified_row_rms_px, CalibrationOptions, PlanarTarget};
    let cell = Cell::new();
    let board = PlanarTarget::chessboard(13, 9, 0.06);
    let n = board.points_m.len();
    let mut rng = calib_support::rng(11);
    let (mut left, mut right) = (Vec::new(), Vec::new());
    while left.len() < 8 {
        let p = calib_support::cell::random_in_cube(&mut rng, 0.4);
        let t = calib_support::cell::target_in_world(&mut rng, &board, p, (15.0, 40.0));
        let [a, mut b] = cell.observe(&mut rng, &format!("v{:02}", left.len()), &board, &t, 0.1);
        if a.corners_px.len() < 80 || b.corners_px.len() < 80 {
            continue;
        }
        if left.len() % 2 == 1 {
            b.point_ids = b.point_ids.iter().map(|i| n - 1 - i).collect();
        }
        left.push(Some(a));
        right.push(Some(b));
    }
    let st = calibrate_stereo(&left, &right, &board, &CalibrationOptions::default()).unwrap();
    assert_eq!(st.calibration.reversed_views.len(), 4, "{:?}", st.calibration.reversed_views);
    let pair = st.pair().unwrap();
    let corners = st.rectified_corners(&pair.rectification, &left, &right, &board);
    let rms = rectified_row_rms_px(&corners, pair.rectification.vertical());
    let truth = (cell.t_cam_world(1) * cell.t_world_cam[0]).translation.vector.norm();
    println!(
        "reversed numbering: {} corner pairs, row RMS {rms:.4} px; baseline {:.3} +- {:.3} mm (truth {:.3} mm)",
        corners.len(),
        st.baseline_mm,
        st.baseline_std_mm,
        truth * 1e3
    );
    assert!(corners.len() >= 8 * 80 && rms < 0.25, "row RMS {rms} px over {} pairs", corners.len());
    assert!((pair.rectification.baseline() - truth).abs() < 3.0 * st.baseline_std_mm * 1e-3 + 1e-6);
}
