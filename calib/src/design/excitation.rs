//! Dynamic excitation: periodic Fourier-series trajectories per degree of freedom, with analytic
//! velocity and acceleration, bounds checked on a fine time grid, optimised for a given linear
//! regressor by a design criterion (Friedrich & Ihlenfeldt; Abdellatif & Heimann).
//!
//! For DOF `i` with `N` harmonics and base frequency `w`:
//!
//! ```text
//! x_i(t)   = sum_l ( a_l / (l w) sin(l w t) - b_l / (l w) cos(l w t) ) + x_i0
//! x_i'(t)  = sum_l ( a_l cos(l w t) + b_l sin(l w t) )
//! x_i''(t) = sum_l ( -a_l l w sin(l w t) + b_l l w cos(l w t) )
//! ```
//!
//! The information of a trajectory is `F = sum_t Y(t)^T Y(t)` over `samples` instants of one
//! period, `Y` the regressor rows at `(x, x', x'')` (any linear-in-parameters model: rigid-body
//! dynamics, a force sensor's wrench model). Bounds on position, velocity and acceleration are
//! checked on `check_samples` instants.
//!
//! # Optimiser
//! A compass (coordinate pattern) search over the coefficients `a, b` and offsets `x0`: each
//! coordinate in turn is moved by `+-step`; a move is kept when the trajectory stays within the
//! bounds and the criterion improves; when no move helps, the step halves. It needs no
//! gradients, handles the bounds by rejecting infeasible moves (the iterate is always
//! feasible), is deterministic, and converges to a local optimum; the source's active-set
//! solver does the same job faster on large problems. The start is a deterministic set of
//! phases (golden-angle spaced) scaled to half of the largest feasible amplitude.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use crate::design::criteria::Criterion;
use crate::error::{CalibError, Result};

/// Coefficients of one degree of freedom.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FourierDof {
    /// Cosine coefficients of the velocity, `a_1..a_N`.
    pub a: Vec<f64>,
    /// Sine coefficients of the velocity, `b_1..b_N`.
    pub b: Vec<f64>,
    /// Offset `x_0`.
    pub x0: f64,
}

/// A periodic Fourier-series trajectory.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FourierTrajectory {
    /// Base frequency `w`, rad/s.
    pub omega_rad_s: f64,
    /// Per degree of freedom.
    pub dofs: Vec<FourierDof>,
}

/// Position, velocity and acceleration of every DOF at one instant.
#[derive(Clone, Debug, PartialEq)]
pub struct TrajectorySample {
    /// Positions.
    pub x: Vec<f64>,
    /// Velocities.
    pub xd: Vec<f64>,
    /// Accelerations.
    pub xdd: Vec<f64>,
}

impl FourierTrajectory {
    /// A resting trajectory (all coefficients zero) with `harmonics` harmonics per DOF.
    pub fn zero(n_dof: usize, harmonics: usize, omega_rad_s: f64) -> Self {
        Self {
            omega_rad_s,
            dofs: (0..n_dof)
                .map(|_| FourierDof { a: vec![0.0; harmonics], b: vec![0.0; harmonics], x0: 0.0 })
                .collect(),
        }
    }

    /// The period `2 pi / w`, seconds.
    pub fn period_s(&self) -> f64 {
        std::f64::consts::TAU / self.omega_rad_s
    }

    /// Position, velocity and acceleration at `t_s` (analytic).
    pub fn eval(&self, t_s: f64) -> TrajectorySample {
        let w = self.omega_rad_s;
        let n = self.dofs.len();
        let mut s = TrajectorySample { x: vec![0.0; n], xd: vec![0.0; n], xdd: vec![0.0; n] };
        for (i, d) in self.dofs.iter().enumerate() {
            let mut x = d.x0;
            let mut xd = 0.0;
            let mut xdd = 0.0;
            for (l0, (a, b)) in d.a.iter().zip(&d.b).enumerate() {
                let lw = (l0 + 1) as f64 * w;
                let (sn, cs) = (lw * t_s).sin_cos();
                x += a / lw * sn - b / lw * cs;
                xd += a * cs + b * sn;
                xdd += -a * lw * sn + b * lw * cs;
            }
            s.x[i] = x;
            s.xd[i] = xd;
            s.xdd[i] = xdd;
        }
        s
    }

    /// The coefficient vector: per DOF `a_1..a_N, b_1..b_N, x_0`.
    pub fn coefficients(&self) -> Vec<f64> {
        self.dofs.iter().flat_map(|d| d.a.iter().chain(&d.b).copied().chain(std::iter::once(d.x0))).collect()
    }

    /// Sets the coefficients from [`FourierTrajectory::coefficients`]' layout.
    pub fn set_coefficients(&mut self, c: &[f64]) -> Result<()> {
        let per: usize = self.dofs.first().map_or(0, |d| 2 * d.a.len() + 1);
        if c.len() != per * self.dofs.len() {
            return Err(CalibError::Data(format!("{} coefficients for {} expected", c.len(), per * self.dofs.len())));
        }
        for (i, d) in self.dofs.iter_mut().enumerate() {
            let n = d.a.len();
            let s = &c[i * per..(i + 1) * per];
            d.a.copy_from_slice(&s[..n]);
            d.b.copy_from_slice(&s[n..2 * n]);
            d.x0 = s[2 * n];
        }
        Ok(())
    }
}

/// Bounds of an excitation trajectory, per DOF.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExcitationBounds {
    /// Position range `[lo, hi]`.
    pub position: Vec<[f64; 2]>,
    /// Largest speed.
    pub velocity: Vec<f64>,
    /// Largest acceleration.
    pub acceleration: Vec<f64>,
}

impl ExcitationBounds {
    fn validate(&self) -> Result<()> {
        let n = self.position.len();
        if n == 0 || self.velocity.len() != n || self.acceleration.len() != n {
            return Err(CalibError::Data(
                "excitation bounds: one position range, speed and acceleration per DOF".into(),
            ));
        }
        for i in 0..n {
            let [lo, hi] = self.position[i];
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return Err(CalibError::Data(format!("excitation bounds: DOF {}: empty position range", i + 1)));
            }
            if !(self.velocity[i] > 0.0 && self.acceleration[i] > 0.0) {
                return Err(CalibError::Data(format!("excitation bounds: DOF {}: limits must be > 0", i + 1)));
            }
        }
        Ok(())
    }
}

/// The first bound a trajectory breaks.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BoundViolation {
    /// 1-based DOF.
    pub dof: usize,
    /// `position`, `velocity` or `acceleration`.
    pub quantity: String,
    /// When.
    pub t_s: f64,
    /// The value.
    pub value: f64,
    /// The bound it breaks.
    pub limit: f64,
}

impl std::fmt::Display for BoundViolation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "DOF {}: {} {:.6} beyond {:.6} at t = {:.4} s",
            self.dof, self.quantity, self.value, self.limit, self.t_s
        )
    }
}

/// Checks every bound at `samples` equally spaced instants of one period.
pub fn check_bounds(
    traj: &FourierTrajectory,
    bounds: &ExcitationBounds,
    samples: usize,
) -> std::result::Result<(), BoundViolation> {
    let period = traj.period_s();
    for k in 0..samples.max(1) {
        let t = period * k as f64 / samples.max(1) as f64;
        let s = traj.eval(t);
        for i in 0..s.x.len() {
            let [lo, hi] = bounds.position[i];
            if s.x[i] < lo || s.x[i] > hi {
                let limit = if s.x[i] < lo { lo } else { hi };
                return Err(BoundViolation { dof: i + 1, quantity: "position".into(), t_s: t, value: s.x[i], limit });
            }
            if s.xd[i].abs() > bounds.velocity[i] {
                return Err(BoundViolation {
                    dof: i + 1,
                    quantity: "velocity".into(),
                    t_s: t,
                    value: s.xd[i],
                    limit: bounds.velocity[i],
                });
            }
            if s.xdd[i].abs() > bounds.acceleration[i] {
                return Err(BoundViolation {
                    dof: i + 1,
                    quantity: "acceleration".into(),
                    t_s: t,
                    value: s.xdd[i],
                    limit: bounds.acceleration[i],
                });
            }
        }
    }
    Ok(())
}

/// Settings of [`optimise_excitation`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExcitationSettings {
    /// Harmonics per DOF (3 to 5 work best in the source).
    pub harmonics: usize,
    /// Period, seconds.
    pub period_s: f64,
    /// Regressor samples per period.
    pub samples: usize,
    /// Instants per period at which the bounds are checked.
    pub check_samples: usize,
    /// The criterion.
    pub criterion: Criterion,
    /// Largest number of criterion evaluations.
    pub max_evaluations: usize,
    /// First step, as a fraction of each coordinate's natural size.
    pub initial_step: f64,
    /// Stop when the step falls below this fraction.
    pub min_step: f64,
}

impl Default for ExcitationSettings {
    fn default() -> Self {
        Self {
            harmonics: 4,
            period_s: 10.0,
            samples: 200,
            check_samples: 2000,
            criterion: Criterion::D,
            max_evaluations: 3000,
            initial_step: 0.25,
            min_step: 1e-3,
        }
    }
}

/// The information `sum_t Y^T Y` of a trajectory over `samples` instants of one period.
pub fn information(
    traj: &FourierTrajectory,
    samples: usize,
    regressor: &dyn Fn(&TrajectorySample) -> Result<DMatrix<f64>>,
) -> Result<DMatrix<f64>> {
    let period = traj.period_s();
    let mut f: Option<DMatrix<f64>> = None;
    for k in 0..samples.max(1) {
        let t = period * k as f64 / samples.max(1) as f64;
        let y = regressor(&traj.eval(t))?;
        if y.iter().any(|v| !v.is_finite()) {
            return Err(CalibError::Data(format!("the regressor is not finite at t = {t:.4} s")));
        }
        let yy = y.transpose() * y;
        match &mut f {
            Some(f) if f.shape() == yy.shape() => *f += yy,
            Some(_) => return Err(CalibError::Data("the regressor changed its number of columns".into())),
            None => f = Some(yy),
        }
    }
    f.ok_or_else(|| CalibError::TooFew("no samples".into()))
}

/// The result of [`optimise_excitation`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExcitationResult {
    /// The optimised trajectory (within the bounds).
    pub trajectory: FourierTrajectory,
    /// Its loss.
    pub loss: f64,
    /// Its criterion value (source's form).
    pub value: f64,
    /// Loss of the start trajectory.
    pub start_loss: f64,
    /// Criterion evaluations used.
    pub evaluations: usize,
    /// `(evaluation, loss)` at every improvement.
    pub history: Vec<(usize, f64)>,
}

/// Optimises a Fourier trajectory for `regressor` within `bounds` (see the module
/// documentation).
pub fn optimise_excitation(
    bounds: &ExcitationBounds,
    settings: &ExcitationSettings,
    regressor: &dyn Fn(&TrajectorySample) -> Result<DMatrix<f64>>,
) -> Result<ExcitationResult> {
    bounds.validate()?;
    if settings.harmonics == 0 || !(settings.period_s.is_finite() && settings.period_s > 0.0) {
        return Err(CalibError::Data("excitation: at least one harmonic and a positive period".into()));
    }
    let n = bounds.position.len();
    let nh = settings.harmonics;
    let omega = std::f64::consts::TAU / settings.period_s;
    let mut traj = FourierTrajectory::zero(n, nh, omega);
    // Deterministic start: golden-angle phases, equal velocity amplitude per harmonic.
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    for (i, d) in traj.dofs.iter_mut().enumerate() {
        d.x0 = 0.5 * (bounds.position[i][0] + bounds.position[i][1]);
        for l in 0..nh {
            let phi = golden * (i * nh + l + 1) as f64;
            d.a[l] = bounds.velocity[i] / nh as f64 * phi.cos();
            d.b[l] = bounds.velocity[i] / nh as f64 * phi.sin();
        }
    }
    let base = traj.coefficients();
    let scaled = |s: f64| -> Vec<f64> {
        let per = 2 * nh + 1;
        base.iter().enumerate().map(|(j, c)| if j % per == 2 * nh { *c } else { c * s }).collect()
    };
    let feasible = |c: &[f64]| -> bool {
        let mut t = traj.clone();
        t.set_coefficients(c).is_ok() && check_bounds(&t, bounds, settings.check_samples).is_ok()
    };
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    while feasible(&scaled(hi)) && hi < 1e6 {
        lo = hi;
        hi *= 2.0;
    }
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if feasible(&scaled(mid)) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let mut c = scaled(0.5 * lo);
    let mut evaluations = 1usize;
    let eval = |c: &[f64]| -> Result<f64> {
        let mut t = traj.clone();
        t.set_coefficients(c)?;
        Ok(settings.criterion.loss(&information(&t, settings.samples, regressor)?))
    };
    let start_loss = eval(&c)?;
    let mut loss = start_loss;
    let mut history = vec![(1usize, loss)];
    // Natural size of each coordinate.
    let per = 2 * nh + 1;
    let unit: Vec<f64> = (0..c.len())
        .map(|j| {
            let i = j / per;
            if j % per == 2 * nh {
                0.5 * (bounds.position[i][1] - bounds.position[i][0])
            } else {
                bounds.velocity[i] / nh as f64
            }
        })
        .collect();
    let mut step = settings.initial_step;
    while step > settings.min_step && evaluations < settings.max_evaluations {
        let mut improved = false;
        for j in 0..c.len() {
            for s in [1.0, -1.0] {
                if evaluations >= settings.max_evaluations {
                    break;
                }
                let mut trial = c.clone();
                trial[j] += s * step * unit[j];
                if !feasible(&trial) {
                    continue;
                }
                evaluations += 1;
                let l = eval(&trial)?;
                if l < loss {
                    c = trial;
                    loss = l;
                    history.push((evaluations, l));
                    improved = true;
                    break;
                }
            }
        }
        if !improved {
            step *= 0.5;
        }
    }
    traj.set_coefficients(&c)?;
    if !loss.is_finite() {
        return Err(CalibError::TooFew(
            "no trajectory within the bounds determines every parameter of the regressor".into(),
        ));
    }
    Ok(ExcitationResult {
        value: settings.criterion.value(loss),
        trajectory: traj,
        loss,
        start_loss,
        evaluations,
        history,
    })
}
