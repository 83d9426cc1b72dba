//! Residual blocks: whitened residuals of some parameter blocks, with analytic Jacobians.

use nalgebra::DMatrix;

use crate::Result;

/// One residual block `r(x_1, ..., x_k)`, already whitened (divided by its standard deviations,
/// or multiplied by the inverse Cholesky factor of its covariance), so that its squared norm is a
/// chi-square term.
///
/// Jacobians are taken with respect to each block's *tangent* step at the current point,
/// `∂r(x_i ⊞ δ_i)/∂δ_i` at `δ_i = 0` (for Euclidean blocks the ordinary derivative). Every
/// implementation in the project is checked against central differences by
/// [`crate::check::check_residual`] in a test.
pub trait Residual: Send + Sync {
    /// Number of residuals.
    fn n_residuals(&self) -> usize;
    /// Evaluates the residuals at `params` (one ambient slice per block, in the order the block
    /// ids were given when the residual was added). When `jacobians` is given, each `Some` entry
    /// is a zeroed `n_residuals x tangent_size` matrix to fill; `None` entries (constant blocks)
    /// need not be computed.
    fn evaluate(
        &self,
        params: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut [Option<DMatrix<f64>>]>,
    ) -> Result<()>;
    /// Names of the residual rows (`"x"`, `"y"`, ...); by default their numbers.
    fn row_names(&self) -> Vec<String> {
        (0..self.n_residuals()).map(|i| i.to_string()).collect()
    }
}

/// A residual given by a function, differentiated numerically (central differences in the
/// tangent space, steps `1e-6` times the given scales). For prototypes and for terms whose
/// analytic derivative is not worth writing; the gradient checker passes it by construction, so
/// prefer analytic Jacobians for anything that matters for speed.
pub struct NumericResidual<F> {
    n: usize,
    f: F,
    manifolds: Vec<std::sync::Arc<dyn crate::Manifold>>,
    steps: Vec<Vec<f64>>,
}

impl<F> NumericResidual<F>
where
    F: Fn(&[&[f64]], &mut [f64]) -> Result<()> + Send + Sync,
{
    /// A residual of `n` rows computed by `f`, over blocks on `manifolds`, with tangent steps
    /// `steps[k][i]` for the central differences.
    pub fn new(n: usize, manifolds: Vec<std::sync::Arc<dyn crate::Manifold>>, steps: Vec<Vec<f64>>, f: F) -> Self {
        Self { n, f, manifolds, steps }
    }
}

impl<F> Residual for NumericResidual<F>
where
    F: Fn(&[&[f64]], &mut [f64]) -> Result<()> + Send + Sync,
{
    fn n_residuals(&self) -> usize {
        self.n
    }
    fn evaluate(
        &self,
        params: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut [Option<DMatrix<f64>>]>,
    ) -> Result<()> {
        (self.f)(params, residuals)?;
        let Some(jacs) = jacobians else { return Ok(()) };
        let mut owned: Vec<Vec<f64>> = params.iter().map(|p| p.to_vec()).collect();
        let (mut rp, mut rm) = (vec![0.0; self.n], vec![0.0; self.n]);
        for (k, jac) in jacs.iter_mut().enumerate() {
            let Some(jac) = jac else { continue };
            let m = &self.manifolds[k];
            let mut delta = vec![0.0; m.tangent_size()];
            for i in 0..m.tangent_size() {
                let h = self.steps[k][i];
                for (sign, out) in [(1.0, &mut rp), (-1.0, &mut rm)] {
                    delta[i] = sign * h;
                    m.plus(params[k], &delta, &mut owned[k]);
                    let views: Vec<&[f64]> = owned.iter().map(|v| v.as_slice()).collect();
                    (self.f)(&views, out)?;
                }
                delta[i] = 0.0;
                owned[k].copy_from_slice(params[k]);
                for r in 0..self.n {
                    jac[(r, i)] = (rp[r] - rm[r]) / (2.0 * h);
                }
            }
        }
        Ok(())
    }
}
