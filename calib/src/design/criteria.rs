//! Design criteria on a Fisher information matrix `F = A^T W A` (Friedrich & Ihlenfeldt; the
//! source's check after Dressler).
//!
//! Every criterion is turned into a *loss* that selection minimises (infinite when `F` is
//! singular); [`Criterion::value`] gives the number in the form the sources state it. With the
//! eigenvalues `lambda` of `F` (the squared singular values `mu^2` of the whitened regressor):
//!
//! | criterion | source's form | loss |
//! | --- | --- | --- |
//! | A | `trace(F^-1) -> min` | `trace(F^-1)` |
//! | D | `det F -> max` | `-ln det F` |
//! | K | `cond(A) -> min` | `sqrt(lambda_max / lambda_min)` |
//! | N | `mu_u^2 / mu_1 -> max` (noise amplification) | `-lambda_min / sqrt(lambda_max)` |
//! | Dressler | `sigma_max^2 / sigma_min < C` | `lambda_max / sqrt(lambda_min)` |
//!
//! The criteria see only the matrix: they do not care whether its rows come from positions
//! measured by cameras, a laser tracker or a force sensor's regressor.

use nalgebra::{DMatrix, SymmetricEigen};
use serde::{Deserialize, Serialize};

/// Relative eigenvalue tolerance of `F` below which it counts as singular (`lambda_min <=
/// RANK_TOL * lambda_max`, i.e. singular values below `1e-6 sigma_max`).
pub const RANK_TOL: f64 = 1e-12;

/// An optimal-design criterion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Criterion {
    /// A-optimal: the summed variance of the (scaled) parameters, `trace(F^-1)`.
    A,
    /// D-optimal: the volume of the confidence ellipsoid, `det F` (maximised).
    #[default]
    D,
    /// K: the condition number of the regressor, `sqrt(cond F)`.
    K,
    /// N: noise amplification index `mu_min^2 / mu_max` (maximised).
    N,
    /// The source's check `sigma_max^2 / sigma_min` (minimised).
    Dressler,
}

impl Criterion {
    /// Every criterion.
    pub const ALL: [Criterion; 5] = [Criterion::A, Criterion::D, Criterion::K, Criterion::N, Criterion::Dressler];

    /// Short name (`A`, `D`, `K`, `N`, `Dressler`).
    pub fn name(self) -> &'static str {
        match self {
            Criterion::A => "A",
            Criterion::D => "D",
            Criterion::K => "K",
            Criterion::N => "N",
            Criterion::Dressler => "Dressler",
        }
    }

    /// What the value means, with its direction.
    pub fn describe(self) -> &'static str {
        match self {
            Criterion::A => "trace(F^-1), smaller is better",
            Criterion::D => "ln det F, larger is better",
            Criterion::K => "cond(A) = sigma_max / sigma_min, smaller is better",
            Criterion::N => "noise amplification index sigma_min^2 / sigma_max, larger is better",
            Criterion::Dressler => "sigma_max^2 / sigma_min, smaller is better",
        }
    }

    /// Whether the eigenvalues of `F` are needed (no closed-form low-rank update).
    pub fn is_spectral(self) -> bool {
        matches!(self, Criterion::K | Criterion::N | Criterion::Dressler)
    }

    /// The loss from the extreme eigenvalues of `F` (spectral criteria; also valid for A and D
    /// only through [`Criterion::loss`]).
    pub fn spectral_loss(self, lambda_min: f64, lambda_max: f64) -> f64 {
        if !(lambda_min > RANK_TOL * lambda_max && lambda_max > 0.0) {
            return f64::INFINITY;
        }
        match self {
            Criterion::K => (lambda_max / lambda_min).sqrt(),
            Criterion::N => -lambda_min / lambda_max.sqrt(),
            Criterion::Dressler => lambda_max / lambda_min.sqrt(),
            // Not spectral: callers use the eigenvalue sums.
            Criterion::A | Criterion::D => f64::NAN,
        }
    }

    /// The loss of an information matrix (symmetric, positive semi-definite); infinite when it
    /// is singular (or holds non-finite entries).
    pub fn loss(self, f: &DMatrix<f64>) -> f64 {
        match Spectrum::of(f) {
            Some(s) => self.loss_of(&s),
            None => f64::INFINITY,
        }
    }

    /// The loss from a spectrum.
    pub fn loss_of(self, s: &Spectrum) -> f64 {
        if !s.full_rank() {
            return f64::INFINITY;
        }
        match self {
            Criterion::A => s.eigenvalues.iter().map(|l| 1.0 / l).sum(),
            Criterion::D => -s.eigenvalues.iter().map(|l| l.ln()).sum::<f64>(),
            _ => self.spectral_loss(s.min(), s.max()),
        }
    }

    /// The criterion's value in the source's form from a loss (A: trace(F^-1); D: ln det F;
    /// K: cond; N: sigma_min^2 / sigma_max; Dressler: sigma_max^2 / sigma_min).
    pub fn value(self, loss: f64) -> f64 {
        match self {
            Criterion::D | Criterion::N => -loss,
            _ => loss,
        }
    }
}

impl std::fmt::Display for Criterion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Criterion {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "a" => Ok(Criterion::A),
            "d" => Ok(Criterion::D),
            "k" => Ok(Criterion::K),
            "n" => Ok(Criterion::N),
            "dressler" => Ok(Criterion::Dressler),
            _ => Err(format!("unknown criterion '{s}' (a, d, k, n, dressler)")),
        }
    }
}

/// The eigenvalues of an information matrix, ascending.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Spectrum {
    /// Eigenvalues, ascending (negative round-off clamped to 0).
    pub eigenvalues: Vec<f64>,
}

impl Spectrum {
    /// The spectrum of a symmetric matrix (its upper and lower triangles averaged); `None` for
    /// an empty or non-finite matrix.
    pub fn of(f: &DMatrix<f64>) -> Option<Self> {
        if f.nrows() == 0 || f.nrows() != f.ncols() || f.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let sym = (f + f.transpose()) * 0.5;
        let mut eigenvalues: Vec<f64> = SymmetricEigen::new(sym).eigenvalues.iter().map(|l| l.max(0.0)).collect();
        eigenvalues.sort_by(|a, b| a.total_cmp(b));
        Some(Self { eigenvalues })
    }

    /// Smallest eigenvalue.
    pub fn min(&self) -> f64 {
        self.eigenvalues.first().copied().unwrap_or(0.0)
    }

    /// Largest eigenvalue.
    pub fn max(&self) -> f64 {
        self.eigenvalues.last().copied().unwrap_or(0.0)
    }

    /// Numerical rank (eigenvalues above [`RANK_TOL`] times the largest).
    pub fn rank(&self) -> usize {
        let m = self.max();
        self.eigenvalues.iter().filter(|l| **l > RANK_TOL * m && **l > 0.0).count()
    }

    /// Whether every eigenvalue counts.
    pub fn full_rank(&self) -> bool {
        self.max() > 0.0 && self.rank() == self.eigenvalues.len()
    }

    /// Singular values of the whitened regressor (`sqrt(lambda)`), descending.
    pub fn singular_values(&self) -> Vec<f64> {
        self.eigenvalues.iter().rev().map(|l| l.sqrt()).collect()
    }
}

/// Every criterion and the spectrum of one information matrix, for reports.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CriteriaSummary {
    /// Number of parameters.
    pub n_params: usize,
    /// Numerical rank.
    pub rank: usize,
    /// Largest singular value of the whitened regressor.
    pub sigma_max: f64,
    /// Smallest singular value.
    pub sigma_min: f64,
    /// A: `trace(F^-1)`.
    pub a: f64,
    /// D: `ln det F`.
    pub ln_det: f64,
    /// K: `sigma_max / sigma_min`.
    pub condition: f64,
    /// N: `sigma_min^2 / sigma_max`.
    pub noise_amplification: f64,
    /// Dressler: `sigma_max^2 / sigma_min`.
    pub dressler: f64,
}

impl CriteriaSummary {
    /// The summary of `f` (`None` for an empty or non-finite matrix).
    pub fn of(f: &DMatrix<f64>) -> Option<Self> {
        let s = Spectrum::of(f)?;
        let v = |c: Criterion| c.value(c.loss_of(&s));
        Some(Self {
            n_params: s.eigenvalues.len(),
            rank: s.rank(),
            sigma_max: s.max().sqrt(),
            sigma_min: s.min().sqrt(),
            a: v(Criterion::A),
            ln_det: v(Criterion::D),
            condition: v(Criterion::K),
            noise_amplification: v(Criterion::N),
            dressler: v(Criterion::Dressler),
        })
    }

    /// The value of one criterion.
    pub fn get(&self, c: Criterion) -> f64 {
        match c {
            Criterion::A => self.a,
            Criterion::D => self.ln_det,
            Criterion::K => self.condition,
            Criterion::N => self.noise_amplification,
            Criterion::Dressler => self.dressler,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_of_a_diagonal_matrix() {
        let f = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![4.0, 1.0, 16.0]));
        let s = CriteriaSummary::of(&f).unwrap();
        assert!((s.a - (0.25 + 1.0 + 1.0 / 16.0)).abs() < 1e-12);
        assert!((s.ln_det - 64f64.ln()).abs() < 1e-12);
        assert!((s.condition - 4.0).abs() < 1e-12);
        assert!((s.noise_amplification - 1.0 / 4.0).abs() < 1e-12);
        assert!((s.dressler - 16.0).abs() < 1e-12);
        let sing = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![1.0, 0.0]));
        for c in Criterion::ALL {
            assert!(c.loss(&sing).is_infinite(), "{c}");
        }
    }
}
