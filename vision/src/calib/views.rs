//! The views before a calibration: their checks (sizes, corners, spread of the board's poses) and their homographies; the median of a list.

use super::*;

/// Median of a list (0 for an empty one).
pub fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

/// Checks the views' shapes against the target; all views must share one image size.
pub(crate) fn check_views(views: &[&View], target: &PlanarTarget) -> Result<ImageSize> {
    for v in views {
        if v.point_ids.len() != v.corners_px.len() {
            return Err(VisionError::InvalidInput {
                detail: format!("{}: {} point ids for {} corners", v.name, v.point_ids.len(), v.corners_px.len()),
            });
        }
        if let Some(&bad) = v.point_ids.iter().find(|&&i| i >= target.points_m.len()) {
            return Err(VisionError::InvalidInput {
                detail: format!("{}: point id {bad}, but the target has {} points", v.name, target.points_m.len()),
            });
        }
        if v.corners_px.iter().any(|p| !(p.x.is_finite() && p.y.is_finite())) {
            return Err(VisionError::InvalidInput { detail: format!("{}: a corner is not finite", v.name) });
        }
    }
    let Some(first) = views.first() else {
        return Err(VisionError::TooFewViews { usable: 0, needed: MIN_VIEWS, detail: "no views were given".into() });
    };
    let mut sizes: Vec<(ImageSize, Vec<&str>)> = Vec::new();
    for v in views {
        match sizes.iter_mut().find(|(s, _)| *s == v.image_size) {
            Some((_, names)) => names.push(&v.name),
            None => sizes.push((v.image_size, vec![&v.name])),
        }
    }
    if sizes.len() > 1 {
        sizes.sort_by_key(|(_, n)| std::cmp::Reverse(n.len()));
        let detail = sizes
            .iter()
            .map(|(s, names)| format!("{}x{}: {}", s.width_px, s.height_px, names.join(", ")))
            .collect::<Vec<_>>()
            .join("; ");
        return Err(VisionError::ImageSizeMismatch {
            detail: format!("{detail} (calibrate each camera and resolution separately)"),
        });
    }
    Ok(first.image_size)
}

/// The homography of a view (pixels from target-plane coordinates, metres), or why it has none.
pub(crate) fn view_homography(
    view: &View,
    target: &PlanarTarget,
    t_plane_target: &Isometry3<f64>,
) -> std::result::Result<nalgebra::Matrix3<f64>, String> {
    if view.corners_px.len() < 4 {
        return Err(format!("{} corners, a view needs at least 4", view.corners_px.len()));
    }
    let src: Vec<Point2<f64>> = view
        .point_ids
        .iter()
        .map(|&i| {
            let q = t_plane_target * target.points_m[i];
            Point2::new(q.x, q.y)
        })
        .collect();
    homography::homography_dlt(&src, &view.corners_px)
        .ok_or_else(|| "the corners are collinear or coincide (no homography)".to_string())
}
