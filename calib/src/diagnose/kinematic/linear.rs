//! The linearised joint refit behind the candidate screening.
//!
//! At a calibrated model (geometry plus the effects accepted so far, fitted on the analysis
//! rows) the whitened residuals `r` and the Jacobian `X` of the predictions with respect to
//! every free parameter are computed once; `X` is the kinematic calibration's own Jacobian
//! (`kinematic::prediction_jacobian`: analytic for frames, tool, joint offsets and serial
//! corrections), not a second differentiation of the model. Adding a candidate effect with prediction columns
//! `C` and refitting geometry and effect together on a set of training rows is then the linear
//! least-squares problem `min |r - X dx - C theta|` over those rows: the geometry is refitted
//! with the effect, never frozen. Because the start point is a converged fit and the effects
//! are small, this is the Gauss-Newton step of the full refit; the accepted candidate is
//! confirmed with full non-linear refits (see the parent module).
//!
//! Per fold the training rows' `X` is decomposed once by the least-squares layer's truncated
//! SVD (`U`, pseudo-inverse: [`ferrocal_lsq::linear::TruncatedSvd`]); each candidate then costs
//! a few products with its one or two columns.

use ferrocal_lsq::linear::TruncatedSvd;
use nalgebra::{DMatrix, DVector, Isometry3, Vector3};

use crate::effects::{axis_wobble, holding_torques, link_bendings, EffectSpec};
use crate::error::Result;
use crate::kinematic::{prediction_jacobian, CalibratedModel, KinematicCalibration};
use crate::measurement::PoseMeasurement;

/// A joint's wobble directions and axis point (`effects::axis_wobble`), device frame.
pub(crate) type Wobble = (Vector3<f64>, Vector3<f64>, nalgebra::Point3<f64>);

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
    /// Per row and joint (serial chains; empty otherwise): the wobble directions and the axis
    /// point of each revolute joint (`effects::axis_wobble`), in the device frame; zeros for a
    /// prismatic joint.
    pub wobble: Vec<Vec<Wobble>>,
    /// Per row: predicted position in the device frame.
    pub p0: Vec<Vector3<f64>>,
    /// Per row: position standard deviation.
    pub sigma: Vec<f64>,
    /// The model's base frame in the device frame.
    pub frame: Isometry3<f64>,
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
        // The calibration's own Jacobian at the calibrated model (analytic where it has an
        // analytic form), whitened by each row's sigma: free parameters' columns scaled to unit
        // norm, and the joint offsets' columns as the derivative per joint reading.
        let jac = prediction_jacobian(cal, rows, sigma)?;
        let mut base = DMatrix::zeros(3 * n, cal.free.len());
        for (k, &idx) in cal.free.iter().enumerate() {
            let c = jac.column(idx);
            let norm = c.norm();
            if norm > 0.0 {
                base.set_column(k, &(c / norm));
            }
        }
        let nj = cm.joint_offsets.len();
        let dq = jac.columns(cal.layout.offsets.start, nj).into_owned();
        let f: Isometry3<f64> = cm.device_frame;
        let mut ds = DVector::zeros(3 * n);
        for i in 0..n {
            let v = (p0[i] - f.translation.vector) / sigma[i];
            ds.fixed_rows_mut::<3>(3 * i).copy_from(&v);
        }
        let mut tau = Vec::with_capacity(n);
        let mut bend = Vec::with_capacity(n);
        let mut wobble = Vec::with_capacity(n);
        for row in rows {
            tau.push(holding_torques(&cm.load_model, &row.q, row.payload_kg.unwrap_or(0.0))?);
            let mut per_link = Vec::new();
            // (Link bending is not modelled on chains with coupled joints: no candidate uses it.)
            if matches!(&cm.load_model, ferrocal_robot::RobotModel::Serial(c) if !c.has_mimic_joints()) {
                let (q, _) = cm.effective(row)?;
                per_link = link_bendings(&cm.load_model, &q, row.payload_kg.unwrap_or(0.0))?
                    .into_iter()
                    .map(|(v, pivot)| (f.rotation * v, f * pivot))
                    .collect();
            }
            bend.push(per_link);
            let mut per_joint = Vec::new();
            if let ferrocal_robot::RobotModel::Serial(_) = &cm.load_model {
                let (q, _) = cm.effective(row)?;
                for (j, kind) in ferrocal_robot::Kinematics::joint_kinds(&cm.load_model).iter().enumerate() {
                    per_joint.push(if *kind == ferrocal_robot::JointKind::Revolute {
                        let (e1, e2, pivot) = axis_wobble(&cm.load_model, j + 1, &q)?;
                        (f.rotation * e1, f.rotation * e2, f * pivot)
                    } else {
                        (Vector3::zeros(), Vector3::zeros(), nalgebra::Point3::origin())
                    });
                }
            }
            wobble.push(per_joint);
        }
        Ok(Self { n, r, base, dq, ds, tau, bend, wobble, p0, sigma: sigma.to_vec(), frame: f })
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
            wobble: self.wobble.clone(),
            p0: self.p0.clone(),
            sigma: self.sigma.clone(),
            frame: self.frame,
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
            EffectSpec::AxisMisalignment { joint } => {
                let mut c = DMatrix::zeros(3 * n, 2);
                for i in 0..n {
                    let (e1, e2, pivot) = self.wobble.get(i)?.get(joint - 1)?;
                    let lever = self.p0[i] - pivot.coords;
                    for (k, e) in [e1, e2].into_iter().enumerate() {
                        let d = e.cross(&lever) / self.sigma[i];
                        c.fixed_view_mut::<3, 1>(3 * i, k).copy_from(&d);
                    }
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
            EffectSpec::Custom(_) => None,
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

    /// Prediction columns of an effect of the registry (whitened), each parameter at its typical
    /// size and divided by it: its joint corrections through the joint columns, its length
    /// factor through the length column, its pose correction (at the readings) moving the
    /// predicted point.
    pub fn custom_columns(
        &self,
        effect: &dyn crate::effects::Effect,
        model: &ferrocal_robot::RobotModel,
        rows: &[&PoseMeasurement],
    ) -> Option<DMatrix<f64>> {
        let scales = effect.scales();
        let nj = self.dq.ncols();
        let mut c = DMatrix::zeros(3 * self.n, scales.len());
        for (k, s) in scales.iter().enumerate() {
            let mut theta = vec![0.0; scales.len()];
            theta[k] = *s;
            for (i, row) in rows.iter().enumerate().take(self.n) {
                let mut dq = vec![0.0; nj];
                effect.add_joint_delta(model, row, &theta, &mut dq).ok()?;
                let mut d = self.dq.fixed_view::<3, 1>(3 * i, 0) * 0.0;
                for (j, v) in dq.iter().enumerate() {
                    d += self.dq.fixed_view::<3, 1>(3 * i, j) * *v;
                }
                d += self.ds.fixed_rows::<3>(3 * i) * (effect.length_scale(row, &theta) - 1.0);
                if effect.corrects_pose() {
                    let iso = effect.pose_correction(model, row, &row.q, &theta).ok()?;
                    let p_base = self.frame.inverse_transform_point(&self.p0[i].into());
                    let moved = self.frame * (iso * p_base);
                    d += (moved.coords - self.p0[i]) / self.sigma[i];
                }
                c.fixed_view_mut::<3, 1>(3 * i, k).copy_from(&(d / *s));
            }
        }
        Some(c)
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
            EffectSpec::CoupledTransmission { driver, .. } => vec![row.q[driver - 1]],
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
    /// Decomposes `lin.base` on `train` (the least-squares layer's truncated SVD, singular
    /// values below `1e-9` of the largest cut).
    pub fn new(lin: &Lin, train: &[usize]) -> Result<Self> {
        let x = gather(&lin.base, train);
        let y = gather_v(&lin.r, train);
        let svd = TruncatedSvd::new(&x, 1e-9)?;
        let uk = svd.range_basis().clone();
        let pinv = svd.pseudo_inverse();
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

/// Least squares `min |b - a x|` for a few columns, tolerant of a (near) zero or repeated
/// column: the least-squares layer's truncated SVD (relative tolerance `1e-6`, the minimum-norm
/// solution); zeros when the columns are not finite.
pub(crate) fn small_lstsq(a: &DMatrix<f64>, b: &DVector<f64>) -> DVector<f64> {
    match TruncatedSvd::new(a, 1e-6) {
        Ok(svd) => svd.solve(&DMatrix::from_column_slice(b.len(), 1, b.as_slice())).column(0).into_owned(),
        Err(_) => DVector::zeros(a.ncols()),
    }
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

#[cfg(test)]
mod tests {
    use ferrocal_robot::{Kinematics, Parameterized};
    use nalgebra::Vector3;

    use super::*;
    use crate::frames::exp6;
    use crate::kinematic::{calibrate, KinematicOptions, ModelParams};

    /// A deterministic sequence in [-1, 1).
    fn wave(k: usize) -> f64 {
        ((k as f64 * 12.9898).sin() * 43758.5453).fract() * 2.0 - 1.0
    }

    /// `cm` with candidate `idx` of the layout moved by `h` the way the screen's parameters
    /// move: a left increment of the device frame, a right increment of the tool, additive
    /// offsets, model and effect parameters.
    fn moved(cal: &KinematicCalibration, idx: usize, h: f64) -> CalibratedModel {
        let (l, mut c) = (&cal.layout, cal.calibrated.clone());
        let mut d = [0.0; 6];
        if l.frame.contains(&idx) {
            d[idx - l.frame.start] = h;
            c.device_frame = exp6(&d) * c.device_frame;
        } else if l.tool.contains(&idx) {
            d[idx - l.tool.start] = h;
            c.tool *= exp6(&d);
        } else if l.offsets.contains(&idx) {
            c.joint_offsets[idx - l.offsets.start] += h;
        } else if l.model.contains(&idx) {
            let mut v = c.model.parameter_values();
            v[l.model_index[idx - l.model.start]] += h;
            c.model.set_parameter_values(&v).unwrap();
        } else {
            let e = l.effects.iter().position(|r| r.contains(&idx)).unwrap();
            c.effects[e].1[idx - l.effects[e].start] += h;
        }
        c
    }

    /// The errors of the screen's Jacobian (the calibration's own, re-based at the calibrated
    /// model) against central differences of the calibrated model's predictions, on a UR5
    /// calibrated with a periodic joint error and a joint compliance: the largest error of a
    /// unit-norm free column (first output: the serial corrections' columns; second: every
    /// other one) and the largest relative error of a joint reading's column.
    fn screen_jacobian_errors(model_params: ModelParams) -> (f64, f64, f64, f64) {
        let model = ferrocal_robot::presets::preset("ur5").unwrap();
        let data: Vec<PoseMeasurement> = (0..40)
            .map(|i| {
                let q: Vec<f64> = (0..6).map(|j| 1.5 * wave(6 * i + j)).collect();
                let t = Isometry3::new(Vector3::new(0.4, -0.1, 0.2), Vector3::new(0.1, -0.3, 1.2))
                    * model.forward(&q).unwrap()
                    * Isometry3::translation(0.05, 0.02, 0.1);
                let noise = Vector3::new(wave(900 + 3 * i), wave(901 + 3 * i), wave(902 + 3 * i)) * 1e-4;
                let mut row = PoseMeasurement::new(format!("p{i}"), q, t.translation.vector + noise);
                row.payload_kg = Some(2.0);
                row
            })
            .collect();
        let rows: Vec<&PoseMeasurement> = data.iter().collect();
        let effects =
            vec![EffectSpec::PeriodicJointError { joint: 2, period_si: 0.7 }, EffectSpec::JointCompliance { joint: 3 }];
        let opts = KinematicOptions { use_orientation: false, effects, model_params, ..KinematicOptions::default() };
        let cal = calibrate(&model, &rows, &opts).unwrap();
        let sigma: Vec<f64> = (0..rows.len()).map(|i| 2e-5 * (1.0 + 0.5 * wave(70 + i).abs())).collect();
        let lin = Lin::build(&cal, &rows, &sigma).unwrap();
        let difference = |idx: usize, h: f64| -> DVector<f64> {
            let a = predictions(&moved(&cal, idx, h), &rows).unwrap();
            let b = predictions(&moved(&cal, idx, -h), &rows).unwrap();
            DVector::from_fn(3 * rows.len(), |k, _| (a[k / 3][k % 3] - b[k / 3][k % 3]) / (2.0 * h * sigma[k / 3]))
        };
        let (mut corrections, mut others, mut joints) = (0.0f64, 0.0f64, 0.0f64);
        for (k, &idx) in cal.free.iter().enumerate() {
            let c = difference(idx, 1e-4 * cal.layout.scales[idx]);
            let e = (lin.base.column(k) - &c / c.norm()).norm();
            if cal.layout.names[idx].contains(".corr_") {
                corrections = corrections.max(e);
            } else {
                others = others.max(e);
            }
        }
        for j in 0..6 {
            let c = difference(cal.layout.offsets.start + j, 1e-6);
            joints = joints.max((lin.dq.column(j) - &c).norm() / c.norm());
        }
        assert!(cal.free.len() >= 14, "{} free parameters", cal.free.len());
        // The largest calibrated correction rotation angle.
        let largest_rotation =
            cal.params.iter().filter(|p| p.name.contains(".corr_r")).map(|p| p.value.abs()).fold(0.0, f64::max);
        (corrections, others, joints, largest_rotation)
    }

    /// Frames, tool, joint offsets and effects: the screen's columns are the derivatives of the
    /// calibrated predictions to the accuracy of the differences.
    #[test]
    fn the_screen_uses_the_derivative_of_the_calibrated_predictions() {
        let (corrections, others, joints, _) = screen_jacobian_errors(ModelParams::None);
        assert_eq!(corrections, 0.0, "no correction is free");
        assert!(others < 1e-6, "|analytic - numeric| = {others:.2e} of a unit column");
        assert!(joints < 1e-6, "joint columns: relative error {joints:.2e}");
        // With the per-joint correction transforms free: the correction columns are the
        // calibration Jacobian's, exact at any correction (left Jacobians of the rotation
        // vectors; measured 6e-9 with corrections up to 8 mrad; they were first order, 8e-3,
        // before that Jacobian became exact).
        let (corrections, others, joints, rotation) = screen_jacobian_errors(ModelParams::Default);
        eprintln!(
            "correction columns: largest error {corrections:.2e} of a unit column; rotations up to {rotation:.2e} rad"
        );
        assert!(corrections < 1e-6, "correction columns: {corrections:.2e} of a unit column ({rotation:.2e} rad)");
        assert!(others < 1e-6 && joints < 1e-6, "{others:.2e}, {joints:.2e}");
    }
}
