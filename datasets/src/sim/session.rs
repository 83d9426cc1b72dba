//! The `simulate` workflow's edges: the cell file read for a session folder
//! ([`cell_for_session`]) and what was written, in words ([`session_summary`]); the session
//! itself is written by [`super::simulate`].

use std::path::Path;

use super::{CellConfig, SessionManifest};
use crate::error::{DatasetError, Result};

/// The cell of the file `config` for a session written to `out`, its seed replaced by `seed`
/// when given. The session folder must not hold (or be) the cell file: `--force` replaces the
/// folder.
pub fn cell_for_session(config: &Path, out: &Path, seed: Option<u64>) -> Result<CellConfig> {
    if let (Ok(cfg_path), Ok(out_path)) = (config.canonicalize(), out.canonicalize()) {
        if cfg_path.starts_with(&out_path) {
            return Err(DatasetError::Input(format!(
                "--out {} holds the cell file {}; choose another folder",
                out.display(),
                config.display()
            )));
        }
    }
    let mut cfg = CellConfig::from_file(config)?;
    if let Some(s) = seed {
        cfg.seed = s;
    }
    Ok(cfg)
}

/// What a session written to `out` holds, in words: poses, cameras, the tracker and the notes.
pub fn session_summary(manifest: &SessionManifest, out: &Path) -> String {
    format!(
        "session written to {}: {} poses, {} camera(s){}{}",
        out.display(),
        manifest.n_poses,
        manifest.cameras.len(),
        if manifest.tracker.is_some() { ", laser tracker" } else { "" },
        if manifest.notes.is_empty() {
            String::new()
        } else {
            format!("; {} note(s) in manifest.json", manifest.notes.len())
        }
    )
}
