//! The kinematic family's words and plots: the input an effect shows against, the statement of
//! a finding, the evidence (residuals against that input before and after).

use ferrocal_robot::JointKind;
use nalgebra::Vector3;

use super::family::Ctx;
use super::linear::Lin;
use super::screen::implied;
use super::{DiagnoseOptions, DiagnoseReport, InputStructure};
use crate::diagnose::report::{fmt_p, sig, Evidence};
use crate::diagnose::report::{CandidateRow, Verdict};
use crate::effects::EffectSpec;

pub(super) fn telling_input(spec: &EffectSpec, names: &[String]) -> String {
    let jn = |j: usize| names.get(j - 1).cloned().unwrap_or_default();
    match spec {
        EffectSpec::JointCompliance { joint } => format!("gravity_torque{joint} (load torque on {})", jn(*joint)),
        EffectSpec::Backlash { joint } => format!("dir{joint} (approach direction of {})", jn(*joint)),
        EffectSpec::JointScaleError { joint } | EffectSpec::PeriodicJointError { joint, .. } => {
            format!("q{joint} ({})", jn(*joint))
        }
        EffectSpec::ThermalExpansion { .. } => "temp_c".into(),
        EffectSpec::TimeDrift => "t_s".into(),
        EffectSpec::CoupledTransmission { driver, .. } => format!("q{driver} ({})", jn(*driver)),
        EffectSpec::AxisMisalignment { joint } => format!("q{joint} ({}), twice per revolution", jn(*joint)),
        EffectSpec::LinkCompliance { link } => {
            format!("bending moment on link {link} (between {} and {})", jn(*link), jn(link + 1))
        }
        EffectSpec::Custom(e) => e.telling_input(names),
    }
}

/// Plain-words statement of an accepted effect.
#[allow(clippy::too_many_arguments)]
pub(super) fn statement(
    spec: &EffectSpec,
    theta: &[f64],
    rel_std: f64,
    before: f64,
    after: f64,
    p: f64,
    m: usize,
    ctx: &Ctx,
    lin: &Lin,
) -> String {
    let t = theta.first().copied().unwrap_or(0.0);
    let pm = format!("(+-{:.0} %)", (rel_std * 100.0).max(1.0));
    let prismatic = spec.joint().is_some_and(|j| ctx.kinds.get(j - 1) == Some(&JointKind::Prismatic));
    let what = match spec {
        EffectSpec::Custom(e) => e.statement(theta),
        EffectSpec::JointCompliance { joint } => {
            let tmax = lin.tau.iter().map(|v| v[joint - 1].abs()).fold(0.0, f64::max);
            if prismatic {
                format!(
                    "joint {joint} gives way by {} m per N of load force {pm}, up to {} mm over these poses",
                    sig(t, 2),
                    sig(t * tmax * 1e3, 2)
                )
            } else {
                format!(
                    "joint {joint} deflects {} rad per N m of gravity torque {pm}, up to {} mrad over these poses",
                    sig(t, 2),
                    sig(t * tmax * 1e3, 2)
                )
            }
        }
        EffectSpec::Backlash { joint } => {
            let size = if prismatic {
                format!("{} mm", sig(t.abs() * 1e3, 2))
            } else {
                format!("{} mrad ({} deg)", sig(t.abs() * 1e3, 2), sig(t.abs().to_degrees(), 2))
            };
            if t >= 0.0 {
                format!(
                    "joint {joint} has {size} of backlash {pm}: where it stops depends on the direction it was approached from, the link lagging behind the motion"
                )
            } else {
                format!(
                    "joint {joint}'s position depends on the direction it was approached from by {size} {pm}, the link ahead of its reading in the direction of motion (it leads: a load that coasts onto the leading tooth flank as it decelerates, a controller that overshoots, or a dir column defined the other way round); modelled as a backlash of negative sign"
                )
            }
        }
        EffectSpec::JointScaleError { joint } => format!(
            "joint {joint}'s reading is off by a factor of {} (a scale error of {} ppm {pm})",
            format_args!("{:.6}", 1.0 + t),
            sig(t * 1e6, 3)
        ),
        EffectSpec::PeriodicJointError { joint, period_si } => {
            let a = t.hypot(theta.get(1).copied().unwrap_or(0.0));
            if prismatic {
                format!(
                    "joint {joint} has a periodic error of {} mm amplitude {pm} repeating every {} mm of travel",
                    sig(a * 1e3, 2),
                    sig(period_si * 1e3, 3)
                )
            } else {
                format!(
                    "joint {joint} has a periodic error of {} mrad amplitude {pm} repeating every {} deg of its angle ({} times per revolution)",
                    sig(a * 1e3, 2),
                    sig(period_si.to_degrees(), 3),
                    sig(std::f64::consts::TAU / period_si, 3)
                )
            }
        }
        EffectSpec::ThermalExpansion { reference_temp_c } => {
            let (lo, hi) = ctx
                .rows
                .iter()
                .filter_map(|r| r.temp_c)
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| (l.min(v), h.max(v)));
            format!(
                "lengths grow by {} ppm per K of temperature {pm} (the temperature ran from {:.1} to {:.1} C; reference {:.1} C)",
                sig(t * 1e6, 3),
                lo,
                hi,
                reference_temp_c
            )
        }
        EffectSpec::LinkCompliance { link } => {
            let mmax = lin.bend.iter().filter_map(|b| b.get(link - 1)).map(|(v, _)| v.norm()).fold(0.0, f64::max);
            format!(
                "link {link} (between joints {link} and {}) bends {} rad per N m of the load moment it carries across joint {}'s axis {pm}, up to {} mrad over these poses",
                link + 1,
                sig(t, 2),
                link + 1,
                sig(t * mmax * 1e3, 2)
            )
        }
        EffectSpec::CoupledTransmission { joint, driver } => {
            let unit = |j: usize| if ctx.kinds.get(j - 1) == Some(&JointKind::Prismatic) { "m" } else { "rad" };
            format!(
                "joint {joint}'s reading is off in proportion to joint {driver}'s {}: {} {} per {} {pm} (a coupled transmission)",
                if ctx.kinds.get(driver - 1) == Some(&JointKind::Prismatic) { "position" } else { "angle" },
                sig(t, 3),
                unit(*joint),
                unit(*driver)
            )
        }
        EffectSpec::AxisMisalignment { joint } => {
            let c = theta.get(1).copied().unwrap_or(0.0);
            format!(
                "joint {joint}'s axis wobbles as it turns: the links beyond it tilt by {} mrad {pm} about a direction normal to the axis that turns with the joint (twice per revolution as seen from the base; phase {:.0} deg), which no fixed axis placement reproduces",
                sig(t.hypot(c) * 1e3, 2),
                c.atan2(t).to_degrees()
            )
        }
        EffectSpec::TimeDrift => {
            let hours = ctx.rows.iter().filter_map(|r| r.t_s).fold(0.0f64, f64::max) / 3600.0;
            format!(
                "lengths drift by {} ppm per hour {pm} over the {:.1} h recording, as a machine warming up does",
                sig(t * 1e6, 3),
                hours
            )
        }
    };
    format!(
        "{what}; modelling it lowers the held-out RMS from {} to {} mm ({} after correcting for {m} candidates)",
        sig(before, 3),
        sig(after, 3),
        fmt_p(p)
    )
}

pub(super) fn evidence(
    finding: usize,
    spec: &EffectSpec,
    ctx: &Ctx,
    lin: &Lin,
    e0: &[Vector3<f64>],
    e1: &[Vector3<f64>],
    telling: &str,
) -> Evidence {
    let ds = nalgebra::DMatrix::from_column_slice(lin.ds.len(), 1, lin.ds.as_slice());
    let link_col;
    let (x, col, c, factor, y_label): (Vec<f64>, &nalgebra::DMatrix<f64>, usize, f64, String) = match spec {
        EffectSpec::LinkCompliance { link } => {
            // The effect's column per unit of bend: the implied bend angle per row.
            let moments: Vec<f64> = lin.bend.iter().map(|b| b.get(link - 1).map_or(0.0, |(v, _)| v.norm())).collect();
            let mut m = ctx.effect_columns(lin, spec).unwrap_or_else(|| nalgebra::DMatrix::zeros(3 * lin.n, 1));
            for (i, mi) in moments.iter().enumerate() {
                let scale = if *mi > 0.0 { *mi } else { 1.0 };
                for r in 0..3 {
                    m[(3 * i + r, 0)] /= scale;
                }
            }
            link_col = m;
            (moments, &link_col, 0, 1e3, format!("bend of link {link} implied by the held-out residual [mrad]"))
        }
        EffectSpec::AxisMisalignment { joint } => {
            // The tilt about the first wobble direction implied per row, against the joint angle.
            link_col = ctx.effect_columns(lin, spec).unwrap_or_else(|| nalgebra::DMatrix::zeros(3 * lin.n, 2));
            (
                ctx.rows.iter().map(|r| r.q[joint - 1].to_degrees()).collect(),
                &link_col,
                0,
                1e3,
                format!("tilt of joint {joint}'s axis about its first wobble direction implied by the held-out residual [mrad]"),
            )
        }
        EffectSpec::Custom(e) => {
            // The effect's first parameter implied per row, against its joint's angle (or the row).
            link_col = ctx
                .effect_columns(lin, spec)
                .unwrap_or_else(|| nalgebra::DMatrix::zeros(3 * lin.n, e.scales().len().max(1)));
            let x = match e.joint() {
                Some(j) => ctx.rows.iter().map(|r| r.q[j - 1].to_degrees()).collect(),
                None => (1..=ctx.rows.len()).map(|i| i as f64).collect(),
            };
            let first = e.parameters(&ctx.kinds).first().map_or_else(String::new, |(n, _)| n.clone());
            (x, &link_col, 0, 1.0, format!("{first} implied by the held-out residual"))
        }
        EffectSpec::ThermalExpansion { .. } => (
            ctx.rows.iter().map(|r| r.temp_c.unwrap_or(f64::NAN)).collect(),
            &ds,
            0,
            1e6,
            "implied relative length change [ppm]".into(),
        ),
        EffectSpec::TimeDrift => (
            ctx.rows.iter().map(|r| r.t_s.unwrap_or(f64::NAN) / 3600.0).collect(),
            &ds,
            0,
            1e6,
            "implied relative length change [ppm]".into(),
        ),
        _ => {
            let j = spec.joint().unwrap_or(1) - 1;
            let x = match spec {
                EffectSpec::JointCompliance { .. } => lin.tau.iter().map(|t| t[j]).collect(),
                EffectSpec::Backlash { .. } => ctx
                    .rows
                    .iter()
                    .map(|r| r.dir.as_ref().and_then(|d| d.get(j)).copied().unwrap_or(0) as f64)
                    .collect(),
                EffectSpec::PeriodicJointError { period_si, .. } => {
                    ctx.rows.iter().map(|r| (r.q[j] / period_si).rem_euclid(1.0) * 360.0).collect()
                }
                EffectSpec::CoupledTransmission { driver, .. } => {
                    ctx.rows.iter().map(|r| r.q[driver - 1].to_degrees()).collect()
                }
                _ => ctx.rows.iter().map(|r| r.q[j].to_degrees()).collect(),
            };
            let unit = if ctx.kinds[j] == JointKind::Prismatic { "mm" } else { "mrad" };
            (x, &lin.dq, j, 1e3, format!("joint {} error implied by the held-out residual [{unit}]", j + 1))
        }
    };
    let (b, _) = implied(col, c, e0);
    let (a, _) = implied(col, c, e1);
    let x_label = match spec {
        EffectSpec::JointCompliance { .. } => format!("{telling} [N m]"),
        EffectSpec::TimeDrift => "time [h]".into(),
        EffectSpec::ThermalExpansion { .. } => "temperature [C]".into(),
        EffectSpec::LinkCompliance { .. } => format!("{telling} [N m]"),
        EffectSpec::Backlash { .. } => telling.to_string(),
        EffectSpec::Custom(e) if e.joint().is_none() => telling.to_string(),
        EffectSpec::PeriodicJointError { period_si, .. } => {
            format!("{telling} modulo its period of {} deg (phase in the cycle) [deg]", sig(period_si.to_degrees(), 3))
        }
        _ => format!("{telling} [deg]"),
    };
    Evidence {
        finding,
        x_label,
        y_label,
        x,
        before: b.iter().map(|v| v * factor).collect(),
        after: a.iter().map(|v| v * factor).collect(),
    }
}

/// The kinematic verdict of a candidate row in words (`m`: candidates of the step).
pub(super) fn verdict_words(row: &CandidateRow, m: usize, opts: &DiagnoseOptions) -> String {
    match &row.verdict {
        Verdict::Pending => "not decided (not applicable when fitted on all the data)".into(),
        Verdict::Unscored(why) => why.clone(),
        Verdict::TooSmall => format!(
            "held-out improvement {:.2} % below {:.1} %",
            row.improvement * 100.0,
            opts.min_improvement * 100.0
        ),
        Verdict::NotSignificant => {
            format!("not significant ({} after correcting for {m} candidates)", fmt_p(row.p_corrected))
        }
        Verdict::NotBest => "not the best candidate".into(),
        Verdict::NotExamined => "significant, not examined further this step".into(),
        Verdict::Overlap(sa) => format!(
            "rejected: nearly a combination of geometric parameters (sine of the angle to the geometric Jacobian {:.3}, variance inflation {:.0})",
            sa,
            1.0 / (sa * sa).max(1e-300)
        ),
        Verdict::Implausible(why) => format!("rejected as physically implausible: {why}"),
        Verdict::Unstable(why) => format!("rejected as unstable across the folds: {why}"),
        Verdict::RefitFailed(e) => format!("rejected: the full refit failed ({e})"),
        Verdict::NotConfirmed { improvement, p_corrected } => format!(
            "rejected by the full refits: held-out improvement {:.2} %, {} after correcting for {m} candidates",
            improvement * 100.0,
            fmt_p(*p_corrected)
        ),
        Verdict::Explained { by, p_added, p_rival_added } => format!(
            "rejected: {by} explains it (fitted together, {by} still improves the held-out fit, {}, while this adds nothing to it, {})",
            fmt_p(*p_rival_added),
            fmt_p(*p_added)
        ),
        Verdict::NotSeparable { with, p_added, p_rival_added } => format!(
            "not claimed: the held-out data cannot tell it from {with} (fitted together, neither adds to the other: {} and {})",
            fmt_p(*p_added),
            fmt_p(*p_rival_added)
        ),
        Verdict::Accepted { p_corrected } => {
            format!("ACCEPTED ({} after correcting for {m} candidates)", fmt_p(*p_corrected))
        }
    }
}

/// The screen's p-value (corrected) below which structure is called strong in the summary.
pub const STRONG_STRUCTURE_P: f64 = 1e-6;

/// The report's top sentence: the findings, or why nothing was claimed; and whether
/// structure remains (see [`DiagnoseReport::summary`]).
pub(super) fn summary(report: &DiagnoseReport, opts: &DiagnoseOptions) -> String {
    let strongest = |tests: &[InputStructure]| -> Option<InputStructure> {
        tests.iter().filter(|t| t.significant).min_by(|a, b| a.p_corrected.total_cmp(&b.p_corrected)).cloned()
    };
    let inputs = |tests: &[InputStructure]| -> String {
        let mut v: Vec<String> = Vec::new();
        for t in tests.iter().filter(|t| t.significant && t.p_corrected < STRONG_STRUCTURE_P) {
            if !v.contains(&t.input) {
                v.push(t.input.clone());
            }
        }
        v.truncate(6);
        v.join(", ")
    };
    let unit = "mm";
    let mut out = if report.findings.is_empty() {
        let strong = strongest(&report.screening_nominal).filter(|t| t.p_corrected < STRONG_STRUCTURE_P);
        match strong {
            None => "No finding: nothing beyond the geometric model is supported by the held-out data, and the residuals show no strong structure.".to_string(),
            Some(t) => {
                // The best significant candidate of the first step and what happened to it.
                let best = report.steps.first().and_then(|s| {
                    s.candidates
                        .iter()
                        .filter(|c| c.p_corrected < opts.alpha && c.improvement >= opts.min_improvement)
                        .max_by(|a, b| a.improvement.total_cmp(&b.improvement))
                });
                let why = match best {
                    Some(c) => format!(
                        "the best candidate, {} ({:.0} % better held out, {}), was {}",
                        c.label,
                        c.improvement * 100.0,
                        fmt_p(c.p_corrected),
                        c.verdict.trim_start_matches("rejected").trim_start_matches(':').trim_start()
                    ),
                    None => "no candidate effect of the list improves the held-out fit significantly: the physics behind it is not among the candidates (or needs several effects at once)".to_string(),
                };
                format!(
                    "No finding, although the held-out residuals depend strongly on {} ({} for {} against {}): {why}.",
                    inputs(&report.screening_nominal),
                    fmt_p(t.p_corrected),
                    t.quantity,
                    t.input
                )
            }
        }
    } else {
        let names: Vec<String> = report
            .findings
            .iter()
            .map(|f| {
                let on = if f.joints.is_empty() {
                    String::new()
                } else {
                    format!(
                        " on joint{} {}",
                        if f.joints.len() > 1 { "s" } else { "" },
                        f.joints.iter().map(|j| j.to_string()).collect::<Vec<_>>().join(", ")
                    )
                };
                let unusual =
                    if f.statement.starts_with("UNUSUAL") { " (unusually large: see its statement)" } else { "" };
                format!("{}{on}{unusual}", f.effect)
            })
            .collect();
        format!(
            "{} finding{}: {}; held-out RMS {} -> {} {unit}.",
            report.findings.len(),
            if report.findings.len() == 1 { "" } else { "s" },
            names.join(", "),
            sig(report.nominal.heldout_rms_mm, 3),
            sig(report.final_fit.heldout_rms_mm, 3)
        )
    };
    if !report.findings.is_empty() {
        if let Some(t) = strongest(&report.screening_final).filter(|t| t.p_corrected < STRONG_STRUCTURE_P) {
            out.push_str(&format!(
                " Structure remains against {} ({} for {}): more physics than was found, or an effect of another form.",
                inputs(&report.screening_final),
                fmt_p(t.p_corrected),
                t.quantity
            ));
        }
    }
    out
}
