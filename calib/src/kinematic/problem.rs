//! The least-squares problem of [`super::calibrate`]: whitened residuals of every row and their
//! Jacobian (analytic for the frames, tool, joint offsets and serial corrections).

use ferrocal_robot::{Kinematics, Parameterized, RobotModel, Unit};
use nalgebra::{DMatrix, DVector, Isometry3, Translation3, UnitQuaternion, Vector3};

use super::{model_for_row, row_error, CalibratedModel, Cost, StateLayout};
use crate::effects::EffectSpec;
use crate::error::{CalibError, Result};
use crate::frames::exp6;
use crate::lsq::Problem;
use crate::measurement::PoseMeasurement;
use ferrocal_lsq::so3;

pub(super) struct KinProblem<'a> {
    pub(super) base_model: RobotModel,
    pub(super) rows: &'a [&'a PoseMeasurement],
    pub(super) layout: &'a StateLayout,
    pub(super) f0: Isometry3<f64>,
    pub(super) tool0: Isometry3<f64>,
    pub(super) use_ori: bool,
    /// Start values of all candidates.
    pub(super) start: Vec<f64>,
    /// Free candidate indices.
    pub(super) free: Vec<usize>,
    pub(super) sigma_pos: Vec<f64>,
    pub(super) sigma_ori: Vec<f64>,
    /// Per row, the whitening matrix `W = L^-1` of the row's covariance block `L L^T` (3 x 3,
    /// or 6 x 6 with orientations), when the row carries a covariance; `None` rows are divided
    /// by `sigma_pos` / `sigma_ori` exactly as before covariances existed.
    pub(super) whiten: Vec<Option<DMatrix<f64>>>,
    pub(super) effects: Vec<EffectSpec>,
    pub(super) cost: Cost,
    /// Legs of a parallel robot (closure cost).
    pub(super) n_legs: usize,
}

impl KinProblem<'_> {
    pub(super) fn full(&self, x: &[f64]) -> Vec<f64> {
        let mut v = self.start.clone();
        for (k, &i) in self.free.iter().enumerate() {
            v[i] = x[k];
        }
        v
    }

    pub(super) fn model_for(&self, full: &[f64]) -> Result<RobotModel> {
        let mut m = self.base_model.clone();
        if !self.layout.model_index.is_empty() {
            let mut vals = m.parameter_values();
            for (k, &pi) in self.layout.model_index.iter().enumerate() {
                vals[pi] = full[self.layout.model.start + k];
            }
            m.set_parameter_values(&vals)?;
        }
        Ok(m)
    }

    pub(super) fn frames(&self, full: &[f64]) -> (Isometry3<f64>, Isometry3<f64>) {
        let f = exp6(&full[self.layout.frame.clone()]) * self.f0;
        let t = &full[self.layout.tool.clone()];
        let tool =
            if t.len() == 6 { self.tool0 * exp6(t) } else { self.tool0 * Isometry3::translation(t[0], t[1], t[2]) };
        (f, tool)
    }

    pub(super) fn calibrated(&self, full: &[f64]) -> Result<CalibratedModel> {
        let (device_frame, tool) = self.frames(full);
        Ok(CalibratedModel {
            model: self.model_for(full)?,
            device_frame,
            tool,
            joint_offsets: full[self.layout.offsets.clone()].to_vec(),
            orientation_calibrated: self.use_ori,
            effects: self
                .effects
                .iter()
                .zip(&self.layout.effects)
                .map(|(e, r)| (e.clone(), full[r.clone()].to_vec()))
                .collect(),
            load_model: self.base_model.clone(),
        })
    }

    pub(super) fn block(&self) -> usize {
        if self.cost == Cost::Closure {
            return self.n_legs;
        }
        if self.use_ori {
            6
        } else {
            3
        }
    }

    /// Closure residuals: leg-length errors at the measured pose, over the row's sigma (a row's
    /// full covariance is not used here: leg lengths are not the measured coordinates).
    pub(super) fn closure_residuals(&self, cm: &CalibratedModel) -> Result<DVector<f64>> {
        let b = self.block();
        let par =
            cm.model.parallel().ok_or_else(|| CalibError::Data("the closure cost needs a parallel robot".into()))?;
        let mech = par.mechanism()?;
        let mut r = DVector::zeros(self.rows.len() * b);
        let f_inv = cm.device_frame.inverse();
        let tool_inv = cm.tool.inverse();
        for (k, row) in self.rows.iter().enumerate() {
            let (q, scale) = cm.effective(row).map_err(|e| row_error(row, e))?;
            let rot = row.orientation.unwrap_or_else(UnitQuaternion::identity);
            let t_dev = Isometry3::from_parts(Translation3::from(row.position_m), rot);
            let mut t_base_target = f_inv * t_dev;
            if scale != 1.0 {
                t_base_target.translation.vector /= scale;
            }
            let t_base_tool = t_base_target * tool_inv;
            let legs = mech.leg_states(&q, &t_base_tool).map_err(|e| row_error(row, e))?;
            for (j, leg) in legs.iter().enumerate() {
                r[k * b + j] = leg.length_error_m() / self.sigma_pos[k];
            }
        }
        Ok(r)
    }

    /// Whitened residuals of every row for a calibrated model.
    pub(super) fn residuals_of(&self, cm: &CalibratedModel) -> Result<DVector<f64>> {
        if self.cost == Cost::Closure {
            return self.closure_residuals(cm);
        }
        let b = self.block();
        let mut r = DVector::zeros(self.rows.len() * b);
        for (k, row) in self.rows.iter().enumerate() {
            let t = cm.predict_row(row).map_err(|e| row_error(row, e))?;
            if let Some(w) = &self.whiten[k] {
                let mut e = DVector::zeros(b);
                e.fixed_rows_mut::<3>(0).copy_from(&(row.position_m - t.translation.vector));
                if self.use_ori {
                    let qm = row.orientation.expect("checked");
                    e.fixed_rows_mut::<3>(3).copy_from(&(qm * t.rotation.inverse()).scaled_axis());
                }
                r.rows_mut(k * b, b).copy_from(&(w * e));
                continue;
            }
            let e = (row.position_m - t.translation.vector) / self.sigma_pos[k];
            r.fixed_rows_mut::<3>(k * b).copy_from(&e);
            if self.use_ori {
                let qm = row.orientation.expect("checked");
                let w = (qm * t.rotation.inverse()).scaled_axis() / self.sigma_ori[k];
                r.fixed_rows_mut::<3>(k * b + 3).copy_from(&w);
            }
        }
        Ok(r)
    }
}

impl Problem for KinProblem<'_> {
    fn n_params(&self) -> usize {
        self.free.len()
    }
    fn n_residuals(&self) -> usize {
        self.rows.len() * self.block()
    }
    fn block_size(&self) -> usize {
        self.block()
    }
    fn scales(&self) -> Vec<f64> {
        self.free.iter().map(|&i| self.layout.scales[i]).collect()
    }
    fn residuals(&self, x: &[f64]) -> Result<DVector<f64>> {
        let full = self.full(x);
        let cm = self.calibrated(&full)?;
        self.residuals_of(&cm)
    }
    fn jacobian(&self, x: &[f64]) -> Result<DMatrix<f64>> {
        let full = self.full(x);
        let jfull = self.full_jacobian(&full)?;
        let mut j = DMatrix::zeros(jfull.nrows(), self.free.len());
        for (k, &i) in self.free.iter().enumerate() {
            j.set_column(k, &jfull.column(i));
        }
        Ok(j)
    }
}

impl KinProblem<'_> {
    /// The central difference of the whitened residuals along candidate `col` at `full`, step
    /// `h`: a numeric column of [`Self::full_jacobian`].
    fn central_difference(&self, full: &[f64], col: usize, h: f64) -> Result<DVector<f64>> {
        let mut fp = full.to_vec();
        fp[col] += h;
        let rp = self.residuals_of(&self.calibrated(&fp)?)?;
        fp[col] -= 2.0 * h;
        let rm = self.residuals_of(&self.calibrated(&fp)?)?;
        Ok((rp - rm) / (2.0 * h))
    }

    /// Jacobian of the whitened residuals with respect to every candidate at `full`.
    pub(super) fn full_jacobian(&self, full: &[f64]) -> Result<DMatrix<f64>> {
        if self.cost == Cost::Closure {
            let mut jac = DMatrix::zeros(self.n_residuals(), self.layout.len());
            for col in 0..self.layout.len() {
                let h = 1e-3 * self.layout.scales[col];
                jac.set_column(col, &self.central_difference(full, col, h)?);
            }
            return Ok(jac);
        }
        let b = self.block();
        let cm = self.calibrated(full)?;
        let n_cand = self.layout.len();
        let mut jac = DMatrix::zeros(self.rows.len() * b, n_cand);
        let rf = cm.device_frame.rotation;
        // Analytic columns: frame, tool, offsets, serial corrections.
        let serial = match &cm.model {
            RobotModel::Serial(c) => Some(c),
            _ => None,
        };
        // (column, joint index into the chain's joints, correction component).
        let corr_cols: Vec<(usize, usize, usize)> = match serial {
            Some(chain) => self
                .layout
                .model_index
                .iter()
                .enumerate()
                .filter_map(|(k, &pi)| {
                    let name = &self.base_model.parameters()[pi].name;
                    let joint = chain.joint_of_parameter(name)?;
                    let comp = ferrocal_robot::serial::CORRECTION_NAMES
                        .iter()
                        .position(|c| name.ends_with(&format!(".{c}")))?;
                    Some((self.layout.model.start + k, joint, comp))
                })
                .collect(),
            None => Vec::new(),
        };
        let params = self.base_model.parameters();
        let frame_t = Vector3::new(
            full[self.layout.frame.start],
            full[self.layout.frame.start + 1],
            full[self.layout.frame.start + 2],
        );
        let frame_jl = so3::left_jacobian(&Vector3::new(
            full[self.layout.frame.start + 3],
            full[self.layout.frame.start + 4],
            full[self.layout.frame.start + 5],
        ));
        let tool_jr = (self.layout.tool.len() == 6).then(|| {
            let r = &full[self.layout.tool.start + 3..self.layout.tool.start + 6];
            so3::right_jacobian(&Vector3::new(r[0], r[1], r[2]))
        });
        // Per corrected joint, `J_l` of its correction rotation and the rotation itself.
        let corr_rot: Vec<(nalgebra::Matrix3<f64>, UnitQuaternion<f64>)> = match serial {
            Some(chain) => chain
                .joints
                .iter()
                .map(|j| {
                    let c = Vector3::new(j.correction[3], j.correction[4], j.correction[5]);
                    (so3::left_jacobian(&c), UnitQuaternion::from_scaled_axis(c))
                })
                .collect(),
            None => Vec::new(),
        };
        // Compliant joints: the joint readings (and offsets) reach the kinematics through the
        // equilibrium `q_eff = q0 - C tau(q_eff)`, whose derivative is `(I + C K)^-1`.
        let compliance = crate::effects::compliances(&cm.effects, cm.model.dof())?;
        let compliant = compliance.iter().any(|c| *c != 0.0);
        for (k, row) in self.rows.iter().enumerate() {
            let (qq, scale) = cm.effective(row).map_err(|e| row_error(row, e))?;
            let row_model = model_for_row(&cm.model, row)?;
            let t_base_flange = row_model.forward(&qq).map_err(|e| row_error(row, e))?;
            // The flange-side geometry before the effects' pose corrections and length scale
            // (levers of the joint and correction columns), and the prediction itself.
            let t_dev_tool = cm.device_frame * t_base_flange * cm.tool;
            let p = t_dev_tool.translation.vector;
            let t_pred = cm.predict_row(row).map_err(|e| row_error(row, e))?;
            let sp = self.sigma_pos[k];
            let so = self.sigma_ori[k];
            let whiten = self.whiten[k].as_ref();
            // The orientation residual `log(R_meas R_pred^-1)` moves by `-J_r(e)^-1 dw` under a
            // left rotation `dw` of the prediction.
            let jr_inv = if self.use_ori {
                let qm = row.orientation.expect("checked");
                so3::right_jacobian_inverse(&(qm * t_pred.rotation.inverse()).scaled_axis())
            } else {
                nalgebra::Matrix3::identity()
            };
            // d(prediction) columns: (dp, dw) in the device frame; residual = -d(prediction).
            let mut put = |col: usize, dp: Vector3<f64>, dw: Vector3<f64>| {
                let dw = jr_inv * dw;
                if let Some(w) = whiten {
                    let mut d = DVector::zeros(b);
                    d.fixed_rows_mut::<3>(0).copy_from(&dp);
                    if self.use_ori {
                        d.fixed_rows_mut::<3>(3).copy_from(&dw);
                    }
                    jac.view_mut((k * b, col), (b, 1)).copy_from(&(-(w * d)));
                    return;
                }
                jac.fixed_view_mut::<3, 1>(k * b, col).copy_from(&(-dp / sp));
                if self.use_ori {
                    jac.fixed_view_mut::<3, 1>(k * b + 3, col).copy_from(&(-dw / so));
                }
            };
            // Device frame `exp6(x) f0` (left increment of the translation `x_t` and rotation
            // `x_r`): dp = dt + (J_l(x_r) dr) x (p - x_t), dw = J_l(x_r) dr.
            let lever_frame = t_pred.translation.vector - frame_t;
            for a in 0..3 {
                put(self.layout.frame.start + a, Vector3::ith(a, 1.0), Vector3::zeros());
                let w = frame_jl.column(a).into_owned();
                put(self.layout.frame.start + 3 + a, w.cross(&lever_frame), w);
            }
            // Tool `tool0 exp6(x)` (translation in the tool0 frame; rotation on the right, so
            // dw = R_pred J_r(x_r) dr, and the rotation does not move the target point).
            let t_dev_tool0 = cm.device_frame * t_base_flange * self.tool0;
            for a in 0..self.layout.tool.len().min(3) {
                put(
                    self.layout.tool.start + a,
                    scale * (t_dev_tool0.rotation * Vector3::ith(a, 1.0)),
                    Vector3::zeros(),
                );
            }
            if let Some(jr) = &tool_jr {
                for a in 0..3 {
                    let w = t_dev_tool.rotation * jr.column(a).into_owned();
                    put(self.layout.tool.start + 3 + a, Vector3::zeros(), w);
                }
            }
            // Joint offsets: geometric Jacobian of the model's tool point, moved to the target.
            let mut jg = row_model.jacobian(&qq).map_err(|e| row_error(row, e))?;
            if compliant {
                let payload = row.payload_kg.unwrap_or(0.0);
                let m = crate::effects::equilibrium_sensitivity(&cm.load_model, &qq, &compliance, payload)
                    .map_err(|e| row_error(row, e))?;
                jg *= m;
            }
            let lever = p - (cm.device_frame * t_base_flange).translation.vector;
            for i in 0..cm.model.dof() {
                let v = rf * Vector3::new(jg[(0, i)], jg[(1, i)], jg[(2, i)]);
                let w = rf * Vector3::new(jg[(3, i)], jg[(4, i)], jg[(5, i)]);
                put(self.layout.offsets.start + i, scale * (v + w.cross(&lever)), w);
            }
            // Serial corrections: link `A Exp(c)` with `A` the uncorrected link frame and
            // `Exp(c) = (c_t, exp(c_r))`: dp = R_A dc_t; for the rotation, w = R_A J_l(c_r) dc_r,
            // dp = w x (p - o_link), dw = w.
            if let (Some(_), RobotModel::Serial(chain)) = (serial, row_model.as_ref()) {
                if !corr_cols.is_empty() {
                    let fr = chain.frames(&qq).map_err(|e| row_error(row, e))?;
                    for &(col, j, comp) in &corr_cols {
                        if !chain.moves_tip(j) {
                            continue; // a joint of another branch does not move this row's tip
                        }
                        let link = cm.device_frame * fr.corrected[j];
                        let (jl, r_c) = &corr_rot[j];
                        let r_a = link.rotation * r_c.inverse();
                        if comp < 3 {
                            put(col, scale * (r_a * Vector3::ith(comp, 1.0)), Vector3::zeros());
                        } else {
                            let w = r_a * jl.column(comp - 3).into_owned();
                            put(col, scale * w.cross(&(p - link.translation.vector)), w);
                        }
                    }
                }
            }
        }
        // Numeric columns: effect parameters.
        for r in &self.layout.effects {
            for col in r.clone() {
                let h = 1e-3 * self.layout.scales[col];
                jac.set_column(col, &self.central_difference(full, col, h)?);
            }
        }
        // Numeric columns: model parameters without an analytic form.
        let analytic: Vec<usize> = corr_cols.iter().map(|c| c.0).collect();
        for (kk, &pi) in self.layout.model_index.iter().enumerate() {
            let col = self.layout.model.start + kk;
            if analytic.contains(&col) {
                continue;
            }
            let h = match params[pi].unit {
                Unit::Metre => 1e-7,
                Unit::Radian => 1e-7,
                _ => 1e-7,
            };
            jac.set_column(col, &self.central_difference(full, col, h)?);
        }
        Ok(jac)
    }
}

/// Per row, the whitening matrix `W = L^-1` of the covariance block the residual uses, when the
/// row carries a covariance and `use_covariance` is set: the position block (3 x 3) without
/// orientations; with orientations the 6 x 6 covariance, or for a position-only covariance the
/// position block beside `sigma_ori^2 I` (no cross terms). `W Sigma W^T = I`, so the whitened
/// residual `W e` has unit covariance. The closure cost keeps the scalar sigmas (`None`).
pub(super) fn whitening_matrices(
    rows: &[&PoseMeasurement],
    use_ori: bool,
    sigma_ori: &[f64],
    use_covariance: bool,
    cost: Cost,
) -> Result<Vec<Option<DMatrix<f64>>>> {
    rows.iter()
        .zip(sigma_ori)
        .map(|(r, &so)| {
            let Some(c) = r.covariance.as_ref().filter(|_| use_covariance && cost == Cost::ForwardKinematics) else {
                return Ok(None);
            };
            c.validate().map_err(|e| row_error(r, e))?;
            let block = match (use_ori, c.pose()) {
                (false, _) => DMatrix::from_fn(3, 3, |i, j| c.position_m2()[(i, j)]),
                (true, Some(m6)) => DMatrix::from_fn(6, 6, |i, j| m6[(i, j)]),
                (true, None) => {
                    let p = c.position_m2();
                    DMatrix::from_fn(6, 6, |i, j| match (i < 3, j < 3) {
                        (true, true) => p[(i, j)],
                        (false, false) if i == j => so * so,
                        _ => 0.0,
                    })
                }
            };
            let n = block.nrows();
            let chol = block.cholesky().ok_or_else(|| row_error(r, "the covariance is not positive definite"))?;
            let w = chol
                .l()
                .solve_lower_triangular(&DMatrix::identity(n, n))
                .ok_or_else(|| row_error(r, "the covariance's Cholesky factor is singular"))?;
            Ok(Some(w))
        })
        .collect()
}
