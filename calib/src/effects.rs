//! Named physical effects beyond the geometric model, as regressor families that calibration can
//! identify jointly with the geometric parameters (and `diagnose` can test).
//!
//! This is the identification side's own description of the physics; the cell simulator in
//! `ferrocal-datasets` describes the same effects independently (no shared code), so a mistake
//! in one is not silently mirrored in the other.
//!
//! Each effect changes the joint values the kinematics sees (`q -> q + dq`) or scales the
//! model's lengths, as a function of the row's inputs (joints, approach directions, temperature,
//! time, payload) and the effect's parameters `theta`:
//!
//! | effect | parameters | correction |
//! | --- | --- | --- |
//! | `joint_compliance` | `c` (rad/(N m) or m/N) | `dq_j = -c tau_j(q_eff, payload)` at the equilibrium (below), `tau` the holding torque from the model's inertials (a serial chain's links, or 1 kg at the tool for other models, when `c` then absorbs the mass) |
//! | `backlash` | `b` (rad or m) | `dq_j = -b d_j / 2`, `d_j` the approach direction |
//! | `joint_scale_error` | `s` | `dq_j = s q_j` |
//! | `periodic_joint_error` | `a, b` (rad or m), period `P` fixed | `dq_j = a sin(2 pi q_j / P) + b cos(2 pi q_j / P)` |
//! | `thermal_expansion` | `alpha` (1/K) | every length scales by `1 + alpha (T - T_ref)`: the target position in the model's base frame scales by that factor |
//! | `time_drift` | `v` (per hour) | as thermal expansion with `t` in hours instead of `T - T_ref` |
//! | `coupled_transmission` | `c` (joint units of `J` per joint unit of `K`) | `dq_J = c q_K`: joint `J`'s transmission is coupled to joint `K`'s motion (a wrist whose motors sit on an earlier link, a cable passing a joint) |
//! | `axis_misalignment` | `c_x, c_y` (rad) | revolute joint `J`'s axis wobbles with its angle: everything beyond the joint turns about the joint's axis point by the rotation vector `c_x e_1(q) + c_y e_2(q)`, `e_1 = cos 2q u + sin 2q v`, `e_2 = -sin 2q u + cos 2q v` with `(u, v)` normal to the axis and fixed on the joint's stationary side ([`axis_wobble`]): a tilt of amplitude `hypot(c_x, c_y)` whose direction turns once per revolution relative to the moving link (twice relative to the stationary side) |
//!
//! Joint compliance is solved as the equilibrium of every compliant joint together,
//! `q_eff = q0 - C tau(q_eff)` ([`compliance_equilibrium`]), where `q0` is the reading with the
//! zero offsets and the other effects' corrections: the joint holds the load at the angle it
//! deflects to, not at the commanded one. The fixed-point iteration converges when the
//! compliance times the gravity stiffness `d tau / d q` is below 1 at every joint (it contracts by
//! that factor per iteration: 3-5 iterations to 1e-9 rad for a sag of tens of mrad) and stops
//! with [`CalibError::Equilibrium`] naming the joint otherwise. The first iterate,
//! `q0 - C tau(q0)`, is the one-step deflection; they differ by about the sag times the factor
//! `c dtau/dq` (0.5 mrad for a 25 mrad sag at a factor of 0.02).
//!
//! Coupled (mimic) joints: effects are indexed over the actuated joints (1-based, as the
//! measurement table's `q1..qN`); `tau` is the actuated coordinates' holding torque, so a mimic
//! joint's torque reaches its leader's entry times the multiplier (`tau_leader + m tau_mimic`),
//! and `joint_compliance:J` on a leader is the compliance of the whole transmission its drive
//! moves (the leader and the joints coupled to it), deflecting the leader's coordinate and with
//! it the mimic joints (see `docs/diagnose.md`, "Coupled joints").
//!
//! Why that form of axis misalignment: a tilt of the axis fixed on the stationary side is a
//! different axis direction, and a tilt fixed on the moving link (its direction turning once per
//! revolution as seen from the stationary side) is a different link frame: both are geometric
//! parameters (as in spindle metrology, where the once-per-revolution tilt is the artefact's
//! misalignment, not the axis's error motion). The lowest wobble the geometry cannot absorb turns
//! with the joint as seen from the link, i.e. at twice the joint's rate as seen from the base.

use ferrocal_robot::{JointKind, Kinematics, RobotModel, Unit};
use nalgebra::{DMatrix, DVector, Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

pub use crate::effect_registry::{CustomEffect, Effect};
use crate::error::{CalibError, Result};
use crate::measurement::PoseMeasurement;

/// One effect with its fixed settings (joint numbers are 1-based).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "effect", rename_all = "snake_case")]
pub enum EffectSpec {
    /// A joint deflects in proportion to the load torque it carries.
    JointCompliance {
        /// Joint (1-based).
        joint: usize,
    },
    /// A joint's position depends on the direction it was approached from.
    Backlash {
        /// Joint (1-based).
        joint: usize,
    },
    /// A joint's reading is off by a factor.
    JointScaleError {
        /// Joint (1-based).
        joint: usize,
    },
    /// A joint's error repeats with a fixed period in its own travel.
    PeriodicJointError {
        /// Joint (1-based).
        joint: usize,
        /// Period in joint units (rad or m).
        period_si: f64,
    },
    /// Lengths change with temperature.
    ThermalExpansion {
        /// Temperature at which the geometric parameters hold.
        reference_temp_c: f64,
    },
    /// Lengths change with time (warm-up without a temperature reading).
    TimeDrift,
    /// A link bends under the load it carries: link `link` (1-based; the body moved by joint
    /// `link`, carrying joint `link + 1`) turns, about its midpoint, by `compliance` times the
    /// gravity moment of everything beyond it taken at its far end, without that moment's
    /// component along joint `link + 1`'s axis (which the joint carries: joint compliance).
    LinkCompliance {
        /// Link (1-based, 1 to joints - 1).
        link: usize,
    },
    /// A joint's error is proportional to another joint's angle: `dq_joint = c q_driver`.
    CoupledTransmission {
        /// The joint whose reading is off (1-based).
        joint: usize,
        /// The joint whose motion drives the error (1-based, not `joint`).
        driver: usize,
    },
    /// A revolute joint's axis is not where the nominal model puts it at every angle: the links
    /// beyond it tilt by a small angle whose direction turns with the joint (see the table in
    /// the module documentation and [`axis_wobble`]).
    AxisMisalignment {
        /// Joint (1-based, revolute, of a serial chain).
        joint: usize,
    },
    /// An effect of the registry ([`crate::effect_registry`]): defined by a type implementing
    /// [`Effect`], written and read by its own name and settings.
    #[serde(untagged)]
    Custom(CustomEffect),
}

impl EffectSpec {
    /// The effect's name in `shared/spec/diagnose.md`'s vocabulary.
    pub fn name(&self) -> &'static str {
        match self {
            EffectSpec::JointCompliance { .. } => "joint_compliance",
            EffectSpec::Backlash { .. } => "backlash",
            EffectSpec::JointScaleError { .. } => "joint_scale_error",
            EffectSpec::PeriodicJointError { .. } => "periodic_joint_error",
            EffectSpec::ThermalExpansion { .. } => "thermal_expansion",
            EffectSpec::TimeDrift => "thermal_expansion",
            EffectSpec::LinkCompliance { .. } => "link_compliance",
            EffectSpec::CoupledTransmission { .. } => "coupled_transmission",
            EffectSpec::AxisMisalignment { .. } => "axis_misalignment",
            EffectSpec::Custom(e) => e.name(),
        }
    }

    /// Whether the effect moves the predicted pose rigidly ([`EffectSpec::pose_correction`])
    /// rather than changing joint values or lengths.
    pub fn corrects_pose(&self) -> bool {
        match self {
            EffectSpec::Custom(e) => e.corrects_pose(),
            other => matches!(other, EffectSpec::LinkCompliance { .. } | EffectSpec::AxisMisalignment { .. }),
        }
    }

    /// The joint it belongs to (1-based), if any.
    pub fn joint(&self) -> Option<usize> {
        match self {
            EffectSpec::JointCompliance { joint }
            | EffectSpec::Backlash { joint }
            | EffectSpec::JointScaleError { joint }
            | EffectSpec::PeriodicJointError { joint, .. }
            | EffectSpec::CoupledTransmission { joint, .. }
            | EffectSpec::AxisMisalignment { joint } => Some(*joint),
            EffectSpec::Custom(e) => e.joint(),
            EffectSpec::ThermalExpansion { .. } | EffectSpec::TimeDrift | EffectSpec::LinkCompliance { .. } => None,
        }
    }

    /// The joints a report names for it: the joint of a joint effect, the two joints a link
    /// connects for link compliance, none for length changes.
    pub fn joints_reported(&self) -> Vec<usize> {
        match self {
            EffectSpec::LinkCompliance { link } => vec![*link, link + 1],
            EffectSpec::CoupledTransmission { joint, driver } => vec![*joint, *driver],
            EffectSpec::Custom(e) => e.joints_reported(),
            other => other.joint().into_iter().collect(),
        }
    }

    /// Names and units of its parameters (joint units follow the joint's kind).
    pub fn parameters(&self, kinds: &[JointKind]) -> Vec<(String, Unit)> {
        let ju = |j: usize| match kinds.get(j - 1) {
            Some(JointKind::Prismatic) => (Unit::Metre, "m"),
            _ => (Unit::Radian, "rad"),
        };
        match self {
            EffectSpec::JointCompliance { joint } => {
                let per = if ju(*joint).0 == Unit::Metre { "m_per_n" } else { "rad_per_nm" };
                vec![(format!("joint{joint}.compliance_{per}"), Unit::Dimensionless)]
            }
            EffectSpec::Backlash { joint } => {
                let (u, s) = ju(*joint);
                vec![(format!("joint{joint}.backlash_{s}"), u)]
            }
            EffectSpec::JointScaleError { joint } => vec![(format!("joint{joint}.scale_error"), Unit::Dimensionless)],
            EffectSpec::PeriodicJointError { joint, .. } => {
                let (u, s) = ju(*joint);
                vec![(format!("joint{joint}.periodic_sin_{s}"), u), (format!("joint{joint}.periodic_cos_{s}"), u)]
            }
            EffectSpec::ThermalExpansion { .. } => vec![("thermal.alpha_per_k".into(), Unit::Dimensionless)],
            EffectSpec::TimeDrift => vec![("drift.per_hour".into(), Unit::Dimensionless)],
            EffectSpec::LinkCompliance { link } => {
                vec![(format!("link{link}.compliance_rad_per_nm"), Unit::Dimensionless)]
            }
            EffectSpec::CoupledTransmission { joint, driver } => {
                vec![(format!("joint{joint}.coupling_per_joint{driver}"), Unit::Dimensionless)]
            }
            EffectSpec::AxisMisalignment { joint } => vec![
                (format!("joint{joint}.wobble_x_rad"), Unit::Radian),
                (format!("joint{joint}.wobble_y_rad"), Unit::Radian),
            ],
            EffectSpec::Custom(e) => e.parameters(kinds),
        }
    }

    /// The typical size of each parameter (for scaling the problem).
    pub fn scales(&self) -> Vec<f64> {
        match self {
            EffectSpec::JointCompliance { .. } => vec![1e-6],
            EffectSpec::Backlash { .. } => vec![1e-4],
            EffectSpec::JointScaleError { .. } => vec![1e-4],
            EffectSpec::PeriodicJointError { .. } => vec![1e-4, 1e-4],
            EffectSpec::ThermalExpansion { .. } => vec![1e-5],
            EffectSpec::TimeDrift => vec![1e-5],
            EffectSpec::LinkCompliance { .. } => vec![1e-6],
            EffectSpec::CoupledTransmission { .. } => vec![1e-4],
            EffectSpec::AxisMisalignment { .. } => vec![1e-4, 1e-4],
            EffectSpec::Custom(e) => e.scales(),
        }
    }

    /// Whether a row carries the inputs the effect needs (else it cannot be tested on it).
    pub fn missing_input(&self, row: &PoseMeasurement) -> Option<&'static str> {
        match self {
            EffectSpec::Backlash { joint } => match &row.dir {
                Some(d) if d.get(joint - 1).is_some_and(|v| *v != 0) => None,
                _ => Some("approach directions (dir columns)"),
            },
            EffectSpec::ThermalExpansion { .. } => row.temp_c.is_none().then_some("temperature (temp_c)"),
            EffectSpec::TimeDrift => row.t_s.is_none().then_some("time (t_s)"),
            EffectSpec::Custom(e) => e.missing_input(row),
            _ => None,
        }
    }

    /// Checks the effect against the model.
    pub fn validate(&self, model: &RobotModel) -> Result<()> {
        if let Some(j) = self.joint() {
            if j == 0 || j > model.dof() {
                return Err(CalibError::Data(format!(
                    "effect {}: joint {j} does not exist (the model has {} joints, numbered from 1)",
                    self.name(),
                    model.dof()
                )));
            }
        }
        if let EffectSpec::Custom(e) = self {
            return e.validate(model);
        }
        if let EffectSpec::LinkCompliance { link } = self {
            let RobotModel::Serial(_) = model else {
                return Err(CalibError::Data(
                    "link_compliance: only serial chains have links that carry their successors".into(),
                ));
            };
            if *link == 0 || *link >= model.dof() {
                return Err(CalibError::Data(format!(
                    "link_compliance: link {link} does not carry a further joint (links 1 to {} do)",
                    model.dof().saturating_sub(1)
                )));
            }
        }
        if let EffectSpec::CoupledTransmission { joint, driver } = self {
            if *driver == 0 || *driver > model.dof() || driver == joint {
                return Err(CalibError::Data(format!(
                    "coupled_transmission: the driving joint {driver} must be another joint of the model (1 to {}, not {joint})",
                    model.dof()
                )));
            }
        }
        if let EffectSpec::AxisMisalignment { joint } = self {
            let RobotModel::Serial(_) = model else {
                return Err(CalibError::Data(
                    "axis_misalignment: only serial chains have a joint axis that carries the links beyond it".into(),
                ));
            };
            if model.joint_kinds()[joint - 1] != JointKind::Revolute {
                return Err(CalibError::Data(format!(
                    "axis_misalignment: joint {joint} is prismatic (the wobbling axis is a revolute joint's)"
                )));
            }
        }
        if let EffectSpec::PeriodicJointError { period_si, .. } = self {
            if !(period_si.is_finite() && *period_si > 0.0) {
                return Err(CalibError::Data(format!(
                    "periodic_joint_error: period must be positive, got {period_si}"
                )));
            }
        }
        Ok(())
    }

    /// Adds the effect's joint corrections for `row` to `dq`. For `joint_compliance` that is the
    /// one-step deflection `-c tau(q_reading)`; [`CalibratedModel::effective`](crate::kinematic::CalibratedModel::effective)
    /// solves the equilibrium instead ([`compliance_equilibrium`]).
    pub fn add_joint_delta(
        &self,
        model: &RobotModel,
        row: &PoseMeasurement,
        theta: &[f64],
        dq: &mut [f64],
    ) -> Result<()> {
        match self {
            EffectSpec::JointCompliance { joint } => {
                let tau = holding_torques(model, &row.q, row.payload_kg.unwrap_or(0.0))?;
                dq[joint - 1] -= theta[0] * tau[joint - 1];
            }
            EffectSpec::Backlash { joint } => {
                let d = row.dir.as_ref().and_then(|d| d.get(joint - 1)).copied().unwrap_or(0) as f64;
                dq[joint - 1] -= theta[0] * d / 2.0;
            }
            EffectSpec::JointScaleError { joint } => dq[joint - 1] += theta[0] * row.q[joint - 1],
            EffectSpec::PeriodicJointError { joint, period_si } => {
                let x = std::f64::consts::TAU * row.q[joint - 1] / period_si;
                dq[joint - 1] += theta[0] * x.sin() + theta[1] * x.cos();
            }
            EffectSpec::CoupledTransmission { joint, driver } => dq[joint - 1] += theta[0] * row.q[driver - 1],
            EffectSpec::Custom(e) => e.add_joint_delta(model, row, theta, dq)?,
            EffectSpec::ThermalExpansion { .. }
            | EffectSpec::TimeDrift
            | EffectSpec::LinkCompliance { .. }
            | EffectSpec::AxisMisalignment { .. } => {}
        }
        Ok(())
    }

    /// The rigid correction of the predicted pose (in the model's base frame) the effect causes
    /// at effective joints `q`, for parameters `theta`: the identity except for link compliance
    /// and axis misalignment ([`EffectSpec::corrects_pose`]).
    pub fn pose_correction(
        &self,
        model: &RobotModel,
        row: &PoseMeasurement,
        q: &[f64],
        theta: &[f64],
    ) -> Result<Isometry3<f64>> {
        match self {
            EffectSpec::LinkCompliance { link } => {
                let (axis, pivot) = link_bending(model, *link, q, row.payload_kg.unwrap_or(0.0))?;
                let rot = UnitQuaternion::from_scaled_axis(axis * theta[0]);
                // Rotation about `pivot`: x -> pivot + R (x - pivot).
                let t = pivot.coords - rot * pivot.coords;
                Ok(Isometry3::from_parts(Translation3::from(t), rot))
            }
            EffectSpec::AxisMisalignment { joint } => {
                let (e1, e2, pivot) = axis_wobble(model, *joint, q)?;
                let rot = UnitQuaternion::from_scaled_axis(e1 * theta[0] + e2 * theta[1]);
                let t = pivot.coords - rot * pivot.coords;
                Ok(Isometry3::from_parts(Translation3::from(t), rot))
            }
            EffectSpec::Custom(e) => e.pose_correction(model, row, q, theta),
            _ => Ok(Isometry3::identity()),
        }
    }

    /// The factor by which the effect scales lengths for `row` (1 for joint effects).
    pub fn length_scale(&self, row: &PoseMeasurement, theta: &[f64]) -> f64 {
        match self {
            EffectSpec::ThermalExpansion { reference_temp_c } => {
                1.0 + theta[0] * (row.temp_c.unwrap_or(*reference_temp_c) - reference_temp_c)
            }
            EffectSpec::TimeDrift => 1.0 + theta[0] * row.t_s.unwrap_or(0.0) / 3600.0,
            EffectSpec::Custom(e) => e.length_scale(row, theta),
            _ => 1.0,
        }
    }
}

/// The wobble directions of revolute joint `joint` (1-based) of a serial chain at `q`, and the
/// point it tilts about, in the model's base frame: `(e_1, e_2, pivot)`. `(u, v)` are unit
/// vectors normal to the joint's axis, fixed on its stationary side (`u` the first of the
/// stationary frame's basis vectors at more than about 53 deg from the axis, made normal to it;
/// `v = axis x u`);
/// `e_1 = cos 2q u + sin 2q v`, `e_2 = axis x e_1`; the pivot is the joint's axis point.
pub fn axis_wobble(model: &RobotModel, joint: usize, q: &[f64]) -> Result<(Vector3<f64>, Vector3<f64>, Point3<f64>)> {
    let RobotModel::Serial(chain) = model else {
        return Err(CalibError::Data("axis_misalignment needs a serial chain".into()));
    };
    let Some(i) = joint.checked_sub(1).and_then(|a| chain.joint_index_of_actuated(a)) else {
        return Err(CalibError::Data(format!("axis_misalignment: joint {joint} does not exist")));
    };
    let frames = chain.frames(q)?;
    let z = frames.axes[i];
    let stationary = if i == 0 { chain.base.rotation } else { frames.links[i - 1].rotation };
    let z_local = stationary.inverse() * z;
    // The first basis vector well away from the axis (a fixed choice: the least aligned one would
    // flip between two equally aligned ones with rounding).
    let k = (0..3).find(|&k| z_local[k].abs() < 0.6).unwrap_or(0);
    let e_k = Vector3::ith(k, 1.0);
    let u_local = (e_k - z_local * z_local.dot(&e_k)).normalize();
    let u = stationary * u_local;
    let v = z.cross(&u);
    let (s, c) = (2.0 * q[joint - 1]).sin_cos();
    let e1 = u * c + v * s;
    let e2 = z.cross(&e1);
    Ok((e1, e2, frames.axis_points[i]))
}

/// Link bending at `q` per unit compliance: the rotation vector (rad per rad/(N m), i.e. the
/// load moment in N m) of link `link` (1-based) and the point it turns about, both in the
/// model's base frame. The moment is gravity's moment, about the link's far end (the axis point
/// of joint `link + 1`), on every body beyond the link and the payload at the tool, without its
/// component along joint `link + 1`'s axis; the pivot is the midpoint between the axis points of
/// joints `link` and `link + 1` (a beam under end load turns about a point inside its span).
pub fn link_bending(
    model: &RobotModel,
    link: usize,
    q: &[f64],
    payload_kg: f64,
) -> Result<(Vector3<f64>, Point3<f64>)> {
    let n = model.dof();
    if link == 0 || link >= n {
        return Err(CalibError::Data(format!("link_compliance: link {link} does not carry a further joint")));
    }
    Ok(link_bendings(model, q, payload_kg)?[link - 1])
}

/// [`link_bending`] for every link that carries a further joint (links 1 to joints - 1, in
/// order), from one forward-kinematics pass.
pub fn link_bendings(model: &RobotModel, q: &[f64], payload_kg: f64) -> Result<Vec<(Vector3<f64>, Point3<f64>)>> {
    let RobotModel::Serial(chain) = model else {
        return Err(CalibError::Data("link_compliance needs a serial chain".into()));
    };
    chain.require_no_mimic("link_compliance")?;
    let frames = chain.frames(q)?;
    let g = Vector3::from(chain.gravity_m_s2);
    // The loads beyond each link: (mass, position), bodies in chain order, the payload last.
    let mut loads: Vec<(usize, f64, Point3<f64>)> = chain
        .joints
        .iter()
        .enumerate()
        .filter_map(|(i, j)| j.inertial.as_ref().map(|inr| (i, inr.mass_kg, frames.links[i] * Point3::from(inr.com_m))))
        .collect();
    if payload_kg != 0.0 {
        loads.push((chain.joints.len(), payload_kg, Point3::from(frames.tool.translation.vector)));
    }
    Ok((1..chain.joints.len())
        .map(|link| {
            let end = frames.axis_points[link];
            let z = frames.axes[link];
            let moment = loads
                .iter()
                .filter(|(i, _, _)| *i >= link)
                .fold(Vector3::zeros(), |m, (_, mass, p)| m + (p - end).cross(&(g * *mass)));
            let bending = moment - z * z.dot(&moment);
            let pivot = Point3::from((frames.axis_points[link - 1].coords + end.coords) / 2.0);
            (bending, pivot)
        })
        .collect())
}

/// Holding torques (forces for prismatic joints) at `q` under gravity with `payload_kg` at the
/// tool: a serial chain's link inertials through the Jacobian transpose; for other models, 1 kg
/// plus the payload at the tool.
pub fn holding_torques(model: &RobotModel, q: &[f64], payload_kg: f64) -> Result<Vec<f64>> {
    match model {
        RobotModel::Serial(chain) => Ok(chain.gravity_torques(q, payload_kg)?),
        other => {
            let jac = other.jacobian(q)?;
            let f = Vector3::new(0.0, 0.0, 9.80665 * (1.0 + payload_kg));
            Ok((0..other.dof()).map(|i| jac[(0, i)] * f.x + jac[(1, i)] * f.y + jac[(2, i)] * f.z).collect())
        }
    }
}

/// Largest number of fixed-point iterations of [`compliance_equilibrium`].
pub const EQUILIBRIUM_MAX_ITERATIONS: usize = 100;

/// The largest deflection (rad or m) an equilibrium of [`compliance_equilibrium`] may have from
/// the readings: twice the limit beyond which the diagnosis calls a compliance meaningless
/// (0.25 rad); a solution further away is a joint that fell over, not one that deflected.
pub const EQUILIBRIUM_MAX_DEFLECTION: f64 = 0.5;

/// Convergence tolerance of [`compliance_equilibrium`]: the largest joint change of the last
/// iteration (rad or m). Well below the 1e-9 rad that matters for a pose, so that the central
/// differences of the effect columns (steps of 1e-9 rad/(N m), joint changes of 1e-8 rad) see
/// a smooth function.
pub const EQUILIBRIUM_TOLERANCE: f64 = 1e-12;

/// The compliance of every joint (`n` of them) from the `joint_compliance` effects among
/// `effects` (summed per joint; zero elsewhere).
pub fn compliances(effects: &[(EffectSpec, Vec<f64>)], n: usize) -> Result<Vec<f64>> {
    let mut c = vec![0.0; n];
    for (e, theta) in effects {
        if let EffectSpec::JointCompliance { joint } = e {
            let v = joint
                .checked_sub(1)
                .and_then(|j| c.get_mut(j))
                .ok_or_else(|| CalibError::Data(format!("joint_compliance: joint {joint} does not exist")))?;
            *v += theta.first().copied().unwrap_or(0.0);
        }
    }
    Ok(c)
}

/// `d q_eff / d q0` of the equilibrium `q_eff = q0 - C tau(q_eff)` at its solution `q_eff`:
/// `(I + C K)^-1` with `K = d tau / d q` (central differences of [`holding_torques`]).
pub fn equilibrium_sensitivity(
    model: &RobotModel,
    q_eff: &[f64],
    compliance: &[f64],
    payload_kg: f64,
) -> Result<DMatrix<f64>> {
    let n = q_eff.len();
    let mut a = DMatrix::identity(n, n);
    let h = 1e-6;
    for k in 0..n {
        let (mut qp, mut qm) = (q_eff.to_vec(), q_eff.to_vec());
        qp[k] += h;
        qm[k] -= h;
        let (tp, tm) = (holding_torques(model, &qp, payload_kg)?, holding_torques(model, &qm, payload_kg)?);
        for j in 0..n {
            a[(j, k)] += compliance[j] * (tp[j] - tm[j]) / (2.0 * h);
        }
    }
    a.try_inverse().ok_or_else(|| equilibrium_failure(model, q_eff, compliance, payload_kg))
}

/// The joint values at which compliant joints hold their load: the solution of
/// `q = q0 - C tau(q)` with `C = diag(compliance)` (one per joint, rad/(N m) or m/N; zero for a
/// stiff joint) and `tau` the [`holding_torques`] with `payload_kg`, by fixed-point iteration
/// from `q0` to a change below [`EQUILIBRIUM_TOLERANCE`]. The iteration contracts by the largest
/// `c_j d tau_j / d q_j` (gravity stiffness); when an iteration's change does not shrink, or
/// after [`EQUILIBRIUM_MAX_ITERATIONS`], Newton's method takes over from `q0`; when that fails
/// too, it stops with [`CalibError::Equilibrium`] naming the joint with the largest such factor.
pub fn compliance_equilibrium(model: &RobotModel, q0: &[f64], compliance: &[f64], payload_kg: f64) -> Result<Vec<f64>> {
    if compliance.len() != q0.len() {
        return Err(CalibError::Data(format!(
            "compliance equilibrium: {} compliances for {} joints",
            compliance.len(),
            q0.len()
        )));
    }
    if compliance.iter().all(|c| *c == 0.0) {
        return Ok(q0.to_vec());
    }
    let next = |q: &[f64]| -> Result<Vec<f64>> {
        let tau = holding_torques(model, q, payload_kg)?;
        Ok(q0.iter().zip(compliance).zip(&tau).map(|((a, c), t)| a - c * t).collect())
    };
    let change = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
    let mut q = q0.to_vec();
    let mut last = f64::INFINITY;
    for _ in 0..EQUILIBRIUM_MAX_ITERATIONS {
        let q_new = next(&q)?;
        let d = change(&q_new, &q);
        q = q_new;
        if d <= EQUILIBRIUM_TOLERANCE {
            return Ok(q);
        }
        if d.is_nan() || d >= last {
            break;
        }
        last = d;
    }
    // The iteration contracts only when every mode of `C K` is below 1 in size; with several
    // compliant joints coupled through the torques (a torso under two arms) it can stall where
    // the equilibrium is still well defined. Newton's method on `q - q0 + C tau(q) = 0` solves
    // those; it fails only when `I + C K` is singular or the steps do not shrink (the structure
    // would buckle under its own weight).
    equilibrium_newton(model, q0, compliance, payload_kg)
        .ok_or_else(|| equilibrium_failure(model, &q, compliance, payload_kg))
}

/// Newton's method for [`compliance_equilibrium`] from `q0` (the Jacobian `I + C K` by central
/// differences, as [`equilibrium_sensitivity`]); `None` when it does not converge.
fn equilibrium_newton(model: &RobotModel, q0: &[f64], compliance: &[f64], payload_kg: f64) -> Option<Vec<f64>> {
    let n = q0.len();
    let mut q = q0.to_vec();
    let mut last = f64::INFINITY;
    for _ in 0..EQUILIBRIUM_MAX_ITERATIONS {
        let tau = holding_torques(model, &q, payload_kg).ok()?;
        let f = DVector::from_fn(n, |j, _| q[j] - q0[j] + compliance[j] * tau[j]);
        let jac = equilibrium_sensitivity(model, &q, compliance, payload_kg).ok()?;
        let step = jac * f;
        let d = step.amax();
        for (qj, s) in q.iter_mut().zip(step.iter()) {
            *qj -= s;
        }
        let deflection = q.iter().zip(q0).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        if deflection > EQUILIBRIUM_MAX_DEFLECTION {
            // A joint turned that far has fallen, not deflected: no linear compliance means it.
            return None;
        }
        if d <= EQUILIBRIUM_TOLERANCE {
            return Some(q);
        }
        if !d.is_finite() || (d >= last && d > 1e3 * EQUILIBRIUM_TOLERANCE) {
            return None;
        }
        last = d;
    }
    None
}

/// The error of a diverging equilibrium: the joint with the largest compliance times gravity
/// stiffness (central differences of the holding torque).
fn equilibrium_failure(model: &RobotModel, q: &[f64], compliance: &[f64], payload_kg: f64) -> CalibError {
    let h = 1e-6;
    let factor = |j: usize| -> f64 {
        let mut qp = q.to_vec();
        qp[j] += h;
        let mut qm = q.to_vec();
        qm[j] -= h;
        match (holding_torques(model, &qp, payload_kg), holding_torques(model, &qm, payload_kg)) {
            (Ok(a), Ok(b)) => compliance[j] * (a[j] - b[j]) / (2.0 * h),
            _ => f64::NAN,
        }
    };
    let (j, f) = (0..q.len())
        .filter(|&j| compliance[j] != 0.0)
        .map(|j| (j, factor(j)))
        .filter(|(_, f)| f.is_finite())
        .fold((0, f64::NAN), |best, (j, f)| if best.1.is_nan() || f.abs() > best.1.abs() { (j, f) } else { best });
    let names = model.joint_names();
    CalibError::Equilibrium { joint: j + 1, name: names.get(j).cloned().unwrap_or_default(), factor: f }
}

#[cfg(test)]
#[path = "effects_tests.rs"]
mod tests;
