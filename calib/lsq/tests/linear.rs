//! The linear least-squares routine against known answers: one test per rank policy on
//! hand-made rank-deficient matrices, weighted problems with closed-form solutions, and the
//! covariance against Monte Carlo on small seeded problems.

use ferrocal_lsq::linear::{fit, CovarianceScale, LinearFit, LinearOptions, RankPolicy, TruncatedSvd, Weighting};
use ferrocal_lsq::LsqError;
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

fn names(n: usize) -> Vec<String> {
    (0..n).map(|i| format!("p{i}")).collect()
}

fn named(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}

/// `t_i = i / (m - 1)` on `[0, 1]`.
fn t(m: usize, i: usize) -> f64 {
    i as f64 / (m - 1) as f64
}

fn opts(policy: RankPolicy) -> LinearOptions {
    LinearOptions::new(policy, 1e-9)
}

fn assert_close(a: f64, b: f64, tol: f64, what: &str) {
    assert!((a - b).abs() <= tol, "{what}: {a} vs {b} (tolerance {tol})");
}

/// Columns `slope t`, `offset 1`, `sum t + 1` (= slope + offset), `t^2`: rank 3 of 4, the first
/// three cannot be told apart; a fifth, zero column has no effect at all.
#[test]
fn refuse_names_the_dependent_columns() {
    let m = 20;
    let a = DMatrix::from_fn(m, 4, |i, j| match j {
        0 => t(m, i),
        1 => 1.0,
        2 => t(m, i) + 1.0,
        _ => t(m, i) * t(m, i),
    });
    let y = DVector::from_fn(m, |i, _| 1.0 + 2.0 * t(m, i));
    let n = named(&["slope", "offset", "sum", "curvature"]);
    match fit(&a, &y, &n, &Weighting::Unit, &opts(RankPolicy::Refuse)).unwrap_err() {
        LsqError::RankDeficient { rank, n_params, no_effect, coupled, message } => {
            assert_eq!((rank, n_params), (3, 4), "{message}");
            assert!(no_effect.is_empty(), "{message}");
            assert_eq!(coupled, vec![named(&["slope", "offset", "sum"])], "{message}");
            assert!(message.contains("rank 3 for 4") && !message.contains("curvature"), "{message}");
        }
        other => panic!("expected a rank deficiency, got {other}"),
    }
    // A zero column: refused with its name, whatever else is in the regressor.
    let a0 = DMatrix::from_fn(m, 2, |i, j| if j == 0 { t(m, i) } else { 0.0 });
    match fit(&a0, &y, &named(&["slope", "dead"]), &Weighting::Unit, &opts(RankPolicy::Refuse)).unwrap_err() {
        LsqError::RankDeficient { no_effect, message, .. } => {
            assert_eq!(no_effect, named(&["dead"]));
            assert!(message.contains("'dead' has no effect"), "{message}");
        }
        other => panic!("expected a rank deficiency, got {other}"),
    }
    // Without redundancy the refusing policy does not fit at all.
    let e = fit(
        &a.columns(0, 2).into_owned().rows(0, 2).into_owned(),
        &y.rows(0, 2).into_owned(),
        &names(2),
        &Weighting::Unit,
        &opts(RankPolicy::Refuse),
    );
    assert!(matches!(e, Err(LsqError::TooFew(_))));
}

/// Columns `1`, `1` (a duplicate), `t`, `0`: the truncated SVD returns the minimum-norm
/// solution of the scaled problem (the duplicate pair shares the offset equally, the zero column
/// gets 0), infinite standard deviations for the undetermined parameters and a finite one for
/// the slope, and predictions equal to the data.
#[test]
fn truncate_returns_the_minimum_norm_solution() {
    let m = 11;
    let a = DMatrix::from_fn(m, 4, |i, j| match j {
        0 | 1 => 1.0,
        2 => t(m, i),
        _ => 0.0,
    });
    // Data on the line 2 + 3 t plus a pattern orthogonal to 1 and t (a discrete quadratic),
    // so that the residuals and s0 are known too.
    let mean_t2 = (0..m).map(|i| t(m, i).powi(2)).sum::<f64>() / m as f64;
    let quad: Vec<f64> = (0..m).map(|i| (t(m, i) - 0.5).powi(2) - (mean_t2 - 0.25)).collect();
    let qn = quad.iter().map(|v| v * v).sum::<f64>().sqrt();
    let y = DVector::from_fn(m, |i, _| 2.0 + 3.0 * t(m, i) + 0.01 * quad[i] / qn);
    let opts = LinearOptions { covariance: CovarianceScale::APriori, ..opts(RankPolicy::Truncate) };
    let f = fit(&a, &y, &names(4), &Weighting::Unit, &opts).unwrap();
    assert_eq!((f.rank, f.dof), (2, m - 2));
    assert_close(f.values[0], 1.0, 1e-12, "first offset");
    assert_close(f.values[1], 1.0, 1e-12, "duplicate offset");
    assert_close(f.values[2], 3.0, 1e-12, "slope");
    assert_eq!(f.values[3], 0.0, "a zero column contributes nothing");
    assert!(f.std[0].is_infinite() && f.std[1].is_infinite() && f.std[3].is_infinite(), "{:?}", f.std);
    // The slope's variance is that of simple regression: 1 / sum (t - mean)^2.
    let sxx: f64 = (0..m).map(|i| (t(m, i) - 0.5).powi(2)).sum();
    assert_close(f.std[2], 1.0 / sxx.sqrt(), 1e-12, "slope std");
    // The residual is exactly the orthogonal pattern: chi^2 = 0.01^2.
    assert_close(f.chi2, 1e-4, 1e-15, "chi2");
    assert_close(f.s0, (1e-4 / (m - 2) as f64).sqrt(), 1e-15, "s0");
    // The decomposition alone: projection and pseudo-inverse agree with the fit.
    let svd = TruncatedSvd::new(&a, 1e-9).unwrap();
    assert_eq!(svd.rank(), 2);
    let yy = DMatrix::from_column_slice(m, 1, y.as_slice());
    let x = svd.solve(&yy);
    for j in 0..4 {
        assert_close(x[(j, 0)], f.values[j], 1e-12, "solve");
    }
    let res = svd.project_out(&yy);
    assert_close(res.norm(), 0.01, 1e-14, "projected residual");
    let pinv = svd.pseudo_inverse();
    assert_close((&pinv * &yy - &x).norm(), 0.0, 1e-12, "pseudo-inverse");
    assert!(svd.null_component(2) < 1e-12 && svd.null_component(0) > 0.5);
}

/// Columns `t`, `1`, `1` (a duplicate), `0`: pivoted QR keeps the slope and one of the two
/// offsets, holds the other and the zero column at zero, and fits the kept ones exactly as a
/// two-parameter line would.
#[test]
fn drop_pivoted_holds_the_redundant_columns_at_zero() {
    let m = 15;
    let a = DMatrix::from_fn(m, 4, |i, j| match j {
        0 => t(m, i),
        1 | 2 => 1.0,
        _ => 0.0,
    });
    let y = DVector::from_fn(m, |i, _| 0.5 - 4.0 * t(m, i) + if i % 2 == 0 { 0.02 } else { -0.02 });
    let n = named(&["slope", "offset_a", "offset_b", "dead"]);
    let f = fit(&a, &y, &n, &Weighting::Unit, &opts(RankPolicy::DropPivoted)).unwrap();
    assert_eq!(f.rank, 2);
    assert_eq!(f.dropped.len(), 2, "{:?}", f.dropped_names());
    assert!(f.dropped.contains(&3), "the zero column is dropped: {:?}", f.dropped_names());
    assert!(f.dropped.contains(&1) ^ f.dropped.contains(&2), "one offset is dropped: {:?}", f.dropped_names());
    let kept_offset = if f.dropped.contains(&1) { 2 } else { 1 };
    // The same line fitted with two columns.
    let line = a.select_columns(&[0, kept_offset]);
    let g = fit(&line, &y, &named(&["slope", "offset"]), &Weighting::Unit, &opts(RankPolicy::Refuse)).unwrap();
    assert_close(f.values[0], g.values[0], 1e-12, "slope");
    assert_close(f.values[kept_offset], g.values[1], 1e-12, "offset");
    assert_close(f.std[0], g.std[0], 1e-12, "slope std");
    assert_close(f.std[kept_offset], g.std[1], 1e-12, "offset std");
    for &d in &f.dropped {
        assert_eq!(f.values[d], 0.0);
        assert!(f.std[d].is_infinite());
        assert!(f.covariance.row(d).iter().all(|v| *v == 0.0));
    }
    assert_eq!(f.dof, m - 2);
    assert_close(f.s0, g.s0, 1e-14, "s0");
    // The pivoted R diagonal says the same: two large entries, then (numerically) zeros.
    assert!(f.r_diagonal[1] > 1e-3 && f.r_diagonal[2] < 1e-12, "{:?}", f.r_diagonal);
}

/// A weighted mean and a weighted line: the closed-form weighted sums, a priori and
/// a posteriori.
#[test]
fn weighted_problems_match_their_closed_forms() {
    let y = DVector::from_vec(vec![10.1, 9.8, 10.4, 9.9, 10.0, 10.3]);
    let sigma = vec![0.1, 0.2, 0.4, 0.1, 0.3, 0.2];
    let w: Vec<f64> = sigma.iter().map(|s| 1.0 / (s * s)).collect();
    let sw: f64 = w.iter().sum();
    let mean = y.iter().zip(&w).map(|(v, w)| v * w).sum::<f64>() / sw;
    let chi2: f64 = y.iter().zip(&w).map(|(v, w)| w * (v - mean).powi(2)).sum();
    let ones = DMatrix::from_element(6, 1, 1.0);
    for policy in [RankPolicy::Refuse, RankPolicy::Truncate, RankPolicy::DropPivoted] {
        let prior = LinearOptions { covariance: CovarianceScale::APriori, ..opts(policy) };
        let f = fit(&ones, &y, &names(1), &Weighting::Sigmas(sigma.clone()), &prior).unwrap();
        assert_close(f.values[0], mean, 1e-12, "weighted mean");
        assert_close(f.std[0], 1.0 / sw.sqrt(), 1e-12, "a-priori std");
        assert_close(f.chi2, chi2, 1e-9, "chi2");
        let post = fit(&ones, &y, &names(1), &Weighting::Sigmas(sigma.clone()), &opts(policy)).unwrap();
        assert_close(post.s0, (chi2 / 5.0).sqrt(), 1e-12, "s0");
        assert_close(post.std[0], (chi2 / 5.0 / sw).sqrt(), 1e-12, "a-posteriori std");
    }
    // Weighted line y = b + k x with the textbook sums.
    let x = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
    let a = DMatrix::from_fn(6, 2, |i, j| if j == 0 { 1.0 } else { x[i] });
    let (mut s, mut sx, mut sxx, mut sy, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for i in 0..6 {
        s += w[i];
        sx += w[i] * x[i];
        sxx += w[i] * x[i] * x[i];
        sy += w[i] * y[i];
        sxy += w[i] * x[i] * y[i];
    }
    let det = s * sxx - sx * sx;
    let (b, k) = ((sxx * sy - sx * sxy) / det, (s * sxy - sx * sy) / det);
    let prior = LinearOptions { covariance: CovarianceScale::APriori, ..opts(RankPolicy::Refuse) };
    let f = fit(&a, &y, &named(&["b", "k"]), &Weighting::Sigmas(sigma.clone()), &prior).unwrap();
    assert_close(f.values[0], b, 1e-12, "intercept");
    assert_close(f.values[1], k, 1e-12, "slope");
    assert_close(f.covariance[(0, 0)], sxx / det, 1e-12 * sxx / det, "var b");
    assert_close(f.covariance[(1, 1)], s / det, 1e-12 * s / det, "var k");
    assert_close(f.covariance[(0, 1)], -sx / det, 1e-12 * sx / det, "cov b k");
    // The same noise as one full (diagonal) covariance of all rows: the same answer.
    let full = DMatrix::from_diagonal(&DVector::from_iterator(6, sigma.iter().map(|s| s * s)));
    let g = fit(&a, &y, &named(&["b", "k"]), &Weighting::Block(full), &prior).unwrap();
    assert_close(g.values[1], k, 1e-12, "slope, full covariance");
    assert_close(g.std[1], f.std[1], 1e-12, "slope std, full covariance");
}

/// Sample covariance of estimates over seeded noise draws.
fn monte_carlo(
    a: &DMatrix<f64>,
    truth: &DVector<f64>,
    sigma: &[f64],
    opts: &LinearOptions,
    draws: usize,
    seed: u64,
    map: impl Fn(&LinearFit) -> DVector<f64>,
) -> (DMatrix<f64>, f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let y0 = a * truth;
    let mut samples = Vec::with_capacity(draws);
    let mut s0sq = 0.0;
    for _ in 0..draws {
        let y = DVector::from_fn(y0.len(), |i, _| {
            let e: f64 = StandardNormal.sample(&mut rng);
            y0[i] + sigma[i] * e
        });
        let f = fit(a, &y, &names(a.ncols()), &Weighting::Sigmas(sigma.to_vec()), opts).unwrap();
        s0sq += f.s0 * f.s0;
        samples.push(map(&f));
    }
    let n = samples[0].len();
    let mean = samples.iter().fold(DVector::zeros(n), |acc, s| acc + s) / draws as f64;
    let mut c = DMatrix::zeros(n, n);
    for s in &samples {
        let d = s - &mean;
        c += &d * d.transpose();
    }
    (c / (draws - 1) as f64, s0sq / draws as f64)
}

/// Compares a Monte-Carlo covariance with a predicted one: variances within 10 % (2000 draws:
/// the sample variance's relative standard error is 3 %), correlations within 0.1.
fn assert_covariance(mc: &DMatrix<f64>, predicted: &DMatrix<f64>, what: &str) {
    let n = mc.nrows();
    for i in 0..n {
        let r = mc[(i, i)] / predicted[(i, i)];
        assert!((r - 1.0).abs() < 0.1, "{what}: variance {i}: Monte Carlo / predicted = {r}");
        for j in 0..i {
            let cm = mc[(i, j)] / (mc[(i, i)] * mc[(j, j)]).sqrt();
            let cp = predicted[(i, j)] / (predicted[(i, i)] * predicted[(j, j)]).sqrt();
            assert!((cm - cp).abs() < 0.1, "{what}: correlation {i},{j}: {cm} vs {cp}");
        }
    }
}

/// A cubic on 30 heteroscedastic rows: the a-priori covariance against the spread of 2000
/// seeded fits, and `s0^2` averaging 1, for each policy; for the truncated policy on a
/// rank-deficient regressor, the covariance of the (unique) predictions.
#[test]
fn covariance_agrees_with_monte_carlo() {
    let m = 30;
    let a = DMatrix::from_fn(m, 4, |i, j| (2.0 * t(m, i) - 1.0).powi(j as i32) * [1.0, 10.0, 0.5, 2.0][j]);
    let sigma: Vec<f64> = (0..m).map(|i| 0.05 * (1.0 + (i % 4) as f64)).collect();
    let truth = DVector::from_vec(vec![1.0, -0.2, 0.7, 0.05]);
    for (k, policy) in [RankPolicy::Refuse, RankPolicy::Truncate, RankPolicy::DropPivoted].into_iter().enumerate() {
        let prior = LinearOptions { covariance: CovarianceScale::APriori, ..opts(policy) };
        let y0 = &a * &truth;
        let f = fit(&a, &y0, &names(4), &Weighting::Sigmas(sigma.clone()), &prior).unwrap();
        let (mc, s0sq) =
            monte_carlo(&a, &truth, &sigma, &prior, 2000, 40 + k as u64, |f| DVector::from_column_slice(&f.values));
        assert_covariance(&mc, &f.covariance, &format!("{policy:?}"));
        // E[s0^2] = 1; its mean over 2000 draws has a standard error of 0.006.
        assert!((s0sq - 1.0).abs() < 0.03, "{policy:?}: mean s0^2 {s0sq}");
    }
    // Rank-deficient: a duplicated column. The parameters are not determined, the predictions
    // A u are, with covariance A C A^T.
    let dup = DMatrix::from_fn(m, 3, |i, j| if j == 2 { a[(i, 1)] } else { a[(i, j)] });
    let truth = DVector::from_vec(vec![1.0, -0.1, -0.1]);
    let prior = LinearOptions { covariance: CovarianceScale::APriori, ..opts(RankPolicy::Truncate) };
    let f = fit(&dup, &(&dup * &truth), &names(3), &Weighting::Sigmas(sigma.clone()), &prior).unwrap();
    assert_eq!(f.rank, 2);
    let rows = [0usize, 10, 29];
    let pick = DMatrix::from_fn(rows.len(), 3, |r, c| dup[(rows[r], c)]);
    let predicted = &pick * &f.covariance * pick.transpose();
    let (mc, _) =
        monte_carlo(&dup, &truth, &sigma, &prior, 2000, 77, |f| &pick * DVector::from_column_slice(&f.values));
    assert_covariance(&mc, &predicted, "truncated predictions");
}
