//! Missing physics of a force-sensing end-effector (methods.md section 5): identify the rigid
//! body and the sensor offsets (model 0), then test on held-out poses whether the sensor forces
//! also depend on where the platform is and how it is tilted (its deformation, the `K` terms of
//! models 1, 2, 4 and 5), instead of accepting the mass and centre of gravity such a deformation
//! biases.
//!
//! A family of the diagnose engine ([`super::engine`]): the candidates are the quasi-static
//! models whose terms contain the current model's; each is fitted on the training folds of a
//! K-fold split over poses and scored by the held-out squared force errors per pose. A candidate
//! counts when its improvement is significant in a paired t test over the held-out poses
//! (Bonferroni over the candidates of the step) and at least `min_improvement` of the held-out
//! RMS; the engine examines the counting ones ranked by improvement, and among those the held-out
//! data cannot tell from the best one, the one with the fewest parameters first (the simulated
//! rig's true deformation, model 5, before model 4). Finally the held-out residuals are screened
//! against the platform coordinates for structure no candidate explains.
//!
//! A second kind of candidate is sensor cross-talk (`sensor_crosstalk`): each sensor reads
//! fractions of the other sensors' loads ([`super::force_crosstalk`]: only the directions of the
//! 30 coefficients the data can tell from the model's own terms are fitted, 8 at one payload).
//! Cross-talk and a deformation model are look-alikes (both add sensor forces that follow the
//! platform's tilt): before one is accepted, the two are fitted together and each must add to
//! the other on the held-out poses ([`super::engine`]'s joint comparison). Once cross-talk is
//! accepted, the deformation models are screened with it.

use std::collections::BTreeMap;

use ferrocal_robot::dynamics::{gibbs_vector, MotionState};
use ferrocal_robot::Pose;
use nalgebra::{DMatrix, DVector, Matrix6};
use serde::{Deserialize, Serialize};

use super::engine::{
    select, AllFit, Baseline, Correction, Describe, Family, Improvement, Policy, Screened, Selection, StepStart, Test,
};
use super::force_crosstalk;
use super::report::{best_verdict, Decision, Finding, Unit};
use super::stats::{binned_anova, bonferroni, quantile_groups};
use crate::dynamics::{SensorModel, SensorRegressor};
use crate::error::{CalibError, Result};
use ferrocal_lsq::linear::{fit, LinearFit, LinearOptions, Weighting};

mod cv;
mod types;
use cv::*;
pub use types::*;

/// What a model adds to another, in words.
fn added_terms(from: SensorModel, to: SensorModel) -> (bool, bool, String) {
    let (a, b) = (from.terms(), to.terms());
    let mut parts = Vec::new();
    let position = (b.k1 && !a.k1) || (b.k2 && !a.k2);
    let orientation = (b.k4 && !a.k4) || (b.k5 && !a.k5);
    if b.k1 && !a.k1 {
        parts.push("K1 (sensor forces linear in the platform position)");
    }
    if b.k2 && !a.k2 {
        parts.push("K2 (a deformation wrench linear in the platform position)");
    }
    if b.k4 && !a.k4 {
        parts.push("K4 (wrench linear in the platform tilt)");
    }
    if b.k5 && !a.k5 {
        parts.push("K5 (a deformation wrench linear in the platform tilt)");
    }
    (position, orientation, parts.join(" and "))
}

fn regressor(reg: &SensorRegressor, model: SensorModel, poses: &[Pose]) -> Result<DMatrix<f64>> {
    let states: Vec<MotionState> = poses.iter().map(|p| MotionState::at_rest(*p)).collect();
    reg.regressor(model, &states)
}

fn rows_of(a: &DMatrix<f64>, idx: &[usize]) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(6 * idx.len(), a.ncols());
    for (k, &i) in idx.iter().enumerate() {
        out.view_mut((6 * k, 0), (6, a.ncols())).copy_from(&a.view((6 * i, 0), (6, a.ncols())));
    }
    out
}

fn vec_of(y: &DVector<f64>, idx: &[usize]) -> DVector<f64> {
    let mut out = DVector::zeros(6 * idx.len());
    for (k, &i) in idx.iter().enumerate() {
        out.fixed_rows_mut::<6>(6 * k).copy_from(&y.fixed_rows::<6>(6 * i));
    }
    out
}

/// The load columns the cross-talk acts on: the rigid body's (gravity) loads. The cross-talk of
/// the deformation forces (a few per cent of the gravity loads on the simulated rig, so 1e-4 of
/// them at 1 % cross-talk) is below the noise and not modelled; including it would let the
/// deformation terms' position dependence open cross-talk directions the data cannot pin down.
fn load_columns(model: SensorModel) -> Vec<bool> {
    model.names().iter().map(|n| ferrocal_robot::dynamics::RIGID_BODY_NAMES.contains(&n.as_str())).collect()
}

/// Largest plausible cross-talk fraction (strain-gauge sensors: a few per cent at most).
const MAX_CROSSTALK: f64 = 0.05;

/// A candidate: a deformation model (with the accepted cross-talk, if any), or cross-talk.
#[derive(Clone, Copy, Debug, PartialEq)]
enum ForceCand {
    Model(SensorModel),
    Crosstalk,
    /// A deformation model and cross-talk together (a model that contains more terms, e.g.
    /// model 4, can absorb both: offered while cross-talk is not yet modelled).
    ModelCrosstalk(SensorModel),
}

/// A fit on all the poses.
struct Full {
    names: Vec<String>,
    values: Vec<f64>,
    crosstalk: Option<Matrix6<f64>>,
    /// Cross-talk directions fitted (the identifiable ones), when cross-talk is modelled.
    crosstalk_dirs: usize,
    rms_n: f64,
}

impl Full {
    fn get(&self, name: &str) -> Option<f64> {
        self.names.iter().position(|n| n == name).map(|i| self.values[i])
    }
}

fn rms(sse: &[f64]) -> f64 {
    (sse.iter().sum::<f64>() / (6 * sse.len()).max(1) as f64).sqrt()
}

/// The quasi-static sensor models as a candidate family: each candidate is a model whose terms
/// contain the current one's.
struct ForceFamily<'a> {
    reg: &'a SensorRegressor,
    poses: &'a [Pose],
    y: DVector<f64>,
    folds: usize,
    current: SensorModel,
    crosstalk: bool,
    current_fit: Full,
    current_sse: Vec<f64>,
    current_res: DMatrix<f64>,
}

impl ForceFamily<'_> {
    /// The cross-talk directions `model` leaves identifiable on all the poses.
    fn crosstalk_directions(&self, model: SensorModel) -> usize {
        let Ok(a) = regressor(self.reg, model, self.poses) else { return 30 };
        let rows: Vec<usize> = (0..self.poses.len()).collect();
        force_crosstalk::fit(&a, &self.y, &load_columns(model), &rows).identifiable
    }

    fn full_fit(&self, m: SensorModel, crosstalk: bool) -> Result<Full> {
        let a = regressor(self.reg, m, self.poses)?;
        if !crosstalk {
            let f = fit(&a, &self.y, &m.names(), &Weighting::Unit, &LinearOptions::default())?;
            return Ok(linear_full(f));
        }
        let load = load_columns(m);
        let rows: Vec<usize> = (0..self.poses.len()).collect();
        let f = force_crosstalk::fit(&a, &self.y, &load, &rows);
        let pred = force_crosstalk::predict(&a, &load, &f, &rows);
        let rms_n = ((&self.y - pred).norm_squared() / self.y.len().max(1) as f64).sqrt();
        Ok(Full {
            names: m.names(),
            values: f.theta.iter().copied().collect(),
            crosstalk: Some(f.c),
            crosstalk_dirs: f.identifiable,
            rms_n,
        })
    }

    fn cv(&self, m: SensorModel, crosstalk: bool) -> Result<(Vec<f64>, DMatrix<f64>)> {
        cross_validate(self.reg, m, self.poses, &self.y, self.folds, crosstalk)
    }
}

fn linear_full(f: LinearFit) -> Full {
    Full { names: f.names.clone(), values: f.values.clone(), crosstalk: None, crosstalk_dirs: 0, rms_n: f.rms_residual }
}

fn mass_cog(f: &Full) -> (f64, f64) {
    let m = f.get("m_kg").unwrap_or(f64::NAN);
    let mcz = f.get("mcz_kgm").unwrap_or(f64::NAN);
    (m, mcz / m)
}

impl Family for ForceFamily<'_> {
    type Candidate = ForceCand;
    type Effect = ForceCand;
    type Screen = (Vec<f64>, DMatrix<f64>);
    type Fit = Full;

    fn unit(&self) -> Unit {
        Unit::Newton
    }

    fn begin_step(&mut self, _accepted: &[ForceCand]) -> Result<StepStart> {
        let mse = self.current_sse.iter().sum::<f64>() / self.current_sse.len().max(1) as f64;
        Ok(StepStart::Baseline(Baseline { heldout: rms(&self.current_sse), mse }))
    }

    fn candidates(&self, _accepted: &[ForceCand], _retired: &[ForceCand]) -> Vec<ForceCand> {
        let current = self.current;
        let mut out: Vec<ForceCand> = [1u8, 2, 4, 5]
            .iter()
            .filter_map(|id| SensorModel::new(*id).ok())
            .filter(|c| {
                let (a, b) = (current.terms(), c.terms());
                *c != current
                    && (!a.k1 || b.k1)
                    && (!a.k2 || b.k2)
                    && (!a.k4 || b.k4)
                    && (!a.k5 || b.k5)
                    && (!a.k3 || b.k3)
            })
            .map(ForceCand::Model)
            .collect();
        if !self.crosstalk {
            let models: Vec<SensorModel> =
                out.iter().filter_map(|c| if let ForceCand::Model(m) = c { Some(*m) } else { None }).collect();
            out.push(ForceCand::Crosstalk);
            out.extend(models.into_iter().map(ForceCand::ModelCrosstalk));
        }
        out
    }

    fn describe(&self, c: &ForceCand) -> Describe {
        match c {
            ForceCand::Model(m) => {
                let (_, _, words) = added_terms(self.current, *m);
                Describe {
                    label: format!("{m} (adds {words})"),
                    effect: "platform_deformation".into(),
                    joints: Vec::new(),
                    n_params: m.n_params(),
                }
            }
            ForceCand::Crosstalk => Describe {
                label: "sensor_crosstalk (each sensor reads fractions of the other sensors' loads)".into(),
                effect: "sensor_crosstalk".into(),
                joints: Vec::new(),
                // The directions the fit can use, not the 30 coefficients (parsimony).
                n_params: self.current.n_params() + self.crosstalk_directions(self.current),
            },
            ForceCand::ModelCrosstalk(m) => {
                let (_, _, words) = added_terms(self.current, *m);
                Describe {
                    label: format!("{m} and sensor_crosstalk (adds {words} and cross-talk)"),
                    effect: COMBINED.into(),
                    joints: Vec::new(),
                    n_params: m.n_params() + self.crosstalk_directions(*m),
                }
            }
        }
    }

    fn screen(&mut self, c: &ForceCand) -> Result<Screened<Self::Screen>> {
        let cv = match c {
            ForceCand::Model(m) => self.cv(*m, self.crosstalk),
            ForceCand::Crosstalk => self.cv(self.current, true),
            ForceCand::ModelCrosstalk(m) => self.cv(*m, true),
        };
        Ok(match cv {
            Ok((sse, res)) => {
                let d = self.current_sse.iter().zip(&sse).map(|(a, b)| a - b).collect();
                Screened::Scored { d, heldout: rms(&sse), data: (sse, res) }
            }
            Err(e) => Screened::Unscored { heldout: f64::NAN, why: format!("cannot be fitted: {e}") },
        })
    }

    /// Cross-talk and a deformation model are look-alikes (both reproduce sensor forces linear
    /// in the platform's tilt); two deformation models are nested or compared by the screening.
    fn look_alikes(&mut self, c: &ForceCand, others: &[&ForceCand]) -> Result<Vec<usize>> {
        Ok(others
            .iter()
            .enumerate()
            .filter(|(_, o)| {
                matches!(
                    (c, o),
                    (ForceCand::Crosstalk, ForceCand::Model(_)) | (ForceCand::Model(_), ForceCand::Crosstalk)
                )
            })
            .map(|(i, _)| i)
            .collect())
    }

    /// A deformation model and cross-talk fitted together on the training folds.
    fn screen_together(&mut self, pair: &[(&ForceCand, &Self::Screen)]) -> Result<Option<Vec<f64>>> {
        let model = match pair {
            [(ForceCand::Model(m), _), (ForceCand::Crosstalk, _)]
            | [(ForceCand::Crosstalk, _), (ForceCand::Model(m), _)] => *m,
            _ => return Ok(None),
        };
        let Ok((sse, _)) = self.cv(model, true) else { return Ok(None) };
        Ok(Some(self.current_sse.iter().zip(&sse).map(|(a, b)| a - b).collect()))
    }

    fn fit_all(&mut self, c: &ForceCand, _screen: &Self::Screen) -> Result<Option<AllFit<ForceCand, Full>>> {
        let new_fit = match c {
            ForceCand::Model(m) => self.full_fit(*m, self.crosstalk)?,
            ForceCand::Crosstalk => self.full_fit(self.current, true)?,
            ForceCand::ModelCrosstalk(m) => self.full_fit(*m, true)?,
        };
        let mut parameters = BTreeMap::new();
        for (name, v) in new_fit.names.iter().zip(&new_fit.values) {
            if self.current_fit.get(name).is_none() {
                parameters.insert(name.clone(), *v);
            }
        }
        if let (ForceCand::Crosstalk | ForceCand::ModelCrosstalk(_), Some(cm)) = (c, &new_fit.crosstalk) {
            for i in 0..6 {
                for j in (0..6).filter(|&j| j != i) {
                    parameters.insert(format!("c_{}_{}", i + 1, j + 1), cm[(i, j)]);
                }
            }
            parameters.insert("largest_crosstalk".into(), cm.amax());
            parameters.insert("crosstalk_directions_fitted".into(), new_fit.crosstalk_dirs as f64);
        }
        Ok(Some(AllFit { effect: *c, parameters, overlap_sine: None, data: new_fit }))
    }

    fn plausible(&self, fit: &AllFit<ForceCand, Full>) -> std::result::Result<(), String> {
        match (&fit.effect, &fit.data.crosstalk) {
            (ForceCand::Crosstalk | ForceCand::ModelCrosstalk(_), Some(c)) if c.amax() > MAX_CROSSTALK => Err(format!(
                "a cross-talk of {:.1} % exceeds the bound of {:.0} %",
                c.amax() * 100.0,
                MAX_CROSSTALK * 100.0
            )),
            _ => Ok(()),
        }
    }

    fn accept(
        &mut self,
        fit: AllFit<ForceCand, Full>,
        screen: &Self::Screen,
        decision: &Decision,
    ) -> Result<Finding<ForceCand>> {
        if fit.effect == ForceCand::Crosstalk {
            return Ok(self.accept_crosstalk(fit, screen, decision));
        }
        let (ForceCand::Model(cand) | ForceCand::ModelCrosstalk(cand)) = fit.effect else {
            unreachable!("handled above")
        };
        let combined = matches!(fit.effect, ForceCand::ModelCrosstalk(_));
        let crosstalk_words = combined.then(|| self.crosstalk_statement(&fit.data, decision));
        let new_fit = fit.data;
        let (before, after, p, m) =
            (decision.heldout_before, decision.heldout_after, decision.p_corrected, decision.candidates_tried);
        let (m_before, c_before) = mass_cog(&self.current_fit);
        let (m_after, c_after) = mass_cog(&new_fit);
        let (position, orientation, words) = added_terms(self.current, cand);
        let mut parameters = fit.parameters;
        parameters.insert("mass_before_kg".into(), m_before);
        parameters.insert("mass_after_kg".into(), m_after);
        parameters.insert("cog_z_before_m".into(), c_before);
        parameters.insert("cog_z_after_m".into(), c_after);
        let depends = match (position, orientation) {
            (true, true) => "on the platform's position and tilt",
            (false, true) => "on the platform's tilt",
            _ => "on the platform's position",
        };
        let statement = format!(
            "the sensor forces depend {depends} beyond the rigid-body load: the end-effector deforms ({words}); modelling it lowers the held-out force RMS from {before:.3} to {after:.3} N (p = {p:.1e} after correcting for {m} candidates), and moves the identified mass from {m_before:.2} to {m_after:.2} kg and the centre of gravity from {:.1} to {:.1} mm above the flange: without it the rigid-body parameters absorb the deformation",
            c_before * 1e3,
            c_after * 1e3
        );
        let (statement, effect) = match crosstalk_words {
            Some(words) => (format!("{statement}{SPLIT}{words}"), COMBINED),
            None => (statement, "platform_deformation"),
        };
        self.crosstalk |= combined;
        self.current = cand;
        self.current_fit = new_fit;
        self.current_sse = screen.0.clone();
        self.current_res = screen.1.clone();
        Ok(Finding::without_evidence(fit.effect, effect, parameters, (before, after), statement, decision.clone()))
    }
}

impl ForceFamily<'_> {
    /// The cross-talk's sentence of a finding.
    fn crosstalk_statement(&self, fit: &Full, decision: &Decision) -> String {
        let (before, after, p, m) =
            (decision.heldout_before, decision.heldout_after, decision.p_corrected, decision.candidates_tried);
        let c = fit.crosstalk.unwrap_or_else(Matrix6::zeros);
        let (mut bi, mut bj) = (0, 1);
        for i in 0..6 {
            for j in (0..6).filter(|&j| j != i) {
                if c[(i, j)].abs() > c[(bi, bj)].abs() {
                    (bi, bj) = (i, j);
                }
            }
        }
        let (m_before, _) = mass_cog(&self.current_fit);
        let (m_after, _) = mass_cog(fit);
        format!(
            "each sensor reads fractions of the other sensors' loads (cross-talk): the largest identified is {:.2} % of sensor {}'s load in sensor {}; modelling it lowers the held-out force RMS from {before:.3} to {after:.3} N (p = {p:.1e} after correcting for {m} candidates) and moves the identified mass from {m_before:.2} to {m_after:.2} kg. From one payload only part of the cross-talk shows: {dirs} of its 30 directions, those that neither leave every load unchanged nor repeat a change of mass, centre of gravity or offsets (angle sine below {min_sine}), which are projected out and not claimed; the coefficients are the smallest that produce the fitted part, a lower bound of the true ones",
            c[(bi, bj)] * 100.0,
            bj + 1,
            bi + 1,
            dirs = fit.crosstalk_dirs,
            min_sine = force_crosstalk::MIN_SINE,
        )
    }

    fn accept_crosstalk(
        &mut self,
        fit: AllFit<ForceCand, Full>,
        screen: &(Vec<f64>, DMatrix<f64>),
        decision: &Decision,
    ) -> Finding<ForceCand> {
        let statement = self.crosstalk_statement(&fit.data, decision);
        let (m_before, _) = mass_cog(&self.current_fit);
        let (m_after, _) = mass_cog(&fit.data);
        let mut parameters = fit.parameters;
        parameters.insert("mass_before_kg".into(), m_before);
        parameters.insert("mass_after_kg".into(), m_after);
        self.crosstalk = true;
        self.current_fit = fit.data;
        self.current_sse = screen.0.clone();
        self.current_res = screen.1.clone();
        Finding::without_evidence(
            ForceCand::Crosstalk,
            "sensor_crosstalk",
            parameters,
            (decision.heldout_before, decision.heldout_after),
            statement,
            decision.clone(),
        )
    }
}

/// The engine's effect name of a deformation model accepted together with cross-talk; the
/// report lists it as two findings.
const COMBINED: &str = "platform_deformation+sensor_crosstalk";

/// Separates the two sentences of a combined finding.
const SPLIT: &str = "\n";

/// Whether a parameter belongs to the cross-talk part of a finding.
fn is_crosstalk_parameter(name: &str) -> bool {
    name.starts_with("c_") || name.contains("crosstalk")
}

/// The report's findings: a combined one becomes a `platform_deformation` and a
/// `sensor_crosstalk` finding with the same held-out figures.
fn report_findings(findings: &[Finding<ForceCand>]) -> Vec<ForceFinding> {
    let mut out = Vec::new();
    for f in findings {
        let base = ForceFinding {
            effect: f.effect.clone(),
            joints: f.joints.clone(),
            parameters: f.parameters.clone(),
            heldout_rms_before_n: f.heldout_before,
            heldout_rms_after_n: f.heldout_after,
            explained_fraction: f.explained_fraction,
            p_value: f.decision.p_corrected,
            statement: f.statement.clone(),
        };
        if f.effect != COMBINED {
            out.push(base);
            continue;
        }
        let (deformation, crosstalk) = f.statement.split_once(SPLIT).unwrap_or((&f.statement, ""));
        let split = |xt: bool| -> BTreeMap<String, f64> {
            f.parameters
                .iter()
                .filter(|(k, _)| is_crosstalk_parameter(k) == xt || k.starts_with("mass_"))
                .map(|(k, v)| (k.clone(), *v))
                .collect()
        };
        out.push(ForceFinding {
            effect: "platform_deformation".into(),
            parameters: split(false),
            statement: format!("{deformation} (accepted together with the cross-talk below)"),
            ..base.clone()
        });
        out.push(ForceFinding {
            effect: "sensor_crosstalk".into(),
            parameters: split(true),
            statement: format!("{crosstalk} (accepted together with the deformation above)"),
            ..base
        });
    }
    out
}

/// Runs the analysis on averaged sensor forces (`forces`: poses x 6, newtons) at `poses`.
pub fn diagnose_force_sensor(
    reg: &SensorRegressor,
    poses: &[Pose],
    forces: &DMatrix<f64>,
    opts: &ForceDiagnoseOptions,
) -> Result<ForceDiagnoseReport> {
    let n = poses.len();
    if forces.nrows() != n || forces.ncols() != 6 {
        return Err(CalibError::Data(format!(
            "{} poses but a force table of {} x {} (one row of six sensor forces per pose)",
            n,
            forces.nrows(),
            forces.ncols()
        )));
    }
    let model0 = SensorModel::new(0)?;
    let largest = SensorModel::new(4)?.n_params();
    let empty = |why: String| ForceDiagnoseReport {
        nominal: ForceFit::default(),
        findings: Vec::new(),
        final_fit: ForceFinalFit::default(),
        unexplained: ForceUnexplained::default(),
        declined: Some(why),
        candidates: Vec::new(),
        mass_kg: [f64::NAN; 2],
        cog_z_m: [f64::NAN; 2],
        settings: opts.clone(),
    };
    // Each training fold must over-determine the largest candidate (30 parameters, 6 equations
    // per pose) several times over.
    let needed = (3 * largest).div_ceil(6) * opts.folds.max(2) / (opts.folds.max(2) - 1) + 1;
    if n < needed {
        return Ok(empty(format!(
            "{n} poses: at least {needed} are needed to hold poses out and still fit every candidate; nothing is claimed"
        )));
    }
    let y = DVector::from_iterator(6 * n, (0..n).flat_map(|k| (0..6).map(move |c| forces[(k, c)])));
    let nominal_fit = linear_full(fit(
        &regressor(reg, model0, poses)?,
        &y,
        &model0.names(),
        &Weighting::Unit,
        &LinearOptions::default(),
    )?);
    let (m0, c0) = mass_cog(&nominal_fit);
    let (current_sse, current_res) = cross_validate(reg, model0, poses, &y, opts.folds, false)?;
    let k = opts.folds.clamp(2, n);
    let nominal = ForceFit {
        n_train: n - n.div_ceil(k),
        n_heldout: n,
        train_rms_n: nominal_fit.rms_n,
        heldout_rms_n: rms(&current_sse),
    };
    let mut family = ForceFamily {
        reg,
        poses,
        y,
        folds: opts.folds,
        current: model0,
        crosstalk: false,
        current_fit: nominal_fit,
        current_sse,
        current_res,
    };
    let policy = Policy {
        alpha: opts.alpha,
        min_improvement: opts.min_improvement,
        max_effects: usize::MAX,
        min_sin_angle: 0.0,
        test: Test::PairedT,
        correction: Correction::PerCandidate,
        improvement: Improvement::RmsFraction,
        // Ranked: among the candidates the held-out data cannot tell from the best one, the one
        // with the fewest parameters is examined first (cross-talk's 8 identifiable directions
        // against model 4's 20 added terms, which reproduce much the same tilt pattern).
        selection: Selection::Ranked { max_checked: 3 },
    };
    let diagnosis = select(&mut family, &policy)?;
    let (m1, c1) = mass_cog(&family.current_fit);
    let unexplained = screen(poses, &family.current_res, opts.alpha);
    Ok(ForceDiagnoseReport {
        nominal,
        findings: report_findings(&diagnosis.findings),
        final_fit: ForceFinalFit {
            model: family.current.id(),
            train_rms_n: family.current_fit.rms_n,
            heldout_rms_n: rms(&family.current_sse),
        },
        unexplained,
        declined: None,
        candidates: diagnosis
            .steps
            .iter()
            .map(|s| {
                s.rows
                    .iter()
                    .map(|r| ForceCandidateScore {
                        candidate: r.label.clone(),
                        heldout_rms_n: r.heldout_after,
                        p_value: r.p_corrected,
                        verdict: best_verdict(
                            r,
                            opts.alpha,
                            opts.min_improvement,
                            "rejected as physically implausible",
                        ),
                        status: r.verdict.status().to_string(),
                    })
                    .collect()
            })
            .collect(),
        mass_kg: [m0, m1],
        cog_z_m: [c0, c1],
        settings: opts.clone(),
    })
}

/// Held-out residuals of each sensor against each platform coordinate (five quantile bins, a
/// weighted one-way analysis of variance), Bonferroni over the 36 tests; a dependence counts
/// when it is significant and explains at least 5 % of the residual variance.
fn screen(poses: &[Pose], res: &DMatrix<f64>, alpha: f64) -> ForceUnexplained {
    let names = ["x", "y", "z", "phi_x", "phi_y", "phi_z"];
    let coords: Vec<[f64; 6]> = poses
        .iter()
        .map(|p| {
            let g = gibbs_vector(&p.rotation).unwrap_or_default();
            let t = p.translation.vector;
            [t.x, t.y, t.z, g.x, g.y, g.z]
        })
        .collect();
    let w = vec![1.0; poses.len()];
    let mut depends_on = Vec::new();
    for (c, name) in names.iter().enumerate() {
        let x: Vec<f64> = coords.iter().map(|v| v[c]).collect();
        let spread =
            x.iter().fold(f64::NEG_INFINITY, |a, b| a.max(*b)) - x.iter().fold(f64::INFINITY, |a, b| a.min(*b));
        if spread <= 1e-12 {
            continue;
        }
        let groups = quantile_groups(&x, 5);
        let found = (0..6).any(|s| {
            let y: Vec<f64> = (0..poses.len()).map(|i| res[(i, s)]).collect();
            let t = binned_anova(&x, &y, &w, &groups, 5);
            bonferroni(t.p_value, 36) < alpha && t.explained > 0.05
        });
        if found {
            depends_on.push(name.to_string());
        }
    }
    ForceUnexplained { structure_found: !depends_on.is_empty(), depends_on }
}
