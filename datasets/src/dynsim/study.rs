//! The sources' experiments, run on the simulator: each function simulates the data, runs the
//! identification of `ferrocal_calib::dynamics` and returns the numbers the sources report, so
//! that tests can assert them and `ferrocal dynamics study` can tabulate them.
//!
//! - [`models_study`]: models 0 to 9 on one quasi-static pose set and one trajectory
//!   (Friedrich & Ihlenfeldt, Table 3);
//! - [`reduction_study`]: pose reduction from a pool by a criterion, down to the rank limit;
//! - [`excitation_study`]: D-optimal against condition-number excitation in repeated
//!   identifications of the hexapod's 24 parameters (Abdellatif & Heimann);
//! - [`filtering_study`]: frequency- against time-domain processing, judged on a validation
//!   trajectory;
//! - [`payload_study`]: payload steps re-identified quasi-statically and dynamically;
//! - [`hexapod_study`]: the hexapod's rigid-body and friction parameters against the truth;
//! - [`ml_study`]: the maximum-likelihood cutoff frequency;
//! - [`ptp_study`]: the optimised Fourier excitation against point-to-point moves.

use ferrocal_calib::design::criteria::Criterion;
use ferrocal_calib::design::excitation::{ExcitationBounds, ExcitationSettings, FourierTrajectory};
use ferrocal_calib::dynamics::design::{
    candidate_poses, optimise_trajectory, pose_pool, reduce_poses, reference_scale, Reduction,
};
use ferrocal_calib::dynamics::force_sensor::{SensorModel, SensorRegressor};
use ferrocal_calib::dynamics::identify::{
    identify, identify_from_streams, motion_states, poses_from_legs, regressor_of, DynamicFit, RowModel,
};
use ferrocal_calib::dynamics::{Differentiation, NoiseModel, SensorRows};
use ferrocal_lsq::linear::{fit, identifiability, rank_message, LinearFit, LinearOptions, Weighting};
use ferrocal_robot::dynamics::{HexapodDynamics, MotionState};
use ferrocal_robot::Pose;
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::{DynamicRecord, HexapodSim, PlatformSim, Sampling};
use crate::error::{DatasetError, Result};

mod hexapod;
pub use hexapod::{hexapod_study, ml_study, ptp_study, refusal_of, ExcitationRun, HexapodStudy, MlStudy};

fn calib(what: &str) -> impl FnOnce(ferrocal_calib::CalibError) -> DatasetError + '_ {
    move |e| DatasetError::Input(format!("{what}: {e}"))
}

fn lsq(what: &str) -> impl FnOnce(ferrocal_lsq::LsqError) -> DatasetError + '_ {
    move |e| DatasetError::Input(format!("{what}: {e}"))
}

/// Pose coordinates of the hexapod's home.
pub fn home_coordinates(sim_home: &Pose) -> [f64; 6] {
    ferrocal_robot::dynamics::motion::coordinates_from_pose(sim_home)
}

/// Half ranges of the quasi-static pose box: +-60 mm in x and y, +-40 mm in z, +-10 deg of
/// roll and pitch, +-12 deg of yaw.
pub const STATIC_HALF_RANGE: [f64; 6] = [0.06, 0.06, 0.04, 0.1745, 0.1745, 0.2094];

/// Bounds of excitation trajectories around a home pose, per pose coordinate (m, rad).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MotionLimits {
    /// Half range of each coordinate about the home pose.
    pub half_range: [f64; 6],
    /// Largest speed.
    pub velocity: [f64; 6],
    /// Largest acceleration.
    pub acceleration: [f64; 6],
}

impl Default for MotionLimits {
    /// +-40 mm, +-30 mm (z), +-0.12 rad, +-0.15 rad (yaw); 0.15 m/s, 0.8 rad/s; 2 m/s^2, 8 rad/s^2.
    fn default() -> Self {
        Self {
            half_range: [0.04, 0.04, 0.03, 0.12, 0.12, 0.15],
            velocity: [0.15, 0.15, 0.1, 0.8, 0.8, 1.0],
            acceleration: [2.0, 2.0, 1.5, 8.0, 8.0, 10.0],
        }
    }
}

impl MotionLimits {
    /// The bounds about `home`.
    pub fn bounds(&self, home: &[f64; 6]) -> ExcitationBounds {
        ExcitationBounds {
            position: (0..6).map(|i| [home[i] - self.half_range[i], home[i] + self.half_range[i]]).collect(),
            velocity: self.velocity.to_vec(),
            acceleration: self.acceleration.to_vec(),
        }
    }
}

/// Settings of the dynamic experiments.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DynamicSetup {
    /// Excitation period, s.
    pub period_s: f64,
    /// Harmonics of the Fourier series.
    pub harmonics: usize,
    /// Periods recorded (at least 2: the noise covariance comes from their deviations).
    pub periods: usize,
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Cutoff of the frequency-domain processing, Hz.
    pub cutoff_hz: f64,
    /// Criterion evaluations of the trajectory optimisation (1: the feasible start only).
    pub max_evaluations: usize,
    /// Regressor samples per period in the optimisation.
    pub design_samples: usize,
    /// Bounds of the trajectories.
    pub limits: MotionLimits,
}

impl Default for DynamicSetup {
    fn default() -> Self {
        Self {
            period_s: 4.0,
            harmonics: 4,
            periods: 2,
            rate_hz: 200.0,
            cutoff_hz: 2.5,
            max_evaluations: 1,
            design_samples: 100,
            limits: MotionLimits::default(),
        }
    }
}

impl DynamicSetup {
    /// Samples per period.
    pub fn samples_per_period(&self) -> usize {
        (self.period_s * self.rate_hz).round() as usize
    }

    /// The synchronised sampling of the whole record.
    pub fn sampling(&self) -> Sampling {
        Sampling::synchronous(self.rate_hz, self.samples_per_period() * self.periods)
    }

    fn excitation(&self, criterion: Criterion) -> ExcitationSettings {
        ExcitationSettings {
            harmonics: self.harmonics,
            period_s: self.period_s,
            samples: self.design_samples,
            check_samples: 1000,
            criterion,
            max_evaluations: self.max_evaluations,
            ..ExcitationSettings::default()
        }
    }
}

/// An excitation optimised for `model` by `criterion` (see [`DynamicSetup::max_evaluations`]).
pub fn excitation_for(
    model: &dyn RowModel,
    hexapod: &ferrocal_robot::parallel::Hexapod,
    setup: &DynamicSetup,
    criterion: Criterion,
    sigma_n: f64,
) -> Result<FourierTrajectory> {
    let home = home_coordinates(&hexapod.home);
    let bounds = setup.limits.bounds(&home);
    let scale = reference_scale(model, &bounds).map_err(calib("excitation scale"))?;
    let r = optimise_trajectory(model, hexapod, &bounds, &setup.excitation(criterion), &scale, sigma_n)
        .map_err(calib("excitation"))?;
    Ok(r.trajectory)
}

/// Records a Fourier trajectory with a platform simulator.
pub fn record_platform(
    sim: &PlatformSim,
    traj: &FourierTrajectory,
    setup: &DynamicSetup,
    seed: u64,
) -> Result<DynamicRecord> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    sim.record(&|t| traj.eval(t), &setup.sampling(), &mut rng)
}

/// Records a Fourier trajectory with a hexapod simulator.
pub fn record_hexapod(
    sim: &HexapodSim,
    traj: &FourierTrajectory,
    setup: &DynamicSetup,
    seed: u64,
) -> Result<DynamicRecord> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    sim.record(&|t| traj.eval(t), &setup.sampling(), &mut rng)
}

/// One model's line of the models table.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ModelRow {
    /// The model.
    pub model: u8,
    /// Its description.
    pub description: String,
    /// Parameters here.
    pub n_params: usize,
    /// Parameters in the source (`None`: "not identifiable").
    pub source_n_params: Option<usize>,
    /// Rank of the regressor on the data.
    pub rank: usize,
    /// The refusal message when not identifiable.
    pub refused: Option<String>,
    /// Identified mass and its standard deviation, kg.
    pub mass_kg: Option<(f64, f64)>,
    /// Identified centre of gravity, m.
    pub cog_m: Option<[f64; 3]>,
    /// `s0` of the fit (unit weights: residual RMS, N).
    pub s0: Option<f64>,
    /// Largest `|estimate - truth| / sigma` over the parameters with a true value.
    pub max_normalised_error: Option<f64>,
    /// Pearson correlations of the estimates (when fitted).
    pub correlation: Option<DMatrix<f64>>,
    /// `|R|` of the QR decomposition of the whitened, column-scaled regressor (when fitted).
    pub r_factor: Option<DMatrix<f64>>,
}

/// Result of [`models_study`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ModelsStudy {
    /// True mass, kg.
    pub true_mass_kg: f64,
    /// True centre of gravity, m.
    pub true_cog_m: [f64; 3],
    /// Rows for models 0 to 9.
    pub rows: Vec<ModelRow>,
    /// Quasi-static poses used.
    pub poses: usize,
    /// Dynamic samples used.
    pub samples: usize,
}

fn model_row(
    model: SensorModel,
    reg: &SensorRegressor,
    a: &DMatrix<f64>,
    y: &DVector<f64>,
    w: &Weighting,
    sim: &PlatformSim,
) -> Result<ModelRow> {
    let names = model.names();
    let id = identifiability(a, &names, w, 1e-9).map_err(lsq("identifiability"))?;
    let base = ModelRow {
        model: model.id(),
        description: model.description().to_string(),
        n_params: model.n_params(),
        source_n_params: model.source_n_params(),
        rank: id.rank,
        refused: None,
        mass_kg: None,
        cog_m: None,
        s0: None,
        max_normalised_error: None,
        correlation: None,
        r_factor: None,
    };
    match fit(a, y, &names, w, &LinearOptions::default()) {
        Ok(f) => {
            let truth = reg.true_values(model, &sim.truth());
            Ok(ModelRow {
                mass_kg: Some((f.values[0], f.std[0])),
                cog_m: Some([f.values[1] / f.values[0], f.values[2] / f.values[0], f.values[3] / f.values[0]]),
                s0: Some(f.s0),
                max_normalised_error: Some(max_normalised_error(&f, &truth)),
                correlation: Some(f.correlation.clone()),
                r_factor: Some(f.r_factor.clone()),
                ..base
            })
        }
        Err(e) => Ok(ModelRow { refused: Some(e.to_string()), ..base }),
    }
}

/// Largest `|estimate - truth| / sigma` over the parameters with a true value.
pub fn max_normalised_error(f: &LinearFit, truth: &[Option<f64>]) -> f64 {
    f.values
        .iter()
        .zip(&f.std)
        .zip(truth)
        .filter_map(|((v, s), t)| t.map(|t| (v - t).abs() / s.max(1e-300)))
        .fold(0.0, f64::max)
}

/// The quasi-static regressor and averaged forces of a static record for a model.
pub fn static_problem(
    reg: &SensorRegressor,
    model: SensorModel,
    poses: &[Pose],
    forces: &DMatrix<f64>,
) -> Result<(DMatrix<f64>, DVector<f64>)> {
    let states: Vec<MotionState> = poses.iter().map(|p| MotionState::at_rest(*p)).collect();
    let a = reg.regressor(model, &states).map_err(calib("regressor"))?;
    let y = DVector::from_iterator(forces.len(), (0..forces.nrows()).flat_map(|k| (0..6).map(move |c| forces[(k, c)])));
    Ok((a, y))
}

/// Models 0 to 9: the quasi-static ones from `n_poses` poses (averages of `samples_per_pose`
/// readings), the dynamic ones from one trajectory (frequency-domain processing, Gauss-Markov
/// with the covariance from the repeated periods).
pub fn models_study(
    sim: &PlatformSim,
    n_poses: usize,
    samples_per_pose: usize,
    setup: &DynamicSetup,
    seed: u64,
) -> Result<ModelsStudy> {
    let reg = SensorRegressor::new(sim.sensors.clone(), sim.deformation.reference_xy_m).map_err(calib("sensors"))?;
    let home = home_coordinates(&sim.hexapod.home);
    let poses = candidate_poses(&sim.hexapod, n_poses, &home, &STATIC_HALF_RANGE, 0.005).map_err(calib("poses"))?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let rec = sim.static_record(&poses, samples_per_pose, &mut rng)?;
    let mut rows = Vec::new();
    for id in 0..=5u8 {
        let model = SensorModel::new(id).map_err(calib("model"))?;
        let (a, y) = static_problem(&reg, model, &rec.poses, &rec.forces_n)?;
        rows.push(model_row(model, &reg, &a, &y, &Weighting::Unit, sim)?);
    }
    let rows_model = SensorRows { regressor: &reg, model: SensorModel::new(9).map_err(calib("model"))? };
    let traj = excitation_for(&rows_model, &sim.hexapod, setup, Criterion::D, sim.noise.sigma_n)?;
    let drec = record_platform(sim, &traj, setup, seed.wrapping_add(1))?;
    let poses_sig = poses_from_legs(&sim.hexapod, &drec.legs).map_err(calib("forward kinematics"))?;
    let states = motion_states(&poses_sig, &Differentiation::Frequency { cutoff_hz: setup.cutoff_hz })
        .map_err(calib("differentiation"))?;
    let cov = ferrocal_calib::dynamics::signals::period_statistics(
        "sensor forces",
        &drec.forces.values,
        setup.samples_per_period(),
    )
    .map_err(calib("noise"))?
    .covariance;
    let fy = &drec.forces.values;
    let y = DVector::from_iterator(fy.len(), (0..fy.nrows()).flat_map(|k| (0..6).map(move |c| fy[(k, c)])));
    for id in 6..=9u8 {
        let model = SensorModel::new(id).map_err(calib("model"))?;
        let a = regressor_of(&SensorRows { regressor: &reg, model }, &states).map_err(calib("regressor"))?;
        rows.push(model_row(model, &reg, &a, &y, &Weighting::Block(cov.clone()), sim)?);
    }
    Ok(ModelsStudy {
        true_mass_kg: sim.body.mass_kg,
        true_cog_m: [sim.body.com_m.x, sim.body.com_m.y, sim.body.com_m.z],
        rows,
        poses: poses.len(),
        samples: states.len(),
    })
}

/// Result of [`reduction_study`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ReductionStudy {
    /// The model.
    pub model: u8,
    /// Pool size.
    pub pool: usize,
    /// The reduction (predicted deviations at the pool and at the kept count).
    pub reduction: Reduction,
    /// Ratios `reduced_std / full_std` per parameter (names in model order).
    pub ratios: Vec<(String, f64)>,
    /// Standard deviations of the mass from actual fits with the pool and with the kept poses
    /// (simulated data, unit weights), kg.
    pub fitted_mass_std_kg: (f64, f64),
}

/// Pose reduction for `model` from a pool of `pool` poses to `keep` by `criterion`, run on to
/// the rank limit.
pub fn reduction_study(
    sim: &PlatformSim,
    model: SensorModel,
    pool: usize,
    keep: usize,
    criterion: Criterion,
    seed: u64,
) -> Result<ReductionStudy> {
    let reg = SensorRegressor::new(sim.sensors.clone(), sim.deformation.reference_xy_m).map_err(calib("sensors"))?;
    let home = home_coordinates(&sim.hexapod.home);
    let poses = candidate_poses(&sim.hexapod, pool, &home, &STATIC_HALF_RANGE, 0.005).map_err(calib("poses"))?;
    let rows = SensorRows { regressor: &reg, model };
    let sigma = sim.noise.sigma_n.max(1e-6);
    let p = pose_pool(&rows, &poses, sigma).map_err(calib("pose pool"))?;
    let reduction = reduce_poses(&p, keep, criterion).map_err(calib("reduction"))?;
    let ratios = model
        .names()
        .into_iter()
        .zip(reduction.reduced_std.iter().zip(&reduction.full_std).map(|(r, f)| r / f))
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let rec = sim.static_record(&poses, 1, &mut rng)?;
    let fit_std = |idx: &[usize]| -> Result<f64> {
        let ps: Vec<Pose> = idx.iter().map(|&k| poses[k]).collect();
        let f = DMatrix::from_fn(idx.len(), 6, |r, c| rec.forces_n[(idx[r], c)]);
        let (a, y) = static_problem(&reg, model, &ps, &f)?;
        let lf = fit(&a, &y, &model.names(), &Weighting::Unit, &LinearOptions::default()).map_err(lsq("fit"))?;
        Ok(lf.std[0])
    };
    let all: Vec<usize> = (0..poses.len()).collect();
    let fitted_mass_std_kg = (fit_std(&all)?, fit_std(&reduction.chosen)?);
    Ok(ReductionStudy { model: model.id(), pool: poses.len(), reduction, ratios, fitted_mass_std_kg })
}

/// Result of [`excitation_study`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ExcitationStudy {
    /// Parameter names.
    pub names: Vec<String>,
    /// True values.
    pub truth: Vec<f64>,
    /// Standard deviation over the repeats, D-optimal trajectory.
    pub std_d: Vec<f64>,
    /// Standard deviation over the repeats, condition-number trajectory.
    pub std_k: Vec<f64>,
    /// Mean of the estimates, D-optimal trajectory.
    pub mean_d: Vec<f64>,
    /// Mean of the estimates, condition-number trajectory.
    pub mean_k: Vec<f64>,
    /// Mean over the repeats of each fit's own standard deviation, D-optimal trajectory.
    pub predicted_d: Vec<f64>,
    /// The same, condition-number trajectory.
    pub predicted_k: Vec<f64>,
    /// Repeats.
    pub repeats: usize,
    /// Parameters with a smaller deviation over the repeats under the D-optimal design.
    pub d_better: usize,
    /// Parameters with a smaller predicted deviation under the D-optimal design.
    pub d_better_predicted: usize,
    /// The two trajectories (D, K).
    pub trajectories: [FourierTrajectory; 2],
}

fn mean_std(values: &[Vec<f64>]) -> (Vec<f64>, Vec<f64>) {
    let n = values.len() as f64;
    let p = values[0].len();
    let mean: Vec<f64> = (0..p).map(|j| values.iter().map(|v| v[j]).sum::<f64>() / n).collect();
    let std = (0..p)
        .map(|j| (values.iter().map(|v| (v[j] - mean[j]).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt())
        .collect();
    (mean, std)
}

/// D-optimal against condition-number excitation for the hexapod's 24 parameters: both
/// trajectories optimised with `setup`, `repeats` simulated recordings of each identified
/// (frequency domain, Gauss-Markov with the period covariance).
pub fn excitation_study(sim: &HexapodSim, setup: &DynamicSetup, repeats: usize, seed: u64) -> Result<ExcitationStudy> {
    let dynm = HexapodDynamics::new(&sim.hexapod).map_err(|e| DatasetError::Config(e.to_string()))?;
    let td = excitation_for(&dynm, &sim.hexapod, setup, Criterion::D, sim.noise.sigma_n)?;
    let tk = excitation_for(&dynm, &sim.hexapod, setup, Criterion::K, sim.noise.sigma_n)?;
    let d = Differentiation::Frequency { cutoff_hz: setup.cutoff_hz };
    let noise = NoiseModel::Periods { samples_per_period: setup.samples_per_period() };
    let mut est = [Vec::new(), Vec::new()];
    let mut pred = [Vec::new(), Vec::new()];
    for r in 0..repeats.max(2) {
        for (j, t) in [&td, &tk].iter().enumerate() {
            let rec = record_hexapod(sim, t, setup, seed.wrapping_add(1000 * r as u64 + j as u64))?;
            let f = identify_from_streams(&sim.hexapod, &dynm, &rec.legs, &rec.forces, &d, &noise)
                .map_err(calib("identification"))?;
            est[j].push(f.fit.values);
            pred[j].push(f.fit.std);
        }
    }
    let (mean_d, std_d) = mean_std(&est[0]);
    let (mean_k, std_k) = mean_std(&est[1]);
    let (predicted_d, _) = mean_std(&pred[0]);
    let (predicted_k, _) = mean_std(&pred[1]);
    let d_better = std_d.iter().zip(&std_k).filter(|(a, b)| a < b).count();
    let d_better_predicted = predicted_d.iter().zip(&predicted_k).filter(|(a, b)| a < b).count();
    Ok(ExcitationStudy {
        names: HexapodDynamics::parameter_names(),
        truth: sim.truth(),
        std_d,
        std_k,
        mean_d,
        mean_k,
        predicted_d,
        predicted_k,
        repeats: repeats.max(2),
        d_better,
        d_better_predicted,
        trajectories: [td, tk],
    })
}

/// One processing's result in [`filtering_study`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FilteringRow {
    /// The processing.
    pub label: String,
    /// RMS of measured minus predicted forces on the validation trajectory, N.
    pub validation_rms_n: f64,
    /// The same on the identification trajectory, N.
    pub identification_rms_n: f64,
    /// RMS of the acceleration error of the processed identification data against the truth
    /// (translational coordinates), m/s^2.
    pub acceleration_rms_m_s2: f64,
    /// Identified platform mass, kg.
    pub mass_kg: f64,
}

/// Result of [`filtering_study`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FilteringStudy {
    /// Frequency domain, then time domain.
    pub rows: Vec<FilteringRow>,
    /// The noise-free validation forces' RMS against the truth: the floor set by the noise, N.
    pub noise_floor_n: f64,
    /// True platform mass, kg.
    pub true_mass_kg: f64,
}

fn rms_rows(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    ((a - b).norm_squared() / a.len() as f64).sqrt()
}

/// Frequency- against time-domain processing (same cutoff; the time domain with a 4th-order
/// zero-phase Butterworth and central differences): identify the hexapod on one trajectory,
/// predict the forces measured on another.
pub fn filtering_study(sim: &HexapodSim, setup: &DynamicSetup, seed: u64) -> Result<FilteringStudy> {
    let dynm = HexapodDynamics::new(&sim.hexapod).map_err(|e| DatasetError::Config(e.to_string()))?;
    let train = excitation_for(&dynm, &sim.hexapod, setup, Criterion::D, sim.noise.sigma_n)?;
    let other = DynamicSetup { harmonics: setup.harmonics.saturating_sub(1).max(2), ..setup.clone() };
    let valid = excitation_for(&dynm, &sim.hexapod, &other, Criterion::K, sim.noise.sigma_n)?;
    let rt = record_hexapod(sim, &train, setup, seed)?;
    let rv = record_hexapod(sim, &valid, setup, seed.wrapping_add(7))?;
    let noise = NoiseModel::Periods { samples_per_period: setup.samples_per_period() };
    let mut rows = Vec::new();
    for d in [
        Differentiation::Frequency { cutoff_hz: setup.cutoff_hz },
        Differentiation::TimeDomain { cutoff_hz: setup.cutoff_hz, order: 4 },
    ] {
        let pt = poses_from_legs(&sim.hexapod, &rt.legs).map_err(calib("forward kinematics"))?;
        let st = motion_states(&pt, &d).map_err(calib("processing"))?;
        let f: DynamicFit = identify(&dynm, &st, &rt.forces.values, &noise).map_err(calib("identification"))?;
        let pv = poses_from_legs(&sim.hexapod, &rv.legs).map_err(calib("forward kinematics"))?;
        let sv = motion_states(&pv, &d).map_err(calib("processing"))?;
        let predict = |states: &[MotionState]| -> Result<DMatrix<f64>> {
            let a = regressor_of(&dynm, states).map_err(calib("regressor"))?;
            let p = a * DVector::from_column_slice(&f.fit.values);
            Ok(DMatrix::from_fn(states.len(), 6, |k, c| p[6 * k + c]))
        };
        let acc_err: f64 = st
            .iter()
            .zip(&rt.true_states)
            .map(|(a, b)| (a.acceleration_m_s2 - b.acceleration_m_s2).norm_squared())
            .sum::<f64>()
            / (3 * st.len()) as f64;
        rows.push(FilteringRow {
            label: d.label(),
            validation_rms_n: rms_rows(&rv.forces.values, &predict(&sv)?),
            identification_rms_n: rms_rows(&rt.forces.values, &predict(&st)?),
            acceleration_rms_m_s2: acc_err.sqrt(),
            mass_kg: f.fit.values[0],
        });
    }
    Ok(FilteringStudy {
        rows,
        noise_floor_n: rms_rows(&rv.forces.values, &rv.true_forces),
        true_mass_kg: sim.platform.mass_kg,
    })
}

/// One payload step of [`payload_study`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PayloadRow {
    /// True payload, kg.
    pub payload_kg: f64,
    /// Identified total mass and `s0`, quasi-static (model 5).
    pub static_mass_kg: f64,
    /// `s0` of the quasi-static fit.
    pub static_s0: f64,
    /// Identified total mass, dynamic (model 9).
    pub dynamic_mass_kg: f64,
    /// `s0` of the dynamic fit.
    pub dynamic_s0: f64,
    /// Identified payload (total less the unloaded identification), quasi-static, kg.
    pub static_payload_kg: f64,
    /// Identified payload, dynamic, kg.
    pub dynamic_payload_kg: f64,
}

/// Payload steps (see [`super::payload_steps`]) re-identified with model 5 from `n_poses`
/// averaged poses and with model 9 from one trajectory. The first row is the unloaded rig.
pub fn payload_study(
    sim: &PlatformSim,
    steps: usize,
    step_kg: f64,
    n_poses: usize,
    samples_per_pose: usize,
    setup: &DynamicSetup,
    seed: u64,
) -> Result<Vec<PayloadRow>> {
    let reg = SensorRegressor::new(sim.sensors.clone(), sim.deformation.reference_xy_m).map_err(calib("sensors"))?;
    let home = home_coordinates(&sim.hexapod.home);
    let poses = candidate_poses(&sim.hexapod, n_poses, &home, &STATIC_HALF_RANGE, 0.005).map_err(calib("poses"))?;
    let m5 = SensorModel::new(5).map_err(calib("model"))?;
    let m9 = SensorModel::new(9).map_err(calib("model"))?;
    let traj = excitation_for(
        &SensorRows { regressor: &reg, model: m9 },
        &sim.hexapod,
        setup,
        Criterion::D,
        sim.noise.sigma_n,
    )?;
    let d = Differentiation::Frequency { cutoff_hz: setup.cutoff_hz };
    let noise = NoiseModel::Periods { samples_per_period: setup.samples_per_period() };
    let mut loads = vec![None];
    loads.extend(super::payload_steps(steps, step_kg).into_iter().map(Some));
    let mut out: Vec<PayloadRow> = Vec::new();
    for (k, load) in loads.iter().enumerate() {
        let s = match load {
            Some(p) => sim.with_payload(p),
            None => sim.clone(),
        };
        let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_add(100 * k as u64));
        let rec = s.static_record(&poses, samples_per_pose, &mut rng)?;
        let (a, y) = static_problem(&reg, m5, &rec.poses, &rec.forces_n)?;
        let fs =
            fit(&a, &y, &m5.names(), &Weighting::Unit, &LinearOptions::default()).map_err(lsq("quasi-static fit"))?;
        let drec = record_platform(&s, &traj, setup, seed.wrapping_add(100 * k as u64 + 1))?;
        let fd = identify_from_streams(
            &s.hexapod,
            &SensorRows { regressor: &reg, model: m9 },
            &drec.legs,
            &drec.forces,
            &d,
            &noise,
        )
        .map_err(calib("dynamic fit"))?;
        let (m0s, m0d) =
            out.first().map_or((fs.values[0], fd.fit.values[0]), |r| (r.static_mass_kg, r.dynamic_mass_kg));
        out.push(PayloadRow {
            payload_kg: load.map_or(0.0, |p| p.mass_kg),
            static_mass_kg: fs.values[0],
            static_s0: fs.s0,
            dynamic_mass_kg: fd.fit.values[0],
            dynamic_s0: fd.fit.s0,
            static_payload_kg: fs.values[0] - m0s,
            dynamic_payload_kg: fd.fit.values[0] - m0d,
        });
    }
    Ok(out)
}
