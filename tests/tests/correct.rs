//! `ferrocal correct` on the shared UR5 recording's calibration: each row's command depends on
//! that row alone (`--program` and `--targets`), short programs with the tool pointing down
//! correct without error, an unreachable target is named while the others are written, and every
//! command carries its landing uncertainty. Where the corrected commands land on a robot that is
//! not the model is the closed-loop study (`datasets/tests/closed_loop.rs`).

use std::path::{Path, PathBuf};

use ferrocal_tests::{ferrocal, import_ur5, json, ok};

/// The UR5 table and its calibration, in `dir`.
fn calibrated(dir: &Path) -> (PathBuf, PathBuf) {
    let table = import_ur5(dir);
    let cal = dir.join("cal.json");
    ok(ferrocal().args(["calibrate", "--robot", "ur5", "--measurements"]).arg(&table).arg("--out").arg(&cal));
    (table, cal)
}

/// Runs `correct` on `input` (`--program` or `--targets`) and returns the CSV's header and rows
/// by pose id, and the JSON report.
fn correct(
    cal: &Path,
    flag: &str,
    input: &Path,
    out: &Path,
) -> (Vec<String>, Vec<Vec<String>>, serde_json::Value, std::process::Output) {
    let j = out.with_extension("json");
    let o = ferrocal_tests::run(
        ferrocal()
            .args(["correct", "--robot", "ur5", "--calibration"])
            .arg(cal)
            .arg(flag)
            .arg(input)
            .arg("--out")
            .arg(out)
            .arg("--json")
            .arg(&j),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(out).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines.map(|l| l.split(',').map(String::from).collect()).collect();
    (header, rows, json(&j), o)
}

fn joints_of(header: &[String], rows: &[Vec<String>], id: &str) -> Vec<f64> {
    let row = rows.iter().find(|r| r[0] == id).unwrap_or_else(|| panic!("no row {id}"));
    (1..=6)
        .map(|j| {
            let c = header.iter().position(|h| *h == format!("q{j}_deg")).unwrap();
            row[c].parse().unwrap()
        })
        .collect()
}

/// The must-hold: the same row, alone, among 5 others or among 11 others, gets the same
/// command to 1e-6 deg, as a program row and as a target (the table's measured position, its
/// joints as the start).
#[test]
fn a_rows_command_is_the_same_alone_among_5_or_among_11_others() {
    let tmp = tempfile::tempdir().unwrap();
    let (table, cal) = calibrated(tmp.path());
    let text = std::fs::read_to_string(&table).unwrap();
    let lines: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
    let (header, body) = (lines[0], &lines[1..13]);
    let id = body[3].split(',').next().unwrap().to_string();
    for flag in ["--program", "--targets"] {
        let mut got = Vec::new();
        for (name, rows) in [("alone", vec![body[3]]), ("six", body[..6].to_vec()), ("twelve", body.to_vec())] {
            let input = tmp.path().join(format!("{name}{flag}.csv"));
            std::fs::write(&input, format!("{header}\n{}\n", rows.join("\n"))).unwrap();
            let (h, r, j, _) = correct(&cal, flag, &input, &tmp.path().join(format!("{name}{flag}_out.csv")));
            assert_eq!(r.len(), rows.len(), "{flag} {name}: every row written");
            assert_eq!(j["n_written"], rows.len());
            got.push(joints_of(&h, &r, &id));
        }
        for other in &got[1..] {
            for (a, b) in got[0].iter().zip(other) {
                assert!((a - b).abs() < 1e-6, "{flag}: {:?} vs {:?}", got[0], other);
            }
        }
        eprintln!("{flag}: row {id} gets {:?} deg alone, among 5 and among 11 others", got[0]);
    }
}

/// Programs of 1, 2, 6 and 12 moves with the tool pointing down (joints 4-6 fixed, joint 1
/// turning), which a fit of the frames over the program refused, correct without error, and
/// every command carries a landing uncertainty of the calibration's size.
#[test]
fn short_programs_with_the_tool_pointing_down_correct_with_their_landing_uncertainty() {
    let tmp = tempfile::tempdir().unwrap();
    let (_, cal) = calibrated(tmp.path());
    for n in [1usize, 2, 6, 12] {
        let mut text = String::from("pose_id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\n");
        for k in 0..n {
            text.push_str(&format!("pick{k},{},-80,100,-110,-90,0\n", -30.0 + 5.0 * k as f64));
        }
        let program = tmp.path().join(format!("down{n}.csv"));
        std::fs::write(&program, text).unwrap();
        let (_, rows, j, o) = correct(&cal, "--program", &program, &tmp.path().join(format!("down{n}_out.csv")));
        assert_eq!(rows.len(), n);
        for r in j["rows"].as_array().unwrap() {
            let s = r["landing_sigma_mm"].as_f64().unwrap();
            assert!(s > 0.005 && s < 1.0, "{r}");
            assert!(r["residual_mm"].as_f64().unwrap() < 1e-6, "{r}");
        }
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(stdout.contains("predicted landing error"), "{stdout}");
        // The recording's joint 5 stayed within 47-147 deg: at -90 deg every row is outside the
        // calibrated region, and the verdict says so, by how much.
        let verdict = stdout.lines().last().unwrap();
        assert!(
            verdict.starts_with("verdict: warning")
                && verdict.contains(&format!("{n} of {n} rows lie outside the region"))
                && verdict.contains("joint 5 136.8 deg beyond"),
            "{verdict}"
        );
        for r in j["rows"].as_array().unwrap() {
            assert_eq!(r["outside_joint"], 5, "{r}");
        }
    }
}

/// A target the robot cannot reach is named in the verdict and left out; the others are
/// written, in the motion programs too.
#[test]
fn an_unreachable_target_is_named_and_the_others_are_written() {
    let tmp = tempfile::tempdir().unwrap();
    let (table, cal) = calibrated(tmp.path());
    let text = std::fs::read_to_string(&table).unwrap();
    let lines: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
    let header: Vec<&str> = lines[0].split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    // The measured positions of three rows as targets without a start, and one 3 m further out.
    let mut targets = String::from("pose_id,x_mm,y_mm,z_mm\n");
    for (k, l) in lines[1..4].iter().enumerate() {
        let c: Vec<&str> = l.split(',').collect();
        targets.push_str(&format!("t{k},{},{},{}\n", c[col("x_mm")], c[col("y_mm")], c[col("z_mm")]));
    }
    let c: Vec<&str> = lines[4].split(',').collect();
    let far: f64 = c[col("x_mm")].parse::<f64>().unwrap() + 3000.0;
    targets.push_str(&format!("too_far,{far},{},{}\n", c[col("y_mm")], c[col("z_mm")]));
    let input = tmp.path().join("targets.csv");
    std::fs::write(&input, targets).unwrap();
    let out = tmp.path().join("out.csv");
    let script = tmp.path().join("out.script");
    let o = ferrocal_tests::run(
        ferrocal()
            .args(["correct", "--robot", "ur5", "--calibration"])
            .arg(&cal)
            .arg("--targets")
            .arg(&input)
            .arg("--out")
            .arg(&out)
            .arg("--urscript")
            .arg(&script),
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&o.stderr));
    let verdict = stdout.lines().last().unwrap();
    assert!(
        verdict.starts_with("verdict: warning") && verdict.contains("cannot be reached") && verdict.contains("too_far"),
        "{verdict}"
    );
    assert!(stdout.contains("pose too_far (line 5) not written"), "{stdout}");
    let csv = std::fs::read_to_string(&out).unwrap();
    assert_eq!(csv.lines().filter(|l| l.starts_with('t')).count(), 3, "{csv}");
    assert!(!csv.contains("too_far"));
    let s = std::fs::read_to_string(&script).unwrap();
    assert_eq!(s.matches("movej(").count(), 3, "{s}");
}
