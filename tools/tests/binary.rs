//! Smoke tests of the built binary. Their presence also makes `cargo test --workspace` build the
//! `ferrocal` binary that the end-to-end tests in `tests/` run.

use std::process::Command;

fn ferrocal() -> Command {
    Command::new(env!("CARGO_BIN_EXE_ferrocal"))
}

#[test]
fn version_names_the_package_version() {
    let out = ferrocal().arg("--version").output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert_eq!(text.trim(), format!("ferrocal {}", env!("CARGO_PKG_VERSION")));
}

#[test]
fn unknown_command_fails_with_a_usage_message() {
    let out = ferrocal().arg("no-such-command").output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("no-such-command"), "stderr: {err}");
}

#[test]
fn robot_info_lists_the_ur5_joints() {
    let out = ferrocal().args(["robot", "info", "--robot", "ur5"]).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "stderr: {}", String::from_utf8_lossy(&out.stderr));
    assert!(text.contains("ur5") || text.contains("UR5"), "stdout: {text}");
}

#[test]
fn doctor_finds_every_library_answering_and_ends_with_the_verdict() {
    let out = ferrocal().arg("doctor").output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "stdout: {text}\nstderr: {}", String::from_utf8_lossy(&out.stderr));
    let last = text.lines().last().unwrap_or_default();
    assert!(last.starts_with("verdict: pass: ") && last.contains("; next: "), "{last}");
    for lib in ["opencv", "apriltag", "ceres"] {
        assert!(text.to_lowercase().contains(lib), "{lib} probed: {text}");
    }
}
