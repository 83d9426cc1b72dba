//! A pool of candidates (poses, samples) and their contributions to the Fisher information.
//!
//! Each candidate `k` contributes `F_k = R_k^T R_k`, where `R_k` holds its whitened,
//! column-scaled regressor rows (3 per measured position, 6 per force-sensor wrench, any number
//! per candidate). Build a pool from row blocks, from a regressor whose rows come in fixed
//! groups, or from per-candidate information matrices (factored here). The information of a
//! subset is the sum of its candidates' contributions.

use nalgebra::{DMatrix, SymmetricEigen};

use crate::design::criteria::Criterion;
use crate::error::{CalibError, Result};

/// Candidates with their regressor rows.
#[derive(Clone, Debug, PartialEq)]
pub struct InformationPool {
    n_params: usize,
    /// All rows, row-major, `n_params` each.
    rows: Vec<f64>,
    /// Rows of candidate `k`: `starts[k]..starts[k + 1]`.
    starts: Vec<usize>,
    names: Vec<String>,
}

impl InformationPool {
    /// A pool from one block of rows per candidate (all with `names.len()` columns).
    pub fn from_blocks(blocks: &[DMatrix<f64>], names: Vec<String>) -> Result<Self> {
        let p = names.len();
        if p == 0 {
            return Err(CalibError::Data("a design pool needs at least one parameter".into()));
        }
        let mut rows = Vec::new();
        let mut starts = vec![0];
        for (k, b) in blocks.iter().enumerate() {
            if b.ncols() != p {
                return Err(CalibError::Data(format!("candidate {}: {} columns for {p} parameters", k + 1, b.ncols())));
            }
            if b.iter().any(|v| !v.is_finite()) {
                return Err(CalibError::Data(format!("candidate {}: non-finite regressor entry", k + 1)));
            }
            for r in 0..b.nrows() {
                rows.extend(b.row(r).iter());
            }
            starts.push(starts[k] + b.nrows());
        }
        Ok(Self { n_params: p, rows, starts, names })
    }

    /// A pool from a regressor whose rows come in groups of `rows_per_candidate` (3 per
    /// measured position, 6 per wrench).
    pub fn from_grouped_rows(a: &DMatrix<f64>, rows_per_candidate: usize, names: Vec<String>) -> Result<Self> {
        if rows_per_candidate == 0 || !a.nrows().is_multiple_of(rows_per_candidate) {
            return Err(CalibError::Data(format!(
                "{} rows do not split into groups of {rows_per_candidate}",
                a.nrows()
            )));
        }
        let blocks: Vec<DMatrix<f64>> = (0..a.nrows() / rows_per_candidate)
            .map(|k| a.rows(k * rows_per_candidate, rows_per_candidate).into_owned())
            .collect();
        Self::from_blocks(&blocks, names)
    }

    /// A pool from per-candidate information contributions (symmetric positive semi-definite
    /// `p x p` matrices), factored as `sqrt(lambda_i) v_i^T` over their non-negligible
    /// eigenpairs.
    pub fn from_information(infos: &[DMatrix<f64>], names: Vec<String>) -> Result<Self> {
        let p = names.len();
        let mut blocks = Vec::with_capacity(infos.len());
        for (k, f) in infos.iter().enumerate() {
            if f.nrows() != p || f.ncols() != p {
                return Err(CalibError::Data(format!(
                    "candidate {}: a {}x{} information matrix for {p} parameters",
                    k + 1,
                    f.nrows(),
                    f.ncols()
                )));
            }
            if f.iter().any(|v| !v.is_finite()) {
                return Err(CalibError::Data(format!("candidate {}: non-finite information entry", k + 1)));
            }
            let e = SymmetricEigen::new((f + f.transpose()) * 0.5);
            let top = e.eigenvalues.iter().copied().fold(0.0, f64::max);
            if e.eigenvalues.iter().any(|l| *l < -1e-9 * top.max(1e-300)) {
                return Err(CalibError::Data(format!(
                    "candidate {}: the information matrix is not positive semi-definite",
                    k + 1
                )));
            }
            let keep: Vec<usize> = (0..p).filter(|&i| e.eigenvalues[i] > 1e-14 * top && top > 0.0).collect();
            let mut b = DMatrix::zeros(keep.len(), p);
            for (r, &i) in keep.iter().enumerate() {
                let s = e.eigenvalues[i].sqrt();
                for c in 0..p {
                    b[(r, c)] = s * e.eigenvectors[(c, i)];
                }
            }
            blocks.push(b);
        }
        Self::from_blocks(&blocks, names)
    }

    /// Number of candidates.
    pub fn len(&self) -> usize {
        self.starts.len() - 1
    }

    /// Whether the pool has no candidate.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Number of parameters (columns).
    pub fn n_params(&self) -> usize {
        self.n_params
    }

    /// Parameter names.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Number of rows of candidate `k`.
    pub fn block_len(&self, k: usize) -> usize {
        self.starts[k + 1] - self.starts[k]
    }

    /// The rows of candidate `k`, row-major.
    pub fn block(&self, k: usize) -> &[f64] {
        &self.rows[self.starts[k] * self.n_params..self.starts[k + 1] * self.n_params]
    }

    /// Adds `sign * R_k^T R_k` to `f`.
    pub fn accumulate(&self, k: usize, sign: f64, f: &mut DMatrix<f64>) {
        let p = self.n_params;
        for row in self.block(k).chunks_exact(p) {
            for j in 0..p {
                let s = sign * row[j];
                if s == 0.0 {
                    continue;
                }
                let col = &mut f.as_mut_slice()[j * p..(j + 1) * p];
                for (c, r) in col.iter_mut().zip(row) {
                    *c += s * r;
                }
            }
        }
    }

    /// The information `sum_k R_k^T R_k` of a subset (indices may repeat: a candidate measured
    /// twice counts twice).
    pub fn information(&self, subset: &[usize]) -> DMatrix<f64> {
        let mut f = DMatrix::zeros(self.n_params, self.n_params);
        for &k in subset {
            self.accumulate(k, 1.0, &mut f);
        }
        f
    }

    /// The criterion's loss of a subset (infinite when it does not determine every parameter).
    pub fn loss(&self, subset: &[usize], criterion: Criterion) -> f64 {
        criterion.loss(&self.information(subset))
    }

    /// Checks that every index is a candidate.
    pub fn check_indices(&self, subset: &[usize]) -> Result<()> {
        match subset.iter().find(|&&k| k >= self.len()) {
            Some(k) => Err(CalibError::Data(format!("candidate {k} is not in the pool of {}", self.len()))),
            None => Ok(()),
        }
    }
}
