//! A problem posed in blocks: named parameter blocks on manifolds, residual blocks over some of
//! them with a robust loss each, and the index that names every number of the state and of the
//! measurements.

use std::sync::Arc;

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::dense::{self, DenseProblem, LmOptions, Summary};
use crate::{Euclidean, Loss, LsqError, Manifold, Residual, Result};

/// The handle of a parameter block.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct BlockId(pub usize);

/// The handle of a residual block.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct ResidualId(pub usize);

/// One parameter block: its stored values, the manifold they live on, whether it is held fixed,
/// and the typical size of a step in each tangent coordinate (for scaling).
#[derive(Clone, Debug)]
pub struct ParameterBlock {
    /// Name, unique in the problem (`"camera0"`, `"frame"`, `"view17"`).
    pub name: String,
    /// Stored (ambient) values.
    pub values: Vec<f64>,
    /// The manifold.
    pub manifold: Arc<dyn Manifold>,
    /// Held at its value.
    pub constant: bool,
    /// Typical step per tangent coordinate (1 unless set).
    pub scales: Vec<f64>,
    /// Names of the tangent coordinates (the manifold's unless set).
    pub coordinate_names: Vec<String>,
}

struct ResidualEntry {
    name: String,
    residual: Box<dyn Residual>,
    blocks: Vec<BlockId>,
    loss: Loss,
}

/// Which back end solves a [`Problem`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Backend {
    /// Dense Levenberg-Marquardt for up to [`SolverOptions::dense_limit`] free coordinates,
    /// Ceres beyond.
    #[default]
    Auto,
    /// The dense Levenberg-Marquardt of [`crate::dense`].
    Dense,
    /// Ceres (sparse Schur), in rounds re-linearised at the current point for manifold blocks.
    Ceres,
}

/// The linear solver Ceres uses for its steps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CeresLinearSolver {
    /// Dense QR of the whole Jacobian (small problems, the most accurate).
    DenseQr,
    /// Dense Schur complement over Ceres' automatic elimination ordering (bundle adjustments).
    #[default]
    DenseSchur,
}

/// Options of [`Problem::solve`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SolverOptions {
    /// Back end.
    pub backend: Backend,
    /// Largest number of free tangent coordinates [`Backend::Auto`] gives the dense back end.
    pub dense_limit: usize,
    /// Maximum iterations (per Ceres round).
    pub max_iterations: usize,
    /// Relative cost decrease that counts as converged.
    pub cost_tolerance: f64,
    /// Scaled step size that counts as converged.
    pub step_tolerance: f64,
    /// Initial Levenberg-Marquardt damping (dense back end).
    pub initial_lambda: f64,
    /// Ceres rounds at most (each re-linearises the manifold blocks at the current point).
    pub max_rounds: usize,
    /// Threads Ceres may use.
    pub threads: usize,
    /// Ceres' linear solver.
    pub ceres_linear_solver: CeresLinearSolver,
}

impl Default for SolverOptions {
    fn default() -> Self {
        Self {
            backend: Backend::Auto,
            dense_limit: 200,
            max_iterations: 100,
            cost_tolerance: 1e-12,
            step_tolerance: 1e-10,
            initial_lambda: 1e-3,
            max_rounds: 10,
            threads: 1,
            ceres_linear_solver: CeresLinearSolver::DenseSchur,
        }
    }
}

impl SolverOptions {
    /// Checks every option.
    pub fn validate(&self) -> Result<()> {
        self.lm().validate()?;
        if self.max_rounds == 0 || self.threads == 0 {
            return Err(LsqError::Setup("solver options: max_rounds and threads must be at least 1".into()));
        }
        Ok(())
    }

    fn lm(&self) -> LmOptions {
        LmOptions {
            max_iterations: self.max_iterations,
            cost_tolerance: self.cost_tolerance,
            step_tolerance: self.step_tolerance,
            initial_lambda: self.initial_lambda,
            loss: Loss::Squared,
        }
    }
}

/// Where one free block sits in the state vector (its tangent coordinates).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StateEntry {
    /// The block.
    pub block: BlockId,
    /// Its name.
    pub name: String,
    /// First state coordinate.
    pub offset: usize,
    /// Number of coordinates (tangent size).
    pub size: usize,
    /// The coordinates' names.
    pub coordinates: Vec<String>,
}

/// The state index: every free coordinate by block and name (as mrcal's `state_index_*`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StateIndex {
    /// Free blocks in state order.
    pub entries: Vec<StateEntry>,
}

impl StateIndex {
    /// Number of free coordinates.
    pub fn len(&self) -> usize {
        self.entries.last().map_or(0, |e| e.offset + e.size)
    }
    /// Whether nothing is free.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// First state coordinate of a block (`None` when it is constant).
    pub fn offset(&self, block: BlockId) -> Option<usize> {
        self.entries.iter().find(|e| e.block == block).map(|e| e.offset)
    }
    /// The first state coordinate of every block of a problem with `n_blocks` blocks (`None` for
    /// the constant ones), in one pass.
    pub(crate) fn block_offsets(&self, n_blocks: usize) -> Vec<Option<usize>> {
        let mut out = vec![None; n_blocks];
        for e in &self.entries {
            out[e.block.0] = Some(e.offset);
        }
        out
    }

    /// The state coordinate of a block's named coordinate.
    pub fn coordinate(&self, block: BlockId, name: &str) -> Option<usize> {
        let e = self.entries.iter().find(|e| e.block == block)?;
        e.coordinates.iter().position(|c| c == name).map(|i| e.offset + i)
    }
    /// `"block.coordinate"` for every state coordinate, in order.
    pub fn names(&self) -> Vec<String> {
        self.entries.iter().flat_map(|e| e.coordinates.iter().map(move |c| format!("{}.{c}", e.name))).collect()
    }
}

/// Where one residual block sits in the residual vector.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeasurementEntry {
    /// The residual block.
    pub residual: ResidualId,
    /// Its name.
    pub name: String,
    /// First row.
    pub offset: usize,
    /// Rows.
    pub size: usize,
    /// The rows' names.
    pub rows: Vec<String>,
}

/// The measurement index: every residual row by block and name.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MeasurementIndex {
    /// Residual blocks in order.
    pub entries: Vec<MeasurementEntry>,
}

impl MeasurementIndex {
    /// Number of residual rows.
    pub fn len(&self) -> usize {
        self.entries.last().map_or(0, |e| e.offset + e.size)
    }
    /// Whether there are no residuals.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// First row of a residual block.
    pub fn offset(&self, residual: ResidualId) -> Option<usize> {
        self.entries.get(residual.0).map(|e| e.offset)
    }
    /// `"block.row"` for every residual row, in order.
    pub fn names(&self) -> Vec<String> {
        self.entries.iter().flat_map(|e| e.rows.iter().map(move |r| format!("{}.{r}", e.name))).collect()
    }
}

/// The solution of [`Problem::solve`]: the summary, and the problem's blocks hold the values.
#[derive(Clone, Debug)]
pub struct Solution {
    /// How it went.
    pub summary: Summary,
    /// The back end that solved it.
    pub backend: Backend,
}

/// Covariance of the free state at the current point (see [`Problem::covariance`]).
#[derive(Clone, Debug)]
pub struct Covariance {
    /// `s0^2 (J^T J)^-1` over the state index (tangent units of each block).
    pub matrix: DMatrix<f64>,
    /// A-posteriori standard deviation of unit weight.
    pub s0: f64,
    /// The state the matrix is over.
    pub index: StateIndex,
}

impl Covariance {
    /// Standard deviation of every state coordinate.
    pub fn std(&self) -> Vec<f64> {
        (0..self.matrix.nrows()).map(|i| self.matrix[(i, i)].max(0.0).sqrt()).collect()
    }
    /// The covariance block of one parameter block (`None` when it is constant).
    pub fn block(&self, id: BlockId) -> Option<DMatrix<f64>> {
        let e = self.index.entries.iter().find(|e| e.block == id)?;
        Some(self.matrix.view((e.offset, e.offset), (e.size, e.size)).into_owned())
    }
}

/// A least-squares problem in blocks.
#[derive(Default)]
pub struct Problem {
    blocks: Vec<ParameterBlock>,
    residuals: Vec<ResidualEntry>,
}

impl std::fmt::Debug for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Problem")
            .field("blocks", &self.blocks.iter().map(|b| &b.name).collect::<Vec<_>>())
            .field("residual_blocks", &self.residuals.len())
            .finish()
    }
}

impl Problem {
    /// An empty problem.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a parameter block; its values must lie on the manifold and its name must be new.
    pub fn add_block(&mut self, name: &str, values: Vec<f64>, manifold: Arc<dyn Manifold>) -> Result<BlockId> {
        if self.blocks.iter().any(|b| b.name == name) {
            return Err(LsqError::Setup(format!("parameter block '{name}' added twice")));
        }
        if values.len() != manifold.ambient_size() || !manifold.contains(&values) {
            return Err(LsqError::Setup(format!(
                "parameter block '{name}': {} values {values:?} are not a point of the {} manifold",
                values.len(),
                manifold.name()
            )));
        }
        let k = manifold.tangent_size();
        let coordinate_names = manifold.tangent_names();
        self.blocks.push(ParameterBlock {
            name: name.into(),
            values,
            manifold,
            constant: false,
            scales: vec![1.0; k],
            coordinate_names,
        });
        Ok(BlockId(self.blocks.len() - 1))
    }

    /// Adds a Euclidean block.
    pub fn add_euclidean(&mut self, name: &str, values: Vec<f64>) -> Result<BlockId> {
        let n = values.len();
        self.add_block(name, values, Arc::new(Euclidean { n }))
    }

    fn check_id(&self, id: BlockId) -> Result<&ParameterBlock> {
        self.blocks.get(id.0).ok_or_else(|| LsqError::Setup(format!("no parameter block {}", id.0)))
    }

    /// Holds a block at its value (or frees it again).
    pub fn set_constant(&mut self, id: BlockId, constant: bool) -> Result<()> {
        self.check_id(id)?;
        self.blocks[id.0].constant = constant;
        Ok(())
    }

    /// Sets the typical step of each tangent coordinate (positive, finite).
    pub fn set_scales(&mut self, id: BlockId, scales: Vec<f64>) -> Result<()> {
        let b = self.check_id(id)?;
        if scales.len() != b.manifold.tangent_size() || scales.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(LsqError::Setup(format!("parameter block '{}': bad scales {scales:?}", b.name)));
        }
        self.blocks[id.0].scales = scales;
        Ok(())
    }

    /// Names the tangent coordinates of a block (`"fx_px"`, `"k1"`, ...).
    pub fn set_coordinate_names(&mut self, id: BlockId, names: Vec<String>) -> Result<()> {
        let b = self.check_id(id)?;
        if names.len() != b.manifold.tangent_size() {
            return Err(LsqError::Setup(format!("parameter block '{}': {} names", b.name, names.len())));
        }
        self.blocks[id.0].coordinate_names = names;
        Ok(())
    }

    /// Adds a residual block over `blocks` (in the order its [`Residual::evaluate`] expects).
    pub fn add_residual(
        &mut self,
        name: &str,
        residual: Box<dyn Residual>,
        blocks: &[BlockId],
        loss: Loss,
    ) -> Result<ResidualId> {
        loss.validate()?;
        for &b in blocks {
            self.check_id(b)?;
        }
        if residual.n_residuals() == 0 {
            return Err(LsqError::Setup(format!("residual block '{name}' has no rows")));
        }
        self.residuals.push(ResidualEntry { name: name.into(), residual, blocks: blocks.to_vec(), loss });
        Ok(ResidualId(self.residuals.len() - 1))
    }

    /// A parameter block.
    pub fn block(&self, id: BlockId) -> &ParameterBlock {
        &self.blocks[id.0]
    }

    /// Every parameter block, in the order they were added.
    pub fn blocks(&self) -> &[ParameterBlock] {
        &self.blocks
    }

    /// The state index over the free blocks.
    pub fn state_index(&self) -> StateIndex {
        let mut entries = Vec::new();
        let mut offset = 0;
        for (k, b) in self.blocks.iter().enumerate() {
            if b.constant {
                continue;
            }
            let size = b.manifold.tangent_size();
            entries.push(StateEntry {
                block: BlockId(k),
                name: b.name.clone(),
                offset,
                size,
                coordinates: b.coordinate_names.clone(),
            });
            offset += size;
        }
        StateIndex { entries }
    }

    /// The measurement index over the residual blocks.
    pub fn measurement_index(&self) -> MeasurementIndex {
        let mut entries = Vec::new();
        let mut offset = 0;
        for (k, r) in self.residuals.iter().enumerate() {
            let size = r.residual.n_residuals();
            entries.push(MeasurementEntry {
                residual: ResidualId(k),
                name: r.name.clone(),
                offset,
                size,
                rows: r.residual.row_names(),
            });
            offset += size;
        }
        MeasurementIndex { entries }
    }

    /// `(first row, rows, loss)` of every residual block: the measurement index without the
    /// names, for the solvers' inner loops.
    pub(crate) fn row_layout(&self) -> Vec<(usize, usize, Loss)> {
        let mut offset = 0;
        self.residuals
            .iter()
            .map(|e| {
                let size = e.residual.n_residuals();
                offset += size;
                (offset - size, size, e.loss)
            })
            .collect()
    }

    /// Residuals and (optionally) the Jacobian over the state index at `values` (one ambient
    /// vector per block).
    fn evaluate_at(
        &self,
        values: &[Vec<f64>],
        index: &StateIndex,
        with_jacobian: bool,
    ) -> Result<(DVector<f64>, Option<DMatrix<f64>>)> {
        let layout = self.row_layout();
        let n_rows = layout.last().map_or(0, |&(o, n, _)| o + n);
        let mut r = DVector::zeros(n_rows);
        let mut jac = with_jacobian.then(|| DMatrix::zeros(n_rows, index.len()));
        let offsets = index.block_offsets(self.blocks.len());
        for (entry, &(row, size, _)) in self.residuals.iter().zip(&layout) {
            let params: Vec<&[f64]> = entry.blocks.iter().map(|b| values[b.0].as_slice()).collect();
            let mut rows = vec![0.0; size];
            let mut jacs: Option<Vec<Option<DMatrix<f64>>>> = jac.as_ref().map(|_| {
                entry
                    .blocks
                    .iter()
                    .map(|b| offsets[b.0].map(|_| DMatrix::zeros(size, self.blocks[b.0].manifold.tangent_size())))
                    .collect()
            });
            entry.residual.evaluate(&params, &mut rows, jacs.as_deref_mut())?;
            r.rows_mut(row, size).copy_from_slice(&rows);
            if let (Some(jac), Some(jacs)) = (jac.as_mut(), jacs) {
                for (b, jb) in entry.blocks.iter().zip(jacs) {
                    if let (Some(off), Some(jb)) = (offsets[b.0], jb) {
                        let mut view = jac.view_mut((row, off), (size, jb.ncols()));
                        view += &jb;
                    }
                }
            }
        }
        Ok((r, jac))
    }

    fn current_values(&self) -> Vec<Vec<f64>> {
        self.blocks.iter().map(|b| b.values.clone()).collect()
    }

    /// Whitened residuals at the current values, in measurement-index order.
    pub fn residuals(&self) -> Result<DVector<f64>> {
        Ok(self.evaluate_at(&self.current_values(), &self.state_index(), false)?.0)
    }

    /// Residuals and Jacobian (over the state index) at the current values.
    pub fn linearize(&self) -> Result<(DVector<f64>, DMatrix<f64>)> {
        let (r, j) = self.evaluate_at(&self.current_values(), &self.state_index(), true)?;
        Ok((r, j.expect("asked for")))
    }

    /// The robust cost `sum_b rho_b(|r_b|^2) / 2` at the current values.
    pub fn cost(&self) -> Result<f64> {
        let r = self.residuals()?;
        Ok(self
            .row_layout()
            .into_iter()
            .map(|(row, size, loss)| loss.rho(r.rows(row, size).norm_squared()).0)
            .sum::<f64>()
            * 0.5)
    }

    /// Solves the problem in place (the blocks hold the solution afterwards).
    pub fn solve(&mut self, opts: &SolverOptions) -> Result<Solution> {
        opts.validate()?;
        if self.residuals.is_empty() {
            return Err(LsqError::Setup("the problem has no residual blocks".into()));
        }
        let index = self.state_index();
        if index.is_empty() {
            return Err(LsqError::Setup("every parameter block is constant: nothing to solve for".into()));
        }
        let backend = match opts.backend {
            Backend::Auto if index.len() <= opts.dense_limit => Backend::Dense,
            Backend::Auto => Backend::Ceres,
            b => b,
        };
        let summary = match backend {
            Backend::Ceres => crate::ceres::solve(self, &index, opts)?,
            _ => {
                let adapter = DenseAdapter { problem: self, index: &index };
                let x0 = adapter.stack(&self.current_values());
                let res = dense::solve(&adapter, &x0, &opts.lm())?;
                let values = adapter.unstack(&res.x);
                for (b, v) in self.blocks.iter_mut().zip(values) {
                    b.values = v;
                }
                res.summary
            }
        };
        Ok(Solution { summary, backend })
    }

    /// Covariance of the free state at the current values, `s0^2 (J^T J)^-1`.
    pub fn covariance(&self) -> Result<Covariance> {
        let (r, j) = self.linearize()?;
        let (matrix, s0) = crate::covariance(&j, &r)?;
        Ok(Covariance { matrix, s0, index: self.state_index() })
    }

    /// Covariance of the free blocks in `global` with every other free block marginalised by the
    /// Schur complement (each of the others must be a *local* block: the residuals that touch it
    /// touch no other local block). The matrix is over `global`'s coordinates in the given order.
    pub fn schur_covariance(&self, global: &[BlockId]) -> Result<Covariance> {
        let full = self.state_index();
        let (r, j) = self.linearize()?;
        let free_global: Vec<&StateEntry> = global
            .iter()
            .map(|g| {
                full.entries
                    .iter()
                    .find(|e| e.block == *g)
                    .ok_or_else(|| LsqError::Setup(format!("block {} is constant or unknown", g.0)))
            })
            .collect::<Result<_>>()?;
        let locals: Vec<&StateEntry> = full.entries.iter().filter(|e| !global.contains(&e.block)).collect();
        // Local blocks must not share residuals.
        for e in &self.residuals {
            let n_local = e.blocks.iter().filter(|b| locals.iter().any(|l| l.block == **b)).count();
            if n_local > 1 {
                return Err(LsqError::Setup(format!(
                    "residual block '{}' touches {n_local} local blocks: the Schur complement needs at most one",
                    e.name
                )));
            }
        }
        let order: Vec<&StateEntry> = free_global.iter().copied().chain(locals.iter().copied()).collect();
        let mut permuted = DMatrix::zeros(j.nrows(), j.ncols());
        let mut col = 0;
        let mut entries = Vec::new();
        for e in &order {
            permuted.columns_mut(col, e.size).copy_from(&j.columns(e.offset, e.size));
            if entries.len() < free_global.len() {
                entries.push(StateEntry { offset: col, ..(*e).clone() });
            }
            col += e.size;
        }
        let n_global: usize = free_global.iter().map(|e| e.size).sum();
        let sizes: Vec<usize> = locals.iter().map(|e| e.size).collect();
        let (matrix, s0) = crate::schur_covariance(&permuted, &r, n_global, &sizes)?;
        Ok(Covariance { matrix, s0, index: StateIndex { entries } })
    }

    pub(crate) fn residual_entries(&self) -> impl Iterator<Item = (&str, &dyn Residual, &[BlockId], Loss)> {
        self.residuals.iter().map(|e| (e.name.as_str(), e.residual.as_ref(), e.blocks.as_slice(), e.loss))
    }

    pub(crate) fn set_all_values(&mut self, values: Vec<Vec<f64>>) {
        for (b, v) in self.blocks.iter_mut().zip(values) {
            b.values = v;
        }
    }
}

/// The block problem seen by the dense back end: `x` stacks the ambient values of the free
/// blocks, a step is in their tangent spaces.
struct DenseAdapter<'a> {
    problem: &'a Problem,
    index: &'a StateIndex,
}

impl DenseAdapter<'_> {
    fn stack(&self, values: &[Vec<f64>]) -> Vec<f64> {
        self.index.entries.iter().flat_map(|e| values[e.block.0].iter().copied()).collect()
    }

    fn unstack(&self, x: &[f64]) -> Vec<Vec<f64>> {
        let mut values = self.problem.current_values();
        let mut k = 0;
        for e in &self.index.entries {
            let n = values[e.block.0].len();
            values[e.block.0].copy_from_slice(&x[k..k + n]);
            k += n;
        }
        values
    }
}

impl DenseProblem for DenseAdapter<'_> {
    fn n_params(&self) -> usize {
        self.index.len()
    }
    fn n_ambient(&self) -> usize {
        self.index.entries.iter().map(|e| self.problem.blocks[e.block.0].manifold.ambient_size()).sum()
    }
    fn n_residuals(&self) -> usize {
        self.problem.row_layout().last().map_or(0, |&(o, n, _)| o + n)
    }
    fn residual_blocks(&self, _loss: &Loss) -> Vec<(usize, usize, Loss)> {
        self.problem.row_layout()
    }
    fn residuals(&self, x: &[f64]) -> Result<DVector<f64>> {
        Ok(self.problem.evaluate_at(&self.unstack(x), self.index, false)?.0)
    }
    fn jacobian(&self, x: &[f64]) -> Result<DMatrix<f64>> {
        Ok(self.problem.evaluate_at(&self.unstack(x), self.index, true)?.1.expect("asked for"))
    }
    fn scales(&self) -> Vec<f64> {
        self.index.entries.iter().flat_map(|e| self.problem.blocks[e.block.0].scales.iter().copied()).collect()
    }
    fn retract(&self, x: &[f64], dx: &[f64]) -> Vec<f64> {
        let mut out = x.to_vec();
        let (mut a, mut t) = (0, 0);
        for e in &self.index.entries {
            let m = &self.problem.blocks[e.block.0].manifold;
            let (na, nt) = (m.ambient_size(), m.tangent_size());
            m.plus(&x[a..a + na], &dx[t..t + nt], &mut out[a..a + na]);
            a += na;
            t += nt;
        }
        out
    }
}
