//! Real photographs: the AprilTag C library's own test photos (NASA Swarmathon) with its
//! labels, and OpenCV's stereo calibration sample against OpenCV's chessboard recipe.

use std::path::PathBuf;

use ferrocal_vision::detect::apriltag::{compare_tag_backends, AprilTagDetector, AprilTagOptions, TagRefine};
use ferrocal_vision::detect::baseline::opencv_find_chessboard;
use ferrocal_vision::detect::{detect, load_gray, DetectOptions, Pattern, TagFamily};
use nalgebra::Point2;

/// One view's corners with their target points (metres).
type View = Vec<(Point2<f64>, [f64; 3])>;

/// Per camera: (our corners with target points, OpenCV's corners) per image.
type Views = std::collections::BTreeMap<String, Vec<(View, Vec<Point2<f64>>)>>;

/// A folder of `../shared/data`; CI always has it, so a missing folder fails the test by name.
fn data(dir: &str) -> PathBuf {
    let p = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/")).join(dir);
    assert!(p.is_dir(), "{} is missing: ../shared/data must be beside the checkout", p.display());
    p
}

/// One label line: `id, (x0 y0), (x1 y1), (x2 y2), (x3 y3)`; corners shifted by -0.5 px from
/// the library's convention (pixel centres at integer + 0.5) to this project's.
fn parse_labels(text: &str) -> Vec<(u32, [Point2<f64>; 4])> {
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let (id, rest) = l.split_once(',').unwrap();
            let nums: Vec<f64> =
                rest.replace(['(', ')', ','], " ").split_whitespace().map(|v| v.parse().unwrap()).collect();
            assert_eq!(nums.len(), 8, "{l}");
            let c = |k: usize| Point2::new(nums[2 * k] - 0.5, nums[2 * k + 1] - 0.5);
            (id.trim().parse().unwrap(), [c(0), c(1), c(2), c(3)])
        })
        .collect()
}

/// Matches detections to labels by id and nearest centre; returns per-tag mean corner errors.
fn match_tags(found: &[(u32, [Point2<f64>; 4])], labels: &[(u32, [Point2<f64>; 4])]) -> Vec<f64> {
    let centre = |c: &[Point2<f64>; 4]| (c[0].coords + c[1].coords + c[2].coords + c[3].coords) / 4.0;
    let mut used = vec![false; found.len()];
    let mut out = Vec::new();
    for (id, lc) in labels {
        let best = found
            .iter()
            .enumerate()
            .filter(|(k, f)| f.0 == *id && !used[*k])
            .min_by(|a, b| (centre(&a.1 .1) - centre(lc)).norm().total_cmp(&(centre(&b.1 .1) - centre(lc)).norm()));
        if let Some((k, f)) = best {
            if (centre(&f.1) - centre(lc)).norm() < 5.0 {
                used[k] = true;
                out.push((0..4).map(|q| (f.1[q] - lc[q]).norm()).sum::<f64>() / 4.0);
            }
        }
    }
    out
}

#[test]
fn nasa_photos_all_47_tags_match_the_library_labels() {
    let dir = data("apriltag_nasa");
    let mut names: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "jpg"))
        .collect();
    names.sort();
    assert_eq!(names.len(), 3);
    let (mut total, mut matched, mut sum, mut max) = (0usize, 0usize, 0.0f64, 0.0f64);
    let (mut ref_sum, mut ref_n, mut ref_max) = (0.0f64, 0usize, 0.0f64);
    for img_path in &names {
        let labels = parse_labels(&std::fs::read_to_string(img_path.with_extension("txt")).unwrap());
        let img = load_gray(img_path).unwrap();
        let mut det = AprilTagDetector::new(TagFamily::Tag36h11, AprilTagOptions::default()).unwrap();
        let tags = det.detect(&img).unwrap();
        let found: Vec<(u32, [Point2<f64>; 4])> = tags.iter().map(|t| (t.id, t.corners_px)).collect();
        let errs = match_tags(&found, &labels);
        // Edge-model refinement of the same tags, compared with the labels.
        let mut rdet = AprilTagDetector::new(
            TagFamily::Tag36h11,
            AprilTagOptions { refine: TagRefine::EdgeModel, ..AprilTagOptions::default() },
        )
        .unwrap();
        let rtags = rdet.detect(&img).unwrap();
        let rfound: Vec<(u32, [Point2<f64>; 4])> = rtags.iter().map(|t| (t.id, t.best_corners_px())).collect();
        let rerrs = match_tags(&rfound, &labels);
        let refined = rtags.iter().filter(|t| t.refined.is_some()).count();
        let cmp = compare_tag_backends(&img, TagFamily::Tag36h11, &AprilTagOptions::default()).unwrap();
        println!(
            "{}: {} labels, {} found, {} matched, mean corner diff {:.4} px; refined {}/{}: mean diff to labels {:.3} px; \
             kornia: {} tags ({} common with C), mean corner diff {:.3} px, C {:.1} ms, kornia {:.1} ms",
            img_path.file_name().unwrap().to_string_lossy(),
            labels.len(),
            tags.len(),
            errs.len(),
            errs.iter().sum::<f64>() / errs.len().max(1) as f64,
            refined,
            rtags.len(),
            rerrs.iter().sum::<f64>() / rerrs.len().max(1) as f64,
            cmp.kornia_ids.len(),
            cmp.common,
            cmp.mean_corner_diff_px,
            cmp.c_seconds * 1e3,
            cmp.kornia_seconds * 1e3
        );
        total += labels.len();
        matched += errs.len();
        sum += errs.iter().sum::<f64>();
        max = errs.iter().copied().fold(max, f64::max);
        ref_sum += rerrs.iter().sum::<f64>();
        ref_n += rerrs.len();
        ref_max = rerrs.iter().copied().fold(ref_max, f64::max);
    }
    let mean = sum / matched as f64;
    println!(
        "NASA: {matched}/{total} tags, mean corner diff {mean:.4} px, worst tag {max:.4} px; refined: mean {:.3} px, worst {ref_max:.3} px",
        ref_sum / ref_n.max(1) as f64
    );
    assert_eq!(total, 47);
    assert_eq!(matched, 47);
    assert!(mean < 0.1, "{mean}");
}

#[test]
fn opencv_stereo_chessboards_agree_with_opencv() {
    let dir = data("opencv_stereo");
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "jpg"))
        .collect();
    paths.sort();
    assert_eq!(paths.len(), 26);
    let pattern: Pattern = "chessboard:9x6:25mm".parse().unwrap();
    let options = DetectOptions::default();
    let (mut sum2, mut n, mut worst, mut coarse2) = (0.0f64, 0usize, 0.0f64, 0.0f64);
    let (mut mean_d, mut mean_dc) = (nalgebra::Vector2::<f64>::zeros(), nalgebra::Vector2::<f64>::zeros());
    let mut per_image = Vec::new();
    // Per camera: (our corners with target points, OpenCV's corners).
    let mut views: Views = Default::default();
    for p in &paths {
        let img = load_gray(p).unwrap();
        let ours = detect(&img, &pattern, &options, None).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert_eq!(ours.len(), 1);
        let ours_t: Vec<(Point2<f64>, [f64; 3])> = ours[0]
            .corners
            .iter()
            .map(|c| {
                let t = c.target_m.unwrap();
                (c.position_px, [t.x, t.y, t.z])
            })
            .collect();
        let ours = ours[0].corners_px();
        assert_eq!(ours.len(), 54);
        let coarse =
            detect(&img, &pattern, &DetectOptions { refine: false, ..options.clone() }, None).unwrap()[0].corners_px();
        let cv = opencv_find_chessboard(&img, 9, 6, Some(5))
            .unwrap()
            .unwrap_or_else(|| panic!("OpenCV misses {}", p.display()));
        // OpenCV orders the corners either way round.
        let dist = |rev: bool, a: &[Point2<f64>]| -> Vec<f64> {
            (0..54).map(|k| (a[k] - cv[if rev { 53 - k } else { k }]).norm()).collect()
        };
        let d0 = dist(false, &ours);
        let d1 = dist(true, &ours);
        let (d, rev) = if d0.iter().sum::<f64>() < d1.iter().sum::<f64>() { (d0, false) } else { (d1, true) };
        let dc = dist(rev, &coarse);
        for k in 0..54 {
            let c = cv[if rev { 53 - k } else { k }];
            mean_d += ours[k] - c;
            mean_dc += coarse[k] - c;
        }
        let cam =
            if p.file_name().unwrap().to_string_lossy().starts_with("left") { "left" } else { "right" }.to_string();
        views.entry(cam).or_default().push((ours_t, cv.clone()));
        let rms = (d.iter().map(|v| v * v).sum::<f64>() / 54.0).sqrt();
        per_image.push((
            p.file_name().unwrap().to_string_lossy().to_string(),
            rms,
            d.iter().copied().fold(0.0, f64::max),
        ));
        sum2 += d.iter().map(|v| v * v).sum::<f64>();
        coarse2 += dc.iter().map(|v| v * v).sum::<f64>();
        n += 54;
        worst = d.iter().copied().fold(worst, f64::max);
    }
    for (name, rms, max) in &per_image {
        println!("{name}: RMS {rms:.3} px, max {max:.3} px from OpenCV findChessboardCorners + cornerSubPix 11x11");
    }
    let rms = (sum2 / n as f64).sqrt();
    println!(
        "mean signed difference: refined ({:.3}, {:.3}) px, coarse ({:.3}, {:.3}) px",
        mean_d.x / n as f64,
        mean_d.y / n as f64,
        mean_dc.x / n as f64,
        mean_dc.y / n as f64
    );
    println!(
        "opencv_stereo: 26/26 boards, {n} corners: RMS difference {rms:.3} px, worst {worst:.3} px (coarse X-corners: RMS {:.3} px)",
        (coarse2 / n as f64).sqrt()
    );
    // Which corners does a camera model explain better? OpenCV's calibrateCamera (5-coefficient
    // Brown model, fixed aspect ratio) on each set.
    for (cam, vs) in &views {
        let ours: Vec<View> = vs.iter().map(|v| v.0.clone()).collect();
        let cv: Vec<View> = vs
            .iter()
            .map(|v| {
                v.1.iter()
                    .enumerate()
                    .map(|(k, p)| (*p, [(k % 9) as f64 * 0.025, (k / 9) as f64 * 0.025, 0.0]))
                    .collect()
            })
            .collect();
        println!(
            "{cam}: calibrateCamera reprojection RMS with our corners {:.4} px, with OpenCV's corners {:.4} px",
            calibration_rms(&ours),
            calibration_rms(&cv)
        );
    }
    assert!(rms < 0.25, "{rms}");
    assert!(worst < 1.0, "{worst}");
}

fn calibration_rms(views: &[View]) -> f64 {
    use opencv::core::{Mat, Point2f, Point3f, Size, TermCriteria, Vector};
    use opencv::prelude::*;
    let mut obj: Vector<Vector<Point3f>> = Vector::new();
    let mut img: Vector<Vector<Point2f>> = Vector::new();
    for v in views {
        obj.push(v.iter().map(|(_, t)| Point3f::new(t[0] as f32, t[1] as f32, t[2] as f32)).collect());
        img.push(v.iter().map(|(p, _)| Point2f::new(p.x as f32, p.y as f32)).collect());
    }
    let mut k = Mat::eye(3, 3, opencv::core::CV_64F).unwrap().to_mat().unwrap();
    let mut d = Mat::default();
    let mut r: Vector<Mat> = Vector::new();
    let mut t: Vector<Mat> = Vector::new();
    let crit =
        TermCriteria::new(opencv::core::TermCriteria_COUNT + opencv::core::TermCriteria_EPS, 100, 1e-12).unwrap();
    opencv::calib3d::calibrate_camera(
        &obj,
        &img,
        Size::new(640, 480),
        &mut k,
        &mut d,
        &mut r,
        &mut t,
        opencv::calib3d::CALIB_FIX_ASPECT_RATIO,
        crit,
    )
    .unwrap()
}
