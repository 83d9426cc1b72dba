//! Experiment design for the linear models: pose pools and their reduction (quasi-static),
//! excitation trajectories (dynamic), built on [`crate::design`].
//!
//! - [`candidate_poses`]: a deterministic, evenly spread pool of reachable hexapod poses
//!   (Halton sequence in a box of pose coordinates, kept when the inverse kinematics is within
//!   the leg limits);
//! - [`pose_pool`]: each pose's six whitened regressor rows at rest, column-scaled with
//!   `h_l = 1 / ||a_l||` of the whole pool, as an [`InformationPool`];
//! - [`reduce_poses`]: greedy deletion by a criterion from the whole pool down to the rank
//!   limit, with the predicted standard deviations at the full and at the reduced count;
//! - [`optimise_trajectory`]: a Fourier-series excitation optimised for a model within bounds on
//!   pose, velocity and acceleration ([`crate::design::excitation`]), checked against the legs'
//!   limits through the inverse kinematics;
//! - [`PointToPoint`]: the alternative of smooth point-to-point moves between poses.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use ferrocal_robot::dynamics::motion::pose_from_coordinates;
use ferrocal_robot::dynamics::MotionState;
use ferrocal_robot::parallel::Hexapod;
use ferrocal_robot::{Kinematics, Pose};

use super::identify::RowModel;
use crate::design::criteria::Criterion;
use crate::design::excitation::{
    check_bounds, optimise_excitation, ExcitationBounds, ExcitationResult, ExcitationSettings, FourierTrajectory,
    TrajectorySample,
};
use crate::design::pool::InformationPool;
use crate::design::selection::{greedy_deletion, DeletionHistory};
use crate::error::{CalibError, Result};
use ferrocal_lsq::linear::predicted_std;

/// Names of the six pose coordinates, for messages.
pub const POSE_COORDINATES: [&str; 6] = ["x", "y", "z", "roll", "pitch", "yaw"];

/// The `i`-th element of the van der Corput sequence in `base` (one coordinate of a Halton
/// sequence).
pub(crate) fn radical_inverse(mut i: usize, base: usize) -> f64 {
    let mut f = 1.0;
    let mut r = 0.0;
    while i > 0 {
        f /= base as f64;
        r += f * (i % base) as f64;
        i /= base;
    }
    r
}

/// `count` reachable flange poses in the box `centre +- half_range` of pose coordinates
/// (`x, y, z` m, `roll, pitch, yaw` rad), spread by a Halton sequence; a pose is kept when the
/// inverse kinematics succeeds within the legs' limits shrunk by `margin_m`. Fails when fewer
/// than `count` are found in `50 count` tries.
pub fn candidate_poses(
    model: &Hexapod,
    count: usize,
    centre: &[f64; 6],
    half_range: &[f64; 6],
    margin_m: f64,
) -> Result<Vec<Pose>> {
    const PRIMES: [usize; 6] = [2, 3, 5, 7, 11, 13];
    let limits = model.joint_limits();
    let mut out = Vec::with_capacity(count);
    let mut i = 1;
    while out.len() < count {
        if i > 50 * count.max(1) {
            return Err(CalibError::TooFew(format!(
                "only {} of {count} poses in the box are reachable within the leg limits: shrink the box",
                out.len()
            )));
        }
        let x: [f64; 6] =
            std::array::from_fn(|d| centre[d] + half_range[d] * (2.0 * radical_inverse(i, PRIMES[d]) - 1.0));
        i += 1;
        let flange = pose_from_coordinates(&x);
        let Ok(q) = model.inverse_unchecked(&(flange * model.tool)) else {
            continue;
        };
        if q.iter().zip(&limits).all(|(v, l)| l.contains(*v, margin_m)) {
            out.push(flange);
        }
    }
    Ok(out)
}

/// A pool of poses for a model, with the scaling that went into it.
#[derive(Clone, Debug)]
pub struct PosePool {
    /// The candidates' whitened, column-scaled rows.
    pub pool: InformationPool,
    /// Column scale factors `h_l` (of the whitened rows).
    pub column_scale: Vec<f64>,
    /// Noise of one averaged sensor force, N.
    pub sigma_n: f64,
}

/// The pool of `poses` at rest for `model` with averaged-force noise `sigma_n` (N).
pub fn pose_pool(model: &dyn RowModel, poses: &[Pose], sigma_n: f64) -> Result<PosePool> {
    if !(sigma_n > 0.0 && sigma_n.is_finite()) {
        return Err(CalibError::Data(format!("force noise {sigma_n} N must be positive")));
    }
    let names = model.names();
    let n = names.len();
    let mut a = DMatrix::zeros(6 * poses.len(), n);
    for (k, p) in poses.iter().enumerate() {
        model.fill(&MotionState::at_rest(*p), &mut a, 6 * k)?;
    }
    a /= sigma_n;
    let mut h = vec![0.0; n];
    for (j, hj) in h.iter_mut().enumerate() {
        let norm = a.column(j).norm();
        if norm.is_nan() || norm <= 0.0 {
            return Err(CalibError::TooFew(format!("parameter '{}' has no effect at any pose of the pool", names[j])));
        }
        *hj = 1.0 / norm;
        a.column_mut(j).scale_mut(*hj);
    }
    let pool = InformationPool::from_grouped_rows(&a, 6, names)?;
    Ok(PosePool { pool, column_scale: h, sigma_n })
}

/// A pose reduction and what it costs in parameter deviations.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Reduction {
    /// The greedy deletion from the whole pool to the rank limit (criterion against count).
    pub history: DeletionHistory,
    /// The poses kept at `count` (pool indices).
    pub chosen: Vec<usize>,
    /// The count asked for.
    pub count: usize,
    /// Predicted standard deviations with the whole pool (model units).
    pub full_std: Vec<f64>,
    /// Predicted standard deviations with the chosen poses.
    pub reduced_std: Vec<f64>,
    /// Median over the parameters of `reduced_std / full_std`.
    pub median_ratio: f64,
}

/// Greedy deletion of `pool` by `criterion` down to the rank limit; the set at `count` with its
/// predicted deviations.
pub fn reduce_poses(pool: &PosePool, count: usize, criterion: Criterion) -> Result<Reduction> {
    let all: Vec<usize> = (0..pool.pool.len()).collect();
    let history = greedy_deletion(&pool.pool, &all, 0, criterion, 8)?;
    let chosen = history.subset_at(count).ok_or_else(|| {
        CalibError::TooFew(format!(
            "{count} poses cannot determine all {} parameters: the smallest full-rank set has {}",
            pool.pool.n_params(),
            history.minimum_count
        ))
    })?;
    let std_of = |subset: &[usize]| -> Result<Vec<f64>> {
        let s = predicted_std(&pool.pool.information(subset))
            .ok_or_else(|| CalibError::Numeric("the information of the chosen poses is singular".into()))?;
        Ok(s.iter().zip(&pool.column_scale).map(|(v, h)| v * h).collect())
    };
    let full_std = std_of(&all)?;
    let reduced_std = std_of(&chosen)?;
    let mut ratios: Vec<f64> = reduced_std.iter().zip(&full_std).map(|(r, f)| r / f).collect();
    ratios.sort_by(|a, b| a.total_cmp(b));
    let median_ratio = ratios[ratios.len() / 2];
    Ok(Reduction { history, chosen, count, full_std, reduced_std, median_ratio })
}

/// Checks a Fourier trajectory against its bounds; the message names the coordinate, the
/// quantity, the value, the bound and the time.
pub fn check_trajectory(traj: &FourierTrajectory, bounds: &ExcitationBounds, samples: usize) -> Result<()> {
    if traj.dofs.len() != bounds.position.len() {
        return Err(CalibError::Data(format!(
            "the trajectory has {} coordinates, the bounds {}",
            traj.dofs.len(),
            bounds.position.len()
        )));
    }
    check_bounds(traj, bounds, samples).map_err(|v| {
        let name = POSE_COORDINATES.get(v.dof - 1).copied().unwrap_or("?");
        CalibError::Data(format!(
            "the trajectory leaves its bounds: coordinate {} ({name}) {} {:.6} beyond {:.6} at t = {:.4} s",
            v.dof, v.quantity, v.value, v.limit, v.t_s
        ))
    })
}

/// Checks that the legs stay within their limits along a trajectory (`samples` instants of
/// `period_s`), through the inverse kinematics.
pub fn check_leg_limits(
    model: &Hexapod,
    eval: &dyn Fn(f64) -> TrajectorySample,
    period_s: f64,
    samples: usize,
) -> Result<()> {
    let limits = model.joint_limits();
    for k in 0..samples.max(1) {
        let t = period_s * k as f64 / samples.max(1) as f64;
        let s = eval(t);
        let x: [f64; 6] = std::array::from_fn(|i| s.x[i]);
        let q = model
            .inverse_unchecked(&(pose_from_coordinates(&x) * model.tool))
            .map_err(|e| CalibError::Data(format!("the trajectory leaves the workspace at t = {t:.4} s: {e}")))?;
        for (i, (v, l)) in q.iter().zip(&limits).enumerate() {
            if !l.contains(*v, 0.0) {
                return Err(CalibError::Data(format!(
                    "the trajectory drives leg {} to {:.4} m at t = {t:.4} s, outside its limits [{:.4}, {:.4}] m",
                    i + 1,
                    v,
                    l.lower,
                    l.upper
                )));
            }
        }
    }
    Ok(())
}

/// Column scale factors of a model's regressor over a reference motion that uses every
/// coordinate at half its bounds (so that criteria such as the condition number do not depend
/// on the parameters' units).
pub fn reference_scale(model: &dyn RowModel, bounds: &ExcitationBounds) -> Result<Vec<f64>> {
    let n = model.names().len();
    let k = 240;
    let mut a = DMatrix::zeros(6 * k, n);
    let freq = [1.0, 1.3, 1.7, 2.3, 2.9, 3.1];
    for j in 0..k {
        let t = j as f64 / k as f64 * std::f64::consts::TAU;
        let mut x = [0.0; 6];
        let mut xd = [0.0; 6];
        let mut xdd = [0.0; 6];
        for i in 0..6 {
            let [lo, hi] = bounds.position[i];
            let (c, r) = (0.5 * (lo + hi), 0.25 * (hi - lo));
            let ph = freq[i] * t;
            x[i] = c + r * ph.sin();
            xd[i] = 0.5 * bounds.velocity[i] * ph.cos();
            xdd[i] = -0.5 * bounds.acceleration[i] * ph.sin();
        }
        model.fill(&MotionState::from_coordinates(&x, &xd, &xdd)?, &mut a, 6 * j)?;
    }
    (0..n)
        .map(|j| {
            let v = a.column(j).norm();
            if v > 0.0 {
                Ok(1.0 / v)
            } else {
                Err(CalibError::TooFew(format!("parameter '{}' has no effect on any motion", model.names()[j])))
            }
        })
        .collect()
}

/// Rows of a model at a trajectory sample, column-scaled and divided by the force noise.
fn scaled_rows(model: &dyn RowModel, s: &TrajectorySample, scale: &[f64], sigma_n: f64) -> Result<DMatrix<f64>> {
    let x: [f64; 6] = std::array::from_fn(|i| s.x[i]);
    let xd: [f64; 6] = std::array::from_fn(|i| s.xd[i]);
    let xdd: [f64; 6] = std::array::from_fn(|i| s.xdd[i]);
    let mut rows = DMatrix::zeros(6, scale.len());
    model.fill(&MotionState::from_coordinates(&x, &xd, &xdd)?, &mut rows, 0)?;
    for (j, h) in scale.iter().enumerate() {
        rows.column_mut(j).scale_mut(h / sigma_n);
    }
    Ok(rows)
}

/// Optimises a Fourier excitation for `model` (see [`optimise_excitation`]); `scale` are column
/// scale factors (e.g. [`reference_scale`]), `sigma_n` the force noise of one sample. The result
/// is checked against `hexapod`'s leg limits.
pub fn optimise_trajectory(
    model: &dyn RowModel,
    hexapod: &Hexapod,
    bounds: &ExcitationBounds,
    settings: &ExcitationSettings,
    scale: &[f64],
    sigma_n: f64,
) -> Result<ExcitationResult> {
    if bounds.position.len() != 6 {
        return Err(CalibError::Data("a platform excitation has 6 pose coordinates".into()));
    }
    let reg = |s: &TrajectorySample| scaled_rows(model, s, scale, sigma_n);
    let r = optimise_excitation(bounds, settings, &reg)?;
    check_trajectory(&r.trajectory, bounds, settings.check_samples)?;
    let t = r.trajectory.clone();
    check_leg_limits(hexapod, &|time| t.eval(time), t.period_s(), 500)?;
    Ok(r)
}

/// Smooth point-to-point moves through waypoints and back to the first, each coordinate with
/// the profile `s(tau) = tau - sin(2 pi tau) / (2 pi)` (zero velocity and acceleration at both
/// ends; peak speed `2 d / T`, peak acceleration `2 pi d / T^2`), all coordinates of a move
/// sharing its duration, the shortest that keeps every coordinate within its speed and
/// acceleration bounds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PointToPoint {
    /// The waypoints (pose coordinates); the motion returns to the first.
    pub waypoints: Vec<[f64; 6]>,
    /// Duration of move `k` (from waypoint `k` to `k + 1`, the last back to the first), s.
    pub durations_s: Vec<f64>,
}

impl PointToPoint {
    /// The moves through `waypoints` within `bounds` (positions are checked too).
    pub fn new(waypoints: Vec<[f64; 6]>, bounds: &ExcitationBounds) -> Result<Self> {
        if waypoints.len() < 2 {
            return Err(CalibError::TooFew("a point-to-point motion needs at least two waypoints".into()));
        }
        if bounds.position.len() != 6 {
            return Err(CalibError::Data("point-to-point bounds need 6 coordinates".into()));
        }
        for (k, w) in waypoints.iter().enumerate() {
            for i in 0..6 {
                let [lo, hi] = bounds.position[i];
                if !(w[i] >= lo && w[i] <= hi) {
                    return Err(CalibError::Data(format!(
                        "waypoint {} leaves its bounds: coordinate {} ({}) {:.6} outside [{lo:.6}, {hi:.6}]",
                        k + 1,
                        i + 1,
                        POSE_COORDINATES[i],
                        w[i]
                    )));
                }
            }
        }
        let n = waypoints.len();
        let durations_s = (0..n)
            .map(|k| {
                let (a, b) = (&waypoints[k], &waypoints[(k + 1) % n]);
                (0..6)
                    .map(|i| {
                        let d = (b[i] - a[i]).abs();
                        (2.0 * d / bounds.velocity[i])
                            .max((2.0 * std::f64::consts::PI * d / bounds.acceleration[i]).sqrt())
                    })
                    .fold(1e-3, f64::max)
                    * 1.0001
            })
            .collect();
        Ok(Self { waypoints, durations_s })
    }

    /// Total duration, s.
    pub fn period_s(&self) -> f64 {
        self.durations_s.iter().sum()
    }

    /// Position, velocity and acceleration at `t_s` (periodic).
    pub fn eval(&self, t_s: f64) -> TrajectorySample {
        let period = self.period_s();
        let mut t = t_s.rem_euclid(period);
        let n = self.waypoints.len();
        let mut k = 0;
        while k + 1 < n && t >= self.durations_s[k] {
            t -= self.durations_s[k];
            k += 1;
        }
        let d = self.durations_s[k];
        let tau = (t / d).clamp(0.0, 1.0);
        let two_pi = std::f64::consts::TAU;
        let s = tau - (two_pi * tau).sin() / two_pi;
        let sd = (1.0 - (two_pi * tau).cos()) / d;
        let sdd = two_pi * (two_pi * tau).sin() / (d * d);
        let (a, b) = (&self.waypoints[k], &self.waypoints[(k + 1) % n]);
        TrajectorySample {
            x: (0..6).map(|i| a[i] + (b[i] - a[i]) * s).collect(),
            xd: (0..6).map(|i| (b[i] - a[i]) * sd).collect(),
            xdd: (0..6).map(|i| (b[i] - a[i]) * sdd).collect(),
        }
    }
}
