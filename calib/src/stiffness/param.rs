//! Parameterizations of the compliance model: the complete entries, and reduced parameters
//! that are linear combinations of them (symmetric pairs share one value, aggregated
//! compliances are carried by one representative).

use ferrocal_robot::stiffness::ComplianceLayout;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// One reduced parameter: `pi_complete += value * coef` over its basis entries.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReducedParam {
    /// Name (`link2.k26`, `joint3.k+link2.k66`).
    pub name: String,
    /// Unit.
    pub unit: String,
    /// Complete-model entries it sets, with their coefficients.
    pub basis: Vec<(usize, f64)>,
    /// Complete-model entries it stands for without setting them (aggregated ones).
    pub absorbed: Vec<usize>,
}

/// A list of reduced parameters over a complete layout.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Parameterization {
    /// Number of complete-model entries.
    pub n_complete: usize,
    /// The parameters.
    pub params: Vec<ReducedParam>,
}

impl Parameterization {
    /// Every complete entry as its own parameter.
    pub fn complete(layout: &ComplianceLayout) -> Self {
        let params = layout
            .params
            .iter()
            .enumerate()
            .map(|(i, p)| ReducedParam {
                name: p.name.clone(),
                unit: p.unit.clone(),
                basis: vec![(i, 1.0)],
                absorbed: vec![],
            })
            .collect();
        Self { n_complete: layout.len(), params }
    }

    /// Number of parameters.
    pub fn len(&self) -> usize {
        self.params.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.params.is_empty()
    }

    /// Names.
    pub fn names(&self) -> Vec<String> {
        self.params.iter().map(|p| p.name.clone()).collect()
    }

    /// Index of a parameter by name.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.params.iter().position(|p| p.name == name)
    }

    /// The `n_complete x len` matrix `B` with `pi_complete = B pi`.
    pub fn basis_matrix(&self) -> DMatrix<f64> {
        let mut b = DMatrix::zeros(self.n_complete, self.params.len());
        for (j, p) in self.params.iter().enumerate() {
            for &(i, c) in &p.basis {
                b[(i, j)] += c;
            }
        }
        b
    }

    /// Complete values from reduced ones.
    pub fn expand(&self, values: &[f64]) -> DVector<f64> {
        let mut out = DVector::zeros(self.n_complete);
        for (p, v) in self.params.iter().zip(values) {
            for &(i, c) in &p.basis {
                out[i] += c * v;
            }
        }
        out
    }

    /// Reduced values that best represent complete ones: each parameter's value is the
    /// coefficient-weighted mean of its entries, plus its absorbed entries (an aggregated
    /// parameter carries the sum of the compliances in series).
    pub fn project(&self, complete: &[f64]) -> Vec<f64> {
        self.params
            .iter()
            .map(|p| {
                let den: f64 = p.basis.iter().map(|(_, c)| c * c).sum();
                let own: f64 = p.basis.iter().map(|(i, c)| c * complete[*i]).sum::<f64>() / den.max(1e-300);
                own + p.absorbed.iter().map(|i| complete[*i]).sum::<f64>()
            })
            .collect()
    }

    /// The parameterization without the parameters at `drop` (indices).
    pub fn without(&self, drop: &[usize]) -> Self {
        Self {
            n_complete: self.n_complete,
            params: self.params.iter().enumerate().filter(|(i, _)| !drop.contains(i)).map(|(_, p)| p.clone()).collect(),
        }
    }
}
