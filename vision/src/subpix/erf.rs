//! The standard normal distribution, written out for the edge model.

/// `1 / sqrt(2 pi)`.
const INV_SQRT_2PI: f64 = 0.398_942_280_401_432_7;

/// Complementary error function, fractional error below 1.2e-7 everywhere (Chebyshev fit of
/// `erfc(x) = t exp(-x^2 + P(t))`, `t = 1 / (1 + |x| / 2)`, Numerical Recipes 6.2).
pub(crate) fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98 + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// Standard normal cumulative distribution `Phi(z)`.
pub(crate) fn normal_cdf(z: f64) -> f64 {
    0.5 * erfc(-z * std::f64::consts::FRAC_1_SQRT_2)
}

/// Standard normal density `phi(z)`.
pub(crate) fn normal_pdf(z: f64) -> f64 {
    INV_SQRT_2PI * (-0.5 * z * z).exp()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cdf_matches_known_values_and_pdf_is_its_derivative() {
        // Phi(1) = 0.841344746068543, Phi(-2) = 0.022750131948179, Phi(0) = 0.5.
        assert!((normal_cdf(1.0) - 0.841_344_746_068_543).abs() < 2e-7);
        assert!((normal_cdf(-2.0) - 0.022_750_131_948_179).abs() < 2e-8);
        assert!((normal_cdf(0.0) - 0.5).abs() < 1e-7);
        assert!((normal_cdf(1.7) + normal_cdf(-1.7) - 1.0).abs() < 1e-15);
        for z in [-3.0, -1.2, -0.1, 0.4, 2.5] {
            let h = 1e-5;
            let d = (normal_cdf(z + h) - normal_cdf(z - h)) / (2.0 * h);
            assert!((d - normal_pdf(z)).abs() < 1e-6, "{z}");
        }
    }
}
