//! The six-link Gantry-Tau error model: every link with its own geometry, so the platform
//! orientation follows from the links instead of being constant.

use nalgebra::{DMatrix, DVector, Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use super::legs::{apply_twist, cart_carriages, cart_root, solve_square, Leg, LegSide, Mechanism};
use super::{
    check_direction, check_positive, check_vector, three_cart_joints, vec_names, Branch, Guideway, Link, ParallelRobot,
    SolverOptions,
};
use crate::error::{Result, RobotError};
use crate::geometry::Pose;
use crate::kinematics::{check_len, JointKind, JointLimits, Kinematics, Mobility};
use crate::params::{check_values, ParamInfo, Parameterized, Unit};

/// The arm (0-based) of each of the six links of a Gantry-Tau: clusters of 1, 2 and 3 links.
pub(crate) const LINK_ARMS: [usize; 6] = [0, 1, 1, 2, 2, 2];

/// `link{arm}_{k}` (both 1-based) for link `index` of the fixed cluster layout.
pub(crate) fn link_name(index: usize) -> String {
    match LINK_ARMS.get(index) {
        Some(&arm) => {
            let k = LINK_ARMS[..index].iter().filter(|&&a| a == arm).count();
            format!("link{}_{}", arm + 1, k + 1)
        }
        // Only reachable for a model with too many links, which validation rejects.
        None => format!("link{}", index + 1),
    }
}

/// Checks the cluster layout (6 links: 1 on arm 1, 2 on arm 2, 3 on arm 3, in that order) and the
/// links' numbers.
pub(crate) fn check_links(links: &[Link]) -> Result<()> {
    if links.len() != 6 || links.iter().zip(LINK_ARMS).any(|(l, a)| l.arm != a) {
        return Err(RobotError::BadParameter {
            name: "links".into(),
            value: links.len() as f64,
            reason: "a Gantry-Tau needs 6 links: 1 on arm 1, 2 on arm 2, 3 on arm 3, in that order".into(),
        });
    }
    for (k, l) in links.iter().enumerate() {
        let n = link_name(k);
        check_vector(&format!("{n}.A"), &l.a_m)?;
        check_vector(&format!("{n}.B0"), &l.b0_m)?;
        check_positive(&format!("{n}.L_m"), l.length_m)?;
        for (what, ax) in [("base_axis", l.base_axis), ("platform_axis", l.platform_axis)] {
            if let Some(ax) = ax {
                check_direction(&format!("{n}.{what}"), &ax)?;
            }
        }
    }
    Ok(())
}

/// Checks the three guideways.
pub(crate) fn check_guideways(g: &[Guideway; 3]) -> Result<()> {
    for (i, gw) in g.iter().enumerate() {
        check_direction(&format!("guide{}.v", i + 1), &gw.v)?;
        JointLimits::new(&format!("cart{}", i + 1), gw.limits.lower, gw.limits.upper)?;
    }
    Ok(())
}

/// Parameters of the guideway directions, `guide{i}.v_{x,y,z}`.
pub(crate) fn guideway_params(g: &[Guideway; 3], out: &mut Vec<ParamInfo>) {
    for (i, gw) in g.iter().enumerate() {
        for (n, v) in vec_names(&format!("guide{}.v", i + 1), "").into_iter().zip(gw.v.iter()) {
            out.push(ParamInfo::new(n, Unit::Dimensionless, *v));
        }
    }
}

/// Parameters of the links, `link{i}_{k}.{a}_{x,y,z}_m`, `.B0_*_m`, `.L_m`.
pub(crate) fn link_params(links: &[Link], a_name: &str, out: &mut Vec<ParamInfo>) {
    for (k, l) in links.iter().enumerate() {
        let n = link_name(k);
        for (name, v) in vec_names(&format!("{n}.{a_name}"), "_m").into_iter().zip(l.a_m.iter()) {
            out.push(ParamInfo::new(name, Unit::Metre, *v));
        }
        for (name, v) in vec_names(&format!("{n}.B0"), "_m").into_iter().zip(l.b0_m.iter()) {
            out.push(ParamInfo::new(name, Unit::Metre, *v));
        }
        out.push(ParamInfo::new(format!("{n}.L_m"), Unit::Metre, l.length_m));
    }
}

/// Writes link parameters from `values` (7 per link) into `links`.
pub(crate) fn set_link_params(links: &mut [Link], values: &[f64]) {
    for (l, v) in links.iter_mut().zip(values.chunks_exact(7)) {
        l.a_m = Vector3::new(v[0], v[1], v[2]);
        l.b0_m = Vector3::new(v[3], v[4], v[5]);
        l.length_m = v[6];
    }
}

/// The legs of a Gantry-Tau: link `k` on carriage `arm`, parameters from index `first` on.
pub(crate) fn gantry_legs(links: &[Link], guideways: &[Guideway; 3], first: usize) -> Vec<Leg> {
    links
        .iter()
        .enumerate()
        .map(|(k, l)| Leg {
            name: link_name(k),
            carriage: Some(l.arm),
            a_m: l.a_m,
            b0_m: l.b0_m,
            length_m: l.length_m,
            length_joint: None,
            a_param: Some(first + 7 * k),
            b0_param: Some(first + 7 * k + 3),
            length_param: Some(first + 7 * k + 6),
            side: Some(LegSide { direction: guideways[l.arm].v, branch: guideways[l.arm].branch }),
            base_axis: l.base_axis,
            platform_axis: l.platform_axis,
        })
        .collect()
}

/// The six-link Gantry-Tau error model (mobility [`Mobility::Translation3Coupled`]).
///
/// Three guideways (cart `i` at `q_i v_i`), six links in clusters of 1, 2 and 3, link `j` of arm
/// `i` from `A_ij = A0_ij + q_i v_i` to `B_ij = T + R B0_ij`. Parameters: `guide{i}.v_*` (9), then
/// per link `A0` (3), `B0` (3), `L` (1): 51 in all.
///
/// - Forward kinematics: Newton on the tool pose (position, rotation-vector increment) from the
///   cluster start ([`Mechanism::cluster_start`]: each cluster averaged into one link, the three
///   spheres intersected on the side [`GantryTau6::assembly`], identity orientation). A result
///   whose links left their branch or that lies farther from the start than the solver's bounds
///   is rejected with [`RobotError::FkNotConverged`].
/// - Inverse kinematics: Newton on the three cart positions and the platform orientation together
///   for the commanded tool position, from the closed-form solution of the averaged clusters with
///   identity orientation; failures are reported, never a wrong answer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GantryTau6 {
    /// Model name.
    pub name: String,
    /// The three guideways, in joint order.
    pub guideways: [Guideway; 3],
    /// The six links: 1 on arm 1, 2 on arm 2, 3 on arm 3, in that order. `a_m` is `A0`, the
    /// base-side joint centre at `q = 0`, base frame.
    pub links: Vec<Link>,
    /// Assembly mode of the cluster start (see [`Branch`]).
    pub assembly: Branch,
    /// `T_flange_tool` (not a parameter: it is exactly redundant with the `B0` points).
    pub tool: Pose,
    /// Newton settings and guard.
    pub solver: SolverOptions,
}

impl GantryTau6 {
    /// The solver settings models of this kind start with: orientation within 0.2 rad and position
    /// within 0.2 m of the cluster start.
    pub fn default_solver() -> SolverOptions {
        SolverOptions { max_translation_m: 0.2, max_rotation_rad: 0.2, ..SolverOptions::default() }
    }

    /// Checks the layout and numbers.
    pub fn validate(&self) -> Result<()> {
        check_guideways(&self.guideways)?;
        check_links(&self.links)
    }

    /// The start of the inverse kinematics: cluster-averaged closed form at `p` (tool position)
    /// with identity platform orientation. An arm whose averaged cluster has no real root starts
    /// 0.1 m on its branch side of the cart position closest to the target; that arm is returned
    /// so that a failure can name it.
    fn ik_start(&self, p: &Vector3<f64>) -> Result<(Vec<f64>, Pose, Option<usize>)> {
        let t_flange = p - self.tool.translation.vector;
        let mut q = vec![0.0; 3];
        let mut centres = [Vector3::zeros(); 3];
        let mut missed = None;
        for (i, g) in self.guideways.iter().enumerate() {
            let (mut a, mut l, mut n) = (Vector3::zeros(), 0.0, 0.0);
            for link in self.links.iter().filter(|k| k.arm == i) {
                a += link.a_m - link.b0_m;
                l += link.length_m;
                n += 1.0;
            }
            a /= n;
            l /= n;
            q[i] = cart_root(&a, &g.v, &t_flange, l, g.branch).unwrap_or_else(|| {
                missed = missed.or(Some(i));
                (g.v.dot(&(t_flange - a)) + g.branch.sign() * 0.1 * g.v.norm()) / g.v.norm_squared()
            });
            centres[i] = a + g.v * q[i];
        }
        let side =
            Branch::of((centres[1] - centres[0]).cross(&(centres[2] - centres[0])).dot(&(t_flange - centres[0])));
        if missed.is_none() && side != self.assembly {
            return Err(RobotError::Unreachable {
                reason: format!(
                    "the target lies in the '{}' assembly mode; the model works in '{}'",
                    side.as_str(),
                    self.assembly.as_str()
                ),
            });
        }
        let start = Isometry3::from_parts(Translation3::from(t_flange), UnitQuaternion::identity()) * self.tool;
        Ok((q, start, missed))
    }

    /// Inverse kinematics that also returns the tool pose the mechanism takes (its orientation
    /// follows from the links). No limit check.
    pub fn inverse_pose(&self, position_m: &Vector3<f64>) -> Result<(Vec<f64>, Pose)> {
        self.validate()?;
        if position_m.iter().any(|v| !v.is_finite()) {
            return Err(RobotError::Unreachable { reason: "the target position is not finite".into() });
        }
        let (q, start, missed) = self.ik_start(position_m)?;
        self.newton_ik(q, start).map_err(|e| match missed {
            Some(i) => RobotError::Unreachable {
                reason: format!("arm {}: the target is out of reach of the links of guideway {}", i + 1, i + 1),
            },
            None => e,
        })
    }

    /// Newton on carts and platform orientation at the fixed tool position of `start`.
    fn newton_ik(&self, mut q: Vec<f64>, start: Pose) -> Result<(Vec<f64>, Pose)> {
        let mech = self.mechanism()?;
        let mut x = start;
        let opts = &self.solver;
        let mut res = f64::INFINITY;
        let mut last_rot = 0.0;
        for it in 0..opts.max_iterations {
            let lin = mech.linearize(&q, &x)?;
            res = lin.max_length_error_m();
            let jac = DMatrix::from_fn(6, 6, |r, c| if c < 3 { lin.fq[(r, c)] } else { lin.fx[(r, c)] });
            let Some(mut step) = solve_square(jac, &(-&lin.f)) else {
                return Err(RobotError::IkNotConverged { iterations: it + 1, residual_m: res, residual_rad: last_rot });
            };
            let done = res <= opts.tolerance_m;
            if done && step.norm() >= 1e-6 {
                step = DVector::zeros(6);
            }
            if !done {
                let n = step.norm();
                if n > opts.max_step {
                    step *= opts.max_step / n;
                }
            }
            for i in 0..3 {
                q[i] += step[i];
            }
            let dw: Vector3<f64> = step.fixed_rows::<3>(3).into();
            last_rot = dw.norm();
            x = apply_twist(&x, &Vector3::zeros(), &dw);
            if done {
                let states = mech.leg_states(&q, &x)?;
                if let Some(msg) = mech.side_violation(&states) {
                    return Err(RobotError::Unreachable {
                        reason: format!("the solution leaves the working configuration: {msg}"),
                    });
                }
                let dr = x.rotation.angle_to(&start.rotation);
                if dr > opts.max_rotation_rad {
                    return Err(RobotError::IkNotConverged { iterations: it + 1, residual_m: res, residual_rad: dr });
                }
                return Ok((q, x));
            }
        }
        Err(RobotError::IkNotConverged { iterations: opts.max_iterations, residual_m: res, residual_rad: last_rot })
    }
}

impl Parameterized for GantryTau6 {
    fn parameters(&self) -> Vec<ParamInfo> {
        let mut out = Vec::with_capacity(51);
        guideway_params(&self.guideways, &mut out);
        link_params(&self.links, "A0", &mut out);
        out
    }

    fn set_parameter_values(&mut self, values: &[f64]) -> Result<()> {
        let info = self.parameters();
        check_values(values, info.len(), &info)?;
        let mut next = self.clone();
        for (i, g) in next.guideways.iter_mut().enumerate() {
            g.v = Vector3::new(values[3 * i], values[3 * i + 1], values[3 * i + 2]);
        }
        set_link_params(&mut next.links, &values[9..]);
        next.validate()?;
        *self = next;
        Ok(())
    }
}

impl Kinematics for GantryTau6 {
    three_cart_joints!(guideways);

    fn mobility(&self) -> Mobility {
        Mobility::Translation3Coupled
    }

    fn forward(&self, q: &[f64]) -> Result<Pose> {
        check_len(q, 3)?;
        let mech = self.mechanism()?;
        let start = mech.cluster_start(q, self.assembly)?;
        mech.solve_pose(q, &start, &self.solver)
    }

    /// Newton on carts and orientation (see the type's documentation); `seed` is ignored and the
    /// target's orientation too. Limits are checked.
    fn inverse(&self, t_base_tool: &Pose, _seed: &[f64]) -> Result<Vec<f64>> {
        let (q, _) = self.inverse_pose(&t_base_tool.translation.vector)?;
        self.check_joints(&q)?;
        Ok(q)
    }

    fn jacobian(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        self.mechanism_jacobian(q, false)
    }
}

impl ParallelRobot for GantryTau6 {
    fn mechanism(&self) -> Result<Mechanism> {
        self.validate()?;
        let carriages = cart_carriages([0, 1, 2].map(|i| self.guideways[i].v), |i| 3 * i);
        Ok(Mechanism {
            joint_names: self.joint_names(),
            n_params: 51,
            carriages,
            legs: gantry_legs(&self.links, &self.guideways, 9),
            tool: self.tool,
        })
    }
}
