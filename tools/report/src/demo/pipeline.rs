//! The run of `ferrocal demo` ([`demo_report`]): every stage's section in order, the report
//! opening with the pipeline as a story ([`super::story`]) and a summary of every section's
//! status. The sections that are commands of their
//! own (camera, plan, diagnose) run through the binary's command line in-process
//! ([`RunCommand`]), as a user would call them.

use std::path::Path;
use std::process::ExitCode;

use ferrocal_calib::diagnose::{diagnose, DiagnoseOptions};
use ferrocal_robot::RobotModel;
use serde_json::Value;

use super::*;
use crate::report::{write_atomic, Provenance, Report};

/// What the demo runs on (the arguments of `ferrocal demo`).
#[derive(Clone, Copy, Debug)]
pub struct DemoSettings<'a> {
    /// Folder for the report and its data files.
    pub out: &'a Path,
    /// Folder of the shared real recordings (parts of the demo use them when present).
    pub data: &'a Path,
    /// Random configurations per model in the kinematics self-check.
    pub samples: usize,
    /// Seed of every random choice.
    pub seed: u64,
    /// A smaller simulated cell (fewer poses and board views).
    pub quick: bool,
}

/// Runs a `ferrocal` command in-process, as a user would call it (the arguments without the
/// program's name); its exit status, or its error.
pub type RunCommand<'a> = &'a dyn Fn(&[String]) -> Result<ExitCode>;

fn strings(parts: &[&str]) -> Vec<String> {
    parts.iter().map(|s| s.to_string()).collect()
}

/// The demo's report: every section in order, each not checked reported, the summary first and
/// the inputs that were present in its provenance (`provenance`: the settings, made when the
/// demo started). `tick` follows the long steps.
pub fn demo_report(d: &DemoSettings, mut prov: Provenance, tick: Tick, run: RunCommand) -> Result<Report> {
    let mut report = Report::new("ferrocal demo: the pipeline on the built-in example", prov.clone());
    let s = &mut report.sections;
    s.push(backends());
    s.push(models(d.samples, d.seed, tick)?);
    let ur5_csv = d.data.join("ur5_tracker/ur5_grid_train.csv");
    s.push(ur5_targets(&ur5_csv)?);
    if ur5_csv.exists() {
        prov.add_input(&ur5_csv);
    }
    s.push(safety(d.samples, d.seed, tick)?);
    let session = d.out.join("session");
    s.push(simulated_cell(d.seed, d.quick, &session, tick)?);
    s.extend(tracker_calibration(&session)?);
    s.push(cameras_vs_tracker(&session, tick)?);
    s.extend(real_calibration(d.data)?);
    let ur10 = d.data.join("ur10_tracker/Series_A/measurements_grid.csv");
    if ur10.exists() {
        prov.add_input(&ur10);
    }
    s.extend(real_camera_sections(d, run)?);
    s.push(printed_targets_section(d.seed)?);
    s.push(plan_section(d, run)?);
    s.extend(diagnose_sections(d, tick)?);
    s.push(crate::compensate::demo_section(&ur5_csv, UR5_ATTRIBUTION, tick)?);
    s.push(crate::compensate::corrected_section(d.seed, &d.out.join("closed-loop"))?);
    s.push(crate::handeye::demo::demo_section(d.data, &d.out.join("handeye"), tick)?);
    s.push(crate::handeye::demo::positioner_section(d.data)?);
    s.push(crate::handeye::joint_demo::joint_section(d.seed, d.quick)?);
    s.push(crate::handeye::rig_demo::rig_section(&d.out.join("handeye-rig"), d.seed, d.quick, run)?);
    s.push(crate::handeye::physics_demo::physics_section(d.seed, d.quick)?);
    s.push(crate::recording::demo_section(d.data, &d.out.join("measure-real"))?);
    for set in
        ["test_set_charuco/cal_data.yaml", "test_set_10x10/cal_data.yaml", "kinematic_calibration/measurements.yaml"]
    {
        let cal = d.data.join("industrial_calibration").join(set);
        if cal.exists() {
            prov.add_input(&cal);
        }
    }
    s.push(crate::dynamics::demo_section(d.seed, d.quick)?);
    s.push(force_diagnose(d.seed)?);
    s.push(crate::stiffness::demo_section(d.seed, d.quick)?);
    s.push(crate::motion::demo_section(d.seed)?);
    s.push(crate::motion_cell::demo_section(d.seed)?);
    s.iter_mut().for_each(reported_unless_checked);
    // The story first (open), then the summary of every check and every stage, each folded
    // under its heading (the verdict box above the story counts the checks).
    let summary = report.summary_section();
    let story = super::story::story_section(&report.sections);
    report.sections.insert(0, summary);
    report.sections.insert(0, story);
    report.open_sections = 1;
    report.provenance = prov;
    Ok(report)
}

/// The terminal line of the demo's report written to `html`: how many sections passed, failed,
/// were skipped and were reported.
pub fn written_line(report: &Report, html: &Path) -> String {
    let n = report.counts();
    format!(
        "report written: {} ({} passed, {} failed, {} skipped, {} reported)",
        html.display(),
        n.passed,
        n.failed,
        n.skipped,
        n.reported
    )
}

/// Real images: the left and right cameras of the OpenCV sample calibrated and compared with the
/// reference values, the stereo baseline, and what the default camera model leaves out.
fn real_camera_sections(d: &DemoSettings, run: RunCommand) -> Result<Vec<Section>> {
    let dir = d.data.join("opencv_stereo");
    if !dir.join("left01.jpg").exists() {
        return Ok(vec![camera_real_skipped(&dir)]);
    }
    let out = d.out.join("camera");
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
        run(&strings(&argv))
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
            pair.push(serde_json::from_str::<Value>(&std::fs::read_to_string(&j)?)?);
        }
        let cv = pair.pop().expect("two runs");
        let own = pair.pop().expect("two runs");
        held_out.push((side, own, cv));
    }
    let (left, right, json) = (glob("left"), glob("right"), stereo_json.display().to_string());
    let argv =
        ["camera", "stereo", "--left", &left, "--right", &right, "--pattern", pattern, "--fix-aspect", "--json", &json];
    run(&strings(&argv))?;
    let read = |p: &Path| -> Result<Value> { Ok(serde_json::from_str(&std::fs::read_to_string(p)?)?) };
    let mut out_sections =
        vec![camera_real(&read(&left_json)?, &read(&right_json)?, &read(&stereo_json)?), camera_own_corners(&held_out)];

    // Detections made elsewhere: the left camera's own corners saved, then read back instead of
    // the images.
    let observations = out.join("left_observations.csv");
    let from_images = out.join("left_own.json");
    calibrate("left", &from_images, &["--save-observations", &observations.display().to_string()])?;
    let from_observations = out.join("left_from_observations.json");
    let (obs, json) = (observations.display().to_string(), from_observations.display().to_string());
    run(&strings(&[
        "camera",
        "calibrate",
        "--observations",
        &obs,
        "--pattern",
        pattern,
        "--fix-aspect",
        "--json",
        &json,
    ]))?;
    out_sections.push(camera_observations(&read(&from_images)?, &read(&from_observations)?));

    // What the default camera model leaves out.
    let mut reports = Vec::new();
    for side in ["left", "right"] {
        let path = out.join(format!("diagnose_{side}.json"));
        let (images, json) = (glob(side), path.display().to_string());
        run(&strings(&["diagnose", "--images", &images, "--pattern", pattern, "--json", &json]))?;
        reports.push((side, read(&path)?));
    }
    out_sections.push(camera_diagnose(&reports));
    Ok(out_sections)
}

/// The planner on the example plan: workspace, measurable region, pose selection, simulated
/// calibrations and the robot programs, in its own report linked from here.
fn plan_section(d: &DemoSettings, run: RunCommand) -> Result<Section> {
    let plan_path = d.out.join("plan_gantry_tau_l1.toml");
    std::fs::create_dir_all(d.out)?;
    write_atomic(&plan_path, EXAMPLE_PLAN.as_bytes())?;
    let out = d.out.join("plan");
    let sims = if d.quick { "20" } else { "200" };
    let subsets = if d.quick { "100" } else { "1000" };
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
        &d.seed.to_string(),
    ]);
    let code = run(&argv)?;
    let rep: Value = serde_json::from_str(&std::fs::read_to_string(out.join("report.json"))?)?;
    let name = plan_path.file_name().map(|f| f.to_string_lossy().to_string()).unwrap_or_default();
    Ok(plan(&rep, code == ExitCode::SUCCESS, &name, sims))
}

/// `diagnose` on the real UR5 recording: what the geometric model leaves out; and the
/// recordings shaped like the real ones that fixed vetoes missed.
fn diagnose_sections(d: &DemoSettings, tick: Tick) -> Result<Vec<Section>> {
    let ur5 = d.data.join("ur5_tracker/ur5_grid_train.csv");
    if !ur5.exists() {
        let mut s = Section::new("diagnose", "Diagnose: what the UR5's geometric model leaves out");
        s.skipped(format!("{} is not present", ur5.display()));
        return Ok(vec![s]);
    }
    let set = ferrocal_datasets::import::import_ur5_grid(&ur5)?;
    let model = RobotModel::load("ur5")?;
    tick("diagnosing the UR5", 0, 1);
    let rep = diagnose(&model, &set.rows, &DiagnoseOptions::default());
    tick("diagnosing the UR5", 1, 1);
    let mut out = crate::diagnose::sections(&rep?, Some(UR5_ATTRIBUTION));
    for s in &mut out {
        s.id = format!("ur5-{}", s.id);
        s.title = format!("UR5 diagnose: {}", s.title.to_lowercase());
    }
    // Recordings shaped like the real ones the fixed vetoes missed (the seed the tests check).
    // The humanoid torso (two more diagnoses of 400 poses, about two minutes) only in the full demo.
    tick("diagnosing the large and leading cases", 0, 1);
    let cases =
        ferrocal_datasets::sim::scenario::diagnose_cases(ferrocal_datasets::sim::scenario::DEMO_CASES_SEED, !d.quick);
    tick("diagnosing the large and leading cases", 1, 1);
    out.push(crate::diagnose::cases_section(&cases?));
    Ok(out)
}
