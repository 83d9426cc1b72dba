//! The verdicts of the model commands (`robot info/fk/ik/check`, `dynamics identify`,
//! `stiffness identify`, `handeye study`, the simulators): which numbers each holds against
//! which limit of [`Thresholds`], and the next step in words (`docs/verdicts.md`).

use super::super::{Check, Status, Thresholds, Verdict};

/// `robot info`: the model loaded with its joints and parameters; a warning names the joints
/// without limits (`unlimited`), which `robot fk`, `plan` and the safety checks cannot hold to
/// a range.
pub fn robot_info(joints: usize, parameters: usize, unlimited: &[String]) -> Verdict {
    let checks = vec![
        Check::at_least(
            "robot.joints",
            &format!("model loaded ({parameters} parameters), joints"),
            "",
            joints as f64,
            1.0,
            1.0,
        ),
        Check::flag(
            "robot.unlimited_joints",
            &format!("joints without limits: {}", unlimited.join(", ")),
            "every joint has limits",
            !unlimited.is_empty(),
        ),
    ];
    Verdict::with_next(checks, |c| {
        match c {
        None => "use the model: ferrocal robot fk / ik, or --robot of calibrate and plan".into(),
        Some(_) => "give the joints their travel (URDF <limit lower upper>, or the model file's limits) if the robot has one; a joint that turns endlessly may stay as it is".into(),
    }
    })
}

/// `robot fk`: how close the joints are to their limits. `margins` holds, for every joint with
/// finite limits, its name and its distance from the nearer limit as a fraction of its range
/// (joints outside their limits are refused before).
pub fn robot_fk(t: &Thresholds, joints: usize, margins: &[(String, f64)]) -> Verdict {
    let mut checks = vec![Check::flag(
        "robot.unlimited_joints",
        &format!("{} of {joints} joints without limits (not checked)", joints - margins.len()),
        &format!("{joints} joints within their limits"),
        margins.len() < joints,
    )];
    if let Some((name, m)) = margins.iter().min_by(|a, b| a.1.total_cmp(&b.1)) {
        checks.push(Check::at_least(
            "robot.limit_margin",
            &format!("smallest distance from a limit ({name}), fraction of its range"),
            "",
            *m,
            t.robot.limit_margin_warn,
            f64::NEG_INFINITY,
        ));
    }
    Verdict::with_next(checks, |c| {
        match c.map(|c| c.name.as_str()) {
        None => "use the pose; ferrocal robot ik --pose <x,y,z,rx,ry,rz> goes back to joint values".into(),
        Some("robot.limit_margin") => "the configuration is at the end of a joint's travel: the controller's soft limits may stop it there; choose joint values further inside".into(),
        _ => "the joints without limits were not checked: give them limits in the model if the robot has them (ferrocal robot info lists them)".into(),
    }
    })
}

/// The outcome of `robot ik`.
#[derive(Clone, Debug, PartialEq)]
pub enum IkOutcome {
    /// A solution, with the distance (mm) and angle (deg) of its tool pose from the target.
    Solved {
        /// Position residual, mm.
        position_mm: f64,
        /// Orientation residual, degrees.
        orientation_deg: f64,
    },
    /// No solution: why, in words (did not converge, unreachable, outside the joint limits).
    NoSolution(String),
}

/// `robot ik`: a solution whose tool pose is at the target within the limits; no solution fails.
pub fn robot_ik(t: &Thresholds, outcome: &IkOutcome) -> Verdict {
    let l = &t.robot;
    let checks = match outcome {
        IkOutcome::Solved { position_mm, orientation_deg } => vec![
            Check::at_most(
                "robot.ik_position_mm",
                "solution's tool position from the target",
                "mm",
                *position_mm,
                l.ik_position_mm_fail,
                l.ik_position_mm_fail,
            ),
            Check::at_most(
                "robot.ik_orientation_deg",
                "solution's tool orientation from the target",
                "deg",
                *orientation_deg,
                l.ik_orientation_deg_fail,
                l.ik_orientation_deg_fail,
            ),
        ],
        IkOutcome::NoSolution(why) => vec![Check {
            name: "robot.ik_solution".into(),
            value: 0.0,
            limit: 1.0,
            status: Status::Fail,
            what: format!("no solution: {why} (fail)"),
        }],
    };
    Verdict::with_next(checks, |c| {
        match c {
        None => "check the joint values with ferrocal robot check --safety <file> --joints <them> before moving there".into(),
        Some(_) => "check that the pose is within the robot's reach (mm, rotation vector in degrees), or give another start with --seed (another configuration)".into(),
    }
    })
}

/// `robot check`: the safety result itself; `violations` counts the unsafe findings (joint
/// values and the move). The limit is the safety file's, not a threshold.
pub fn robot_check(violations: usize) -> Verdict {
    let checks = vec![Check::at_most(
        "robot.safety_violations",
        "safety violations (the safety file's limits)",
        "",
        violations as f64,
        0.0,
        0.0,
    )];
    Verdict::with_next(checks, |c| {
        match c {
        None => "the joint values (and the move) are safe under this configuration: send them to the robot".into(),
        Some(_) => "do not send these joint values: read the unsafe lines above and choose others (or a move through another path)".into(),
    }
    })
}

/// The figures of a linear identification (`dynamics identify`, `identify-static`) that its
/// verdict holds against the limits.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearFitFigures {
    /// Parameters the data do not determine (infinite standard deviation or dropped), by name.
    pub undetermined: Vec<String>,
    /// Condition number of the weighted, column-scaled regressor.
    pub condition_number: f64,
    /// Relative standard deviation of the mass, when the model has one.
    pub mass_relative_std: Option<f64>,
    /// The a-posteriori variance factor when the weights are the measured noise (else `None`:
    /// with unit weights s0 is the residual RMS in newtons, which has no limit).
    pub s0_weighted: Option<f64>,
}

impl LinearFitFigures {
    /// The figures of `fit`; `weighted` when its weights are the noise measured from repeated
    /// periods.
    pub fn of(fit: &ferrocal_lsq::linear::LinearFit, weighted: bool) -> Self {
        let undetermined = (0..fit.names.len())
            .filter(|&i| !fit.std[i].is_finite() || fit.dropped.contains(&i))
            .map(|i| fit.names[i].clone())
            .collect();
        let mass_relative_std = fit.get("m_kg").map(|(v, s)| s / v.abs());
        Self {
            undetermined,
            condition_number: fit.condition_number,
            mass_relative_std,
            s0_weighted: weighted.then_some(fit.s0),
        }
    }
}

/// `dynamics identify` and `identify-static`: every parameter determined, the regressor's
/// conditioning, the mass's precision and, with measured noise, the fit against that noise.
pub fn dynamics_identify(t: &Thresholds, f: &LinearFitFigures) -> Verdict {
    let l = &t.dynamics;
    let mut checks = vec![
        Check::at_most(
            "dynamics.undetermined",
            &if f.undetermined.is_empty() {
                "parameters not determined".to_string()
            } else {
                format!("parameters not determined ({})", f.undetermined.join(", "))
            },
            "",
            f.undetermined.len() as f64,
            l.undetermined_warn,
            f64::INFINITY,
        ),
        Check::at_most(
            "dynamics.condition_number",
            "condition number",
            "",
            f.condition_number,
            l.condition_number_warn,
            f64::INFINITY,
        ),
    ];
    if let Some(r) = f.mass_relative_std {
        checks.push(Check::at_most(
            "dynamics.mass_relative_std",
            "mass relative std",
            "",
            r,
            l.mass_relative_std_warn,
            f64::INFINITY,
        ));
    }
    if let Some(s0) = f.s0_weighted {
        checks.push(Check::at_most("dynamics.s0", "s0 against the measured noise", "", s0, l.s0_warn, f64::INFINITY));
    }
    Verdict::with_next(checks, |c| {
        match c.map(|c| c.name.as_str()) {
        None => "use the parameters (the JSON with --json); identify a second recording to confirm them".into(),
        Some("dynamics.s0") => "the residuals exceed the measured noise: try the next model up (--model), or look for effects the model leaves out (cross-talk, friction)".into(),
        _ => "the recording excites the parameters poorly: record a richer excitation (ferrocal dynamics study designs one) or more poses spread over the workspace, or identify a smaller model".into(),
    }
    })
}

/// `stiffness identify`: a physical estimate (`physical_problems` empty; else a failure, exit
/// status 2), and the fit's s0 against the table's stated noise.
pub fn stiffness_identify(t: &Thresholds, physical_problems: &[String], s0: f64, kept: usize) -> Verdict {
    let checks = vec![
        Check::at_most(
            "stiffness.physical_problems",
            &if physical_problems.is_empty() {
                format!("{kept} parameters kept; estimates no spring can have")
            } else {
                format!("estimates no spring can have ({})", physical_problems.join("; "))
            },
            "",
            physical_problems.len() as f64,
            0.0,
            0.0,
        ),
        Check::at_most("stiffness.s0", "s0 against the table's sigma", "", s0, t.stiffness.s0_warn, f64::INFINITY),
    ];
    Verdict::with_next(checks, |c| {
        match c.map(|c| c.name.as_str()) {
        None => "use the parameters (parameters.json with --out) for compensation".into(),
        Some("stiffness.s0") => "the deflections scatter more than the table's sigma_mm says: check the stated noise and the measurement, or look for effects the model leaves out".into(),
        _ => "use only the trusted parameters (stderr lists them); measure more configurations with loads in more directions and identify again".into(),
    }
    })
}

/// `stiffness identify` when the loads leave parameters unexcited: no estimate at all.
pub fn stiffness_unexcited(why: &str) -> Verdict {
    let checks = vec![Check {
        name: "stiffness.unexcited".into(),
        value: 1.0,
        limit: 0.0,
        status: Status::Fail,
        what: format!("no estimate: {why} (fail)"),
    }];
    Verdict::new(
        checks,
        "measure configurations and loads that move every joint and load every link, then identify again",
    )
}

/// One mount's figures of `handeye study`.
#[derive(Clone, Debug, PartialEq)]
pub struct CoverageFigures {
    /// The mount's name.
    pub mount: String,
    /// Simulations that gave an estimate.
    pub runs: usize,
    /// Simulations whose calibration failed.
    pub failed: usize,
    /// 3-sigma coverage of the translation coordinates (fraction).
    pub translation: f64,
    /// 3-sigma coverage of the rotation coordinates.
    pub rotation: f64,
}

/// `handeye study`: the smallest 3-sigma coverage over the mounts and coordinates, and the
/// simulations that failed.
pub fn handeye_study(t: &Thresholds, rows: &[CoverageFigures]) -> Verdict {
    let l = &t.study;
    let mut worst = (f64::INFINITY, String::new());
    for r in rows {
        for (v, what) in [(r.translation, "translation"), (r.rotation, "rotation")] {
            if v < worst.0 || !v.is_finite() {
                worst = (v, format!("{} {what}", r.mount));
            }
        }
    }
    let runs: usize = rows.iter().map(|r| r.runs).sum();
    let failed: usize = rows.iter().map(|r| r.failed).sum();
    let checks = vec![
        Check::at_least(
            "study.coverage_3sigma",
            &format!("smallest 3-sigma coverage ({}, {runs} runs)", worst.1),
            "",
            if runs == 0 { f64::NAN } else { worst.0 },
            l.coverage_3sigma_warn,
            l.coverage_3sigma_fail,
        ),
        Check::at_most(
            "study.failed_runs",
            "simulations that failed",
            "",
            failed as f64,
            l.failed_runs_warn,
            f64::INFINITY,
        ),
    ];
    Verdict::with_next(checks, |c| {
        match c.map(|c| c.name.as_str()) {
        None => "the stated standard deviations can be trusted: use them with ferrocal handeye's results".into(),
        Some("study.failed_runs") => "read why the simulations failed (stderr), then run the study again".into(),
        _ => "the stated standard deviations are too small: run more simulations (--simulations) to confirm, then treat handeye's std with caution".into(),
    }
    })
}

/// The simulators (`simulate`, `dynamics simulate`, `stiffness simulate`, `handeye simulate`):
/// what was written, counted (`section` names the checks, `<section>.<what>`); a count of 0 fails.
pub fn simulated(section: &str, counts: &[(&str, usize)], next: &str) -> Verdict {
    let checks = counts
        .iter()
        .map(|(what, n)| {
            let key = what.split_whitespace().last().unwrap_or(what);
            Check::at_least(&format!("{section}.{key}"), &format!("{what} written"), "", *n as f64, 1.0, 1.0)
        })
        .collect();
    Verdict::with_next(checks, |c| match c {
        None => next.to_string(),
        Some(_) => "nothing was simulated: check the sizes given (counts, periods, poses)".into(),
    })
}
