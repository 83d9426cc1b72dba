//! `ferrocal handeye`'s check of the robot's motion against the camera's, before the fit
//! ([`ferrocal_calib::handeye::agreement`]): between two images the flange's rotation angle is the
//! board's, and its travel along the screw axis is the board's times the print scale, whatever the
//! hand-eye transform. A recording whose motions disagree is refused with the likely cause, found
//! by reading the table another way (quaternions in another order, a joint column in another
//! unit, another robot model of the same joint count, the other mount) and keeping the reading
//! that agrees; one image whose motions disagree with every other image's is named with its row
//! (and the row it does fit, when one does), and left out of the fit when the evidence is strong.
//!
//! The limits are ratios to the recording's own figures: a rotation disagreement relative to the
//! rotations themselves, a travel disagreement relative to the travels, an image's residuals
//! relative to the median pair's (the data's noise), so that a noisy but sound recording (the
//! real industrial_calibration sets: relative disagreements of at most 0.07 with the 10x10 set's
//! uncalibrated nominal intrinsics, 0.03 otherwise) passes.

use std::collections::HashMap;

use nalgebra::{Isometry3, Quaternion, UnitQuaternion};
use serde::Serialize;

use ferrocal_calib::handeye::agreement::{motion_agreement, MotionAgreement};
use ferrocal_calib::handeye::{HandEyeView, Mount, StartPoses};
use ferrocal_robot::{Kinematics, RobotModel};

use super::{PosesTable, RobotReading};
use crate::error::{DatasetError, Result};
use crate::import::units::JointUnit;

/// Rotation disagreement over the median rotation beyond which the run warns.
pub const ROTATION_WARN: f64 = 0.15;
/// ... and beyond which it is refused.
pub const ROTATION_FAIL: f64 = 0.3;
/// Travel disagreement over the median travel beyond which the run warns.
pub const TRAVEL_WARN: f64 = 0.15;
/// ... and beyond which it is refused.
pub const TRAVEL_FAIL: f64 = 0.3;
/// The robot's travels over the camera's (the print scale) may be this factor off 1 before a
/// warning.
pub const SCALE_WARN: f64 = 1.08;
/// ... and this far before a refusal (a target printed at 80 % or a wrong robot model).
pub const SCALE_FAIL: f64 = 1.25;
/// An image whose median residual is this many times the median pair's is named in a warning.
pub const VIEW_WARN: f64 = 6.0;
/// ... and this many times is left out of the fit.
pub const VIEW_DROP: f64 = 12.0;
/// Residuals an image must exceed besides the ratio to be named: degrees, millimetres (far
/// below any robot's accuracy; they keep a nearly noise-free simulation from naming rounding).
pub const VIEW_FLOOR_DEG_MM: (f64, f64) = (0.1, 1.0);
/// The other mount is named when its closed-form residuals are smaller than the given mount's
/// by these factors (translation, rotation).
pub const MOUNT_RATIO: (f64, f64) = (3.0, 2.0);
/// A flange-side transform (`T_flange_camera`, `T_flange_target`) longer than this, metres, is
/// no tool: when the other mount fits the motions with such a transform, the refusal names
/// inverted poses (`T_flange_base` written for `T_base_flange`) rather than the mount. The
/// inverted table of the charuco set fits as eye-in-hand with a camera 1.26 m from the flange.
/// The same length as `handeye.tool_offset_mm_fail` (1000 mm).
pub const INVERTED_TOOL_M: f64 = 1.0;
/// At most this share of the images is left out; more disagreeing images is a warning.
pub const MAX_DROPPED_SHARE: f64 = 0.2;

/// An image named by the check.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FlaggedView {
    /// The image.
    pub image: String,
    /// Its row's line in the poses table.
    pub line: u64,
    /// Median rotation residual over its pairs, degrees.
    pub rotation_deg: f64,
    /// Median translation residual over its pairs, millimetres.
    pub translation_mm: f64,
    /// Its residuals over the median pair's (the larger of rotation and translation).
    pub ratio: f64,
    /// Left out of the fit.
    pub dropped: bool,
    /// Why, in words.
    pub reason: String,
}

/// What the check found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MotionCheck {
    /// The figures (`None`: fewer than four images with a PnP pose, nothing compared).
    pub agreement: Option<MotionAgreement>,
    /// Images named, some left out.
    pub flagged: Vec<FlaggedView>,
    /// Warnings for the verdict.
    pub warnings: Vec<String>,
}

impl MotionCheck {
    /// The JSON of `handeye`'s `motion_check`.
    pub fn to_json(&self) -> serde_json::Value {
        let a = self.agreement.as_ref();
        serde_json::json!({
            "figures": a,
            "relative_rotation": a.map(MotionAgreement::relative_rotation),
            "relative_travel": a.map(MotionAgreement::relative_travel),
            "limits": {
                "relative_rotation_warn": ROTATION_WARN, "relative_rotation_fail": ROTATION_FAIL,
                "relative_travel_warn": TRAVEL_WARN, "relative_travel_fail": TRAVEL_FAIL,
                "scale_factor_warn": SCALE_WARN, "scale_factor_fail": SCALE_FAIL,
                "view_ratio_warn": VIEW_WARN, "view_ratio_drop": VIEW_DROP,
            },
            "flagged": self.flagged,
            "dropped": self.flagged.iter().filter(|f| f.dropped).map(|f| &f.image).collect::<Vec<_>>(),
            "warnings": self.warnings,
        })
    }
}

/// How far the figures are from agreeing: 1 at the first warning limit (the largest of the three
/// ratios to their limits).
fn badness(a: &MotionAgreement, fail: bool) -> f64 {
    let (r, t, s) =
        if fail { (ROTATION_FAIL, TRAVEL_FAIL, SCALE_FAIL) } else { (ROTATION_WARN, TRAVEL_WARN, SCALE_WARN) };
    let scale = if a.scale > 0.0 { a.scale.ln().abs() / s.ln() } else { f64::INFINITY };
    (a.relative_rotation() / r).max(a.relative_travel() / t).max(scale)
}

/// The figures in words.
fn figures_words(a: &MotionAgreement) -> String {
    format!(
        "rotation angles differ by {:.2} deg at the median pair (of {:.1} deg), travels along the screw axis by {:.1} mm (of {:.1} mm), the robot's travels are {:.3} times the camera's",
        a.rotation_disagreement_deg, a.median_rotation_deg, a.travel_disagreement_mm, a.median_travel_mm, a.scale
    )
}

/// The table's rows of the views, and every row's flange pose for the row search.
struct Rows<'a> {
    table: &'a PosesTable,
    robot: Option<&'a RobotModel>,
    /// Row index of each view.
    of_view: Vec<usize>,
}

impl Rows<'_> {
    /// Flange poses of the views' rows read with `f` (joints to pose, or a flange pose rewritten).
    fn poses(&self, f: &dyn Fn(&RobotReading) -> Option<Isometry3<f64>>) -> Option<Vec<Isometry3<f64>>> {
        self.of_view.iter().map(|&r| f(&self.table.rows[r].robot)).collect()
    }
}

/// Forward kinematics of `q` on `m`, `None` when it fails.
fn fk(m: &RobotModel, q: &[f64]) -> Option<Isometry3<f64>> {
    (q.len() == m.dof()).then(|| m.forward(q).ok()).flatten()
}

/// Other readings of the table, each with the flange poses it gives and its words.
fn alternatives(rows: &Rows, mount: Mount) -> Vec<(String, Vec<Isometry3<f64>>, Mount)> {
    let mut out = Vec::new();
    let flange_rows = rows.table.joint_units.is_empty();
    if flange_rows {
        let reorder = |f: &dyn Fn(&Quaternion<f64>) -> Quaternion<f64>| {
            rows.poses(&|r| match r {
                RobotReading::Flange(t) => Some(Isometry3::from_parts(
                    t.translation,
                    UnitQuaternion::from_quaternion(f(t.rotation.quaternion())),
                )),
                RobotReading::Joints(_) => None,
            })
        };
        if let Some(p) = reorder(&|q| Quaternion::new(q.k, q.w, q.i, q.j)) {
            out.push((
                "the quaternions look written x y z w (scalar last) under the columns qw, qx, qy, qz: read so, ".into(),
                p,
                mount,
            ));
        }
        if let Some(p) = reorder(&|q| Quaternion::new(q.i, q.j, q.k, q.w)) {
            out.push((
                "the quaternions look written w x y z (scalar first) under columns named for x y z w: read so, ".into(),
                p,
                mount,
            ));
        }
    }
    if let Some(robot) = rows.robot {
        let units = &rows.table.joint_units;
        let rescaled = |cols: &[usize], factor: f64| {
            rows.poses(&|r| match r {
                RobotReading::Joints(q) => {
                    let q: Vec<f64> =
                        q.iter().enumerate().map(|(k, v)| if cols.contains(&k) { v * factor } else { *v }).collect();
                    fk(robot, &q)
                }
                RobotReading::Flange(_) => None,
            })
        };
        let (deg, rad) = (std::f64::consts::PI / 180.0, 180.0 / std::f64::consts::PI);
        let rad_cols: Vec<usize> = (0..units.len()).filter(|&k| units[k] == JointUnit::Rad).collect();
        if rad_cols.len() > 1 {
            if let Some(p) = rescaled(&rad_cols, deg) {
                out.push((
                    "the joint columns look like degrees under _rad headers: read as degrees (name them q<i>_deg), "
                        .into(),
                    p,
                    mount,
                ));
            }
        }
        for (k, u) in units.iter().enumerate() {
            let (factor, words) = match u {
                JointUnit::Rad => (deg, format!("q{}_deg", k + 1)),
                JointUnit::Deg => (rad, format!("q{}_rad", k + 1)),
                _ => continue,
            };
            if let Some(p) = rescaled(&[k], factor) {
                let (unit, other) = if *u == JointUnit::Rad { ("rad", "degrees") } else { ("deg", "radians") };
                out.push((
                    format!("the column q{}_{unit} looks like {other}: read so (name it {words}), ", k + 1),
                    p,
                    mount,
                ));
            }
        }
        for name in ferrocal_robot::presets::PRESET_NAMES {
            let Ok(other) = RobotModel::load(name) else { continue };
            if other.name() == robot.name() || other.dof() != robot.dof() {
                continue;
            }
            let p = rows.poses(&|r| match r {
                RobotReading::Joints(q) => fk(&other, q),
                RobotReading::Flange(_) => None,
            });
            if let Some(p) = p {
                out.push((
                    format!(
                        "the joint readings look recorded on a {name}, not a {}: with --robot {name}, ",
                        robot.name()
                    ),
                    p,
                    mount,
                ));
            }
        }
    }
    out
}

/// Checks the recording's robot motions against the PnP motions of `start` (the views the fit
/// would use), with the table and the robot model for the other readings. A refusal is an
/// error naming the cause; otherwise the figures, the images named and the warnings. `views`
/// whose flagged entry says `dropped` are to be left out by the caller.
pub fn check_motion(
    mount: Mount,
    start: &StartPoses,
    table: &PosesTable,
    robot: Option<&RobotModel>,
) -> Result<MotionCheck> {
    let by_name: HashMap<&str, usize> = table.rows.iter().enumerate().map(|(i, r)| (r.image.as_str(), i)).collect();
    let used: Vec<(&HandEyeView, Isometry3<f64>, usize)> = start
        .views
        .iter()
        .zip(&start.pnp)
        .filter_map(|(v, p)| Some((v, (*p)?, *by_name.get(v.name.as_str())?)))
        .collect();
    let flange: Vec<Isometry3<f64>> = used.iter().map(|u| u.0.t_base_flange).collect();
    let cams: Vec<Isometry3<f64>> = used.iter().map(|u| u.1).collect();
    let Some(a) = motion_agreement(mount, &flange, &cams) else {
        return Ok(MotionCheck { agreement: None, flagged: Vec::new(), warnings: Vec::new() });
    };
    let rows = Rows { table, robot, of_view: used.iter().map(|u| u.2).collect() };
    let file = table.file.display();
    // The mount: the angles and travels do not tell the mounts apart, the residuals of the
    // closed form do.
    let other = if mount == Mount::EyeInHand { Mount::EyeToHand } else { Mount::EyeInHand };
    if let Some(b) = motion_agreement(other, &flange, &cams) {
        if b.residual_translation_mm * MOUNT_RATIO.0 <= a.residual_translation_mm
            && b.residual_rotation_deg * MOUNT_RATIO.1 <= a.residual_rotation_deg
        {
            let residuals = format!(
                "the closed form's residuals at the median pair are {:.2} deg and {:.1} mm with --mount {}, {:.2} deg and {:.1} mm with --mount {}",
                b.residual_rotation_deg, b.residual_translation_mm, other.name(),
                a.residual_rotation_deg, a.residual_translation_mm, mount.name()
            );
            // Inverted poses fit as the other mount, with the world transform in the flange's
            // place: a "tool" of metres.
            let tool_m = b.closed_form_x.translation.vector.norm();
            if tool_m > INVERTED_TOOL_M {
                return Err(DatasetError::Input(format!(
                    "{file}: the robot poses look inverted (T_flange_base written where T_base_flange is meant): the motions fit the camera's only as {} ({residuals}), and then with a {} {:.0} mm from the flange, which is no tool; invert every pose of the table (or its convention) and keep --mount {}",
                    other.name(), if other == Mount::EyeInHand { "camera" } else { "target" }, tool_m * 1e3, mount.name()
                )));
            }
            return Err(DatasetError::Input(format!(
                "{file}: the robot's motions fit the camera's as {}, not {}: {residuals}; re-run with --mount {} (if the camera is mounted as --mount {} says, the poses are inverted instead: T_flange_base written for T_base_flange)",
                other.name(), mount.name(), other.name(), mount.name()
            )));
        }
    }
    if badness(&a, false) > 1.0 {
        // Another reading of the table that agrees, and clearly better.
        let best = alternatives(&rows, mount)
            .into_iter()
            .filter_map(|(words, p, m)| motion_agreement(m, &p, &cams).map(|b| (badness(&b, false), words, b)))
            .min_by(|x, y| x.0.total_cmp(&y.0));
        let intro = format!(
            "{file}: the robot's motions between the images disagree with the camera's ({} pairs of {} images): {}",
            a.n_pairs,
            a.n_views,
            figures_words(&a)
        );
        if let Some((_, words, alt)) = best.filter(|b| b.0 <= 1.0 && b.0 < badness(&a, false) / 3.0) {
            return Err(DatasetError::Input(format!(
                "{intro}; {words}the rotations agree to {:.2} deg and the travels to {:.1} mm (scale {:.3})",
                alt.rotation_disagreement_deg, alt.travel_disagreement_mm, alt.scale
            )));
        }
        if badness(&a, true) > 1.0 {
            return Err(DatasetError::Input(format!(
                "{intro}; check the robot model (--robot), the poses' convention (T_base_flange, quaternion scalar first, the units the headers name), --mount and the target's size in --pattern"
            )));
        }
        let warning = format!(
            "the robot's motions agree only roughly with the camera's: {}; check the units of the poses table and the target's size",
            figures_words(&a)
        );
        return Ok(MotionCheck { agreement: Some(a), flagged: Vec::new(), warnings: vec![warning] });
    }
    let flagged = flag_views(&a, &used, &rows, mount, &flange, &cams);
    let warnings = flagged.iter().map(|f| f.reason.clone()).collect();
    Ok(MotionCheck { agreement: Some(a), flagged, warnings })
}

/// An image's residuals over the median pair's, `None` below the floors.
fn view_ratio(a: &MotionAgreement, k: usize) -> Option<f64> {
    let v = &a.views[k];
    ratio_of(a, (v.residual_rotation_deg, v.residual_translation_mm))
}

/// Median residuals `(deg, mm)` of an image over the median pair's, `None` below the floors.
fn ratio_of(a: &MotionAgreement, (rot, trans): (f64, f64)) -> Option<f64> {
    let r = (rot / a.residual_rotation_deg.max(1e-9)).max(trans / a.residual_translation_mm.max(1e-9));
    (rot >= VIEW_FLOOR_DEG_MM.0 || trans >= VIEW_FLOOR_DEG_MM.1).then_some(r)
}

/// The images whose motions disagree with all the others', each with the row its board pose
/// fits instead when one does.
fn flag_views(
    a: &MotionAgreement,
    used: &[(&HandEyeView, Isometry3<f64>, usize)],
    rows: &Rows,
    mount: Mount,
    flange: &[Isometry3<f64>],
    cams: &[Isometry3<f64>],
) -> Vec<FlaggedView> {
    let suspects: Vec<(usize, f64)> =
        (0..a.n_views).filter_map(|k| view_ratio(a, k).filter(|r| *r >= VIEW_WARN).map(|r| (k, r))).collect();
    if suspects.is_empty() {
        return Vec::new();
    }
    let table = rows.table;
    let all_rows: Vec<Option<Isometry3<f64>>> = table
        .rows
        .iter()
        .map(|r| match &r.robot {
            RobotReading::Flange(t) => Some(*t),
            RobotReading::Joints(q) => rows.robot.and_then(|m| fk(m, q)),
        })
        .collect();
    let max_dropped = ((a.n_views as f64 * MAX_DROPPED_SHARE).floor() as usize).max(1);
    let too_many = suspects.len() > max_dropped;
    let file = table.file.display();
    // The row whose pose each suspect's board pose fits best, when it fits.
    let fits: Vec<Option<usize>> = suspects
        .iter()
        .map(|&(k, _)| {
            let own = used[k].2;
            let mut best: Option<(f64, usize)> = None;
            for (r, pose) in all_rows.iter().enumerate() {
                let Some(pose) = pose.filter(|_| r != own) else { continue };
                let mut trial = flange.to_vec();
                trial[k] = pose;
                let ratio = ratio_of(a, a.view_residuals(mount, k, &trial, cams)).unwrap_or(0.0);
                if best.is_none_or(|x| ratio < x.0) {
                    best = Some((ratio, r));
                }
            }
            best.filter(|b| b.0 < VIEW_WARN / 2.0).map(|b| b.1)
        })
        .collect();
    // The image whose view each suspect's robot pose fits instead, when one does.
    let fits_image: Vec<Option<usize>> = suspects
        .iter()
        .map(|&(k, _)| {
            let mut best: Option<(f64, usize)> = None;
            for m in (0..cams.len()).filter(|&m| m != k) {
                let mut trial = cams.to_vec();
                trial[k] = cams[m];
                let ratio = ratio_of(a, a.view_residuals(mount, k, flange, &trial)).unwrap_or(0.0);
                if best.is_none_or(|x| ratio < x.0) {
                    best = Some((ratio, m));
                }
            }
            best.filter(|b| b.0 < VIEW_WARN / 2.0).map(|b| b.1)
        })
        .collect();
    suspects
        .iter()
        .zip(fits.iter().zip(&fits_image))
        .map(|(&(k, ratio), (fit, fit_image))| {
            let (view, _, row) = used[k];
            let line = table.rows[row].line;
            let v = &a.views[k];
            let figures = format!(
                "its motions to the other images disagree by {:.2} deg and {:.1} mm at the median, {:.0} times the recording's median pair ({:.2} deg, {:.1} mm)",
                v.residual_rotation_deg, v.residual_translation_mm, ratio, a.residual_rotation_deg, a.residual_translation_mm
            );
            let cause = match fit {
                Some(r) => {
                    let swapped = suspects.iter().zip(&fits).any(|(s, f)| used[s.0].2 == *r && *f == Some(row));
                    let other = &table.rows[*r];
                    if swapped {
                        format!("the rows of {} (line {line}) and {} (line {}) look swapped", view.name, other.image, other.line)
                    } else {
                        format!(
                            "image {} looks paired with the wrong row (line {line}): its board pose fits the robot pose on line {} (the row of {})",
                            view.name, other.line, other.image
                        )
                    }
                }
                None => match fit_image {
                    Some(m) => {
                        let other = &table.rows[used[*m].2];
                        format!(
                            "image {} looks paired with the wrong row: the robot pose on its line {line} fits the view of image {} (line {}), not its own",
                            view.name, other.image, other.line
                        )
                    }
                    None => format!("the robot pose of image {} (line {line}) looks wrong, e.g. a typo", view.name),
                },
            };
            let dropped = !too_many && ratio >= VIEW_DROP;
            let action = if dropped {
                "left out of the fit".to_string()
            } else if too_many {
                format!("kept: {} of {} images disagree, too many to leave out", suspects.len(), a.n_views)
            } else {
                "kept (the evidence is not strong enough to leave it out)".to_string()
            };
            FlaggedView {
                image: view.name.clone(),
                line,
                rotation_deg: v.residual_rotation_deg,
                translation_mm: v.residual_translation_mm,
                ratio,
                dropped,
                reason: format!("{file}: {cause}: {figures}; {action}"),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrocal_calib::Split;
    use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};
    use nalgebra::Vector3;

    /// A UR5 joint table whose first joint, which stays within +-11 deg, is written in degrees
    /// under `q1_rad` (below the table's own two-turn check): the motion check names the column;
    /// the same table in radians passes, and a row 50 mm off is named and left out.
    #[test]
    fn a_joint_column_in_degrees_within_two_turns_is_named() {
        let ur5 = RobotModel::load("ur5").unwrap();
        let mount = Mount::EyeToHand;
        let x = Isometry3::new(Vector3::new(0.02, -0.01, 0.08), Vector3::new(0.1, 0.2, -0.3));
        let w = Isometry3::new(Vector3::new(0.9, 0.3, 1.4), Vector3::new(2.6, 0.1, 0.4));
        let joints: Vec<Vec<f64>> = (0..10)
            .map(|k| {
                let f = k as f64;
                vec![
                    0.19 * (1.7 * f).sin(),
                    -1.6 + 0.3 * f.cos(),
                    1.4 + 0.2 * (0.9 * f).sin(),
                    -1.4 + 0.4 * (1.3 * f).cos(),
                    1.5 + 0.3 * f.sin(),
                    0.5 * f,
                ]
            })
            .collect();
        let cams: Vec<Isometry3<f64>> =
            joints.iter().map(|q| mount.t_camera_target(&x, &w, &ur5.forward(q).unwrap())).collect();
        let camera = CameraModel::new(
            Intrinsics { fx_px: 1000.0, fy_px: 1000.0, cx_px: 640.0, cy_px: 480.0 },
            Distortion::None,
            ImageSize { width_px: 1280, height_px: 960 },
        )
        .unwrap();
        let check = |first_in_degrees: bool, off_m: f64| {
            let mut text = String::from("image,q1_rad,q2_rad,q3_rad,q4_rad,q5_rad,q6_rad\n");
            for (k, q) in joints.iter().enumerate() {
                let q1 = if first_in_degrees { q[0].to_degrees() } else { q[0] };
                text.push_str(&format!("{k}.png,{q1},{},{},{},{},{}\n", q[1], q[2], q[3], q[4], q[5]));
            }
            let table = super::super::poses::parse_handeye_poses(&text, std::path::Path::new("poses.csv")).unwrap();
            let flange = table.flange_poses(Some(&ur5)).unwrap();
            let views: Vec<HandEyeView> = flange
                .iter()
                .enumerate()
                .map(|(k, f)| HandEyeView {
                    name: format!("{k}.png"),
                    split: Split::Train,
                    t_base_flange: if k == 4 { Isometry3::translation(off_m, 0.0, 0.0) * f } else { *f },
                    image_size: camera.image_size,
                    point_ids: Vec::new(),
                    corners_px: Vec::new(),
                    covariances_px2: Vec::new(),
                })
                .collect();
            let start = StartPoses {
                views,
                skipped: Vec::new(),
                camera,
                initial: None,
                pnp: cams.iter().map(|c| Some(*c)).collect(),
            };
            check_motion(mount, &start, &table, Some(&ur5))
        };
        let e = check(true, 0.0).unwrap_err().to_string();
        assert!(e.contains("poses.csv") && e.contains("the column q1_rad looks like degrees"), "{e}");
        let clean = check(false, 0.0).unwrap();
        assert!(clean.warnings.is_empty() && clean.flagged.is_empty(), "{clean:?}");
        let off = check(false, 0.05).unwrap();
        assert_eq!(off.flagged.len(), 1, "{off:?}");
        assert!(off.flagged[0].dropped && off.flagged[0].image == "4.png" && off.flagged[0].line == 6, "{off:?}");
    }
}
