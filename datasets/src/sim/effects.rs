//! The true robot of the simulated cell: a nominal model with geometric errors, and optional
//! non-geometric effects. Every effect is off unless configured.
//!
//! This is the simulator's own description of the physics. The `diagnose` analysis in
//! `ferrocal-calib` models the same effects independently (no code is shared), so that a bug in
//! one is not mirrored in the other.
//!
//! # Equations
//! The robot is commanded `q_cmd` and reaches the pose `T = FK(p_true + dp(q_cmd, c), q_eff)`:
//! the forward kinematics of the nominal model with parameters `p_true` (nominal plus geometric
//! errors) plus condition-dependent parameter changes `dp`, at effective joint values `q_eff`.
//! For joint `i` (SI joint units: rad or m), with conditions `c` (time `t`, temperature `T_c`,
//! payload `m_p`, approach direction `d_i` = +1/-1/0):
//!
//! | effect | equation |
//! | --- | --- |
//! | joint scale error | `q_eff,i = (1 + s_i) q_i` |
//! | periodic joint error | `q_eff,i += A_i sin(2 pi q_i / P_i + phi_i)` |
//! | backlash | `q_eff,i -= d_i b_i / 2` (the joint stops short by half the dead band `b_i`) |
//! | joint compliance | `q_eff,i -= k_i tau_i(q, m_p)`, `tau_i = dV/dq_i`, `V = -sum_bodies m g . p_com(q)` |
//! | thermal expansion | every length parameter `l` becomes `l (1 + alpha (T_c - T_ref))` |
//! | parameter drift (guideway misalignment) | parameter `p_j += a q_i + b q_i^2` |
//! | coupled transmission | `q_eff,i += c q_k`: joint `i` turns by `c` per unit of joint `k`'s commanded motion (its drive passes through joint `k`) |
//! | axis wobble (axis misalignment) | everything beyond revolute joint `i` turns about the joint's axis point by `a (cos(q_i + phi) x_i + sin(q_i + phi) y_i)`, `x_i, y_i` unit vectors normal to the axis fixed in the moving link `i` |
//!
//! Joint compliance uses the holding torque `tau = dV/dq` of the potential energy, computed here
//! by central differences of `V` (an independent route from the Jacobian-transpose formula of
//! the robot crate). Its sign: a joint carrying a holding torque `tau` deflects by `-k tau`, i.e.
//! it sags in the direction gravity pulls.

use ferrocal_robot::{JointKind, Kinematics, Parameterized, Pose, RobotModel, Unit};
use nalgebra::{Point3, Vector3};
use rand::Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

use crate::error::DatasetError;

/// Sizes of the random geometric errors added to the nominal parameters (one standard
/// deviation per parameter, by unit).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeometricErrors {
    /// Length parameters.
    #[serde(default)]
    pub length_sigma_mm: f64,
    /// Angle parameters.
    #[serde(default)]
    pub angle_sigma_mrad: f64,
    /// Dimensionless parameters (direction components, scales).
    #[serde(default)]
    pub dimensionless_sigma: f64,
    /// Parameters left exactly nominal (by name prefix, e.g. `base.` or `tool.`).
    #[serde(default)]
    pub keep_nominal: Vec<String>,
    /// Explicit offsets added after the random ones, by parameter name (SI units).
    #[serde(default)]
    pub offsets: std::collections::BTreeMap<String, f64>,
}

impl Default for GeometricErrors {
    fn default() -> Self {
        Self {
            length_sigma_mm: 0.0,
            angle_sigma_mrad: 0.0,
            dimensionless_sigma: 0.0,
            keep_nominal: Vec::new(),
            offsets: Default::default(),
        }
    }
}

/// One non-geometric effect of the true robot. Joint numbers are 1-based.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Effect {
    /// `q_eff = (1 + scale_error) q`.
    JointScaleError {
        /// Joint (1-based).
        joint: usize,
        /// Relative scale error.
        scale_error: f64,
    },
    /// `q_eff += amplitude sin(2 pi q / period + phase)`.
    PeriodicJointError {
        /// Joint (1-based).
        joint: usize,
        /// Amplitude in joint units (rad or m).
        amplitude_si: f64,
        /// Period in joint units (rad or m).
        period_si: f64,
        /// Phase.
        #[serde(default)]
        phase_rad: f64,
    },
    /// `q_eff -= dir * width / 2`: the joint stops short by half its dead band.
    Backlash {
        /// Joint (1-based).
        joint: usize,
        /// Dead band in joint units (rad or m).
        width_si: f64,
    },
    /// `q_eff -= compliance * tau`, with `tau` the holding torque (force) under gravity and payload.
    JointCompliance {
        /// Joint (1-based).
        joint: usize,
        /// Compliance: rad/(N m) for revolute joints, m/N for prismatic ones.
        compliance_si: f64,
    },
    /// Every length parameter scales by `1 + alpha (T - reference)`.
    ThermalExpansion {
        /// Expansion coefficient, 1/K (steel: 11.5e-6, aluminium: 23e-6).
        alpha_per_k: f64,
        /// Temperature at which the parameters hold.
        reference_temp_c: f64,
    },
    /// A serial link that bends under the load it carries: everything beyond link `link` (the body
    /// joint `link` moves, 1-based) turns about the midpoint between the axis points of joints
    /// `link` and `link + 1` by `compliance * M`, with `M` gravity's moment on those bodies and
    /// the payload about joint `link + 1`'s axis point, less its component along that axis.
    LinkCompliance {
        /// Link (1-based, 1 to joints - 1).
        link: usize,
        /// Compliance, rad/(N m).
        compliance_si: f64,
    },
    /// Joint `joint` turns by `ratio` times joint `driver`'s commanded value on top of its own
    /// (its motor or cable is routed through the driving joint, and the controller does not
    /// compensate the coupling exactly): `q_eff,joint += ratio q_cmd,driver`.
    CoupledTransmission {
        /// The joint that is off (1-based).
        joint: usize,
        /// The joint whose motion drives the error (1-based).
        driver: usize,
        /// Joint units of `joint` per joint unit of `driver`.
        ratio: f64,
    },
    /// A revolute joint whose axis wobbles as it turns (a bearing seat that is not round, a
    /// housing that deflects with the angle): the link it moves, and everything beyond, is tilted
    /// by `tilt_rad` about the direction `cos(q + phase) x + sin(q + phase) y`, with `x, y` unit
    /// vectors normal to the joint's axis that turn with the link, about the joint's axis point
    /// (`q` the joint's effective angle).
    AxisWobble {
        /// Joint (1-based, revolute).
        joint: usize,
        /// Tilt, rad.
        tilt_rad: f64,
        /// Phase.
        #[serde(default)]
        phase_rad: f64,
    },
    /// A parameter that changes with a joint: `p += linear q + quadratic q^2` (a guideway that is
    /// not straight or not parallel to its nominal direction).
    ParameterDrift {
        /// Parameter name in the model's vector.
        parameter: String,
        /// Joint (1-based).
        joint: usize,
        /// Coefficient of `q`.
        #[serde(default)]
        linear: f64,
        /// Coefficient of `q^2`.
        #[serde(default)]
        quadratic: f64,
    },
}

impl Effect {
    /// The effect's name in the vocabulary of `shared/spec/diagnose.md`.
    pub fn spec_name(&self) -> &'static str {
        match self {
            Effect::JointScaleError { .. } => "joint_scale_error",
            Effect::PeriodicJointError { .. } => "periodic_joint_error",
            Effect::Backlash { .. } => "backlash",
            Effect::JointCompliance { .. } => "joint_compliance",
            Effect::ThermalExpansion { .. } => "thermal_expansion",
            Effect::ParameterDrift { .. } | Effect::AxisWobble { .. } => "axis_misalignment",
            Effect::LinkCompliance { .. } => "link_compliance",
            Effect::CoupledTransmission { .. } => "coupled_transmission",
        }
    }

    /// The 1-based joint the effect belongs to, if any.
    pub fn joint(&self) -> Option<usize> {
        match self {
            Effect::JointScaleError { joint, .. }
            | Effect::PeriodicJointError { joint, .. }
            | Effect::Backlash { joint, .. }
            | Effect::JointCompliance { joint, .. }
            | Effect::ParameterDrift { joint, .. }
            | Effect::CoupledTransmission { joint, .. }
            | Effect::AxisWobble { joint, .. } => Some(*joint),
            Effect::ThermalExpansion { .. } | Effect::LinkCompliance { .. } => None,
        }
    }
}

/// Conditions of one measurement.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Conditions {
    /// Time since the start of the session.
    pub t_s: f64,
    /// Temperature.
    pub temp_c: f64,
    /// Payload at the tool.
    pub payload_kg: f64,
    /// Approach direction per joint (+1, -1, 0).
    pub dir: Vec<i8>,
}

/// The true robot: nominal model, true parameters, effects.
#[derive(Clone, Debug)]
pub struct TrueRobot {
    /// The nominal model (what the calibration starts from).
    pub nominal: RobotModel,
    /// The model with the true geometric parameters.
    pub truth: RobotModel,
    /// Non-geometric effects.
    pub effects: Vec<Effect>,
    /// Mass of the moving platform of a parallel robot (serial arms use their link inertials).
    pub platform_mass_kg: f64,
    /// Joint compliances deflect under the torques of the deflected pose (the torque
    /// equilibrium `q = q_cmd - C tau(q)` solved by fixed-point iteration) rather than of the
    /// commanded one: the physics of an arm that sags tens of milliradians (the calibration's
    /// effect model solves the same equilibrium, written apart in `calib::effects`).
    pub compliance_equilibrium: bool,
}

impl TrueRobot {
    /// Draws the geometric errors with `rng` and validates the effects against the model.
    pub fn new(
        nominal: RobotModel,
        errors: &GeometricErrors,
        effects: Vec<Effect>,
        platform_mass_kg: f64,
        rng: &mut impl Rng,
    ) -> Result<Self, DatasetError> {
        let params = nominal.parameters();
        let n_joints = nominal.dof();
        for e in &effects {
            if let Some(j) = e.joint() {
                if j == 0 || j > n_joints {
                    return Err(DatasetError::Config(format!(
                        "effect {}: joint {j} does not exist (the robot has {n_joints} joints, numbered from 1)",
                        e.spec_name()
                    )));
                }
            }
            if let Effect::ParameterDrift { parameter, .. } = e {
                if !params.iter().any(|p| &p.name == parameter) {
                    return Err(DatasetError::Config(format!(
                        "effect axis_misalignment: the model has no parameter '{parameter}'"
                    )));
                }
            }
            if let Effect::CoupledTransmission { joint, driver, .. } = e {
                if *driver == 0 || *driver > n_joints || driver == joint {
                    return Err(DatasetError::Config(format!(
                        "coupled_transmission: driving joint {driver} must be another joint (1 to {n_joints})"
                    )));
                }
            }
            if let Effect::AxisWobble { joint, .. } = e {
                let serial = matches!(nominal, RobotModel::Serial(_));
                if !serial || nominal.joint_kinds()[joint - 1] != JointKind::Revolute {
                    return Err(DatasetError::Config(format!(
                        "axis wobble: joint {joint} must be a revolute joint of a serial chain"
                    )));
                }
            }
            if let Effect::PeriodicJointError { period_si, .. } = e {
                if !(period_si.is_finite() && *period_si > 0.0) {
                    return Err(DatasetError::Config(format!(
                        "periodic_joint_error: period must be > 0, got {period_si}"
                    )));
                }
            }
        }
        let mut values = nominal.parameter_values();
        for (v, p) in values.iter_mut().zip(&params) {
            if errors.keep_nominal.iter().any(|k| p.name.starts_with(k.as_str())) {
                continue;
            }
            let sigma = match p.unit {
                Unit::Metre => errors.length_sigma_mm * 1e-3,
                Unit::Radian => errors.angle_sigma_mrad * 1e-3,
                Unit::Dimensionless => errors.dimensionless_sigma,
                Unit::Kilogram => 0.0,
            };
            if sigma > 0.0 {
                let n = Normal::new(0.0, sigma).map_err(|e| DatasetError::Config(e.to_string()))?;
                *v += n.sample(rng);
            }
        }
        for (name, off) in &errors.offsets {
            let Some(i) = params.iter().position(|p| &p.name == name) else {
                return Err(DatasetError::Config(format!(
                    "geometric error offset: the model has no parameter '{name}'"
                )));
            };
            values[i] += off;
        }
        let mut truth = nominal.clone();
        truth
            .set_parameter_values(&values)
            .map_err(|e| DatasetError::Config(format!("true parameters rejected by the model: {e}")))?;
        Ok(Self { nominal, truth, effects, platform_mass_kg, compliance_equilibrium: false })
    }

    /// Holding torques (forces) `dV/dq` at `q` under gravity and `payload_kg`, by central
    /// differences of the potential energy.
    pub fn holding_torques(&self, model: &RobotModel, q: &[f64], payload_kg: f64) -> Result<Vec<f64>, DatasetError> {
        let v =
            |q: &[f64]| -> Result<f64, DatasetError> { potential_energy(model, q, payload_kg, self.platform_mass_kg) };
        let kinds = model.joint_kinds();
        let mut out = Vec::with_capacity(q.len());
        for i in 0..q.len() {
            let h = match kinds[i] {
                JointKind::Revolute => 1e-6,
                JointKind::Prismatic => 1e-6,
            };
            let mut qp = q.to_vec();
            let mut qm = q.to_vec();
            qp[i] += h;
            qm[i] -= h;
            out.push((v(&qp)? - v(&qm)?) / (2.0 * h));
        }
        Ok(out)
    }

    /// The holding torques at the torque equilibrium of the joint compliances: `q = q_cmd - C
    /// tau(q)` iterated from the commanded pose until the pose changes by less than 1e-9 rad (the torques' finite differences are good to
    /// about 1e-10 rad of deflection; at
    /// most 50 iterations; a compliance so large that the iteration diverges is an error).
    pub fn equilibrium_torques(
        &self,
        model: &RobotModel,
        q_cmd: &[f64],
        payload_kg: f64,
    ) -> Result<Vec<f64>, DatasetError> {
        let compliances: Vec<(usize, f64)> = self
            .effects
            .iter()
            .filter_map(|e| match e {
                Effect::JointCompliance { joint, compliance_si } => Some((joint - 1, *compliance_si)),
                _ => None,
            })
            .collect();
        let mut q = q_cmd.to_vec();
        for _ in 0..50 {
            let tau = self.holding_torques(model, &q, payload_kg)?;
            let mut next = q_cmd.to_vec();
            for &(j, c) in &compliances {
                next[j] -= c * tau[j];
            }
            let step = next.iter().zip(&q).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            q = next;
            if step < 1e-9 {
                return self.holding_torques(model, &q, payload_kg);
            }
        }
        Err(DatasetError::Config(
            "the joint compliances are too large for a torque equilibrium (the iteration does not settle)".into(),
        ))
    }

    /// The model with condition-dependent parameters for commanded joints `q_cmd`.
    pub fn model_at(&self, q_cmd: &[f64], c: &Conditions) -> Result<RobotModel, DatasetError> {
        let params = self.truth.parameters();
        let mut values: Vec<f64> = params.iter().map(|p| p.value).collect();
        let mut changed = false;
        for e in &self.effects {
            match e {
                Effect::ThermalExpansion { alpha_per_k, reference_temp_c } => {
                    let f = 1.0 + alpha_per_k * (c.temp_c - reference_temp_c);
                    for (v, p) in values.iter_mut().zip(&params) {
                        if p.unit == Unit::Metre {
                            *v *= f;
                        }
                    }
                    changed = true;
                }
                Effect::ParameterDrift { parameter, joint, linear, quadratic } => {
                    let q = q_cmd[joint - 1];
                    let i = params.iter().position(|p| &p.name == parameter).expect("validated in new()");
                    values[i] += linear * q + quadratic * q * q;
                    changed = true;
                }
                _ => {}
            }
        }
        let mut m = self.truth.clone();
        if changed {
            m.set_parameter_values(&values)
                .map_err(|e| DatasetError::Config(format!("condition-dependent parameters rejected: {e}")))?;
        }
        Ok(m)
    }

    /// Effective joint values for commanded joints `q_cmd` under conditions `c`.
    pub fn effective_joints(
        &self,
        model: &RobotModel,
        q_cmd: &[f64],
        c: &Conditions,
    ) -> Result<Vec<f64>, DatasetError> {
        let mut q = q_cmd.to_vec();
        let mut torques: Option<Vec<f64>> = None;
        for e in &self.effects {
            match e {
                Effect::JointScaleError { joint, scale_error } => q[joint - 1] += scale_error * q_cmd[joint - 1],
                Effect::PeriodicJointError { joint, amplitude_si, period_si, phase_rad } => {
                    q[joint - 1] +=
                        amplitude_si * (std::f64::consts::TAU * q_cmd[joint - 1] / period_si + phase_rad).sin();
                }
                Effect::Backlash { joint, width_si } => {
                    let d = c.dir.get(joint - 1).copied().unwrap_or(0) as f64;
                    q[joint - 1] -= d * width_si / 2.0;
                }
                Effect::CoupledTransmission { joint, driver, ratio } => {
                    q[joint - 1] += ratio * q_cmd[driver - 1];
                }
                Effect::JointCompliance { joint, compliance_si } => {
                    if torques.is_none() {
                        torques = Some(if self.compliance_equilibrium {
                            self.equilibrium_torques(model, q_cmd, c.payload_kg)?
                        } else {
                            self.holding_torques(model, q_cmd, c.payload_kg)?
                        });
                    }
                    let tau = torques.as_ref().expect("just set")[joint - 1];
                    q[joint - 1] -= compliance_si * tau;
                }
                Effect::ThermalExpansion { .. }
                | Effect::ParameterDrift { .. }
                | Effect::LinkCompliance { .. }
                | Effect::AxisWobble { .. } => {}
            }
        }
        Ok(q)
    }

    /// The true tool pose (base frame of the true model) for commanded joints under conditions.
    pub fn tool_pose(&self, q_cmd: &[f64], c: &Conditions) -> Result<Pose, DatasetError> {
        let model = self.model_at(q_cmd, c)?;
        let q = self.effective_joints(&model, q_cmd, c)?;
        let mut pose =
            model.forward(&q).map_err(|e| DatasetError::Config(format!("true forward kinematics failed: {e}")))?;
        for e in &self.effects {
            if let Effect::LinkCompliance { link, compliance_si } = e {
                pose = link_bend(&model, *link, &q, c.payload_kg, *compliance_si)? * pose;
            }
            if let Effect::AxisWobble { joint, tilt_rad, phase_rad } = e {
                pose = axis_wobble(&model, *joint, &q, *tilt_rad, *phase_rad)? * pose;
            }
        }
        Ok(pose)
    }
}

/// The rigid motion of everything beyond wobbling joint `joint` (1-based): the moving link's
/// frame after the joint's motion gives two directions normal to the axis that turn with it; the
/// tilt direction is `cos(q + phase)` and `sin(q + phase)` of them, the turn is about the axis
/// point.
fn axis_wobble(
    model: &RobotModel,
    joint: usize,
    q: &[f64],
    tilt_rad: f64,
    phase_rad: f64,
) -> Result<Pose, DatasetError> {
    let RobotModel::Serial(chain) = model else {
        return Err(DatasetError::Config("axis wobble: the model is not a serial chain".into()));
    };
    chain.require_no_mimic("the simulator's axis wobble").map_err(|e| DatasetError::Config(e.to_string()))?;
    let f = chain.frames(q).map_err(|e| DatasetError::Config(format!("kinematics failed: {e}")))?;
    let link = f.links[joint - 1].rotation;
    // The axis in the moving link's own coordinates, and two normals to it fixed in the link.
    let axis = (link.inverse() * f.axes[joint - 1]).normalize();
    let helper = if axis.z.abs() < 0.8 { Vector3::z() } else { Vector3::x() };
    let x = axis.cross(&helper).normalize();
    let y = axis.cross(&x);
    let angle = q[joint - 1] + phase_rad;
    let direction = link * (x * angle.cos() + y * angle.sin());
    let rot = nalgebra::UnitQuaternion::from_scaled_axis(direction * tilt_rad);
    let pivot = f.axis_points[joint - 1].coords;
    Ok(Pose::from_parts(nalgebra::Translation3::from(pivot - rot * pivot), rot))
}

/// Potential energy `V = -sum m g . p` of the moving bodies at `q`: the links' inertials for a
/// serial chain (plus the payload at the tool), or a platform mass plus payload at the tool.
fn potential_energy(
    model: &RobotModel,
    q: &[f64],
    payload_kg: f64,
    platform_mass_kg: f64,
) -> Result<f64, DatasetError> {
    let kin_err = |e: ferrocal_robot::RobotError| DatasetError::Config(format!("kinematics failed: {e}"));
    match model {
        RobotModel::Serial(chain) => {
            let f = chain.frames(q).map_err(kin_err)?;
            let g = Vector3::from(chain.gravity_m_s2);
            let mut v = 0.0;
            for (i, j) in chain.joints.iter().enumerate() {
                if let Some(inr) = &j.inertial {
                    let p = f.links[i] * Point3::from(inr.com_m);
                    v -= inr.mass_kg * g.dot(&p.coords);
                }
            }
            Ok(v - payload_kg * g.dot(&f.tool.translation.vector))
        }
        #[allow(unreachable_patterns)]
        other => {
            let g = Vector3::new(0.0, 0.0, -9.80665);
            let p = other.forward(q).map_err(kin_err)?.translation.vector;
            Ok(-(platform_mass_kg + payload_kg) * g.dot(&p))
        }
    }
}

/// The rigid motion of everything beyond bent link `link` (1-based): the gravity moment across
/// joint `link + 1`'s axis is taken as the derivative of the distal bodies' potential energy with
/// respect to a small turn about each of two directions normal to that axis (central
/// differences), and the bodies turn by `compliance_si` times it about the link's midpoint.
fn link_bend(
    model: &RobotModel,
    link: usize,
    q: &[f64],
    payload_kg: f64,
    compliance_si: f64,
) -> Result<Pose, DatasetError> {
    let RobotModel::Serial(chain) = model else {
        return Err(DatasetError::Config("link_compliance: the model is not a serial chain".into()));
    };
    chain.require_no_mimic("the simulator's link compliance").map_err(|e| DatasetError::Config(e.to_string()))?;
    let n = chain.joints.len();
    if link == 0 || link >= n {
        return Err(DatasetError::Config(format!(
            "link_compliance: link {link} carries no further joint (1 to {})",
            n - 1
        )));
    }
    let f = chain.frames(q).map_err(|e| DatasetError::Config(format!("kinematics failed: {e}")))?;
    let g = Vector3::from(chain.gravity_m_s2);
    let end = f.axis_points[link];
    let z = f.axes[link].normalize();
    // Distal masses: the links beyond and the payload at the tool.
    let mut bodies: Vec<(f64, Point3<f64>)> = chain
        .joints
        .iter()
        .enumerate()
        .skip(link)
        .filter_map(|(i, j)| j.inertial.as_ref().map(|inr| (inr.mass_kg, f.links[i] * Point3::from(inr.com_m))))
        .collect();
    bodies.push((payload_kg, Point3::from(f.tool.translation.vector)));
    let energy = |u: &Vector3<f64>, a: f64| -> f64 {
        let r = nalgebra::UnitQuaternion::from_scaled_axis(u * a);
        bodies.iter().map(|(m, p)| -m * g.dot(&(end.coords + r * (p - end)))).sum()
    };
    let u1 = if z.x.abs() < 0.9 { z.cross(&Vector3::x()) } else { z.cross(&Vector3::y()) }.normalize();
    let u2 = z.cross(&u1);
    let h = 1e-6;
    let mut bend = Vector3::zeros();
    for u in [u1, u2] {
        // The moment gravity exerts about `u`: minus the energy's derivative along the turn.
        let m_u = -(energy(&u, h) - energy(&u, -h)) / (2.0 * h);
        bend += u * m_u;
    }
    let pivot = (f.axis_points[link - 1].coords + end.coords) / 2.0;
    let rot = nalgebra::UnitQuaternion::from_scaled_axis(bend * compliance_si);
    Ok(Pose::from_parts(nalgebra::Translation3::from(pivot - rot * pivot), rot))
}
