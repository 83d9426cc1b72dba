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
    }
    m
}

/// (d): sign and size.
pub(super) fn plausible(
    spec: &EffectSpec,
    theta: &[f64],
    ctx: &Ctx,
    lin: &Lin,
    opts: &DiagnoseOptions,
) -> Result<(), String> {
    let b = &opts.bounds;
    let t = theta.first().copied().unwrap_or(0.0);
    let prismatic = spec.joint().is_some_and(|j| ctx.kinds.get(j - 1) == Some(&JointKind::Prismatic));
    let (unit, scale) = if prismatic { ("mm", 1e3) } else { ("mrad", 1e3) };
    match spec {
        EffectSpec::JointCompliance { joint } => {
            if t <= 0.0 {
                return Err(format!("negative compliance ({}): joint {joint} would rise against its load", sig(t, 2)));
            }
            let tmax = lin.tau.iter().map(|v| v[joint - 1].abs()).fold(0.0, f64::max);
            let defl = t * tmax;
            let bound = if prismatic { b.max_deflection_m } else { b.max_deflection_rad };
            if defl > bound {
                return Err(format!(
                    "a deflection of {} {unit} at the largest load exceeds the bound of {} {unit}",
                    sig(defl * scale, 2),
                    sig(bound * scale, 2)
                ));
            }
        }
        EffectSpec::Backlash { .. } => {
            if t <= 0.0 {
                return Err(format!(
                    "negative backlash ({} {unit}): the joint would overshoot, not stop short",
                    sig(t * scale, 2)
                ));
            }
            let bound = if prismatic { b.max_backlash_m } else { b.max_backlash_rad };
            if t > bound {
                return Err(format!(
                    "backlash {} {unit} exceeds the bound of {} {unit}",
                    sig(t * scale, 2),
                    sig(bound * scale, 2)
                ));
            }
        }
        EffectSpec::JointScaleError { .. } => {
            if t.abs() > b.max_scale_error {
                return Err(format!("scale error {} exceeds the bound of {}", sig(t, 2), sig(b.max_scale_error, 2)));
            }
        }
        EffectSpec::CoupledTransmission { .. } => {
            // A coupling is a transmission ratio error like a scale error: the same bound.
            if t.abs() > b.max_scale_error {
                return Err(format!("coupling {} exceeds the bound of {}", sig(t, 2), sig(b.max_scale_error, 2)));
            }
        }
        EffectSpec::AxisMisalignment { .. } => {
            let a = t.hypot(theta.get(1).copied().unwrap_or(0.0));
            if a > b.max_axis_wobble_rad {
                return Err(format!(
                    "a tilt of {} mrad exceeds the bound of {} mrad",
                    sig(a * 1e3, 2),
                    sig(b.max_axis_wobble_rad * 1e3, 2)
                ));
            }
        }
        EffectSpec::PeriodicJointError { .. } => {
            let a = theta.first().copied().unwrap_or(0.0).hypot(theta.get(1).copied().unwrap_or(0.0));
            let bound = if prismatic { b.max_periodic_m } else { b.max_periodic_rad };
            if a > bound {
                return Err(format!(
                    "amplitude {} {unit} exceeds the bound of {} {unit}",
                    sig(a * scale, 2),
                    sig(bound * scale, 2)
                ));
            }
        }
        EffectSpec::ThermalExpansion { .. } => {
            let [lo, hi] = b.thermal_alpha_per_k;
            if !(lo..=hi).contains(&t) {
                return Err(format!(
                    "expansion coefficient {} per K is outside the range of metals ({} to {} per K)",
                    sig(t, 2),
                    sig(lo, 2),
                    sig(hi, 2)
                ));
            }
        }
        EffectSpec::TimeDrift => {
            if t.abs() > b.max_drift_per_hour {
                return Err(format!(
                    "a length drift of {} ppm per hour exceeds the bound of {} ppm per hour",
                    sig(t * 1e6, 2),
                    sig(b.max_drift_per_hour * 1e6, 2)
                ));
            }
        }
        EffectSpec::LinkCompliance { link } => {
            if t <= 0.0 {
                return Err(format!("negative compliance ({}): link {link} would bend against its load", sig(t, 2)));
            }
            let mmax = lin.bend.iter().filter_map(|b| b.get(link - 1)).map(|(v, _)| v.norm()).fold(0.0, f64::max);
            let defl = t * mmax;
            if defl > b.max_deflection_rad {
                return Err(format!(
                    "a bend of {} mrad at the largest load exceeds the bound of {} mrad",
                    sig(defl * 1e3, 2),
                    sig(b.max_deflection_rad * 1e3, 2)
                ));
            }
        }
    }
    Ok(())
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
