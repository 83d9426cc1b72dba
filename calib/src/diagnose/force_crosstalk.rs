//! Force-sensor cross-talk for the force family ([`super::force`]): each sensor reads its own
//! load plus small fractions of the other sensors' loads, `f_i,meas = f_i + sum_j C_ij f_j`
//! (`j != i`, `f` the load forces without the sensors' offsets).
//!
//! The model is bilinear (the loads come from the rigid-body and deformation parameters); it is
//! linearised once: the loads of the model fitted without cross-talk give the cross-talk
//! columns, and parameters and cross-talk are fitted together (minimum-norm least squares on
//! unit-norm columns); predictions use the same loads, so fit and prediction agree. The error of
//! the linearisation is of the order of the cross-talk times the change of the loads it causes
//! (1e-4 of the forces for a 1 % cross-talk). Alternating (recomputing the loads from the joint
//! fit) was tried and wanders along directions the data cannot fix. From one payload only part of `C` is identifiable: every
//! load varies linearly with gravity in the platform frame, so `C` shows through the sensor-space
//! gravity terms (`K3` of docs/dynamics.md) beyond what the rigid body explains; the reported
//! `C` is the minimum-norm one, its size a lower bound of the true cross-talk's.

use nalgebra::{DMatrix, DVector, Matrix6};

/// Relative singular value below which a direction of the joint fit is cut: the cross-talk
/// columns nearly repeat the rigid body's gravity columns, and a nearly singular direction fitted
/// to the noise spoils the held-out prediction.
const TRUNCATION: f64 = 1e-9;

/// A fit of a sensor model plus cross-talk.
pub(super) struct CrosstalkFit {
    /// The model's parameters (its column order).
    pub theta: DVector<f64>,
    /// Cross-talk fractions (zero diagonal).
    pub c: Matrix6<f64>,
    /// The parameters of the fit without cross-talk, whose loads give the cross-talk columns.
    pub theta_loads: DVector<f64>,
    /// Cross-talk directions fitted (those the model's own columns do not nearly repeat).
    pub identifiable: usize,
}

/// The load forces (no offsets) per pose of `rows` under `theta`: `a` is the model's
/// regressor (6 rows per pose), `load` marks the columns whose forces the cross-talk acts on.
fn loads(a: &DMatrix<f64>, theta: &DVector<f64>, load: &[bool], rows: &[usize]) -> Vec<[f64; 6]> {
    rows.iter()
        .map(|&k| {
            let mut f = [0.0; 6];
            for (s, v) in f.iter_mut().enumerate() {
                *v = (0..a.ncols()).filter(|&c| load[c]).map(|c| a[(6 * k + s, c)] * theta[c]).sum();
            }
            f
        })
        .collect()
}

/// The 30 cross-talk columns (order: receiving sensor `i`, then source `j != i`) for poses with
/// loads `f`.
fn columns(f: &[[f64; 6]]) -> DMatrix<f64> {
    let mut x = DMatrix::zeros(6 * f.len(), 30);
    for (k, fk) in f.iter().enumerate() {
        let mut col = 0;
        for i in 0..6 {
            for (j, fj) in fk.iter().enumerate() {
                if j == i {
                    continue;
                }
                x[(6 * k + i, col)] = *fj;
                col += 1;
            }
        }
    }
    x
}

fn rows_of(a: &DMatrix<f64>, idx: &[usize]) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(6 * idx.len(), a.ncols());
    for (k, &i) in idx.iter().enumerate() {
        out.view_mut((6 * k, 0), (6, a.ncols())).copy_from(&a.view((6 * i, 0), (6, a.ncols())));
    }
    out
}

/// Minimum-norm least squares on unit-norm columns (singular values below [`TRUNCATION`] of
/// the largest cut).
fn min_norm(x: &DMatrix<f64>, y: &DVector<f64>) -> DVector<f64> {
    let norms: Vec<f64> = x.column_iter().map(|c| c.norm()).collect();
    let mut xs = x.clone();
    for (k, n) in norms.iter().enumerate() {
        if *n > 0.0 {
            xs.column_mut(k).scale_mut(1.0 / n);
        }
    }
    let svd = xs.svd(true, true);
    let tol = svd.singular_values.max() * TRUNCATION;
    let z = svd.solve(y, tol).unwrap_or_else(|_| DVector::zeros(x.ncols()));
    DVector::from_iterator(x.ncols(), z.iter().zip(&norms).map(|(v, n)| if *n > 0.0 { v / n } else { 0.0 }))
}

/// Smallest sine of the angle between a cross-talk direction and the model's columns for the
/// direction to be fitted: below it the direction trades with the rigid body, the offsets or
/// the deformation terms (variance inflation above `1 / MIN_SINE^2` = 100) and is left out.
pub(super) const MIN_SINE: f64 = 0.1;

/// Fits the model (regressor `a`, load columns `load`) plus the identifiable part of the
/// cross-talk on poses `rows` of the forces `y` (6 per pose).
///
/// The 30 cross-talk columns (built from the loads of the fit without cross-talk) are reduced
/// to their range (12 of the 30 directions leave every load unchanged: at rest each load is
/// linear in gravity in the platform frame, so each sensor's 5 coefficients act through 3
/// numbers), then to the directions whose angle to the model's own columns has a sine of at
/// least [`MIN_SINE`]: the 4 that reproduce a change of mass and centre of gravity and the one
/// that, at tilts of a few degrees, nearly repeats the offsets (gravity along the platform's
/// axis barely changes) are projected out. The reported `C` is the smallest (minimum-norm) one
/// that produces the fitted part; the part projected out is not claimed.
pub(super) fn fit(a: &DMatrix<f64>, y: &DVector<f64>, load: &[bool], rows: &[usize]) -> CrosstalkFit {
    let a_r = rows_of(a, rows);
    let y_r = DVector::from_iterator(6 * rows.len(), rows.iter().flat_map(|&k| (0..6).map(move |s| y[6 * k + s])));
    let theta_loads = min_norm(&a_r, &y_r);
    let x = columns(&loads(a, &theta_loads, load, rows));
    // The range of the cross-talk columns: x = U S V^T, kept where S is not negligible.
    let svd_x = x.clone().svd(true, true);
    let (Some(u), Some(v_t)) = (svd_x.u.as_ref(), svd_x.v_t.as_ref()) else {
        return CrosstalkFit { theta: theta_loads.clone(), c: Matrix6::zeros(), theta_loads, identifiable: 0 };
    };
    let smax = svd_x.singular_values.max();
    let keep: Vec<usize> =
        (0..svd_x.singular_values.len()).filter(|&k| smax > 0.0 && svd_x.singular_values[k] > smax * 1e-9).collect();
    let u_r = DMatrix::from_fn(x.nrows(), keep.len(), |r, c| u[(r, keep[c])]);
    // An orthonormal basis of the model's columns.
    let svd_a = a_r.clone().svd(true, false);
    let amax = svd_a.singular_values.max();
    let ua = svd_a.u.as_ref().expect("requested");
    let qa_cols: Vec<usize> =
        (0..svd_a.singular_values.len()).filter(|&k| svd_a.singular_values[k] > amax * 1e-10).collect();
    let qa = DMatrix::from_fn(a_r.nrows(), qa_cols.len(), |r, c| ua[(r, qa_cols[c])]);
    // Principal angles between range(x) and the model's columns.
    let perp = &u_r - &qa * (qa.transpose() * &u_r);
    let svd_p = perp.svd(false, true);
    let w_t = svd_p.v_t.as_ref().expect("requested");
    let dirs: Vec<usize> = (0..svd_p.singular_values.len()).filter(|&k| svd_p.singular_values[k] >= MIN_SINE).collect();
    // w: coordinates (in u_r) of the kept directions; b = u_r w their columns.
    let w = DMatrix::from_fn(keep.len(), dirs.len(), |r, c| w_t[(dirs[c], r)]);
    let b = &u_r * &w;
    let mut full = DMatrix::zeros(a_r.nrows(), a_r.ncols() + dirs.len());
    full.columns_mut(0, a_r.ncols()).copy_from(&a_r);
    full.columns_mut(a_r.ncols(), dirs.len()).copy_from(&b);
    let z = min_norm(&full, &y_r);
    let theta = z.rows(0, a_r.ncols()).into_owned();
    let coef = z.rows(a_r.ncols(), dirs.len()).into_owned();
    // The minimum-norm C with x c = b coef: c = V_r S_r^-1 w coef.
    let t = &w * coef;
    let mut cvec = DVector::zeros(30);
    for (k, &kk) in keep.iter().enumerate() {
        let scale = t[k] / svd_x.singular_values[kk];
        for j in 0..30 {
            cvec[j] += v_t[(kk, j)] * scale;
        }
    }
    let mut c = Matrix6::zeros();
    let mut col = 0;
    for i in 0..6 {
        for j in 0..6 {
            if j != i {
                c[(i, j)] = cvec[col];
                col += 1;
            }
        }
    }
    CrosstalkFit { theta, c, theta_loads, identifiable: dirs.len() }
}

/// Predicted forces (6 per pose of `rows`) under a fit.
pub(super) fn predict(a: &DMatrix<f64>, load: &[bool], fit: &CrosstalkFit, rows: &[usize]) -> DVector<f64> {
    let base = rows_of(a, rows) * &fit.theta;
    let f = loads(a, &fit.theta_loads, load, rows);
    DVector::from_iterator(
        6 * rows.len(),
        f.iter().enumerate().flat_map(|(k, fk)| {
            let cf = fit.c * nalgebra::Vector6::from_column_slice(fk);
            let base = &base;
            (0..6).map(move |s| base[6 * k + s] + cf[s])
        }),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Forces built by the model plus a known cross-talk are fitted back to the accuracy of the
    /// linearisation.
    #[test]
    fn alternation_recovers_a_known_crosstalk() {
        let n = 60;
        // A toy regressor: per pose and sensor, two load columns and the sensor's offset.
        let mut a = DMatrix::zeros(6 * n, 8);
        for k in 0..n {
            for s in 0..6 {
                let u = ((k * 7 + s * 3) as f64 * 0.37).sin();
                let v = ((k * 5 + s * 11) as f64 * 0.23).cos();
                a[(6 * k + s, 0)] = 40.0 + 10.0 * u;
                a[(6 * k + s, 1)] = 15.0 * v * (1.0 + s as f64 * 0.1);
                a[(6 * k + s, 2 + s)] = 1.0;
            }
        }
        let load: Vec<bool> = (0..8).map(|c| c < 2).collect();
        let theta = DVector::from_vec(vec![1.2, -0.7, 3.0, -2.0, 1.0, 0.5, -1.5, 2.5]);
        let mut c = Matrix6::zeros();
        c[(0, 1)] = 0.015;
        c[(3, 4)] = -0.01;
        c[(5, 2)] = 0.02;
        let rows: Vec<usize> = (0..n).collect();
        let truth = CrosstalkFit { theta: theta.clone(), c, theta_loads: theta, identifiable: 30 };
        let y = predict(&a, &load, &truth, &rows);
        let got = fit(&a, &y, &load, &rows);
        let back = predict(&a, &load, &got, &rows);
        let err = (&back - &y).amax();
        // The linearisation's error: the cross-talk (2 %) times the load change it causes.
        assert!(err < 1e-3 * y.amax(), "largest force error {err:e} of {:e}", y.amax());
    }
}
