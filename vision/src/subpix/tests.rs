//! Unit tests of the edge model: the closed-form bound, covariance against Monte-Carlo
//! sampling, quadrilaterals, noise estimation, bad options.

use nalgebra::{Matrix2, Point2};

use super::grid::estimate_noise;
use super::line::{LineState, Sample, Segment};
use super::*;
use crate::detect::{detect, synth, DetectOptions, Pattern};

/// A straight vertical edge, white-noise pixels: the fitted offset's variance (Fisher) agrees
/// with the closed form `2 sqrt(pi) sigma^2 s / (L b^2)`.
#[test]
fn offset_variance_matches_the_closed_form() {
    let (s, b, sigma, len) = (1.3, 150.0, 2.0, 60usize);
    let mut samples = Vec::new();
    // Rows centred on the origin: the offset at the origin is then not mixed with the angle.
    for y in 0..len {
        let y = y as f64 - 0.5 * (len as f64 - 1.0);
        for x in -12i32..=12 {
            let u = f64::from(x) - 0.3;
            samples.push(Sample { x: f64::from(x), y, v: 30.0 + b * erf::normal_cdf(u / s), w: 1.0 / (sigma * sigma) });
        }
    }
    let mut line = LineState::straight(0.0, 0.3, vec![Segment { a: 30.0, b, ln_s: s.ln(), g: 0.0, samples }]);
    let fit = line.solve(20).unwrap();
    let fisher_sd = fit.h_inv_line[(1, 1)].sqrt();
    let closed = edge_offset_crb_px(len as f64, b, s, sigma);
    println!("edge offset bound: Fisher {fisher_sd:.5} px, closed form {closed:.5} px");
    // Unknown levels and blur cost a little (the step's derivative is not orthogonal to the
    // constant level within a finite band).
    assert!(fisher_sd >= closed * 0.99 && fisher_sd < closed * 1.15, "{fisher_sd} vs {closed}");
}

/// The reported covariance and the Cramer-Rao bound agree with the scatter of the corners over
/// 40 noise draws of the same scene.
#[test]
fn covariance_matches_monte_carlo() {
    let pattern: Pattern = "chessboard:4x3:25mm".parse().unwrap();
    let scene = synth::chessboard_scene(320, 240, 4, 3, 40.0, 1, 1.2, 3.0);
    let lin = synth::render_linear(&scene);
    let mut all: Vec<Vec<Point2<f64>>> = Vec::new();
    let mut reported = vec![Matrix2::<f64>::zeros(); 12];
    let mut crb = vec![Matrix2::<f64>::zeros(); 12];
    let draws = 40;
    for seed in 0..draws {
        let mut sc = scene.clone();
        sc.seed = 1000 + seed;
        let img = synth::quantise(&sc, &lin);
        let d = detect(&img, &pattern, &DetectOptions::default(), None).unwrap();
        for (k, c) in d[0].corners.iter().enumerate() {
            reported[k] += c.covariance_px2.unwrap() / draws as f64;
            crb[k] += c.crb_px2.unwrap() / draws as f64;
        }
        all.push(d[0].corners_px());
    }
    let (mut emp_tr, mut rep_tr, mut crb_tr) = (0.0, 0.0, 0.0);
    for k in 0..12 {
        let mean = all.iter().map(|c| c[k].coords).sum::<nalgebra::Vector2<f64>>() / draws as f64;
        let cov = all.iter().map(|c| (c[k].coords - mean) * (c[k].coords - mean).transpose()).sum::<Matrix2<f64>>()
            / (draws - 1) as f64;
        emp_tr += cov.trace();
        rep_tr += reported[k].trace();
        crb_tr += crb[k].trace();
    }
    let ratio = emp_tr / rep_tr;
    println!(
        "Monte-Carlo ({draws} draws): empirical sigma {:.4} px, reported {:.4} px, CRB {:.4} px (RMS over corners)",
        (emp_tr / 12.0).sqrt(),
        (rep_tr / 12.0).sqrt(),
        (crb_tr / 12.0).sqrt()
    );
    // 40 draws x 12 corners x 2 axes: the variance ratio is known to about +-10 %.
    assert!((0.7..1.4).contains(&ratio), "{ratio}");
    assert!((crb_tr / rep_tr - 1.0).abs() < 0.25);
}

#[test]
fn quad_corners_of_a_dark_square() {
    let scene = synth::plate_scene(400, 300, 50.0, 2, 1.0, 1.0);
    let img = synth::render(&scene);
    let truth = synth::plate_truth(&scene);
    let f = GrayF32::from_gray8(&img).unwrap();
    // The bottom-right square (corners 16..20: TL, TR, BR, BL), started 0.7 px off.
    let start: Vec<Point2<f64>> = truth[16..20].iter().map(|p| p + nalgebra::Vector2::new(0.5, -0.5)).collect();
    let (out, summary) = refine_quad(&f, &[start[0], start[1], start[2], start[3]], &RefineOptions::default()).unwrap();
    for (k, c) in out.iter().enumerate() {
        let c = c.unwrap();
        let e = (c.position_px - truth[16 + k]).norm();
        assert!(e < 0.05, "corner {k}: {e}");
        assert!(c.blur_px > 0.9 && c.blur_px < 1.3, "{}", c.blur_px);
    }
    let noise = summary.noise.unwrap();
    assert!(noise.offset_dn2 > 0.3 && noise.offset_dn2 < 3.0, "{noise:?}");
}

#[test]
fn noise_model_from_pooled_residuals_and_from_the_sensor() {
    // r^2 = 2 + 0.05 m exactly.
    let mut s = [0.0f64; 5];
    for m in [10.0, 50.0, 100.0, 200.0].repeat(4) {
        let r2 = 2.0 + 0.05 * m;
        s[0] += 1.0;
        s[1] += m;
        s[2] += m * m;
        s[3] += r2;
        s[4] += m * r2;
    }
    let n = estimate_noise(&s).unwrap();
    assert!((n.offset_dn2 - 2.0).abs() < 1e-9 && (n.slope_dn - 0.05).abs() < 1e-12);
    let m = NoiseModel::from_sensor(40.0, 6.0, 4.0, true);
    // Var at 195 DN: (S + 36) / 1600 + 1/12 with S = 40 (195 - 4).
    let want = (40.0 * 191.0 + 36.0) / 1600.0 + 1.0 / 12.0;
    assert!((m.variance_dn2(195.0) - want).abs() < 1e-9);
}

#[test]
fn bad_options_and_grids_are_rejected() {
    let f = GrayF32::from_vec(10, 10, vec![0.0; 100]).unwrap();
    let grid = CheckerGrid::checkerboard(1, 1, true, Some(false), vec![None; 4]);
    let bad = RefineOptions { max_segment_px: f64::NAN, ..RefineOptions::default() };
    assert!(matches!(refine_grid(&f, &grid, &[], &bad), Err(VisionError::BadOption { name: "max_segment_px", .. })));
    let short = CheckerGrid { points_px: vec![None; 3], ..grid.clone() };
    assert!(refine_grid(&f, &short, &[], &RefineOptions::default()).is_err());
    assert!(refine_grid(&f, &grid, &[(5, 0)], &RefineOptions::default()).is_err());
    // Nothing to fit: the corner comes back as None, no panic.
    let (out, _) = refine_grid(&f, &grid, &[(0, 0)], &RefineOptions::default()).unwrap();
    assert!(out[0].is_none());
}
