//! Simulated dynamics tables through the file readers and both identifications (the flow of
//! `ferrocal dynamics simulate` then `identify` and `identify-static`).

use ferrocal_calib::dynamics::identify::identify_from_streams;
use ferrocal_calib::dynamics::{Differentiation, NoiseModel, SensorModel, SensorRows};
use ferrocal_datasets::dynsim::study::static_problem;
use ferrocal_datasets::dynsim::tables::{simulated_tables, Rig, TableSettings};
use ferrocal_datasets::dynsim::PlatformSim;
use ferrocal_datasets::formats::dynamics_tables::{read_static_table, read_stream, FORCE_COLUMNS, LEG_COLUMNS};
use ferrocal_lsq::linear::{fit, LinearOptions, Weighting};

#[test]
fn simulated_tables_identify() {
    let dir = tempfile::tempdir().unwrap();
    let settings = TableSettings {
        rig: Rig::Platform,
        payload_kg: 19.93,
        periods: 2,
        rate_hz: 100.0,
        poses: 60,
        seed: 3,
        crosstalk: 0.0,
    };
    let files = simulated_tables(&settings).unwrap();
    let names: Vec<&str> = files.iter().map(|f| f.0).collect();
    assert_eq!(names, ["legs.csv", "forces.csv", "static.csv", "truth.json"]);
    for (name, text) in &files {
        std::fs::write(dir.path().join(name), text).unwrap();
    }
    let legs = read_stream(&dir.path().join("legs.csv"), "leg positions", &LEG_COLUMNS).unwrap();
    let forces = read_stream(&dir.path().join("forces.csv"), "sensor forces", &FORCE_COLUMNS).unwrap();
    let sim = PlatformSim::preset();
    let reg = sim.sensor_regressor().unwrap();
    let model = SensorRows { regressor: &reg, model: SensorModel::new(9).unwrap() };
    let d = Differentiation::Frequency { cutoff_hz: 2.5 };
    let f = identify_from_streams(
        &sim.hexapod,
        &model,
        &legs,
        &forces,
        &d,
        &NoiseModel::Periods { samples_per_period: 400 },
    )
    .unwrap();
    let m = f.fit.values[0];
    assert!((m - (33.78 + 19.93)).abs() < 0.01 * 53.71, "{m}");

    let (poses, forces) = read_static_table(&dir.path().join("static.csv")).unwrap();
    assert_eq!(poses.len(), 60);
    let m5 = SensorModel::new(5).unwrap();
    let (a, y) = static_problem(&reg, m5, &poses, &forces).unwrap();
    let f = fit(&a, &y, &m5.names(), &Weighting::Unit, &LinearOptions::default()).unwrap();
    let m = f.values[0];
    assert!((m - (33.78 + 19.93)).abs() < 0.02 * 53.71, "{m}");
}
