//! The calibration file reader (`evaluate`, `export`, `correct --calibration cal.json`): any
//! bytes give a file or an error; a file read is checked against the UR5 model and applied.
#![no_main]

use ferrocal_calib::file::CalibrationFile;
use ferrocal_robot::RobotModel;
use libfuzzer_sys::fuzz_target;

mod common;

fuzz_target!(|data: &[u8]| {
    let path = common::temp_file("cal.json", data);
    let Ok(file) = CalibrationFile::read(&path) else { return };
    let ur5 = RobotModel::load("ur5").expect("preset");
    let _ = file.check_robot("ur5", &ur5);
    let _ = file.apply(&ur5);
});
