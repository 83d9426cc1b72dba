//! Detection and false-alarm rates of `ferrocal diagnose` on simulated tracker recordings.
//!
//! For three serial arms (UR5 and UR10 presets, the example URDF; all with link inertials) and
//! every effect kind, recordings are simulated with the effect's size set to a multiple of the
//! tracker noise, plus recordings with no effect at all. The size `rho` is the visible part of
//! the effect: the RMS residual it leaves after a geometric calibration on noise-free
//! measurements (what frames, offsets and link corrections cannot absorb), divided by the RMS
//! of the tracker's 3-D noise (`sqrt(3) sigma`, sigma = 15 um + 6 um/m at nominal noise). The
//! raw displacement ratio (before any absorption) is in the CSV as `rho_raw`. Each recording draws
//! the joint (compliance: 2 or 3; other joint effects: 1 to 5), the period of a periodic error,
//! 150, 250 or 400 poses, nominal or doubled noise, a constant or varying payload, and whether
//! the table carries sigma. Tables always carry `t_s`, `temp_c` (a warm-up), `dir` and
//! `payload_kg`.
//!
//! Run: `cargo run --release -p ferrocal-datasets --example diagnose_study -- [--out DIR]
//! [--per-cell N] [--seed S]`. Writes `study.csv` (one line per recording), `summary.md`,
//! `summary.csv` and `detection.svg` into DIR (default `out/diagnose_study`).

#[path = "../tests/diagnose_support/mod.rs"]
mod diagnose_support;

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use diagnose_support::{example_urdf, simulate_with_truth, Order, Payload, Scenario};
use ferrocal_calib::diagnose::{diagnose, DiagnoseOptions};
use ferrocal_calib::kinematic::{calibrate, KinematicOptions};
use ferrocal_datasets::sim::Effect;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const KINDS: [&str; 8] = [
    "joint_compliance",
    "link_compliance",
    "backlash",
    "joint_scale_error",
    "periodic_joint_error",
    "thermal_expansion",
    "coupled_transmission",
    "axis_misalignment",
];
const RATIOS: [f64; 5] = [0.25, 0.5, 1.0, 2.0, 4.0];

struct Rec {
    robot: String,
    kind: String,
    joint: usize,
    ratio: f64,
    rho_raw: f64,
    n_poses: usize,
    noise: f64,
    sigma_col: bool,
    payload: String,
    detected: bool,
    first_correct: bool,
    wrong: bool,
    /// Kinds of other findings on the true joint (look-alikes).
    confused: String,
    findings: String,
    seconds: f64,
}

/// The effect of `kind` on `joint` with its size parameter `x` (for thermal: the temperature rise).
/// `driver`: the driving joint of a coupled transmission.
fn effect(kind: &str, joint: usize, driver: usize, x: f64, period: f64, phase: f64) -> Option<Effect> {
    Some(match kind {
        "joint_compliance" => Effect::JointCompliance { joint, compliance_si: x },
        // `joint` is the link's number here (link k joins joints k and k + 1).
        "link_compliance" => Effect::LinkCompliance { link: joint, compliance_si: x },
        "backlash" => Effect::Backlash { joint, width_si: x },
        "joint_scale_error" => Effect::JointScaleError { joint, scale_error: x },
        "periodic_joint_error" => {
            Effect::PeriodicJointError { joint, amplitude_si: x, period_si: period, phase_rad: phase }
        }
        "thermal_expansion" => Effect::ThermalExpansion { alpha_per_k: 23e-6, reference_temp_c: 20.0 },
        "coupled_transmission" => Effect::CoupledTransmission { joint, driver, ratio: x },
        "axis_misalignment" => Effect::AxisWobble { joint, tilt_rad: x, phase_rad: phase },
        _ => return None,
    })
}

fn main() {
    let mut out = PathBuf::from("out/diagnose_study");
    let mut per_cell = 4usize;
    let mut seed = 1u64;
    let mut order = Order::Random;
    let mut kinds: Vec<String> = KINDS.iter().map(|k| k.to_string()).collect();
    let mut robot_filter: Option<Vec<String>> = None;
    let mut ratios: Vec<f64> = RATIOS.to_vec();
    // Direction-dependent errors of both signs (the link lagging or leading), and a second
    // effect (a compliance of joint 2 or 3) beside the first one.
    let mut both_signs = false;
    let mut pair = false;
    let args: Vec<String> = std::env::args().collect();
    let mut i = 1;
    while i < args.len() {
        let v = args.get(i + 1).cloned().unwrap_or_default();
        match args[i].as_str() {
            "--out" => out = PathBuf::from(v),
            "--per-cell" => per_cell = v.parse().expect("--per-cell N"),
            "--seed" => seed = v.parse().expect("--seed S"),
            "--order" => {
                order = match v.as_str() {
                    "random" => Order::Random,
                    "planned" => Order::Planned,
                    "from-home" => Order::FromHome,
                    o => panic!("--order random|planned|from-home, got {o}"),
                }
            }
            "--kinds" => kinds = v.split(',').map(str::to_string).collect(),
            "--robots" => robot_filter = Some(v.split(',').map(str::to_string).collect()),
            "--ratios" => ratios = v.split(',').map(|x| x.parse().expect("--ratios R,R,..")).collect(),
            "--signs" => {
                both_signs = match v.as_str() {
                    "both" => true,
                    "positive" => false,
                    o => panic!("--signs both|positive, got {o}"),
                }
            }
            "--pair" => {
                pair = match v.as_str() {
                    "compliance" => true,
                    "none" => false,
                    o => panic!("--pair compliance|none, got {o}"),
                }
            }
            a => panic!("unknown argument {a}"),
        }
        i += 2;
    }
    std::fs::create_dir_all(&out).expect("output folder");
    let robots: Vec<String> = ["ur5".to_string(), "ur10".to_string(), example_urdf()]
        .into_iter()
        .filter(|r| {
            robot_filter
                .as_ref()
                .is_none_or(|f| f.iter().any(|x| r.rsplit('/').next().unwrap_or(r).starts_with(x.as_str())))
        })
        .collect();
    let opts = DiagnoseOptions::default();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut recs: Vec<Rec> = Vec::new();
    let t_all = Instant::now();
    let mut timing_400: Vec<f64> = Vec::new();
    let mut skipped = 0usize;
    for robot in &robots {
        let short = robot.rsplit('/').next().unwrap_or(robot).trim_end_matches(".urdf").to_string();
        let mut jobs: Vec<(String, f64)> = Vec::new();
        if kinds.iter().any(|k| k == "none") {
            for _ in 0..per_cell * ratios.len() {
                jobs.push(("none".into(), 0.0));
            }
        }
        for k in kinds.iter().filter(|k| *k != "none") {
            for &r in &ratios {
                for _ in 0..per_cell {
                    jobs.push((k.clone(), r));
                }
            }
        }
        for (kind, ratio) in jobs {
            let s_seed: u64 = rng.random();
            let joint = match kind.as_str() {
                "joint_compliance" | "link_compliance" => rng.random_range(2..=3),
                "thermal_expansion" | "none" => 0,
                _ => rng.random_range(1..=5),
            };
            // A coupled transmission's driving joint: another of joints 1 to 6.
            let driver = if kind == "coupled_transmission" {
                let k = rng.random_range(1..=5);
                if k >= joint {
                    k + 1
                } else {
                    k
                }
            } else {
                0
            };
            let periods = [std::f64::consts::TAU, 1.0, 0.3, std::f64::consts::TAU / 50.0];
            let period = periods[rng.random_range(0..periods.len())];
            let phase = rng.random_range(0.0..std::f64::consts::TAU);
            let n_poses = [150, 250, 400][rng.random_range(0..3)];
            let noise = if rng.random_bool(0.5) { 1.0 } else { 2.0 };
            let payload = if rng.random_bool(0.5) { Payload::Constant(2.0) } else { Payload::Varying(0.0, 5.0) };
            let sigma_col = rng.random_bool(0.5);
            let mut sc = Scenario::new(robot, None, s_seed);
            sc.n_poses = n_poses;
            sc.noise_scale = noise;
            sc.payload = payload;
            sc.with_sigma = true;
            sc.order = order;
            // Size the effect: a unit-size run gives the displacement per unit.
            let unit = match kind.as_str() {
                "joint_compliance" | "link_compliance" => 1e-5,
                "thermal_expansion" => 4.0,
                "joint_scale_error" => 1e-4,
                _ => 1e-4,
            };
            let mut rho_raw = 0.0;
            if kind != "none" {
                if kind == "thermal_expansion" {
                    sc.temp_c = (20.0, 20.0 + unit);
                }
                sc.effect = effect(&kind, joint, driver, unit, period, phase);
                // Noise-free run: what a geometric calibration cannot absorb is the visible size.
                let tiny = 1e-6;
                sc.noise_scale = tiny;
                let (model, rows, disp) = simulate_with_truth(&sc);
                sc.noise_scale = noise;
                let refs: Vec<&ferrocal_calib::PoseMeasurement> = rows.iter().collect();
                let kopts = KinematicOptions { use_orientation: false, ..KinematicOptions::default() };
                let visible_m = match calibrate(&model, &refs, &kopts) {
                    Ok(c) => c.train_after.rms_mm * 1e-3,
                    Err(_) => diagnose_support::rms(&disp),
                };
                let noise_rms =
                    (rows.iter().map(|r| 3.0 * (r.sigma_m.unwrap_or(0.0) / tiny * noise).powi(2)).sum::<f64>()
                        / rows.len() as f64)
                        .sqrt();
                let x = unit * ratio * noise_rms / visible_m.max(1e-15);
                rho_raw = diagnose_support::rms(&disp) / visible_m.max(1e-15) * ratio;
                // Physically sensible sizes only (what a real arm could have).
                let cap = match kind.as_str() {
                    "joint_compliance" | "link_compliance" => 1e-4,
                    "thermal_expansion" => 15.0,
                    // Diagnose's own bound (Bounds::max_axis_wobble_rad).
                    "axis_misalignment" => 2e-3,
                    _ => 5e-3,
                };
                if x > cap {
                    eprintln!("{short:>14} {kind:>22} j{joint} rho {ratio:<5} skipped: it would need a size of {x:.2e} (cap {cap:e})");
                    skipped += 1;
                    continue;
                }
                // A leading link: the direction-dependent error of the other sign.
                let x = if both_signs && kind == "backlash" && rng.random_bool(0.5) { -x } else { x };
                if kind == "thermal_expansion" {
                    sc.temp_c = (20.0, 20.0 + x);
                } else {
                    sc.effect = effect(&kind, joint, driver, x, period, phase);
                }
            }
            // The second effect: a compliance on joint 2 or 3, not the first effect's joint.
            let second = if pair {
                let j2 = if joint == 2 || (joint != 3 && rng.random_bool(0.5)) { 3 } else { 2 };
                sc.extra_effects = vec![Effect::JointCompliance { joint: j2, compliance_si: 8e-6 }];
                Some(j2)
            } else {
                None
            };
            sc.with_sigma = sigma_col;
            let (model, rows, _) = simulate_with_truth(&sc);
            let t0 = Instant::now();
            let rep = match diagnose(&model, &rows, &opts) {
                Ok(r) => r,
                Err(e) => {
                    eprintln!("{short} {kind} seed {s_seed}: diagnose failed: {e}");
                    continue;
                }
            };
            let secs = t0.elapsed().as_secs_f64();
            if n_poses == 400 {
                timing_400.push(secs);
            }
            let want_joints: Vec<usize> = match (kind.as_str(), joint) {
                (_, 0) => vec![],
                ("link_compliance", k) => vec![k, k + 1],
                ("coupled_transmission", j) => vec![j, driver],
                (_, j) => vec![j],
            };
            let is_true = |f: &ferrocal_calib::diagnose::Finding| f.effect == kind && f.joints == want_joints;
            let is_second = |f: &ferrocal_calib::diagnose::Finding| {
                second.is_some_and(|j2| f.effect == "joint_compliance" && f.joints == vec![j2])
            };
            let detected = rep.findings.iter().any(is_true);
            // With a second effect: both found (in any order).
            let first_correct = match second {
                None => rep.findings.first().is_some_and(is_true),
                Some(_) => (kind == "none" || detected) && rep.findings.iter().any(is_second),
            };
            let wrong = rep.findings.iter().any(|f| !is_true(f) && !is_second(f));
            let confused = rep
                .findings
                .iter()
                .filter(|f| f.effect != kind && !want_joints.is_empty() && f.joints == want_joints)
                .map(|f| f.effect.clone())
                .collect::<Vec<_>>()
                .join(" ");
            let findings =
                rep.findings.iter().map(|f| format!("{}{:?}", f.effect, f.joints)).collect::<Vec<_>>().join(" ");
            eprintln!(
                "{short:>14} {kind:>22} j{joint}{} rho {ratio:<5} n {n_poses} noise x{noise} -> [{findings}] {}{:.2} s",
                match &sc.effect {
                    Some(Effect::Backlash { width_si, .. }) if *width_si < 0.0 => " (leading)",
                    _ => "",
                },
                if kind == "none" {
                    if rep.findings.is_empty() {
                        "ok "
                    } else {
                        "FALSE ALARM "
                    }
                } else if first_correct && !wrong {
                    "ok "
                } else if detected && second.is_some() && !wrong {
                    "found, the second effect missed "
                } else if detected {
                    "found, with extra claims "
                } else if wrong {
                    "WRONG "
                } else {
                    "missed "
                },
                secs
            );
            if std::env::var_os("DIAGNOSE_STUDY_VERBOSE").is_some() && kind != "none" && (!first_correct || wrong) {
                eprintln!("    effect {:?}, seed {s_seed}; declined: {:?}", sc.effect, rep.declined);
                for (k, st) in rep.steps.iter().enumerate() {
                    for c in st.candidates.iter().take(4) {
                        eprintln!(
                            "    step {} {:<45} improvement {:>6.2} % p {:.1e}: {}",
                            k + 1,
                            c.label,
                            c.improvement * 100.0,
                            c.p_corrected,
                            c.verdict
                        );
                    }
                }
                for n in &rep.notes {
                    eprintln!("    note: {n}");
                }
            }
            recs.push(Rec {
                robot: short.clone(),
                kind: kind.clone(),
                joint,
                ratio,
                rho_raw,
                n_poses,
                noise,
                sigma_col,
                payload: match payload {
                    Payload::Constant(_) => "constant".into(),
                    Payload::Varying(..) => "varying".into(),
                },
                detected,
                first_correct,
                wrong,
                confused,
                findings,
                seconds: secs,
            });
        }
    }
    // Per-recording CSV.
    let mut csv = String::from(
        "robot,effect,joint,rho,rho_raw,n_poses,noise_scale,sigma_column,payload,detected,first_correct,wrong_claim,findings,seconds\n",
    );
    for r in &recs {
        let _ = writeln!(
            csv,
            "{},{},{},{},{:.2},{},{},{},{},{},{},{},{},{:.3}",
            r.robot,
            r.kind,
            r.joint,
            r.ratio,
            r.rho_raw,
            r.n_poses,
            r.noise,
            r.sigma_col,
            r.payload,
            r.detected,
            r.first_correct,
            r.wrong,
            r.findings,
            r.seconds
        );
    }
    std::fs::write(out.join("study.csv"), csv).expect("write study.csv");
    // Summary.
    let rate =
        |v: &[&Rec], f: &dyn Fn(&Rec) -> bool| -> (usize, usize) { (v.iter().filter(|r| f(r)).count(), v.len()) };
    let none: Vec<&Rec> = recs.iter().filter(|r| r.kind == "none").collect();
    let (fa, nn) = rate(&none, &|r| !r.findings.is_empty());
    let mut md = String::new();
    let _ = writeln!(md, "# Diagnose study: detection and false-alarm rates\n");
    let _ = writeln!(
        md,
        "{} simulated recordings (UR5, UR10, example_arm6.urdf; 150/250/400 poses; tracker noise 15 um + 6 um/m, x1 or x2), seed {seed}, {:.0} s in all.\n",
        recs.len(),
        t_all.elapsed().as_secs_f64()
    );
    let _ = writeln!(
        md,
        "rho = RMS residual the effect leaves after a geometric calibration on noise-free data / RMS of the tracker's 3-D noise (rho_raw in study.csv: the raw displacement before any absorption). Detection: the true effect on the true joint is among the findings. Wrong claim: a finding that is not the true effect.\n"
    );
    let _ = writeln!(
        md,
        "Recordings skipped because the effect would have needed an unphysical size (compliance above 1e-4 rad/N m, backlash, scale error or periodic amplitude above 5e-3, a warm-up above 15 K): {skipped}\n"
    );
    let _ = writeln!(
        md,
        "False alarms (no effect simulated; any finding counts): {fa} of {nn} = {:.1} %\n",
        100.0 * fa as f64 / nn.max(1) as f64
    );
    let mut header = String::from("| effect |");
    let mut sep = String::from("| --- |");
    for r in &ratios {
        let _ = write!(header, " rho {r} |");
        sep.push_str(" --- |");
    }
    let _ =
        writeln!(md, "Detection rate (true effect found, in %; wrong claims in brackets; n recordings; - none: the size would have been unphysical), by size:\n\n{header}\n{sep}");
    let mut sum_csv = String::from("effect,rho,n,detected,first_correct,wrong_claim\n");
    let mut curves: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for k in kinds.iter().filter(|k| *k != "none") {
        let k = k.as_str();
        let mut line = format!("| {k} |");
        let mut pts = Vec::new();
        for &r in &ratios {
            let v: Vec<&Rec> = recs.iter().filter(|x| x.kind == k && x.ratio == r).collect();
            let (d, n) = rate(&v, &|x| x.detected);
            let (w, _) = rate(&v, &|x| x.wrong);
            let (fc, _) = rate(&v, &|x| x.first_correct);
            let pct = 100.0 * d as f64 / n.max(1) as f64;
            if n == 0 {
                line.push_str(" - |");
            } else {
                let _ = write!(line, " {pct:.0} ({:.0}) n={n} |", 100.0 * w as f64 / n as f64);
                pts.push((r, pct));
            }
            let _ = writeln!(sum_csv, "{k},{r},{n},{d},{fc},{w}");
        }
        let _ = writeln!(md, "{line}");
        curves.push((k.to_string(), pts));
    }
    let _ = writeln!(sum_csv, "none,0,{nn},0,0,{fa}");
    let _ = writeln!(md, "\nPer robot:\n\n| robot | recordings with an effect | detected | wrong claims | no-effect recordings | false alarms |\n| --- | --- | --- | --- | --- | --- |");
    for rb in ["ur5", "ur10", "example_arm6"] {
        let v: Vec<&Rec> = recs.iter().filter(|x| x.robot == rb && x.kind != "none").collect();
        let z: Vec<&Rec> = recs.iter().filter(|x| x.robot == rb && x.kind == "none").collect();
        let (d, n) = rate(&v, &|x| x.detected);
        let (w, _) = rate(&v, &|x| x.wrong);
        let (f, nz) = rate(&z, &|x| !x.findings.is_empty());
        let _ = writeln!(md, "| {rb} | {n} | {d} | {w} | {nz} | {f} |");
    }
    let big: Vec<&Rec> = recs.iter().filter(|x| x.kind != "none" && x.ratio >= 1.0).collect();
    let (d, n) = rate(&big, &|x| x.first_correct && !x.wrong);
    let _ = writeln!(
        md,
        "\nExactly the true effect and nothing else, rho >= 1: {d} of {n} = {:.1} %",
        100.0 * d as f64 / n.max(1) as f64
    );
    // Look-alikes: a finding of another kind on the true joint (e.g. backlash named as a scale
    // error), per kind, at rho >= 1.
    let _ = writeln!(md, "\nNamed as another effect on the true joint (rho >= 1):\n\n| effect | recordings | other kind on its joint | which |\n| --- | --- | --- | --- |");
    for k in kinds.iter().filter(|k| *k != "none") {
        let v: Vec<&Rec> = big.iter().copied().filter(|x| &x.kind == k).collect();
        let conf: Vec<&Rec> = v.iter().copied().filter(|x| !x.confused.is_empty()).collect();
        let mut which: Vec<String> = conf.iter().map(|x| x.confused.clone()).collect();
        which.sort();
        which.dedup();
        let _ = writeln!(md, "| {k} | {} | {} | {} |", v.len(), conf.len(), which.join(", "));
    }
    let _ = writeln!(md, "\nApproach directions: {order:?} order.");
    if !timing_400.is_empty() {
        let mean = timing_400.iter().sum::<f64>() / timing_400.len() as f64;
        let max = timing_400.iter().copied().fold(0.0, f64::max);
        let _ = writeln!(md, "\nRuntime of one 400-pose recording (this build, one thread): mean {mean:.2} s, max {max:.2} s over {} recordings", timing_400.len());
    }
    std::fs::write(out.join("summary.md"), &md).expect("write summary.md");
    std::fs::write(out.join("summary.csv"), sum_csv).expect("write summary.csv");
    std::fs::write(out.join("detection.svg"), svg_plot(&curves, 100.0 * fa as f64 / nn.max(1) as f64))
        .expect("write svg");
    println!("{md}");
}

/// Detection rate against log2(rho) per effect kind, with the false-alarm rate as a dashed line.
fn svg_plot(curves: &[(String, Vec<(f64, f64)>)], false_alarm_pct: f64) -> String {
    let (w, h, l, r, t, b) = (720.0, 420.0, 70.0, 200.0, 30.0, 50.0);
    let x_of = |rho: f64| l + (rho.log2() + 2.0) / 4.0 * (w - l - r);
    let y_of = |p: f64| t + (1.0 - p / 100.0) * (h - t - b);
    let colours = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd"];
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n<text x=\"{}\" y=\"18\" font-size=\"15\">Detection rate by effect size (diagnose study)</text>\n",
        l
    );
    for p in [0.0, 25.0, 50.0, 75.0, 100.0] {
        let _ = writeln!(
            s,
            "<line x1=\"{l}\" x2=\"{}\" y1=\"{y}\" y2=\"{y}\" stroke=\"#ddd\"/><text x=\"{}\" y=\"{}\" text-anchor=\"end\">{p:.0} %</text>",
            w - r,
            l - 6.0,
            y_of(p) + 4.0,
            y = y_of(p)
        );
    }
    for rho in RATIOS {
        let _ = writeln!(
            s,
            "<line x1=\"{x}\" x2=\"{x}\" y1=\"{t}\" y2=\"{}\" stroke=\"#eee\"/><text x=\"{x}\" y=\"{}\" text-anchor=\"middle\">{rho}</text>",
            h - b,
            h - b + 16.0,
            x = x_of(rho)
        );
    }
    let _ = writeln!(
        s,
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">effect size / noise (rho, log scale)</text>",
        (l + w - r) / 2.0,
        h - 12.0
    );
    for (k, (name, pts)) in curves.iter().enumerate() {
        let c = colours[k % colours.len()];
        let path: Vec<String> = pts.iter().map(|(x, y)| format!("{:.1},{:.1}", x_of(*x), y_of(*y))).collect();
        let _ =
            writeln!(s, "<polyline fill=\"none\" stroke=\"{c}\" stroke-width=\"2\" points=\"{}\"/>", path.join(" "));
        for (x, y) in pts {
            let _ = writeln!(s, "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"3\" fill=\"{c}\"/>", x_of(*x), y_of(*y));
        }
        let ly = t + 20.0 + 18.0 * k as f64;
        let _ = writeln!(
            s,
            "<line x1=\"{}\" x2=\"{}\" y1=\"{ly}\" y2=\"{ly}\" stroke=\"{c}\" stroke-width=\"2\"/><text x=\"{}\" y=\"{}\">{name}</text>",
            w - r + 10.0,
            w - r + 30.0,
            w - r + 35.0,
            ly + 4.0
        );
    }
    let fy = y_of(false_alarm_pct);
    let _ = writeln!(
        s,
        "<line x1=\"{l}\" x2=\"{}\" y1=\"{fy}\" y2=\"{fy}\" stroke=\"black\" stroke-dasharray=\"5,4\"/><text x=\"{}\" y=\"{}\">false alarms {false_alarm_pct:.1} %</text>",
        w - r,
        w - r + 10.0,
        fy + 4.0
    );
    s.push_str("</svg>\n");
    s
}
