//! The demo's section on the target's physics in the hand-eye chain: a simulated eye-to-hand
//! recording whose printed sheet is rolled onto a cylinder and printed long along x, the
//! selection on the training images ([`select_chain_physics`]), and the held-out images with
//! and without what it found.

use crate::error::Result;
use ferrocal_calib::check::Check;
use ferrocal_calib::handeye::physics::{select_chain_physics, PhysicsOptions};
use ferrocal_calib::handeye::{calibrate_hand_eye, HandEyeOptions, Mount};
use ferrocal_datasets::handeye::sim::{simulate_hand_eye, HandEyeSimConfig};
use serde_json::json;

use crate::report::Section;

/// The roll radius of the simulated sheet, metres (a sag of about 0.45 mm at its x edges).
const ROLL_RADIUS_M: f64 = 16.0;

/// The printed x spacing over the y spacing.
const PRINT_ASPECT: f64 = 1.003;

/// The section: seed `seed`, 24 training and 12 held-out images (16 and 8 when `quick`).
pub fn physics_section(seed: u64, quick: bool) -> Result<Section> {
    let mut s = Section::new("handeye-physics", "The target's true shape in the hand-eye chain");
    let (n_train, n_test) = if quick { (16, 8) } else { (24, 12) };
    let config = HandEyeSimConfig {
        n_train,
        n_test,
        roll_radius_m: Some(ROLL_RADIUS_M),
        print_aspect: PRINT_ASPECT,
        ..HandEyeSimConfig::default_for(Mount::EyeToHand)
    };
    let (data, _) = simulate_hand_eye(&config, seed)?;
    let base = HandEyeOptions { fit_target_scale: true, ..HandEyeOptions::default() };
    let report = select_chain_physics(&data, &base, &PhysicsOptions::default())?;
    let flat = calibrate_hand_eye(&data, &base)?;
    let fit = calibrate_hand_eye(&data, &report.chosen.options(&base))?;
    let before = flat.figures.heldout_rms_px.unwrap_or(f64::NAN);
    let after = fit.figures.heldout_rms_px.unwrap_or(f64::NAN);
    let half_m = 4.0 * config.spacing_m * PRINT_ASPECT;
    let sag_mm = ROLL_RADIUS_M * (1.0 - (half_m / ROLL_RADIUS_M).cos()) * 1e3;
    s.text(format!(
        "A simulated eye-to-hand cell (1280 x 960 px camera, a 9 x 6 grid at 30 mm on the flange, 0.1 px corner \
         noise, 0.05 mm robot noise, seed {seed}, {n_train} training and {n_test} held-out images) whose printed \
         sheet is rolled onto a cylinder of {ROLL_RADIUS_M} m radius ({sag_mm:.3} mm out of plane at its x edges, \
         lengths kept along the arc) and printed {:.1} % long along x. The chain's bending model is quadratic \
         (bowl, saddle, twist), not a cylinder: the bending is not of the estimator's model family; the print \
         scale is. `handeye` tries each effect on the training images alone (K folds; the held-out images take \
         no part) and keeps what predicts held-out training images better; `--no-physics` skips this.",
        (PRINT_ASPECT - 1.0) * 100.0
    ));
    s.text(super::physics::physics_line(&report));
    for f in &report.findings {
        s.text(f.statement.clone());
    }
    let mut rows = vec![vec![
        "held-out chain RMS (px)".to_string(),
        format!("{before:.4}"),
        format!("{after:.4}"),
        "-".to_string(),
    ]];
    if let Some(form) = &fit.target_form {
        let d = &form.deformation;
        if let Some(std) = form.shape_std_m {
            rows.push(vec![
                "bowl / saddle / twist at the edge (mm)".into(),
                "0 / 0 / 0 (flat)".into(),
                format!(
                    "{:.3} / {:.3} / {:.3} (+- {:.3})",
                    d.shape_m[0] * 1e3,
                    d.shape_m[1] * 1e3,
                    d.shape_m[2] * 1e3,
                    std[0] * 1e3
                ),
                format!("{:.3} / {:.3} / 0 (the cylinder)", sag_mm / 2.0, sag_mm / 2.0),
            ]);
        }
        if let Some(std) = form.scale_x_std {
            rows.push(vec![
                "x against y print scale (ppm)".into(),
                "0".into(),
                format!("{:.0} +- {:.0}", d.scale[0] * 1e6, std * 1e6),
                format!("{:.0}", (PRINT_ASPECT - 1.0) * 1e6),
            ]);
        }
    }
    s.table("Without and with the physics found", &["quantity", "flat target", "with the physics", "truth"], rows);
    let found: Vec<&str> = report.findings.iter().map(|f| f.effect.as_str()).collect();
    let both = found.contains(&"target_nonflatness") && found.contains(&"target_print_scale");
    s.data = json!({"seed": seed, "physics": report, "heldout_rms_px": {"flat": before, "with_physics": after}});
    s.check(Check::from_bool(
        "the bent, long-printed target is found on the training images and improves held-out images",
        both && after < before,
        format!("found {found:?}; held-out chain RMS {before:.4} -> {after:.4} px"),
    ));
    Ok(s)
}
