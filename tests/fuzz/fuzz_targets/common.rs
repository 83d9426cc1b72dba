//! Shared by the fuzz targets: the input written to a file, for the readers that take a path.

use std::path::PathBuf;

/// Writes `bytes` to `name` in a folder of this process (in `/dev/shm` when there is one) and
/// returns its path.
pub fn temp_file(name: &str, bytes: &[u8]) -> PathBuf {
    let base = if std::path::Path::new("/dev/shm").is_dir() { PathBuf::from("/dev/shm") } else { std::env::temp_dir() };
    let dir = base.join(format!("ferrocal-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temporary folder");
    let path = dir.join(name);
    std::fs::write(&path, bytes).expect("temporary file");
    path
}
