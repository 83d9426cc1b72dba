//! SVG plots for the reports (plotters' SVG backend).

use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

pub mod scene3d;
pub use scene3d::Scene3d;

/// Colours of successive series.
const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(127, 127, 127),
];

/// One named series of points.
pub struct Series<'a> {
    /// Legend name.
    pub name: &'a str,
    /// Points `(x, y)`.
    pub points: &'a [(f64, f64)],
    /// Draw as a connected line (else markers).
    pub line: bool,
}

fn range_of(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vals.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if hi - lo < 1e-12 {
        let pad = if lo.abs() > 0.0 { lo.abs() * 0.1 } else { 1.0 };
        return (lo - pad, hi + pad);
    }
    let pad = (hi - lo) * 0.05;
    (lo - pad, hi + pad)
}

/// The series' names, boxed in the upper right corner of a chart.
fn draw_legend<'a>(chart: &mut ChartContext<'a, SVGBackend<'a>, Cartesian2d<RangedCoordf64, RangedCoordf64>>) {
    let _ = chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw();
}

/// A scatter or line plot of one or more series.
pub fn xy_plot(title: &str, x_label: &str, y_label: &str, series: &[Series]) -> String {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (720, 420)).into_drawing_area();
        let _ = root.fill(&WHITE);
        let (x0, x1) = range_of(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
        let (y0, y1) = range_of(series.iter().flat_map(|s| s.points.iter().map(|p| p.1)));
        let Ok(mut chart) = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, y0..y1)
        else {
            return svg_error(title);
        };
        let _ = chart.configure_mesh().x_desc(x_label).y_desc(y_label).light_line_style(RGBColor(235, 235, 235)).draw();
        for (k, s) in series.iter().enumerate() {
            let c = PALETTE[k % PALETTE.len()];
            let pts: Vec<(f64, f64)> =
                s.points.iter().copied().filter(|p| p.0.is_finite() && p.1.is_finite()).collect();
            let drawn = if s.line {
                chart.draw_series(LineSeries::new(pts, c.stroke_width(2)))
            } else {
                chart.draw_series(pts.into_iter().map(|p| Circle::new(p, 2, c.filled())))
            };
            if let Ok(a) = drawn {
                a.label(s.name).legend(move |(x, y)| Rectangle::new([(x, y - 4), (x + 12, y + 4)], c.filled()));
            }
        }
        if series.len() > 1 {
            draw_legend(&mut chart);
        }
        let _ = root.present();
    }
    svg
}

/// One bar per item, coloured by group (e.g. train and test), with the items' labels along x.
/// `bars` are `(label, group, value)`; groups are coloured in order of first appearance and
/// named in the legend.
pub fn bar_chart(title: &str, y_label: &str, bars: &[(String, String, f64)]) -> String {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (720, 400)).into_drawing_area();
        let _ = root.fill(&WHITE);
        let top = bars.iter().map(|b| b.2).filter(|v| v.is_finite()).fold(0.0, f64::max).max(1e-12) * 1.15;
        let n = bars.len().max(1);
        let Ok(mut chart) = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(50)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..n as f64, 0.0..top)
        else {
            return svg_error(title);
        };
        let labels: Vec<String> = bars.iter().map(|b| b.0.clone()).collect();
        let _ = chart
            .configure_mesh()
            .y_desc(y_label)
            .x_labels(n.min(40))
            .x_label_formatter(&|x| labels.get(x.floor() as usize).cloned().unwrap_or_default())
            .light_line_style(RGBColor(235, 235, 235))
            .draw();
        let mut groups: Vec<&str> = Vec::new();
        for b in bars {
            if !groups.contains(&b.1.as_str()) {
                groups.push(&b.1);
            }
        }
        for (g, name) in groups.iter().enumerate() {
            let c = PALETTE[g % PALETTE.len()];
            let rects =
                bars.iter().enumerate().filter(|(_, b)| b.1 == *name && b.2.is_finite()).map(|(k, b)| {
                    Rectangle::new([(k as f64 + 0.15, 0.0), (k as f64 + 0.85, b.2)], c.mix(0.8).filled())
                });
            if let Ok(a) = chart.draw_series(rects) {
                a.label(*name).legend(move |(x, y)| Rectangle::new([(x, y - 4), (x + 12, y + 4)], c.filled()));
            }
        }
        draw_legend(&mut chart);
        let _ = root.present();
    }
    svg
}

/// A histogram of `values` with `bins` equal bins.
pub fn histogram(title: &str, x_label: &str, values: &[f64], bins: usize) -> String {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (720, 380)).into_drawing_area();
        let _ = root.fill(&WHITE);
        let (lo, hi) = range_of(values.iter().copied());
        let bins = bins.max(1);
        let w = (hi - lo) / bins as f64;
        let mut counts = vec![0usize; bins];
        for v in values.iter().filter(|v| v.is_finite()) {
            let k = (((v - lo) / w) as usize).min(bins - 1);
            counts[k] += 1;
        }
        let top = counts.iter().copied().max().unwrap_or(1).max(1) as f64 * 1.1;
        let Ok(mut chart) = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(lo..hi, 0.0..top)
        else {
            return svg_error(title);
        };
        let _ = chart.configure_mesh().x_desc(x_label).y_desc("count").draw();
        let _ = chart.draw_series(counts.iter().enumerate().map(|(k, c)| {
            let x = lo + w * k as f64;
            Rectangle::new([(x, 0.0), (x + w, *c as f64)], PALETTE[0].mix(0.7).filled())
        }));
        let _ = root.present();
    }
    svg
}

/// A matrix as a colour map (correlation and R-factor pictures of the calibration reports) (values clamped to `[lo, hi]`), with row/column labels.
pub fn matrix_map(title: &str, labels: &[String], values: &[Vec<f64>], lo: f64, hi: f64) -> String {
    let mut svg = String::new();
    let n = values.len().max(1);
    let cell = (560 / n).clamp(4, 40) as i32;
    let size = cell * n as i32;
    {
        let root = SVGBackend::with_string(&mut svg, ((size + 200) as u32, (size + 80) as u32)).into_drawing_area();
        let _ = root.fill(&WHITE);
        let _ = root.draw(&Text::new(title.to_string(), (10, 10), ("sans-serif", 16)));
        for (i, row) in values.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                let t = ((v - lo) / (hi - lo)).clamp(0.0, 1.0);
                // Blue (lo) - white - red (hi).
                let (r, g, b) = if t < 0.5 {
                    let s = t / 0.5;
                    ((255.0 * s) as u8, (255.0 * s) as u8, 255)
                } else {
                    let s = (1.0 - t) / 0.5;
                    (255, (255.0 * s) as u8, (255.0 * s) as u8)
                };
                let x = 150 + j as i32 * cell;
                let y = 40 + i as i32 * cell;
                let _ = root.draw(&Rectangle::new([(x, y), (x + cell, y + cell)], RGBColor(r, g, b).filled()));
            }
            if let Some(l) = labels.get(i) {
                if cell >= 8 {
                    let _ = root.draw(&Text::new(l.clone(), (5, 40 + i as i32 * cell + cell / 3), ("sans-serif", 10)));
                }
            }
        }
        let _ = root.present();
    }
    svg
}

fn svg_error(title: &str) -> String {
    format!("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"400\" height=\"40\"><text x=\"5\" y=\"20\">{title}: no data to plot</text></svg>")
}
