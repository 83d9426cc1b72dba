//! The recipe of `docs/architecture.md` ("Adding an effect"), followed from outside the library:
//! a toy effect, a joint error growing with the square of the joint angle
//! (`dq_J = a q_J^2`), is one type implementing `ferrocal_calib::effect_registry::{Effect,
//! EffectKind}` and one `register_effect` call. No library file names it, yet the effect list
//! parses it, JSON writes and reads it, the kinematic fit identifies it jointly with the
//! geometry, and `diagnose` finds it on a simulated UR5 whose truth carries it (simulated through
//! the same trait: the calibrated model with the effect predicts the measured points).
//! The registration is process-wide: no other test of this binary runs the library's diagnose.

use std::sync::Arc;

use ferrocal_calib::diagnose::{diagnose, DiagnoseOptions};
use ferrocal_calib::effect_list::parse_effect_list;
use ferrocal_calib::effect_registry::{register_effect, CustomEffect, Effect, EffectKind};
use ferrocal_calib::effects::EffectSpec;
use ferrocal_calib::kinematic::{calibrate, CalibratedModel, KinematicOptions};
use ferrocal_calib::PoseMeasurement;
use ferrocal_robot::{JointKind, RobotModel, Unit};
use nalgebra::{Isometry3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// The toy effect: joint `joint`'s error is `a q^2`.
#[derive(Debug)]
struct Quadratic {
    joint: usize,
}

impl Effect for Quadratic {
    fn name(&self) -> &'static str {
        "toy_quadratic_joint_error"
    }
    fn settings(&self) -> serde_json::Map<String, serde_json::Value> {
        let mut m = serde_json::Map::new();
        m.insert("joint".into(), self.joint.into());
        m
    }
    fn list_fields(&self) -> Vec<String> {
        vec![self.joint.to_string()]
    }
    fn joint(&self) -> Option<usize> {
        Some(self.joint)
    }
    fn parameters(&self, _kinds: &[JointKind]) -> Vec<(String, Unit)> {
        vec![(format!("joint{}.quadratic_per_rad", self.joint), Unit::Dimensionless)]
    }
    fn scales(&self) -> Vec<f64> {
        vec![1e-4]
    }
    fn add_joint_delta(
        &self,
        _model: &RobotModel,
        row: &PoseMeasurement,
        theta: &[f64],
        dq: &mut [f64],
    ) -> ferrocal_calib::Result<()> {
        let q = row.q[self.joint - 1];
        dq[self.joint - 1] += theta[0] * q * q;
        Ok(())
    }
}

/// Its registry entry: `toy_quadratic_joint_error:J` in lists, `{"effect": ..., "joint": J}` in
/// JSON, one candidate per revolute joint in `diagnose`.
struct QuadraticKind;

impl EffectKind for QuadraticKind {
    fn name(&self) -> &'static str {
        "toy_quadratic_joint_error"
    }
    fn parse(&self, fields: &[&str]) -> Result<Arc<dyn Effect>, String> {
        match fields {
            [j] => j.parse().map(|joint| Arc::new(Quadratic { joint }) as Arc<dyn Effect>).map_err(|e| format!("{e}")),
            _ => Err("one joint number expected".into()),
        }
    }
    fn read_json(&self, value: &serde_json::Value) -> Result<Arc<dyn Effect>, String> {
        let joint = value["joint"].as_u64().ok_or("no joint")? as usize;
        Ok(Arc::new(Quadratic { joint }))
    }
    fn candidates(&self, model: &RobotModel, _rows: &[&PoseMeasurement]) -> Vec<Arc<dyn Effect>> {
        use ferrocal_robot::Kinematics;
        let kinds = model.joint_kinds();
        (1..=kinds.len())
            .filter(|j| kinds[j - 1] == JointKind::Revolute)
            .map(|joint| Arc::new(Quadratic { joint }) as Arc<dyn Effect>)
            .collect()
    }
}

const SIGMA_M: f64 = 20e-6;
const TRUE_A: f64 = 2e-3;

/// A UR5 whose joint 2 carries the toy effect, measured with 20 um noise per axis.
fn simulate(n: usize, seed: u64) -> (RobotModel, Vec<PoseMeasurement>) {
    let model = RobotModel::Serial(ferrocal_robot::presets::ur5());
    let mut truth = CalibratedModel::nominal(model.clone());
    truth.device_frame = Isometry3::new(Vector3::new(1.2, -0.3, 0.1), Vector3::new(0.0, 0.0, 0.4));
    truth.effects = vec![(EffectSpec::Custom(CustomEffect::new(Quadratic { joint: 2 })), vec![TRUE_A])];
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, SIGMA_M).unwrap();
    let rows = (0..n)
        .map(|i| {
            let q: Vec<f64> = (0..6).map(|_| rng.random_range(-1.5..1.5)).collect();
            let mut row = PoseMeasurement::new(format!("p{i}"), q, Vector3::zeros());
            let p = truth.predict_row(&row).unwrap().translation.vector;
            row.position_m = p + Vector3::from_fn(|_, _| noise.sample(&mut rng));
            row
        })
        .collect();
    (model, rows)
}

#[test]
fn a_toy_effect_added_from_outside_the_library_is_parsed_fitted_and_found() {
    register_effect(Arc::new(QuadraticKind)).unwrap();
    // A built-in name is not taken over.
    struct Impostor;
    impl EffectKind for Impostor {
        fn name(&self) -> &'static str {
            "backlash"
        }
        fn parse(&self, _: &[&str]) -> Result<Arc<dyn Effect>, String> {
            Err("no".into())
        }
        fn read_json(&self, _: &serde_json::Value) -> Result<Arc<dyn Effect>, String> {
            Err("no".into())
        }
    }
    assert!(register_effect(Arc::new(Impostor)).is_err());

    // The list and JSON spellings.
    let spec = parse_effect_list("toy_quadratic_joint_error:2").unwrap().remove(0);
    assert_eq!(spec.name(), "toy_quadratic_joint_error");
    let json = serde_json::to_value(&spec).unwrap();
    assert_eq!(json, serde_json::json!({"effect": "toy_quadratic_joint_error", "joint": 2}));
    assert_eq!(serde_json::from_value::<EffectSpec>(json).unwrap(), spec);
    let built_in = serde_json::to_value(EffectSpec::Backlash { joint: 3 }).unwrap();
    assert_eq!(built_in, serde_json::json!({"effect": "backlash", "joint": 3}));
    let e = parse_effect_list("toy_quadratic_joint_errr:2").unwrap_err().to_string();
    assert!(e.contains("unknown effect") && e.contains("toy_quadratic_joint_error"), "{e}");

    // Fitted with the geometry: the truth's value, and the held-out error at the noise.
    let (model, rows) = simulate(160, 7);
    let train: Vec<&PoseMeasurement> = rows.iter().enumerate().filter(|(i, _)| i % 4 != 0).map(|(_, r)| r).collect();
    let test: Vec<&PoseMeasurement> = rows.iter().step_by(4).collect();
    let geo_opts = KinematicOptions { sigma_position_m: SIGMA_M, ..KinematicOptions::default() };
    let geo = calibrate(&model, &train, &geo_opts).unwrap();
    let opts = KinematicOptions { effects: vec![spec.clone()], ..geo_opts.clone() };
    let cal = calibrate(&model, &train, &opts).unwrap();
    let (geo_held, held) =
        (geo.calibrated.evaluate(&test).unwrap().rms_mm, cal.calibrated.evaluate(&test).unwrap().rms_mm);
    let p = cal.params.iter().find(|p| p.name == "joint2.quadratic_per_rad").expect("the toy's parameter");
    eprintln!(
        "toy effect: a = {:.4e} (truth {TRUE_A:.1e}); held out {geo_held:.4} mm geometric, {held:.4} mm with it",
        p.value
    );
    assert!((p.value - TRUE_A).abs() < 0.02 * TRUE_A, "{p:?}");
    assert!(held < 0.05 && geo_held > 3.0 * held, "{geo_held} {held}");

    // Found by diagnose among its candidates, named in its words.
    let dopts = DiagnoseOptions { sigma_position_m: SIGMA_M, sigma_from_data: false, ..DiagnoseOptions::default() };
    let report = diagnose(&model, &rows, &dopts).unwrap();
    let first = report.findings.first().expect("a finding");
    eprintln!("diagnose: {}", first.statement);
    assert_eq!(first.spec, spec);
    assert_eq!(first.joints, vec![2]);
    assert!(first.statement.contains("toy_quadratic_joint_error"), "{}", first.statement);
}
