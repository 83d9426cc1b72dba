//! Bad input through the binary (issue #16, docs/reliability.md): every case ends in a clear
//! error or a correct result, never a hang, never exit 0 with a wrong result, never a destroyed
//! file. Each test is named after the input it tries.

use std::path::{Path, PathBuf};
use std::process::Output;
use std::time::{Duration, Instant};

use ferrocal_tests::{data, ferrocal, import_ur5, json, run};

/// Runs a command that must fail within `limit`; returns its stderr.
fn fails_within(cmd: &mut std::process::Command, limit: Duration) -> String {
    let t0 = Instant::now();
    let out: Output = cmd.output().unwrap();
    let took = t0.elapsed();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "{cmd:?} succeeded; stderr: {err}");
    assert!(took < limit, "{cmd:?} took {took:?}");
    err
}

/// The imported UR5 table with some rows rewritten by `edit(row index, cells)`.
fn edited(dir: &Path, name: &str, rows: Option<usize>, edit: impl Fn(usize, &mut Vec<String>)) -> PathBuf {
    let table = import_ur5(dir);
    let text = std::fs::read_to_string(&table).unwrap();
    let mut out = String::new();
    let mut k = 0;
    for line in text.lines() {
        if line.starts_with('#') || line.starts_with("pose_id") {
            out.push_str(line);
            out.push('\n');
            continue;
        }
        if rows.is_some_and(|n| k >= n) {
            break;
        }
        let mut cells: Vec<String> = line.split(',').map(str::to_string).collect();
        edit(k, &mut cells);
        out.push_str(&cells.join(","));
        out.push('\n');
        k += 1;
    }
    let p = dir.join(name);
    std::fs::write(&p, out).unwrap();
    p
}

fn calibrate(table: &Path, out: &Path) -> std::process::Command {
    let mut c = ferrocal();
    c.args(["calibrate", "--robot", "ur5", "--measurements"]).arg(table).arg("--out").arg(out);
    c
}

#[test]
fn joint_of_1e308_is_refused_by_calibrate_and_diagnose_naming_the_row() {
    let tmp = tempfile::tempdir().unwrap();
    let t = edited(tmp.path(), "huge.csv", Some(60), |k, c| {
        if k == 7 {
            c[2] = "1e308".into();
        }
    });
    let cal = tmp.path().join("cal.json");
    let err = fails_within(&mut calibrate(&t, &cal), Duration::from_secs(30));
    assert!(err.contains("line 10, column 'q2_rad'") && err.contains("1e308"), "{err}");
    let err = fails_within(
        ferrocal()
            .args(["diagnose", "--robot", "ur5", "--measurements"])
            .arg(&t)
            .arg("--json")
            .arg(tmp.path().join("d.json")),
        Duration::from_secs(30),
    );
    assert!(err.contains("line 10, column 'q2_rad'"), "{err}");
    assert!(!cal.exists());
}

#[test]
fn fk_with_huge_joints_is_refused_instead_of_printing_nan() {
    let err = fails_within(
        ferrocal().args(["robot", "fk", "--robot", "ur5", "--joints", "0,1e300,0,0,0,0"]),
        Duration::from_secs(10),
    );
    assert!(err.contains("joint 2") && err.contains("outside the limits") && !err.contains("NaN"), "{err}");
    let out = run(ferrocal().args(["robot", "fk", "--robot", "ur5", "--joints", "0,-90,0,-90,0,0"]));
    assert!(out.status.success() && !String::from_utf8_lossy(&out.stdout).contains("NaN"));
}

#[test]
fn degrees_under_a_rad_header_are_refused_naming_the_column_and_unit() {
    let tmp = tempfile::tempdir().unwrap();
    let to_deg = |c: &mut Vec<String>| {
        for v in c.iter_mut().take(7).skip(1) {
            *v = v.parse::<f64>().unwrap().to_degrees().to_string();
        }
    };
    let all = edited(tmp.path(), "deg.csv", Some(100), |_, c| to_deg(c));
    let cal = tmp.path().join("cal.json");
    let err = fails_within(&mut calibrate(&all, &cal), Duration::from_secs(30));
    assert!(err.contains("column 'q1_rad'") && err.contains("name the column q1_deg"), "{err}");
    // Half the rows in degrees: the rows are counted and the unit suggested.
    let half = edited(tmp.path(), "half.csv", Some(100), |k, c| {
        if k % 2 == 1 {
            to_deg(c)
        }
    });
    let err = fails_within(&mut calibrate(&half, &cal), Duration::from_secs(30));
    assert!(err.contains("look like degrees while the others do not") && err.contains("of 100 rows"), "{err}");
    assert!(!cal.exists());
}

#[test]
fn table_cut_in_its_last_field_is_refused_or_warned() {
    let tmp = tempfile::tempdir().unwrap();
    let t = edited(tmp.path(), "t.csv", Some(100), |_, c| {
        for v in c.iter_mut().skip(7) {
            *v = format!("{:.6}", v.parse::<f64>().unwrap());
        }
    });
    let text = std::fs::read_to_string(&t).unwrap();
    let cut = tmp.path().join("cut.csv");
    std::fs::write(&cut, &text[..text.len() - 5]).unwrap();
    let cal = tmp.path().join("cal.json");
    let err = fails_within(&mut calibrate(&cut, &cal), Duration::from_secs(30));
    assert!(err.contains("column 'z_mm'") && err.contains("cut short"), "{err}");
    // Complete but without its final line end: calibrated, with a warning.
    std::fs::write(&cut, text.trim_end()).unwrap();
    let out = run(&mut calibrate(&cut, &cal));
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("warning: ") && cal.exists());
}

#[test]
fn evaluate_refuses_calibration_missing_parameters_for_another_robot_or_duplicated() {
    let tmp = tempfile::tempdir().unwrap();
    let t = edited(tmp.path(), "t.csv", Some(120), |_, _| {});
    let cal = tmp.path().join("cal.json");
    assert!(run(calibrate(&t, &cal).arg("--no-validation")).status.success());
    let full = json(&cal);
    let evaluate = |robot: &str, c: &Path| {
        let mut cmd = ferrocal();
        cmd.args(["evaluate", "--robot", robot, "--calibration"])
            .arg(c)
            .arg("--measurements")
            .arg(&t)
            .arg("--json")
            .arg(tmp.path().join("ev.json"));
        cmd
    };
    assert!(run(&mut evaluate("ur5", &cal)).status.success());
    // A table of headers only is refused, not scored as "RMS 0 mm, pass".
    let empty = edited(tmp.path(), "empty.csv", Some(0), |_, _| {});
    let err = fails_within(
        ferrocal()
            .args(["evaluate", "--robot", "ur5", "--calibration"])
            .arg(&cal)
            .arg("--measurements")
            .arg(&empty)
            .arg("--json")
            .arg(tmp.path().join("empty.json")),
        Duration::from_secs(30),
    );
    assert!(err.contains("empty.csv: the table has no rows to score"), "{err}");
    assert!(!tmp.path().join("empty.json").exists());
    let err = fails_within(&mut evaluate("ur10", &cal), Duration::from_secs(30));
    assert!(err.contains("made for robot 'ur5', not 'ur10'"), "{err}");
    let write = |name: &str, v: &serde_json::Value| {
        let p = tmp.path().join(name);
        std::fs::write(&p, serde_json::to_string(v).unwrap()).unwrap();
        p
    };
    // `correct` refuses a program in degrees under `_rad` headers, by row.
    let deg = edited(tmp.path(), "deg.csv", Some(30), |_, c| {
        for v in c.iter_mut().take(7).skip(1) {
            *v = v.parse::<f64>().unwrap().to_degrees().to_string();
        }
    });
    let err = fails_within(
        ferrocal()
            .args(["correct", "--robot", "ur5", "--calibration"])
            .arg(&cal)
            .arg("--program")
            .arg(&deg)
            .arg("--out")
            .arg(tmp.path().join("corrected.csv")),
        Duration::from_secs(30),
    );
    assert!(err.contains("deg.csv: line ") && err.contains("outside the limits"), "{err}");
    // Two outputs on one path are refused before any work, and nothing is written: `correct`
    // with `--krl` equal to `--out`, `--rapid` equal to `--gcode`; `export --urdf X --dh X`.
    let program = edited(tmp.path(), "program.csv", Some(20), |_, _| {});
    let same = tmp.path().join("same.out");
    for extra in [["--krl", "--out"], ["--rapid", "--gcode"]] {
        let mut c = ferrocal();
        c.args(["correct", "--robot", "ur5", "--calibration"]).arg(&cal).arg("--program").arg(&program);
        if extra[1] != "--out" {
            c.arg("--out").arg(tmp.path().join("corrected.csv"));
        }
        let err = fails_within(c.arg(extra[0]).arg(&same).arg(extra[1]).arg(&same), Duration::from_secs(30));
        assert!(err.contains("named as two outputs"), "{extra:?}: {err}");
        assert!(!same.exists() && !tmp.path().join("corrected.csv").exists(), "{extra:?}: nothing written");
    }
    let err = fails_within(
        ferrocal()
            .args(["export", "--robot", "ur5", "--calibration"])
            .arg(&cal)
            .arg("--urdf")
            .arg(&same)
            .arg("--dh")
            .arg(&same),
        Duration::from_secs(30),
    );
    assert!(err.contains("named as two outputs"), "{err}");
    assert!(!same.exists(), "export wrote nothing");
    let mut cut = full.clone();
    cut["parameters"].as_array_mut().unwrap().truncate(5);
    let err = fails_within(&mut evaluate("ur5", &write("cut.json", &cut)), Duration::from_secs(30));
    assert!(err.contains("lacks 67 of the 72 parameters"), "{err}");
    let mut twice = full.clone();
    let p0 = twice["parameters"][0].clone();
    twice["parameters"].as_array_mut().unwrap().push(p0);
    let err = fails_within(&mut evaluate("ur5", &write("twice.json", &twice)), Duration::from_secs(30));
    assert!(err.contains("'base.x_m' more than once"), "{err}");
}

#[test]
fn params_naming_nothing_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let t = edited(tmp.path(), "t.csv", Some(60), |_, _| {});
    let cal = tmp.path().join("cal.json");
    for (params, says) in [(",", "names no parameter"), ("joint9,bogus", "'joint9', 'bogus' match(es) no parameter")] {
        let err = fails_within(calibrate(&t, &cal).args(["--params", params]), Duration::from_secs(30));
        assert!(err.contains(says), "{params}: {err}");
    }
    assert!(!cal.exists());
}

#[test]
fn repeated_single_pose_table_is_refused_with_the_count_of_independent_poses() {
    let tmp = tempfile::tempdir().unwrap();
    let first: std::cell::RefCell<Option<Vec<String>>> = Default::default();
    let t = edited(tmp.path(), "same.csv", Some(200), |k, c| {
        let mut f = first.borrow_mut();
        let keep = f.get_or_insert_with(|| c.clone());
        c[1..].clone_from_slice(&keep[1..]);
        c[0] = k.to_string();
    });
    let cal = tmp.path().join("cal.json");
    let err = fails_within(&mut calibrate(&t, &cal), Duration::from_secs(30));
    assert!(err.contains("200 rows hold 1 independent pose"), "{err}");
    // Five distinct poses, each repeated 40 times: 15 equations cannot carry the parameters.
    let t = edited(tmp.path(), "five.csv", Some(200), |_, _| {});
    let text = std::fs::read_to_string(&t).unwrap();
    let lines: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
    let mut five = format!("{}\n", lines[0]);
    for k in 0..200 {
        let row = lines[1 + k % 5 * 37];
        five.push_str(&format!("{k}{}\n", &row[row.find(',').unwrap()..]));
    }
    std::fs::write(&t, five).unwrap();
    let err = fails_within(calibrate(&t, &cal).arg("--no-validation"), Duration::from_secs(60));
    assert!(err.contains("only 5 independent poses") && err.contains("rank-deficient"), "{err}");
    assert!(!cal.exists());
}

#[test]
fn long_cell_is_cut_in_the_error_message() {
    let tmp = tempfile::tempdir().unwrap();
    let t = edited(tmp.path(), "long.csv", Some(20), |k, c| {
        if k == 3 {
            c[8] = format!("1{}x", "2".repeat(5_000_000));
        }
    });
    let err = fails_within(&mut calibrate(&t, &tmp.path().join("c.json")), Duration::from_secs(30));
    assert!(
        err.contains("(5000002 characters)") && err.len() < 2000,
        "{} bytes: {}",
        err.len(),
        &err[..300.min(err.len())]
    );
}

#[test]
fn urdf_mimic_joint_is_coupled_or_refused_by_name_and_a_5000_joint_chain_loads_in_seconds() {
    let tmp = tempfile::tempdir().unwrap();
    let chain = |n: usize, leader: Option<&str>| {
        let mut s = String::from("<robot name=\"long\">\n<link name=\"l0\"/>\n");
        for i in 1..=n {
            let m = match leader {
                Some(l) if i == 3 => format!("<mimic joint=\"{l}\"/>"),
                _ => String::new(),
            };
            s.push_str(&format!(
                "<link name=\"l{i}\"/><joint name=\"j{i}\" type=\"revolute\"><parent link=\"l{}\"/><child link=\"l{i}\"/><origin xyz=\"0 0 0.01\"/><axis xyz=\"0 0 1\"/><limit lower=\"-3\" upper=\"3\"/>{m}</joint>\n",
                i - 1
            ));
        }
        s + "</robot>\n"
    };
    // A mimic joint is a coupled joint: five actuated joints of six.
    let p = tmp.path().join("mimic.urdf");
    std::fs::write(&p, chain(6, Some("j2"))).unwrap();
    let out = run(ferrocal().args(["robot", "info", "--robot"]).arg(&p));
    assert!(out.status.success() && String::from_utf8_lossy(&out.stdout).contains("(5 joints"));
    // A mimic of a joint that does not exist is refused by name.
    let p = tmp.path().join("bad_mimic.urdf");
    std::fs::write(&p, chain(6, Some("j9"))).unwrap();
    let err = fails_within(ferrocal().args(["robot", "info", "--robot"]).arg(&p), Duration::from_secs(10));
    assert!(err.contains("joint 'j3' mimics joint 'j9', which is not defined"), "{err}");
    let p = tmp.path().join("long.urdf");
    std::fs::write(&p, chain(5000, None)).unwrap();
    let t0 = Instant::now();
    let out = run(ferrocal().args(["robot", "info", "--robot"]).arg(&p));
    let secs = t0.elapsed().as_secs_f64();
    assert!(out.status.success() && String::from_utf8_lossy(&out.stdout).contains("5000 joints"));
    assert!(secs < 10.0, "5000-joint URDF took {secs:.1} s (quadratic parsing took minutes)");
}

#[test]
fn simulate_refuses_a_tracker_with_negative_sigma() {
    let tmp = tempfile::tempdir().unwrap();
    let cell =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../datasets/cells/gantry_tau_l1.toml"))
            .unwrap()
            .replace("sigma_const_um = 15.0", "sigma_const_um = -15.0");
    let p = tmp.path().join("cell.toml");
    std::fs::write(&p, cell).unwrap();
    let out_dir = tmp.path().join("session");
    let err = fails_within(
        ferrocal().args(["simulate", "--config"]).arg(&p).arg("--out").arg(&out_dir),
        Duration::from_secs(30),
    );
    assert!(err.contains("sigma_const_um = -15"), "{err}");
    assert!(!out_dir.exists());
}

#[test]
fn truncated_jpeg_and_huge_png_are_refused_by_name_and_the_batch_goes_on() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("imgs");
    std::fs::create_dir(&dir).unwrap();
    std::fs::copy(data("opencv_stereo/left01.jpg"), dir.join("left01.jpg")).unwrap();
    let bytes = std::fs::read(data("opencv_stereo/left02.jpg")).unwrap();
    std::fs::write(dir.join("half.jpg"), &bytes[..bytes.len() / 2]).unwrap();
    // A PNG header declaring 20000 x 20000 pixels.
    let mut png = vec![0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A, 0, 0, 0, 13];
    let ihdr: Vec<u8> =
        [b"IHDR".as_slice(), &20000u32.to_be_bytes(), &20000u32.to_be_bytes(), &[8, 0, 0, 0, 0]].concat();
    png.extend(&ihdr);
    png.extend(crc32(&ihdr).to_be_bytes());
    let idat: Vec<u8> = [b"IDAT".as_slice(), &[0x78, 0x9C, 0x63, 0, 0, 0, 1, 0, 1]].concat();
    png.extend(9u32.to_be_bytes());
    png.extend(&idat);
    png.extend(crc32(&idat).to_be_bytes());
    std::fs::write(dir.join("huge.png"), png).unwrap();
    let out_json = tmp.path().join("det.json");
    let out = run(ferrocal()
        .args(["detect", "--pattern", "chessboard:9x6:25mm", "--images"])
        .arg(&dir)
        .arg("--json")
        .arg(&out_json));
    assert!(!out.status.success(), "a failed image is not a success");
    let d = json(&out_json);
    let by_name =
        |n: &str| d.as_array().unwrap().iter().find(|x| x["image"].as_str().unwrap().ends_with(n)).unwrap().clone();
    assert!(by_name("half.jpg")["error"].as_str().unwrap().contains("truncated"));
    assert!(by_name("huge.png")["error"].as_str().unwrap().contains("20000 x 20000"));
    assert_eq!(by_name("left01.jpg")["detections"][0]["corners_px"].as_array().unwrap().len(), 54);
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for b in bytes {
        c ^= u32::from(*b);
        for _ in 0..8 {
            c = if c & 1 == 1 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
        }
    }
    !c
}

#[test]
fn out_naming_an_input_is_refused_in_every_command() {
    let tmp = tempfile::tempdir().unwrap();
    let t = edited(tmp.path(), "t.csv", Some(60), |_, _| {});
    let before = std::fs::read(&t).unwrap();
    let err = fails_within(&mut calibrate(&t, &t), Duration::from_secs(30));
    assert!(err.contains("would overwrite the input"), "{err}");
    let err = fails_within(
        ferrocal().args(["diagnose", "--robot", "ur5", "--measurements"]).arg(&t).arg("--json").arg(&t),
        Duration::from_secs(30),
    );
    assert!(err.contains("would overwrite the input"), "{err}");
    let err = fails_within(
        ferrocal().args(["import", "table", "--input"]).arg(&t).arg("--out").arg(&t),
        Duration::from_secs(30),
    );
    assert!(err.contains("would overwrite the input"), "{err}");
    let cal = tmp.path().join("cal.json");
    let err = fails_within(calibrate(&t, &cal).arg("--json").arg(&cal), Duration::from_secs(30));
    assert!(err.contains("two outputs"), "{err}");
    assert_eq!(std::fs::read(&t).unwrap(), before, "the input is untouched");
}

#[cfg(unix)]
#[test]
fn symlink_or_device_at_the_output_is_not_replaced() {
    let tmp = tempfile::tempdir().unwrap();
    let t = edited(tmp.path(), "t.csv", Some(60), |_, _| {});
    let target = tmp.path().join("elsewhere.json");
    std::fs::write(&target, "keep").unwrap();
    let link = tmp.path().join("cal.json");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let err = fails_within(&mut calibrate(&t, &link), Duration::from_secs(30));
    assert!(err.contains("symbolic link"), "{err}");
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    assert_eq!(std::fs::read_to_string(&target).unwrap(), "keep");
    let err = fails_within(
        ferrocal().args(["import", "table", "--input"]).arg(&t).arg("--out").arg("/dev/null"),
        Duration::from_secs(30),
    );
    assert!(err.contains("not a regular file"), "{err}");
}

#[test]
fn failing_report_leaves_no_calibration_file() {
    let tmp = tempfile::tempdir().unwrap();
    let t = edited(tmp.path(), "t.csv", Some(120), |_, _| {});
    let cal = tmp.path().join("cal.json");
    // The report's folder is a file: the report cannot be written.
    let blocker = tmp.path().join("blocker");
    std::fs::write(&blocker, "x").unwrap();
    let out = run(calibrate(&t, &cal).arg("--report").arg(blocker.join("rep.html")));
    assert!(!out.status.success());
    assert!(!cal.exists(), "the calibration file is written only with its report");
    let leftovers: Vec<_> = std::fs::read_dir(tmp.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

/// The UR5 table with a typo in one row: 50 mm added to one x (case a), x and y swapped in
/// another row (case b). The residual test of `ferrocal calibrate` names the row (stderr, the
/// JSON's `dropped_rows`, a warning in the verdict), leaves it out of the fit and of the held-out
/// score, and the held-out result is within 5 % of the clean table's; the clean table drops
/// nothing.
#[test]
fn a_typo_row_in_the_ur5_table_is_named_and_its_result_matches_the_clean_table() {
    let tmp = tempfile::tempdir().unwrap();
    let table = import_ur5(tmp.path());
    let text = std::fs::read_to_string(&table).unwrap();
    let calibrate = |csv: &Path, name: &str| -> (serde_json::Value, String) {
        let rep = tmp.path().join(format!("{name}.json"));
        let out = run(ferrocal()
            .args(["calibrate", "--robot", "ur5", "--measurements"])
            .arg(csv)
            .arg("--out")
            .arg(tmp.path().join(format!("{name}_cal.json")))
            .arg("--json")
            .arg(&rep));
        let stderr = String::from_utf8_lossy(&out.stderr).to_string();
        assert!(out.status.code().is_some_and(|c| c <= 1), "{name}: {stderr}");
        (json(&rep), stderr)
    };
    let (clean, _) = calibrate(&table, "clean");
    assert_eq!(clean["dropped_rows"].as_array().map(Vec::len), Some(0), "{}", clean["dropped_rows"]);
    let clean_mm = clean["heldout"]["after"]["mean_mm"].as_f64().unwrap();
    // The clean table's largest row against the threshold of 12 (measured 4.32).
    let clean_ratio = clean["largest_residual_ratio"].as_f64().unwrap();
    assert!(clean_ratio > 2.0 && clean_ratio < 6.0, "{clean_ratio}");
    // The data rows after the comment and the header.
    let lines: Vec<&str> = text.lines().collect();
    let header = lines.iter().position(|l| l.starts_with("pose_id")).unwrap();
    let cols: Vec<&str> = lines[header].split(',').collect();
    let (ix, iy) = (cols.iter().position(|c| *c == "x_mm").unwrap(), cols.iter().position(|c| *c == "y_mm").unwrap());
    for (case, row) in [("a", header + 101), ("b", header + 302)] {
        let mut cells: Vec<String> = lines[row].split(',').map(str::to_string).collect();
        let id = cells[0].clone();
        if case == "a" {
            cells[ix] = format!("{}", cells[ix].parse::<f64>().unwrap() + 50.0);
        } else {
            cells.swap(ix, iy);
        }
        let mut bad: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
        bad[row] = cells.join(",");
        let csv = tmp.path().join(format!("typo_{case}.csv"));
        std::fs::write(&csv, bad.join("\n") + "\n").unwrap();
        let (rep, stderr) = calibrate(&csv, &format!("typo_{case}"));
        let dropped: Vec<&str> =
            rep["dropped_rows"].as_array().unwrap().iter().map(|d| d["pose_id"].as_str().unwrap()).collect();
        assert_eq!(dropped, vec![id.as_str()], "case {case}: {stderr}");
        assert!(stderr.contains(&format!("row '{id}' (line {})", row + 1)) && stderr.contains("typo"), "{stderr}");
        assert_eq!(rep["verdict"]["status"], "warning", "{}", rep["verdict"]);
        let mm = rep["heldout"]["after"]["mean_mm"].as_f64().unwrap();
        let ratio = rep["dropped_rows"][0]["ratio"].as_f64().unwrap();
        eprintln!(
            "case {case}: row {id} dropped at {ratio:.0} times the scale; held-out mean {mm:.4} mm against the clean table's {clean_mm:.4} mm (largest clean row {clean_ratio:.2})"
        );
        assert!((mm - clean_mm).abs() <= 0.05 * clean_mm, "case {case}: {mm} vs {clean_mm}");
    }
    // Every tenth row 50 mm off (100 rows, beyond the cap of 10 rows or 5 %): not typos but a
    // broken table; nothing is dropped, the verdict fails (exit 1) and says what to check.
    let mut bad: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    for row in (header + 1..lines.len()).step_by(10) {
        let mut cells: Vec<String> = lines[row].split(',').map(str::to_string).collect();
        cells[ix] = format!("{}", cells[ix].parse::<f64>().unwrap() + 50.0);
        bad[row] = cells.join(",");
    }
    let csv = tmp.path().join("typo_many.csv");
    std::fs::write(&csv, bad.join("\n") + "\n").unwrap();
    let rep_path = tmp.path().join("many.json");
    let out = run(ferrocal()
        .args(["calibrate", "--robot", "ur5", "--no-validation", "--measurements"])
        .arg(&csv)
        .arg("--out")
        .arg(tmp.path().join("many_cal.json"))
        .arg("--json")
        .arg(&rep_path));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    let rep = json(&rep_path);
    assert_eq!(rep["dropped_rows"].as_array().map(Vec::len), Some(0));
    assert_eq!(rep["verdict"]["status"], "fail", "{}", rep["verdict"]);
    let note = rep["outlier_note"].as_str().unwrap();
    assert!(note.contains("100 of 1000 rows") && note.contains("too many to be typos"), "{note}");
    assert!(stderr.contains("calibrate.rows_beyond") && stderr.contains("--keep"), "{stderr}");
}

/// The UR10 series B table (1495 poses in several arm configurations) is clean but its tracker
/// states sigmas of 0.002-0.057 mm against residuals of 0.36 mm (median): over the stated sigma,
/// 17 rows stood beyond 8 times the others. The residual test's noise floor and threshold of 12
/// keep every row (the largest stands at 9.1 times the scale).
#[test]
fn the_clean_ur10_series_b_table_loses_no_row_to_the_residual_test() {
    let tmp = tempfile::tempdir().unwrap();
    let table = tmp.path().join("ur10b.csv");
    run(ferrocal()
        .args(["import", "ur10", "--input"])
        .arg(data("ur10_tracker/Series_B/measurements_joint_configurations.csv"))
        .arg("--out")
        .arg(&table));
    let rep = tmp.path().join("rep.json");
    let out = run(ferrocal()
        .args(["calibrate", "--robot", "ur10", "--no-validation", "--measurements"])
        .arg(&table)
        .arg("--out")
        .arg(tmp.path().join("cal.json"))
        .arg("--json")
        .arg(&rep));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // Issue #44: its s0 of about 21 over the tracker's 0.02 mm is the model's error, and the note
    // says so first (not "set the sigma to the device's noise").
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("the model leaves errors of this size unexplained"), "{stderr}");
    assert!(!stderr.contains("set the rows' sigma"), "{stderr}");
    let rep = json(&rep);
    // ... and the model checks of issue #44 pass on this real table (1.29 mm, 0.094 deg).
    for c in rep["verdict"]["checks"].as_array().unwrap() {
        if c["name"].as_str().is_some_and(|n| n.starts_with("calibrate.model_change")) {
            assert_eq!(c["status"], "pass", "{c}");
        }
    }
    assert_eq!(rep["dropped_rows"].as_array().map(Vec::len), Some(0), "{}", rep["dropped_rows"]);
    assert!(rep["outlier_note"].is_null(), "{}", rep["outlier_note"]);
    let ratio = rep["largest_residual_ratio"].as_f64().unwrap();
    eprintln!("UR10 series B: largest row at {ratio:.2} times the scale");
    assert!(ratio > 5.0 && ratio < 12.0, "{ratio}");
}

#[cfg(unix)]
#[test]
fn a_fifo_or_device_as_an_image_and_sizes_beyond_a_bound_are_named_before_any_work() {
    let tmp = tempfile::tempdir().unwrap();
    let fifo = tmp.path().join("camera.png");
    assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let detect = |img: &Path| {
        let out = ferrocal()
            .args(["detect", "--pattern", "chessboard:9x6:25mm", "--images"])
            .arg(img)
            .arg("--json")
            .arg(tmp.path().join("d.json"))
            .output()
            .unwrap();
        assert_ne!(out.status.code(), Some(0));
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    // A FIFO is never opened (opening one would wait for a writer forever).
    let err = detect(&fifo);
    assert!(err.contains("camera.png") && err.contains("named pipe (FIFO), not an image file"), "{err}");
    let err = detect(Path::new("/dev/zero"));
    assert!(err.contains("/dev/zero") && err.contains("character device"), "{err}");
    // A sample rate that would need 384 TB is refused by name, without a panic.
    let err = fails_within(
        ferrocal().args(["dynamics", "simulate", "--rate-hz", "1e12", "--out"]).arg(tmp.path().join("dyn")),
        Duration::from_secs(30),
    );
    assert!(err.contains("--rate-hz 1000000000000") && err.contains("at most"), "{err}");
    assert!(!err.contains("panicked") && !err.contains("memory allocation"), "{err}");
    // 100,000 rendered images are refused before the first is written.
    let he = tmp.path().join("he");
    let err = fails_within(
        ferrocal().args(["handeye", "simulate", "--mount", "eye-to-hand", "--train", "100000", "--out"]).arg(&he),
        Duration::from_secs(30),
    );
    assert!(err.contains("at most 2000"), "{err}");
    assert!(!he.exists(), "nothing written");
}

/// A plan asking for a billion simulated calibrations (in its file or by flag) is refused at
/// once, naming the key and the bound, and writes nothing.
#[test]
fn a_plan_with_a_billion_simulated_calibrations_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join("datasets/cells/plan_gantry_tau_l1.toml")).unwrap();
    assert!(text.contains("runs = 50"), "the built-in plan changed");
    let plan = tmp.path().join("plan.toml");
    std::fs::write(&plan, text.replace("runs = 50", "runs = 1000000000")).unwrap();
    let out_dir = tmp.path().join("out");
    let e = fails_within(
        ferrocal().args(["plan", "--plan"]).arg(&plan).arg("--out").arg(&out_dir),
        Duration::from_secs(60),
    );
    assert!(e.contains("[simulation] runs = 1000000000") && e.contains("more than 10000"), "{e}");
    let e = fails_within(
        ferrocal()
            .args(["plan", "--simulations", "20000", "--plan"])
            .arg(root.join("datasets/cells/plan_gantry_tau_l1.toml"))
            .arg("--out")
            .arg(&out_dir),
        Duration::from_secs(60),
    );
    assert!(e.contains("--simulations = 20000") && e.contains("more than 10000"), "{e}");
    assert!(!out_dir.exists(), "an output was written");
}
