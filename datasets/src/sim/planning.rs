//! Simulated calibrations of a measurement plan: the simulator behind the Monte Carlo check of
//! `ferrocal plan` (true robots with geometric errors measured by the plan's device) and random
//! pose subsets to compare a selection with.

use std::collections::BTreeMap;

use ferrocal_calib::design::criteria::Criterion;
use ferrocal_calib::design::flow::PlanDesign;
use ferrocal_calib::design::kinematic::{row_sigma_m, CalibrationSimulator, SimulatedCell};
use ferrocal_calib::{CalibError, PoseMeasurement};
use ferrocal_robot::{Kinematics, Parameterized, RobotModel};
use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{Conditions, GeometricErrors, TrueRobot};

/// Simulated campaigns with the datasets crate's true robot: geometric errors drawn per run, the
/// measured point in the device frame with Gaussian noise of the device's covariance at the pose.
pub struct DatasetsSimulator {
    /// The a-priori model.
    pub nominal: RobotModel,
    /// Geometric errors of the true robots.
    pub errors: GeometricErrors,
    /// `T_device_base`.
    pub t_device_base: Isometry3<f64>,
    /// Measured point in the tool frame.
    pub point_in_tool_m: Vector3<f64>,
    /// Seed.
    pub seed: u64,
}

impl CalibrationSimulator for DatasetsSimulator {
    fn simulate(
        &mut self,
        run: usize,
        train: &[Vec<f64>],
        covariances: &[Matrix3<f64>],
        validation: &[Vec<f64>],
    ) -> ferrocal_calib::Result<SimulatedCell> {
        let data = |e: String| CalibError::Data(e);
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed.wrapping_mul(1_000_003).wrapping_add(run as u64));
        let truth = TrueRobot::new(self.nominal.clone(), &self.errors, vec![], 0.0, &mut rng)
            .map_err(|e| data(e.to_string()))?;
        let cond = Conditions { temp_c: 20.0, dir: vec![0; self.nominal.dof()], ..Default::default() };
        let position = |q: &[f64]| -> ferrocal_calib::Result<Vector3<f64>> {
            let t = truth.tool_pose(q, &cond).map_err(|e| data(e.to_string()))?;
            Ok((self.t_device_base * t * Point3::from(self.point_in_tool_m)).coords)
        };
        let mut rows = Vec::with_capacity(train.len());
        for (k, (q, c)) in train.iter().zip(covariances).enumerate() {
            let l = c.cholesky().ok_or_else(|| data(format!("pose {}: covariance not positive definite", k + 1)))?.l();
            let z = Vector3::new(gauss(&mut rng), gauss(&mut rng), gauss(&mut rng));
            let mut row = PoseMeasurement::new(format!("{}", k + 1), q.clone(), position(q)? + l * z);
            row.sigma_m = Some(row_sigma_m(c));
            rows.push(row);
        }
        let truth_map: BTreeMap<String, f64> =
            truth.truth.parameters().into_iter().map(|p| (p.name, p.value)).collect();
        let validation_true_m = validation.iter().map(|q| position(q)).collect::<ferrocal_calib::Result<_>>()?;
        Ok(SimulatedCell { rows, truth: truth_map, validation_true_m })
    }
}

/// A standard normal sample (Box-Muller).
fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>();
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Best and median criterion value of `n` random subsets of `count` candidates of the design's
/// pool, and how many of them were singular (`None` when `n` is 0 or `count` exceeds the pool).
pub fn random_subsets(
    design: &PlanDesign,
    count: usize,
    n: usize,
    criterion: Criterion,
    seed: u64,
) -> Option<(f64, f64, usize)> {
    let pool = &design.kinematic.pool;
    if n == 0 || count > pool.len() {
        return None;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut idx: Vec<usize> = (0..pool.len()).collect();
    let mut losses = Vec::with_capacity(n);
    for _ in 0..n {
        // Partial Fisher-Yates shuffle.
        for i in 0..count {
            let j = rng.random_range(i..idx.len());
            idx.swap(i, j);
        }
        losses.push(pool.loss(&idx[..count], criterion));
    }
    let singular = losses.iter().filter(|l| !l.is_finite()).count();
    losses.sort_by(|a, b| a.total_cmp(b));
    let best = criterion.value(losses[0]);
    let median = criterion.value(losses[losses.len() / 2]);
    Some((best, median, singular))
}
