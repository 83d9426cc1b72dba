//! `ferrocal plan`'s workflow: the source's automated calibration flow from a plan file (TOML,
//! `docs/plan-format.md`): workspace by search cut by every safety zone, the measurable region of
//! the cameras (or tracker), the regular grid for the wanted count, a denser pool, pose selection
//! by a design criterion, the predicted calibration checked against simulated calibrations, a
//! safe visiting order and the robot programs. [`run_plan`] computes everything and composes the
//! files; `ferrocal_report::plan` turns the result into the report and writes the folder.

use std::path::PathBuf;

use ferrocal_calib::design::criteria::Criterion;
use ferrocal_calib::design::flow::{plan_design, PlanDesign};
use ferrocal_calib::design::kinematic::{monte_carlo, MonteCarloReport};
use ferrocal_robot::program::{gcode, krl, path_csv, plan_path, rapid_module, urscript, verify_path, PlannedPath};
use ferrocal_robot::safety::SafetyChecker;
use ferrocal_robot::RobotModel;

use crate::error::{DatasetError, Result};
use crate::formats::plan_file::{check_runs, device, measure_steps, session_plan_toml, PlanFile};
use crate::sim::{random_subsets, DatasetsSimulator};

/// What `ferrocal plan` was asked for: the plan file, the output folder and the overrides of the
/// plan file's settings.
#[derive(Clone, Debug)]
pub struct PlanRequest {
    /// The plan file (TOML).
    pub plan: PathBuf,
    /// Folder for the poses, programs and report.
    pub out: PathBuf,
    /// Simulated calibrations of the Monte Carlo check (0: skip; the plan file's by default).
    pub simulations: Option<usize>,
    /// Override of the selection criterion.
    pub criterion: Option<Criterion>,
    /// Override of the wanted number of poses.
    pub wanted: Option<usize>,
    /// Random subsets of the chosen size compared with the selection.
    pub random_subsets: usize,
    /// Override of the seed of the random pool, subsets and simulations.
    pub seed: Option<u64>,
    /// Replace `out` when it exists and is not empty (refused otherwise).
    pub force: bool,
}

/// Everything `ferrocal plan` computed, with the files it writes (the report aside).
#[derive(Debug)]
pub struct PlanRun {
    /// The request.
    pub request: PlanRequest,
    /// The plan file, with the request's overrides applied.
    pub plan: PlanFile,
    /// The robot model.
    pub model: RobotModel,
    /// Workspace, measurable region, grid, selection and prediction.
    pub design: PlanDesign,
    /// Simulated calibrations asked for.
    pub runs: usize,
    /// The Monte Carlo check (two or more runs).
    pub monte_carlo: Option<MonteCarloReport>,
    /// Random subsets of the chosen size: best and median criterion, count.
    pub random: Option<(f64, f64, usize)>,
    /// The checked path through the chosen poses.
    pub path: PlannedPath,
    /// The files of the run folder by name (poses, path, grid, programs, session plan).
    pub files: Vec<(String, Vec<u8>)>,
    /// The KUKA program's file name.
    pub krl_file: String,
    /// Why no URScript was written (a machine that is not a six-joint revolute arm).
    pub no_urscript: Option<String>,
    /// The G-code's largest chord deviation, mm.
    pub gcode_chord_mm: f64,
}

/// Runs the flow of `ferrocal plan` on `req`: `log` receives progress lines, `on_run(k, runs)`
/// the progress of the simulated calibrations. Nothing is written.
pub fn run_plan(req: &PlanRequest, log: &dyn Fn(&str), on_run: &dyn Fn(usize, usize)) -> Result<PlanRun> {
    if let (Ok(p), Ok(o)) = (req.plan.canonicalize(), req.out.canonicalize()) {
        if p.starts_with(&o) {
            return Err(DatasetError::Input(format!(
                "{} holds the plan file {}; choose another folder",
                req.out.display(),
                req.plan.display()
            )));
        }
    }
    let mut plan = PlanFile::from_file(&req.plan)?;
    if let Some(c) = req.criterion {
        plan.design.criterion = c;
    }
    if let Some(w) = req.wanted {
        plan.design.wanted_poses = w;
        plan.design.pool_size = plan.design.pool_size.max(w);
    }
    if let Some(s) = req.seed {
        plan.design.seed = s;
        plan.simulation.seed = s;
    }
    let runs = req.simulations.unwrap_or(plan.simulation.runs);
    check_runs(runs, "--simulations")?;
    let model = RobotModel::load(&plan.robot.model)
        .map_err(|e| DatasetError::from(e).context(format!("robot model '{}'", plan.robot.model)))?;
    let checker =
        SafetyChecker::new(&model, plan.safety.clone()).map_err(|e| DatasetError::from(e).context("[safety]"))?;
    let dev = device(&plan)?;
    let design = plan_design(&model, &checker, dev.as_ref(), &plan.workspace, &plan.identify, &plan.design, log)?;

    let monte_carlo = if runs >= 2 {
        log(&format!("{runs} simulated calibrations"));
        let mut sim = DatasetsSimulator {
            nominal: model.clone(),
            errors: plan.simulation.errors.clone(),
            t_device_base: dev.t_device_base(),
            point_in_tool_m: dev.measured_point_in_tool_m(),
            seed: plan.simulation.seed,
        };
        let (d, chosen) = (&design, &design.chosen);
        let r =
            monte_carlo(&model, &d.options, &d.kinematic, chosen, &d.validation, &mut sim, runs, |k| on_run(k, runs));
        Some(r.map_err(|e| DatasetError::from(e).context("Monte Carlo check"))?)
    } else {
        None
    };

    log(&format!("ordering {} poses", design.chosen.len()));
    let poses: Vec<Vec<f64>> = design.chosen.iter().map(|&k| design.kinematic.poses[k].clone()).collect();
    let path = plan_path(&model, &checker, &design.map.home, &poses, &design.kinematic.poses, &plan.path)
        .map_err(|e| DatasetError::from(e).context("ordering the poses"))?;
    if let Err(e) = verify_path(&checker, &path) {
        return Err(DatasetError::Input(format!("internal error: the planned path failed its own safety check: {e}")));
    }
    let header = vec![
        format!("ferrocal plan {} ({})", env!("CARGO_PKG_VERSION"), chrono::Utc::now().to_rfc3339()),
        format!("plan file {}; robot {}; device {}", req.plan.display(), model.name(), design.device),
        format!(
            "{} measurements; every configuration and joint-space segment checked against the safety zones",
            path.measurements()
        ),
    ];
    let dwell_s = plan.path.dwell_s;
    let mut files: Vec<(String, Vec<u8>)> = vec![
        ("poses.csv".into(), path_csv(&model, &path, true)?.into_bytes()),
        ("path.csv".into(), path_csv(&model, &path, false)?.into_bytes()),
    ];
    let grid_path = measure_steps(&design.kinematic.poses, &design.grid_indices);
    let grid = path_csv(&model, &grid_path, true)?;
    files.push(("grid_poses.csv".into(), grid.into_bytes()));
    let rapid = rapid_module(&model, &path, dwell_s, &plan.program, &header)?;
    files.push(("program.mod".into(), rapid.into_bytes()));
    let g = gcode(&model, &path, dwell_s, &plan.program, &header)?;
    files.push(("program.ngc".into(), g.text.clone().into_bytes()));
    let krl_file = format!("{}.src", plan.program.krl_name);
    let k = krl(&model, &path, dwell_s, &plan.program, &header)?;
    files.push((krl_file.clone(), k.into_bytes()));
    // URScript only for a six-joint revolute arm; other machines get no script (said in the report).
    let no_urscript = match urscript(&model, &path, dwell_s, &plan.program, &header) {
        Ok(text) => {
            files.push(("program.script".into(), text.into_bytes()));
            None
        }
        Err(e) => Some(e.to_string()),
    };
    files.push(("session_plan.toml".into(), session_plan_toml(&design.map.home, &path, dwell_s).into_bytes()));
    let random =
        random_subsets(&design, design.chosen.len(), req.random_subsets, design.settings.criterion, plan.design.seed);
    Ok(PlanRun {
        request: req.clone(),
        plan,
        model,
        design,
        runs,
        monte_carlo,
        random,
        path,
        files,
        krl_file,
        no_urscript,
        gcode_chord_mm: g.max_chord_deviation_mm,
    })
}
