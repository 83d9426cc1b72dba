//! Observations of deflections and the weighted linear problem they give.
//!
//! # Measurement layout
//! Each observation contributes a block of rows: 6 for a measured pose `(dp, dphi)`, 3 per
//! marker for markers on the tool. Every row is divided by its standard deviation (the inverse
//! noise covariance of independent components), so positions in metres and orientations in
//! radians weigh by their own noise. [`LinearProblem::blocks`] gives each observation's rows,
//! [`LinearProblem::position_triples`] the start of every 3-row position (for errors in mm).

use std::ops::Range;

use ferrocal_robot::stiffness::{ComplianceLayout, Loading, NoiseModel, VjmModel, WrenchLimits};
use nalgebra::{DMatrix, DVector, Vector3, Vector6};
use serde::{Deserialize, Serialize};

use crate::stiffness::error::{Result, StiffnessIdError};

/// What was measured for one observation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Measured {
    /// The tool's displacement: `dt = (dp m, dphi rad)` in the base frame.
    Pose {
        /// The displacement.
        dt: [f64; 6],
        /// Its noise.
        noise: NoiseModel,
    },
    /// Displacements of markers fixed to the tool, base frame (a laser tracker's reflectors:
    /// partial-pose measurement, full pose with three markers).
    Markers {
        /// Marker positions in the tool frame.
        markers_in_tool_m: Vec<[f64; 3]>,
        /// Their measured displacements.
        dp_m: Vec<[f64; 3]>,
        /// Standard deviation of each coordinate of a displacement.
        sigma_m: f64,
    },
}

/// One deflection measurement: configuration, loads, what was seen.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Observation {
    /// Id for messages.
    pub id: String,
    /// Joint values.
    pub q: Vec<f64>,
    /// The loads.
    pub loading: Loading,
    /// The measurement.
    pub measured: Measured,
    /// The noise-free values of the same rows, when known (simulations), for reports.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truth: Option<Vec<f64>>,
}

/// The weighted linear problem `y = A pi + e` over the complete parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearProblem {
    /// The complete parameter layout.
    pub layout: ComplianceLayout,
    /// Whitened regressor (rows x complete parameters).
    pub a: DMatrix<f64>,
    /// Whitened measurements.
    pub y: DVector<f64>,
    /// Whitened noise-free measurements, when every observation has its truth.
    pub y_true: Option<DVector<f64>>,
    /// Standard deviation of every row (to return to SI units).
    pub sigma: Vec<f64>,
    /// Rows of every observation.
    pub blocks: Vec<Range<usize>>,
    /// Observation ids.
    pub ids: Vec<String>,
    /// First row of every 3-row position (tool position or marker).
    pub position_triples: Vec<usize>,
}

fn finite3(v: &[f64; 3]) -> bool {
    v.iter().all(|x| x.is_finite())
}

impl LinearProblem {
    /// The problem of `observations` on `model` (the model's geometry and inertials; its
    /// compliance values are not used). Wrenches are checked against `limits`.
    pub fn from_observations(model: &VjmModel, observations: &[Observation], limits: &WrenchLimits) -> Result<Self> {
        let layout = model.layout()?;
        let p = layout.len();
        let mut rows: Vec<DMatrix<f64>> = Vec::with_capacity(observations.len());
        let mut y = Vec::new();
        let mut y_true = Vec::new();
        let mut all_truth = true;
        let mut sigma = Vec::new();
        let mut blocks = Vec::new();
        let mut triples = Vec::new();
        let bad = |o: &Observation, reason: String| StiffnessIdError::Observation { id: o.id.clone(), reason };
        for o in observations {
            if o.q.len() != model.dof() {
                return Err(bad(o, format!("{} joint values for a {}-joint robot", o.q.len(), model.dof())));
            }
            o.loading.tool_wrench.check(limits).map_err(|e| bad(o, e.to_string()))?;
            let start = y.len();
            let (a, meas, sig): (DMatrix<f64>, Vec<f64>, Vec<f64>) = match &o.measured {
                Measured::Pose { dt, noise } => {
                    noise.validate().map_err(|e| bad(o, e.to_string()))?;
                    if dt.iter().any(|v| !v.is_finite()) {
                        return Err(bad(o, "non-finite measured displacement".into()));
                    }
                    let a = model.observation_matrix(&o.q, &o.loading).map_err(|e| bad(o, e.to_string()))?;
                    triples.push(start);
                    (a, dt.to_vec(), noise.pose_sigmas().to_vec())
                }
                Measured::Markers { markers_in_tool_m, dp_m, sigma_m } => {
                    if markers_in_tool_m.is_empty() || markers_in_tool_m.len() != dp_m.len() {
                        return Err(bad(
                            o,
                            format!("{} markers but {} displacements", markers_in_tool_m.len(), dp_m.len()),
                        ));
                    }
                    if !(sigma_m.is_finite() && *sigma_m > 0.0) {
                        return Err(bad(o, format!("marker noise {sigma_m} m must be positive")));
                    }
                    if !markers_in_tool_m.iter().chain(dp_m).all(finite3) {
                        return Err(bad(o, "non-finite marker position or displacement".into()));
                    }
                    let mk: Vec<Vector3<f64>> = markers_in_tool_m.iter().map(|m| Vector3::from(*m)).collect();
                    let a = model.marker_matrix(&o.q, &o.loading, &mk).map_err(|e| bad(o, e.to_string()))?;
                    for k in 0..mk.len() {
                        triples.push(start + 3 * k);
                    }
                    (a, dp_m.iter().flatten().copied().collect(), vec![*sigma_m; 3 * mk.len()])
                }
            };
            match &o.truth {
                Some(t) if t.len() == meas.len() => y_true.extend(t.iter().zip(&sig).map(|(v, s)| v / s)),
                Some(t) => {
                    return Err(bad(o, format!("{} truth values for {} measured rows", t.len(), meas.len())));
                }
                None => all_truth = false,
            }
            let mut a = a;
            for (r, s) in sig.iter().enumerate() {
                a.row_mut(r).scale_mut(1.0 / s);
            }
            y.extend(meas.iter().zip(&sig).map(|(v, s)| v / s));
            sigma.extend(sig);
            blocks.push(start..y.len());
            rows.push(a);
        }
        let m = y.len();
        let mut a = DMatrix::zeros(m, p);
        for (b, r) in blocks.iter().zip(&rows) {
            a.rows_mut(b.start, b.len()).copy_from(r);
        }
        Ok(Self {
            layout,
            a,
            y: DVector::from_vec(y),
            y_true: (all_truth && !observations.is_empty()).then(|| DVector::from_vec(y_true)),
            sigma,
            blocks,
            ids: observations.iter().map(|o| o.id.clone()).collect(),
            position_triples: triples,
        })
    }

    /// The one-link problem: a spring observed directly, `dt = k w`, one 6-row block per
    /// wrench (measured deflections `dts`, noise `noise`; `truth` the noise-free deflections).
    pub fn direct(
        layout: ComplianceLayout,
        wrenches: &[Vector6<f64>],
        dts: &[Vector6<f64>],
        truth: Option<&[Vector6<f64>]>,
        noise: &NoiseModel,
    ) -> Result<Self> {
        noise.validate()?;
        if layout.spring_names.len() != 1 || layout.n_joints != 0 {
            return Err(StiffnessIdError::Options("a direct problem needs the layout of a single spring".into()));
        }
        if wrenches.len() != dts.len() || truth.is_some_and(|t| t.len() != dts.len()) {
            return Err(StiffnessIdError::Options(format!(
                "{} wrenches for {} deflections",
                wrenches.len(),
                dts.len()
            )));
        }
        let sig = noise.pose_sigmas();
        let m = 6 * wrenches.len();
        let mut a = DMatrix::zeros(m, 36);
        let mut y = DVector::zeros(m);
        let mut yt = DVector::zeros(m);
        let eye = nalgebra::Matrix6::identity();
        for (k, (w, d)) in wrenches.iter().zip(dts).enumerate() {
            if w.iter().chain(d.iter()).any(|v| !v.is_finite()) {
                return Err(StiffnessIdError::Observation {
                    id: format!("load {}", k + 1),
                    reason: "non-finite value".into(),
                });
            }
            let block = ferrocal_robot::stiffness::regressor::spring_block(&eye, w);
            for r in 0..6 {
                for c in 0..36 {
                    a[(6 * k + r, c)] = block[(r, c)] / sig[r];
                }
                y[6 * k + r] = d[r] / sig[r];
                if let Some(t) = truth {
                    yt[6 * k + r] = t[k][r] / sig[r];
                }
            }
        }
        Ok(Self {
            layout,
            a,
            y,
            y_true: truth.map(|_| yt),
            sigma: (0..m).map(|r| sig[r % 6]).collect(),
            blocks: (0..wrenches.len()).map(|k| 6 * k..6 * k + 6).collect(),
            ids: (0..wrenches.len()).map(|k| format!("load {}", k + 1)).collect(),
            position_triples: (0..wrenches.len()).map(|k| 6 * k).collect(),
        })
    }

    /// Number of rows.
    pub fn n_rows(&self) -> usize {
        self.y.len()
    }

    /// The problem restricted to some observations.
    pub fn subset(&self, observations: &[usize]) -> Self {
        let mut rows = Vec::new();
        let mut blocks = Vec::new();
        let mut triples = Vec::new();
        for &k in observations {
            let b = &self.blocks[k];
            let start = rows.len();
            for t in self.position_triples.iter().filter(|t| b.contains(*t)) {
                triples.push(start + (t - b.start));
            }
            rows.extend(b.clone());
            blocks.push(start..rows.len());
        }
        let a = DMatrix::from_fn(rows.len(), self.a.ncols(), |i, j| self.a[(rows[i], j)]);
        let pick = |v: &DVector<f64>| DVector::from_iterator(rows.len(), rows.iter().map(|&r| v[r]));
        Self {
            layout: self.layout.clone(),
            a,
            y: pick(&self.y),
            y_true: self.y_true.as_ref().map(pick),
            sigma: rows.iter().map(|&r| self.sigma[r]).collect(),
            blocks,
            ids: observations.iter().map(|&k| self.ids[k].clone()).collect(),
            position_triples: triples,
        }
    }

    /// Position errors (norms of every 3-row position, metres) of whitened residuals `e`.
    pub fn position_errors_m(&self, e: &DVector<f64>) -> Vec<f64> {
        self.position_triples
            .iter()
            .map(|&t| (0..3).map(|k| (e[t + k] * self.sigma[t + k]).powi(2)).sum::<f64>().sqrt())
            .collect()
    }
}
