//! Procedural images with exact truth (tests/support/synth.rs): the edge-model refinement
//! against OpenCV's cornerSubPix (11 x 11, from the same initial corners), partial views, the
//! Gantry-Tau plate with and without a background image.

use crate::synth;

use ferrocal_vision::detect::baseline::opencv_corner_subpix;
use ferrocal_vision::detect::{detect, median_background, DetectOptions, Pattern};
use ferrocal_vision::subpix::NoiseModel;
use nalgebra::Point2;

struct Errors {
    ours2: f64,
    cv2: f64,
    coarse2: f64,
    crb2: f64,
    cov2: f64,
    n: usize,
}

fn rms(s: f64, n: usize) -> f64 {
    (s / n as f64).sqrt()
}

/// Chessboards at several blur and noise levels; returns summed squared errors.
fn chessboard_errors(blur_px: f64, noise_dn: f64, seeds: u64) -> Errors {
    let pattern: Pattern = "chessboard:7x5:25mm".parse().unwrap();
    let mut e = Errors { ours2: 0.0, cv2: 0.0, coarse2: 0.0, crb2: 0.0, cov2: 0.0, n: 0 };
    for pose in 0..seeds {
        let scene = synth::chessboard_scene(640, 480, 7, 5, 42.0, pose, blur_px, noise_dn);
        let img = synth::render(&scene);
        let truth = synth::chessboard_truth(&scene);
        let mut options = DetectOptions::default();
        options.refine_options.noise = ferrocal_vision::subpix::NoiseSpec::Known(NoiseModel {
            offset_dn2: noise_dn * noise_dn + 1.0 / 12.0,
            slope_dn: 0.0,
        });
        let coarse = detect(&img, &pattern, &DetectOptions { refine: false, ..options.clone() }, None).unwrap();
        let ours = detect(&img, &pattern, &options, None).unwrap();
        let coarse_px = coarse[0].corners_px();
        let cv = opencv_corner_subpix(&img, &coarse_px, 5, 0.001).unwrap();
        // The synthetic board is upright: our row-by-row order is the truth's order.
        for (k, t) in truth.iter().enumerate() {
            let c = &ours[0].corners[k];
            e.ours2 += (c.position_px - t).norm_squared();
            e.cv2 += (cv[k] - t).norm_squared();
            e.coarse2 += (coarse_px[k] - t).norm_squared();
            e.crb2 += c.crb_px2.map_or(f64::NAN, |m| m.trace());
            e.cov2 += c.covariance_px2.map_or(f64::NAN, |m| m.trace());
            e.n += 1;
        }
    }
    e
}

#[test]
fn edge_model_beats_corner_subpix_on_known_truth() {
    let mut worse = Vec::new();
    for (blur, noise) in [(0.8, 0.0), (0.8, 2.0), (1.5, 2.0), (2.5, 4.0)] {
        let e = chessboard_errors(blur, noise, 3);
        println!(
            "blur {blur} px, noise {noise} DN: RMS error ours {:.4} px, cornerSubPix 11x11 {:.4} px, coarse {:.4} px; \
             CRB {:.4} px, reported sigma {:.4} px ({} corners)",
            rms(e.ours2, e.n),
            rms(e.cv2, e.n),
            rms(e.coarse2, e.n),
            rms(e.crb2, e.n),
            rms(e.cov2, e.n),
            e.n
        );
        if rms(e.ours2, e.n) >= rms(e.cv2, e.n) {
            worse.push((blur, noise));
        }
    }
    assert!(worse.is_empty(), "cornerSubPix better at {worse:?}");
}

fn plate_at(shift: (f64, f64), roll_deg: f64, blur_px: f64, noise_dn: f64, seed: u64) -> synth::Scene {
    let (w, h) = (800u32, 600u32);
    let f = 900.0;
    let square_m = 0.04;
    let dist = f * square_m / 45.0;
    let hm = synth::homography(
        f,
        399.5,
        299.5,
        (3, 3),
        square_m,
        dist,
        roll_deg,
        10.0,
        -14.0,
        (shift.0 * dist, shift.1 * dist),
    );
    synth::Scene {
        width: w,
        height: h,
        h: hm,
        layout: synth::Layout::Plate { margin: 0.5 },
        dark_dn: 25.0,
        light_dn: 210.0,
        background_dn: 80.0,
        blur_px,
        noise_dn,
        seed,
        lens: None,
    }
}

fn plate_rms(found: &[Point2<f64>], truth: &[Point2<f64>]) -> f64 {
    assert_eq!(found.len(), 20);
    (found.iter().zip(truth).map(|(a, b)| (a - b).norm_squared()).sum::<f64>() / 20.0).sqrt()
}

#[test]
fn plate_found_with_all_twenty_corners() {
    let pattern: Pattern = "plate:40mm".parse().unwrap();
    for (k, (blur, noise)) in [(0.7, 1.0), (1.5, 3.0), (2.5, 3.0)].into_iter().enumerate() {
        let scene = plate_at((0.05 * k as f64, -0.08), 5.0 + 9.0 * k as f64, blur, noise, k as u64);
        let img = synth::render(&scene);
        let truth = synth::plate_truth(&scene);
        let found = detect(&img, &pattern, &DetectOptions::default(), None).unwrap();
        assert_eq!(found.len(), 1);
        let c = found[0].corners_px();
        let e = plate_rms(&c, &truth);
        let cv = opencv_corner_subpix(
            &img,
            &detect(&img, &pattern, &DetectOptions { refine: false, ..Default::default() }, None).unwrap()[0]
                .corners_px(),
            5,
            0.001,
        )
        .unwrap();
        println!("plate blur {blur} noise {noise}: RMS corner error {e:.4} px (cornerSubPix 11x11 from the same start {:.4} px)", plate_rms(&cv, &truth));
        assert!(e < 0.05, "{e}");
        // Target positions follow the renderer's plate layout.
        let t0 = found[0].corners[0].target_m.unwrap();
        assert!((t0.x + 0.06).abs() < 1e-12 && (t0.y - 0.06).abs() < 1e-12);
    }
}

/// A printed plate on the wall (static) next to the moving plate: without the background only
/// the image is searched and both are found; with the median background only the moving one.
#[test]
fn plate_background_subtraction_keeps_the_moving_plate() {
    let pattern: Pattern = "plate:40mm".parse().unwrap();
    let wall = plate_at((-0.35, -0.2), 3.0, 1.0, 0.0, 1);
    let wall_lin = synth::render_linear(&wall);
    let frames: Vec<(image::GrayImage, synth::Scene)> = (0..7)
        .map(|k| {
            let moving =
                plate_at((0.05 + 0.06 * k as f64, 0.12 + 0.02 * k as f64), 20.0 + 3.0 * k as f64, 1.0, 2.0, 10 + k);
            let lin = synth::render_linear(&moving);
            // Composite: the moving plate in front of the wall scene.
            let comp: Vec<f64> = lin
                .iter()
                .zip(&wall_lin)
                .map(|(m, w)| if (m - moving.background_dn).abs() > 1e-9 { *m } else { *w })
                .collect();
            (synth::quantise(&moving, &comp), moving)
        })
        .collect();
    let imgs: Vec<image::GrayImage> = frames.iter().map(|f| f.0.clone()).collect();
    let bg = median_background(&imgs).unwrap();
    let (img, moving) = &frames[3];
    let without = detect(img, &pattern, &DetectOptions::default(), None).unwrap();
    let with = detect(img, &pattern, &DetectOptions::default(), Some(&bg)).unwrap();
    println!("plates found: {} without the background, {} with it", without.len(), with.len());
    assert_eq!(without.len(), 2);
    assert_eq!(with.len(), 1);
    let e = plate_rms(&with[0].corners_px(), &synth::plate_truth(moving));
    assert!(e < 0.05, "{e}");
}

#[test]
fn partial_chessboard_returns_visible_corners_with_board_indices() {
    let pattern: Pattern = "chessboard:9x6:25mm".parse().unwrap();
    let mut scene = synth::chessboard_scene(640, 480, 9, 6, 60.0, 1, 1.0, 1.0);
    // Shift the board so that its right part leaves the image.
    let shift = nalgebra::Matrix3::new(1.0, 0.0, 260.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
    scene.h = shift * scene.h;
    let img = synth::render(&scene);
    let truth = synth::chessboard_truth(&scene);
    assert!(detect(&img, &pattern, &DetectOptions::default(), None).is_err());
    let found = detect(&img, &pattern, &DetectOptions { partial: true, ..Default::default() }, None).unwrap();
    let d = &found[0];
    assert!(!d.complete);
    let visible = truth.iter().filter(|p| p.x > 12.0 && p.x < 627.0 && p.y > 12.0 && p.y < 467.0).count();
    println!(
        "partial view: {} of {} corners returned ({} inside the image), anchored {}",
        d.corners.len(),
        truth.len(),
        visible,
        d.anchored
    );
    assert!(d.corners.len() >= visible - 6 && d.corners.len() < 54);
    assert!(d.anchored);
    for c in &d.corners {
        let [r, col] = c.grid_index.unwrap();
        let t = truth[(r * 9 + col) as usize];
        assert!((c.position_px - t).norm() < 0.1, "corner ({r}, {col}) at {:?}, truth {t:?}", c.position_px);
    }
}

/// Strong barrel distortion (k1 = -0.25 at f = 600 px): corners from local lines without a
/// lens model, and from lines fitted in undistorted coordinates with the camera model (local
/// and whole lines).
#[test]
fn distortion_with_and_without_a_camera_model() {
    use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};
    use ferrocal_vision::subpix::LineSupport;
    let pattern: Pattern = "chessboard:9x6:25mm".parse().unwrap();
    let (f, cx, cy, k1) = (600.0, 319.5, 239.5, -0.25);
    let camera = CameraModel::new(
        Intrinsics { fx_px: f, fy_px: f, cx_px: cx, cy_px: cy },
        Distortion::Brown5 { k1, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0 },
        ImageSize { width_px: 640, height_px: 480 },
    )
    .unwrap();
    let mut sums = [0.0f64; 3];
    let mut n = 0usize;
    for pose in 0..2 {
        let mut scene = synth::chessboard_scene(640, 480, 9, 6, 36.0, pose, 1.0, 1.5);
        scene.h = synth::homography(
            f,
            cx,
            cy,
            (7, 10),
            0.025,
            f * 0.025 / 36.0,
            4.0 + 5.0 * pose as f64,
            10.0,
            -12.0,
            (0.0, 0.0),
        );
        scene.lens = Some((f, cx, cy, k1));
        let img = synth::render(&scene);
        let truth = synth::chessboard_truth(&scene);
        let variants = [
            DetectOptions::default(),
            {
                let mut o = DetectOptions::default();
                o.refine_options.camera = Some(camera);
                o
            },
            {
                let mut o = DetectOptions::default();
                o.refine_options.camera = Some(camera);
                o.refine_options.support = LineSupport::Global;
                o
            },
        ];
        for (k, o) in variants.iter().enumerate() {
            let d = detect(&img, &pattern, o, None).unwrap();
            sums[k] += d[0].corners.iter().zip(&truth).map(|(c, t)| (c.position_px - t).norm_squared()).sum::<f64>();
        }
        n += truth.len();
    }
    let r: Vec<f64> = sums.iter().map(|s| (s / n as f64).sqrt()).collect();
    println!(
        "barrel distortion: RMS error local lines without a lens model {:.4} px, local lines with the camera model {:.4} px, \
         whole lines with the camera model {:.4} px",
        r[0], r[1], r[2]
    );
    assert!(r[0] < 0.05 && r[1] < 0.03 && r[2] < 0.03, "{r:?}");
    assert!(r[2] <= r[1] * 1.05, "{r:?}");
}

/// The tag36h11 bitmap of `id` from the C library (10 x 10 cells with the white border ring).
fn tag_cells(id: i32) -> Vec<bool> {
    // SAFETY: the family and the image come from the library and are freed here; the image
    // buffer holds `height * stride` bytes.
    unsafe {
        let fam = apriltag_sys::tag36h11_create();
        let im = apriltag_sys::apriltag_to_image(fam, id);
        let (w, h, stride) = ((*im).width as usize, (*im).height as usize, (*im).stride as usize);
        assert_eq!((w, h), (10, 10));
        let buf = std::slice::from_raw_parts((*im).buf, h * stride);
        let cells = (0..h).flat_map(|y| (0..w).map(move |x| (y, x))).map(|(y, x)| buf[y * stride + x] < 128).collect();
        apriltag_sys::image_u8_destroy(im);
        apriltag_sys::tag36h11_destroy(fam);
        cells
    }
}

/// A 3 x 2 board of tag36h11 tags (ids 4..10, 1-cell gaps): every tag found with its id and
/// board position; the C library's corners and the edge-model corners against the truth.
#[test]
fn apriltag_board_on_known_truth() {
    use ferrocal_vision::detect::{AprilTagOptions, TagRefine};
    let (cols, rows, first) = (3usize, 2usize, 4i32);
    // Board of cells: each tag 10 x 10 (white ring included) + 1 white cell between tags.
    let (bw, bh) = (cols * 11 - 1, rows * 11 - 1);
    let mut dark = vec![false; bw * bh];
    for t in 0..cols * rows {
        let cells = tag_cells(first + t as i32);
        let (r0, c0) = ((t / cols) * 11, (t % cols) * 11);
        for y in 0..10 {
            for x in 0..10 {
                dark[(r0 + y) * bw + c0 + x] = cells[y * 10 + x];
            }
        }
    }
    let f = 900.0;
    let cell_px = 7.0;
    let hm = synth::homography(f, 399.5, 299.5, (bh, bw), 0.005, f * 0.005 / cell_px, 6.0, 12.0, -10.0, (0.0, 0.0));
    let scene = synth::Scene {
        width: 800,
        height: 600,
        h: hm,
        layout: synth::Layout::Cells { cols: bw, rows: bh, dark, margin: 2.0 },
        dark_dn: 25.0,
        light_dn: 210.0,
        background_dn: 80.0,
        blur_px: 1.0,
        noise_dn: 2.0,
        seed: 3,
        lens: None,
    };
    let img = synth::render(&scene);
    // Truth: the black border square of each tag spans cells 1..9.
    let mut truth = Vec::new();
    for t in 0..cols * rows {
        let (y0, x0) = (((t / cols) * 11) as f64, ((t % cols) * 11) as f64);
        for (x, y) in [(1.0, 1.0), (9.0, 1.0), (9.0, 9.0), (1.0, 9.0)] {
            truth.push(synth::apply(&scene.h, x0 + x, y0 + y));
        }
    }
    // Tag side 8 cells = 40 mm, gap 3 cells = 15 mm between black borders.
    let pattern: Pattern = "aprilboard:3x2:40mm:15mm:4".parse().unwrap();
    let mut errs = Vec::new();
    for refine in [TagRefine::Backend, TagRefine::EdgeModel] {
        let options =
            DetectOptions { apriltag: AprilTagOptions { refine, ..Default::default() }, ..Default::default() };
        let found = detect(&img, &pattern, &options, None).unwrap();
        let mut ids: Vec<u32> = found.iter().map(|d| d.id.unwrap()).collect();
        ids.sort_unstable();
        assert_eq!(ids, vec![4, 5, 6, 7, 8, 9]);
        let mut s2 = 0.0;
        for d in &found {
            for c in &d.corners {
                let nearest = truth.iter().map(|t| (c.position_px - t).norm_squared()).fold(f64::INFINITY, f64::min);
                s2 += nearest;
            }
            // Board positions: tag 4 is top-left; its top-left corner (index 3) is up-left of
            // the board centre.
            if d.id == Some(4) {
                let t = d.corners[3].target_m.unwrap();
                assert!((t.x + 0.075).abs() < 1e-9 && (t.y - 0.0475).abs() < 1e-9, "{t:?}");
            }
            if refine == TagRefine::EdgeModel {
                assert!(d.corners.iter().all(|c| c.covariance_px2.is_some()));
            }
        }
        errs.push((s2 / (found.len() * 4) as f64).sqrt());
    }
    println!(
        "AprilTag board (tags of 56 px, blur 1, noise 2 DN): RMS corner error C library {:.4} px, edge model {:.4} px",
        errs[0], errs[1]
    );
    assert!(errs[1] < errs[0] && errs[1] < 0.05, "{errs:?}");
}
