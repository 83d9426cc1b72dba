//! Whether the cameras of a rig agree on the target, pose by pose (`measure --session`'s
//! cross-check, `docs/reliability.md`): each camera's single-camera target pose carried into
//! camera 0's frame by the calibrated rig, compared; the cheap hypotheses that explain a
//! disagreement (image lists swapped, one list shifted by an image); and the refusals of a
//! measurement whose data contradict themselves.

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use ferrocal_vision::pose::{estimate_pose_rig, CornerNoise, RigObservation};

use super::{ImageCorners, SessionMeasurement};
use crate::error::DatasetError;

/// One pose seen by camera 0 and another camera: the target pose from each camera alone (PnP
/// plus refinement on that camera's corners), carried into camera 0's frame by the calibrated
/// rig, compared.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PoseAgreement {
    /// Pose id.
    pub pose_id: String,
    /// The other camera (camera 0 is the reference).
    pub camera: usize,
    /// Distance between the two positions, mm.
    pub difference_mm: f64,
    /// The difference in standard deviations: `sqrt(d^T (C_0 + C_c)^-1 d)` with the position
    /// covariances of the two single-camera poses (corner noise and the rig's uncertainty).
    pub sigmas: f64,
    /// Distance of the target from camera 0 (camera 0 alone), mm.
    pub distance_mm: f64,
}

/// Whether the cameras of the rig agree on the target, pose by pose, and what made them
/// disagree when a cheap hypothesis explains it (lists swapped, one list shifted by an image).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct CameraAgreement {
    /// Every pose seen by camera 0 and another camera, in the session's order.
    pub poses: Vec<PoseAgreement>,
    /// Per hypothesis tried (`"swap 0 1"`, `"shift 1 +1"`, ...): the poses compared under it.
    #[serde(skip)]
    pub hypotheses: Vec<(Hypothesis, Vec<PoseAgreement>)>,
    /// File names of the pose images per camera, in the session's order (for messages).
    pub images: Vec<Vec<Option<String>>>,
    /// Camera names.
    pub camera_names: Vec<String>,
}

/// A guess at what went wrong with the image lists.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Hypothesis {
    /// The pose images of camera 0 and this camera are each other's.
    Swapped(usize),
    /// This camera's image `k + offset` is camera 0's image `k`.
    Shifted(usize, i64),
}

/// Whether one compared pose disagrees: beyond `sigmas` standard deviations and beyond
/// `relative` times the target's distance (a floor for rigs whose stated sigmas are tiny).
pub fn disagrees(p: &PoseAgreement, sigmas: f64, relative: f64) -> bool {
    p.sigmas > sigmas && p.difference_mm > relative * p.distance_mm
}

/// Compares the single-camera poses of camera 0 (`c0[k]`) and camera `c` (`cc[k + offset]`).
#[allow(clippy::too_many_arguments)]
pub(super) fn compare_cameras(
    rig: &ferrocal_vision::pose::CameraRig,
    points: &[Point3<f64>],
    ids: &[String],
    c: usize,
    c0: &[Option<ImageCorners>],
    cc: &[Option<ImageCorners>],
    offset: i64,
    sigma_px: f64,
) -> Vec<PoseAgreement> {
    let point_ids: Vec<usize> = (0..points.len()).collect();
    let single = |camera: usize, ic: &ImageCorners| {
        let obs = RigObservation {
            camera,
            point_ids: point_ids.clone(),
            corners_px: ic.px.clone(),
            noise: if ic.covariance_px2.is_empty() {
                CornerNoise::Isotropic { sigma_px }
            } else {
                CornerNoise::from_detected(&ic.covariance_px2, sigma_px)
            },
        };
        estimate_pose_rig(rig, points, std::slice::from_ref(&obs)).ok()
    };
    let mut out = Vec::new();
    for (k, a) in c0.iter().enumerate() {
        let j = k as i64 + offset;
        let (Some(a), Some(Some(b))) = (a, usize::try_from(j).ok().and_then(|j| cc.get(j))) else { continue };
        let (Some(pa), Some(pb)) = (single(0, a), single(c, b)) else { continue };
        let d = pb.position_mm - pa.position_mm;
        let cov = pa.covariance.fixed_view::<3, 3>(0, 0) + pb.covariance.fixed_view::<3, 3>(0, 0);
        let sigmas = cov.try_inverse().map_or(f64::INFINITY, |inv| (d.transpose() * inv * d)[(0, 0)].max(0.0).sqrt());
        out.push(PoseAgreement {
            pose_id: ids[k].clone(),
            camera: c,
            difference_mm: d.norm(),
            sigmas,
            distance_mm: pa.position_mm.norm(),
        });
    }
    out
}

impl CameraAgreement {
    /// The poses that disagree (see [`disagrees`]).
    pub fn disagreeing(&self, sigmas: f64, relative: f64) -> Vec<&PoseAgreement> {
        self.poses.iter().filter(|p| disagrees(p, sigmas, relative)).collect()
    }

    /// The fraction of the compared poses that disagree (0 without any compared).
    pub fn disagreeing_fraction(&self, sigmas: f64, relative: f64) -> f64 {
        self.disagreeing(sigmas, relative).len() as f64 / self.poses.len().max(1) as f64
    }

    /// The first hypothesis under which at most a fifth of at least three compared poses
    /// disagree, with its description.
    pub fn explanation(&self, sigmas: f64, relative: f64) -> Option<String> {
        let (h, poses) = self.hypotheses.iter().find(|(_, poses)| {
            poses.len() >= 3 && poses.iter().filter(|p| disagrees(p, sigmas, relative)).count() * 5 <= poses.len()
        })?;
        let name = |c: usize| self.camera_names.get(c).cloned().unwrap_or_else(|| format!("camera {c}"));
        let file = |c: usize, k: i64| -> String {
            usize::try_from(k)
                .ok()
                .and_then(|k| self.images.get(c).and_then(|l| l.get(k)).cloned().flatten())
                .unwrap_or_else(|| "?".into())
        };
        Some(match *h {
            Hypothesis::Swapped(c) => format!(
                "the {} and {} images look swapped: with the two lists exchanged, {} of {} poses agree; exchange the two cameras' pose image lists (or folders)",
                name(0),
                name(c),
                poses.len() - poses.iter().filter(|p| disagrees(p, sigmas, relative)).count(),
                poses.len()
            ),
            Hypothesis::Shifted(c, o) => {
                let k = if o > 0 { 0 } else { -o };
                format!(
                    "the {} camera's list looks shifted by one image: image k of the {} pairs with image k{}{} of the {} ({} with {}); {} of {} poses agree so; fix the list (a missing or extra image in one camera)",
                    name(c),
                    name(0),
                    if o > 0 { "+" } else { "-" },
                    o.abs(),
                    name(c),
                    file(0, k),
                    file(c, k + o),
                    poses.len() - poses.iter().filter(|p| disagrees(p, sigmas, relative)).count(),
                    poses.len()
                )
            }
        })
    }
}

impl SessionMeasurement {
    /// The longest camera baseline of the rig, m (0 with one camera).
    pub fn baseline_m(&self) -> f64 {
        self.rig.t_cam_cam0.iter().map(|t| t.translation.vector.norm()).fold(0.0, f64::max)
    }

    /// The median distance of the target from camera 0, m: camera 0's own pose where it saw the
    /// target, else the rig's (NaN without any pose).
    pub fn median_distance_m(&self) -> f64 {
        let mut d: Vec<f64> = if self.agreement.poses.is_empty() {
            self.rows.rows.iter().map(|r| r.position_m.norm()).collect()
        } else {
            self.agreement.poses.iter().map(|p| p.distance_mm * 1e-3).collect()
        };
        d.sort_by(f64::total_cmp);
        d.get(d.len() / 2).copied().unwrap_or(f64::NAN)
    }

    /// Refuses a measurement whose data contradict themselves (`docs/reliability.md`): a rig
    /// baseline or target distance beyond `l.distance_m_fail` (a square size in the wrong unit),
    /// or more than `l.cameras_disagree_fraction_fail` of the poses on which the cameras disagree
    /// (image lists swapped or shifted, named when swapping or shifting makes them agree).
    pub fn check_consistent(&self, l: &ferrocal_calib::verdict::MeasureLimits) -> Result<(), DatasetError> {
        let baseline = self.baseline_m();
        if baseline > l.distance_m_fail {
            return Err(DatasetError::Input(format!(
                "the calibration board's square size looks wrong: it makes the cameras {baseline:.1} m apart (more than {} m, measure.distance_m_fail); did you mean mm? (the session's manifest.json, calibration_board.square_m, is in metres)",
                l.distance_m_fail
            )));
        }
        let distance = self.median_distance_m();
        if distance > l.distance_m_fail {
            return Err(DatasetError::Input(format!(
                "the target's square size looks wrong: it puts the target {distance:.1} m from the camera (median; more than {} m, measure.distance_m_fail); did you mean mm? (the session's manifest.json, target.square_m, is in metres)",
                l.distance_m_fail
            )));
        }
        let a = &self.agreement;
        let (s, r) = (l.cameras_disagree_sigmas, l.cameras_disagree_relative);
        let bad = a.disagreeing(s, r);
        if a.poses.len() >= 3 && a.disagreeing_fraction(s, r) > l.cameras_disagree_fraction_fail {
            let median = {
                let mut d: Vec<f64> = bad.iter().map(|p| p.difference_mm).collect();
                d.sort_by(f64::total_cmp);
                d[d.len() / 2]
            };
            let cause = a.explanation(s, r).unwrap_or_else(|| {
                "no swap or one-image shift of the lists explains it: check that each camera's images are of the same robot poses, in the same order, and that the calibration images belong to this rig".into()
            });
            return Err(DatasetError::Input(format!(
                "the cameras disagree on {} of {} poses (the target from each camera alone, carried by the calibrated rig, {median:.1} mm apart in the median, more than {s} sigma, measure.cameras_disagree_sigmas): {cause}; nothing written",
                bad.len(),
                a.poses.len()
            )));
        }
        Ok(())
    }
}
