//! Identifiability of a parameter vector from the Jacobian of a (whitened, column-scaled) cost.
//!
//! - Structural: the SVD `A = U S V^T` gives the rank `r`; Klimchik's grouping reads the rows of
//!   `V`: a parameter whose row in the null-space part `V_{r+1..n}` is zero is identifiable (G1),
//!   one whose row in `V_{1..r}` is zero has no effect at all (G2, not identifiable), the others
//!   trade against each other in coupled groups (G3, semi-identifiable) along the null-space
//!   directions. QR with column pivoting chooses which parameters to keep: the first `r` pivots;
//!   the others are fixed at their current values (Dressler: a diagonal `R_ii` below the
//!   tolerance marks a parameter that is not identifiable).
//! - Practical: with the covariance of the fit, the parameter-to-noise ratio
//!   `nu_i = |pi_i| / sigma_i` says which identifiable parameters the data resolve.

use faer::Mat;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use crate::{LsqError, Result};

/// How one parameter fared.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ParamClass {
    /// Identifiable on its own (G1).
    Identifiable,
    /// No effect on the measurements (G2).
    NotIdentifiable,
    /// Trades against other parameters (G3); the group index is in [`Identifiability::groups`].
    Coupled,
}

/// Parameters that trade against each other.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CoupledGroup {
    /// Parameter indices.
    pub params: Vec<usize>,
    /// How many of them must be fixed (`dim - rank` of the group).
    pub deficiency: usize,
    /// The unobservable combinations, as `(parameter index, coefficient)` lists (null-space
    /// directions restricted to the group, in scaled units).
    pub combinations: Vec<Vec<(usize, f64)>>,
}

/// The identifiability analysis of one Jacobian.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Identifiability {
    /// Parameter names.
    pub names: Vec<String>,
    /// Numerical rank.
    pub rank: usize,
    /// Singular values of the scaled Jacobian, descending.
    pub singular_values: Vec<f64>,
    /// `sigma_max / sigma_min` over the kept parameters.
    pub condition_number: f64,
    /// The source's check `sigma_max^2 / sigma_min` over the kept parameters.
    pub dressler_ratio: f64,
    /// Class per parameter.
    pub classes: Vec<ParamClass>,
    /// Coupled groups.
    pub groups: Vec<CoupledGroup>,
    /// `|R_ii|` of the pivoted QR, in pivot order.
    pub r_diagonal: Vec<f64>,
    /// Column pivot order of the QR (parameter indices).
    pub pivot_order: Vec<usize>,
    /// Parameters to fix (not identifiable, or the redundant members of coupled groups).
    pub fixed: Vec<usize>,
    /// Relative tolerance used for the rank.
    pub tolerance: f64,
    /// Per parameter: the kept parameters a fixed one trades against, as `(kept index, c)`
    /// with the fixed column `a_j ~ sum c_k a_k` over the kept columns (columns of `a` as
    /// given, so in its scaling), strongest first; only terms carrying at least 5 % of the
    /// column are listed. Empty for kept parameters and for those with no effect at all.
    #[serde(default)]
    pub trades_against: Vec<Vec<(usize, f64)>>,
}

impl Identifiability {
    /// Indices of the parameters that are kept.
    pub fn kept(&self) -> Vec<usize> {
        (0..self.names.len()).filter(|i| !self.fixed.contains(i)).collect()
    }

    /// Plain-words description of each coupled group: its members, how many are fixed, and
    /// the strongest terms of (at most three of) its unobservable combinations.
    pub fn describe_groups(&self) -> Vec<String> {
        self.groups
            .iter()
            .filter(|g| g.deficiency > 0)
            .map(|g| {
                let names: Vec<&str> = g.params.iter().map(|&i| self.names[i].as_str()).collect();
                let combos: Vec<String> = g
                    .combinations
                    .iter()
                    .take(3)
                    .map(|c| {
                        let mut c = c.clone();
                        c.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
                        let more = c.len().saturating_sub(4);
                        let mut t = c
                            .iter()
                            .take(4)
                            .map(|(i, w)| format!("{w:+.2} {}", self.names[*i]))
                            .collect::<Vec<_>>()
                            .join(" ");
                        if more > 0 {
                            t.push_str(&format!(" (+{more} smaller terms)"));
                        }
                        t
                    })
                    .collect();
                format!(
                    "{} parameters trade against each other ({} fixed): {}; unobservable directions include: {}",
                    names.len(),
                    g.deficiency,
                    names.join(", "),
                    combos.join("; ")
                )
            })
            .collect()
    }
}

/// Converts a nalgebra matrix to faer.
pub(crate) fn to_faer(a: &DMatrix<f64>) -> Mat<f64> {
    Mat::from_fn(a.nrows(), a.ncols(), |i, j| a[(i, j)])
}

/// Analyses `a` (residuals x parameters, already whitened and column-scaled). A singular value
/// below `rel_tol * sigma_max` counts as zero.
pub fn analyze(a: &DMatrix<f64>, names: &[String], rel_tol: f64) -> Result<Identifiability> {
    analyze_impl(a, names, rel_tol, None)
}

/// Like [`analyze`], but which of several redundant parameters are kept follows `priority`
/// (one rank per parameter, lower kept first) instead of the column norms alone: a pivoted
/// Gram-Schmidt that takes the columns of the first priority (largest remaining norm first)
/// while their remaining norm exceeds `rel_tol * sigma_max`, then those of the next priority
/// against what is kept, and so on; the numerical rank (from the SVD) bounds how many are kept.
/// A parameter of a later priority is thus fixed whenever the earlier ones already explain
/// its column, however large its norm.
pub fn analyze_prioritized(
    a: &DMatrix<f64>,
    names: &[String],
    priority: &[u32],
    rel_tol: f64,
) -> Result<Identifiability> {
    if priority.len() != a.ncols() {
        return Err(LsqError::Setup(format!("{} priorities for {} parameters", priority.len(), a.ncols())));
    }
    analyze_impl(a, names, rel_tol, Some(priority))
}

fn analyze_impl(a: &DMatrix<f64>, names: &[String], rel_tol: f64, priority: Option<&[u32]>) -> Result<Identifiability> {
    let (m, n) = a.shape();
    if names.len() != n {
        return Err(LsqError::Setup(format!("{} names for {n} parameters", names.len())));
    }
    if n == 0 {
        return Err(LsqError::Setup("no parameters to analyse".into()));
    }
    let fa = to_faer(a);
    let svd = fa.thin_svd().map_err(|e| LsqError::Numeric(format!("SVD failed: {e:?}")))?;
    let s: Vec<f64> = (0..m.min(n)).map(|i| svd.S()[i]).collect();
    let smax = s.first().copied().unwrap_or(0.0);
    if smax <= 0.0 {
        return Err(LsqError::TooFew("the measurements do not depend on any parameter".into()));
    }
    let rank = s.iter().filter(|v| **v > rel_tol * smax).count();
    // V is n x min(m, n); the null space also includes columns beyond min(m, n) when m < n.
    let full = if m < n { Some(fa.svd().map_err(|e| LsqError::Numeric(format!("SVD failed: {e:?}")))?) } else { None };
    let v = match &full {
        Some(f) => f.V().to_owned(),
        None => svd.V().to_owned(),
    };
    let vcols = v.ncols();
    let tiny = 1e-6;
    let mut classes = vec![ParamClass::Identifiable; n];
    for (i, class) in classes.iter_mut().enumerate() {
        let null_norm: f64 = (rank..vcols).map(|k| v[(i, k)] * v[(i, k)]).sum::<f64>().sqrt();
        let range_norm: f64 = (0..rank).map(|k| v[(i, k)] * v[(i, k)]).sum::<f64>().sqrt();
        *class = if null_norm < tiny {
            ParamClass::Identifiable
        } else if range_norm < tiny {
            ParamClass::NotIdentifiable
        } else {
            ParamClass::Coupled
        };
    }
    // Coupled groups: connected components over shared null-space directions.
    let mut group_of: Vec<Option<usize>> = vec![None; n];
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for k in rank..vcols {
        let members: Vec<usize> =
            (0..n).filter(|&i| classes[i] == ParamClass::Coupled && v[(i, k)].abs() > 1e-3).collect();
        if members.is_empty() {
            continue;
        }
        let existing: Vec<usize> = members.iter().filter_map(|&i| group_of[i]).collect();
        let gi = match existing.first() {
            Some(&g) => g,
            None => {
                groups.push(Vec::new());
                groups.len() - 1
            }
        };
        // Merge other groups into gi.
        for &other in existing.iter().skip(1) {
            if other != gi {
                let moved = std::mem::take(&mut groups[other]);
                for &i in &moved {
                    group_of[i] = Some(gi);
                }
                groups[gi].extend(moved);
            }
        }
        for &i in &members {
            if group_of[i].is_none() {
                group_of[i] = Some(gi);
                groups[gi].push(i);
            }
        }
    }
    // Parameters classed coupled but below the 1e-3 threshold in every direction join alone.
    for i in 0..n {
        if classes[i] == ParamClass::Coupled && group_of[i].is_none() {
            groups.push(vec![i]);
            group_of[i] = Some(groups.len() - 1);
        }
    }
    // Pivoted QR (or its prioritized form) decides which parameters to keep.
    let kmax = m.min(n);
    let (pivot_order, r_diagonal) = match priority {
        Some(p) => prioritized_pivots(a, p, rank, rel_tol * smax),
        None => {
            let qr = fa.col_piv_qr();
            let r = qr.R();
            let (fwd, _) = qr.P().arrays();
            (fwd.to_vec(), (0..kmax).map(|i| r[(i, i)].abs()).collect())
        }
    };
    let mut fixed: Vec<usize> = pivot_order.iter().skip(rank).copied().collect();
    fixed.sort_unstable();
    let groups: Vec<CoupledGroup> = groups
        .into_iter()
        .filter(|g| !g.is_empty())
        .map(|mut params| {
            params.sort_unstable();
            let deficiency = params.iter().filter(|i| fixed.contains(i)).count();
            let mut combinations = Vec::new();
            for k in rank..vcols {
                let c: Vec<(usize, f64)> =
                    params.iter().filter(|&&i| v[(i, k)].abs() > 1e-3).map(|&i| (i, v[(i, k)])).collect();
                if c.len() > 1 || (c.len() == 1 && params.len() == 1) {
                    combinations.push(c);
                }
            }
            CoupledGroup { params, deficiency, combinations }
        })
        .collect();
    // Conditioning over the kept columns.
    let kept: Vec<usize> = (0..n).filter(|i| !fixed.contains(i)).collect();
    let (condition_number, dressler_ratio) = if kept.is_empty() {
        (f64::INFINITY, f64::INFINITY)
    } else {
        let sub = Mat::from_fn(m, kept.len(), |i, j| a[(i, kept[j])]);
        let sv = sub.singular_values().map_err(|e| LsqError::Numeric(format!("SVD failed: {e:?}")))?;
        let hi = sv.iter().copied().fold(0.0, f64::max);
        let lo = sv.iter().copied().fold(f64::INFINITY, f64::min);
        (hi / lo, hi * hi / lo)
    };
    let trades_against = trade_offs(a, &kept)?;
    Ok(Identifiability {
        names: names.to_vec(),
        rank,
        singular_values: s,
        condition_number,
        dressler_ratio,
        classes,
        groups,
        r_diagonal,
        pivot_order,
        fixed,
        tolerance: rel_tol,
        trades_against,
    })
}

/// The pivot order and `|R_ii|` of a Gram-Schmidt with column pivoting that exhausts each
/// priority (ascending) before the next; columns whose remaining norm is at most `abs_tol` wait
/// until every priority has had its turn, and at most `rank` columns are taken by priority.
fn prioritized_pivots(a: &DMatrix<f64>, priority: &[u32], rank: usize, abs_tol: f64) -> (Vec<usize>, Vec<f64>) {
    let n = a.ncols();
    let mut w = a.clone();
    let mut taken = vec![false; n];
    let mut order = Vec::with_capacity(n);
    let mut diag = Vec::with_capacity(n);
    let mut levels: Vec<u32> = priority.to_vec();
    levels.sort_unstable();
    levels.dedup();
    let best = |w: &DMatrix<f64>, taken: &[bool], level: Option<u32>| {
        (0..n)
            .filter(|&j| !taken[j] && level.is_none_or(|l| priority[j] == l))
            .map(|j| (j, w.column(j).norm()))
            .max_by(|x, y| x.1.total_cmp(&y.1))
    };
    let take = |w: &mut DMatrix<f64>, taken: &mut [bool], j: usize, norm: f64| {
        taken[j] = true;
        if norm <= 0.0 {
            return;
        }
        let q = w.column(j) / norm;
        for c in (0..n).filter(|&c| !taken[c]) {
            // Twice, for the orthogonality the rank decisions rely on.
            for _ in 0..2 {
                let d = q.dot(&w.column(c));
                w.column_mut(c).axpy(-d, &q, 1.0);
            }
        }
    };
    let levels_then_rest = levels.iter().map(|&l| Some(l)).chain(std::iter::once(None));
    for level in levels_then_rest {
        while order.len() < rank {
            let Some((j, norm)) = best(&w, &taken, level) else { break };
            if level.is_some() && norm <= abs_tol {
                break;
            }

            take(&mut w, &mut taken, j, norm);
            order.push(j);
            diag.push(norm);
        }
    }
    // The rest, largest remaining norm first.
    while let Some((j, norm)) = best(&w, &taken, None) {
        take(&mut w, &mut taken, j, norm);
        order.push(j);
        diag.push(norm);
    }
    diag.truncate(a.nrows().min(n));
    (order, diag)
}

/// For every column not in `kept`: the kept columns it is (in the least-squares sense) a
/// combination of, `(index, coefficient)` for the terms carrying at least 5 % of the column's
/// norm, strongest first (see [`Identifiability::trades_against`]).
fn trade_offs(a: &DMatrix<f64>, kept: &[usize]) -> Result<Vec<Vec<(usize, f64)>>> {
    let n = a.ncols();
    let mut out = vec![Vec::new(); n];
    let others: Vec<usize> = (0..n).filter(|j| !kept.contains(j)).collect();
    if kept.is_empty() || others.is_empty() {
        return Ok(out);
    }
    let ak = DMatrix::from_fn(a.nrows(), kept.len(), |i, j| a[(i, kept[j])]);
    let b = DMatrix::from_fn(a.nrows(), others.len(), |i, j| a[(i, others[j])]);
    let svd = ak.clone().svd(true, true);
    let eps = svd.singular_values.max() * 1e-12;
    let c = svd.solve(&b, eps).map_err(|e| LsqError::Numeric(format!("trade-off solve failed: {e}")))?;
    let knorm: Vec<f64> = (0..kept.len()).map(|k| ak.column(k).norm()).collect();
    let amax = (0..n).map(|j| a.column(j).norm()).fold(0.0, f64::max);
    for (col, &j) in others.iter().enumerate() {
        let own = a.column(j).norm();
        if own <= 1e-9 * amax {
            continue;
        }
        let mut terms: Vec<(usize, f64, f64)> = (0..kept.len())
            .map(|k| (kept[k], c[(k, col)], (c[(k, col)] * knorm[k]).abs()))
            .filter(|t| t.2 >= 0.05 * own)
            .collect();
        terms.sort_by(|x, y| y.2.total_cmp(&x.2));
        out[j] = terms.into_iter().map(|(k, c, _)| (k, c)).collect();
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_redundant_and_dead_parameters() {
        // y = p0 t + (p1 + p2) + 0 * p3: p1 and p2 coupled, p3 dead, p0 identifiable.
        let m = 20;
        let a = DMatrix::from_fn(m, 4, |i, j| match j {
            0 => i as f64 * 0.1,
            1 | 2 => 1.0,
            _ => 0.0,
        });
        let names: Vec<String> = ["slope", "offset_a", "offset_b", "dead"].iter().map(|s| s.to_string()).collect();
        let id = analyze(&a, &names, 1e-9).unwrap();
        assert_eq!(id.rank, 2);
        assert_eq!(
            id.classes,
            vec![ParamClass::Identifiable, ParamClass::Coupled, ParamClass::Coupled, ParamClass::NotIdentifiable]
        );
        assert_eq!(id.fixed.len(), 2);
        assert!(id.fixed.contains(&3));
        assert!(id.fixed.contains(&1) ^ id.fixed.contains(&2));
        let g = id.groups.iter().find(|g| g.params == vec![1, 2]).expect("offsets grouped");
        assert_eq!(g.deficiency, 1);
        let text = id.describe_groups().join("\n");
        assert!(text.contains("offset_a") && text.contains("offset_b"), "{text}");
    }

    #[test]
    fn priority_decides_which_redundant_parameter_is_kept() {
        // y = p0 t + 3 p1 + p2 (p1 has the larger column) + 0.5 p3 t: with p2 preferred, p1 is
        // fixed however large its column, and it trades against p2 with coefficient 3; p3
        // against p0 with 0.5.
        let m = 20;
        let a = DMatrix::from_fn(m, 4, |i, j| match j {
            0 => i as f64 * 0.1,
            1 => 3.0,
            2 => 1.0,
            _ => i as f64 * 0.05,
        });
        let names: Vec<String> = ["slope", "big", "small", "slope_b"].iter().map(|s| s.to_string()).collect();
        let plain = analyze(&a, &names, 1e-9).unwrap();
        assert!(plain.fixed.contains(&2), "plain pivoting keeps the larger column: {:?}", plain.fixed);
        let id = analyze_prioritized(&a, &names, &[1, 1, 0, 2], 1e-9).unwrap();
        assert_eq!(id.rank, 2);
        assert_eq!(id.fixed, vec![1, 3]);
        assert_eq!(id.trades_against[1].len(), 1);
        assert_eq!(id.trades_against[1][0].0, 2);
        assert!((id.trades_against[1][0].1 - 3.0).abs() < 1e-9, "{:?}", id.trades_against[1]);
        assert_eq!(id.trades_against[3][0].0, 0);
        assert!((id.trades_against[3][0].1 - 0.5).abs() < 1e-9, "{:?}", id.trades_against[3]);
        assert!(id.trades_against[0].is_empty() && id.trades_against[2].is_empty());
        assert!(analyze_prioritized(&a, &names, &[0, 1], 1e-9).is_err());
    }
}
