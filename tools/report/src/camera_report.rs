//! The HTML report of `ferrocal camera calibrate --report R.html`: the intrinsics with their
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

use nalgebra::{DMatrix, Point2, Point3};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use serde_json::json;

use ferrocal_vision::calib::heldout::HeldOut;
use ferrocal_vision::calib::{CameraCalibration, PlanarTarget, View};
use ferrocal_vision::camera::CameraModel;

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
    // The target's outline: its points' bounding rectangle on its plane.
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for p in &target.points_m {
        (x0, x1, y0, y1) = (x0.min(p.x), x1.max(p.x), y0.min(p.y), y1.max(p.y));
    }
    let outline = [
        Point3::new(x0, y0, 0.0),
        Point3::new(x1, y0, 0.0),
        Point3::new(x1, y1, 0.0),
        Point3::new(x0, y1, 0.0),
        Point3::new(x0, y0, 0.0),
    ];
    let views: Vec<Vec<Point3<f64>>> =
        cal.views.iter().filter(|v| v.used).map(|v| outline.iter().map(|p| v.t_cam_target * p).collect()).collect();
    for (title, a, b, a_name) in [
        ("Seen from above (x against z)", 0usize, 2usize, "x [m]"),
        ("Seen from the side (y against z)", 1, 2, "y [m]"),
    ] {
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, (PLOT_W, 420)).into_drawing_area();
            let _ = root.fill(&WHITE);
            let all = views.iter().flatten();
            let (lo_a, hi_a) = all.clone().fold((0.0f64, 0.0f64), |(l, h), p| (l.min(p[a]), h.max(p[a])));
            let hi_b = all.fold(0.0f64, |h, p| h.max(p[b])) * 1.1 + 1e-3;
            let pad = 0.1 * (hi_a - lo_a).max(1e-3);
            if let Ok(mut chart) = ChartBuilder::on(&root)
                .caption(title, ("sans-serif", 16))
                .margin(10)
                .x_label_area_size(35)
                .y_label_area_size(50)
                .build_cartesian_2d(0.0..hi_b, (lo_a - pad)..(hi_a + pad))
            {
                let _ = chart.configure_mesh().x_desc("z [m] (along the optical axis)").y_desc(a_name).draw();
                let _ = chart.draw_series(std::iter::once(Circle::new((0.0, 0.0), 5, BLACK.filled())));
                for (i, v) in views.iter().enumerate() {
                    let c = Palette99::pick(i);
                    let _ = chart.draw_series(std::iter::once(PathElement::new(
                        v.iter().map(|p| (p[b], p[a])).collect::<Vec<_>>(),
                        c.stroke_width(2),
                    )));
                }
            }
            let _ = root.present();
        }
        s.figure(&format!("{title}: the camera at the origin (black), each used view's target outline"), svg);
    }
    s
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
