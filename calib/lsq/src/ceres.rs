//! The Ceres back end for large sparse problems (bundle adjustments: hundreds of pose blocks).
//!
//! The Rust binding of Ceres takes Euclidean parameter blocks only, so each free block is handed
//! to Ceres as its tangent step `δ` around the current point `x0` (the cost sees `x0 ⊞ δ`), and
//! the solve runs in rounds: after each, `x0 ← x0 ⊞ δ` and the steps restart from zero, until the
//! manifold blocks stop moving. Within a round the Jacobian given for `δ ≠ 0` is the tangent
//! Jacobian at `x0 ⊞ δ`, exact at `δ = 0`, so the final round, which barely moves, is exact.

use ceres_solver::solver::LinearSolverType;
use ceres_solver::{CostFunctionType, NllsProblem, ParameterBlockOrIndex, SolverOptions as CeresOptions};
use nalgebra::DMatrix;

use crate::dense::{Summary, Termination};
use crate::problem::{CeresLinearSolver, SolverOptions, StateIndex};
use crate::{LsqError, Problem, Result};

/// Whether Ceres' own log lines reach stderr. Ceres logs through its bundled glog, unconditionally
/// for some messages ("Linear solver failure. Failed to compute a step", "Terminating: Initial
/// residual and Jacobian evaluation failed"), also on runs whose result is fine: the solver's
/// outcome is in the [`Summary`] this crate returns, so by default only glog's fatal messages
/// are shown; `shown` (a command's `--verbose`) lets every level through. Set it once, before
/// solving (it writes glog's process-wide `minloglevel` flag).
pub fn show_ceres_log(shown: bool) {
    extern "C" {
        // glog's `int32 FLAGS_minloglevel` (namespace fLI), statically linked from the bundled
        // glog that ceres-solver-src builds (without gflags, so the flag is a plain global).
        #[link_name = "_ZN3fLI17FLAGS_minloglevelE"]
        static mut GLOG_MINLOGLEVEL: i32;
    }
    // glog's severities: INFO 0, WARNING 1, ERROR 2, FATAL 3.
    let level = if shown { 0 } else { 3 };
    // SAFETY: the symbol is glog's 32-bit integer flag, defined and initialised by the linked
    // glog before main; it is written through a raw pointer (no reference to the mutable
    // static), and the callers set it before any solver thread runs.
    unsafe {
        std::ptr::addr_of_mut!(GLOG_MINLOGLEVEL).write(level);
    }
}

fn failed(detail: impl std::fmt::Display) -> LsqError {
    LsqError::Diverged(format!("Ceres: {detail}"))
}

/// What one Ceres round did.
struct Round {
    initial_cost: f64,
    final_cost: f64,
    iterations: usize,
    report: String,
    /// Largest tangent step of a manifold (non-Euclidean) block.
    max_step: f64,
    /// The blocks' values after the round.
    values: Vec<Vec<f64>>,
}

/// One Ceres round.
fn round(problem: &Problem, index: &StateIndex, opts: &SolverOptions) -> Result<Round> {
    let blocks = problem.blocks();
    let x0: Vec<Vec<f64>> = blocks.iter().map(|b| b.values.clone()).collect();
    let free = index.block_offsets(blocks.len());
    let mut ceres_index: Vec<Option<usize>> = vec![None; blocks.len()];
    let mut next = 0usize;
    let mut nlls = NllsProblem::new();
    let mut n_added = 0usize;
    for (_name, residual, ids, loss) in problem.residual_entries() {
        let free_ids: Vec<usize> = ids.iter().map(|b| b.0).filter(|&k| free[k].is_some()).collect();
        if free_ids.is_empty() {
            continue;
        }
        let n_res = residual.n_residuals();
        let ids_all: Vec<usize> = ids.iter().map(|b| b.0).collect();
        let x0_ref = &x0;
        let free_ref = &free;
        let cost: CostFunctionType =
            Box::new(move |p: &[&[f64]], res: &mut [f64], jac: Option<&mut [Option<&mut [&mut [f64]]>]>| {
                // Ambient values of every block of this residual: x0 ⊞ δ for the free ones.
                let mut values: Vec<Vec<f64>> = Vec::with_capacity(ids_all.len());
                let mut slot = 0;
                for &k in &ids_all {
                    let b = &blocks[k];
                    if free_ref[k].is_some() {
                        let mut v = vec![0.0; b.manifold.ambient_size()];
                        b.manifold.plus(&x0_ref[k], p[slot], &mut v);
                        slot += 1;
                        values.push(v);
                    } else {
                        values.push(x0_ref[k].clone());
                    }
                }
                let views: Vec<&[f64]> = values.iter().map(|v| v.as_slice()).collect();
                let want = jac.is_some();
                let mut jacs: Vec<Option<DMatrix<f64>>> = ids_all
                    .iter()
                    .map(|&k| {
                        (want && free_ref[k].is_some())
                            .then(|| DMatrix::zeros(n_res, blocks[k].manifold.tangent_size()))
                    })
                    .collect();
                let ok = residual.evaluate(&views, res, want.then_some(jacs.as_mut_slice())).is_ok();
                if !ok || res.iter().any(|v| !v.is_finite()) {
                    return false;
                }
                if let Some(jac) = jac {
                    let mut slot = 0;
                    for (k, jk) in ids_all.iter().zip(&jacs) {
                        if free_ref[*k].is_none() {
                            continue;
                        }
                        if let (Some(d), Some(jk)) = (&mut jac[slot], jk) {
                            for r in 0..n_res {
                                for c in 0..jk.ncols() {
                                    d[r][c] = jk[(r, c)];
                                }
                            }
                        }
                        slot += 1;
                    }
                }
                true
            });
        let mut params: Vec<ParameterBlockOrIndex> = Vec::with_capacity(free_ids.len());
        for &k in &free_ids {
            match ceres_index[k] {
                Some(i) => params.push(i.into()),
                None => {
                    ceres_index[k] = Some(next);
                    next += 1;
                    params.push(vec![0.0; blocks[k].manifold.tangent_size()].into());
                }
            }
        }
        let mut builder = nlls.residual_block_builder().set_cost(cost, n_res).set_parameters(params);
        if let Some(l) = loss.to_ceres() {
            builder = builder.set_loss(l);
        }
        nlls = builder.build_into_problem().map_err(failed)?.0;
        n_added += 1;
    }
    if n_added == 0 {
        return Err(LsqError::Setup("no residual block touches a free parameter block".into()));
    }
    let options = CeresOptions::builder()
        .max_num_iterations(opts.max_iterations as i32)
        .function_tolerance(opts.cost_tolerance)
        .gradient_tolerance(1e-16)
        .parameter_tolerance(opts.step_tolerance)
        .linear_solver_type(match opts.ceres_linear_solver {
            CeresLinearSolver::DenseQr => LinearSolverType::DENSE_QR,
            CeresLinearSolver::DenseSchur => LinearSolverType::DENSE_SCHUR,
        })
        .num_threads(opts.threads as i32)
        .build()
        .map_err(failed)?;
    let solution = nlls.solve(&options).map_err(failed)?;
    let summary = &solution.summary;
    if !summary.is_solution_usable() {
        return Err(failed(summary.brief_report()));
    }
    let iterations = (summary.num_successful_steps() + summary.num_unsuccessful_steps()).max(0) as usize;
    let mut values = x0.clone();
    let mut max_step: f64 = 0.0;
    for (k, idx) in ceres_index.iter().enumerate() {
        let Some(i) = idx else { continue };
        let delta = &solution.parameters[*i];
        let b = &blocks[k];
        b.manifold.plus(&x0[k], delta, &mut values[k]);
        if b.manifold.name() != "euclidean" {
            max_step = max_step.max(delta.iter().fold(0.0f64, |a, v| a.max(v.abs())));
        }
    }
    Ok(Round {
        initial_cost: summary.initial_cost(),
        final_cost: summary.final_cost(),
        iterations,
        report: summary.brief_report(),
        max_step,
        values,
    })
}

/// Solves `problem` in place with Ceres.
pub(crate) fn solve(problem: &mut Problem, index: &StateIndex, opts: &SolverOptions) -> Result<Summary> {
    let mut initial_cost = None;
    let (mut final_cost, mut iterations, mut report) = (0.0, 0, String::new());
    let mut settled = false;
    for _ in 0..opts.max_rounds {
        let r = round(problem, index, opts)?;
        initial_cost.get_or_insert(r.initial_cost);
        final_cost = r.final_cost;
        iterations += r.iterations;
        report = r.report;
        problem.set_all_values(r.values);
        if r.max_step < 1e-10 || r.iterations == 0 {
            settled = true;
            break;
        }
    }
    let ceres_term = report.split("Termination:").nth(1).map(|s| s.trim().to_string()).unwrap_or_default();
    let stop = if !settled {
        Termination::IterationLimit
    } else if ceres_term.starts_with("CONVERGENCE") {
        Termination::CostTolerance
    } else if ceres_term.starts_with("NO_CONVERGENCE") {
        Termination::IterationLimit
    } else {
        Termination::Failed
    };
    // Residuals only: forming the dense Jacobian here would undo what the sparse back end is for
    // (the bundle adjustment computes its conditioning from its Schur complement).
    let r = problem.residuals()?;
    let downweighted_blocks = problem
        .row_layout()
        .into_iter()
        .filter(|&(row, size, loss)| loss.rho(r.rows(row, size).norm_squared()).1 < 0.5)
        .count();
    Ok(Summary {
        iterations,
        initial_cost: initial_cost.unwrap_or(final_cost),
        final_cost,
        termination: report,
        stop,
        converged: stop.converged(),
        downweighted_blocks,
        condition_number: None,
    })
}
