//! The identification equation: the tool's deflection is linear in the compliance entries,
//! `dt_j = A(q_j, w_j) pi + eps_j`.
//!
//! The complete parameter vector `pi` ([`ComplianceLayout`]) holds, in this order:
//! 1. the compliance of every actuated joint (`joint<j>.k`);
//! 2. all 36 entries of every spring's compliance matrix, row by row (`link<i>.k<r><c>`, 1-based
//!    row and column as in the source: `k26` couples force y and rotation z);
//! 3. with a gravity compensator on joint `j`: `joint<j>.gc_kks` (`k_j K_s`) and
//!    `joint<j>.gc_kks_s0` (`k_j K_s s0`).
//!
//! For a 6-DOF arm with a spring on each of its 7 links that is `6 + 7 * 36 = 258` entries, the
//! source's complete model. Column of joint `j`: `J_j tau_j`; of spring entry `(r, c)`:
//! `J_s[:, r] v_s[c]` with `v_s` the wrench the spring transmits; of the compensator terms:
//! `J_j (-s s')` and `J_j s'`.
//!
//! Measurements: the whole tool pose (6 rows) or the positions of markers fixed to the tool (3
//! rows each, `dp_k = dp - [r_k]x dphi`); rows are weighted by the inverse noise covariance
//! ([`NoiseModel`]) so that millimetres and milliradians never mix unweighted.

use nalgebra::{DMatrix, Vector3};
use serde::{Deserialize, Serialize};

use crate::geometry::skew;
use crate::kinematics::JointKind;
use crate::stiffness::error::{Result, StiffnessError};
use crate::stiffness::model::{Aggregation, Loading, VjmJacobians, VjmModel};

/// What one complete-model parameter is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ParamKind {
    /// Compliance of an actuated joint (0-based).
    Joint {
        /// Joint index.
        joint: usize,
    },
    /// An entry of a spring's compliance matrix (0-based spring, row, column).
    Spring {
        /// Spring index.
        spring: usize,
        /// Row (0..3 translation, 3..6 rotation).
        row: usize,
        /// Column (0..3 force, 3..6 moment).
        col: usize,
    },
    /// `k_j K_s`: the compensator's stiffness times its joint's compliance.
    CompensatorStiffness,
    /// `k_j K_s s0`: the same times the spring's free length.
    CompensatorPreload,
}

/// One complete-model parameter.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ComplianceParam {
    /// Name (`joint2.k`, `link3.k26`, `joint2.gc_kks`).
    pub name: String,
    /// What it is.
    pub kind: ParamKind,
    /// Its unit.
    pub unit: String,
}

/// The layout of a VJM model's complete compliance parameter vector (names, kinds, springs,
/// aggregations): the structure the reduction needs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ComplianceLayout {
    /// Every parameter, in vector order.
    pub params: Vec<ComplianceParam>,
    /// Number of actuated joints.
    pub n_joints: usize,
    /// Spring names.
    pub spring_names: Vec<String>,
    /// Beam axis of every spring (its sparsity template).
    pub beam_axes: Vec<Option<usize>>,
    /// Joint compliances indistinguishable from a spring entry.
    pub aggregations: Vec<Aggregation>,
}

fn entry_unit(r: usize, c: usize) -> &'static str {
    match (r < 3, c < 3) {
        (true, true) => "m/N",
        (false, false) => "rad/(N m)",
        (true, false) => "m/(N m)",
        (false, true) => "rad/N",
    }
}

impl ComplianceLayout {
    fn springs_part(names: &[String], first_spring: usize, params: &mut Vec<ComplianceParam>) {
        for (k, name) in names.iter().enumerate() {
            for r in 0..6 {
                for c in 0..6 {
                    params.push(ComplianceParam {
                        name: format!("{name}.k{}{}", r + 1, c + 1),
                        kind: ParamKind::Spring { spring: first_spring + k, row: r, col: c },
                        unit: entry_unit(r, c).to_string(),
                    });
                }
            }
        }
    }

    /// The layout of a single spring observed directly (the one-link experiment: the measured
    /// deflection is the spring's own, `dt = k w`).
    pub fn single_spring(name: &str, beam_axis: Option<usize>) -> Self {
        let mut params = Vec::new();
        Self::springs_part(&[name.to_string()], 0, &mut params);
        Self {
            params,
            n_joints: 0,
            spring_names: vec![name.to_string()],
            beam_axes: vec![beam_axis],
            aggregations: Vec::new(),
        }
    }

    /// Number of parameters.
    pub fn len(&self) -> usize {
        self.params.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.params.is_empty()
    }

    /// Parameter names.
    pub fn names(&self) -> Vec<String> {
        self.params.iter().map(|p| p.name.clone()).collect()
    }

    /// Index of joint `j`'s compliance (0-based joint).
    pub fn joint_index(&self, j: usize) -> Option<usize> {
        self.params.iter().position(|p| p.kind == ParamKind::Joint { joint: j })
    }

    /// Index of entry `(row, col)` of spring `s` (all 0-based).
    pub fn spring_index(&self, s: usize, row: usize, col: usize) -> Option<usize> {
        self.params.iter().position(|p| p.kind == ParamKind::Spring { spring: s, row, col })
    }

    /// Index of a parameter by name.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.params.iter().position(|p| p.name == name)
    }
}

/// Standard deviations of one measurement (per axis), whose inverse squares weight its rows.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct NoiseModel {
    /// Position noise.
    pub sigma_position_m: f64,
    /// Orientation noise.
    pub sigma_orientation_rad: f64,
}

impl NoiseModel {
    /// Checks that both are finite and positive.
    pub fn validate(&self) -> Result<()> {
        if !(self.sigma_position_m.is_finite()
            && self.sigma_position_m > 0.0
            && self.sigma_orientation_rad.is_finite()
            && self.sigma_orientation_rad > 0.0)
        {
            return Err(StiffnessError::Structure(format!(
                "noise standard deviations must be positive: {} m, {} rad",
                self.sigma_position_m, self.sigma_orientation_rad
            )));
        }
        Ok(())
    }

    /// Standard deviation of each of the 6 pose rows.
    pub fn pose_sigmas(&self) -> [f64; 6] {
        let (p, r) = (self.sigma_position_m, self.sigma_orientation_rad);
        [p, p, p, r, r, r]
    }
}

/// The regressor of one spring observed through the 6 x 6 Jacobian `j_s` with transmitted
/// wrench `v` (its frame): column `6 r + c` is `J_s[:, r] v[c]`. With `j_s = I` and `v = w` this
/// is the one-link equation `dt_i = sum_j k_ij w_j`.
pub fn spring_block(j_s: &nalgebra::Matrix6<f64>, v: &nalgebra::Vector6<f64>) -> DMatrix<f64> {
    let mut a = DMatrix::zeros(6, 36);
    for r in 0..6 {
        for c in 0..6 {
            if v[c] != 0.0 {
                a.fixed_view_mut::<6, 1>(0, 6 * r + c).copy_from(&(j_s.column(r) * v[c]));
            }
        }
    }
    a
}

impl VjmModel {
    /// The complete parameter layout of this model.
    pub fn layout(&self) -> Result<ComplianceLayout> {
        let mut params = Vec::new();
        for (j, joint) in self.chain.joints.iter().enumerate() {
            params.push(ComplianceParam {
                name: format!("joint{}.k", j + 1),
                kind: ParamKind::Joint { joint: j },
                unit: match joint.kind {
                    JointKind::Revolute => "rad/(N m)".into(),
                    JointKind::Prismatic => "m/N".into(),
                },
            });
        }
        let names: Vec<String> = self.springs.iter().map(|s| s.name.clone()).collect();
        ComplianceLayout::springs_part(&names, 0, &mut params);
        if let Some(c) = &self.compensator {
            params.push(ComplianceParam {
                name: format!("joint{}.gc_kks", c.joint),
                kind: ParamKind::CompensatorStiffness,
                unit: "rad/m^2".into(),
            });
            params.push(ComplianceParam {
                name: format!("joint{}.gc_kks_s0", c.joint),
                kind: ParamKind::CompensatorPreload,
                unit: "rad/m".into(),
            });
        }
        Ok(ComplianceLayout {
            params,
            n_joints: self.dof(),
            spring_names: names,
            beam_axes: self.springs.iter().map(|s| s.beam_axis).collect(),
            aggregations: self.aggregations()?,
        })
    }

    /// The model's own values of the complete parameters.
    pub fn complete_values(&self) -> Vec<f64> {
        let mut v = self.joint_compliance.clone();
        for s in &self.springs {
            for r in 0..6 {
                for c in 0..6 {
                    v.push(s.compliance[(r, c)]);
                }
            }
        }
        if let Some(c) = &self.compensator {
            let k = self.joint_compliance[c.joint - 1];
            v.push(k * c.stiffness_n_per_m);
            v.push(k * c.stiffness_n_per_m * c.free_length_m);
        }
        v
    }

    /// The observation matrix `A(q, loading)` (6 x layout length): the tool's `(dp, dphi)` in
    /// the base frame is `A pi`.
    pub fn observation_matrix(&self, q: &[f64], loading: &Loading) -> Result<DMatrix<f64>> {
        let frames = self.chain.frames(q)?;
        let jac = self.jacobians_at(&frames, None);
        let tr = self.transmitted_at(&frames, loading)?;
        Ok(self.assemble(&jac, &tr))
    }

    fn assemble(&self, jac: &VjmJacobians, tr: &crate::stiffness::model::Transmitted) -> DMatrix<f64> {
        let n = self.dof();
        let n_s = self.springs.len();
        let n_c = if self.compensator.is_some() { 2 } else { 0 };
        let mut a = DMatrix::zeros(6, n + 36 * n_s + n_c);
        for j in 0..n {
            a.set_column(j, &(jac.joints.column(j) * tr.joints[j]));
        }
        for (s, (js, v)) in jac.springs.iter().zip(&tr.springs).enumerate() {
            let block = spring_block(js, v);
            a.view_mut((0, n + 36 * s), (6, 36)).copy_from(&block);
        }
        if let (Some(c), Some(basis)) = (&self.compensator, tr.compensator) {
            let col = jac.joints.column(c.joint - 1).clone_owned();
            a.set_column(n + 36 * n_s, &(&col * basis[0]));
            a.set_column(n + 36 * n_s + 1, &(&col * basis[1]));
        }
        a
    }

    /// Rows for markers fixed to the tool (`markers_in_tool_m`, tool frame): 3 per marker, the
    /// base-frame displacement of each marker, `A_k = [I, -[r_k]x] A` with `r_k` the marker's
    /// offset from the tool point.
    pub fn marker_matrix(
        &self,
        q: &[f64],
        loading: &Loading,
        markers_in_tool_m: &[Vector3<f64>],
    ) -> Result<DMatrix<f64>> {
        let a = self.observation_matrix(q, loading)?;
        let tool = self.chain.frames(q)?.tool;
        Ok(marker_rows(&a, &tool.rotation, markers_in_tool_m))
    }
}

/// Marker rows from 6-row twist rows `a` (see [`VjmModel::marker_matrix`]).
pub fn marker_rows(
    a: &DMatrix<f64>,
    tool_rotation: &nalgebra::UnitQuaternion<f64>,
    markers_in_tool_m: &[Vector3<f64>],
) -> DMatrix<f64> {
    let p = a.ncols();
    let mut out = DMatrix::zeros(3 * markers_in_tool_m.len(), p);
    let top = a.rows(0, 3);
    let bottom = a.rows(3, 3);
    for (k, m) in markers_in_tool_m.iter().enumerate() {
        let r = tool_rotation * m;
        let rows = top - skew(&r) * bottom;
        out.rows_mut(3 * k, 3).copy_from(&rows);
    }
    out
}
