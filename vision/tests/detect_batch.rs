//! Bad input in a batch: every image gets its own result, failures carry a clear message, the
//! batch goes on; a pattern string that does not parse says what is expected.

use crate::synth;

use ferrocal_vision::detect::{DetectOptions, Detector, ImageResult, Pattern};

#[test]
fn bad_images_are_reported_per_image_and_the_batch_continues() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("board.png");
    synth::render(&synth::chessboard_scene(640, 480, 7, 5, 40.0, 2, 1.0, 1.0)).save(&good).unwrap();
    let empty = dir.path().join("empty.png");
    std::fs::write(&empty, b"").unwrap();
    let corrupt = dir.path().join("corrupt.jpg");
    std::fs::write(&corrupt, b"\xff\xd8\xff\xe0 this is not really a JPEG").unwrap();
    let blank = dir.path().join("blank.png");
    image::GrayImage::from_pixel(320, 240, image::Luma([128])).save(&blank).unwrap();
    let missing = dir.path().join("missing.png");
    let pattern: Pattern = "chessboard:7x5:25mm".parse().unwrap();
    let mut det = Detector::new(pattern, DetectOptions::default(), None).unwrap();
    let results: Vec<ImageResult> =
        [&empty, &good, &corrupt, &blank, &missing].iter().map(|p| det.detect_file(p)).collect();
    for r in &results {
        println!("{}: {} detections, error: {:?}", r.image, r.detections.len(), r.error);
    }
    let err = |k: usize| results[k].error.clone().unwrap_or_default();
    assert!(err(0).contains("empty.png") && err(0).contains("empty"), "{}", err(0));
    assert!(results[1].error.is_none());
    assert_eq!(results[1].detections.len(), 1);
    assert_eq!(results[1].detections[0].corners_px.len(), 35);
    assert!(results[1].detections[0].id.is_none());
    assert!(err(2).contains("corrupt.jpg") && err(2).contains("decode"), "{}", err(2));
    assert!(err(3).contains("not found"), "{}", err(3));
    assert!(err(4).contains("missing.png"), "{}", err(4));
    // The JSON of the contract: image, detections with id and corners_px, error only on failure.
    let json = serde_json::to_value(&results).unwrap();
    assert!(json[1].get("error").is_none());
    assert!(json[1]["detections"][0]["id"].is_null());
    assert_eq!(json[1]["detections"][0]["corners_px"][0].as_array().unwrap().len(), 2);
    assert!(json[0]["error"].is_string());
    assert_eq!(json[0]["detections"].as_array().unwrap().len(), 0);
}

#[test]
fn pattern_that_does_not_parse_names_itself_and_the_expected_forms() {
    let e = "chessboard:9x6".parse::<Pattern>().unwrap_err().to_string();
    assert!(e.contains("'chessboard:9x6'") && e.contains("expected") && e.contains("plate:<square>mm"), "{e}");
    let e = "apriltag:tag99h9".parse::<Pattern>().unwrap_err().to_string();
    assert!(e.contains("unknown AprilTag family") && e.contains("tag36h11"), "{e}");
}
