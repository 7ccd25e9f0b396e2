//! The CLI test binary: runs the built `clipsat` binary end to end (`CARGO_BIN_EXE_clipsat`): its outputs,
//! refusals, determinism across runs, and the window under Xvfb (ignored; `bash .ci/view-xvfb`). Run one
//! module with `cargo test --test cli fly::`.

mod bad_input;
mod bench_all;
mod determinism;
mod fly;
mod hash;
mod render_json;
mod view_xvfb;
