//! The measurement table reader (`calibrate --measurements`, `diagnose`, `import` outputs):
//! any bytes give a table or an error; a table read is checked against the UR5 model and
//! written back, and what is written reads again.
#![no_main]

use ferrocal_datasets::import::{measurements_to_string, parse_measurements, read_measurements, WriteOptions};
use ferrocal_robot::RobotModel;
use libfuzzer_sys::fuzz_target;

mod common;

fuzz_target!(|data: &[u8]| {
    let table = match std::str::from_utf8(data) {
        Ok(text) => parse_measurements(text, "fuzz.csv"),
        Err(_) => read_measurements(common::temp_file("fuzz.csv", data)),
    };
    let Ok(table) = table else { return };
    let kinds = table.joint_kinds();
    let _ = table.check_joint_kinds(&kinds);
    if kinds.len() == 6 {
        let ur5 = RobotModel::load("ur5").expect("preset");
        let _ = table.check_joint_values(&ur5.kinematics().joint_limits(), "ur5");
    }
    if let Ok(text) = measurements_to_string(&table.set, &WriteOptions::si_like(&table)) {
        parse_measurements(&text, "written.csv").expect("a table the writer wrote reads again");
    }
});
