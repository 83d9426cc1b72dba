//! The [planning] issue on the source's L1 cell with one camera (datasets/cells/
//! plan_gantry_tau_l1.toml): the workspace left after the obstacles, the grid spacing for 100
//! wanted poses, the criterion, the predicted calibration checked by simulated calibrations (the
//! datasets simulator), and the checked path with its programs, all from one plan.

use crate::plan_support;

use ferrocal_calib::design::criteria::Criterion;
use ferrocal_calib::design::flow::{plan_design, DesignSettings};
use ferrocal_calib::design::kinematic::monte_carlo;
use ferrocal_robot::program::{plan_path, rapid_module, verify_path, StepKind};
use ferrocal_robot::safety::SafetyChecker;
use ferrocal_robot::workspace::{MeasuringDevice, TrackerView, WorkspaceSettings};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use plan_support::*;

#[test]
fn l1_one_camera_plan_report() {
    let parts = load_plan(&l1_plan_path());
    assert_eq!(parts.cameras.len(), 1, "the source's single-camera set-up");
    let checker = SafetyChecker::new(&parts.model, parts.safety.clone()).unwrap();
    let rig = camera_rig(&parts);
    let d =
        plan_design(&parts.model, &checker, &rig, &parts.workspace, &parts.identify, &parts.design, |_| {}).unwrap();

    // Workspace: every zone of the source is applied and takes its share.
    let w = &d.workspace;
    let names: Vec<&str> = w.stages.iter().map(|s| s.name.as_str()).collect();
    for want in [
        "spherical-joint limit 30",
        "workspace-edge margin 0.1",
        "obstacle 'work table'",
        "obstacle 'camera stand'",
        "measurable by camera left",
    ] {
        assert!(names.iter().any(|n| n.contains(want)), "{want} missing from {names:?}");
    }
    assert!(w.stages.iter().all(|s| s.removed > 0), "every constraint removes something: {:?}", w.stages);
    assert!(w.fraction_after_obstacles > 0.3 && w.fraction_after_obstacles < 1.0, "{}", w.fraction_after_obstacles);
    assert!(w.measurable > 0 && w.measurable_volume > 0.05 && w.measurable_volume < w.kinematic_volume);

    // The regular grid for 100 wanted poses (source: 0.1367 m -> 112 poses).
    assert_eq!(d.grid.wanted, 100);
    assert!(d.grid.spacing > 0.1 && d.grid.spacing < 0.35, "{}", d.grid.spacing);
    let expect = (w.measurable_volume / 100.0).cbrt();
    assert!((d.grid.spacing - expect).abs() < 1e-12);
    assert!(d.grid.count >= 60 && d.grid.count <= 150, "{}", d.grid.count);
    assert!(d.pool_grid.count >= 350, "{}", d.pool_grid.count);

    // Selection and checks.
    assert_eq!(d.settings.criterion, Criterion::D);
    assert!(d.criteria.rank == 21 && d.criteria.ln_det.is_finite());
    assert!(d.chosen.len() >= 100);
    let h = &d.selection.history;
    let grid_loss = d.kinematic.pool.loss(&d.grid_indices, Criterion::D);
    let greedy_at_grid = h.loss_at(d.grid_indices.len()).unwrap();
    assert!(greedy_at_grid < grid_loss, "at the grid's own count the selection beats the regular grid");
    assert!(h.minimum_count >= 7 && h.minimum_count <= 12, "{}", h.minimum_count);
    // The source's singular values are 0.3 to 64 for 112 poses; ours have that size.
    assert!(d.dressler.sigma_max > 10.0 && d.dressler.sigma_max < 200.0, "{:?}", d.dressler);
    assert!(d.dressler.sigma_min > 0.01 && d.dressler.sigma_min < 2.0, "{:?}", d.dressler);
    let wanted = parts.design.max_rms_error_mm.unwrap();
    assert!(d.passed && d.prediction.heldout_rms_mm <= wanted);
    if d.rounds.len() > 1 {
        assert!(d.rounds[0].heldout_rms_mm > wanted, "poses are added only when a check fails");
        assert!(d.rounds.windows(2).all(|r| r[1].count > r[0].count));
    }

    // Simulated calibrations against the prediction (the study runs 200; here 30, looser).
    let mut sim = DatasetsSimulator {
        nominal: parts.model.clone(),
        errors: parts.errors.clone(),
        t_device_base: rig.t_device_base(),
        point_in_tool_m: rig.measured_point_in_tool_m(),
        seed: 11,
    };
    let mc =
        monte_carlo(&parts.model, &d.options, &d.kinematic, &d.chosen, &d.validation, &mut sim, 30, |_| {}).unwrap();
    assert_eq!(mc.used, 30, "{:?}", mc.skipped);
    assert_eq!(mc.parameters.len(), 21);
    for p in &mc.parameters {
        assert!(p.ratio > 0.6 && p.ratio < 1.4, "{}: simulated / predicted = {:.3}", p.name, p.ratio);
    }
    assert!(mc.median_ratio > 0.8 && mc.median_ratio < 1.2, "{}", mc.median_ratio);
    let r = mc.simulated_heldout_rms_mm / mc.predicted_heldout_rms_mm;
    assert!(r > 0.75 && r < 1.33, "held-out {} vs {}", mc.simulated_heldout_rms_mm, mc.predicted_heldout_rms_mm);

    // The path: approached from a fixed side, every segment checked.
    let poses: Vec<Vec<f64>> = d.chosen.iter().map(|&k| d.kinematic.poses[k].clone()).collect();
    let path = plan_path(&parts.model, &checker, &d.map.home, &poses, &d.kinematic.poses, &parts.path).unwrap();
    verify_path(&checker, &path).unwrap();
    assert_eq!(path.measurements(), poses.len());
    assert!(path.steps.iter().filter(|s| s.kind == StepKind::Measure).all(|s| s.dir == vec![1, 1, 1]));
    assert!(path.ordered_s <= path.nearest_neighbour_s);
    let rapid = rapid_module(&parts.model, &path, parts.path.dwell_s, &parts.program, &[]).unwrap();
    assert!(rapid.starts_with("MODULE L1Calibration"));
    assert_eq!(rapid.matches("MoveAbsJ").count(), path.steps.len());

    eprintln!(
        "L1, one camera: kinematic workspace {:.3} m^3, {:.1} % left after obstacles, measurable {:.3} m^3; \
         grid for 100 wanted: spacing {:.4} m -> {} poses; pool {} (spacing {:.4} m); \
         rounds {:?}; D (ln det) {:.2} for {} poses (regular grid {:.2} for {}); \
         sigma {:.3}..{:.2}, sigma_max^2/sigma_min {:.0}, cond {:.0}; predicted held-out RMS {:.4} mm; \
         Monte Carlo (30): median ratio {:.3}, worst |ratio-1| {:.3}, held-out {:.4} mm; path {} steps, {:.0} s travel",
        w.kinematic_volume,
        100.0 * w.fraction_after_obstacles,
        w.measurable_volume,
        d.grid.spacing,
        d.grid.count,
        d.pool_grid.count,
        d.pool_grid.spacing,
        d.rounds.iter().map(|r| (r.count, (r.heldout_rms_mm * 1e4).round() / 1e4, r.passed)).collect::<Vec<_>>(),
        d.criteria.ln_det,
        d.chosen.len(),
        d.grid_criteria.as_ref().map_or(f64::NAN, |g| g.ln_det),
        d.grid_indices.len(),
        d.dressler.sigma_min,
        d.dressler.sigma_max,
        d.dressler.ratio,
        d.dressler.condition,
        d.prediction.heldout_rms_mm,
        mc.median_ratio,
        mc.worst_ratio_deviation,
        mc.simulated_heldout_rms_mm,
        path.steps.len(),
        path.travel_s
    );
}

#[test]
fn l1_with_a_laser_tracker_instead_of_the_camera() {
    let parts = load_plan(&l1_plan_path());
    let checker = SafetyChecker::new(&parts.model, parts.safety.clone()).unwrap();
    // The built-in cell's tracker.
    let tracker = TrackerView {
        name: "tracker".into(),
        t_base_tracker: Isometry3::from_parts(
            Translation3::new(2.0, 0.8, 0.3),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 150f64.to_radians()),
        ),
        range_m: [0.5, 10.0],
        sigma_const_um: 15.0,
        sigma_per_m_um: 6.0,
        reflector_in_tool_m: Vector3::zeros(),
        reflector_axis_in_tool: None,
        max_incidence_deg: 30.0,
        occluders: parts.safety.obstacles.clone(),
    };
    let ws = WorkspaceSettings { search_spacing_m: 0.08, ..parts.workspace.clone() };
    let design = DesignSettings { wanted_poses: 40, pool_size: 200, max_rms_error_mm: None, ..parts.design.clone() };
    let d = plan_design(&parts.model, &checker, &tracker, &ws, &parts.identify, &design, |_| {}).unwrap();
    assert!(d.device.contains("laser tracker"));
    // The tracker sees more of the workspace than the camera and measures far better.
    assert!(d.workspace.measurable_fraction > 0.5, "{}", d.workspace.measurable_fraction);
    assert!(d.prediction.heldout_rms_mm < 0.05, "{}", d.prediction.heldout_rms_mm);
    let mut sim = DatasetsSimulator {
        nominal: parts.model.clone(),
        errors: parts.errors.clone(),
        t_device_base: tracker.t_device_base(),
        point_in_tool_m: tracker.measured_point_in_tool_m(),
        seed: 5,
    };
    let mc =
        monte_carlo(&parts.model, &d.options, &d.kinematic, &d.chosen, &d.validation, &mut sim, 20, |_| {}).unwrap();
    assert!(mc.median_ratio > 0.7 && mc.median_ratio < 1.3, "{}", mc.median_ratio);
    eprintln!(
        "L1, tracker: measurable {:.1} %, {} poses, predicted held-out {:.4} mm, simulated {:.4} mm, median ratio {:.3}",
        100.0 * d.workspace.measurable_fraction,
        d.chosen.len(),
        d.prediction.heldout_rms_mm,
        mc.simulated_heldout_rms_mm,
        mc.median_ratio
    );
}
