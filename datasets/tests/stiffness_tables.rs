//! The simulated deflection table through its reader and the reduced identification (the flow of
//! `ferrocal stiffness simulate` then `identify`), and the reader's errors with file, line and
//! column.

use std::collections::BTreeMap;

use ferrocal_calib::stiffness::problem::LinearProblem;
use ferrocal_calib::stiffness::reduce::{reduce, ReductionSettings};
use ferrocal_calib::stiffness::LoadCase;
use ferrocal_datasets::formats::deflections::read_deflections;
use ferrocal_datasets::stiffsim::tables::simulated_deflections;
use ferrocal_datasets::stiffsim::{StiffSim, StiffSimConfig};
use ferrocal_robot::stiffness::presets::stiffness_preset;
use ferrocal_robot::stiffness::WrenchLimits;

#[test]
fn simulate_then_identify_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let sim = simulated_deflections(3, 25).unwrap();
    assert_eq!(sim.measurements, 75);
    let csv = dir.path().join("deflections.csv");
    std::fs::write(&csv, &sim.csv).unwrap();
    let model = stiffness_preset("kr270-like").unwrap().unwrap();
    let prior = model.complete_values();
    let limits = WrenchLimits::default();
    let obs = read_deflections(&csv, &model, &limits).unwrap();
    assert_eq!(obs.len(), 75);
    let problem = LinearProblem::from_observations(&model, &obs, &limits).unwrap();
    let red = reduce(&problem, None, Some(&prior[..]), &ReductionSettings { nu_threshold: 2.0, ..Default::default() })
        .unwrap();
    assert!(red.physical_problems.is_empty(), "{:?}", red.physical_problems);
    let p: BTreeMap<String, f64> =
        problem.layout.names().into_iter().zip(red.complete_values.iter().copied()).collect();
    // The identified model predicts the deflection under 250 kg like the truth does.
    let names = model.layout().unwrap().names();
    let est: Vec<f64> = names.iter().map(|n| p[n]).collect();
    let tru: Vec<f64> = names.iter().map(|n| sim.truth[n]).collect();
    let mut check = StiffSim::kr270(StiffSimConfig { seed: 99, ..StiffSimConfig::default() }).unwrap();
    let (mut err, mut size) = (0.0, 0.0);
    for q in check.random_configurations(20) {
        let l = LoadCase::payload(250.0, [0.1, 0.0, 0.2]).loading(&model, &q).unwrap();
        let a = model.observation_matrix(&q, &l).unwrap();
        let (de, dt) = (&a * nalgebra::DVector::from_vec(est.clone()), &a * nalgebra::DVector::from_vec(tru.clone()));
        err += (de.rows(0, 3) - dt.rows(0, 3)).norm_squared();
        size += dt.rows(0, 3).norm_squared();
    }
    assert!(err.sqrt() < 0.05 * size.sqrt(), "prediction error {:.3e} of {:.3e} m", err.sqrt(), size.sqrt());
}

#[test]
fn reader_errors_name_file_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let text = simulated_deflections(3, 3).unwrap().csv;
    let model = stiffness_preset("kr270-like").unwrap().unwrap();
    let read = |name: &str, lines: &[String]| {
        let p = dir.path().join(name);
        std::fs::write(&p, lines.join("\n")).unwrap();
        read_deflections(&p, &model, &WrenchLimits::default()).unwrap_err().to_string()
    };
    // Unknown frame.
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    lines[2] = lines[2].replacen(",base,", ",gripper,", 1);
    let e = read("bad.csv", &lines);
    assert!(e.contains("bad.csv:3, column 'frame'") && e.contains("gripper") && e.contains("flange"), "{e}");
    // A moment in N mm.
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let mut cells: Vec<String> = lines[5].split(',').map(String::from).collect();
    cells[8] = "9.81e3".into(); // fx_n of a 0 kg row: fine alone; moment next
    cells[11] = "250000".into(); // mx_nm typed in N mm
    lines[5] = cells.join(",");
    let e = read("bad2.csv", &lines);
    assert!(e.contains("bad2.csv:6") && e.contains("N mm"), "{e}");
    // Not a number.
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    lines[4] = lines[4].replacen(",base,", ",base,x", 1);
    let e = read("bad3.csv", &lines);
    assert!(e.contains("bad3.csv:5, column 'fx_n'") && e.contains("not a number"), "{e}");
    // A missing column.
    let lines: Vec<String> = text.lines().map(|l| l.replacen("sigma_mm", "sigma", 1)).collect();
    let e = read("bad4.csv", &lines);
    assert!(e.contains("bad4.csv: missing column 'sigma_mm'"), "{e}");
}
