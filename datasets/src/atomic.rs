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

/// The folder of `path` and the temporary name beside it that a write is staged under.
fn staging_path(path: &Path) -> (&Path, PathBuf) {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    (dir, dir.join(format!(".{name}.tmp{}", std::process::id())))
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
}
