//! The parallel-robot model TOML reader (`--robot cell.toml`): any text gives a model or an
//! error; a model read evaluates its forward kinematics at mid-limits and is written back.
#![no_main]

use std::path::Path;

use ferrocal_robot::parallel::file::{parse_str, to_toml_string};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(model) = parse_str(text, Path::new("fuzz.toml")) else { return };
    let k = model.kinematics();
    let q: Vec<f64> = k
        .joint_limits()
        .iter()
        .map(|l| {
            let mid = 0.5 * (l.lower + l.upper);
            if mid.is_finite() {
                mid
            } else {
                0.0
            }
        })
        .collect();
    let _ = k.forward(&q);
    let _ = to_toml_string(&model);
});
