//! HTML + JSON reports with SVG plots, written atomically, with their provenance.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::error::{Context, Result};
use ferrocal_calib::check::{Check, CheckCounts, CheckStatus};
use ferrocal_calib::verdict::Verdict;
use serde::Serialize;
use serde_json::Value;

/// What produced a report: version, commit, command line, inputs, settings, time.
#[derive(Clone, Debug, Serialize)]
pub struct Provenance {
    /// ferrocal version.
    pub version: String,
    /// Git commit of the build (`+changes` when built from a modified tree).
    pub commit: String,
    /// The command line.
    pub command: Vec<String>,
    /// Input files with their sizes in bytes (0 when missing).
    pub inputs: Vec<(String, u64)>,
    /// Settings in effect.
    pub settings: Value,
    /// Start time (UTC, RFC 3339).
    pub started: String,
}

impl Provenance {
    /// Provenance of the current process with the given settings.
    pub fn new(settings: Value) -> Self {
        Self {
            version: env!("CARGO_PKG_VERSION").to_string(),
            commit: env!("FERROCAL_GIT_HASH").to_string(),
            command: std::env::args().collect(),
            inputs: Vec::new(),
            settings,
            started: chrono::Utc::now().to_rfc3339(),
        }
    }

    /// Records an input file.
    pub fn add_input(&mut self, path: &Path) {
        let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
        self.inputs.push((path.display().to_string(), size));
    }
}

/// One block of a report section.
#[derive(Clone, Debug)]
pub enum Block {
    /// A paragraph of plain text (escaped).
    Text(String),
    /// A table with a caption, a header and rows of cells.
    Table {
        /// Caption.
        caption: String,
        /// Column names.
        header: Vec<String>,
        /// Cells, row by row.
        rows: Vec<Vec<String>>,
    },
    /// An inline SVG figure with a caption.
    Figure {
        /// Caption.
        caption: String,
        /// SVG markup.
        svg: String,
    },
    /// Data attribution (source and licence), shown in small print.
    Attribution(String),
    /// Verbatim text.
    Pre(String),
}

/// A report section.
#[derive(Clone, Debug)]
pub struct Section {
    /// Anchor id.
    pub id: String,
    /// Heading.
    pub title: String,
    /// The section's check, shown beside the heading, if any: only a passed check counts as
    /// passing; a skipped or reported one says so.
    pub status: Option<Check>,
    /// Blocks in order.
    pub blocks: Vec<Block>,
    /// Machine-readable results of the section, copied into the JSON.
    pub data: Value,
}

impl Section {
    /// An empty section.
    pub fn new(id: &str, title: &str) -> Self {
        Self { id: id.to_string(), title: title.to_string(), status: None, blocks: Vec::new(), data: Value::Null }
    }
    /// Adds a paragraph.
    pub fn text(&mut self, t: impl Into<String>) -> &mut Self {
        self.blocks.push(Block::Text(t.into()));
        self
    }
    /// Adds a table.
    pub fn table(&mut self, caption: &str, header: &[&str], rows: Vec<Vec<String>>) -> &mut Self {
        self.blocks.push(Block::Table {
            caption: caption.to_string(),
            header: header.iter().map(|s| s.to_string()).collect(),
            rows,
        });
        self
    }
    /// Adds a figure.
    pub fn figure(&mut self, caption: &str, svg: String) -> &mut Self {
        self.blocks.push(Block::Figure { caption: caption.to_string(), svg });
        self
    }
    /// Adds an attribution line.
    pub fn attribution(&mut self, t: &str) -> &mut Self {
        self.blocks.push(Block::Attribution(t.to_string()));
        self
    }
    /// Adds verbatim text.
    pub fn pre(&mut self, t: impl Into<String>) -> &mut Self {
        self.blocks.push(Block::Pre(t.into()));
        self
    }
    /// Sets a pass (`ok`) or fail status shown beside the heading.
    pub fn status(&mut self, ok: bool, t: impl Into<String>) -> &mut Self {
        self.status = Some(Check::from_bool(self.title.clone(), ok, t));
        self
    }
    /// Sets the section's check.
    pub fn check(&mut self, c: Check) -> &mut Self {
        self.status = Some(c);
        self
    }
    /// Marks the section skipped (its input is absent) and says why in the text.
    pub fn skipped(&mut self, why: impl Into<String>) -> &mut Self {
        let why = why.into();
        self.text(format!("{why}: section skipped."));
        self.check(Check::skipped(self.title.clone(), why))
    }
    /// Marks the section as reporting numbers without a pass/fail criterion.
    pub fn reported(&mut self, what: impl Into<String>) -> &mut Self {
        self.check(Check::reported(self.title.clone(), what))
    }
    /// True when the section's check failed (a section without a check does not fail).
    pub fn failed(&self) -> bool {
        self.status.as_ref().is_some_and(Check::failed)
    }
    /// The text shown beside the heading.
    fn badge(&self) -> String {
        match &self.status {
            None => String::new(),
            Some(c) => {
                let class = match c.status {
                    CheckStatus::Pass => "ok",
                    CheckStatus::Fail => "bad",
                    CheckStatus::Skipped | CheckStatus::Reported => "note",
                };
                format!(" <span class=\"{class}\">{}</span>", esc(&status_text(c)))
            }
        }
    }
}

/// The status text of a check: its detail, prefixed with `skipped` or `reported` when the
/// check has no pass/fail outcome.
fn status_text(c: &Check) -> String {
    match c.status {
        CheckStatus::Pass | CheckStatus::Fail => c.detail.clone(),
        CheckStatus::Skipped | CheckStatus::Reported if c.detail.starts_with(c.status.name()) => c.detail.clone(),
        CheckStatus::Skipped | CheckStatus::Reported if c.detail.is_empty() => c.status.name().to_string(),
        CheckStatus::Skipped | CheckStatus::Reported => format!("{}: {}", c.status.name(), c.detail),
    }
}

/// A report: title, provenance, sections.
pub struct Report {
    /// Title.
    pub title: String,
    /// What produced it.
    pub provenance: Provenance,
    /// Sections in order.
    pub sections: Vec<Section>,
    /// The command's verdict, shown first (the box under the title) and written to the JSON.
    /// Without one the HTML keeps an empty slot ([`VERDICT_SLOT`]) where the box goes.
    pub verdict: Option<Verdict>,
    /// How many sections, from the first, are shown whole; the others show their heading and
    /// first paragraph, with their tables and figures folded (`<details>`) below. A section
    /// whose check failed is always shown whole.
    pub open_sections: usize,
}

/// Reports with more sections than this fold each later section whole under its heading.
pub const COMPACT_AFTER: usize = 12;

/// Where the verdict box goes in a report written before its verdict was known.
pub const VERDICT_SLOT: &str = "<!-- ferrocal:verdict -->";

/// The verdict as the box that opens a report: the status, the next step, and each check with
/// its value and limit.
pub fn verdict_box(v: &Verdict) -> String {
    let mut h = String::new();
    let status = v.status.name();
    let _ = write!(
        h,
        "<div class=\"verdict v-{status}\" id=\"verdict\"><p><strong>Verdict: {}</strong></p><p><strong>Next:</strong> {}</p>",
        status.to_uppercase(),
        esc(if v.next.trim().is_empty() { "none" } else { v.next.trim() })
    );
    if !v.checks.is_empty() {
        h.push_str("<table><tr><th>check</th><th>result</th><th>status</th></tr>");
        for c in &v.checks {
            let _ = write!(
                h,
                "<tr><td>{}</td><td class=\"l\">{}</td><td class=\"s-{}\">{}</td></tr>",
                esc(&c.name),
                esc(&c.what),
                c.status.name(),
                c.status.name()
            );
        }
        h.push_str("</table>");
    }
    h.push_str("</div>");
    h
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

impl Report {
    /// An empty report.
    pub fn new(title: &str, provenance: Provenance) -> Self {
        Self { title: title.to_string(), provenance, sections: Vec::new(), verdict: None, open_sections: 2 }
    }

    /// A report of `sections`.
    pub fn of(title: &str, provenance: Provenance, sections: Vec<Section>) -> Self {
        Self { sections, ..Self::new(title, provenance) }
    }

    /// True when a section's check failed.
    pub fn failed(&self) -> bool {
        self.sections.iter().any(Section::failed)
    }

    /// Counts of the sections' check outcomes (sections without a check are not counted).
    pub fn counts(&self) -> CheckCounts {
        CheckCounts::of(self.sections.iter().filter_map(|s| s.status.as_ref()))
    }

    /// A summary section: every section with a check and its status, and the counts. It has no
    /// check of its own (it would count every other one twice).
    pub fn summary_section(&self) -> Section {
        let n = self.counts();
        let mut s = Section::new("summary", "Summary");
        s.text(format!(
            "{} checks passed, {} failed, {} skipped (input absent), {} reported without a pass/fail criterion. Skipped and reported sections are not counted as passing.",
            n.passed, n.failed, n.skipped, n.reported
        ));
        let rows = self
            .sections
            .iter()
            .filter_map(|x| x.status.as_ref().map(|c| (x, c)))
            .map(|(x, c)| vec![x.title.clone(), c.status.name().to_string(), c.detail.clone()])
            .collect();
        s.table("Sections", &["section", "status", "detail"], rows);
        s.data = serde_json::json!({
            "counts": n,
            "sections": self.sections.iter().filter_map(|x| x.status.as_ref().map(|c| serde_json::json!({
                "id": x.id, "status": c.status, "detail": c.detail,
            }))).collect::<Vec<_>>(),
        });
        s
    }

    /// The report as HTML (self-contained: styles and SVG inline).
    pub fn to_html(&self) -> String {
        let mut h = String::new();
        let _ = write!(
            h,
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title>\n<style>{}</style></head><body>\n<h1>{}</h1>\n",
            esc(&self.title),
            CSS,
            esc(&self.title)
        );
        match &self.verdict {
            Some(v) => h.push_str(&verdict_box(v)),
            None => h.push_str(VERDICT_SLOT),
        }
        h.push('\n');
        // A long report (more than COMPACT_AFTER sections) folds each later section whole under
        // a one-line heading: the headings are then the table of contents.
        let compact = self.sections.len() > COMPACT_AFTER;
        if !compact {
            h.push_str("<nav><ul>");
            for s in &self.sections {
                let _ = write!(h, "<li><a href=\"#{}\">{}</a>{}</li>", esc(&s.id), esc(&s.title), s.badge());
            }
            h.push_str("</ul></nav>\n");
        }
        for (i, s) in self.sections.iter().enumerate() {
            let open = i < self.open_sections || s.failed();
            if open || !compact {
                let _ = writeln!(h, "<section id=\"{}\"><h2>{}{}</h2>", esc(&s.id), esc(&s.title), s.badge());
            } else {
                let _ = writeln!(
                    h,
                    "<section id=\"{}\" class=\"folded\"><details><summary><strong>{}</strong>{}</summary>",
                    esc(&s.id),
                    esc(&s.title),
                    s.badge()
                );
            }
            // A folded section of a short report keeps its first paragraph in view.
            let lead = usize::from(!open && !compact && matches!(s.blocks.first(), Some(Block::Text(_))));
            for (k, b) in s.blocks.iter().enumerate() {
                if !open && !compact && k == lead {
                    let n = s.blocks.len() - lead;
                    let _ = writeln!(
                        h,
                        "<details><summary>{n} more item{} (tables, figures, notes)</summary>",
                        if n == 1 { "" } else { "s" }
                    );
                }
                match b {
                    Block::Text(t) => {
                        let _ = writeln!(h, "<p>{}</p>", esc(t));
                    }
                    Block::Pre(t) => {
                        let _ = writeln!(h, "<pre>{}</pre>", esc(t));
                    }
                    Block::Attribution(t) => {
                        let _ = writeln!(h, "<p class=\"attr\">{}</p>", esc(t));
                    }
                    Block::Figure { caption, svg } => {
                        let _ = writeln!(h, "<figure>{svg}<figcaption>{}</figcaption></figure>", esc(caption));
                    }
                    Block::Table { caption, header, rows } => {
                        let _ = write!(h, "<table><caption>{}</caption><tr>", esc(caption));
                        for c in header {
                            let _ = write!(h, "<th>{}</th>", esc(c));
                        }
                        h.push_str("</tr>");
                        for r in rows {
                            h.push_str("<tr>");
                            for c in r {
                                // Numbers (with or without a unit) align right, words left.
                                let numeric = c.len() < 25
                                    && c.trim_start().starts_with(|ch: char| ch.is_ascii_digit() || "+-.".contains(ch));
                                let class = if numeric { " class=\"n\"" } else { "" };
                                let _ = write!(h, "<td{class}>{}</td>", esc(c));
                            }
                            h.push_str("</tr>");
                        }
                        h.push_str("</table>\n");
                    }
                }
            }
            if !open && (compact || s.blocks.len() > lead) {
                h.push_str("</details>\n");
            }
            h.push_str("</section>\n");
        }
        let p = &self.provenance;
        let _ = write!(
            h,
            "<section id=\"provenance\"><h2>Provenance</h2><table><tr><th>ferrocal</th><td>{} (commit {})</td></tr><tr><th>command</th><td><code>{}</code></td></tr><tr><th>started</th><td>{}</td></tr>",
            esc(&p.version),
            esc(&p.commit),
            esc(&p.command.join(" ")),
            esc(&p.started)
        );
        for (f, size) in &p.inputs {
            let _ = write!(h, "<tr><th>input</th><td>{} ({size} bytes)</td></tr>", esc(f));
        }
        let _ = writeln!(
            h,
            "<tr><th>settings</th><td><pre>{}</pre></td></tr></table></section>\n</body></html>",
            esc(&serde_json::to_string_pretty(&p.settings).unwrap_or_default())
        );
        h
    }

    /// The report as JSON: provenance plus each section's data, keyed by section id.
    pub fn to_json(&self) -> Value {
        let mut sections = serde_json::Map::new();
        for s in &self.sections {
            let mut m = serde_json::Map::new();
            m.insert("title".into(), Value::String(s.title.clone()));
            if let Some(c) = &s.status {
                // `ok` only where there is a criterion: a skipped or reported section is not
                // passing.
                if c.has_criterion() {
                    m.insert("ok".into(), Value::Bool(c.passed()));
                }
                m.insert("status".into(), Value::String(status_text(c)));
                m.insert("check".into(), Value::String(c.status.name().into()));
            }
            m.insert("data".into(), s.data.clone());
            sections.insert(s.id.clone(), Value::Object(m));
        }
        let mut j = serde_json::json!({
            "title": self.title,
            "provenance": self.provenance,
            "sections": sections,
        });
        if let Some(v) = &self.verdict {
            crate::verdict::add_verdict(&mut j, v);
        }
        j
    }

    /// Writes `index.html` and `report.json` into `dir` (created if needed), each atomically.
    pub fn write(&self, dir: &Path) -> Result<PathBuf> {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create report folder {}", dir.display()))?;
        write_atomic(&dir.join("report.json"), serde_json::to_string_pretty(&self.to_json())?.as_bytes())?;
        let html = dir.join("index.html");
        write_atomic(&html, self.to_html().as_bytes())?;
        Ok(html)
    }
}

/// The current time as RFC 3339 (UTC), as reports and written programs state it.
pub fn now_rfc3339() -> String {
    chrono::Utc::now().to_rfc3339()
}

/// Whether two paths name the same existing file (after resolving links and `..`); false when
/// either does not exist yet.
pub fn same_file(a: &Path, b: &Path) -> bool {
    matches!((a.canonicalize(), b.canonicalize()), (Ok(x), Ok(y)) if x == y)
}

/// Refuses a target that exists and is not a regular file (a symbolic link, a device node, a
/// folder): the temporary file's rename would replace the link or node itself, silently.
pub fn check_regular_target(path: &Path) -> Result<()> {
    Ok(ferrocal_datasets::atomic::check_regular_target(path)?)
}

/// Refuses outputs that name an input (the same file, through any path) or each other, and
/// targets that are not regular files; called before any work is written.
pub fn check_outputs(outputs: &[&Path], inputs: &[&Path]) -> Result<()> {
    for (k, out) in outputs.iter().enumerate() {
        if let Some(i) = inputs.iter().find(|i| same_file(out, i) || out == *i) {
            crate::bail!("{} would overwrite the input {}; choose another output", out.display(), i.display());
        }
        if outputs[..k].iter().any(|o| same_file(out, o) || o == out) {
            crate::bail!("{} is named as two outputs", out.display());
        }
        check_regular_target(out)?;
    }
    Ok(())
}

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename, so that a
/// reader never sees a half-written file; a target that is not a regular file is refused and a
/// failed write leaves no temporary file behind (`ferrocal_datasets::atomic`).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    Ok(ferrocal_datasets::atomic::write_atomic(path, bytes, &[])?)
}

/// Writes several files as one commit: every file is first written beside its target under a
/// temporary name, then all are renamed into place; if any write fails, none of the targets is
/// touched (the renames that follow cannot run out of space).
pub fn write_all_atomic(files: &[(&Path, &[u8])]) -> Result<()> {
    Ok(ferrocal_datasets::atomic::write_all_atomic(files, &[])?)
}

/// A run folder written aside and moved into place: the files are written into a hidden sibling
/// folder (`.NAME.partial-PID`), and [`commit`](Self::commit) renames it to the target, so that
/// the target holds either the complete set of a run or what it held before, never a mix.
/// Dropped without a commit (an error on the way), the sibling is removed. A process killed
/// before the commit leaves only the hidden sibling.
#[derive(Debug)]
pub struct StagedFolder {
    target: PathBuf,
    staged: PathBuf,
    committed: bool,
}

impl StagedFolder {
    /// Checks that `target` can take a run folder: absent, an empty folder, or (with `force`) a
    /// folder to replace; a symbolic link, a file or device, and a non-empty folder without
    /// `force` are refused. Call before any work, then [`create`](Self::create) to write.
    pub fn check(target: &Path, force: bool) -> Result<()> {
        match std::fs::symlink_metadata(target) {
            Err(_) => Ok(()),
            Ok(m) if m.file_type().is_symlink() => crate::bail!(
                "{} is a symbolic link; refusing to replace it (name the folder it points to, or another path)",
                target.display()
            ),
            Ok(m) if !m.is_dir() => crate::bail!("{} exists and is not a folder", target.display()),
            Ok(_) => {
                let empty = std::fs::read_dir(target)
                    .with_context(|| format!("cannot read {}", target.display()))?
                    .next()
                    .is_none();
                if empty || force {
                    Ok(())
                } else {
                    crate::bail!(
                        "{} exists and is not empty; choose another folder or pass --force to replace it",
                        target.display()
                    )
                }
            }
        }
    }

    /// Creates the hidden sibling folder that the run writes into.
    pub fn create(target: &Path) -> Result<Self> {
        let (dir, name) = folder_parts(target);
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create folder {}", dir.display()))?;
        let staged = dir.join(ferrocal_datasets::atomic::staging_name(&name, "partial-"));
        if staged.exists() {
            std::fs::remove_dir_all(&staged).with_context(|| format!("cannot remove {}", staged.display()))?;
        }
        std::fs::create_dir(&staged).with_context(|| format!("cannot create folder {}", staged.display()))?;
        Ok(Self { target: target.to_path_buf(), staged, committed: false })
    }

    /// The folder to write the run's files into.
    pub fn path(&self) -> &Path {
        &self.staged
    }

    /// Moves the written folder into place. An existing target is first renamed aside (to
    /// `.NAME.old-PID`) and removed after the move, so an interrupted commit leaves the old
    /// folder aside or the new one in place, never a mix of both.
    pub fn commit(mut self) -> Result<PathBuf> {
        ferrocal_datasets::pause_before_commit();
        let (dir, name) = folder_parts(&self.target);
        let old = dir.join(ferrocal_datasets::atomic::staging_name(&name, "old-"));
        let had_target = std::fs::symlink_metadata(&self.target).is_ok();
        if had_target {
            std::fs::rename(&self.target, &old)
                .with_context(|| format!("cannot move {} aside", self.target.display()))?;
        }
        if let Err(e) = std::fs::rename(&self.staged, &self.target) {
            if had_target {
                let _ = std::fs::rename(&old, &self.target);
            }
            return Err(e)
                .with_context(|| format!("cannot move {} to {}", self.staged.display(), self.target.display()));
        }
        self.committed = true;
        if had_target {
            let _ = std::fs::remove_dir_all(&old);
        }
        Ok(self.target.clone())
    }
}

impl Drop for StagedFolder {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.staged);
        }
    }
}

/// The parent folder (`.` for a bare name) and the file name of a folder path.
fn folder_parts(path: &Path) -> (&Path, String) {
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    (dir, path.file_name().and_then(|n| n.to_str()).unwrap_or("out").to_string())
}

const CSS: &str = "body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}\
h1{border-bottom:2px solid #335}h2{margin-top:2em;border-bottom:1px solid #ccc}\
table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:left;font-variant-numeric:tabular-nums}td.n{text-align:right}\
th{background:#eef}caption{font-weight:bold;text-align:left;padding:4px 0}\
figure{margin:1em 0}figcaption{font-size:90%;color:#444}.attr{font-size:80%;color:#666}\
.ok{color:#fff;background:#2a7;padding:1px 6px;border-radius:3px;font-size:70%}\
.bad{color:#fff;background:#c33;padding:1px 6px;border-radius:3px;font-size:70%}\
.note{color:#fff;background:#888;padding:1px 6px;border-radius:3px;font-size:70%}\
pre{background:#f6f6f6;padding:6px;overflow-x:auto;white-space:pre-wrap}nav ul{columns:2}\
details>summary{cursor:pointer;color:#335;margin:.5em 0}section.folded{margin:.2em 0;border-bottom:1px solid #eee}\
section.folded summary{font-size:110%;padding:.3em 0}.verdict td{text-align:left}table{max-width:100%;display:block;overflow-x:auto}\
svg,img{max-width:100%;height:auto}\
.verdict{border:2px solid #888;border-left-width:10px;border-radius:4px;padding:.4em 1em;margin:1em 0}\
.verdict p{margin:.3em 0}.verdict table{margin:.5em 0}.verdict td.l{text-align:left}\
.v-pass{border-color:#2a7;background:#f0faf4}.v-warning{border-color:#d90;background:#fff8e6}\
.v-fail{border-color:#c33;background:#fdf0f0}.s-pass{color:#2a7}.s-warning{color:#b70}.s-fail{color:#c33;font-weight:bold}";

/// An 8-bit grey image as an inline `<img>` (PNG, base64), for figures.
pub fn inline_png(img: &image::GrayImage, alt: &str) -> String {
    use base64::Engine as _;
    let mut bytes = Vec::new();
    let ok = image::DynamicImage::ImageLuma8(img.clone())
        .write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png)
        .is_ok();
    if !ok {
        return format!("<p>({alt}: could not encode)</p>");
    }
    format!(
        "<img alt=\"{}\" src=\"data:image/png;base64,{}\" style=\"max-width:100%\"/>",
        esc(alt),
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

#[cfg(test)]
mod tests;
