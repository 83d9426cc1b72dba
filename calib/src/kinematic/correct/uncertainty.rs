//! The landing uncertainty of a corrected command: the calibration's parameter covariance
//! carried to the position its command lands at, plus the scatter the calibrated model leaves
//! unexplained on its own poses.
//!
//! A corrected command `q` solves `p(q; θ̂) = p_wanted`; on the robot it lands at `p(q; θ)`, so
//! its error is `J_θ (θ - θ̂)` to first order, with covariance `J_θ Σ_θ J_θᵀ`. What the model
//! family cannot represent (a link that bends, a gear's eccentricity) is not in `Σ_θ`: its size
//! is the position scatter of the calibration's own poses beyond their measurement noise,
//! `σ_u² = max(0, Σ|e|² / (3n - p) - σ_meas²)` per axis, added as `σ_u² I`.

use nalgebra::{DMatrix, Matrix3, SymmetricEigen, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{CalibError, Result};
use crate::frames::exp6;
use crate::kinematic::{CalibratedModel, KinematicCalibration};
use crate::measurement::PoseMeasurement;
use ferrocal_robot::{Kinematics, Parameterized};

/// The covariance of a calibration's free parameters, by name, and the scatter it leaves
/// unexplained.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Uncertainty {
    /// The free parameters (the kinematic calibration's names: `frame.*` a left increment of
    /// the device frame `Exp(δ) F`, `target_tool.*` a right increment of the tool `T Exp(δ)`,
    /// `offset.q<i>_*` the joint offsets, then model and effect parameters by name).
    pub names: Vec<String>,
    /// Their covariance (SI), row by row.
    pub covariance: Vec<Vec<f64>>,
    /// Per-axis standard deviation of the position error the calibrated model leaves
    /// unexplained on its own poses beyond their measurement noise, m.
    pub unmodelled_sigma_m: f64,
    /// The factor the covariance was multiplied by for the lack of fit its measurements show
    /// beyond their noise (1: none). A joint calibration of robot and camera scales by the
    /// view-level χ² per degree of freedom when it exceeds 1 (`calib::handeye::joint`).
    #[serde(default = "one")]
    pub lack_of_fit_scale: f64,
}

fn one() -> f64 {
    1.0
}

impl Uncertainty {
    /// From a kinematic calibration and the rows it was fitted on.
    pub fn from_kinematic(cal: &KinematicCalibration, rows: &[&PoseMeasurement]) -> Result<Self> {
        let default_sigma_m = cal.sigma_position_m;
        let names: Vec<String> = cal.free.iter().map(|&i| cal.layout.names[i].clone()).collect();
        let c = &cal.covariance;
        let covariance = (0..c.nrows()).map(|i| (0..c.ncols()).map(|j| c[(i, j)]).collect()).collect();
        let (pos, _) = cal.calibrated.errors(rows)?;
        let block = if cal.used_orientation { 6.0 } else { 3.0 };
        let p_pos = names.len() as f64 * 3.0 / block;
        let dof = (3.0 * rows.len() as f64 - p_pos).max(1.0);
        let total = pos.iter().map(|e| e.norm_squared()).sum::<f64>() / dof;
        let noise = rows
            .iter()
            .map(|r| match &r.covariance {
                Some(c) => c.position_m2().trace() / 3.0,
                None => r.sigma_m.unwrap_or(default_sigma_m).powi(2),
            })
            .sum::<f64>()
            / rows.len().max(1) as f64;
        Ok(Self { names, covariance, unmodelled_sigma_m: (total - noise).max(0.0).sqrt(), lack_of_fit_scale: 1.0 })
    }

    /// Multiplies the covariance by `chi2_per_dof` when it exceeds 1 (a lack of fit beyond the
    /// measurements' noise), and records the factor.
    pub fn scale_by_lack_of_fit(&mut self, chi2_per_dof: f64) {
        if chi2_per_dof.is_finite() && chi2_per_dof > 1.0 {
            for row in &mut self.covariance {
                for v in row.iter_mut() {
                    *v *= chi2_per_dof;
                }
            }
            self.lack_of_fit_scale *= chi2_per_dof;
        }
    }

    /// The covariance as a matrix, checked against the names.
    pub fn matrix(&self) -> Result<DMatrix<f64>> {
        let n = self.names.len();
        if self.covariance.len() != n || self.covariance.iter().any(|r| r.len() != n) {
            return Err(CalibError::Data(format!(
                "the calibration's covariance is not {n} x {n} for its {n} named parameters"
            )));
        }
        let m = DMatrix::from_fn(n, n, |i, j| self.covariance[i][j]);
        if m.iter().any(|v| !v.is_finite()) {
            return Err(CalibError::Data("the calibration's covariance holds a value that is not a number".into()));
        }
        Ok(m)
    }

    /// Covariance of the landing position (device frame, m²) of the command `row` (its joints
    /// and conditions) under `cal`.
    pub fn landing_covariance(&self, cal: &CalibratedModel, row: &PoseMeasurement) -> Result<Matrix3<f64>> {
        let sigma = self.matrix()?;
        let n = self.names.len();
        let mut j = DMatrix::zeros(3, n);
        for (k, name) in self.names.iter().enumerate() {
            let h = (sigma[(k, k)].max(0.0).sqrt() * 0.1).max(1e-12);
            let plus = perturbed(cal, name, h)?.predict_row(row)?.translation.vector;
            let minus = perturbed(cal, name, -h)?.predict_row(row)?.translation.vector;
            j.set_column(k, &((plus - minus) / (2.0 * h)));
        }
        let c = &j * sigma * j.transpose();
        let u = self.unmodelled_sigma_m.powi(2);
        Ok(Matrix3::from_fn(|a, b| c[(a, b)] + if a == b { u } else { 0.0 }))
    }
}

/// `cal` with the named parameter moved by `d` (SI; the names of [`Uncertainty::names`]).
pub fn perturbed(cal: &CalibratedModel, name: &str, d: f64) -> Result<CalibratedModel> {
    let mut c = cal.clone();
    const AXES: [&str; 6] = ["x_m", "y_m", "z_m", "rx_rad", "ry_rad", "rz_rad"];
    let six = |axis: &str| {
        AXES.iter().position(|a| *a == axis).map(|k| {
            let mut v = [0.0; 6];
            v[k] = d;
            exp6(&v)
        })
    };
    if let Some(step) = name.strip_prefix("frame.").and_then(six) {
        c.device_frame = step * c.device_frame;
        return Ok(c);
    }
    if let Some(step) = name.strip_prefix("target_tool.").and_then(six) {
        c.tool *= step;
        return Ok(c);
    }
    if let Some(k) = name
        .strip_prefix("offset.q")
        .and_then(|s| s.strip_suffix("_rad").or_else(|| s.strip_suffix("_m")))
        .and_then(|s| s.parse::<usize>().ok())
    {
        if let Some(o) = k.checked_sub(1).and_then(|i| c.joint_offsets.get_mut(i)) {
            *o += d;
            return Ok(c);
        }
    }
    let kinds = c.load_model.joint_kinds();
    for (e, values) in &mut c.effects {
        if let Some(k) = e.parameters(&kinds).iter().position(|(n, _)| n == name) {
            values[k] += d;
            return Ok(c);
        }
    }
    let info = c.model.parameters();
    let Some(i) = info.iter().position(|p| p.name == name) else {
        return Err(CalibError::Data(format!(
            "the calibration's covariance names parameter '{name}', which the model '{}' does not have",
            c.model.name()
        )));
    };
    let mut values = c.model.parameter_values();
    values[i] += d;
    c.model.set_parameter_values(&values)?;
    Ok(c)
}

/// The radius that holds 68.27 % of a zero-mean 3-D Gaussian error with covariance `c` (the
/// one-sigma probability of one dimension): `1.878 σ` for an isotropic `σ² I`, `σ` when one
/// axis alone carries `σ²`. Integrated over 800 directions (a Fibonacci sphere), solved by
/// bisection.
pub fn radius_68(c: &Matrix3<f64>) -> f64 {
    let e = SymmetricEigen::new(0.5 * (c + c.transpose()));
    // Sorted, so that the quadrature does not depend on the order the decomposition returns.
    let mut sorted: Vec<f64> = e.eigenvalues.iter().map(|v| v.max(0.0).sqrt()).collect();
    sorted.sort_by(f64::total_cmp);
    let s = Vector3::new(sorted[0], sorted[1], sorted[2]);
    let largest = s.max();
    if largest <= 0.0 || !largest.is_finite() {
        return 0.0;
    }
    const N: usize = 800;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let stretch: Vec<f64> = (0..N)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / N as f64;
            let r = (1.0 - z * z).sqrt();
            let u = Vector3::new(r * (golden * i as f64).cos(), r * (golden * i as f64).sin(), z);
            u.component_mul(&s).norm()
        })
        .collect();
    let p = |radius: f64| stretch.iter().map(|l| chi3_cdf(radius / l.max(1e-300))).sum::<f64>() / N as f64;
    let (mut lo, mut hi) = (0.0, 4.0 * largest);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if p(mid) < 0.682_689_5 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// `P(|z| <= s)` for `z` a standard normal 3-vector (the chi distribution with 3 degrees of
/// freedom).
fn chi3_cdf(s: f64) -> f64 {
    if s > 40.0 {
        return 1.0;
    }
    erf(s / std::f64::consts::SQRT_2) - (2.0 / std::f64::consts::PI).sqrt() * s * (-0.5 * s * s).exp()
}

/// The error function (Abramowitz and Stegun 7.1.26, absolute error below 1.5e-7).
fn erf(x: f64) -> f64 {
    let sign = x.signum();
    let x = x.abs();
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let poly =
        t * (0.254_829_592 + t * (-0.284_496_736 + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    sign * (1.0 - poly * (-x * x).exp())
}
