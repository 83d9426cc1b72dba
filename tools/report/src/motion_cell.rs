//! Report of `ferrocal motion cell` and the demo's cell section: the compliant 3-DOF Gantry-Tau
//! cell identified from independent excitations of its three drives (the measured frequency
//! response's singular values against the fitted physical model's, the modes against the truth,
//! validation on another record) and learning control from the actuator side, a tool estimate
//! and tool measurements. Simulation only; the experiments are
//! `ferrocal_datasets::motion::{cell, cell_study, cell_ilc}`.

use crate::error::Result;
use ferrocal_calib::check::Check;
use ferrocal_datasets::motion::cell::CompliantCell;
use ferrocal_datasets::motion::cell_ilc::{cell_ilc, CellIlcCase, CellIlcResult};
use ferrocal_datasets::motion::cell_study::{
    identify_cell, identify_poses, CellIdentifyResult, CellIdentifySettings, PoseModes,
};
use serde_json::json;

use crate::plot::{self, Series};
use crate::report::{Provenance, Report, Section};

fn identification_section(cell: &CompliantCell, id: &CellIdentifyResult) -> Section {
    let mut sec =
        Section::new("motion-cell-identification", "3-DOF cell: identification of the compliant structure (simulated)");
    let s = &id.settings;
    sec.text(format!(
        "The L1's nominal 3-DOF kinematics with compliance: each drive (the source's closed loop, {:.0} ms, {} samples of dead time) moves its cart through a drive train ({:.2e} N/m), each arm's link cluster is an axial spring ({:.2e}-{:.2e} N/m) to an {:.0} kg platform under gravity; integrated nonlinearly (geometry, preload). Carts at {:?} m; all three drives excited at once by independent random binary references of +-{:.1} mm, {:.0} s to fit, another {:.0} s to validate; tracker {:.0} µm per axis. The fit is a linear physical model about the pose (masses given, 8 stiffnesses and dampings fitted): not the simulator's model family.",
        1e3 * cell.dt_s,
        cell.servo_delay_samples,
        cell.structure.drive_n_m,
        cell.structure.link_n_m.iter().copied().fold(f64::INFINITY, f64::min),
        cell.structure.link_n_m.iter().copied().fold(0.0, f64::max),
        cell.structure.platform_kg,
        s.motors_m,
        1e3 * s.amplitude_m,
        s.estimation_s,
        s.validation_s,
        1e6 * s.tracker_sigma_m
    ));
    sec.table(
        "Modes: the physical fit (first-order standard deviations) against the truth linearised at the pose",
        &["mode", "truth (Hz)", "truth damping", "fitted (Hz)", "std (Hz)", "error"],
        id.physical_modes
            .iter()
            .zip(&id.true_modes)
            .enumerate()
            .map(|(k, (m, t))| {
                vec![
                    (k + 1).to_string(),
                    format!("{:.3}", t[0]),
                    format!("{:.3}", t[1]),
                    format!("{:.3}", m.frequency_hz),
                    format!("{:.3}", m.frequency_std_hz),
                    format!("{:+.3} %", 100.0 * m.relative_error),
                ]
            })
            .collect(),
    );
    sec.table(
        "Physical parameters",
        &["parameter", "fitted", "std", "truth"],
        id.physical
            .iter()
            .map(|(n, v, sd, t)| vec![n.clone(), format!("{v:.4e}"), format!("{sd:.2e}"), format!("{t:.4e}")])
            .collect(),
    );
    sec.table(
        "Drive loops fitted from reference to encoder (truth: pole 0.9647, 5 samples of dead time plus the hold's one)",
        &["drive", "pole", "delay (samples)", "static gain"],
        id.actuators
            .iter()
            .enumerate()
            .map(|(i, (p, nk, g))| vec![(i + 1).to_string(), format!("{p:.4}"), nk.to_string(), format!("{g:.4}")])
            .collect(),
    );
    let pts = |k: usize, v: &[[f64; 3]]| -> Vec<(f64, f64)> {
        id.frequency_hz.iter().zip(v).map(|(f, s)| (f.log10(), 20.0 * s[k].max(1e-12).log10())).collect()
    };
    let (m0, m1, m2) = (pts(0, &id.measured_singular), pts(1, &id.measured_singular), pts(2, &id.measured_singular));
    let (f0, f1, f2) = (pts(0, &id.model_singular), pts(1, &id.model_singular), pts(2, &id.model_singular));
    sec.figure(
        "Singular values of the response from the encoders to the tool (dB of m/m): measured by Welch's method (4 s segments) against the fitted model",
        plot::xy_plot(
            "encoders -> tool",
            "log10 frequency (Hz)",
            "singular value (dB)",
            &[
                Series { name: "measured 1", points: &m0, line: false },
                Series { name: "measured 2", points: &m1, line: false },
                Series { name: "measured 3", points: &m2, line: false },
                Series { name: "model 1", points: &f0, line: true },
                Series { name: "model 2", points: &f1, line: true },
                Series { name: "model 3", points: &f2, line: true },
            ],
        ),
    );
    let coh: Vec<(f64, f64)> = id.frequency_hz.iter().zip(&id.coherence).map(|(f, c)| (f.log10(), *c)).collect();
    sec.figure(
        "Mean multiple coherence of the tool with the encoders (where it is low the measured response is noise or leakage: the lightly damped first mode's peak, and above 40 Hz where the drives pass little)",
        plot::xy_plot("coherence", "log10 frequency (Hz)", "coherence", &[Series { name: "coherence", points: &coh, line: true }]),
    );
    let worst = id.physical_modes.iter().map(|m| m.relative_error.abs()).fold(0.0f64, f64::max);
    sec.data = serde_json::to_value(id).unwrap_or_default();
    sec.data["largest_mode_error"] = json!(worst);
    sec.check(Check::all(
        "3-DOF cell identification",
        &[
            Check::from_bool(
                "every resonance within 5 % of the truth",
                id.physical_modes.len() == 6 && worst < 0.05,
                format!("{} modes, largest relative error {:.3} %", id.physical_modes.len(), 100.0 * worst),
            ),
            Check::from_bool(
                "validated on a record not used to fit",
                id.validation_fit_percent > 90.0,
                format!(
                    "fit {:.2} % on the fitting record, {:.2} % on the validation record",
                    id.estimation_fit_percent, id.validation_fit_percent
                ),
            ),
        ],
    ));
    sec
}

fn poses_section(rows: &[PoseModes], s: &CellIdentifySettings) -> Section {
    let mut sec = Section::new("motion-cell-poses", "3-DOF cell: the modes over the workspace (simulated)");
    sec.text(format!(
        "The structure's modes move with the links' directions, as the source's resonances did from position to position (its Table 6.4). Each pose identified from its own {:.0} s record and validated on another {:.0} s.",
        s.estimation_s, s.validation_s
    ));
    sec.table(
        "Modes per pose: truth / fitted (Hz); largest relative error; validation fit",
        &["carts (m)", "tool (m)", "mode 1", "mode 2", "mode 3", "carts' modes", "largest error", "validation"],
        rows.iter()
            .map(|p| {
                let m = |k: usize| {
                    p.fitted.get(k).map_or("-".into(), |f| format!("{:.2} / {:.2}", f.true_hz, f.frequency_hz))
                };
                let carts = p.true_hz.iter().skip(3).map(|f| format!("{f:.1}")).collect::<Vec<_>>().join(", ");
                let worst = p.fitted.iter().map(|f| f.relative_error.abs()).fold(0.0f64, f64::max);
                vec![
                    format!("{:+.2}, {:+.2}, {:+.2}", p.motors_m[0], p.motors_m[1], p.motors_m[2]),
                    format!("{:+.3}, {:+.3}, {:+.3}", p.tool_m[0], p.tool_m[1], p.tool_m[2]),
                    m(0),
                    m(1),
                    m(2),
                    carts,
                    format!("{:.3} %", 100.0 * worst),
                    format!("{:.2} %", p.validation_fit_percent),
                ]
            })
            .collect(),
    );
    let worst = rows.iter().flat_map(|p| p.fitted.iter().map(|f| f.relative_error.abs())).fold(0.0f64, f64::max);
    let lowest: Vec<f64> = rows.iter().filter_map(|p| p.true_hz.first().copied()).collect();
    sec.data = json!({"poses": rows, "largest_mode_error": worst});
    sec.check(Check::from_bool(
        "every pose's resonances within 5 %",
        rows.iter().all(|p| p.fitted.len() == 6) && worst < 0.05,
        format!(
            "{} poses, largest relative error {:.3} %; the lowest mode between {:.2} and {:.2} Hz",
            rows.len(),
            100.0 * worst,
            lowest.iter().copied().fold(f64::INFINITY, f64::min),
            lowest.iter().copied().fold(0.0, f64::max)
        ),
    ));
    sec
}

fn ilc_section(r: &CellIlcResult) -> Section {
    let mut sec = Section::new(
        "motion-cell-ilc",
        "3-DOF cell: learning control on actuator-side and tool-side errors (simulated)",
    );
    let s = &r.settings;
    sec.text(format!(
        "A tool path out by ({:.0}, {:.0}, {:.0}) mm in {:.2} s and back, {} samples per trial, {} trials after the first; norm-optimal lifted ILC (weight {:.0e}): per drive from its identified loop on the actuator side, 3 x 3 from the identified loops and structure on the tool side. The tool estimate is the encoders' rigid kinematics plus the fitted model's deflection; the tracker measures at {:.0} µm. True tool-path RMS error (3-D) per trial.",
        1e3 * s.displacement_m[0],
        1e3 * s.displacement_m[1],
        1e3 * s.displacement_m[2],
        s.move_s,
        r.samples,
        s.iterations,
        s.weight,
        1e6 * s.tracker_sigma_m
    ));
    let pts: Vec<Vec<(f64, f64)>> = r
        .runs
        .iter()
        .map(|x| x.tool_rms_m.iter().enumerate().map(|(k, v)| (k as f64, (1e6 * v).max(1e-3).log10())).collect())
        .collect();
    let series: Vec<Series> =
        r.runs.iter().zip(&pts).map(|(x, p)| Series { name: x.case.label(), points: p, line: true }).collect();
    sec.figure(
        "Tool-path RMS error over trials (log10 µm)",
        plot::xy_plot("3-DOF cell learning control", "trial", "log10 tool RMS error (µm)", &series),
    );
    sec.table(
        "Tool-path RMS error (µm)",
        &["error learnt from", "trial 0", "trial 1", "trial 2", "trial 5", "last trial"],
        r.runs
            .iter()
            .map(|x| {
                let at = |k: usize| x.tool_rms_m.get(k).map_or("-".into(), |v| format!("{:.1}", 1e6 * v));
                vec![x.case.label().to_string(), at(0), at(1), at(2), at(5), at(x.tool_rms_m.len() - 1)]
            })
            .collect(),
    );
    let last = |c: CellIlcCase| {
        r.runs.iter().find(|x| x.case == c).and_then(|x| x.tool_rms_m.last().copied()).unwrap_or(f64::NAN)
    };
    let (act, est, meas) =
        (last(CellIlcCase::Actuator), last(CellIlcCase::ToolEstimate), last(CellIlcCase::ToolMeasurement));
    sec.data = json!({
        "settings": s,
        "samples": r.samples,
        "runs": r.runs,
        "last_trial_tool_rms_m": {
            "actuator": act,
            "tool_estimate": est,
            "tool_measurement": meas,
            "tool_camera": s.camera.as_ref().map(|_| last(CellIlcCase::ToolCamera)),
        },
    });
    sec.check(Check::from_bool(
        "tool-side learning at least 5x better than actuator-side on the cell",
        est * 5.0 < act && meas * 5.0 < act,
        format!(
            "actuator side {:.1} µm, tool estimate {:.1} µm ({:.0}x), tool measurement {:.1} µm ({:.0}x)",
            1e6 * act,
            1e6 * est,
            act / est,
            1e6 * meas,
            act / meas
        ),
    ));
    if let Some(c) = &s.camera {
        sec.text(format!(
            "Tool camera: a {} x {} px camera (f = {:.0} px) {:.2} m in front of the platform's {} x {} chessboard, a frame every {} samples, {:.1} ms exposure rendered as {} sub-frames along the 3-D path (motion blur), poses against a tare (8 still frames) at rest; learnt on the frames' samples only, each at its exposure's middle sample, the update averaged over a frame period and, after two trials, over the trials.",
            c.width_px,
            c.height_px,
            c.focal_px,
            c.distance_m,
            c.board_inner.0,
            c.board_inner.1,
            c.frame_every,
            1e3 * c.exposure_s,
            c.sub_frames
        ));
        let cam = last(CellIlcCase::ToolCamera);
        sec.check(Check::from_bool(
            "camera-in-the-loop learning at least 5x better than actuator-side on the cell",
            cam * 5.0 < act,
            format!("actuator side {:.1} µm, tool camera {:.1} µm ({:.0}x)", 1e6 * act, 1e6 * cam, act / cam),
        ));
    }
    sec
}

/// Cart positions of the pose comparison, m.
const POSES_M: [[f64; 3]; 4] = [[0.0, 0.0, 0.0], [-0.4, 0.3, 0.1], [0.3, -0.3, 0.4], [0.5, 0.5, -0.2]];

/// Runs the cell's identification (at the home pose and over the workspace) and learning control.
pub fn cell_sections(seed: u64, quick: bool, progress: &dyn Fn(&str)) -> Result<Vec<Section>> {
    let cell = CompliantCell::l1_like();
    let ids = if quick {
        CellIdentifySettings { estimation_s: 20.0, validation_s: 10.0, seed, ..Default::default() }
    } else {
        CellIdentifySettings { seed, ..Default::default() }
    };
    let id = identify_cell(&cell, &ids, progress)?;
    let mut out = vec![identification_section(&cell, &id)];
    let pose_settings = CellIdentifySettings {
        estimation_s: ids.estimation_s / 2.0,
        validation_s: ids.validation_s / 2.0,
        ..ids.clone()
    };
    let rows = identify_poses(&cell, &POSES_M, &pose_settings, progress)?;
    out.push(poses_section(&rows, &pose_settings));
    // The camera case renders every trial: the reduced camera when quick.
    let camera = if quick {
        ferrocal_datasets::motion::cell_tracking::reduced_camera()
    } else {
        ferrocal_datasets::motion::tracking::TrackingSettings::default()
    };
    let s = ferrocal_datasets::motion::cell_ilc::CellIlcSettings { seed, camera: Some(camera), ..Default::default() };
    out.push(ilc_section(&cell_ilc(&cell, &id, &s, progress)?));
    Ok(out)
}

/// The cell's report (`ferrocal motion cell`).
pub fn cell_report(seed: u64, quick: bool, progress: &dyn Fn(&str)) -> Result<Report> {
    let sections = cell_sections(seed, quick, progress)?;
    let prov = Provenance::new(json!({"seed": seed, "quick": quick}));
    let mut report =
        Report::new("The compliant 3-DOF Gantry-Tau cell: identification and learning control (simulated)", prov);
    report.sections = sections;
    Ok(report)
}

/// The demo's section: the short identification and the learning control on the cell.
pub fn demo_section(seed: u64) -> Result<Section> {
    let mut secs = cell_sections(seed, true, &|_| {})?.into_iter();
    let mut sec = secs.next().expect("identification section");
    sec.id = "motion-cell".into();
    sec.title =
        "The compliant 3-DOF Gantry-Tau cell: identification and learning control (simulated, Dressler ch. 6-7)".into();
    let mut checks: Vec<Check> = sec.status.iter().cloned().collect();
    for s in secs {
        sec.blocks.extend(s.blocks);
        checks.extend(s.status);
    }
    sec.check(Check::all("3-DOF cell identification and learning control", &checks));
    sec.text("Full experiment: `ferrocal motion cell --out DIR`; docs/motion.md.");
    Ok(sec)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cell_demo_section_passes_its_checks_and_has_the_figures() {
        let s = demo_section(2).unwrap();
        assert_eq!(s.id, "motion-cell");
        assert!(s.status.as_ref().is_some_and(Check::passed), "{:?}", s.status);
        let figures = s.blocks.iter().filter(|b| matches!(b, crate::report::Block::Figure { .. })).count();
        assert_eq!(figures, 3, "singular values, coherence, learning curves");
    }
}
