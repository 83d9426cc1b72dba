//! The motion experiments of Dressler ch. 6-7 on the simulated compliant axis, a short seeded
//! version of `cargo run --release -p ferrocal-datasets --example motion_study`. The truth is a
//! linear two-mass chain behind a delayed first-order actuator loop; the black-box models are of
//! the truth's family, the physical fit integrates the same structure by its own Runge-Kutta code
//! (same family, different discretisation): these tolerances are what the method achieves when
//! the model structure is right.

use ferrocal_datasets::motion::study::{identify_axis, ilc_experiment, IdentifySettings, IlcCase, IlcSettings};
use ferrocal_datasets::motion::CompliantAxis;

#[test]
fn identification_finds_both_modes_within_5_percent_and_tool_side_ilc_beats_actuator_side_5x() {
    let axis = CompliantAxis::l1_like();
    let truth = axis.modes().unwrap();
    let settings = IdentifySettings { estimation_s: 20.0, validation_s: 10.0, seed: 7, ..IdentifySettings::default() };
    let id = identify_axis(&axis, &settings).unwrap();

    // Resonances: the tracker-rate black boxes (reference and encoder to tool) and the physical
    // chain both modes, the camera-rate model the first (the second is above its Nyquist frequency).
    let e = &id.frequency_errors;
    for (what, err) in [("tracker", &e.tracker), ("chain", &e.chain), ("physical", &e.physical)] {
        assert_eq!(err.len(), 2, "{what}: {err:?}");
        assert!(err.iter().all(|v| v.abs() < 0.05), "{what} mode errors {err:?} (truth {truth:?})");
    }
    assert!(e.camera_first.abs() < 0.05, "camera first mode error {}", e.camera_first);
    // Each identified frequency's own sigma covers the truth at 4 sigma for the physical fit.
    for (m, t) in id.physical_modes.iter().zip(&truth) {
        assert!((m[0] - t.frequency_hz).abs() < 4.0 * m[1] + 0.002 * t.frequency_hz, "physical mode {m:?} vs {t:?}");
    }
    // Validated on a record not used to fit: the simulation reproduces it.
    for (what, m) in [
        ("actuator", &id.actuator),
        ("tool", &id.tool_tracker),
        ("chain", &id.chain_tracker),
        ("camera", &id.tool_camera),
    ] {
        assert!(m.validation_fit_percent > 95.0, "{what} validation fit {:.2} %", m.validation_fit_percent);
    }
    // The actuator loop: the source's pole 0.9647 and five samples of dead time (six from the
    // reference to the encoder reading, which is read before the update).
    assert!((-id.actuator.a[0] - id.true_actuator_pole).abs() < 1e-4, "pole {:?}", id.actuator.a);
    assert_eq!(id.actuator.delay_samples, 6);

    // Learning control along a 20 mm move in 0.15 s: actuator-side learning leaves the
    // compliance error in, tool-side learning removes it.
    let runs = ilc_experiment(&axis, &id, &IlcSettings { seed: 7, ..IlcSettings::default() }).unwrap();
    let last = |c: IlcCase| *runs.iter().find(|r| r.case == c).unwrap().tool_rms_m.last().unwrap();
    let first = runs[0].tool_rms_m[0];
    let (act, est, meas) = (last(IlcCase::Actuator), last(IlcCase::ToolEstimate), last(IlcCase::ToolMeasurement));
    assert!(act > 0.03 * first, "actuator-side ILC: tool error {act} of {first} m");
    assert!(est * 5.0 < act, "tool-estimate ILC {est} m vs actuator-side {act} m");
    assert!(meas * 5.0 < act, "tool-measurement ILC {meas} m vs actuator-side {act} m");
    // The measured case stops at the tracker's noise (10 µm per sample, averaged by the filter).
    assert!(meas < 20e-6, "tool-measurement ILC {meas} m");

    // A 20 N contact force after the move, which the encoder cannot see: learning on the model's
    // estimate from the encoder converges to the wrong path, learning on the Kalman estimate
    // (encoder, model and a 50 Hz camera 12 ms late) does not.
    let runs =
        ilc_experiment(&axis, &id, &IlcSettings { seed: 7, contact_force_n: 20.0, ..IlcSettings::default() }).unwrap();
    let last = |c: IlcCase| *runs.iter().find(|r| r.case == c).unwrap().tool_rms_m.last().unwrap();
    let (act, est, kal) = (last(IlcCase::Actuator), last(IlcCase::ToolEstimate), last(IlcCase::ToolKalman));
    assert!(est > 2e-4, "model-only estimate under contact: {est} m");
    assert!(kal * 3.0 < est && kal * 5.0 < act, "Kalman {kal} m, model only {est} m, actuator {act} m");
}
