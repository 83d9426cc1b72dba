//! The source's 6-DOF study on the simulated KR 270-like arm, end to end: a candidate pool of
//! configurations and payloads, the model reduction, the experiment chosen by the planner's
//! criterion for the reduced regressor, the identification, and the compensation of a 2.5 kN
//! class task load by the mirror method with the reduced model, a rigid-link / compliant-joint
//! model and the design estimates.

use ferrocal_calib::design::criteria::Criterion;
use ferrocal_calib::design::selection::SelectionSettings;
use ferrocal_calib::stiffness::compensate::{compliant_pose, error_norms, mirror, CompliancePredictor};
use ferrocal_calib::stiffness::error::Result;
use ferrocal_calib::stiffness::fit::{fit, Fit};
use ferrocal_calib::stiffness::problem::{LinearProblem, Observation};
use ferrocal_calib::stiffness::reduce::{reduce, Reduction, ReductionSettings};
use ferrocal_calib::stiffness::{design_experiment, ExperimentDesign, LoadCase, Parameterization};
use ferrocal_robot::stiffness::{ParamKind, WrenchLimits};
use ferrocal_robot::Kinematics;
use serde::{Deserialize, Serialize};

use crate::stiffsim::{StiffSim, StiffSimConfig};

/// Settings of [`arm_study`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ArmStudySettings {
    /// The cell.
    pub sim: StiffSimConfig,
    /// Candidate configurations (each measured under every payload).
    pub n_pool: usize,
    /// Measurements the experiment design keeps.
    pub n_design: usize,
    /// Validation measurements (random configurations and payloads).
    pub n_validation: usize,
    /// Task configurations for the compensation.
    pub n_task: usize,
    /// Payloads of the calibration experiment (absolute measurements).
    pub payloads: Vec<LoadCase>,
    /// The task's load.
    pub task_load: LoadCase,
    /// The design criterion.
    pub criterion: Criterion,
    /// The reduction's settings.
    pub reduction: ReductionSettings,
}

impl ArmStudySettings {
    /// The full study: 60 candidate configurations under 3 loads (0, 150 and 270 kg), 60 chosen
    /// by D-optimality, 40 validation and 50 task poses under 250 kg (2.45 kN).
    pub fn full(seed: u64) -> Self {
        Self {
            sim: StiffSimConfig { seed, ..StiffSimConfig::default() },
            n_pool: 60,
            n_design: 60,
            n_validation: 40,
            n_task: 50,
            payloads: vec![
                LoadCase::payload(0.0, [0.0; 3]),
                LoadCase::payload(150.0, [0.25, 0.0, 0.15]),
                LoadCase::payload(270.0, [0.0, 0.25, 0.3]),
            ],
            task_load: LoadCase::payload(250.0, [0.1, 0.0, 0.2]),
            criterion: Criterion::D,
            reduction: ReductionSettings::default(),
        }
    }

    /// A faster version (fewer poses) for demos and tests.
    pub fn quick(seed: u64) -> Self {
        Self { n_pool: 40, n_design: 45, n_validation: 25, n_task: 30, ..Self::full(seed) }
    }
}

/// Errors of one compensation variant over the task poses.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CompensationErrors {
    /// Which model compensated (`none` for the uncompensated robot).
    pub model: String,
    /// Its free parameter count.
    pub n_params: usize,
    /// RMS position error of the tool point.
    pub rms_m: f64,
    /// Largest position error.
    pub max_m: f64,
    /// RMS orientation error.
    pub rms_rad: f64,
    /// Position error per task pose.
    pub per_pose_m: Vec<f64>,
}

/// The study's results.
#[derive(Clone, Debug, Serialize)]
pub struct ArmStudy {
    /// The settings.
    pub settings: ArmStudySettings,
    /// The reduction on the designed experiment.
    pub reduction: Reduction,
    /// The experiment design over the candidate pool.
    pub design: ExperimentDesign,
    /// The rigid-link / compliant-joint fit (joint compliances and the compensator terms).
    pub rigid_link_fit: Fit,
    /// Uncompensated, design estimates, rigid-link / compliant-joint, reduced model, and the M5
    /// model (all identifiable parameters, before the parameter-to-noise threshold).
    pub compensation: Vec<CompensationErrors>,
    /// Largest tool force of the task.
    pub task_force_n: f64,
    /// Measurements in the pool, the design, validation.
    pub counts: [usize; 3],
    /// Physical problems of the M5 estimate (every identifiable parameter free).
    pub m5_physical_problems: Vec<String>,
}

impl ArmStudy {
    /// The compensation row of a model.
    pub fn errors(&self, model: &str) -> Option<&CompensationErrors> {
        self.compensation.iter().find(|c| c.model == model)
    }
}

/// Parameters of a rigid-link / compliant-joint model within a complete layout: the joint
/// compliances and the compensator terms.
pub fn rigid_link_param(layout: &ferrocal_robot::stiffness::ComplianceLayout) -> Parameterization {
    let complete = Parameterization::complete(layout);
    let keep: Vec<usize> =
        (0..layout.len()).filter(|&i| matches!(layout.params[i].kind, ParamKind::Spring { .. })).collect();
    complete.without(&keep)
}

/// Runs the study.
pub fn arm_study(settings: &ArmStudySettings) -> Result<ArmStudy> {
    let mut sim = StiffSim::kr270(settings.sim.clone())?;
    let limits = WrenchLimits::default();
    let prior = sim.nominal.complete_values();
    // Candidate pool: every configuration under every payload.
    let qs = sim.random_configurations(settings.n_pool);
    let mut cands = Vec::new();
    let mut obs: Vec<Observation> = Vec::new();
    for (k, q) in qs.iter().enumerate() {
        for (l, p) in settings.payloads.iter().enumerate() {
            obs.push(sim.observe(&format!("c{k:03}_{l}"), q, p)?);
            cands.push((q.clone(), *p));
        }
    }
    let pool = LinearProblem::from_observations(&sim.nominal, &obs, &limits)?;
    // Structure (M1 to M5) from the pool; the design keeps the measurements best for it.
    let structural = reduce(&pool, None, Some(&prior), &settings.reduction)?;
    let mut m5 = structural.param.clone();
    for f in structural.fixed.iter().filter(|f| f.step == "M6") {
        m5.params.push(f.param.clone());
    }
    let m5_prior = m5.project(&prior);
    let sel = SelectionSettings { criterion: settings.criterion, ..SelectionSettings::default() };
    let n_design = settings.n_design.min(cands.len());
    let design = design_experiment(
        &sim.nominal,
        &m5,
        &cands,
        &sim.markers(),
        settings.sim.sigma_m,
        &m5_prior,
        n_design,
        &sel,
        settings.sim.seed,
    )?;
    let problem = pool.subset(&design.chosen);
    // Validation.
    let vq = sim.random_configurations(settings.n_validation);
    let mut vobs = Vec::new();
    for (k, q) in vq.iter().enumerate() {
        let p = settings.payloads[k % settings.payloads.len()];
        vobs.push(sim.observe(&format!("v{k:03}"), q, &p)?);
    }
    let validation = LinearProblem::from_observations(&sim.nominal, &vobs, &limits)?;
    let reduction = reduce(&problem, Some(&validation), Some(&prior), &settings.reduction)?;
    // Rigid-link / compliant-joint model on the same measurements.
    let rl = rigid_link_param(&problem.layout);
    let rigid_link_fit = fit(&problem, &rl, settings.reduction.rank_tol)?;
    let rl_complete: Vec<f64> = rl.expand(&rigid_link_fit.values).iter().copied().collect();
    // Compensation of the task load.
    let predictors = [
        ("design estimates", sim.nominal.layout()?.len(), prior.clone()),
        ("rigid links, compliant joints", rl.len(), rl_complete),
        ("reduced model", reduction.param.len(), reduction.complete_values.clone()),
        (
            "M5 model (before the threshold)",
            reduction.step("M5").map(|s| s.n_params).unwrap_or(0),
            reduction.step("M5").map(|s| s.complete_values.clone()).unwrap_or_default(),
        ),
    ];
    let tq = sim.random_configurations(settings.n_task);
    let mut rows = vec![CompensationErrors {
        model: "none".into(),
        n_params: 0,
        rms_m: 0.0,
        max_m: 0.0,
        rms_rad: 0.0,
        per_pose_m: vec![],
    }];
    let mut task_force_n: f64 = 0.0;
    for q in &tq {
        let t_des = sim.nominal.chain.forward(q)?;
        let actual = compliant_pose(&sim.truth, q, &settings.task_load)?;
        let (ep, er) = error_norms(&t_des, &actual);
        rows[0].per_pose_m.push(ep);
        rows[0].rms_rad += er * er;
        task_force_n = task_force_n.max(settings.task_load.wrench(&sim.nominal, q)?.force_n.norm());
    }
    for (name, n, values) in predictors {
        let pred = CompliancePredictor::new(sim.nominal.clone(), values)?;
        let mut row = CompensationErrors {
            model: name.into(),
            n_params: n,
            rms_m: 0.0,
            max_m: 0.0,
            rms_rad: 0.0,
            per_pose_m: vec![],
        };
        for q in &tq {
            let t_des = sim.nominal.chain.forward(q)?;
            let m = mirror(&pred, q, &settings.task_load, 2)?;
            let actual = compliant_pose(&sim.truth, &m.q_command, &settings.task_load)?;
            let (ep, er) = error_norms(&t_des, &actual);
            row.per_pose_m.push(ep);
            row.rms_rad += er * er;
        }
        rows.push(row);
    }
    for r in &mut rows {
        let n = r.per_pose_m.len().max(1) as f64;
        r.rms_m = (r.per_pose_m.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
        r.max_m = r.per_pose_m.iter().copied().fold(0.0, f64::max);
        r.rms_rad = (r.rms_rad / n).sqrt();
    }
    Ok(ArmStudy {
        settings: settings.clone(),
        design,
        rigid_link_fit,
        compensation: rows,
        task_force_n,
        counts: [obs.len(), n_design, vobs.len()],
        m5_physical_problems: reduction
            .step("M5")
            .map(|m| {
                ferrocal_calib::stiffness::reduce::physical_problems(&problem.layout, &m.complete_values)
                    .into_iter()
                    .map(|(_, t)| t)
                    .collect()
            })
            .unwrap_or_default(),
        reduction,
    })
}

/// Noisy deflections `k w + e` of a directly observed spring and the noise-free ones.
pub fn one_link_measurements(
    k: &nalgebra::Matrix6<f64>,
    wrenches: &[nalgebra::Vector6<f64>],
    noise: &ferrocal_robot::stiffness::NoiseModel,
    seed: u64,
) -> (Vec<nalgebra::Vector6<f64>>, Vec<nalgebra::Vector6<f64>>) {
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let s = noise.pose_sigmas();
    let truth: Vec<nalgebra::Vector6<f64>> = wrenches.iter().map(|w| k * w).collect();
    let meas = truth
        .iter()
        .map(|t| {
            nalgebra::Vector6::from_fn(|r, _| {
                let e: f64 = StandardNormal.sample(&mut rng);
                t[r] + s[r] * e
            })
        })
        .collect();
    (meas, truth)
}

/// The source's one-link experiment repeated over seeds.
#[derive(Clone, Debug, Serialize)]
pub struct OneLinkStudy {
    /// Ratios of every entry at the true values (complete model, design with `sigma_i / 100`).
    pub ratios: Vec<ferrocal_calib::stiffness::onelink::EntryNu>,
    /// Loads of the design.
    pub n_loads: usize,
    /// Simulated experiments.
    pub trials: usize,
    /// Naive estimates with a negative `k11`.
    pub naive_negative_k11: usize,
    /// Naive estimates with asymmetric pairs.
    pub naive_asymmetric: usize,
    /// Naive estimates with any physical problem.
    pub naive_unphysical: usize,
    /// Reduced estimates with any physical problem.
    pub reduced_unphysical: usize,
    /// Reduced estimates that kept `k11`.
    pub reduced_kept_k11: usize,
    /// Mean free parameter count of the reduced estimates.
    pub reduced_mean_params: f64,
    /// RMS prediction error against the truth on validation loads: naive, reduced (mean over
    /// trials).
    pub validation_truth_rms_m: [f64; 2],
    /// The first trial's naive estimate (row-major 6 x 6).
    pub example_naive: Vec<f64>,
    /// The first trial's reduced estimate (row-major 6 x 6).
    pub example_reduced: Vec<f64>,
}

/// Runs the one-link experiment `trials` times (50 repeats of +-10 N / +-10 N m per axis).
pub fn one_link_study(trials: usize, seed: u64) -> Result<OneLinkStudy> {
    use ferrocal_calib::stiffness::onelink::{
        entry_ratios, one_link_layout, one_link_problem, orthogonal_design, SOURCE_NOISE,
    };
    use ferrocal_calib::stiffness::reduce::{physical_problems, prediction_rms};
    let k = ferrocal_robot::stiffness::presets::orthoglide_link_compliance();
    let w = orthogonal_design(50, 10.0, 10.0);
    let vw = orthogonal_design(5, 10.0, 10.0);
    let layout = one_link_layout();
    let ratios = entry_ratios(&k, &w, &SOURCE_NOISE)?;
    let mut st = OneLinkStudy {
        ratios,
        n_loads: w.len(),
        trials,
        naive_negative_k11: 0,
        naive_asymmetric: 0,
        naive_unphysical: 0,
        reduced_unphysical: 0,
        reduced_kept_k11: 0,
        reduced_mean_params: 0.0,
        validation_truth_rms_m: [0.0; 2],
        example_naive: vec![],
        example_reduced: vec![],
    };
    for t in 0..trials {
        let s = seed.wrapping_mul(1000).wrapping_add(t as u64);
        let (meas, truth) = one_link_measurements(&k, &w, &SOURCE_NOISE, s);
        let problem = one_link_problem(&w, &meas, Some(&truth), &SOURCE_NOISE)?;
        let (vm, vt) = one_link_measurements(&k, &vw, &SOURCE_NOISE, s ^ 0xABCD);
        let validation = one_link_problem(&vw, &vm, Some(&vt), &SOURCE_NOISE)?;
        let naive = fit(&problem, &Parameterization::complete(&layout), 1e-12)?;
        let probs = physical_problems(&layout, &naive.values);
        st.naive_negative_k11 += usize::from(naive.values[0] < 0.0);
        st.naive_asymmetric += usize::from(probs.iter().any(|(_, p)| p.contains("asymmetric")));
        st.naive_unphysical += usize::from(!probs.is_empty());
        let red = reduce(&problem, Some(&validation), None, &ReductionSettings::default())?;
        st.reduced_unphysical += usize::from(!red.physical_problems.is_empty());
        st.reduced_kept_k11 += usize::from(red.param.index_of("link.k11").is_some());
        st.reduced_mean_params += red.param.len() as f64 / trials as f64;
        let nv = nalgebra::DVector::from_vec(naive.values.clone());
        let rv = nalgebra::DVector::from_vec(red.complete_values.clone());
        st.validation_truth_rms_m[0] += prediction_rms(&validation, &nv).1.unwrap_or(0.0) / trials as f64;
        st.validation_truth_rms_m[1] += prediction_rms(&validation, &rv).1.unwrap_or(0.0) / trials as f64;
        if t == 0 {
            st.example_naive = naive.values.clone();
            st.example_reduced = red.complete_values.clone();
        }
    }
    Ok(st)
}
