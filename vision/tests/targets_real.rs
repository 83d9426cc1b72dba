//! ChArUco boards and circle grids on real recordings: the ROS-Industrial
//! industrial_calibration example data, Apache-2.0 (`../shared/data/industrial_calibration`).
//!
//! - `test_set_charuco`: 16 images 1600 x 1200 of a 5 x 7 ChArUco board (36.195 mm squares,
//!   18.256 mm markers, DICT_6X6_250) seen by a fixed AVT Mako camera; the source gives the
//!   camera's calibrated intrinsics (fx 1352.0, fy 1356.1, cx 789.7, cy 627.3, no distortion).
//! - `test_set_10x10`: 15 images 640 x 480 of a modified 10 x 10 circle grid (25.4 mm between
//!   centres in the source's configuration; the label printed on the target reads "20 mm
//!   between dots, small dot 10 mm, big dot 20 mm diameter") from a Kinect on the wrist.
//!
//! Our side is asserted; OpenCV's side (`interpolateCornersCharuco`, `findCirclesGrid`) is
//! printed beside it ([`compare_with_opencv`]).

use std::path::PathBuf;

use ferrocal_vision::calib::compare::compare_with_opencv;
use ferrocal_vision::calib::corners::{detect_pattern_views, CornerMethod};
use ferrocal_vision::calib::{calibrate_pattern, CalibrationOptions, CalibrationPattern as Pattern};
use ferrocal_vision::detect::aruco::{detect_markers, ArucoDictionary, MarkerParams};
use ferrocal_vision::detect::{detect, load_gray, DetectOptions, Pattern as DetectPattern};
use ferrocal_vision::pose::homography::homography_dlt;
use nalgebra::{Point2, Vector3};

const CHARUCO: &str = "charuco:5x7:36.195mm:18.256mm:DICT_6X6_250";
const GRID: &str = "circlegrid:10x10:25.4mm:modified";

/// The images of a set, sorted by number; a missing folder fails the test by name.
fn images(set: &str) -> Vec<PathBuf> {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/industrial_calibration"))
        .join(set)
        .join("images");
    assert!(dir.is_dir(), "{} is missing: ../shared/data must be beside the checkout", dir.display());
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
    v.sort_by_key(|p| p.file_stem().and_then(|s| s.to_str()).and_then(|s| s.parse::<u32>().ok()));
    v
}

#[test]
fn charuco_set_every_image_gives_corners_with_ids_and_calibrates() {
    let paths = images("test_set_charuco");
    assert_eq!(paths.len(), 16);
    let pattern = Pattern::parse(CHARUCO).unwrap();
    let found = detect_pattern_views(&paths, &pattern, CornerMethod::Own);
    assert!(found.skipped.is_empty(), "{:?}", found.skipped);
    let mut total = 0;
    for (p, v) in paths.iter().zip(&found.slots) {
        let v = v.as_ref().unwrap_or_else(|| panic!("{}: no view", p.display()));
        let mut ids = v.point_ids.clone();
        ids.sort();
        ids.dedup();
        assert_eq!(ids.len(), v.point_ids.len(), "{}: an id twice", p.display());
        assert!(ids.iter().all(|&i| i < 24), "{}: ids {ids:?}", p.display());
        assert!(v.corners_px.len() >= 10, "{}: {} corners", p.display(), v.corners_px.len());
        total += v.corners_px.len();
    }
    let views: Vec<_> = found.slots.into_iter().flatten().collect();
    let cal = calibrate_pattern(&views, &pattern, None, &CalibrationOptions::default()).unwrap().calibration;
    let k = cal.camera.intrinsics;
    println!(
        "ferrocal: {total} corners in 16 images; RMS {:.4} px; fx {:.1} fy {:.1} cx {:.1} cy {:.1} (std {:.1?}); distortion {:.4?} (std {:.4?})",
        cal.rms_px,
        k.fx_px,
        k.fy_px,
        k.cx_px,
        k.cy_px,
        &cal.std[..4],
        cal.camera.distortion.coefficients(),
        &cal.std[4..]
    );
    assert!(total >= 360, "{total} of 384 corners");
    assert!(cal.rms_px < 0.75, "RMS {:.4} px (the source's threshold is 1.5 px)", cal.rms_px);
    // The source's calibrated intrinsics, in units of our standard deviations.
    let source = [1352.02747, 1356.14287, 789.67065, 627.2995];
    let ours = [k.fx_px, k.fy_px, k.cx_px, k.cy_px];
    for (i, name) in ["fx", "fy", "cx", "cy"].iter().enumerate() {
        let z = (ours[i] - source[i]) / cal.std[i];
        println!("{name}: ours {:.1} +- {:.1}, source {:.1}: {:+.1} sigma", ours[i], cal.std[i], source[i], z);
        assert!(z.abs() < 5.0, "{name}: {z:+.1} sigma from the source's value");
    }
    // Markers decoded with OpenCV's default detector parameters and with ferrocal's.
    let dict = ArucoDictionary::Dict6x6_250;
    let (mut n_cv, mut n_ours) = (0, 0);
    for p in &paths {
        let img = load_gray(p).unwrap();
        n_cv += detect_markers(&img, dict, MarkerParams::OpenCv).unwrap().iter().filter(|m| m.id < 17).count();
        n_ours += detect_markers(&img, dict, MarkerParams::Tolerant).unwrap().iter().filter(|m| m.id < 17).count();
    }
    println!("markers decoded: {n_ours} of 272 with ferrocal's parameters, {n_cv} with OpenCV's defaults");
    assert!(n_ours >= n_cv);
    println!("{}", compare_with_opencv(&paths, &pattern, &CalibrationOptions::default()).unwrap());
}

#[test]
fn charuco_markers_coarse_to_fine_keep_every_marker_of_the_full_resolution_pass() {
    use ferrocal_vision::detect::charuco::{board_markers, CharucoOptions};
    let DetectPattern::Charuco(board) = CHARUCO.parse().unwrap() else { unreachable!() };
    let paths = images("test_set_charuco");
    // 2: a tilted board, markers missed at half resolution; 7: one marker only the windows decode.
    for k in [2, 7] {
        let img = load_gray(&paths[k]).unwrap();
        let ids = |m: &[ferrocal_vision::detect::aruco::Marker]| {
            let mut v: Vec<u32> = m.iter().map(|m| m.id).filter(|&i| i < board.n_markers()).collect();
            v.sort();
            v
        };
        let full = ids(&detect_markers(&img, board.dictionary, MarkerParams::Tolerant).unwrap());
        let (found, windows) = board_markers(&img, &board, &CharucoOptions::default()).unwrap();
        let fine = ids(&found);
        println!("{k}.png: full resolution {full:?}, coarse to fine {fine:?} ({windows} windows)");
        assert!(full.iter().all(|i| fine.contains(i)), "{k}.png: full {full:?}, coarse to fine {fine:?}");
        let mut dedup = fine.clone();
        dedup.dedup();
        assert_eq!(dedup, fine, "{k}.png: an id twice");
    }
}

/// Counts the dark pixels within `r` px of `c` (darker than the mean of the square around).
fn dark_area(img: &image::GrayImage, c: Point2<f64>, r: f64) -> usize {
    let (x0, x1) = ((c.x - r).floor().max(0.0) as u32, ((c.x + r).ceil() as u32).min(img.width() - 1));
    let (y0, y1) = ((c.y - r).floor().max(0.0) as u32, ((c.y + r).ceil() as u32).min(img.height() - 1));
    let px: Vec<(u32, u32, f64)> = (y0..=y1)
        .flat_map(|y| (x0..=x1).map(move |x| (x, y)))
        .map(|(x, y)| (x, y, f64::from(img.get_pixel(x, y)[0])))
        .collect();
    let mean = px.iter().map(|p| p.2).sum::<f64>() / px.len() as f64;
    px.iter().filter(|p| (f64::from(p.0) - c.x).hypot(f64::from(p.1) - c.y) <= r && p.2 < mean).count()
}

#[test]
fn circle_grid_set_every_image_gives_100_centres_in_order() {
    let paths = images("test_set_10x10");
    assert_eq!(paths.len(), 15);
    let pattern: DetectPattern = GRID.parse().unwrap();
    let DetectPattern::CircleGrid(grid) = pattern else { unreachable!() };
    let points = grid.target_points_m();
    let mut ratios = Vec::new();
    for p in &paths {
        let img = load_gray(p).unwrap();
        let d =
            detect(&img, &pattern, &DetectOptions::default(), None).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        let d = &d[0];
        assert_eq!(d.corners.len(), 100, "{}", p.display());
        let ids: Vec<u32> = d.corners.iter().map(|c| c.point_id.unwrap()).collect();
        assert_eq!(ids, (0..100).collect::<Vec<u32>>());
        // The order against geometry: one homography maps the target's lattice onto all 100
        // centres (a wrong order leaves residuals of whole spacings; lens distortion a few px).
        let src: Vec<Point2<f64>> = points.iter().map(|q| Point2::new(q.x, q.y)).collect();
        let dst = d.corners_px();
        let h = homography_dlt(&src, &dst).unwrap();
        let res: Vec<f64> = src
            .iter()
            .zip(&dst)
            .map(|(s, t)| {
                let q = h * Vector3::new(s.x, s.y, 1.0);
                (Point2::new(q.x / q.z, q.y / q.z) - t).norm()
            })
            .collect();
        let worst = res.iter().copied().fold(0.0, f64::max);
        let spacing = (dst[1] - dst[0]).norm();
        // The large dot is dot 0: by far the most dark pixels around any centre.
        let areas: Vec<usize> = dst.iter().map(|c| dark_area(&img, *c, 0.45 * spacing)).collect();
        let mut sorted = areas.clone();
        sorted.sort();
        let median = sorted[50];
        println!(
            "{}: homography residual max {worst:.3} px (spacing {spacing:.1} px); dark area dot 0 {} px, median {median} px; radii {:.2?} mm",
            p.display(),
            areas[0],
            d.circle_radii_m.unwrap().map(|r| r * 1e3)
        );
        assert!(worst < 0.25 * spacing, "{}: homography residual {worst:.2} px", p.display());
        assert!(
            areas[0] == sorted[99] && areas[0] as f64 > 1.8 * median as f64,
            "{}: dot 0 is not the large dot",
            p.display()
        );
        let r = d.circle_radii_m.unwrap();
        ratios.push([r[0] / (grid.spacing_mm * 1e-3), r[1] / (grid.spacing_mm * 1e-3)]);
    }
    let med = |k: usize| {
        let mut v: Vec<f64> = ratios.iter().map(|r| r[k]).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    println!(
        "dot radius / spacing as imaged: small {:.3}, large {:.3}; the printed label (10 and 20 mm dots, 20 mm apart) \
         gives 0.250 and 0.500; 10 and 20 mm dots 25.4 mm apart would give 0.197 and 0.394",
        med(0),
        med(1)
    );
    let cal_pattern = Pattern::parse(GRID).unwrap();
    let found = detect_pattern_views(&paths, &cal_pattern, CornerMethod::Own);
    let views: Vec<_> = found.slots.into_iter().flatten().collect();
    assert_eq!(views.len(), 15);
    let pc = calibrate_pattern(&views, &cal_pattern, found.circle_radii_m, &CalibrationOptions::default()).unwrap();
    let cal = &pc.calibration;
    let k = cal.camera.intrinsics;
    println!(
        "ferrocal: RMS {:.4} px; fx {:.1} fy {:.1} cx {:.1} cy {:.1} (std {:.1?}); distortion {:.4?}",
        cal.rms_px,
        k.fx_px,
        k.fy_px,
        k.cx_px,
        k.cy_px,
        &cal.std[..4],
        cal.camera.distortion.coefficients()
    );
    let bias = pc.circle_bias.as_ref().unwrap();
    println!("{bias}");
    assert!(cal.rms_px < 0.5, "RMS {:.4} px (the source's threshold is 1.5 px)", cal.rms_px);
    println!("{}", compare_with_opencv(&paths, &cal_pattern, &CalibrationOptions::default()).unwrap());
}
