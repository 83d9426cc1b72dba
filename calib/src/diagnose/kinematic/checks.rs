//! The kinematic family's checks of an examined candidate: its parameters in named units,
//! physical plausibility of sign and size, stability over the folds.

use std::collections::BTreeMap;

use ferrocal_robot::JointKind;

use super::family::{Ctx, LinScore};
use super::linear::Lin;
use super::DiagnoseOptions;
use crate::diagnose::report::sig;
use crate::effects::EffectSpec;

/// Parameters with unit-carrying names (angles in rad and deg).
pub(super) fn parameter_map(spec: &EffectSpec, theta: &[f64], kinds: &[JointKind]) -> BTreeMap<String, f64> {
    let mut m = BTreeMap::new();
    let prismatic = spec.joint().is_some_and(|j| kinds.get(j - 1) == Some(&JointKind::Prismatic));
    let t0 = theta.first().copied().unwrap_or(f64::NAN);
    let angle = |m: &mut BTreeMap<String, f64>, base: &str, v: f64| {
        if prismatic {
            m.insert(format!("{base}_m"), v);
            m.insert(format!("{base}_mm"), v * 1e3);
        } else {
            m.insert(format!("{base}_rad"), v);
            m.insert(format!("{base}_deg"), v.to_degrees());
        }
    };
    match spec {
        EffectSpec::JointCompliance { .. } => {
            m.insert(if prismatic { "compliance_m_per_n" } else { "compliance_rad_per_nm" }.into(), t0);
        }
        EffectSpec::Backlash { .. } => angle(&mut m, "backlash", t0),
        EffectSpec::JointScaleError { .. } => {
            m.insert("scale_error".into(), t0);
        }
        EffectSpec::PeriodicJointError { period_si, .. } => {
            let a = theta.first().copied().unwrap_or(0.0);
            let b = theta.get(1).copied().unwrap_or(0.0);
            angle(&mut m, "amplitude", a.hypot(b));
            angle(&mut m, "period", *period_si);
            m.insert("phase_rad".into(), b.atan2(a));
            m.insert("phase_deg".into(), b.atan2(a).to_degrees());
            m.insert("sin_coefficient".into(), a);
            m.insert("cos_coefficient".into(), b);
            if !prismatic {
                m.insert("cycles_per_revolution".into(), std::f64::consts::TAU / period_si);
            }
        }
        EffectSpec::ThermalExpansion { reference_temp_c } => {
            m.insert("alpha_per_k".into(), t0);
            m.insert("reference_temp_c".into(), *reference_temp_c);
        }
        EffectSpec::TimeDrift => {
            m.insert("drift_per_hour".into(), t0);
        }
        EffectSpec::LinkCompliance { .. } => {
            m.insert("compliance_rad_per_nm".into(), t0);
        }
        EffectSpec::CoupledTransmission { .. } => {
            m.insert("coupling".into(), t0);
        }
        EffectSpec::AxisMisalignment { .. } => {
            let c = theta.get(1).copied().unwrap_or(0.0);
            m.insert("wobble_x_rad".into(), t0);
            m.insert("wobble_y_rad".into(), c);
            m.insert("tilt_amplitude_rad".into(), t0.hypot(c));
            m.insert("tilt_amplitude_mrad".into(), t0.hypot(c) * 1e3);
            m.insert("phase_deg".into(), c.atan2(t0).to_degrees());
        }
        EffectSpec::Custom(e) => m = e.parameter_map(theta, kinds),
    }
    m
}

/// How a fitted effect's sign and size compare with what machines do.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Assessment {
    /// `Err`: no machine does this (a linear model stretched past its meaning): vetoed.
    pub(super) possible: Result<(), String>,
    /// Outside the typical range of industrial arms, or of an unusual sign, in words: claimed
    /// only on strong held-out evidence, and then reported as such.
    pub(super) unusual: Option<String>,
}

impl Default for Assessment {
    fn default() -> Self {
        Self { possible: Ok(()), unusual: None }
    }
}

/// (d): sign and size, as evidence. [`Bounds`](super::Bounds) holds the typical ranges (beyond
/// them an effect is unusual, not impossible: lightweight and torque-controlled arms sag tens
/// of milliradians, links can lead their motors, carbon fibre shrinks when warmed) and the
/// limits past which the linear model of the effect no longer means anything.
pub(super) fn assess(spec: &EffectSpec, theta: &[f64], ctx: &Ctx, lin: &Lin, opts: &DiagnoseOptions) -> Assessment {
    if let EffectSpec::Custom(e) = spec {
        let p = e.plausibility(theta);
        return Assessment { possible: p.impossible.map_or(Ok(()), Err), unusual: p.unusual };
    }
    let b = &opts.bounds;
    let t = theta.first().copied().unwrap_or(0.0);
    let prismatic = spec.joint().is_some_and(|j| ctx.kinds.get(j - 1) == Some(&JointKind::Prismatic));
    let (unit, scale) = if prismatic { ("mm", 1e3) } else { ("mrad", 1e3) };
    let mut out = Assessment::default();
    let mut unusual: Vec<String> = Vec::new();
    // A size against its typical and its impossible limit.
    let mut size = |what: String, value: f64, typical: f64, limit: f64, u: &str, k: f64, hint: &str| {
        if value > limit {
            out.possible = Err(format!(
                "{what} of {} {u} is beyond {} {u}, where a linear model of this effect no longer describes a machine (check the model or the units)",
                sig(value * k, 2),
                sig(limit * k, 2)
            ));
        } else if value > typical {
            unusual.push(format!(
                "{what} of {} {u} is unusually large (typical industrial arms stay below {} {u}){hint}",
                sig(value * k, 2),
                sig(typical * k, 2)
            ));
        }
    };
    match spec {
        EffectSpec::JointCompliance { joint } => {
            let tmax = lin.tau.iter().map(|v| v[joint - 1].abs()).fold(0.0, f64::max);
            let (typ, lim) = if prismatic {
                (b.max_deflection_m, b.limit_deflection_m)
            } else {
                (b.max_deflection_rad, b.limit_deflection_rad)
            };
            size(
                format!("joint {joint}'s deflection at the largest load"),
                t.abs() * tmax,
                typ,
                lim,
                unit,
                scale,
                ": a compliant joint; check the gearbox, the brake or the joint's torque control",
            );
            if t < 0.0 {
                unusual.push(format!(
                    "the compliance is negative ({}): joint {joint} moves against its load, as an over-compensated gravity model in the joint's torque control or a load model with the wrong masses would make it",
                    sig(t, 2)
                ));
            }
        }
        EffectSpec::LinkCompliance { link } => {
            let mmax = lin.bend.iter().filter_map(|b| b.get(link - 1)).map(|(v, _)| v.norm()).fold(0.0, f64::max);
            size(
                format!("link {link}'s bend at the largest load"),
                t.abs() * mmax,
                b.max_deflection_rad,
                b.limit_deflection_rad,
                "mrad",
                1e3,
                ": a flexible link; check its mounting and the load it carries",
            );
            if t < 0.0 {
                unusual.push(format!(
                    "the compliance is negative ({}): link {link} bends against its load, which a wrong mass in the model can mimic",
                    sig(t, 2)
                ));
            }
        }
        EffectSpec::Backlash { joint } => {
            // Either sign is a direction-dependent error: a lagging link (backlash) or a
            // leading one (a load that coasts onto the leading flank; a `dir` defined the other
            // way round). Only the size is judged.
            let (typ, lim) = if prismatic {
                (b.max_backlash_m, b.limit_backlash_m)
            } else {
                (b.max_backlash_rad, b.limit_backlash_rad)
            };
            size(
                format!("joint {joint}'s direction-dependent error"),
                t.abs(),
                typ,
                lim,
                unit,
                scale,
                ": a worn or loose drive train",
            );
        }
        EffectSpec::JointScaleError { joint } => size(
            format!("joint {joint}'s scale error"),
            t.abs() * 1e6,
            b.max_scale_error * 1e6,
            b.limit_scale_error * 1e6,
            "ppm",
            1.0,
            ": check the gear ratio or the encoder resolution in the controller",
        ),
        EffectSpec::CoupledTransmission { joint, driver } => size(
            format!("joint {joint}'s coupling to joint {driver}"),
            t.abs() * 1e6,
            b.max_scale_error * 1e6,
            b.limit_scale_error * 1e6,
            "ppm",
            1.0,
            ": check the coupling ratio in the controller",
        ),
        EffectSpec::AxisMisalignment { joint } => size(
            format!("joint {joint}'s axis tilt"),
            t.hypot(theta.get(1).copied().unwrap_or(0.0)),
            b.max_axis_wobble_rad,
            b.limit_axis_wobble_rad,
            "mrad",
            1e3,
            ": check the joint's bearing",
        ),
        EffectSpec::PeriodicJointError { joint, .. } => {
            let a = t.hypot(theta.get(1).copied().unwrap_or(0.0));
            let (typ, lim) = if prismatic {
                (b.max_periodic_m, b.limit_periodic_m)
            } else {
                (b.max_periodic_rad, b.limit_periodic_rad)
            };
            size(
                format!("joint {joint}'s periodic error amplitude"),
                a,
                typ,
                lim,
                unit,
                scale,
                ": check the gear or the encoder's mounting",
            );
        }
        EffectSpec::ThermalExpansion { .. } => {
            let [lo, hi] = b.thermal_alpha_per_k;
            if t.abs() > b.limit_thermal_alpha_per_k {
                out.possible = Err(format!(
                    "expansion coefficient {} per K is beyond {} per K, which no structural material shows (check the temperature column's unit)",
                    sig(t, 2),
                    sig(b.limit_thermal_alpha_per_k, 2)
                ));
            } else if !(lo..=hi).contains(&t) {
                unusual.push(format!(
                    "expansion coefficient {} per K is outside the range of metals ({} to {} per K): carbon fibre, a mixed structure, or a thermometer far from the structure",
                    sig(t, 2),
                    sig(lo, 2),
                    sig(hi, 2)
                ));
            }
        }
        EffectSpec::TimeDrift => size(
            "a length drift per hour".into(),
            t.abs() * 1e6,
            b.max_drift_per_hour * 1e6,
            b.limit_drift_per_hour * 1e6,
            "ppm",
            1.0,
            ": a machine warming up; record its temperature",
        ),
        EffectSpec::Custom(_) => {}
    }
    if out.possible.is_ok() && !unusual.is_empty() {
        out.unusual = Some(unusual.join("; "));
    }
    out
}

/// (b): the same sign and a similar size in every fold; returns the jackknife relative standard
/// deviation of the main parameter (the amplitude of a periodic error).
pub(super) fn stability(spec: &EffectSpec, theta_all: &[f64], ls: &LinScore, ctx: &Ctx) -> Result<f64, String> {
    let k = ls.theta_folds.len() as f64;
    let main = |t: &[f64]| match spec {
        EffectSpec::PeriodicJointError { .. } | EffectSpec::AxisMisalignment { .. } => {
            t.first().copied().unwrap_or(0.0).hypot(t.get(1).copied().unwrap_or(0.0))
        }
        _ => t.first().copied().unwrap_or(0.0),
    };
    let all = main(theta_all);
    let per: Vec<f64> = ls.theta_folds.iter().map(|t| main(t.as_slice())).collect();
    if let EffectSpec::PeriodicJointError { joint, period_si } = spec {
        let f_all = 1.0 / period_si;
        let grid = &ctx.grids[joint - 1];
        let step = if grid.len() > 1 { grid[1] - grid[0] } else { f_all * 0.01 };
        for (i, f) in ls.freq_folds.iter().enumerate() {
            if (f - f_all).abs() > step {
                return Err(format!(
                    "fold {} finds a period of {} instead of {}",
                    i + 1,
                    sig(1.0 / f, 3),
                    sig(*period_si, 3)
                ));
            }
        }
        for (i, a) in per.iter().enumerate() {
            if !(0.5 * all..=2.0 * all).contains(a) {
                return Err(format!("fold {} finds an amplitude of {} instead of {}", i + 1, sig(*a, 2), sig(all, 2)));
            }
        }
    } else {
        for (i, v) in per.iter().enumerate() {
            if v * all <= 0.0 {
                return Err(format!("fold {} finds the opposite sign ({} against {})", i + 1, sig(*v, 2), sig(all, 2)));
            }
        }
    }
    let mean = per.iter().sum::<f64>() / k;
    let jack = ((k - 1.0) / k * per.iter().map(|v| (v - mean).powi(2)).sum::<f64>()).sqrt();
    let rel = jack / all.abs().max(1e-300);
    if rel > 0.5 {
        return Err(format!("the folds scatter by {:.0} % of the value", rel * 100.0));
    }
    Ok(rel)
}
