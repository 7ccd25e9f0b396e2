//! Determinism: outputs depend on the inputs only, not on llvmpipe's thread count (`LP_NUM_THREADS`), on
//! other load on the machine, or on the run. The binary runs as a subprocess so each run gets its own
//! environment and its own GL context.
//!
//! Debug against release is pinned elsewhere: `frame_hash_sequence_is_pinned` in tests/cpu/fly_paths.rs holds a
//! golden frame-hash sequence that `cargo test --release --test cpu fly_paths::` must reproduce.

use std::process::Output;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

fn clipsat(args: &[&str], env: &[(&str, &str)]) -> Output {
    super::clipsat_env(args, env)
}

fn json(out: &Output) -> serde_json::Value {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "clipsat failed: {err}");
    assert!(!err.contains("panicked"), "{err}");
    serde_json::from_slice(&out.stdout).expect("stdout is JSON")
}

fn field(j: &serde_json::Value, key: &str) -> String {
    j[key]
        .as_str()
        .unwrap_or_else(|| panic!("no `{key}` in {j}"))
        .to_owned()
}

const FLY: [&str; 12] = [
    "fly",
    "--profile",
    "gles3-low",
    "--terrain",
    "procedural:size=257",
    "--path",
    "teleport:25",
    "--frames",
    "100",
    "--speed",
    "150",
    "--json",
];

/// The per-frame hashes of a `fly` run (through `--hash-out`) and its run hash.
fn fly_hashes(tag: &str, env: &[(&str, &str)]) -> (String, String) {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("determinism");
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let file = dir.join(format!("{tag}.txt"));
    let f = file.to_string_lossy();
    let mut args = FLY.to_vec();
    args.extend(["--hash-out", &f]);
    let j = json(&clipsat(&args, env));
    let text = std::fs::read_to_string(&file).expect("hash file");
    (text, field(&j, "run_hash"))
}

const RENDER: [&str; 12] = [
    "render",
    "--profile",
    "gles3-low",
    "--terrain",
    "procedural:size=257",
    "--size",
    "160x90",
    "--camera",
    "-500,-500,900",
    "--look-at",
    "3000,3000,0",
    "--json",
];

fn render_hash(tag: &str, env: &[(&str, &str)]) -> String {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("determinism");
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let png = dir.join(format!("{tag}.png"));
    let p = png.to_string_lossy();
    let mut args = RENDER.to_vec();
    args.extend(["--out", &p]);
    field(&json(&clipsat(&args, env)), "image_hash")
}

#[test]
fn the_same_fly_through_twice_gives_the_same_frame_hashes() {
    let a = fly_hashes("twice-a", &[]);
    let b = fly_hashes("twice-b", &[]);
    assert_eq!(a, b);
    // And `--check` agrees with it.
    let file = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("determinism/twice-a.txt");
    let f = file.to_string_lossy();
    let mut args = FLY.to_vec();
    args.extend(["--check", &f]);
    json(&clipsat(&args, &[]));
}

#[test]
fn llvmpipe_thread_count_changes_nothing() {
    let one = render_hash("lp1", &[("LP_NUM_THREADS", "1")]);
    let four = render_hash("lp4", &[("LP_NUM_THREADS", "4")]);
    assert_eq!(one, four, "image hash with LP_NUM_THREADS=1 vs 4");
    // The CPU plan does not use llvmpipe, but the environment must not leak into it either.
    let one = fly_hashes("fly-lp1", &[("LP_NUM_THREADS", "1")]);
    let four = fly_hashes("fly-lp4", &[("LP_NUM_THREADS", "4")]);
    assert_eq!(one, four, "frame hashes with LP_NUM_THREADS=1 vs 4");
    eprintln!("image {one:?} / frames {}", four.1);
}

#[test]
fn concurrent_cpu_load_changes_nothing() {
    let quiet_image = render_hash("quiet", &[("LP_NUM_THREADS", "4")]);
    let quiet_fly = fly_hashes("quiet", &[]);

    // Busy threads compete with the render and the flight for the CPU (timing changes, results must not).
    let stop = Arc::new(AtomicBool::new(false));
    let busy: Vec<_> = (0..4)
        .map(|i| {
            let stop = Arc::clone(&stop);
            std::thread::spawn(move || {
                let mut x = 0x9E37_79B9_u64 + i;
                while !stop.load(Ordering::Relaxed) {
                    for _ in 0..10_000 {
                        x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
                    }
                    std::hint::black_box(x);
                }
            })
        })
        .collect();
    let loaded_image = render_hash("loaded", &[("LP_NUM_THREADS", "4")]);
    let loaded_fly = fly_hashes("loaded", &[]);
    stop.store(true, Ordering::Relaxed);
    for t in busy {
        t.join().expect("busy thread");
    }
    assert_eq!(quiet_image, loaded_image, "image hash under load");
    assert_eq!(quiet_fly, loaded_fly, "frame hashes under load");
}

/// An emptied cache folder `determinism-<name>` in the tests' scratch space (path and text), and the
/// path of a PNG `<name>.png` beside it for `render --out`.
fn fresh_cache(name: &str) -> (std::path::PathBuf, String, String) {
    let tmp = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    let cache = tmp.join(format!("determinism-{name}"));
    let _ = std::fs::remove_dir_all(&cache);
    let dir = tmp.join("determinism");
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let text = cache.to_string_lossy().into_owned();
    let png = dir
        .join(format!("{name}.png"))
        .to_string_lossy()
        .into_owned();
    (cache, text, png)
}

/// `render` streams a plain source by default, from a package baked into the cache on first use: the
/// first run into an empty `CLIPSAT_CACHE` bakes, the second finds the bake, and both draw the same image;
/// the frame hashes of `fly` likewise. `--resident` loads the terrain whole instead.
#[test]
fn a_clean_and_a_warm_cache_give_the_same_hashes() {
    let (cache, c, p) = fresh_cache("cache");
    let env = [("CLIPSAT_CACHE", c.as_str())];
    let mut args = RENDER.to_vec();
    args.extend(["--out", &p]);
    let clean = json(&clipsat(&args, &env));
    let baked = std::fs::read_dir(&cache).map_or(0, |d| {
        d.filter_map(std::result::Result::ok)
            .filter(|e| e.path().extension().is_some_and(|x| x == "clipsat"))
            .count()
    });
    assert_eq!(baked, 1, "the first run bakes one package into the cache");
    let warm = json(&clipsat(&args, &env));
    assert_eq!(clean["streamed"], true, "{clean}");
    assert_eq!(warm["streamed"], true, "{warm}");
    assert_eq!(field(&clean, "image_hash"), field(&warm, "image_hash"));
    assert_eq!(
        fly_hashes("cache-clean", &env).1,
        fly_hashes("cache-warm", &env).1
    );
    args.push("--resident");
    let resident = json(&clipsat(&args, &env));
    assert_eq!(resident["streamed"], false, "{resident}");
    let _ = std::fs::remove_dir_all(&cache);
}

/// A cached package the build cannot read (an older format, or damaged) is baked again, not an error:
/// the file under the cache's name with its format version set back to 1, then cut short, each time
/// rebaked to the same image. (A new format also gets a new cache name, `terrain-<key>-v<format>`.)
#[test]
fn a_stale_cached_package_is_baked_again() {
    let (cache, c, p) = fresh_cache("stale");
    let env = [("CLIPSAT_CACHE", c.as_str())];
    let mut args = RENDER.to_vec();
    args.extend(["--out", &p]);
    let first = field(&json(&clipsat(&args, &env)), "image_hash");
    let package = std::fs::read_dir(&cache)
        .expect("cache folder")
        .filter_map(std::result::Result::ok)
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|x| x == "clipsat"))
        .expect("a cached package");
    let good = std::fs::read(&package).expect("read the package");
    // magic "CLIPSAT\0", then the version (u32, little-endian).
    let mut old = good.clone();
    old[8..12].copy_from_slice(&1u32.to_le_bytes());
    let cut = good[..good.len() / 2].to_vec();
    for (what, bytes) in [("version 1", old), ("truncated", cut)] {
        std::fs::write(&package, bytes).expect("write the stale package");
        let j = json(&clipsat(&args, &env));
        assert_eq!(j["streamed"], true, "{what}: {j}");
        assert_eq!(
            field(&j, "image_hash"),
            first,
            "{what}: rebaked to the same image"
        );
        assert_eq!(
            std::fs::read(&package).expect("read the rebaked package"),
            good,
            "{what}: the rebake writes the same bytes"
        );
    }
    let _ = std::fs::remove_dir_all(&cache);
}

/// Concurrent first uses of one terrain in an empty cache are safe: each process bakes the package (and
/// its SAT LOD tables) under its own temporary name and renames it into place, so three renders started
/// together all succeed, stream, and draw the same image, and no temporary file is left.
#[test]
fn concurrent_first_bakes_of_one_terrain_agree() {
    let cache = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("determinism-concurrent");
    let _ = std::fs::remove_dir_all(&cache);
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("determinism");
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let children: Vec<_> = (0..3)
        .map(|i| {
            let png = dir.join(format!("concurrent-{i}.png"));
            std::process::Command::new(env!("CARGO_BIN_EXE_clipsat"))
                .args(RENDER)
                .args(["--lod", "sat", "--out"])
                .arg(png)
                .env("CLIPSAT_CACHE", &cache)
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .expect("start clipsat")
        })
        .collect();
    let hashes: Vec<String> = children
        .into_iter()
        .map(|c| {
            let j = json(&c.wait_with_output().expect("clipsat runs"));
            assert_eq!(j["streamed"], true, "{j}");
            field(&j, "image_hash")
        })
        .collect();
    assert!(hashes.windows(2).all(|w| w[0] == w[1]), "{hashes:?}");
    let leftovers: Vec<_> = std::fs::read_dir(&cache)
        .expect("cache folder")
        .filter_map(std::result::Result::ok)
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("tmp") || n.contains("records"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
    let _ = std::fs::remove_dir_all(&cache);
}
