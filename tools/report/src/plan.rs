//! `ferrocal plan`: the source's automated calibration flow from a plan file (TOML,
//! `docs/plan-format.md`): workspace by search cut by every safety zone, the measurable region of
//! the cameras (or tracker), the regular grid for the wanted count, a denser pool, pose selection
//! by a design criterion, the predicted calibration checked against simulated calibrations, a
//! safe visiting order and the robot programs, with an HTML report.

use std::path::PathBuf;

use crate::error::{Context, Result};
use ferrocal_calib::check;
use ferrocal_calib::design::flow::PlanDesign;
use ferrocal_calib::design::kinematic::{predict, MonteCarloReport};
use ferrocal_calib::verdict::Verdict;
use ferrocal_datasets::formats::plan_file::PlanFile;
use ferrocal_datasets::plan::PlanRun;
use ferrocal_robot::program::{PlannedPath, StepKind};
use ferrocal_robot::{Kinematics, RobotModel};
use nalgebra::Vector3;
use serde_json::json;

use crate::plot::{self, Series};
use crate::report::{Provenance, Report, Section, StagedFolder};

/// The terminal line of a plan: how many poses were planned, whether the checks passed, the
/// report.
pub fn plan_line(run: &PlanRun) -> String {
    let checks = if run.design.passed { "checks passed" } else { "a check FAILED" };
    let html = run.request.out.join("index.html");
    format!("{} poses planned ({checks}); report {}", run.path.measurements(), html.display())
}

/// The report of a plan: summary, workspace, selection, prediction, path and programs.
pub fn plan_report(run: &PlanRun) -> Report {
    let (req, plan, model, design) = (&run.request, &run.plan, &run.model, &run.design);
    let mut prov = Provenance::new(json!({
        "plan": plan.name,
        "design": plan.design,
        "identify": plan.identify,
        "simulations": run.runs,
        "random_subsets": req.random_subsets,
    }));
    prov.add_input(&req.plan);
    let title = if plan.name.is_empty() { format!("Measurement plan for {}", model.name()) } else { plan.name.clone() };
    let mut rep = Report::new(&title, prov);
    let mc = run.monte_carlo.as_ref();
    rep.sections.push(summary_section(design, &run.path, mc, run.random));
    rep.sections.push(workspace_section(model, design));
    rep.sections.push(selection_section(design, run.random, req.random_subsets));
    rep.sections.push(prediction_section(design, mc));
    let no_ur = run.no_urscript.as_deref();
    rep.sections.push(path_section(model, &run.path, plan, run.gcode_chord_mm, &run.krl_file, no_ur));
    rep
}

/// Writes the plan's folder (`run.request.out`): its files, `report.json` with `verdict` and
/// `index.html` opening with its box, written aside and moved into place together; returns the
/// HTML's path.
pub fn write_plan(run: &PlanRun, report: Report, verdict: &Verdict) -> Result<PathBuf> {
    let mut json = report.to_json();
    crate::verdict::add_verdict(&mut json, verdict);
    let mut report = report;
    report.verdict = Some(verdict.clone());
    let (json, html) = (serde_json::to_string_pretty(&json)?.into_bytes(), report.to_html().into_bytes());
    let pages = [("report.json", &json), ("index.html", &html)];
    let staged = StagedFolder::create(&run.request.out)?;
    for (name, bytes) in run.files.iter().map(|(n, b)| (n.as_str(), b)).chain(pages) {
        let p = staged.path().join(name);
        std::fs::write(&p, bytes).with_context(|| format!("cannot write {}", p.display()))?;
    }
    Ok(staged.commit()?.join("index.html"))
}

/// Formats a parameter value in its unit (mm for metres, 1e-3 for dimensionless, mrad).
fn fmt_param(name: &str, v: f64) -> String {
    if name.ends_with("_m") {
        format!("{:.4} mm", v * 1e3)
    } else if name.ends_with("_rad") {
        format!("{:.4} mrad", v * 1e3)
    } else {
        format!("{:.4} e-3", v * 1e3)
    }
}

fn tool_positions(model: &RobotModel, poses: &[&Vec<f64>]) -> Vec<Vector3<f64>> {
    poses.iter().filter_map(|q| model.forward(q).ok().map(|t| t.translation.vector * 1e3)).collect()
}

/// Tool positions (mm, in the robot's base frame, +z up) as a 3-D figure the reader turns: one
/// colour per series, drawn as a line (`true`) or as dots, with the base frame.
fn positions_scene(title: &str, series: &[(&str, Vec<Vector3<f64>>, bool)]) -> String {
    let mut sc = plot::Scene3d::new(title, "mm");
    let extent = series.iter().flat_map(|s| s.1.iter().map(|p| p.norm())).fold(0.0, f64::max).max(1.0);
    sc.frame(&nalgebra::Isometry3::identity(), 0.12 * extent, "base");
    for (k, (name, pts, line)) in series.iter().enumerate() {
        let pts: Vec<nalgebra::Point3<f64>> = pts.iter().map(|p| nalgebra::Point3::from(*p)).collect();
        match line {
            true => sc.line(&pts, k, 1.5),
            false => sc.dots(&pts, k, if pts.len() > 200 { 1.5 } else { 3.0 }),
        }
        sc.legend(k, name);
    }
    sc.to_svg()
}

fn summary_section(
    d: &PlanDesign,
    path: &PlannedPath,
    mc: Option<&MonteCarloReport>,
    random: Option<(f64, f64, usize)>,
) -> Section {
    let mut s = Section::new("summary", "Summary");
    s.status(d.passed, if d.passed { "checks passed" } else { "check failed" });
    let w = &d.workspace;
    let c = d.settings.criterion;
    let mut rows = vec![
        vec!["device".into(), d.device.clone()],
        vec![
            "workspace left after obstacles".into(),
            format!(
                "{:.1} % ({:.3} of {:.3} {})",
                100.0 * w.fraction_after_obstacles,
                w.safe_volume,
                w.kinematic_volume,
                w.volume_unit
            ),
        ],
        vec![
            "measurable region".into(),
            format!(
                "{:.3} {} ({:.1} % of the workspace)",
                w.measurable_volume,
                w.volume_unit,
                100.0 * w.measurable_fraction
            ),
        ],
        vec![
            format!("regular grid for {} wanted poses", d.grid.wanted),
            format!("spacing {:.4} -> {} poses (source: 100 -> 0.1367 m -> 112)", d.grid.spacing, d.grid.count),
        ],
        vec!["optimisation pool".into(), format!("{} poses (spacing {:.4})", d.pool_grid.count, d.pool_grid.spacing)],
        vec![
            format!("criterion {c} of the chosen {} poses", d.chosen.len()),
            format!("{:.4} ({})", d.criteria.get(c), c.describe()),
        ],
        vec![
            "sigma_max^2 / sigma_min (SI Jacobian)".into(),
            format!(
                "{:.1} (sigma {:.3} .. {:.2}; limit {}{})",
                d.dressler.ratio,
                d.dressler.sigma_min,
                d.dressler.sigma_max,
                d.dressler.limit,
                if d.settings.enforce_dressler { "" } else { ", reported, not enforced" }
            ),
        ],
        vec![
            "predicted held-out RMS error".into(),
            format!(
                "{:.4} mm (model error, measurement noise {:.3} mm RMS)",
                d.prediction.heldout_rms_mm, d.prediction.noise_rms_mm
            ),
        ],
    ];
    if let Some((best, median, _)) = random {
        rows.push(vec![
            format!("random subsets of {} poses", d.chosen.len()),
            format!("best {best:.4}, median {median:.4}"),
        ]);
    }
    if let Some(m) = mc {
        rows.push(vec![
            format!("simulated calibrations ({} used)", m.used),
            format!(
                "held-out RMS {:.4} mm (predicted {:.4}); parameter scatter / prediction: median {:.3}, worst |ratio - 1| {:.3}",
                m.simulated_heldout_rms_mm, m.predicted_heldout_rms_mm, m.median_ratio, m.worst_ratio_deviation
            ),
        ]);
    }
    rows.push(vec![
        "path".into(),
        format!(
            "{} steps, {} measurements, travel {:.0} s + measuring {:.0} s, {} detour(s)",
            path.steps.len(),
            path.measurements(),
            path.travel_s,
            path.dwell_s,
            path.detours
        ),
    ]);
    s.table("The plan in numbers", &["quantity", "value"], rows);
    for n in &d.notes {
        s.text(n.clone());
    }
    s.data = json!({
        "device": d.device,
        "workspace_fraction_after_obstacles": w.fraction_after_obstacles,
        "measurable_volume": w.measurable_volume,
        "volume_unit": w.volume_unit,
        "grid_spacing": d.grid.spacing,
        "grid_count": d.grid.count,
        "wanted": d.grid.wanted,
        "pool_count": d.pool_grid.count,
        "chosen": d.chosen.len(),
        "criterion": c,
        "criterion_value": d.criteria.get(c),
        "criteria": d.criteria,
        "dressler": d.dressler,
        "predicted_heldout_rms_mm": d.prediction.heldout_rms_mm,
        "passed": d.passed,
        "notes": d.notes,
    });
    s
}

fn workspace_section(model: &RobotModel, d: &PlanDesign) -> Section {
    let mut s = Section::new("workspace", "Workspace and measurable region");
    let w = &d.workspace;
    s.text(format!(
        "Grid search over {} lattice nodes (spacing {}). Every node is classified by the first constraint it breaks, in this order; the volume is the count times the cell volume.",
        w.total, w.spacing
    ));
    let cell = if w.total > 0 && w.kinematic > 0 { w.kinematic_volume / w.kinematic as f64 } else { 0.0 };
    let rows = w
        .stages
        .iter()
        .map(|st| {
            vec![
                st.name.clone(),
                st.removed.to_string(),
                st.survivors.to_string(),
                format!("{:.4}", st.survivors as f64 * cell),
            ]
        })
        .collect();
    s.table(
        "Survivors after each constraint",
        &["constraint", "removed", "left", &format!("volume left ({})", w.volume_unit)],
        rows,
    );
    if !w.unmeasurable.is_empty() {
        s.table(
            "Why the device cannot measure",
            &["reason", "nodes"],
            w.unmeasurable.iter().map(|(r, n)| vec![r.clone(), n.to_string()]).collect(),
        );
    }
    let step = (d.map.measurable.len() / 800).max(1);
    let region: Vec<&Vec<f64>> = d.map.measurable.iter().step_by(step).map(|c| &c.q).collect();
    let grid: Vec<&Vec<f64>> = d.grid_indices.iter().map(|&k| &d.kinematic.poses[k]).collect();
    let chosen: Vec<&Vec<f64>> = d.chosen.iter().map(|&k| &d.kinematic.poses[k]).collect();
    let scene = positions_scene(
        "Tool positions",
        &[
            ("measurable region", tool_positions(model, &region), false),
            ("regular grid", tool_positions(model, &grid), false),
            ("chosen", tool_positions(model, &chosen), false),
        ],
    );
    s.figure(
        "Measurable region (sampled), the source's regular grid and the chosen poses, in mm in the robot's base frame (drag to turn)",
        scene,
    );
    s.data = serde_json::to_value(w).unwrap_or_default();
    s
}

fn selection_section(d: &PlanDesign, random: Option<(f64, f64, usize)>, n_random: usize) -> Section {
    let c = d.settings.criterion;
    let mut s = Section::new("selection", &format!("Pose selection by the {c} criterion"));
    s.text(format!(
        "Greedy deletion from {} candidates (the pool and the regular grid), removing at every step the pose whose removal degrades {} least (rank-one downdates of the information), on down to the smallest set that keeps full rank ({} poses), then exchange refinement at the chosen count.",
        d.kinematic.poses.len(),
        c.describe(),
        d.selection.history.minimum_count
    ));
    let curve: Vec<(f64, f64)> = d.selection.history.curve().iter().map(|(n, v)| (*n as f64, *v)).collect();
    let chosen_pt = [(d.selection.chosen.len() as f64, d.selection.value)];
    let grid_pt: Vec<(f64, f64)> =
        d.grid_criteria.as_ref().map(|g| vec![(d.grid_indices.len() as f64, g.get(c))]).unwrap_or_default();
    let rand_pt: Vec<(f64, f64)> = random.map(|r| vec![(d.chosen.len() as f64, r.0)]).unwrap_or_default();
    let series = [
        Series { name: "greedy deletion", points: &curve, line: true },
        Series { name: "chosen (after exchange)", points: &chosen_pt, line: false },
        Series { name: "regular grid", points: &grid_pt, line: false },
        Series { name: "best random subset", points: &rand_pt, line: false },
    ];
    s.figure(
        &format!("Criterion {c} against the number of poses"),
        plot::xy_plot(&format!("{c} criterion vs count"), "poses", c.describe(), &series),
    );
    // Predicted accuracy against the count along the greedy path.
    let h = &d.selection.history;
    let n = h.start.len();
    let mut counts: Vec<usize> = Vec::new();
    let mut k = h.minimum_count.max(1) as f64;
    while (k as usize) <= n {
        counts.push(k as usize);
        k *= 1.15;
        k = k.ceil();
    }
    let acc: Vec<(f64, f64)> = counts
        .iter()
        .filter_map(|&m| {
            let sub = h.subset_at(m)?;
            let val: Vec<usize> = (0..n).filter(|i| !sub.contains(i)).collect();
            predict(&d.kinematic, &sub, &val).ok().map(|p| (m as f64, p.heldout_rms_mm))
        })
        .collect();
    s.figure(
        "Predicted held-out RMS error of the greedy sets against the count",
        plot::xy_plot(
            "Predicted accuracy vs count",
            "poses",
            "held-out RMS model error (mm)",
            &[Series { name: "greedy sets", points: &acc, line: true }],
        ),
    );
    let mut rows = vec![vec![
        format!("chosen ({})", d.chosen.len()),
        format!("{:.4}", d.criteria.a),
        format!("{:.3}", d.criteria.ln_det),
        format!("{:.2}", d.criteria.condition),
        format!("{:.4e}", d.criteria.noise_amplification),
        format!("{:.4}", d.prediction.heldout_rms_mm),
    ]];
    if let (Some(g), Some(p)) = (&d.grid_criteria, &d.grid_prediction) {
        rows.push(vec![
            format!("regular grid ({})", d.grid_indices.len()),
            format!("{:.4}", g.a),
            format!("{:.3}", g.ln_det),
            format!("{:.2}", g.condition),
            format!("{:.4e}", g.noise_amplification),
            format!("{:.4}", p.heldout_rms_mm),
        ]);
    }
    s.table(
        "Every criterion of the chosen set and of the source's grid",
        &["set", "A", "D (ln det)", "K", "N", "held-out RMS (mm)"],
        rows,
    );
    if let Some((best, median, singular)) = random {
        s.text(format!(
            "{n_random} random subsets of {} candidates: best {c} = {best:.4}, median {median:.4} ({singular} singular); the chosen set: {:.4}.",
            d.chosen.len(),
            d.selection.value
        ));
    }
    let rounds = d
        .rounds
        .iter()
        .map(|r| {
            vec![
                r.count.to_string(),
                format!("{:.4}", r.value),
                format!("{:.1}", r.dressler.ratio),
                format!("{:.4}", r.heldout_rms_mm),
                if r.passed { "passed".into() } else { r.failures.join("; ") },
            ]
        })
        .collect();
    s.table(
        "Rounds of the flow (poses are added while a check fails)",
        &["poses", c.name(), "sigma_max^2/sigma_min", "held-out RMS (mm)", "result"],
        rounds,
    );
    s.text(format!(
        "The source's check sigma_max^2 / sigma_min < C (C = {} for the L1) is computed on the unwhitened position Jacobian in SI units (metres per metre, per unit direction component), whose singular values here ({:.3} to {:.2}) have the size the source reports (0.3 to 64). With the source's own numbers the ratio is 64^2 / 0.3 = 13653, and it grows with the square root of the count: as stated it cannot hold for C = 200, so it is reported and enforced only when the plan asks for it (enforce_dressler); the flow adds poses while the predicted accuracy misses the wanted one.",
        d.dressler.limit, d.dressler.sigma_min, d.dressler.sigma_max
    ));
    s.data = json!({
        "criterion": c,
        "curve": d.selection.history.curve(),
        "minimum_count": d.selection.history.minimum_count,
        "greedy_value": c.value(d.selection.greedy_loss),
        "chosen_value": d.selection.value,
        "exchange": d.selection.exchange,
        "grid_criteria": d.grid_criteria,
        "random_subsets": random.map(|(b, m, s)| json!({"n": n_random, "best": b, "median": m, "singular": s})),
        "rounds": d.rounds,
        "accuracy_vs_count": acc,
    });
    s
}

fn prediction_section(d: &PlanDesign, mc: Option<&MonteCarloReport>) -> Section {
    let mut s = Section::new("prediction", "Predicted and simulated calibration");
    let p = &d.prediction;
    s.text(format!(
        "Predicted standard deviation of every identified parameter from the information of the chosen poses with the device's noise (per-pose covariance; the calibration weights each pose with one sigma, so the prediction is the sandwich covariance of that fit; the bound with the full covariance is shown beside it). Predicted held-out RMS model error at the {} validation poses: {:.4} mm ({:.4} mm with full-covariance weighting).",
        p.n_validation, p.heldout_rms_mm, p.heldout_rms_optimal_mm
    ));
    let mut rows = Vec::new();
    for (i, n) in p.names.iter().enumerate() {
        let mut r = vec![n.clone(), fmt_param(n, p.std_si[i]), fmt_param(n, p.std_optimal_si[i])];
        if let Some(m) = mc {
            match m.parameters.iter().find(|x| &x.name == n) {
                Some(x) => {
                    r.push(fmt_param(n, x.simulated_std_si));
                    r.push(format!("{:.3}", x.ratio));
                    r.push(fmt_param(n, x.mean_error_si));
                }
                None => r.extend(["-".to_string(), "-".to_string(), "-".to_string()]),
            }
        }
        rows.push(r);
    }
    let header: Vec<&str> = if mc.is_some() {
        vec![
            "parameter",
            "predicted std",
            "full-covariance bound",
            "simulated std",
            "simulated / predicted",
            "simulated mean error",
        ]
    } else {
        vec!["parameter", "predicted std", "full-covariance bound"]
    };
    s.table("Parameter deviations", &header, rows);
    if let Some(m) = mc {
        s.check(check::monte_carlo(m));
        s.text(format!(
            "{} simulated calibrations ({} used): true robots drawn with the plan's geometric errors, measurements with the device's noise, calibrated with the same options; simulated held-out RMS model error {:.4} mm against the predicted {:.4} mm. The sampling error of a standard deviation from {} runs is about {:.0} %.",
            m.runs,
            m.used,
            m.simulated_heldout_rms_mm,
            m.predicted_heldout_rms_mm,
            m.used,
            100.0 / (2.0 * m.used as f64).sqrt()
        ));
        for sk in &m.skipped {
            s.text(sk.clone());
        }
        let pts: Vec<(f64, f64)> =
            m.parameters.iter().map(|x| (x.predicted_std_si * 1e3, x.simulated_std_si * 1e3)).collect();
        let hi = pts.iter().map(|p| p.0.max(p.1)).fold(0.0, f64::max) * 1.05;
        let diag = [(0.0, 0.0), (hi, hi)];
        s.figure(
            "Simulated against predicted standard deviation per parameter (mm, mrad or 1e-3); the line is equality",
            plot::xy_plot(
                "Predicted vs simulated deviations",
                "predicted std",
                "simulated std",
                &[
                    Series { name: "parameters", points: &pts, line: false },
                    Series { name: "equal", points: &diag, line: true },
                ],
            ),
        );
    }
    s.data = json!({ "prediction": p, "monte_carlo": mc });
    s
}

fn path_section(
    model: &RobotModel,
    path: &PlannedPath,
    plan: &PlanFile,
    chord_mm: f64,
    krl_file: &str,
    ur_script: Option<&str>,
) -> Section {
    let mut s = Section::new("path", "Path and programs");
    s.text(format!(
        "Nearest neighbour from home then 2-opt under the time metric max_i |dq_i| / v_i: {:.0} s -> {:.0} s between the measured poses; with approach and via moves {:.0} s of travel, {:.0} s of measuring. Approach: {:?}. Every configuration and every straight joint-space segment between consecutive steps ({} segments checked, {} detour(s) through safe via configurations) passed the safety checker.",
        path.nearest_neighbour_s,
        path.ordered_s,
        path.travel_s,
        path.dwell_s,
        plan.path.approach,
        path.checked_segments,
        path.detours
    ));
    let all: Vec<&Vec<f64>> = path.steps.iter().map(|s| &s.q).collect();
    let meas: Vec<&Vec<f64>> = path.steps.iter().filter(|s| s.kind == StepKind::Measure).map(|s| &s.q).collect();
    let scene = positions_scene(
        "Path",
        &[("path", tool_positions(model, &all), true), ("measurements", tool_positions(model, &meas), false)],
    );
    s.figure("The path of the tool, in mm in the robot's base frame (drag to turn)", scene);
    s.table(
        "Files",
        &["file", "what"],
        vec![
            vec![
                "poses.csv".into(),
                "the measurement poses in visiting order (joints in deg / mm, approach directions, tool position)"
                    .into(),
            ],
            vec!["path.csv".into(), "every step: home, approach, measure, via".into()],
            vec!["grid_poses.csv".into(), "the source's regular grid for the wanted count".into()],
            vec![
                "program.mod".into(),
                format!("ABB RAPID module {} (MoveAbsJ, WaitTime \\InPos)", plan.program.rapid_module),
            ],
            vec![
                "program.ngc".into(),
                format!(
                    "G-code, {:?} axes, F{}{}",
                    plan.program.gcode_axes,
                    plan.program.gcode_feed_mm_min,
                    if chord_mm > 0.0 { format!(", largest chord deviation {chord_mm:.3} mm") } else { String::new() }
                ),
            ],
            vec![krl_file.to_string(), format!("KUKA KRL program {} (PTP AXIS, WAIT SEC)", plan.program.krl_name)],
            vec![
                "program.script".into(),
                match ur_script {
                    None => format!("URScript {} (movej, sleep)", plan.program.urscript_name),
                    Some(why) => format!("not written: {why}"),
                },
            ],
            vec!["session_plan.toml".into(), "the poses as a [plan] table for ferrocal simulate".into()],
        ],
    );
    s.data = json!({
        "steps": path.steps.len(),
        "measurements": path.measurements(),
        "travel_s": path.travel_s,
        "dwell_s": path.dwell_s,
        "nearest_neighbour_s": path.nearest_neighbour_s,
        "ordered_s": path.ordered_s,
        "detours": path.detours,
        "checked_segments": path.checked_segments,
        "gcode_max_chord_deviation_mm": chord_mm,
    });
    s
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use ferrocal_datasets::plan::{run_plan, PlanRequest};

    use super::*;

    #[test]
    fn plan_command_writes_the_report() {
        let dir = std::env::temp_dir().join(format!("ferrocal-report-plan-test-{}", std::process::id()));
        let args = PlanRequest {
            plan: Path::new(env!("CARGO_MANIFEST_DIR")).join("../../datasets/cells/plan_gantry_tau_l1.toml"),
            out: dir.clone(),
            simulations: Some(8),
            criterion: None,
            wanted: Some(40),
            random_subsets: 50,
            seed: None,
            force: false,
        };
        let run = run_plan(&args, &|_| {}, &|_, _| {}).unwrap();
        let report = plan_report(&run);
        let failed = crate::verdict::failed_sections(&report.to_json());
        let t = ferrocal_calib::verdict::Thresholds::default();
        let verdict = ferrocal_calib::verdict::commands::plan(&t, run.design.passed, &failed, "index.html");
        let html = write_plan(&run, report, &verdict).unwrap();
        assert!(run.path.measurements() >= 40 && html.exists());
        for f in
            ["poses.csv", "path.csv", "grid_poses.csv", "program.mod", "program.ngc", "session_plan.toml", "index.html"]
        {
            assert!(dir.join(f).exists(), "{f} missing");
        }
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
        let s = &j["sections"]["summary"]["data"];
        assert!(s["workspace_fraction_after_obstacles"].as_f64().unwrap() > 0.0);
        assert!(s["grid_spacing"].as_f64().unwrap() > 0.0);
        assert!(j["sections"]["prediction"]["data"]["monte_carlo"]["used"].as_u64().unwrap() >= 2);
        assert_eq!(j["verdict"], verdict.to_json());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
