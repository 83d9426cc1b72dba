//! The output files of one command, composed first and written together
//! ([`write_all_atomic`]): a failure on the way writes none of them, and no output is half-set.

use std::path::{Path, PathBuf};

use ferrocal_calib::verdict::Verdict;
use serde::Serialize;

use crate::error::Result;
use crate::report::{write_all_atomic, Report};

/// Files composed in memory, in the order they were added, written as one commit by
/// [`Outputs::write`].
#[derive(Clone, Debug, Default)]
pub struct Outputs(Vec<(PathBuf, Vec<u8>)>);

impl Outputs {
    /// Adds `value` as pretty-printed JSON at `path`.
    pub fn json(&mut self, path: &Path, value: &impl Serialize) -> Result<()> {
        self.text(path, serde_json::to_string_pretty(value)?);
        Ok(())
    }

    /// The JSON `value` at `path` and, when given, a report as HTML at its path, opening with
    /// the box of `verdict` (no report without its JSON).
    pub fn json_and_report(
        path: &Path,
        value: &impl Serialize,
        report: Option<(&Path, Report)>,
        verdict: &Verdict,
    ) -> Result<Self> {
        let mut out = Self::default();
        out.json(path, value)?;
        if let Some((p, r)) = report {
            out.html(p, r, verdict);
        }
        Ok(out)
    }

    /// Adds the JSON object `value` with `"verdict"` (`verdict`) at `path`.
    pub fn json_with_verdict(&mut self, path: &Path, mut value: serde_json::Value, verdict: &Verdict) -> Result<()> {
        crate::verdict::add_verdict(&mut value, verdict);
        self.json(path, &value)
    }

    /// The files of [`Outputs::json_with_verdict`] alone, when `path` is given (none without).
    pub fn verdict_json(
        path: Option<&Path>,
        value: impl FnOnce() -> serde_json::Value,
        verdict: &Verdict,
    ) -> Result<Self> {
        let mut out = Self::default();
        if let Some(p) = path {
            out.json_with_verdict(p, value(), verdict)?;
        }
        Ok(out)
    }

    /// Adds `value` as pretty-printed JSON at `path`, before every file added so far.
    pub fn json_first(&mut self, path: &Path, value: &impl Serialize) -> Result<()> {
        self.0.insert(0, (path.to_path_buf(), serde_json::to_string_pretty(value)?.into_bytes()));
        Ok(())
    }

    /// Adds `text` (or any bytes) at `path`.
    pub fn text(&mut self, path: &Path, text: impl Into<Vec<u8>>) {
        self.0.push((path.to_path_buf(), text.into()));
    }

    /// Adds `report` as HTML at `path`, opening with the box of `verdict`.
    pub fn html(&mut self, path: &Path, mut report: Report, verdict: &Verdict) {
        report.verdict = Some(verdict.clone());
        self.text(path, report.to_html());
    }

    /// Adds a report folder `dir`: `report.json` (the report's JSON with `verdict`) and
    /// `index.html` opening with the box of `verdict`, as [`Report::write`] lays them out.
    pub fn report_folder(&mut self, dir: &Path, report: Report, verdict: &Verdict) -> Result<()> {
        let mut json = report.to_json();
        crate::verdict::add_verdict(&mut json, verdict);
        self.json(&dir.join("report.json"), &json)?;
        self.html(&dir.join("index.html"), report, verdict);
        Ok(())
    }

    /// The paths, in order.
    pub fn paths(&self) -> impl Iterator<Item = &Path> {
        self.0.iter().map(|(p, _)| p.as_path())
    }

    /// Writes every file as one commit ([`write_all_atomic`]), then names them on stdout
    /// (`wrote: ...`, unless `--quiet`).
    pub fn write(&self) -> Result<()> {
        write_all_atomic(&self.0.iter().map(|(p, b)| (p.as_path(), b.as_slice())).collect::<Vec<_>>())?;
        if let Some(line) = crate::term::wrote_line(self.paths()) {
            crate::say!("{line}");
        }
        Ok(())
    }
}
