//! Verdicts: the one-line judgement every command that computes a result ends with
//! (`shared/spec/cli.md`, "Verdicts").
//!
//! A [`Verdict`] is a list of named [`Check`]s, each a number held against a named limit, and
//! the next step in words. Its [`Status`] is the worst of its checks. On the terminal it is one
//! line ([`Verdict::line`]):
//!
//! ```text
//! verdict: warning: reprojection RMS 0.62 px > 0.5 px (warning), 13 views >= 10; next: ...
//! ```
//!
//! and in a JSON report the object `{"status", "checks": [{"name", "value", "limit", "status",
//! "what"}], "next"}` ([`Verdict::to_json`]). The limits come from [`Thresholds`]: named, with
//! documented defaults, overridable from a TOML file (`docs/verdicts.md` lists them all).
//!
//! ```
//! use ferrocal_calib::verdict::{Check, Status, Verdict};
//! let checks = vec![Check::at_most("camera.rms_px", "reprojection RMS", "px", 0.62, 0.5, 2.0)];
//! let v = Verdict::new(checks, "record more views");
//! assert_eq!(v.status, Status::Warning);
//! assert!(v.line().starts_with("verdict: warning: reprojection RMS 0.62 px > 0.5 px"));
//! ```

pub mod commands;
mod thresholds;

pub use thresholds::{
    CalibrateLimits, CameraLimits, DetectLimits, DiagnoseLimits, DynamicsLimits, EvaluateLimits, ExportLimits,
    HandeyeLimits, ImportLimits, MeasureLimits, PlanLimits, RobotLimits, StereoLimits, StiffnessLimits, StudyLimits,
    Thresholds, ThresholdsError,
};

use serde::{Deserialize, Serialize};

/// The outcome of a check or of a whole verdict, from best to worst.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Within every limit: use the result.
    Pass,
    /// Usable, but a number is beyond its warning limit: read the line before relying on it.
    Warning,
    /// A number is beyond its failure limit: the result should not be used as it is.
    Fail,
}

impl Status {
    /// `pass`, `warning` or `fail`.
    pub fn name(self) -> &'static str {
        match self {
            Status::Pass => "pass",
            Status::Warning => "warning",
            Status::Fail => "fail",
        }
    }
}

impl std::fmt::Display for Status {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// One number held against its limits.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Check {
    /// The check's name, `<section>.<quantity>` as in the thresholds file (e.g. `camera.rms_px`).
    pub name: String,
    /// The measured value (in the unit its name or `what` states); `null` in JSON when it could
    /// not be computed.
    pub value: f64,
    /// The limit the value was held against: the warning limit while the value is within the
    /// failure limit, the failure limit once it is beyond it.
    pub limit: f64,
    /// The outcome.
    pub status: Status,
    /// The check in words, with the value and the limit (`reprojection RMS 0.62 px > 0.5 px
    /// (warning)`).
    pub what: String,
}

impl Check {
    /// A check of a value that must stay small: [`Status::Fail`] above `fail`,
    /// [`Status::Warning`] above `warn`, else [`Status::Pass`]. A limit of `f64::INFINITY`
    /// disables that level. A value that is not finite (not computed) is a warning.
    pub fn at_most(name: &str, label: &str, unit: &str, value: f64, warn: f64, fail: f64) -> Self {
        Self::judge(name, label, unit, value, warn, fail, true)
    }

    /// A check of a value that must stay large: [`Status::Fail`] below `fail`,
    /// [`Status::Warning`] below `warn`, else [`Status::Pass`]. A limit of `f64::NEG_INFINITY`
    /// disables that level. A value that is not finite (not computed) is a warning.
    pub fn at_least(name: &str, label: &str, unit: &str, value: f64, warn: f64, fail: f64) -> Self {
        Self::judge(name, label, unit, value, warn, fail, false)
    }

    /// A condition that is a warning when it holds (value 1) and a pass when not (value 0),
    /// e.g. structure left unexplained; `holds` and `absent` say each case in words.
    pub fn flag(name: &str, holds: &str, absent: &str, condition: bool) -> Self {
        Self {
            name: name.into(),
            value: if condition { 1.0 } else { 0.0 },
            limit: 0.0,
            status: if condition { Status::Warning } else { Status::Pass },
            what: if condition { format!("{holds} (warning)") } else { absent.to_string() },
        }
    }

    fn judge(name: &str, label: &str, unit: &str, value: f64, warn: f64, fail: f64, upper: bool) -> Self {
        let beyond = |limit: f64| if upper { value > limit } else { value < limit };
        let unit = if unit.is_empty() { String::new() } else { format!(" {unit}") };
        let (gt, le) = if upper { (">", "<=") } else { ("<", ">=") };
        let (status, limit, what) = if !value.is_finite() {
            (Status::Warning, if warn.is_finite() { warn } else { fail }, format!("{label} not computed (warning)"))
        } else if beyond(fail) {
            (Status::Fail, fail, format!("{label} {}{unit} {gt} {}{unit} (fail)", fmt_num(value), fmt_num(fail)))
        } else if beyond(warn) {
            (Status::Warning, warn, format!("{label} {}{unit} {gt} {}{unit} (warning)", fmt_num(value), fmt_num(warn)))
        } else {
            let limit = if warn.is_finite() { warn } else { fail };
            let what = if limit.is_finite() {
                format!("{label} {}{unit} {le} {}{unit}", fmt_num(value), fmt_num(limit))
            } else {
                format!("{label} {}{unit}", fmt_num(value))
            };
            (Status::Pass, limit, what)
        };
        Self { name: name.into(), value, limit, status, what }
    }
}

/// A number in at most four significant digits, without trailing zeros (`0.62`, `1.424`,
/// `2`, `3.1e-06`).
pub fn fmt_num(v: f64) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        return format!("{v:.2e}");
    }
    let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// The judgement of one command's result.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Verdict {
    /// The worst status of the checks ([`Status::Pass`] without checks).
    pub status: Status,
    /// What was checked.
    pub checks: Vec<Check>,
    /// The next step, in words.
    pub next: String,
}

impl Verdict {
    /// The verdict of `checks` with the next step `next`; its status is the worst of the checks.
    pub fn new(checks: Vec<Check>, next: impl Into<String>) -> Self {
        Self { status: worst(&checks), checks, next: next.into() }
    }

    /// The verdict of `checks` with the next step chosen from the first check of the worst
    /// status: `next(Some(check))` when a check is beyond a limit, `next(None)` when all pass.
    pub fn with_next(checks: Vec<Check>, next: impl FnOnce(Option<&Check>) -> String) -> Self {
        let n = next(first_problem(&checks));
        Self::new(checks, n)
    }

    /// True when the verdict is [`Status::Fail`].
    pub fn failed(&self) -> bool {
        self.status == Status::Fail
    }

    /// The terminal line: `verdict: <status>: <checks in words>; next: <next step>` (one line;
    /// line breaks in the words become spaces).
    pub fn line(&self) -> String {
        let what = if self.checks.is_empty() {
            "nothing to check".to_string()
        } else {
            self.checks.iter().map(|c| c.what.as_str()).collect::<Vec<_>>().join(", ")
        };
        let next = if self.next.trim().is_empty() { "none" } else { self.next.trim() };
        format!("verdict: {}: {}; next: {}", self.status, one_line(&what), one_line(next))
    }

    /// The JSON object `{"status", "checks": [{"name", "value", "limit", "status", "what"}],
    /// "next"}`.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or(serde_json::Value::Null)
    }
}

/// `v` with the unit doubts its input table raised (`advice`: each doubt's likely unit and the
/// header that would say it, e.g. `the values look like metres; if so, name the columns x_m,
/// y_m, z_m`) as its first check, `input.units` (a warning; not a key of the thresholds file),
/// and its next step: fix the units first, since every figure of the result rests on them.
/// Unchanged without doubts.
pub fn with_unit_doubts(mut v: Verdict, advice: &[&str]) -> Verdict {
    if advice.is_empty() {
        return v;
    }
    let words = advice.join("; ");
    v.checks.insert(
        0,
        Check::flag(
            "input.units",
            &format!("the table's units look wrong: {words}"),
            "units as the headers name",
            true,
        ),
    );
    v.status = worst(&v.checks);
    v.next = format!(
        "fix the table's units first ({words}) and run again: every figure above rests on them (then: {})",
        v.next.trim()
    );
    v
}

/// The worst status of `checks` ([`Status::Pass`] when empty).
pub fn worst(checks: &[Check]) -> Status {
    checks.iter().map(|c| c.status).max().unwrap_or(Status::Pass)
}

/// The first check of the worst status, when that status is not [`Status::Pass`].
pub fn first_problem(checks: &[Check]) -> Option<&Check> {
    let w = worst(checks);
    if w == Status::Pass {
        return None;
    }
    checks.iter().find(|c| c.status == w)
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

#[cfg(test)]
mod tests;
