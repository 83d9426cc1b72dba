//! Writes a session from a cell file: `cargo run -p ferrocal-datasets --example simulate_cell -- CELL OUT`.
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let cfg = ferrocal_datasets::sim::CellConfig::from_file(std::path::Path::new(&args[1])).unwrap();
    let m = ferrocal_datasets::sim::simulate(&cfg, std::path::Path::new(&args[2]), true, |k, n| {
        if k % 10 == 0 {
            eprintln!("{k}/{n}");
        }
    })
    .unwrap();
    println!("{}", serde_json::to_string_pretty(&m).unwrap());
}
