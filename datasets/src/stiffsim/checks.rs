//! The pass/fail checks of the elastostatic study (`ferrocal stiffness study`, the demo): the
//! simulated experiments against the source's numbers (Klimchik et al. 2015), as [`Check`]s that
//! can fail.

use ferrocal_calib::check::Check;
use ferrocal_calib::stiffness::onelink::SOURCE_NU;

use super::study::{ArmStudy, OneLinkStudy};

/// A parameter-to-noise ratio below this cannot be identified (the source's threshold).
pub const USABLE_NU: f64 = 2.0;
/// Relative agreement of a one-link ratio with the source's (absolute 0.005 for small ratios).
pub const NU_TOLERANCE: f64 = 0.005;
/// The source's count of unusable entries of the one-link compliance matrix (of 36).
pub const SOURCE_UNUSABLE: usize = 27;
/// The smallest share of the compliance error the reduced model's compensation must remove.
pub const MIN_REMOVED: f64 = 0.9;
/// The range of the final parameter count of the 6-DOF reduction (the source: 26).
pub const FINAL_PARAMETERS: std::ops::RangeInclusive<usize> = 8..=40;

/// True when a one-link ratio agrees with the source's.
pub fn nu_agrees(nu: f64, source: f64) -> bool {
    (nu - source).abs() <= (NU_TOLERANCE * source).max(NU_TOLERANCE)
}

/// One-link entries whose ratio at the true values is below [`USABLE_NU`].
pub fn unusable_entries(st: &OneLinkStudy) -> usize {
    st.ratios.iter().filter(|e| e.nu < USABLE_NU).count()
}

/// The largest relative deviation of the ten non-zero one-link ratios from the source's.
pub fn max_nu_deviation(st: &OneLinkStudy) -> f64 {
    SOURCE_NU
        .iter()
        .filter_map(|(n, v)| st.ratios.iter().find(|e| e.name == *n).map(|e| (e.nu - v).abs() / v))
        .fold(0.0, f64::max)
}

/// The one-link study: every ratio as the source's, its 27 unusable entries, every naive
/// estimate unphysical and every reduced one physical.
pub fn one_link(st: &OneLinkStudy) -> Check {
    let agree = SOURCE_NU
        .iter()
        .filter_map(|(n, source)| st.ratios.iter().find(|e| e.name == *n).map(|e| nu_agrees(e.nu, *source)))
        .all(|ok| ok);
    let ok = agree
        && unusable_entries(st) == SOURCE_UNUSABLE
        && st.reduced_unphysical == 0
        && st.naive_unphysical == st.trials;
    Check::from_bool(
        "one-link parameter-to-noise ratios",
        ok,
        if ok { "ratios as the source's; reduced estimates physical" } else { "a check failed" },
    )
}

/// The 6-DOF study: the reduced model's compensation removes more than [`MIN_REMOVED`] of the
/// compliance error and beats the rigid-link model, with a final count in [`FINAL_PARAMETERS`].
pub fn arm(s: &ArmStudy) -> Check {
    let none = s.errors("none").map(|c| c.rms_m).unwrap_or(0.0);
    let red = s.errors("reduced model").map(|c| c.rms_m).unwrap_or(f64::INFINITY);
    let rl = s.errors("rigid links, compliant joints").map(|c| c.rms_m).unwrap_or(0.0);
    let last = s.reduction.param.len();
    let removed = 1.0 - red / none;
    Check::from_bool(
        "6-DOF reduction and compensation",
        removed > MIN_REMOVED && rl > red && FINAL_PARAMETERS.contains(&last),
        format!(
            "{} -> {last} parameters; {:.1} % of the compliance error removed; rigid-link model leaves {:.1} x more",
            s.reduction.steps[0].n_params,
            100.0 * removed,
            rl / red
        ),
    )
}

/// The demo's check: [`arm`], the one-link ratios within [`NU_TOLERANCE`] of the source's and
/// every reduced one-link estimate physical.
pub fn demo(one: &OneLinkStudy, s: &ArmStudy) -> Check {
    let a = arm(s);
    let ok = a.passed() && max_nu_deviation(one) < NU_TOLERANCE && one.reduced_unphysical == 0;
    Check::from_bool("elastostatic identification", ok, a.detail)
}
