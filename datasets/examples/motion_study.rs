//! The motion experiments on the simulated compliant axis: identification (tracker and camera
//! rate, physical chain) and learning control with the three measurement cases.
//!
//! `cargo run --release -p ferrocal-datasets --example motion_study -- [--seed S] [--json F]`

use ferrocal_datasets::motion::study::{identify_axis, ilc_experiment, IdentifySettings, IlcSettings};
use ferrocal_datasets::motion::CompliantAxis;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let get = |k: &str| args.iter().position(|a| a == k).and_then(|i| args.get(i + 1)).cloned();
    let seed: u64 = get("--seed").map_or(Ok(1), |s| s.parse())?;
    let axis = CompliantAxis::l1_like();
    let settings = IdentifySettings { seed, ..IdentifySettings::default() };
    let t = std::time::Instant::now();
    let id = identify_axis(&axis, &settings)?;
    eprintln!("identification {:.1} s", t.elapsed().as_secs_f64());
    println!("{}", serde_json::to_string_pretty(&id)?);
    let t = std::time::Instant::now();
    let w: f64 = get("--w").map_or(Ok(1e-4), |s| s.parse())?;
    let force: f64 = get("--contact-force-n").map_or(Ok(0.0), |s| s.parse())?;
    let runs =
        ilc_experiment(&axis, &id, &IlcSettings { weight: w, contact_force_n: force, seed, ..IlcSettings::default() })?;
    eprintln!("ILC {:.1} s", t.elapsed().as_secs_f64());
    for r in &runs {
        println!(
            "{:?}: {}",
            r.case,
            r.tool_rms_m.iter().map(|v| format!("{:.1}", v * 1e6)).collect::<Vec<_>>().join(" ")
        );
    }
    if let Some(f) = get("--json") {
        std::fs::write(f, serde_json::to_string_pretty(&serde_json::json!({"identify": id, "ilc": runs}))?)?;
    }
    Ok(())
}
