//! The motion experiments of Dressler ch. 6-7 on the simulated compliant axis: identification
//! from a random binary excitation (actuator model, black-box tool model, physical chain) with
//! validation on a separate record, at tracker rate and at camera rate; and iterative learning
//! control with the three measurement cases of chapter 7.

use ferrocal_calib::motion::identify::{self, DiscreteModel, Mode};
use ferrocal_calib::motion::ilc::{rms, Ilc};
use ferrocal_calib::motion::kalman::{EstimatorNoise, ToolEstimator};
use ferrocal_calib::motion::physical::{self, PhysicalFit};
use serde::Serialize;

use super::{quintic_move, random_binary_reference, CompliantAxis, SensorNoise, TrueMode};
use crate::error::{DatasetError, Result};

/// Settings of the identification experiment.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IdentifySettings {
    /// Length of the estimation record, s.
    pub estimation_s: f64,
    /// Length of the validation record (another excitation), s.
    pub validation_s: f64,
    /// Amplitude of the excitation, m.
    pub amplitude_m: f64,
    /// Samples per level of the random binary excitation at the tracker rate.
    pub hold_samples: usize,
    /// Tool measurement noise at the tracker rate, m.
    pub tracker_sigma_m: f64,
    /// Camera frame period in samples of the axis (the camera sees every n-th sample).
    pub camera_every: usize,
    /// Camera measurement noise, m.
    pub camera_sigma_m: f64,
    /// Seed.
    pub seed: u64,
}

impl Default for IdentifySettings {
    /// 60 s of estimation, 30 s of validation, +-2 mm, a tracker at 10 µm every 4 ms, a camera
    /// at 50 Hz with 30 µm.
    fn default() -> Self {
        Self {
            estimation_s: 60.0,
            validation_s: 30.0,
            amplitude_m: 0.002,
            hold_samples: 1,
            tracker_sigma_m: 10e-6,
            camera_every: 5,
            camera_sigma_m: 30e-6,
            seed: 1,
        }
    }
}

/// A black-box model as reported.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ModelReport {
    /// Denominator `a1 ..`.
    pub a: Vec<f64>,
    /// Numerator `b0 ..`.
    pub b: Vec<f64>,
    /// Dead time, samples.
    pub delay_samples: usize,
    /// Sample time, s.
    pub dt_s: f64,
    /// Modes `(Hz, std Hz, damping, std)`.
    pub modes: Vec<[f64; 4]>,
    /// Fit on the estimation record, percent.
    pub estimation_fit_percent: f64,
    /// Fit on the validation record (not used to fit), percent.
    pub validation_fit_percent: f64,
}

impl ModelReport {
    /// The model itself (without its covariance), for simulation and frequency responses.
    pub fn model(&self) -> DiscreteModel {
        DiscreteModel {
            a: self.a.clone(),
            b: self.b.clone(),
            nk: self.delay_samples,
            dt_s: self.dt_s,
            covariance: nalgebra::DMatrix::zeros(0, 0),
            residual_std: 0.0,
        }
    }
}

fn mode_rows(modes: &[Mode]) -> Vec<[f64; 4]> {
    modes.iter().map(|m| [m.frequency_hz, m.frequency_std_hz, m.damping, m.damping_std]).collect()
}

fn report(m: &DiscreteModel, est: (&[f64], &[f64]), val: (&[f64], &[f64])) -> ModelReport {
    ModelReport {
        a: m.a.clone(),
        b: m.b.clone(),
        delay_samples: m.nk,
        dt_s: m.dt_s,
        modes: mode_rows(&m.modes()),
        estimation_fit_percent: identify::fit_percent(est.1, &m.simulate(est.0)),
        validation_fit_percent: identify::fit_percent(val.1, &m.simulate(val.0)),
    }
}

/// The identification experiment's results.
#[derive(Clone, Debug, Serialize)]
pub struct IdentifyResult {
    /// Settings used.
    pub settings: IdentifySettings,
    /// The truth's modes `(Hz, damping)`.
    pub true_modes: Vec<[f64; 2]>,
    /// The truth's actuator pole and dead time.
    pub true_actuator_pole: f64,
    /// Reference to encoder: the closed actuator loop (order 1).
    pub actuator: ModelReport,
    /// Reference to tool at the tracker rate (order 5).
    pub tool_tracker: ModelReport,
    /// Encoder to tool at the tracker rate (order 4: the structure alone, both modes).
    pub chain_tracker: ModelReport,
    /// Reference to tool at the camera rate (order 3: the lag and the first mode; the second mode
    /// lies above the camera's Nyquist frequency).
    pub tool_camera: ModelReport,
    /// The physical chain fitted at the tracker rate: `m1, k1, k2, d1, d2` and their std.
    pub physical: [[f64; 2]; 5],
    /// The physical chain's modes `(Hz, std Hz, damping, std)`.
    pub physical_modes: Vec<[f64; 4]>,
    /// Relative error of each identified frequency against the truth (tracker-rate black boxes:
    /// both modes; camera: the first; physical: both).
    pub frequency_errors: FrequencyErrors,
}

impl IdentifyResult {
    /// The fitted physical chain as parameters, with the platform mass `m2_kg` it was fitted
    /// with (given, not fitted).
    pub fn physical_chain(&self, m2_kg: f64) -> physical::ChainParams {
        physical::ChainParams {
            m1_kg: self.physical[0][0],
            m2_kg,
            k1_n_m: self.physical[1][0],
            k2_n_m: self.physical[2][0],
            d1_n_s_m: self.physical[3][0],
            d2_n_s_m: self.physical[4][0],
        }
    }
}

/// Relative frequency errors, fractions.
#[derive(Clone, Debug, Serialize)]
pub struct FrequencyErrors {
    /// Tracker-rate black box (reference to tool), per mode.
    pub tracker: Vec<f64>,
    /// Tracker-rate black box of the chain alone (encoder to tool), per mode. The encoder is
    /// not held between samples, so a discrete model of the truth's order is an approximation.
    pub chain: Vec<f64>,
    /// Camera-rate black box, first mode.
    pub camera_first: f64,
    /// Physical chain, per mode.
    pub physical: Vec<f64>,
}

fn rel(est: &[[f64; 4]], truth: &[TrueMode], i: usize) -> f64 {
    est.get(i).map_or(f64::NAN, |m| m[0] / truth[i].frequency_hz - 1.0)
}

/// Runs the identification experiment on `axis`.
pub fn identify_axis(axis: &CompliantAxis, s: &IdentifySettings) -> Result<IdentifyResult> {
    let truth = axis.modes()?;
    let n_est = (s.estimation_s / axis.dt_s).round() as usize;
    let n_val = (s.validation_s / axis.dt_s).round() as usize;
    let tracker = SensorNoise { tool_sigma_m: s.tracker_sigma_m, ..SensorNoise::default() };
    let est = axis.run(&random_binary_reference(n_est, s.hold_samples, s.amplitude_m, s.seed), tracker, s.seed)?;
    let val = axis.run(
        &random_binary_reference(n_val, s.hold_samples, s.amplitude_m, s.seed + 1000),
        tracker,
        s.seed + 1000,
    )?;
    let c = |e: ferrocal_calib::CalibError| DatasetError::Input(format!("motion identification: {e}"));
    let dt = axis.dt_s;

    let nk_a = identify::estimate_delay(&est.reference_m, &est.encoder_m, 1, 1, 12, dt).map_err(c)?;
    let act = identify::fit_output_error(&est.reference_m, &est.encoder_m, 1, 1, nk_a, dt).map_err(c)?;
    let nk_t = identify::estimate_delay(&est.reference_m, &est.tool_measured_m, 5, 5, 12, dt).map_err(c)?;
    let tool = identify::fit_output_error(&est.reference_m, &est.tool_measured_m, 5, 5, nk_t, dt).map_err(c)?;

    // Camera rate: the excitation held over each frame, every n-th sample seen.
    let every = s.camera_every.max(1);
    let cam_noise = SensorNoise { tool_sigma_m: s.camera_sigma_m, ..SensorNoise::default() };
    let cam_rec = |n: usize, seed: u64| -> Result<(Vec<f64>, Vec<f64>)> {
        let r = random_binary_reference(n, s.hold_samples * every, s.amplitude_m, seed);
        let rec = axis.run(&r, cam_noise, seed)?;
        Ok((
            rec.reference_m.iter().step_by(every).copied().collect(),
            rec.tool_measured_m.iter().step_by(every).copied().collect(),
        ))
    };
    let (cu, cy) = cam_rec(n_est, s.seed + 2000)?;
    let (cvu, cvy) = cam_rec(n_val, s.seed + 3000)?;
    let cdt = dt * every as f64;
    let nk_c = identify::estimate_delay(&cu, &cy, 3, 3, 6, cdt).map_err(c)?;
    let cam = identify::fit_output_error(&cu, &cy, 3, 3, nk_c, cdt).map_err(c)?;

    // Encoder to tool: the chain alone (the actuator's lag and dead time removed), where the upper
    // mode shows in the tool more clearly than from the reference.
    let nk_ch = identify::estimate_delay(&est.encoder_m, &est.tool_measured_m, 4, 4, 4, dt).map_err(c)?;
    let chain = identify::fit_output_error(&est.encoder_m, &est.tool_measured_m, 4, 4, nk_ch, dt).map_err(c)?;
    let start = if chain.modes().len() >= 2 { chain.modes() } else { tool.modes() };
    let phys: PhysicalFit =
        physical::fit_chain(&est.encoder_m, &est.tool_measured_m, dt, axis.chain.m2_kg, &start).map_err(c)?;
    let p = phys.params;
    let sd = phys.std;
    let tool_r = report(&tool, (&est.reference_m, &est.tool_measured_m), (&val.reference_m, &val.tool_measured_m));
    let cam_r = report(&cam, (&cu, &cy), (&cvu, &cvy));
    let chain_r = report(&chain, (&est.encoder_m, &est.tool_measured_m), (&val.encoder_m, &val.tool_measured_m));
    let phys_modes = mode_rows(&phys.modes);
    let frequency_errors = FrequencyErrors {
        tracker: (0..2).map(|i| rel(&tool_r.modes, &truth, i)).collect(),
        chain: (0..2).map(|i| rel(&chain_r.modes, &truth, i)).collect(),
        camera_first: rel(&cam_r.modes, &truth, 0),
        physical: (0..2).map(|i| rel(&phys_modes, &truth, i)).collect(),
    };
    Ok(IdentifyResult {
        settings: s.clone(),
        true_modes: truth.iter().map(|m| [m.frequency_hz, m.damping]).collect(),
        true_actuator_pole: (-axis.dt_s / axis.servo_tau_s).exp(),
        actuator: report(&act, (&est.reference_m, &est.encoder_m), (&val.reference_m, &val.encoder_m)),
        tool_tracker: tool_r,
        chain_tracker: chain_r,
        tool_camera: cam_r,
        physical: [
            [p.m1_kg, sd.m1_kg],
            [p.k1_n_m, sd.k1_n_m],
            [p.k2_n_m, sd.k2_n_m],
            [p.d1_n_s_m, sd.d1_n_s_m],
            [p.d2_n_s_m, sd.d2_n_s_m],
        ],
        physical_modes: phys_modes,
        frequency_errors,
    })
}

/// The three measurement cases of learning control (chapter 7).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum IlcCase {
    /// The error from the encoder; the learning matrix from the actuator model.
    Actuator,
    /// The error from the tool estimated by the physical model from the encoder.
    ToolEstimate,
    /// The error from the measured tool (a tracker at the sample rate).
    ToolMeasurement,
    /// The error from the Kalman estimate of the tool: encoder, physical model and the camera
    /// (every few samples, delayed).
    ToolKalman,
}

/// Settings of the learning-control experiment.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IlcSettings {
    /// Trials after the first.
    pub iterations: usize,
    /// Length of the quintic move, m.
    pub distance_m: f64,
    /// Duration of the move, s.
    pub move_s: f64,
    /// Input weight of the norm-optimal update.
    pub weight: f64,
    /// A contact force on the platform that ramps in over 0.1 s after the move ends (0: none),
    /// N: what the encoder cannot see and a camera can.
    pub contact_force_n: f64,
    /// Camera frame period, samples.
    pub camera_every: usize,
    /// Camera latency, samples.
    pub camera_delay_samples: usize,
    /// Camera noise, m.
    pub camera_sigma_m: f64,
    /// Seed of the sensor noise.
    pub seed: u64,
}

impl Default for IlcSettings {
    /// Ten trials of a 20 mm move in 0.15 s, weight 1e-4, no contact force, a 50 Hz camera
    /// (every 5th sample at 4 ms) 12 ms late with 30 µm.
    fn default() -> Self {
        Self {
            iterations: 10,
            distance_m: 0.02,
            move_s: 0.15,
            weight: 1e-4,
            contact_force_n: 0.0,
            camera_every: 5,
            camera_delay_samples: 3,
            camera_sigma_m: 30e-6,
            seed: 1,
        }
    }
}

/// One case's true tool-path RMS error per iteration (0 is the first trial), m.
#[derive(Clone, Debug, Serialize)]
pub struct IlcRun {
    /// The case.
    pub case: IlcCase,
    /// True tool-path RMS error per trial, m.
    pub tool_rms_m: Vec<f64>,
    /// The measured error the controller saw per trial, RMS, m.
    pub measured_rms_m: Vec<f64>,
}

/// Runs `s.iterations` trials of each case along a quintic move, learning matrices from the
/// models identified in `id`.
pub fn ilc_experiment(axis: &CompliantAxis, id: &IdentifyResult, s: &IlcSettings) -> Result<Vec<IlcRun>> {
    let (iterations, distance_m, move_s, w, seed) = (s.iterations, s.distance_m, s.move_s, s.weight, s.seed);
    let dt = axis.dt_s;
    let n = ((0.1 + move_s + 0.6) / dt).round() as usize;
    let yd = quintic_move(n, dt, 0.1, move_s, distance_m);
    let (g_act, g_tool) = (id.actuator.model(), id.tool_tracker.model());
    let ph = id.physical_chain(axis.chain.m2_kg);
    let c = |e: ferrocal_calib::CalibError| DatasetError::Input(format!("learning control: {e}"));
    let t_contact = 0.1 + move_s;
    let force: Vec<f64> =
        (0..n).map(|k| s.contact_force_n * ((k as f64 * dt - t_contact) / 0.1).clamp(0.0, 1.0)).collect();
    let kalman = ToolEstimator::new(
        &ph,
        dt,
        EstimatorNoise { accel_sigma_m_s2: 0.05, force_step_n: 0.5, camera_sigma_m: s.camera_sigma_m },
        s.camera_delay_samples,
    )
    .map_err(c)?;
    let every = s.camera_every.max(1);
    let noise = SensorNoise { tool_sigma_m: id.settings.tracker_sigma_m, ..SensorNoise::default() };
    let mut runs = Vec::new();
    for case in [IlcCase::Actuator, IlcCase::ToolEstimate, IlcCase::ToolMeasurement, IlcCase::ToolKalman] {
        let h = match case {
            IlcCase::Actuator => g_act.impulse_response(n),
            _ => g_tool.impulse_response(n),
        };
        let ilc = Ilc::norm_optimal(&h, w).map_err(c)?;
        let mut u = yd.clone();
        let mut run = IlcRun { case, tool_rms_m: Vec::new(), measured_rms_m: Vec::new() };
        for k in 0..=iterations {
            // Every trial starts at rest at the path's start, whatever the learned input's first
            // sample: one sample of rest ahead of the input, dropped from the record.
            let mut padded = Vec::with_capacity(n + 1);
            padded.push(yd[0]);
            padded.extend_from_slice(&u);
            let mut f = vec![0.0];
            f.extend_from_slice(&force);
            let mut rec = axis.run_with_force(&padded, &f, noise, seed + k as u64)?;
            for s in [&mut rec.encoder_m, &mut rec.tool_true_m, &mut rec.tool_measured_m] {
                s.remove(0);
            }
            let seen: Vec<f64> = match case {
                IlcCase::Actuator => rec.encoder_m.clone(),
                IlcCase::ToolEstimate => ph.simulate(&rec.encoder_m, dt, 8),
                IlcCase::ToolMeasurement => rec.tool_measured_m.clone(),
                IlcCase::ToolKalman => {
                    let camera = camera_frames(&rec.tool_true_m, every, s.camera_sigma_m, seed + 500 + k as u64);
                    kalman.estimate(&rec.encoder_m, &camera, dt).map_err(c)?.iter().map(|e| e.position_m).collect()
                }
            };
            let e: Vec<f64> = yd.iter().zip(&seen).map(|(a, b)| a - b).collect();
            let truth_e: Vec<f64> = yd.iter().zip(&rec.tool_true_m).map(|(a, b)| a - b).collect();
            run.tool_rms_m.push(rms(&truth_e));
            run.measured_rms_m.push(rms(&e));
            if k < iterations {
                u = ilc.update(&u, &e).map_err(c)?;
            }
        }
        runs.push(run);
    }
    Ok(runs)
}

/// The camera's frames of a tool path: every `every`-th sample with normal noise.
fn camera_frames(tool_m: &[f64], every: usize, sigma_m: f64, seed: u64) -> Vec<Option<f64>> {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let normal = Normal::new(0.0, sigma_m.max(f64::MIN_POSITIVE)).expect("finite sigma");
    tool_m.iter().enumerate().map(|(k, y)| (k % every == 0).then(|| y + normal.sample(&mut rng))).collect()
}

/// Refuses a contact force (`--contact-force-n`) outside 0 to 1000 N.
pub fn check_contact_force(f_n: f64) -> Result<()> {
    if !(0.0..=1000.0).contains(&f_n) {
        return Err(DatasetError::Input(format!("--contact-force-n {f_n} N: give a force from 0 to 1000 N")));
    }
    Ok(())
}

/// Refuses a number of learning-control trials after the first (`--iterations`) outside 1 to 50.
pub fn check_iterations(iterations: usize) -> Result<()> {
    if !(1..=50).contains(&iterations) {
        return Err(DatasetError::Input(format!("--iterations {iterations}: give 1 to 50 trials after the first")));
    }
    Ok(())
}
