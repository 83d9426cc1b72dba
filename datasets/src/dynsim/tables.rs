//! Simulated tables of `ferrocal dynamics simulate`: leg and force streams from one D-optimal
//! excitation, the quasi-static pose table (platform rig) and the truth, as the files
//! (`legs.csv`, `forces.csv`, `static.csv`, `truth.json`) the identification commands read.

use ferrocal_calib::design::criteria::Criterion;
use ferrocal_calib::dynamics::force_sensor::SensorModel;
use ferrocal_calib::dynamics::SensorRows;
use ferrocal_robot::dynamics::motion::coordinates_from_pose;
use ferrocal_robot::dynamics::HexapodDynamics;
use rand::SeedableRng;
use serde_json::json;

use super::study::{excitation_for, record_hexapod, record_platform, DynamicSetup, STATIC_HALF_RANGE};
use super::{payload_steps, HexapodSim, PlatformSim};
use crate::error::{DatasetError, Result};
use crate::formats::dynamics_tables::{static_csv, stream_csv, FORCE_COLUMNS, LEG_COLUMNS};

/// Which rig is simulated (`platform`, `hexapod` by name).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Rig {
    /// The force-sensing end-effector: sensor forces.
    Platform,
    /// The hexapod: actuator forces.
    Hexapod,
}

/// What to simulate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TableSettings {
    /// Which rig.
    pub rig: Rig,
    /// Extra payload on the end-effector (platform rig), kg, as the payload steps mount it.
    pub payload_kg: f64,
    /// Periods of the 4 s excitation recorded.
    pub periods: usize,
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Poses of the quasi-static table (platform rig).
    pub poses: usize,
    /// Seed.
    pub seed: u64,
    /// Sensor cross-talk (platform rig), a fraction: see [`crosstalk_pattern`]. 0: none.
    pub crosstalk: f64,
}

/// The most samples one simulated excitation may hold (periods x 4 s x rate): 2 million, about
/// 300 MB of tables; real rigs record 1-10 kHz for minutes, far below it.
pub const MAX_EXCITATION_SAMPLES: f64 = 2.0e6;
/// The most poses of one quasi-static table.
pub const MAX_STATIC_POSES: usize = 100_000;

impl TableSettings {
    /// Refuses settings whose tables could not be held (a rate of 1e12 Hz) before anything is
    /// allocated, naming the flag and the bound.
    pub fn check(&self) -> Result<()> {
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0) {
            return Err(DatasetError::Input(format!("--rate-hz {}: must be a positive sample rate", self.rate_hz)));
        }
        let samples = self.periods.max(1) as f64 * 4.0 * self.rate_hz;
        if samples > MAX_EXCITATION_SAMPLES {
            return Err(DatasetError::Input(format!(
                "--rate-hz {} with --periods {} asks for {samples:.3e} samples; at most {MAX_EXCITATION_SAMPLES:.0e} are simulated (lower the rate or the periods)",
                self.rate_hz, self.periods
            )));
        }
        if self.poses > MAX_STATIC_POSES {
            return Err(DatasetError::Input(format!(
                "--poses {}: at most {MAX_STATIC_POSES} quasi-static poses are simulated",
                self.poses
            )));
        }
        if !(self.payload_kg.is_finite() && self.payload_kg >= 0.0 && self.crosstalk.is_finite()) {
            return Err(DatasetError::Input(format!(
                "--payload-kg {} and --crosstalk {} must be finite, the payload not negative",
                self.payload_kg, self.crosstalk
            )));
        }
        Ok(())
    }
}

/// The cross-talk pattern of `ferrocal dynamics simulate --crosstalk F`: sensor `i` reads `F` of
/// the next sensor's load and `-F / 2` of the previous one's (cyclic: neighbouring struts of the
/// framework share a mounting).
pub fn crosstalk_pattern(fraction: f64) -> [[f64; 6]; 6] {
    let mut c = [[0.0; 6]; 6];
    for (i, row) in c.iter_mut().enumerate() {
        row[(i + 1) % 6] = fraction;
        row[(i + 5) % 6] = -fraction / 2.0;
    }
    c
}

fn err(what: &'static str) -> impl Fn(String) -> DatasetError {
    move |e| DatasetError::Input(format!("{what}: {e}"))
}

/// The simulated files: `(file name, contents)` in writing order.
pub fn simulated_tables(s: &TableSettings) -> Result<Vec<(&'static str, String)>> {
    s.check()?;
    let setup =
        DynamicSetup { periods: s.periods.max(1), rate_hz: s.rate_hz, max_evaluations: 300, ..DynamicSetup::default() };
    let mut files = Vec::new();
    match s.rig {
        Rig::Platform => {
            let base = PlatformSim::preset();
            let sim = if s.payload_kg > 0.0 {
                let mut p =
                    payload_steps(1, s.payload_kg).pop().ok_or_else(|| DatasetError::Input("no payload".into()))?;
                p.mass_kg = s.payload_kg;
                base.with_payload(&p)
            } else {
                base
            };
            let sim = PlatformSim { crosstalk: crosstalk_pattern(s.crosstalk), ..sim };
            let reg = PlatformSim::preset().sensor_regressor().map_err(|e| err("sensors")(e.to_string()))?;
            let model9 = SensorModel::new(9).map_err(|e| err("model 9")(e.to_string()))?;
            let rows = SensorRows { regressor: &reg, model: model9 };
            let traj = excitation_for(&rows, &sim.hexapod, &setup, Criterion::D, sim.noise.sigma_n)?;
            let rec = record_platform(&sim, &traj, &setup, s.seed)?;
            files.push(("legs.csv", stream_csv(&LEG_COLUMNS, &rec.legs)));
            files.push(("forces.csv", stream_csv(&FORCE_COLUMNS, &rec.forces)));
            let home = coordinates_from_pose(&sim.hexapod.home);
            let poses = ferrocal_calib::dynamics::design::candidate_poses(
                &sim.hexapod,
                s.poses,
                &home,
                &STATIC_HALF_RANGE,
                0.005,
            )
            .map_err(|e| err("poses")(e.to_string()))?;
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(s.seed.wrapping_add(1));
            let st = sim.static_record(&poses, 200, &mut rng)?;
            files.push(("static.csv", static_csv(&st.poses, &st.forces_n)));
            let truth = sim.truth();
            let v = json!({"rig": "platform", "mass_kg": truth.body.mass_kg, "com_m": [truth.body.com_m.x, truth.body.com_m.y, truth.body.com_m.z],
                "offsets_n": truth.offsets_n, "deformation_k0_k1_k2_k3": truth.deformation, "samples_per_period": setup.samples_per_period(),
                "model9": reg.true_values(model9, &truth)});
            files.push(("truth.json", serde_json::to_string_pretty(&v)?));
        }
        Rig::Hexapod => {
            let sim = HexapodSim::preset();
            let dynm = HexapodDynamics::new(&sim.hexapod).map_err(|e| err("hexapod")(e.to_string()))?;
            let traj = excitation_for(&dynm, &sim.hexapod, &setup, Criterion::D, sim.noise.sigma_n)?;
            let rec = record_hexapod(&sim, &traj, &setup, s.seed)?;
            files.push(("legs.csv", stream_csv(&LEG_COLUMNS, &rec.legs)));
            files.push(("forces.csv", stream_csv(&FORCE_COLUMNS, &rec.forces)));
            let v = json!({"rig": "hexapod", "names": HexapodDynamics::parameter_names(), "truth": sim.truth(), "samples_per_period": setup.samples_per_period()});
            files.push(("truth.json", serde_json::to_string_pretty(&v)?));
        }
    }
    Ok(files)
}
