//! The source's one-link example (one Orthoglide link, Klimchik et al. 2015): a spring observed
//! directly, `dt = k w`, with 25 um / 0.25 mrad noise and loads up to 10 N / 10 N m.
//!
//! Row `i` of `dt` depends only on row `i` of `k`, so with the wrench matrix `W` (one load per
//! row) the covariance of row `i`'s entries is `sigma_i^2 (W^T W)^-1`. The orthogonal design of
//! [`orthogonal_design`] (each axis loaded by `+-F` in turn, `n` times) gives
//! `W^T W = 2 n F^2 I`: with `F = 10` and `n = 50`, `10^4 I`, i.e. every entry of row `i` has the
//! standard deviation `sigma_i / 100` the source's ratios assume.

use ferrocal_robot::stiffness::{ComplianceLayout, NoiseModel};
use nalgebra::{Matrix6, Vector6};
use serde::{Deserialize, Serialize};

use crate::stiffness::error::Result;
use crate::stiffness::fit::fit;
use crate::stiffness::param::Parameterization;
use crate::stiffness::problem::LinearProblem;

/// The source's parameter-to-noise ratios for the non-zero entries (1-based row and column).
pub const SOURCE_NU: [(&str, f64); 10] = [
    ("k11", 0.18),
    ("k22", 320.0),
    ("k26", 1592.0),
    ("k33", 146.0),
    ("k35", 684.0),
    ("k44", 1504.0),
    ("k53", 68.4),
    ("k55", 436.0),
    ("k62", 159.0),
    ("k66", 1060.0),
];

/// The source's noise: 25 um and 0.25 mrad.
pub const SOURCE_NOISE: NoiseModel = NoiseModel { sigma_position_m: 25e-6, sigma_orientation_rad: 0.25e-3 };

/// The spring's layout (beam along x, the Orthoglide link's template).
pub fn one_link_layout() -> ComplianceLayout {
    ComplianceLayout::single_spring("link", Some(0))
}

/// `repeats` loads of `+force_n` and of `-force_n` along each force axis, and of `+-torque_nm`
/// about each moment axis.
pub fn orthogonal_design(repeats: usize, force_n: f64, torque_nm: f64) -> Vec<Vector6<f64>> {
    let mut out = Vec::with_capacity(12 * repeats);
    for _ in 0..repeats {
        for axis in 0..6 {
            let mag = if axis < 3 { force_n } else { torque_nm };
            for sign in [1.0, -1.0] {
                let mut w = Vector6::zeros();
                w[axis] = sign * mag;
                out.push(w);
            }
        }
    }
    out
}

/// One entry's parameter-to-noise ratio.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EntryNu {
    /// `k<row><col>`, 1-based.
    pub name: String,
    /// The true value.
    pub value: f64,
    /// Its standard deviation in the complete (36-parameter) model.
    pub std: f64,
    /// `|value| / std`.
    pub nu: f64,
}

/// Parameter-to-noise ratios of every entry of `k` for the design `wrenches` and `noise`, from
/// the covariance `(A^T S^-1 A)^-1` of the complete 36-parameter model.
pub fn entry_ratios(k: &Matrix6<f64>, wrenches: &[Vector6<f64>], noise: &NoiseModel) -> Result<Vec<EntryNu>> {
    let layout = one_link_layout();
    let dts: Vec<Vector6<f64>> = wrenches.iter().map(|w| k * w).collect();
    let problem = LinearProblem::direct(layout.clone(), wrenches, &dts, None, noise)?;
    let f = fit(&problem, &Parameterization::complete(&layout), 1e-12)?;
    Ok((0..36)
        .map(|i| {
            let (r, c) = (i / 6, i % 6);
            let v = k[(r, c)];
            EntryNu { name: format!("k{}{}", r + 1, c + 1), value: v, std: f.std[i], nu: v.abs() / f.std[i] }
        })
        .collect())
}

/// The one-link problem of measured deflections.
pub fn one_link_problem(
    wrenches: &[Vector6<f64>],
    measured: &[Vector6<f64>],
    truth: Option<&[Vector6<f64>]>,
    noise: &NoiseModel,
) -> Result<LinearProblem> {
    LinearProblem::direct(one_link_layout(), wrenches, measured, truth, noise)
}
