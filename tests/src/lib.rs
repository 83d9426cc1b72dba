//! The end-to-end tests' harness: the `ferrocal` binary that `cargo test --workspace` builds,
//! the shared recordings, and small helpers. The tests themselves live in `tests/`.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The built `ferrocal` binary (beside the test executable's folder).
pub fn ferrocal() -> Command {
    // target/<profile>/deps/cli-xxxx -> target/<profile>/ferrocal
    let exe = std::env::current_exe().unwrap();
    let dir = exe.parent().unwrap().parent().unwrap();
    let bin = dir.join(format!("ferrocal{}", std::env::consts::EXE_SUFFIX));
    assert!(bin.exists(), "{} not built: run `cargo build -p ferrocal` or `cargo test --workspace`", bin.display());
    Command::new(bin)
}

/// A file or folder of `../shared/data`; CI always has it, so a missing one fails the test by name.
pub fn data(rel: &str) -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data").join(rel);
    assert!(p.exists(), "{} is missing: ../shared/data must be beside the checkout", p.display());
    p
}

/// Runs a command; prints its output when it fails.
pub fn run(cmd: &mut Command) -> Output {
    let out = cmd.output().unwrap();
    if !out.status.success() {
        eprintln!("stdout: {}\nstderr: {}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    }
    out
}

/// A JSON file.
pub fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Asserts that the HTML report `html` opens with the verdict box of the verdict in the JSON
/// `json` wrote by the same run (same status, same next step).
pub fn assert_verdict_box(html: &Path, json_of_run: &serde_json::Value) {
    let page = std::fs::read_to_string(html).unwrap();
    let v = &json_of_run["verdict"];
    let status = v["status"].as_str().unwrap_or_else(|| panic!("no verdict in the JSON: {json_of_run}"));
    let at = page
        .find(&format!("class=\"verdict v-{status}\""))
        .unwrap_or_else(|| panic!("{}: no {status} verdict box", html.display()));
    let first_section = page.find("<section").unwrap_or(page.len());
    assert!(at < first_section, "{}: the verdict box is not first", html.display());
    assert!(page.contains(&format!("Verdict: {}", status.to_uppercase())));
    let next = v["next"]
        .as_str()
        .unwrap()
        .replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;");
    assert!(page.contains(&next), "{}: the next step is not in the box", html.display());
}

/// Runs a command that must succeed.
pub fn ok(cmd: &mut Command) -> Output {
    let out = run(cmd);
    assert!(out.status.success(), "{cmd:?} failed");
    out
}

/// The real UR5 recording imported as a measurement table `dir/ur5.csv`.
pub fn import_ur5(dir: &Path) -> PathBuf {
    let table = dir.join("ur5.csv");
    ok(ferrocal()
        .args(["import", "ur5", "--input"])
        .arg(data("ur5_tracker/ur5_grid_train.csv"))
        .arg("--out")
        .arg(&table));
    table
}

/// `ferrocal calibrate --robot ROBOT --measurements TABLE --out CAL --json JSON`; more arguments
/// may follow.
pub fn calibrate_cmd(robot: impl AsRef<OsStr>, table: &Path, cal: &Path, json: &Path) -> Command {
    let mut c = ferrocal();
    c.args(["calibrate", "--robot"])
        .arg(robot)
        .arg("--measurements")
        .arg(table)
        .arg("--out")
        .arg(cal)
        .arg("--json")
        .arg(json);
    c
}

/// `ferrocal GLOBAL... evaluate --robot ROBOT --calibration CAL --measurements TABLE --json JSON`
/// (`global`: the arguments before the command, e.g. `--keep`, `--thresholds FILE`); more
/// arguments may follow.
pub fn evaluate_cmd(global: &[&str], robot: impl AsRef<OsStr>, cal: &Path, table: &Path, json: &Path) -> Command {
    let mut c = ferrocal();
    c.args(global)
        .args(["evaluate", "--robot"])
        .arg(robot)
        .arg("--calibration")
        .arg(cal)
        .arg("--measurements")
        .arg(table)
        .arg("--json")
        .arg(json);
    c
}
