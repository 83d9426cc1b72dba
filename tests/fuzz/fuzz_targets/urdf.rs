//! The URDF reader (`--robot arm.urdf`): any text gives a chain or an error; a chain read
//! evaluates its forward kinematics and Jacobian at zero joints (Ok or Err).
#![no_main]

use ferrocal_robot::serial::{parse_urdf_str, UrdfOptions};
use ferrocal_robot::Kinematics;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(chain) = parse_urdf_str(text, &UrdfOptions::default()) else { return };
    let q = vec![0.0; chain.dof()];
    let _ = chain.forward(&q);
    let _ = chain.jacobian(&q);
});
