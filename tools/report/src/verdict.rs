//! How the commands end: the verdict line on stdout, the verdict object in their JSON, the exit
//! status of a failed result (`shared/spec/cli.md`, "Verdicts"; `docs/verdicts.md`). The checks
//! themselves are built per command from [`ferrocal_calib::verdict`].

use std::path::Path;
use std::process::ExitCode;

use crate::error::Result;
use ferrocal_calib::verdict::{Check, Thresholds, Verdict};
use ferrocal_datasets::measure::{ReprojectionScreen, ReprojectionScreening};
use serde_json::Value;

/// The global settings of the verdicts: the limits and whether a failed result is kept.
#[derive(Clone, Debug, Default)]
pub struct VerdictSettings {
    /// The limits (defaults, or read from `--thresholds FILE.toml`).
    pub thresholds: Thresholds,
    /// `--keep`: a result whose verdict is `fail` exits 0.
    pub keep: bool,
}

impl VerdictSettings {
    /// The settings of `--thresholds` (defaults without a file) and `--keep`.
    pub fn new(thresholds: Option<&Path>, keep: bool) -> Result<Self> {
        let thresholds = match thresholds {
            Some(p) => Thresholds::load(p)?,
            None => Thresholds::default(),
        };
        Ok(Self { thresholds, keep })
    }

    /// Ends a command whose outputs are written: prints the verdict line as the last line of
    /// stdout and returns `ok` unless the verdict failed; a failed verdict says so on stderr and
    /// returns `fail_code` (1 for most commands) unless `--keep` was given.
    pub fn conclude_with(&self, v: &Verdict, ok: ExitCode, fail_code: u8) -> ExitCode {
        println!("{}", v.line());
        if !v.failed() {
            return ok;
        }
        let names: Vec<&str> =
            v.checks.iter().filter(|c| c.status == v.status).map(|c| c.name.as_str()).collect::<Vec<_>>();
        if self.keep {
            eprintln!("ferrocal: the result failed its checks ({}); kept because of --keep", names.join(", "));
            ok
        } else {
            eprintln!(
                "ferrocal: the result failed its checks ({}); its outputs are written; --keep accepts it (exit status 0)",
                names.join(", ")
            );
            ExitCode::from(fail_code)
        }
    }

    /// [`VerdictSettings::conclude_with`] with success 0 and failure 1.
    pub fn conclude(&self, v: &Verdict) -> ExitCode {
        self.conclude_with(v, ExitCode::SUCCESS, 1)
    }
}

/// Adds `"verdict"` to a JSON report (an object; other values are left as they are).
pub fn add_verdict(report: &mut Value, v: &Verdict) {
    if let Some(o) = report.as_object_mut() {
        o.insert("verdict".into(), v.to_json());
    }
}

/// The checks of a report's JSON (`report.json` of the studies and `plan`): sections whose check
/// failed (failure above `failed_fail`) and, when `skipped_warn` is given, sections skipped
/// (warning above it). `section` prefixes the check names (`plan`, `demo`, ...).
pub fn report_checks(report: &Value, section: &str, failed_fail: f64, skipped_warn: Option<f64>) -> Vec<Check> {
    let status_of = |v: &Value| v.get("check").and_then(Value::as_str).map(str::to_string);
    let statuses: Vec<(String, String)> = report
        .get("sections")
        .and_then(Value::as_object)
        .map(|m| m.iter().filter_map(|(k, v)| status_of(v).map(|s| (k.clone(), s))).collect())
        .unwrap_or_default();
    let failed: Vec<&str> = statuses.iter().filter(|(_, s)| s == "fail").map(|(k, _)| k.as_str()).collect();
    let passed = statuses.iter().filter(|(_, s)| s == "pass").count();
    let label = if failed.is_empty() {
        format!("report checks failed (of {} with a criterion, {passed} passed)", passed + failed.len())
    } else {
        format!("report checks failed ({})", failed.join(", "))
    };
    let mut out = vec![Check::at_most(
        &format!("{section}.failed_checks"),
        &label,
        "",
        failed.len() as f64,
        failed_fail,
        failed_fail,
    )];
    if let Some(w) = skipped_warn {
        let skipped = statuses.iter().filter(|(_, s)| s == "skipped").count();
        out.push(Check::at_most(
            &format!("{section}.skipped"),
            "sections skipped",
            "",
            skipped as f64,
            w,
            f64::INFINITY,
        ));
    }
    out
}

/// `measure` (both forms): the fraction of the poses measured, the camera's reprojection RMS
/// (`rms_label` says which RMS: the calibration's, or the median of the poses' own) and the
/// images (poses) whose reprojection RMS is far above the others' (`screening`, a warning).
pub fn measure_verdict(
    t: &Thresholds,
    measured: usize,
    total: usize,
    rms_label: &str,
    rms_px: f64,
    screening: &ReprojectionScreening,
    out: Option<&Path>,
) -> Verdict {
    let l = &t.measure;
    let flagged: Vec<&str> = screening.flagged.iter().map(|o| o.what.as_str()).collect();
    let left_out = if screening.note.is_some() { "kept: too many to leave out" } else { "left out" };
    let checks = vec![
        Check::at_least(
            "measure.measured_fraction",
            &format!("{measured} of {total} poses measured, fraction"),
            "",
            measured as f64 / total.max(1) as f64,
            l.measured_fraction_warn,
            l.measured_fraction_fail,
        ),
        Check::at_most("measure.rms_px", rms_label, "px", rms_px, l.rms_px_warn, l.rms_px_fail),
        Check::flag(
            "measure.reprojection_outliers",
            &format!(
                "{} with a reprojection RMS of {} times the median's ({:.3} px) or more ({left_out}): {}",
                flagged.len(),
                ferrocal_calib::verdict::fmt_num(ReprojectionScreen::default().ratio),
                screening.median_rms_px,
                flagged.join(", ")
            ),
            "no image far above the others' reprojection RMS",
            !flagged.is_empty(),
        ),
    ];
    let table = out.map_or("<the table>".to_string(), |p| p.display().to_string());
    Verdict::with_next(checks, |c| {
        match c.map(|c| c.name.as_str()) {
        None => format!("calibrate from the table: ferrocal calibrate --robot <model> --measurements {table} --out <cal.json>"),
        Some("measure.measured_fraction") => {
            "read why the images were left out (stderr and the JSON's skipped list); fix the pattern string or retake them".into()
        }
        Some("measure.reprojection_outliers") => format!(
            "look at {} (a wrong detection, blur, a reflection, a partly covered target, another pose's image) and retake or remove them",
            flagged.join(", ")
        ),
        _ => "the camera model fits the images poorly: calibrate the camera on its own (ferrocal camera calibrate) and pass it as --intrinsics".into(),
    }
    })
}

/// Ends a study (`demo`, `dynamics study`, `stiffness study`, `motion ...`): its verdict counts
/// the report's failed and skipped checks (`<name>.failed_checks`, `<name>.skipped`), the report
/// folder `dir` (`report.json` with the verdict, `index.html` opening with its box) is written
/// as one commit, and a failed verdict exits 2, these commands' documented status for a failed
/// check (0 with `--keep`).
pub fn conclude_report(vs: &VerdictSettings, report: crate::Report, dir: &Path, name: &str) -> Result<ExitCode> {
    let l = &vs.thresholds.study;
    let checks = report_checks(&report.to_json(), name, l.failed_checks_fail, Some(l.skipped_warn));
    let html = dir.join("index.html");
    let v = Verdict::with_next(checks, |c| match c.map(|c| c.name.rsplit('.').next().unwrap_or("")) {
        None => format!("read the report: {}", html.display()),
        Some("skipped") => {
            format!("give the missing inputs (the skipped sections of {} say which) and run again", html.display())
        }
        Some(_) => {
            format!("read the failed sections of {} (their status says what missed its criterion)", html.display())
        }
    });
    let mut files = crate::Outputs::default();
    files.report_folder(dir, report, &v)?;
    files.write()?;
    Ok(vs.conclude_with(&v, ExitCode::SUCCESS, 2))
}

/// The sections whose check failed in a report's JSON (`Report::to_json`), by name.
pub fn failed_sections(report: &Value) -> Vec<String> {
    report["sections"]
        .as_object()
        .map(|m| m.iter().filter(|(_, v)| v["check"] == "fail").map(|(k, _)| k.clone()).collect())
        .unwrap_or_default()
}
