//! The 6-DOF F1 Gantry-Tau: rotating plate on cart 2, rotating and tilting plate on cart 3.

use nalgebra::{DMatrix, Vector3};
use serde::{Deserialize, Serialize};

use super::gantry_tau6::{check_guideways, check_links, gantry_legs, guideway_params, link_params, set_link_params};
use super::legs::{cart_root, Carriage, Mechanism, Stage};
use super::{check_direction, check_vector, vec_names, Branch, Guideway, Link, ParallelRobot, SolverOptions};
use crate::error::{Result, RobotError};
use crate::geometry::{wrap_angle, Pose};
use crate::kinematics::{check_len, JointKind, JointLimits, Kinematics, Mobility};
use crate::params::{check_values, ParamInfo, Parameterized, Unit};

/// A revolute stage of an F1 carriage: turns by `q` about `axis` through `point_m`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RotaryStage {
    /// A point on the axis, in the previous frame (the cart frame, with base axes and its origin
    /// at the cart's position `q v`, for the first plate; the rotating plate's frame for the
    /// tilting plate).
    pub point_m: Vector3<f64>,
    /// Axis direction in the previous frame (normalised when used).
    pub axis: Vector3<f64>,
    /// Limits, radians.
    pub limits: JointLimits,
}

/// The F1-type 6-DOF Gantry-Tau (mobility [`Mobility::Full6`]).
///
/// Actuators, in order: `cart1`, `cart2`, `cart3` (metres) and `rot2` (the plate on cart 2),
/// `rot3` (the plate on cart 3), `tilt3` (the plate carried by `rot3`), radians. Arm 1 is a cart
/// with one link; arm 2 the serial chain `H_2(q_2, q_4)` with two links; arm 3 `H_3(q_3, q_5, q_6)`
/// with three. Parameters: `guide{i}.v_*` (9), `rot2`, `rot3`, `tilt3` each `p_*_m` and `axis_*`
/// (18), per link `A` (in the arm's last frame), `B0`, `L` (42): 69 in all. Positions along a
/// rotation axis and rotations about it are redundant; the calibration engine finds that.
///
/// - Inverse kinematics: arm 1 in closed form; arms 2 and 3 by Newton on their own joints, from
///   the plates at zero and the cart from the closed form of the averaged cluster; when that fails
///   the seed's values for the arm are tried. A solution with a link off its branch is rejected.
/// - Forward kinematics: Newton on the pose from the cluster start
///   ([`Mechanism::cluster_start`]); if that fails or breaks the guard, continuation from the
///   plates at zero (where the parallelogram clusters make the cluster start nearly exact) to the
///   requested plate angles.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GantryTauF1 {
    /// Model name.
    pub name: String,
    /// The three guideways (carts 1..3).
    pub guideways: [Guideway; 3],
    /// The plate on cart 2 (joint 4).
    pub rot2: RotaryStage,
    /// The plate on cart 3 (joint 5).
    pub rot3: RotaryStage,
    /// The tilting plate carried by `rot3` (joint 6).
    pub tilt3: RotaryStage,
    /// Six links: 1 on arm 1, 2 on arm 2, 3 on arm 3, in that order; `a_m` in the arm's last
    /// frame.
    pub links: Vec<Link>,
    /// Assembly mode of the cluster start (see [`Branch`]).
    pub assembly: Branch,
    /// `T_flange_tool` (not a parameter: exactly redundant with the `B0` points).
    pub tool: Pose,
    /// Newton settings and guard.
    pub solver: SolverOptions,
}

const STAGE_NAMES: [&str; 3] = ["rot2", "rot3", "tilt3"];

impl GantryTauF1 {
    /// The solver settings models of this kind start with.
    pub fn default_solver() -> SolverOptions {
        SolverOptions::default()
    }

    fn stages(&self) -> [&RotaryStage; 3] {
        [&self.rot2, &self.rot3, &self.tilt3]
    }

    fn stages_mut(&mut self) -> [&mut RotaryStage; 3] {
        [&mut self.rot2, &mut self.rot3, &mut self.tilt3]
    }

    /// Checks the layout and numbers.
    pub fn validate(&self) -> Result<()> {
        check_guideways(&self.guideways)?;
        for (name, st) in STAGE_NAMES.iter().zip(self.stages()) {
            check_vector(&format!("{name}.p"), &st.point_m)?;
            check_direction(&format!("{name}.axis"), &st.axis)?;
            JointLimits::new(name, st.limits.lower, st.limits.upper)?;
        }
        check_links(&self.links)
    }

    /// Inverse kinematics without the limit check (see the type's documentation).
    pub fn inverse_unchecked(&self, t_base_tool: &Pose, seed: &[f64]) -> Result<Vec<f64>> {
        let mech = self.mechanism()?;
        if t_base_tool.translation.vector.iter().any(|v| !v.is_finite())
            || !t_base_tool.rotation.coords.iter().all(|v| v.is_finite())
        {
            return Err(RobotError::Unreachable { reason: "the target pose is not finite".into() });
        }
        let zeros = vec![0.0; 6];
        let at_zero = mech.leg_states(&zeros, t_base_tool)?;
        let mut q = zeros.clone();
        let seed_ok = seed.len() == 6 && seed.iter().all(|v| v.is_finite());
        for (arm, (legs, joints)) in
            [(vec![0], vec![0]), (vec![1, 2], vec![1, 3]), (vec![3, 4, 5], vec![2, 4, 5])].into_iter().enumerate()
        {
            let g = &self.guideways[arm];
            let unreachable = || RobotError::Unreachable {
                reason: format!("arm {}: the target is out of reach of the links of guideway {}", arm + 1, arm + 1),
            };
            let own_root =
                |k: usize| cart_root(&at_zero[k].a_m, &g.v, &at_zero[k].b_m, self.links[k].length_m, g.branch);
            if joints.len() == 1 {
                q[arm] = own_root(legs[0]).ok_or_else(unreachable)?;
                continue;
            }
            // Start: plates at zero and the cart from the closed form of the averaged cluster;
            // failing that, the mean of the links' own roots; failing that, 0.1 m on the arm's
            // branch side of the cart position closest to the averaged platform point.
            let n = legs.len() as f64;
            let a = legs.iter().map(|&k| at_zero[k].a_m).sum::<Vector3<f64>>() / n;
            let b = legs.iter().map(|&k| at_zero[k].b_m).sum::<Vector3<f64>>() / n;
            let l = legs.iter().map(|&k| self.links[k].length_m).sum::<f64>() / n;
            let cluster_root = cart_root(&a, &g.v, &b, l, g.branch);
            let own: Vec<f64> = legs.iter().filter_map(|&k| own_root(k)).collect();
            let cart = cluster_root
                .or_else(|| (!own.is_empty()).then(|| own.iter().sum::<f64>() / own.len() as f64))
                .unwrap_or_else(|| (g.v.dot(&(b - a)) + g.branch.sign() * 0.1 * g.v.norm()) / g.v.norm_squared());
            let mut start = q.clone();
            start[arm] = cart;
            for &j in &joints[1..] {
                start[j] = 0.0;
            }
            let mut starts = vec![start.clone()];
            if seed_ok {
                for &j in &joints {
                    start[j] = seed[j];
                }
                starts.push(start);
            }
            let mut found = None;
            let mut last_err = None;
            for s in &starts {
                match mech.solve_joints(&legs, &joints, s, t_base_tool, &self.solver) {
                    Ok(sol) => {
                        let states = mech.leg_states(&sol, t_base_tool)?;
                        match legs.iter().find_map(|&k| mech.leg_side_violation(k, &states[k])) {
                            None => {
                                found = Some(sol);
                                break;
                            }
                            Some(msg) => {
                                last_err = Some(RobotError::Unreachable {
                                    reason: format!(
                                        "arm {}: the solution leaves the working configuration: {msg}",
                                        arm + 1
                                    ),
                                })
                            }
                        }
                    }
                    Err(e) => last_err = Some(e),
                }
            }
            let Some(sol) = found else {
                return Err(match (cluster_root, last_err) {
                    (Some(_), Some(e)) => e,
                    _ => unreachable(),
                });
            };
            for &j in &joints {
                q[j] = sol[j];
            }
        }
        for v in &mut q[3..] {
            *v = wrap_angle(*v);
        }
        let states = mech.leg_states(&q, t_base_tool)?;
        if let Some(msg) = mech.side_violation(&states) {
            return Err(RobotError::Unreachable {
                reason: format!("the solution leaves the working configuration: {msg}"),
            });
        }
        Ok(q)
    }
}

impl Parameterized for GantryTauF1 {
    fn parameters(&self) -> Vec<ParamInfo> {
        let mut out = Vec::with_capacity(69);
        guideway_params(&self.guideways, &mut out);
        for (name, st) in STAGE_NAMES.iter().zip(self.stages()) {
            for (n, v) in vec_names(&format!("{name}.p"), "_m").into_iter().zip(st.point_m.iter()) {
                out.push(ParamInfo::new(n, Unit::Metre, *v));
            }
            for (n, v) in vec_names(&format!("{name}.axis"), "").into_iter().zip(st.axis.iter()) {
                out.push(ParamInfo::new(n, Unit::Dimensionless, *v));
            }
        }
        link_params(&self.links, "A", &mut out);
        out
    }

    fn set_parameter_values(&mut self, values: &[f64]) -> Result<()> {
        let info = self.parameters();
        check_values(values, info.len(), &info)?;
        let mut next = self.clone();
        for (i, g) in next.guideways.iter_mut().enumerate() {
            g.v = Vector3::new(values[3 * i], values[3 * i + 1], values[3 * i + 2]);
        }
        for (k, st) in next.stages_mut().into_iter().enumerate() {
            let v = &values[9 + 6 * k..15 + 6 * k];
            st.point_m = Vector3::new(v[0], v[1], v[2]);
            st.axis = Vector3::new(v[3], v[4], v[5]);
        }
        set_link_params(&mut next.links, &values[27..]);
        next.validate()?;
        *self = next;
        Ok(())
    }
}

impl Kinematics for GantryTauF1 {
    fn dof(&self) -> usize {
        6
    }

    fn joint_names(&self) -> Vec<String> {
        ["cart1", "cart2", "cart3", "rot2", "rot3", "tilt3"].map(String::from).to_vec()
    }

    fn joint_kinds(&self) -> Vec<JointKind> {
        let mut k = vec![JointKind::Prismatic; 3];
        k.extend([JointKind::Revolute; 3]);
        k
    }

    fn joint_limits(&self) -> Vec<JointLimits> {
        let mut l: Vec<JointLimits> = self.guideways.iter().map(|g| g.limits).collect();
        l.extend(self.stages().map(|s| s.limits));
        l
    }

    fn mobility(&self) -> Mobility {
        Mobility::Full6
    }

    fn forward(&self, q: &[f64]) -> Result<Pose> {
        check_len(q, 6)?;
        let mech = self.mechanism()?;
        let direct = mech.cluster_start(q, self.assembly).and_then(|start| mech.solve_pose(q, &start, &self.solver));
        let Err(first) = direct else {
            return direct;
        };
        let mut q_a = q.to_vec();
        q_a[3..].fill(0.0);
        let continued = mech
            .cluster_start(&q_a, self.assembly)
            .and_then(|start| mech.solve_pose(&q_a, &start, &self.solver))
            .and_then(|pose_a| mech.solve_pose_continuation(&q_a, &pose_a, q, &self.solver));
        continued.map_err(|second| RobotError::FkNotConverged {
            reason: format!("from the cluster start: {first}; by continuation from the plates at zero: {second}"),
        })
    }

    /// See the type's documentation; `seed` is the fallback start for arms 2 and 3. Limits are
    /// checked.
    fn inverse(&self, t_base_tool: &Pose, seed: &[f64]) -> Result<Vec<f64>> {
        let q = self.inverse_unchecked(t_base_tool, seed)?;
        self.check_joints(&q)?;
        Ok(q)
    }

    fn jacobian(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        self.mechanism_jacobian(q, false)
    }
}

impl ParallelRobot for GantryTauF1 {
    fn mechanism(&self) -> Result<Mechanism> {
        self.validate()?;
        let cart = |i: usize| Stage::cart(i, self.guideways[i].v, 3 * i);
        let rot = |k: usize, joint: usize| {
            let st = self.stages()[k];
            Stage {
                joint,
                kind: JointKind::Revolute,
                offset_m: st.point_m,
                axis: st.axis,
                offset_param: Some(9 + 6 * k),
                axis_param: Some(12 + 6 * k),
            }
        };
        let carriages = vec![
            Carriage { name: "arm1".into(), stages: vec![cart(0)] },
            Carriage { name: "arm2".into(), stages: vec![cart(1), rot(0, 3)] },
            Carriage { name: "arm3".into(), stages: vec![cart(2), rot(1, 4), rot(2, 5)] },
        ];
        Ok(Mechanism {
            joint_names: self.joint_names(),
            n_params: 69,
            carriages,
            legs: gantry_legs(&self.links, &self.guideways, 27),
            tool: self.tool,
        })
    }
}
