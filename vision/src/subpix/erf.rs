//! The standard normal distribution, written out for the edge model.
//!
//! The line fits evaluate `Phi` and `phi` at every pixel of every Levenberg-Marquardt step;
//! [`NormalTable`] serves both from one table lookup (cubic Hermite interpolation of tabulated
//! values and derivatives, no `exp`): `phi` within 1e-9 of [`normal_pdf`], `Phi` within 5e-8 of
//! [`normal_cdf`] and no farther from the true `Phi` than [`normal_cdf`] is.

use std::sync::OnceLock;

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

/// `a b + c`: one fused multiply-add with `FMA` (a single rounding; call it so only inside
/// functions compiled for a CPU with FMA, else it is a slow library call), else a product and
/// a sum.
#[inline(always)]
pub(crate) fn madd<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FMA {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// Half-width of the tabulated range of `z`; outside, the closed forms are used.
const Z_MAX: f64 = 8.0;
/// Table nodes per unit of `z`.
const PER_UNIT: f64 = 64.0;
/// Number of intervals of the table.
const INTERVALS: usize = (2.0 * Z_MAX * PER_UNIT) as usize;

/// `Phi` and `phi` tabulated on `z_k = -8 + k / 64`, interpolated by cubic Hermite
/// polynomials through the values and the derivatives (`Phi' = phi`, `phi' = -z phi`):
/// interpolation error below 3e-10 for `phi`; `Phi`'s nodes come from [`normal_cdf`], whose
/// own error (1.2e-7 fractional) dominates. Each interval stores both cubics' coefficients
/// in the local coordinate `t` in `[0, 1)`, so a lookup is two Horner evaluations.
pub(crate) struct NormalTable {
    /// Per interval, `Phi = c0 + t (c1 + t (c2 + t c3))` and `phi` likewise:
    /// `[c0, c1, c2, c3, p0, p1, p2, p3]`.
    coefficients: Vec<[f64; 8]>,
}

/// The cubic `f(t) = y0 + t (h s0 + t (...))` through `y0`, `y1` with slopes `s0`, `s1` (per
/// unit of `z`) at the ends of an interval of width `h`, in `t = (z - z0) / h`: its Horner
/// coefficients.
fn hermite_coefficients(y0: f64, s0: f64, y1: f64, s1: f64, h: f64) -> [f64; 4] {
    let (m0, m1) = (h * s0, h * s1);
    [y0, m0, 3.0 * (y1 - y0) - 2.0 * m0 - m1, 2.0 * (y0 - y1) + m0 + m1]
}

impl NormalTable {
    /// The table (built once, on first use).
    pub(crate) fn get() -> &'static NormalTable {
        static TABLE: OnceLock<NormalTable> = OnceLock::new();
        TABLE.get_or_init(|| {
            let h = 1.0 / PER_UNIT;
            let node = |k: usize| {
                let z = k as f64 / PER_UNIT - Z_MAX;
                (z, normal_cdf(z), normal_pdf(z))
            };
            let coefficients = (0..INTERVALS)
                .map(|k| {
                    let ((z0, c0, p0), (z1, c1, p1)) = (node(k), node(k + 1));
                    let c = hermite_coefficients(c0, p0, c1, p1, h);
                    let p = hermite_coefficients(p0, -z0 * p0, p1, -z1 * p1, h);
                    [c[0], c[1], c[2], c[3], p[0], p[1], p[2], p[3]]
                })
                .collect();
            NormalTable { coefficients }
        })
    }

    /// `(Phi(z), phi(z))`.
    #[inline(always)]
    pub(crate) fn cdf_pdf(&self, z: f64) -> (f64, f64) {
        self.cdf_pdf_with::<false>(z)
    }

    /// `(Phi(z), phi(z))`; with `FMA`, the Horner steps are fused multiply-adds (call only
    /// where the CPU has them, see [`madd`]).
    #[inline(always)]
    pub(crate) fn cdf_pdf_with<const FMA: bool>(&self, z: f64) -> (f64, f64) {
        let x = (z + Z_MAX) * PER_UNIT;
        // Also catches NaN.
        if !(x >= 0.0 && x < INTERVALS as f64) {
            return (normal_cdf(z), normal_pdf(z));
        }
        let k = x as usize;
        let t = x - k as f64;
        let [c0, c1, c2, c3, p0, p1, p2, p3] = self.coefficients[k];
        let horner = |a0, a1, a2, a3| madd::<FMA>(t, madd::<FMA>(t, madd::<FMA>(t, a3, a2), a1), a0);
        (horner(c0, c1, c2, c3), horner(p0, p1, p2, p3))
    }

    /// `Phi(z)`.
    #[inline]
    pub(crate) fn cdf(&self, z: f64) -> f64 {
        self.cdf_pdf(z).0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `Phi(z)` to about 1e-14: Simpson's rule on `phi` from 0 (`Phi(0) = 1/2`).
    fn reference_cdf(z: f64) -> f64 {
        let n = 2 * ((z.abs() * 200.0).ceil() as usize).max(1);
        let h = z / n as f64;
        let mut s = normal_pdf(0.0) + normal_pdf(z);
        for k in 1..n {
            s += if k % 2 == 1 { 4.0 } else { 2.0 } * normal_pdf(k as f64 * h);
        }
        0.5 + s * h / 3.0
    }

    #[test]
    fn table_matches_the_closed_forms() {
        let t = NormalTable::get();
        let (mut cdf_ref, mut cdf_closed, mut table_closed, mut pdf): (f64, f64, f64, f64) = (0.0, 0.0, 0.0, 0.0);
        for i in -4000..=4000 {
            let z = i as f64 * 2e-3 + 0.123_456_7e-4;
            let (c, p) = t.cdf_pdf(z);
            let r = reference_cdf(z);
            cdf_ref = cdf_ref.max((c - r).abs());
            cdf_closed = cdf_closed.max((normal_cdf(z) - r).abs());
            table_closed = table_closed.max((c - normal_cdf(z)).abs());
            pdf = pdf.max((p - normal_pdf(z)).abs());
        }
        // The table is as close to the true Phi as the closed form is (whose fractional error
        // is below 1.2e-7), and within 5e-8 of the closed form; phi within 1e-9.
        assert!(cdf_ref <= cdf_closed + 1e-9, "{cdf_ref:e} {cdf_closed:e}");
        assert!(table_closed < 5e-8, "{table_closed:e}");
        assert!(pdf < 1e-9, "{pdf:e}");
        for z in [-40.0, -8.0, 7.999_999, 8.0, 12.0, f64::INFINITY] {
            let (c, p) = t.cdf_pdf(z);
            assert!((c - normal_cdf(z)).abs() < 5e-8 && (p - normal_pdf(z)).abs() < 1e-9, "{z}");
        }
        assert!(t.cdf(f64::NAN).is_nan());
    }

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
