//! Outputs committed whole: every file is written beside its target under a hidden temporary name
//! (`.NAME.tmpPID`), then all are renamed into place, so that a reader never sees half a file and
//! a failed write touches no target. The one implementation behind every command's outputs (the
//! report crate's `write_atomic` and `write_all_atomic` call it).

use std::path::{Path, PathBuf};

use crate::error::{DatasetError, Result};

/// Whether two paths name the same existing file (through any links); otherwise whether they
/// are equal as written.
fn same(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    }
}

/// Refuses a target that exists and is not a regular file (a symbolic link, a device node, a
/// folder): the temporary file's rename would replace the link or node itself, silently.
pub fn check_regular_target(path: &Path) -> Result<()> {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => Err(DatasetError::Input(format!(
            "{} is a symbolic link; refusing to replace it (write to the file it names, or another path)",
            path.display()
        ))),
        Ok(m) if !m.is_file() => Err(DatasetError::Input(format!(
            "{} exists and is not a regular file (a device or folder); refusing to replace it",
            path.display()
        ))),
        _ => Ok(()),
    }
}

/// The longest file name most file systems take, bytes.
const MAX_NAME_BYTES: usize = 255;

/// The hidden name a write of `name` is staged under: `.NAME.TAGPID`, with `NAME` cut (and
/// marked with a hash of the whole name, so two long names never share a staging name) when
/// the whole would be longer than a file name may be: a legal 250-character output stays
/// writable.
pub fn staging_name(name: &str, tag: &str) -> String {
    let suffix = format!(".{tag}{}", std::process::id());
    let whole = format!(".{name}{suffix}");
    if whole.len() <= MAX_NAME_BYTES {
        return whole;
    }
    // FNV-1a of the whole name.
    let hash = name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3));
    let mark = format!("~{:08x}", hash as u32);
    let mut keep = MAX_NAME_BYTES - 1 - suffix.len() - mark.len();
    while !name.is_char_boundary(keep) {
        keep -= 1;
    }
    format!(".{}{mark}{suffix}", &name[..keep])
}

/// The folder of `path` and the temporary name beside it that a write is staged under.
fn staging_path(path: &Path) -> (&Path, PathBuf) {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    (dir, dir.join(staging_name(&name, "tmp")))
}

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename, so that a
/// reader never sees half a file; refuses to write onto one of `inputs`.
pub fn write_atomic(path: &Path, bytes: &[u8], inputs: &[&Path]) -> Result<()> {
    write_all_atomic(&[(path, bytes)], inputs)
}

/// Writes several files as one commit: each is written beside its target under a temporary
/// name (the target's folder created if missing), then all are renamed into place; a failed
/// write touches no target and leaves no temporary file. Refuses to write onto one of `inputs`
/// and to replace anything but a regular file.
pub fn write_all_atomic(files: &[(&Path, &[u8])], inputs: &[&Path]) -> Result<()> {
    for (path, _) in files {
        if inputs.iter().any(|i| same(path, i)) {
            return Err(DatasetError::Input(format!("refusing to overwrite the input {}", path.display())));
        }
        check_regular_target(path)?;
    }
    let mut staged: Vec<(PathBuf, &Path)> = Vec::new();
    let cleanup = |staged: &[(PathBuf, &Path)]| {
        for (t, _) in staged {
            let _ = std::fs::remove_file(t);
        }
    };
    for (path, bytes) in files {
        let (dir, tmp) = staging_path(path);
        let r = std::fs::create_dir_all(dir).and_then(|_| std::fs::write(&tmp, bytes));
        staged.push((tmp, path));
        if let Err(source) = r {
            cleanup(&staged);
            return Err(DatasetError::Write { path: path.to_path_buf(), source });
        }
    }
    crate::pause_before_commit();
    for (k, (tmp, path)) in staged.iter().enumerate() {
        if let Err(source) = std::fs::rename(tmp, path) {
            cleanup(&staged[k..]);
            return Err(DatasetError::Write { path: path.to_path_buf(), source });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn files_are_committed_together_and_inputs_and_links_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("sub/a.txt"), dir.path().join("b.txt"));
        write_all_atomic(&[(&a, b"one"), (&b, b"two")], &[]).unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "one");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "two");
        let e = write_atomic(&b, b"x", &[&b]).unwrap_err().to_string();
        assert!(e.contains("input"), "{e}");
        #[cfg(unix)]
        {
            let link = dir.path().join("link.txt");
            std::os::unix::fs::symlink(&b, &link).unwrap();
            let e = write_atomic(&link, b"x", &[]).unwrap_err().to_string();
            assert!(e.contains("symbolic link"), "{e}");
            assert_eq!(std::fs::read_to_string(&b).unwrap(), "two");
        }
        let e = write_atomic(dir.path(), b"x", &[]).unwrap_err().to_string();
        assert!(e.contains("not a regular file"), "{e}");
        let left: Vec<_> =
            std::fs::read_dir(dir.path()).unwrap().filter_map(|e| e.ok()).map(|e| e.file_name()).collect();
        assert!(left.iter().all(|n| !n.to_string_lossy().contains(".tmp")), "{left:?}");
    }

    #[test]
    fn a_legal_250_character_name_is_written_and_long_names_stage_apart() {
        let dir = tempfile::tempdir().unwrap();
        let long_a = format!("{}a.csv", "x".repeat(245));
        let long_b = format!("{}b.csv", "x".repeat(245));
        assert_eq!(long_a.len(), 250);
        let (sa, sb) = (staging_name(&long_a, "tmp"), staging_name(&long_b, "tmp"));
        assert!(sa.len() <= MAX_NAME_BYTES && sb.len() <= MAX_NAME_BYTES, "{} {}", sa.len(), sb.len());
        assert_ne!(sa, sb, "two long names never share a staging name");
        let (pa, pb) = (dir.path().join(&long_a), dir.path().join(&long_b));
        write_all_atomic(&[(&pa, b"1"), (&pb, b"2")], &[]).unwrap();
        assert_eq!(std::fs::read(&pa).unwrap(), b"1");
        assert_eq!(std::fs::read(&pb).unwrap(), b"2");
        // Multi-byte names are cut on a character boundary.
        let wide = "\u{00e9}".repeat(125);
        assert!(staging_name(&wide, "partial-").len() <= MAX_NAME_BYTES);
        assert_eq!(staging_name("t.csv", "tmp"), format!(".t.csv.tmp{}", std::process::id()));
    }
}
