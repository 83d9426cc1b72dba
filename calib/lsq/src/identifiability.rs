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
    // Pivoted QR decides which parameters to keep.
    let qr = fa.col_piv_qr();
    let r = qr.R();
    let (fwd, _) = qr.P().arrays();
    let pivot_order: Vec<usize> = fwd.to_vec();
    let kmax = m.min(n);
    let r_diagonal: Vec<f64> = (0..kmax).map(|i| r[(i, i)].abs()).collect();
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
    })
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
}
