//! The frame-hash file of `clipsat fly --hash-out` and `--check` (stage 2's output, kept for later runs).
//!
//! Format: `# clipsat frame hashes v1`, then one `# key=value` line per run parameter, then one
//! `frame<TAB>hash16` line per frame, frames 0, 1, 2, ... in order. A check refuses a file whose parameters
//! differ from the run's (the terrain is compared by content hash, not by the name it was loaded under).

use std::fmt::Write as _;
use std::path::Path;

use clipsat::hash::hex;
use clipsat::{Error, Result};

/// The first line of every frame-hash file.
const MAGIC: &str = "# clipsat frame hashes v1";

/// Parameter keys that name the run but are not compared (the same terrain may be loaded under another path).
const INFORMATIONAL: [&str; 1] = ["terrain"];

/// A frame-hash file: the run's parameters and one hash per frame.
#[derive(Debug)]
pub(crate) struct HashFile {
    pub(crate) params: Vec<(String, String)>,
    pub(crate) hashes: Vec<u64>,
}

/// Writes `hashes` under a header of `params`.
pub(crate) fn write(path: &Path, params: &[(&str, String)], hashes: &[u64]) -> Result<()> {
    super::ensure_parent(path)?;
    let mut text = String::with_capacity(32 * (hashes.len() + params.len() + 1));
    text.push_str(MAGIC);
    text.push('\n');
    for (k, v) in params {
        let _ = writeln!(text, "# {k}={v}");
    }
    for (f, h) in hashes.iter().enumerate() {
        let _ = writeln!(text, "{f}\t{}", hex(*h));
    }
    std::fs::write(path, text).map_err(|e| Error::io(path, "cannot write", e))
}

/// Reads and validates a frame-hash file: magic, `key=value` header, consecutive frames, 16 hex digits each,
/// and as many frames as the header's `frames` says.
pub(crate) fn read(path: &Path) -> Result<HashFile> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, "cannot read", e))?;
    parse(path, &bytes)
}

/// [`read`] on bytes already read; `path` names the file in errors.
pub(crate) fn parse(path: &Path, bytes: &[u8]) -> Result<HashFile> {
    let text = std::str::from_utf8(bytes)
        .map_err(|_| Error::format(path, "not a frame-hash file (not UTF-8 text)"))?;
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, l)) if l.trim_end() == MAGIC => {}
        _ => {
            return Err(Error::format(
                path,
                format!("not a frame-hash file (first line is not `{MAGIC}`)"),
            ))
        }
    }
    let mut params = Vec::new();
    let mut hashes = Vec::new();
    for (i, line) in lines {
        let at = |reason: String| Error::format(path, format!("line {}: {reason}", i + 1));
        let line = line.trim_end();
        if let Some(kv) = line.strip_prefix('#') {
            if !hashes.is_empty() {
                return Err(at("header line after the first frame".into()));
            }
            let (k, v) = kv
                .trim()
                .split_once('=')
                .ok_or_else(|| at(format!("header `{line}` is not `# key=value`")))?;
            params.push((k.to_owned(), v.to_owned()));
            continue;
        }
        if line.is_empty() {
            continue;
        }
        let (f, h) = line
            .split_once('\t')
            .ok_or_else(|| at(format!("`{line}` is not `frame<TAB>hash`")))?;
        let f: usize = f
            .parse()
            .map_err(|_| at(format!("frame `{f}` is not a number")))?;
        if f != hashes.len() {
            return Err(at(format!(
                "frame {f} where frame {} was due",
                hashes.len()
            )));
        }
        if h.len() != 16 || !h.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(at(format!("hash `{h}` is not 16 hex digits")));
        }
        let h = u64::from_str_radix(h, 16).map_err(|e| at(format!("hash `{h}`: {e}")))?;
        hashes.push(h);
    }
    let file = HashFile { params, hashes };
    let frames = file
        .param("frames")
        .ok_or_else(|| Error::format(path, "header has no `frames=` line"))?;
    let frames: usize = frames
        .parse()
        .map_err(|_| Error::format(path, format!("header `frames={frames}` is not a number")))?;
    if file.hashes.len() != frames {
        return Err(Error::format(
            path,
            format!(
                "truncated: header says {frames} frames, file holds {}",
                file.hashes.len()
            ),
        ));
    }
    Ok(file)
}

impl HashFile {
    fn param(&self, key: &str) -> Option<&str> {
        self.params
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// Refuses a file written for other parameters than `params` (every key, both ways, but the
    /// informational ones).
    pub(crate) fn check_params(&self, path: &Path, params: &[(&str, String)]) -> Result<()> {
        for (k, v) in params {
            if INFORMATIONAL.contains(k) {
                continue;
            }
            match self.param(k) {
                Some(f) if f == v => {}
                Some(f) => {
                    return Err(Error::format(
                        path,
                        format!("written for {k}={f}, this run has {k}={v}: not the same run"),
                    ))
                }
                None => {
                    return Err(Error::format(
                        path,
                        format!("header has no `{k}=` line (this run has {k}={v})"),
                    ))
                }
            }
        }
        if let Some((k, _)) = self
            .params
            .iter()
            .find(|(k, _)| !params.iter().any(|(p, _)| p == k))
        {
            return Err(Error::format(
                path,
                format!("header names `{k}`, which this run does not have"),
            ));
        }
        Ok(())
    }
}

/// A content hash of a profile's values (its JSON form: every field, floats written shortest round-trip).
pub(crate) fn profile_hash(profile: &clipsat::profile::Profile) -> Result<String> {
    let json = serde_json::to_string(profile).map_err(|e| Error::Invalid {
        what: format!("profile {}", profile.name),
        reason: format!("cannot be written as JSON: {e}"),
    })?;
    let mut h = clipsat::hash::Hash64::new();
    h.write_bytes(json.as_bytes());
    Ok(hex(h.finish()))
}

/// A content hash of a terrain: dimensions, spacing and every height's bits.
pub(crate) fn terrain_hash(hm: &clipsat::source::Heightmap) -> String {
    let mut h = clipsat::hash::Hash64::new();
    h.write_u32(hm.width());
    h.write_u32(hm.height());
    h.write_f32(hm.spacing());
    for &z in hm.heights() {
        h.write_f32(z);
    }
    hex(h.finish())
}

/// The frame-hash file parser under the in-test fuzzer (`tests/fuzz/harness.rs`, as in
/// `tests/cpu/fuzz_parsers.rs`): it lives in the binary, so its fuzz target runs among the binary's tests.
#[cfg(test)]
#[path = "../../../tests/fuzz/harness.rs"]
mod fuzz_harness;

#[cfg(test)]
mod fuzz {
    use super::fuzz_harness as harness;

    /// The target: any bytes, an `Err` or a file whose frame count matches its header; never a panic.
    fn parse_hash_file(data: &[u8]) -> String {
        match super::parse(std::path::Path::new("fuzz.txt"), data) {
            Ok(f) => {
                assert_eq!(
                    f.param("frames").and_then(|n| n.parse().ok()),
                    Some(f.hashes.len())
                );
                "ok".into()
            }
            Err(e) => e
                .to_string()
                .split(|c: char| !c.is_ascii_alphabetic())
                .filter(|w| w.len() >= 3)
                .take(6)
                .collect::<Vec<_>>()
                .join(" "),
        }
    }

    /// 0.5 s by default; `CLIPSAT_FUZZ_SECS=600 cargo test --release --bin clipsat parse_hash_file_fuzz --
    /// --nocapture` for a long run.
    #[test]
    fn parse_hash_file_fuzz() {
        let secs = std::env::var("CLIPSAT_FUZZ_SECS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(0.5);
        let r = harness::fuzz(
            "parse_hash_file",
            parse_hash_file,
            std::time::Duration::from_secs_f64(secs),
            clipsat::hash::hash_bytes(b"parse_hash_file") ^ 17,
            8192,
        );
        eprintln!(
            "fuzz parse_hash_file: {} executions, {} crashes, corpus {} + {} new, {} outcomes",
            r.execs, r.crashes, r.corpus, r.added, r.outcomes
        );
        assert_eq!(r.crashes, 0, "crashing inputs saved as {:?}", r.artifacts);
    }
}
