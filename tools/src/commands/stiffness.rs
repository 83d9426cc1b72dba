//! `ferrocal stiffness`: elastostatic identification of serial robots by the virtual joint
//! method with practical identifiability (Klimchik et al. 2015).
//!
//! - `study`: the source's one-link and 6-DOF studies on the simulator, tabulated beside the
//!   source's numbers (HTML report with SVG plots);
//! - `simulate`: writes a deflection table of the simulated KR 270-like arm to try `identify` on;
//! - `identify`: the reduced compliance model from a table of joint angles, wrenches and measured
//!   deflections, with the reduction table and the parameters that can be trusted.
//!
//! File format: `docs/stiffness.md`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{anyhow, bail, Context, Result};
use ferrocal_calib::stiffness::onelink::SOURCE_NU;
use ferrocal_calib::stiffness::problem::{LinearProblem, Measured, Observation};
use ferrocal_calib::stiffness::reduce::{reduce, Reduction, ReductionSettings};
use ferrocal_calib::stiffness::{LoadCase, StiffnessIdError};
use ferrocal_datasets::stiffsim::study::{arm_study, one_link_study, ArmStudy, ArmStudySettings, OneLinkStudy};
use ferrocal_datasets::stiffsim::{StiffSim, StiffSimConfig};
use ferrocal_robot::stiffness::presets::{stiffness_preset, STIFFNESS_PRESETS};
use ferrocal_robot::stiffness::{Loading, VjmModel, WrenchLimits, WrenchSpec};
use serde_json::json;

use crate::plot::{self, Series};
use crate::report::{write_atomic, Provenance, Report, Section};

/// `ferrocal stiffness`.
#[derive(Debug, clap::Args)]
#[command(
    about = "Elastostatic (compliance) identification with practical identifiability and compliance compensation",
    long_about = "The virtual joint model of a serial arm (compliant joints, a 6x6 compliance matrix per link, a gravity compensator), its identification from deflections measured under loads, the source's model reduction (symmetry, sparsity templates, aggregation, SVD partition, coupled groups, parameter-to-noise threshold) and compensation of a task load by the mirror method.\n\nFile format and method: docs/stiffness.md."
)]
pub struct StiffnessArgs {
    /// What to do.
    #[command(subcommand)]
    pub command: StiffnessCommand,
}

/// The subcommands of `ferrocal stiffness`.
#[derive(Debug, clap::Subcommand)]
pub enum StiffnessCommand {
    /// Run the source's one-link and 6-DOF studies on the simulator and write an HTML report
    /// beside the source's numbers. Exits 0 when every check passes, 2 when the report was
    /// written but a check failed.
    Study(StudyArgs),
    /// Write a simulated deflection table of the KR 270-like arm (deflections.csv) and its true
    /// compliances (truth.json).
    Simulate(SimulateArgs),
    /// Identify the reduced compliance model from a deflection table. Exits 2 when the estimate
    /// is not physical or the loads leave parameters unexcited.
    Identify(IdentifyArgs),
}

/// `ferrocal stiffness study`.
#[derive(Debug, clap::Args)]
pub struct StudyArgs {
    /// Folder for index.html and report.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Seed of every simulation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulated one-link experiments.
    #[arg(long, default_value_t = 100)]
    pub trials: usize,
    /// Smaller 6-DOF experiment.
    #[arg(long)]
    pub quick: bool,
}

/// `ferrocal stiffness simulate`.
#[derive(Debug, clap::Args)]
pub struct SimulateArgs {
    /// Folder for deflections.csv and truth.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Configurations (each measured without payload, with 150 kg and with 270 kg).
    #[arg(long, default_value_t = 30)]
    pub configurations: usize,
}

/// `ferrocal stiffness identify`.
#[derive(Debug, clap::Args)]
pub struct IdentifyArgs {
    /// The deflection table (CSV, docs/stiffness.md).
    #[arg(long)]
    pub measurements: PathBuf,
    /// The stiffness model: a stiffness preset with design estimates (kr270-like), or any serial
    /// robot (preset name, URDF, model file) with one spring per link and no design estimates.
    #[arg(long, default_value = "kr270-like")]
    pub model: String,
    /// Smallest parameter-to-noise ratio kept.
    #[arg(long, default_value_t = 2.0)]
    pub nu_threshold: f64,
    /// Folder for a report (index.html, report.json) and parameters.json.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Runs `ferrocal stiffness`.
pub fn run(args: &StiffnessArgs) -> Result<ExitCode> {
    match &args.command {
        StiffnessCommand::Study(a) => run_study(a),
        StiffnessCommand::Simulate(a) => run_simulate(a),
        StiffnessCommand::Identify(a) => run_identify(a),
    }
}

fn um(v: f64) -> String {
    format!("{:.1}", v * 1e6)
}

fn mm(v: f64) -> String {
    format!("{:.3}", v * 1e3)
}

/// The source's parameter counts per step (M4 and M6 not stated).
const SOURCE_COUNTS: [(&str, &str); 7] =
    [("M0", "258"), ("M1", "153"), ("M2", "62"), ("M3", "56"), ("M4", "-"), ("M5", "26"), ("M6", "-")];

fn section_one_link(st: &OneLinkStudy) -> Section {
    let mut sec = Section::new("one-link", "One Orthoglide link: parameter-to-noise ratios and the naive estimate");
    sec.text(format!(
        "The source's compliance matrix, noise 25 um / 0.25 mrad, {} loads of +-10 N / +-10 N m along each axis (W^T W = 10^4 I, so every entry of row i has the standard deviation sigma_i / 100). Ratios from the covariance (A^T S^-1 A)^-1 of the complete 36-parameter model at the true values.",
        st.n_loads
    ));
    let mut rows = Vec::new();
    let mut all_ok = true;
    for (name, source) in SOURCE_NU {
        let Some(e) = st.ratios.iter().find(|e| e.name == name) else { continue };
        let ok = (e.nu - source).abs() <= (0.005 * source).max(0.005);
        all_ok &= ok;
        rows.push(vec![
            name.to_string(),
            format!("{:.3e}", e.value),
            format!("{:.2e}", e.std),
            format!("{:.4}", e.nu),
            format!("{source}"),
            if ok { "agrees" } else { "DIFFERS" }.into(),
        ]);
    }
    sec.table("Non-zero entries", &["entry", "value", "std", "nu (ours)", "nu (source)", ""], rows);
    let unusable = st.ratios.iter().filter(|e| e.nu < 2.0).count();
    let pts_ours: Vec<(f64, f64)> = SOURCE_NU
        .iter()
        .enumerate()
        .filter_map(|(i, (n, _))| st.ratios.iter().find(|e| e.name == *n).map(|e| (i as f64, e.nu.log10())))
        .collect();
    let pts_src: Vec<(f64, f64)> = SOURCE_NU.iter().enumerate().map(|(i, (_, v))| (i as f64, v.log10())).collect();
    sec.figure(
        "log10 of the parameter-to-noise ratio of the ten non-zero entries (k11, k22, k26, k33, k35, k44, k53, k55, k62, k66), ours against the source's",
        plot::xy_plot(
            "Parameter-to-noise ratios",
            "entry (k11 ... k66)",
            "log10 nu",
            &[
                Series { name: "ours", points: &pts_ours, line: false },
                Series { name: "source", points: &pts_src, line: true },
            ],
        ),
    );
    sec.table(
        &format!("{} simulated experiments", st.trials),
        &["", "naive (36 entries)", "reduced", "source"],
        vec![
            vec![
                "entries with nu < 2 at the true values".into(),
                unusable.to_string(),
                "-".into(),
                "27 of 36 unusable".into(),
            ],
            vec![
                "negative k11".into(),
                st.naive_negative_k11.to_string(),
                "0 (k11 fixed or positive)".into(),
                "k11 negative".into(),
            ],
            vec!["asymmetric matrix".into(), st.naive_asymmetric.to_string(), "0 (by M1)".into(), "asymmetric".into()],
            vec![
                "any physical problem".into(),
                st.naive_unphysical.to_string(),
                st.reduced_unphysical.to_string(),
                "-".into(),
            ],
            vec![
                "free parameters".into(),
                "36".into(),
                format!("{:.2} (k11 kept in {})", st.reduced_mean_params, st.reduced_kept_k11),
                "-".into(),
            ],
            vec![
                "validation RMS vs truth (um)".into(),
                um(st.validation_truth_rms_m[0]),
                um(st.validation_truth_rms_m[1]),
                "-".into(),
            ],
        ],
    );
    let ok = all_ok && unusable == 27 && st.reduced_unphysical == 0 && st.naive_unphysical == st.trials;
    sec.status(ok, if ok { "ratios as the source's; reduced estimates physical" } else { "a check failed" });
    sec.data = json!({"ratios": st.ratios, "study": st});
    sec
}

fn reduction_table(red: &Reduction) -> Vec<Vec<String>> {
    red.steps
        .iter()
        .map(|s| {
            let src = SOURCE_COUNTS.iter().find(|(c, _)| *c == s.code).map(|(_, v)| *v).unwrap_or("-");
            vec![
                s.code.clone(),
                s.title.clone(),
                s.n_params.to_string(),
                src.to_string(),
                s.rank.to_string(),
                format!("{:.3e}", s.condition_number),
                format!("{:.2}", s.s0),
                s.validation_rms_m.map(um).unwrap_or_else(|| "-".into()),
                s.validation_truth_rms_m.map(um).unwrap_or_else(|| "-".into()),
                s.cost_m.map(|c| format!("{:+.1}", c * 1e6)).unwrap_or_else(|| "-".into()),
                s.note.clone(),
            ]
        })
        .collect()
}

const REDUCTION_HEADER: [&str; 11] = [
    "step",
    "what",
    "parameters",
    "source",
    "rank",
    "cond",
    "s0",
    "validation RMS (um)",
    "vs truth (um)",
    "cost (um)",
    "note",
];

/// The source's compensation results (mm): uncompensated, rigid-link/compliant-joint, reduced.
const SOURCE_COMP: [(&str, &str, &str); 3] =
    [("none", "4.58", "8.18"), ("rigid links, compliant joints", "0.73", "1.76"), ("reduced model", "0.21", "0.49")];

fn compensation_rows(s: &ArmStudy) -> Vec<Vec<String>> {
    s.compensation
        .iter()
        .map(|c| {
            let src = SOURCE_COMP.iter().find(|(n, ..)| *n == c.model);
            vec![
                c.model.clone(),
                c.n_params.to_string(),
                mm(c.rms_m),
                mm(c.max_m),
                format!("{:.3}", c.rms_rad * 1e3),
                src.map(|s| s.1.to_string()).unwrap_or_else(|| "-".into()),
                src.map(|s| s.2.to_string()).unwrap_or_else(|| "-".into()),
            ]
        })
        .collect()
}

const COMP_HEADER: [&str; 7] =
    ["compensation", "parameters", "RMS (mm)", "max (mm)", "RMS rot (mrad)", "source RMS (mm)", "source max (mm)"];

fn arm_checks(s: &ArmStudy) -> (bool, String) {
    let none = s.errors("none").map(|c| c.rms_m).unwrap_or(0.0);
    let red = s.errors("reduced model").map(|c| c.rms_m).unwrap_or(f64::INFINITY);
    let rl = s.errors("rigid links, compliant joints").map(|c| c.rms_m).unwrap_or(0.0);
    let last = s.reduction.param.len();
    let removed = 1.0 - red / none;
    let ok = removed > 0.9 && rl > red && (8..=40).contains(&last);
    (
        ok,
        format!(
            "{} -> {last} parameters; {:.1} % of the compliance error removed; rigid-link model leaves {:.1} x more",
            s.reduction.steps[0].n_params,
            100.0 * removed,
            rl / red
        ),
    )
}

fn sections_arm(s: &ArmStudy) -> Vec<Section> {
    let mut out = Vec::new();
    let mut sec = Section::new("arm-reduction", "KR 270-like arm: model reduction M0 to M6");
    sec.text(format!(
        "Simulated KR 270-like arm: joint and link compliances 30 % away from the design estimates, a gravity compensator spring on joint 2, a laser tracker (30 um) on three reflectors. {} candidate measurements ({} configurations x {} payloads), {} kept by the {} criterion, {} validation measurements. Our counts include the compensator's two terms (k K_s and k K_s s0): 258 + 2. Fixed parameters take the design estimates; the cost of a step is the change of the validation RMS against the truth.",
        s.counts[0],
        s.settings.n_pool,
        s.settings.payloads.len(),
        s.counts[1],
        s.settings.criterion.name(),
        s.counts[2]
    ));
    sec.table("Parameters after each step, with the accuracy cost", &REDUCTION_HEADER, reduction_table(&s.reduction));
    let pts: Vec<(f64, f64)> =
        s.reduction.steps.iter().enumerate().map(|(i, st)| (i as f64, st.n_params as f64)).collect();
    let src: Vec<(f64, f64)> = [(0.0, 258.0), (1.0, 153.0), (2.0, 62.0), (3.0, 56.0), (5.0, 26.0)].to_vec();
    let val: Vec<(f64, f64)> = s
        .reduction
        .steps
        .iter()
        .enumerate()
        .filter_map(|(i, st)| st.validation_truth_rms_m.map(|v| (i as f64, v * 1e6)))
        .collect();
    sec.figure(
        "Free parameters after each step (M0 ... M6), ours and the source's",
        plot::xy_plot(
            "Model reduction",
            "step",
            "parameters",
            &[Series { name: "ours", points: &pts, line: true }, Series { name: "source", points: &src, line: false }],
        ),
    );
    sec.figure(
        "Validation RMS against the truth after each step (um)",
        plot::xy_plot(
            "Accuracy of each step",
            "step",
            "RMS (um)",
            &[Series { name: "validation", points: &val, line: true }],
        ),
    );
    for g in &s.reduction.coupled_groups {
        sec.text(format!("M5: {g}"));
    }
    if !s.reduction.physical_problems.is_empty() {
        sec.text(format!("The final estimate is not physical: {}", s.reduction.physical_problems.join("; ")));
    }
    sec.data = json!({"steps": s.reduction.steps, "fixed": s.reduction.fixed, "final": s.reduction.param.names()});
    out.push(sec);

    let mut sec = Section::new("arm-design", "Experiment design for the reduced regressor");
    let med = |v: &[f64]| {
        let mut v: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    sec.table(
        "Chosen measurements against random sets of the same size (the planner's greedy deletion and exchange)",
        &["", "chosen", "random (median of 15)"],
        vec![
            vec![
                format!("{} ({})", s.design.criterion.name(), s.design.criterion.describe()),
                format!("{:.2}", s.design.value),
                format!("{:.2}", s.design.random_value),
            ],
            vec![
                "median predicted relative std of the M5 parameters".into(),
                format!("{:.3}", med(&s.design.relative_std)),
                format!("{:.3}", med(&s.design.random_relative_std)),
            ],
        ],
    );
    out.push(sec);

    let mut sec = Section::new("arm-compensation", "Compensation of a 2.5 kN class task load (mirror method)");
    sec.text(format!(
        "{} task configurations under a {:.0} kg payload (up to {:.0} N); the links' weight and the compensator act too. Each model predicts the deflection, the robot is commanded to the mirrored target (two passes), the true compliant robot's tool error is measured.",
        s.settings.n_task,
        s.settings.task_load.mass_kg,
        s.task_force_n
    ));
    sec.table("Tool position error after compensation", &COMP_HEADER, compensation_rows(s));
    if let Some(m5) = s.reduction.step("M5") {
        let layout = s.reduction.fit.names.len();
        let problems = s.m5_physical_problems.len();
        sec.text(format!(
            "The M5 row keeps every identifiable parameter ({} of them, before the parameter-to-noise threshold): it predicts these loads at least as well, but its estimates are not physical ({problems} problem(s): negative compliances, couplings beyond their diagonal), while the reduced model has {layout} parameters, each resolved (nu >= {}) or clearly away from its design estimate.",
            m5.n_params, s.settings.reduction.nu_threshold
        ));
    }
    let series: Vec<(String, Vec<(f64, f64)>)> = s
        .compensation
        .iter()
        .map(|c| (c.model.clone(), c.per_pose_m.iter().enumerate().map(|(i, e)| (i as f64, e * 1e3)).collect()))
        .filter(|(n, _)| n != "none")
        .collect();
    let ser: Vec<Series> = series.iter().map(|(n, p)| Series { name: n, points: p, line: false }).collect();
    sec.figure(
        "Residual position error per task configuration (mm) after compensation",
        plot::xy_plot("Residual error", "task configuration", "error (mm)", &ser),
    );
    let (ok, msg) = arm_checks(s);
    sec.status(ok, msg);
    sec.data = json!({"compensation": s.compensation, "task_force_n": s.task_force_n});
    out.push(sec);
    out
}

fn run_study(a: &StudyArgs) -> Result<ExitCode> {
    let t0 = std::time::Instant::now();
    if a.trials == 0 {
        bail!("--trials must be at least 1");
    }
    let one = one_link_study(a.trials, a.seed)?;
    let settings = if a.quick { ArmStudySettings::quick(a.seed) } else { ArmStudySettings::full(a.seed) };
    let arm = arm_study(&settings)?;
    let mut sections = vec![section_one_link(&one)];
    sections.extend(sections_arm(&arm));
    let ok = sections.iter().all(|s| s.status.as_ref().is_none_or(|(ok, _)| *ok));
    let prov = Provenance::new(json!({"seed": a.seed, "trials": a.trials, "quick": a.quick}));
    let mut report =
        Report::new("Elastostatic identification with practical identifiability (Klimchik et al. 2015)", prov);
    report.sections = sections;
    let html = report.write(&a.out)?;
    println!("wrote {} ({:.1} s)", html.display(), t0.elapsed().as_secs_f64());
    Ok(if ok { ExitCode::SUCCESS } else { ExitCode::from(2) })
}

/// The demo's section: the one-link ratios and the 6-DOF reduction and compensation beside the
/// source's numbers (a second or two in release).
pub fn demo_section(seed: u64, quick: bool) -> Result<Section> {
    let one = one_link_study(if quick { 10 } else { 40 }, seed)?;
    let arm = arm_study(&ArmStudySettings::quick(seed))?;
    let mut sec = Section::new("stiffness", "Elastostatic identification: practical identifiability (simulated)");
    let max_dev = SOURCE_NU
        .iter()
        .filter_map(|(n, v)| one.ratios.iter().find(|e| e.name == *n).map(|e| (e.nu - v).abs() / v))
        .fold(0.0, f64::max);
    let counts: Vec<String> = arm.reduction.steps.iter().map(|s| s.n_params.to_string()).collect();
    let c = |m: &str| arm.errors(m).map(|c| (mm(c.rms_m), mm(c.max_m))).unwrap_or_default();
    let (n, r, red) = (c("none"), c("rigid links, compliant joints"), c("reduced model"));
    let m5 = c("M5 model (before the threshold)");
    sec.table(
        "Headline numbers beside the source's (Klimchik et al. 2015)",
        &["", "ours", "source"],
        vec![
            vec![
                "one link: parameter-to-noise ratios (10 non-zero entries)".into(),
                format!("largest deviation {:.2} %", 100.0 * max_dev),
                "0.18 ... 1592".into(),
            ],
            vec![
                "one link: naive / reduced estimates with a physical problem".into(),
                format!("{} / {} of {}", one.naive_unphysical, one.reduced_unphysical, one.trials),
                "naive fails (k11 < 0, asymmetric)".into(),
            ],
            vec!["6-DOF reduction M0 ... M6".into(), counts.join(" -> "), "258 -> 153 -> 62 -> 56 -> 26".into()],
            vec!["uncompensated RMS / max (mm)".into(), format!("{} / {}", n.0, n.1), "4.58 / 8.18".into()],
            vec!["rigid-link, compliant-joint model (mm)".into(), format!("{} / {}", r.0, r.1), "0.73 / 1.76".into()],
            vec!["reduced model (mm)".into(), format!("{} / {}", red.0, red.1), "0.21 / 0.49".into()],
            vec![
                "M5 model: all identifiable parameters, unphysical values (mm)".into(),
                format!("{} / {}", m5.0, m5.1),
                "-".into(),
            ],
        ],
    );
    let (ok, msg) = arm_checks(&arm);
    let ok = ok && max_dev < 0.005 && one.reduced_unphysical == 0;
    sec.status(ok, msg);
    sec.text("Full study: `ferrocal stiffness study --out DIR`; method and file format: docs/stiffness.md.");
    sec.data = json!({"one_link_max_ratio_deviation": max_dev, "counts": counts, "compensation": arm.compensation});
    Ok(sec)
}

const LOAD_COLUMNS: [&str; 7] = ["frame", "fx_n", "fy_n", "fz_n", "mx_nm", "my_nm", "mz_nm"];
const MARKER_COLUMNS: [&str; 7] = ["marker_x_mm", "marker_y_mm", "marker_z_mm", "dx_mm", "dy_mm", "dz_mm", "sigma_mm"];

fn run_simulate(a: &SimulateArgs) -> Result<ExitCode> {
    let mut sim = StiffSim::kr270(StiffSimConfig { seed: a.seed, ..StiffSimConfig::default() })?;
    let qs = sim.random_configurations(a.configurations);
    let loads = [
        LoadCase::payload(0.0, [0.0; 3]),
        LoadCase::payload(150.0, [0.25, 0.0, 0.15]),
        LoadCase::payload(270.0, [0.0, 0.25, 0.3]),
    ];
    let n = sim.nominal.dof();
    let mut text = String::from("# ferrocal stiffness simulate: KR 270-like arm, tracker on three reflectors\n");
    let mut header: Vec<String> = vec!["id".into()];
    header.extend((1..=n).map(|j| format!("q{j}_deg")));
    header.extend(LOAD_COLUMNS.iter().map(|s| s.to_string()));
    header.push("self_weight".into());
    header.extend(MARKER_COLUMNS.iter().map(|s| s.to_string()));
    text.push_str(&header.join(","));
    text.push('\n');
    for (k, q) in qs.iter().enumerate() {
        for (l, load) in loads.iter().enumerate() {
            let o = sim.observe(&format!("c{k:03}_{l}"), q, load)?;
            let w = o.loading.tool_wrench;
            let Measured::Markers { markers_in_tool_m, dp_m, sigma_m } = &o.measured else { unreachable!() };
            for (m, d) in markers_in_tool_m.iter().zip(dp_m) {
                let mut cells: Vec<String> = vec![o.id.clone()];
                cells.extend(q.iter().map(|v| format!("{:.6}", v.to_degrees())));
                cells.push("base".into());
                cells.extend(w.force_n.iter().chain(w.torque_nm.iter()).map(|v| format!("{v:.4}")));
                cells.push("1".into());
                cells.extend(m.iter().map(|v| format!("{:.3}", v * 1e3)));
                cells.extend(d.iter().map(|v| format!("{:.5}", v * 1e3)));
                cells.push(format!("{:.4}", sigma_m * 1e3));
                text.push_str(&cells.join(","));
                text.push('\n');
            }
        }
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("cannot create {}", a.out.display()))?;
    write_atomic(&a.out.join("deflections.csv"), text.as_bytes())?;
    let layout = sim.truth.layout()?;
    let truth: BTreeMap<String, f64> = layout.names().into_iter().zip(sim.truth.complete_values()).collect();
    write_atomic(&a.out.join("truth.json"), serde_json::to_string_pretty(&truth)?.as_bytes())?;
    println!("wrote {} ({} measurements)", a.out.join("deflections.csv").display(), qs.len() * loads.len());
    Ok(ExitCode::SUCCESS)
}

/// Reads the deflection table into observations (errors carry `file:line`).
pub fn read_deflections(path: &Path, model: &VjmModel, limits: &WrenchLimits) -> Result<Vec<Observation>> {
    let file = std::fs::File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let mut rd = csv::ReaderBuilder::new().comment(Some(b'#')).trim(csv::Trim::All).flexible(true).from_reader(file);
    let header: Vec<String> =
        rd.headers().with_context(|| format!("{}: no header", path.display()))?.iter().map(String::from).collect();
    let n = model.dof();
    let mut need: Vec<String> = vec!["id".into()];
    need.extend((1..=n).map(|j| format!("q{j}_deg")));
    need.extend(LOAD_COLUMNS.iter().map(|s| s.to_string()));
    need.push("self_weight".into());
    need.extend(MARKER_COLUMNS.iter().map(|s| s.to_string()));
    let col = |name: &str| header.iter().position(|h| h == name);
    for c in &need {
        if col(c).is_none() {
            bail!("{}: missing column '{c}' (need {})", path.display(), need.join(","));
        }
    }
    let mut obs: Vec<Observation> = Vec::new();
    let mut by_id: BTreeMap<String, usize> = BTreeMap::new();
    for rec in rd.records() {
        let rec = rec.with_context(|| format!("{}: unreadable row", path.display()))?;
        let line = rec.position().map(|p| p.line()).unwrap_or(0);
        let at = |c: &str| format!("{}:{line}, column '{c}'", path.display());
        let get = |c: &str| -> Result<&str> {
            rec.get(col(c).unwrap_or(usize::MAX)).ok_or_else(|| anyhow!("{}: missing value", at(c)))
        };
        let num = |c: &str| -> Result<f64> {
            let t = get(c)?;
            let v: f64 = t.parse().map_err(|_| anyhow!("{}: '{t}' is not a number", at(c)))?;
            if !v.is_finite() {
                bail!("{}: '{t}' is not finite", at(c));
            }
            Ok(v)
        };
        let id = get("id")?.to_string();
        let q: Vec<f64> = (1..=n).map(|j| num(&format!("q{j}_deg")).map(f64::to_radians)).collect::<Result<_>>()?;
        // Moments are about the tool point: its position in the named frame.
        let frame = get("frame")?.to_string();
        let t = model.frame_pose(&q, &frame).map_err(|e| anyhow!("{}: {e}", at("frame")))?;
        let tool = model.chain.frames(&q).map_err(|e| anyhow!("{}:{line}: {e}", path.display()))?.tool;
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
            other => bail!("{}: '{other}' is not 0 or 1", at("self_weight")),
        };
        let marker = [num("marker_x_mm")? * 1e-3, num("marker_y_mm")? * 1e-3, num("marker_z_mm")? * 1e-3];
        let dp = [num("dx_mm")? * 1e-3, num("dy_mm")? * 1e-3, num("dz_mm")? * 1e-3];
        let sigma = num("sigma_mm")? * 1e-3;
        if sigma <= 0.0 {
            bail!("{}: sigma must be positive", at("sigma_mm"));
        }
        match by_id.get(&id) {
            Some(&k) => {
                let o = &mut obs[k];
                if o.q.iter().zip(&q).any(|(a, b)| (a - b).abs() > 1e-9) {
                    bail!("{}:{line}: observation '{id}' has other joint values than its first row", path.display());
                }
                if let Measured::Markers { markers_in_tool_m, dp_m, .. } = &mut o.measured {
                    markers_in_tool_m.push(marker);
                    dp_m.push(dp);
                }
            }
            None => {
                let w =
                    model.resolve_wrench(&q, &spec, limits).map_err(|e| anyhow!("{}:{line}: {e}", path.display()))?;
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
        bail!("{}: no measurements", path.display());
    }
    Ok(obs)
}

fn run_identify(a: &IdentifyArgs) -> Result<ExitCode> {
    // A stiffness preset carries design estimates (the values fixed parameters take); any other
    // serial model (robot preset, URDF, model file) gets one spring per link and zero priors.
    let (model, prior) = match stiffness_preset(&a.model) {
        Some(m) => {
            let m = m?;
            let prior = m.complete_values();
            (m, Some(prior))
        }
        None => {
            let robot = ferrocal_robot::RobotModel::load(&a.model).map_err(|e| {
                anyhow!(
                    "'{}' is neither a stiffness preset ({}) nor a robot model: {e}",
                    a.model,
                    STIFFNESS_PRESETS.join(", ")
                )
            })?;
            let ferrocal_robot::RobotModel::Serial(chain) = robot else {
                bail!("'{}' is not a serial arm: the virtual joint model needs a serial chain", a.model);
            };
            (VjmModel::with_link_springs(chain)?, None)
        }
    };
    let limits = WrenchLimits::default();
    let obs = read_deflections(&a.measurements, &model, &limits)?;
    let problem = LinearProblem::from_observations(&model, &obs, &limits)?;
    let settings = ReductionSettings { nu_threshold: a.nu_threshold, ..ReductionSettings::default() };
    let red = match reduce(&problem, None, prior.as_deref(), &settings) {
        Ok(r) => r,
        Err(e @ StiffnessIdError::Unexcited { .. }) => {
            eprintln!("error: {e}");
            return Ok(ExitCode::from(2));
        }
        Err(e) => return Err(e.into()),
    };
    println!("{:4} {:>5} {:>5} {:>10} {:>6}  what", "step", "n", "rank", "cond", "s0");
    for s in &red.steps {
        println!(
            "{:4} {:>5} {:>5} {:>10.3e} {:>6.2}  {}",
            s.code, s.n_params, s.rank, s.condition_number, s.s0, s.title
        );
    }
    println!("\n{:32} {:>12} {:>10} {:>8} {:>12}", "parameter", "estimate", "std", "nu", "prior");
    let f = &red.fit;
    let prior_red = red.param.project(prior.as_deref().unwrap_or(&vec![0.0; problem.layout.len()]));
    for (i, p0) in prior_red.iter().enumerate() {
        println!(
            "{:32} {:>12.4e} {:>10.2e} {:>8.1} {:>12.4e}  {}",
            f.names[i], f.values[i], f.std[i], f.nu[i], p0, f.units[i]
        );
    }
    let ok = red.physical_problems.is_empty();
    if !ok {
        eprintln!("error: the estimate is not physical: {}", red.physical_problems.join("; "));
        let trusted: Vec<String> = (0..red.param.len())
            .filter(|&i| {
                !red.physical_problems.iter().any(|p| p.starts_with(f.names[i].split('.').next().unwrap_or("")))
            })
            .map(|i| f.names[i].clone())
            .collect();
        eprintln!("parameters that can be trusted: {}", trusted.join(", "));
    }
    if let Some(out) = &a.out {
        let mut prov = Provenance::new(json!({"model": a.model, "nu_threshold": a.nu_threshold}));
        prov.add_input(&a.measurements);
        let mut report = Report::new(&format!("Compliance identification of {}", a.model), prov);
        let mut sec = Section::new("reduction", "Model reduction");
        sec.table("Parameters after each step", &REDUCTION_HEADER, reduction_table(&red));
        let rows = (0..red.param.len())
            .map(|i| {
                vec![
                    f.names[i].clone(),
                    format!("{:.4e}", f.values[i]),
                    format!("{:.2e}", f.std[i]),
                    format!("{:.1}", f.nu[i]),
                    format!("{:.4e}", prior_red[i]),
                    f.units[i].clone(),
                ]
            })
            .collect();
        sec.table("Identified parameters", &["parameter", "estimate", "std", "nu", "design estimate", "unit"], rows);
        sec.status(ok, if ok { "physical".to_string() } else { red.physical_problems.join("; ") });
        report.sections.push(sec);
        let html = report.write(out)?;
        let params: BTreeMap<String, f64> = layout_values(&problem, &red);
        write_atomic(&out.join("parameters.json"), serde_json::to_string_pretty(&params)?.as_bytes())?;
        println!("wrote {}", html.display());
    }
    Ok(if ok { ExitCode::SUCCESS } else { ExitCode::from(2) })
}

fn layout_values(problem: &LinearProblem, red: &Reduction) -> BTreeMap<String, f64> {
    problem.layout.names().into_iter().zip(red.complete_values.iter().copied()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("ferrocal-stiff-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn simulate_then_identify_round_trip() {
        let dir = temp("rt");
        let code = run_simulate(&SimulateArgs { out: dir.clone(), seed: 3, configurations: 25 }).unwrap();
        assert_eq!(code, ExitCode::SUCCESS);
        let csv = dir.join("deflections.csv");
        let out = dir.join("id");
        let code = run_identify(&IdentifyArgs {
            measurements: csv.clone(),
            model: "kr270-like".into(),
            nu_threshold: 2.0,
            out: Some(out.clone()),
        })
        .unwrap();
        assert!(out.join("index.html").exists() && out.join("parameters.json").exists());
        let p: BTreeMap<String, f64> =
            serde_json::from_slice(&std::fs::read(out.join("parameters.json")).unwrap()).unwrap();
        let t: BTreeMap<String, f64> = serde_json::from_slice(&std::fs::read(dir.join("truth.json")).unwrap()).unwrap();
        // The identified model predicts the deflection under 250 kg like the truth does.
        let model = stiffness_preset("kr270-like").unwrap().unwrap();
        let names = model.layout().unwrap().names();
        let est: Vec<f64> = names.iter().map(|n| p[n]).collect();
        let tru: Vec<f64> = names.iter().map(|n| t[n]).collect();
        let mut sim = StiffSim::kr270(StiffSimConfig { seed: 99, ..StiffSimConfig::default() }).unwrap();
        let (mut err, mut size) = (0.0, 0.0);
        for q in sim.random_configurations(20) {
            let l = LoadCase::payload(250.0, [0.1, 0.0, 0.2]).loading(&model, &q).unwrap();
            let a = model.observation_matrix(&q, &l).unwrap();
            let (de, dt) =
                (&a * nalgebra::DVector::from_vec(est.clone()), &a * nalgebra::DVector::from_vec(tru.clone()));
            err += (de.rows(0, 3) - dt.rows(0, 3)).norm_squared();
            size += dt.rows(0, 3).norm_squared();
        }
        assert!(err.sqrt() < 0.05 * size.sqrt(), "prediction error {:.3e} of {:.3e} m", err.sqrt(), size.sqrt());
        assert_eq!(code, ExitCode::SUCCESS);
        // Any serial model runs (without design estimates); a parallel robot is refused.
        let ur5 = IdentifyArgs { measurements: csv.clone(), model: "ur5".into(), nu_threshold: 2.0, out: None };
        assert!(run_identify(&ur5).is_ok());
        let hex = IdentifyArgs { model: "hexapod".into(), ..ur5 };
        let e = run_identify(&hex).unwrap_err().to_string();
        assert!(e.contains("not a serial arm"), "{e}");
        // Unknown frame and a moment in N mm, with file and line.
        let text = std::fs::read_to_string(&csv).unwrap();
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        lines[2] = lines[2].replacen(",base,", ",gripper,", 1);
        std::fs::write(dir.join("bad.csv"), lines.join("\n")).unwrap();
        let model = stiffness_preset("kr270-like").unwrap().unwrap();
        let e = read_deflections(&dir.join("bad.csv"), &model, &WrenchLimits::default()).unwrap_err().to_string();
        assert!(e.contains("bad.csv:3, column 'frame'") && e.contains("gripper") && e.contains("flange"), "{e}");
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        let mut cells: Vec<String> = lines[5].split(',').map(String::from).collect();
        cells[8] = "9.81e3".into(); // fx_n of a 0 kg row: fine alone; moment next
        cells[11] = "250000".into(); // mx_nm typed in N mm
        lines[5] = cells.join(",");
        std::fs::write(dir.join("bad2.csv"), lines.join("\n")).unwrap();
        let e = read_deflections(&dir.join("bad2.csv"), &model, &WrenchLimits::default()).unwrap_err().to_string();
        assert!(e.contains("bad2.csv:6") && e.contains("N mm"), "{e}");
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        lines[4] = lines[4].replacen(",base,", ",base,x", 1);
        std::fs::write(dir.join("bad3.csv"), lines.join("\n")).unwrap();
        let e = read_deflections(&dir.join("bad3.csv"), &model, &WrenchLimits::default()).unwrap_err().to_string();
        assert!(e.contains("bad3.csv:5, column 'fx_n'") && e.contains("not a number"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn quick_study_writes_its_report() {
        let dir = temp("study");
        let code = run_study(&StudyArgs { out: dir.clone(), seed: 1, trials: 10, quick: true }).unwrap();
        let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
        assert!(html.contains("1592") && html.contains("0.73") && html.contains("<svg"), "report content");
        if std::env::var_os("FERROCAL_KEEP_STUDY").is_none() {
            let _ = std::fs::remove_dir_all(&dir);
        } else {
            eprintln!("study in {} (exit {code:?})", dir.display());
        }
        assert_eq!(code, ExitCode::SUCCESS);
    }

    #[test]
    fn demo_section_has_the_headline_table() {
        let t = std::time::Instant::now();
        let s = demo_section(1, true).unwrap();
        assert_eq!(s.id, "stiffness");
        assert!(s.status.as_ref().is_some_and(|(ok, _)| *ok), "{:?}", s.status);
        eprintln!("demo section: {:.1} s", t.elapsed().as_secs_f64());
    }
}
