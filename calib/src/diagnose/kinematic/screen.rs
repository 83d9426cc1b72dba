//! Screening of held-out residuals against every recorded input (what no candidate explains).

use nalgebra::Vector3;

use super::family::Ctx;
use super::linear::Lin;
use super::InputStructure;
use crate::diagnose::stats::{self, binned_anova, bonferroni, quantile_groups};
use crate::measurement::PoseMeasurement;

/// Implied joint error (joint units) and its weight of a whitened residual, per row.
pub(super) fn implied(col: &nalgebra::DMatrix<f64>, c: usize, e: &[Vector3<f64>]) -> (Vec<f64>, Vec<f64>) {
    let mut u = Vec::with_capacity(e.len());
    let mut w = Vec::with_capacity(e.len());
    for (i, ei) in e.iter().enumerate() {
        let d = col.fixed_view::<3, 1>(3 * i, c);
        let dd = d.norm_squared();
        if dd > 0.0 {
            u.push(d.dot(ei) / dd);
            w.push(dd);
        } else {
            u.push(0.0);
            w.push(0.0);
        }
    }
    (u, w)
}

/// Screening of held-out residuals `e` (whitened, per analysis row) against every input.
pub(super) fn screen(ctx: &Ctx, lin: &Lin, e: &[Vector3<f64>]) -> Vec<InputStructure> {
    let n = ctx.rows.len();
    let bins = (n / 25).clamp(4, 12);
    let mut tests: Vec<(String, String, stats::BinnedTest)> = Vec::new();
    let ds = nalgebra::DMatrix::from_column_slice(lin.ds.len(), 1, lin.ds.as_slice());
    let nj = ctx.kinds.len();
    let vary = |x: &[f64]| {
        let (lo, hi) = x.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| (l.min(*v), h.max(*v)));
        hi - lo > 1e-9 * (lo.abs() + hi.abs()).max(1e-12)
    };
    for j in 0..nj {
        let (u, w) = implied(&lin.dq, j, e);
        if w.iter().all(|v| *v == 0.0) {
            continue;
        }
        let qty = format!("joint {} angle error ({})", j + 1, ctx.names.get(j).cloned().unwrap_or_default());
        for k in 0..nj {
            let x = ctx.q(k);
            if vary(&x) {
                let g = quantile_groups(&x, bins);
                tests.push((qty.clone(), format!("q{}", k + 1), binned_anova(&x, &u, &w, &g, bins)));
            }
        }
        let tau: Vec<f64> = lin.tau.iter().map(|t| t[j]).collect();
        if vary(&tau) {
            let g = quantile_groups(&tau, bins);
            tests.push((qty.clone(), format!("gravity_torque{}", j + 1), binned_anova(&tau, &u, &w, &g, bins)));
        }
        if ctx.rows.iter().all(|r| r.dir.as_ref().is_some_and(|d| d.len() > j)) {
            let x: Vec<f64> = ctx.rows.iter().map(|r| r.dir.as_ref().map_or(0, |d| d[j]) as f64).collect();
            let g: Vec<usize> = x
                .iter()
                .map(|v| {
                    if *v < 0.0 {
                        0
                    } else if *v > 0.0 {
                        1
                    } else {
                        2
                    }
                })
                .collect();
            tests.push((qty.clone(), format!("dir{}", j + 1), binned_anova(&x, &u, &w, &g, 2)));
        }
    }
    let (v, w) = implied(&ds, 0, e);
    let qty = "relative length change".to_string();
    let mut scalar = |name: &str, get: &dyn Fn(&PoseMeasurement) -> Option<f64>| {
        let x: Vec<f64> = ctx.rows.iter().filter_map(|r| get(r)).collect();
        if x.len() == n && vary(&x) {
            let g = quantile_groups(&x, bins);
            tests.push((qty.clone(), name.to_string(), binned_anova(&x, &v, &w, &g, bins)));
        }
    };
    scalar("t_s", &|r| r.t_s);
    scalar("temp_c", &|r| r.temp_c);
    scalar("payload_kg", &|r| r.payload_kg);
    let m = tests.len();
    tests
        .into_iter()
        .map(|(quantity, input, t)| {
            let pc = bonferroni(t.p_value, m);
            InputStructure {
                quantity,
                input,
                f: t.f,
                p_value: t.p_value,
                p_corrected: pc,
                explained_fraction: t.explained,
                significant: pc < ctx.opts.alpha,
            }
        })
        .collect()
}
