//! Bad images in a calibration batch: each is reported with a clear reason and the batch goes
//! on (unreadable, empty, pattern not found, different image size, missing file); too few usable
//! views is an error that says how many were usable.

use std::path::{Path, PathBuf};

use ferrocal_vision::calib::corners::{
    chessboard_corners_opencv, detect_view_slots, detect_views, CornerMethod, SubpixWindow,
};
use ferrocal_vision::calib::{calibrate_camera, CalibrationOptions, CalibrationPattern, PlanarTarget};
use ferrocal_vision::detect::Pattern;
use ferrocal_vision::VisionError;

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/opencv_stereo/");

/// The data folder; CI always has `../shared` beside the checkout, so a missing folder fails
/// the test (naming the path) instead of passing it unseen.
fn data_dir() -> &'static Path {
    let p = Path::new(DATA);
    assert!(p.is_dir(), "{DATA} is missing: these tests need ../shared/data/opencv_stereo beside the checkout");
    p
}

fn left(i: u32) -> PathBuf {
    data_dir().join(format!("left{i:02}.jpg"))
}

/// A temporary folder with one file of each kind of bad image (none copied from the data set:
/// the larger image is drawn by pasting a data image into a bigger canvas in the temp folder).
fn bad_images(dir: &Path) -> Vec<PathBuf> {
    let empty = dir.join("empty.jpg");
    std::fs::write(&empty, b"").unwrap();
    let corrupt = dir.join("corrupt.jpg");
    std::fs::write(&corrupt, b"this is not a JPEG").unwrap();
    let blank = dir.join("blank.png");
    image::GrayImage::from_pixel(640, 480, image::Luma([128])).save(&blank).unwrap();
    let big = dir.join("big.png");
    let src = image::open(left(6)).unwrap().to_luma8();
    let mut canvas = image::GrayImage::from_pixel(800, 600, image::Luma([200]));
    image::imageops::replace(&mut canvas, &src, 80, 60);
    canvas.save(&big).unwrap();
    vec![empty, corrupt, blank, big, dir.join("missing.jpg")]
}

#[test]
fn every_bad_image_is_reported_and_the_batch_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = "chessboard:9x6:25mm".parse::<Pattern>().unwrap();
    let mut paths: Vec<PathBuf> = (1..=5).map(left).collect();
    paths.extend(bad_images(dir.path()));
    let (slots, skipped) = detect_view_slots(
        &paths,
        &CalibrationPattern::of(&pattern).unwrap(),
        CornerMethod::OpenCv(SubpixWindow::OpenCv),
    );
    assert_eq!(slots.len(), paths.len());
    assert_eq!(slots.iter().flatten().count(), 5);
    let reason = |name: &str| {
        skipped
            .iter()
            .find(|s| s.image.file_name().unwrap() == name)
            .unwrap_or_else(|| panic!("{name} not reported: {skipped:?}"))
            .reason
            .clone()
    };
    assert!(reason("empty.jpg").contains("empty file"), "{}", reason("empty.jpg"));
    assert!(reason("corrupt.jpg").contains("cannot decode"), "{}", reason("corrupt.jpg"));
    assert!(reason("blank.png").contains("not found"), "{}", reason("blank.png"));
    assert!(reason("big.png").contains("800x600") && reason("big.png").contains("640x480"), "{}", reason("big.png"));
    assert!(reason("missing.jpg").contains("cannot open"), "{}", reason("missing.jpg"));
    // Each message names its image.
    for s in &skipped {
        assert!(s.to_string().contains(&*s.image.to_string_lossy()));
    }
    // The batch goes on: the usable views calibrate.
    let views: Vec<_> = slots.into_iter().flatten().collect();
    let opts = CalibrationOptions { fix_aspect: true, ..Default::default() };
    let cal = calibrate_camera(&views, &PlanarTarget::of_pattern(&pattern).unwrap(), &opts).unwrap();
    assert!(cal.rms_px < 0.6, "rms {}", cal.rms_px);
    // The larger image alone is a fine view of the board.
    let c = chessboard_corners_opencv(&dir.path().join("big.png"), 9, 6).unwrap();
    assert_eq!((c.image_size.width_px, c.image_size.height_px), (800, 600));
}

#[test]
fn too_few_usable_views_is_an_error_that_counts_them() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = "chessboard:9x6:25mm".parse::<Pattern>().unwrap();
    let mut paths = vec![left(1), left(3)];
    paths.extend(bad_images(dir.path()));
    let (views, skipped) =
        detect_views(&paths, &CalibrationPattern::of(&pattern).unwrap(), CornerMethod::OpenCv(SubpixWindow::Adaptive));
    assert_eq!(views.len(), 2);
    assert_eq!(skipped.len(), 5);
    let e = calibrate_camera(&views, &PlanarTarget::of_pattern(&pattern).unwrap(), &CalibrationOptions::default())
        .unwrap_err();
    assert!(matches!(e, VisionError::TooFewViews { usable: 2, needed: 3, .. }), "{e}");
    assert!(e.to_string().starts_with("2 usable view(s), at least 3 needed"), "{e}");
}

#[test]
fn a_wrong_pattern_size_is_not_found_in_any_image() {
    let e = chessboard_corners_opencv(&left(1), 8, 6).unwrap_err();
    assert!(matches!(e, VisionError::ImageUnusable { .. }));
    assert!(e.to_string().contains("left01.jpg") && e.to_string().contains("8x6"), "{e}");
}
