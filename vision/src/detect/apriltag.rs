//! AprilTags: the C library (through the `apriltag` crate) as the detector, kornia-apriltag run
//! beside it for comparison, corner refinement of the outer border, and AprilTag boards of
//! known layout.
//!
//! # Library version, resolution and corner refinement
//! The workspace links the C library 3.2.0 (`apriltag-sys` 0.3). By default
//! ([`AprilTagOptions::default`]) quads are fitted at full resolution (decimation 1), where the
//! library's edge refinement (which exists to undo decimation) is off: this finds all 47 tags of
//! the library's own test photos and reproduces its published corners, whereas the library's
//! speed default (decimation 2 with edge refinement) finds 34 of them with corners 0.3 to 0.5 px
//! away. [`TagRefine::EdgeModel`] refits the four outer border edges with this project's
//! blurred-step model ([`crate::subpix::refine_quad`]) and reports covariances.
//!
//! # Conventions
//! The C library reports corners with pixel centres at integer + 0.5 (its issue #121): this
//! module subtracts 0.5 so that corners follow this project's convention (pixel `(0, 0)` is the
//! centre of the top-left pixel). kornia-apriltag follows the C library's convention and gets
//! the same shift. Corners keep the C library's order: counter-clockwise around the tag as
//! printed (y up), starting at the bottom-left corner: bottom-left, bottom-right, top-right,
//! top-left; kornia's corners are put into the same order (through its decoded homography).

use std::time::Instant;

use image::GrayImage;
use nalgebra::{Point2, Point3};
use serde::{Deserialize, Serialize};

use super::image::GrayF32;
use super::pattern::{Pattern, TagFamily};
use super::{Corner, Detection};
use crate::error::{Result, VisionError};
use crate::subpix::{refine_quad, RefineOptions, RefinedCorner};

/// Which implementation decodes the tags.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TagBackend {
    /// The AprilTag C library (the reference).
    #[default]
    CLibrary,
    /// kornia-apriltag (pure Rust).
    Kornia,
}

/// Options of the AprilTag detectors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct AprilTagOptions {
    /// Which implementation.
    pub backend: TagBackend,
    /// Quad detection on an image decimated by this factor (the C library's default 2).
    pub decimation: f32,
    /// Threads of the C library.
    pub threads: u8,
    /// Bit errors corrected (0..=2; the C library's demo uses 2).
    pub max_hamming: u8,
    /// How the corners are refined.
    pub refine: TagRefine,
}

impl Default for AprilTagOptions {
    /// Full resolution (decimation 1), 2 bits corrected, the backend's corners.
    fn default() -> Self {
        Self { backend: TagBackend::CLibrary, decimation: 1.0, threads: 1, max_hamming: 2, refine: TagRefine::Backend }
    }
}

/// Corner refinement of AprilTags.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TagRefine {
    /// The backend's corners (the C library refines its edges itself when decimating).
    #[default]
    Backend,
    /// This project's blurred-step fit of the outer border edges, with covariances.
    EdgeModel,
}

/// One decoded tag.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TagDetection {
    /// Family.
    pub family: TagFamily,
    /// Id.
    pub id: u32,
    /// Bits corrected.
    pub hamming: u32,
    /// The decoder's margin (higher is surer).
    pub decision_margin: f32,
    /// Corners as the backend reports them, shifted to the pixel-centre convention, C-library
    /// order.
    pub corners_px: [Point2<f64>; 4],
    /// The corners refined by the edge model, when asked for and successful.
    pub refined: Option<[RefinedCorner; 4]>,
}

impl TagDetection {
    /// The best corners: refined where available.
    pub fn best_corners_px(&self) -> [Point2<f64>; 4] {
        match &self.refined {
            Some(r) => [r[0].position_px, r[1].position_px, r[2].position_px, r[3].position_px],
            None => self.corners_px,
        }
    }
}

fn c_family(f: TagFamily) -> apriltag::Family {
    match f {
        TagFamily::Tag16h5 => apriltag::Family::tag_16h5(),
        TagFamily::Tag25h9 => apriltag::Family::tag_25h9(),
        TagFamily::Tag36h11 => apriltag::Family::tag_36h11(),
        TagFamily::TagCircle21h7 => apriltag::Family::tag_circle_21h7(),
        TagFamily::TagCircle49h12 => apriltag::Family::tag_circle_49h12(),
        TagFamily::TagCustom48h12 => apriltag::Family::tag_custom_48h12(),
        TagFamily::TagStandard41h12 => apriltag::Family::tag_standard_41h12(),
        TagFamily::TagStandard52h13 => apriltag::Family::tag_standard_52h13(),
    }
}

fn kornia_family(f: TagFamily) -> kornia_apriltag::family::TagFamilyKind {
    use kornia_apriltag::family::TagFamilyKind as K;
    match f {
        TagFamily::Tag16h5 => K::Tag16H5,
        TagFamily::Tag25h9 => K::Tag25H9,
        TagFamily::Tag36h11 => K::Tag36H11,
        TagFamily::TagCircle21h7 => K::TagCircle21H7,
        TagFamily::TagCircle49h12 => K::TagCircle49H12,
        TagFamily::TagCustom48h12 => K::TagCustom48H12,
        TagFamily::TagStandard41h12 => K::TagStandard41H12,
        TagFamily::TagStandard52h13 => K::TagStandard52H13,
    }
}

/// A reusable AprilTag detector for one family (the C library's detector and its decoding
/// tables are built once).
pub struct AprilTagDetector {
    family: TagFamily,
    options: AprilTagOptions,
    c: Option<apriltag::Detector>,
    kornia: Option<(kornia_apriltag::AprilTagDecoder, (usize, usize))>,
}

impl std::fmt::Debug for AprilTagDetector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AprilTagDetector").field("family", &self.family).field("options", &self.options).finish()
    }
}

fn backend_err(library: &'static str, e: impl std::fmt::Display) -> VisionError {
    VisionError::Backend { library, message: e.to_string() }
}

impl AprilTagDetector {
    /// Builds a detector.
    pub fn new(family: TagFamily, options: AprilTagOptions) -> Result<Self> {
        if !(options.decimation.is_finite() && options.decimation >= 1.0) {
            return Err(VisionError::BadOption {
                name: "decimation",
                value: options.decimation.to_string(),
                reason: "must be >= 1".into(),
            });
        }
        if options.max_hamming > 3 {
            return Err(VisionError::BadOption {
                name: "max_hamming",
                value: options.max_hamming.to_string(),
                reason: "must lie in 0..=3".into(),
            });
        }
        Ok(Self { family, options, c: None, kornia: None })
    }

    /// The family.
    pub fn family(&self) -> TagFamily {
        self.family
    }

    /// Detects the tags of an image with the configured backend.
    pub fn detect(&mut self, img: &GrayImage) -> Result<Vec<TagDetection>> {
        if img.width() == 0 || img.height() == 0 {
            return Err(VisionError::BadImage { reason: "the image has no pixels".into() });
        }
        let mut tags = match self.options.backend {
            TagBackend::CLibrary => self.detect_c(img)?,
            TagBackend::Kornia => self.detect_kornia(img)?,
        };
        tags.sort_by(|a, b| a.id.cmp(&b.id).then(a.corners_px[0].x.total_cmp(&b.corners_px[0].x)));
        if self.options.refine == TagRefine::EdgeModel && self.family.classic_border() {
            let f = GrayF32::from_gray8(img)?;
            for t in &mut tags {
                t.refined = refine_tag(&f, self.family, &t.corners_px)?;
            }
        }
        Ok(tags)
    }

    /// The C library's detections.
    pub fn detect_c(&mut self, img: &GrayImage) -> Result<Vec<TagDetection>> {
        if self.c.is_none() {
            let mut d = apriltag::DetectorBuilder::new()
                .add_family_bits(c_family(self.family), self.options.max_hamming as usize)
                .build()
                .map_err(|e| backend_err("apriltag (C)", format!("{e:?}")))?;
            d.set_decimation(self.options.decimation);
            d.set_thread_number(self.options.threads.max(1));
            d.set_refine_edges(self.options.decimation > 1.0);
            self.c = Some(d);
        }
        let det = self.c.as_mut().expect("built above");
        let (w, h) = (img.width() as usize, img.height() as usize);
        let mut im =
            apriltag::Image::zeros_with_stride(w, h, w).map_err(|e| backend_err("apriltag (C)", format!("{e:?}")))?;
        im.as_slice_mut().copy_from_slice(img.as_raw());
        let family = self.family;
        Ok(det
            .detect(&im)
            .into_iter()
            .map(|d| {
                let c = d.corners();
                TagDetection {
                    family,
                    id: d.id() as u32,
                    hamming: d.hamming() as u32,
                    decision_margin: d.decision_margin(),
                    corners_px: c.map(|p| Point2::new(p[0] - 0.5, p[1] - 0.5)),
                    refined: None,
                }
            })
            .collect())
    }

    /// kornia-apriltag's detections, corners put into the C library's order.
    pub fn detect_kornia(&mut self, img: &GrayImage) -> Result<Vec<TagDetection>> {
        use kornia_apriltag::{AprilTagDecoder, DecodeTagsConfig};
        use kornia_image::{Image, ImageSize};
        let (w, h) = (img.width() as usize, img.height() as usize);
        let rebuild = !matches!(&self.kornia, Some((_, s)) if *s == (w, h));
        if rebuild {
            let mut cfg = DecodeTagsConfig::new(vec![kornia_family(self.family)])
                .map_err(|e| backend_err("kornia-apriltag", e))?;
            cfg.downscale_factor = self.options.decimation.round().max(1.0) as usize;
            let dec = AprilTagDecoder::new(cfg, ImageSize { width: w, height: h })
                .map_err(|e| backend_err("kornia-apriltag", e))?;
            self.kornia = Some((dec, (w, h)));
        }
        let (dec, _) = self.kornia.as_mut().expect("built above");
        dec.clear();
        let src = Image::<u8, 1>::new(ImageSize { width: w, height: h }, img.as_raw().clone())
            .map_err(|e| backend_err("kornia-image", e))?;
        let found = dec.decode(&src).map_err(|e| backend_err("kornia-apriltag", e))?;
        let family = self.family;
        Ok(found
            .into_iter()
            .map(|d| {
                // kornia keeps the quad's corners in image order and puts the decoded
                // rotation into the homography; the C library's corners are that homography
                // at the tag coordinates (-1, 1), (1, 1), (1, -1), (-1, -1).
                let hp = |x: f32, y: f32| d.quad.homography_project(x, y);
                let k = [hp(-1.0, 1.0), hp(1.0, 1.0), hp(1.0, -1.0), hp(-1.0, -1.0)];
                TagDetection {
                    family,
                    id: u32::from(d.id),
                    hamming: u32::from(d.hamming),
                    decision_margin: d.decision_margin,
                    corners_px: k.map(|p| Point2::new(f64::from(p.x) - 0.5, f64::from(p.y) - 0.5)),
                    refined: None,
                }
            })
            .collect())
    }
}

/// Refines a tag's four corners from its outer border edges: the band is kept inside the
/// black border cell and the white cell around it.
fn refine_tag(img: &GrayF32, family: TagFamily, corners: &[Point2<f64>; 4]) -> Result<Option<[RefinedCorner; 4]>> {
    let side = (0..4).map(|k| (corners[(k + 1) % 4] - corners[k]).norm()).fold(f64::INFINITY, f64::min);
    let (border, _) = family.cells();
    let cell = side / f64::from(border);
    if cell < 2.0 {
        return Ok(None);
    }
    let options =
        RefineOptions { max_band_px: Some((cell - 0.5).max(1.0)), max_segment_px: 1e4, ..RefineOptions::default() };
    let (out, _) = refine_quad(img, corners, &options)?;
    let mut res = Vec::with_capacity(4);
    for (rc, c0) in out.into_iter().zip(corners) {
        match rc {
            Some(rc) if (rc.position_px - c0).norm() < 0.5 * cell => res.push(rc),
            _ => return Ok(None),
        }
    }
    Ok(Some([res[0], res[1], res[2], res[3]]))
}

/// The corner positions of a tag centred at `(xc, yc)` with half side `h`, C-library order
/// (target frame: x right, y up).
fn tag_target(xc: f64, yc: f64, h: f64) -> [Point3<f64>; 4] {
    [
        Point3::new(xc - h, yc - h, 0.0),
        Point3::new(xc + h, yc - h, 0.0),
        Point3::new(xc + h, yc + h, 0.0),
        Point3::new(xc - h, yc + h, 0.0),
    ]
}

/// Turns tag detections into [`Detection`]s; `target(id)` gives the tag's corner positions
/// on the target when known.
pub(crate) fn to_detections(tags: &[TagDetection], target: impl Fn(u32) -> Option<[Point3<f64>; 4]>) -> Vec<Detection> {
    tags.iter()
        .map(|t| {
            let tp = target(t.id);
            let corners = (0..4)
                .map(|k| {
                    let (pos, cov, crb) = match &t.refined {
                        Some(r) => (r[k].position_px, Some(r[k].covariance_px2), r[k].crb_px2),
                        None => (t.corners_px[k], None, None),
                    };
                    Corner {
                        position_px: pos,
                        covariance_px2: cov,
                        crb_px2: crb,
                        target_m: tp.map(|p| p[k]),
                        grid_index: None,
                        point_id: None,
                    }
                })
                .collect();
            Detection { id: Some(t.id), corners, complete: true, anchored: true, circle_radii_m: None }
        })
        .collect()
}

/// Target positions of single tags of side `tag_mm` (tag-centred frame).
pub(crate) fn single_tag_target(tag_mm: Option<f64>) -> impl Fn(u32) -> Option<[Point3<f64>; 4]> {
    move |_| tag_mm.map(|t| tag_target(0.0, 0.0, 0.5 * t * 1e-3))
}

/// Corner positions of the `k`-th tag (`k = id - first_id`) of an AprilTag board pattern,
/// `None` for other patterns. `aprilboard`: the layout of `ferrocal_datasets`'
/// `TargetConfig::AprilTagBoard` (origin at the board centre, ids row by row from the
/// top-left); `aprilgrid`: Kalibr's Aprilgrid (origin at the bottom-left corner of the first
/// tag's black border, ids row by row from the bottom-left). Both: x right, y up as printed.
pub(crate) fn board_target(pattern: &Pattern) -> Option<impl Fn(u32) -> Option<[Point3<f64>; 4]>> {
    let Pattern::AprilBoard { cols, rows, tag_mm, spacing_mm, kalibr, .. } = *pattern else {
        return None;
    };
    Some(move |k: u32| {
        if k >= cols * rows {
            return None;
        }
        let (r, c) = (f64::from(k / cols), f64::from(k % cols));
        let pitch = (tag_mm + spacing_mm) * 1e-3;
        let h = 0.5 * tag_mm * 1e-3;
        let (xc, yc) = if kalibr {
            (c * pitch + h, r * pitch + h)
        } else {
            ((c - 0.5 * (f64::from(cols) - 1.0)) * pitch, (0.5 * (f64::from(rows) - 1.0) - r) * pitch)
        };
        Some(tag_target(xc, yc, h))
    })
}

/// The two backends on the same image.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TagBackendComparison {
    /// Ids found by the C library (sorted).
    pub c_ids: Vec<u32>,
    /// Ids found by kornia-apriltag (sorted).
    pub kornia_ids: Vec<u32>,
    /// Tags found by both (same id, same place).
    pub common: usize,
    /// Mean and largest corner distance between the two over the common tags, pixels.
    pub mean_corner_diff_px: f64,
    /// Largest corner distance, pixels.
    pub max_corner_diff_px: f64,
    /// Wall time of the C library, seconds.
    pub c_seconds: f64,
    /// Wall time of kornia-apriltag, seconds.
    pub kornia_seconds: f64,
}

/// Runs the C library and kornia-apriltag on the same image and compares ids, corners and
/// time (tags of the same id are matched by their centres, within a quarter of the side).
pub fn compare_tag_backends(
    img: &GrayImage,
    family: TagFamily,
    options: &AprilTagOptions,
) -> Result<TagBackendComparison> {
    let mut det = AprilTagDetector::new(family, AprilTagOptions { refine: TagRefine::Backend, ..options.clone() })?;
    let t0 = Instant::now();
    let c = det.detect_c(img)?;
    let c_seconds = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let k = det.detect_kornia(img)?;
    let kornia_seconds = t1.elapsed().as_secs_f64();
    let mut c_ids: Vec<u32> = c.iter().map(|t| t.id).collect();
    let mut kornia_ids: Vec<u32> = k.iter().map(|t| t.id).collect();
    c_ids.sort_unstable();
    kornia_ids.sort_unstable();
    let centre = |t: &TagDetection| t.corners_px.iter().fold(nalgebra::Vector2::zeros(), |a, p| a + p.coords) / 4.0;
    let (mut sum, mut n, mut max, mut common) = (0.0, 0usize, 0.0f64, 0usize);
    let mut used = vec![false; k.len()];
    for a in &c {
        let best = k
            .iter()
            .enumerate()
            .filter(|(i, b)| b.id == a.id && !used[*i])
            .min_by(|x, y| (centre(x.1) - centre(a)).norm().total_cmp(&(centre(y.1) - centre(a)).norm()));
        // Same tag: centres within a quarter of the tag's side.
        let side = (a.corners_px[1] - a.corners_px[0]).norm();
        if let Some((i, b)) = best.filter(|(_, b)| (centre(b) - centre(a)).norm() < 0.25 * side) {
            used[i] = true;
            common += 1;
            for q in 0..4 {
                let d = (a.corners_px[q] - b.corners_px[q]).norm();
                sum += d;
                n += 1;
                max = max.max(d);
            }
        }
    }
    Ok(TagBackendComparison {
        c_ids,
        kornia_ids,
        common,
        mean_corner_diff_px: if n > 0 { sum / n as f64 } else { f64::NAN },
        max_corner_diff_px: max,
        c_seconds,
        kornia_seconds,
    })
}
