//! The plan file reader (`ferrocal plan --plan plan.toml`): any bytes give a plan or an error;
//! a plan read builds its measuring device and camera views (Ok or Err).
#![no_main]

use ferrocal_datasets::formats::plan_file::{camera_view, device, PlanFile};
use libfuzzer_sys::fuzz_target;

mod common;

fuzz_target!(|data: &[u8]| {
    let path = common::temp_file("plan.toml", data);
    let Ok(plan) = PlanFile::from_file(&path) else { return };
    let _ = device(&plan);
    for c in &plan.cameras {
        let _ = camera_view(c);
    }
});
