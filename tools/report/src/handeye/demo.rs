//! The demo's hand-eye section: the two real robot-camera recordings of ROS-Industrial's
//! industrial_calibration examples, imported and calibrated as a user would (`import ic-handeye
//! --test-every 2`, then `handeye` with the camera calibrated from the training images), with the
//! robot poses exact (the default) or as noisy measurements, the print scale fitted (the default)
//! or nominal, OpenCV's best hand-eye solver beside them on the same corners, and the source's own
//! acceptance thresholds.

use std::path::Path;

use crate::error::{Context, Result};
use ferrocal_calib::check::Check;
use ferrocal_calib::handeye::opencv::{best_baseline, opencv_baselines};
use ferrocal_calib::handeye::{calibrate_hand_eye, ChainFigures, HandEyeOptions, IntrinsicsMode};
use ferrocal_datasets::handeye::{import_ic_handeye, load_recording, read_handeye_poses};
use ferrocal_datasets::import::images::expand_image_specs;
use ferrocal_vision::calib::CalibrationOptions;
use serde_json::json;

use crate::report::Section;

/// The recordings' attribution, shown wherever results on them are.
pub const IC_ATTRIBUTION: &str = "ROS-Industrial industrial_calibration example data, Apache-2.0";

/// One real set and the source's thresholds for it.
struct RealSet {
    folder: &'static str,
    /// The source's mean camera-to-target difference against per-image PnP: mm, degrees.
    pnp_limit: (f64, f64),
}

const SETS: [RealSet; 2] = [
    RealSet { folder: "test_set_charuco", pnp_limit: (6.0, 1.5) },
    RealSet { folder: "test_set_10x10", pnp_limit: (20.0, 3.0) },
];

/// The source's limit on the fit's residual RMS, pixels.
const SOURCE_RMS_LIMIT_PX: f64 = 1.5;

struct Run {
    label: &'static str,
    ours: ChainFigures,
    opencv: Option<(String, ChainFigures)>,
}

/// A demo section on the industrial_calibration recordings (`id`, `title`), with their
/// attribution, and their folder under `data` with `work` created; no folder (and the section
/// says it is skipped) when the data is not present.
pub(crate) fn ic_section(
    id: &str,
    title: &str,
    data: &Path,
    work: &Path,
) -> Result<(Section, Option<std::path::PathBuf>)> {
    let mut s = Section::new(id, title);
    s.attribution(IC_ATTRIBUTION);
    let root = data.join("industrial_calibration");
    if !root.exists() {
        s.skipped(format!("{} is not present", root.display()));
        return Ok((s, None));
    }
    std::fs::create_dir_all(work).with_context(|| format!("creating {}", work.display()))?;
    Ok((s, Some(root)))
}

/// The section; `data` is `../shared/data`, `work` a folder for the imported poses tables.
pub fn demo_section(data: &Path, work: &Path, tick: crate::demo::Tick) -> Result<Section> {
    let (mut s, root) = ic_section("handeye-real", "Hand-eye calibration on real robot-camera recordings", data, work)?;
    let Some(root) = root else { return Ok(s) };
    let mut rows = Vec::new();
    let mut checks = Vec::new();
    let mut data_json = Vec::new();
    let mut warnings = Vec::new();
    let mut scales = Vec::new();
    let mut cells: Vec<(String, String)> = Vec::new();
    for (k, set) in SETS.iter().enumerate() {
        tick("hand-eye (real)", k as u64, SETS.len() as u64);
        let dir = root.join(set.folder);
        let csv = work.join(format!("{}.poses.csv", set.folder));
        let ic = import_ic_handeye(&dir, &csv, Some(2), None)?;
        let pattern_text =
            ic.pattern.clone().with_context(|| format!("{}: no target in cal_data.yaml", dir.display()))?;
        let pattern: ferrocal_vision::detect::Pattern = pattern_text.parse()?;
        let table = read_handeye_poses(&csv)?;
        let flange = table.flange_poses(None)?;
        let mut skipped_images = Vec::new();
        let paths = expand_image_specs(&[dir.join("images")], &mut skipped_images);
        let (rec, skipped) = load_recording(&paths, &table, &flange, &pattern, ic.mount)?;
        let mut runs = Vec::new();
        for (label, exact, scale) in [
            ("robot poses exact, print scale fitted (default)", true, true),
            ("exact, nominal scale", true, false),
            ("as measurements, print scale fitted", false, true),
            ("as measurements, nominal scale", false, false),
        ] {
            let mut options = HandEyeOptions {
                intrinsics: IntrinsicsMode::Calibrate(CalibrationOptions::default()),
                fit_target_scale: scale,
                ..HandEyeOptions::default()
            };
            if !exact {
                (options.robot_sigma_m, options.robot_sigma_rad) = HandEyeOptions::MEASURED_POSE_SIGMAS;
            }
            let r = calibrate_hand_eye(&rec, &options).with_context(|| format!("hand-eye on {}", dir.display()))?;
            let camera = r.initial_camera.as_ref().map_or(r.camera, |c| c.camera);
            let baselines = opencv_baselines(&rec, &options, &camera);
            let opencv = best_baseline(&baselines)
                .and_then(|b| b.figures.clone().map(|f| (format!("{} {}", b.function, b.method), f)));
            warnings.extend(r.warnings.iter().map(|w| format!("{} ({}): {w}", set.folder, label)));
            if let Some((v, sd)) = r.target_scale {
                scales.push(format!("{} ({label}): {v:.5} +- {sd:.5}", set.folder));
            }
            if runs.is_empty() {
                let (caption, svg) = super::scene::cell_figure(&r, &rec);
                cells.push((format!("{} ({}, {label}): {caption}", set.folder, ic.mount.name()), svg));
            }
            runs.push(Run { label, ours: r.figures, opencv });
        }
        for run in &runs {
            let f = &run.ours;
            rows.push(vec![
                set.folder.to_string(),
                run.label.to_string(),
                f4(Some(f.train_rms_px)),
                f4(f.heldout_rms_px),
                run.opencv.as_ref().map_or("-".into(), |(_, o)| f4(o.heldout_rms_px)),
                format!("{} / {}", f4(f.heldout_pnp_position_mm), f4(f.heldout_pnp_rotation_deg)),
                run.opencv.as_ref().map_or("-".into(), |(_, o)| {
                    format!("{} / {}", f4(o.heldout_pnp_position_mm), f4(o.heldout_pnp_rotation_deg))
                }),
                format!("{} mm / {} deg", set.pnp_limit.0, set.pnp_limit.1),
            ]);
            data_json.push(json!({
                "set": set.folder, "pattern": pattern_text, "mount": ic.mount.name(), "mode": run.label,
                "ours": run.ours, "opencv_best": run.opencv.as_ref().map(|(n, f)| json!({"method": n, "figures": f})),
                "images": paths.len(), "skipped": skipped.len() + skipped_images.len(),
            }));
        }
        let default = &runs[0].ours;
        let within = default.heldout_pnp_position_mm.is_some_and(|p| p < set.pnp_limit.0)
            && default.heldout_pnp_rotation_deg.is_some_and(|r| r < set.pnp_limit.1);
        checks.push((
            within,
            format!(
                "{}: held-out PnP agreement {} mm / {} deg (source: < {} mm / {} deg)",
                set.folder,
                f4(default.heldout_pnp_position_mm),
                f4(default.heldout_pnp_rotation_deg),
                set.pnp_limit.0,
                set.pnp_limit.1
            ),
        ));
        let exact = &runs[0];
        let beats = match (exact.ours.heldout_rms_px, exact.opencv.as_ref().and_then(|(_, o)| o.heldout_rms_px)) {
            (Some(a), Some(b)) => a < b,
            _ => false,
        };
        checks.push((
            beats,
            format!(
                "{}: held-out chain RMS (default: exact poses, print scale fitted) {} px against OpenCV's best {} px",
                set.folder,
                f4(exact.ours.heldout_rms_px),
                exact.opencv.as_ref().map_or("-".into(), |(_, o)| f4(o.heldout_rms_px))
            ),
        ));
        checks.push((
            exact.ours.train_rms_px < SOURCE_RMS_LIMIT_PX
                && exact.ours.heldout_rms_px.is_some_and(|h| h < SOURCE_RMS_LIMIT_PX),
            format!(
                "{}: fit residual RMS {:.4} px, held-out {} px (source: fit < {SOURCE_RMS_LIMIT_PX} px)",
                set.folder,
                exact.ours.train_rms_px,
                f4(exact.ours.heldout_rms_px)
            ),
        ));
    }
    tick("hand-eye (real)", SETS.len() as u64, SETS.len() as u64);
    s.text(
        "Each set is imported with every second image held out (`ferrocal import ic-handeye --test-every 2`); \
         the camera is calibrated from the training images and refined with the chain in pixels; OpenCV's \
         hand-eye solvers run on the same corners with the same camera and the best of them is shown. \
         The held-out images are used by no fit. The chain RMS predicts each image's corners from the \
         reported robot pose, the hand-eye transform and the fixed frame; the PnP agreement compares the \
         chain's camera-to-target pose with a per-image PnP, which is the source's own acceptance measure; \
         the PnP uses the same target geometry as the chain (the fitted print scale where it is fitted). \
         On both recordings, taking the robot poses as exact predicts held-out pixels better than modelling \
         them as independent noisy measurements: the robots' errors here are systematic, not per-pose noise.",
    );
    s.table(
        "Real recordings (held-out: every second image)",
        &[
            "set",
            "robot poses",
            "fit RMS [px]",
            "held-out RMS [px]",
            "OpenCV best held-out [px]",
            "held-out PnP agreement [mm / deg]",
            "OpenCV best held-out PnP [mm / deg]",
            "source limit",
        ],
        rows,
    );
    s.text(format!(
        "The source also asks for a residual below {SOURCE_RMS_LIMIT_PX} px; held-out images are not part of \
         its test. With the print scale fitted and the robot poses exact (the default) ours are below it on \
         held-out images on both sets; with the nominal scale they are above it (see the table)."
    ));
    s.text(format!(
        "The printed targets are not at their nominal scale: fitting the print scale against the robots' metric \
         poses (the default; `--nominal-target-scale` holds it) finds {}. It is fitted by default because the \
         training images alone call for it: on both sets it lies many standard deviations from 1 and lowers \
         the training RMS; the held-out images played no part in that choice.",
        scales.join("; ")
    ));
    for w in &warnings {
        s.text(format!("The tool's warning on {w}."));
    }
    for (caption, svg) in cells {
        s.figure(&caption, svg);
    }
    let ok = checks.iter().all(|c| c.0);
    let detail = checks.iter().map(|c| format!("{} {}", if c.0 { "ok:" } else { "FAILED:" }, c.1)).collect::<Vec<_>>();
    s.data = json!({"runs": data_json, "checks": detail, "warnings": warnings, "print_scales": scales});
    s.check(Check::from_bool("hand-eye on real recordings", ok, detail.join("; ")));
    Ok(s)
}

fn f4(v: Option<f64>) -> String {
    v.map_or("-".into(), |x| format!("{x:.4}"))
}

/// The demo's positioner section: the real two-axis positioner of the industrial_calibration
/// kinematic example (a fixed camera measuring the target's 6-DoF pose), every fourth pose held
/// out, calibrated against the nominal baselines (frames only; frames and joint offsets; the
/// source's mount guesses), with the weighting and effects chosen by cross-validation on the
/// training poses.
pub fn positioner_section(data: &Path) -> Result<Section> {
    use ferrocal_calib::kinematic::{calibrate, KinematicOptions, ModelParams};
    use ferrocal_calib::Split;

    let mut s = Section::new("positioner-real", "A real two-axis positioner calibrated from camera poses");
    s.attribution(IC_ATTRIBUTION);
    let dir = data.join("industrial_calibration/kinematic_calibration");
    if !dir.exists() {
        s.skipped(format!("{} is not present", dir.display()));
        return Ok(s);
    }
    let set = ferrocal_datasets::handeye::read_ic_kinematic(&dir, Some(4))?;
    let train: Vec<_> = set.rows.iter().filter(|r| r.split == Some(Split::Train)).collect();
    let test: Vec<_> = set.rows.iter().filter(|r| r.split == Some(Split::Test)).collect();
    let model = ferrocal_robot::RobotModel::Serial(ferrocal_datasets::handeye::ic_positioner_nominal());
    let base = KinematicOptions {
        sigma_position_m: 0.3e-3,
        sigma_orientation_rad: 0.03f64.to_radians(),
        ..Default::default()
    };
    let variants = [
        ("nominal DH, camera frame and target mount fitted", ModelParams::None, false),
        ("nominal DH, frames and joint offsets fitted", ModelParams::None, true),
        ("calibrated (per-joint corrections, frames, offsets)", ModelParams::Default, true),
    ];
    use ferrocal_datasets::handeye::positioner as pos;
    // The weighting and the effects beside the geometry, chosen by 5-fold cross-validation on
    // the training poses alone.
    let choice = pos::choose_by_cross_validation(&model, &train, &base, 5)?;
    let chosen_label = format!(
        "calibrated, chosen by 5-fold cross-validation on the training poses: {} weighting, effects '{}'",
        choice.shape.name(),
        choice.effects
    );
    let mut rows = Vec::new();
    let mut stats = Vec::new();
    let mut models = Vec::new();
    for (label, params, offsets) in variants {
        let opts = KinematicOptions { model_params: params, joint_offsets: offsets, ..base.clone() };
        let cal = calibrate(&model, &train, &opts).with_context(|| format!("positioner: {label}"))?;
        models.push((label.to_string(), cal.calibrated));
    }
    let chosen_opts = pos::with_effects(&base, &choice.effects)?;
    let (chosen, _) = pos::estimate_pose_covariance(&model, &train, &chosen_opts, choice.shape)?;
    models.push((chosen_label.clone(), chosen.calibrated));
    // `ferrocal diagnose` on the training poses (frames placed in the model first), then the
    // calibration with its effects: the pre-specified route for the effects.
    let (diag_list, diag) = pos::diagnose_effects(&ferrocal_datasets::handeye::ic_positioner_nominal(), &train, &base)?;
    let diag_cal = calibrate(&model, &train, &pos::with_effects(&base, &diag_list)?)
        .context("positioner: calibration with diagnose's effects")?;
    models.push((
        format!("calibrated with the effects diagnose finds on the training poses: '{diag_list}'"),
        diag_cal.calibrated,
    ));
    for (label, calibrated) in &models {
        let (errs, _) = calibrated.errors(&test)?;
        let e: Vec<f64> = errs.iter().map(|p| p.norm() * 1e3).collect();
        let st = calibrated.evaluate(&test)?;
        let spread = (e.iter().map(|v| (v - st.mean_mm).powi(2)).sum::<f64>() / e.len() as f64).sqrt();
        rows.push(vec![
            label.to_string(),
            format!("{:.4}", st.mean_mm),
            format!("{spread:.4}"),
            format!("{:.4}", st.max_mm),
            f4(st.mean_deg),
            f4(st.max_deg),
        ]);
        stats.push(json!({"model": label, "held_out": st, "spread_mm": spread}));
    }
    s.text(format!(
        "{} observations: a fixed camera measured the pose of a target on a two-axis positioner; every fourth \
         pose ({} in all) is held out and used by no fit (`ferrocal import ic-kinematic --input DIR --out t.csv \
         --test-every 4 --robot-out positioner.urdf`, then `ferrocal calibrate` and `ferrocal evaluate`). The \
         model is the source's nominal DH chain; the camera frame and the target mount start from the closed \
         form of AX = ZB on the measured poses. The source validates on the poses it fitted; here the \
         baselines are fitted on the same training poses as the calibration, which is harder to beat than \
         the nominal model with rough mount guesses.",
        set.rows.len(),
        test.len()
    ));
    s.table(
        "Held-out poses",
        &["model", "mean [mm]", "spread (std) [mm]", "max [mm]", "mean [deg]", "max [deg]"],
        rows,
    );
    let (cam, tgt) = pos::read_initial_guesses(&dir)?;
    let guess = pos::source_guess_baseline(&model, &test, &cam, &tgt)?;
    s.text(format!(
        "The source's own nominal model, the nominal DH chain with the data set's initial mount guesses \
         (`pose_initial_guesses.yaml`, the camera's mount taken as the positioner's base), is off by {:.1} mm and \
         {:.1} deg on the held-out poses: those guesses are starting values for an optimiser, not a usable \
         model, so it is no yardstick. Against the strict baseline (nominal DH with both frames fitted on the \
         training poses) the calibrations gain {:.1} % (geometry), {:.1} % (chosen by cross-validation) and \
         {:.1} % (with the effects `ferrocal diagnose` finds on the training poses: {}). \
         Weighting the camera's pose measurements by a covariance estimated from the training residuals \
         (variance components, per axis or full, in the camera's frame) does not help here: the residuals are \
         not larger in depth than across the image (they are dominated by what the model leaves out, not by \
         the camera's noise), and cross-validation keeps the scalar weights.",
        guess.mean_mm,
        guess.mean_deg.unwrap_or(f64::NAN),
        100.0
            * (1.0
                - stats[2]["held_out"]["mean_mm"].as_f64().unwrap_or(f64::NAN)
                    / stats[0]["held_out"]["mean_mm"].as_f64().unwrap_or(f64::NAN)),
        100.0
            * (1.0
                - stats[3]["held_out"]["mean_mm"].as_f64().unwrap_or(f64::NAN)
                    / stats[0]["held_out"]["mean_mm"].as_f64().unwrap_or(f64::NAN)),
        100.0
            * (1.0
                - stats[4]["held_out"]["mean_mm"].as_f64().unwrap_or(f64::NAN)
                    / stats[0]["held_out"]["mean_mm"].as_f64().unwrap_or(f64::NAN)),
        diag.findings.iter().map(|f| f.statement.as_str()).collect::<Vec<_>>().join("; "),
    ));
    let get = |k: usize, f: &str| stats[k]["held_out"][f].as_f64().unwrap_or(f64::NAN);
    let (nominal_mm, calibrated_mm, calibrated_deg) = (get(0, "mean_mm"), get(4, "mean_mm"), get(4, "mean_deg"));
    s.data = json!({
        "n": set.rows.len(), "n_test": test.len(), "models": stats, "cross_validation": choice,
        "source_guess_baseline": guess, "diagnose_effects": diag_list, "diagnose_findings": diag.findings,
    });
    s.check(Check::from_bool(
        "positioner within the source's thresholds and more than 10 % better than nominal",
        calibrated_mm < 2.0 && calibrated_deg < 0.2 && calibrated_mm < 0.9 * nominal_mm,
        format!(
            "held-out mean {calibrated_mm:.4} mm, {calibrated_deg:.4} deg (source: < 2 mm, 0.2 deg); nominal with fitted frames {nominal_mm:.4} mm ({:.1} % better; the issue asks for more than 10 %)",
            100.0 * (1.0 - calibrated_mm / nominal_mm)
        ),
    ));
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The positioner section on the real set (when present): the held-out table has the three
    /// fitted models, the one chosen by cross-validation and the one with diagnose's effects;
    /// that one meets the source's thresholds and is more than 10 % better than the nominal
    /// model with fitted frames (measured: 0.3961 against 0.4525 mm).
    #[test]
    fn positioner_section_runs_on_the_real_set() {
        let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
        if !data.join("industrial_calibration/kinematic_calibration").exists() {
            return;
        }
        let s = positioner_section(&data).unwrap();
        let models = s.data["models"].as_array().unwrap();
        assert_eq!(models.len(), 5);
        assert!(models[3]["model"].as_str().unwrap().contains("cross-validation"));
        assert!(models[4]["model"].as_str().unwrap().contains("diagnose"));
        let mean_mm = models[4]["held_out"]["mean_mm"].as_f64().unwrap();
        let nominal_mm = models[0]["held_out"]["mean_mm"].as_f64().unwrap();
        assert!(mean_mm < 2.0 && mean_mm < 0.9 * nominal_mm, "{mean_mm} against {nominal_mm}");
        assert!(s.data["source_guess_baseline"]["mean_mm"].as_f64().unwrap() > mean_mm);
    }
}
