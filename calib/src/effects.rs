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
//! | `joint_compliance` | `c` (rad/(N m) or m/N) | `dq_j = -c tau_j(q, payload)`, `tau` the holding torque from the model's inertials (a serial chain's links, or 1 kg at the tool for other models, when `c` then absorbs the mass) |
//! | `backlash` | `b` (rad or m) | `dq_j = -b d_j / 2`, `d_j` the approach direction |
//! | `joint_scale_error` | `s` | `dq_j = s q_j` |
//! | `periodic_joint_error` | `a, b` (rad or m), period `P` fixed | `dq_j = a sin(2 pi q_j / P) + b cos(2 pi q_j / P)` |
//! | `thermal_expansion` | `alpha` (1/K) | every length scales by `1 + alpha (T - T_ref)`: the target position in the model's base frame scales by that factor |
//! | `time_drift` | `v` (per hour) | as thermal expansion with `t` in hours instead of `T - T_ref` |
//! | `coupled_transmission` | `c` (joint units of `J` per joint unit of `K`) | `dq_J = c q_K`: joint `J`'s transmission is coupled to joint `K`'s motion (a wrist whose motors sit on an earlier link, a cable passing a joint) |
//! | `axis_misalignment` | `c_x, c_y` (rad) | revolute joint `J`'s axis wobbles with its angle: everything beyond the joint turns about the joint's axis point by the rotation vector `c_x e_1(q) + c_y e_2(q)`, `e_1 = cos 2q u + sin 2q v`, `e_2 = -sin 2q u + cos 2q v` with `(u, v)` normal to the axis and fixed on the joint's stationary side ([`axis_wobble`]): a tilt of amplitude `hypot(c_x, c_y)` whose direction turns once per revolution relative to the moving link (twice relative to the stationary side) |
//!
//! Why that form of axis misalignment: a tilt of the axis fixed on the stationary side is a
//! different axis direction, and a tilt fixed on the moving link (its direction turning once per
//! revolution as seen from the stationary side) is a different link frame: both are geometric
//! parameters (as in spindle metrology, where the once-per-revolution tilt is the artefact's
//! misalignment, not the axis's error motion). The lowest wobble the geometry cannot absorb turns
//! with the joint as seen from the link, i.e. at twice the joint's rate as seen from the base.

use ferrocal_robot::{JointKind, Kinematics, RobotModel, Unit};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

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
        }
    }

    /// Whether the effect moves the predicted pose rigidly ([`EffectSpec::pose_correction`])
    /// rather than changing joint values or lengths.
    pub fn corrects_pose(&self) -> bool {
        matches!(self, EffectSpec::LinkCompliance { .. } | EffectSpec::AxisMisalignment { .. })
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
            EffectSpec::ThermalExpansion { .. } | EffectSpec::TimeDrift | EffectSpec::LinkCompliance { .. } => None,
        }
    }

    /// The joints a report names for it: the joint of a joint effect, the two joints a link
    /// connects for link compliance, none for length changes.
    pub fn joints_reported(&self) -> Vec<usize> {
        match self {
            EffectSpec::LinkCompliance { link } => vec![*link, link + 1],
            EffectSpec::CoupledTransmission { joint, driver } => vec![*joint, *driver],
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

    /// Adds the effect's joint corrections for `row` to `dq`.
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
    if joint == 0 || joint > chain.joints.len() {
        return Err(CalibError::Data(format!("axis_misalignment: joint {joint} does not exist")));
    }
    let i = joint - 1;
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
    let (s, c) = (2.0 * q[i]).sin_cos();
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
