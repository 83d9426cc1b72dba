//! The hostile-input suite of issue #30 as one table through the binary: a user's slips (not
//! attacks) from the issue's "Why", each an input edit, the command line, the exit status and
//! the words the message must hold. Every case must end within its time bound, never panic,
//! and leave none of its outputs behind when it refuses. The slow cases (those that detect
//! corners in real images, render a recording or fit a large table) stay in their own tests
//! (`reliability`, `measure`, `handeye_checks`, `positioner`); docs/reliability.md lists both.

use std::path::Path;
use std::time::{Duration, Instant};

use ferrocal_calib::file::CalibrationFile;
use ferrocal_calib::kinematic::CalibratedModel;
use ferrocal_robot::RobotModel;
use ferrocal_tests::{ferrocal, import_ur5};

/// One hostile input.
struct Case {
    /// The input in the issue's words.
    what: &'static str,
    /// Writes the case's input into the folder (beside the base files `small.csv`, `cal.json`,
    /// `prog.csv`).
    edit: fn(&Path),
    /// The command line; `{d}` is the folder, `{root}` the repository.
    args: &'static [&'static str],
    /// The exit status.
    exit: i32,
    /// Words the output (stderr and stdout) must hold.
    says: &'static [&'static str],
    /// Outputs (in the folder) that must not exist afterwards.
    absent: &'static [&'static str],
}

/// The data rows of `small.csv` with `f` applied to each (cells by column); the comment and the
/// header kept (the header through `header`).
fn rewrite(d: &Path, name: &str, header: fn(&str) -> String, f: fn(usize, &str, &mut String)) {
    let text = std::fs::read_to_string(d.join("small.csv")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let cols: Vec<&str> = lines[1].split(',').collect();
    let mut out = vec![lines[0].to_string(), header(lines[1])];
    for (k, line) in lines[2..].iter().enumerate() {
        let mut cells: Vec<String> = line.split(',').map(str::to_string).collect();
        for (c, cell) in cells.iter_mut().enumerate() {
            f(k, cols[c], cell);
        }
        out.push(cells.join(","));
    }
    std::fs::write(d.join(name), out.join("\n") + "\n").unwrap();
}

fn same(h: &str) -> String {
    h.to_string()
}

/// A calibration file whose `joint1.alpha_rad` (nominal pi/2) is `value`.
fn twist(d: &Path, name: &str, value: f64) {
    let mut c: CalibrationFile = serde_json::from_str(&std::fs::read_to_string(d.join("cal.json")).unwrap()).unwrap();
    c.parameters.iter_mut().find(|p| p.name == "joint1.alpha_rad").unwrap().value = value;
    std::fs::write(d.join(name), serde_json::to_string(&c).unwrap()).unwrap();
}

fn nothing(_: &Path) {}

const CASES: &[Case] = &[
    Case {
        what: "a German spreadsheet CSV (';' and decimal commas)",
        edit: |d| {
            let text = std::fs::read_to_string(d.join("small.csv")).unwrap();
            let chars: Vec<char> = text.chars().collect();
            let digit = |j: usize| chars.get(j).is_some_and(|c| c.is_ascii_digit());
            let out: String = (0..chars.len())
                .map(|i| match chars[i] {
                    ',' => ';',
                    '.' if i > 0 && digit(i - 1) && digit(i + 1) => ',',
                    c => c,
                })
                .collect();
            std::fs::write(d.join("german.csv"), out).unwrap();
        },
        args: &["calibrate", "--robot", "ur5", "--measurements", "{d}/german.csv", "--out", "{d}/c.json"],
        exit: 1,
        says: &["german.csv", "separated by ';'", "'.' as the decimal point"],
        absent: &["c.json"],
    },
    Case {
        what: "CR-only line ends (classic Mac)",
        edit: |d| {
            let text = std::fs::read_to_string(d.join("small.csv")).unwrap();
            std::fs::write(d.join("cr.csv"), text.replace('\n', "\r")).unwrap();
        },
        args: &["import", "table", "--input", "{d}/cr.csv", "--out", "{d}/cr_out.csv"],
        exit: 0,
        says: &["imported 40 rows"],
        absent: &[],
    },
    Case {
        what: "a table of headers only",
        edit: |d| {
            let text = std::fs::read_to_string(d.join("small.csv")).unwrap();
            let head: Vec<&str> = text.lines().take(2).collect();
            std::fs::write(d.join("empty.csv"), head.join("\n") + "\n").unwrap();
        },
        args: &[
            "evaluate",
            "--robot",
            "ur5",
            "--calibration",
            "{d}/cal.json",
            "--measurements",
            "{d}/empty.csv",
            "--json",
            "{d}/e.json",
        ],
        exit: 1,
        says: &["empty.csv", "no rows to score"],
        absent: &["e.json"],
    },
    Case {
        what: "the same table given to calibrate",
        edit: nothing,
        args: &["calibrate", "--robot", "ur5", "--measurements", "{d}/empty.csv", "--out", "{d}/c.json"],
        exit: 1,
        says: &["empty.csv", "0 independent pose(s)"],
        absent: &["c.json"],
    },
    Case {
        what: "a joint of 1e308",
        edit: |d| {
            rewrite(d, "huge.csv", same, |k, col, cell| {
                if k == 3 && col == "q3_rad" {
                    *cell = "1e308".into();
                }
            })
        },
        args: &["calibrate", "--robot", "ur5", "--measurements", "{d}/huge.csv", "--out", "{d}/c.json"],
        exit: 1,
        says: &["huge.csv: line 6, column 'q3_rad'", "not a plausible joint value"],
        absent: &["c.json"],
    },
    Case {
        what: "degrees under _rad headers",
        edit: |d| {
            rewrite(d, "deg.csv", same, |_, col, cell| {
                if col.ends_with("_rad") {
                    *cell = format!("{}", cell.parse::<f64>().unwrap().to_degrees());
                }
            })
        },
        args: &["calibrate", "--robot", "ur5", "--measurements", "{d}/deg.csv", "--out", "{d}/c.json"],
        exit: 1,
        says: &["deg.csv: line 3, column 'q1_rad'", "look like degrees", "name the column q1_deg"],
        absent: &["c.json"],
    },
    Case {
        what: "radians under _deg headers",
        edit: |d| rewrite(d, "rad.csv", |h| h.replace("_rad", "_deg"), |_, _, _| {}),
        args: &["import", "table", "--input", "{d}/rad.csv", "--out", "{d}/rad_out.csv"],
        exit: 0,
        says: &["warning: ", "rad.csv", "look like radians", "name the columns q<i>_rad"],
        absent: &[],
    },
    Case {
        what: "metres under _mm headers",
        edit: |d| {
            rewrite(d, "metres.csv", same, |_, col, cell| {
                if col.ends_with("_mm") {
                    *cell = format!("{}", cell.parse::<f64>().unwrap() / 1000.0);
                }
            })
        },
        args: &["import", "table", "--input", "{d}/metres.csv", "--out", "{d}/metres_out.csv"],
        exit: 0,
        says: &["warning: ", "metres.csv", "look like metres", "name the columns x_m, y_m, z_m"],
        absent: &[],
    },
    Case {
        what: "metres under _mm headers given to calibrate (issue #44)",
        edit: nothing,
        args: &["calibrate", "--robot", "ur5", "--measurements", "{d}/metres.csv", "--out", "{d}/c.json"],
        exit: 1,
        says: &[
            "error: the table's units look wrong (the values look like metres; if so, name the columns x_m, y_m, z_m)",
        ],
        absent: &["c.json"],
    },
    Case {
        what: "metres under _mm headers given to diagnose (issue #44)",
        edit: nothing,
        args: &["diagnose", "--robot", "ur5", "--measurements", "{d}/metres.csv", "--json", "{d}/dg.json"],
        exit: 1,
        says: &["error: the table's units look wrong (the values look like metres"],
        absent: &["dg.json"],
    },
    Case {
        what: "UR5 rows calibrated as a UR10 (issue #44)",
        edit: nothing,
        args: &["calibrate", "--robot", "ur10", "--measurements", "{d}/small.csv", "--out", "{d}/c.json"],
        exit: 1,
        says: &["the solver did not converge", "changing joint2.corr_x_m by +18", "wrong --robot?"],
        absent: &["c.json"],
    },
    Case {
        what: "import says what calibrate will hold out (issue #44)",
        edit: nothing,
        args: &["import", "table", "--input", "{d}/small.csv", "--out", "{d}/held.csv"],
        exit: 0,
        says: &["imported 40 rows (0 marked test; no split column: calibrate holds out every second row, 20 of 40)"],
        absent: &[],
    },
    Case {
        what: "200 rows of one repeated pose",
        edit: |d| {
            let text = std::fs::read_to_string(d.join("small.csv")).unwrap();
            let lines: Vec<&str> = text.lines().collect();
            let mut out = vec![lines[0].to_string(), lines[1].to_string()];
            let cells: Vec<&str> = lines[2].split(',').collect();
            for k in 0..200 {
                out.push(format!("r{k},{}", cells[1..].join(",")));
            }
            std::fs::write(d.join("one_pose.csv"), out.join("\n") + "\n").unwrap();
        },
        args: &["calibrate", "--robot", "ur5", "--measurements", "{d}/one_pose.csv", "--out", "{d}/c.json"],
        exit: 1,
        says: &["the 200 rows hold 1 independent pose(s)"],
        absent: &["c.json"],
    },
    Case {
        what: "--params naming nothing",
        edit: nothing,
        args: &[
            "calibrate",
            "--robot",
            "ur5",
            "--measurements",
            "{d}/small.csv",
            "--out",
            "{d}/c.json",
            "--params",
            ",",
        ],
        exit: 1,
        says: &["names no parameter"],
        absent: &["c.json"],
    },
    Case {
        what: "a twist of 1e308 rad in a calibration file",
        edit: |d| twist(d, "huge_cal.json", 1e308),
        args: &["export", "--robot", "ur5", "--calibration", "{d}/huge_cal.json", "--dh", "{d}/dh.csv"],
        exit: 1,
        says: &["huge_cal.json", "'joint1.alpha_rad' = 1.000e308 rad", "not a calibration of this robot"],
        absent: &["dh.csv"],
    },
    Case {
        what: "a twist of 90 (degrees) in a radian field",
        edit: |d| twist(d, "deg_cal.json", 90.0),
        args: &[
            "correct",
            "--robot",
            "ur5",
            "--calibration",
            "{d}/deg_cal.json",
            "--program",
            "{d}/prog.csv",
            "--out",
            "{d}/o.csv",
        ],
        exit: 1,
        says: &["'joint1.alpha_rad' = 90.000000 rad", "was it written in degrees?"],
        absent: &["o.csv"],
    },
    Case {
        what: "export --urdf X --dh X",
        edit: nothing,
        args: &["export", "--robot", "ur5", "--calibration", "{d}/cal.json", "--urdf", "{d}/X", "--dh", "{d}/X"],
        exit: 1,
        says: &["is named as two outputs"],
        absent: &["X"],
    },
    Case {
        what: "correct --krl equal to --out",
        edit: nothing,
        args: &[
            "correct",
            "--robot",
            "ur5",
            "--calibration",
            "{d}/cal.json",
            "--program",
            "{d}/prog.csv",
            "--out",
            "{d}/K.src",
            "--krl",
            "{d}/K.src",
        ],
        exit: 1,
        says: &["K.src is named as two outputs"],
        absent: &["K.src"],
    },
    Case {
        what: "correct --rapid equal to --gcode",
        edit: nothing,
        args: &[
            "correct",
            "--robot",
            "ur5",
            "--calibration",
            "{d}/cal.json",
            "--program",
            "{d}/prog.csv",
            "--out",
            "{d}/o.csv",
            "--rapid",
            "{d}/R.mod",
            "--gcode",
            "{d}/R.mod",
        ],
        exit: 1,
        says: &["R.mod is named as two outputs"],
        absent: &["R.mod", "o.csv"],
    },
    Case {
        what: "correct --out naming its program",
        edit: nothing,
        args: &[
            "correct",
            "--robot",
            "ur5",
            "--calibration",
            "{d}/cal.json",
            "--program",
            "{d}/prog.csv",
            "--out",
            "{d}/prog.csv",
        ],
        exit: 1,
        says: &["would overwrite the input", "prog.csv"],
        absent: &[],
    },
    Case {
        what: "robot fk with a joint of 1e300",
        edit: nothing,
        args: &["robot", "fk", "--robot", "ur5", "--joints", "0,1e300,0,0,0,0"],
        exit: 1,
        says: &["joint 2", "outside the limits"],
        absent: &[],
    },
    Case {
        what: "a glob matching no image",
        edit: nothing,
        args: &[
            "detect",
            "--pattern",
            "chessboard:9x6:25mm",
            "--images",
            "{d}/nomatch/*.png",
            "--json",
            "{d}/det.json",
        ],
        exit: 1,
        says: &["no image file matches", "nomatch/*.png"],
        absent: &["det.json"],
    },
    Case {
        what: "a FIFO given as an image",
        edit: |d| {
            let fifo = d.join("camera.png");
            assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        },
        args: &["detect", "--pattern", "chessboard:9x6:25mm", "--images", "{d}/camera.png", "--json", "{d}/det.json"],
        exit: 2,
        says: &["camera.png", "named pipe (FIFO), not an image file"],
        absent: &[],
    },
    Case {
        what: "/dev/zero given as an image",
        edit: nothing,
        args: &["detect", "--pattern", "chessboard:9x6:25mm", "--images", "/dev/zero", "--json", "{d}/det.json"],
        exit: 2,
        says: &["/dev/zero", "character device"],
        absent: &[],
    },
    Case {
        what: "dynamics simulate --rate-hz 1e12",
        edit: nothing,
        args: &["dynamics", "simulate", "--rate-hz", "1e12", "--out", "{d}/dyn"],
        exit: 1,
        says: &["--rate-hz 1000000000000", "at most"],
        absent: &["dyn"],
    },
    Case {
        what: "handeye simulate --train 100000",
        edit: nothing,
        args: &["handeye", "simulate", "--mount", "eye-to-hand", "--train", "100000", "--out", "{d}/he"],
        exit: 1,
        says: &["at most 2000"],
        absent: &["he"],
    },
    Case {
        what: "plan --simulations 20000",
        edit: nothing,
        args: &[
            "plan",
            "--simulations",
            "20000",
            "--plan",
            "{root}/datasets/cells/plan_gantry_tau_l1.toml",
            "--out",
            "{d}/plan_out",
        ],
        exit: 1,
        says: &["--simulations = 20000", "more than 10000"],
        absent: &["plan_out"],
    },
    Case {
        what: "a legal 250-character output name",
        edit: nothing,
        args: &["import", "table", "--input", "{d}/small.csv", "--out", "{d}/{long}"],
        exit: 0,
        says: &["imported 40 rows"],
        absent: &[],
    },
];

#[cfg(unix)]
#[test]
fn hostile_inputs_are_refused_or_flagged_naming_the_cause() {
    let started = Instant::now();
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    // The base files: 40 rows of the UR5 table, the nominal UR5 as a calibration file, a program.
    let ur5 = std::fs::read_to_string(import_ur5(d)).unwrap();
    let lines: Vec<&str> = ur5.lines().take(42).collect();
    assert!(lines[1].starts_with("pose_id,q1_rad"), "{}", lines[1]);
    std::fs::write(d.join("small.csv"), lines.join("\n") + "\n").unwrap();
    let model = RobotModel::load("ur5").unwrap();
    let cal = CalibrationFile::new("ur5", &CalibratedModel::nominal(model));
    std::fs::write(d.join("cal.json"), serde_json::to_string_pretty(&cal).unwrap()).unwrap();
    let program: Vec<String> = lines[1..8].iter().map(|l| l.split(',').take(7).collect::<Vec<_>>().join(",")).collect();
    std::fs::write(d.join("prog.csv"), program.join("\n") + "\n").unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let long = format!("{}.csv", "a".repeat(246));
    let mut failures = Vec::new();
    for case in CASES {
        (case.edit)(d);
        let args: Vec<String> = case
            .args
            .iter()
            .map(|a| {
                a.replace("{d}", &d.display().to_string())
                    .replace("{root}", &root.display().to_string())
                    .replace("{long}", &long)
            })
            .collect();
        let t0 = Instant::now();
        let out = ferrocal().args(&args).output().unwrap();
        let took = t0.elapsed();
        let text = format!("{}{}", String::from_utf8_lossy(&out.stderr), String::from_utf8_lossy(&out.stdout));
        let mut wrong = Vec::new();
        if out.status.code() != Some(case.exit) {
            wrong.push(format!("exit {:?}, expected {}", out.status.code(), case.exit));
        }
        wrong.extend(case.says.iter().filter(|s| !text.contains(**s)).map(|s| format!("no '{s}'")));
        if text.contains("panicked") || text.contains("memory allocation") {
            wrong.push("a panic or an allocation failure".into());
        }
        wrong.extend(case.absent.iter().filter(|f| d.join(f).exists()).map(|f| format!("{f} was written")));
        if took > Duration::from_secs(20) {
            wrong.push(format!("took {took:?}"));
        }
        if !wrong.is_empty() {
            failures.push(format!(
                "{}: {}\n  ferrocal {}\n  {}",
                case.what,
                wrong.join("; "),
                args.join(" "),
                text.trim()
            ));
        }
    }
    // The 250-character name was written, and no staging file is left beside it.
    assert!(d.join(&long).exists(), "{long} not written");
    let staged: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(staged.is_empty(), "staging files left: {staged:?}");
    assert!(failures.is_empty(), "{} of {} cases:\n{}", failures.len(), CASES.len(), failures.join("\n"));
    eprintln!("{} hostile inputs in {:.1} s", CASES.len(), started.elapsed().as_secs_f64());
}
