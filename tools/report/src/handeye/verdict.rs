//! The verdict of `ferrocal handeye` (`docs/verdicts.md`): the chain reprojection RMS against
//! industrial_calibration's 1.5 px, the chain RMS over the per-image PnP RMS of the same images
//! and camera (a wrong `--mount` or a wrong pose convention shows a chain residual far above
//! PnP's), and the chain's agreement with PnP in position and orientation.

use ferrocal_calib::handeye::{ChainFigures, HandEyeData, HandEyeResult, JointCalibration, Mount};
use ferrocal_calib::verdict::{fmt_num, Check, Status, Thresholds, Verdict};
use ferrocal_calib::Split;
use ferrocal_vision::pose::{estimate_pose, CornerNoise};

/// Fallback corner noise for corners the detector gives no covariance for, pixels (PnP's
/// weights only; the RMS does not depend on it much).
const FALLBACK_SIGMA_PX: f64 = 0.1;

/// The pooled per-image PnP reprojection RMS, pixels, over the images of `split` that the chain
/// figures score, with `result`'s camera: the floor the chain residual is compared with.
pub fn pnp_rms_px(data: &HandEyeData, result: &HandEyeResult, split: Split) -> Option<f64> {
    let scored: std::collections::HashSet<&str> =
        result.figures.views.iter().filter(|v| v.split == split).map(|v| v.name.as_str()).collect();
    let (mut sum, mut n) = (0.0, 0usize);
    for v in data.views.iter().filter(|v| v.split == split && scored.contains(v.name.as_str())) {
        let noise = CornerNoise::from_detected(&v.covariances_px2, FALLBACK_SIGMA_PX);
        if let Ok(e) = estimate_pose(&result.camera, &data.target_points_m, &v.point_ids, &v.corners_px, &noise) {
            sum += e.rms_px * e.rms_px * e.n_corners as f64;
            n += e.n_corners;
        }
    }
    (n > 0).then(|| (sum / n as f64).sqrt())
}

/// The checks of the chain figures `f` (held-out images when there are any, else training)
/// with the PnP floor `pnp_px`; `prefix` names them (`handeye` or `handeye.joint`).
pub fn chain_checks(t: &Thresholds, f: &ChainFigures, pnp_px: Option<f64>, prefix: &str) -> Vec<Check> {
    let l = &t.handeye;
    let (which, rms, pos, rot) = match f.heldout_rms_px {
        Some(h) => ("held-out", h, f.heldout_pnp_position_mm, f.heldout_pnp_rotation_deg),
        None => ("training", f.train_rms_px, f.train_pnp_position_mm, f.train_pnp_rotation_deg),
    };
    let mut out = vec![Check::at_most(
        &format!("{prefix}.chain_rms_px"),
        &format!("{which} chain RMS"),
        "px",
        rms,
        l.chain_rms_px_warn,
        l.chain_rms_px_fail,
    )];
    if let Some(p) = pnp_px {
        let floor = p.max(l.pnp_floor_px);
        let words = if floor > p {
            format!("chain RMS over {} px (per-image PnP RMS {} px, floored)", fmt_num(floor), fmt_num(p))
        } else {
            format!("chain over per-image PnP RMS ({} px)", fmt_num(p))
        };
        out.push(Check::at_most(
            &format!("{prefix}.chain_over_pnp"),
            &words,
            "",
            rms / floor,
            l.chain_over_pnp_warn,
            l.chain_over_pnp_fail,
        ));
    }
    if let Some(p) = pos {
        out.push(Check::at_most(
            &format!("{prefix}.pnp_position_mm"),
            &format!("{which} distance from PnP"),
            "mm",
            p,
            l.pnp_position_mm_warn,
            l.pnp_position_mm_fail,
        ));
    }
    if let Some(r) = rot {
        out.push(Check::at_most(
            &format!("{prefix}.pnp_rotation_deg"),
            &format!("{which} angle from PnP"),
            "deg",
            r,
            l.pnp_rotation_deg_warn,
            l.pnp_rotation_deg_fail,
        ));
    }
    out
}

/// What a hand-eye run was given, for advice that does not suggest what the run already did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RunFlags {
    /// `--intrinsics` was given (the camera held fixed).
    pub intrinsics: bool,
    /// The camera given by `--intrinsics` has no lens distortion (every coefficient zero, as
    /// industrial_calibration's `cal_data.yaml` intrinsics).
    pub intrinsics_without_distortion: bool,
    /// `--robot-poses-as-measurements` was given.
    pub robot_poses_as_measurements: bool,
}

impl RunFlags {
    /// The flags of a run's options (the given camera file read again: a file that cannot be
    /// read counts as distorted; the run itself refused it before).
    pub fn of(run: &ferrocal_datasets::handeye::HandEyeRunOptions) -> Self {
        let undistorted = run
            .intrinsics
            .as_deref()
            .and_then(|p| ferrocal_datasets::handeye::recording::read_camera_file(p).ok())
            .is_some_and(|c| c.distortion.coefficients().iter().all(|k| *k == 0.0));
        Self {
            intrinsics: run.intrinsics.is_some(),
            intrinsics_without_distortion: undistorted,
            robot_poses_as_measurements: run.robot_poses_as_measurements,
        }
    }
}

/// The verdict of a hand-eye run from its checks; `has_heldout` says whether test images were
/// scored, `joint_out` is the calibration file of `--out`, `flags` what the run was given (the
/// next step never suggests what the run already did).
pub fn handeye_verdict(
    checks: Vec<Check>,
    mount: Mount,
    has_heldout: bool,
    joint_out: Option<&str>,
    flags: RunFlags,
) -> Verdict {
    let other = match mount {
        Mount::EyeInHand => "eye-to-hand",
        Mount::EyeToHand => "eye-in-hand",
    };
    // Whether the chain stays near the PnP floor: then the corners do not fit the camera
    // itself, and the robot's poses are not what lifts the chain.
    let near_floor = checks.iter().any(|c| c.name.ends_with(".chain_over_pnp") && c.status == Status::Pass);
    Verdict::with_next(checks, |c| {
        let Some(c) = c else {
            return match joint_out {
                Some(out) => format!("use the calibrated robot: ferrocal evaluate --robot <model> --calibration {out} --measurements <a tracker table> --refit-frame"),
                None if has_heldout => "use the hand-eye transform (hand_eye in the JSON)".into(),
                None => "use the hand-eye transform; mark some rows `test` in the poses table to check it on images the fit did not see".into(),
            };
        };
        let name = c.name.rsplit('.').next().unwrap_or("");
        match (name, c.status) {
            ("tool_offset_mm", _) => format!(
                "the poses look inverted: write T_base_flange (the flange in the robot's base frame) in the poses table, not its inverse, and run again with the --mount the camera really has (the motions fit --mount {} only because of the inversion)",
                mount.name()
            ),
            ("chain_over_pnp" | "chain_rms_px", Status::Fail) => format!(
                "the chain does not explain the images: re-run with --mount {other}, and check the poses' convention (T_base_flange, quaternion scalar first, mm)"
            ),
            ("chain_over_pnp" | "chain_rms_px", _) if flags.intrinsics_without_distortion => "the camera given by --intrinsics has no lens distortion, and the corners do not fit it: drop --intrinsics so that the camera (with its distortion) is calibrated from the images, or give intrinsics with the lens distortion".into(),
            ("chain_rms_px", _) if near_floor && flags.intrinsics => "the chain stays near the single-image poses' floor but above the limit: the corners fit the given camera poorly; drop --intrinsics so that the camera is calibrated from the images, or check that the file is this camera's at this resolution".into(),
            ("chain_over_pnp" | "chain_rms_px", _) if !flags.robot_poses_as_measurements => "the robot's poses scatter more than the corners: give --robot-poses-as-measurements, or calibrate the robot with --robot and --out".into(),
            ("chain_over_pnp" | "chain_rms_px", _) if flags.intrinsics => "the chain stays above the corners' noise with the robot's poses as measurements: drop --intrinsics (the camera calibrated from the images), or calibrate the robot with --robot and --out".into(),
            ("chain_over_pnp" | "chain_rms_px", _) => "the chain stays above the corners' noise with the robot's poses as measurements: calibrate the robot with joint readings, --robot and --out, or check the poses table's precision (digits, units)".into(),
            _ => "the chain and the single-image poses disagree: check the camera (--intrinsics, or more varied views) and the target's size in --pattern".into(),
        }
    })
}

/// The verdict of a hand-eye run: `checks` ([`fit_checks`], and [`joint_checks`] with a joint
/// adjustment written to `joint_out`) on the chain of `result`, with what the run was given.
pub fn run_verdict(
    checks: Vec<Check>,
    result: &HandEyeResult,
    joint_out: Option<&std::path::Path>,
    flags: RunFlags,
) -> Verdict {
    let out = joint_out.map(|p| p.display().to_string());
    handeye_verdict(checks, result.mount, result.figures.heldout_rms_px.is_some(), out.as_deref(), flags)
}

/// The checks of a hand-eye fit: its chain figures against the PnP floor, on the held-out
/// images when there are any, else on the training ones.
pub fn fit_checks(t: &Thresholds, data: &HandEyeData, result: &HandEyeResult) -> Vec<Check> {
    let split = if result.figures.heldout_rms_px.is_some() { Split::Test } else { Split::Train };
    let mut checks = vec![tool_offset_check(t, result)];
    checks.extend(chain_checks(t, &result.figures, pnp_rms_px(data, result, split), "handeye"));
    checks
}

/// The length of the flange-side transform (`T_flange_camera`, `T_flange_target`) against
/// `handeye.tool_offset_mm_*`: beyond, no tool is that long and the poses look inverted (an
/// inverted table fits the other mount with the world transform in the flange's place).
pub fn tool_offset_check(t: &Thresholds, result: &HandEyeResult) -> Check {
    let l = &t.handeye;
    let tool = result.hand_eye.transform.translation.vector.norm() * 1e3;
    let world = result.world.transform.translation.vector.norm() * 1e3;
    let mut c = Check::at_most(
        "handeye.tool_offset_mm",
        &format!("{} length", result.mount.hand_eye_name()),
        "mm",
        tool,
        l.tool_offset_mm_warn,
        l.tool_offset_mm_fail,
    );
    if c.status != Status::Pass {
        c.what = format!(
            "{}: no tool is this long ({} is {} mm): the robot poses look inverted (T_flange_base written for T_base_flange)",
            c.what,
            result.mount.world_name(),
            fmt_num(world)
        );
    }
    c
}

/// The checks of the joint adjustment's chain, scored as the hand-eye fit's (no PnP floor: its
/// camera is the adjustment's own).
pub fn joint_checks(t: &Thresholds, joint: &JointCalibration) -> Vec<Check> {
    chain_checks(t, &joint.figures, None, "handeye.joint")
        .into_iter()
        .filter(|c| c.name.ends_with("chain_rms_px"))
        .collect()
}

/// The check of the robot's motions against the camera's before the fit
/// ([`ferrocal_datasets::handeye::motion_check`]): a warning naming the images it found off (or
/// the rough agreement), a pass with the figures otherwise.
pub fn motion_check(m: &ferrocal_datasets::handeye::MotionCheck) -> Check {
    let absent = match &m.agreement {
        Some(a) => format!(
            "robot and camera motions agree: rotation {} deg, travel {} mm at the median pair",
            fmt_num(a.rotation_disagreement_deg),
            fmt_num(a.travel_disagreement_mm)
        ),
        None => "robot and camera motions not compared (fewer than 4 images with a PnP pose)".into(),
    };
    let holds = match m.flagged.len() {
        0 => m.warnings.join("; "),
        n => format!(
            "{n} image(s) whose robot pose disagrees with the camera: {}",
            m.flagged
                .iter()
                .map(|f| format!("{} (line {}{})", f.image, f.line, if f.dropped { ", left out" } else { "" }))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    Check::flag("handeye.motion_check", &holds, &absent, !m.warnings.is_empty())
}
