//! Lead-through with tool force feedback (issue [motion] item 5, the control concept of Dressler
//! ch. 8): an operator guides the tool by hand; a force sensor between the hand and the tool
//! reads the push, and an admittance law turns it into the actuator's reference,
//! `r_k+1 = r_k + dt F_f,k / D_a` (`D_a` the admittance damping: 1 N moves the axis at `1 / D_a`
//! m/s), `F_f` the force through a first-order low-pass against the sensor's noise. The sensor
//! sits at the tool, beyond the compliant structure, so the loop is not collocated. What limits
//! a light admittance here (measured by [`stability_map`] on the L1-like axis): the loop through
//! the operator's stiffness, the admittance's integration and the actuator loop's lag and dead
//! time (24 ms to the carriage) goes unstable below about 25 N s/m; a force low-pass adds lag and
//! moves that limit up (2 and 5 Hz: unstable at 25 N s/m), so the filter is for noise only and
//! its cut-off should stay well above the operator's motion.
//!
//! The operator is a spring and damper (`k_h`, `d_h`, a relaxed human arm) whose other end
//! follows the intended path; the force on the tool is what the hand's spring and damper carry.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

use super::{quintic_move, CompliantAxis};
use crate::error::{DatasetError, Result};

/// Settings of one lead-through run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LeadSettings {
    /// Admittance damping, N s/m.
    pub admittance_n_s_m: f64,
    /// Cut-off of the force low-pass, Hz (0: no filter).
    pub force_cutoff_hz: f64,
    /// Hand stiffness, N/m.
    pub hand_stiffness_n_m: f64,
    /// Hand damping, N s/m.
    pub hand_damping_n_s_m: f64,
    /// Length of the guided move, m.
    pub distance_m: f64,
    /// Duration of the intended move, s.
    pub move_s: f64,
    /// Standard deviation of the force sensor's Gaussian noise, N (seeded by `seed`).
    pub sensor_sigma_n: f64,
    /// Seed of the sensor noise.
    pub seed: u64,
}

impl Default for LeadSettings {
    /// 100 N s/m, a 5 Hz low-pass, a hand of 1500 N/m and 60 N s/m guiding 100 mm in 1.5 s,
    /// 0.2 N sensor noise.
    fn default() -> Self {
        Self {
            admittance_n_s_m: 100.0,
            force_cutoff_hz: 5.0,
            hand_stiffness_n_m: 1500.0,
            hand_damping_n_s_m: 60.0,
            distance_m: 0.1,
            move_s: 1.5,
            sensor_sigma_n: 0.2,
            seed: 1,
        }
    }
}

impl LeadSettings {
    /// Checks the settings; the error names the first bad field and its value.
    pub fn validate(&self) -> Result<()> {
        let positive = [
            ("admittance_n_s_m", self.admittance_n_s_m),
            ("hand_stiffness_n_m", self.hand_stiffness_n_m),
            ("move_s", self.move_s),
        ];
        let non_negative = [
            ("force_cutoff_hz", self.force_cutoff_hz),
            ("hand_damping_n_s_m", self.hand_damping_n_s_m),
            ("sensor_sigma_n", self.sensor_sigma_n),
        ];
        let bad = |field: &str, v: f64, what: &str| {
            Err(DatasetError::Input(format!("lead-through: {field} = {v} must be {what}")))
        };
        if let Some((f, v)) = positive.iter().find(|(_, v)| !(v.is_finite() && *v > 0.0)) {
            return bad(f, *v, "finite and positive");
        }
        if let Some((f, v)) = non_negative.iter().find(|(_, v)| !(v.is_finite() && *v >= 0.0)) {
            return bad(f, *v, "finite and not negative");
        }
        if !self.distance_m.is_finite() {
            return bad("distance_m", self.distance_m, "finite");
        }
        Ok(())
    }
}

/// What a run shows.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LeadResult {
    /// The settings.
    pub settings: LeadSettings,
    /// RMS force the operator pushes with during the move, N.
    pub force_rms_n: f64,
    /// Largest force, N.
    pub force_max_n: f64,
    /// Tool position when the hand has arrived and rested 1 s, relative to the goal, m.
    pub final_error_m: f64,
    /// RMS of the tool's ringing in the last second (its position minus its 0.1 s moving mean),
    /// m: near zero when the loop is stable.
    pub final_oscillation_m: f64,
    /// Whether the run stayed bounded and did not ring (ringing below 100 µm, no divergence).
    pub stable: bool,
    /// Tool position per sample, m.
    pub tool_m: Vec<f64>,
    /// Hand (intended) position per sample, m.
    pub hand_m: Vec<f64>,
    /// Sensor force per sample, N.
    pub force_n: Vec<f64>,
}

/// Runs a lead-through on `axis`.
pub fn lead_through(axis: &CompliantAxis, s: &LeadSettings) -> Result<LeadResult> {
    s.validate()?;
    let dt = axis.dt_s;
    let n = ((0.2 + s.move_s + 1.5) / dt).round() as usize;
    let hand = quintic_move(n, dt, 0.2, s.move_s, s.distance_m);
    let (ad, bd, bf) = axis.discrete();
    let mut x = nalgebra::SVector::<f64, 5>::zeros();
    let delay = axis.servo_delay_samples;
    let mut refs = vec![0.0; n + 1];
    let alpha =
        if s.force_cutoff_hz > 0.0 { 1.0 - (-std::f64::consts::TAU * s.force_cutoff_hz * dt).exp() } else { 1.0 };
    let mut filtered = 0.0;
    let (mut tool, mut force) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let mut rng = ChaCha8Rng::seed_from_u64(s.seed);
    let normal = Normal::new(0.0, s.sensor_sigma_n).expect("validated sigma");
    let mut noise = || normal.sample(&mut rng);
    for k in 0..n {
        let v_hand = if k + 1 < n { (hand[k + 1] - hand[k]) / dt } else { 0.0 };
        let f = s.hand_stiffness_n_m * (hand[k] - x[3]) + s.hand_damping_n_s_m * (v_hand - x[4]);
        tool.push(x[3]);
        force.push(f);
        if !f.is_finite() || f.abs() > 1e6 {
            break;
        }
        filtered += alpha * (f + noise() - filtered);
        refs[k + 1] = refs[k] + dt * filtered / s.admittance_n_s_m;
        let delayed = if k >= delay { refs[k - delay] } else { 0.0 };
        // The hand's force acts on the platform (and through the structure on the carriage).
        x = ad * x + bd * delayed + bf * f;
    }
    let done = tool.len() == n;
    // Ringing: the tool's deviation from its own 0.1 s moving mean over the last second (the
    // structure's modes are above 10 Hz; a slow approach to the goal does not count).
    let last = (1.0 / dt) as usize;
    let half = (0.05 / dt) as usize;
    let from = tool.len().saturating_sub(last + half).max(half);
    let to = tool.len().saturating_sub(half);
    let dev: Vec<f64> =
        (from..to).map(|k| tool[k] - tool[k - half..=k + half].iter().sum::<f64>() / (2 * half + 1) as f64).collect();
    let final_oscillation_m = (dev.iter().map(|v| v * v).sum::<f64>() / dev.len().max(1) as f64).sqrt();
    let moving = ((0.2 / dt) as usize, ((0.2 + s.move_s) / dt) as usize);
    let during = &force[moving.0.min(force.len())..moving.1.min(force.len())];
    let force_rms_n = (during.iter().map(|f| f * f).sum::<f64>() / during.len().max(1) as f64).sqrt();
    Ok(LeadResult {
        settings: s.clone(),
        force_rms_n,
        force_max_n: force.iter().fold(0.0f64, |m, f| m.max(f.abs())),
        final_error_m: tool.last().copied().unwrap_or(f64::NAN) - s.distance_m,
        final_oscillation_m,
        stable: done
            && final_oscillation_m < 1e-4
            && tool.iter().all(|v| v.abs() < 10.0 * s.distance_m.abs().max(0.01)),
        tool_m: tool,
        hand_m: hand,
        force_n: force,
    })
}

/// One cell of the stability map.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct StabilityCell {
    /// Admittance damping, N s/m.
    pub admittance_n_s_m: f64,
    /// Low-pass cut-off, Hz (0: none).
    pub force_cutoff_hz: f64,
    /// Whether the run was stable.
    pub stable: bool,
    /// The operator's RMS force during the move, N.
    pub force_rms_n: f64,
}

/// Lead-through runs over admittances and filter cut-offs (the other settings from `base`).
pub fn stability_map(
    axis: &CompliantAxis,
    base: &LeadSettings,
    admittances: &[f64],
    cutoffs_hz: &[f64],
) -> Result<Vec<StabilityCell>> {
    let mut out = Vec::new();
    for &c in cutoffs_hz {
        for &a in admittances {
            let r = lead_through(axis, &LeadSettings { admittance_n_s_m: a, force_cutoff_hz: c, ..base.clone() })?;
            out.push(StabilityCell {
                admittance_n_s_m: a,
                force_cutoff_hz: c,
                stable: r.stable,
                force_rms_n: r.force_rms_n,
            });
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each bad setting is refused with its field's name; the defaults pass.
    #[test]
    fn bad_lead_settings_name_their_field() {
        assert!(LeadSettings::default().validate().is_ok());
        let d = LeadSettings::default;
        for (s, field) in [
            (LeadSettings { admittance_n_s_m: 0.0, ..d() }, "admittance_n_s_m"),
            (LeadSettings { admittance_n_s_m: f64::NAN, ..d() }, "admittance_n_s_m"),
            (LeadSettings { hand_stiffness_n_m: -1.0, ..d() }, "hand_stiffness_n_m"),
            (LeadSettings { move_s: f64::INFINITY, ..d() }, "move_s"),
            (LeadSettings { force_cutoff_hz: -5.0, ..d() }, "force_cutoff_hz"),
            (LeadSettings { hand_damping_n_s_m: f64::NAN, ..d() }, "hand_damping_n_s_m"),
            (LeadSettings { sensor_sigma_n: -0.1, ..d() }, "sensor_sigma_n"),
            (LeadSettings { distance_m: f64::NAN, ..d() }, "distance_m"),
        ] {
            let e = lead_through(&CompliantAxis::l1_like(), &s).unwrap_err().to_string();
            assert!(e.contains(field), "{field}: {e}");
        }
        // A zero filter cut-off (no filter) and zero noise are allowed.
        assert!(LeadSettings { force_cutoff_hz: 0.0, sensor_sigma_n: 0.0, ..d() }.validate().is_ok());
    }

    /// A 100 N s/m admittance guides the tool 100 mm with about 9 N and settles on the goal;
    /// one ten times lighter diverges; a heavier one needs proportionally more push.
    #[test]
    fn an_admittance_guides_the_tool_to_its_goal_and_a_ten_times_lighter_one_diverges() {
        let axis = CompliantAxis::l1_like();
        let good = lead_through(&axis, &LeadSettings::default()).unwrap();
        assert!(good.stable, "oscillation {} m, error {} m", good.final_oscillation_m, good.final_error_m);
        assert!(good.final_error_m.abs() < 1e-3, "final error {} m", good.final_error_m);
        assert!(good.force_rms_n < 20.0, "operator force {} N RMS", good.force_rms_n);
        let unfiltered = lead_through(
            &axis,
            &LeadSettings { force_cutoff_hz: 0.0, admittance_n_s_m: 10.0, ..LeadSettings::default() },
        )
        .unwrap();
        assert!(!unfiltered.stable, "unfiltered light admittance settled: {} m", unfiltered.final_oscillation_m);
        // Effort: a heavier admittance needs proportionally more push.
        let heavy = lead_through(&axis, &LeadSettings { admittance_n_s_m: 400.0, ..LeadSettings::default() }).unwrap();
        assert!(
            heavy.stable && heavy.force_rms_n > 2.0 * good.force_rms_n,
            "{} vs {} N, oscillation {} m, error {} m",
            heavy.force_rms_n,
            good.force_rms_n,
            heavy.final_oscillation_m,
            heavy.final_error_m
        );
        // The map: light admittances go unstable, a low-pass adds lag (25 N s/m: stable
        // unfiltered, unstable behind a 5 Hz low-pass).
        let map = stability_map(&axis, &LeadSettings::default(), &[10.0, 25.0, 100.0], &[0.0, 5.0]).unwrap();
        let at =
            |a: f64, c: f64| map.iter().find(|m| m.admittance_n_s_m == a && m.force_cutoff_hz == c).unwrap().stable;
        assert!(
            !at(10.0, 0.0) && !at(10.0, 5.0) && at(25.0, 0.0) && !at(25.0, 5.0) && at(100.0, 0.0) && at(100.0, 5.0),
            "{map:?}"
        );
        eprintln!(
            "good {:.2} N rms, err {:.3} mm; heavy {:.2} N; unfiltered osc {:.3} mm",
            good.force_rms_n,
            1e3 * good.final_error_m,
            heavy.force_rms_n,
            1e3 * unfiltered.final_oscillation_m
        );
    }
}
