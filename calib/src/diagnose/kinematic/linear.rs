//! The linearised joint refit behind the candidate screening.
//!
//! At a calibrated model (geometry plus the effects accepted so far, fitted on the analysis
//! rows) the whitened residuals `r` and the Jacobian `X` of the predictions with respect to
//! every free parameter are computed once. Adding a candidate effect with prediction columns
//! `C` and refitting geometry and effect together on a set of training rows is then the linear
//! least-squares problem `min |r - X dx - C theta|` over those rows: the geometry is refitted
//! with the effect, never frozen. Because the start point is a converged fit and the effects
//! are small, this is the Gauss-Newton step of the full refit; the accepted candidate is
//! confirmed with full non-linear refits (see the parent module).
//!
//! Per fold the training rows' `X` is decomposed once by SVD (`U`, pseudo-inverse); each
//! candidate then costs a few products with its one or two columns.

use ferrocal_robot::Parameterized;
use nalgebra::{DMatrix, DVector, Isometry3, Vector3};

use crate::effects::{holding_torques, link_bendings, EffectSpec};
use crate::error::{CalibError, Result};
use crate::frames::exp6;
use crate::kinematic::{CalibratedModel, KinematicCalibration, StateLayout};
use crate::measurement::PoseMeasurement;

/// Residuals and Jacobians of one calibrated model on the analysis rows (all whitened: divided
/// by each row's position standard deviation).
pub(crate) struct Lin {
    /// Number of rows.
    pub n: usize,
    /// `(measured - predicted) / sigma`, 3 per row.
    pub r: DVector<f64>,
    /// Prediction derivatives for the free parameters, columns scaled to unit norm.
    pub base: DMatrix<f64>,
    /// Prediction derivative per joint reading (`d p / d q_j / sigma`), one column per joint.
    pub dq: DMatrix<f64>,
    /// Prediction derivative per relative length change (`d p / d s / sigma`).
    pub ds: DVector<f64>,
    /// Holding torques per row and joint (from the calibrated model, with each row's payload).
    pub tau: Vec<Vec<f64>>,
    /// Per row and link (serial chains; empty otherwise): the bending load moment and the point
    /// the link turns about (`effects::link_bending`), in the device frame.
    pub bend: Vec<Vec<(Vector3<f64>, nalgebra::Point3<f64>)>>,
    /// Per row: predicted position in the device frame.
    pub p0: Vec<Vector3<f64>>,
    /// Per row: position standard deviation.
    pub sigma: Vec<f64>,
}

/// The calibrated model with candidate parameter `idx` moved by `h`.
fn perturbed(cm: &CalibratedModel, layout: &StateLayout, idx: usize, h: f64) -> Result<CalibratedModel> {
    let mut c = cm.clone();
    if layout.frame.contains(&idx) {
        let mut d = [0.0; 6];
        d[idx - layout.frame.start] = h;
        c.device_frame = exp6(&d) * c.device_frame;
    } else if layout.tool.contains(&idx) {
        let mut d = [0.0; 6];
        d[idx - layout.tool.start] = h;
        c.tool *= exp6(&d);
    } else if layout.offsets.contains(&idx) {
        c.joint_offsets[idx - layout.offsets.start] += h;
    } else if layout.model.contains(&idx) {
        let pi = layout.model_index[idx - layout.model.start];
        let mut v = c.model.parameter_values();
        v[pi] += h;
        c.model.set_parameter_values(&v)?;
    } else if let Some(e) = layout.effects.iter().position(|r| r.contains(&idx)) {
        let start = layout.effects[e].start;
        c.effects[e].1[idx - start] += h;
    } else {
        return Err(CalibError::Data(format!("parameter index {idx} is outside the layout")));
    }
    Ok(c)
}

fn predictions(cm: &CalibratedModel, rows: &[&PoseMeasurement]) -> Result<Vec<Vector3<f64>>> {
    rows.iter().map(|r| cm.predict_row(r).map(|t| t.translation.vector)).collect()
}

impl Lin {
    /// Linearises `cal` (a calibration on `rows`) with per-row sigmas `sigma`.
    pub fn build(cal: &KinematicCalibration, rows: &[&PoseMeasurement], sigma: &[f64]) -> Result<Self> {
        let cm = &cal.calibrated;
        let n = rows.len();
        let p0 = predictions(cm, rows)?;
        let mut r = DVector::zeros(3 * n);
        for i in 0..n {
            let e = (rows[i].position_m - p0[i]) / sigma[i];
            r.fixed_rows_mut::<3>(3 * i).copy_from(&e);
        }
        let column = |plus: &CalibratedModel, minus: &CalibratedModel, h: f64| -> Result<DVector<f64>> {
            let a = predictions(plus, rows)?;
            let b = predictions(minus, rows)?;
            let mut c = DVector::zeros(3 * n);
            for i in 0..n {
                let d = (a[i] - b[i]) / (2.0 * h * sigma[i]);
                c.fixed_rows_mut::<3>(3 * i).copy_from(&d);
            }
            Ok(c)
        };
        let mut base = DMatrix::zeros(3 * n, cal.free.len());
        for (k, &idx) in cal.free.iter().enumerate() {
            let h = 1e-3 * cal.layout.scales[idx];
            let c = column(&perturbed(cm, &cal.layout, idx, h)?, &perturbed(cm, &cal.layout, idx, -h)?, h)?;
            let norm = c.norm();
            if norm > 0.0 {
                base.set_column(k, &(c / norm));
            }
        }
        let nj = cm.joint_offsets.len();
        let mut dq = DMatrix::zeros(3 * n, nj);
        for j in 0..nj {
            let h = 1e-6;
            let mut a = cm.clone();
            a.joint_offsets[j] += h;
            let mut b = cm.clone();
            b.joint_offsets[j] -= h;
            dq.set_column(j, &column(&a, &b, h)?);
        }
        let f: Isometry3<f64> = cm.device_frame;
        let mut ds = DVector::zeros(3 * n);
        for i in 0..n {
            let v = (p0[i] - f.translation.vector) / sigma[i];
            ds.fixed_rows_mut::<3>(3 * i).copy_from(&v);
        }
        let mut tau = Vec::with_capacity(n);
        let mut bend = Vec::with_capacity(n);
        for row in rows {
            tau.push(holding_torques(&cm.load_model, &row.q, row.payload_kg.unwrap_or(0.0))?);
            let mut per_link = Vec::new();
            if let ferrocal_robot::RobotModel::Serial(_) = &cm.load_model {
                let (q, _) = cm.effective(row)?;
                per_link = link_bendings(&cm.load_model, &q, row.payload_kg.unwrap_or(0.0))?
                    .into_iter()
                    .map(|(v, pivot)| (f.rotation * v, f * pivot))
                    .collect();
            }
            bend.push(per_link);
        }
        Ok(Self { n, r, base, dq, ds, tau, bend, p0, sigma: sigma.to_vec() })
    }

    /// The same linearisation with the base columns `drop` removed and the residuals `r` of the
    /// model with those parameters at zero (an accepted effect left out).
    pub fn without(&self, drop: &[usize], r: DVector<f64>) -> Self {
        let keep: Vec<usize> = (0..self.base.ncols()).filter(|c| !drop.contains(c)).collect();
        let base = DMatrix::from_fn(self.base.nrows(), keep.len(), |i, k| self.base[(i, keep[k])]);
        Self {
            n: self.n,
            r,
            base,
            dq: self.dq.clone(),
            ds: self.ds.clone(),
            tau: self.tau.clone(),
            bend: self.bend.clone(),
            p0: self.p0.clone(),
            sigma: self.sigma.clone(),
        }
    }

    /// Prediction columns of a candidate effect on every row (whitened): joint effects through
    /// the joint's column times the effect's regressor, length effects through the length
    /// column. `None` when the effect has no column form here.
    pub fn effect_columns(
        &self,
        spec: &EffectSpec,
        model_kinds: usize,
        rows: &[&PoseMeasurement],
    ) -> Option<DMatrix<f64>> {
        let n = self.n;
        match spec {
            EffectSpec::ThermalExpansion { reference_temp_c } => {
                let mut c = DMatrix::zeros(3 * n, 1);
                for (i, row) in rows.iter().enumerate().take(n) {
                    let dt = row.temp_c? - reference_temp_c;
                    c.fixed_view_mut::<3, 1>(3 * i, 0).copy_from(&(self.ds.fixed_rows::<3>(3 * i) * dt));
                }
                Some(c)
            }
            EffectSpec::LinkCompliance { link } => {
                let mut c = DMatrix::zeros(3 * n, 1);
                for i in 0..n {
                    let (v, pivot) = self.bend.get(i)?.get(link - 1)?;
                    let d = v.cross(&(self.p0[i] - pivot.coords)) / self.sigma[i];
                    c.fixed_view_mut::<3, 1>(3 * i, 0).copy_from(&d);
                }
                Some(c)
            }
            EffectSpec::TimeDrift => {
                let mut c = DMatrix::zeros(3 * n, 1);
                for (i, row) in rows.iter().enumerate().take(n) {
                    let h = row.t_s? / 3600.0;
                    c.fixed_view_mut::<3, 1>(3 * i, 0).copy_from(&(self.ds.fixed_rows::<3>(3 * i) * h));
                }
                Some(c)
            }
            _ => {
                let j = spec.joint()? - 1;
                if j >= model_kinds {
                    return None;
                }
                let k = spec.scales().len();
                let mut c = DMatrix::zeros(3 * n, k);
                for (i, row) in rows.iter().enumerate().take(n) {
                    let g = self.regressor(spec, j, i, row);
                    for (kk, gv) in g.iter().enumerate() {
                        let v = self.dq.fixed_view::<3, 1>(3 * i, j) * *gv;
                        c.fixed_view_mut::<3, 1>(3 * i, kk).copy_from(&v);
                    }
                }
                Some(c)
            }
        }
    }

    /// `dq_j = sum_k theta_k g_k(row)`: the regressors `g_k` of a joint effect for row `i`.
    fn regressor(&self, spec: &EffectSpec, j: usize, i: usize, row: &PoseMeasurement) -> Vec<f64> {
        match spec {
            EffectSpec::JointCompliance { .. } => vec![-self.tau[i][j]],
            EffectSpec::Backlash { .. } => {
                let d = row.dir.as_ref().and_then(|d| d.get(j)).copied().unwrap_or(0) as f64;
                vec![-d / 2.0]
            }
            EffectSpec::JointScaleError { .. } => vec![row.q[j]],
            EffectSpec::PeriodicJointError { period_si, .. } => {
                let x = std::f64::consts::TAU * row.q[j] / period_si;
                vec![x.sin(), x.cos()]
            }
            _ => vec![],
        }
    }
}

/// Rows `idx` (3 entries per row) of a matrix.
pub(crate) fn gather(m: &DMatrix<f64>, idx: &[usize]) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(3 * idx.len(), m.ncols());
    for (k, &i) in idx.iter().enumerate() {
        out.view_mut((3 * k, 0), (3, m.ncols())).copy_from(&m.view((3 * i, 0), (3, m.ncols())));
    }
    out
}

/// Entries of rows `idx` of a vector.
pub(crate) fn gather_v(v: &DVector<f64>, idx: &[usize]) -> DVector<f64> {
    let mut out = DVector::zeros(3 * idx.len());
    for (k, &i) in idx.iter().enumerate() {
        out.fixed_rows_mut::<3>(3 * k).copy_from(&v.fixed_rows::<3>(3 * i));
    }
    out
}

/// The base model decomposed on a set of training rows.
pub(crate) struct Basis {
    /// Training rows (indices into the analysis rows).
    pub train: Vec<usize>,
    /// Orthonormal basis of the training rows' base columns.
    pub u: DMatrix<f64>,
    /// Pseudo-inverse of the training rows' base columns.
    pub pinv: DMatrix<f64>,
    /// Training residuals after the base refit (orthogonal to `u`).
    pub y_tilde: DVector<f64>,
}

impl Basis {
    /// Decomposes `lin.base` on `train`.
    pub fn new(lin: &Lin, train: &[usize]) -> Result<Self> {
        let x = gather(&lin.base, train);
        let y = gather_v(&lin.r, train);
        let svd = x.clone().svd(true, true);
        let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
            return Err(CalibError::Numeric("SVD of the training Jacobian failed".into()));
        };
        let smax = svd.singular_values.iter().copied().fold(0.0, f64::max);
        let keep: Vec<usize> =
            (0..svd.singular_values.len()).filter(|&k| svd.singular_values[k] > 1e-9 * smax.max(1e-300)).collect();
        let uk = DMatrix::from_fn(u.nrows(), keep.len(), |i, k| u[(i, keep[k])]);
        let mut pinv = DMatrix::zeros(x.ncols(), x.nrows());
        for &k in &keep {
            let s = svd.singular_values[k];
            let vcol = vt.row(k).transpose();
            let ucol = u.column(k);
            pinv += (vcol / s) * ucol.transpose();
        }
        let y_tilde = &y - &uk * (uk.transpose() * &y);
        Ok(Self { train: train.to_vec(), u: uk, pinv, y_tilde })
    }
}

/// One cross-validation fold: the basis of its training rows and the base model's held-out
/// residuals on its test rows.
pub(crate) struct Fold {
    /// Training decomposition.
    pub basis: Basis,
    /// Held-out rows.
    pub test: Vec<usize>,
    /// Base columns on the held-out rows.
    pub x_te: DMatrix<f64>,
    /// Held-out residuals of the refitted base model.
    pub e0: DVector<f64>,
}

impl Fold {
    /// The fold with held-out rows `test` (the others train).
    pub fn new(lin: &Lin, test: &[usize]) -> Result<Self> {
        let train: Vec<usize> = (0..lin.n).filter(|i| !test.contains(i)).collect();
        let basis = Basis::new(lin, &train)?;
        let y_tr = gather_v(&lin.r, &train);
        let x_te = gather(&lin.base, test);
        let e0 = gather_v(&lin.r, test) - &x_te * (&basis.pinv * y_tr);
        Ok(Self { basis, test: test.to_vec(), x_te, e0 })
    }
}

/// Least squares `min |b - a x|` for a few columns, tolerant of a (near) zero column.
pub(crate) fn small_lstsq(a: &DMatrix<f64>, b: &DVector<f64>) -> DVector<f64> {
    let g = a.transpose() * a;
    let rhs = a.transpose() * b;
    let k = g.nrows();
    let tr = (0..k).map(|i| g[(i, i)]).sum::<f64>().max(1e-300);
    let svd = g.svd(true, true);
    svd.solve(&rhs, 1e-12 * tr).unwrap_or_else(|_| DVector::zeros(k))
}

/// A candidate's columns fitted together with the base model on a basis' training rows.
pub(crate) struct JointFit {
    /// The candidate's parameters.
    pub theta: DVector<f64>,
    /// `pinv * C_train`: how the base parameters shift per unit of the candidate's.
    pub shift: DMatrix<f64>,
}

/// Fits candidate columns `c` (all analysis rows) jointly with the base on `basis`.
pub(crate) fn joint_fit(basis: &Basis, c: &DMatrix<f64>) -> JointFit {
    let c_tr = gather(c, &basis.train);
    let c_tilde = &c_tr - &basis.u * (basis.u.transpose() * &c_tr);
    let theta = small_lstsq(&c_tilde, &basis.y_tilde);
    let shift = &basis.pinv * &c_tr;
    JointFit { theta, shift }
}

/// Held-out residuals on a fold after adding the candidate columns `c`.
pub(crate) fn heldout_with(fold: &Fold, c: &DMatrix<f64>) -> (DVector<f64>, DVector<f64>) {
    let fit = joint_fit(&fold.basis, c);
    let c_te = gather(c, &fold.test);
    let g = c_te - &fold.x_te * &fit.shift;
    let e1 = &fold.e0 - g * &fit.theta;
    (e1, fit.theta)
}

/// The sine of the smallest principal angle between the candidate's columns and the span of
/// the base columns on the basis' rows (1: orthogonal; 0: a combination of the base).
pub(crate) fn sin_angle(basis: &Basis, c: &DMatrix<f64>) -> f64 {
    let c_tr = gather(c, &basis.train);
    // Orthonormalise the candidate's own columns first.
    let mut q = c_tr.clone();
    for k in 0..q.ncols() {
        for l in 0..k {
            let d = q.column(l).dot(&q.column(k));
            let col_l = q.column(l).clone_owned();
            q.column_mut(k).axpy(-d, &col_l, 1.0);
        }
        let nrm = q.column(k).norm();
        if nrm <= 0.0 {
            return 0.0;
        }
        q.column_mut(k).scale_mut(1.0 / nrm);
    }
    let t = &q - &basis.u * (basis.u.transpose() * &q);
    let sv = t.svd(false, false).singular_values;
    sv.iter().copied().fold(f64::INFINITY, f64::min).clamp(0.0, 1.0)
}

/// Per-row weights and projections for scanning the period of a periodic joint error quickly:
/// for training row `l`, `w_l = U_l^T d_l` (`d_l` the joint's column), `u_l = d_l . y~_l` and
/// `c_l = |d_l|^2`.
pub(crate) struct PeriodScan {
    w: DMatrix<f64>,
    u: Vec<f64>,
    c2: Vec<f64>,
    q: Vec<f64>,
}

impl PeriodScan {
    /// Prepares the scan of joint `j` on `basis`.
    pub fn new(lin: &Lin, basis: &Basis, j: usize, q_all: &[f64]) -> Self {
        let m = basis.train.len();
        let r = basis.u.ncols();
        let mut w = DMatrix::zeros(r, m);
        let mut u = vec![0.0; m];
        let mut c2 = vec![0.0; m];
        let mut q = vec![0.0; m];
        for (l, &i) in basis.train.iter().enumerate() {
            let d = lin.dq.fixed_view::<3, 1>(3 * i, j);
            let ub = basis.u.view((3 * l, 0), (3, r));
            w.set_column(l, &(ub.transpose() * d));
            u[l] = d.dot(&basis.y_tilde.fixed_rows::<3>(3 * l));
            c2[l] = d.norm_squared();
            q[l] = q_all[i];
        }
        Self { w, u, c2, q }
    }

    /// Training sum of squares removed by a sinusoid of frequency `f` (cycles per joint unit).
    pub fn gain(&self, f: f64) -> f64 {
        let m = self.q.len();
        let mut s = DVector::zeros(m);
        let mut c = DVector::zeros(m);
        let (mut ss, mut sc, mut cc, mut bs, mut bc) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for l in 0..m {
            let x = std::f64::consts::TAU * f * self.q[l];
            let (sn, cs) = x.sin_cos();
            s[l] = sn;
            c[l] = cs;
            ss += self.c2[l] * sn * sn;
            sc += self.c2[l] * sn * cs;
            cc += self.c2[l] * cs * cs;
            bs += self.u[l] * sn;
            bc += self.u[l] * cs;
        }
        let ws = &self.w * s;
        let wc = &self.w * c;
        let g11 = ss - ws.dot(&ws);
        let g12 = sc - ws.dot(&wc);
        let g22 = cc - wc.dot(&wc);
        let det = g11 * g22 - g12 * g12;
        let tr = (g11 + g22).max(1e-300);
        if det <= 1e-10 * tr * tr {
            // Degenerate: fit the better single direction.
            let a = if g11 > 0.0 { bs * bs / g11 } else { 0.0 };
            let b = if g22 > 0.0 { bc * bc / g22 } else { 0.0 };
            return a.max(b);
        }
        (g22 * bs * bs - 2.0 * g12 * bs * bc + g11 * bc * bc) / det
    }

    /// The frequency of largest gain over `grid`, refined by golden-section search within one
    /// grid step either side; returns `(frequency, gain)`.
    pub fn best(&self, grid: &[f64]) -> (f64, f64) {
        let mut best = (f64::NAN, f64::NEG_INFINITY);
        let mut best_k = 0;
        for (k, &f) in grid.iter().enumerate() {
            let g = self.gain(f);
            if g > best.1 {
                best = (f, g);
                best_k = k;
            }
        }
        if grid.len() < 2 {
            return best;
        }
        let step =
            if best_k + 1 < grid.len() { grid[best_k + 1] - grid[best_k] } else { grid[best_k] - grid[best_k - 1] };
        let (mut a, mut b) = (best.0 - step, best.0 + step);
        let phi = 0.5 * (5f64.sqrt() - 1.0);
        let mut x1 = b - phi * (b - a);
        let mut x2 = a + phi * (b - a);
        let mut g1 = self.gain(x1);
        let mut g2 = self.gain(x2);
        for _ in 0..30 {
            if g1 > g2 {
                b = x2;
                x2 = x1;
                g2 = g1;
                x1 = b - phi * (b - a);
                g1 = self.gain(x1);
            } else {
                a = x1;
                x1 = x2;
                g1 = g2;
                x2 = a + phi * (b - a);
                g2 = self.gain(x2);
            }
        }
        let (f, g) = if g1 > g2 { (x1, g1) } else { (x2, g2) };
        if g > best.1 && f > 0.0 {
            (f, g)
        } else {
            best
        }
    }
}
