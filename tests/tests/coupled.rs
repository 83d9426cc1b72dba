//! A coupled robot (URDF `<mimic>`) with gravity sag, calibrated with `joint_compliance` on every
//! loaded joint through the library and through `ferrocal calibrate` / `ferrocal evaluate`.
//!
//! Simulated; the simulator computes the same physics with independently written code: its own
//! forward kinematics (homogeneous transforms composed here from the joint origins, not the robot
//! crate's chain), its own holding torques (central differences of the potential energy in the
//! actuated coordinates, not the Jacobian transpose), and the compliance truth solved by
//! iterating the equilibrium `q = q_cmd + offset - C tau(q)` to 1e-11 rad. The arm: a yaw joint,
//! shoulder and elbow pitch, a passive pitch joint coupled to the elbow (`q4 = -0.6 q3 + 0.05`,
//! a parallelogram-like linkage; the truth's multiplier is 1 % off, -0.606), wrist pitch and
//! roll; links of 1-4 kg; 300 poses, 0.5 mm motion-capture noise per axis, every fourth pose
//! held out. Truth geometry: mm-level origin errors, mrad-level origin rotations and zero
//! offsets; compliances giving 25 mrad of sag at the largest torque of each loaded joint.

use std::path::Path;

use ferrocal_calib::effects::EffectSpec;
use ferrocal_calib::kinematic::{calibrate, KinematicOptions};
use ferrocal_calib::PoseMeasurement;
use ferrocal_robot::serial::{parse_urdf_str, UrdfOptions};
use ferrocal_robot::RobotModel;
use ferrocal_tests::{ferrocal, json, ok};
use nalgebra::{Matrix3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Noise per axis (m).
const SIGMA_M: f64 = 0.5e-3;
/// Mimic coupling of the nominal model: `q4 = M q3 + O`.
const M: f64 = -0.6;
const O: f64 = 0.05;

/// One joint of the simulator: origin translation and rpy in the parent link, axis, the link's
/// mass and centre of mass.
#[derive(Clone)]
struct SimJoint {
    xyz: Vector3<f64>,
    rpy: Vector3<f64>,
    axis: Vector3<f64>,
    mass: f64,
    com: Vector3<f64>,
}

/// The nominal arm (physical joint order; joint 4 is the mimic joint).
fn nominal_joints() -> Vec<SimJoint> {
    let j = |xyz: [f64; 3], axis: [f64; 3], mass: f64, com: [f64; 3]| SimJoint {
        xyz: Vector3::from(xyz),
        rpy: Vector3::zeros(),
        axis: Vector3::from(axis),
        mass,
        com: Vector3::from(com),
    };
    vec![
        j([0.0, 0.0, 0.30], [0.0, 0.0, 1.0], 4.0, [0.0, 0.0, 0.05]),
        j([0.0, 0.0, 0.10], [0.0, 1.0, 0.0], 3.0, [0.20, 0.0, 0.0]),
        j([0.40, 0.0, 0.0], [0.0, 1.0, 0.0], 2.5, [0.17, 0.0, 0.0]),
        j([0.35, 0.0, 0.0], [0.0, 1.0, 0.0], 2.0, [0.12, 0.0, 0.0]),
        j([0.25, 0.0, 0.0], [0.0, 1.0, 0.0], 1.5, [0.05, 0.0, 0.01]),
        j([0.10, 0.0, 0.0], [1.0, 0.0, 0.0], 1.0, [0.04, 0.02, 0.0]),
    ]
}

/// The tool point in the last link (nominal).
const TOOL: [f64; 3] = [0.08, 0.02, 0.03];

/// The nominal arm as URDF.
fn urdf() -> String {
    let mut s = String::from("<robot name=\"coupled_arm\">\n  <link name=\"base\"/>\n");
    let joints = nominal_joints();
    for (i, j) in joints.iter().enumerate() {
        s.push_str(&format!(
            "  <link name=\"l{}\"><inertial><origin xyz=\"{} {} {}\"/><mass value=\"{}\"/>\
             <inertia ixx=\"0.01\" iyy=\"0.01\" izz=\"0.01\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>\n",
            i + 1,
            j.com.x,
            j.com.y,
            j.com.z,
            j.mass
        ));
    }
    s.push_str("  <link name=\"tool0\"/>\n");
    for (i, j) in joints.iter().enumerate() {
        let parent = if i == 0 { "base".to_string() } else { format!("l{i}") };
        let mimic =
            if i == 3 { format!("<mimic joint=\"j3\" multiplier=\"{M}\" offset=\"{O}\"/>") } else { String::new() };
        s.push_str(&format!(
            "  <joint name=\"j{}\" type=\"revolute\"><parent link=\"{parent}\"/><child link=\"l{}\"/>\
             <origin xyz=\"{} {} {}\" rpy=\"0 0 0\"/><axis xyz=\"{} {} {}\"/><limit lower=\"-3.1\" upper=\"3.1\"/>{mimic}</joint>\n",
            i + 1,
            i + 1,
            j.xyz.x,
            j.xyz.y,
            j.xyz.z,
            j.axis.x,
            j.axis.y,
            j.axis.z
        ));
    }
    s.push_str(&format!(
        "  <joint name=\"tool\" type=\"fixed\"><parent link=\"l6\"/><child link=\"tool0\"/><origin xyz=\"{} {} {}\"/></joint>\n</robot>\n",
        TOOL[0], TOOL[1], TOOL[2]
    ));
    s
}

/// A rigid transform as rotation and translation.
#[derive(Clone, Copy)]
struct Tf(Matrix3<f64>, Vector3<f64>);

impl Tf {
    fn then(&self, o: &Tf) -> Tf {
        Tf(self.0 * o.0, self.0 * o.1 + self.1)
    }
    fn apply(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.0 * p + self.1
    }
}

/// Rotation by `angle` about unit `axis` (Rodrigues).
fn rot(axis: &Vector3<f64>, angle: f64) -> Matrix3<f64> {
    let k = Matrix3::new(0.0, -axis.z, axis.y, axis.z, 0.0, -axis.x, -axis.y, axis.x, 0.0);
    Matrix3::identity() + k * angle.sin() + k * k * (1.0 - angle.cos())
}

/// URDF's fixed-axis roll-pitch-yaw: `Rz(yaw) Ry(pitch) Rx(roll)`.
fn rpy(r: &Vector3<f64>) -> Matrix3<f64> {
    rot(&Vector3::z(), r.z) * rot(&Vector3::y(), r.y) * rot(&Vector3::x(), r.x)
}

/// The true robot.
struct Truth {
    joints: Vec<SimJoint>,
    tool: Vector3<f64>,
    multiplier: f64,
    mimic_offset: f64,
    /// Zero offsets of the five actuated joints.
    offsets: [f64; 5],
    /// Compliances of the five actuated joints (rad/(N m)).
    compliance: [f64; 5],
    device: Tf,
}

impl Truth {
    /// Every joint's angle from the five actuated ones.
    fn all(&self, q: &[f64; 5]) -> [f64; 6] {
        [q[0], q[1], q[2], self.multiplier * q[2] + self.mimic_offset, q[3], q[4]]
    }

    /// Link frames (after each joint's motion) in the base frame.
    fn links(&self, q: &[f64; 5]) -> Vec<Tf> {
        let a = self.all(q);
        let mut t = Tf(Matrix3::identity(), Vector3::zeros());
        let mut out = Vec::new();
        for (j, qi) in self.joints.iter().zip(a) {
            t = t.then(&Tf(rpy(&j.rpy), j.xyz)).then(&Tf(rot(&j.axis, qi), Vector3::zeros()));
            out.push(t);
        }
        out
    }

    /// The tool point in the base frame.
    fn tool_point(&self, q: &[f64; 5]) -> Vector3<f64> {
        self.links(q)[5].apply(&self.tool)
    }

    /// Potential energy of the links under 9.80665 m/s^2 along -z of the base.
    fn energy(&self, q: &[f64; 5]) -> f64 {
        let links = self.links(q);
        self.joints.iter().zip(&links).map(|(j, l)| j.mass * 9.80665 * l.apply(&j.com).z).sum()
    }

    /// Holding torques of the actuated joints: `dV/dq` by central differences (a step of 1e-4
    /// rad: truncation 1e-9 relative, rounding 1e-11 N m).
    fn torques(&self, q: &[f64; 5]) -> [f64; 5] {
        let h = 1e-4;
        std::array::from_fn(|k| {
            let (mut p, mut m) = (*q, *q);
            p[k] += h;
            m[k] -= h;
            (self.energy(&p) - self.energy(&m)) / (2.0 * h)
        })
    }

    /// The joints where the drives hold the load: `q = q_cmd + offset - C tau(q)`, iterated.
    fn equilibrium(&self, q_cmd: &[f64; 5]) -> [f64; 5] {
        let q0: [f64; 5] = std::array::from_fn(|k| q_cmd[k] + self.offsets[k]);
        let mut q = q0;
        for _ in 0..200 {
            let tau = self.torques(&q);
            let next: [f64; 5] = std::array::from_fn(|k| q0[k] - self.compliance[k] * tau[k]);
            let d = (0..5).map(|k| (next[k] - q[k]).abs()).fold(0.0, f64::max);
            q = next;
            if d < 1e-11 {
                return q;
            }
        }
        panic!("the simulator's equilibrium did not converge");
    }
}

/// One simulated row: commanded joints, measured point (device frame, m), noise, held out.
struct Row {
    q: [f64; 5],
    p: Vector3<f64>,
    noise: Vector3<f64>,
    test: bool,
}

/// The truth and 300 rows (deterministic).
fn simulate() -> (Truth, Vec<Row>) {
    let mut rng = ChaCha8Rng::seed_from_u64(28);
    let mut joints = nominal_joints();
    for j in &mut joints {
        j.xyz += Vector3::from_fn(|_, _| rng.random_range(-1.0e-3..1.0e-3));
        j.rpy += Vector3::from_fn(|_, _| rng.random_range(-1.5e-3..1.5e-3));
    }
    let mut truth = Truth {
        joints,
        tool: Vector3::from(TOOL) + Vector3::new(0.4e-3, -0.3e-3, 0.5e-3),
        multiplier: M * 1.01,
        mimic_offset: O + 2e-3,
        offsets: std::array::from_fn(|_| rng.random_range(-3e-3..3e-3)),
        compliance: [0.0; 5],
        device: Tf(rot(&Vector3::new(0.1, 0.2, 0.97).normalize(), 0.5), Vector3::new(1.8, -0.6, 0.4)),
    };
    let lo = [-2.5, -1.0, -1.4, -1.4, -3.0];
    let hi = [2.5, 1.3, 1.4, 1.4, 3.0];
    let qs: Vec<[f64; 5]> = (0..300).map(|_| std::array::from_fn(|k| rng.random_range(lo[k]..hi[k]))).collect();
    // 25 mrad of sag at each loaded joint's largest holding torque over the poses.
    let mut peak = [0.0f64; 5];
    for q in &qs {
        for (p, t) in peak.iter_mut().zip(truth.torques(q)) {
            *p = p.max(t.abs());
        }
    }
    // Joint 1's axis is vertical but for the origins' mrad tilts: it carries next to nothing.
    assert!(peak[0] < 0.1 && peak[1] > 10.0, "peak torques {peak:?} N m");
    truth.compliance = std::array::from_fn(|k| if k == 0 { 0.0 } else { 25e-3 / peak[k] });
    let normal = Normal::new(0.0, SIGMA_M).unwrap();
    let rows = qs
        .iter()
        .enumerate()
        .map(|(i, q)| {
            let q_eff = truth.equilibrium(q);
            let noise = Vector3::from_fn(|_, _| normal.sample(&mut rng));
            let p = truth.device.apply(&truth.tool_point(&q_eff)) + noise;
            Row { q: *q, p, noise, test: i % 4 == 3 }
        })
        .collect();
    (truth, rows)
}

fn rms_mm(v: impl Iterator<Item = Vector3<f64>>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), e| (s + e.norm_squared(), n + 1));
    (s / n as f64).sqrt() * 1e3
}

/// The held-out RMS of the true model: the noise on the held-out rows (mm).
fn truth_rms(rows: &[Row]) -> f64 {
    rms_mm(rows.iter().filter(|r| r.test).map(|r| r.noise))
}

fn measurements(rows: &[Row]) -> Vec<PoseMeasurement> {
    rows.iter()
        .enumerate()
        .map(|(i, r)| {
            let mut m = PoseMeasurement::new(format!("p{i}"), r.q.to_vec(), r.p);
            m.split = Some(if r.test { ferrocal_calib::Split::Test } else { ferrocal_calib::Split::Train });
            m
        })
        .collect()
}

fn effects() -> Vec<EffectSpec> {
    (2..=5).map(|joint| EffectSpec::JointCompliance { joint }).collect()
}

#[test]
fn simulated_coupled_arm_library_calibration_finds_the_sag() {
    let (truth, rows) = simulate();
    let chain = parse_urdf_str(&urdf(), &UrdfOptions::default()).unwrap();
    let model = RobotModel::Serial(chain);
    let all = measurements(&rows);
    let train: Vec<&PoseMeasurement> = all.iter().filter(|r| r.split == Some(ferrocal_calib::Split::Train)).collect();
    let test: Vec<&PoseMeasurement> = all.iter().filter(|r| r.split == Some(ferrocal_calib::Split::Test)).collect();
    let floor = truth_rms(&rows);
    let geo_opts = KinematicOptions { sigma_position_m: SIGMA_M, ..KinematicOptions::default() };
    let geo = calibrate(&model, &train, &geo_opts).unwrap();
    let geo_held = geo.calibrated.evaluate(&test).unwrap().rms_mm;
    let opts = KinematicOptions { effects: effects(), ..geo_opts.clone() };
    let cal = calibrate(&model, &train, &opts).unwrap();
    let held = cal.calibrated.evaluate(&test).unwrap().rms_mm;
    eprintln!(
        "coupled arm (simulated), held-out RMS: true model (noise) {floor:.4} mm, geometric {geo_held:.4} mm, with joint_compliance:2-5 {held:.4} mm; training {:.4} mm, s0 {:.3}",
        cal.train_after.rms_mm, cal.s0
    );
    eprintln!("  solver: {:?} after {} iterations", cal.summary.termination, cal.summary.iterations);
    assert!(held <= 1.15 * floor, "held-out RMS {held:.4} mm vs the true model's {floor:.4} mm");
    assert!(geo_held > 1.5 * held, "the geometric calibration ({geo_held:.4} mm) should miss the sag");
    for joint in 2..=5 {
        let name = format!("joint{joint}.compliance_rad_per_nm");
        let p = cal.params.iter().find(|p| p.name == name).unwrap_or_else(|| panic!("{name}"));
        let want = truth.compliance[joint - 1];
        assert!(p.free, "{name} was fixed: {p:?}");
        let sd = p.std.unwrap_or(f64::INFINITY);
        eprintln!("  {name}: {:.4e} +- {sd:.1e} (truth {want:.4e}, {:+.1} %)", p.value, 100.0 * (p.value / want - 1.0));
        assert!(
            (p.value - want).abs() <= (3.0 * sd).max(0.1 * want),
            "{name}: {:.4e} +- {sd:.1e}, truth {want:.4e}",
            p.value
        );
    }
    let coupling = cal.params.iter().find(|p| p.name == "mimic1.coupling").expect("mimic1.coupling");
    eprintln!(
        "  mimic1.coupling: {:.5} +- {:.1e} (truth {:.5}, nominal {M})",
        coupling.value,
        coupling.std.unwrap_or(f64::NAN),
        truth.multiplier
    );
    assert!(coupling.free && (coupling.value - truth.multiplier).abs() < 1e-3, "{coupling:?}");
}

fn write_table(path: &Path, rows: &[Row], only_test: bool) {
    let mut s = String::from("pose_id,q1_rad,q2_rad,q3_rad,q4_rad,q5_rad,x_m,y_m,z_m,split\n");
    for (i, r) in rows.iter().enumerate().filter(|(_, r)| !only_test || r.test) {
        let q: Vec<String> = r.q.iter().map(|v| format!("{v:.17e}")).collect();
        s.push_str(&format!(
            "p{i},{},{:.17e},{:.17e},{:.17e},{}\n",
            q.join(","),
            r.p.x,
            r.p.y,
            r.p.z,
            if r.test { "test" } else { "train" }
        ));
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn simulated_coupled_arm_binary_calibrate_and_evaluate() {
    let (_, rows) = simulate();
    let tmp = tempfile::tempdir().unwrap();
    let robot = tmp.path().join("coupled_arm.urdf");
    std::fs::write(&robot, urdf()).unwrap();
    let table = tmp.path().join("coupled.csv");
    let test = tmp.path().join("coupled_test.csv");
    write_table(&table, &rows, false);
    write_table(&test, &rows, true);
    let floor = truth_rms(&rows);
    let run = |effects: Option<&str>, name: &str| -> f64 {
        let cal = tmp.path().join(format!("{name}.json"));
        let mut cmd = ferrocal();
        cmd.args(["calibrate", "--robot"]).arg(&robot).arg("--measurements").arg(&table);
        // --keep: the geometric-only fit is meant to be poor (its verdict fails); the numbers
        // are what this test compares.
        cmd.args(["--sigma-mm", "0.5", "--keep", "--out"]).arg(&cal);
        if let Some(e) = effects {
            cmd.args(["--effects", e]);
        }
        ok(&mut cmd);
        let out = tmp.path().join(format!("{name}_eval.json"));
        ok(ferrocal()
            .args(["evaluate", "--robot"])
            .arg(&robot)
            .arg("--calibration")
            .arg(&cal)
            .arg("--measurements")
            .arg(&test)
            .arg("--json")
            .arg(&out)
            .arg("--keep"));
        let e = json(&out);
        assert_eq!(e["n"].as_u64(), Some(75));
        e["rms_mm"].as_f64().unwrap()
    };
    let geo = run(None, "geo");
    let comp = run(Some("joint_compliance:2,joint_compliance:3,joint_compliance:4,joint_compliance:5"), "comp");
    eprintln!(
        "coupled arm (simulated) through the binary, held-out RMS: true model {floor:.4} mm, geometric {geo:.4} mm, with compliance {comp:.4} mm"
    );
    assert!(comp <= 1.15 * floor, "held-out RMS {comp:.4} mm vs the true model's {floor:.4} mm");
    assert!(geo > 1.5 * comp, "geometric {geo:.4} mm vs compliant {comp:.4} mm");
}

/// The branched humanoid-class robot (`ferrocal_datasets::sim::humanoid`: a torso with a coupled
/// pitch joint carrying two arms, the left hand measured, the right arm's weight on the torso),
/// simulated apart from the analysis (`sim::tree`). `ferrocal calibrate --effects` with
/// `joint_compliance` on every loaded joint (2 to 10; joint 1 is a vertical yaw) through its URDF
/// against the geometric fit and the true model's held-out error (the noise).
#[test]
fn simulated_branched_humanoid_binary_calibrate_with_compliance_on_every_loaded_joint() {
    let rec = ferrocal_datasets::sim::humanoid::recording(81, 400, true).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let robot = tmp.path().join("humanoid.urdf");
    std::fs::write(&robot, &rec.urdf).unwrap();
    let write = |path: &Path, only_test: bool| {
        let n = rec.rows[0].q.len();
        let mut s: Vec<String> = (1..=n).map(|k| format!("q{k}_rad")).collect();
        s.insert(0, "pose_id".into());
        let mut text = s.join(",") + ",x_m,y_m,z_m,split\n";
        for r in rec.rows.iter().filter(|r| !only_test || r.split == Some(ferrocal_calib::Split::Test)) {
            let q: Vec<String> = r.q.iter().map(|v| format!("{v:.17e}")).collect();
            let split = if r.split == Some(ferrocal_calib::Split::Test) { "test" } else { "train" };
            let p = r.position_m;
            text.push_str(&format!("{},{},{:.17e},{:.17e},{:.17e},{split}\n", r.pose_id, q.join(","), p.x, p.y, p.z));
        }
        std::fs::write(path, text).unwrap();
    };
    let (table, test) = (tmp.path().join("humanoid.csv"), tmp.path().join("humanoid_test.csv"));
    write(&table, false);
    write(&test, true);
    let run = |effects: Option<String>, name: &str| -> f64 {
        let cal = tmp.path().join(format!("{name}.json"));
        let mut cmd = ferrocal();
        cmd.args(["calibrate", "--robot"]).arg(&robot).arg("--measurements").arg(&table);
        cmd.args(["--sigma-mm", "0.75", "--keep", "--out"]).arg(&cal);
        if let Some(e) = &effects {
            cmd.args(["--effects", e]);
        }
        ok(&mut cmd);
        let out = tmp.path().join(format!("{name}_eval.json"));
        ok(ferrocal()
            .args(["evaluate", "--robot"])
            .arg(&robot)
            .arg("--calibration")
            .arg(&cal)
            .arg("--measurements")
            .arg(&test)
            .args(["--keep", "--json"])
            .arg(&out));
        let e = json(&out);
        assert_eq!(e["n"].as_u64(), Some(100));
        e["rms_mm"].as_f64().unwrap()
    };
    let geo = run(None, "geo");
    let all: Vec<String> = (2..=10).map(|j| format!("joint_compliance:{j}")).collect();
    let comp = run(Some(all.join(",")), "comp");
    let floor = rec.truth_held_out_mm;
    eprintln!(
        "branched humanoid (simulated) through the binary, held-out RMS: true model {floor:.4} mm, geometric {geo:.4} mm, joint_compliance:2-10 {comp:.4} mm"
    );
    assert!(comp <= 1.15 * floor, "held-out RMS {comp:.4} mm vs the true model's {floor:.4} mm");
    assert!(geo > 3.0 * comp, "geometric {geo:.4} mm vs compliant {comp:.4} mm");
}
