//! The HTML reports of `ferrocal camera calibrate --report R.html` and `ferrocal camera stereo
//! --report R.html` ([`stereo_report`]: both cameras' sections, the rig in 3-D and the
//! rectification check). The mono report: the intrinsics with their
//! standard deviations, every view's reprojection error, the residual vectors over the image,
//! where the corners fell (coverage), the target poses seen from above and from the side, and
//! how uncertain the projection is across the image.
//!
//! Projection uncertainty (in the spirit of mrcal): for a grid of pixels, the ray through each
//! pixel is taken to the views' median distance, projected back through the calibrated model, and
//! the parameter covariance propagated, `sigma_px = sqrt(trace(J C J^T) / 2)` with `J` the
//! projection's Jacobian with respect to the camera parameters. This is the part of the
//! uncertainty that the intrinsics carry; the uncertainty of where the camera sits (which mrcal
//! also marginalises) is not included.

use nalgebra::{DMatrix, Isometry3, Point2, Point3, Vector3};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use serde_json::json;

use ferrocal_vision::calib::heldout::HeldOut;
use ferrocal_vision::calib::{
    rectified_row_rms_px, CameraCalibration, PlanarTarget, RectifiedCorner, StereoCalibration, View,
};
use ferrocal_vision::camera::io::StereoPair;
use ferrocal_vision::camera::CameraModel;

use crate::plot::Scene3d;
use crate::report::{Provenance, Report, Section};

/// Width of the image plots, pixels of the SVG.
const PLOT_W: u32 = 720;

/// Everything the report shows, besides the calibration.
pub struct CameraReportInput<'a> {
    /// The pattern string.
    pub pattern: &'a str,
    /// The views the calibration was given (in the order of `cal.views`).
    pub views: &'a [View],
    /// The target.
    pub target: &'a PlanarTarget,
    /// Held-out views, when some were held out.
    pub held_out: Option<&'a HeldOut>,
    /// Settings and inputs.
    pub provenance: Provenance,
}

/// The report.
pub fn camera_report(cal: &CameraCalibration, input: CameraReportInput) -> Report {
    let mut rep = Report::new(&format!("Camera calibration ({})", input.pattern), input.provenance);
    rep.sections.push(summary(cal, input.held_out));
    rep.sections.push(per_view(cal, input.held_out));
    let residuals = residuals(cal, input.views, input.target);
    rep.sections.push(image_section(cal, &residuals));
    rep.sections.push(extrinsics(cal, input.target));
    rep.sections.push(projection_uncertainty(cal));
    rep
}

fn summary(cal: &CameraCalibration, held_out: Option<&HeldOut>) -> Section {
    let mut s = Section::new("camera", "The camera");
    let k = cal.camera.intrinsics;
    let mut rows = vec![
        vec!["fx [px]".into(), format!("{:.3}", k.fx_px), format!("{:.3}", cal.std[0])],
        vec!["fy [px]".into(), format!("{:.3}", k.fy_px), format!("{:.3}", cal.std[1])],
        vec!["cx [px]".into(), format!("{:.3}", k.cx_px), format!("{:.3}", cal.std[2])],
        vec!["cy [px]".into(), format!("{:.3}", k.cy_px), format!("{:.3}", cal.std[3])],
    ];
    let names = cal.camera.distortion.kind().coefficient_names();
    for (i, (n, v)) in names.iter().zip(cal.camera.distortion.coefficients()).enumerate() {
        rows.push(vec![
            n.to_string(),
            format!("{v:.6}"),
            format!("{:.6}", cal.std.get(4 + i).copied().unwrap_or(f64::NAN)),
        ]);
    }
    s.table("Intrinsics and distortion", &["parameter", "value", "standard deviation"], rows);
    let used = cal.views.iter().filter(|v| v.used).count();
    s.text(format!(
        "RMS reprojection error {:.4} px over {used} views ({} corners); {}",
        cal.rms_px,
        cal.summary.n_corners,
        match held_out.and_then(|h| h.rms_px) {
            Some(r) => format!(
                "on {} held-out views {r:.4} px (each view's pose fitted, the camera fixed).",
                held_out.map_or(0, |h| h.views.len())
            ),
            None => "no views held out (`--test-every K` holds every K-th image out).".into(),
        }
    ));
    for w in &cal.summary.warnings {
        s.text(format!("Warning: {w}"));
    }
    s.data = json!({"rms_px": cal.rms_px, "std": cal.std, "held_out": held_out});
    s
}

fn per_view(cal: &CameraCalibration, held_out: Option<&HeldOut>) -> Section {
    let mut s = Section::new("views", "Reprojection error per view");
    let short =
        |n: &str| std::path::Path::new(n).file_name().map_or(n.to_string(), |f| f.to_string_lossy().into_owned());
    let mut bars: Vec<(String, String, f64)> = cal
        .views
        .iter()
        .map(|v| {
            let group = if v.outlier {
                "outlier"
            } else if v.used {
                "fit"
            } else {
                "left out"
            };
            (short(&v.name), group.to_string(), v.rms_px)
        })
        .collect();
    if let Some(h) = held_out {
        bars.extend(h.views.iter().filter_map(|v| v.rms_px.map(|r| (short(&v.name), "held out".to_string(), r))));
    }
    s.figure("RMS reprojection error of each view", crate::plot::bar_chart("Per-view RMS", "RMS [px]", &bars));
    s
}

/// Every used corner: observed pixel and `projected - observed`.
fn residuals(cal: &CameraCalibration, views: &[View], target: &PlanarTarget) -> Vec<(Point2<f64>, [f64; 2])> {
    let mut out = Vec::new();
    for (v, r) in views.iter().zip(&cal.views) {
        if !r.used {
            continue;
        }
        for (id, px) in v.point_ids.iter().zip(&v.corners_px) {
            let Some(p) = target.points_m.get(*id) else { continue };
            if let Ok(q) = cal.camera.project(&(r.t_cam_target * p)) {
                out.push((*px, [q.x - px.x, q.y - px.y]));
            }
        }
    }
    out
}

/// A chart whose axes are the image's pixels, v pointing down as in the image.
type ImageChart<'a, 'b> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

fn image_chart<'a, 'b>(
    root: &'a DrawingArea<SVGBackend<'b>, plotters::coord::Shift>,
    title: &str,
    camera: &CameraModel,
) -> Option<ImageChart<'a, 'b>> {
    let (w, h) = (camera.image_size.width_px as f64, camera.image_size.height_px as f64);
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 16))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(50)
        .build_cartesian_2d(-0.5..w - 0.5, h - 0.5..-0.5)
        .ok()?;
    chart.configure_mesh().x_desc("u [px]").y_desc("v [px]").disable_mesh().draw().ok()?;
    Some(chart)
}

fn plot_height(camera: &CameraModel) -> u32 {
    let (w, h) = (camera.image_size.width_px as f64, camera.image_size.height_px as f64);
    ((PLOT_W as f64 - 60.0) * h / w + 80.0).round() as u32
}

fn image_section(cal: &CameraCalibration, residuals: &[(Point2<f64>, [f64; 2])]) -> Section {
    let mut s = Section::new("image", "Residuals and coverage over the image");
    let cam = &cal.camera;
    // Residual vectors, scaled so that the 95th percentile length is 4 % of the image width.
    let mut lens: Vec<f64> = residuals.iter().map(|(_, r)| r[0].hypot(r[1])).collect();
    lens.sort_by(f64::total_cmp);
    let p95 = lens.get(lens.len() * 95 / 100).copied().unwrap_or(0.0).max(1e-9);
    let scale = 0.04 * cam.image_size.width_px as f64 / p95;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (PLOT_W, plot_height(cam))).into_drawing_area();
        let _ = root.fill(&WHITE);
        let title = format!("Residuals (projected - observed) x {scale:.0}");
        if let Some(mut chart) = image_chart(&root, &title, cam) {
            let _ = chart.draw_series(residuals.iter().map(|(p, r)| {
                PathElement::new(vec![(p.x, p.y), (p.x + scale * r[0], p.y + scale * r[1])], RGBColor(214, 39, 40))
            }));
        }
        let _ = root.present();
    }
    s.figure(
        &format!("Each corner's residual vector drawn from where it was seen, magnified {scale:.0} times (95 % are shorter than {p95:.3} px): a pattern (radial, one corner of the image) means the model leaves something out; noise looks random."),
        svg,
    );
    let mut cov = String::new();
    {
        let root = SVGBackend::with_string(&mut cov, (PLOT_W, plot_height(cam))).into_drawing_area();
        let _ = root.fill(&WHITE);
        if let Some(mut chart) = image_chart(&root, "Coverage: every corner used", cam) {
            let _ = chart.draw_series(
                residuals.iter().map(|(p, _)| Circle::new((p.x, p.y), 1, RGBColor(31, 119, 180).filled())),
            );
        }
        let _ = root.present();
    }
    s.figure("Where the corners fell. Distortion is only known where corners were seen: empty corners of the image are extrapolated.", cov);
    s
}

fn extrinsics(cal: &CameraCalibration, target: &PlanarTarget) -> Section {
    let mut s = Section::new("extrinsics", "Target poses in the camera frame");
    let boards: Vec<Isometry3<f64>> = cal.views.iter().filter(|v| v.used).map(|v| v.t_cam_target).collect();
    let svg = board_scene("The camera and the board poses", &[(Isometry3::identity(), "camera")], &boards, target);
    s.figure(
        "In 3-D, in the camera's frame (drag to turn): the camera's viewing pyramid along its optical axis (+z), each used view's target outline (a dot on its origin corner).",
        svg,
    );
    s
}

/// The cameras (`t_frame_camera`, label) and the target outlines at `boards` (`t_frame_target`)
/// in one frame whose first camera looks along +z with image rows down (-y drawn up), as a 3-D
/// figure the reader turns.
fn board_scene(
    title: &str,
    cameras: &[(Isometry3<f64>, &str)],
    boards: &[Isometry3<f64>],
    target: &PlanarTarget,
) -> String {
    let outline = crate::plot::scene3d::target_outline(&target.points_m, 1.0);
    let depth = boards.iter().map(|t| t.translation.vector.norm()).fold(0.0, f64::max).max(1e-3);
    let mut sc = Scene3d::new(title, "m").with_up(-Vector3::y());
    for (i, t) in boards.iter().enumerate() {
        let k = 1 + i % 5;
        sc.outline(&outline.map(|p| t * p), k, 1.5);
        sc.dots(&[t * outline[0]], k, 2.5);
    }
    for (i, (t, label)) in cameras.iter().enumerate() {
        sc.camera(t, 0.15 * depth, if i == 0 { 5 } else { 0 }, label);
    }
    sc.to_svg()
}

/// The camera parameter covariance in the model's full parameter order (a fixed aspect ratio's
/// shared focal length expanded to fx and fy).
fn full_covariance(cal: &CameraCalibration) -> Option<DMatrix<f64>> {
    let n = cal.camera.n_parameters();
    let c = &cal.covariance;
    if c.nrows() == n {
        return Some(c.clone());
    }
    if c.nrows() + 1 == n {
        // Columns f, cx, cy, k... -> fx = fy = f.
        let mut t = DMatrix::zeros(n, n - 1);
        t[(0, 0)] = 1.0;
        t[(1, 0)] = cal.camera.intrinsics.fy_px / cal.camera.intrinsics.fx_px;
        for i in 2..n {
            t[(i, i - 1)] = 1.0;
        }
        return Some(&t * c * t.transpose());
    }
    None
}

fn projection_uncertainty(cal: &CameraCalibration) -> Section {
    let mut s = Section::new("uncertainty", "Projection uncertainty across the image");
    let Some(cov) = full_covariance(cal) else {
        s.text("The calibration's covariance has an unexpected size: no uncertainty map.");
        return s;
    };
    let mut dist: Vec<f64> =
        cal.views.iter().filter(|v| v.used).map(|v| v.t_cam_target.translation.vector.norm()).collect();
    dist.sort_by(f64::total_cmp);
    let d = dist.get(dist.len() / 2).copied().unwrap_or(1.0);
    let cam = &cal.camera;
    let (w, h) = (cam.image_size.width_px as f64, cam.image_size.height_px as f64);
    let (nx, ny) = (24usize, ((24.0 * h / w).round() as usize).max(2));
    let mut grid = vec![vec![f64::NAN; nx]; ny];
    for (j, row) in grid.iter_mut().enumerate() {
        for (i, cell) in row.iter_mut().enumerate() {
            let px = Point2::new((i as f64 + 0.5) * w / nx as f64 - 0.5, (j as f64 + 0.5) * h / ny as f64 - 0.5);
            let Ok(ray) = cam.unproject(&px) else { continue };
            let Ok(p) = cam.project_with_jacobians(&Point3::from(ray * d / ray.norm())) else { continue };
            let jc = DMatrix::from_fn(2, cov.nrows(), |r, c| p.d_pixel_d_params[(r, c)]);
            let sc = &jc * &cov * jc.transpose();
            *cell = (0.5 * (sc[(0, 0)] + sc[(1, 1)])).max(0.0).sqrt();
        }
    }
    let vals: Vec<f64> = grid.iter().flatten().copied().filter(|v| v.is_finite()).collect();
    let hi = vals.iter().cloned().fold(0.0, f64::max).max(1e-12);
    let lo = vals.iter().cloned().fold(f64::INFINITY, f64::min);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (PLOT_W, plot_height(cam))).into_drawing_area();
        let _ = root.fill(&WHITE);
        let title = format!("Projection sigma at {d:.2} m: {lo:.4} (white) to {hi:.4} px (red)");
        if let Some(mut chart) = image_chart(&root, &title, cam) {
            let _ = chart.draw_series(grid.iter().enumerate().flat_map(|(j, row)| {
                row.iter().enumerate().map(move |(i, v)| {
                    let t = if v.is_finite() { ((v - lo) / (hi - lo).max(1e-12)).clamp(0.0, 1.0) } else { 0.0 };
                    let c = RGBColor(255, (255.0 * (1.0 - t)) as u8, (255.0 * (1.0 - t)) as u8);
                    let (x0, y0) = (i as f64 * w / nx as f64 - 0.5, j as f64 * h / ny as f64 - 0.5);
                    Rectangle::new([(x0, y0), (x0 + w / nx as f64, y0 + h / ny as f64)], c.filled())
                })
            }));
        }
        let _ = root.present();
    }
    s.figure("How far a point at the views' median distance may project from where the calibrated model puts it, from the intrinsics' covariance alone: small where the corners were, growing where the model extrapolates.", svg);
    s.data = json!({"distance_m": d, "sigma_px_min": lo, "sigma_px_max": hi, "grid": grid});
    s
}

/// Everything the stereo report shows, besides the calibration.
pub struct StereoReportInput<'a> {
    /// The pattern string.
    pub pattern: &'a str,
    /// The left views as given to the calibration (`None` where the pattern was not found).
    pub left: &'a [Option<View>],
    /// The right views, paired with the left ones by index.
    pub right: &'a [Option<View>],
    /// The target.
    pub target: &'a PlanarTarget,
    /// The pair with its rectification.
    pub pair: &'a StereoPair,
    /// Corners seen in both images of a pair, rectified.
    pub corners: &'a [RectifiedCorner],
    /// Settings and inputs.
    pub provenance: Provenance,
}

/// Limit of the rectified row difference RMS for the rectification check, pixels.
pub const ROW_RMS_LIMIT_PX: f64 = 0.5;

/// The report of `ferrocal camera stereo --report R.html`: the rig (extrinsics with standard
/// deviations, baseline), per camera the sections of the mono report (intrinsics, per-view
/// errors, residual vectors and coverage, projection uncertainty), the two cameras and the
/// board poses from above and from the side, and the rectification check (the row difference
/// of corresponding corners after rectification).
pub fn stereo_report(st: &StereoCalibration, input: StereoReportInput) -> Report {
    let mut rep = Report::new(&format!("Stereo calibration ({})", input.pattern), input.provenance);
    rep.sections.push(rig_summary(st, input.pair));
    let n = input.target.points_m.len();
    for (k, (name, cal, views)) in
        [("left", st.left(), input.left), ("right", st.right(), input.right)].into_iter().enumerate()
    {
        // The views as the joint adjustment numbered them (a reversed view's ids flipped).
        let views: Vec<View> = views
            .iter()
            .flatten()
            .map(|v| {
                let mut v = v.clone();
                if st.calibration.reversed_views.iter().any(|(c, nm)| *c == k && *nm == v.name) {
                    v.point_ids = v.point_ids.iter().map(|id| n.wrapping_sub(1 + id)).collect();
                }
                v
            })
            .collect();
        let res = residuals(cal, &views, input.target);
        for mut s in [summary(cal, None), per_view(cal, None), image_section(cal, &res), projection_uncertainty(cal)] {
            s.id = format!("{name}-{}", s.id);
            s.title = format!("{} camera: {}", if k == 0 { "Left" } else { "Right" }, s.title);
            rep.sections.push(s);
        }
    }
    rep.sections.push(rig_views(st, input.target));
    rep.sections.push(rectification_check(input.pair, input.corners));
    rep
}

fn rig_summary(st: &StereoCalibration, pair: &StereoPair) -> Section {
    let mut s = Section::new("rig", "The rig: T_right_left");
    let mut rows = Vec::new();
    for (i, axis) in ["x", "y", "z"].iter().enumerate() {
        rows.push(vec![
            format!("rotation {axis} [deg]"),
            format!("{:.4}", st.rotation_deg[i]),
            format!("{:.4}", st.rotation_std_deg[i]),
        ]);
    }
    for (i, axis) in ["x", "y", "z"].iter().enumerate() {
        rows.push(vec![
            format!("translation {axis} [mm]"),
            format!("{:.3}", st.translation_mm[i]),
            format!("{:.3}", st.translation_std_mm[i]),
        ]);
    }
    rows.push(vec!["baseline [mm]".into(), format!("{:.3}", st.baseline_mm), format!("{:.3}", st.baseline_std_mm)]);
    s.table(
        "p_right = R p_left + T (OpenCV's R, T; rotation as a rotation vector)",
        &["parameter", "value", "standard deviation"],
        rows,
    );
    s.text(format!(
        "RMS reprojection error {:.4} px over both cameras (left {:.4} px, right {:.4} px), {} target poses, {} seen by both cameras; s0 {:.4} px.",
        st.calibration.rms_px,
        st.left().rms_px,
        st.right().rms_px,
        st.calibration.n_views,
        st.calibration.n_shared_views,
        st.calibration.s0_px
    ));
    if !st.calibration.reversed_views.is_empty() {
        s.text(format!(
            "Views whose corner numbering was reversed to match the left camera's: {}.",
            st.calibration.reversed_views.iter().map(|(_, n)| n.as_str()).collect::<Vec<_>>().join(", ")
        ));
    }
    s.data = json!({
        "rotation_deg": st.rotation_deg.as_slice(), "rotation_std_deg": st.rotation_std_deg.as_slice(),
        "translation_mm": st.translation_mm.as_slice(), "translation_std_mm": st.translation_std_mm.as_slice(),
        "baseline_mm": st.baseline_mm, "baseline_std_mm": st.baseline_std_mm, "rms_px": st.calibration.rms_px,
        "t_m": pair.t_m.as_slice(),
    });
    s
}

/// The two cameras and every used board pose in the left camera's frame, in 3-D.
fn rig_views(st: &StereoCalibration, target: &PlanarTarget) -> Section {
    let mut s = Section::new("rig-3d", "The rig and the board poses in 3-D");
    let boards: Vec<Isometry3<f64>> = st.left().views.iter().filter(|v| v.used).map(|v| v.t_cam_target).collect();
    let t_left_right = st.t_right_left.inverse();
    let cameras = [(Isometry3::identity(), "left"), (t_left_right, "right")];
    s.figure(
        "In the left camera's frame (drag to turn): both cameras' viewing pyramids, each used board pose's outline (a dot on its origin corner).",
        board_scene("The rig and the board poses", &cameras, &boards, target),
    );
    s.data = json!({"right_centre_in_left_m": (t_left_right * Point3::origin()).coords.as_slice(), "n_boards": boards.len()});
    s
}

fn rectification_check(pair: &StereoPair, corners: &[RectifiedCorner]) -> Section {
    let mut s = Section::new("rectification", "Rectification and epipolar check");
    let rc = &pair.rectification;
    let vertical = rc.vertical();
    let rms = rectified_row_rms_px(corners, vertical);
    let diff = |c: &RectifiedCorner| if vertical { c.left_px.x - c.right_px.x } else { c.left_px.y - c.right_px.y };
    let max = corners.iter().map(|c| diff(c).abs()).fold(0.0, f64::max);
    s.table(
        "The rectified cameras (Bouguet's method as OpenCV's stereoRectify: alpha = -1, CALIB_ZERO_DISPARITY)",
        &["quantity", "value"],
        vec![
            vec!["f' [px]".into(), format!("{:.3}", rc.focal_px())],
            vec!["cx', cy' [px]".into(), format!("{:.3}, {:.3}", rc.p1[(0, 2)], rc.p1[(1, 2)])],
            vec!["baseline [mm]".into(), format!("{:.3}", rc.baseline() * 1e3)],
            vec!["P2[0][3] = -f' B [px m]".into(), format!("{:.4}", rc.p2[(0, 3)])],
            vec!["corner pairs".into(), corners.len().to_string()],
            vec!["row difference RMS [px]".into(), format!("{rms:.4}")],
            vec!["largest row difference [px]".into(), format!("{max:.4}")],
        ],
    );
    s.text("Every corner seen in both images of a pair is undistorted and turned into both rectified images: a correct rectification puts it on the same row in both (the same column for vertical stereo). What remains is corner noise and model error.");
    let pts: Vec<(f64, f64)> =
        corners.iter().map(|c| (if vertical { c.left_px.y } else { c.left_px.x }, diff(c))).collect();
    s.figure(
        "Row difference of each corner pair against its rectified position: a trend across the image means the extrinsics or a lens model are off.",
        crate::plot::xy_plot(
            "Rectified row difference v_left - v_right",
            if vertical { "v left [px]" } else { "u left [px]" },
            "row difference [px]",
            &[crate::plot::Series { name: "corner pairs", points: &pts, line: false }],
        ),
    );
    s.status(
        rms < ROW_RMS_LIMIT_PX,
        format!("row difference RMS {rms:.4} px (limit {ROW_RMS_LIMIT_PX} px) over {} corner pairs", corners.len()),
    );
    s.data = json!({"row_rms_px": rms, "row_max_px": max, "n_corner_pairs": corners.len(), "focal_px": rc.focal_px(),
        "baseline_mm": rc.baseline() * 1e3});
    s
}
