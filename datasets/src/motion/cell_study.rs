//! Identification of the compliant 3-DOF cell (issue [motion] item 3 for the whole cell): all
//! three drives excited at once by independent random binary references about one pose, the
//! tool measured by a tracker; the frequency response from the encoders to the tool and its
//! singular values' peaks (non-parametric), and the linear physical model of
//! `ferrocal_calib::motion::mimo_fit` fitted to the record and validated on another.

use ferrocal_calib::motion::identify::{self, DiscreteModel};
use ferrocal_calib::motion::mimo_fit::{self, CellFit, CellGeometry, CellStructure};
use ferrocal_calib::motion::mimo_frf;
use serde::Serialize;

use super::cell::CompliantCell;
use super::random_binary_reference;
use crate::error::{DatasetError, Result};

/// Settings of the cell's identification.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CellIdentifySettings {
    /// Motor positions of the pose, m.
    pub motors_m: [f64; 3],
    /// Length of the estimation record, s.
    pub estimation_s: f64,
    /// Length of the validation record (other excitations), s.
    pub validation_s: f64,
    /// Excitation amplitude of every drive, m.
    pub amplitude_m: f64,
    /// Samples per level of the random binary excitations.
    pub hold_samples: usize,
    /// Tracker noise per axis, m.
    pub tracker_sigma_m: f64,
    /// Encoder resolution, m.
    pub encoder_resolution_m: f64,
    /// Welch segment, samples.
    pub segment: usize,
    /// Disjoint blocks for the peaks' standard deviations.
    pub blocks: usize,
    /// Seed.
    pub seed: u64,
}

impl Default for CellIdentifySettings {
    /// The carts at zero; 60 s to fit, 30 s to validate, +-2 mm, a tracker at 10 µm every 4 ms,
    /// 1 µm encoders, segments of 1024 samples (0.24 Hz), four blocks.
    fn default() -> Self {
        Self {
            motors_m: [0.0; 3],
            estimation_s: 60.0,
            validation_s: 30.0,
            amplitude_m: 0.002,
            hold_samples: 1,
            tracker_sigma_m: 10e-6,
            encoder_resolution_m: 1e-6,
            segment: 1024,
            blocks: 4,
            seed: 1,
        }
    }
}

/// One mode compared with the truth.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ModeComparison {
    /// Estimated frequency, Hz.
    pub frequency_hz: f64,
    /// Its standard deviation, Hz.
    pub frequency_std_hz: f64,
    /// The true mode it is compared with, Hz.
    pub true_hz: f64,
    /// Relative error.
    pub relative_error: f64,
}

/// The cell's identification results.
#[derive(Clone, Debug, Serialize)]
pub struct CellIdentifyResult {
    /// Settings used.
    pub settings: CellIdentifySettings,
    /// The truth's modes at the pose `(Hz, damping)` (the simulator linearised with its preload).
    pub true_modes: Vec<[f64; 2]>,
    /// The dominant resonance of the measured response (the fit's start), Hz.
    pub dominant_hz: f64,
    /// The fitted physical model's modes compared with the true modes in order.
    pub physical_modes: Vec<ModeComparison>,
    /// The fitted physical parameters `(name, value, std, truth)`.
    pub physical: Vec<(String, f64, f64, f64)>,
    /// Fit on the estimation record, percent.
    pub estimation_fit_percent: f64,
    /// Fit on the validation record (not used to fit), percent.
    pub validation_fit_percent: f64,
    /// Standard deviation of the tool's simulation error, m.
    pub residual_std_m: f64,
    /// Frequencies of the response plots, Hz.
    pub frequency_hz: Vec<f64>,
    /// Singular values of the measured response at those frequencies.
    pub measured_singular: Vec<[f64; 3]>,
    /// Singular values of the fitted model's response.
    pub model_singular: Vec<[f64; 3]>,
    /// Mean coherence of the outputs with the inputs.
    pub coherence: Vec<f64>,
    /// Each drive's closed loop fitted from its reference to its encoder (order 1):
    /// `(pole, dead time in samples, static gain)`.
    pub actuators: Vec<(f64, usize, f64)>,
    /// The drives' fitted models.
    #[serde(skip)]
    pub actuator_models: Vec<DiscreteModel>,
    /// The geometry used by the fit.
    #[serde(skip)]
    pub geometry: Option<CellGeometry>,
    /// The fit itself.
    #[serde(skip)]
    pub fit: Option<CellFit>,
}

fn references(n: usize, s: &CellIdentifySettings, seed: u64) -> Vec<[f64; 3]> {
    let r: Vec<Vec<f64>> =
        (0..3).map(|i| random_binary_reference(n, s.hold_samples, s.amplitude_m, seed * 7 + i as u64)).collect();
    (0..n).map(|k| [0, 1, 2].map(|i| s.motors_m[i] + r[i][k])).collect()
}

fn singular_of(h: &[[nalgebra::Complex<f64>; 3]; 3]) -> [f64; 3] {
    let m = nalgebra::DMatrix::from_fn(3, 3, |r, c| h[r][c]);
    let sv = m.singular_values();
    let mut s = [sv[0], sv[1], sv[2]];
    s.sort_by(|a, b| b.total_cmp(a));
    s
}

/// Runs the identification of the cell at one pose.
pub fn identify_cell(
    cell: &CompliantCell,
    s: &CellIdentifySettings,
    progress: &dyn Fn(&str),
) -> Result<CellIdentifyResult> {
    if !(s.estimation_s > 0.0 && s.validation_s > 0.0 && s.amplitude_m > 0.0 && s.blocks >= 1) {
        return Err(DatasetError::Input(format!(
            "cell identification: record lengths, amplitude and blocks must be positive: {s:?}"
        )));
    }
    let n_est = (s.estimation_s / cell.dt_s).round() as usize;
    let n_val = (s.validation_s / cell.dt_s).round() as usize;
    progress(&format!("cell: simulating {:.0} s + {:.0} s of excitation at 3 drives", s.estimation_s, s.validation_s));
    let rest = |n: usize, seed: u64| {
        let mut r = vec![s.motors_m; 50];
        r.extend(references(n, s, seed));
        r
    };
    let est = cell.run(&rest(n_est, s.seed), s.encoder_resolution_m, s.tracker_sigma_m, s.seed)?;
    let val = cell.run(&rest(n_val, s.seed + 1000), s.encoder_resolution_m, s.tracker_sigma_m, s.seed + 1000)?;
    let truth = cell.modes_at(s.motors_m)?;
    let true_modes: Vec<[f64; 2]> = truth.iter().map(|m| [m.frequency_hz, m.damping]).collect();
    progress("cell: frequency response; fitting the physical model");
    let frf = mimo_frf::welch_frf(&est.encoder_m, &est.tool_measured_m, cell.dt_s, s.segment)
        .map_err(|e| DatasetError::Input(format!("cell identification: {e}")))?;
    // A data-driven start: equal links, the drive ten times stiffer, all scaled so that the
    // lowest mode sits on the response's dominant resonance; 2 % damping.
    let geometry = cell.geometry_at(s.motors_m)?;
    let dominant = frf.dominant_hz(1.0, 0.45 / cell.dt_s).ok_or_else(|| {
        DatasetError::Input("cell identification: the frequency response shows no resonance to start from".into())
    })?;
    let unit = |k: f64| CellStructure {
        platform_kg: cell.platform_kg,
        cart_kg: cell.cart_kg,
        drive_n_m: 10.0 * k,
        drive_n_s_m: 2.0 * 0.02 * (10.0 * k * cell.cart_kg).sqrt(),
        link_n_m: [k; 3],
        link_n_s_m: [2.0 * 0.02 * (k * cell.platform_kg).sqrt(); 3],
    };
    let f1 = unit(1.0).modes(&geometry).first().map(|m| m.0).unwrap_or(f64::NAN);
    let start = unit((dominant / f1).powi(2));
    let fit = mimo_fit::fit_cell(&geometry, &est.encoder_m, &est.tool_measured_m, cell.dt_s, &start)
        .map_err(|e| DatasetError::Input(format!("cell identification: {e}")))?;
    let fit_of = |rec: &super::cell::CellRecord| {
        let a0 = rec.encoder_m[0];
        let motors: Vec<[f64; 3]> = rec.encoder_m.iter().map(|r| [0, 1, 2].map(|j| r[j] - a0[j])).collect();
        let rest = [0, 1, 2].map(|j| rec.tool_measured_m[..10].iter().map(|r| r[j]).sum::<f64>() / 10.0);
        let sim: Vec<[f64; 3]> = fit
            .structure
            .simulate(&geometry, &motors, cell.dt_s)
            .iter()
            .map(|r| [0, 1, 2].map(|j| r[j] + rest[j]))
            .collect();
        mimo_fit::fit_percent_3(&rec.tool_measured_m, &sim)
    };
    let physical_modes: Vec<ModeComparison> = fit
        .modes
        .iter()
        .zip(&truth)
        .map(|(m, t)| ModeComparison {
            frequency_hz: m.frequency_hz,
            frequency_std_hz: m.frequency_std_hz,
            true_hz: t.frequency_hz,
            relative_error: m.frequency_hz / t.frequency_hz - 1.0,
        })
        .collect();
    progress("cell: the drives' closed loops");
    let mut actuator_models = Vec::new();
    for i in 0..3 {
        let r: Vec<f64> = est.reference_m.iter().map(|v| v[i]).collect();
        let a: Vec<f64> = est.encoder_m.iter().map(|v| v[i]).collect();
        let c = |e| DatasetError::Input(format!("cell identification: drive {}: {e}", i + 1));
        let nk = identify::estimate_delay(&r, &a, 1, 1, 12, cell.dt_s).map_err(c)?;
        actuator_models.push(identify::fit_output_error(&r, &a, 1, 1, nk, cell.dt_s).map_err(c)?);
    }
    let actuators = actuator_models.iter().map(|m| (-m.a[0], m.nk, m.dc_gain())).collect();
    let tv = cell.structure();
    let truth_free = [
        tv.link_n_m[0],
        tv.link_n_m[1],
        tv.link_n_m[2],
        tv.link_n_s_m[0],
        tv.link_n_s_m[1],
        tv.link_n_s_m[2],
        tv.drive_n_m,
        tv.drive_n_s_m,
    ];
    let fs = fit.structure;
    let fitted = [
        fs.link_n_m[0],
        fs.link_n_m[1],
        fs.link_n_m[2],
        fs.link_n_s_m[0],
        fs.link_n_s_m[1],
        fs.link_n_s_m[2],
        fs.drive_n_m,
        fs.drive_n_s_m,
    ];
    let physical = CellStructure::parameter_names()
        .iter()
        .enumerate()
        .map(|(i, n)| (n.to_string(), fitted[i], fit.std[i], truth_free[i]))
        .collect();
    let model_singular = frf.frequency_hz.iter().map(|&f| singular_of(&fs.frequency_response(&geometry, f))).collect();
    Ok(CellIdentifyResult {
        settings: s.clone(),
        true_modes,
        dominant_hz: dominant,
        physical_modes,
        physical,
        estimation_fit_percent: fit_of(&est),
        validation_fit_percent: fit_of(&val),
        residual_std_m: fit.residual_std_m,
        frequency_hz: frf.frequency_hz.clone(),
        measured_singular: frf.singular.clone(),
        model_singular,
        actuators,
        actuator_models,
        coherence: frf.coherence.iter().map(|c| c.iter().sum::<f64>() / 3.0).collect(),
        geometry: Some(geometry),
        fit: Some(fit),
    })
}

/// The modes at one pose: the truth's and the physical fit's.
#[derive(Clone, Debug, Serialize)]
pub struct PoseModes {
    /// Motor positions, m.
    pub motors_m: [f64; 3],
    /// The tool at rest there, m.
    pub tool_m: [f64; 3],
    /// The truth's mode frequencies, Hz.
    pub true_hz: Vec<f64>,
    /// The fitted modes compared with them.
    pub fitted: Vec<ModeComparison>,
    /// Validation fit, percent.
    pub validation_fit_percent: f64,
}

/// Identifies the cell at several poses (the structure's modes move with the links' directions,
/// as the source's resonances did over the workspace), each from its own records.
pub fn identify_poses(
    cell: &CompliantCell,
    poses_m: &[[f64; 3]],
    s: &CellIdentifySettings,
    progress: &dyn Fn(&str),
) -> Result<Vec<PoseModes>> {
    poses_m
        .iter()
        .enumerate()
        .map(|(k, p)| {
            progress(&format!("cell: pose {} of {} (motors {p:?} m)", k + 1, poses_m.len()));
            let r = identify_cell(
                cell,
                &CellIdentifySettings { motors_m: *p, seed: s.seed + 10 * k as u64, ..s.clone() },
                &|_| {},
            )?;
            let x = cell.equilibrium(*p)?;
            Ok(PoseModes {
                motors_m: *p,
                tool_m: [x[9], x[10], x[11]],
                true_hz: r.true_modes.iter().map(|m| m[0]).collect(),
                fitted: r.physical_modes.clone(),
                validation_fit_percent: r.validation_fit_percent,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_short_record_finds_the_cells_modes_within_five_percent_and_validates() {
        let cell = CompliantCell::l1_like();
        let s = CellIdentifySettings { estimation_s: 20.0, validation_s: 10.0, ..Default::default() };
        let r = identify_cell(&cell, &s, &|m| eprintln!("{m}")).unwrap();
        eprintln!("truth {:?}", r.true_modes);
        eprintln!("physical {:?}", r.physical_modes);
        eprintln!("params {:?}", r.physical);
        eprintln!("fit {} / {} %", r.estimation_fit_percent, r.validation_fit_percent);
        assert!(r.physical_modes.iter().all(|m| m.relative_error.abs() < 0.05), "{:?}", r.physical_modes);
        assert!(r.validation_fit_percent > 90.0, "{}", r.validation_fit_percent);
        for (pole, nk, gain) in &r.actuators {
            assert!((pole - 0.9647).abs() < 2e-3 && *nk == 6 && (gain - 1.0).abs() < 0.01, "{:?}", r.actuators);
        }
        // The measured response agrees with the model's where it is coherent.
        let close = (0..r.frequency_hz.len())
            .filter(|&k| r.coherence[k] > 0.95)
            .all(|k| (r.measured_singular[k][0] / r.model_singular[k][0] - 1.0).abs() < 0.15);
        assert!(close);
    }

    #[test]
    fn the_modes_move_over_the_workspace_and_are_found_at_every_pose() {
        let cell = CompliantCell::l1_like();
        let s = CellIdentifySettings { estimation_s: 10.0, validation_s: 5.0, ..Default::default() };
        let poses = [[0.0; 3], [-0.4, 0.3, 0.1], [0.3, -0.3, 0.4]];
        let r = identify_poses(&cell, &poses, &s, &|_| {}).unwrap();
        for p in &r {
            eprintln!(
                "{:?} {:?} {:?}",
                p.motors_m,
                p.true_hz,
                p.fitted.iter().map(|m| m.relative_error).collect::<Vec<_>>()
            );
            assert!(p.fitted.iter().all(|m| m.relative_error.abs() < 0.05), "{p:?}");
        }
        let lowest: Vec<f64> = r.iter().map(|p| p.true_hz[0]).collect();
        let spread = lowest.iter().copied().fold(0.0, f64::max) / lowest.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(spread > 1.02, "the lowest mode hardly moves: {lowest:?}");
    }
}
