//! `ferrocal demo`: the whole pipeline on the built-in example, as one HTML report.
//!
//! Each stage of the project adds a section. Today: the external libraries, the robot models'
//! self-checks, the UR5 preset against a real laser-tracker recording, and the safety zones.

use std::path::Path;
use std::process::ExitCode;

use anyhow::Result;
use ferrocal_robot::check::{self_check, SelfCheck};
use ferrocal_robot::presets;
use ferrocal_robot::safety::{ObstacleBox, SafetyChecker, SafetyConfig};
use ferrocal_robot::serial::{parse_urdf_str, UrdfOptions};
use ferrocal_robot::{Kinematics, Parameterized, Pose, RobotModel};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::json;

use crate::cli::DemoArgs;
use crate::plot::{self, Series};
use crate::progress;
use crate::report::{Provenance, Report, Section};

/// The example arm shipped with the binary.
pub const EXAMPLE_URDF: &str = include_str!("../../../robot/models/example_arm6.urdf");

pub fn run(args: &DemoArgs) -> Result<ExitCode> {
    let settings = json!({"samples": args.samples, "seed": args.seed, "data": args.data.display().to_string()});
    let mut prov = Provenance::new(settings);
    let mut report = Report::new("ferrocal demo: the pipeline on the built-in example", prov.clone());
    let mut all_ok = true;

    eprintln!("ferrocal demo -> {}", args.out.display());
    let s = section_backends();
    all_ok &= s.status.as_ref().is_none_or(|(ok, _)| *ok);
    report.sections.push(s);

    let s = section_models(args)?;
    all_ok &= s.status.as_ref().is_none_or(|(ok, _)| *ok);
    report.sections.push(s);

    let ur5_csv = args.data.join("ur5_tracker/ur5_grid_train.csv");
    let s = section_ur5_targets(&ur5_csv)?;
    if ur5_csv.exists() {
        prov.add_input(&ur5_csv);
    }
    all_ok &= s.status.as_ref().is_none_or(|(ok, _)| *ok);
    report.sections.push(s);

    let s = section_safety(args)?;
    all_ok &= s.status.as_ref().is_none_or(|(ok, _)| *ok);
    report.sections.push(s);

    report.provenance = prov;
    let html = report.write(&args.out)?;
    eprintln!("report written: {}", html.display());
    Ok(if all_ok { ExitCode::SUCCESS } else { ExitCode::from(2) })
}

fn section_backends() -> Section {
    let mut s = Section::new("setup", "Set-up: the external libraries");
    let probes = ferrocal_vision::backends::probe_backends();
    let ok = probes.iter().all(|b| b.ok);
    s.text("Each library the project builds on answers a small real call: OpenCV (the baseline every vision result is compared with), the AprilTag C library, kornia-rs and Ceres.");
    s.table(
        "Backends",
        &["library", "role", "answer", "ok"],
        probes
            .iter()
            .map(|b| {
                vec![b.name.into(), b.role.into(), b.detail.clone(), if b.ok { "yes".into() } else { "NO".into() }]
            })
            .collect(),
    );
    s.data = serde_json::to_value(&probes).unwrap_or_default();
    s.status(ok, if ok { "ok" } else { "a backend failed" });
    s
}

/// The models the demo checks: presets plus the shipped example URDF.
fn demo_models() -> Result<Vec<(String, RobotModel)>> {
    let mut out = Vec::new();
    for name in presets::PRESET_NAMES {
        out.push((format!("preset {name}"), presets::preset(name)?));
    }
    let urdf = parse_urdf_str(EXAMPLE_URDF, &UrdfOptions::default())?;
    out.push(("URDF example_arm6".into(), RobotModel::Serial(urdf)));
    Ok(out)
}

fn section_models(args: &DemoArgs) -> Result<Section> {
    let mut s = Section::new("models", "Robot models: forward/inverse kinematics and Jacobians");
    s.text(format!(
        "Every model is checked on {} random joint configurations within its limits (seed {}): forward kinematics, inverse kinematics from a seed near the configuration, forward again; and each Jacobian column against central finite differences. Near-singular configurations (smallest singular value of the Jacobian below 0.05) are counted and skipped, since the inverse there is not unique.",
        args.samples, args.seed
    ));
    let models = demo_models()?;
    let mut rows = Vec::new();
    let mut data = Vec::new();
    let mut ok = true;
    for (label, model) in &models {
        let pb = progress::bar(args.samples as u64, label);
        let c: SelfCheck = self_check(model, args.samples, args.seed, || pb.inc(1));
        pb.finish_and_clear();
        let pass = c.worst_position_m < 1e-9
            && c.worst_orientation_rad < 1e-9
            && c.worst_jacobian_rel < 1e-6
            && c.ik_failed == 0;
        ok &= pass;
        rows.push(vec![
            label.clone(),
            model.dof().to_string(),
            model.n_parameters().to_string(),
            format!("{}", c.round_trips),
            format!("{}", c.near_singular + c.fk_failed),
            format!("{:.1e}", c.worst_position_m),
            format!("{:.1e}", c.worst_orientation_rad),
            format!("{:.1e}", c.worst_joint),
            format!("{:.1e}", c.worst_jacobian_rel),
            if pass { "ok".into() } else { "FAILED".into() },
        ]);
        data.push(json!({"model": label, "check": c}));
    }
    s.table(
        "Self-check of every model",
        &[
            "model",
            "joints",
            "parameters",
            "round trips",
            "skipped",
            "worst pos. [m]",
            "worst rot. [rad]",
            "worst joint",
            "Jacobian rel. err.",
            "verdict",
        ],
        rows,
    );
    s.data = json!(data);
    s.status(ok, if ok { "all within 1e-9" } else { "FAILED" });
    Ok(s)
}

fn section_ur5_targets(csv_path: &Path) -> Result<Section> {
    let mut s = Section::new("ur5-targets", "UR5 preset against a real laser-tracker recording");
    s.attribution("Data: UR5 with a GTS3800 laser tracker, 1000 grid poses, from P. Jacobi, \"A Hybrid Error Compensation Method for Enhancing the Pose Accuracy of Serial Industrial Robots\", MSc thesis, Tsinghua University, 2025 (MIT licence).");
    if !csv_path.exists() {
        s.text(format!("{} is not present: section skipped.", csv_path.display()));
        s.status(true, "skipped");
        return Ok(s);
    }
    let mut robot = presets::ur5();
    robot.tool = Pose::translation(0.0, 0.09e-3, 31.0e-3);
    let mut rdr = csv::Reader::from_path(csv_path)?;
    let mut errs = Vec::new();
    for (k, rec) in rdr.records().enumerate() {
        let rec = rec?;
        let v: Vec<f64> = rec
            .iter()
            .enumerate()
            .map(|(c, x)| {
                x.parse::<f64>().map_err(|_| {
                    anyhow::anyhow!("{}: line {}, column {}: '{x}' is not a number", csv_path.display(), k + 2, c + 1)
                })
            })
            .collect::<Result<_>>()?;
        let q: Vec<f64> = v[7..13].iter().map(|d| d.to_radians()).collect();
        let p = robot.forward(&q)?.translation.vector * 1e3;
        errs.push(((p.x - v[1]).powi(2) + (p.y - v[2]).powi(2) + (p.z - v[3]).powi(2)).sqrt());
    }
    let worst = errs.iter().copied().fold(0.0, f64::max);
    let mean = errs.iter().sum::<f64>() / errs.len().max(1) as f64;
    s.text(format!(
        "The recording's target positions are the nominal forward kinematics of the commanded joints with the maker's DH table plus a tool offset of about (0, 0.09, 31.0) mm. The preset reproduces all {} targets with a mean difference of {:.4} mm and a worst of {:.4} mm (requirement: 0.05 mm).",
        errs.len(), mean, worst
    ));
    s.figure(
        "Difference between the preset's forward kinematics and the recorded targets",
        plot::histogram("UR5 preset vs recorded targets", "difference [mm]", &errs, 30),
    );
    s.data = json!({"rows": errs.len(), "mean_mm": mean, "max_mm": worst});
    let ok = worst < 0.05 && errs.len() == 1000;
    s.status(ok, if ok { "within 0.05 mm" } else { "FAILED" });
    Ok(s)
}

/// The example cell: a UR5 on a table, with a wall, a fixture and a carried plate.
pub fn example_safety() -> SafetyConfig {
    SafetyConfig {
        joint_margin: 0.05,
        plate_radius_m: 0.08,
        link_radius_m: 0.05,
        workspace_edge_margin_m: 0.05,
        obstacles: vec![
            ObstacleBox { name: "table".into(), min_m: [-1.5, -1.5, -0.8], max_m: [1.5, 1.5, -0.02], margin_m: 0.03 },
            ObstacleBox { name: "wall".into(), min_m: [-1.5, 0.55, -0.8], max_m: [1.5, 0.7, 1.5], margin_m: 0.05 },
            ObstacleBox { name: "fixture".into(), min_m: [0.35, -0.2, -0.02], max_m: [0.6, 0.2, 0.25], margin_m: 0.03 },
        ],
        ..SafetyConfig::default()
    }
}

fn section_safety(args: &DemoArgs) -> Result<Section> {
    let mut s = Section::new("safety", "Safety zones: a UR5 on a table, beside a wall and a fixture");
    let robot = presets::ur5();
    let cfg = example_safety();
    let checker = SafetyChecker::new(&robot, cfg.clone())?;
    let mut rng = ChaCha8Rng::seed_from_u64(args.seed);
    let n = args.samples.min(3000);
    let pb = progress::bar(n as u64, "safety: random poses");
    let (mut safe_pts, mut unsafe_pts) = (Vec::new(), Vec::new());
    let mut counts = std::collections::BTreeMap::<String, usize>::new();
    let mut safe_q = Vec::new();
    for _ in 0..n {
        pb.inc(1);
        let q: Vec<f64> = (0..6).map(|_| rng.random_range(-3.0..3.0)).collect();
        let p = robot.forward(&q)?.translation.vector;
        let v = checker.violations(&q, 0.0);
        if v.is_empty() {
            safe_pts.push((p.x, p.y));
            safe_q.push(q);
        } else {
            unsafe_pts.push((p.x, p.y));
            for x in &v {
                let key = match x {
                    ferrocal_robot::safety::Violation::Obstacle { obstacle, .. } => format!("obstacle '{obstacle}'"),
                    ferrocal_robot::safety::Violation::JointLimit { .. } => "joint limit".into(),
                    ferrocal_robot::safety::Violation::WorkspaceEdge { .. } => "workspace edge".into(),
                    ferrocal_robot::safety::Violation::SphericalJoint { .. } => "spherical joint".into(),
                    ferrocal_robot::safety::Violation::Kinematics { .. } => "kinematics".into(),
                };
                *counts.entry(key).or_default() += 1;
            }
        }
    }
    pb.finish_and_clear();
    // Moves between consecutive safe poses.
    let (mut moves_ok, mut moves_bad) = (0, 0);
    for w in safe_q.windows(2).take(200) {
        match checker.check_move(&w[0], &w[1]) {
            Ok(()) => moves_ok += 1,
            Err(_) => moves_bad += 1,
        }
    }
    s.text(format!(
        "{n} random joint configurations: {} safe ({:.1} %). A configuration is safe when every joint keeps {:.2} rad from its limits, the carried plate (bounding radius {:.0} mm) and every link (radius {:.0} mm) keep each obstacle's margin, and the tool is {:.0} mm inside the reachable workspace. Of {} straight joint-space moves between consecutive safe poses, {moves_ok} are safe all the way and {moves_bad} would pass through a zone.",
        safe_pts.len(),
        100.0 * safe_pts.len() as f64 / n.max(1) as f64,
        cfg.joint_margin, cfg.plate_radius_m * 1e3, cfg.link_radius_m * 1e3, cfg.workspace_edge_margin_m * 1e3,
        moves_ok + moves_bad
    ));
    s.pre(format!(
        "# the example cell's safety zones (ferrocal robot check --safety FILE reads this format)\n{}",
        toml::to_string_pretty(&cfg).unwrap_or_default()
    ));
    s.table(
        "Why configurations were refused (a configuration may violate several zones)",
        &["zone", "configurations"],
        counts.iter().map(|(k, v)| vec![k.clone(), v.to_string()]).collect(),
    );
    s.figure(
        "Tool positions seen from above: safe and refused configurations",
        plot::xy_plot(
            "UR5 tool positions (top view)",
            "x [m]",
            "y [m]",
            &[
                Series { name: "safe", points: &safe_pts, line: false },
                Series { name: "refused", points: &unsafe_pts, line: false },
            ],
        ),
    );
    s.data = json!({"configurations": n, "safe": safe_pts.len(), "refused_by": counts, "moves_safe": moves_ok, "moves_refused": moves_bad, "config": cfg});
    let ok = !safe_pts.is_empty();
    s.status(ok, "ok");
    Ok(s)
}
