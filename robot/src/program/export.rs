//! Program writers for a planned path: ABB RAPID, Universal Robots URScript, KUKA KRL,
//! joint-target CSV and G-code.

use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

use super::{PlannedPath, StepKind};
use crate::error::{Result, RobotError};
use crate::kinematics::JointKind;
use crate::safety::SafetyBody;

/// Settings of the program writers (TOML table `[program]` of a plan file).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProgramSettings {
    /// RAPID module name.
    #[serde(default = "default_module")]
    pub rapid_module: String,
    /// RAPID `speeddata` of the moves.
    #[serde(default = "default_speed")]
    pub rapid_speed: String,
    /// RAPID `zonedata` of the moves.
    #[serde(default = "default_zone")]
    pub rapid_zone: String,
    /// RAPID `tooldata`.
    #[serde(default = "default_tool")]
    pub rapid_tool: String,
    /// A RAPID statement run after the wait at every measurement (e.g. `PulseDO doCamera;`).
    #[serde(default)]
    pub rapid_trigger: Option<String>,
    /// G-code axes: the joints, or the tool pose.
    #[serde(default)]
    pub gcode_axes: GcodeAxes,
    /// Axis letters for the joints (default `X Y Z A B C`).
    #[serde(default)]
    pub gcode_letters: Vec<String>,
    /// Feed rate, mm/min (degrees/min for rotary axes).
    #[serde(default = "default_feed")]
    pub gcode_feed_mm_min: f64,
    /// Longest tool travel of one G1 step in pose mode, millimetres.
    #[serde(default = "default_step")]
    pub gcode_max_step_mm: f64,
    /// A G-code line written after the dwell at every measurement (e.g. `M64 P0`).
    #[serde(default)]
    pub gcode_trigger: Option<String>,
    /// URScript program (function) name.
    #[serde(default = "default_program_name")]
    pub urscript_name: String,
    /// URScript `movej` joint speed, rad/s.
    #[serde(default = "default_urscript_speed")]
    pub urscript_speed_rad_s: f64,
    /// URScript `movej` joint acceleration, rad/s^2.
    #[serde(default = "default_urscript_accel")]
    pub urscript_accel_rad_s2: f64,
    /// URScript `movel` tool speed of a program's linear moves, m/s.
    #[serde(default = "default_urscript_linear_speed")]
    pub urscript_linear_speed_m_s: f64,
    /// URScript `movel` tool acceleration of a program's linear moves, m/s^2.
    #[serde(default = "default_urscript_linear_accel")]
    pub urscript_linear_accel_m_s2: f64,
    /// A URScript statement run after the wait at every measurement (e.g. `set_digital_out(0, True)`).
    #[serde(default)]
    pub urscript_trigger: Option<String>,
    /// KUKA KRL program name (the `DEF` name; the file should carry the same name).
    #[serde(default = "default_program_name")]
    pub krl_name: String,
    /// KUKA KRL axis velocity, percent of the maximum (`$VEL_AXIS`), 1-100.
    #[serde(default = "default_krl_velocity")]
    pub krl_velocity_percent: f64,
    /// A KRL statement run after the wait at every measurement (e.g. `$OUT[1]=TRUE`).
    #[serde(default)]
    pub krl_trigger: Option<String>,
}

fn default_module() -> String {
    "FerrocalPlan".into()
}
fn default_speed() -> String {
    "v100".into()
}
fn default_zone() -> String {
    "fine".into()
}
fn default_tool() -> String {
    "tool0".into()
}
fn default_feed() -> f64 {
    1000.0
}
fn default_step() -> f64 {
    5.0
}
/// The URScript and KRL programs' default name.
fn default_program_name() -> String {
    "ferrocal_plan".into()
}
fn default_urscript_speed() -> f64 {
    0.5
}
fn default_urscript_accel() -> f64 {
    1.0
}
fn default_urscript_linear_speed() -> f64 {
    0.25
}
fn default_urscript_linear_accel() -> f64 {
    1.2
}
fn default_krl_velocity() -> f64 {
    20.0
}

impl Default for ProgramSettings {
    fn default() -> Self {
        Self {
            rapid_module: default_module(),
            rapid_speed: default_speed(),
            rapid_zone: default_zone(),
            rapid_tool: default_tool(),
            rapid_trigger: None,
            gcode_axes: GcodeAxes::Joints,
            gcode_letters: Vec::new(),
            gcode_feed_mm_min: default_feed(),
            gcode_max_step_mm: default_step(),
            gcode_trigger: None,
            urscript_name: default_program_name(),
            urscript_speed_rad_s: default_urscript_speed(),
            urscript_accel_rad_s2: default_urscript_accel(),
            urscript_linear_speed_m_s: default_urscript_linear_speed(),
            urscript_linear_accel_m_s2: default_urscript_linear_accel(),
            urscript_trigger: None,
            krl_name: default_program_name(),
            krl_velocity_percent: default_krl_velocity(),
            krl_trigger: None,
        }
    }
}

/// What the G-code axes are.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GcodeAxes {
    /// One axis letter per joint (a machine whose axes are the joints).
    #[default]
    Joints,
    /// The tool pose `X Y Z` (mm) and `A B C` (roll, pitch, yaw in degrees) for a controller
    /// that runs the kinematics itself (a hexapod).
    Pose,
}

pub(super) fn rapid_identifier(s: &str, what: &str) -> Result<()> {
    identifier(s, what, "RAPID", 32)
}

/// A program identifier of `language`: a letter, then letters, digits or `_`, at most `max`
/// characters.
fn identifier(s: &str, what: &str, language: &str, max: usize) -> Result<()> {
    let ok = !s.is_empty()
        && s.len() <= max
        && s.chars().next().is_some_and(|c| c.is_ascii_alphabetic())
        && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    if ok {
        Ok(())
    } else {
        Err(RobotError::Safety(format!(
            "program settings: {what} '{s}' is not a {language} identifier (a letter, then letters, digits or '_', at most {max})"
        )))
    }
}

fn user_value(v: f64, kind: JointKind) -> f64 {
    match kind {
        JointKind::Revolute => v.to_degrees(),
        JointKind::Prismatic => v * 1e3,
    }
}

/// An ABB RAPID module that visits the path: a `jointtarget` per step (robot axes in degrees
/// for revolute joints and millimetres for linear ones; unused robot axes 0, unused external
/// axes `9E9`; joints beyond six go to the external axes), `MoveAbsJ` to each, and at every
/// measurement `WaitTime \InPos` for the path's dwell time (then the trigger statement, if any).
pub fn rapid_module<R: SafetyBody + ?Sized>(
    model: &R,
    path: &PlannedPath,
    dwell_s: f64,
    settings: &ProgramSettings,
    header: &[String],
) -> Result<String> {
    rapid_identifier(&settings.rapid_module, "rapid_module")?;
    rapid_identifier(&settings.rapid_speed, "rapid_speed")?;
    rapid_identifier(&settings.rapid_zone, "rapid_zone")?;
    rapid_identifier(&settings.rapid_tool, "rapid_tool")?;
    dwell_range(dwell_s)?;
    let kinds = model.joint_kinds();
    if kinds.len() > 12 {
        return Err(RobotError::Safety(format!("a RAPID jointtarget holds 12 axes; the robot has {}", kinds.len())));
    }
    let mut s = String::new();
    let _ = writeln!(s, "MODULE {}", settings.rapid_module);
    for h in header {
        let _ = writeln!(s, "  ! {}", h.replace('\n', " "));
    }
    let _ = writeln!(s, "  ! {}; robot axes in deg (revolute) and mm (linear)", count_line(path));
    for (k, st) in path.steps.iter().enumerate() {
        let mut rob = [0.0f64; 6];
        let mut ext = [9e9f64; 6];
        for (i, (v, kind)) in st.q.iter().zip(&kinds).enumerate() {
            let u = user_value(*v, *kind);
            if i < 6 {
                rob[i] = u;
            } else {
                ext[i - 6] = u;
            }
        }
        let f = |v: &[f64]| {
            v.iter()
                .map(|x| if *x == 9e9 { "9E+09".to_string() } else { format!("{x:.4}") })
                .collect::<Vec<_>>()
                .join(",")
        };
        let _ = writeln!(s, "  CONST jointtarget jt{:04} := [[{}],[{}]];", k + 1, f(&rob), f(&ext));
    }
    let _ = writeln!(s);
    let _ = writeln!(s, "  PROC main()");
    let mut n_meas = 0;
    for (k, st) in path.steps.iter().enumerate() {
        let mut what = step_label(st);
        if st.kind == StepKind::MoveLinear {
            what.push_str(LINEAR_AS_JOINT);
        }
        let _ = writeln!(
            s,
            "    MoveAbsJ jt{:04}, {}, {}, {}; ! {what}",
            k + 1,
            settings.rapid_speed,
            settings.rapid_zone,
            settings.rapid_tool
        );
        write_after_move(&mut s, st, dwell_s, &mut n_meas, &settings.rapid_trigger, "    ", |w| {
            format!("    WaitTime \\InPos, {dwell_s:.2}; ! {w}")
        });
    }
    let _ = writeln!(s, "  ENDPROC");
    let _ = writeln!(s, "ENDMODULE");
    Ok(s)
}

/// The path as CSV: `step, kind, pose, q<i>_<deg|mm>, dir<i>, x_mm, y_mm, z_mm` (tool position
/// from the forward kinematics). With `only_measurements`, measure steps only.
pub fn path_csv<R: SafetyBody + ?Sized>(model: &R, path: &PlannedPath, only_measurements: bool) -> Result<String> {
    let kinds = model.joint_kinds();
    let mut s = String::from("step,kind,pose");
    for (i, k) in kinds.iter().enumerate() {
        let _ = write!(s, ",q{}_{}", i + 1, if *k == JointKind::Revolute { "deg" } else { "mm" });
    }
    for i in 0..kinds.len() {
        let _ = write!(s, ",dir{}", i + 1);
    }
    s.push_str(",x_mm,y_mm,z_mm\n");
    for (k, st) in path.steps.iter().enumerate() {
        if only_measurements && st.kind != StepKind::Measure {
            continue;
        }
        let kind = match st.kind {
            StepKind::Home => "home",
            StepKind::Approach => "approach",
            StepKind::Measure => "measure",
            StepKind::Via => "via",
            StepKind::Move => "move",
            StepKind::MoveLinear => "move_linear",
        };
        let pose = st.pose.map(|p| (p + 1).to_string()).unwrap_or_default();
        let _ = write!(s, "{},{kind},{pose}", k + 1);
        for (v, kind) in st.q.iter().zip(&kinds) {
            let _ = write!(s, ",{:.6}", user_value(*v, *kind));
        }
        for d in &st.dir {
            let _ = write!(s, ",{d}");
        }
        let p = model.forward(&st.q)?.translation.vector * 1e3;
        let _ = writeln!(s, ",{:.4},{:.4},{:.4}", p.x, p.y, p.z);
    }
    Ok(s)
}

/// What [`gcode`] wrote.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GcodeProgram {
    /// The program text.
    pub text: String,
    /// G1 lines.
    pub moves: usize,
    /// Pose mode: the largest distance between the controller's straight tool line and the
    /// checked joint-space path, at the midpoints of the steps, millimetres (0 in joint mode).
    pub max_chord_deviation_mm: f64,
}

/// G-code for the path (`G21 G90 G94`, one `G1 ... F` per step, `G4 P<s>` dwell at every
/// measurement, then the trigger line). Joint mode writes one letter per joint (mm / deg);
/// pose mode writes the tool pose and cuts every joint-space segment into steps of at most
/// `gcode_max_step_mm` tool travel, so the controller's interpolation stays close to the
/// checked path (the largest deviation is reported).
pub fn gcode<R: SafetyBody + ?Sized>(
    model: &R,
    path: &PlannedPath,
    dwell_s: f64,
    settings: &ProgramSettings,
    header: &[String],
) -> Result<GcodeProgram> {
    dwell_range(dwell_s)?;
    let kinds = model.joint_kinds();
    let feed = settings.gcode_feed_mm_min;
    if !(feed.is_finite() && feed > 0.0) {
        return Err(RobotError::Safety(format!("program settings: gcode_feed_mm_min must be > 0, got {feed}")));
    }
    let step_mm = settings.gcode_max_step_mm;
    if !(step_mm.is_finite() && step_mm > 0.0) {
        return Err(RobotError::Safety(format!("program settings: gcode_max_step_mm must be > 0, got {step_mm}")));
    }
    let default_letters = ["X", "Y", "Z", "A", "B", "C", "U", "V", "W"];
    let letters: Vec<String> = if settings.gcode_letters.is_empty() {
        if kinds.len() > default_letters.len() {
            return Err(RobotError::Safety(format!(
                "program settings: give gcode_letters for the {} joints",
                kinds.len()
            )));
        }
        default_letters[..kinds.len()].iter().map(|s| s.to_string()).collect()
    } else if settings.gcode_letters.len() != kinds.len() {
        return Err(RobotError::Safety(format!(
            "program settings: gcode_letters has {} letters, the robot has {} joints",
            settings.gcode_letters.len(),
            kinds.len()
        )));
    } else {
        settings.gcode_letters.clone()
    };
    if let Some(l) = letters.iter().find(|l| l.is_empty() || !l.chars().all(|c| c.is_ascii_alphabetic())) {
        return Err(RobotError::Safety(format!("program settings: '{l}' is not a G-code axis letter")));
    }
    let mut s = String::new();
    for h in header {
        let _ = writeln!(s, "({})", h.replace(['(', ')'], "").replace('\n', " "));
    }
    let _ = writeln!(
        s,
        "(axes: {})",
        match settings.gcode_axes {
            GcodeAxes::Joints => "joints, mm for linear and deg for rotary axes".to_string(),
            GcodeAxes::Pose => "tool pose X Y Z mm, A B C roll pitch yaw deg".to_string(),
        }
    );
    let _ = writeln!(s, "G21 G90 G94");
    let mut moves = 0;
    let mut worst_dev = 0.0f64;
    let pose_words = |q: &[f64]| -> Result<(String, nalgebra::Vector3<f64>)> {
        let t = model.forward(q)?;
        let (p, r) = crate::geometry::position_mm_rpy_deg(&t);
        Ok((
            format!("X{:.4} Y{:.4} Z{:.4} A{:.4} B{:.4} C{:.4}", p[0], p[1], p[2], r[0], r[1], r[2]),
            t.translation.vector * 1e3,
        ))
    };
    let mut n_meas = 0;
    for (k, st) in path.steps.iter().enumerate() {
        match settings.gcode_axes {
            GcodeAxes::Joints => {
                let words: Vec<String> =
                    st.q.iter()
                        .zip(&kinds)
                        .zip(&letters)
                        .map(|((v, kind), l)| format!("{l}{:.4}", user_value(*v, *kind)))
                        .collect();
                let _ = writeln!(s, "G1 {} F{feed:.1}", words.join(" "));
                moves += 1;
            }
            GcodeAxes::Pose => {
                let prev = if k == 0 { st.q.clone() } else { path.steps[k - 1].q.clone() };
                let p0 = model.forward(&prev)?.translation.vector * 1e3;
                // Tool travel bound from a fine sampling of the joint-space segment.
                let mut travel = 0.0;
                let mut last = p0;
                for j in 1..=32 {
                    let u = j as f64 / 32.0;
                    let q: Vec<f64> = prev.iter().zip(&st.q).map(|(a, b)| a + (b - a) * u).collect();
                    let p = model.forward(&q)?.translation.vector * 1e3;
                    travel += (p - last).norm();
                    last = p;
                }
                let n = ((travel / step_mm).ceil() as usize).max(1);
                let mut prev_p = p0;
                for j in 1..=n {
                    let u = j as f64 / n as f64;
                    let q: Vec<f64> = prev.iter().zip(&st.q).map(|(a, b)| a + (b - a) * u).collect();
                    let um = (j as f64 - 0.5) / n as f64;
                    let qm: Vec<f64> = prev.iter().zip(&st.q).map(|(a, b)| a + (b - a) * um).collect();
                    let (words, p) = pose_words(&q)?;
                    let pm = model.forward(&qm)?.translation.vector * 1e3;
                    worst_dev = worst_dev.max((pm - (prev_p + p) * 0.5).norm());
                    prev_p = p;
                    let _ = writeln!(s, "G1 {words} F{feed:.1}");
                    moves += 1;
                }
            }
        }
        if matches!(st.kind, StepKind::Move | StepKind::MoveLinear) {
            let _ = writeln!(s, "(step {}: {})", k + 1, step_label(st).replace(['(', ')'], ""));
        }
        write_after_move(&mut s, st, dwell_s, &mut n_meas, &settings.gcode_trigger, "", |w| match st.kind {
            StepKind::Measure => format!("G4 P{dwell_s:.2} ({w}, pose {})", st.pose.map_or(0, |p| p + 1)),
            _ => format!("G4 P{dwell_s:.2} ({w})"),
        });
    }
    let _ = writeln!(s, "M2");
    Ok(GcodeProgram { text: s, moves, max_chord_deviation_mm: worst_dev })
}

/// What a step is for, in words (the comments of the program writers).
fn step_label(st: &super::PathStep) -> String {
    match (st.kind, st.pose) {
        (StepKind::Home, _) => "home".to_string(),
        (StepKind::Approach, Some(p)) => format!("approach pose {}", p + 1),
        (StepKind::Measure, Some(p)) => format!("measure pose {}", p + 1),
        (StepKind::Via, _) => "via".to_string(),
        (StepKind::Move | StepKind::MoveLinear, p) => match (&st.label, p) {
            (Some(l), _) => l.replace(['\n', '\r'], " "),
            (None, Some(p)) => format!("move {}", p + 1),
            (None, None) => "move".to_string(),
        },
        (_, None) => String::new(),
    }
}

/// The header line that counts a path's steps: a user's program counts its moves, a
/// measurement path its steps and measurements.
fn count_line(path: &PlannedPath) -> String {
    let moves = path.program_moves();
    if moves > 0 && path.measurements() == 0 {
        format!("{moves} moves")
    } else {
        format!("{} steps, {} measurements", path.steps.len(), path.measurements())
    }
}

/// What a writer does after the move to a step: a measurement waits the dwell time and runs the
/// trigger; a program's move waits only when a dwell time is asked; other steps do nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum AfterMove {
    Nothing,
    Dwell,
    Measure,
}

fn after_move(st: &super::PathStep, dwell_s: f64) -> AfterMove {
    match st.kind {
        StepKind::Measure => AfterMove::Measure,
        StepKind::Move | StepKind::MoveLinear if dwell_s > 0.0 => AfterMove::Dwell,
        _ => AfterMove::Nothing,
    }
}

/// Writes what follows the move to `st` (see [`AfterMove`]): the line `wait(what)`, the
/// language's wait of the dwell time commented `what` (`measurement N`, counted in `n_meas`, or
/// `dwell`), and after a measurement's wait the trigger statement, if any, indented by `indent`.
fn write_after_move(
    s: &mut String,
    st: &super::PathStep,
    dwell_s: f64,
    n_meas: &mut usize,
    trigger: &Option<String>,
    indent: &str,
    wait: impl Fn(&str) -> String,
) {
    match after_move(st, dwell_s) {
        AfterMove::Measure => {
            *n_meas += 1;
            let _ = writeln!(s, "{}", wait(&format!("measurement {n_meas}")));
            if let Some(t) = trigger {
                let _ = writeln!(s, "{indent}{t}");
            }
        }
        AfterMove::Dwell => {
            let _ = writeln!(s, "{}", wait("dwell"));
        }
        AfterMove::Nothing => {}
    }
}

/// The comment a joint-interpolating writer adds to a program's linear move.
const LINEAR_AS_JOINT: &str = " (linear in the program; written with joint interpolation: this language's linear move needs a Cartesian target in the controller's frames)";

/// A finite joint value for a program line, or an error naming the step and joint.
fn finite_joint(v: f64, step: usize, joint: usize) -> Result<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(RobotError::Safety(format!("program step {}: joint {} is not a finite number ({v})", step + 1, joint + 1)))
    }
}

/// A Universal Robots URScript program that visits the path: one function with a `movej` per
/// step (joint positions in radians, the settings' joint speed and acceleration) and at every
/// measurement a `sleep` of the dwell time (then the trigger statement, if any), called at the
/// end of the file. URScript moves the six revolute arm joints: any other robot is refused.
pub fn urscript<R: SafetyBody + ?Sized>(
    model: &R,
    path: &PlannedPath,
    dwell_s: f64,
    settings: &ProgramSettings,
    header: &[String],
) -> Result<String> {
    identifier(&settings.urscript_name, "urscript_name", "URScript", 63)?;
    let kinds = model.joint_kinds();
    if kinds.len() != 6 || kinds.iter().any(|k| *k != JointKind::Revolute) {
        return Err(RobotError::Safety(format!(
            "URScript moves six revolute joints; this robot has {} joints ({} linear)",
            kinds.len(),
            kinds.iter().filter(|k| **k == JointKind::Prismatic).count()
        )));
    }
    let (v, a) = (settings.urscript_speed_rad_s, settings.urscript_accel_rad_s2);
    if !(v.is_finite() && v > 0.0 && v <= 3.15 && a.is_finite() && a > 0.0 && a <= 40.0) {
        return Err(RobotError::Safety(format!(
            "program settings: urscript_speed_rad_s must be in (0, 3.15] and urscript_accel_rad_s2 in (0, 40]; got {v} and {a}"
        )));
    }
    dwell_range(dwell_s)?;
    let mut s = String::new();
    for h in header {
        let _ = writeln!(s, "# {}", h.replace('\n', " "));
    }
    let _ = writeln!(s, "# {}; joints in rad", count_line(path));
    let (lv, la) = (settings.urscript_linear_speed_m_s, settings.urscript_linear_accel_m_s2);
    if path.steps.iter().any(|st| st.kind == StepKind::MoveLinear)
        && !(lv.is_finite() && lv > 0.0 && lv <= 5.0 && la.is_finite() && la > 0.0 && la <= 50.0)
    {
        return Err(RobotError::Safety(format!(
            "program settings: urscript_linear_speed_m_s must be in (0, 5] and urscript_linear_accel_m_s2 in (0, 50]; got {lv} and {la}"
        )));
    }
    let _ = writeln!(s, "def {}():", settings.urscript_name);
    let mut n_meas = 0;
    for (k, st) in path.steps.iter().enumerate() {
        let q: Vec<String> =
            st.q.iter()
                .enumerate()
                .map(|(j, x)| finite_joint(*x, k, j).map(|x| format!("{x:.7}")))
                .collect::<Result<_>>()?;
        if st.kind == StepKind::MoveLinear {
            // movel takes joint positions too: the target is their forward kinematics.
            let _ =
                writeln!(s, "  movel([{}], a={la:.3}, v={lv:.3})  # step {}: {}", q.join(", "), k + 1, step_label(st));
        } else {
            let _ =
                writeln!(s, "  movej([{}], a={a:.3}, v={v:.3})  # step {}: {}", q.join(", "), k + 1, step_label(st));
        }
        write_after_move(&mut s, st, dwell_s, &mut n_meas, &settings.urscript_trigger, "  ", |w| {
            format!("  sleep({dwell_s:.2})  # {w}")
        });
    }
    let _ = writeln!(s, "end");
    let _ = writeln!(s, "{}()", settings.urscript_name);
    Ok(s)
}

/// A KUKA KRL program (`.src`) that visits the path: `DEF name()`, the usual `BAS(#INITMOV,0)`
/// initialisation, the settings' axis velocity, a `PTP {AXIS: A1 .. A6}` per step (degrees for
/// revolute and millimetres for linear axes; joints beyond six as external axes `E1 ..`), and at
/// every measurement `WAIT SEC` for the dwell time (then the trigger statement, if any).
pub fn krl<R: SafetyBody + ?Sized>(
    model: &R,
    path: &PlannedPath,
    dwell_s: f64,
    settings: &ProgramSettings,
    header: &[String],
) -> Result<String> {
    identifier(&settings.krl_name, "krl_name", "KRL", 24)?;
    let kinds = model.joint_kinds();
    if kinds.len() > 12 {
        return Err(RobotError::Safety(format!("a KRL AXIS/E6AXIS holds 12 axes; the robot has {}", kinds.len())));
    }
    let vel = settings.krl_velocity_percent;
    if !(vel.is_finite() && (1.0..=100.0).contains(&vel)) {
        return Err(RobotError::Safety(format!(
            "program settings: krl_velocity_percent must be in [1, 100], got {vel}"
        )));
    }
    dwell_range(dwell_s)?;
    let mut s = String::new();
    let _ = writeln!(s, "DEF {}( )", settings.krl_name);
    for h in header {
        let _ = writeln!(s, "; {}", h.replace('\n', " "));
    }
    let _ = writeln!(s, "; {}; axes in deg (revolute) and mm (linear)", count_line(path));
    let _ = writeln!(s, "BAS (#INITMOV,0 )");
    let _ = writeln!(s, "FOR I=1 TO 6");
    let _ = writeln!(s, "  $VEL_AXIS[I]={vel:.0}");
    let _ = writeln!(s, "ENDFOR");
    let mut n_meas = 0;
    for (k, st) in path.steps.iter().enumerate() {
        let mut words = Vec::with_capacity(st.q.len());
        for (j, (v, kind)) in st.q.iter().zip(&kinds).enumerate() {
            let u = user_value(finite_joint(*v, k, j)?, *kind);
            let name = if j < 6 { format!("A{}", j + 1) } else { format!("E{}", j - 5) };
            words.push(format!("{name} {u:.4}"));
        }
        let mut what = step_label(st);
        if st.kind == StepKind::MoveLinear {
            what.push_str(LINEAR_AS_JOINT);
        }
        let _ = writeln!(s, "PTP {{AXIS: {}}} ; step {}: {what}", words.join(", "), k + 1);
        write_after_move(&mut s, st, dwell_s, &mut n_meas, &settings.krl_trigger, "", |w| {
            format!("WAIT SEC {dwell_s:.2} ; {w}")
        });
    }
    let _ = writeln!(s, "END");
    Ok(s)
}

/// The dwell time a program may wait at a measurement: finite, 0 to one hour.
fn dwell_range(dwell_s: f64) -> Result<()> {
    if dwell_s.is_finite() && (0.0..=3600.0).contains(&dwell_s) {
        Ok(())
    } else {
        Err(RobotError::Safety(format!("the dwell time must be 0 to 3600 s, got {dwell_s}")))
    }
}
