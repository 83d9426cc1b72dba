//! The cell file reader (`ferrocal simulate --cell cell.toml`): any text gives a cell or an
//! error; a cell read gives its camera poses (Ok or Err) and is written back.
#![no_main]

use std::path::Path;

use ferrocal_datasets::sim::CellConfig;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(cell) = CellConfig::from_toml_str(text, Path::new("cell.toml")) else { return };
    for c in &cell.cameras {
        let _ = c.t_world_cam();
    }
    if let Some(t) = &cell.tracker {
        let _ = t.validate();
    }
    let _ = cell.to_toml();
});
