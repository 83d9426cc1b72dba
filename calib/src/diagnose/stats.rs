//! Small statistics toolbox of the diagnosis: distribution tails (Student t, F), a paired
//! one-sided test, a weighted one-way analysis of variance over bins of an input, and the
//! multiple-testing correction.
//!
//! Written from the textbook definitions: the regularised incomplete beta function by its
//! continued fraction (modified Lentz), `ln Gamma` by the Lanczos approximation.

/// `ln Gamma(x)` for `x > 0` (Lanczos, g = 7, 9 coefficients; relative error below 1e-13).
pub fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection.
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Continued fraction of the incomplete beta function (modified Lentz).
fn beta_cf(a: f64, b: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let qab = a + b;
    let qap = a + 1.0;
    let qam = a - 1.0;
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    if d.abs() < TINY {
        d = TINY;
    }
    d = 1.0 / d;
    let mut h = d;
    // One Lentz step with the partial numerator `aa`: the factor it multiplies `h` by.
    let mut step = |aa: f64| {
        d = 1.0 + aa * d;
        if d.abs() < TINY {
            d = TINY;
        }
        c = 1.0 + aa / c;
        if c.abs() < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        d * c
    };
    for m in 1..=400 {
        let m = m as f64;
        let m2 = 2.0 * m;
        h *= step(m * (b - m) * x / ((qam + m2) * (a + m2)));
        let del = step(-(a + m) * (qab + m) * x / ((a + m2) * (qap + m2)));
        h *= del;
        if (del - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

/// The regularised incomplete beta function `I_x(a, b)`.
pub fn inc_beta(a: f64, b: f64, x: f64) -> f64 {
    if x.is_nan() || x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let ln_front = ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln();
    let front = ln_front.exp();
    if x < (a + 1.0) / (a + b + 2.0) {
        front * beta_cf(a, b, x) / a
    } else {
        1.0 - front * beta_cf(b, a, 1.0 - x) / b
    }
}

/// Upper tail `P(T > t)` of Student's t with `dof` degrees of freedom.
pub fn student_t_upper(t: f64, dof: f64) -> f64 {
    if t.is_nan() || dof <= 0.0 {
        return 1.0;
    }
    let x = dof / (dof + t * t);
    let tail = 0.5 * inc_beta(dof / 2.0, 0.5, x);
    if t > 0.0 {
        tail
    } else {
        1.0 - tail
    }
}

/// Upper tail `P(F > f)` of the F distribution with `(d1, d2)` degrees of freedom.
pub fn f_upper(f: f64, d1: f64, d2: f64) -> f64 {
    if f.is_nan() || f <= 0.0 || d1 <= 0.0 || d2 <= 0.0 {
        return 1.0;
    }
    inc_beta(d2 / 2.0, d1 / 2.0, d2 / (d2 + d1 * f))
}

/// Result of a one-sided paired test that the mean of `d` is positive.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PairedTest {
    /// Number of pairs.
    pub n: usize,
    /// Mean of the differences.
    pub mean: f64,
    /// Standard error of the mean.
    pub std_error: f64,
    /// t statistic.
    pub t: f64,
    /// One-sided p-value (no multiple-testing correction).
    pub p_value: f64,
}

/// One-sided paired t test of `mean(d) > 0` (`d` e.g. held-out squared errors before minus
/// after modelling an effect).
pub fn paired_test(d: &[f64]) -> PairedTest {
    let n = d.len();
    if n < 3 {
        return PairedTest { n, p_value: 1.0, ..Default::default() };
    }
    let mean = d.iter().sum::<f64>() / n as f64;
    let var = d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    let se = (var / n as f64).sqrt();
    let t = if se > 0.0 {
        mean / se
    } else if mean > 0.0 {
        f64::INFINITY
    } else {
        0.0
    };
    let p = if t.is_infinite() { 0.0 } else { student_t_upper(t, (n - 1) as f64) };
    PairedTest { n, mean, std_error: se, t, p_value: p }
}

/// One-sided exact sign test of `median(d) > 0` (zeros dropped).
pub fn sign_test(d: &[f64]) -> f64 {
    let pos = d.iter().filter(|v| **v > 0.0).count();
    let n = d.iter().filter(|v| **v != 0.0).count();
    if n == 0 {
        return 1.0;
    }
    // P(X >= pos) for X ~ Binomial(n, 1/2).
    let mut p = 0.0;
    let mut c = 1.0f64; // C(n, k) / 2^n computed in log space for stability
    let ln2n = n as f64 * std::f64::consts::LN_2;
    for k in 0..=n {
        if k > 0 {
            c *= (n - k + 1) as f64 / k as f64;
        }
        if k >= pos {
            p += (c.ln() - ln2n).exp();
        }
    }
    p.min(1.0)
}

/// Bonferroni-corrected p-value for `m` tests (the Holm step-down gives the same value for the
/// smallest p-value, which is the one the diagnosis acts on).
pub fn bonferroni(p: f64, m: usize) -> f64 {
    (p * m.max(1) as f64).min(1.0)
}

/// A weighted one-way analysis of variance of `y` over groups (bins of an input).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BinnedTest {
    /// Number of groups with data.
    pub groups: usize,
    /// F statistic.
    pub f: f64,
    /// p-value of "the group means are equal".
    pub p_value: f64,
    /// Per group: (centre of the input, weighted mean of y, its standard error, count).
    pub means: Vec<(f64, f64, f64, usize)>,
    /// Fraction of the weighted variance of y explained by the group means.
    pub explained: f64,
}

/// Weighted one-way ANOVA of `y` (weights `w`, the inverse variances up to a common factor)
/// over the groups `group[i]` (`0..n_groups`); `x` gives each group's centre for plots.
pub fn binned_anova(x: &[f64], y: &[f64], w: &[f64], group: &[usize], n_groups: usize) -> BinnedTest {
    let mut sw = vec![0.0; n_groups];
    let mut swy = vec![0.0; n_groups];
    let mut sx = vec![0.0; n_groups];
    let mut cnt = vec![0usize; n_groups];
    for i in 0..y.len() {
        let g = group[i];
        if g >= n_groups || w[i].is_nan() || w[i] <= 0.0 || !y[i].is_finite() {
            continue;
        }
        sw[g] += w[i];
        swy[g] += w[i] * y[i];
        sx[g] += x[i];
        cnt[g] += 1;
    }
    let used: Vec<usize> = (0..n_groups).filter(|&g| cnt[g] >= 2).collect();
    let k = used.len();
    let n: usize = used.iter().map(|&g| cnt[g]).sum();
    if k < 2 || n <= k + 1 {
        return BinnedTest { groups: k, p_value: 1.0, ..Default::default() };
    }
    let mean_g: Vec<f64> = (0..n_groups).map(|g| if sw[g] > 0.0 { swy[g] / sw[g] } else { 0.0 }).collect();
    let tot_w: f64 = used.iter().map(|&g| sw[g]).sum();
    let grand = used.iter().map(|&g| swy[g]).sum::<f64>() / tot_w;
    let between: f64 = used.iter().map(|&g| sw[g] * (mean_g[g] - grand).powi(2)).sum();
    let mut within = 0.0;
    for i in 0..y.len() {
        let g = group[i];
        if g < n_groups && cnt[g] >= 2 && w[i] > 0.0 && y[i].is_finite() {
            within += w[i] * (y[i] - mean_g[g]).powi(2);
        }
    }
    let d1 = (k - 1) as f64;
    let d2 = (n - k) as f64;
    let s2 = within / d2;
    let f = if s2 > 0.0 { between / d1 / s2 } else { 0.0 };
    let means = used.iter().map(|&g| (sx[g] / cnt[g] as f64, mean_g[g], (s2 / sw[g]).sqrt(), cnt[g])).collect();
    BinnedTest {
        groups: k,
        f,
        p_value: f_upper(f, d1, d2),
        means,
        explained: if between + within > 0.0 { between / (between + within) } else { 0.0 },
    }
}

/// Groups of equal count over the sorted values of `x` (`n_bins` quantile bins).
pub fn quantile_groups(x: &[f64], n_bins: usize) -> Vec<usize> {
    let n = x.len();
    let mut idx: Vec<usize> = (0..n).collect();
    idx.sort_by(|a, b| x[*a].total_cmp(&x[*b]));
    let mut g = vec![0usize; n];
    for (rank, &i) in idx.iter().enumerate() {
        g[i] = (rank * n_bins / n.max(1)).min(n_bins.saturating_sub(1));
    }
    // Ties across a bin edge go to the lower bin, so equal inputs share a group.
    for w in idx.windows(2) {
        if x[w[1]] == x[w[0]] {
            g[w[1]] = g[w[0]];
        }
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tails_match_known_values() {
        // t with 10 dof: P(T > 2.228) = 0.025.
        assert!((student_t_upper(2.228_138_85, 10.0) - 0.025).abs() < 1e-6);
        assert!((student_t_upper(0.0, 5.0) - 0.5).abs() < 1e-12);
        assert!((student_t_upper(-2.228_138_85, 10.0) - 0.975).abs() < 1e-6);
        // F(3, 20): P(F > 3.098) = 0.05.
        assert!((f_upper(3.098_391_2, 3.0, 20.0) - 0.05).abs() < 1e-5);
        assert!((ln_gamma(5.0) - 24f64.ln()).abs() < 1e-12);
        assert!((ln_gamma(0.5) - std::f64::consts::PI.sqrt().ln()).abs() < 1e-12);
    }

    #[test]
    fn anova_sees_a_step_and_not_noise() {
        let x: Vec<f64> = (0..200).map(|i| i as f64).collect();
        let noise: Vec<f64> = (0..200).map(|i| ((i * 7919 % 200) as f64 / 200.0 - 0.5) * 0.2).collect();
        let step: Vec<f64> = x.iter().zip(&noise).map(|(x, n)| if *x < 100.0 { *n } else { n + 0.2 }).collect();
        let w = vec![1.0; 200];
        let g = quantile_groups(&x, 8);
        assert!(binned_anova(&x, &step, &w, &g, 8).p_value < 1e-6);
        let t = paired_test(&[1.0, 2.0, 1.5, 1.2, 0.8, 1.1]);
        assert!(t.p_value < 1e-3 && t.mean > 0.0);
    }
}
