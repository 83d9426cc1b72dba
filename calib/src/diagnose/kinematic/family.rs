//! The kinematic candidate family: each kind of [`EffectSpec`] on each joint or link where the
//! recording can show it (a periodic error with its period searched in each training fold),
//! screened by a linearised joint refit with the geometry (`linear.rs`) and confirmed by full
//! non-linear refits on the folds.

use ferrocal_robot::{JointKind, RobotModel};
use nalgebra::{DVector, Vector3};

use super::checks::{assess, parameter_map, stability};
use super::linear::{heldout_with, joint_fit, sin_angle, Basis, Fold, Lin, PeriodScan};
use super::screen::screen;
use super::words::{evidence, statement, telling_input};
use super::{DiagnoseOptions, InputStructure};
use crate::diagnose::engine::{AllFit, Baseline, Confirmation, Describe, Family, Screened, StepStart};
use crate::diagnose::report::{Decision, Finding, Unit};
use crate::diagnose::stats::paired_test;
use crate::effects::EffectSpec;
use crate::error::Result;
use crate::kinematic::{calibrate, KinematicCalibration, KinematicOptions};
use crate::lsq::LmOptions;
use crate::measurement::PoseMeasurement;

mod cand;
pub(super) use cand::{flatten, Cand, Ctx, LinScore};

impl Ctx<'_> {
    pub(super) fn kin_opts(&self, effects: Vec<EffectSpec>) -> KinematicOptions {
        KinematicOptions {
            model_params: self.opts.model_params.clone(),
            use_orientation: false,
            sigma_position_m: self.opts.sigma_position_m,
            effects,
            lm: LmOptions { max_iterations: 100, ..LmOptions::default() },
            ..KinematicOptions::default()
        }
    }

    pub(super) fn q(&self, j: usize) -> Vec<f64> {
        self.rows.iter().map(|r| r.q[j]).collect()
    }

    pub(super) fn mm(&self, e_whitened: &[Vector3<f64>]) -> f64 {
        let n = e_whitened.len().max(1);
        (e_whitened.iter().zip(&self.sigma).map(|(e, s)| (e * *s).norm_squared()).sum::<f64>() / n as f64).sqrt() * 1e3
    }

    /// Held-out errors (metres) of every analysis row from non-linear fits on the other folds.
    pub(super) fn nonlinear_cv(
        &self,
        effects_for_fold: &dyn Fn(usize) -> Vec<EffectSpec>,
    ) -> Result<Vec<Vector3<f64>>> {
        let mut out = vec![Vector3::zeros(); self.rows.len()];
        for (k, test) in self.folds_idx.iter().enumerate() {
            let train: Vec<&PoseMeasurement> =
                (0..self.rows.len()).filter(|i| !test.contains(i)).map(|i| self.rows[i]).collect();
            let cal = calibrate(self.model, &train, &self.kin_opts(effects_for_fold(k)))?;
            let te: Vec<&PoseMeasurement> = test.iter().map(|&i| self.rows[i]).collect();
            let (pos, _) = cal.calibrated.errors(&te)?;
            for (e, &i) in pos.into_iter().zip(test) {
                out[i] = e;
            }
        }
        Ok(out)
    }

    pub(super) fn effect_columns(&self, lin: &Lin, spec: &EffectSpec) -> Option<nalgebra::DMatrix<f64>> {
        match spec {
            EffectSpec::Custom(e) => lin.custom_columns(&**e, self.model, &self.rows),
            _ => lin.effect_columns(spec, self.kinds.len(), &self.rows),
        }
    }

    /// The columns of several effects side by side.
    pub(super) fn columns_of(&self, lin: &Lin, specs: &[EffectSpec]) -> Option<nalgebra::DMatrix<f64>> {
        let blocks: Vec<nalgebra::DMatrix<f64>> =
            specs.iter().map(|s| self.effect_columns(lin, s)).collect::<Option<_>>()?;
        let ncols = blocks.iter().map(|b| b.ncols()).sum();
        let mut cols = nalgebra::DMatrix::zeros(3 * self.rows.len(), ncols);
        let mut at = 0;
        for b in &blocks {
            cols.columns_mut(at, b.ncols()).copy_from(b);
            at += b.ncols();
        }
        Some(cols)
    }

    pub(super) fn periodic_spec(joint: usize, f: f64) -> EffectSpec {
        EffectSpec::PeriodicJointError { joint, period_si: 1.0 / f }
    }

    /// Linear cross-validation of a candidate.
    pub(super) fn linear_cv(&self, lin: &Lin, folds: &[Fold], cand: &Cand) -> Option<LinScore> {
        let n = self.rows.len();
        let mut d = vec![0.0; n];
        let mut e1v = vec![Vector3::zeros(); n];
        let mut theta_folds = Vec::new();
        let mut freq_folds = Vec::new();
        let fixed_cols = match cand {
            Cand::Fixed(s) => Some(self.effect_columns(lin, s)?),
            Cand::Group(v) => Some(self.columns_of(lin, v)?),
            Cand::Periodic { .. } => None,
        };
        for fold in folds {
            let cols = match cand {
                Cand::Fixed(_) | Cand::Group(_) => fixed_cols.clone()?,
                Cand::Periodic { joint } => {
                    let scan = PeriodScan::new(lin, &fold.basis, joint - 1, &self.q(joint - 1));
                    let (f, _) = scan.best(&self.grids[joint - 1]);
                    freq_folds.push(f);
                    self.effect_columns(lin, &Self::periodic_spec(*joint, f))?
                }
            };
            let (e1, theta) = heldout_with(fold, &cols);
            for (k, &i) in fold.test.iter().enumerate() {
                let a = fold.e0.fixed_rows::<3>(3 * k).clone_owned();
                let b = e1.fixed_rows::<3>(3 * k).clone_owned();
                d[i] = a.norm_squared() - b.norm_squared();
                e1v[i] = b;
            }
            theta_folds.push(theta);
        }
        Some(LinScore { d, e1: e1v, theta_folds, freq_folds })
    }
}

/// Two candidates are look-alikes, and are compared jointly before either is accepted, when
/// the largest canonical correlation of their prediction columns, after the base model's
/// columns are projected out, reaches this.
pub(super) const LOOK_ALIKE_CORRELATION: f64 = 0.3;

/// The largest canonical correlation between the columns `a` and `b` (all analysis rows) after
/// the base model's columns (`basis`, fitted on all rows) are projected out: 1 when some
/// combination of one is a combination of the other, 0 when they are orthogonal.
pub(super) fn canonical_correlation(basis: &Basis, a: &nalgebra::DMatrix<f64>, b: &nalgebra::DMatrix<f64>) -> f64 {
    let project = |m: &nalgebra::DMatrix<f64>| {
        let mt = super::linear::gather(m, &basis.train);
        &mt - &basis.u * (basis.u.transpose() * &mt)
    };
    let orth = |m: nalgebra::DMatrix<f64>| {
        ferrocal_lsq::linear::TruncatedSvd::new(&m, 1e-9).ok().map(|s| s.range_basis().clone())
    };
    let (Some(qa), Some(qb)) = (orth(project(a)), orth(project(b))) else { return 0.0 };
    if qa.ncols() == 0 || qb.ncols() == 0 {
        return 0.0;
    }
    let m = qa.transpose() * qb;
    m.singular_values().iter().copied().fold(0.0, f64::max).min(1.0)
}

/// The state of one step: the linearisation at the current model and its folds.
struct StepData {
    lin: Lin,
    folds: Vec<Fold>,
    basis_all: Basis,
    /// Per analysis row: whitened held-out residual of the current model (linear refits).
    e0: Vec<Vector3<f64>>,
    /// Held-out errors of the current model from full refits (computed once a step, when needed).
    base_nl: Option<Vec<Vector3<f64>>>,
}

/// The kinematic family: the analysis rows, the candidates and the current calibration.
pub(super) struct KinematicFamily<'a> {
    pub(super) ctx: Ctx<'a>,
    pub(super) validation: Vec<&'a PoseMeasurement>,
    pub(super) cands: Vec<Cand>,
    /// The current calibration (geometry plus the accepted effects).
    pub(super) cal: KinematicCalibration,
    step: Option<StepData>,
    /// The accepted effects, flattened.
    accepted: Vec<EffectSpec>,
    first: bool,
    /// Cross-validated RMS (mm) and screening of the geometric model.
    pub(super) nominal_cv_mm: f64,
    pub(super) screening_nominal: Vec<InputStructure>,
    /// The same at the current model.
    pub(super) final_cv_mm: f64,
    pub(super) screening_final: Vec<InputStructure>,
    /// Training and validation RMS (mm) of the current model.
    pub(super) final_train_mm: f64,
    pub(super) final_heldout_mm: f64,
}

impl<'a> KinematicFamily<'a> {
    pub(super) fn new(
        ctx: Ctx<'a>,
        validation: Vec<&'a PoseMeasurement>,
        cands: Vec<Cand>,
        geo: KinematicCalibration,
        heldout_mm: f64,
    ) -> Self {
        let train = geo.train_after.rms_mm;
        Self {
            ctx,
            validation,
            cands,
            cal: geo,
            step: None,
            accepted: Vec::new(),
            first: true,
            nominal_cv_mm: f64::NAN,
            screening_nominal: Vec::new(),
            final_cv_mm: f64::NAN,
            screening_final: Vec::new(),
            final_train_mm: train,
            final_heldout_mm: heldout_mm,
        }
    }

    fn step(&self) -> &StepData {
        self.step.as_ref().expect("a step has begun")
    }

    /// Backward check: an earlier effect that the later ones have made unnecessary (its index,
    /// the p-value of leaving it out and the change of the held-out error).
    fn backward(&self, accepted: &[Vec<EffectSpec>], st: &StepData) -> Result<Option<(usize, f64, f64)>> {
        let (ctx, cal) = (&self.ctx, &self.cal);
        if accepted.len() < 2 {
            return Ok(None);
        }
        let mut first = 0;
        for (e, set) in accepted.iter().enumerate().take(accepted.len() - 1) {
            // The flattened effects of accepted set `e`.
            let members = first..first + set.len();
            first += set.len();
            let cols: Vec<usize> = (0..cal.free.len())
                .filter(|&k| members.clone().any(|m| cal.layout.effects[m].contains(&cal.free[k])))
                .collect();
            // Leaving it out: its parameters at zero, the rest refitted without them.
            let mut cm0 = cal.calibrated.clone();
            for m in members {
                cm0.effects[m].1.iter_mut().for_each(|v| *v = 0.0);
            }
            let (err0, _) = cm0.errors(&ctx.rows)?;
            let mut r0 = DVector::zeros(3 * ctx.rows.len());
            for (i, v) in err0.iter().enumerate() {
                r0.fixed_rows_mut::<3>(3 * i).copy_from(&(v / ctx.sigma[i]));
            }
            let red = st.lin.without(&cols, r0);
            let mut d = vec![0.0; ctx.rows.len()];
            for (fold, t) in st.folds.iter().zip(&ctx.folds_idx) {
                let f_red = Fold::new(&red, t)?;
                for (k, &i) in t.iter().enumerate() {
                    d[i] =
                        f_red.e0.fixed_rows::<3>(3 * k).norm_squared() - fold.e0.fixed_rows::<3>(3 * k).norm_squared();
                }
            }
            let t = paired_test(&d);
            let sse: f64 = st.e0.iter().map(|v| v.norm_squared()).sum::<f64>() / st.e0.len() as f64;
            if t.p_value >= ctx.opts.alpha || t.mean / sse < ctx.opts.min_improvement {
                return Ok(Some((e, t.p_value, t.mean / sse)));
            }
        }
        Ok(None)
    }

    fn validation_rms_mm(&self, cal: &KinematicCalibration) -> Result<f64> {
        Ok(cal.calibrated.evaluate(&self.validation)?.rms_mm)
    }
}

impl Family for KinematicFamily<'_> {
    type Candidate = Cand;
    /// The effects of one accepted candidate (one, or a group's members).
    type Effect = Vec<EffectSpec>;
    type Screen = LinScore;
    /// The effect's parameters of the linearised all-rows fit.
    type Fit = Vec<f64>;

    fn unit(&self) -> Unit {
        Unit::Millimetre
    }

    fn begin_step(&mut self, accepted: &[Vec<EffectSpec>]) -> Result<StepStart> {
        let ctx = &self.ctx;
        let lin = Lin::build(&self.cal, &ctx.rows, &ctx.sigma)?;
        let folds: Vec<Fold> = ctx.folds_idx.iter().map(|t| Fold::new(&lin, t)).collect::<Result<_>>()?;
        let all: Vec<usize> = (0..ctx.rows.len()).collect();
        let basis_all = Basis::new(&lin, &all)?;
        let mut e0 = vec![Vector3::zeros(); ctx.rows.len()];
        for fold in &folds {
            for (k, &i) in fold.test.iter().enumerate() {
                e0[i] = fold.e0.fixed_rows::<3>(3 * k).clone_owned();
            }
        }
        let st = StepData { lin, folds, basis_all, e0, base_nl: None };
        if let Some((index, p_value, change)) = self.backward(accepted, &st)? {
            let mut effects = accepted.to_vec();
            effects.remove(index);
            self.cal = calibrate(self.ctx.model, &self.ctx.rows, &self.ctx.kin_opts(flatten(&effects)))?;
            self.final_train_mm = self.cal.train_after.rms_mm;
            if !self.validation.is_empty() {
                self.final_heldout_mm = self.validation_rms_mm(&self.cal)?;
            }
            self.step = None;
            return Ok(StepStart::Pruned { index, p_value, change });
        }
        let cv_before_mm = self.ctx.mm(&st.e0);
        let screening = screen(&self.ctx, &st.lin, &st.e0);
        if self.first {
            self.nominal_cv_mm = cv_before_mm;
            self.screening_nominal = screening.clone();
            self.first = false;
        }
        self.final_cv_mm = cv_before_mm;
        self.screening_final = screening;
        let mse = st.e0.iter().map(|e| e.norm_squared()).sum::<f64>() / st.e0.len() as f64;
        self.step = Some(st);
        self.accepted = flatten(accepted);
        Ok(StepStart::Baseline(Baseline { heldout: cv_before_mm, mse }))
    }

    fn candidates(&self, accepted: &[Vec<EffectSpec>], retired: &[Vec<EffectSpec>]) -> Vec<Cand> {
        let done: Vec<EffectSpec> = flatten(accepted).into_iter().chain(flatten(retired)).collect();
        let mut open: Vec<Cand> =
            self.cands.iter().filter(|c| !done.iter().any(|s| c.covered_by(s))).cloned().collect();
        // Compliance on every loaded joint not yet modelled, together (when at least two).
        let members: Vec<EffectSpec> = open
            .iter()
            .filter_map(|c| match c {
                Cand::Fixed(s @ EffectSpec::JointCompliance { .. }) => Some(s.clone()),
                _ => None,
            })
            .collect();
        if members.len() >= 2 {
            open.push(Cand::Group(members));
        }
        open
    }

    fn describe(&self, c: &Cand) -> Describe {
        Describe { label: c.label(), effect: c.name().into(), joints: c.joints(), n_params: c.n_params() }
    }

    fn screen(&mut self, c: &Cand) -> Result<Screened<LinScore>> {
        let st = self.step();
        Ok(match self.ctx.linear_cv(&st.lin, &st.folds, c) {
            None => Screened::Skip,
            Some(ls) => Screened::Scored { d: ls.d.clone(), heldout: self.ctx.mm(&ls.e1), data: ls },
        })
    }

    fn fit_all(&mut self, c: &Cand, _ls: &LinScore) -> Result<Option<AllFit<Vec<EffectSpec>, Vec<f64>>>> {
        let (ctx, st) = (&self.ctx, self.step());
        let specs = match c {
            Cand::Periodic { joint } => {
                let scan = PeriodScan::new(&st.lin, &st.basis_all, joint - 1, &ctx.q(joint - 1));
                vec![Ctx::periodic_spec(*joint, scan.best(&ctx.grids[joint - 1]).0)]
            }
            c => c.specs(None).unwrap_or_default(),
        };
        let Some(cols) = ctx.columns_of(&st.lin, &specs) else { return Ok(None) };
        let fit = joint_fit(&st.basis_all, &cols);
        let sa = sin_angle(&st.basis_all, &cols);
        let theta: Vec<f64> = fit.theta.iter().copied().collect();
        let parameters = parameters_of(&specs, &theta, &ctx.kinds);
        Ok(Some(AllFit { effect: specs, parameters, overlap_sine: Some(sa), data: theta }))
    }

    fn look_alikes(&mut self, c: &Cand, others: &[&Cand]) -> Result<Vec<usize>> {
        let (ctx, st) = (&self.ctx, self.step());
        let cols_all = |cand: &Cand| -> Option<nalgebra::DMatrix<f64>> {
            let specs = match cand {
                Cand::Periodic { joint } => {
                    let scan = PeriodScan::new(&st.lin, &st.basis_all, joint - 1, &ctx.q(joint - 1));
                    vec![Ctx::periodic_spec(*joint, scan.best(&ctx.grids[joint - 1]).0)]
                }
                c => c.specs(None)?,
            };
            ctx.columns_of(&st.lin, &specs)
        };
        let Some(own) = cols_all(c) else { return Ok(Vec::new()) };
        let mut out = Vec::new();
        for (k, o) in others.iter().enumerate() {
            // Another form of the same effect on the same joint is not a rival (the periodic
            // error's fixed and searched periods).
            if o.name() == c.name() && o.joints() == c.joints() {
                continue;
            }
            // A group and one of its members are nested, not rivals: the group is examined
            // only when no member passed alone (the engine's order).
            let nested = |g: &Cand, m: &Cand| match (g, m) {
                (Cand::Group(v), Cand::Fixed(s)) => v.contains(s),
                _ => false,
            };
            if nested(c, o) || nested(o, c) {
                continue;
            }
            let Some(cols) = cols_all(o) else { continue };
            if canonical_correlation(&st.basis_all, &own, &cols) >= LOOK_ALIKE_CORRELATION {
                out.push(k);
            }
        }
        Ok(out)
    }

    fn screen_together(&mut self, cands: &[(&Cand, &LinScore)]) -> Result<Option<Vec<f64>>> {
        let (ctx, st) = (&self.ctx, self.step());
        let mut d = vec![0.0; ctx.rows.len()];
        for (k, fold) in st.folds.iter().enumerate() {
            let mut specs = Vec::with_capacity(cands.len());
            for (c, ls) in cands {
                let Some(v) = c.specs(ls.freq_folds.get(k).copied()) else { return Ok(None) };
                specs.extend(v);
            }
            let Some(cols) = ctx.columns_of(&st.lin, &specs) else { return Ok(None) };
            let (e1, _) = heldout_with(fold, &cols);
            for (kk, &i) in fold.test.iter().enumerate() {
                d[i] = fold.e0.fixed_rows::<3>(3 * kk).norm_squared() - e1.fixed_rows::<3>(3 * kk).norm_squared();
            }
        }
        Ok(Some(d))
    }

    fn plausible(&self, fit: &AllFit<Vec<EffectSpec>, Vec<f64>>) -> std::result::Result<(), String> {
        for (spec, theta) in members(&fit.effect, &fit.data) {
            assess(spec, theta, &self.ctx, &self.step().lin, self.ctx.opts).possible?;
        }
        Ok(())
    }

    fn unusual(&self, fit: &AllFit<Vec<EffectSpec>, Vec<f64>>) -> Option<String> {
        let words: Vec<String> = members(&fit.effect, &fit.data)
            .filter_map(|(spec, theta)| assess(spec, theta, &self.ctx, &self.step().lin, self.ctx.opts).unusual)
            .collect();
        (!words.is_empty()).then(|| words.join("; "))
    }

    fn stability(&self, fit: &AllFit<Vec<EffectSpec>, Vec<f64>>, ls: &LinScore) -> std::result::Result<f64, String> {
        if fit.effect.len() == 1 {
            return stability(&fit.effect[0], &fit.data, ls, &self.ctx);
        }
        // A group stands when the folds agree on its largest member (by deflection it causes
        // over the poses); the others may be small and scatter.
        let mut best: Option<(f64, std::result::Result<f64, String>)> = None;
        let mut at = 0;
        for spec in &fit.effect {
            let n = spec.scales().len();
            let sub = LinScore {
                d: Vec::new(),
                e1: Vec::new(),
                theta_folds: ls.theta_folds.iter().map(|t| t.rows(at, n).clone_owned()).collect(),
                freq_folds: Vec::new(),
            };
            let theta = &fit.data[at..at + n];
            let size = member_size(spec, theta, &self.step().lin);
            let r = stability(spec, theta, &sub, &self.ctx);
            if best.as_ref().is_none_or(|(s, _)| size > *s) {
                best = Some((size, r));
            }
            at += n;
        }
        best.map_or(Ok(0.0), |(_, r)| r)
    }

    fn confirm(
        &mut self,
        cand: &Cand,
        accepted: &[Vec<EffectSpec>],
        ls: &LinScore,
    ) -> Result<Option<std::result::Result<Confirmation, String>>> {
        if self.step().base_nl.is_none() {
            let base = self.ctx.nonlinear_cv(&|_| flatten(accepted))?;
            if let Some(st) = self.step.as_mut() {
                st.base_nl = Some(base);
            }
        }
        let ctx = &self.ctx;
        let base_nl = self.step().base_nl.as_deref().unwrap_or_default();
        let with_spec = |fold: usize| -> Vec<EffectSpec> {
            let mut v = flatten(accepted);
            v.extend(cand.specs(ls.freq_folds.get(fold).copied()).unwrap_or_default());
            v
        };
        let cand_nl = match ctx.nonlinear_cv(&with_spec) {
            Ok(v) => v,
            Err(e) => return Ok(Some(Err(e.to_string()))),
        };
        let n = ctx.rows.len();
        let d: Vec<f64> =
            (0..n).map(|i| (base_nl[i].norm_squared() - cand_nl[i].norm_squared()) / ctx.sigma[i].powi(2)).collect();
        let mse = (0..n).map(|i| base_nl[i].norm_squared() / ctx.sigma[i].powi(2)).sum::<f64>() / n as f64;
        let rms = |v: &[Vector3<f64>]| (v.iter().map(|e| e.norm_squared()).sum::<f64>() / v.len() as f64).sqrt() * 1e3;
        Ok(Some(Ok(Confirmation { d, mse, heldout_before: rms(base_nl), heldout_after: rms(&cand_nl) })))
    }

    fn accept(
        &mut self,
        fit: AllFit<Vec<EffectSpec>, Vec<f64>>,
        ls: &LinScore,
        decision: &Decision,
    ) -> Result<Finding<Vec<EffectSpec>>> {
        let specs = fit.effect;
        let mut effects = self.accepted.clone();
        effects.extend(specs.iter().cloned());
        let ctx = &self.ctx;
        let new_cal = calibrate(ctx.model, &ctx.rows, &ctx.kin_opts(effects))?;
        let (cv_b, cv_a) = (decision.heldout_before, decision.heldout_after);
        let (before, after) = if self.validation.is_empty() {
            (cv_b, cv_a)
        } else {
            (self.validation_rms_mm(&self.cal)?, self.validation_rms_mm(&new_cal)?)
        };
        let n_fx = new_cal.layout.effects.len();
        let ranges: Vec<std::ops::Range<usize>> = new_cal.layout.effects[n_fx.saturating_sub(specs.len())..].to_vec();
        let theta: Vec<f64> = ranges.iter().flat_map(|r| r.clone().map(|i| new_cal.params[i].value)).collect();
        let std_cov = ranges.first().and_then(|r| new_cal.params.get(r.start)).and_then(|p| p.std);
        let explained =
            if before > 0.0 { ((before * before - after * after) / (before * before)).max(0.0) } else { 0.0 };
        let spec = &specs[0];
        let telling = telling_input(spec, &ctx.names);
        let st = self.step();
        let (p_corr, m) = (decision.p_corrected, decision.candidates_tried);
        let words: Vec<String> = members(&specs, &theta)
            .map(|(sp, th)| statement(sp, th, decision.relative_std, before, after, p_corr, m, ctx, &st.lin))
            .collect();
        let mut statement = if specs.len() == 1 {
            words.join("; ")
        } else {
            format!("{} found together (each alone may be too small to pass): {}", decision.label, words.join("; "))
        };
        if let Some(c) = &decision.caution {
            statement = format!("UNUSUAL: {c}. {statement}");
        }
        if !decision.alternatives.is_empty() {
            statement.push_str(&format!(
                "; the held-out data fit {} about as well, so that reading cannot be excluded",
                decision.alternatives.join(" or ")
            ));
        }
        let ev = evidence(0, spec, ctx, &st.lin, &st.e0, &ls.e1, &telling);
        let finding = Finding {
            effect: spec.name().into(),
            joints: specs.iter().flat_map(|s| s.joints_reported()).collect(),
            parameters: parameters_of(&specs, &theta, &ctx.kinds),
            heldout_before: before,
            heldout_after: after,
            explained_fraction: explained,
            statement,
            std_from_covariance: std_cov,
            telling_input: telling,
            evidence: Some(ev),
            decision: decision.clone(),
            accepted: specs,
        };
        self.final_train_mm = new_cal.train_after.rms_mm;
        self.final_heldout_mm = if self.validation.is_empty() { cv_a } else { after };
        self.cal = new_cal;
        Ok(finding)
    }
}

/// Each effect of a set with its slice of the parameters `theta`.
pub(super) fn members<'s>(
    specs: &'s [EffectSpec],
    theta: &'s [f64],
) -> impl Iterator<Item = (&'s EffectSpec, &'s [f64])> {
    let mut at = 0;
    specs.iter().map(move |s| {
        let n = s.scales().len().min(theta.len().saturating_sub(at));
        let slice = &theta[at..at + n];
        at += n;
        (s, slice)
    })
}

/// The parameters of a set of effects with unit-carrying names; a group's are prefixed with the
/// member's joint (`joint3.compliance_rad_per_nm`).
pub(super) fn parameters_of(
    specs: &[EffectSpec],
    theta: &[f64],
    kinds: &[JointKind],
) -> std::collections::BTreeMap<String, f64> {
    if specs.len() == 1 {
        return parameter_map(&specs[0], theta, kinds);
    }
    let mut out = std::collections::BTreeMap::new();
    for (k, (spec, th)) in members(specs, theta).enumerate() {
        let tag = spec.joint().map_or(format!("effect{}", k + 1), |j| format!("joint{j}"));
        for (name, v) in parameter_map(spec, th, kinds) {
            out.insert(format!("{tag}.{name}"), v);
        }
    }
    out
}

/// A member's size, to find a group's largest: the deflection it causes at the largest load for
/// a compliance, else its main parameter's magnitude.
fn member_size(spec: &EffectSpec, theta: &[f64], lin: &Lin) -> f64 {
    let t = theta.first().copied().unwrap_or(0.0).abs();
    match spec {
        EffectSpec::JointCompliance { joint } => t * lin.tau.iter().map(|v| v[joint - 1].abs()).fold(0.0, f64::max),
        _ => t,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    pub(super) fn candidates_cover_one_another_only_within_their_kind() {
        let c = Cand::Fixed(EffectSpec::TimeDrift);
        assert!(c.covered_by(&EffectSpec::ThermalExpansion { reference_temp_c: 20.0 }));
        let b = Cand::Fixed(EffectSpec::Backlash { joint: 2 });
        assert!(b.covered_by(&EffectSpec::Backlash { joint: 2 }));
        assert!(!b.covered_by(&EffectSpec::Backlash { joint: 3 }));
        assert!(!b.covered_by(&EffectSpec::JointCompliance { joint: 2 }));
        let p = Cand::Periodic { joint: 1 };
        assert!(p.covered_by(&EffectSpec::PeriodicJointError { joint: 1, period_si: 0.1 }));
    }
}
