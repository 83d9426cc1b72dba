//! The force-sensing end-effector's identification models 0 to 9 (Friedrich & Ihlenfeldt 2021)
//! as linear regressors `f_q = A u`.
//!
//! Every model predicts the six sensor forces of one sample as
//! `f_q = J_P^T (f_Dyn - f_G) + f_q0 + f_K(x)` (see [`ferrocal_robot::dynamics`]), with the
//! parameter blocks, in this order:
//!
//! | block | columns | parameters |
//! | --- | --- | --- |
//! | rigid body | `J_P^T Y` | `m, m c` (quasi-static), plus `I_xx .. I_zz` about the platform origin (dynamic) |
//! | offsets | `I_6` | `f_q0` (6) |
//! | K1 | `e_i x`, `e_i y` | `K_1` (6 x 2, sensor space, on the platform position `x, y`): 12 |
//! | K2 | `J_P^T [k0 (x, y, 0); k1 z x (x, y, 0)]` | `k0, k1` |
//! | K3 | `e_i (R^T g)_j` | `K_3` (6 x 3, sensor space, on gravity in the platform frame): 18 |
//! | K4 | `J_P^T e_r phi_c` | `K_4` (4 x 2: `f_x, f_y, m_x, m_y` from `phi_x, phi_y`): 8 |
//! | K5 | `J_P^T [k2 z x phi; k3 (phi_x, phi_y, 0)]` | `k2, k3` |
//!
//! `x, y` are the platform's position relative to the reference (the hexapod's home), `phi` the
//! Gibbs vector of its orientation. The models:
//!
//! | model | blocks | parameters (source) |
//! | --- | --- | --- |
//! | 0 | rigid (4) + offsets | 10 (10) |
//! | 1 | 0 + K1 | 22 (22) |
//! | 2 | 0 + K2 | 12 (12) |
//! | 3 | 1 + K3 | 40 (not identifiable) |
//! | 4 | 1 + K4 | 30 (30) |
//! | 5 | 2 + K5 | 14 (14) |
//! | 6 | rigid (10) + offsets | 16 (16) |
//! | 7 | 6 + K2 | 18 (18) |
//! | 8 | 6 + K1 + K4 | 36 (36) |
//! | 9 | 6 + K2 + K5 | 20 (20) |
//!
//! Our readings where the source's summary leaves freedom: `K_4` acts in wrench space on the two
//! tilt components of `phi` (which gives the source's 30 parameters of model 4); model 3's
//! orientation term is built on `R^T g` in sensor space, which contains the gravity columns, so
//! `m` and `m c` cannot be told from it: rank 36 of 40, whatever the data.

use nalgebra::{DMatrix, Matrix6, Vector3, Vector6};
use serde::{Deserialize, Serialize};

use ferrocal_robot::dynamics::{
    body_regressor, gibbs_vector, MotionState, RigidBody, SensorFrame, GRAVITY_M_S2, RIGID_BODY_NAMES,
};

use crate::error::{CalibError, Result};

/// The parameter blocks of a model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Terms {
    /// The six inertia parameters (dynamic models).
    pub inertia: bool,
    /// `K_1` (12).
    pub k1: bool,
    /// `k0, k1`.
    pub k2: bool,
    /// `K_3` on `R^T g` (18).
    pub k3: bool,
    /// `K_4` (8).
    pub k4: bool,
    /// `k2, k3`.
    pub k5: bool,
}

/// One of the identification models 0 to 9.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct SensorModel(u8);

impl SensorModel {
    /// Every model, 0 to 9.
    pub const ALL: [SensorModel; 10] = [
        SensorModel(0),
        SensorModel(1),
        SensorModel(2),
        SensorModel(3),
        SensorModel(4),
        SensorModel(5),
        SensorModel(6),
        SensorModel(7),
        SensorModel(8),
        SensorModel(9),
    ];

    /// Model `id` (0 to 9).
    pub fn new(id: u8) -> Result<Self> {
        if id <= 9 {
            Ok(Self(id))
        } else {
            Err(CalibError::Data(format!(
                "there is no model {id}: the force-sensor models are 0 to 5 (quasi-static) and 6 to 9 (dynamic)"
            )))
        }
    }

    /// The model's number.
    pub fn id(self) -> u8 {
        self.0
    }

    /// Whether the model has the inertia parameters (models 6 to 9).
    pub fn is_dynamic(self) -> bool {
        self.0 >= 6
    }

    /// The parameter blocks.
    pub fn terms(self) -> Terms {
        let t = Terms::default();
        match self.0 {
            0 => t,
            1 => Terms { k1: true, ..t },
            2 => Terms { k2: true, ..t },
            3 => Terms { k1: true, k3: true, ..t },
            4 => Terms { k1: true, k4: true, ..t },
            5 => Terms { k2: true, k5: true, ..t },
            6 => Terms { inertia: true, ..t },
            7 => Terms { inertia: true, k2: true, ..t },
            8 => Terms { inertia: true, k1: true, k4: true, ..t },
            _ => Terms { inertia: true, k2: true, k5: true, ..t },
        }
    }

    /// The number of parameters the source gives (`None` for model 3, "not identifiable").
    pub fn source_n_params(self) -> Option<usize> {
        [Some(10), Some(22), Some(12), None, Some(30), Some(14), Some(16), Some(18), Some(36), Some(20)]
            [self.0 as usize]
    }

    /// A short description.
    pub fn description(self) -> &'static str {
        [
            "quasi-static: mass, centre of gravity, offsets",
            "quasi-static: model 0 + K1 (position deformation, 12)",
            "quasi-static: model 0 + K2 (position deformation k0, k1)",
            "quasi-static: model 1 + K3 on R^T g (not identifiable)",
            "quasi-static: model 1 + K4 (orientation deformation, 8)",
            "quasi-static: model 2 + K5 (orientation deformation k2, k3)",
            "dynamic: model 0 + inertia",
            "dynamic: model 2 + inertia",
            "dynamic: model 4 + inertia",
            "dynamic: model 5 + inertia",
        ][self.0 as usize]
    }

    /// Parameter names in column order.
    pub fn names(self) -> Vec<String> {
        let t = self.terms();
        let mut out: Vec<String> =
            RIGID_BODY_NAMES[..if t.inertia { 10 } else { 4 }].iter().map(|s| s.to_string()).collect();
        out.extend((1..=6).map(|i| format!("fq0_{i}_N")));
        if t.k1 {
            for i in 1..=6 {
                out.push(format!("K1_{i}x_N_m"));
                out.push(format!("K1_{i}y_N_m"));
            }
        }
        if t.k2 {
            out.push("k0_N_m".into());
            out.push("k1_Nm_m".into());
        }
        if t.k3 {
            for i in 1..=6 {
                for c in ["gx", "gy", "gz"] {
                    out.push(format!("K3_{i}{c}_kg"));
                }
            }
        }
        if t.k4 {
            for r in ["fx_N", "fy_N", "mx_Nm", "my_Nm"] {
                for c in ["phix", "phiy"] {
                    let (q, unit) = r.split_once('_').unwrap_or((r, ""));
                    out.push(format!("K4_{q}_{c}_{unit}"));
                }
            }
        }
        if t.k5 {
            out.push("k2_N".into());
            out.push("k3_Nm".into());
        }
        out
    }

    /// Number of parameters.
    pub fn n_params(self) -> usize {
        let t = self.terms();
        4 + 6
            + if t.inertia { 6 } else { 0 }
            + if t.k1 { 12 } else { 0 }
            + if t.k2 { 2 } else { 0 }
            + if t.k3 { 18 } else { 0 }
            + if t.k4 { 8 } else { 0 }
            + if t.k5 { 2 } else { 0 }
    }
}

impl std::fmt::Display for SensorModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "model {}", self.0)
    }
}

impl std::str::FromStr for SensorModel {
    type Err = CalibError;
    fn from_str(s: &str) -> Result<Self> {
        let id: u8 = s
            .trim()
            .trim_start_matches("model")
            .trim()
            .parse()
            .map_err(|_| CalibError::Data(format!("'{s}' is not a model number (0 to 9)")))?;
        SensorModel::new(id)
    }
}

/// The true values behind a simulated data set, for comparison with an identification.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SensorTruth {
    /// The body the sensors carry (end-effector and payload), platform frame.
    pub body: RigidBody,
    /// Sensor offsets, N.
    pub offsets_n: [f64; 6],
    /// Deformation coefficients `k0` (N/m), `k1` (N m/m), `k2` (N), `k3` (N m); zeros when the
    /// data have no deformation.
    pub deformation: [f64; 4],
}

/// Builds the models' regressor rows for one sensor framework.
#[derive(Clone, Debug, PartialEq)]
pub struct SensorRegressor {
    frame: SensorFrame,
    force_map: Matrix6<f64>,
    reference_xy_m: [f64; 2],
    gravity_m_s2: Vector3<f64>,
}

impl SensorRegressor {
    /// The regressor of `frame`, with deformation positions measured from `reference_xy_m` (the
    /// hexapod's home position, base frame).
    pub fn new(frame: SensorFrame, reference_xy_m: [f64; 2]) -> Result<Self> {
        let force_map = frame.force_map()?;
        Ok(Self { frame, force_map, reference_xy_m, gravity_m_s2: GRAVITY_M_S2 })
    }

    /// The sensor framework.
    pub fn frame(&self) -> &SensorFrame {
        &self.frame
    }

    /// `J_P^T`.
    pub fn force_map(&self) -> &Matrix6<f64> {
        &self.force_map
    }

    /// Writes the six rows of one state into `out` from row `row0`.
    pub fn fill(&self, model: SensorModel, state: &MotionState, out: &mut DMatrix<f64>, row0: usize) -> Result<()> {
        let n = model.n_params();
        if out.ncols() != n || out.nrows() < row0 + 6 {
            return Err(CalibError::Data(format!(
                "a {}x{} buffer cannot take rows {}..{} of {model} ({n} columns)",
                out.nrows(),
                out.ncols(),
                row0 + 1,
                row0 + 6
            )));
        }
        let t = model.terms();
        let s = if t.inertia { *state } else { MotionState::at_rest(state.pose) };
        let body = s.body(&self.gravity_m_s2);
        let y = body_regressor(&body);
        let jt = &self.force_map;
        let n_rb = if t.inertia { 10 } else { 4 };
        let yr = jt * y.columns(0, n_rb);
        for r in 0..6 {
            for c in 0..n_rb {
                out[(row0 + r, c)] = yr[(r, c)];
            }
            for c in 0..6 {
                out[(row0 + r, n_rb + c)] = if r == c { 1.0 } else { 0.0 };
            }
        }
        let mut col = n_rb + 6;
        let p = state.pose.translation.vector;
        let (x, yy) = (p.x - self.reference_xy_m[0], p.y - self.reference_xy_m[1]);
        let mut put = |v: &Vector6<f64>, col: &mut usize| {
            for r in 0..6 {
                out[(row0 + r, *col)] = v[r];
            }
            *col += 1;
        };
        if t.k1 {
            for i in 0..6 {
                let mut ex = Vector6::zeros();
                ex[i] = x;
                put(&ex, &mut col);
                let mut ey = Vector6::zeros();
                ey[i] = yy;
                put(&ey, &mut col);
            }
        }
        if t.k2 {
            put(&(jt * Vector6::new(x, yy, 0.0, 0.0, 0.0, 0.0)), &mut col);
            put(&(jt * Vector6::new(0.0, 0.0, 0.0, -yy, x, 0.0)), &mut col);
        }
        if t.k3 {
            for i in 0..6 {
                for j in 0..3 {
                    let mut e = Vector6::zeros();
                    e[i] = body.gravity_m_s2[j];
                    put(&e, &mut col);
                }
            }
        }
        let phi = if t.k4 || t.k5 {
            gibbs_vector(&state.pose.rotation).ok_or_else(|| {
                CalibError::Data("the platform is turned by half a turn: its Gibbs vector is infinite".into())
            })?
        } else {
            Vector3::zeros()
        };
        if t.k4 {
            for r in [0usize, 1, 3, 4] {
                for c in 0..2 {
                    let mut w = Vector6::zeros();
                    w[r] = phi[c];
                    put(&(jt * w), &mut col);
                }
            }
        }
        if t.k5 {
            put(&(jt * Vector6::new(-phi.y, phi.x, 0.0, 0.0, 0.0, 0.0)), &mut col);
            put(&(jt * Vector6::new(0.0, 0.0, 0.0, phi.x, phi.y, 0.0)), &mut col);
        }
        debug_assert_eq!(col, n);
        Ok(())
    }

    /// The six rows of one state.
    pub fn rows(&self, model: SensorModel, state: &MotionState) -> Result<DMatrix<f64>> {
        let mut out = DMatrix::zeros(6, model.n_params());
        self.fill(model, state, &mut out, 0)?;
        Ok(out)
    }

    /// The stacked regressor of many states (six rows each, in state order).
    pub fn regressor(&self, model: SensorModel, states: &[MotionState]) -> Result<DMatrix<f64>> {
        let mut out = DMatrix::zeros(6 * states.len(), model.n_params());
        for (k, s) in states.iter().enumerate() {
            self.fill(model, s, &mut out, 6 * k)?;
        }
        Ok(out)
    }

    /// The values a model should identify from data simulated with `truth` (`None` where the
    /// model has no true value: model 3's gravity terms, or a deformation block that cannot
    /// represent the simulated deformation, reported as the closest equivalent otherwise).
    pub fn true_values(&self, model: SensorModel, truth: &SensorTruth) -> Vec<Option<f64>> {
        let t = model.terms();
        let u = truth.body.parameters();
        let mut out: Vec<Option<f64>> = u[..if t.inertia { 10 } else { 4 }].iter().map(|v| Some(*v)).collect();
        out.extend(truth.offsets_n.iter().map(|v| Some(*v)));
        let [k0, k1, k2, k3] = truth.deformation;
        if t.k1 {
            let cx = self.force_map * Vector6::new(k0, 0.0, 0.0, 0.0, k1, 0.0);
            let cy = self.force_map * Vector6::new(0.0, k0, 0.0, -k1, 0.0, 0.0);
            for i in 0..6 {
                out.push(Some(cx[i]));
                out.push(Some(cy[i]));
            }
        }
        if t.k2 {
            out.push(Some(k0));
            out.push(Some(k1));
        }
        if t.k3 {
            out.extend(std::iter::repeat_n(None, 18));
        }
        if t.k4 {
            // f_x = -k2 phi_y, f_y = k2 phi_x, m_x = k3 phi_x, m_y = k3 phi_y.
            out.extend([0.0, -k2, k2, 0.0, k3, 0.0, 0.0, k3].map(Some));
        }
        if t.k5 {
            out.push(Some(k2));
            out.push(Some(k3));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parameter_counts_match_the_source() {
        for m in SensorModel::ALL {
            assert_eq!(m.names().len(), m.n_params(), "{m}");
            if let Some(n) = m.source_n_params() {
                assert_eq!(m.n_params(), n, "{m}");
            }
        }
        assert_eq!(SensorModel::new(3).unwrap().n_params(), 40);
        assert!(SensorModel::new(10).is_err());
        assert_eq!("model 7".parse::<SensorModel>().unwrap().id(), 7);
    }
}
