//! The lead-through sections of the motion study: the hand-guided axis and where its force sensor sits.

use super::*;

/// The lead-through section: admittance control on the tool force sensor (Dressler ch. 8's
/// concept), one guided move and the stability map.
pub(super) fn leadthrough_section(axis: &CompliantAxis, base: &LeadSettings) -> Result<Section> {
    let run = lead_through(axis, base)?;
    let mut sec = Section::new("motion-leadthrough", "Lead-through with tool force feedback (simulated)");
    sec.text(format!(
        "An operator (a spring of {:.0} N/m and damper of {:.0} N s/m whose other end follows the intended path) guides the tool {:.0} mm in {:.1} s; a force sensor {} ({:.1} N noise) feeds an admittance law r' = F / D_a through a first-order low-pass into the actuator's reference.{}",
        base.hand_stiffness_n_m,
        base.hand_damping_n_s_m,
        1e3 * base.distance_m,
        base.move_s,
        placement_name(base.sensor),
        base.sensor_sigma_n,
        if base.sensor == SensorPlacement::Tool {
            " The loop is not collocated (the sensor is beyond the compliant structure)."
        } else {
            ""
        }
    ));
    let dt = axis.dt_s;
    let t = |v: &[f64], scale: f64| -> Vec<(f64, f64)> {
        v.iter().enumerate().map(|(k, x)| (k as f64 * dt, scale * x)).collect()
    };
    let (hand, tool, force) = (t(&run.hand_m, 1e3), t(&run.tool_m, 1e3), t(&run.force_n, 1.0));
    sec.figure(
        &format!(
            "Guided move at D_a = {:.0} N s/m, {:.0} Hz low-pass: hand and tool (mm)",
            base.admittance_n_s_m, base.force_cutoff_hz
        ),
        plot::xy_plot(
            "lead-through",
            "time (s)",
            "position (mm)",
            &[
                Series { name: "hand (intended)", points: &hand, line: true },
                Series { name: "tool", points: &tool, line: true },
            ],
        ),
    );
    sec.figure(
        "The operator's force on the tool (N)",
        plot::xy_plot(
            "lead-through force",
            "time (s)",
            "force (N)",
            &[Series { name: "sensor force", points: &force, line: true }],
        ),
    );
    let admittances = [10.0, 25.0, 50.0, 100.0, 200.0, 400.0];
    let cutoffs = [0.0, 2.0, 5.0, 10.0];
    let map = stability_map(axis, base, &admittances, &cutoffs)?;
    let mut header = vec!["D_a (N s/m)".to_string()];
    header.extend(cutoffs.iter().map(|c| if *c > 0.0 { format!("{c:.0} Hz low-pass") } else { "no filter".into() }));
    let header_ref: Vec<&str> = header.iter().map(String::as_str).collect();
    sec.table(
        "Stability map: operator's RMS force during the move, or 'unstable'",
        &header_ref,
        admittances
            .iter()
            .map(|a| {
                let mut row = vec![format!("{a:.0}")];
                row.extend(cutoffs.iter().map(|c| {
                    map.iter().find(|m| m.admittance_n_s_m == *a && m.force_cutoff_hz == *c).map_or("-".into(), |m| {
                        if m.stable {
                            format!("{:.1} N", m.force_rms_n)
                        } else {
                            "unstable".into()
                        }
                    })
                }));
                row
            })
            .collect(),
    );
    if base.sensor == SensorPlacement::Tool {
        sec.text("What limits a light admittance here is the loop through the operator's stiffness, the admittance's integration and the actuator's lag and dead time, not the structural mode: a force low-pass adds lag and moves the limit up, so it is for the sensor's noise only.");
    }
    let placement = placement_comparison(axis, base, &mut sec)?;
    sec.data = json!({
        "settings": base,
        "force_rms_n": run.force_rms_n,
        "force_max_n": run.force_max_n,
        "final_error_m": run.final_error_m,
        "final_oscillation_m": run.final_oscillation_m,
        "stable": run.stable,
        "stability_map": map,
        "sensor_placement": placement,
    });
    sec.check(Check::from_bool(
        "guided to the goal without ringing",
        run.stable && run.final_error_m.abs() < 1e-3,
        format!(
            "operator force {:.1} N RMS (largest {:.1} N), tool {:.3} mm from the goal 1.5 s after the hand, ringing {:.2} µm",
            run.force_rms_n,
            run.force_max_n,
            1e3 * run.final_error_m,
            1e6 * run.final_oscillation_m
        ),
    ));
    Ok(sec)
}

pub(super) fn placement_name(p: SensorPlacement) -> &'static str {
    match p {
        SensorPlacement::Tool => "at the tool (hand to tool)",
        SensorPlacement::Carriage => "at the carriage (actuator to links)",
        SensorPlacement::CarriageCompensated => "at the carriage, rigid-body inertia added back from the encoder",
    }
}

/// Dressler ch. 8's placement question: the stability map's runs (unfiltered and 5 Hz) with the
/// force sensor at the tool and at the carriage, a table, a figure of the readings against the
/// hand's force at 200 N s/m, and the numbers for the JSON.
pub(super) fn placement_comparison(
    axis: &CompliantAxis,
    base: &LeadSettings,
    sec: &mut Section,
) -> Result<serde_json::Value> {
    let grid = [25.0, 50.0, 100.0, 200.0, 400.0];
    let cutoffs = [0.0, 5.0];
    let (probe_a, probe_c) = (200.0, 5.0);
    let mut rows = Vec::new();
    let mut data = Vec::new();
    let mut probes = Vec::new();
    for p in [SensorPlacement::Tool, SensorPlacement::Carriage, SensorPlacement::CarriageCompensated] {
        let b = LeadSettings { sensor: p, ..base.clone() };
        let map = stability_map(axis, &b, &grid, &cutoffs)?;
        let probe = lead_through(axis, &LeadSettings { admittance_n_s_m: probe_a, force_cutoff_hz: probe_c, ..b })?;
        let cell = |a: f64, c: f64| {
            map.iter().find(|m| m.admittance_n_s_m == a && m.force_cutoff_hz == c).map_or("-".into(), |m| {
                if m.stable {
                    format!("{:.1} N", m.force_rms_n)
                } else {
                    "unstable".into()
                }
            })
        };
        let mut row = vec![placement_name(p).to_string()];
        row.extend(grid.iter().map(|a| format!("{} / {}", cell(*a, 0.0), cell(*a, 5.0))));
        row.push(format!("{:.2} N", probe.sensor_error_rms_n));
        rows.push(row);
        data.push(json!({
            "sensor": p,
            "stability_map": map,
            "probe_admittance_n_s_m": probe_a,
            "probe_force_cutoff_hz": probe_c,
            "probe_stable": probe.stable,
            "probe_force_rms_n": probe.force_rms_n,
            "probe_reading_minus_hand_rms_n": probe.sensor_error_rms_n,
        }));
        probes.push((p, probe));
    }
    let mut header = vec!["force sensor".to_string()];
    header.extend(grid.iter().map(|a| format!("D_a {a:.0}: no filter / 5 Hz")));
    header.push(format!("reading minus hand force, RMS during the move (D_a {probe_a:.0}, {probe_c:.0} Hz)"));
    let header_ref: Vec<&str> = header.iter().map(String::as_str).collect();
    sec.table(
        "Force-sensor placement (Dressler ch. 8): the operator's RMS force, or 'unstable', per admittance (N s/m)",
        &header_ref,
        rows,
    );
    sec.text("A sensor at the carriage reads what the structure puts on the actuator: the hand's force minus the inertial forces of the links and the platform (F_h - m1 x1'' - m2 x2''), so the modes' motion is fed back into the admittance. Unfiltered it needs a heavier admittance than the sensor at the tool, and a low-pass, which only adds lag for the tool's sensor, helps it by removing the modes from the reading. Adding the rigid-body inertia (m1 + m2) a'' back from the encoder's second difference leaves the compliance's inertial forces and the encoder's quantisation.");
    let dt = axis.dt_s;
    let series_of = |v: &[f64]| -> Vec<(f64, f64)> { v.iter().enumerate().map(|(k, f)| (k as f64 * dt, *f)).collect() };
    let carriage = probes.iter().find(|(p, _)| *p == SensorPlacement::Carriage).map(|(_, r)| r);
    let compensated = probes.iter().find(|(p, _)| *p == SensorPlacement::CarriageCompensated).map(|(_, r)| r);
    if let (Some(c), Some(k)) = (carriage, compensated) {
        let (hand, read_c, read_k) = (series_of(&c.force_n), series_of(&c.sensor_n), series_of(&k.sensor_n));
        sec.figure(
            &format!("The hand's force and the carriage sensor's readings (before noise) at D_a = {probe_a:.0} N s/m, {probe_c:.0} Hz low-pass"),
            plot::xy_plot(
                "force-sensor placement",
                "time (s)",
                "force (N)",
                &[
                    Series { name: "hand force", points: &hand, line: true },
                    Series { name: "carriage sensor", points: &read_c, line: true },
                    Series { name: "carriage sensor, inertia added back", points: &read_k, line: true },
                ],
            ),
        );
    }
    Ok(serde_json::Value::Array(data))
}
