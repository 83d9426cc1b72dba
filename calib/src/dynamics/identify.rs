//! Dynamic identification from trajectories: the pose from numerical forward kinematics,
//! velocities and accelerations by filtering, noise covariances from repeated periods,
//! Gauss-Markov estimation and the maximum-likelihood cutoff (Abdellatif & Heimann 2009).
//!
//! The chain is
//!
//! 1. [`poses_from_legs`]: measured leg positions -> platform pose coordinates by Newton on the
//!    hexapod's closure equations (warm-started from the previous sample);
//! 2. [`motion_states`]: pose coordinates -> pose, twist and acceleration by the chosen
//!    [`Differentiation`] (frequency domain or time domain, see [`super::signals`]);
//! 3. [`identify`]: the stacked regressor of a [`RowModel`] against the measured forces, weighted
//!    with the forces' full 6 x 6 noise covariance estimated from repeated periods
//!    ([`NoiseModel::Periods`]): the Gauss-Markov estimate;
//! 4. [`ml_cutoff`]: the cutoff frequency as the one extra parameter of a maximum-likelihood
//!    estimate over the measured poses and forces:
//!    `J(f_c) = sum_t e_x^T S_x^-1 e_x + sum_t e_f^T S_f^-1 e_f` with `e_x` the part of the measured
//!    pose that the filter removes and `e_f` the force residual of the Gauss-Markov fit at `f_c`,
//!    minimised over the DFT bins.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use ferrocal_robot::dynamics::motion::{coordinates_from_pose, pose_from_coordinates};
use ferrocal_robot::dynamics::{HexapodDynamics, MotionState};
use ferrocal_robot::parallel::{Hexapod, ParallelRobot};
use ferrocal_robot::Kinematics;

use super::force_sensor::{SensorModel, SensorRegressor};
use super::signals::{check_synchronised, period_statistics, time_domain, SampledSignal, Spectrum};
use crate::error::{CalibError, Result};
use ferrocal_lsq::linear::{fit, LinearFit, LinearOptions, Weighting};

/// A model whose measurements (six per sample) are linear in its parameters.
pub trait RowModel {
    /// Parameter names in column order.
    fn names(&self) -> Vec<String>;
    /// Writes the six rows of one state into `out` from row `row0`.
    fn fill(&self, state: &MotionState, out: &mut DMatrix<f64>, row0: usize) -> Result<()>;
}

/// A force-sensor model on its sensor framework.
#[derive(Clone, Copy, Debug)]
pub struct SensorRows<'a> {
    /// The framework's regressor.
    pub regressor: &'a SensorRegressor,
    /// The model.
    pub model: SensorModel,
}

impl RowModel for SensorRows<'_> {
    fn names(&self) -> Vec<String> {
        self.model.names()
    }
    fn fill(&self, state: &MotionState, out: &mut DMatrix<f64>, row0: usize) -> Result<()> {
        self.regressor.fill(self.model, state, out, row0)
    }
}

/// The hexapod's actuator forces (24 parameters).
impl RowModel for HexapodDynamics {
    fn names(&self) -> Vec<String> {
        HexapodDynamics::parameter_names()
    }
    fn fill(&self, state: &MotionState, out: &mut DMatrix<f64>, row0: usize) -> Result<()> {
        let y = self.regressor(state)?;
        if out.ncols() != 24 || out.nrows() < row0 + 6 {
            return Err(CalibError::Data("the hexapod regressor needs a buffer of 24 columns".into()));
        }
        out.view_mut((row0, 0), (6, 24)).copy_from(&y);
        Ok(())
    }
}

/// The stacked regressor of many states (six rows each).
pub fn regressor_of(model: &dyn RowModel, states: &[MotionState]) -> Result<DMatrix<f64>> {
    let n = model.names().len();
    let mut out = DMatrix::zeros(6 * states.len(), n);
    for (k, s) in states.iter().enumerate() {
        model.fill(s, &mut out, 6 * k).map_err(|e| CalibError::Data(format!("sample {}: {e}", k + 1)))?;
    }
    Ok(out)
}

/// How velocities and accelerations are obtained from the poses.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum Differentiation {
    /// DFT, rectangular window at `cutoff_hz`, `j w` differentiation.
    Frequency {
        /// Cutoff, Hz.
        cutoff_hz: f64,
    },
    /// Zero-phase Butterworth of `order` at `cutoff_hz`, then central differences.
    TimeDomain {
        /// Cutoff, Hz.
        cutoff_hz: f64,
        /// Even filter order.
        order: usize,
    },
}

impl Differentiation {
    /// A short label for reports.
    pub fn label(&self) -> String {
        match self {
            Differentiation::Frequency { cutoff_hz } => format!("frequency domain (DFT, f_c = {cutoff_hz:.3} Hz)"),
            Differentiation::TimeDomain { cutoff_hz, order } => {
                format!("time domain (Butterworth order {order} forward-backward, f_c = {cutoff_hz:.3} Hz, central differences)")
            }
        }
    }
}

/// Platform pose coordinates `(x, y, z, roll, pitch, yaw)` of the flange from measured leg
/// positions, by forward kinematics warm-started from the previous sample (the angles are
/// unwrapped to stay continuous).
pub fn poses_from_legs(model: &Hexapod, legs: &SampledSignal) -> Result<SampledSignal> {
    if legs.values.ncols() != 6 {
        return Err(CalibError::Data(format!(
            "the {} have {} channels; a hexapod has 6 legs",
            legs.name,
            legs.values.ncols()
        )));
    }
    let mech = model.mechanism()?;
    let tool_inv = model.tool.inverse();
    let mut out = DMatrix::zeros(legs.len(), 6);
    let mut prev: Option<ferrocal_robot::Pose> = None;
    let mut last = [0.0; 6];
    for k in 0..legs.len() {
        let q: Vec<f64> = legs.values.row(k).iter().copied().collect();
        let solved = match prev {
            Some(p) => mech.solve_pose(&q, &p, &model.solver).or_else(|_| model.forward(&q)),
            None => model.forward(&q),
        };
        let tool = solved.map_err(|e| {
            CalibError::Data(format!("{}: sample {} (t = {:.4} s): {e}", legs.name, k + 1, legs.time(k)))
        })?;
        prev = Some(tool);
        let mut c = coordinates_from_pose(&(tool * tool_inv));
        if k > 0 {
            for i in 3..6 {
                // Unwrapped onto the previous sample in one step (a loop of +-2 pi steps never
                // ends on a huge angle, where subtracting 2 pi changes nothing).
                let d = c[i] - last[i];
                if d.is_finite() && d.abs() > std::f64::consts::PI {
                    c[i] = last[i] + ferrocal_robot::geometry::wrap_angle(d);
                }
            }
        }
        last = c;
        for i in 0..6 {
            out[(k, i)] = c[i];
        }
    }
    SampledSignal::uniform("platform poses", legs.start_s, legs.rate_hz, out)
}

/// Pose coordinates and their derivatives, per channel.
fn derivatives(poses: &SampledSignal, d: &Differentiation) -> Result<[DMatrix<f64>; 3]> {
    let n = poses.len();
    let mut out = [DMatrix::zeros(n, 6), DMatrix::zeros(n, 6), DMatrix::zeros(n, 6)];
    for c in 0..6 {
        let x = poses.channel(c);
        let parts = match *d {
            Differentiation::Frequency { cutoff_hz } => {
                check_cutoff(cutoff_hz, poses.rate_hz)?;
                Spectrum::of(&x, poses.rate_hz).derivatives(cutoff_hz)
            }
            Differentiation::TimeDomain { cutoff_hz, order } => time_domain(&x, poses.rate_hz, cutoff_hz, order)?,
        };
        for (o, p) in out.iter_mut().zip(parts.iter()) {
            for k in 0..n {
                o[(k, c)] = p[k];
            }
        }
    }
    Ok(out)
}

fn check_cutoff(cutoff_hz: f64, rate_hz: f64) -> Result<()> {
    if !(cutoff_hz > 0.0 && cutoff_hz.is_finite()) {
        return Err(CalibError::Data(format!("cutoff {cutoff_hz} Hz must be positive")));
    }
    if cutoff_hz > 0.5 * rate_hz {
        return Err(CalibError::Data(format!(
            "cutoff {cutoff_hz} Hz lies above the Nyquist frequency {} Hz",
            0.5 * rate_hz
        )));
    }
    Ok(())
}

fn states_from(x: &DMatrix<f64>, v: &DMatrix<f64>, a: &DMatrix<f64>) -> Result<Vec<MotionState>> {
    (0..x.nrows())
        .map(|k| {
            let row = |m: &DMatrix<f64>| -> [f64; 6] { std::array::from_fn(|i| m[(k, i)]) };
            MotionState::from_coordinates(&row(x), &row(v), &row(a)).map_err(CalibError::from)
        })
        .collect()
}

/// Motion states (pose, twist, acceleration) from pose coordinates.
pub fn motion_states(poses: &SampledSignal, d: &Differentiation) -> Result<Vec<MotionState>> {
    if poses.values.ncols() != 6 {
        return Err(CalibError::Data(format!("the {} need 6 pose coordinates per sample", poses.name)));
    }
    let [x, v, a] = derivatives(poses, d)?;
    states_from(&x, &v, &a)
}

/// The noise model of the measured forces.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NoiseModel {
    /// Unit weights (ordinary least squares).
    Unit,
    /// A known 6 x 6 covariance of one sample's forces.
    Known(DMatrix<f64>),
    /// The covariance estimated from the deviations of repeated periods of this many samples
    /// (Gauss-Markov with the full, cross-correlated covariance).
    Periods {
        /// Samples per period.
        samples_per_period: usize,
    },
}

/// The result of [`identify`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct DynamicFit {
    /// The fit.
    pub fit: LinearFit,
    /// The forces' noise covariance used as weight (`None` for unit weights).
    pub force_covariance: Option<DMatrix<f64>>,
    /// Samples used.
    pub samples: usize,
}

/// Identifies a model from states and the forces measured at them (samples x 6).
pub fn identify(
    model: &dyn RowModel,
    states: &[MotionState],
    forces: &DMatrix<f64>,
    noise: &NoiseModel,
) -> Result<DynamicFit> {
    if forces.ncols() != 6 {
        return Err(CalibError::Data(format!("{} force channels; the models predict 6", forces.ncols())));
    }
    if states.len() != forces.nrows() {
        return Err(CalibError::Data(format!(
            "{} motion states but {} force samples: the pose and force streams must be synchronised sample by sample",
            states.len(),
            forces.nrows()
        )));
    }
    let cov = match noise {
        NoiseModel::Unit => None,
        NoiseModel::Known(c) => Some(c.clone()),
        NoiseModel::Periods { samples_per_period } => {
            Some(period_statistics("sensor forces", forces, *samples_per_period)?.covariance)
        }
    };
    let a = regressor_of(model, states)?;
    let y = nalgebra::DVector::from_iterator(
        forces.len(),
        (0..forces.nrows()).flat_map(|k| (0..6).map(move |c| forces[(k, c)])),
    );
    let w = match &cov {
        Some(c) => Weighting::Block(c.clone()),
        None => Weighting::Unit,
    };
    let fit = fit(&a, &y, &model.names(), &w, &LinearOptions::default())?;
    Ok(DynamicFit { fit, force_covariance: cov, samples: states.len() })
}

/// Identifies a model from the raw streams: leg positions and forces (checked to be
/// synchronised), forward kinematics, differentiation, then [`identify`].
pub fn identify_from_streams(
    hexapod: &Hexapod,
    model: &dyn RowModel,
    legs: &SampledSignal,
    forces: &SampledSignal,
    d: &Differentiation,
    noise: &NoiseModel,
) -> Result<DynamicFit> {
    check_synchronised(legs, forces)?;
    let poses = poses_from_legs(hexapod, legs)?;
    let states = motion_states(&poses, d)?;
    identify(model, &states, &forces.values, noise)
}

/// Settings of [`ml_cutoff`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MlSettings {
    /// Samples per period of the excitation (for the noise covariances).
    pub samples_per_period: usize,
    /// Lowest cutoff tried, Hz.
    pub min_hz: f64,
    /// Highest cutoff tried, Hz.
    pub max_hz: f64,
    /// Points of the first, logarithmic grid (then every bin around the best).
    pub grid: usize,
}

/// The result of [`ml_cutoff`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct MlResult {
    /// The maximum-likelihood cutoff, Hz.
    pub cutoff_hz: f64,
    /// The Gauss-Markov fit at that cutoff.
    pub fit: DynamicFit,
    /// `(f_c, J(f_c))` of every cutoff tried, ascending in `f_c`.
    pub curve: Vec<(f64, f64)>,
    /// Noise covariance of the pose coordinates (from repeated periods).
    pub pose_covariance: DMatrix<f64>,
}

/// The maximum-likelihood estimate with the cutoff frequency as the one extra parameter (see
/// the module documentation). `poses` from [`poses_from_legs`], `forces` synchronised with them.
pub fn ml_cutoff(
    model: &dyn RowModel,
    poses: &SampledSignal,
    forces: &SampledSignal,
    settings: &MlSettings,
) -> Result<MlResult> {
    check_synchronised(poses, forces)?;
    if !(settings.min_hz > 0.0 && settings.max_hz > settings.min_hz) {
        return Err(CalibError::Data(format!(
            "cutoff search range {} .. {} Hz is empty",
            settings.min_hz, settings.max_hz
        )));
    }
    check_cutoff(settings.max_hz, poses.rate_hz)?;
    let sx = period_statistics("platform poses", &poses.values, settings.samples_per_period)?.covariance;
    let sx_inv = sx
        .clone()
        .cholesky()
        .ok_or_else(|| CalibError::Data("the pose noise covariance is singular: are the poses noise-free?".into()))?
        .inverse();
    let spectra: Vec<Spectrum> = (0..6).map(|c| Spectrum::of(&poses.channel(c), poses.rate_hz)).collect();
    let noise = NoiseModel::Periods { samples_per_period: settings.samples_per_period };
    let n = poses.len();
    let res = spectra[0].resolution_hz();
    let evaluate = |fc: f64| -> Result<(f64, DynamicFit)> {
        let mut x = DMatrix::zeros(n, 6);
        let mut v = DMatrix::zeros(n, 6);
        let mut a = DMatrix::zeros(n, 6);
        for (c, s) in spectra.iter().enumerate() {
            let [px, pv, pa] = s.derivatives(fc);
            for k in 0..n {
                x[(k, c)] = px[k];
                v[(k, c)] = pv[k];
                a[(k, c)] = pa[k];
            }
        }
        let states = states_from(&x, &v, &a)?;
        let f = identify(model, &states, &forces.values, &noise)?;
        let e = &poses.values - &x;
        let jx: f64 = (0..n).map(|k| (e.row(k) * &sx_inv * e.row(k).transpose())[(0, 0)]).sum();
        Ok((jx + f.fit.chi2, f))
    };
    let bin = |f: f64| (f / res).round().max(1.0);
    let mut tried: Vec<(f64, f64)> = Vec::new();
    let mut best: Option<(f64, f64, DynamicFit)> = None;
    let consider = |fc: f64, tried: &mut Vec<(f64, f64)>, best: &mut Option<(f64, f64, DynamicFit)>| -> Result<()> {
        if tried.iter().any(|(f, _)| (f - fc).abs() < 0.5 * res) {
            return Ok(());
        }
        let (j, f) = evaluate(fc)?;
        tried.push((fc, j));
        if best.as_ref().is_none_or(|b| j < b.1) {
            *best = Some((fc, j, f));
        }
        Ok(())
    };
    let g = settings.grid.max(2);
    let ratio = (settings.max_hz / settings.min_hz).powf(1.0 / (g - 1) as f64);
    for i in 0..g {
        let fc = bin(settings.min_hz * ratio.powi(i as i32)) * res;
        consider(fc, &mut tried, &mut best)?;
    }
    let centre = best.as_ref().map_or(settings.min_hz, |b| b.0);
    let (lo, hi) =
        (bin((centre / ratio).max(settings.min_hz)) as usize, bin((centre * ratio).min(settings.max_hz)) as usize);
    for k in lo..=hi {
        consider(k as f64 * res, &mut tried, &mut best)?;
    }
    tried.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (cutoff_hz, _, fit) = best.ok_or_else(|| CalibError::TooFew("no cutoff could be evaluated".into()))?;
    Ok(MlResult { cutoff_hz, fit, curve: tried, pose_covariance: sx })
}

/// A state's pose from coordinates.
pub fn pose_of(x: &[f64; 6]) -> ferrocal_robot::Pose {
    pose_from_coordinates(x)
}
