//! The closed-loop study of corrected programs over seeds (`datasets::sim::closed_loop`), as JSON
//! on stdout: `cargo run --release -p ferrocal-datasets --example closed_loop -- [N_SEEDS] [FIRST]`.

use ferrocal_datasets::sim::closed_loop::{run_closed_loop, summarise_closed_loop, ClosedLoopConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let n: u64 = args.get(1).map_or(Ok(10), |s| s.parse())?;
    let first: u64 = args.get(2).map_or(Ok(100), |s| s.parse())?;
    let dir = std::env::temp_dir().join(format!("ferrocal_closed_loop_{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let config = ClosedLoopConfig::ur5();
    let mut runs = Vec::new();
    for seed in first..first + n {
        let r = run_closed_loop(&config, seed, &dir)?;
        eprintln!("{}", r.summary_line());
        for (name, p) in [("tracker", &r.tracker), ("camera", &r.camera)] {
            for x in &p.rows {
                eprintln!(
                    "  {name} {}: landed {:.4} true frame {:.4} sigma {:.4} uncorrected {:.4} sigma_min {:.4}",
                    x.pose_id, x.landed_mm, x.landed_true_mm, x.sigma_mm, x.uncorrected_mm, x.sigma_min_m
                );
            }
        }
        runs.push(r);
    }
    let s = summarise_closed_loop(runs);
    std::fs::remove_dir_all(&dir).ok();
    println!(
        "{}",
        serde_json::to_string_pretty(&serde_json::json!({
            "median_ratio": s.median_ratio, "coverage": s.coverage, "median_improvement": s.median_improvement,
            "median_true_improvement": s.median_true_improvement, "median_targets_ratio": s.median_targets_ratio,
        }))?
    );
    Ok(())
}
