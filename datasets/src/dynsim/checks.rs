//! The pass/fail checks of the dynamics study (`ferrocal dynamics study`, the demo): each
//! experiment's result against what the sources found, as a [`Check`] that can fail.

use ferrocal_calib::check::Check;

use super::study::{ExcitationStudy, FilteringStudy, HexapodStudy, ModelsStudy, PayloadRow, ReductionStudy};

/// A model-3-like estimate is biased when its mass is this many standard deviations off.
pub const BIAS_SIGMAS: f64 = 5.0;
/// The largest |estimate - truth| / std an unbiased model (4, 5, 8, 9, the hexapod) may show.
pub const MAX_NORMALISED_ERROR: f64 = 4.5;
/// The largest relative error of a re-identified total mass or payload.
pub const MAX_PAYLOAD_ERROR: f64 = 0.01;

/// The source's Table 3 pattern: models 0 to 2 biased in mass, 4, 5, 8 and 9 within
/// [`MAX_NORMALISED_ERROR`] of the truth, model 3 refused.
pub fn models(s: &ModelsStudy) -> Check {
    let m = s.true_mass_kg;
    let row = |id: u8| s.rows.iter().find(|r| r.model == id);
    let biased = |id: u8| row(id).and_then(|r| r.mass_kg).is_some_and(|(v, sd)| (v - m).abs() > BIAS_SIGMAS * sd);
    let ok = [0u8, 1, 2].iter().all(|&i| biased(i))
        && [4u8, 5, 8, 9]
            .iter()
            .all(|&i| row(i).and_then(|r| r.max_normalised_error).is_some_and(|e| e < MAX_NORMALISED_ERROR))
        && row(3).is_some_and(|r| r.refused.is_some());
    Check::from_bool(
        "force-sensor models 0 to 9",
        ok,
        if ok { "pattern of the source's Table 3" } else { "pattern NOT reproduced" },
    )
}

/// The worst relative error of the re-identified total masses and payloads of `rows`.
pub fn worst_payload_error(rows: &[PayloadRow], true_mass_kg: f64) -> f64 {
    let mut worst: f64 = 0.0;
    for r in rows {
        let total = true_mass_kg + r.payload_kg;
        worst = worst.max(((r.static_mass_kg - total) / total).abs()).max(((r.dynamic_mass_kg - total) / total).abs());
        if r.payload_kg > 0.0 {
            worst = worst
                .max(((r.static_payload_kg - r.payload_kg) / r.payload_kg).abs())
                .max(((r.dynamic_payload_kg - r.payload_kg) / r.payload_kg).abs());
        }
    }
    worst
}

/// Payload steps re-identified within [`MAX_PAYLOAD_ERROR`].
pub fn payload(rows: &[PayloadRow], true_mass_kg: f64) -> Check {
    let worst = worst_payload_error(rows, true_mass_kg);
    Check::from_bool(
        "payload steps",
        worst < MAX_PAYLOAD_ERROR,
        format!("worst {:.2} % (target 1 %, source -3.9 %)", 100.0 * worst),
    )
}

/// Pose reduction: the minimum before the rank is lost is the source's 3 poses, and the
/// deviations grow.
pub fn reduction(r: &ReductionStudy) -> Check {
    let red = &r.reduction;
    Check::from_bool(
        "quasi-static pose reduction",
        red.history.minimum_count == 3 && red.median_ratio > 1.0,
        format!("growth {:.1}x (source ~5x), minimum {} (source 3)", red.median_ratio, red.history.minimum_count),
    )
}

/// The worst |estimate - truth| / std of the hexapod's parameters.
pub fn worst_hexapod_error(h: &HexapodStudy) -> f64 {
    (0..h.names.len()).map(|i| ((h.fit.values[i] - h.truth[i]) / h.fit.std[i]).abs()).fold(0.0, f64::max)
}

/// Hexapod rigid-body and friction parameters within [`MAX_NORMALISED_ERROR`] of the truth.
pub fn hexapod(h: &HexapodStudy) -> Check {
    let worst = worst_hexapod_error(h);
    Check::from_bool("hexapod parameters", worst < MAX_NORMALISED_ERROR, format!("worst {worst:.1} sigma"))
}

/// The D-optimal excitation gives smaller deviations for at least two thirds of the parameters.
pub fn excitation(e: &ExcitationStudy) -> Check {
    Check::from_bool(
        "D-optimal against condition-number excitation",
        e.d_better * 3 >= 2 * e.names.len(),
        format!("D better for {} of 24", e.d_better),
    )
}

/// Frequency-domain processing predicts the validation trajectory better than time-domain
/// processing (the source's finding).
pub fn filtering(fs: &FilteringStudy) -> Check {
    let ok = fs.rows[0].validation_rms_n < fs.rows[1].validation_rms_n;
    Check::from_bool(
        "frequency- against time-domain processing",
        ok,
        if ok { "frequency domain predicts better" } else { "time domain predicts better" },
    )
}
