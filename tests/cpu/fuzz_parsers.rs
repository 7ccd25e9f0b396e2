//! Fuzzing in `cargo test`: every parser (PNG, GeoTIFF, .hgt, ASCII grid, raw, profile TOML, scene TOML,
//! terrain package, imagery PNG/JPEG, imagery package, a tile mosaic's list and GDAL VRT) runs its
//! committed corpus, then random mutations of it for [`DEFAULT_SECS`] seconds per target (about 4 s of
//! wall time for the file on 2 cores). No input may panic; a crash writes its input to
//! `tests/fuzz/artifacts/TARGET/` and fails. The targets are the cargo-fuzz targets' bodies
//! (`tests/fuzz/fuzz_targets/targets.rs`); the driver is `tests/fuzz/harness.rs`.
//!
//! A longer run, every target for `CLIPSAT_FUZZ_SECS` seconds (default 120) with seed `CLIPSAT_FUZZ_SEED`:
//! `CLIPSAT_FUZZ_SECS=600 cargo test --release --test cpu fuzz_parsers:: -- --ignored --nocapture`.

#[path = "../fuzz/harness.rs"]
mod harness;
#[path = "../fuzz/fuzz_targets/targets.rs"]
mod targets;

use std::time::Duration;

/// Seconds of mutation per target in the default run.
const DEFAULT_SECS: f64 = 0.5;

/// Longest input per target: big enough for every seed plus growth, small enough to stay fast.
fn max_len(target: &str) -> usize {
    match target {
        "load_hgt_full" => 64,
        _ => 8192,
    }
}

fn seed(target: &str) -> u64 {
    let base = std::env::var("CLIPSAT_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(17);
    clipsat::hash::hash_bytes(target.as_bytes()) ^ base
}

fn body(name: &str) -> targets::Target {
    targets::TARGETS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, f)| *f)
        .unwrap_or_else(|| panic!("no target {name}"))
}

fn run(name: &str, secs: f64) -> harness::Report {
    let r = harness::fuzz(
        name,
        body(name),
        Duration::from_secs_f64(secs),
        seed(name),
        max_len(name),
    );
    eprintln!(
        "fuzz {name}: {} executions, {} crashes, corpus {} + {} new, {} outcomes, slowest input {:.1} ms",
        r.execs,
        r.crashes,
        r.corpus,
        r.added,
        r.outcomes,
        r.slowest.as_secs_f64() * 1e3
    );
    assert!(
        r.crashes == 0,
        "{name}: {} crashing inputs, saved as {:?}; fix each and add a regression test",
        r.crashes,
        r.artifacts
    );
    assert!(
        r.slowest < Duration::from_secs(2),
        "{name}: an input took {:?} (a hang in the making)",
        r.slowest
    );
    r
}

macro_rules! fuzz_tests {
    ($($name:ident),*) => {$(
        #[test]
        fn $name() {
            run(stringify!($name), DEFAULT_SECS);
        }
    )*};
}

fuzz_tests!(
    load_png,
    load_tiff,
    load_hgt,
    load_hgt_full,
    load_asc,
    load_ehdr,
    load_dted,
    load_xyz,
    load_raw,
    parse_profile,
    parse_scene,
    load_package,
    load_imagery,
    load_imagery_package,
    load_mosaic
);

/// The tile mosaic's seeds, a list and a VRT of its two tiles, read: mutations start from a mosaic.
#[test]
fn mosaic_seeds_read() {
    for (path, seed) in harness::corpus("load_mosaic") {
        let out = targets::load_mosaic(&seed);
        assert!(out.starts_with("ok"), "{}: {out}", path.display());
    }
}

/// Every target has a corpus folder and a test above (a new target cannot be left out of the run).
#[test]
fn every_target_has_a_corpus() {
    for (name, _) in targets::TARGETS {
        assert!(
            !harness::corpus(name).is_empty(),
            "target {name} has no corpus in tests/fuzz/corpus/{name}"
        );
    }
}

/// The long run: every target for `CLIPSAT_FUZZ_SECS` seconds, two at a time; prints a table.
#[test]
#[ignore = "minutes: CLIPSAT_FUZZ_SECS=600 cargo test --release --test cpu fuzz_parsers:: -- --ignored --nocapture"]
fn fuzz_every_parser_long() {
    let secs: f64 = std::env::var("CLIPSAT_FUZZ_SECS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(120.0);
    let names: Vec<&str> = targets::TARGETS.iter().map(|(n, _)| *n).collect();
    let mut rows = Vec::new();
    for pair in names.chunks(2) {
        let done: Vec<_> = std::thread::scope(|s| {
            let hs: Vec<_> = pair
                .iter()
                .map(|n| s.spawn(move || (*n, run(n, secs))))
                .collect();
            hs.into_iter().filter_map(|h| h.join().ok()).collect()
        });
        rows.extend(done);
    }
    eprintln!("| target | seconds | executions | crashes | corpus + new | outcomes |");
    eprintln!("|---|---|---|---|---|---|");
    for (n, r) in rows {
        eprintln!(
            "| {n} | {secs} | {} | {} | {} + {} | {} |",
            r.execs, r.crashes, r.corpus, r.added, r.outcomes
        );
    }
}
