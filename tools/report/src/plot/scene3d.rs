//! A 3-D scene as an SVG figure the reader turns by dragging.
//!
//! The figure is an orthographic view drawn here, in Rust, at a default angle (readable without
//! scripts, in print and in the JSON twin), and every element carries its 3-D coordinates
//! (`data-p`, normalised to the scene's bounding sphere) for a few lines of inline script that
//! redraw it at the angle the reader drags to. Nothing is loaded from elsewhere: the report
//! works offline. The script's projection is the one of [`project`], written twice (Rust and
//! JavaScript): `scripts/report_check.py` turns every scene in a real browser to the default
//! angle (`svg.turn(...svg.home)`) and checks that the script draws what Rust drew, then to
//! other angles and checks that the scene stays inside its figure.

use std::fmt::Write as _;

use nalgebra::{Isometry3, Point3, Rotation3, Vector3};

use super::PALETTE;

/// Width and height of the figure, px.
const W_PX: f64 = 720.0;
const H_PX: f64 = 520.0;
/// The default view: azimuth and elevation, radians.
const AZIMUTH_RAD: f64 = -0.95;
const ELEVATION_RAD: f64 = 0.45;

/// What an element of the scene is drawn as.
#[derive(Clone, Debug)]
enum Shape {
    /// A polyline (closed: back to its first point).
    Line { closed: bool, width_px: f64 },
    /// A filled dot at the one point.
    Dot { radius_px: f64 },
    /// A text label at the one point.
    Label(String),
}

#[derive(Clone, Debug)]
struct Item {
    pts: Vec<Point3<f64>>,
    colour: String,
    shape: Shape,
}

/// A scene of lines, dots, cameras and frames in one metric frame, with a legend.
#[derive(Clone, Debug)]
pub struct Scene3d {
    title: String,
    unit: String,
    up: Vector3<f64>,
    items: Vec<Item>,
    legend: Vec<(String, String)>,
}

/// The colour of series `k` (the plots' palette), as SVG text.
pub fn colour(k: usize) -> String {
    let c = PALETTE[k % PALETTE.len()];
    format!("#{:02x}{:02x}{:02x}", c.0, c.1, c.2)
}

/// The outline of a planar target: the corners of its points' bounding rectangle on its plane
/// (z = 0), in order, each coordinate times `scale` (e.g. 1e3 for metres to mm).
pub fn target_outline(points: &[Point3<f64>], scale: f64) -> [Point3<f64>; 4] {
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for p in points {
        (x0, x1, y0, y1) = (x0.min(p.x), x1.max(p.x), y0.min(p.y), y1.max(p.y));
    }
    [(x0, y0), (x1, y0), (x1, y1), (x0, y1)].map(|(x, y)| Point3::new(x * scale, y * scale, 0.0))
}

/// Screen coordinates (px) of the normalised point `p` seen from azimuth `az` and elevation
/// `el` (radians, about the scene's up axis +z): orthographic, right-handed, `k` px per unit,
/// the centre at `(cx, cy)`.
pub fn project(p: &[f64; 3], az: f64, el: f64, k: f64, cx: f64, cy: f64) -> (f64, f64) {
    let (sa, ca, se, ce) = (az.sin(), az.cos(), el.sin(), el.cos());
    let u = -sa * p[0] + ca * p[1];
    let v = -se * ca * p[0] - se * sa * p[1] + ce * p[2];
    (cx + k * u, cy - k * v)
}

impl Scene3d {
    /// An empty scene titled `title` whose lengths are in `unit` (shown in the caption and on
    /// the scale bar); up is +z.
    pub fn new(title: &str, unit: &str) -> Self {
        Self { title: title.into(), unit: unit.into(), up: Vector3::z(), items: Vec::new(), legend: Vec::new() }
    }

    /// The direction drawn upwards (e.g. `-y` for a camera frame).
    pub fn with_up(mut self, up: Vector3<f64>) -> Self {
        if up.norm() > 0.0 {
            self.up = up.normalize();
        }
        self
    }

    /// Whether nothing was added.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    fn push(&mut self, pts: Vec<Point3<f64>>, colour: String, shape: Shape) {
        if !pts.is_empty() && pts.iter().all(|p| p.coords.iter().all(|v| v.is_finite())) {
            self.items.push(Item { pts, colour, shape });
        }
    }

    /// A polyline through `pts` in colour `k`.
    pub fn line(&mut self, pts: &[Point3<f64>], k: usize, width_px: f64) {
        self.push(pts.to_vec(), colour(k), Shape::Line { closed: false, width_px });
    }

    /// A closed outline through `pts` in colour `k`.
    pub fn outline(&mut self, pts: &[Point3<f64>], k: usize, width_px: f64) {
        self.push(pts.to_vec(), colour(k), Shape::Line { closed: true, width_px });
    }

    /// One dot per point in colour `k`.
    pub fn dots(&mut self, pts: &[Point3<f64>], k: usize, radius_px: f64) {
        for p in pts {
            self.push(vec![*p], colour(k), Shape::Dot { radius_px });
        }
    }

    /// A text label at `p`.
    pub fn label(&mut self, p: Point3<f64>, text: &str) {
        self.push(vec![p], "#222".into(), Shape::Label(text.into()));
    }

    /// A camera at `t_world_camera` as a viewing pyramid `size` deep along its optical axis
    /// (+z, image rows along +y), in colour `k`, with a tick on its image's top edge and a label.
    pub fn camera(&mut self, t_world_camera: &Isometry3<f64>, size: f64, k: usize, label: &str) {
        let c = t_world_camera * Point3::origin();
        let (w, h) = (0.6 * size, 0.45 * size);
        let corners = [(-w, -h), (w, -h), (w, h), (-w, h)].map(|(x, y)| t_world_camera * Point3::new(x, y, size));
        self.outline(&corners, k, 1.5);
        for q in &corners {
            self.line(&[c, *q], k, 1.0);
        }
        let top = [t_world_camera * Point3::new(-0.2 * w, -h, size), t_world_camera * Point3::new(0.0, -1.4 * h, size)];
        self.line(&[top[0], top[1], t_world_camera * Point3::new(0.2 * w, -h, size)], k, 1.0);
        self.dots(&[c], k, 3.5);
        self.label(c, label);
    }

    /// A coordinate frame at `t` with axes `size` long (x red, y green, z blue) and a label.
    pub fn frame(&mut self, t: &Isometry3<f64>, size: f64, label: &str) {
        let o = t * Point3::origin();
        for (axis, rgb) in [(Vector3::x(), "#d62728"), (Vector3::y(), "#2ca02c"), (Vector3::z(), "#1f77b4")] {
            self.push(vec![o, t * Point3::from(axis * size)], rgb.into(), Shape::Line { closed: false, width_px: 2.0 });
        }
        self.label(o, label);
    }

    /// A legend entry: colour `k` means `text`.
    pub fn legend(&mut self, k: usize, text: &str) {
        self.legend.push((colour(k), text.into()));
    }

    /// The points rotated so that `up` is +z, their centre and the radius of the sphere about
    /// it that holds them all.
    fn normalised(&self) -> (Vec<Vec<[f64; 3]>>, f64) {
        let r_up = Rotation3::rotation_between(&self.up, &Vector3::z())
            .unwrap_or_else(|| Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI));
        let pts: Vec<Vec<Point3<f64>>> =
            self.items.iter().map(|it| it.pts.iter().map(|p| r_up * p).collect()).collect();
        let all = || pts.iter().flatten();
        let (mut lo, mut hi) = (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY));
        for p in all() {
            lo = lo.inf(&p.coords);
            hi = hi.sup(&p.coords);
        }
        let centre = if lo.x.is_finite() { (lo + hi) / 2.0 } else { Vector3::zeros() };
        let radius = all().map(|p| (p.coords - centre).norm()).fold(0.0, f64::max).max(1e-12);
        let norm = pts.iter().map(|v| v.iter().map(|p| ((p.coords - centre) / radius).into())).map(Iterator::collect);
        (norm.collect(), radius)
    }

    /// The figure: an `<svg>` with the view at the default angle, a scale bar, the legend and
    /// the script that turns it.
    pub fn to_svg(&self) -> String {
        let (pts, radius) = self.normalised();
        let (cx, cy) = (W_PX / 2.0, 30.0 + (H_PX - 30.0) / 2.0);
        let k = 0.46 * (H_PX - 40.0).min(W_PX);
        let at = |p: &[f64; 3]| project(p, AZIMUTH_RAD, ELEVATION_RAD, k, cx, cy);
        let mut s = String::new();
        let _ = write!(
            s,
            r##"<svg xmlns="http://www.w3.org/2000/svg" width="{W_PX}" height="{H_PX}" viewBox="0 0 {W_PX} {H_PX}" style="max-width:100%;height:auto;cursor:grab;touch-action:none" class="scene3d"><rect width="100%" height="100%" fill="white"/><text x="{}" y="20" text-anchor="middle" font-family="sans-serif" font-size="16">{}</text><text x="{}" y="{}" text-anchor="end" font-family="sans-serif" font-size="11" fill="#666">drag to turn; lengths in {}</text>"##,
            W_PX / 2.0,
            esc(&self.title),
            W_PX - 8.0,
            H_PX - 8.0,
            esc(&self.unit)
        );
        for (item, p) in self.items.iter().zip(&pts) {
            let data: Vec<String> = p.iter().map(|q| format!("{:.4} {:.4} {:.4}", q[0], q[1], q[2])).collect();
            let data = data.join(" ");
            let xy: Vec<(f64, f64)> = p.iter().map(at).collect();
            match &item.shape {
                Shape::Line { closed, width_px } => {
                    let points: Vec<String> = xy.iter().map(|(x, y)| format!("{x:.1},{y:.1}")).collect();
                    let tag = if *closed { "polygon" } else { "polyline" };
                    let _ = write!(
                        s,
                        r#"<{tag} data-p="{data}" points="{}" fill="none" stroke="{}" stroke-width="{width_px}" stroke-linejoin="round"/>"#,
                        points.join(" "),
                        item.colour
                    );
                }
                Shape::Dot { radius_px } => {
                    let _ = write!(
                        s,
                        r#"<circle data-p="{data}" cx="{:.1}" cy="{:.1}" r="{radius_px}" fill="{}"/>"#,
                        xy[0].0, xy[0].1, item.colour
                    );
                }
                Shape::Label(text) => {
                    let _ = write!(
                        s,
                        r#"<text data-p="{data}" x="{:.1}" y="{:.1}" font-family="sans-serif" font-size="12" fill="{}">{}</text>"#,
                        xy[0].0 + 4.0,
                        xy[0].1 - 4.0,
                        item.colour,
                        esc(text)
                    );
                }
            }
        }
        // Scale bar: orthographic, so its length on screen does not change as the view turns.
        let bar = nice_length(radius / 2.0);
        let bar_px = k * bar / radius;
        let _ = write!(
            s,
            r##"<line x1="12" y1="{y:.1}" x2="{x2:.1}" y2="{y:.1}" stroke="#222" stroke-width="2"/><text x="12" y="{ty:.1}" font-family="sans-serif" font-size="11">{} {}</text>"##,
            fmt_length(bar),
            esc(&self.unit),
            y = H_PX - 14.0,
            x2 = 12.0 + bar_px,
            ty = H_PX - 20.0
        );
        for (i, (c, text)) in self.legend.iter().enumerate() {
            let y = 40.0 + 16.0 * i as f64;
            let _ = write!(
                s,
                r#"<rect x="10" y="{:.1}" width="12" height="4" fill="{c}"/><text x="28" y="{:.1}" font-family="sans-serif" font-size="12">{}</text>"#,
                y - 4.0,
                y + 1.0,
                esc(text)
            );
        }
        let _ = write!(s, "<script>{}</script></svg>", script(k, cx, cy));
        s
    }
}

/// The script that redraws the figure it sits in at the angle the reader drags to ([`project`]).
/// Inside an inline `<svg>` of an HTML page a script is parsed as markup, so it holds no `<`
/// and no `&`.
fn script(k: f64, cx: f64, cy: f64) -> String {
    format!(
        "(function(){{var s=document.currentScript.parentNode,az={AZIMUTH_RAD},el={ELEVATION_RAD},k={k},cx={cx},cy={cy};\
var E=[].slice.call(s.querySelectorAll('[data-p]')),P=E.map(function(e){{return e.getAttribute('data-p').split(' ').map(Number)}});\
function f(x,y,z){{var sa=Math.sin(az),ca=Math.cos(az),se=Math.sin(el),ce=Math.cos(el);return[cx+k*(-sa*x+ca*y),cy-k*(-se*ca*x-se*sa*y+ce*z)]}}\
function r(v){{return v.toFixed(1)}}\
function draw(){{E.forEach(function(e,i){{var p=P[i],o=[];for(var j=0;p.length>j+2;j+=3)o.push(f(p[j],p[j+1],p[j+2]));var t=e.tagName.toLowerCase();\
if(t=='circle'){{e.setAttribute('cx',r(o[0][0]));e.setAttribute('cy',r(o[0][1]))}}else if(t=='text'){{e.setAttribute('x',r(o[0][0]+4));e.setAttribute('y',r(o[0][1]-4))}}\
else e.setAttribute('points',o.map(function(q){{return r(q[0])+','+r(q[1])}}).join(' '))}})}}\
var d=null;s.addEventListener('pointerdown',function(v){{d=[v.clientX,v.clientY,az,el];s.setPointerCapture(v.pointerId)}});\
s.addEventListener('pointermove',function(v){{if(!d)return;az=d[2]-(v.clientX-d[0])*0.01;el=Math.max(-1.55,Math.min(1.55,d[3]+(v.clientY-d[1])*0.01));draw()}});\
s.addEventListener('pointerup',function(){{d=null}});s.home=[az,el];s.turn=function(a,b){{az=a;el=b;draw()}};}})();"
    )
}

/// A round length (1, 2 or 5 times a power of ten) at or below `x`.
fn nice_length(x: f64) -> f64 {
    if !(x > 0.0 && x.is_finite()) {
        return 1.0;
    }
    let p = 10f64.powf(x.log10().floor());
    [5.0, 2.0, 1.0].into_iter().map(|m| m * p).find(|v| *v <= x).unwrap_or(p)
}

fn fmt_length(v: f64) -> String {
    if v >= 1.0 {
        format!("{v:.0}")
    } else {
        let digits = (-v.log10().floor()).max(0.0) as usize;
        format!("{v:.digits$}")
    }
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

#[cfg(test)]
mod tests;
