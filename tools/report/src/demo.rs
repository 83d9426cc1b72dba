//! The sections of `ferrocal demo`: the whole pipeline on the built-in example. Each stage adds
//! a section with a check that can fail ([`ferrocal_datasets::checks`]); a section whose input
//! is absent is skipped and one without a criterion is reported, and neither counts as passing.
//!
//! The sections that run other commands (the plan, the real-camera calibration, the UR5
//! diagnosis) are built here from those commands' JSON by [`plan`], [`camera_real`] and
//! [`camera_diagnose`]; [`pipeline::demo_report`] runs every stage in order.

use std::path::Path;

use crate::error::Result;
use ferrocal_calib::check::Check;
use ferrocal_datasets::checks::{self, OPENCV_LEFT_PUBLISHED, OPENCV_RIGHT_RECOMPUTED};
use ferrocal_robot::check::{self_check, SelfCheck};
use ferrocal_robot::presets;
use ferrocal_robot::serial::{parse_urdf_str, UrdfOptions};
use ferrocal_robot::{Kinematics, Parameterized, RobotModel};
use serde_json::{json, Value};

use crate::plot::{self, Series};
use crate::report::{inline_png, Block, Section};

mod camera;
pub mod pipeline;
pub mod story;
pub use camera::{
    camera_diagnose, camera_observations, camera_own_corners, camera_real, camera_real_skipped, printed_targets_section,
};

/// Progress of a long step: `(label, position, length)`.
pub type Tick<'a> = &'a dyn Fn(&str, u64, u64);

/// The example arm shipped with the binary.
pub const EXAMPLE_URDF: &str = include_str!("../../../robot/models/example_arm6.urdf");
/// The example cell shipped with the binary (`datasets/cells/gantry_tau_l1.toml`).
pub const EXAMPLE_CELL: &str = include_str!("../../../datasets/cells/gantry_tau_l1.toml");
/// The example plan file shipped with the binary.
pub const EXAMPLE_PLAN: &str = include_str!("../../../datasets/cells/plan_gantry_tau_l1.toml");

/// The attribution of the UR5 recording.
pub const UR5_ATTRIBUTION: &str = "Data: UR5 with a GTS3800 laser tracker, 1000 grid poses, from P. Jacobi, MSc thesis, Tsinghua University, 2025 (MIT licence).";

/// The attribution of the OpenCV stereo sample.
pub const OPENCV_ATTRIBUTION: &str = "Images: the OpenCV stereo calibration sample (opencv/opencv samples/data, originally the Caltech camera calibration toolbox example; Apache-2.0 licence).";

/// Marks a section that has no check as reporting numbers without a criterion.
pub fn reported_unless_checked(s: &mut Section) {
    if s.status.is_none() {
        s.reported("numbers shown without a pass/fail criterion");
    }
}

/// The external libraries answering a small real call each.
pub fn backends() -> Section {
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
    s.check(Check::from_bool("external libraries", ok, if ok { "ok" } else { "a backend failed" }));
    s
}

/// The models the demo checks: presets plus the shipped example URDF.
pub fn demo_models() -> Result<Vec<(String, RobotModel)>> {
    let mut out = Vec::new();
    for name in presets::PRESET_NAMES {
        out.push((format!("preset {name}"), presets::preset(name)?));
    }
    let urdf = parse_urdf_str(EXAMPLE_URDF, &UrdfOptions::default())?;
    out.push(("URDF example_arm6".into(), RobotModel::Serial(urdf)));
    Ok(out)
}

/// Every robot model's self-check on `samples` random configurations (seed `seed`).
pub fn models(samples: usize, seed: u64, tick: Tick) -> Result<Section> {
    let mut s = Section::new("models", "Robot models: forward/inverse kinematics and Jacobians");
    s.text(format!(
        "Every model is checked on {} random joint configurations within its limits (seed {}): forward kinematics, inverse kinematics from a seed near the configuration, forward again; and each Jacobian column against central finite differences. Near-singular configurations (smallest singular value of the Jacobian below 0.05) are counted and skipped, since the inverse there is not unique.",
        samples, seed
    ));
    let models = demo_models()?;
    let mut rows = Vec::new();
    let mut data = Vec::new();
    let mut verdicts = Vec::new();
    for (label, model) in &models {
        let done = std::cell::Cell::new(0u64);
        let c: SelfCheck = self_check(model, samples, seed, || {
            done.set(done.get() + 1);
            tick(label, done.get(), samples as u64)
        });
        let verdict = checks::self_check(label, &c);
        let pass = verdict.passed();
        verdicts.push(verdict);
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
    let ok = verdicts.iter().all(Check::passed);
    s.check(Check::from_bool("robot models", ok, if ok { "all within 1e-9" } else { "FAILED" }));
    Ok(s)
}

/// The example cell: a UR5 on a table, with a wall, a fixture and a carried plate.
pub use ferrocal_datasets::safety::example_safety;

/// Random UR5 configurations against the example cell's safety zones.
pub fn safety(samples: usize, seed: u64, tick: Tick) -> Result<Section> {
    let mut s = Section::new("safety", "Safety zones: a UR5 on a table, beside a wall and a fixture");
    let study = ferrocal_datasets::safety::safety_study(samples, seed, &|k, n| tick("safety: random poses", k, n))?;
    let (n, cfg, counts) = (study.n, &study.config, &study.refused_by);
    let (safe_pts, unsafe_pts) = (&study.safe_xy_m, &study.refused_xy_m);
    let (moves_ok, moves_bad) = (study.moves_safe, study.moves_refused);
    s.text(format!(
        "{n} random joint configurations: {} safe ({:.1} %). A configuration is safe when every joint keeps {:.2} rad from its limits, the carried plate (bounding radius {:.0} mm) and every link (radius {:.0} mm) keep each obstacle's margin, and the tool is {:.0} mm inside the reachable workspace. Of {} straight joint-space moves between consecutive safe poses, {moves_ok} are safe all the way and {moves_bad} would pass through a zone.",
        safe_pts.len(),
        100.0 * safe_pts.len() as f64 / n.max(1) as f64,
        cfg.joint_margin, cfg.plate_radius_m * 1e3, cfg.link_radius_m * 1e3, cfg.workspace_edge_margin_m * 1e3,
        moves_ok + moves_bad
    ));
    s.pre(format!(
        "# the example cell's safety zones (ferrocal robot check --safety FILE reads this format)\n{}",
        toml::to_string(cfg).unwrap_or_default()
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
                Series { name: "safe", points: safe_pts, line: false },
                Series { name: "refused", points: unsafe_pts, line: false },
            ],
        ),
    );
    s.data = json!({"configurations": n, "safe": safe_pts.len(), "refused_by": counts, "moves_safe": moves_ok, "moves_refused": moves_bad, "config": cfg});
    let refused_by_table = study.planted_refused_by_table;
    s.check(checks::safety(safe_pts.len(), n, refused_by_table.then_some("table")));
    Ok(s)
}

/// The built-in cell simulated into `session` (smaller when `quick`).
pub fn simulated_cell(seed: u64, quick: bool, session: &Path, tick: Tick) -> Result<Section> {
    use ferrocal_datasets::sim::{simulate, CellConfig};
    let mut s = Section::new("cell", "Simulated cell: Gantry-Tau L1, two 5 MP cameras and a laser tracker");
    let mut cfg = CellConfig::from_toml_str(EXAMPLE_CELL, Path::new("datasets/cells/gantry_tau_l1.toml"))?;
    cfg.seed ^= seed.wrapping_sub(1);
    if quick {
        if let ferrocal_datasets::sim::PlanConfig::Grid { spacing_m, .. } = &mut cfg.plan {
            *spacing_m = 0.2;
        }
        if let Some(b) = &mut cfg.calibration_board {
            b.views = 10;
        }
    }
    let manifest = simulate(&cfg, session, true, |k, n| tick("simulating the cell", k as u64, n as u64))?;
    let n_images: usize = manifest.cameras.iter().map(|c| c.images.iter().flatten().count()).sum();
    s.text(format!(
        "The built-in cell (datasets/cells/gantry_tau_l1.toml): the L1's nominal model of the source with random geometric errors (0.5 mm on lengths and positions, 2e-3 on guideway directions) as the true robot, {} poses on a grid, a laser tracker (15 um + 6 um/m) and two 5 MP cameras 2.5 m away photographing the plate of five squares. Written to {}: {} images, the joint table, the tracker table (measurement CSV) and the ground truth apart.",
        manifest.n_poses,
        session.display(),
        n_images
    ));
    for cam in &manifest.cameras {
        if let Some(Some(first)) = cam.images.first() {
            if let Ok(img) = image::open(session.join(first)) {
                let small = image::imageops::resize(
                    &img.to_luma8(),
                    cam.width_px / 4,
                    cam.height_px / 4,
                    image::imageops::FilterType::Triangle,
                );
                s.blocks.push(Block::Figure {
                    caption: format!("Camera '{}', pose 1 (shown at 1/4 scale): exact pixel coverage, lens distortion, blur, vignetting, uneven light, shot and read noise, 8-bit quantisation", cam.name),
                    svg: inline_png(&small, &cam.name),
                });
            }
        }
    }
    s.table(
        "Session",
        &["item", "value"],
        vec![
            vec!["poses".into(), manifest.n_poses.to_string()],
            vec![
                "cameras".into(),
                manifest
                    .cameras
                    .iter()
                    .map(|c| format!("{} ({}x{})", c.name, c.width_px, c.height_px))
                    .collect::<Vec<_>>()
                    .join(", "),
            ],
            vec!["tracker table".into(), manifest.tracker.clone().unwrap_or_default()],
            vec!["notes".into(), manifest.notes.len().to_string()],
        ],
    );
    s.data = serde_json::to_value(&manifest)?;
    s.check(checks::simulated_cell(n_images, manifest.n_poses, manifest.tracker.is_some()));
    Ok(s)
}

/// The simulated L1 calibrated from the session's tracker table, checked on held-out poses and
/// against the truth.
pub fn tracker_calibration(session: &Path) -> Result<Vec<Section>> {
    use ferrocal_calib::kinematic::{calibrate, split_rows, KinematicOptions};
    use ferrocal_datasets::sim::SessionTruth;
    let table = ferrocal_datasets::import::read_measurements(session.join("tracker.csv"))?;
    let truth: SessionTruth = serde_json::from_str(&std::fs::read_to_string(session.join("truth/truth.json"))?)?;
    let model = RobotModel::load(&truth.cell.robot.model)?;
    let (train, test) = split_rows(&table.set.rows, true);
    let cal = calibrate(&model, &train, &KinematicOptions::default())?;
    let nominal = calibrate(
        &model,
        &train,
        &KinematicOptions {
            model_params: ferrocal_calib::kinematic::ModelParams::None,
            joint_offsets: false,
            ..KinematicOptions::default()
        },
    )?;
    let before = nominal.calibrated.evaluate(&test)?;
    let after = cal.calibrated.evaluate(&test)?;
    // Against the truth: predicted minus true tool positions in the tracker frame.
    let t_world_tracker = truth.t_world_tracker.unwrap_or_else(nalgebra::Isometry3::identity);
    let mut model_err = Vec::new();
    for r in &test {
        let pt = truth
            .poses
            .iter()
            .find(|p| p.pose_id == r.pose_id)
            .map(|p| (t_world_tracker.inverse() * p.t_world_tool).translation.vector);
        if let (Some(pt), Ok(pred)) = (pt, cal.calibrated.predict(&r.q)) {
            model_err.push((pred.translation.vector - pt).norm() * 1e3);
        }
    }
    let model_mean = model_err.iter().sum::<f64>() / model_err.len().max(1) as f64;
    let mut sections =
        crate::calibrate::calibration_sections(&cal, &Some((cal.clone(), before.clone(), after.clone())), &train);
    for s in &mut sections {
        s.id = format!("cell-{}", s.id);
        s.title = format!("Simulated L1 from the tracker: {}", s.title.to_lowercase());
    }
    let mut head = Section::new("cell-calibration", "Simulated L1 calibrated from the laser tracker");
    head.text(format!(
        "The L1's modified model (21 parameters: L_i, A_i^s, v_i per arm) identified with the tracker's frame from every second pose of the session, checked on the others. Held out: mean {:.3} mm before, {:.3} mm after calibration (tracker noise included); the calibrated model's predictions are {:.3} mm from the true positions on average. The source reports 0.7 mm (ideal model) and 0.23 mm (modified model) on the real L1, whose errors are not only geometric.",
        before.mean_mm, after.mean_mm, model_mean
    ));
    head.data = serde_json::json!({"heldout_before": before, "heldout_after": after, "model_error_vs_truth_mean_mm": model_mean, "fixed": cal.params.iter().filter(|p| !p.free).map(|p| &p.name).collect::<Vec<_>>()});
    head.check(checks::cell_calibration(&after, model_mean));
    let mut out = vec![head];
    out.extend(sections);
    Ok(out)
}

/// The UR5 and the UR10 calibrated from the real tracker recordings under `data` (skipped when
/// absent).
pub fn real_calibration(data: &Path) -> Result<Vec<Section>> {
    use ferrocal_calib::kinematic::{calibrate, split_rows, KinematicOptions, ModelParams};
    let mut out = Vec::new();
    let ur5 = data.join("ur5_tracker/ur5_grid_train.csv");
    let mut s = Section::new("ur5-calibration", "UR5 calibrated from a real laser tracker");
    s.attribution("Data: UR5 with a GTS3800 laser tracker, 1000 grid poses, from P. Jacobi, MSc thesis, Tsinghua University, 2025 (MIT licence). Measured = target + dif.");
    if ur5.exists() {
        let set = ferrocal_datasets::import::import_ur5_grid(&ur5)?;
        let model = RobotModel::load("ur5")?;
        let (train, test) = split_rows(&set.rows, true);
        let cal = calibrate(&model, &train, &KinematicOptions::default())?;
        let nominal = calibrate(
            &model,
            &train,
            &KinematicOptions { model_params: ModelParams::None, joint_offsets: false, ..KinematicOptions::default() },
        )?;
        let before = nominal.calibrated.evaluate(&test)?;
        let after = cal.calibrated.evaluate(&test)?;
        s.text(format!(
            "Complete geometric error model (a 6-parameter correction per joint, joint offsets, tracker frame and tool offset; redundant parameters fixed by the identifiability analysis), fitted on every second grid pose and checked on the others: mean {:.3} mm with the nominal model (frames registered) and {:.3} mm calibrated (RMS {:.3} mm, max {:.3} mm). The thesis reports 2.57 mm uncalibrated and 0.155 mm for its MDH model plus a neural network on 20 random test poses kept aside; `ferrocal calibrate` fits all 1000 poses for delivery.",
            before.mean_mm, after.mean_mm, after.rms_mm, after.max_mm
        ));
        s.data = serde_json::json!({"heldout_before": before, "heldout_after": after});
        s.check(checks::ur5_calibration(&after));
        out.push(s);
        let mut detail = crate::calibrate::calibration_sections(&cal, &Some((cal.clone(), before, after)), &train);
        for d in &mut detail {
            d.id = format!("ur5-{}", d.id);
            d.title = format!("UR5: {}", d.title.to_lowercase());
        }
        out.extend(detail);
    } else {
        s.skipped(format!("{} is not present", ur5.display()));
        out.push(s);
    }
    let ur10 = data.join("ur10_tracker/Series_A/measurements_grid.csv");
    let mut s = Section::new("ur10-calibration", "UR10 series A: positions and full 6-DoF poses");
    s.attribution("Data: UR10 with a Leica laser tracker and T-Mac probe, C. Landgraf, K. Ernst, G. Schleth, M. Fabritius, M. F. Huber, IEEE CASE 2021 (christianlandgraf/ipa-robot-accuracy, MIT licence).");
    if ur10.exists() {
        let set = ferrocal_datasets::import::import_ur10_measurements(&ur10)?;
        let model = RobotModel::load("ur10")?;
        let (train, test) = split_rows(&set.rows, true);
        let mut rows_t = Vec::new();
        let mut data = Vec::new();
        let mut positions_rms_mm = f64::NAN;
        for (label, use_ori) in [("positions only", false), ("positions and orientations", true)] {
            let opts = KinematicOptions {
                use_orientation: use_ori,
                sigma_position_m: 50e-6,
                sigma_orientation_rad: 0.01f64.to_radians(),
                ..KinematicOptions::default()
            };
            let cal = calibrate(&model, &train, &opts)?;
            let e = cal.calibrated.evaluate(&test)?;
            if !use_ori {
                positions_rms_mm = e.rms_mm;
            }
            rows_t.push(vec![
                label.to_string(),
                train.len().to_string(),
                test.len().to_string(),
                format!("{:.3}", e.mean_mm),
                format!("{:.3}", e.rms_mm),
                format!("{:.3}", e.max_mm),
                e.mean_deg.map(|v| format!("{v:.4}")).unwrap_or_default(),
            ]);
            data.push(serde_json::json!({"fit": label, "heldout": e}));
        }
        s.text(format!(
            "Split: every second pose of the {} rows for fitting, the others held out. The geometric model leaves {:.3} mm RMS on the held-out positions{}",
            set.rows.len(),
            positions_rms_mm,
            if positions_rms_mm > 0.2 {
                ": more than the tracker's noise, so something beyond geometry is in these data (temperature drift is a candidate: see `ferrocal diagnose`)."
            } else {
                "."
            }
        ));
        s.table(
            "Held-out errors, UR10 series A",
            &["fit", "train", "held out", "mean [mm]", "RMS [mm]", "max [mm]", "mean orientation [deg]"],
            rows_t,
        );
        s.data = serde_json::json!(data);
        s.reported("held-out errors shown; no pass/fail criterion");
    } else {
        s.skipped(format!("{} is not present", ur10.display()));
    }
    out.push(s);
    Ok(out)
}

/// The session measured by its cameras and compared with its tracker.
pub fn cameras_vs_tracker(session: &Path, tick: Tick) -> Result<Section> {
    // (The corner source: the real detector on the rendered images.)
    use ferrocal_datasets::measure::{compare_with_tracker, measure_session, CornerSource, MeasureOptions};
    let mut s = Section::new("cameras", "Cameras in place of the tracker: the source's end-to-end experiment");
    let opts = MeasureOptions {
        corners: CornerSource::Detector,
        corner_sigma_px: 0.02,
        calibration: ferrocal_vision::calib::CalibrationOptions::default(),
    };
    tick("measuring with the cameras", 0, 1);
    let m = measure_session(session, &opts)?;
    tick("measuring with the cameras", 1, 1);
    let tracker = ferrocal_datasets::import::read_measurements(session.join("tracker.csv"))?.set;
    let truth: ferrocal_datasets::sim::SessionTruth =
        serde_json::from_str(&std::fs::read_to_string(session.join("truth/truth.json"))?)?;
    let model = RobotModel::load(&truth.cell.robot.model)?;
    let c = compare_with_tracker(
        &model,
        &m.rows,
        &tracker,
        &m.poses,
        &ferrocal_calib::kinematic::KinematicOptions::default(),
    )?;
    s.text(format!(
        "Both cameras are calibrated (intrinsics and relative pose) from the 20 views of the calibration board, then the plate's pose is estimated at every robot pose from both cameras at once, with its covariance, and written as a measurement table in the first camera's frame: the same input the robot calibration takes from a tracker. Corners come from this project's detector and sub-pixel edge refinement on the rendered images (blur, noise, vignetting, 8-bit). Rig calibration RMS {:.4} px; {} poses measured; {} notes (board views partly out of the image are not used).",
        m.rig.rms_px, m.poses.len(), m.skipped.len()
    ));
    s.table(
        "Held-out tracker poses (every second pose of the grid), position errors",
        &["model calibrated from", "mean [mm]", "RMS [mm]", "max [mm]"],
        vec![
            vec![
                "nominal model (frames registered)".into(),
                format!("{:.4}", c.nominal_model.mean_mm),
                format!("{:.4}", c.nominal_model.rms_mm),
                format!("{:.4}", c.nominal_model.max_mm),
            ],
            vec![
                "laser tracker".into(),
                format!("{:.4}", c.tracker_model.mean_mm),
                format!("{:.4}", c.tracker_model.rms_mm),
                format!("{:.4}", c.tracker_model.max_mm),
            ],
            vec![
                "cameras".into(),
                format!("{:.4}", c.camera_model.mean_mm),
                format!("{:.4}", c.camera_model.rms_mm),
                format!("{:.4}", c.camera_model.max_mm),
            ],
        ],
    );
    s.text(format!(
        "The camera system against the tracker (after one rigid registration): mean {:.4} mm over {} poses. The source measured 1.7 mm (systematic, largest at the image borders) and a camera-calibrated model 1.5 mm off, against 0.125 mm from the tracker.",
        c.camera_mean_mm, c.n_common
    ));
    s.figure(
        "Camera system error against the tracker",
        plot::histogram("Camera vs tracker", "position error [mm]", &c.camera_errors_mm, 30),
    );
    let by_x: Vec<(f64, f64)> = c.image_centre_px.iter().zip(&c.camera_errors_mm).map(|(p, e)| (p[0], *e)).collect();
    let by_d: Vec<(f64, f64)> = c.distance_m.iter().zip(&c.camera_errors_mm).map(|(d, e)| (*d, *e)).collect();
    s.figure(
        "Error against the target's image position in camera 0 (the source's errors grew towards the borders)",
        plot::xy_plot(
            "Error vs image column",
            "image x [px]",
            "error [mm]",
            &[Series { name: "pose", points: &by_x, line: false }],
        ),
    );
    s.figure(
        "Error against the distance from camera 0",
        plot::xy_plot(
            "Error vs distance",
            "distance [m]",
            "error [mm]",
            &[Series { name: "pose", points: &by_d, line: false }],
        ),
    );
    let ratio = c.camera_model.mean_mm / c.tracker_model.mean_mm;
    s.data = serde_json::json!({"rig_rms_px": m.rig.rms_px, "comparison": c, "ratio_camera_to_tracker_model": ratio});
    s.check(checks::cameras_vs_tracker(&c));
    Ok(s)
}

/// `diagnose` on a simulated force-sensing end-effector whose deformation the rigid-body model
/// leaves out (methods.md section 5).
pub fn force_diagnose(seed: u64) -> Result<Section> {
    use ferrocal_calib::diagnose::force::{diagnose_force_sensor, ForceDiagnoseOptions};
    use ferrocal_calib::dynamics::design::candidate_poses;
    use ferrocal_datasets::dynsim::study::{home_coordinates, STATIC_HALF_RANGE};
    use ferrocal_datasets::dynsim::PlatformSim;
    let mut s = Section::new("force-diagnose", "Diagnose: the force-sensing end-effector's concealed deformation");
    let sim = PlatformSim::preset();
    let reg = sim.sensor_regressor()?;
    let home = home_coordinates(&sim.hexapod.home);
    let poses = candidate_poses(&sim.hexapod, 120, &home, &STATIC_HALF_RANGE, 0.005)?;
    let rec = sim.static_record_seeded(&poses, 20, seed)?;
    let rep = diagnose_force_sensor(&reg, &rec.poses, &rec.forces_n, &ForceDiagnoseOptions::default())?;
    let truth = sim.truth();
    s.text(format!(
        "Simulated rig (the source's 33.78 kg end-effector on six 1-DOF sensors, with a deformation depending on the platform's position and tilt), 120 quasi-static poses of 20 readings. `ferrocal diagnose --forces static.csv` fits the rigid body and offsets (model 0) and tests the deformation terms on held-out poses. {}",
        rep.findings.first().map_or("No finding.".to_string(), |f| format!("Finding: {}.", f.statement))
    ));
    s.table(
        "Rigid-body parameters without and with the deformation",
        &["model", "held-out force RMS [N]", "mass [kg]", "CoG height [mm]"],
        vec![
            vec![
                "0 (rigid body + offsets)".into(),
                format!("{:.3}", rep.nominal.heldout_rms_n),
                format!("{:.2}", rep.mass_kg[0]),
                format!("{:.1}", rep.cog_z_m[0] * 1e3),
            ],
            vec![
                format!("{} (final)", rep.final_fit.model),
                format!("{:.3}", rep.final_fit.heldout_rms_n),
                format!("{:.2}", rep.mass_kg[1]),
                format!("{:.1}", rep.cog_z_m[1] * 1e3),
            ],
            vec![
                "truth".into(),
                "-".into(),
                format!("{:.2}", truth.body.mass_kg),
                format!("{:.1}", truth.body.com_m.z * 1e3),
            ],
        ],
    );
    s.data = serde_json::to_value(&rep)?;
    s.check(checks::force_diagnose(!rep.findings.is_empty(), rep.mass_kg[1], truth.body.mass_kg));
    Ok(s)
}
/// The UR5 preset against the targets of the real recording `csv_path` (skipped when absent):
/// the tool offset fitted on every second row, the preset checked on the others.
pub fn ur5_targets(csv_path: &Path) -> Result<Section> {
    let mut s = Section::new("ur5-targets", "UR5 preset against a real laser-tracker recording");
    s.attribution("Data: UR5 with a GTS3800 laser tracker, 1000 grid poses, from P. Jacobi, \"A Hybrid Error Compensation Method for Enhancing the Pose Accuracy of Serial Industrial Robots\", MSc thesis, Tsinghua University, 2025 (MIT licence).");
    if !csv_path.exists() {
        s.skipped(format!("{} is not present", csv_path.display()));
        return Ok(s);
    }
    let grid = ferrocal_datasets::import::read_ur5_grid(csv_path)?;
    let r = checks::ur5_target_reproduction(&grid)?;
    let t = r.tool_offset_mm;
    s.text(format!(
        "The recording's target positions are the nominal forward kinematics of the commanded joints with the maker's DH table plus a tool offset the recording does not state. That offset is fitted from these data (least squares on every second row: ({:.3}, {:.3}, {:.3}) mm), so this is not an independent measurement of the tool: it checks the preset's DH table on the {} rows the offset was not fitted on. The preset reproduces them with a mean difference of {:.4} mm and a worst of {:.4} mm (requirement: 0.05 mm).",
        t[0], t[1], t[2], r.errors_mm.len(), r.mean_mm, r.max_mm
    ));
    s.figure(
        "Difference between the preset's forward kinematics and the recorded targets (rows not used to fit the tool offset)",
        plot::histogram("UR5 preset vs recorded targets", "difference [mm]", &r.errors_mm, 30),
    );
    s.data = json!({"rows": r.rows, "mean_mm": r.mean_mm, "max_mm": r.max_mm, "tool_offset_mm": t, "tool_offset": "fitted from these data", "fit_rows": r.fit_rows, "checked_rows": r.errors_mm.len()});
    s.check(checks::ur5_targets(&r));
    Ok(s)
}

/// The planning section from the plan's `report.json` (`rep`), whether the plan passed its
/// checks, the plan file's name and the number of simulated calibrations.
pub fn plan(rep: &Value, passed: bool, plan_file: &str, sims: &str) -> Section {
    let mut s = Section::new("plan", "Planning measurement poses: Gantry-Tau L1 seen by the cell's left camera");
    let sec = &rep["sections"];
    let sm = &sec["summary"]["data"];
    let g = |v: &Value| v.as_f64().unwrap_or(f64::NAN);
    s.table(
        "The plan in numbers",
        &["quantity", "value"],
        vec![
            vec![
                "workspace kept after the safety zones".into(),
                format!("{:.1} %", 100.0 * g(&sm["workspace_fraction_after_obstacles"])),
            ],
            vec![
                "measurable volume (device)".into(),
                format!("{:.3} m^3 ({})", g(&sm["measurable_volume"]), sm["device"].as_str().unwrap_or("-")),
            ],
            vec![
                "regular grid for the wanted count".into(),
                format!(
                    "{} poses at {:.4} m spacing for {} wanted",
                    sm["grid_count"],
                    g(&sm["grid_spacing"]),
                    sm["wanted"]
                ),
            ],
            vec![
                "chosen poses (criterion)".into(),
                format!(
                    "{} ({}) from a pool of {}",
                    sm["chosen"],
                    sm["criterion"].as_str().unwrap_or("-"),
                    sm["pool_count"]
                ),
            ],
            vec!["rank / parameters".into(), format!("{} / {}", sm["criteria"]["rank"], sm["criteria"]["n_params"])],
            vec!["predicted held-out RMS".into(), format!("{:.3} mm", g(&sm["predicted_heldout_rms_mm"]))],
            vec![
                "simulated / predicted parameter std (median)".into(),
                format!("{:.3}", g(&sec["prediction"]["data"]["monte_carlo"]["median_ratio"])),
            ],
            vec![
                "path: measurements, checked segments, travel".into(),
                format!(
                    "{}, {}, {:.0} s",
                    sec["path"]["data"]["measurements"],
                    sec["path"]["data"]["checked_segments"],
                    g(&sec["path"]["data"]["travel_s"])
                ),
            ],
        ],
    );
    let summary = &sec["summary"];
    s.text(format!(
        "`ferrocal plan --plan {} --out plan --simulations {sims}`: the whole plan (workspace, measurable region, selection, prediction against {sims} simulated calibrations, path, RAPID and G-code programs) is in plan/index.html.",
        plan_file
    ));
    s.data = summary["data"].clone();
    s.check(Check::from_bool(
        "measurement plan",
        passed,
        if passed { "plan passes its checks" } else { "a plan check failed (see plan/index.html)" },
    ));
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_safety_section_refuses_the_configuration_planted_in_the_table() {
        let s = safety(200, 1, &|_, _, _| {}).unwrap();
        let c = s.status.as_ref().expect("the safety check");
        assert_eq!(c.status, ferrocal_calib::check::CheckStatus::Pass, "{}", c.detail);
        assert!(c.detail.contains("planted in the table is refused"), "{}", c.detail);
    }
}
