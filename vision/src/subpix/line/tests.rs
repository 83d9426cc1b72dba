//! Tests of the line fits.

use super::*;
use std::cell::Cell;

thread_local! {
    /// Passes computing the normal equations ([`LineState::evaluate`]) on this thread.
    pub(super) static EVALUATIONS: Cell<usize> = const { Cell::new(0) };
}

/// Normal-equation passes of `f` on this thread.
fn evaluations<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let before = EVALUATIONS.with(Cell::get);
    let out = f();
    (out, EVALUATIONS.with(Cell::get) - before)
}

/// A noiseless synthetic band: the fit recovers the line, the blur and the intensities.
#[test]
fn recovers_a_synthetic_edge() {
    let (phi, d, sig, a, b) = (0.3f64, 0.37, 1.3, 40.0, 150.0);
    let mut samples = Vec::new();
    for i in -20..=20 {
        for j in -20..=20 {
            let (x, y) = (i as f64, j as f64);
            let u = phi.cos() * x + phi.sin() * y - d;
            if u.abs() < 5.0 {
                samples.push(Sample { x, y, v: a + b * normal_cdf(u / sig), w: 1.0 });
            }
        }
    }
    let mut line = LineState::straight(0.25, 0.0, vec![Segment { a: 0.0, b: 0.0, ln_s: 0.0, g: 0.0, samples }]);
    line.init_intensities();
    let fit = line.solve(50).unwrap();
    assert!((line.phi - phi).abs() < 1e-7, "{}", line.phi);
    assert!((line.d - d).abs() < 1e-6, "{}", line.d);
    assert!((line.segments[0].ln_s.exp() - sig).abs() < 1e-5);
    assert!((line.segments[0].b - b).abs() < 1e-4);
    assert!(fit.chi2 < 1e-8);
}

/// An edge bent by `kappa` through the corner at the origin, seen on either side of it (the
/// two segments of a chessboard line bent by lens distortion): the straight line passes the
/// corner at the mean sagitta, the parabola at the corner.
#[test]
fn a_bent_edge_is_fitted_at_its_tangent() {
    let (d, kappa, sig) = (0.2f64, 2e-4, 1.0);
    let segment = |sign: f64| {
        let mut samples = Vec::new();
        for i in 5..=60 {
            for j in -6..=6 {
                let (x, y) = (sign * i as f64, j as f64);
                let u = y - d - 0.5 * kappa * x * x;
                samples.push(Sample { x, y, v: 30.0 + 150.0 * normal_cdf(u / sig), w: 1.0 });
            }
        }
        Segment { a: 0.0, b: 0.0, ln_s: 0.0, g: 0.0, samples }
    };
    let phi = std::f64::consts::FRAC_PI_2;
    let mut straight = LineState::straight(phi, 0.0, vec![segment(-1.0), segment(1.0)]);
    straight.init_intensities();
    straight.solve(60).unwrap();
    // The mean sagitta over |x| in 5..60 is about kappa (60^3 - 5^3) / (6 * 55) = 0.13 px.
    assert!(straight.d - d > 0.08, "straight line at {}", straight.d);
    let mut bent = LineState { curved: true, ..LineState::straight(phi, 0.0, vec![segment(-1.0), segment(1.0)]) };
    bent.init_intensities();
    let fit = bent.solve(60).unwrap();
    assert!((bent.d - d).abs() < 1e-5 && (bent.phi - phi).abs() < 1e-7, "{} {}", bent.d, bent.phi);
    assert!((bent.kappa - kappa).abs() < 1e-8 && fit.p == 3 + 2 * PS && fit.chi2 < 1e-6, "{}", bent.kappa);
}

/// A noisy edge whose pixels are weighted by a signal-dependent noise model: one
/// Gauss-Newton step from the unweighted fit lands on the weighted optimum that
/// Levenberg-Marquardt reaches at the tight tolerance (to 1e-4 px, covariance to 1 %); a
/// start 3 px off falls back to Levenberg-Marquardt and converges all the same.
#[test]
fn one_step_from_the_unweighted_fit_is_the_weighted_fit() {
    let (model, line) = noisy_edge(12345);
    let mut line = line;
    line.solve_to(50, LOOSE).unwrap();
    line.set_weights(Some(&model));
    let mut exact = line.clone();
    let fe = exact.solve_to(50, TIGHT).unwrap();
    let mut near = line.clone();
    let fnear = near.solve_from_near(50).unwrap();
    assert!((near.d - exact.d).abs() < 1e-4 && (near.phi - exact.phi).abs() < 1e-6, "{} {}", near.d, exact.d);
    // The weights did move the line (else the test would show nothing).
    assert!((line.d - exact.d).abs() > 1e-4, "{} {}", line.d, exact.d);
    for k in 0..2 {
        let r = fnear.h_inv_line[(k, k)] / fe.h_inv_line[(k, k)];
        assert!((r - 1.0).abs() < 0.01, "{r}");
    }
    assert!((fnear.chi2 / fe.chi2 - 1.0).abs() < 1e-6);
    let mut far = line.clone();
    far.d += 3.0;
    far.solve_from_near(50).unwrap();
    assert!((far.d - exact.d).abs() < 1e-5, "{} {}", far.d, exact.d);
}

/// An intermediate fit from a start a fraction of a pixel off ends on the point
/// Levenberg-Marquardt at [`LOOSE`] ends on (the same iterates, bit for bit), with one pass
/// of normal equations fewer on most of a few noisy edges (never more); its cost is the
/// cost at that point.
#[test]
fn an_intermediate_fit_ends_on_the_same_point_one_pass_earlier() {
    let mut saved = 0;
    for seed in [1u64, 7, 12345, 99, 2024] {
        let (_, mut line) = noisy_edge(seed);
        // As the line snapped to the strongest gradient starts.
        (line.phi, line.d) = (1.19, -0.1);
        line.init_intensities();
        let mut full = line.clone();
        let (ff, n_full) = evaluations(|| full.solve_to(50, LOOSE).unwrap());
        let (fi, n_inter) = evaluations(|| line.solve_intermediate(50).unwrap());
        assert_eq!((line.d, line.phi), (full.d, full.phi), "seed {seed}");
        assert_eq!(line.segments[0].ln_s, full.segments[0].ln_s);
        assert!(n_inter + 1 == n_full || n_inter == n_full, "seed {seed}: {n_inter} against {n_full} passes");
        saved += n_full - n_inter;
        assert!((fi.chi2 / ff.chi2 - 1.0).abs() < 1e-12 && (fi.chi2 / line.cost() - 1.0).abs() < 1e-12);
    }
    // Where the contraction does not promise it (seed 99), the fit takes every pass.
    assert!(saved >= 3, "{saved} passes saved of 5 fits");
}

/// The sums over unit weights (multiplications skipped) are those of the weighted path:
/// with every weight 2 (an exact scaling) the cost and normal equations double, bit for bit.
#[test]
fn unit_weights_give_the_weighted_sums() {
    let (_, line) = noisy_edge(3);
    let mut doubled = line.clone();
    doubled.segments[0].samples.iter_mut().for_each(|p| p.w = 2.0);
    let ((c1, (h1, g1)), (c2, (h2, g2))) = (line.evaluate(), doubled.evaluate());
    assert!(c1 > 0.0 && c2 == 2.0 * c1 && h2 == 2.0 * &h1 && g2 == 2.0 * &g1, "{c1} {c2}");
}

/// A straight edge (normal angle 1.2 rad, 0.31 px from the origin, blur 1.4 px, levels 25
/// and 195 DN) with signal-dependent noise (`seed` of the generator), its pixels within
/// 6 px, and the noise model; the line starts at angle 1.15, distance 0, intensities
/// fitted.
fn noisy_edge(seed: u64) -> (NoiseModel, LineState) {
    let (phi, d, sig, a, b) = (1.2f64, -0.31, 1.4, 25.0, 170.0);
    let mut state = seed;
    let mut noise = move || {
        // Sum of 4 uniforms (LCG), variance 1.
        let mut s = 0.0;
        for _ in 0..4 {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            s += (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        }
        s * 3f64.sqrt()
    };
    let model = NoiseModel { offset_dn2: 2.0, slope_dn: 0.08 };
    let mut samples = Vec::new();
    for i in -30..=30 {
        for j in -30..=30 {
            let (x, y) = (i as f64, j as f64);
            let u = phi.cos() * x + phi.sin() * y - d;
            if u.abs() < 6.0 {
                let m = a + b * normal_cdf(u / sig);
                samples.push(Sample { x, y, v: m + model.variance_dn2(m).sqrt() * noise(), w: 1.0 });
            }
        }
    }
    let mut line = LineState::straight(1.15, 0.0, vec![Segment { a: 0.0, b: 0.0, ln_s: 0.0, g: 0.0, samples }]);
    line.init_intensities();
    (model, line)
}

/// The sums compiled for AVX2 and FMA (where the CPU has them) are those of the portable
/// code up to rounding, for straight and bent lines, unit and other weights.
#[test]
fn the_dispatched_sums_are_the_portable_sums() {
    let (model, mut line) = noisy_edge(5);
    for weighted in [false, true] {
        if weighted {
            line.set_weights(Some(&model));
        }
        let seg = &line.segments[0];
        // Relative to the scales of the sums (Cauchy-Schwarz bounds: an entry near zero is a
        // sum of terms that are not).
        let close = |(c1, h1, g1): SegmentSums, (c2, h2, g2): SegmentSums| {
            let near = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-11 * scale;
            let d = |a: usize| h1[a][a].max(1e-300);
            let ok = near(c1, c2, c1)
                && (0..6).all(|a| near(g1[a], g2[a], (d(a) * c1).sqrt()))
                && (0..6).all(|a| (0..6).all(|b| near(h1[a][b], h2[a][b], (d(a) * d(b)).sqrt())));
            if !ok {
                eprintln!("{c1} {c2}\n{g1:?}\n{g2:?}\n{h1:?}\n{h2:?}");
            }
            ok
        };
        if weighted {
            assert!(close(line.segment_sums::<5, false>(seg), line.segment_sums_with::<5, false, false>(seg)));
        } else {
            assert!(close(line.segment_sums::<5, true>(seg), line.segment_sums_with::<5, true, false>(seg)));
        }
        let bent = LineState { curved: true, kappa: 1e-3, ..line.clone() };
        let seg = &bent.segments[0];
        assert!(close(bent.segment_sums::<6, false>(seg), bent.segment_sums_with::<6, false, false>(seg)));
        assert!((line.cost() / line.cost_with::<false>() - 1.0).abs() < 1e-12);
    }
}
