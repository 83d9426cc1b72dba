//! Report of `ferrocal motion study` and the demo's motion section: the compliant axis
//! identified from a random binary excitation (Bode plot and pole map against the truth, modes
//! with their standard deviations, validation on another record) and learning control with
//! the measurement cases of Dressler ch. 7 (tool error over trials). Simulation only; the
//! experiments are `ferrocal_datasets::motion::study`.

use crate::error::Result;
use ferrocal_calib::check::Check;
use ferrocal_calib::motion::ilc::rms as ilc_rms;
use ferrocal_calib::motion::sync::SyncSettings;
use ferrocal_datasets::motion::leadthrough::{lead_through, stability_map, LeadSettings, SensorPlacement};
use ferrocal_datasets::motion::study::{
    identify_axis, ilc_experiment, IdentifyResult, IdentifySettings, IlcRun, IlcSettings,
};
use ferrocal_datasets::motion::tracking::{
    synchronise, SyncReport, TrackedSequence, Tracker, TrackingSettings, MODEL_TIMING_STD_S,
};
use ferrocal_datasets::motion::{quintic_move, CompliantAxis, SensorNoise};
use serde_json::json;

use crate::plot::{self, Series};
use crate::report::{Provenance, Report, Section};

mod leadthrough;
use leadthrough::leadthrough_section;

/// The identification's table, Bode plot, pole map and checks.
fn identification_section(axis: &CompliantAxis, id: &IdentifyResult) -> Section {
    let mut sec = Section::new(
        "motion-identification",
        "Compliant axis: identification from a random binary excitation (simulated)",
    );
    let s = &id.settings;
    sec.text(format!(
        "One axis of an L1-like Gantry-Tau: the source's closed actuator loop at {:.0} ms (pole {:.4}, {} samples of dead time) drives a two-mass chain with modes at {:.2} and {:.2} Hz. Excitation +-{:.1} mm, {:.0} s to fit and another {:.0} s record to validate; tracker {:.0} µm at every sample, camera {:.0} µm every {}th sample. The black-box models are of the truth's family (linear, same order): this shows the method when the structure is right.",
        1e3 * axis.dt_s,
        id.true_actuator_pole,
        axis.servo_delay_samples,
        id.true_modes[0][0],
        id.true_modes[1][0],
        1e3 * s.amplitude_m,
        s.estimation_s,
        s.validation_s,
        1e6 * s.tracker_sigma_m,
        1e6 * s.camera_sigma_m,
        s.camera_every
    ));
    let modes = |m: &[[f64; 4]]| {
        if m.is_empty() {
            "-".to_string()
        } else {
            m.iter().map(|r| format!("{:.3} +- {:.3}", r[0], r[1])).collect::<Vec<_>>().join(", ")
        }
    };
    let row = |name: &str, what: &str, m: &ferrocal_datasets::motion::study::ModelReport| {
        vec![
            name.to_string(),
            what.to_string(),
            format!("{} / {}", m.a.len(), m.b.len()),
            m.delay_samples.to_string(),
            modes(&m.modes),
            format!("{:.2} %", m.estimation_fit_percent),
            format!("{:.2} %", m.validation_fit_percent),
        ]
    };
    sec.table(
        "Identified models (modes in Hz with first-order standard deviations; fit = 100 (1 - |y - y_sim| / |y - mean y|))",
        &["model", "from -> to", "order a / b", "delay (samples)", "modes (Hz)", "fit, fitting record", "fit, validation record"],
        vec![
            row("actuator", "reference -> encoder", &id.actuator),
            row("chain", "encoder -> tool (tracker rate)", &id.chain_tracker),
            row("tool", "reference -> tool (tracker rate)", &id.tool_tracker),
            row("tool, camera rate", "reference -> tool", &id.tool_camera),
            vec![
                "physical chain".into(),
                "encoder -> tool (tracker rate)".into(),
                "M, D, K (m2 given)".into(),
                "-".into(),
                modes(&id.physical_modes),
                "-".into(),
                "-".into(),
            ],
        ],
    );
    let names = ["m1 (kg)", "k1 (N/m)", "k2 (N/m)", "d1 (N s/m)", "d2 (N s/m)"];
    let c = &axis.chain;
    let truth = [c.m1_kg, c.k1_n_m, c.k2_n_m, c.d1_n_s_m, c.d2_n_s_m];
    sec.table(
        "Physical chain (the record determines the modes; m1 and k1 only through their ratio when m1 is poorly excited)",
        &["parameter", "fitted", "std", "truth"],
        names
            .iter()
            .zip(&id.physical)
            .zip(truth)
            .map(|((n, p), t)| vec![n.to_string(), format!("{:.4e}", p[0]), format!("{:.2e}", p[1]), format!("{t:.4e}")])
            .collect(),
    );
    // Bode magnitude: the truth's chain, the black box and the physical fit.
    let chain_true = axis.chain;
    let chain_fit = id.physical_chain(axis.chain.m2_kg);
    let black = id.chain_tracker.model();
    let nyquist = 0.5 / axis.dt_s;
    let freqs: Vec<f64> =
        (0..400).map(|i| 10f64.powf(-0.5 + i as f64 * (nyquist.log10() + 0.5 - 0.01) / 399.0)).collect();
    let db = |c: nalgebra::Complex<f64>| 20.0 * c.norm().log10();
    let t: Vec<(f64, f64)> = freqs.iter().map(|f| (f.log10(), db(chain_true.frequency_response(*f)))).collect();
    let b: Vec<(f64, f64)> = freqs.iter().map(|f| (f.log10(), db(black.frequency_response(*f)))).collect();
    let p: Vec<(f64, f64)> = freqs.iter().map(|f| (f.log10(), db(chain_fit.frequency_response(*f)))).collect();
    sec.figure(
        "Bode magnitude, carriage to tool: truth, black box (order 4 from the encoder; the encoder is not held between samples, so this discrete model is an approximation) and physical fit",
        plot::xy_plot(
            "carriage -> tool",
            "log10 frequency (Hz)",
            "magnitude (dB)",
            &[
                Series { name: "truth", points: &t, line: true },
                Series { name: "black box", points: &b, line: true },
                Series { name: "physical fit", points: &p, line: true },
            ],
        ),
    );
    // Pole map: identified poles and the truth's (z = exp(s dt)), with the unit circle.
    let circle: Vec<(f64, f64)> =
        (0..=180).map(|i| i as f64 * std::f64::consts::TAU / 180.0).map(|a| (a.cos(), a.sin())).collect();
    let true_poles: Vec<(f64, f64)> = id
        .true_modes
        .iter()
        .flat_map(|m| {
            let w = std::f64::consts::TAU * m[0];
            let s = nalgebra::Complex::new(-m[1] * w, w * (1.0 - m[1] * m[1]).max(0.0).sqrt());
            let z = (s * axis.dt_s).exp();
            [(z.re, z.im), (z.re, -z.im)]
        })
        .chain(std::iter::once((id.true_actuator_pole, 0.0)))
        .collect();
    let pole_pts = |m: &ferrocal_datasets::motion::study::ModelReport| -> Vec<(f64, f64)> {
        m.model().poles().iter().map(|z| (z.re, z.im)).collect()
    };
    let (pc, pa, pt) = (pole_pts(&id.chain_tracker), pole_pts(&id.actuator), pole_pts(&id.tool_tracker));
    sec.figure(
        "Pole map (z-plane at the tracker rate): the truth's modes and actuator pole against the identified models' poles",
        plot::xy_plot(
            "poles",
            "Re z",
            "Im z",
            &[
                Series { name: "unit circle", points: &circle, line: true },
                Series { name: "truth", points: &true_poles, line: false },
                Series { name: "chain (encoder -> tool)", points: &pc, line: false },
                Series { name: "actuator", points: &pa, line: false },
                Series { name: "tool (reference -> tool)", points: &pt, line: false },
            ],
        ),
    );
    let e = &id.frequency_errors;
    let worst = e
        .tracker
        .iter()
        .chain(&e.chain)
        .chain(&e.physical)
        .chain(std::iter::once(&e.camera_first))
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let pct = |v: &[f64]| v.iter().map(|x| format!("{:+.3} %", 100.0 * x)).collect::<Vec<_>>().join(", ");
    let min_val = [&id.actuator, &id.tool_tracker, &id.chain_tracker, &id.tool_camera]
        .iter()
        .map(|m| m.validation_fit_percent)
        .fold(f64::INFINITY, f64::min);
    sec.data = serde_json::to_value(id).unwrap_or_default();
    sec.check(Check::all(
        "motion identification",
        &[
            Check::from_bool(
                "resonances within 5 % of the truth",
                worst < 0.05
                    && [&e.tracker, &e.chain, &e.physical].iter().all(|v| v.len() == 2 && v.iter().all(|x| x.is_finite())),
                format!(
                    "largest relative error {:.2} % (reference -> tool: {}; encoder -> tool: {}; physical: {}; camera, first mode: {:+.3} %)",
                    100.0 * worst,
                    pct(&e.tracker),
                    pct(&e.chain),
                    pct(&e.physical),
                    100.0 * e.camera_first
                ),
            ),
            Check::from_bool(
                "validated on a record not used to fit",
                min_val > 90.0,
                format!("smallest validation fit {min_val:.2} % (actuator, tool, chain and camera-rate models)"),
            ),
        ],
    ));
    sec
}

fn case_name(r: &IlcRun) -> &'static str {
    use ferrocal_datasets::motion::study::IlcCase;
    match r.case {
        IlcCase::Actuator => "actuator (encoder)",
        IlcCase::ToolEstimate => "tool estimated from the encoder by the physical model",
        IlcCase::ToolMeasurement => "tool measured (tracker)",
        IlcCase::ToolKalman => "tool by the Kalman estimate (encoder, model, delayed camera)",
    }
}

/// The learning-control section: tool error over trials per case, table and check.
fn ilc_section(runs: &[IlcRun], s: &IlcSettings, id_suffix: &str) -> Section {
    let title = if s.contact_force_n > 0.0 {
        format!("Learning control with a {:.0} N contact force the encoder cannot see (simulated)", s.contact_force_n)
    } else {
        "Learning control on actuator-side and tool-side errors (simulated)".to_string()
    };
    let mut sec = Section::new(&format!("motion-ilc{id_suffix}"), &title);
    sec.text(format!(
        "Norm-optimal lifted ILC (weight {:.0e}) along a {:.0} mm quintic move in {:.2} s, {} trials after the first; learning matrices from the identified models. Camera every {}th sample, {} samples late, {:.0} µm. True tool-path RMS error per trial.",
        s.weight,
        1e3 * s.distance_m,
        s.move_s,
        s.iterations,
        s.camera_every,
        s.camera_delay_samples,
        1e6 * s.camera_sigma_m
    ));
    let pts: Vec<Vec<(f64, f64)>> = runs
        .iter()
        .map(|r| r.tool_rms_m.iter().enumerate().map(|(k, v)| (k as f64, (1e6 * v).max(1e-3).log10())).collect())
        .collect();
    let series: Vec<Series> =
        runs.iter().zip(&pts).map(|(r, p)| Series { name: case_name(r), points: p, line: true }).collect();
    sec.figure(
        "Tool-path RMS error over trials (log10 µm)",
        plot::xy_plot("learning control", "trial", "log10 tool RMS error (µm)", &series),
    );
    sec.table(
        "Tool-path RMS error (µm)",
        &["error measured on", "trial 0", "trial 1", "trial 2", "trial 5", "last trial"],
        runs.iter()
            .map(|r| {
                let at = |k: usize| r.tool_rms_m.get(k).map_or("-".into(), |v| format!("{:.1}", 1e6 * v));
                vec![case_name(r).to_string(), at(0), at(1), at(2), at(5), at(r.tool_rms_m.len() - 1)]
            })
            .collect(),
    );
    use ferrocal_datasets::motion::study::IlcCase;
    let last =
        |c: IlcCase| runs.iter().find(|r| r.case == c).and_then(|r| r.tool_rms_m.last().copied()).unwrap_or(f64::NAN);
    let (act, est, kal) = (last(IlcCase::Actuator), last(IlcCase::ToolEstimate), last(IlcCase::ToolKalman));
    sec.data = json!({
        "settings": s,
        "runs": runs,
        "last_trial_tool_rms_m": runs
            .iter()
            .map(|r| {
                let case = serde_json::to_value(r.case).ok().and_then(|v| v.as_str().map(String::from));
                (case.unwrap_or_default(), json!(r.tool_rms_m.last()))
            })
            .collect::<serde_json::Map<_, _>>(),
    });
    if s.contact_force_n > 0.0 {
        sec.check(Check::from_bool(
            "the camera-corrected estimate learns what the encoder cannot see",
            kal * 3.0 < est && kal * 5.0 < act,
            format!(
                "Kalman {:.1} µm, model-only estimate {:.1} µm, actuator side {:.1} µm",
                1e6 * kal,
                1e6 * est,
                1e6 * act
            ),
        ));
    } else {
        sec.check(Check::from_bool(
            "tool-side learning at least 5x better than actuator-side",
            est * 5.0 < act,
            format!("tool estimate {:.1} µm against actuator side {:.1} µm ({:.0}x)", 1e6 * est, 1e6 * act, act / est),
        ));
    }
    sec
}

/// The vision-tracking section: a chessboard on the moving tool, rendered with motion blur.
fn tracking_section(s: &TrackingSettings, seq: &TrackedSequence, sync: &TrackingSync) -> Section {
    let mut sec =
        Section::new("motion-tracking", "Vision tracking of the moving tool (rendered frames with motion blur)");
    sec.text(format!(
        "A {}x{} camera (f = {:.0} px) {:.2} m from a {}x{} chessboard of {:.0} mm squares on the tool; one frame every {} axis samples, {:.1} ms exposure rendered as the mean of {} sub-frames (the plate moves during the exposure), shot and read noise, the sub-pixel edge detector and the pose with the corners' covariances; positions along the axis relative to a still frame (the tare). Latency (exposure's second half and {:.1} ms processing): {:.1} ms = {} samples. The camera model is the renderer's own (a calibrated camera assumed).",
        s.width_px, s.height_px, s.focal_px, s.distance_m, s.board_inner.0, s.board_inner.1, 1e3 * s.square_m, s.frame_every, 1e3 * s.exposure_s, s.sub_frames, 1e3 * s.processing_s, 1e3 * seq.latency_s, seq.latency_samples
    ));
    let err: Vec<(f64, f64)> =
        seq.frames.iter().map(|f| (f.sample as f64, 1e6 * (f.position_m - f.truth_mean_m))).collect();
    let up: Vec<(f64, f64)> = seq.frames.iter().map(|f| (f.sample as f64, 3e6 * f.std_m)).collect();
    let down: Vec<(f64, f64)> = up.iter().map(|p| (p.0, -p.1)).collect();
    sec.figure(
        "Tracking error per frame against the exposure-averaged truth, with the stated +-3 sigma",
        plot::xy_plot(
            "vision tracking",
            "axis sample",
            "error (µm)",
            &[
                Series { name: "error", points: &err, line: false },
                Series { name: "+3 sigma", points: &up, line: true },
                Series { name: "-3 sigma", points: &down, line: true },
            ],
        ),
    );
    let rms = ilc_rms(&seq.frames.iter().map(|f| f.position_m - f.truth_mean_m).collect::<Vec<_>>());
    let z = ilc_rms(&seq.frames.iter().map(|f| (f.position_m - f.truth_mean_m) / f.std_m).collect::<Vec<_>>());
    let sigma = ilc_rms(&seq.frames.iter().map(|f| f.std_m).collect::<Vec<_>>());
    sec.data = json!({"settings": s, "frames": seq.frames.len(), "missed": seq.missed, "rms_error_m": rms, "rms_sigma_m": sigma, "rms_error_over_sigma": z, "latency_samples": seq.latency_samples, "clock_sync": sync.chain, "clock_sync_encoder_only": sync.encoder_only.as_ref().ok(), "frames_mapped_to_capture_sample": sync.frames_mapped});
    let accuracy = Check::from_bool(
        "tracked positions within their stated uncertainty",
        seq.missed.is_empty() && !seq.frames.is_empty() && z < 3.0,
        format!(
            "{} frames, {} missed; RMS error {:.2} µm, stated sigma {:.2} µm (RMS of error / sigma {z:.2})",
            seq.frames.len(),
            seq.missed.len(),
            1e6 * rms,
            1e6 * sigma
        ),
    );
    let r = &sync.chain;
    sec.text(format!(
        "Synchronisation: the camera stamps its frames on its own clock ({:.1} ms ahead of the encoder's in this simulation, {:.0} ppm); the offset is estimated from the data (ferrocal_calib::motion::sync): the tool track the identified physical chain predicts from the encoder, interpolated by a cubic spline and averaged over each exposure, against the {} frames inside the record, a 1 ms grid search over -50..100 ms and Gauss-Newton on the offset and a position bias; the standard deviation from the residual and the track's slope ({:.1} µs), with a stated model timing uncertainty of {:.0} µs in quadrature (what the residual cannot show: the chain driven by the linearly interpolated encoder, and the blurred board's detection error that grows with the speed, a time shift of 3-12 µs each in studies over seeds). Estimated {:.4} ms +- {:.4} ms (truth {:.4} ms, error {:+.2} µs = {:+.2} sigma; reduced chi-square {:.2}, residual RMS {:.2} µm). {} With the estimate every frame's stamp maps to its capture sample ({} of {}), which the Kalman case of learning control below assumes; without it each frame would be taken {:.1} samples late.",
        1e3 * r.true_offset_s,
        r.true_rate_ppm,
        r.frames_used,
        1e6 * r.offset_std_fit_s,
        1e6 * MODEL_TIMING_STD_S,
        1e3 * r.offset_s,
        1e3 * r.offset_std_s,
        1e3 * r.true_offset_s,
        1e6 * (r.offset_s - r.true_offset_s),
        r.offset_z(),
        r.reduced_chi2,
        1e6 * r.residual_rms_m,
        match &sync.encoder_only {
            Ok(e) => format!(
                "With the encoder itself as the model (no chain) the estimate is {:.4} ms +- {:.4} ms ({:+.1} sigma from the truth): the structure's lag and oscillation, not in the model, bias it.",
                1e3 * e.offset_s,
                1e3 * e.offset_std_s,
                e.offset_z()
            ),
            Err(e) => format!("With the encoder itself as the model the estimator refuses: {e}."),
        },
        sync.frames_mapped,
        seq.frames.len(),
        r.true_offset_s / sync.dt_s
    ));
    let clock = Check::from_bool(
        "camera clock offset within 3 sigma of the truth",
        r.offset_z().abs() < 3.0 && r.offset_std_s < 1e-3 && sync.frames_mapped == seq.frames.len(),
        format!(
            "estimated {:.4} +- {:.4} ms, truth {:.4} ms ({:+.2} sigma); {} of {} frames mapped to their capture sample",
            1e3 * r.offset_s,
            1e3 * r.offset_std_s,
            1e3 * r.true_offset_s,
            r.offset_z(),
            sync.frames_mapped,
            seq.frames.len()
        ),
    );
    sec.check(Check::all("vision tracking", &[accuracy, clock]));
    sec
}

/// The camera clock estimated in the tracking experiment.
struct TrackingSync {
    /// Against the track the identified chain predicts from the encoder.
    chain: SyncReport,
    /// Against the encoder itself as the model (for comparison), or why it was refused.
    encoder_only: std::result::Result<SyncReport, String>,
    /// Frames whose stamp, mapped to the encoder clock by the estimate, rounds to their capture
    /// sample.
    frames_mapped: usize,
    dt_s: f64,
}

/// The tracker's settings: the 1 MP camera, or with `quick` a 640 x 400 one closer to the board.
fn tracking_settings(quick: bool, seed: u64) -> TrackingSettings {
    if quick {
        TrackingSettings {
            width_px: 640,
            height_px: 400,
            focal_px: 700.0,
            distance_m: 0.6,
            seed,
            ..TrackingSettings::default()
        }
    } else {
        TrackingSettings { seed, ..TrackingSettings::default() }
    }
}

/// Tracks the tool along the learning-control move (the first trial, no learning) and returns
/// the sequence with its settings and the camera clock estimated against the chain identified
/// in `id`.
fn tracking_experiment(
    axis: &CompliantAxis,
    id: &IdentifyResult,
    quick: bool,
    seed: u64,
) -> Result<(TrackingSettings, TrackedSequence, TrackingSync)> {
    let s = tracking_settings(quick, seed);
    let il = IlcSettings::default();
    let n = ((0.1 + il.move_s + 0.2) / axis.dt_s).round() as usize;
    let rec = axis.run(&quintic_move(n, axis.dt_s, 0.1, il.move_s, il.distance_m), SensorNoise::default(), seed)?;
    let seq = Tracker::new(&s)?.track(&rec.tool_true_m, axis.dt_s)?;
    let dt = axis.dt_s;
    let predicted = id.physical_chain(axis.chain.m2_kg).simulate(&rec.encoder_m, dt, 8);
    let sync = SyncSettings { model_timing_std_s: MODEL_TIMING_STD_S, ..SyncSettings::default() };
    let (clock, chain) = synchronise(&seq, &s, &predicted, dt, &sync)?;
    let encoder_only = synchronise(&seq, &s, &rec.encoder_m, dt, &sync).map(|r| r.1).map_err(|e| e.to_string());
    let frames_mapped =
        seq.frames.iter().filter(|f| (clock.encoder_time_s(f.stamp_s) / dt).round() as usize == f.sample).count();
    Ok((s, seq, TrackingSync { chain, encoder_only, frames_mapped, dt_s: dt }))
}

/// The identification experiment's settings: 60 s to fit and 30 s to validate, or with `quick`
/// 20 s and 10 s.
fn identify_settings(seed: u64, quick: bool) -> IdentifySettings {
    if quick {
        IdentifySettings { estimation_s: 20.0, validation_s: 10.0, seed, ..IdentifySettings::default() }
    } else {
        IdentifySettings { seed, ..IdentifySettings::default() }
    }
}

/// Options of the learning-control experiment (`ferrocal motion ilc` and `motion study`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct IlcOptions {
    /// Contact force of the second variant, N (0: only the variant without).
    pub contact_force_n: f64,
    /// Trials after the first.
    pub iterations: usize,
}

impl Default for IlcOptions {
    /// A 20 N contact force, ten trials after the first.
    fn default() -> Self {
        Self { contact_force_n: 20.0, iterations: IlcSettings::default().iterations }
    }
}

/// The learning-control sections (without and, when `o.contact_force_n > 0`, with a contact
/// force), the camera's frame period and latency those of the tracker `ts`.
fn ilc_sections(
    axis: &CompliantAxis,
    id: &IdentifyResult,
    camera_every: usize,
    camera_delay_samples: usize,
    seed: u64,
    o: &IlcOptions,
    progress: &dyn Fn(&str),
) -> Result<Vec<Section>> {
    progress("learning control");
    let s0 =
        IlcSettings { seed, camera_every, camera_delay_samples, iterations: o.iterations, ..IlcSettings::default() };
    let mut out = vec![ilc_section(&ilc_experiment(axis, id, &s0)?, &s0, "")];
    if o.contact_force_n > 0.0 {
        progress("learning control under a contact force");
        let s1 = IlcSettings { contact_force_n: o.contact_force_n, ..s0.clone() };
        out.push(ilc_section(&ilc_experiment(axis, id, &s1)?, &s1, "-contact"));
    }
    Ok(out)
}

/// Runs the experiments: identification, vision tracking, learning control without and with a
/// contact force (the Kalman case with the tracked camera's latency), lead-through.
pub fn study_sections(seed: u64, quick: bool, contact_force_n: f64, progress: &dyn Fn(&str)) -> Result<Vec<Section>> {
    let axis = CompliantAxis::l1_like();
    progress("identification");
    let id = identify_axis(&axis, &identify_settings(seed, quick))?;
    let mut out = vec![identification_section(&axis, &id)];
    progress("vision tracking");
    let (ts, seq, sync) = tracking_experiment(&axis, &id, quick, seed)?;
    out.push(tracking_section(&ts, &seq, &sync));
    let o = IlcOptions { contact_force_n, ..IlcOptions::default() };
    out.extend(ilc_sections(&axis, &id, ts.frame_every, seq.latency_samples, seed, &o, progress)?);
    progress("lead-through");
    out.push(leadthrough_section(&axis, &LeadSettings::default())?);
    Ok(out)
}

fn report_of(title: &str, settings: serde_json::Value, sections: Vec<Section>) -> Report {
    let mut report = Report::new(title, Provenance::new(settings));
    report.sections = sections;
    report
}

/// The study's report (`ferrocal motion study`): every experiment of the chapters 6-8.
pub fn study_report(seed: u64, quick: bool, contact_force_n: f64, progress: &dyn Fn(&str)) -> Result<Report> {
    let sections = study_sections(seed, quick, contact_force_n, progress)?;
    Ok(report_of(
        "Compliance dynamics and learning control on tool-side estimates (simulated)",
        json!({"seed": seed, "quick": quick, "contact_force_n": contact_force_n}),
        sections,
    ))
}

/// Chapter 6 (`ferrocal motion identify`): the identification with its Bode plot, pole map and
/// validation fits.
pub fn identify_report(seed: u64, quick: bool, progress: &dyn Fn(&str)) -> Result<Report> {
    let axis = CompliantAxis::l1_like();
    progress("identification");
    let id = identify_axis(&axis, &identify_settings(seed, quick))?;
    Ok(report_of(
        "Compliant axis: identification and validation (simulated, Dressler ch. 6)",
        json!({"experiment": "identify", "seed": seed, "quick": quick}),
        vec![identification_section(&axis, &id)],
    ))
}

/// Chapter 7 (`ferrocal motion ilc`): learning control over trials, without and with a contact
/// force. The learning matrices come from the identification (run first, as in the study, and
/// summarised by its check); the camera's frame period and latency are the tracker's (a still
/// frame is tracked to read them, no move is rendered).
pub fn ilc_report(seed: u64, quick: bool, o: &IlcOptions, progress: &dyn Fn(&str)) -> Result<Report> {
    let axis = CompliantAxis::l1_like();
    progress("identification (for the learning matrices)");
    let id = identify_axis(&axis, &identify_settings(seed, quick))?;
    let mut idsec = identification_section(&axis, &id);
    idsec.blocks.retain(|b| !matches!(b, crate::report::Block::Figure { .. }));
    let ts = tracking_settings(quick, seed);
    let latency = Tracker::new(&ts)?.track(&[0.0], axis.dt_s)?.latency_samples;
    let mut sections = vec![idsec];
    sections.extend(ilc_sections(&axis, &id, ts.frame_every, latency, seed, o, progress)?);
    Ok(report_of(
        "Learning control on actuator-side and tool-side errors (simulated, Dressler ch. 7)",
        json!({"experiment": "ilc", "seed": seed, "quick": quick, "contact_force_n": o.contact_force_n, "iterations": o.iterations}),
        sections,
    ))
}

/// The rendered camera tracking (`ferrocal motion track`): the tool along the learning-control
/// move, tracked in motion-blurred frames.
pub fn track_report(seed: u64, quick: bool, progress: &dyn Fn(&str)) -> Result<Report> {
    let axis = CompliantAxis::l1_like();
    // The chain that predicts the tool track for the clock's synchronisation.
    progress("identification (the chain for the camera clock)");
    let id = identify_axis(&axis, &identify_settings(seed, quick))?;
    progress("vision tracking");
    let (ts, seq, sync) = tracking_experiment(&axis, &id, quick, seed)?;
    Ok(report_of(
        "Vision tracking of the moving tool (simulated, rendered frames)",
        json!({"experiment": "track", "seed": seed, "quick": quick}),
        vec![tracking_section(&ts, &seq, &sync)],
    ))
}

/// Chapter 8 (`ferrocal motion leadthrough`): a guided move with the given settings and the
/// stability map over admittances and force filters.
pub fn leadthrough_report(s: &LeadSettings, progress: &dyn Fn(&str)) -> Result<Report> {
    let axis = CompliantAxis::l1_like();
    progress("lead-through");
    Ok(report_of(
        "Lead-through with tool force feedback (simulated, Dressler ch. 8)",
        json!({"experiment": "leadthrough", "settings": s}),
        vec![leadthrough_section(&axis, s)?],
    ))
}

/// The demo's section: the short identification and both learning-control experiments.
pub fn demo_section(seed: u64) -> Result<Section> {
    let mut secs = study_sections(seed, true, 20.0, &|_| {})?.into_iter();
    let mut sec = secs.next().expect("identification section");
    sec.id = "motion".into();
    sec.title = "Compliance dynamics, tool estimation and learning control (simulated, Dressler ch. 6-7)".into();
    let mut checks: Vec<Check> = sec.status.iter().cloned().collect();
    for s in secs {
        sec.blocks.extend(s.blocks);
        checks.extend(s.status);
    }
    sec.check(Check::all("motion identification and learning control", &checks));
    sec.text("Full study: `ferrocal motion study --out DIR [--contact-force-n 20]`; one experiment: `ferrocal motion identify|ilc|track|leadthrough --out DIR`; docs/motion.md.");
    Ok(sec)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demo_section_passes_its_checks_and_has_the_figures() {
        let s = demo_section(3).unwrap();
        assert_eq!(s.id, "motion");
        assert!(s.status.as_ref().is_some_and(Check::passed), "{:?}", s.status);
        let figures = s.blocks.iter().filter(|b| matches!(b, crate::report::Block::Figure { .. })).count();
        assert_eq!(
            figures, 8,
            "Bode, pole map, tracking errors, two learning curves, lead-through move, force and sensor placement"
        );
    }
}
