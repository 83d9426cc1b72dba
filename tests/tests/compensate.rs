//! The calibration with the physics in it leaves the tool: `diagnose --out` writes it,
//! `evaluate` predicts with it, `calibrate --effects` fits the same model from scratch, and
//! `evaluate --refit-frame` scores a model against another device's table (shared/spec/cli.md).
//! On the real UR5 recording (UR5 tracker data of the shared set; see its README for source and
//! licence).

use std::path::{Path, PathBuf};

use ferrocal_tests::{ferrocal, import_ur5, json, ok};

/// The UR5 table with a split column that is not interleaved: blocks of 50 consecutive poses,
/// every fourth block held out (`test`).
fn ur5_blocks(dir: &Path) -> PathBuf {
    let table = import_ur5(dir);
    let text = std::fs::read_to_string(&table).unwrap();
    let mut csv = String::new();
    let mut row = 0usize;
    for line in text.lines() {
        if line.starts_with('#') {
            continue;
        }
        if line.starts_with("pose_id") {
            csv.push_str(&format!("{line},split\n"));
            continue;
        }
        let split = if (row / 50) % 4 == 3 { "test" } else { "train" };
        csv.push_str(&format!("{line},{split}\n"));
        row += 1;
    }
    assert_eq!(row, 1000);
    let p = dir.join("ur5_blocks.csv");
    std::fs::write(&p, csv).unwrap();
    p
}

/// The test rows alone (a table `evaluate` scores).
fn test_rows(table: &Path, dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(table).unwrap();
    let mut lines = text.lines();
    let mut out = format!("{}\n", lines.next().unwrap());
    for l in lines.filter(|l| l.ends_with(",test")) {
        out.push_str(l);
        out.push('\n');
    }
    let p = dir.join("ur5_test.csv");
    std::fs::write(&p, out).unwrap();
    p
}

fn evaluate(cal: &Path, table: &Path, json_out: &Path, refit: bool) -> serde_json::Value {
    evaluate_with(cal, table, json_out, refit, &[])
}

/// `evaluate` with global flags before the command (`--keep`: a failed verdict exits 0).
fn evaluate_with(cal: &Path, table: &Path, json_out: &Path, refit: bool, flags: &[&str]) -> serde_json::Value {
    let mut cmd = ferrocal();
    cmd.args(flags)
        .args(["evaluate", "--robot", "ur5", "--calibration"])
        .arg(cal)
        .arg("--measurements")
        .arg(table)
        .arg("--json")
        .arg(json_out);
    if refit {
        cmd.arg("--refit-frame");
    }
    ok(&mut cmd);
    json(json_out)
}

/// Tolerance: the compensated model must lower the held-out mean of the geometric calibration
/// (measured in the stop that added this test: 0.1030 -> 0.0709 mm on these blocks; the test
/// asks for at least 5 %).
#[test]
fn diagnose_out_compensates_held_out_blocks_of_the_ur5() {
    let tmp = tempfile::tempdir().unwrap();
    let table = ur5_blocks(tmp.path());
    let test = test_rows(&table, tmp.path());
    let geo = tmp.path().join("geo.json");
    ok(ferrocal().args(["calibrate", "--robot", "ur5", "--measurements"]).arg(&table).arg("--out").arg(&geo));
    let comp = tmp.path().join("comp.json");
    let diag = tmp.path().join("diag.json");
    ok(ferrocal()
        .args(["diagnose", "--robot", "ur5", "--measurements"])
        .arg(&table)
        .arg("--json")
        .arg(&diag)
        .arg("--report")
        .arg(tmp.path().join("diag.html"))
        .arg("--out")
        .arg(&comp));
    ferrocal_tests::assert_verdict_box(&tmp.path().join("diag.html"), &json(&diag));
    let findings = json(&diag)["findings"].as_array().unwrap().len();
    let c = json(&comp);
    assert_eq!(c["effects"].as_array().unwrap().len(), findings, "every accepted effect is in the calibration");
    assert!(findings >= 1, "the UR5 recording shows periodic joint errors");

    let e_geo = evaluate(&geo, &test, &tmp.path().join("e_geo.json"), false);
    let e_comp = evaluate(&comp, &test, &tmp.path().join("e_comp.json"), false);
    let (g, k) = (e_geo["mean_mm"].as_f64().unwrap(), e_comp["mean_mm"].as_f64().unwrap());
    eprintln!("UR5 held-out blocks ({} poses): geometric {g:.4} mm, with the diagnosed effects {k:.4} mm", e_geo["n"]);
    assert_eq!(e_geo["n"].as_u64(), Some(250));
    assert!(k < 0.95 * g, "compensated {k:.4} mm vs geometric {g:.4} mm");

    // The same model fitted from scratch by `calibrate --effects <diagnose json>`.
    let again = tmp.path().join("again.json");
    ok(ferrocal()
        .args(["calibrate", "--robot", "ur5", "--measurements"])
        .arg(&table)
        .arg("--out")
        .arg(&again)
        .arg("--no-validation")
        .arg("--effects")
        .arg(&diag));
    let e_again = evaluate(&again, &test, &tmp.path().join("e_again.json"), false);
    let a = e_again["mean_mm"].as_f64().unwrap();
    assert!((a - k).abs() < 0.002, "calibrate --effects {a:.4} mm vs diagnose --out {k:.4} mm");
}

/// A table seen from another device frame: without the refit the errors are the frame change;
/// with `--refit-frame` the model scores as it did in its own frame.
#[test]
fn evaluate_refit_frame_scores_a_model_in_another_devices_frame() {
    let tmp = tempfile::tempdir().unwrap();
    let table = import_ur5(tmp.path());
    let cal = tmp.path().join("cal.json");
    ok(ferrocal()
        .args(["calibrate", "--robot", "ur5", "--no-validation", "--measurements"])
        .arg(&table)
        .arg("--out")
        .arg(&cal));
    // Move every measured point by a rigid transform: 30 deg about z, then (1500, -200, 300) mm.
    let text = std::fs::read_to_string(&table).unwrap();
    let mut moved = String::new();
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    for line in text.lines().filter(|l| !l.starts_with('#')) {
        if line.starts_with("pose_id") {
            moved.push_str(line);
            moved.push('\n');
            continue;
        }
        let mut f: Vec<String> = line.split(',').map(String::from).collect();
        let v: Vec<f64> = f[7..10].iter().map(|x| x.parse().unwrap()).collect();
        let p = [c * v[0] - s * v[1] + 1500.0, s * v[0] + c * v[1] - 200.0, v[2] + 300.0];
        for (k, x) in p.iter().enumerate() {
            f[7 + k] = format!("{x:.6}");
        }
        moved.push_str(&f.join(","));
        moved.push('\n');
    }
    let moved_path = tmp.path().join("moved.csv");
    std::fs::write(&moved_path, moved).unwrap();
    let own = evaluate(&cal, &table, &tmp.path().join("own.json"), false);
    // Without the refit the errors are the frame change: the verdict fails (exit 1), and
    // --keep keeps the result to read its numbers.
    let plain_json = tmp.path().join("plain.json");
    let out = ferrocal_tests::run(
        ferrocal()
            .args(["evaluate", "--robot", "ur5", "--calibration"])
            .arg(&cal)
            .arg("--measurements")
            .arg(&moved_path)
            .arg("--json")
            .arg(&plain_json),
    );
    assert_eq!(out.status.code(), Some(1), "a 100 mm error is a failed evaluation");
    assert_eq!(json(&plain_json)["verdict"]["status"], "fail");
    let plain = evaluate_with(&cal, &moved_path, &plain_json, false, &["--keep"]);
    let refit = evaluate(&cal, &moved_path, &tmp.path().join("refit.json"), true);
    let (o, p, r) =
        (own["mean_mm"].as_f64().unwrap(), plain["mean_mm"].as_f64().unwrap(), refit["mean_mm"].as_f64().unwrap());
    eprintln!("own frame {o:.4} mm, moved without refit {p:.1} mm, moved with --refit-frame {r:.4} mm");
    assert!(p > 100.0, "{p}");
    assert!((r - o).abs() < 1e-3, "refit {r} vs own {o}");
    let t = &refit["refit_frame"]["device_frame_after"][0];
    assert!(t.as_array().unwrap().iter().all(|x| x.as_f64().unwrap().is_finite()));
}

/// A calibration that stops at its iteration limit is not delivered as a success.
#[test]
fn an_unconverged_calibration_exits_non_zero_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let table = import_ur5(tmp.path());
    let cal = tmp.path().join("cal.json");
    let out = ferrocal_tests::run(
        ferrocal()
            .args(["calibrate", "--robot", "ur5", "--max-iterations", "1", "--measurements"])
            .arg(&table)
            .arg("--out")
            .arg(&cal),
    );
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("did not converge") && err.contains("--accept-unconverged"), "{err}");
    assert!(!cal.exists(), "an unconverged calibration was written");
    ok(ferrocal()
        .args(["calibrate", "--robot", "ur5", "--max-iterations", "1", "--accept-unconverged", "--measurements"])
        .arg(&table)
        .arg("--out")
        .arg(&cal));
    assert!(cal.exists());
}

/// The URDF export read back as the robot model reproduces `evaluate` on the UR5 table to
/// 1e-6 mm per pose and axis (measured: 9e-13 mm).
#[test]
fn exported_urdf_reproduces_evaluate_on_the_ur5_table() {
    let tmp = tempfile::tempdir().unwrap();
    let table = import_ur5(tmp.path());
    let cal = tmp.path().join("cal.json");
    ok(ferrocal()
        .args(["calibrate", "--robot", "ur5", "--no-validation", "--measurements"])
        .arg(&table)
        .arg("--out")
        .arg(&cal));
    let urdf = tmp.path().join("ur5_calibrated.urdf");
    ok(ferrocal().args(["export", "--robot", "ur5", "--calibration"]).arg(&cal).arg("--urdf").arg(&urdf));
    let companion = tmp.path().join("ur5_calibrated.calibration.json");
    assert!(std::fs::read_to_string(&urdf).unwrap().contains("<link name=\"target\">"));
    let a = evaluate(&cal, &table, &tmp.path().join("a.json"), false);
    let mut cmd = ferrocal();
    cmd.arg("evaluate")
        .arg("--robot")
        .arg(&urdf)
        .arg("--calibration")
        .arg(&companion)
        .arg("--measurements")
        .arg(&table)
        .arg("--json")
        .arg(tmp.path().join("b.json"));
    ok(&mut cmd);
    let b = json(&tmp.path().join("b.json"));
    let (pa, pb) = (a["per_pose"].as_array().unwrap(), b["per_pose"].as_array().unwrap());
    assert_eq!(pa.len(), 1000);
    let worst = pa
        .iter()
        .zip(pb)
        .flat_map(|(x, y)| ["dx_mm", "dy_mm", "dz_mm"].map(|k| (x[k].as_f64().unwrap() - y[k].as_f64().unwrap()).abs()))
        .fold(0.0, f64::max);
    assert!(worst < 1e-6, "{worst:e} mm");
}

/// `ferrocal correct` on the UR5 recording: the calibration's corrected commands for the table's
/// own joints. Under the calibrated model each corrected command reaches the pose the nominal
/// model meant (to 1 nm), and the error it removes is what the calibration found (0.01-5 mm); the
/// corrected commands run on the real robot are checked in simulation
/// (`datasets/tests/closed_loop.rs`). A program without joint columns is refused with
/// its file named, and nothing is written.
#[test]
fn correct_writes_commands_that_the_calibrated_model_puts_on_the_nominal_poses() {
    let tmp = tempfile::tempdir().unwrap();
    let table = import_ur5(tmp.path());
    let cal = tmp.path().join("cal.json");
    ok(ferrocal().args(["calibrate", "--robot", "ur5", "--measurements"]).arg(&table).arg("--out").arg(&cal));
    let program = tmp.path().join("program.csv");
    let text = std::fs::read_to_string(&table).unwrap();
    let lines: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).take(41).collect();
    std::fs::write(&program, lines.join("\n") + "\n").unwrap();
    let out = tmp.path().join("corrected.csv");
    let progs = ["corrected.mod", "corrected.ngc", "corrected.script", "corrected.src"].map(|f| tmp.path().join(f));
    ok(correct_cmd(&cal, &program, &out).args(program_flags(&progs)));
    let text = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<Vec<&str>> = text.lines().filter(|l| !l.starts_with('#')).map(|l| l.split(',').collect()).collect();
    let program_header: Vec<&str> = lines[0].split(',').collect();
    assert!(program_header[1].starts_with("q1_"));
    assert_eq!(rows[0][..2], ["pose_id", "q1_deg"], "revolute joints are written in degrees (spec/cli.md)");
    assert_eq!(rows.len(), 41);
    let col = |name: &str| rows[0].iter().position(|h| *h == name).unwrap();
    let (removed, residual) = (col("removed_error_mm"), col("residual_mm"));
    let mut mean = 0.0;
    for r in &rows[1..] {
        let v: f64 = r[removed].parse().unwrap();
        assert!(r[residual].parse::<f64>().unwrap() < 1e-6, "{r:?}");
        assert!(v > 0.01 && v < 5.0, "{r:?}");
        mean += v / 40.0;
    }
    eprintln!("UR5 program of 40 commands: the correction removes {mean:.4} mm on average");

    // The robot programs carry the same corrected commands (to their printed digits), in order.
    let csv_deg: Vec<Vec<f64>> = rows[1..]
        .iter()
        .map(|r| {
            (1..=6)
                .map(|j| {
                    let v: f64 = r[j].parse().unwrap();
                    if rows[0][j].ends_with("_rad") {
                        v.to_degrees()
                    } else {
                        v
                    }
                })
                .collect()
        })
        .collect();
    for (path, tol_deg) in progs.iter().zip([1e-4, 1e-4, 1e-5, 1e-4]) {
        let got = program_joints_deg(path);
        assert_eq!(got.len(), 40, "{}", path.display());
        for (g, w) in got.iter().zip(&csv_deg) {
            for (a, b) in g.iter().zip(w) {
                assert!((a - b).abs() < tol_deg, "{}: {g:?} vs {w:?}", path.display());
            }
        }
    }
    let krl = std::fs::read_to_string(&progs[3]).unwrap();
    assert!(krl.starts_with("DEF corrected( )") && krl.trim_end().ends_with("END"), "{krl}");
    let script = std::fs::read_to_string(&progs[2]).unwrap();
    assert!(script.contains("def corrected():") && script.trim_end().ends_with("corrected()"));
    // An output onto an input is refused, and nothing is written.
    let o = ferrocal_tests::run(correct_cmd(&cal, &program, tmp.path().join("again.csv")).arg("--rapid").arg(&program));
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("would overwrite"));
    assert!(!tmp.path().join("again.csv").exists());

    let bad = tmp.path().join("bad.csv");
    std::fs::write(&bad, "pose_id,x_mm\n1,2\n").unwrap();
    let out2 = tmp.path().join("never.csv");
    let o = ferrocal_tests::run(&mut correct_cmd(&cal, &bad, &out2));
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("bad.csv"));
    assert!(!out2.exists());

    // A user's program (#33 finding 7): its pose names and motion types are kept in every
    // language, and the programs are motion programs (no measurement steps, no waits).
    let named = tmp.path().join("named.csv");
    let mut text = format!("{},motion\n", lines[0]);
    for (k, l) in lines[1..5].iter().enumerate() {
        let (_, rest) = l.split_once(',').unwrap();
        text.push_str(&format!("weld_seam_{k},{rest},{}\n", if k % 2 == 1 { "linear" } else { "movej" }));
    }
    std::fs::write(&named, &text).unwrap();
    let progs = ["named.mod", "named.ngc", "named.script", "named.src"].map(|f| tmp.path().join(f));
    let o =
        ferrocal_tests::run(correct_cmd(&cal, &named, tmp.path().join("named_out.csv")).args(program_flags(&progs)));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for p in &progs {
        let t = std::fs::read_to_string(p).unwrap();
        for k in 0..4 {
            assert!(t.contains(&format!("weld_seam_{k}")), "{}: pose name {k} lost:\n{t}", p.display());
        }
        for word in ["measure", "sleep(", "WAIT SEC", "WaitTime", "G4 "] {
            assert!(!t.contains(word), "{}: a motion program has '{word}':\n{t}", p.display());
        }
    }
    let script = std::fs::read_to_string(&progs[2]).unwrap();
    let moves: Vec<&str> =
        script.lines().map(str::trim).filter(|l| l.starts_with("movej(") || l.starts_with("movel(")).collect();
    assert_eq!(moves.len(), 4);
    for (k, m) in moves.iter().enumerate() {
        assert_eq!(m.starts_with("movel("), k % 2 == 1, "{m}");
    }
    let krl = std::fs::read_to_string(&progs[3]).unwrap();
    assert_eq!(krl.matches("linear in the program").count(), 2, "{krl}");
    let csv = std::fs::read_to_string(tmp.path().join("named_out.csv")).unwrap();
    assert!(csv.contains(",motion,") && csv.contains(",linear,"), "{csv}");
    let stdout = String::from_utf8_lossy(&o.stdout);
    let verdict = stdout.lines().last().unwrap();
    assert!(verdict.starts_with("verdict: warning:") && verdict.contains("named.src"), "{verdict}");
    // An unknown motion word is refused naming the file, line and column; nothing is written.
    std::fs::write(&named, text.replacen(",linear\n", ",circular\n", 1)).unwrap();
    let out3 = tmp.path().join("never3.csv");
    let o = ferrocal_tests::run(&mut correct_cmd(&cal, &named, &out3));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("named.csv") && err.contains("line 3") && err.contains("circular"),
        "{err}"
    );
    assert!(!out3.exists());
}

/// `ferrocal correct --robot ur5 --calibration CAL --program PROGRAM --out OUT`; more arguments may
/// follow.
fn correct_cmd(cal: &Path, program: &Path, out: impl AsRef<std::ffi::OsStr>) -> std::process::Command {
    let mut c = ferrocal();
    c.args(["correct", "--robot", "ur5", "--calibration"]).arg(cal).arg("--program").arg(program).arg("--out").arg(out);
    c
}

/// The flags that write the four robot programs to `progs` (RAPID, G-code, URScript, KRL).
fn program_flags(progs: &[std::path::PathBuf; 4]) -> Vec<std::ffi::OsString> {
    ["--rapid", "--gcode", "--urscript", "--krl"]
        .iter()
        .zip(progs)
        .flat_map(|(f, p)| [std::ffi::OsString::from(f), p.clone().into_os_string()])
        .collect()
}

/// The joint values (degrees) of every move of a RAPID, G-code, URScript or KRL program that
/// `ferrocal correct` wrote.
fn program_joints_deg(path: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    let nums = |s: &str| -> Vec<f64> { s.split(',').map(|x| x.trim().parse::<f64>().unwrap()).collect() };
    let mut out = Vec::new();
    for l in text.lines().map(str::trim) {
        if let Some(rest) = l.strip_prefix("CONST jointtarget ") {
            let inner = &rest[rest.find("[[").unwrap() + 2..rest.find("],[").unwrap()];
            out.push(nums(inner));
        } else if let Some(rest) = l.strip_prefix("movej([") {
            out.push(nums(&rest[..rest.find(']').unwrap()]).iter().map(|r| r.to_degrees()).collect());
        } else if let Some(rest) = l.strip_prefix("PTP {AXIS: ") {
            let inner = &rest[..rest.find('}').unwrap()];
            out.push(inner.split(',').map(|w| w.split_whitespace().nth(1).unwrap().parse().unwrap()).collect());
        } else if let Some(rest) = l.strip_prefix("G1 ") {
            out.push(
                rest.split_whitespace().filter(|w| !w.starts_with('F')).map(|w| w[1..].parse().unwrap()).collect(),
            );
        }
    }
    out
}

/// Reads `ferrocal export --dh`'s table: the joint rows and the base and tool transforms.
struct DhTable {
    rows: Vec<[f64; 5]>,
    base: nalgebra::Isometry3<f64>,
    tool: nalgebra::Isometry3<f64>,
}

fn read_dh(path: &Path) -> DhTable {
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};
    let text = std::fs::read_to_string(path).unwrap();
    let mut rows = Vec::new();
    let (mut base, mut tool) = (None, None);
    let pose = |v: &[f64]| {
        Isometry3::from_parts(
            Translation3::new(v[0] * 1e-3, v[1] * 1e-3, v[2] * 1e-3),
            UnitQuaternion::from_euler_angles(v[3].to_radians(), v[4].to_radians(), v[5].to_radians()),
        )
    };
    for line in text.lines() {
        let f: Vec<&str> = line.trim_start_matches("# ").split(',').collect();
        if line.starts_with("# base,") || line.starts_with("# tool,") {
            let v: Vec<f64> = f[1..].iter().map(|x| x.parse().unwrap()).collect();
            if f[0] == "base" {
                base = Some(pose(&v));
            } else {
                tool = Some(pose(&v));
            }
        } else if !line.starts_with('#') && !line.starts_with("joint,") {
            assert_eq!(f[1], "revolute", "{line}");
            let v: Vec<f64> = f[2..7].iter().map(|x| x.parse().unwrap()).collect();
            rows.push([v[0], v[1], v[2], v[3], v[4]]);
        }
    }
    DhTable { rows, base: base.unwrap(), tool: tool.unwrap() }
}

/// The table's forward kinematics (its own convention, written in its header):
/// `Rx(alpha) Tx(a) Ry(beta) Rz(theta + q) Tz(d)` per joint, `q` in radians; millimetres out.
fn dh_position_mm(t: &DhTable, q_rad: &[f64]) -> nalgebra::Vector3<f64> {
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
    let rot = |axis: nalgebra::Unit<Vector3<f64>>, a: f64| {
        Isometry3::from_parts(Translation3::identity(), UnitQuaternion::from_axis_angle(&axis, a))
    };
    let mut m = t.base;
    for (r, q) in t.rows.iter().zip(q_rad) {
        let [a_mm, alpha_deg, beta_deg, d_mm, theta_deg] = *r;
        m = m
            * rot(Vector3::x_axis(), alpha_deg.to_radians())
            * Isometry3::translation(a_mm * 1e-3, 0.0, 0.0)
            * rot(Vector3::y_axis(), beta_deg.to_radians())
            * rot(Vector3::z_axis(), theta_deg.to_radians() + q)
            * Isometry3::translation(0.0, 0.0, d_mm * 1e-3);
    }
    (m * t.tool).translation.vector * 1e3
}

/// The DH export, read back from its CSV with the convention its header states, reproduces
/// `evaluate`'s per-pose errors on the UR5 table to 1e-6 mm: the calibrated corrections and
/// zero offsets are in the table, the parallel joints 2-4 in Hayati's form (bounded lengths).
#[test]
fn exported_dh_table_reproduces_evaluate_on_the_ur5_table() {
    let tmp = tempfile::tempdir().unwrap();
    let table = import_ur5(tmp.path());
    let cal = tmp.path().join("cal.json");
    ok(ferrocal()
        .args(["calibrate", "--robot", "ur5", "--no-validation", "--measurements"])
        .arg(&table)
        .arg("--out")
        .arg(&cal));
    let dh = tmp.path().join("ur5_dh.csv");
    ok(ferrocal().args(["export", "--robot", "ur5", "--calibration"]).arg(&cal).arg("--dh").arg(&dh));
    let t = read_dh(&dh);
    assert_eq!(t.rows.len(), 6);
    let text = std::fs::read_to_string(&dh).unwrap();
    assert_eq!(text.lines().filter(|l| l.ends_with(",true")).count(), 2, "joints 3 and 4 in Hayati's form\n{text}");
    for r in &t.rows {
        assert!(r[0].abs() < 1000.0 && r[3].abs() < 1000.0, "{r:?}");
    }
    let a = evaluate(&cal, &table, &tmp.path().join("a.json"), false);
    let per_pose = a["per_pose"].as_array().unwrap();
    let text = std::fs::read_to_string(&table).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let qcols: Vec<(usize, bool)> = header
        .iter()
        .enumerate()
        .filter(|(_, h)| h.starts_with('q') && (h.ends_with("_deg") || h.ends_with("_rad")))
        .map(|(i, h)| (i, h.ends_with("_deg")))
        .collect();
    assert_eq!(qcols.len(), 6, "{header:?}");
    let xyz: Vec<usize> =
        ["x_mm", "y_mm", "z_mm"].iter().map(|n| header.iter().position(|h| h == n).unwrap()).collect();
    let mut worst = 0.0f64;
    for (line, e) in lines.zip(per_pose) {
        let f: Vec<f64> = line.split(',').map(|x| x.parse().unwrap_or(f64::NAN)).collect();
        let q: Vec<f64> = qcols.iter().map(|&(i, deg)| if deg { f[i].to_radians() } else { f[i] }).collect();
        let p = dh_position_mm(&t, &q);
        for (k, name) in ["dx_mm", "dy_mm", "dz_mm"].iter().enumerate() {
            let want = e[name].as_f64().unwrap();
            worst = worst.max((f[xyz[k]] - p[k] - want).abs());
        }
    }
    assert_eq!(per_pose.len(), 1000);
    eprintln!("DH table against evaluate: worst {worst:e} mm");
    assert!(worst < 1e-6, "{worst:e} mm");
}
