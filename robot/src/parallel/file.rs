//! TOML model files for parallel robots (schema: `docs/model-format.md`).
//!
//! [`load`] reads a file, [`parse_str`] a string, [`to_toml_string`] / [`save`] write one. Every
//! loading error names the file, the 1-based line and column, and the table and field at fault.

use std::ops::Range;
use std::path::Path;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use toml::de::{DeTable, DeValue};
use toml::Spanned;

use super::gantry_tau6::LINK_ARMS;
use super::{Branch, GantryArm, GantryTau3, GantryTau6, GantryTauF1, Guideway, Hexapod, HexapodLeg, Link, RotaryStage};
use crate::error::{line_col, Location, Result, RobotError};
use crate::geometry::Pose;
use crate::kinematics::JointLimits;
use crate::model::RobotModel;

/// The model kinds a file can hold (`kind = "..."`).
pub const KINDS: &[&str] = &["gantry_tau_3", "gantry_tau_6", "gantry_tau_f1", "hexapod"];

/// Reads a parallel-robot model file.
pub fn load(path: &Path) -> Result<RobotModel> {
    let text = std::fs::read_to_string(path).map_err(|source| RobotError::Io { path: path.to_path_buf(), source })?;
    parse_str(&text, path)
}

/// Parses a model from `text`; `file` is only used in error messages.
pub fn parse_str(text: &str, file: &Path) -> Result<RobotModel> {
    let cx = Cx { text, file };
    let doc = DeTable::parse(text).map_err(|e| {
        let span = e.span().unwrap_or(0..0);
        cx.err(&span, format!("TOML syntax: {}", e.message().trim()))
    })?;
    let top = Tbl { cx: &cx, map: doc.get_ref(), span: 0..0, what: "the model".into() };
    let kind_v = top.req("kind")?;
    let kind = top.string("kind")?;
    match kind.as_str() {
        "gantry_tau_3" => parse_gt3(&top).map(RobotModel::GantryTau3),
        "gantry_tau_6" => parse_gt6(&top).map(RobotModel::GantryTau6),
        "gantry_tau_f1" => parse_f1(&top).map(RobotModel::GantryTauF1),
        "hexapod" => parse_hexapod(&top).map(RobotModel::Hexapod),
        other => {
            Err(cx.err(&kind_v.span(), format!("unknown model kind '{other}'; expected one of {}", KINDS.join(", "))))
        }
    }
}

/// Writes a parallel-robot model file.
pub fn save(model: &RobotModel, path: &Path) -> Result<()> {
    let text = to_toml_string(model)?;
    std::fs::write(path, text).map_err(|source| RobotError::Io { path: path.to_path_buf(), source })
}

struct Cx<'a> {
    text: &'a str,
    file: &'a Path,
}

impl Cx<'_> {
    fn loc(&self, span: &Range<usize>) -> Location {
        let (line, column) = line_col(self.text, span.start);
        Location { file: self.file.to_path_buf(), line, column }
    }

    fn err(&self, span: &Range<usize>, message: String) -> RobotError {
        RobotError::Parse { location: self.loc(span), message }
    }
}

type Val<'i> = Spanned<DeValue<'i>>;

/// One TOML table with the context needed for messages.
struct Tbl<'a, 'i> {
    cx: &'a Cx<'a>,
    map: &'a DeTable<'i>,
    span: Range<usize>,
    what: String,
}

impl<'a, 'i> Tbl<'a, 'i> {
    fn get(&self, key: &str) -> Option<&'a Val<'i>> {
        self.map.iter().find(|(k, _)| k.get_ref() == key).map(|(_, v)| v)
    }

    fn req(&self, key: &str) -> Result<&'a Val<'i>> {
        self.get(key).ok_or_else(|| self.cx.err(&self.span, format!("{}: missing field `{key}`", self.what)))
    }

    /// Rejects keys outside `allowed` (typos would otherwise be silently ignored).
    fn only(&self, allowed: &[&str]) -> Result<()> {
        for (k, _) in self.map.iter() {
            if !allowed.contains(&k.get_ref().as_ref()) {
                return Err(self.cx.err(
                    &k.span(),
                    format!("{}: unknown field `{}`; expected one of: {}", self.what, k.get_ref(), allowed.join(", ")),
                ));
            }
        }
        Ok(())
    }

    fn number(&self, v: &Val<'i>, what: &str) -> Result<f64> {
        let x = match v.get_ref() {
            DeValue::Float(f) => {
                let s = f.as_str();
                s.parse::<f64>().ok().or_else(|| s.contains("nan").then_some(f64::NAN))
            }
            DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix()).ok().map(|i| i as f64),
            other => {
                return Err(self.cx.err(&v.span(), format!("{what}: expected a number, found {}", other.type_str())))
            }
        };
        let x = x.ok_or_else(|| self.cx.err(&v.span(), format!("{what}: not a valid number")))?;
        if !x.is_finite() {
            return Err(RobotError::NonFinite { location: self.cx.loc(&v.span()), what: what.to_string() });
        }
        Ok(x)
    }

    fn f64(&self, key: &str) -> Result<f64> {
        let v = self.req(key)?;
        self.number(v, &format!("{}: `{key}`", self.what))
    }

    fn positive(&self, key: &str) -> Result<f64> {
        let x = self.f64(key)?;
        if x > 0.0 {
            Ok(x)
        } else {
            Err(self.cx.err(&self.req(key)?.span(), format!("{}: `{key}` must be positive, got {x}", self.what)))
        }
    }

    fn numbers(&self, key: &str, n: usize) -> Result<Vec<f64>> {
        let v = self.req(key)?;
        let what = format!("{}: `{key}`", self.what);
        let arr = v
            .get_ref()
            .as_array()
            .ok_or_else(|| self.cx.err(&v.span(), format!("{what}: expected an array of {n} numbers")))?;
        if arr.len() != n {
            return Err(self.cx.err(&v.span(), format!("{what}: expected {n} numbers, found {}", arr.len())));
        }
        arr.iter().enumerate().map(|(i, e)| self.number(e, &format!("{what}[{i}]"))).collect()
    }

    fn vec3(&self, key: &str) -> Result<Vector3<f64>> {
        let v = self.numbers(key, 3)?;
        Ok(Vector3::new(v[0], v[1], v[2]))
    }

    fn direction(&self, key: &str) -> Result<Vector3<f64>> {
        let v = self.vec3(key)?;
        if v.norm() > 1e-9 {
            Ok(v)
        } else {
            Err(self.cx.err(
                &self.req(key)?.span(),
                format!("{}: `{key}` has zero length; a direction needs a non-zero vector", self.what),
            ))
        }
    }

    fn opt_direction(&self, key: &str) -> Result<Option<Vector3<f64>>> {
        self.get(key).map(|_| self.direction(key)).transpose()
    }

    fn limits(&self, key: &str, joint: &str) -> Result<JointLimits> {
        let v = self.numbers(key, 2)?;
        if v[0] > v[1] {
            return Err(RobotError::BadLimits {
                joint: joint.to_string(),
                lower: v[0],
                upper: v[1],
                location: Some(self.cx.loc(&self.req(key)?.span())),
            });
        }
        Ok(JointLimits { lower: v[0], upper: v[1] })
    }

    fn string(&self, key: &str) -> Result<String> {
        let v = self.req(key)?;
        v.get_ref().as_str().map(str::to_string).ok_or_else(|| {
            self.cx.err(&v.span(), format!("{}: `{key}` must be a string, found {}", self.what, v.get_ref().type_str()))
        })
    }

    fn branch(&self, key: &str) -> Result<Branch> {
        let s = self.string(key)?;
        match s.as_str() {
            "plus" => Ok(Branch::Plus),
            "minus" => Ok(Branch::Minus),
            _ => Err(self.cx.err(
                &self.req(key)?.span(),
                format!("{}: `{key}` must be \"plus\" or \"minus\", got \"{s}\"", self.what),
            )),
        }
    }

    fn integer(&self, key: &str) -> Result<i64> {
        let v = self.req(key)?;
        match v.get_ref() {
            DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix())
                .map_err(|_| self.cx.err(&v.span(), format!("{}: `{key}` is out of range", self.what))),
            other => Err(self
                .cx
                .err(&v.span(), format!("{}: `{key}` must be an integer, found {}", self.what, other.type_str()))),
        }
    }

    fn table(&self, key: &str, what: String) -> Result<Tbl<'a, 'i>> {
        let v = self.req(key)?;
        let map = v
            .get_ref()
            .as_table()
            .ok_or_else(|| self.cx.err(&v.span(), format!("{}: `{key}` must be a table ([{key}])", self.what)))?;
        Ok(Tbl { cx: self.cx, map, span: v.span(), what })
    }

    fn opt_table(&self, key: &str, what: String) -> Result<Option<Tbl<'a, 'i>>> {
        self.get(key).map(|_| self.table(key, what)).transpose()
    }

    /// The `[[key]]` tables; exactly `n` of them.
    fn tables(&self, key: &str, n: usize, what: impl Fn(usize) -> String) -> Result<Vec<Tbl<'a, 'i>>> {
        let v = self.get(key).ok_or_else(|| {
            self.cx.err(&self.span, format!("{}: missing the [[{key}]] tables (this kind needs {n})", self.what))
        })?;
        let arr = v.get_ref().as_array().ok_or_else(|| {
            self.cx.err(&v.span(), format!("{}: `{key}` must be an array of tables ([[{key}]])", self.what))
        })?;
        if arr.len() != n {
            return Err(self
                .cx
                .err(&v.span(), format!("{}: expected {n} [[{key}]] tables, found {}", self.what, arr.len())));
        }
        arr.iter()
            .enumerate()
            .map(|(i, e)| {
                let map = e
                    .get_ref()
                    .as_table()
                    .ok_or_else(|| self.cx.err(&e.span(), format!("{}: `{key}` entries must be tables", self.what)))?;
                Ok(Tbl { cx: self.cx, map, span: e.span(), what: what(i) })
            })
            .collect()
    }

    fn pose(&self, what: String, key: &str) -> Result<Option<Pose>> {
        let Some(t) = self.opt_table(key, what)? else {
            return Ok(None);
        };
        t.only(&["xyz_m", "rotvec_rad"])?;
        let xyz = t.vec3("xyz_m")?;
        let rv = t.vec3("rotvec_rad")?;
        Ok(Some(Isometry3::from_parts(Translation3::from(xyz), UnitQuaternion::from_scaled_axis(rv))))
    }
}

fn parse_gt3(top: &Tbl) -> Result<GantryTau3> {
    top.only(&["kind", "name", "assembly", "arm"])?;
    let arms = top.tables("arm", 3, |i| format!("arm {}", i + 1))?;
    let mut out = Vec::with_capacity(3);
    for (i, t) in arms.iter().enumerate() {
        t.only(&["length_m", "a_m", "v", "branch", "limits_m", "base_axis", "platform_axis"])?;
        out.push(GantryArm {
            length_m: t.positive("length_m")?,
            a_m: t.vec3("a_m")?,
            v: t.direction("v")?,
            limits: t.limits("limits_m", &format!("cart{}", i + 1))?,
            branch: t.branch("branch")?,
            base_axis: t.opt_direction("base_axis")?,
            platform_axis: t.opt_direction("platform_axis")?,
        });
    }
    let arms: [GantryArm; 3] = out.try_into().map_err(|_| top.cx.err(&top.span, "three arms expected".into()))?;
    let m = GantryTau3 { name: top.string("name")?, arms, assembly: top.branch("assembly")? };
    m.validate()?;
    Ok(m)
}

fn parse_guideways(top: &Tbl) -> Result<[Guideway; 3]> {
    let g = top.tables("guideway", 3, |i| format!("guideway {} (cart{})", i + 1, i + 1))?;
    let mut out = Vec::with_capacity(3);
    for (i, t) in g.iter().enumerate() {
        t.only(&["v", "branch", "limits_m"])?;
        out.push(Guideway {
            v: t.direction("v")?,
            limits: t.limits("limits_m", &format!("cart{}", i + 1))?,
            branch: t.branch("branch")?,
        });
    }
    out.try_into().map_err(|_| top.cx.err(&top.span, "three guideways expected".into()))
}

/// The `[[link]]` tables, ordered by arm (stable), checked against the 1-2-3 cluster layout.
fn parse_links(top: &Tbl, a_key: &str) -> Result<Vec<Link>> {
    let tables = top.tables("link", 6, |i| format!("link {}", i + 1))?;
    let mut links = Vec::with_capacity(6);
    for t in &tables {
        t.only(&["arm", a_key, "b0_m", "length_m", "base_axis", "platform_axis"])?;
        let arm = t.integer("arm")?;
        if !(1..=3).contains(&arm) {
            return Err(t.cx.err(&t.req("arm")?.span(), format!("{}: `arm` must be 1, 2 or 3, got {arm}", t.what)));
        }
        links.push(Link {
            arm: (arm - 1) as usize,
            a_m: t.vec3(a_key)?,
            b0_m: t.vec3("b0_m")?,
            length_m: t.positive("length_m")?,
            base_axis: t.opt_direction("base_axis")?,
            platform_axis: t.opt_direction("platform_axis")?,
        });
    }
    let counts = [0, 1, 2].map(|a| links.iter().filter(|l| l.arm == a).count());
    if counts != [1, 2, 3] {
        return Err(top.cx.err(
            &top.get("link").map_or(0..0, |v| v.span()),
            format!(
                "the links must be 1 on arm 1, 2 on arm 2 and 3 on arm 3; found {}, {} and {}",
                counts[0], counts[1], counts[2]
            ),
        ));
    }
    links.sort_by_key(|l| l.arm);
    debug_assert!(links.iter().zip(LINK_ARMS).all(|(l, a)| l.arm == a));
    Ok(links)
}

fn parse_gt6(top: &Tbl) -> Result<GantryTau6> {
    top.only(&["kind", "name", "assembly", "tool", "guideway", "link"])?;
    let m = GantryTau6 {
        name: top.string("name")?,
        guideways: parse_guideways(top)?,
        links: parse_links(top, "a0_m")?,
        assembly: top.branch("assembly")?,
        tool: top.pose("tool".into(), "tool")?.unwrap_or_else(Pose::identity),
        solver: GantryTau6::default_solver(),
    };
    m.validate()?;
    Ok(m)
}

fn parse_f1(top: &Tbl) -> Result<GantryTauF1> {
    top.only(&["kind", "name", "assembly", "tool", "guideway", "rot2", "rot3", "tilt3", "link"])?;
    let stage = |key: &str| -> Result<RotaryStage> {
        let t = top.table(key, format!("rotary stage {key}"))?;
        t.only(&["point_m", "axis", "limits_rad"])?;
        Ok(RotaryStage {
            point_m: t.vec3("point_m")?,
            axis: t.direction("axis")?,
            limits: t.limits("limits_rad", key)?,
        })
    };
    let m = GantryTauF1 {
        name: top.string("name")?,
        guideways: parse_guideways(top)?,
        rot2: stage("rot2")?,
        rot3: stage("rot3")?,
        tilt3: stage("tilt3")?,
        links: parse_links(top, "a_m")?,
        assembly: top.branch("assembly")?,
        tool: top.pose("tool".into(), "tool")?.unwrap_or_else(Pose::identity),
        solver: GantryTauF1::default_solver(),
    };
    m.validate()?;
    Ok(m)
}

fn parse_hexapod(top: &Tbl) -> Result<Hexapod> {
    top.only(&["kind", "name", "home", "tool", "leg"])?;
    let tables = top.tables("leg", 6, |i| format!("leg {}", i + 1))?;
    let mut legs = Vec::with_capacity(6);
    for (i, t) in tables.iter().enumerate() {
        t.only(&["a_m", "b0_m", "length0_m", "limits_m", "base_axis", "platform_axis"])?;
        legs.push(HexapodLeg {
            a_m: t.vec3("a_m")?,
            b0_m: t.vec3("b0_m")?,
            length0_m: t.positive("length0_m")?,
            limits: t.limits("limits_m", &format!("leg{}", i + 1))?,
            base_axis: t.opt_direction("base_axis")?,
            platform_axis: t.opt_direction("platform_axis")?,
        });
    }
    let home = top.pose("the home pose ([home])".into(), "home")?.ok_or_else(|| {
        top.cx.err(&top.span, "the model: missing the [home] table (home pose of the platform)".into())
    })?;
    let m = Hexapod {
        name: top.string("name")?,
        legs,
        home,
        tool: top.pose("tool".into(), "tool")?.unwrap_or_else(Pose::identity),
        solver: Hexapod::default_solver(),
    };
    m.validate()?;
    Ok(m)
}

// ---------------------------------------------------------------------------------------------
// Writing.

fn num(x: f64) -> String {
    // `{:?}` is the shortest text that parses back to the same f64, always with a `.` or exponent.
    format!("{x:?}")
}

fn vec3(v: &Vector3<f64>) -> String {
    format!("[{}, {}, {}]", num(v.x), num(v.y), num(v.z))
}

fn limits(l: &JointLimits) -> String {
    format!("[{}, {}]", num(l.lower), num(l.upper))
}

fn axes(out: &mut String, base: &Option<Vector3<f64>>, platform: &Option<Vector3<f64>>) {
    if let Some(a) = base {
        out.push_str(&format!("base_axis = {}\n", vec3(a)));
    }
    if let Some(a) = platform {
        out.push_str(&format!("platform_axis = {}\n", vec3(a)));
    }
}

fn pose_table(out: &mut String, key: &str, p: &Pose) {
    out.push_str(&format!(
        "\n[{key}]\nxyz_m = {}\nrotvec_rad = {}\n",
        vec3(&p.translation.vector),
        vec3(&p.rotation.scaled_axis())
    ));
}

fn header(kind: &str, name: &str) -> String {
    format!(
        "# ferrocal parallel robot model; schema: docs/model-format.md\nkind = \"{kind}\"\nname = {}\n",
        toml::Value::String(name.to_string())
    )
}

fn guideways(out: &mut String, g: &[Guideway; 3]) {
    for gw in g {
        out.push_str(&format!(
            "\n[[guideway]]\nv = {}\nbranch = \"{}\"\nlimits_m = {}\n",
            vec3(&gw.v),
            gw.branch.as_str(),
            limits(&gw.limits)
        ));
    }
}

fn links(out: &mut String, links: &[Link], a_key: &str) {
    for l in links {
        out.push_str(&format!(
            "\n[[link]]\narm = {}\n{a_key} = {}\nb0_m = {}\nlength_m = {}\n",
            l.arm + 1,
            vec3(&l.a_m),
            vec3(&l.b0_m),
            num(l.length_m)
        ));
        axes(out, &l.base_axis, &l.platform_axis);
    }
}

/// The model as the text of a model file (numbers written so that they read back exactly;
/// rotations as rotation vectors). Serial chains are not written: use URDF for those.
pub fn to_toml_string(model: &RobotModel) -> Result<String> {
    let mut out;
    match model {
        RobotModel::GantryTau3(m) => {
            out = header("gantry_tau_3", &m.name);
            out.push_str(&format!("assembly = \"{}\"\n", m.assembly.as_str()));
            for a in &m.arms {
                out.push_str(&format!(
                    "\n[[arm]]\nlength_m = {}\na_m = {}\nv = {}\nbranch = \"{}\"\nlimits_m = {}\n",
                    num(a.length_m),
                    vec3(&a.a_m),
                    vec3(&a.v),
                    a.branch.as_str(),
                    limits(&a.limits)
                ));
                axes(&mut out, &a.base_axis, &a.platform_axis);
            }
        }
        RobotModel::GantryTau6(m) => {
            out = header("gantry_tau_6", &m.name);
            out.push_str(&format!("assembly = \"{}\"\n", m.assembly.as_str()));
            if m.tool != Pose::identity() {
                pose_table(&mut out, "tool", &m.tool);
            }
            guideways(&mut out, &m.guideways);
            links(&mut out, &m.links, "a0_m");
        }
        RobotModel::GantryTauF1(m) => {
            out = header("gantry_tau_f1", &m.name);
            out.push_str(&format!("assembly = \"{}\"\n", m.assembly.as_str()));
            if m.tool != Pose::identity() {
                pose_table(&mut out, "tool", &m.tool);
            }
            guideways(&mut out, &m.guideways);
            for (key, st) in [("rot2", &m.rot2), ("rot3", &m.rot3), ("tilt3", &m.tilt3)] {
                out.push_str(&format!(
                    "\n[{key}]\npoint_m = {}\naxis = {}\nlimits_rad = {}\n",
                    vec3(&st.point_m),
                    vec3(&st.axis),
                    limits(&st.limits)
                ));
            }
            links(&mut out, &m.links, "a_m");
        }
        RobotModel::Hexapod(m) => {
            out = header("hexapod", &m.name);
            pose_table(&mut out, "home", &m.home);
            if m.tool != Pose::identity() {
                pose_table(&mut out, "tool", &m.tool);
            }
            for l in &m.legs {
                out.push_str(&format!(
                    "\n[[leg]]\na_m = {}\nb0_m = {}\nlength0_m = {}\nlimits_m = {}\n",
                    vec3(&l.a_m),
                    vec3(&l.b0_m),
                    num(l.length0_m),
                    limits(&l.limits)
                ));
                axes(&mut out, &l.base_axis, &l.platform_axis);
            }
        }
        other => {
            return Err(RobotError::Parse {
                location: Location { file: "<model>".into(), line: 1, column: 1 },
                message: format!("model '{}' is not a parallel robot; write serial chains as URDF", other.name()),
            })
        }
    }
    Ok(out)
}
