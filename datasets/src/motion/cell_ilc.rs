//! Iterative learning control on the compliant 3-DOF cell (issue [motion] item 5 for the whole
//! cell, Dressler ch. 7): a tool path out and back, the drives' references learnt over trials
//! from three errors side by side:
//!
//! - actuator side: each drive's encoder against the rigid inverse kinematics of the path,
//!   learnt per drive from its identified closed loop (what the drives alone can do);
//! - tool estimate: the tool estimated from the encoders (their rigid kinematics plus the
//!   identified physical model's deflection), learnt from the cell's identified response (drive
//!   loops times structure, 3 x 3);
//! - tool measurement: the tracker's tool position, learnt from the same response;
//! - tool camera (when a camera is set): the tool's displacement from rendered, motion-blurred
//!   camera frames ([`super::cell_tracking`]) at the camera's frame rate, learnt from the same
//!   response on the frames' samples only (`MimoIlc::norm_optimal_sampled`: the other samples
//!   carry no error, so they get zero weight rather than a held or interpolated guess; holding
//!   the last frame's error would lag it by half a frame period on average and teach a phase
//!   error into the references). Each frame stands at its exposure's middle sample (learning is
//!   offline between trials, so the latency drops out); a missed frame's sample gets the linear
//!   interpolation of its neighbours. The update is averaged over one frame period (the
//!   frame-rate ripple the frames cannot see) and, after two trials, averaged over the trials
//!   (the camera's depth noise).
//!
//! Every trial starts at rest where the previous one did; the desired path starts at the tool's
//! rest position (a static offset at rest is a calibration matter, not a learning one). The
//! learning uses only identified models; the trials run on the nonlinear simulator.

use ferrocal_calib::motion::ilc::{rms, Ilc};
use ferrocal_calib::motion::mimo_ilc::MimoIlc;
use nalgebra::Vector3;
use serde::Serialize;

use super::cell::CompliantCell;
use super::cell_study::CellIdentifyResult;
use super::cell_tracking::{per_sample, CellCamera};
use super::tracking::TrackingSettings;
use crate::error::{DatasetError, Result};

/// Settings of the cell's learning experiment.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CellIlcSettings {
    /// Trials.
    pub iterations: usize,
    /// The path's far point relative to the start, m.
    pub displacement_m: [f64; 3],
    /// Duration of the move out (and of the move back), s.
    pub move_s: f64,
    /// Input weight of the norm-optimal updates.
    pub weight: f64,
    /// Tracker noise per axis, m.
    pub tracker_sigma_m: f64,
    /// Seed of the sensor noise.
    pub seed: u64,
    /// The camera of the tool-camera case (`None`: that case is not run).
    pub camera: Option<TrackingSettings>,
}

impl Default for CellIlcSettings {
    /// Ten trials of a move of (30, 20, -15) mm out in 0.5 s, a pause, and back, weight 1e-4, a
    /// tracker at 10 µm, the default tracking camera.
    fn default() -> Self {
        Self {
            iterations: 10,
            displacement_m: [0.03, 0.02, -0.015],
            move_s: 0.5,
            weight: 1e-4,
            tracker_sigma_m: 10e-6,
            seed: 1,
            camera: Some(TrackingSettings::default()),
        }
    }
}

/// Which error the cell learns from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum CellIlcCase {
    /// The encoders against the rigid inverse kinematics.
    Actuator,
    /// The tool estimated from the encoders through the identified model.
    ToolEstimate,
    /// The tracker's tool measurement.
    ToolMeasurement,
    /// The tool's displacement from rendered camera frames.
    ToolCamera,
}

impl CellIlcCase {
    /// A label for tables and plots.
    pub fn label(&self) -> &'static str {
        match self {
            Self::Actuator => "actuator side",
            Self::ToolEstimate => "tool estimate (model)",
            Self::ToolMeasurement => "tool measurement (tracker)",
            Self::ToolCamera => "tool camera (rendered frames)",
        }
    }
}

/// One case's course over the trials.
#[derive(Clone, Debug, Serialize)]
pub struct CellIlcRun {
    /// The case.
    pub case: CellIlcCase,
    /// RMS of the true tool-path error (3-D distance) per trial, trial 0 the unlearnt one, m.
    pub tool_rms_m: Vec<f64>,
    /// RMS of the error the case learns from, per trial, m.
    pub learnt_rms_m: Vec<f64>,
}

/// The learning experiment's results.
#[derive(Clone, Debug, Serialize)]
pub struct CellIlcResult {
    /// Settings used.
    pub settings: CellIlcSettings,
    /// The cases (the camera's last, when it has a camera).
    pub runs: Vec<CellIlcRun>,
    /// Trial length, samples.
    pub samples: usize,
}

fn quintic(s: f64) -> f64 {
    let s = s.clamp(0.0, 1.0);
    s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)
}

/// The identified impulse response from the drives' references to the tool over `n` samples
/// (`h[k][r][c]`: tool axis `r`, `k` samples after a unit impulse on drive `c`'s reference): each
/// drive's fitted loop, then the fitted structure.
pub fn reference_to_tool_impulse_response(id: &CellIdentifyResult, n: usize) -> Result<Vec<[[f64; 3]; 3]>> {
    let (Some(fit), Some(geometry)) = (id.fit.as_ref(), id.geometry.as_ref()) else {
        return Err(DatasetError::Input("cell ILC: the identification carries no fitted model".into()));
    };
    if id.actuator_models.len() != 3 {
        return Err(DatasetError::Input("cell ILC: the identification carries no drive models".into()));
    }
    let dt = id.actuator_models[0].dt_s;
    let mut h = vec![[[0.0; 3]; 3]; n];
    for (c, model) in id.actuator_models.iter().enumerate() {
        let act = model.impulse_response(n);
        let motors: Vec<[f64; 3]> =
            act.iter().map(|&a| std::array::from_fn(|j| if j == c { a } else { 0.0 })).collect();
        for (hk, y) in h.iter_mut().zip(fit.structure.simulate(geometry, &motors, dt)) {
            for (row, yr) in hk.iter_mut().zip(y) {
                row[c] = yr;
            }
        }
    }
    Ok(h)
}

/// The camera case's Q-filter: a centred moving average over one frame period (`m` samples;
/// the window clamped at the trial's ends). Learning from the frames' samples alone leaves a
/// ripple at the frame rate and its harmonics, which the frames cannot see (zero at every frame);
/// this average has zeros exactly there and passes the structure's band (0.85 at 16 Hz for 5
/// samples at 4 ms), so the learning's fixed point in that band is kept.
fn frame_comb(du: &[[f64; 3]], m: usize) -> Vec<[f64; 3]> {
    let n = du.len();
    if m <= 1 || n == 0 {
        return du.to_vec();
    }
    (0..n)
        .map(|k| {
            let mut acc = [0.0; 3];
            for i in 0..m {
                // Centred: offsets -(m-1)/2 ..= m/2 (for even m the extra sample is ahead).
                let j = (k + i).saturating_sub((m - 1) / 2).min(n - 1);
                (0..3).for_each(|c| acc[c] += du[j][c]);
            }
            acc.map(|v| v / m as f64)
        })
        .collect()
}

/// The camera case's learning gain after trial `it`: full for the first two updates (the
/// deterministic error, far above the camera's noise), then `1 / it`, which averages the later
/// trials' corrections (trial averaging: the camera's depth noise, tens of micrometres per frame,
/// would otherwise be learnt into every trial's references afresh).
fn camera_gain(it: usize) -> f64 {
    if it < 2 {
        1.0
    } else {
        1.0 / it as f64
    }
}

/// Runs the learning cases on the cell, from its identification at the same pose.
pub fn cell_ilc(
    cell: &CompliantCell,
    id: &CellIdentifyResult,
    s: &CellIlcSettings,
    progress: &dyn Fn(&str),
) -> Result<CellIlcResult> {
    if s.iterations == 0 || !(s.move_s > 0.0 && s.weight > 0.0 && s.tracker_sigma_m >= 0.0) {
        return Err(DatasetError::Input(format!(
            "cell ILC: iterations, move time and weight must be positive, the tracker noise not negative: {s:?}"
        )));
    }
    let (Some(fit), Some(geometry)) = (id.fit.as_ref(), id.geometry.as_ref()) else {
        return Err(DatasetError::Input("cell ILC: the identification carries no fitted model".into()));
    };
    if id.actuator_models.len() != 3 {
        return Err(DatasetError::Input("cell ILC: the identification carries no drive models".into()));
    }
    let dt = cell.dt_s;
    let a0 = id.settings.motors_m;
    // Path: rest 0.2 s, out, pause 0.2 s, back, rest 0.4 s.
    let (rest0, pause, tail) = (0.2, 0.2, 0.4);
    let total = rest0 + 2.0 * s.move_s + pause + tail;
    let n = (total / dt).round() as usize;
    let shape: Vec<f64> = (0..n)
        .map(|k| {
            let t = k as f64 * dt;
            quintic((t - rest0) / s.move_s) - quintic((t - rest0 - s.move_s - pause) / s.move_s)
        })
        .collect();
    let d = Vector3::from(s.displacement_m);
    let rigid0 = cell.rigid_tool(&a0)?;
    let rest = cell.equilibrium(a0)?;
    let tool_rest = Vector3::new(rest[9], rest[10], rest[11]);
    let desired: Vec<Vector3<f64>> = shape.iter().map(|&x| tool_rest + d * x).collect();
    let joints: Vec<[f64; 3]> = shape.iter().map(|&x| cell.rigid_joints(&(rigid0 + d * x))).collect::<Result<_>>()?;
    progress(&format!("cell ILC: {n} samples per trial; learning matrices"));

    let act_h: Vec<Vec<f64>> = id.actuator_models.iter().map(|m| m.impulse_response(n)).collect();
    let h = reference_to_tool_impulse_response(id, n)?;
    let mimo = MimoIlc::norm_optimal(&h, s.weight).map_err(|e| DatasetError::Input(format!("cell ILC: {e}")))?;
    let siso: Vec<Ilc> = act_h
        .iter()
        .map(|h| Ilc::norm_optimal(h, s.weight).map_err(|e| DatasetError::Input(format!("cell ILC: {e}"))))
        .collect::<Result<_>>()?;

    // The tool estimated from the encoders: the rigid kinematics of the encoders (nonlinear),
    // plus the model's deflection (its response minus its static part), plus the sag at rest.
    let g0 = fit.structure.frequency_response(geometry, 0.0);
    let sag = tool_rest - rigid0;
    let estimate = |enc: &[[f64; 3]]| -> Result<Vec<[f64; 3]>> {
        let motors: Vec<[f64; 3]> = enc.iter().map(|a| [0, 1, 2].map(|j| a[j] - a0[j])).collect();
        let dynamic = fit.structure.simulate(geometry, &motors, dt);
        enc.iter()
            .zip(&motors)
            .zip(&dynamic)
            .map(|((a, m), y)| {
                let rigid = cell.rigid_tool(a)?;
                Ok([0, 1, 2].map(|r| rigid[r] + sag[r] + y[r] - (0..3).map(|c| g0[r][c].re * m[c]).sum::<f64>()))
            })
            .collect()
    };
    let tool_err = |tool: &[[f64; 3]]| -> Vec<[f64; 3]> {
        tool.iter().zip(&desired).map(|(t, d)| [0, 1, 2].map(|j| d[j] - t[j])).collect()
    };
    let rms3 = |e: &[[f64; 3]]| rms(&e.iter().map(|v| Vector3::from(*v).norm()).collect::<Vec<_>>());
    let camera = s.camera.as_ref().map(CellCamera::new).transpose()?;
    // The camera's learning matrix weighs the error at the frames' samples only.
    let mimo_cam = camera
        .as_ref()
        .map(|c| {
            let frames: Vec<usize> = (0..n).step_by(c.settings().frame_every).collect();
            MimoIlc::norm_optimal_sampled(&h, s.weight, &frames)
                .map_err(|e| DatasetError::Input(format!("cell ILC: {e}")))
        })
        .transpose()?;
    let mut cases = vec![CellIlcCase::Actuator, CellIlcCase::ToolEstimate, CellIlcCase::ToolMeasurement];
    if camera.is_some() {
        cases.push(CellIlcCase::ToolCamera);
    }
    let mut runs = Vec::new();
    for case in cases {
        let mut u = joints.clone();
        let mut run = CellIlcRun { case, tool_rms_m: Vec::new(), learnt_rms_m: Vec::new() };
        for it in 0..=s.iterations {
            let rec = cell.run_from(a0, &u, 1e-6, s.tracker_sigma_m, s.seed + 100 * it as u64)?;
            run.tool_rms_m.push(rms3(&tool_err(&rec.tool_true_m)));
            let e: Vec<[f64; 3]> = match case {
                CellIlcCase::Actuator => {
                    rec.encoder_m.iter().zip(&joints).map(|(a, q)| [0, 1, 2].map(|j| q[j] - a[j])).collect()
                }
                CellIlcCase::ToolEstimate => tool_err(&estimate(&rec.encoder_m)?),
                CellIlcCase::ToolMeasurement => tool_err(&rec.tool_measured_m),
                CellIlcCase::ToolCamera => {
                    let cam = camera.as_ref().ok_or_else(|| DatasetError::Input("cell ILC: no camera".into()))?;
                    let seq = cam.track(&rec.tool_true_m, dt, s.seed + 100 * it as u64)?;
                    let shown = per_sample(&seq.frames, n)
                        .ok_or_else(|| DatasetError::Input(format!("cell ILC: no camera frame in trial {it}")))?;
                    // The tare is the rest pose, so the desired displacement is the path's.
                    shown.iter().zip(&shape).map(|(m, &x)| [0, 1, 2].map(|j| d[j] * x - m[j])).collect()
                }
            };
            run.learnt_rms_m.push(rms3(&e));
            if it == s.iterations {
                break;
            }
            u = match case {
                CellIlcCase::Actuator => {
                    let mut next = u.clone();
                    for (j, l) in siso.iter().enumerate() {
                        let uj: Vec<f64> = u.iter().map(|v| v[j]).collect();
                        let ej: Vec<f64> = e.iter().map(|v| v[j]).collect();
                        let nj = l.update(&uj, &ej).map_err(|e| DatasetError::Input(format!("cell ILC: {e}")))?;
                        next.iter_mut().zip(nj).for_each(|(v, x)| v[j] = x);
                    }
                    next
                }
                CellIlcCase::ToolCamera => {
                    let (l, c) = mimo_cam
                        .as_ref()
                        .zip(camera.as_ref())
                        .ok_or_else(|| DatasetError::Input("cell ILC: no camera".into()))?;
                    let next = l.update(&u, &e).map_err(|e| DatasetError::Input(format!("cell ILC: {e}")))?;
                    let du: Vec<[f64; 3]> = next.iter().zip(&u).map(|(a, b)| [0, 1, 2].map(|j| a[j] - b[j])).collect();
                    let q = frame_comb(&du, c.settings().frame_every);
                    let gain = camera_gain(it);
                    u.iter().zip(&q).map(|(a, b)| [0, 1, 2].map(|j| a[j] + gain * b[j])).collect()
                }
                _ => mimo.update(&u, &e).map_err(|e| DatasetError::Input(format!("cell ILC: {e}")))?,
            };
        }
        progress(&format!(
            "cell ILC {}: tool RMS {:.1} -> {:.1} µm",
            case.label(),
            run.tool_rms_m[0] * 1e6,
            run.tool_rms_m.last().copied().unwrap_or(f64::NAN) * 1e6
        ));
        runs.push(run);
    }
    Ok(CellIlcResult { settings: s.clone(), runs, samples: n })
}

#[cfg(test)]
mod tests {
    use super::super::cell_study::{identify_cell, CellIdentifySettings};
    use super::super::cell_tracking::reduced_camera;
    use super::*;

    #[test]
    fn tool_side_learning_removes_the_compliance_error_the_drives_leave() {
        let cell = CompliantCell::l1_like();
        let ids = CellIdentifySettings { estimation_s: 20.0, validation_s: 5.0, ..Default::default() };
        let id = identify_cell(&cell, &ids, &|_| {}).unwrap();
        // The camera case renders every trial's frames at the reduced resolution (dev profile).
        let s = CellIlcSettings { iterations: 6, camera: Some(reduced_camera()), ..Default::default() };
        let r = cell_ilc(&cell, &id, &s, &|m| eprintln!("{m}")).unwrap();
        let last = |c: CellIlcCase| *r.runs.iter().find(|x| x.case == c).unwrap().tool_rms_m.last().unwrap();
        let (act, meas) = (last(CellIlcCase::Actuator), last(CellIlcCase::ToolMeasurement));
        let est = last(CellIlcCase::ToolEstimate);
        assert!(
            meas * 5.0 < act && est * 5.0 < act,
            "actuator {act} m, tool estimate {est} m, tool measurement {meas} m"
        );
        let cam = last(CellIlcCase::ToolCamera);
        assert!(cam * 5.0 < act, "actuator {act} m, tool camera {cam} m");
    }
}
