//! `ferrocal demo`: the whole pipeline on the built-in example, as one HTML report.
//!
//! Each stage of the project adds a section (`ferrocal_report::demo`, with the checks of
//! `ferrocal_datasets::checks`): the external libraries, the robot models' self-checks, the UR5
//! preset against a real laser-tracker recording, the safety zones, the simulated cell (rendered
//! images measured by the real detector), calibration from the tracker and from the cameras, the
//! UR5 and UR10 calibrated from real tracker data, the OpenCV sample cameras calibrated and
//! diagnosed, the pose planner, the UR5's missing physics found by `diagnose`, the force-sensor
//! and hexapod dynamics identification, and the elastostatic identification with compensation.
//! The sections that are commands of their own (camera, plan, diagnose) run here in-process, as
//! a user would call them. The report opens with a summary of every section's status; skipped
//! and reported sections are not counted as passing, and a failed check exits 2.

use std::path::Path;
use std::process::ExitCode;

use anyhow::Result;
use ferrocal_report::demo;
use ferrocal_report::verdict::VerdictSettings;
use ferrocal_report::{write_atomic, Provenance, Report, Section};
use ferrocal_robot::RobotModel;
use serde_json::json;

use crate::cli::DemoArgs;
use crate::progress::{self, Bars};

/// Runs `ferrocal demo`.
pub fn run(args: &DemoArgs, vs: &VerdictSettings) -> Result<ExitCode> {
    let bars = Bars::default();
    let tick = |label: &str, pos: u64, len: u64| bars.tick(label, pos, len);
    let settings = json!({"samples": args.samples, "seed": args.seed, "data": args.data.display().to_string()});
    let mut prov = Provenance::new(settings);
    let mut report = Report::new("ferrocal demo: the pipeline on the built-in example", prov.clone());
    eprintln!("ferrocal demo -> {}", args.out.display());
    let s = &mut report.sections;
    s.push(demo::backends());
    s.push(demo::models(args.samples, args.seed, &tick)?);
    let ur5_csv = args.data.join("ur5_tracker/ur5_grid_train.csv");
    s.push(demo::ur5_targets(&ur5_csv)?);
    if ur5_csv.exists() {
        prov.add_input(&ur5_csv);
    }
    s.push(demo::safety(args.samples, args.seed, &tick)?);
    let session = args.out.join("session");
    s.push(demo::simulated_cell(args.seed, args.quick, &session, &tick)?);
    s.extend(demo::tracker_calibration(&session)?);
    s.push(demo::cameras_vs_tracker(&session, &tick)?);
    s.extend(demo::real_calibration(&args.data)?);
    let ur10 = args.data.join("ur10_tracker/Series_A/measurements_grid.csv");
    if ur10.exists() {
        prov.add_input(&ur10);
    }
    s.extend(sections_real_camera(args)?);
    s.push(section_plan(args)?);
    s.extend(sections_diagnose(args)?);
    s.push(ferrocal_report::compensate::demo_section(&ur5_csv, demo::UR5_ATTRIBUTION, &tick)?);
    s.push(ferrocal_report::compensate::corrected_section(args.seed)?);
    s.push(ferrocal_report::handeye::demo::demo_section(&args.data, &args.out.join("handeye"), &tick)?);
    s.push(ferrocal_report::handeye::demo::positioner_section(&args.data)?);
    s.push(ferrocal_report::handeye::joint_demo::joint_section(args.seed, args.quick)?);
    s.push(ferrocal_report::recording::demo_section(&args.data, &args.out.join("measure-real"))?);
    for set in
        ["test_set_charuco/cal_data.yaml", "test_set_10x10/cal_data.yaml", "kinematic_calibration/measurements.yaml"]
    {
        let cal = args.data.join("industrial_calibration").join(set);
        if cal.exists() {
            prov.add_input(&cal);
        }
    }
    s.push(ferrocal_report::dynamics::demo_section(args.seed, args.quick)?);
    s.push(demo::force_diagnose(args.seed)?);
    s.push(ferrocal_report::stiffness::demo_section(args.seed, args.quick)?);
    s.push(ferrocal_report::motion::demo_section(args.seed)?);
    s.push(ferrocal_report::motion_cell::demo_section(args.seed)?);
    s.iter_mut().for_each(demo::reported_unless_checked);
    let summary = report.summary_section();
    report.sections.insert(0, summary);
    report.provenance = prov;
    let html = report.write(&args.out)?;
    let n = report.counts();
    println!(
        "report written: {} ({} passed, {} failed, {} skipped, {} reported)",
        html.display(),
        n.passed,
        n.failed,
        n.skipped,
        n.reported
    );
    Ok(ferrocal_report::verdict::conclude_report(vs, &args.out, "demo")?)
}

/// Runs a `ferrocal` command in-process, as a user would call it.
fn run_command(argv: &[String]) -> Result<ExitCode> {
    use clap::Parser;
    let mut full = vec!["ferrocal".to_string()];
    full.extend(argv.iter().cloned());
    let cli = crate::cli::Cli::try_parse_from(&full).map_err(|e| anyhow::anyhow!("{e}"))?;
    super::run(cli)
}

fn strings(parts: &[&str]) -> Vec<String> {
    parts.iter().map(|s| s.to_string()).collect()
}

/// Real images: the left and right cameras of the OpenCV sample calibrated and compared with the
/// reference values, the stereo baseline, and what the default camera model leaves out.
fn sections_real_camera(args: &DemoArgs) -> Result<Vec<Section>> {
    let dir = args.data.join("opencv_stereo");
    if !dir.join("left01.jpg").exists() {
        return Ok(vec![demo::camera_real_skipped(&dir)]);
    }
    let out = args.out.join("camera");
    std::fs::create_dir_all(&out)?;
    let glob = |side: &str| dir.join(format!("{side}*.jpg")).display().to_string();
    let left_json = out.join("left.json");
    let right_json = out.join("right.json");
    let stereo_json = out.join("stereo.json");
    let pattern = "chessboard:9x6:25mm";
    let calibrate = |side: &str, json: &Path, extra: &[&str]| {
        let (images, json) = (glob(side), json.display().to_string());
        let mut argv = vec!["camera", "calibrate", "--images", &images, "--pattern", pattern, "--fix-aspect"];
        argv.extend_from_slice(extra);
        argv.extend_from_slice(&["--json", &json]);
        run_command(&strings(&argv))
    };
    // The published numbers come from OpenCV's corner recipe; the default (own corners) is
    // compared with it on held-out views below.
    calibrate("left", &left_json, &["--corners", "opencv"])?;
    calibrate("right", &right_json, &["--corners", "opencv"])?;
    let mut held_out = Vec::new();
    for side in ["left", "right"] {
        let mut pair = Vec::new();
        for corners in ["own", "opencv"] {
            let j = out.join(format!("{side}_{corners}_heldout.json"));
            calibrate(side, &j, &["--corners", corners, "--test-every", "2"])?;
            pair.push(serde_json::from_str::<serde_json::Value>(&std::fs::read_to_string(&j)?)?);
        }
        let cv = pair.pop().expect("two runs");
        let own = pair.pop().expect("two runs");
        held_out.push((side, own, cv));
    }
    let (left, right, json) = (glob("left"), glob("right"), stereo_json.display().to_string());
    let argv =
        ["camera", "stereo", "--left", &left, "--right", &right, "--pattern", pattern, "--fix-aspect", "--json", &json];
    run_command(&strings(&argv))?;
    let read = |p: &Path| -> Result<serde_json::Value> { Ok(serde_json::from_str(&std::fs::read_to_string(p)?)?) };
    let mut out_sections = vec![
        demo::camera_real(&read(&left_json)?, &read(&right_json)?, &read(&stereo_json)?),
        demo::camera_own_corners(&held_out),
    ];

    // What the default camera model leaves out.
    let mut reports = Vec::new();
    for side in ["left", "right"] {
        let path = out.join(format!("diagnose_{side}.json"));
        let (images, json) = (glob(side), path.display().to_string());
        run_command(&strings(&["diagnose", "--images", &images, "--pattern", pattern, "--json", &json]))?;
        reports.push((side, read(&path)?));
    }
    out_sections.push(demo::camera_diagnose(&reports));
    Ok(out_sections)
}

/// The planner on the example plan: workspace, measurable region, pose selection, simulated
/// calibrations and the robot programs, in its own report linked from here.
fn section_plan(args: &DemoArgs) -> Result<Section> {
    let plan_path = args.out.join("plan_gantry_tau_l1.toml");
    std::fs::create_dir_all(&args.out)?;
    write_atomic(&plan_path, demo::EXAMPLE_PLAN.as_bytes())?;
    let out = args.out.join("plan");
    let sims = if args.quick { "20" } else { "200" };
    let subsets = if args.quick { "100" } else { "1000" };
    let argv = strings(&[
        "plan",
        "--plan",
        &plan_path.display().to_string(),
        "--out",
        &out.display().to_string(),
        "--simulations",
        sims,
        "--random-subsets",
        subsets,
        "--seed",
        &args.seed.to_string(),
    ]);
    let code = run_command(&argv)?;
    let rep: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("report.json"))?)?;
    let name = plan_path.file_name().map(|f| f.to_string_lossy().to_string()).unwrap_or_default();
    Ok(demo::plan(&rep, code == ExitCode::SUCCESS, &name, sims))
}

/// `diagnose` on the real UR5 recording: what the geometric model leaves out.
fn sections_diagnose(args: &DemoArgs) -> Result<Vec<Section>> {
    use ferrocal_calib::diagnose::{diagnose, DiagnoseOptions};
    let ur5 = args.data.join("ur5_tracker/ur5_grid_train.csv");
    if !ur5.exists() {
        let mut s = Section::new("diagnose", "Diagnose: what the UR5's geometric model leaves out");
        s.skipped(format!("{} is not present", ur5.display()));
        return Ok(vec![s]);
    }
    let set = ferrocal_datasets::import::import_ur5_grid(&ur5)?;
    let model = RobotModel::load("ur5")?;
    let pb = progress::bar(1, "diagnosing the UR5");
    let rep = diagnose(&model, &set.rows, &DiagnoseOptions::default())?;
    pb.finish_and_clear();
    let mut out = ferrocal_report::diagnose::sections(&rep, Some(demo::UR5_ATTRIBUTION));
    for s in &mut out {
        s.id = format!("ur5-{}", s.id);
        s.title = format!("UR5 diagnose: {}", s.title.to_lowercase());
    }
    // Recordings shaped like the real ones the fixed vetoes missed (the seed the tests check).
    // The humanoid torso (two more diagnoses of 400 poses, about two minutes) only in the full demo.
    let pb = progress::bar(1, "diagnosing the large and leading cases");
    let cases = ferrocal_datasets::sim::scenario::diagnose_cases(
        ferrocal_datasets::sim::scenario::DEMO_CASES_SEED,
        !args.quick,
    )?;
    pb.finish_and_clear();
    out.push(ferrocal_report::diagnose::cases_section(&cases));
    Ok(out)
}
