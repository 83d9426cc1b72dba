//! Simulated tracker recordings for the missing-physics diagnosis: a true robot (a nominal
//! model with random geometric errors and its effects), random poses visited in order
//! (approach directions from that order), a warm-up temperature history, a payload, and a
//! laser tracker with 15 um + 6 um/m noise. Tables always carry `t_s`, `temp_c`, `dir` and
//! `payload_kg`, whatever the effect. Used by `tests/diagnose_*.rs`,
//! `examples/diagnose_study.rs` and the demo's diagnose cases.

use std::path::Path;

use crate::error::DatasetError;
use crate::sim::{make_plan, Conditions, Effect, Environment, GeometricErrors, PlanConfig, TrackerConfig, TrueRobot};
use ferrocal_calib::PoseMeasurement;
use ferrocal_robot::RobotModel;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// How the payload is set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Payload {
    /// The same mass on every pose.
    Constant(f64),
    /// A mass drawn uniformly per pose.
    Varying(f64, f64),
}

/// How the approach direction of each joint into each pose arises.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Order {
    /// The poses are visited in random order and every joint approaches its next value from
    /// where it was: `dir = sign(q_k - q_k-1)`. A joint at a high angle was then mostly
    /// approached from below, so `dir` correlates with the angle (backlash and scale error
    /// leave similar residuals).
    Random,
    /// A planned approach: before each pose every joint overshoots to one side chosen by the
    /// plan (a balanced random sign, independent of the angle) and approaches from there, so
    /// `dir` carries no information about the angle.
    Planned,
    /// Every pose is approached from the home configuration (the arm returns home between
    /// poses): `dir = sign(q - q_home)`, a step function of the angle, the hardest case for
    /// telling backlash from a scale error (correlation about 0.87 for uniform angles around
    /// home, against about 0.58 for random order).
    FromHome,
}

/// One simulated recording.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// Preset name or model path.
    pub robot: String,
    /// The effect of the true robot, if any.
    pub effect: Option<Effect>,
    /// Number of poses.
    pub n_poses: usize,
    /// Seed.
    pub seed: u64,
    /// Payload.
    pub payload: Payload,
    /// Tracker noise as a multiple of 15 um + 6 um/m.
    pub noise_scale: f64,
    /// Temperature at the start and the end of the warm-up.
    pub temp_c: (f64, f64),
    /// Whether the table carries the tracker's sigma per row.
    pub with_sigma: bool,
    /// Joint ranges of the random plan (empty: the model's limits).
    pub joint_ranges: Vec<[f64; 2]>,
    /// How the approach directions arise.
    pub order: Order,
    /// Further effects of the true robot, beside `effect`.
    pub extra_effects: Vec<Effect>,
    /// Joint compliances at the torque equilibrium of the deflected pose (see
    /// `TrueRobot::compliance_equilibrium`).
    pub compliance_equilibrium: bool,
}

impl Scenario {
    /// Defaults: 250 poses, 2 kg payload, nominal noise, 20 -> 24 C warm-up, sigma column.
    pub fn new(robot: &str, effect: Option<Effect>, seed: u64) -> Self {
        Self {
            robot: robot.to_string(),
            effect,
            n_poses: 250,
            seed,
            payload: Payload::Constant(2.0),
            noise_scale: 1.0,
            temp_c: (20.0, 24.0),
            with_sigma: true,
            joint_ranges: joint_ranges(),
            order: Order::Random,
            extra_effects: Vec::new(),
            compliance_equilibrium: false,
        }
    }
}

/// The example URDF shipped with the robot crate.
pub fn example_urdf() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../robot/models/example_arm6.urdf").display().to_string()
}

/// Joint ranges of the random plans (a working region of a 6-axis arm).
pub fn joint_ranges() -> Vec<[f64; 2]> {
    vec![[-1.5, 1.5], [-2.6, -0.5], [0.3, 2.5], [-2.5, 0.0], [0.5, 2.5], [-1.0, 1.0]]
}

/// Seconds per pose of the plans.
pub const SECONDS_PER_POSE: f64 = 12.0;

/// The tracker of the simulated cell.
pub fn tracker(noise_scale: f64) -> TrackerConfig {
    TrackerConfig {
        position_m: [2.0, 0.5, 0.2],
        rpy_deg: [0.0, 0.0, 160.0],
        sigma_const_um: 15.0 * noise_scale,
        sigma_per_m_um: 6.0 * noise_scale,
        six_dof: false,
        sigma_angle_mrad: 0.0,
        reflector_in_tool_m: [0.0, 0.0, 0.05],
    }
}

/// The recording: the nominal model and the rows.
pub fn simulate(s: &Scenario) -> (RobotModel, Vec<PoseMeasurement>) {
    let (m, rows, _) = simulate_with_truth(s);
    (m, rows)
}

/// A simulated recording: the nominal model, the rows, and the effects' displacement of the
/// measured point per row (metres).
pub type Recording = (RobotModel, Vec<PoseMeasurement>, Vec<Vector3<f64>>);

/// An effect named by its name and 1-based joints.
pub type Named = (String, Vec<usize>);

/// As [`simulate`], also returning the effect's displacement of the measured point per row
/// (panics on a scenario that cannot be simulated: for tests and studies; see
/// [`try_simulate_with_truth`]).
pub fn simulate_with_truth(s: &Scenario) -> Recording {
    match try_simulate_with_truth(s) {
        Ok(v) => v,
        Err(e) => panic!("scenario {} cannot be simulated: {e}", s.robot),
    }
}

/// The recording of `s`: the nominal model, the rows and the effects' displacement of the
/// measured point per row; an error names what cannot be simulated.
pub fn try_simulate_with_truth(s: &Scenario) -> Result<Recording, DatasetError> {
    let nominal = RobotModel::load(&s.robot).map_err(|e| DatasetError::Config(format!("robot {}: {e}", s.robot)))?;
    let mut rng = ChaCha8Rng::seed_from_u64(s.seed);
    let errors = GeometricErrors { length_sigma_mm: 0.3, angle_sigma_mrad: 0.3, ..Default::default() };
    let effects: Vec<Effect> = s.effect.iter().chain(&s.extra_effects).cloned().collect();
    let mut truth = TrueRobot::new(nominal.clone(), &errors, effects, 0.0, &mut rng)?;
    truth.compliance_equilibrium = s.compliance_equilibrium;
    let plain = TrueRobot { effects: Vec::new(), ..truth.clone() };
    let plan_cfg = PlanConfig::Random {
        n: s.n_poses,
        joint_ranges_si: s.joint_ranges.clone(),
        seconds_per_pose: SECONDS_PER_POSE,
        home_si: if s.joint_ranges.is_empty() { vec![] } else { vec![0.0, -1.5, 1.4, -1.2, 1.5, 0.0] },
    };
    let plan = make_plan(&plan_cfg, &nominal, None, &mut rng)?;
    let mut dirs = plan.directions();
    match s.order {
        Order::Random => {}
        Order::Planned => {
            for d in dirs.iter_mut() {
                for v in d.iter_mut() {
                    *v = if rng.random_bool(0.5) { 1 } else { -1 };
                }
            }
        }
        Order::FromHome => {
            for (d, q) in dirs.iter_mut().zip(&plan.poses) {
                for ((v, qi), hi) in d.iter_mut().zip(q).zip(&plan.home) {
                    *v = if qi >= hi { 1 } else { -1 };
                }
            }
        }
    }
    let env =
        Environment { temp_start_c: s.temp_c.0, temp_end_c: s.temp_c.1, warmup_tau_s: 1500.0, ..Default::default() };
    let trk = tracker(s.noise_scale);
    let t_wt = trk.t_world_tracker();
    let mut rows = Vec::with_capacity(plan.poses.len());
    let mut disp = Vec::with_capacity(plan.poses.len());
    for (k, q) in plan.poses.iter().enumerate() {
        let t_s = k as f64 * SECONDS_PER_POSE + rng.random_range(0.0..2.0);
        let payload = match s.payload {
            Payload::Constant(m) => m,
            Payload::Varying(lo, hi) => rng.random_range(lo..hi),
        };
        let c = Conditions { t_s, temp_c: env.temperature_c(t_s), payload_kg: payload, dir: dirs[k].clone() };
        let t = truth.tool_pose(q, &c)?;
        let t0 = plain.tool_pose(q, &c)?;
        let refl = nalgebra::Point3::from(Vector3::from(trk.reflector_in_tool_m));
        disp.push((t_wt.inverse() * t * refl).coords - (t_wt.inverse() * t0 * refl).coords);
        let r = trk.measure(&t, &mut rng);
        let mut m = PoseMeasurement::new(format!("{k}"), q.clone(), r.position_m);
        m.sigma_m = s.with_sigma.then_some(r.sigma_m);
        m.t_s = Some((t_s * 10.0).round() / 10.0);
        m.temp_c = Some((c.temp_c * 100.0).round() / 100.0);
        m.payload_kg = Some(payload);
        m.dir = Some(c.dir.clone());
        rows.push(m);
    }
    Ok((nominal, rows, disp))
}

/// RMS of the effect's displacements (metres).
pub fn rms(v: &[Vector3<f64>]) -> f64 {
    (v.iter().map(|d| d.norm_squared()).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// One of the demo's diagnose cases: a simulated recording shaped like a real one, what the
/// truth holds, and what `diagnose` found.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DiagnoseCase {
    /// What the case is.
    pub name: String,
    /// The true effects in words.
    pub truth: String,
    /// The effects (name, 1-based joints) a right answer names, sorted.
    pub expected: Vec<Named>,
    /// What `diagnose` named, sorted.
    pub found: Vec<Named>,
    /// Whether `found` is exactly `expected` (and, where the true model's held-out RMS is known,
    /// the findings' held-out RMS is within [`HELD_OUT_WITHIN`] of it).
    pub correct: bool,
    /// Held-out RMS of the true model (the noise on the held-out rows), mm, where the simulator
    /// knows it.
    pub truth_heldout_mm: Option<f64>,
    /// Held-out RMS of the geometric model, mm.
    pub heldout_before_mm: f64,
    /// Held-out RMS with the findings, mm.
    pub heldout_after_mm: f64,
    /// The report's top sentence.
    pub summary: String,
    /// The findings' statements.
    pub statements: Vec<String>,
}

/// A lightweight arm's sag (UR5 geometry): compliances that deflect joints 2 and 3 by 20-30 mrad
/// at the largest load (2 to 4 kg payload), at the torque equilibrium, 400 poses, motion-capture
/// noise (about 0.5 mm + 0.2 mm/m), no sigma column; without `with_sag`, its compliance-free twin.
pub fn sagging_arm(seed: u64, with_sag: bool) -> Scenario {
    let mut s = Scenario::new("ur5", None, seed);
    if with_sag {
        s.effect = Some(Effect::JointCompliance { joint: 2, compliance_si: 3.0e-4 });
        s.extra_effects = vec![Effect::JointCompliance { joint: 3, compliance_si: 7.0e-4 }];
    }
    s.compliance_equilibrium = true;
    s.n_poses = 400;
    s.noise_scale = 35.0;
    s.with_sigma = false;
    s.payload = Payload::Varying(2.0, 4.0);
    s
}

/// How close to the true model's held-out RMS a right diagnosis must come (the 1.15x).
pub const HELD_OUT_WITHIN: f64 = 1.15;

/// The seed of the demo's diagnose cases (`tests/diagnose_real_like.rs` checks them on it).
pub const DEMO_CASES_SEED: u64 = 61;

/// The cases the fixed vetoes used to miss (issue [physics-real]): a direction-dependent error
/// whose link leads (alone, and beside a compliance on another joint), an arm that sags 20-30
/// mrad on two joints under motion-capture noise at the torque equilibrium, and its
/// compliance-free twin; diagnosed with the default options.
///
/// With `with_humanoid`, also the humanoid-class torso ([`super::humanoid`]: a coupled torso
/// joint, a second arm hanging on the torso, four joints sagging 25 mrad, 400 poses) and its
/// compliance-free twin, read through the robot's URDF (about two minutes more).
pub fn diagnose_cases(seed: u64, with_humanoid: bool) -> Result<Vec<DiagnoseCase>, DatasetError> {
    use ferrocal_calib::diagnose::{diagnose, DiagnoseOptions};
    let leading = Effect::Backlash { joint: 3, width_si: -7e-4 };
    let mut cases: Vec<(String, String, Scenario, Vec<Named>)> = Vec::new();
    let s = Scenario::new("ur5", Some(leading.clone()), seed);
    cases.push((
        "leading direction-dependent error".into(),
        "joint 3's position depends on the approach direction by 0.04 deg, the link leading its reading (random visiting order)".into(),
        s,
        vec![("backlash".into(), vec![3])],
    ));
    let mut s = Scenario::new("ur5", Some(leading), seed + 1);
    s.extra_effects = vec![Effect::JointCompliance { joint: 2, compliance_si: 5e-6 }];
    cases.push((
        "leading error and a compliance".into(),
        "the same on joint 3, and joint 2 deflecting 5e-6 rad/(N m) under gravity".into(),
        s,
        vec![("backlash".into(), vec![3]), ("joint_compliance".into(), vec![2])],
    ));
    let sag = |with: bool| sagging_arm(seed + 2, with);
    cases.push((
        "sagging lightweight arm".into(),
        "joints 2 and 3 sag 20-30 mrad at the torque equilibrium; 400 poses, 0.5-1 mm motion-capture noise, no sigma column".into(),
        sag(true),
        vec![("joint_compliance".into(), vec![2]), ("joint_compliance".into(), vec![3])],
    ));
    cases.push((
        "its compliance-free twin".into(),
        "the same recording without the compliances".into(),
        sag(false),
        vec![],
    ));
    /// A case before its diagnosis.
    struct Case {
        name: String,
        truth: String,
        recording: Recording,
        expected: Vec<Named>,
        truth_heldout_mm: Option<f64>,
    }
    let mut recordings = Vec::new();
    for (name, truth, scenario, expected) in cases {
        let recording = try_simulate_with_truth(&scenario)?;
        recordings.push(Case { name, truth, recording, expected, truth_heldout_mm: None });
    }
    if with_humanoid {
        use ferrocal_robot::serial::{parse_urdf_str, UrdfOptions};
        for with_sag in [true, false] {
            let rec = super::humanoid::recording(seed + 3, 400, with_sag)?;
            let chain = parse_urdf_str(&rec.urdf, &UrdfOptions::default())
                .map_err(|e| DatasetError::Input(format!("the humanoid's URDF: {e}")))?;
            let (name, truth, expected) = if with_sag {
                (
                    "humanoid torso".to_string(),
                    "a torso with a coupled pitch joint carrying two arms, 11 joints to the measured hand; joints 2, 4, 5 and 7 sag 25 mrad (the hand up to 60 mm); 400 poses, 0.5-1 mm noise".to_string(),
                    super::humanoid::SAGGING_JOINTS.iter().map(|&j| ("joint_compliance".to_string(), vec![j])).collect(),
                )
            } else {
                ("its compliance-free twin".to_string(), "the same torso without the compliances".to_string(), vec![])
            };
            let model = ferrocal_robot::RobotModel::Serial(chain);
            let truth_heldout_mm = Some(rec.truth_held_out_mm);
            recordings.push(Case { name, truth, recording: (model, rec.rows, Vec::new()), expected, truth_heldout_mm });
        }
    }
    let mut out = Vec::new();
    for Case { name, truth, recording: (model, rows, _), mut expected, truth_heldout_mm } in recordings {
        let rep = diagnose(&model, &rows, &DiagnoseOptions::default())
            .map_err(|e| DatasetError::Input(format!("diagnose of the case '{name}': {e}")))?;
        let mut found: Vec<Named> = rep.findings.iter().map(|f| (f.effect.clone(), f.joints.clone())).collect();
        found.sort();
        expected.sort();
        let close = truth_heldout_mm.is_none_or(|t| rep.final_fit.heldout_rms_mm <= HELD_OUT_WITHIN * t);
        out.push(DiagnoseCase {
            correct: found == expected && close,
            truth_heldout_mm,
            name,
            truth,
            expected,
            found,
            heldout_before_mm: rep.nominal.heldout_rms_mm,
            heldout_after_mm: rep.final_fit.heldout_rms_mm,
            summary: rep.summary.clone(),
            statements: rep.findings.iter().map(|f| f.statement.clone()).collect(),
        });
    }
    Ok(out)
}
