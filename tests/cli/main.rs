//! The CLI test binary: runs the built `clipsat` binary end to end (`CARGO_BIN_EXE_clipsat`): its outputs,
//! refusals, determinism across runs, and the window under Xvfb (ignored; `bash .ci/view-xvfb`). Run one
//! module with `cargo test --test cli fly::`.

mod bad_input;
mod bench_all;
mod determinism;
mod fly;
mod hash;
mod render_json;
mod stream_rss;
mod view_xvfb;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the built `clipsat` binary with `args`.
fn clipsat(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_clipsat"))
        .args(args)
        .output()
        .expect("run the clipsat binary")
}

/// A fresh, empty folder `group/name` under the target's test scratch space, for one test's outputs.
fn scratch_in(group: &str, name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(group)
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create scratch folder");
    dir
}
