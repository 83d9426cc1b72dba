//! The `camera calibrate` and `camera stereo` workflows: the pattern found in every image
//! ([`CameraViews::detect`], [`StereoViews::detect`]), the views split into training and
//! held-out ones, the calibration ([`CameraViews::calibrate`], [`StereoViews::calibrate`]), the
//! held-out scoring ([`CameraRun::held_out`]) and the rectified row check of a pair
//! ([`StereoRun::rectify`]); and the views of a camera's diagnosis ([`target_point_views`]).
//! The binary turns its arguments into the options and prints; the
//! report crate turns the results into JSON, camera files and HTML (`ferrocal_report::camera`).
//!
//! A bad image never stops the batch: it is listed in `skipped` with the reason. Too few usable
//! views is an error that says how many were usable and why the others were not.

use std::collections::HashMap;
use std::path::PathBuf;

use ferrocal_calib::verdict::StereoLimits;
use ferrocal_vision::calib::corners::{detect_pattern_views, CornerMethod, PatternViews, SkippedImage};
use ferrocal_vision::calib::heldout::{held_out_reprojection, HeldOut};
use ferrocal_vision::calib::{
    calibrate_pattern, calibrate_stereo, check_pairing, rectified_row_rms_px, CalibrationOptions, CalibrationPattern,
    PairingCheck, PatternCalibration, PlanarTarget, RectifiedCorner, StereoCalibration, View, MIN_VIEWS,
};
use ferrocal_vision::camera::io::StereoPair;
use ferrocal_vision::camera::ImageSize;
use ferrocal_vision::detect::{load_gray, DetectOptions, Detector, Pattern};
use nalgebra::Point3;

use crate::error::{DatasetError, Result};

/// The error of too few usable views: how many were usable of how many images, and why the
/// others were skipped.
///
/// When at least half the skipped images found exactly `(cols - 1) x (rows - 1)` corners of a
/// chessboard, the error says first that the pattern looks given by its squares, with the
/// pattern string to try (`vision::detect::chessboard::squares_hint`).
pub fn too_few_views(what: &str, usable: usize, total: usize, skipped: &[SkippedImage]) -> DatasetError {
    use ferrocal_vision::detect::chessboard::SQUARES_HINT_WORDS;
    let reasons: Vec<String> = skipped.iter().map(ToString::to_string).collect();
    let hinted: Vec<&String> = reasons.iter().filter(|r| r.contains(SQUARES_HINT_WORDS)).collect();
    let squares = match hinted.first() {
        Some(r) if 2 * hinted.len() >= reasons.len() => {
            let hint = &r[r.find(SQUARES_HINT_WORDS).unwrap_or(0) + 2..];
            format!("; {hint} (each of {} image(s) shows exactly that many corners)", hinted.len())
        }
        _ => String::new(),
    };
    let short: Vec<String> =
        reasons.iter().map(|r| r.split(SQUARES_HINT_WORDS).next().unwrap_or(r).to_string()).collect();
    DatasetError::Input(format!(
        "{what}: {usable} usable view(s) of {total} image(s), at least {MIN_VIEWS} needed{}{}",
        squares,
        if reasons.is_empty() { String::new() } else { format!("; skipped: {}", short.join("; ")) }
    ))
}

/// Refuses a stereo pair given `left` and `right` images of different counts (the pairs are
/// formed by sorted order).
pub fn check_pairs(left: usize, right: usize) -> Result<()> {
    if left != right {
        return Err(DatasetError::Input(format!(
            "camera stereo: {left} left and {right} right images; the pairs are formed by sorted order, so give as many of each"
        )));
    }
    Ok(())
}

/// The pattern found in one camera's images.
#[derive(Clone, Debug)]
pub struct CameraViews {
    /// The image files, in order.
    pub paths: Vec<PathBuf>,
    /// What the detector found: one slot per image, and the circle grids' dot radii.
    pub found: PatternViews,
    /// The images left out (named by no file, or unusable), with the reasons.
    pub skipped: Vec<SkippedImage>,
    /// Where the corners came from.
    pub method: CornerMethod,
}

impl CameraViews {
    /// Finds `pattern` in every image of `paths` with the corners of `method`; `skipped` are the
    /// specifications that named no image, to which the unusable images are added.
    pub fn detect(
        paths: Vec<PathBuf>,
        mut skipped: Vec<SkippedImage>,
        pattern: &CalibrationPattern,
        method: CornerMethod,
    ) -> Self {
        let mut found = detect_pattern_views(&paths, pattern, method);
        skipped.append(&mut found.skipped);
        Self { paths, found, skipped, method }
    }

    /// The views of detections made elsewhere ([`crate::import::observations`]) of `pattern`'s
    /// points, one camera's: each image a view of the points it lists, in the file's order;
    /// `image_size` is the images' size. An image without points is skipped with the reason; a
    /// point id the pattern does not have is an error naming the image and the id.
    pub fn from_observations(
        obs: &crate::import::observations::Observations,
        file: &std::path::Path,
        pattern: &CalibrationPattern,
        image_size: ImageSize,
    ) -> Result<Self> {
        let n_points = pattern.target().points_m.len();
        let cameras = obs.cameras();
        if cameras.len() > 1 {
            return Err(DatasetError::Input(format!(
                "{}: observations of {} cameras ({}); camera calibrate takes one camera's",
                file.display(),
                cameras.len(),
                cameras.join(", ")
            )));
        }
        let mut slots = Vec::new();
        let mut skipped = Vec::new();
        let mut paths = Vec::new();
        for i in &obs.images {
            paths.push(PathBuf::from(&i.image));
            if let Some(id) = i.point_ids.iter().find(|&&id| id >= n_points) {
                return Err(DatasetError::Input(format!(
                    "{} (line {}): image '{}' names point {id}, but the pattern {pattern} has points 0 to {}",
                    file.display(),
                    i.line,
                    i.image,
                    n_points.saturating_sub(1)
                )));
            }
            if i.point_ids.is_empty() {
                skipped.push(SkippedImage { image: PathBuf::from(&i.image), reason: "no points observed".into() });
                slots.push(None);
                continue;
            }
            slots.push(Some(View {
                name: i.image.clone(),
                image_size,
                point_ids: i.point_ids.clone(),
                corners_px: i.corners_px.clone(),
            }));
        }
        let found = PatternViews { slots, skipped: Vec::new(), circle_radii_m: None };
        Ok(Self { paths, found, skipped, method: CornerMethod::Observations })
    }

    /// The usable views' detections, as an observations file holds them (`camera` named
    /// `camera`).
    pub fn observations(&self, camera: &str) -> crate::import::observations::Observations {
        use crate::import::observations::{Observations, ObservedImage};
        let images = self
            .found
            .slots
            .iter()
            .flatten()
            .map(|v| ObservedImage {
                image: v.name.clone(),
                camera: camera.to_string(),
                point_ids: v.point_ids.clone(),
                corners_px: v.corners_px.clone(),
                sigma_px: vec![None; v.point_ids.len()],
                line: 0,
            })
            .collect();
        Observations { images }
    }

    /// Calibrates the camera on the views, holding out every `test_every`-th image (the K-th,
    /// 2K-th, ... in order) when given; refused with fewer than [`MIN_VIEWS`] training views.
    pub fn calibrate(
        self,
        pattern: &CalibrationPattern,
        options: &CalibrationOptions,
        test_every: Option<usize>,
    ) -> Result<CameraRun> {
        let k = match test_every {
            Some(0) => return Err(DatasetError::Input("camera calibrate: --test-every must be at least 1".into())),
            Some(k) => k,
            None => usize::MAX,
        };
        let (mut views, mut test_views) = (Vec::new(), Vec::new());
        for (i, slot) in self.found.slots.into_iter().enumerate() {
            match slot {
                Some(v) if (i + 1) % k == 0 => test_views.push(v),
                Some(v) => views.push(v),
                None => {}
            }
        }
        if views.len() < MIN_VIEWS {
            return Err(too_few_views("camera calibrate", views.len(), self.paths.len(), &self.skipped));
        }
        let fit = calibrate_pattern(&views, pattern, self.found.circle_radii_m, options).map_err(|e| {
            DatasetError::Input(format!(
                "camera calibrate: {e} ({} usable views of {} images)",
                views.len(),
                self.paths.len()
            ))
        })?;
        let (paths, skipped, method) = (self.paths, self.skipped, self.method);
        Ok(CameraRun { pattern: *pattern, options: options.clone(), method, paths, skipped, views, test_views, fit })
    }
}

/// One camera calibrated from its images.
#[derive(Clone, Debug)]
pub struct CameraRun {
    /// The pattern.
    pub pattern: CalibrationPattern,
    /// The options of the calibration.
    pub options: CalibrationOptions,
    /// Where the corners came from.
    pub method: CornerMethod,
    /// The image files, in order.
    pub paths: Vec<PathBuf>,
    /// The images left out, with the reasons.
    pub skipped: Vec<SkippedImage>,
    /// The training views.
    pub views: Vec<View>,
    /// The held-out views.
    pub test_views: Vec<View>,
    /// The calibration (with the circle grids' bias correction).
    pub fit: PatternCalibration,
}

impl CameraRun {
    /// The reprojection error of the calibrated camera on the held-out views, each view's pose
    /// fitted with the camera fixed.
    pub fn held_out(&self) -> Result<HeldOut> {
        Ok(held_out_reprojection(&self.fit.calibration.camera, &self.pattern.target(), &self.test_views)?)
    }

    /// The views the calibration used.
    pub fn n_used(&self) -> usize {
        self.fit.calibration.views.iter().filter(|v| v.used).count()
    }
}

/// The pattern found in the images of a stereo pair (paired by order).
#[derive(Clone, Debug)]
pub struct StereoViews {
    /// The left image files.
    pub left_paths: Vec<PathBuf>,
    /// The right image files.
    pub right_paths: Vec<PathBuf>,
    /// One slot per left image.
    pub left: Vec<Option<View>>,
    /// One slot per right image.
    pub right: Vec<Option<View>>,
    /// The images left out, with the reasons.
    pub skipped: Vec<SkippedImage>,
    /// Where the corners came from.
    pub method: CornerMethod,
}

impl StereoViews {
    /// Finds `pattern` in every left and right image with the corners of `method`; `skipped`
    /// are the specifications that named no image, to which the unusable images are added.
    pub fn detect(
        left_paths: Vec<PathBuf>,
        right_paths: Vec<PathBuf>,
        mut skipped: Vec<SkippedImage>,
        pattern: &CalibrationPattern,
        method: CornerMethod,
    ) -> Self {
        let l = detect_pattern_views(&left_paths, pattern, method);
        let r = detect_pattern_views(&right_paths, pattern, method);
        skipped.extend(l.skipped);
        skipped.extend(r.skipped);
        Self { left_paths, right_paths, left: l.slots, right: r.slots, skipped, method }
    }

    /// Calibrates the pair; refused with fewer than [`MIN_VIEWS`] usable views of a camera or
    /// without a pair in which both images show the pattern, and when more than
    /// `limits.pairs_disagree_fraction_fail` of the pairs disagree on the cameras' relative pose
    /// ([`check_pairing`]; the refusal names the shift of the right list that pairs the images
    /// when one makes at least 4 in 5 pairs agree).
    pub fn calibrate(
        self,
        pattern: &CalibrationPattern,
        options: &CalibrationOptions,
        limits: &StereoLimits,
    ) -> Result<StereoRun> {
        let n_left = self.left.iter().flatten().count();
        let n_right = self.right.iter().flatten().count();
        if n_left < MIN_VIEWS || n_right < MIN_VIEWS {
            let (side, n, total) = if n_left < MIN_VIEWS {
                ("left", n_left, self.left_paths.len())
            } else {
                ("right", n_right, self.right_paths.len())
            };
            return Err(too_few_views(&format!("camera stereo ({side} camera)"), n, total, &self.skipped));
        }
        let n_pairs = self.left.iter().zip(&self.right).filter(|(l, r)| l.is_some() && r.is_some()).count();
        if n_pairs == 0 {
            return Err(DatasetError::Input(
                "camera stereo: the pattern was never found in both images of a pair".into(),
            ));
        }
        let target = pattern.target();
        let pairing = check_pairing(&self.left, &self.right, &target, options, limits.pair_distance)
            .map_err(|e| DatasetError::Input(format!("camera stereo: {e}")))?;
        if pairing.disagree_fraction() > limits.pairs_disagree_fraction_fail {
            return Err(DatasetError::Input(pairing_refusal(&pairing, limits)));
        }
        let calibration = calibrate_stereo(&self.left, &self.right, &target, options)
            .map_err(|e| DatasetError::Input(format!("camera stereo: {e}")))?;
        Ok(StereoRun {
            views: self,
            pattern: *pattern,
            target,
            options: options.clone(),
            n_pairs,
            calibration,
            pairing,
        })
    }
}

/// A file name of a view's name (its image path), for messages.
fn file_name(name: &str) -> String {
    std::path::Path::new(name).file_name().map_or_else(|| name.to_string(), |f| f.to_string_lossy().into_owned())
}

/// Share of the pairs at a shift of the right list that must agree before the refusal names
/// the shift.
pub const SHIFT_AGREE_SHARE: f64 = 0.8;

/// The refusal of a recording whose pairs disagree on the cameras' relative pose: the pairs,
/// and the shift of the right list that pairs the images, when one does.
fn pairing_refusal(p: &PairingCheck, limits: &StereoLimits) -> String {
    let names: Vec<String> = p.disagreeing.iter().take(4).map(|n| file_name(n)).collect();
    let more = if p.disagreeing.len() > 4 { format!(" and {} more", p.disagreeing.len() - 4) } else { String::new() };
    let intro = format!(
        "camera stereo: the pairs disagree on the cameras' relative pose: {} of {} pairs ({}{more}) are far from the others' (more than {} of the pairs, stereo.pairs_disagree_fraction_fail)",
        p.disagreeing.len(),
        p.n_pairs,
        names.join(", "),
        limits.pairs_disagree_fraction_fail
    );
    match &p.best_shift {
        Some(s) if s.agreeing as f64 >= SHIFT_AGREE_SHARE * s.compared as f64 => {
            let (l, r) = (file_name(&s.example.0), file_name(&s.example.1));
            let side = if s.shift > 0 { "right" } else { "left" };
            format!(
                "{intro}: the {side} list looks shifted by {} image(s): left image k pairs with right image k{:+} ({l} with {r}); so paired, {} of {} pairs agree. Remove the extra image(s) or fix the lists' order, then calibrate again",
                s.shift.abs(),
                s.shift,
                s.agreeing,
                s.compared
            )
        }
        _ => format!(
            "{intro}: the left and right images do not look taken at the same instants (no shift of the lists by up to 2 images pairs them); check that left image k and right image k show the same board pose"
        ),
    }
}

/// A stereo pair calibrated from its images.
#[derive(Clone, Debug)]
pub struct StereoRun {
    /// The images and the views found in them.
    pub views: StereoViews,
    /// The pattern.
    pub pattern: CalibrationPattern,
    /// The pattern's target.
    pub target: PlanarTarget,
    /// The options of the calibration.
    pub options: CalibrationOptions,
    /// Pairs in which both images show the pattern.
    pub n_pairs: usize,
    /// The calibration.
    pub calibration: StereoCalibration,
    /// The pairs' agreement on the cameras' relative pose, before the joint fit.
    pub pairing: PairingCheck,
}

/// A pair's rectification with the corners seen in both images of a pair, rectified, and the
/// RMS of their row difference.
#[derive(Clone, Debug)]
pub struct Rectified {
    /// The pair as the stereo files hold it, with its rectification.
    pub pair: StereoPair,
    /// Every corner seen in both images of a pair, rectified in both.
    pub corners: Vec<RectifiedCorner>,
    /// RMS of the rectified row difference (column difference for vertical stereo), pixels.
    pub row_rms_px: f64,
}

impl StereoRun {
    /// The pair rectified, with the rectified row check. A pair that cannot be rectified (a wide
    /// fisheye whose image corners lie beyond 90 degrees) is an error only when the outputs need
    /// the rectification (`needed`); else the inner result is the reason.
    pub fn rectify(&self, needed: bool) -> Result<std::result::Result<Rectified, String>> {
        let pair = match self.calibration.pair() {
            Ok(p) => p,
            Err(e) if !needed => return Ok(Err(e.to_string())),
            Err(e) => {
                return Err(DatasetError::Input(format!(
                    "camera stereo: the pair cannot be rectified ({e}); the ROS and OpenCV stereo files and the report need it"
                )))
            }
        };
        let rect = &pair.rectification;
        let corners = self.calibration.rectified_corners(rect, &self.views.left, &self.views.right, &self.target);
        let row_rms_px = rectified_row_rms_px(&corners, rect.vertical());
        Ok(Ok(Rectified { pair, corners, row_rms_px }))
    }

    /// The left images, then the right ones.
    pub fn inputs(&self) -> Vec<PathBuf> {
        self.views.left_paths.iter().chain(&self.views.right_paths).cloned().collect()
    }
}

/// The views of the pattern `pattern` (a pattern string, e.g. `chessboard:9x6:25mm`) in the
/// images of `specs` (files, globs or folders), for a camera's diagnosis: the target's points
/// numbered by their position on the target (a 1 um grid), one view per image that shows the
/// pattern anchored with at least 4 corners. An image left out is named through `warn` with the
/// reason, and the batch goes on; `tick(done, total)` follows the detection. Images of
/// different sizes are refused (one camera, one image size).
pub fn target_point_views(
    specs: &[String],
    pattern: &str,
    warn: &dyn Fn(&str),
    tick: &dyn Fn(usize, usize),
) -> Result<(Vec<View>, PlanarTarget)> {
    let pattern: Pattern = pattern.parse()?;
    let mut detector = Detector::new(pattern, DetectOptions::default(), None)?;
    let mut files = Vec::new();
    for spec in specs {
        let folder = crate::import::list_images(spec, &Default::default())?;
        for s in &folder.skipped {
            warn(&format!("skipped {}: {}", s.path.display(), s.reason));
        }
        files.extend(folder.images.into_iter().map(|e| e.path));
    }
    let mut points: Vec<Point3<f64>> = Vec::new();
    let mut key_of = HashMap::new();
    let mut views = Vec::new();
    for (i, f) in files.iter().enumerate() {
        tick(i, files.len());
        let found = load_gray(f).and_then(|img| {
            let size = ImageSize { width_px: img.width(), height_px: img.height() };
            detector.detect(&img).map(|d| (d, size))
        });
        let (dets, size) = match found {
            Ok(x) => x,
            Err(e) => {
                warn(&format!("{}: {e}", f.display()));
                continue;
            }
        };
        let mut ids = Vec::new();
        let mut px = Vec::new();
        for c in dets.iter().filter(|d| d.anchored).flat_map(|d| &d.corners) {
            let Some(t) = c.target_m else { continue };
            let key = ((t.x * 1e6).round() as i64, (t.y * 1e6).round() as i64, (t.z * 1e6).round() as i64);
            let id = *key_of.entry(key).or_insert_with(|| {
                points.push(t);
                points.len() - 1
            });
            ids.push(id);
            px.push(c.position_px);
        }
        if px.len() < 4 {
            warn(&format!("{}: the pattern was not found whole (or has no size in the pattern string)", f.display()));
            continue;
        }
        let mut v = View::new(f.display().to_string(), size, px);
        v.point_ids = ids;
        views.push(v);
    }
    tick(files.len(), files.len());
    if let Some(first) = views.first() {
        let size = first.image_size;
        if let Some(bad) = views.iter().find(|v| v.image_size != size) {
            return Err(DatasetError::Input(format!(
                "{} is {}x{} px but {} is {}x{}: one camera, one image size",
                bad.name, bad.image_size.width_px, bad.image_size.height_px, first.name, size.width_px, size.height_px
            )));
        }
    }
    Ok((views, PlanarTarget { points_m: points, reversible: false }))
}

/// The views of a stereo pair's diagnosis: the pattern `pattern` (a pattern string, e.g.
/// `chessboard:9x6:25mm`) found in the `left` and `right` images (files, globs or folders),
/// paired by sorted order as `camera stereo` pairs them (refused unless both sides name as many
/// images), with the pattern's target. Images left out are in [`StereoViews::skipped`] with the
/// reason.
pub fn stereo_diagnosis_views(left: &[String], right: &[String], pattern: &str) -> Result<(StereoViews, PlanarTarget)> {
    let pattern: CalibrationPattern = pattern.parse().map_err(|e| DatasetError::Input(format!("--pattern: {e}")))?;
    let mut skipped = Vec::new();
    let paths = |specs: &[String], skipped: &mut Vec<SkippedImage>| {
        crate::import::images::expand_image_specs(&specs.iter().map(PathBuf::from).collect::<Vec<_>>(), skipped)
    };
    let (l, r) = (paths(left, &mut skipped), paths(right, &mut skipped));
    check_pairs(l.len(), r.len())?;
    Ok((StereoViews::detect(l, r, skipped, &pattern, CornerMethod::Own), pattern.target()))
}
