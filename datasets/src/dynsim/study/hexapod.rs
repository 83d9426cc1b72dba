//! The hexapod's dynamics studies: identification, refusals of quasi-static data, maximum likelihood, and point-to-point excitation.

use super::*;

/// Result of [`hexapod_study`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct HexapodStudy {
    /// Parameter names.
    pub names: Vec<String>,
    /// True values.
    pub truth: Vec<f64>,
    /// The fit.
    pub fit: LinearFit,
    /// Samples used.
    pub samples: usize,
}

/// The hexapod's 24 parameters from actuator forces along one D-optimal trajectory.
pub fn hexapod_study(sim: &HexapodSim, setup: &DynamicSetup, seed: u64) -> Result<HexapodStudy> {
    let dynm = HexapodDynamics::new(&sim.hexapod).map_err(|e| DatasetError::Config(e.to_string()))?;
    let traj = excitation_for(&dynm, &sim.hexapod, setup, Criterion::D, sim.noise.sigma_n)?;
    let rec = record_hexapod(sim, &traj, setup, seed)?;
    let f = identify_from_streams(
        &sim.hexapod,
        &dynm,
        &rec.legs,
        &rec.forces,
        &Differentiation::Frequency { cutoff_hz: setup.cutoff_hz },
        &NoiseModel::Periods { samples_per_period: setup.samples_per_period() },
    )
    .map_err(calib("identification"))?;
    Ok(HexapodStudy { names: HexapodDynamics::parameter_names(), truth: sim.truth(), fit: f.fit, samples: f.samples })
}

/// The message of a model that is not identifiable on a quasi-static pose set (for reports).
pub fn refusal_of(sim: &PlatformSim, model: SensorModel, n_poses: usize) -> Result<Option<String>> {
    let reg = SensorRegressor::new(sim.sensors.clone(), sim.deformation.reference_xy_m).map_err(calib("sensors"))?;
    let home = home_coordinates(&sim.hexapod.home);
    let poses = candidate_poses(&sim.hexapod, n_poses, &home, &STATIC_HALF_RANGE, 0.005).map_err(calib("poses"))?;
    let states: Vec<MotionState> = poses.iter().map(|p| MotionState::at_rest(*p)).collect();
    let a = reg.regressor(model, &states).map_err(calib("regressor"))?;
    let id = identifiability(&a, &model.names(), &Weighting::Unit, 1e-9).map_err(lsq("identifiability"))?;
    Ok((id.rank < model.n_params()).then(|| rank_message(&id)))
}

/// Result of [`ml_study`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct MlStudy {
    /// Noise of a leg reading, m.
    pub leg_sigma_m: f64,
    /// The maximum-likelihood cutoff, Hz.
    pub cutoff_hz: f64,
    /// Highest harmonic of the excitation, Hz.
    pub highest_harmonic_hz: f64,
    /// Identified platform mass at that cutoff, kg.
    pub mass_kg: f64,
    /// `(f_c, J(f_c))` of every cutoff tried.
    pub curve: Vec<(f64, f64)>,
}

/// The maximum-likelihood cutoff on the hexapod with leg readings of `leg_sigma_m` noise,
/// searched between 0.3 and 40 Hz (3 periods recorded).
pub fn ml_study(sim: &HexapodSim, setup: &DynamicSetup, leg_sigma_m: f64, seed: u64) -> Result<MlStudy> {
    let sim = HexapodSim { noise: crate::dynsim::ForceNoise { leg_sigma_m, ..sim.noise }, ..sim.clone() };
    let s = DynamicSetup { periods: setup.periods.max(3), ..setup.clone() };
    let dynm = HexapodDynamics::new(&sim.hexapod).map_err(|e| DatasetError::Config(e.to_string()))?;
    let traj = excitation_for(&dynm, &sim.hexapod, &s, Criterion::D, sim.noise.sigma_n)?;
    let rec = record_hexapod(&sim, &traj, &s, seed)?;
    let poses = poses_from_legs(&sim.hexapod, &rec.legs).map_err(calib("forward kinematics"))?;
    let settings = ferrocal_calib::dynamics::identify::MlSettings {
        samples_per_period: s.samples_per_period(),
        min_hz: 0.3,
        max_hz: 40.0_f64.min(0.45 * s.rate_hz),
        grid: 12,
    };
    let r = ferrocal_calib::dynamics::identify::ml_cutoff(&dynm, &poses, &rec.forces, &settings)
        .map_err(calib("maximum likelihood"))?;
    Ok(MlStudy {
        leg_sigma_m,
        cutoff_hz: r.cutoff_hz,
        highest_harmonic_hz: s.harmonics as f64 / s.period_s,
        mass_kg: r.fit.fit.values[0],
        curve: r.curve,
    })
}

/// One excitation of [`ptp_study`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ExcitationRun {
    /// What it is.
    pub label: String,
    /// Period of the motion, s.
    pub period_s: f64,
    /// Samples identified (two periods).
    pub samples: usize,
    /// The fit of model 9.
    pub fit: LinearFit,
}

/// The optimised Fourier excitation (D criterion) against smooth point-to-point moves between
/// the corners of the pose box (90 % of the bounds), both identifying model 9 from two periods
/// (Gauss-Markov with the known force covariance; the point-to-point record is not periodic on
/// the sample grid, so it is processed in the time domain at 5 Hz).
pub fn ptp_study(sim: &PlatformSim, setup: &DynamicSetup, seed: u64) -> Result<[ExcitationRun; 2]> {
    let reg = SensorRegressor::new(sim.sensors.clone(), sim.deformation.reference_xy_m).map_err(calib("sensors"))?;
    let model = SensorModel::new(9).map_err(calib("model"))?;
    let rows = SensorRows { regressor: &reg, model };
    let noise = NoiseModel::Known(sim.noise.covariance());
    let traj = excitation_for(&rows, &sim.hexapod, setup, Criterion::D, sim.noise.sigma_n)?;
    let s2 = DynamicSetup { periods: 2, ..setup.clone() };
    let rec = record_platform(sim, &traj, &s2, seed)?;
    let fourier = identify_from_streams(
        &sim.hexapod,
        &rows,
        &rec.legs,
        &rec.forces,
        &Differentiation::Frequency { cutoff_hz: setup.cutoff_hz },
        &noise,
    )
    .map_err(calib("Fourier excitation"))?;
    let home = home_coordinates(&sim.hexapod.home);
    let h = setup.limits.half_range;
    let waypoints: Vec<[f64; 6]> = (0..8)
        .map(|k| {
            std::array::from_fn(|i| {
                let s = if (k >> (i % 3)) & 1 == 0 { 1.0 } else { -1.0 };
                home[i] + 0.9 * h[i] * if i >= 3 { -s } else { s }
            })
        })
        .collect();
    let ptp = ferrocal_calib::dynamics::design::PointToPoint::new(waypoints, &setup.limits.bounds(&home))
        .map_err(calib("point-to-point"))?;
    let samples = (2.0 * ptp.period_s() * setup.rate_hz).floor() as usize;
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_add(1));
    let prec = sim.record(&|t| ptp.eval(t), &Sampling::synchronous(setup.rate_hz, samples), &mut rng)?;
    let p = identify_from_streams(
        &sim.hexapod,
        &rows,
        &prec.legs,
        &prec.forces,
        &Differentiation::TimeDomain { cutoff_hz: 5.0, order: 4 },
        &noise,
    )
    .map_err(calib("point-to-point excitation"))?;
    Ok([
        ExcitationRun {
            label: format!("Fourier, {} harmonics, D-optimal", setup.harmonics),
            period_s: setup.period_s,
            samples: fourier.samples,
            fit: fourier.fit,
        },
        ExcitationRun {
            label: "point-to-point through the 8 corners of the pose box".into(),
            period_s: ptp.period_s(),
            samples: p.samples,
            fit: p.fit,
        },
    ])
}
