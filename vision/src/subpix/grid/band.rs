//! The rows of a band: which pixels of a row can lie in it ([`row_span`]).

use nalgebra::Vector2;

/// The columns `(first, last)` of pixel row `y_px`, within `cols`, that can hold pixels of a
/// band in pixel coordinates: where `lo <= t . (x - origin) <= hi` and
/// `|n . (x - origin) - d| <= half_width_px` can hold, widened by a pixel either way (the
/// caller tests every pixel of the span; a pixel outside it fails that test). A condition
/// that does not depend on the column does not narrow the span; `first > last` when the row
/// holds none.
#[allow(clippy::too_many_arguments)]
pub(super) fn row_span(
    origin: Vector2<f64>,
    t: Vector2<f64>,
    n: Vector2<f64>,
    d: f64,
    (lo, hi): (f64, f64),
    half_width_px: f64,
    y_px: f64,
    cols: (f64, f64),
) -> (f64, f64) {
    let dy = y_px - origin.y;
    let (mut first, mut last) = cols;
    // Each condition: lower <= slope * (x - origin.x) + offset <= upper.
    for (slope, offset, lower, upper) in [(t.x, t.y * dy, lo, hi), (n.x, n.y * dy - d, -half_width_px, half_width_px)] {
        if slope.abs() > 1e-9 {
            let (p, q) = ((lower - offset) / slope, (upper - offset) / slope);
            first = first.max((origin.x + p.min(q) - 1.0).floor());
            last = last.min((origin.x + p.max(q) + 1.0).ceil());
        }
    }
    (first, last)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every pixel of a band (of any direction, including the axis-parallel ones where a
    /// condition does not depend on the column) lies in its row's span, and the span is not
    /// much wider than the band's row: the band test over the spans finds the same pixels as
    /// over the whole bounding box, with fewer tested.
    #[test]
    fn the_span_holds_every_pixel_of_the_band() {
        let origin = Vector2::new(40.3, 37.8);
        let cols = (0.0, 90.0);
        let (mut in_band, mut tested, mut boxed) = (0usize, 0usize, 0usize);
        for k in 0..48 {
            let angle = k as f64 * std::f64::consts::PI / 24.0;
            let t = Vector2::new(angle.cos(), angle.sin());
            let n = Vector2::new(-t.y, t.x);
            let (d, lo, hi, w) = (0.37 - 0.02 * k as f64, -20.5 + 0.3 * k as f64, 25.2, 4.6);
            let inside = |x: f64, y: f64| {
                let p = Vector2::new(x, y) - origin;
                let tt = t.dot(&p);
                tt >= lo && tt <= hi && (n.dot(&p) - d).abs() <= w
            };
            for y in 0..80 {
                let (first, last) = row_span(origin, t, n, d, (lo, hi), w, y as f64, cols);
                assert!(first >= cols.0 && last <= cols.1);
                for x in 0..=90 {
                    let yes = inside(x as f64, y as f64);
                    boxed += 1;
                    in_band += usize::from(yes);
                    let spanned = x as f64 >= first && x as f64 <= last;
                    tested += usize::from(spanned);
                    assert!(!yes || spanned, "angle {angle} pixel ({x}, {y}) outside its span {first}..{last}");
                }
            }
        }
        assert!(in_band > 10_000, "{in_band}");
        assert!(tested < boxed / 3, "{tested} of {boxed} tested");
    }
}
