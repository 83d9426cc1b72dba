//! The simulated deflection table of `ferrocal stiffness simulate`: the KR 270-like arm at random
//! configurations, each measured without payload, with 150 kg and with 270 kg, in the format of
//! [`crate::formats::deflections`], with the true compliances.

use std::collections::BTreeMap;

use ferrocal_calib::stiffness::error::Result;
use ferrocal_calib::stiffness::LoadCase;

use super::{StiffSim, StiffSimConfig};
use crate::formats::deflections::{header_columns, observation_rows};

/// A simulated deflection table and its truth.
#[derive(Clone, Debug)]
pub struct SimulatedDeflections {
    /// The table (CSV text).
    pub csv: String,
    /// The true value of every parameter of the complete layout, by name.
    pub truth: BTreeMap<String, f64>,
    /// Observations in the table (configurations x payloads).
    pub measurements: usize,
}

/// The table of `configurations` random configurations of the KR 270-like arm (seed `seed`).
pub fn simulated_deflections(seed: u64, configurations: usize) -> Result<SimulatedDeflections> {
    let mut sim = StiffSim::kr270(StiffSimConfig { seed, ..StiffSimConfig::default() })?;
    let qs = sim.random_configurations(configurations);
    let loads = [
        LoadCase::payload(0.0, [0.0; 3]),
        LoadCase::payload(150.0, [0.25, 0.0, 0.15]),
        LoadCase::payload(270.0, [0.0, 0.25, 0.3]),
    ];
    let mut csv = String::from("# ferrocal stiffness simulate: KR 270-like arm, tracker on three reflectors\n");
    csv.push_str(&header_columns(sim.nominal.dof()).join(","));
    csv.push('\n');
    for (k, q) in qs.iter().enumerate() {
        for (l, load) in loads.iter().enumerate() {
            let o = sim.observe(&format!("c{k:03}_{l}"), q, load)?;
            csv.push_str(&observation_rows(&o));
        }
    }
    let layout = sim.truth.layout()?;
    let truth = layout.names().into_iter().zip(sim.truth.complete_values()).collect();
    Ok(SimulatedDeflections { csv, truth, measurements: qs.len() * loads.len() })
}
