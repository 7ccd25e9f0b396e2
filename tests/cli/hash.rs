//! `clipsat fly --hash-out` / `--check` end to end with the built binary: a written file checks clean; a
//! tampered frame fails with exit 1 naming that frame and both hashes; a file for another run, a truncated,
//! missing or garbage file is refused with exit 2 and a clear error, never a panic.

use std::path::{Path, PathBuf};
use std::process::Output;

use super::clipsat;

fn scratch(name: &str) -> PathBuf {
    super::scratch_in("cli_hash", name)
}

/// The run every test writes and checks.
fn run(extra: &[&str]) -> Vec<String> {
    let mut a: Vec<String> = [
        "fly",
        "--profile",
        "gles3-low",
        "--terrain",
        "procedural:size=257",
        "--path",
        "teleport:10",
        "--frames",
        "40",
        "--speed",
        "80",
    ]
    .iter()
    .map(|s| (*s).to_owned())
    .collect();
    a.extend(extra.iter().map(|s| (*s).to_owned()));
    a
}

fn go(args: &[String]) -> Output {
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    clipsat(&refs)
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Exit 2 with a one-line `error:` naming `file`, and no panic.
fn assert_refused(out: &Output, file: &Path, what: &str) {
    let err = stderr(out);
    assert_eq!(out.status.code(), Some(2), "{what}: {err}");
    assert!(!err.contains("panicked"), "{what}: {err}");
    assert!(err.starts_with("error: "), "{what}: {err}");
    assert!(
        err.contains(&file.display().to_string()),
        "{what}: error does not name the file: {err}"
    );
}

fn write_hashes(dir: &Path) -> (PathBuf, String) {
    let file = dir.join("sub/hashes.txt");
    let out = go(&run(&["--hash-out", &file.to_string_lossy()]));
    assert!(out.status.success(), "{}", stderr(&out));
    let text = std::fs::read_to_string(&file).expect("hash file written");
    (file, text)
}

#[test]
fn written_hashes_check_clean_and_a_tampered_frame_fails() {
    let dir = scratch("roundtrip");
    let (file, text) = write_hashes(&dir);
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "# clipsat frame hashes v1");
    for key in [
        "terrain",
        "terrain_hash",
        "profile",
        "path",
        "speed",
        "frames",
        "synth_levels",
    ] {
        assert!(
            lines.iter().any(|l| l.starts_with(&format!("# {key}="))),
            "header lacks {key}: {text}"
        );
    }
    let frames: Vec<&str> = lines
        .iter()
        .filter(|l| !l.starts_with('#'))
        .copied()
        .collect();
    assert_eq!(frames.len(), 40);
    for (i, l) in frames.iter().enumerate() {
        let (f, h) = l.split_once('\t').expect("frame<TAB>hash");
        assert_eq!(f, i.to_string());
        assert!(
            h.len() == 16 && h.chars().all(|c| c.is_ascii_hexdigit()),
            "{l}"
        );
    }

    // The same run checks clean, in text and JSON modes.
    let out = go(&run(&["--check", &file.to_string_lossy()]));
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(String::from_utf8_lossy(&out.stdout).contains("40 frames match"));
    let out = go(&run(&["--check", &file.to_string_lossy(), "--json"]));
    assert!(out.status.success(), "{}", stderr(&out));

    // Tamper with frame 23: the check fails there, exit 1, both hashes named.
    let orig = frames[23].split_once('\t').expect("tab").1;
    let first = if orig.starts_with('0') { "1" } else { "0" };
    let forged = format!("{first}{}", orig.get(1..).expect("16 hex digits"));
    let tampered = text.replace(&format!("\n23\t{orig}\n"), &format!("\n23\t{forged}\n"));
    assert_ne!(tampered, text);
    let bad = dir.join("tampered.txt");
    std::fs::write(&bad, tampered).expect("write");
    let out = go(&run(&["--check", &bad.to_string_lossy()]));
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        err.contains(&format!("frame 23: expected {forged}, got {orig}")),
        "{err}"
    );
}

#[test]
fn mismatched_truncated_missing_and_garbage_files_are_refused() {
    let dir = scratch("refusals");
    let (file, text) = write_hashes(&dir);
    let f = file.to_string_lossy().into_owned();

    // Other parameters than the file's: refused before flying, naming the parameter.
    for (from, to, key) in [
        ("80", "81", "speed"),
        ("gles3-low", "gles3-mid", "profile"),
        ("teleport:10", "teleport:11", "path"),
        ("40", "41", "frames"),
        (
            "procedural:size=257",
            "procedural:size=257,seed=9",
            "terrain_hash",
        ),
    ] {
        let mut a = run(&["--check", &f]);
        a.iter_mut()
            .filter(|s| *s == from)
            .for_each(|s| *s = to.to_owned());
        let out = go(&a);
        assert_refused(&out, &file, key);
        assert!(stderr(&out).contains(key), "{key}: {}", stderr(&out));
    }
    // The plan's viewport (SAT LOD measures pixels) and the profile's values are the run's too: another
    // size, or a profile file that keeps the shipped name with another budget, is another run.
    let out = go(&run(&["--size", "640x360", "--check", &f]));
    assert_refused(&out, &file, "viewport");
    assert!(stderr(&out).contains("viewport="), "{}", stderr(&out));
    let shipped = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("profiles/gles3-low.toml"),
    )
    .expect("the shipped profile");
    let toml = dir.join("gles3-low.toml");
    std::fs::write(
        &toml,
        shipped.replacen(
            "update_samples_per_frame = 8160",
            "update_samples_per_frame = 8000",
            1,
        ),
    )
    .expect("write");
    let mut a = run(&["--check", &f]);
    a.iter_mut()
        .filter(|s| *s == "gles3-low")
        .for_each(|s| *s = toml.to_string_lossy().into_owned());
    let out = go(&a);
    assert_refused(&out, &file, "profile_hash");
    assert!(stderr(&out).contains("profile_hash="), "{}", stderr(&out));
    // A resident run against the file of a streamed one, refused naming that first.
    let out = go(&run(&["--resident", "--check", &f]));
    assert_refused(&out, &file, "streamed");
    assert!(stderr(&out).contains("streamed=true"), "{}", stderr(&out));
    // gles3-low affords no synthesised rings.
    let out = go(&run(&["--synth-levels", "1", "--check", &f]));
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("synthesis"), "{}", stderr(&out));

    let cases: Vec<(&str, Vec<u8>)> = vec![
        (
            "truncated",
            text.lines()
                .take(text.lines().count() - 5)
                .collect::<Vec<_>>()
                .join("\n")
                .into_bytes(),
        ),
        ("empty", Vec::new()),
        ("garbage", b"\x00\xff\x13 not a hash file".to_vec()),
        (
            "no magic",
            text.replacen("# clipsat", "# other", 1).into_bytes(),
        ),
        (
            "bad hash",
            text.replacen("\n5\t", "\n5\tzz", 1).into_bytes(),
        ),
        (
            "skipped frame",
            text.replacen("\n5\t", "\n6\t", 1).into_bytes(),
        ),
        ("no tab", text.replacen("\n5\t", "\n5 ", 1).into_bytes()),
        (
            "no frames line",
            text.lines()
                .filter(|l| !l.starts_with("# frames="))
                .collect::<Vec<_>>()
                .join("\n")
                .into_bytes(),
        ),
        (
            "unknown key",
            text.replacen("# profile=", "# colour=blue\n# profile=", 1)
                .into_bytes(),
        ),
    ];
    for (what, bytes) in cases {
        let p = dir.join(format!("{}.txt", what.replace(' ', "_")));
        std::fs::write(&p, bytes).expect("write");
        let out = go(&run(&["--check", &p.to_string_lossy()]));
        assert_refused(&out, &p, what);
        assert_eq!(stderr(&out).lines().count(), 1, "{what}: {}", stderr(&out));
    }
    let missing = dir.join("missing.txt");
    let out = go(&run(&["--check", &missing.to_string_lossy()]));
    assert_refused(&out, &missing, "missing");
}
