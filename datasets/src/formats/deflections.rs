//! The deflection table of `ferrocal stiffness` (`docs/stiffness.md`): per row an observation
//! id, the joint angles `q1_deg..qn_deg`, the wrench (`frame`, `fx_n..mz_nm` about the tool point),
//! `self_weight` (0 or 1) and one reflector (`marker_x_mm..marker_z_mm`) with its measured
//! displacement (`dx_mm..dz_mm`) and standard deviation (`sigma_mm`). Rows of one id form one
//! observation. Comma-separated, `#` lines are comments; errors name the file, line and column.

use std::collections::BTreeMap;
use std::path::Path;

use ferrocal_calib::stiffness::problem::{Measured, Observation};
use ferrocal_robot::stiffness::presets::{stiffness_preset, STIFFNESS_PRESETS};
use ferrocal_robot::stiffness::{Loading, VjmModel, WrenchLimits, WrenchSpec};
use ferrocal_robot::RobotModel;

use crate::error::{DatasetError, Result};

/// The wrench columns.
pub const LOAD_COLUMNS: [&str; 7] = ["frame", "fx_n", "fy_n", "fz_n", "mx_nm", "my_nm", "mz_nm"];
/// The reflector columns.
pub const MARKER_COLUMNS: [&str; 7] =
    ["marker_x_mm", "marker_y_mm", "marker_z_mm", "dx_mm", "dy_mm", "dz_mm", "sigma_mm"];

fn input(message: String) -> DatasetError {
    DatasetError::Input(message)
}

/// The stiffness model named `name` and its design estimates (the values fixed parameters
/// take): a stiffness preset carries them; any other serial model (robot preset, URDF, model
/// file) gets one spring per link and no design estimates. A parallel robot is refused.
pub fn stiffness_model(name: &str) -> Result<(VjmModel, Option<Vec<f64>>)> {
    if let Some(m) = stiffness_preset(name) {
        let m = m.map_err(|e| input(e.to_string()))?;
        let prior = m.complete_values();
        return Ok((m, Some(prior)));
    }
    let robot = RobotModel::load(name).map_err(|e| {
        input(format!(
            "'{name}' is neither a stiffness preset ({}) nor a robot model: {e}",
            STIFFNESS_PRESETS.join(", ")
        ))
    })?;
    let RobotModel::Serial(chain) = robot else {
        return Err(input(format!("'{name}' is not a serial arm: the virtual joint model needs a serial chain")));
    };
    Ok((VjmModel::with_link_springs(chain).map_err(|e| input(e.to_string()))?, None))
}

/// The columns of a table for an arm of `dof` joints, in writing order.
pub fn header_columns(dof: usize) -> Vec<String> {
    let mut need: Vec<String> = vec!["id".into()];
    need.extend((1..=dof).map(|j| format!("q{j}_deg")));
    need.extend(LOAD_COLUMNS.iter().map(|s| s.to_string()));
    need.push("self_weight".into());
    need.extend(MARKER_COLUMNS.iter().map(|s| s.to_string()));
    need
}

/// The rows of one observation measured by reflectors under a wrench given in the base frame
/// (`self_weight` 1), one row per reflector, each ending in a newline.
pub fn observation_rows(o: &Observation) -> String {
    let mut text = String::new();
    let w = o.loading.tool_wrench;
    let Measured::Markers { markers_in_tool_m, dp_m, sigma_m } = &o.measured else { return text };
    for (m, d) in markers_in_tool_m.iter().zip(dp_m) {
        let mut cells: Vec<String> = vec![o.id.clone()];
        cells.extend(o.q.iter().map(|v| format!("{:.6}", v.to_degrees())));
        cells.push("base".into());
        cells.extend(w.force_n.iter().chain(w.torque_nm.iter()).map(|v| format!("{v:.4}")));
        cells.push("1".into());
        cells.extend(m.iter().map(|v| format!("{:.3}", v * 1e3)));
        cells.extend(d.iter().map(|v| format!("{:.5}", v * 1e3)));
        cells.push(format!("{:.4}", sigma_m * 1e3));
        text.push_str(&cells.join(","));
        text.push('\n');
    }
    text
}

/// Reads the deflection table into observations (errors carry `file:line`).
pub fn read_deflections(path: &Path, model: &VjmModel, limits: &WrenchLimits) -> Result<Vec<Observation>> {
    let file = std::fs::File::open(path).map_err(|source| DatasetError::Io { path: path.to_path_buf(), source })?;
    let mut rd = csv::ReaderBuilder::new().comment(Some(b'#')).trim(csv::Trim::All).flexible(true).from_reader(file);
    let header: Vec<String> = rd
        .headers()
        .map_err(|e| input(format!("{}: no header: {e}", path.display())))?
        .iter()
        .map(String::from)
        .collect();
    let n = model.dof();
    let need = header_columns(n);
    let col = |name: &str| header.iter().position(|h| h == name);
    for c in &need {
        if col(c).is_none() {
            return Err(input(format!("{}: missing column '{c}' (need {})", path.display(), need.join(","))));
        }
    }
    let mut obs: Vec<Observation> = Vec::new();
    let mut by_id: BTreeMap<String, usize> = BTreeMap::new();
    for rec in rd.records() {
        let rec = rec.map_err(|e| input(format!("{}: unreadable row: {e}", path.display())))?;
        let line = rec.position().map(|p| p.line()).unwrap_or(0);
        let at = |c: &str| format!("{}:{line}, column '{c}'", path.display());
        let get = |c: &str| -> Result<&str> {
            rec.get(col(c).unwrap_or(usize::MAX)).ok_or_else(|| input(format!("{}: missing value", at(c))))
        };
        let num = |c: &str| -> Result<f64> {
            let t = get(c)?;
            let v: f64 = t.parse().map_err(|_| input(format!("{}: '{t}' is not a number", at(c))))?;
            if !v.is_finite() {
                return Err(input(format!("{}: '{t}' is not finite", at(c))));
            }
            Ok(v)
        };
        let id = get("id")?.to_string();
        let q: Vec<f64> = (1..=n).map(|j| num(&format!("q{j}_deg")).map(f64::to_radians)).collect::<Result<_>>()?;
        // Moments are about the tool point: its position in the named frame.
        let frame = get("frame")?.to_string();
        let t = model.frame_pose(&q, &frame).map_err(|e| input(format!("{}: {e}", at("frame"))))?;
        let tool = model.chain.frames(&q).map_err(|e| input(format!("{}:{line}: {e}", path.display())))?.tool;
        let p_tool = t.inverse() * nalgebra::Point3::from(tool.translation.vector);
        let spec = WrenchSpec {
            frame,
            force_n: [num("fx_n")?, num("fy_n")?, num("fz_n")?],
            torque_nm: [num("mx_nm")?, num("my_nm")?, num("mz_nm")?],
            point_m: p_tool.coords.into(),
        };
        let self_weight = match get("self_weight")? {
            "1" | "true" | "yes" => true,
            "0" | "false" | "no" => false,
            other => return Err(input(format!("{}: '{other}' is not 0 or 1", at("self_weight")))),
        };
        let marker = [num("marker_x_mm")? * 1e-3, num("marker_y_mm")? * 1e-3, num("marker_z_mm")? * 1e-3];
        let dp = [num("dx_mm")? * 1e-3, num("dy_mm")? * 1e-3, num("dz_mm")? * 1e-3];
        let sigma = num("sigma_mm")? * 1e-3;
        if sigma <= 0.0 {
            return Err(input(format!("{}: sigma must be positive", at("sigma_mm"))));
        }
        match by_id.get(&id) {
            Some(&k) => {
                let o = &mut obs[k];
                if o.q.iter().zip(&q).any(|(a, b)| (a - b).abs() > 1e-9) {
                    return Err(input(format!(
                        "{}:{line}: observation '{id}' has other joint values than its first row",
                        path.display()
                    )));
                }
                if let Measured::Markers { markers_in_tool_m, dp_m, .. } = &mut o.measured {
                    markers_in_tool_m.push(marker);
                    dp_m.push(dp);
                }
            }
            None => {
                let w = model
                    .resolve_wrench(&q, &spec, limits)
                    .map_err(|e| input(format!("{}:{line}: {e}", path.display())))?;
                let loading = if self_weight { Loading::gravity(w) } else { Loading::tool(w) };
                by_id.insert(id.clone(), obs.len());
                obs.push(Observation {
                    id,
                    q,
                    loading,
                    measured: Measured::Markers { markers_in_tool_m: vec![marker], dp_m: vec![dp], sigma_m: sigma },
                    truth: None,
                });
            }
        }
    }
    if obs.is_empty() {
        return Err(input(format!("{}: no measurements", path.display())));
    }
    Ok(obs)
}
