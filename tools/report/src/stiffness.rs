//! Report of `ferrocal stiffness`: elastostatic identification of serial robots by the virtual
//! joint method with practical identifiability (Klimchik et al. 2015): the source's one-link and
//! 6-DOF studies on the simulator beside the source's numbers, and the identification's report,
//! terminal table and parameters.
//! The checks are `ferrocal_datasets::stiffsim::checks`.

use std::collections::BTreeMap;
use std::path::Path;

use crate::error::Result;
use ferrocal_calib::check::Check;
use ferrocal_calib::stiffness::onelink::SOURCE_NU;
use ferrocal_calib::stiffness::problem::LinearProblem;
use ferrocal_calib::stiffness::reduce::Reduction;
use ferrocal_datasets::stiffsim::checks;
use ferrocal_datasets::stiffsim::study::{arm_study, one_link_study, ArmStudy, ArmStudySettings, OneLinkStudy};
use serde_json::json;

use crate::plot::{self, Series};
use crate::report::{Provenance, Report, Section};

fn um(v: f64) -> String {
    format!("{:.1}", v * 1e6)
}

fn mm(v: f64) -> String {
    format!("{:.3}", v * 1e3)
}

/// The source's parameter counts per step (M4 and M6 not stated).
const SOURCE_COUNTS: [(&str, &str); 7] =
    [("M0", "258"), ("M1", "153"), ("M2", "62"), ("M3", "56"), ("M4", "-"), ("M5", "26"), ("M6", "-")];

/// The section of the one-link study.
pub fn section_one_link(st: &OneLinkStudy) -> Section {
    let mut sec = Section::new("one-link", "One Orthoglide link: parameter-to-noise ratios and the naive estimate");
    sec.text(format!(
        "The source's compliance matrix, noise 25 um / 0.25 mrad, {} loads of +-10 N / +-10 N m along each axis (W^T W = 10^4 I, so every entry of row i has the standard deviation sigma_i / 100). Ratios from the covariance (A^T S^-1 A)^-1 of the complete 36-parameter model at the true values.",
        st.n_loads
    ));
    let mut rows = Vec::new();
    for (name, source) in SOURCE_NU {
        let Some(e) = st.ratios.iter().find(|e| e.name == name) else { continue };
        let ok = checks::nu_agrees(e.nu, source);
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
    let unusable = checks::unusable_entries(st);
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
    sec.check(checks::one_link(st));
    sec.data = json!({"ratios": st.ratios, "study": st});
    sec
}

/// The reduction table: every step with its count beside the source's, rank, conditioning,
/// s0, validation errors and cost.
pub fn reduction_table(red: &Reduction) -> Vec<Vec<String>> {
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

/// The header of [`reduction_table`].
pub const REDUCTION_HEADER: [&str; 11] = [
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

/// The sections of the 6-DOF study: the reduction M0 to M6 and the compensation.
pub fn sections_arm(s: &ArmStudy) -> Vec<Section> {
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
    sec.check(checks::arm(s));
    sec.data = json!({"compensation": s.compensation, "task_force_n": s.task_force_n});
    out.push(sec);
    out
}

/// The study's report: the one-link study of `trials` experiments and the 6-DOF study (small
/// when `quick`).
pub fn study_report(seed: u64, trials: usize, quick: bool) -> Result<Report> {
    if trials == 0 {
        crate::bail!("--trials must be at least 1");
    }
    let one = one_link_study(trials, seed)?;
    let settings = if quick { ArmStudySettings::quick(seed) } else { ArmStudySettings::full(seed) };
    let arm = arm_study(&settings)?;
    let prov = Provenance::new(json!({"seed": seed, "trials": trials, "quick": quick}));
    let mut report =
        Report::new("Elastostatic identification with practical identifiability (Klimchik et al. 2015)", prov);
    report.sections.push(section_one_link(&one));
    report.sections.extend(sections_arm(&arm));
    Ok(report)
}

/// The section of an identification (`ferrocal stiffness identify --out`): the reduction table
/// and the identified parameters beside the design estimates `prior` (reduced parameters),
/// passing when the estimate is physical.
pub fn identify_section(red: &Reduction, prior: &[f64]) -> Section {
    let f = &red.fit;
    let mut sec = Section::new("reduction", "Model reduction");
    sec.table("Parameters after each step", &REDUCTION_HEADER, reduction_table(red));
    let rows = (0..red.param.len())
        .map(|i| {
            vec![
                f.names[i].clone(),
                format!("{:.4e}", f.values[i]),
                format!("{:.2e}", f.std[i]),
                format!("{:.1}", f.nu[i]),
                format!("{:.4e}", prior[i]),
                f.units[i].clone(),
            ]
        })
        .collect();
    sec.table("Identified parameters", &["parameter", "estimate", "std", "nu", "design estimate", "unit"], rows);
    let ok = red.physical_problems.is_empty();
    sec.check(Check::from_bool(
        "physical estimate",
        ok,
        if ok { "physical".to_string() } else { red.physical_problems.join("; ") },
    ));
    sec
}

/// The terminal table of an identification: every reduction step, then every identified
/// parameter beside its design estimate `prior` (reduced parameters).
pub fn identify_lines(red: &Reduction, prior: &[f64]) -> Vec<String> {
    let mut out = vec![format!("{:4} {:>5} {:>5} {:>10} {:>6}  what", "step", "n", "rank", "cond", "s0")];
    for s in &red.steps {
        out.push(format!(
            "{:4} {:>5} {:>5} {:>10.3e} {:>6.2}  {}",
            s.code, s.n_params, s.rank, s.condition_number, s.s0, s.title
        ));
    }
    out.push(format!("\n{:32} {:>12} {:>10} {:>8} {:>12}", "parameter", "estimate", "std", "nu", "prior"));
    let f = &red.fit;
    for (i, p0) in prior.iter().enumerate() {
        out.push(format!(
            "{:32} {:>12.4e} {:>10.2e} {:>8.1} {:>12.4e}  {}",
            f.names[i], f.values[i], f.std[i], f.nu[i], p0, f.units[i]
        ));
    }
    out
}

/// The identified parameters that can be trusted when the estimate is not physical: those of
/// the groups no physical problem names.
pub fn trusted_parameters(red: &Reduction) -> Vec<String> {
    let f = &red.fit;
    (0..red.param.len())
        .filter(|&i| !red.physical_problems.iter().any(|p| p.starts_with(f.names[i].split('.').next().unwrap_or(""))))
        .map(|i| f.names[i].clone())
        .collect()
}

/// The report of `ferrocal stiffness identify --out` of the model named `model` from the table
/// `measurements` with the threshold `nu_threshold`: the [`identify_section`].
pub fn identify_report(model: &str, nu_threshold: f64, measurements: &Path, red: &Reduction, prior: &[f64]) -> Report {
    let mut prov = Provenance::new(json!({"model": model, "nu_threshold": nu_threshold}));
    prov.add_input(measurements);
    Report::of(&format!("Compliance identification of {model}"), prov, vec![identify_section(red, prior)])
}

/// Every parameter of the complete model (`problem`'s layout) by name with its value after the
/// reduction `red`: the `parameters.json` of `ferrocal stiffness identify --out`.
pub fn complete_parameters(problem: &LinearProblem, red: &Reduction) -> BTreeMap<String, f64> {
    problem.layout.names().into_iter().zip(red.complete_values.iter().copied()).collect()
}

/// The demo's section: the one-link ratios and the 6-DOF reduction and compensation beside the
/// source's numbers (a second or two in release).
pub fn demo_section(seed: u64, quick: bool) -> Result<Section> {
    let one = one_link_study(if quick { 10 } else { 40 }, seed)?;
    let arm = arm_study(&ArmStudySettings::quick(seed))?;
    let mut sec = Section::new("stiffness", "Elastostatic identification: practical identifiability (simulated)");
    let max_dev = checks::max_nu_deviation(&one);
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
    sec.check(checks::demo(&one, &arm));
    sec.text("Full study: `ferrocal stiffness study --out DIR`; method and file format: docs/stiffness.md.");
    sec.data = json!({"one_link_max_ratio_deviation": max_dev, "counts": counts, "compensation": arm.compensation});
    Ok(sec)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quick_study_writes_its_report() {
        let dir = std::env::temp_dir().join(format!("ferrocal-report-stiff-{}", std::process::id()));
        let report = study_report(1, 10, true).unwrap();
        report.write(&dir).unwrap();
        let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
        assert!(html.contains("1592") && html.contains("0.73") && html.contains("<svg"), "report content");
        let _ = std::fs::remove_dir_all(&dir);
        assert!(!report.failed());
        assert!(study_report(1, 0, true).is_err());
    }

    #[test]
    fn demo_section_has_the_headline_table() {
        let s = demo_section(1, true).unwrap();
        assert_eq!(s.id, "stiffness");
        assert!(s.status.as_ref().is_some_and(Check::passed), "{:?}", s.status);
    }
}
