//! Stage 1b, the bake's files: a bake killed with SIGKILL leaves no partial package and only locked
//! temporaries, which the next bake into the same folder removes (`src/temp.rs`).

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The files in `dir`, by name, sorted.
fn files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map(|d| {
            d.filter_map(std::result::Result::ok)
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

fn bake(terrain: &str, out: &Path) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_clipsat"));
    cmd.args(["bake", terrain, "--json", "--out"])
        .arg(out)
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    cmd
}

/// Kills a bake as soon as it has written a file, then bakes the same package into the same folder: the
/// killed bake left no file at the package's name, and after the second the package is whole and
/// nothing else is left. The killed bake's files are proved dead by their locks, which the kill
/// released. (Before the temporaries were locked and swept, the killed bake left its package's name
/// half written and the second left the first's spilled levels behind.)
#[cfg(unix)]
#[test]
fn a_killed_bake_leaves_nothing_that_a_later_run_uses_or_keeps() {
    let dir = super::scratch_in("bake", "killed");
    let out = dir.join("t.clipsat");
    let terrain = "procedural:size=513";
    let mut child = bake(terrain, &out).spawn().expect("start clipsat bake");
    let start = Instant::now();
    while files(&dir).is_empty() {
        let done = child.try_wait().expect("poll the bake");
        assert!(
            done.is_none(),
            "the bake ended before it was killed: {done:?}"
        );
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no temporary file appeared"
        );
        std::thread::sleep(Duration::from_millis(1));
    }
    child.kill().expect("kill -9 the bake");
    let _ = child.wait();
    let left = files(&dir);
    assert!(
        !out.exists(),
        "a killed bake leaves no package at its name: {left:?}"
    );
    assert!(
        !left.is_empty(),
        "the killed bake left its temporaries (the case under test)"
    );
    let status = bake(terrain, &out).status().expect("run clipsat bake");
    assert!(status.success(), "the second bake failed");
    assert_eq!(
        files(&dir),
        ["t.clipsat"],
        "only the package is left, after {left:?}"
    );
    clipsat::package::Package::open(&out).expect("the package opens");
}
