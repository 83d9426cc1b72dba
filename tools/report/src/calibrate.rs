//! Report sections and the JSON summary of a kinematic calibration (`ferrocal calibrate`, the
//! demo), the output files of `ferrocal calibrate` ([`calibrate_outputs`]) and the JSON of
//! `ferrocal evaluate` ([`evaluate_run_json`]).

use std::path::Path;

use ferrocal_calib::file::CalibrationFile;
use ferrocal_calib::kinematic::correct::Uncertainty;
use ferrocal_calib::kinematic::{CalibratedModel, ErrorStats, KinematicCalibration};
use ferrocal_calib::verdict::Verdict;
use ferrocal_calib::PoseMeasurement;
use ferrocal_datasets::calibration::{CalibrationRun, EvaluateRun, ExportRun, SpatialCheck};
use serde_json::json;

use crate::error::Result;
use crate::outputs::Outputs;
use crate::plot::{self, Series};
use crate::report::{Provenance, Report, Section};
use crate::verdict::add_verdict;

pub use ferrocal_datasets::calibration::Validation;

/// The JSON summary of `ferrocal calibrate --json` (keys per `shared/spec/cli.md`).
pub fn report_json(
    cal: &KinematicCalibration,
    validation: &Validation,
    n_final: usize,
    fixed_split: bool,
) -> serde_json::Value {
    json!({
        "n_poses": n_final,
        "split": if fixed_split { "from the table" } else if validation.is_some() { "validation on every second pose, final fit on all" } else { "none" },
        "train_before": cal.train_before,
        "train_after": cal.train_after,
        "heldout": validation.as_ref().map(|(v, b, a)| json!({"n_train": v.train_after.n, "before": b, "after": a})),
        "s0": cal.s0,
        "used_orientation": cal.used_orientation,
        "parameters": cal.params,
        "identifiability": {
            "rank": cal.identifiability_before.rank,
            "candidates": cal.layout.len(),
            "condition_number": cal.identifiability_after.condition_number,
            "dressler_ratio": cal.identifiability_after.dressler_ratio,
            "singular_values": cal.identifiability_after.singular_values,
            "classes": cal.identifiability_before.names.iter().zip(&cal.identifiability_before.classes).map(|(n, c)| json!({"name": n, "class": c})).collect::<Vec<_>>(),
            "coupled_groups": cal.identifiability_before.describe_groups(),
            "trades_against": cal.trade_offs(),
        },
        "practical_dropped": cal.practical_dropped,
        "advice": cal.advice,
        "solver": cal.summary,
        "device_frame": ferrocal_calib::file::FrameJson::from_isometry(&cal.calibrated.device_frame),
        "tool": ferrocal_calib::file::FrameJson::from_isometry(&cal.calibrated.tool),
    })
}

/// Report sections of a calibration (also used by the demo).
pub fn calibration_sections(
    cal: &KinematicCalibration,
    validation: &Validation,
    rows: &[&PoseMeasurement],
) -> Vec<Section> {
    let mut out = Vec::new();
    let mut s = Section::new("calibration-summary", "Calibration: before and after");
    let row = |name: &str, e: &ErrorStats| {
        vec![
            name.to_string(),
            e.n.to_string(),
            format!("{:.4}", e.mean_mm),
            format!("{:.4}", e.rms_mm),
            format!("{:.4}", e.max_mm),
            format!("{:.4} / {:.4} / {:.4}", e.rms_axis_mm[0], e.rms_axis_mm[1], e.rms_axis_mm[2]),
            e.mean_deg.map(|v| format!("{v:.4}")).unwrap_or_default(),
        ]
    };
    let mut rows_t =
        vec![row("training, nominal model", &cal.train_before), row("training, calibrated", &cal.train_after)];
    if let Some((_, b, a)) = validation {
        rows_t.push(row("held out, nominal model", b));
        rows_t.push(row("held out, calibrated", a));
    }
    s.table(
        "Position errors [mm]",
        &["set", "poses", "mean", "RMS", "max", "RMS x / y / z", "mean orientation [deg]"],
        rows_t,
    );
    s.text(format!(
        "Solver: {} after {} iterations; a-posteriori factor s0 = {:.3} (1 when the stated noise is right). {} of {} candidate parameters identified; {} fixed as not identifiable.",
        cal.summary.termination,
        cal.summary.iterations,
        cal.s0,
        cal.free.len(),
        cal.layout.len(),
        cal.layout.len() - cal.free.len()
    ));
    for a in &cal.advice {
        s.text(format!("Advice: {a}"));
    }
    if let Ok((pos, _)) = cal.calibrated.errors(rows) {
        let norms: Vec<f64> = pos.iter().map(|e| e.norm() * 1e3).collect();
        s.figure(
            "Position errors after calibration (training poses)",
            plot::histogram("Residual position errors", "error [mm]", &norms, 40),
        );
        let pts: Vec<(f64, f64)> = norms.iter().enumerate().map(|(k, v)| (k as f64, *v)).collect();
        s.figure(
            "Residual error per pose in measuring order (structure here points at effects the model leaves out: run `ferrocal diagnose`)",
            plot::xy_plot("Residual per pose", "pose (measuring order)", "error [mm]", &[Series { name: "error", points: &pts, line: false }]),
        );
    }
    out.push(s);
    let mut p = Section::new("calibration-parameters", "Identified parameters");
    p.table(
        "Parameters (lengths in mm, angles in mrad; nu = parameter-to-noise ratio)",
        &["parameter", "start", "value", "std", "nu", "status"],
        cal.params
            .iter()
            .map(|q| {
                let f = match q.unit {
                    ferrocal_robot::Unit::Metre | ferrocal_robot::Unit::Radian => 1e3,
                    _ => 1.0,
                };
                vec![
                    display_name(&q.name, f),
                    format!("{:.4}", q.start * f),
                    format!("{:.4}", q.value * f),
                    q.std.map(|v| format!("{:.4}", v * f)).unwrap_or_default(),
                    q.nu.map(|v| format!("{v:.1}")).unwrap_or_default(),
                    q.fixed_because.clone().unwrap_or_else(|| "identified".into()),
                ]
            })
            .collect(),
    );
    for t in ferrocal_calib::kinematic::describe_trade_offs(&cal.trade_offs()) {
        p.text(format!("Fixed: {t} (exchange rates in the parameters' own units, m and rad)"));
    }
    for g in cal.identifiability_before.describe_groups() {
        p.text(format!("Coupled: {g}"));
    }
    // Correlation picture of the free parameters.
    let n = cal.free.len();
    if n > 1 && n <= 80 {
        let c = &cal.covariance;
        let corr: Vec<Vec<f64>> =
            (0..n).map(|i| (0..n).map(|j| c[(i, j)] / (c[(i, i)] * c[(j, j)]).sqrt()).collect()).collect();
        let labels: Vec<String> = cal.free.iter().map(|&i| cal.layout.names[i].clone()).collect();
        p.figure(
            "Correlation of the identified parameters (blue -1, white 0, red +1)",
            plot::matrix_map("Parameter correlation", &labels, &corr, -1.0, 1.0),
        );
    }
    let sv: Vec<(f64, f64)> = cal
        .identifiability_after
        .singular_values
        .iter()
        .enumerate()
        .map(|(k, v)| (k as f64 + 1.0, v.max(1e-300).log10()))
        .collect();
    p.figure(
        "Singular values of the scaled Jacobian (log10); those below the tolerance are the parameter combinations the data cannot see",
        plot::xy_plot("Singular values", "index", "log10(singular value)", &[Series { name: "sigma", points: &sv, line: false }]),
    );
    p.data = json!({"condition_number": cal.identifiability_after.condition_number});
    out.push(p);
    out
}

/// The `heldout_spatial` object of the report JSON.
pub fn spatial_json(c: &SpatialCheck) -> serde_json::Value {
    json!({
        "split": "rows beyond the median plane normal to the positions' first principal axis held out",
        "plane": c.plane, "n_train": c.n_train, "before": c.before, "after": c.after,
    })
}

/// The JSON of `ferrocal evaluate` (`n`, `mean_mm`, `rms_mm`, `max_mm`, per-axis RMS,
/// orientation errors, per pose) and the statistics, for the calibrated model `cm` on `rows`.
pub fn evaluate_json(cm: &CalibratedModel, rows: &[PoseMeasurement]) -> Result<(serde_json::Value, ErrorStats)> {
    let refs: Vec<&PoseMeasurement> = rows.iter().collect();
    let (pos, ori) = cm.errors(&refs)?;
    let stats = ErrorStats::from_errors(&pos, &ori);
    let per_pose: Vec<serde_json::Value> = rows
        .iter()
        .zip(&pos)
        .map(|(r, e)| json!({"pose_id": r.pose_id, "error_mm": e.norm() * 1e3, "dx_mm": e.x * 1e3, "dy_mm": e.y * 1e3, "dz_mm": e.z * 1e3}))
        .collect();
    let out = json!({
        "n": stats.n, "mean_mm": stats.mean_mm, "rms_mm": stats.rms_mm, "max_mm": stats.max_mm,
        "rms_axis_mm": stats.rms_axis_mm, "mean_deg": stats.mean_deg, "max_deg": stats.max_deg,
        "per_pose": per_pose,
    });
    Ok((out, stats))
}

/// A parameter name for a table whose values are shown in mm and mrad (factor `f` = 1000):
/// the unit suffix follows the values (`joint2.corr_x_m` -> `joint2.corr_x_mm`,
/// `offset.q1_rad` -> `offset.q1_mrad`).
fn display_name(name: &str, f: f64) -> String {
    if f != 1e3 {
        return name.to_string();
    }
    if let Some(stem) = name.strip_suffix("_m") {
        format!("{stem}_mm")
    } else if let Some(stem) = name.strip_suffix("_rad") {
        format!("{stem}_mrad")
    } else {
        name.to_string()
    }
}

/// The physical parameters a metrologist reads, for the terminal: the target-to-flange
/// (tool) offset, the joint zero offsets (mrad, or mm for prismatic joints; "fixed" where the
/// data could not identify them) and how many candidates were fixed as redundant
/// ([`detail_lines`] says what each trades against).
pub fn physical_summary(cal: &KinematicCalibration) -> Vec<String> {
    let mut out = Vec::new();
    let t = cal.calibrated.tool.translation.vector * 1e3;
    out.push(format!(
        "tool offset (target in the flange frame): ({:.3}, {:.3}, {:.3}) mm, length {:.3} mm",
        t.x,
        t.y,
        t.z,
        t.norm()
    ));
    let offsets: Vec<String> = cal
        .params
        .iter()
        .filter(|p| p.name.starts_with("offset."))
        .map(|p| {
            let label = display_name(&p.name, 1e3);
            let label = label.trim_start_matches("offset.");
            match p.std {
                Some(sd) => format!("{label} {:+.4} +- {:.4}", p.value * 1e3, sd * 1e3),
                None => format!("{label} fixed"),
            }
        })
        .collect();
    out.push(format!("joint zero offsets: {}", offsets.join(", ")));
    let n_fixed = cal.trade_offs().len();
    if n_fixed > 0 {
        out.push(format!(
            "{n_fixed} candidate parameters fixed as redundant with others (each at its start value; --verbose lists their trade-offs)"
        ));
    }
    out
}

/// The internals behind [`physical_summary`] (`--verbose`): every identified parameter with its
/// standard deviation, and what each parameter fixed as redundant trades against.
pub fn detail_lines(cal: &KinematicCalibration) -> Vec<String> {
    let mut out = vec!["parameters (value +- standard deviation; lengths in mm, angles in mrad):".to_string()];
    for p in &cal.params {
        let scale = if p.name.ends_with("_m") || p.name.ends_with("_rad") { 1e3 } else { 1.0 };
        match p.std {
            Some(sd) => {
                out.push(format!("  {} {:+.4} +- {:.4}", display_name(&p.name, scale), p.value * scale, sd * scale))
            }
            None => out.push(format!("  {} {:+.4} fixed", display_name(&p.name, scale), p.value * scale)),
        }
    }
    let trades = ferrocal_calib::kinematic::describe_trade_offs(&cal.trade_offs());
    if !trades.is_empty() {
        out.push(format!(
            "{} candidates fixed as redundant (each at its start value; rates per unit, in m and rad):",
            trades.len()
        ));
        out.extend(trades.into_iter().map(|t| format!("  {t}")));
    }
    out
}

/// Where `ferrocal calibrate` writes.
#[derive(Clone, Copy, Debug)]
pub struct CalibrateFiles<'a> {
    /// The calibration file (what `ferrocal evaluate` reads).
    pub out: &'a Path,
    /// The JSON summary.
    pub json: Option<&'a Path>,
    /// The HTML report.
    pub report: Option<&'a Path>,
}

/// The files of `ferrocal calibrate`, composed (not written): the calibration file of the model
/// `robot` (as given on the command line), the JSON summary with the spatial check, the dropped
/// rows and the verdict, and the HTML report of the model named `model`, with the settings
/// `settings` and the table `measurements` in its provenance.
pub fn calibrate_outputs(
    run: &CalibrationRun,
    robot: &str,
    model: &str,
    measurements: &Path,
    settings: serde_json::Value,
    verdict: &Verdict,
    files: &CalibrateFiles,
) -> Result<Outputs> {
    let (cal, mut out) = (&run.cal, Outputs::default());
    let uncertainty = Uncertainty::from_kinematic(cal, &run.final_rows)?;
    out.json(files.out, &CalibrationFile::delivered(robot, &cal.calibrated, &run.final_rows, Some(uncertainty))?)?;
    let mut summary = report_json(cal, &run.validation, run.final_rows.len(), run.fixed_split);
    if let Some(spatial) = &run.heldout_spatial {
        summary["heldout_spatial"] = spatial_json(spatial);
    }
    summary["dropped_rows"] = json!(cal.dropped_rows);
    summary["outlier_note"] = json!(cal.outlier_note);
    summary["largest_residual_ratio"] = json!(cal.largest_residual_ratio);
    add_verdict(&mut summary, verdict);
    if let Some(j) = files.json {
        out.json(j, &summary)?;
    }
    if let Some(h) = files.report {
        let mut prov = Provenance::new(settings);
        prov.add_input(measurements);
        let sections = calibration_sections(cal, &run.validation, &run.final_rows);
        out.html(h, Report::of(&format!("Calibration of {model}"), prov, sections), verdict);
    }
    Ok(out)
}

/// The terminal summary of `ferrocal calibrate` on the model named `model`: the RMS before and
/// after, the held-out errors, then the [`physical_summary`].
pub fn summary_lines(run: &CalibrationRun, model: &str) -> Vec<String> {
    let cal = &run.cal;
    let mut out = vec![format!(
        "calibrated {model} on {} poses: RMS {:.4} mm -> {:.4} mm (mean {:.4} mm){}",
        run.final_rows.len(),
        cal.train_before.rms_mm,
        cal.train_after.rms_mm,
        cal.train_after.mean_mm,
        run.validation
            .as_ref()
            .map(|(_, b, a)| format!("; held out ({} poses): mean {:.4} -> {:.4} mm", a.n, b.mean_mm, a.mean_mm))
            .unwrap_or_default()
    )];
    out.extend(physical_summary(cal));
    out
}

/// The JSON of `ferrocal evaluate` ([`evaluate_json`] with which rows were scored and the frame
/// refit) and the statistics.
pub fn evaluate_run_json(run: &EvaluateRun) -> Result<(serde_json::Value, ErrorStats)> {
    let (mut out, stats) = evaluate_json(&run.model, &run.scored)?;
    out["rows_scored"] = json!(if run.test_only { "test" } else { "all" });
    // A tree's table of several tips: each tip's figures too (docs/trees.md).
    let tips = ferrocal_datasets::trees::tips_of(&run.scored);
    if tips.len() > 1 {
        let mut per_tip = serde_json::Map::new();
        for tip in tips {
            let rows: Vec<&PoseMeasurement> = run.scored.iter().filter(|r| r.tip() == Some(tip.as_str())).collect();
            let s = run.model.evaluate(&rows)?;
            per_tip.insert(tip, json!({"n": s.n, "mean_mm": s.mean_mm, "rms_mm": s.rms_mm, "max_mm": s.max_mm}));
        }
        out["per_tip"] = serde_json::Value::Object(per_tip);
    }
    if let Some(record) = &run.refit {
        out["refit_frame"] = serde_json::to_value(record)?;
    }
    Ok((out, stats))
}

/// The terminal line of `ferrocal evaluate`: which rows were scored (`scored`, in words) and
/// the errors.
pub fn evaluate_line(scored: &str, stats: &ErrorStats) -> String {
    format!("scored on {scored}: mean {:.4} mm, RMS {:.4} mm, max {:.4} mm", stats.mean_mm, stats.rms_mm, stats.max_mm)
}

/// The terminal lines of `ferrocal export`: the DH table written, the URDF and its companion
/// with how far they read back from the calibrated model (`n_effects`: the effects the
/// companion keeps).
pub fn export_lines(ex: &ExportRun, n_effects: usize) -> Vec<String> {
    let mut out: Vec<String> = ex.dh.iter().map(|dh| format!("wrote {}", dh.display())).collect();
    if let (Some(urdf), Some(companion), Some((mm, deg))) = (&ex.urdf, &ex.companion, ex.urdf_roundtrip_mm_deg) {
        let effects = match n_effects {
            0 => String::new(),
            n => format!("; {n} effect(s) kept in the calibration file"),
        };
        out.push(format!(
            "wrote {} and {} (read back: {mm:.2e} mm, {deg:.2e} deg from the calibrated model{effects})",
            urdf.display(),
            companion.display()
        ));
    }
    out
}
