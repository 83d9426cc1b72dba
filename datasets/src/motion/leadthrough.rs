//! Lead-through with tool force feedback (issue [motion] item 5, the control concept of Dressler
//! ch. 8): an operator guides the tool by hand; a force sensor between the hand and the tool
//! reads the push, and an admittance law turns it into the actuator's reference,
//! `r_k+1 = r_k + dt F_f,k / D_a` (`D_a` the admittance damping: 1 N moves the axis at `1 / D_a`
//! m/s), `F_f` the force through a first-order low-pass against the sensor's noise. By default
//! the sensor sits at the tool, beyond the compliant structure, so the loop is not collocated. What limits
//! a light admittance here (measured by [`stability_map`] on the L1-like axis): the loop through
//! the operator's stiffness, the admittance's integration and the actuator loop's lag and dead
//! time (24 ms to the carriage) goes unstable below about 25 N s/m; a force low-pass adds lag and
//! moves that limit up (2 and 5 Hz: unstable at 25 N s/m), so the filter is for noise only and
//! its cut-off should stay well above the operator's motion.
//!
//! The sensor's place is Dressler ch. 8's question ([`SensorPlacement`]): at the carriage it
//! reads the hand's force minus the structure's inertial forces, which feeds the modes back into
//! the admittance (on the L1-like axis, unfiltered, it needs 200 N s/m where the tool's sensor is
//! stable at 25; a 5 Hz low-pass, which only adds lag for the tool's sensor, brings it to 50).
//!
//! The operator is a spring and damper (`k_h`, `d_h`, a relaxed human arm) whose other end
//! follows the intended path; the force on the tool is what the hand's spring and damper carry.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

use ferrocal_calib::motion::ilc::rms;

use super::{quintic_move, CompliantAxis, SensorNoise};
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
    /// Where the force sensor sits.
    pub sensor: SensorPlacement,
}

/// Where the lead-through force sensor sits (Dressler ch. 8's placement question).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SensorPlacement {
    /// Between the operator's hand and the tool: it reads the hand's force.
    Tool,
    /// Between the carriage and the links (at the actuator): it reads the force the structure
    /// puts on the carriage, the hand's force minus the inertial forces of the links and the
    /// platform, `F_h - m1 x1'' - m2 x2''`, averaged over each sample.
    Carriage,
    /// At the carriage, with the rigid-body inertia `(m1 + m2) a''` added back from the
    /// encoder's second difference (1 µm encoder): what is left of the inertial forces is the
    /// compliance's, `-m1 (x1'' - a'') - m2 (x2'' - a'')`, plus the encoder's quantisation.
    CarriageCompensated,
}

impl Default for LeadSettings {
    /// 100 N s/m, a 5 Hz low-pass, a hand of 1500 N/m and 60 N s/m guiding 100 mm in 1.5 s,
    /// 0.2 N sensor noise, the sensor at the tool.
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
            sensor: SensorPlacement::Tool,
        }
    }
}

impl LeadSettings {
    /// The settings of `ferrocal motion leadthrough`: the admittance damping (1 to 100000 N s/m),
    /// the force low-pass cut-off (0 to 100 Hz) and the sensor noise (0 to 100 N), each refused
    /// by its flag's name, with the seed and the sensor's place; the rest the defaults.
    pub fn from_flags(
        admittance_n_s_m: f64,
        force_cutoff_hz: f64,
        sensor_sigma_n: f64,
        seed: u64,
        sensor: SensorPlacement,
    ) -> Result<Self> {
        if !(admittance_n_s_m.is_finite() && (1.0..=1e5).contains(&admittance_n_s_m)) {
            return Err(DatasetError::Input(format!(
                "--admittance-n-s-m {admittance_n_s_m}: give an admittance damping from 1 to 100000 N s/m"
            )));
        }
        if !(0.0..=100.0).contains(&force_cutoff_hz) {
            return Err(DatasetError::Input(format!(
                "--force-cutoff-hz {force_cutoff_hz}: give a cut-off from 0 (no filter) to 100 Hz"
            )));
        }
        if !(0.0..=100.0).contains(&sensor_sigma_n) {
            return Err(DatasetError::Input(format!(
                "--sensor-sigma-n {sensor_sigma_n}: give a force-sensor noise from 0 to 100 N"
            )));
        }
        let s =
            LeadSettings { admittance_n_s_m, force_cutoff_hz, sensor_sigma_n, seed, sensor, ..LeadSettings::default() };
        s.validate()?;
        Ok(s)
    }

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
    /// The hand's force on the tool per sample, N.
    pub force_n: Vec<f64>,
    /// The sensor's reading per sample before its noise, N (the hand's force for a sensor at
    /// the tool).
    pub sensor_n: Vec<f64>,
    /// RMS of the reading (before noise) minus the hand's force during the move, N.
    pub sensor_error_rms_n: f64,
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
    let (mut tool, mut force, mut sensor) = (Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n));
    let mut encoder: Vec<f64> = Vec::with_capacity(n);
    let c = axis.chain;
    // Links' and platform's velocities and the hand's force at the last sample.
    let mut last: Option<(f64, f64, f64)> = None;
    let mut rng = ChaCha8Rng::seed_from_u64(s.seed);
    let normal = Normal::new(0.0, s.sensor_sigma_n).expect("validated sigma");
    let mut noise = || normal.sample(&mut rng);
    for k in 0..n {
        let v_hand = if k + 1 < n { (hand[k + 1] - hand[k]) / dt } else { 0.0 };
        let f = s.hand_stiffness_n_m * (hand[k] - x[3]) + s.hand_damping_n_s_m * (v_hand - x[4]);
        let q = SensorNoise::default().encoder_resolution_m;
        encoder.push((x[0] / q).round() * q);
        let reading = match s.sensor {
            SensorPlacement::Tool => f,
            SensorPlacement::Carriage | SensorPlacement::CarriageCompensated => {
                // The force the structure puts on the carriage, averaged over the last sample
                // (an integrating converter: the drive's input steps at every sample make the
                // stiff link's force ripple within the sample, which an instantaneous reading
                // would alias into a bias): by the momentum of links and platform it is the
                // hand's force held over that sample minus their inertial forces.
                let on_carriage = match &last {
                    Some((v1, v2, f_last)) => f_last - (c.m1_kg * (x[2] - v1) + c.m2_kg * (x[4] - v2)) / dt,
                    None => f,
                };
                let accel = match (s.sensor, encoder.len()) {
                    (SensorPlacement::CarriageCompensated, m) if m >= 3 => {
                        (encoder[m - 1] - 2.0 * encoder[m - 2] + encoder[m - 3]) / (dt * dt)
                    }
                    _ => 0.0,
                };
                on_carriage + (c.m1_kg + c.m2_kg) * accel
            }
        };
        tool.push(x[3]);
        force.push(f);
        sensor.push(reading);
        if !f.is_finite() || f.abs() > 1e6 || !reading.is_finite() {
            break;
        }
        filtered += alpha * (reading + noise() - filtered);
        refs[k + 1] = refs[k] + dt * filtered / s.admittance_n_s_m;
        let delayed = if k >= delay { refs[k - delay] } else { 0.0 };
        // The hand's force acts on the platform (and through the structure on the carriage).
        last = Some((x[2], x[4], f));
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
    let force_rms_n = rms(during);
    let sensor_error: Vec<f64> = (moving.0..moving.1.min(force.len())).map(|k| sensor[k] - force[k]).collect();
    let sensor_error_rms_n = rms(&sensor_error);
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
        sensor_n: sensor,
        sensor_error_rms_n,
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

    /// Dressler ch. 8's placement question: a sensor at the carriage reads the hand's force
    /// minus the structure's inertial forces, which feed the modes back: unfiltered it needs a
    /// heavier admittance than the sensor at the tool (50 N s/m: stable at the tool, unstable
    /// at the carriage), and its reading is off by more than 1 N RMS during the move, much less
    /// once the rigid-body inertia is added back from the encoder.
    #[test]
    fn a_sensor_at_the_carriage_sees_the_inertial_forces_and_needs_a_heavier_admittance() {
        let axis = CompliantAxis::l1_like();
        let run = |sensor, a: f64, c: f64| {
            let s = LeadSettings { sensor, admittance_n_s_m: a, force_cutoff_hz: c, ..LeadSettings::default() };
            lead_through(&axis, &s).unwrap()
        };
        use SensorPlacement::*;
        assert!(run(Tool, 50.0, 0.0).stable);
        assert!(!run(Carriage, 50.0, 0.0).stable);
        assert!(!run(CarriageCompensated, 50.0, 0.0).stable);
        let (tool, carriage, compensated) =
            (run(Tool, 200.0, 5.0), run(Carriage, 200.0, 5.0), run(CarriageCompensated, 200.0, 5.0));
        assert!(tool.stable && carriage.stable && compensated.stable);
        assert_eq!(tool.sensor_error_rms_n, 0.0);
        assert!(carriage.sensor_error_rms_n > 1.0, "{}", carriage.sensor_error_rms_n);
        assert!(
            compensated.sensor_error_rms_n < 0.8 * carriage.sensor_error_rms_n,
            "{} vs {}",
            compensated.sensor_error_rms_n,
            carriage.sensor_error_rms_n
        );
        // Behind the raw carriage sensor the operator also pushes the structure's mass; with the
        // inertia added back the effort is the tool sensor's.
        assert!(carriage.force_rms_n > 1.03 * tool.force_rms_n, "{} vs {} N", carriage.force_rms_n, tool.force_rms_n);
        assert!((compensated.force_rms_n / tool.force_rms_n - 1.0).abs() < 0.02);
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
