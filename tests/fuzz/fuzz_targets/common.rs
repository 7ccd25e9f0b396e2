//! Shared by the loader targets: the loaders read files, so each input is written to a per-process file.

use std::path::PathBuf;

use clipsat::source::{self, LoadOptions};

/// Loads `data` as a file called `name`; any `Err` is fine, a panic is a finding.
pub fn load_as(name: &str, data: &[u8], opts: &LoadOptions) {
    let dir = std::env::temp_dir().join(format!("clipsat-fuzz-{}", std::process::id()));
    let _ = std::fs::create_dir_all(&dir);
    let path: PathBuf = dir.join(name);
    if std::fs::write(&path, data).is_err() {
        return;
    }
    let _ = source::load(&path, opts);
}

/// A sample limit small enough that huge declared sizes are refused, not allocated; a spacing, so files
/// without one are decoded all the way instead of refused early.
pub fn small() -> LoadOptions {
    LoadOptions {
        max_samples: 1 << 21,
        spacing: Some(30.0),
        ..LoadOptions::default()
    }
}
