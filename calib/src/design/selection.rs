//! Choosing candidates from a pool: greedy deletion (with the criterion against the count down to
//! the smallest set that keeps full rank) and exchange refinement.
//!
//! # Greedy deletion
//! Start from the whole pool; at every step remove the candidate whose removal degrades the
//! criterion least (Friedrich & Ihlenfeldt: 480 -> 30 poses, then on until the information loses
//! rank). Removing candidate `k` is a rank-`m_k` downdate `F' = F - R_k^T R_k` (one rank-one
//! downdate per row). With `G = F^-1`, `P = R_k G` and `M = I - P R_k^T` (an `m_k x m_k` matrix):
//!
//! - D: `ln det F' = ln det F + ln det M`;
//! - A: `trace(F'^-1) = trace(G) + trace(M^-1 P P^T)` (Woodbury);
//!
//! so each candidate costs `O(m_k p^2)` and a step `O(n m p^2)`; `F` itself is downdated and
//! re-factored (Cholesky, `O(p^3)`) once per step, so round-off does not accumulate. The
//! spectral criteria (K, N, Dressler) have no such identity: every candidate is screened with the
//! first-order eigenvalue change `lambda_i' ~ lambda_i - |R_k v_i|^2`, and the best few
//! (`screen`) are evaluated exactly. A removal is admissible only when `F'` keeps full rank
//! (`det M` above `1e-10`, then an exact check of the chosen one).
//!
//! # Exchange
//! For each chosen candidate in turn, the best replacement from the rest of the pool is found
//! with the same identities applied to `F_-i = F - R_i^T R_i` (an update, `M = I + P R_j^T`);
//! the swap is made when it improves the criterion. Sweeps repeat until none improves (or
//! `max_sweeps`).

use nalgebra::{Cholesky, DMatrix, Dyn, SymmetricEigen};
use serde::{Deserialize, Serialize};

use crate::design::criteria::{Criterion, Spectrum, RANK_TOL};
use crate::design::pool::InformationPool;
use crate::error::{CalibError, Result};

/// Options of [`select`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SelectionSettings {
    /// The criterion.
    pub criterion: Criterion,
    /// Refine the greedy set by exchange.
    pub exchange: bool,
    /// Largest number of exchange sweeps.
    pub max_sweeps: usize,
    /// Candidates evaluated exactly per step for the spectral criteria.
    pub screen: usize,
}

impl Default for SelectionSettings {
    fn default() -> Self {
        Self { criterion: Criterion::D, exchange: true, max_sweeps: 30, screen: 8 }
    }
}

/// One greedy deletion.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DeletionStep {
    /// Candidates left after it.
    pub count: usize,
    /// The candidate removed (pool index).
    pub removed: usize,
    /// The criterion's loss of the remaining set.
    pub loss: f64,
}

/// The whole greedy deletion: the criterion against the count.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DeletionHistory {
    /// The criterion.
    pub criterion: Criterion,
    /// The start set.
    pub start: Vec<usize>,
    /// Loss of the start set.
    pub start_loss: f64,
    /// The deletions in order.
    pub steps: Vec<DeletionStep>,
    /// The smallest count reached with full rank (deletion stops there, or at the requested
    /// count).
    pub minimum_count: usize,
    /// Whether the deletion stopped because no removal kept full rank.
    pub reached_rank_limit: bool,
}

impl DeletionHistory {
    /// The set left at `count` (`None` outside `minimum_count..=start.len()`).
    pub fn subset_at(&self, count: usize) -> Option<Vec<usize>> {
        if count > self.start.len() || count < self.minimum_count {
            return None;
        }
        let removed: std::collections::HashSet<usize> =
            self.steps.iter().take(self.start.len() - count).map(|s| s.removed).collect();
        Some(self.start.iter().copied().filter(|k| !removed.contains(k)).collect())
    }

    /// Loss at `count`.
    pub fn loss_at(&self, count: usize) -> Option<f64> {
        if count == self.start.len() {
            return Some(self.start_loss);
        }
        self.steps.iter().find(|s| s.count == count).map(|s| s.loss)
    }

    /// `(count, criterion value)` from the start set down to the minimum.
    pub fn curve(&self) -> Vec<(usize, f64)> {
        std::iter::once((self.start.len(), self.criterion.value(self.start_loss)))
            .chain(self.steps.iter().map(|s| (s.count, self.criterion.value(s.loss))))
            .collect()
    }
}

fn inverse_spd(f: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    Cholesky::new(f.clone()).map(|c| c.inverse())
}

/// `P = R G` (m x p) for a block of rows `r` (row-major) and a symmetric `G`.
fn times_g(r: &[f64], m: usize, p: usize, g: &DMatrix<f64>) -> Vec<f64> {
    let gs = g.as_slice();
    let mut out = vec![0.0; m * p];
    for a in 0..m {
        let row = &r[a * p..(a + 1) * p];
        for j in 0..p {
            let col = &gs[j * p..(j + 1) * p];
            out[a * p + j] = row.iter().zip(col).map(|(x, y)| x * y).sum();
        }
    }
    out
}

fn dot_rows(a: &[f64], b: &[f64], m: usize, p: usize) -> DMatrix<f64> {
    DMatrix::from_fn(m, m, |i, j| a[i * p..(i + 1) * p].iter().zip(&b[j * p..(j + 1) * p]).map(|(x, y)| x * y).sum())
}

/// The loss after adding (`sign = 1`) or removing (`sign = -1`) candidate `k`, for the A and D
/// criteria, from `G = F^-1` and the current loss. `None` when the result is (near) singular.
fn low_rank_loss(
    pool: &InformationPool,
    k: usize,
    sign: f64,
    g: &DMatrix<f64>,
    trace_g: f64,
    loss: f64,
    criterion: Criterion,
) -> Option<f64> {
    let p = pool.n_params();
    let m = pool.block_len(k);
    if m == 0 {
        return Some(loss);
    }
    let r = pool.block(k);
    let pg = times_g(r, m, p, g);
    let s = dot_rows(&pg, r, m, p);
    let mm = DMatrix::identity(m, m) + s * sign;
    let chol = Cholesky::new(mm)?;
    let det: f64 = chol.l_dirty().diagonal().iter().map(|d| d * d).product();
    // NaN fails too.
    if det.is_nan() || det <= 1e-10 {
        return None;
    }
    match criterion {
        Criterion::D => Some(loss - det.ln()),
        Criterion::A => {
            let ppt = dot_rows(&pg, &pg, m, p);
            let t = chol.solve(&ppt).trace();
            Some(trace_g - sign * t)
        }
        _ => None,
    }
}

/// First-order spectral loss after adding/removing candidate `k`.
fn screened_loss(pool: &InformationPool, k: usize, sign: f64, eig: &SymmetricEigen<f64, Dyn>, c: Criterion) -> f64 {
    let p = pool.n_params();
    let m = pool.block_len(k);
    let r = pool.block(k);
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for i in 0..p {
        let v = eig.eigenvectors.column(i);
        let mut s = 0.0;
        for a in 0..m {
            let d: f64 = r[a * p..(a + 1) * p].iter().zip(v.iter()).map(|(x, y)| x * y).sum();
            s += d * d;
        }
        let l = (eig.eigenvalues[i] + sign * s).max(0.0);
        lo = lo.min(l);
        hi = hi.max(l);
    }
    c.spectral_loss(lo, hi)
}

/// Best candidate among `cands` to add or remove (`sign`) given the current `f`; returns
/// `(candidate, loss)` or `None` when every candidate leaves `f` singular.
fn best_move(
    pool: &InformationPool,
    f: &DMatrix<f64>,
    cands: &[usize],
    sign: f64,
    criterion: Criterion,
    screen: usize,
) -> Option<(usize, f64)> {
    let exact = |k: usize| {
        let mut f2 = f.clone();
        pool.accumulate(k, sign, &mut f2);
        criterion.loss(&f2)
    };
    let mut best: Option<(usize, f64)> = None;
    let consider = |best: &mut Option<(usize, f64)>, k: usize, l: f64| {
        if l.is_finite() && best.is_none_or(|(_, b)| l < b) {
            *best = Some((k, l));
        }
    };
    if criterion.is_spectral() {
        let eig = SymmetricEigen::new((f + f.transpose()) * 0.5);
        let mut scored: Vec<(f64, usize)> =
            cands.iter().map(|&k| (screened_loss(pool, k, sign, &eig, criterion), k)).collect();
        scored.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for &(_, k) in scored.iter().take(screen.max(1)) {
            consider(&mut best, k, exact(k));
        }
        if best.is_none() {
            // Screening can be fooled near rank loss: fall back to exact evaluations.
            for &(_, k) in scored.iter().skip(screen.max(1)) {
                consider(&mut best, k, exact(k));
            }
        }
        return best;
    }
    match inverse_spd(f) {
        Some(g) => {
            let trace_g = g.trace();
            let loss = criterion.loss(f);
            for &k in cands {
                if let Some(l) = low_rank_loss(pool, k, sign, &g, trace_g, loss, criterion) {
                    consider(&mut best, k, l);
                }
            }
        }
        None => {
            for &k in cands {
                consider(&mut best, k, exact(k));
            }
        }
    }
    best
}

/// Greedy deletion from `start` down to `stop_at` candidates, or until every removal would lose
/// full rank (`stop_at = 0`: run to the minimum).
pub fn greedy_deletion(
    pool: &InformationPool,
    start: &[usize],
    stop_at: usize,
    criterion: Criterion,
    screen: usize,
) -> Result<DeletionHistory> {
    pool.check_indices(start)?;
    let mut f = pool.information(start);
    let start_loss = criterion.loss(&f);
    if !start_loss.is_finite() {
        let rank = Spectrum::of(&f).map_or(0, |s| s.rank());
        return Err(CalibError::TooFew(format!(
            "the {} candidates determine only {rank} of {} parameters: the pool cannot identify them all",
            start.len(),
            pool.n_params()
        )));
    }
    let mut active: Vec<usize> = start.to_vec();
    let mut steps = Vec::new();
    let mut reached_rank_limit = false;
    while active.len() > stop_at.max(1) {
        let mut cands = active.clone();
        let chosen = loop {
            let Some((k, _)) = best_move(pool, &f, &cands, -1.0, criterion, screen) else {
                break None;
            };
            // Exact rank check of the chosen removal.
            let mut f2 = f.clone();
            pool.accumulate(k, -1.0, &mut f2);
            let exact = criterion.loss(&f2);
            if exact.is_finite() {
                break Some((k, exact, f2));
            }
            cands.retain(|&c| c != k);
        };
        let Some((k, loss, f2)) = chosen else {
            reached_rank_limit = true;
            break;
        };
        f = f2;
        active.retain(|&c| c != k);
        steps.push(DeletionStep { count: active.len(), removed: k, loss });
    }
    if active.len() <= 1 && !reached_rank_limit {
        reached_rank_limit = true;
    }
    Ok(DeletionHistory {
        criterion,
        start: start.to_vec(),
        start_loss,
        minimum_count: active.len(),
        steps,
        reached_rank_limit,
    })
}

/// What [`exchange`] did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExchangeOutcome {
    /// The refined set.
    pub chosen: Vec<usize>,
    /// Loss before.
    pub loss_before: f64,
    /// Loss after.
    pub loss_after: f64,
    /// Swaps made.
    pub swaps: usize,
    /// Sweeps run.
    pub sweeps: usize,
}

/// Exchange refinement of `chosen` with the other members of `candidates`.
pub fn exchange(
    pool: &InformationPool,
    chosen: &[usize],
    candidates: &[usize],
    criterion: Criterion,
    max_sweeps: usize,
    screen: usize,
) -> Result<ExchangeOutcome> {
    pool.check_indices(chosen)?;
    pool.check_indices(candidates)?;
    let mut set = chosen.to_vec();
    let mut f = pool.information(&set);
    let loss_before = criterion.loss(&f);
    let mut loss = loss_before;
    let mut swaps = 0;
    let mut sweeps = 0;
    for _ in 0..max_sweeps {
        sweeps += 1;
        let mut improved = false;
        for pos in 0..set.len() {
            let i = set[pos];
            let mut f_minus = f.clone();
            pool.accumulate(i, -1.0, &mut f_minus);
            let outside: Vec<usize> = candidates.iter().copied().filter(|c| !set.contains(c)).collect();
            if outside.is_empty() {
                break;
            }
            let Some((j, _)) = best_move(pool, &f_minus, &outside, 1.0, criterion, screen) else {
                continue;
            };
            let mut f_new = f_minus;
            pool.accumulate(j, 1.0, &mut f_new);
            let l = criterion.loss(&f_new);
            let tol = 1e-10 * loss.abs().max(1e-300);
            if l.is_finite() && (l < loss - tol || !loss.is_finite()) {
                set[pos] = j;
                f = f_new;
                loss = l;
                swaps += 1;
                improved = true;
            }
        }
        if !improved {
            break;
        }
    }
    Ok(ExchangeOutcome { chosen: set, loss_before, loss_after: loss, swaps, sweeps })
}

/// A chosen set with how it was found.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Selection {
    /// The criterion.
    pub criterion: Criterion,
    /// Chosen candidates (pool indices).
    pub chosen: Vec<usize>,
    /// Loss of the chosen set.
    pub loss: f64,
    /// The criterion's value (source's form).
    pub value: f64,
    /// Loss of the greedy set before exchange.
    pub greedy_loss: f64,
    /// The exchange step, when run.
    pub exchange: Option<ExchangeOutcome>,
    /// The greedy deletion over the whole candidate list (criterion against the count).
    pub history: DeletionHistory,
}

/// Chooses `count` of `candidates` by greedy deletion (run on to the rank limit for the
/// curve), then exchange. Fails when `count` is below the smallest full-rank set.
pub fn select(
    pool: &InformationPool,
    candidates: &[usize],
    count: usize,
    settings: &SelectionSettings,
) -> Result<Selection> {
    let history = greedy_deletion(pool, candidates, 0, settings.criterion, settings.screen)?;
    select_from_history(pool, candidates, count, settings, history)
}

/// As [`select`], reusing a greedy deletion of `candidates` that ran far enough.
pub fn select_from_history(
    pool: &InformationPool,
    candidates: &[usize],
    count: usize,
    settings: &SelectionSettings,
    history: DeletionHistory,
) -> Result<Selection> {
    if count > candidates.len() {
        return Err(CalibError::TooFew(format!("{count} wanted from a pool of {} candidates", candidates.len())));
    }
    let greedy = history.subset_at(count).ok_or_else(|| {
        CalibError::TooFew(format!(
            "{count} candidates cannot determine all {} parameters; the smallest full-rank set found has {}",
            pool.n_params(),
            history.minimum_count
        ))
    })?;
    let greedy_loss = pool.loss(&greedy, settings.criterion);
    let (chosen, loss, exchange_out) = if settings.exchange && count < candidates.len() {
        let e = exchange(pool, &greedy, candidates, settings.criterion, settings.max_sweeps, settings.screen)?;
        (e.chosen.clone(), e.loss_after, Some(e))
    } else {
        (greedy, greedy_loss, None)
    };
    Ok(Selection {
        criterion: settings.criterion,
        value: settings.criterion.value(loss),
        chosen,
        loss,
        greedy_loss,
        exchange: exchange_out,
        history,
    })
}

/// Whether `f` has full rank by [`RANK_TOL`].
pub fn full_rank(f: &DMatrix<f64>) -> bool {
    Spectrum::of(f).is_some_and(|s| s.full_rank() && s.min() > RANK_TOL * s.max())
}
