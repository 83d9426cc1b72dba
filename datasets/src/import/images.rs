//! Image folders: the images of a directory or glob pattern that the `image` crate can read
//! (PNG, JPEG, TIFF, BMP, PNM), in natural name order, with an optional joints table.
//!
//! A batch never aborts because of one bad image: an image that cannot be opened or decoded is
//! listed in [`ImageFolder::skipped`] with the reason. Files whose extension is not an image
//! format are ignored (labels, READMEs).
//!
//! The joints table is a CSV file (comma-separated, `.` decimal point, `#` comments) with a column
//! `image` (the image file name; a relative path is matched against the end of the image paths)
//! and joint columns `q1_<u>` ... `qN_<u>` with `<u>` = `rad`, `deg`, `m` or `mm`; other columns
//! are ignored. A row that names a file which is not among the images is an error naming the
//! table, the line and the column.

use std::cmp::Ordering;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::table::{Table, TableFormat};
use super::units::JointUnit;
use crate::error::{DatasetError, Location, Result};

/// Extensions (lower case) of the formats this crate's `image` build reads.
pub const IMAGE_EXTENSIONS: &[&str] = &["png", "jpg", "jpeg", "tif", "tiff", "bmp", "pnm", "pbm", "pgm", "ppm", "pam"];

/// One readable image.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageEntry {
    /// Path as listed.
    pub path: PathBuf,
    /// File name (last path component).
    pub file_name: String,
    /// Width in pixels.
    pub width_px: u32,
    /// Height in pixels.
    pub height_px: u32,
    /// Joint values in SI (rad or m), from the joints table, when one was given and names the
    /// image.
    pub q: Option<Vec<f64>>,
    /// Line of the joints-table row, when matched.
    pub joints_line: Option<u64>,
}

/// An image that was skipped, and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SkippedImage {
    /// The file.
    pub path: PathBuf,
    /// Why it could not be read.
    pub reason: String,
}

impl std::fmt::Display for SkippedImage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.reason)
    }
}

/// Options of [`list_images`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ImageFolderOptions {
    /// Joints table to match by file name.
    pub joints_table: Option<PathBuf>,
    /// Decode every image fully (finds truncated files) instead of reading only the header.
    pub decode: bool,
}

impl Default for ImageFolderOptions {
    fn default() -> Self {
        Self { joints_table: None, decode: true }
    }
}

/// The result of listing an image folder.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageFolder {
    /// The directory or pattern listed.
    pub source: String,
    /// Readable images, natural name order.
    pub images: Vec<ImageEntry>,
    /// Unreadable images with reasons, natural name order.
    pub skipped: Vec<SkippedImage>,
    /// Units of the joints table's columns (empty without a table).
    pub joint_units: Vec<JointUnit>,
}

impl ImageFolder {
    /// A human-readable report of the skipped images (empty when none were skipped).
    pub fn skipped_report(&self) -> String {
        let mut s = String::new();
        for k in &self.skipped {
            let _ = writeln!(s, "skipped {k}");
        }
        s
    }
}

/// One row of a joints table.
#[derive(Clone, Debug, PartialEq)]
pub struct JointsRow {
    /// 1-based line.
    pub line: u64,
    /// The `image` cell.
    pub image: String,
    /// Joint values in SI (rad or m).
    pub q: Vec<f64>,
}

/// A joints table.
#[derive(Clone, Debug, PartialEq)]
pub struct JointsTable {
    /// The file read.
    pub file: PathBuf,
    /// 1-based header line.
    pub header_line: u64,
    /// Unit of each joint column.
    pub joint_units: Vec<JointUnit>,
    /// The rows.
    pub rows: Vec<JointsRow>,
}

/// Compares two names "naturally": runs of digits compare by value (`img2` < `img10`), other text
/// character by character; ties are broken by the plain string order.
pub fn natural_cmp(a: &str, b: &str) -> Ordering {
    let (ab, bb) = (a.as_bytes(), b.as_bytes());
    let (mut i, mut j) = (0, 0);
    while i < ab.len() && j < bb.len() {
        if ab[i].is_ascii_digit() && bb[j].is_ascii_digit() {
            let si = i;
            while i < ab.len() && ab[i].is_ascii_digit() {
                i += 1;
            }
            let sj = j;
            while j < bb.len() && bb[j].is_ascii_digit() {
                j += 1;
            }
            let na = trim_zeros(&ab[si..i]);
            let nb = trim_zeros(&bb[sj..j]);
            let o = na.len().cmp(&nb.len()).then_with(|| na.cmp(nb));
            if o != Ordering::Equal {
                return o;
            }
        } else {
            let o = ab[i].cmp(&bb[j]);
            if o != Ordering::Equal {
                return o;
            }
            i += 1;
            j += 1;
        }
    }
    (ab.len() - i).cmp(&(bb.len() - j)).then_with(|| a.cmp(b))
}

fn trim_zeros(d: &[u8]) -> &[u8] {
    let k = d.iter().take_while(|c| **c == b'0').count();
    &d[k.min(d.len().saturating_sub(1))..]
}

fn has_image_extension(p: &Path) -> bool {
    p.extension().and_then(|e| e.to_str()).is_some_and(|e| IMAGE_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// Lists the images of a directory, a glob pattern (`*`, `?`, `[...]`) or a single file.
pub fn list_images(spec: impl AsRef<Path>, opts: &ImageFolderOptions) -> Result<ImageFolder> {
    let spec = spec.as_ref();
    let text = spec.to_string_lossy().to_string();
    let mut skipped = Vec::new();
    let mut candidates: Vec<PathBuf> = Vec::new();
    if spec.is_dir() {
        let rd = std::fs::read_dir(spec).map_err(|source| DatasetError::Io { path: spec.to_path_buf(), source })?;
        for e in rd {
            match e {
                Ok(e) => {
                    let p = e.path();
                    if p.is_file() && has_image_extension(&p) {
                        candidates.push(p);
                    }
                }
                Err(err) => skipped.push(SkippedImage {
                    path: spec.to_path_buf(),
                    reason: format!("directory entry cannot be read: {err}"),
                }),
            }
        }
    } else if text.contains(['*', '?', '[']) {
        let paths = glob::glob(&text).map_err(|e| DatasetError::Input(format!("bad glob pattern '{text}': {e}")))?;
        for p in paths {
            match p {
                Ok(p) => {
                    if p.is_file() && has_image_extension(&p) {
                        candidates.push(p);
                    }
                }
                Err(e) => skipped.push(SkippedImage { path: e.path().to_path_buf(), reason: e.error().to_string() }),
            }
        }
    } else if spec.is_file() {
        candidates.push(spec.to_path_buf());
    } else if let Some(kind) = special_file_kind(spec) {
        return Err(DatasetError::Input(format!(
            "{}: is a {kind}, not an image file: name the image files (or their folder) instead",
            spec.display()
        )));
    } else {
        return Err(DatasetError::Io {
            path: spec.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such directory or file"),
        });
    }
    candidates.sort_by(|a, b| natural_cmp(&a.to_string_lossy(), &b.to_string_lossy()));

    let mut images = Vec::new();
    for p in candidates {
        match probe(&p, opts.decode) {
            Ok((w, h)) => images.push(ImageEntry {
                file_name: p.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default(),
                path: p,
                width_px: w,
                height_px: h,
                q: None,
                joints_line: None,
            }),
            Err(reason) => skipped.push(SkippedImage { path: p, reason }),
        }
    }
    skipped.sort_by(|a, b| natural_cmp(&a.path.to_string_lossy(), &b.path.to_string_lossy()));

    let mut joint_units = Vec::new();
    if let Some(tp) = &opts.joints_table {
        let table = read_joints_table(tp)?;
        joint_units = table.joint_units.clone();
        let mut first_line: HashMap<usize, u64> = HashMap::new();
        for row in &table.rows {
            let matches = |p: &Path| names_file(&row.image, p);
            if let Some(k) = images.iter().position(|e| matches(&e.path)) {
                if let Some(first) = first_line.insert(k, row.line) {
                    return Err(DatasetError::Invalid {
                        location: Location::new(&table.file, row.line, "image"),
                        message: format!("image '{}' already has joints on line {first}", row.image),
                    });
                }
                images[k].q = Some(row.q.clone());
                images[k].joints_line = Some(row.line);
            } else if skipped.iter().any(|s| matches(&s.path)) {
                // The image exists but is unreadable: it is already reported as skipped.
            } else {
                return Err(DatasetError::MissingFile {
                    location: Location::new(&table.file, row.line, "image"),
                    missing: row.image.clone(),
                    detail: format!(" among the images of {text}"),
                });
            }
        }
    }
    Ok(ImageFolder { source: text, images, skipped, joint_units })
}

/// Whether the table cell `name` names the file `p`: equal file names, or, for a cell with
/// several components, `p` ends with those components.
fn names_file(name: &str, p: &Path) -> bool {
    let n = Path::new(name);
    if n.components().count() > 1 {
        p.ends_with(n)
    } else {
        p.file_name().is_some_and(|f| f == n.as_os_str())
    }
}

fn probe(p: &Path, decode: bool) -> std::result::Result<(u32, u32), String> {
    if decode {
        // Size limit and completeness before any pixel is decoded.
        ferrocal_vision::detect::check_image_file(p)?;
    }
    let reader = image::ImageReader::open(p)
        .map_err(|e| format!("cannot open: {e}"))?
        .with_guessed_format()
        .map_err(|e| format!("cannot read: {e}"))?;
    if reader.format().is_none() {
        return Err("unrecognised image format".into());
    }
    if decode {
        let img = reader.decode().map_err(|e| format!("cannot decode: {e}"))?;
        Ok((img.width(), img.height()))
    } else {
        reader.into_dimensions().map_err(|e| format!("cannot read the header: {e}"))
    }
}

/// Reads a joints table (see the module documentation).
pub fn read_joints_table(path: impl AsRef<Path>) -> Result<JointsTable> {
    let path = path.as_ref();
    let table = Table::read(path, TableFormat::CSV, &|name| joint_column(name).is_some())?;
    let image_col = table.require("image")?;
    let mut joints: HashMap<usize, (usize, JointUnit)> = HashMap::new();
    for (c, name) in table.headers.iter().enumerate() {
        if let Some((i, u)) = joint_column(name) {
            if joints.insert(i, (c, u)).is_some() {
                return Err(DatasetError::Invalid {
                    location: table.header_loc(c),
                    message: format!("joint {i} has two columns"),
                });
            }
        }
    }
    let n = joints.keys().copied().max().unwrap_or(0);
    if n == 0 {
        let mut e = table.missing_column("q1_rad");
        if let DatasetError::MissingColumn { hint, .. } = &mut e {
            *hint = format!("; joint columns are q1_<u> ... qN_<u> with <u> = rad, deg, m or mm{hint}");
        }
        return Err(e);
    }
    let mut cols = Vec::with_capacity(n);
    for i in 1..=n {
        match joints.get(&i) {
            Some(c) => cols.push(*c),
            None => {
                return Err(DatasetError::JointCount {
                    location: Location::new(&table.file, table.header_line, format!("q{i}_<unit>")),
                    message: format!("the header has joint columns up to q{n} but no q{i}"),
                })
            }
        }
    }
    let mut rows = Vec::with_capacity(table.rows.len());
    for row in &table.rows {
        let image = table.text(row, image_col)?.to_string();
        let mut q = Vec::with_capacity(n);
        for (c, u) in &cols {
            q.push(u.to_si(table.number(row, *c)?));
        }
        rows.push(JointsRow { line: row.line, image, q });
    }
    Ok(JointsTable {
        file: path.to_path_buf(),
        header_line: table.header_line,
        joint_units: cols.iter().map(|(_, u)| *u).collect(),
        rows,
    })
}

fn joint_column(name: &str) -> Option<(usize, JointUnit)> {
    let rest = name.strip_prefix('q')?;
    let (num, unit) = rest.split_once('_')?;
    if num.is_empty() || !num.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let i: usize = num.parse().ok().filter(|i| *i > 0)?;
    Some((i, JointUnit::from_suffix(unit)?))
}

/// Writes the joints of the images that have them as a joints table (`image`, `q<i>_<u>`), so a
/// listed folder can be saved and read back. `joint_units` gives the column units.
pub fn write_joints_table(path: impl AsRef<Path>, folder: &ImageFolder, joint_units: &[JointUnit]) -> Result<()> {
    let path = path.as_ref();
    let mut out = String::from("image");
    for (i, u) in joint_units.iter().enumerate() {
        let _ = write!(out, ",q{}_{}", i + 1, u.suffix());
    }
    out.push('\n');
    for e in &folder.images {
        let Some(q) = &e.q else { continue };
        if q.len() != joint_units.len() || q.iter().any(|v| !v.is_finite()) {
            return Err(DatasetError::Input(format!(
                "image {}: {} joint values (finite values needed), the table has {} joint columns",
                e.file_name,
                q.len(),
                joint_units.len()
            )));
        }
        if e.file_name.contains([',', '"', '\n', '\r']) || e.file_name.starts_with('#') {
            out.push('"');
            out.push_str(&e.file_name.replace('"', "\"\""));
            out.push('"');
        } else {
            out.push_str(&e.file_name);
        }
        for (v, u) in q.iter().zip(joint_units) {
            out.push(',');
            out.push_str(&super::measurements::fmt_f64(u.from_si(*v)));
        }
        out.push('\n');
    }
    std::fs::write(path, out).map_err(|source| DatasetError::Write { path: path.to_path_buf(), source })
}

/// What an existing path that is neither a regular file nor a folder is (a FIFO, a device, a
/// socket), for an error that names it; `None` when nothing is there.
fn special_file_kind(path: &Path) -> Option<&'static str> {
    let meta = std::fs::metadata(path).ok()?;
    let t = meta.file_type();
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return Some("named pipe (FIFO)");
        }
        if t.is_char_device() {
            return Some("character device");
        }
        if t.is_block_device() {
            return Some("block device");
        }
        if t.is_socket() {
            return Some("socket");
        }
    }
    (!t.is_file() && !t.is_dir()).then_some("special file")
}

/// Expands files, directories and globs into image paths (natural order, duplicates removed),
/// for the camera calibration; a path that matches nothing is reported as skipped. Unreadable
/// files are kept: the detector reports them with a uniform reason.
pub fn expand_image_specs(
    specs: &[PathBuf],
    skipped: &mut Vec<ferrocal_vision::calib::corners::SkippedImage>,
) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = Vec::new();
    for spec in specs {
        match list_images(spec, &ImageFolderOptions { joints_table: None, decode: false }) {
            Ok(folder) => {
                // Unreadable files are kept: the detector reports them with a uniform reason.
                let mut found: Vec<PathBuf> = folder.images.into_iter().map(|e| e.path).collect();
                found.extend(folder.skipped.into_iter().map(|s| s.path));
                found.sort_by(|a, b| natural_cmp(&a.to_string_lossy(), &b.to_string_lossy()));
                if found.is_empty() {
                    skipped.push(ferrocal_vision::calib::corners::SkippedImage {
                        image: spec.clone(),
                        reason: "no image files match".into(),
                    });
                }
                for p in found {
                    if !out.contains(&p) {
                        out.push(p);
                    }
                }
            }
            Err(e) => skipped
                .push(ferrocal_vision::calib::corners::SkippedImage { image: spec.clone(), reason: e.to_string() }),
        }
    }
    out
}

/// Expands image specifications (files, folders, globs) into a sorted list for the detector:
/// `Ok(path)` for images to process, `Err((name, reason))` for entries that cannot be read (an
/// empty file says so) or a specification that matches nothing.
pub fn image_entries(specs: &[String]) -> Vec<std::result::Result<PathBuf, (String, String)>> {
    let mut out = Vec::new();
    for spec in specs {
        let opts = ImageFolderOptions { joints_table: None, decode: false };
        match list_images(spec, &opts) {
            Ok(folder) => {
                let mut entries: Vec<std::result::Result<PathBuf, (String, String)>> =
                    folder.images.into_iter().map(|e| Ok(e.path)).collect();
                entries.extend(folder.skipped.into_iter().map(|s| {
                    let empty = std::fs::metadata(&s.path).is_ok_and(|m| m.is_file() && m.len() == 0);
                    let reason = if empty {
                        "the file is empty (0 bytes)".to_string()
                    } else {
                        s.reason.trim().replace('\n', " ")
                    };
                    Err((s.path.display().to_string(), reason))
                }));
                entries.sort_by(|a, b| {
                    let name = |e: &std::result::Result<PathBuf, (String, String)>| match e {
                        Ok(p) => p.display().to_string(),
                        Err((n, _)) => n.clone(),
                    };
                    natural_cmp(&name(a), &name(b))
                });
                if entries.is_empty() {
                    out.push(Err((spec.clone(), "no image files match".to_string())));
                }
                out.extend(entries);
            }
            Err(e) => out.push(Err((spec.clone(), e.to_string()))),
        }
    }
    out
}
