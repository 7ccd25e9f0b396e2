//! The 16385 x 16385 flight with its RSS bound: `fly` streams a `procedural:size=16385`
//! package through gles3-mid's 64 MiB tile cache, and its peak RSS exceeds the same flight over a 257^2
//! package by at most `budget.cpu_memory_bytes`; the out-of-core bake of 4097^2 .. 16385^2 terrains stays
//! within a fixed working set; `render --lod sat` over the 16385^2 package, its SAT LOD tables baked out of
//! core on the first run, stays within the same bound of the 257^2 run. Heavy (packages of a few hundred MB and 1.4 GB of temporary level files;
//! minutes in release), so ignored (`render_sg_streams_a_package`, a small streamed SG render, is not):
//! `cargo test --release --test cli stream_rss -- --ignored --nocapture`. Needs `/usr/bin/time`.

use std::path::Path;

use super::clipsat;

/// Peak RSS in bytes of `clipsat args` under `/usr/bin/time -v`, or None when it is not installed.
fn peak_rss(args: &[&str]) -> Option<u64> {
    peak_rss_in(args, None)
}

/// gles3-mid's `budget.cpu_memory_bytes`, the bound both flights' terrain-dependent RSS is held to.
fn gles3_mid_cpu_budget() -> u64 {
    clipsat::profile::Profile::load("gles3-mid")
        .expect("profile")
        .budget
        .cpu_memory_bytes
}

/// Bakes `procedural:size={size}` into `dir/p{size}.clipsat`; returns the package's path and the terrain.
fn bake_procedural(dir: &Path, size: u32) -> (std::path::PathBuf, String) {
    let pkg = dir.join(format!("p{size}.clipsat"));
    let terrain = format!("procedural:size={size}");
    let bake = clipsat(&["bake", &terrain, "--out", &pkg.to_string_lossy(), "--json"]);
    assert!(
        bake.status.success(),
        "bake {terrain}: {}",
        String::from_utf8_lossy(&bake.stderr)
    );
    (pkg, terrain)
}

/// [`peak_rss`] with `CLIPSAT_CACHE` set to `cache` when given.
fn peak_rss_in(args: &[&str], cache: Option<&Path>) -> Option<u64> {
    if !Path::new("/usr/bin/time").is_file() {
        eprintln!("skipping: /usr/bin/time is not installed");
        return None;
    }
    let mut cmd = std::process::Command::new("/usr/bin/time");
    cmd.arg("-v").arg(env!("CARGO_BIN_EXE_clipsat")).args(args);
    if let Some(c) = cache {
        cmd.env("CLIPSAT_CACHE", c);
    }
    let o = cmd.output().expect("run /usr/bin/time");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "clipsat {args:?}: {err}");
    let kib = err
        .lines()
        .find_map(|l| l.trim().strip_prefix("Maximum resident set size (kbytes):"))
        .and_then(|v| v.trim().parse::<u64>().ok())
        .expect("a peak RSS line");
    Some(kib * 1024)
}

#[test]
#[ignore = "minutes and a large scratch package: cargo test --release --test cli stream_rss -- --ignored"]
fn fly_16385_streamed_within_the_cpu_budget() {
    let dir = super::scratch_in("cli_stream_rss", "fly");
    let mut peaks = Vec::new();
    for size in [257u32, 16385] {
        let (pkg, terrain) = bake_procedural(&dir, size);
        let p = pkg.to_string_lossy();
        let fly = [
            "fly",
            "--terrain",
            &p,
            "--profile",
            "gles3-mid",
            "--frames",
            "600",
            "--speed",
            "400",
            "--json",
        ];
        let Some(peak) = peak_rss(&fly) else {
            return;
        };
        eprintln!("fly over {terrain}: peak RSS {} MiB", peak >> 20);
        peaks.push(peak);
        let _ = std::fs::remove_file(&pkg);
    }
    let budget = gles3_mid_cpu_budget();
    assert!(
        peaks[1].saturating_sub(peaks[0]) <= budget,
        "16385^2 flight: {} MiB over the 257^2 one, budget {} MiB",
        peaks[1].saturating_sub(peaks[0]) >> 20,
        budget >> 20
    );
}

/// The bake's working set: a few bands of rows and one tile row, a few MB per 1000 samples of width (the
/// resident bake it replaced peaked at 337 MB for 4097^2 and 1.29 GB for 8193^2).
const BAKE_RSS_BOUND: u64 = 64 << 20;

#[test]
#[ignore = "minutes and large scratch files: cargo test --release --test cli stream_rss -- --ignored"]
fn bake_out_of_core_within_a_fixed_working_set() {
    let dir = super::scratch_in("cli_stream_rss", "bake");
    for size in [4097u32, 8193, 16385] {
        let pkg = dir.join(format!("p{size}.clipsat"));
        let p = pkg.to_string_lossy();
        let terrain = format!("procedural:size={size}");
        let Some(peak) = peak_rss(&["bake", &terrain, "--out", &p, "--json"]) else {
            return;
        };
        eprintln!("bake {terrain}: peak RSS {} MiB", peak >> 20);
        let _ = std::fs::remove_file(&pkg);
        assert!(
            peak <= BAKE_RSS_BOUND,
            "bake {terrain}: peak RSS {} MiB over {} MiB",
            peak >> 20,
            BAKE_RSS_BOUND >> 20
        );
        let left: Vec<_> = std::fs::read_dir(&dir)
            .expect("scratch")
            .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
            .filter(|n| n.contains(".level"))
            .collect();
        assert!(left.is_empty(), "temporary level files left: {left:?}");
    }
}

/// `render --lod sat` on gles3-mid over a `procedural:size=16385` package (the large-terrain case): the first
/// run bakes the SAT LOD tables out of core (`bake::lod_stream`, a 1.1 GB cache file), the second reads
/// them through the file's map, then a `fly --lod sat-conservative` reads them within their resident
/// limit; each run's peak RSS exceeds the same run over a 257^2 package by at most
/// `budget.cpu_memory_bytes`. The resident bake it replaced peaked at 849 MB for 8193^2.
#[test]
#[ignore = "minutes and large scratch files: cargo test --release --test cli stream_rss -- --ignored"]
fn sat_lod_16385_within_the_cpu_budget() {
    let dir = super::scratch_in("cli_stream_rss", "render_sat");
    let cache = dir.join("cache");
    let mut peaks = Vec::new();
    for size in [257u32, 16385] {
        let (pkg, terrain) = bake_procedural(&dir, size);
        let p = pkg.to_string_lossy();
        let render = [
            "render",
            "--terrain",
            &p,
            "--size",
            "320x180",
            "--profile",
            "gles3-mid",
            "--lod",
            "sat",
            "--json",
        ];
        // The flight whose table pages grew with the terrain before their resident limit (419 MiB at
        // 16385^2): sat-conservative's edge terms read columns of a fine level's maxima.
        let fly = [
            "fly",
            "--terrain",
            &p,
            "--profile",
            "gles3-mid",
            "--lod",
            "sat-conservative",
            "--frames",
            "600",
            "--speed",
            "400",
            "--json",
        ];
        let mut runs = Vec::new();
        for (run, args) in [
            ("render, baking the tables", &render[..]),
            ("render, tables mapped", &render[..]),
            ("fly --lod sat-conservative", &fly[..]),
        ] {
            let Some(peak) = peak_rss_in(args, Some(&cache)) else {
                return;
            };
            eprintln!("{run} over {terrain}: peak RSS {} MiB", peak >> 20);
            runs.push(peak);
        }
        peaks.push(runs);
        let _ = std::fs::remove_file(&pkg);
    }
    let _ = std::fs::remove_dir_all(&cache);
    let budget = gles3_mid_cpu_budget();
    for (run, (small, large)) in peaks[0].iter().zip(&peaks[1]).enumerate() {
        let over = large.saturating_sub(*small);
        assert!(
            over <= budget,
            "16385^2 run {run} (render, render, fly): {} MiB over the 257^2 one, budget {} MiB",
            over >> 20,
            budget >> 20
        );
    }
}

/// `render --profile desktop --shading sg --scene evening` (visibility: the largest SG tables) streamed
/// over `procedural:size=4097` against 257^2, second runs (the first bakes the tables out of core): the
/// terrain-dependent peak RSS stays within the two shares of desktop's CPU budget that grow with the
/// terrain in this run, the SG inputs' (`CpuSplit::shading`, 123.7 MiB) and the tile cache's (92.8 MiB).
/// The tile cache's share was left out when this test was written (58.9 MiB over then): measured 143 MiB
/// over on 2026-12-04, as the 257^2 run got 66 MiB leaner.
#[test]
#[ignore = "minutes (the horizons of a 1025^2 grid): cargo test --release --test cli stream_rss -- --ignored"]
fn render_sg_streamed_within_its_memory_shares() {
    let dir = super::scratch_in("cli_stream_rss", "sg_rss");
    let cache = dir.join("cache");
    let mut peaks = Vec::new();
    for size in [257u32, 4097] {
        let (pkg, terrain) = bake_procedural(&dir, size);
        let (p, png) = (
            pkg.to_string_lossy().into_owned(),
            dir.join("sg.png").to_string_lossy().into_owned(),
        );
        let args = [
            "render",
            "--terrain",
            &p,
            "--profile",
            "desktop",
            "--shading",
            "sg",
            "--scene",
            "evening",
            "--size",
            "320x180",
            "--json",
            "--out",
            &png,
        ];
        let (Some(_), Some(peak)) = (
            peak_rss_in(&args, Some(&cache)),
            peak_rss_in(&args, Some(&cache)),
        ) else {
            return;
        };
        eprintln!(
            "render --shading sg over {terrain}: peak RSS {} MiB",
            peak >> 20
        );
        peaks.push(peak);
    }
    let split = clipsat::profile::Profile::load("desktop")
        .expect("profile")
        .cpu_split();
    let shares = split.shading + split.tile_cache;
    assert!(
        peaks[1].saturating_sub(peaks[0]) <= shares,
        "4097^2: {} MiB over the 257^2 render, SG and tile cache shares {} MiB",
        peaks[1].saturating_sub(peaks[0]) >> 20,
        shares >> 20
    );
}

/// `render --shading sg` streams a package: its SG tables are baked from the package's own
/// level that fits the profile's shading share (`CpuSplit::shading`; 257^2 fits gles3-mid's at full
/// resolution), read back from their cache file on the second run to the same image, and `--stream`
/// refuses `--reference`, whose CPU reference reads the whole terrain.
#[test]
fn render_sg_streams_a_package() {
    let dir = super::scratch_in("cli_stream_rss", "sg");
    let (pkg, _) = bake_procedural(&dir, 257);
    let (p, png) = (
        pkg.to_string_lossy().into_owned(),
        dir.join("sg.png").to_string_lossy().into_owned(),
    );
    let args = [
        "render",
        "--terrain",
        &p,
        "--profile",
        "gles3-mid",
        "--shading",
        "sg",
        "--size",
        "96x64",
        "--json",
        "--out",
        &png,
    ];
    let run = || {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_clipsat"))
            .args(args)
            .env("CLIPSAT_CACHE", dir.join("cache"))
            .output()
            .expect("run clipsat");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice::<serde_json::Value>(&o.stdout).expect("json")
    };
    let (first, second) = (run(), run());
    assert_eq!(first["streamed"], true, "{first}");
    assert_eq!(first["shading_grid"], serde_json::json!([257, 257, 1]));
    assert_eq!(first["image_hash"], second["image_hash"]);
    let refused = clipsat(&[
        "render",
        "--terrain",
        "procedural:size=65",
        "--stream",
        "--shading",
        "sg",
        "--reference",
    ]);
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("--stream"));
}
