//! Killed at any moment (issue #16, docs/reliability.md "Killed"): `calibrate`, `plan`,
//! `simulate` and `import` are sent SIGKILL at several moments, and their declared outputs must be
//! all present and complete (each one parses) or all absent; a run folder replaced with --force
//! holds the old run or the new one, never a mix. The deterministic moment is the test-only hook
//! `FERROCAL_TEST_PAUSE_BEFORE_COMMIT` (the command says `test hook: pausing before the commit`
//! on stderr and sleeps right before it moves its outputs into place); the other moments are
//! fixed delays after the start.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use ferrocal_tests::{data, ferrocal, import_ur5, json, run};

/// When the command is killed.
#[derive(Clone, Copy, Debug)]
enum Moment {
    /// At the hook, right before the commit.
    BeforeCommit,
    /// This many milliseconds after the start.
    After(u64),
    /// Not killed: the run completes.
    Never,
}

/// The moments every command is killed at.
const MOMENTS: [Moment; 7] = [
    Moment::After(0),
    Moment::After(5),
    Moment::After(20),
    Moment::After(50),
    Moment::After(200),
    Moment::BeforeCommit,
    Moment::Never,
];

/// Runs `cmd`, killing it at `moment`; true when it was killed before it ended.
fn run_and_kill(cmd: &mut Command, moment: Moment) -> bool {
    cmd.stdout(Stdio::null()).stderr(Stdio::piped());
    if matches!(moment, Moment::BeforeCommit) {
        cmd.env("FERROCAL_TEST_PAUSE_BEFORE_COMMIT", "60000");
    }
    let mut child = cmd.spawn().unwrap();
    let stderr = child.stderr.take().unwrap();
    match moment {
        Moment::BeforeCommit => {
            let mut lines = BufReader::new(stderr).lines();
            let paused = lines.any(|l| l.is_ok_and(|l| l.starts_with("test hook: pausing before the commit")));
            assert!(
                paused,
                "{cmd:?} ended without reaching its commit (a binary built without the test-hooks feature never pauses: build it with `cargo test --workspace`, or `cargo build -p ferrocal --features ferrocal-datasets/test-hooks`)"
            );
            child.kill().unwrap();
            child.wait().unwrap();
            true
        }
        Moment::After(ms) => {
            // Drain stderr so that the command never blocks on a full pipe.
            let drain = std::thread::spawn(move || std::io::copy(&mut { stderr }, &mut std::io::sink()));
            std::thread::sleep(Duration::from_millis(ms));
            let killed = child.try_wait().unwrap().is_none() && child.kill().is_ok();
            child.wait().unwrap();
            let _ = drain.join();
            killed
        }
        Moment::Never => {
            let mut err = String::new();
            std::io::Read::read_to_string(&mut { stderr }, &mut err).unwrap();
            let status = child.wait().unwrap();
            assert!(status.success() || status.code() == Some(2), "{cmd:?} failed: {err}");
            false
        }
    }
}

/// The outputs are all absent, or all present and each accepted by `complete`.
fn all_or_nothing(outputs: &[PathBuf], complete: &dyn Fn(&Path) -> bool, what: &str) -> bool {
    let present: Vec<&PathBuf> = outputs.iter().filter(|p| p.exists()).collect();
    assert!(present.is_empty() || present.len() == outputs.len(), "{what}: a partial set of outputs: {present:?}");
    for p in &present {
        assert!(complete(p), "{what}: {} is incomplete", p.display());
    }
    !present.is_empty()
}

/// Whether a file is a complete measurement table (read again by `calibrate`'s reader).
fn complete_table(p: &Path) -> bool {
    let text = std::fs::read_to_string(p).unwrap();
    text.ends_with('\n') && text.lines().filter(|l| !l.starts_with('#')).count() > 3
}

fn complete_json(p: &Path) -> bool {
    serde_json::from_str::<serde_json::Value>(&std::fs::read_to_string(p).unwrap()).is_ok()
}

fn complete_html(p: &Path) -> bool {
    std::fs::read_to_string(p).unwrap().trim_end().ends_with("</html>")
}

#[test]
fn killed_import_and_calibrate_leave_all_outputs_or_none() {
    let tmp = tempfile::tempdir().unwrap();
    let table = import_ur5(tmp.path());
    // 120 rows keep the calibration short in the dev profile.
    let text = std::fs::read_to_string(&table).unwrap();
    let small = tmp.path().join("small.csv");
    std::fs::write(&small, text.lines().take(122).map(|l| format!("{l}\n")).collect::<String>()).unwrap();
    for (k, moment) in MOMENTS.into_iter().enumerate() {
        let out = tmp.path().join(format!("import{k}.csv"));
        let killed = run_and_kill(
            ferrocal()
                .args(["import", "ur5", "--input"])
                .arg(data("ur5_tracker/ur5_grid_train.csv"))
                .arg("--out")
                .arg(&out),
            moment,
        );
        let there = all_or_nothing(std::slice::from_ref(&out), &complete_table, &format!("import at {moment:?}"));
        assert!(there || killed, "import at {moment:?}: not killed, yet no output");

        let outs = [
            tmp.path().join(format!("cal{k}.json")),
            tmp.path().join(format!("summary{k}.json")),
            tmp.path().join(format!("report{k}.html")),
        ];
        let killed = run_and_kill(
            ferrocal()
                .args(["calibrate", "--robot", "ur5", "--measurements"])
                .arg(&small)
                .arg("--out")
                .arg(&outs[0])
                .arg("--json")
                .arg(&outs[1])
                .arg("--report")
                .arg(&outs[2]),
            moment,
        );
        let complete =
            |p: &Path| if p.extension().is_some_and(|e| e == "html") { complete_html(p) } else { complete_json(p) };
        let there = all_or_nothing(&outs, &complete, &format!("calibrate at {moment:?}"));
        assert!(there || killed, "calibrate at {moment:?}: not killed, yet no output");
        if matches!(moment, Moment::BeforeCommit) {
            assert!(!there, "calibrate killed before its commit left outputs");
        }
    }
    // Only the staged files of killed runs may remain beside the outputs, under hidden names.
    let known = |n: &str| {
        n == "ur5.csv"
            || n == "small.csv"
            || n.starts_with("import")
            || n.starts_with("cal")
            || n.starts_with("summary")
            || n.starts_with("report")
    };
    for e in std::fs::read_dir(tmp.path()).unwrap() {
        let name = e.unwrap().file_name().to_string_lossy().into_owned();
        assert!(name.starts_with('.') || known(&name), "{name} left beside the outputs");
    }
}

/// The files of a complete `plan` run folder.
const PLAN_FILES: [&str; 8] = [
    "poses.csv",
    "path.csv",
    "grid_poses.csv",
    "program.mod",
    "program.ngc",
    "session_plan.toml",
    "report.json",
    "index.html",
];

/// A folder holds the old run (its marker, nothing new) or a complete new one.
fn old_or_complete(dir: &Path, files: &[&str], what: &str) -> bool {
    assert!(dir.is_dir(), "{what}: the folder is gone");
    if dir.join("OLD_RUN").exists() {
        let names: Vec<String> =
            std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        assert_eq!(names, ["OLD_RUN"], "{what}: new files beside the old run");
        return false;
    }
    for f in files {
        let p = dir.join(f);
        assert!(p.exists(), "{what}: {f} missing");
        let ok = match p.extension().and_then(|e| e.to_str()) {
            Some("json") => complete_json(&p),
            Some("html") => complete_html(&p),
            _ => std::fs::metadata(&p).unwrap().len() > 0,
        };
        assert!(ok, "{what}: {f} incomplete");
    }
    true
}

fn stale_folder(dir: &Path) {
    let _ = std::fs::remove_dir_all(dir);
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join("OLD_RUN"), "a stale run").unwrap();
}

#[test]
fn killed_plan_and_simulate_leave_the_old_folder_or_a_complete_new_one() {
    let tmp = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let plan_file = root.join("datasets/cells/plan_gantry_tau_l1.toml");
    // The built-in cell with its tracker only (no cameras, no images) and a coarse grid.
    let cell = std::fs::read_to_string(root.join("datasets/cells/gantry_tau_l1.toml")).unwrap();
    let cell = cell.split("\n[target]").next().unwrap().replace("spacing_m = 0.15", "spacing_m = 0.3");
    assert!(cell.contains("spacing_m = 0.3") && cell.contains("[tracker]"), "the built-in cell changed");
    let cell_path = tmp.path().join("cell.toml");
    std::fs::write(&cell_path, cell).unwrap();

    let plan_dir = tmp.path().join("plan");
    let session = tmp.path().join("session");
    let mut new_plans = 0;
    let mut new_sessions = 0;
    for moment in MOMENTS {
        stale_folder(&plan_dir);
        let killed = run_and_kill(
            ferrocal()
                .args(["plan", "--simulations", "0", "--wanted", "20", "--random-subsets", "10", "--force", "--plan"])
                .arg(&plan_file)
                .arg("--out")
                .arg(&plan_dir),
            moment,
        );
        let new = old_or_complete(&plan_dir, &PLAN_FILES, &format!("plan at {moment:?}"));
        assert!(new || killed, "plan at {moment:?}: not killed, yet the old folder");
        new_plans += usize::from(new);

        stale_folder(&session);
        let killed = run_and_kill(
            ferrocal().args(["simulate", "--force", "--config"]).arg(&cell_path).arg("--out").arg(&session),
            moment,
        );
        let files = ["manifest.json", "joints.csv", "tracker.csv", "cell.toml", "truth/truth.json"];
        let new = old_or_complete(&session, &files, &format!("simulate at {moment:?}"));
        assert!(new || killed, "simulate at {moment:?}: not killed, yet the old folder");
        if new {
            assert!(complete_table(&session.join("tracker.csv")));
            assert!(json(&session.join("manifest.json"))["n_poses"].as_u64().unwrap() > 3);
        }
        new_sessions += usize::from(new);
    }
    assert!(new_plans >= 1 && new_sessions >= 1);

    // Without --force a non-empty folder is refused before any work, and stays as it was.
    stale_folder(&plan_dir);
    let out = ferrocal().args(["plan", "--plan"]).arg(&plan_file).arg("--out").arg(&plan_dir).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("pass --force"), "{err}");
    assert!(!old_or_complete(&plan_dir, &PLAN_FILES, "plan without --force"));
    // An empty folder is taken.
    let empty = tmp.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let out = run(ferrocal()
        .args(["plan", "--simulations", "0", "--wanted", "20", "--random-subsets", "10", "--plan"])
        .arg(&plan_file)
        .arg("--out")
        .arg(&empty));
    assert!(matches!(out.status.code(), Some(0 | 2)), "plan into an empty folder failed");
    assert!(old_or_complete(&empty, &PLAN_FILES, "plan into an empty folder"));
}
