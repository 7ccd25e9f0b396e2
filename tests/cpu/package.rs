//! Stage 1b, the package: round trips within `--max-error` on every shared terrain, damaged packages as
//! errors naming the tile, and the tile cache under a sample budget.

#![expect(
    clippy::cast_possible_truncation,
    reason = "test offsets and indices of small packages fit usize"
)]

use std::path::{Path, PathBuf};

use clipsat::package::{self, BakeOptions, CodecKind, Package, TileCache};
use clipsat::source::Heightmap;
use clipsat::source::{self, LoadOptions};
use clipsat::Error;

use super::shared;

/// Every shared terrain, with the spacing a PNG needs and the default bound the bake must pick.
const SHARED: [(&str, Option<f32>, f64); 8] = [
    ("ps_height_1k.png", Some(160.0), 0.05),
    ("srtm_bigtujunga30m_utm11.tif", None, 0.5),
    ("srtm_bigtujunga30m_utm11_u16dm.png", Some(30.0), 0.5),
    ("n07_w006_3arc_v2.tif", None, 0.5),
    ("n07_w006_3arc_v2_u16dm.png", Some(92.0), 0.5),
    ("N57E011.hgt", None, 0.5),
    (
        "lidar_pkg_dem_1m_400x400.tif",
        None,
        package::write::FLOAT_MAX_ERROR,
    ),
    ("aletsch_200m.tif", None, package::write::FLOAT_MAX_ERROR),
];

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("clipsat-package-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir.join(name)
}

fn bake(hm: &Heightmap, out: &Path, opts: &BakeOptions) -> package::BakeReport {
    package::bake(hm, out, opts, clipsat::Progress::default()).expect("bake")
}

/// Decodes the package and checks every level-0 sample within the bound (plus one f32 rounding).
fn assert_round_trip(name: &str, hm: &Heightmap, path: &Path, bound: f64) {
    let back = Package::open(path)
        .and_then(|p| p.to_heightmap())
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_eq!((back.width(), back.height()), (hm.width(), hm.height()));
    assert_eq!(back.spacing(), hm.spacing());
    assert_eq!(back.origin(), hm.origin());
    for (k, (&a, &b)) in back.heights().iter().zip(hm.heights()).enumerate() {
        let slack = f64::from(f32::EPSILON * b.abs().max(1.0));
        let e = (f64::from(a) - f64::from(b)).abs();
        assert!(
            e <= bound + slack,
            "{name}: sample {k} decoded {a}, source {b}: error {e} over {bound}"
        );
    }
}

/// The shared terrains the default test run bakes: one of integer metres (lossless, read as a TIFF and as
/// a PNG), one of float centimetres and one of float decimetres; `--ignored` bakes all eight (about 20 s
/// of CPU in a test build).
const QUICK: [&str; 4] = [
    "srtm_bigtujunga30m_utm11.tif",
    "srtm_bigtujunga30m_utm11_u16dm.png",
    "lidar_pkg_dem_1m_400x400.tif",
    "aletsch_200m.tif",
];

#[test]
fn shared_terrains_round_trip_within_the_default_bound() {
    round_trips(false);
}

#[test]
#[ignore = "every shared terrain, about 20 s: cargo test --test cpu package:: -- --ignored"]
fn every_shared_terrain_round_trips_within_the_default_bound() {
    round_trips(true);
}

fn round_trips(all: bool) {
    for (name, spacing, bound) in SHARED {
        if !all && !QUICK.contains(&name) {
            continue;
        }
        let Some(hm) = shared(name, spacing) else {
            continue;
        };
        assert_eq!(package::default_max_error(&hm), bound, "{name}");
        let out = temp(&format!("{name}.clipsat"));
        let r = bake(&hm, &out, &BakeOptions::default());
        // The bound is exact in metres; the decoded f32 adds at most half an ulp of the height.
        let (lo, hi) = hm.range();
        let slack = f64::from(f32::EPSILON * lo.abs().max(hi.abs()));
        assert!(r.max_error <= bound + slack, "{name}: {r:?}");
        if bound >= 0.05 {
            // Lattice data at half its step: lossless, every decoded height the source's own.
            assert_eq!(r.max_error, 0.0, "{name}: lossless");
        }
        let per_level: u64 = r.level_bytes.iter().map(|l| l.bytes).sum();
        assert_eq!(per_level, r.tile_bytes, "{name}: the levels' bytes add up");
        assert_round_trip(name, &hm, &out, bound);
        let _ = std::fs::remove_file(&out);
    }
}

#[test]
fn lossy_bounds_hold_for_every_codec() {
    let hm = synthetic(200, 131);
    for codec in CodecKind::ALL {
        for max_error in [0.01, 0.5, 2.0] {
            let out = temp(&format!("lossy-{}-{max_error}.clipsat", codec.name()));
            let opts = BakeOptions {
                max_error: Some(max_error),
                codec,
                tile: 32,
                zstd_level: 3,
                ..BakeOptions::default()
            };
            let r = bake(&hm, &out, &opts);
            assert!(
                r.max_error <= max_error + 1e-4,
                "{codec:?} {max_error}: {r:?}"
            );
            assert_round_trip("procedural", &hm, &out, max_error);
            let _ = std::fs::remove_file(&out);
        }
    }
}

/// A non-square, non-2^k+1 float terrain with relief at several scales.
fn synthetic(w: u32, h: u32) -> Heightmap {
    let heights = (0..w * h)
        .map(|k| {
            let (x, y) = (f64::from(k % w), f64::from(k / w));
            let z =
                900.0 + 300.0 * (x / 23.0).sin() * (y / 17.0).cos() + 7.3 * ((x * y) / 5.0).sin();
            #[expect(clippy::cast_possible_truncation, reason = "heights are f32")]
            let z = z as f32;
            z
        })
        .collect();
    Heightmap::new(Path::new("<synthetic>"), w, h, 25.0, heights)
        .expect("terrain")
        .with_origin(1000.0, -500.0)
}

/// A small package and its bytes, for damaging.
fn small_package(name: &str, (w, h): (u32, u32)) -> (PathBuf, Vec<u8>, Heightmap) {
    let hm = synthetic(w, h);
    let out = temp(name);
    let opts = BakeOptions {
        tile: 16,
        zstd_level: 3,
        ..BakeOptions::default()
    };
    bake(&hm, &out, &opts);
    let bytes = std::fs::read(&out).expect("read back");
    (out, bytes, hm)
}

fn format_reason(r: clipsat::Result<impl std::fmt::Debug>) -> String {
    match r {
        Err(Error::Format { reason, .. }) => reason,
        other => panic!("expected a format error, got {other:?}"),
    }
}

#[test]
fn damaged_packages_are_errors_naming_the_tile() {
    let (path, good, _) = small_package("damaged.clipsat", (97, 75));
    let header = Package::open(&path).expect("good package").header().clone();
    let write = |bytes: &[u8]| std::fs::write(&path, bytes).expect("write");

    // Truncated: the tile table points past the end; named by tile.
    for cut in [good.len() - 1, good.len() / 2] {
        write(&good[..cut]);
        let reason = format_reason(Package::open(&path));
        assert!(reason.contains("tile ("), "{reason}");
    }
    // Truncated inside the header, empty, or not a package.
    for bytes in [&good[..40], &good[..0], b"GIF89a not a terrain".as_slice()] {
        write(bytes);
        assert!(Package::open(&path).is_err());
    }
    // A flipped byte in the header: its checksum.
    let mut bad = good.clone();
    bad[20] ^= 0x10;
    write(&bad);
    assert!(format_reason(Package::open(&path)).contains("checksum"));
    // A wrong version; an older one (version 1 without the SAT LOD tables, version 2 with every
    // level's records stored as one stream, version 3 predicting from the coarser level alone) asks
    // for a new bake.
    let mut bad = good.clone();
    bad[8] = 9;
    write(&bad);
    assert!(format_reason(Package::open(&path)).contains("version"));
    for old in [1u8, 2, 3] {
        bad[8] = old;
        write(&bad);
        let reason = format_reason(Package::open(&path));
        assert!(
            reason.contains(&format!("version {old}")) && reason.contains("bake it again"),
            "{reason}"
        );
    }

    // A flipped byte in each of a few tiles: the file opens, decoding names the tile.
    for (level, t) in [(0usize, (0u32, 0u32)), (0, (3, 2)), (2, (1, 0))] {
        let e = header.tile(level, t.0, t.1).expect("tile exists");
        for at in [0u64, u64::from(e.len) / 2, u64::from(e.len) - 1] {
            let mut bad = good.clone();
            bad[(e.offset + at) as usize] ^= 0x04;
            write(&bad);
            let p = Package::open(&path).expect("the header is intact");
            let reason = format_reason(p.to_heightmap());
            let name = format!("level {level} tile ({}, {})", t.0, t.1);
            assert!(reason.contains(&name), "{reason} should name {name}");
            // The LOD tables' sweeps over the heights (band by band, a band decoded while the one
            // before is worked) name the same tile.
            let dir = path.with_extension("lod-heights");
            let _ = std::fs::remove_dir_all(&dir);
            let params = clipsat::bake::BakeParams {
                p: 8,
                levels: 6,
                synth_levels: 0,
                g0: 10.0,
            };
            let reason = format_reason(clipsat::package::lod_cache::bake_lod_package(
                &p,
                &params,
                &dir,
                clipsat::Progress::default(),
            ));
            assert!(reason.contains(&name), "{reason} should name {name}");
            let _ = std::fs::remove_dir_all(&dir);
        }
    }
    // A flipped byte in a SAT LOD table tile: the heights decode; the tables' build names the tile.
    let lod = header.lod.as_ref().expect("a package has its LOD tables");
    let params = clipsat::bake::BakeParams {
        p: lod.p,
        levels: 6,
        synth_levels: 0,
        g0: 10.0,
    };
    // Level 1's records are derived from the heights (format 3): no tiles to damage.
    assert_eq!(lod.derived, 1);
    assert!(!lod.level(1).expect("level 1").stored);
    for (k, t, at) in [(2u32, (0u32, 0u32), 2u64), (2, (1, 1), 0), (3, (0, 0), 2)] {
        let lv = lod.level(k).expect("level");
        let e = lod.tiles[lv.first_tile + (t.1 * lv.grid.tiles_x + t.0) as usize];
        let mut bad = good.clone();
        // Inside the mean stream, or the first stream's length.
        bad[(e.offset + u64::from(e.len) * at / 3) as usize] ^= 0x20;
        write(&bad);
        let p = Package::open(&path).expect("the header is intact");
        assert!(p.to_heightmap().is_ok(), "the heights are intact");
        let dir = path.with_extension(format!("lod{k}"));
        let _ = std::fs::remove_dir_all(&dir);
        let reason = format_reason(clipsat::package::lod_cache::bake_lod_package(
            &p,
            &params,
            &dir,
            clipsat::Progress::default(),
        ));
        let name = format!("LOD table level {k} tile ({}, {})", t.0, t.1);
        assert!(reason.contains(&name), "{reason} should name {name}");
        let _ = std::fs::remove_dir_all(&dir);
    }
    write(&good);
    assert!(Package::open(&path).and_then(|p| p.to_heightmap()).is_ok());
    let _ = std::fs::remove_file(&path);
}

#[test]
fn cache_decodes_under_a_budget_and_matches_the_full_decode() {
    let (path, _, _) = small_package("cache.clipsat", (300, 211));
    let pkg = Package::open(&path).expect("open");
    let full = pkg.decode_level0().expect("full decode");
    let (w, h) = (pkg.header().width, pkg.header().height);
    // 9 slots per level and a few more: far smaller than the terrain.
    let levels = pkg.header().levels.len() as u64;
    let split = package::CacheSplit::plan(pkg.header(), u64::MAX);
    // A budget larger than the package holds one slot per tile, no more.
    assert_eq!(split.slot_count, pkg.header().tiles.len() as u64);
    let budget_bytes =
        split.header + split.map + split.decoder + (9 * levels + 4) * (16 * 16 * 4 + 64);
    let mut cache = TileCache::new(pkg, budget_bytes, "test").expect("cache");
    // One tile per frame at most (16 x 16 = 256 samples): fetches are refused, never half-done.
    let mut frames = 0;
    loop {
        cache.begin_frame();
        let mut budget = 256u64;
        frames += 1;
        if cache
            .ensure_rect(0, (40, 40, 56, 56), &mut budget)
            .expect("decode")
        {
            break;
        }
        assert!(frames < 100, "never became resident");
    }
    assert!(
        frames > 1,
        "a budget of one tile cannot fetch a tile and its parents in one frame"
    );
    for j in 40..56i64 {
        for i in 40..56i64 {
            let k = cache.units(0, i, j).expect("resident");
            assert_eq!(k, full[(j * i64::from(w) + i) as usize], "({i}, {j})");
        }
    }
    // Everything, frame by frame through a cache smaller than the terrain: every sample equals the full
    // decode while resident.
    for ty in 0..h.div_ceil(16) {
        for tx in 0..w.div_ceil(16) {
            cache.begin_frame();
            let mut budget = u64::MAX;
            assert!(cache.fetch(0, tx, ty, &mut budget).expect("fetch"));
            let tile = cache.tile(0, tx, ty).expect("resident");
            let tw = 16.min(w - tx * 16) as usize;
            for (k, &v) in tile.iter().enumerate() {
                let (i, j) = (tx as usize * 16 + k % tw, ty as usize * 16 + k / tw);
                assert_eq!(v, full[j * w as usize + i]);
            }
        }
    }
    assert!(
        cache.stats().evictions > 0,
        "the cache is smaller than the terrain"
    );
    // Too small a budget is a config error naming the field.
    let pkg = Package::open(&path).expect("open");
    match TileCache::new(pkg, 1000, "tiny") {
        Err(Error::Config { field, .. }) => assert_eq!(field, "budget.cpu_memory_bytes"),
        other => panic!("expected a config error, got {other:?}"),
    }
    let _ = std::fs::remove_file(&path);
}

#[test]
fn cli_bakes_a_package_and_flies_it_streamed() {
    let exe = env!("CARGO_BIN_EXE_clipsat");
    let out = temp("cli.clipsat");
    let run = |args: &[&str]| {
        let o = std::process::Command::new(exe)
            .args(args)
            .output()
            .expect("run clipsat");
        assert!(
            o.status.success(),
            "clipsat {args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        serde_json::from_slice::<serde_json::Value>(&o.stdout).expect("json")
    };
    let path = out.to_str().expect("utf-8 temp path");
    let bake = run(&["bake", "procedural:size=257", "--out", path, "--json"]);
    assert!(
        bake["max_error"].as_f64().expect("max_error")
            <= bake["max_error_bound"].as_f64().expect("bound") + 1e-3
    );
    let info = run(&["info", path, "--json"]);
    assert_eq!(info["width"], 257);
    assert!(
        info["profiles"][0]["tile_cache"]["slot_count"]
            .as_u64()
            .expect("slots")
            > 0
    );
    let fly = run(&[
        "fly",
        "--terrain",
        path,
        "--profile",
        "gles3-low",
        "--frames",
        "200",
        "--speed",
        "300",
        "--json",
    ]);
    assert_eq!(fly["frames_over_budget"], 0);
    assert_eq!(fly["constraint_violations"], 0);
    let budget = fly["budget"].as_u64().expect("budget");
    assert!(
        fly["stream"]["max_fill_plus_decode_samples"]
            .as_u64()
            .expect("max")
            <= budget
    );
    assert!(
        fly["stream"]["tile_cache"]["stats"]["decoded"]
            .as_u64()
            .expect("decoded")
            > 0
    );
    // A damaged package fails the command with the tile named, exit status 2.
    let mut bytes = std::fs::read(&out).expect("read");
    // The last height tile's bytes (the SAT LOD records follow it; `fly` reads no table here).
    let header = Package::open(&out).expect("open").header().clone();
    let tile = header.tiles.iter().max_by_key(|t| t.offset).expect("tiles");
    let last = (tile.offset + u64::from(tile.len)) as usize - 5;
    bytes[last] ^= 0x20;
    std::fs::write(&out, &bytes).expect("write");
    let o = std::process::Command::new(exe)
        .args([
            "fly",
            "--terrain",
            path,
            "--profile",
            "gles3-low",
            "--frames",
            "50",
            "--json",
        ])
        .output()
        .expect("run clipsat");
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("tile (") && err.contains("checksum"), "{err}");
    let _ = std::fs::remove_file(&out);
}

/// The out-of-core bake writes the same bytes whichever way its source is read (a TIFF's strips or
/// tiles, a PNG's rows, a terrain loaded whole) and from one run to the next: the height tiles of each
/// package pinned for the shared terrains and procedural terrains under several options (odd tile
/// sides, every codec, lossy bounds). The pins are the CRC-32 over the height tiles' payloads and their
/// length, re-pinned at format 4 (the tiles were pinned at format 1, e896be5, against the resident bake
/// the out-of-core one replaced, and kept through format 3).
#[test]
fn out_of_core_bake_is_byte_identical_to_the_resident_bake() {
    byte_pins(false);
}

#[test]
#[ignore = "every shared terrain, about 25 s: cargo test --test cpu package:: -- --ignored"]
fn out_of_core_bake_is_byte_identical_on_every_shared_terrain() {
    byte_pins(true);
}

fn byte_pins(all: bool) {
    let pins_seen = std::cell::RefCell::new(Vec::new());
    let check = |name: &str, out: &Path, (crc, len): (u32, usize)| {
        let bytes = std::fs::read(out).expect("read back");
        let header = Package::open(out).expect("open").header().clone();
        let pyramid = header.pyramid_bytes() as usize;
        let start = header.byte_len();
        let payloads = &bytes[start..start + pyramid];
        let got = (crc32fast::hash(payloads), pyramid);
        if got != (crc, len) {
            pins_seen
                .borrow_mut()
                .push(format!("{name}: (0x{:08x}, {})", got.0, got.1));
        }
        let _ = std::fs::remove_file(out);
    };
    let shared_pins: [(&str, Option<f32>, (u32, usize)); 8] = [
        ("ps_height_1k.png", Some(160.0), (0x3949_ee31, 1_488_400)),
        ("srtm_bigtujunga30m_utm11.tif", None, (0x86e0_c1d3, 353_652)),
        (
            "srtm_bigtujunga30m_utm11_u16dm.png",
            Some(30.0),
            (0x86e0_c1d3, 353_652),
        ),
        ("n07_w006_3arc_v2.tif", None, (0x8a2c_9a90, 674_268)),
        (
            "n07_w006_3arc_v2_u16dm.png",
            Some(92.0),
            (0x8a2c_9a90, 674_268),
        ),
        ("N57E011.hgt", None, (0x99bc_5363, 106_877)),
        ("lidar_pkg_dem_1m_400x400.tif", None, (0x1953_0c34, 77_661)),
        ("aletsch_200m.tif", None, (0x14c9_400b, 249_185)),
    ];
    for (name, spacing, pin) in shared_pins {
        if !all && !QUICK.contains(&name) {
            continue;
        }
        let Some(hm) = shared(name, spacing) else {
            continue;
        };
        let out = temp(&format!("pin-{name}.clipsat"));
        if name.ends_with(".tif") || name.ends_with(".png") {
            // Through the bake's own readers: a row of strips or tiles, or a PNG row, at a time.
            let opts = LoadOptions {
                spacing,
                ..LoadOptions::default()
            };
            let mut rows =
                source::open_rows(&clipsat::data_dir().join(name), &opts).expect("open rows");
            let bar = clipsat::Progress::default();
            package::bake_source(&mut *rows, &out, &BakeOptions::default(), bar)
                .expect("bake rows");
        } else {
            bake(&hm, &out, &BakeOptions::default());
        }
        check(name, &out, pin);
    }
    let procedural = |size: u32, seed: u64| {
        source::procedural::Rows::new(&source::procedural::ProceduralParams {
            seed,
            size,
            spacing: 30.0,
        })
        .expect("procedural")
    };
    let opts = |codec: CodecKind, tile: u32, zstd_level: i32, max_error: Option<f64>| BakeOptions {
        max_error,
        codec,
        tile,
        zstd_level,
        ..BakeOptions::default()
    };
    let zstd19 = package::write::DEFAULT_ZSTD_LEVEL;
    let cases = [
        (
            "257",
            257,
            1,
            opts(CodecKind::Zstd, 64, zstd19, None),
            (0x4d7e_b2e4, 120_063),
        ),
        (
            "1025 lz4",
            1025,
            7,
            opts(CodecKind::Lz4, 64, zstd19, Some(0.5)),
            (0xfd4a_7919, 839_086),
        ),
        (
            "257 rans 2 m",
            257,
            3,
            opts(CodecKind::Rans, 32, zstd19, Some(2.0)),
            (0x9cd7_9058, 20_748),
        ),
        (
            "257 tile 16",
            257,
            1,
            opts(CodecKind::Zstd, 16, 3, Some(2.0)),
            (0xfb96_bc05, 46_139),
        ),
        (
            "513 tile 6",
            513,
            1,
            opts(CodecKind::Zstd, 6, zstd19, Some(0.01)),
            (0x590e_c403, 543_065),
        ),
    ];
    for (name, size, seed, o, pin) in cases {
        if !all && size > 513 {
            continue;
        }
        let out = temp(&format!("pin-{size}-{}.clipsat", o.tile));
        package::bake_source(
            &mut procedural(size, seed),
            &out,
            &o,
            clipsat::Progress::default(),
        )
        .expect("bake");
        check(name, &out, pin);
    }
    // The spilled levels are temporary files beside the package, gone after the bake.
    let dir = temp("x").parent().expect("temp dir").to_path_buf();
    let left: Vec<_> = std::fs::read_dir(&dir)
        .expect("temp dir")
        .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
        .filter(|n| n.starts_with("pin-") && n.contains(".level"))
        .collect();
    assert!(left.is_empty(), "temporary level files left: {left:?}");
    let seen = pins_seen.borrow();
    assert!(
        seen.is_empty(),
        "package bytes differ from the pins:\n{}",
        seen.join("\n")
    );
}

/// A raw file baked a band at a time (positioned reads) gives the package of the same file loaded whole.
#[test]
fn raw_files_bake_streamed_as_loaded() {
    let hm = synthetic(203, 131);
    for format in [source::RawFormat::F32, source::RawFormat::U16] {
        let (ext, bytes): (&str, Vec<u8>) = match format {
            source::RawFormat::F32 => (
                "f32",
                hm.heights().iter().flat_map(|h| h.to_le_bytes()).collect(),
            ),
            source::RawFormat::U16 => (
                "r16",
                hm.heights()
                    .iter()
                    .flat_map(|&h| ((h * 10.0) as u16).to_le_bytes())
                    .collect(),
            ),
        };
        let raw = temp(&format!("stream.{ext}"));
        std::fs::write(&raw, bytes).expect("write raw");
        let opts = LoadOptions {
            raw: Some(source::RawLayout {
                width: hm.width(),
                height: hm.height(),
                format,
            }),
            ..LoadOptions::default()
        };
        let (a, b) = (
            temp(&format!("stream-{ext}.clipsat")),
            temp(&format!("whole-{ext}.clipsat")),
        );
        let mut rows = source::open_rows(&raw, &opts).expect("open rows");
        let bar = clipsat::Progress::default();
        let ra = package::bake_source(&mut *rows, &a, &BakeOptions::default(), bar).expect("bake");
        let whole = source::load(&raw, &opts).expect("load");
        let rb = bake(&whole, &b, &BakeOptions::default());
        assert_eq!(ra, rb, "{ext}");
        assert_eq!(
            std::fs::read(&a).expect("a"),
            std::fs::read(&b).expect("b"),
            "{ext}"
        );
        for p in [raw, a, b] {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// The SAT LOD tables of a package, built from the records the package stores (`package::lod_bake`), or
/// baked out of core from the heights of a package without them (`bake::lod_stream`: bands of tiles,
/// rows written in place), are the bytes of the cache file baked from the decoded pyramid in memory, but
/// for the key (a package's tables are keyed by its header, a terrain's by its heights) and so the
/// trailing checksum: odd sizes, several bands, more data levels than the package has, and a flat
/// terrain (no tables).
#[test]
fn lod_tables_baked_out_of_core_match_the_resident_bake() {
    use clipsat::bake::{self, BakeParams, CacheOutcome};
    let flat =
        Heightmap::new(Path::new("<flat>"), 40, 23, 10.0, vec![12.5; 40 * 23]).expect("flat");
    let cases = [
        ("lod-a.clipsat", synthetic(70, 45), 16, 6),
        ("lod-b.clipsat", synthetic(33, 97), 16, 9),
        ("lod-c.clipsat", synthetic(129, 129), 32, 5),
        ("lod-d.clipsat", flat, 16, 4),
    ];
    for (name, hm, tile, levels) in cases {
        let out = temp(name);
        let opts = BakeOptions {
            tile,
            zstd_level: 3,
            ..BakeOptions::default()
        };
        bake(&hm, &out, &opts);
        let pkg = Package::open(&out).expect("open");
        let params = BakeParams {
            p: bake::lod_tables::P,
            levels,
            synth_levels: 0,
            g0: 25.0,
        };
        let dir = out.with_extension("lod");
        let _ = std::fs::remove_dir_all(&dir);
        let (streamed, o) =
            package::lod_cache::bake_lod_package(&pkg, &params, &dir, clipsat::Progress::default())
                .expect("streamed");
        assert_eq!(o, CacheOutcome::Baked, "{name}");
        assert!(streamed.is_mapped(), "{name}: read back through the map");
        let file = bake::cache_path(&dir, package::lod_cache::package_cache_key(&pkg, &params));
        let a = std::fs::read(&file).expect("streamed file");
        // In memory from the decoded package, written by the resident path.
        let (terrain, pyramid) = (
            pkg.to_heightmap().expect("decode"),
            pkg.to_pyramid().expect("pyr"),
        );
        let dir_b = out.with_extension("lodb");
        let _ = std::fs::remove_dir_all(&dir_b);
        let (resident, _) = bake::bake_lod(
            &terrain,
            &pyramid,
            &params,
            &dir_b,
            clipsat::Progress::default(),
        )
        .expect("resident");
        assert_eq!(streamed, resident, "{name}: tables differ");
        let b = std::fs::read(bake::cache_path(&dir_b, bake::cache_key(&terrain, &params)))
            .expect("resident file");
        assert_eq!(a.len(), b.len(), "{name}: lengths");
        assert_eq!(a[..12], b[..12], "{name}: magic and version");
        assert!(
            a[20..a.len() - 8] == b[20..b.len() - 8],
            "{name}: body bytes differ"
        );
        // The same package without its records: the tables computed from its heights, the same bytes.
        let plain = out.with_extension("plain.clipsat");
        bake(
            &hm,
            &plain,
            &BakeOptions {
                lod_tables: false,
                ..opts.clone()
            },
        );
        let plain_pkg = Package::open(&plain).expect("open");
        assert!(plain_pkg.header().lod.is_none() && pkg.header().lod.is_some());
        let dir_c = out.with_extension("lodc");
        let _ = std::fs::remove_dir_all(&dir_c);
        let (from_heights, _) = package::lod_cache::bake_lod_package(
            &plain_pkg,
            &params,
            &dir_c,
            clipsat::Progress::default(),
        )
        .expect("from heights");
        assert_eq!(
            from_heights, resident,
            "{name}: tables from the heights differ"
        );
        let c = std::fs::read(bake::cache_path(
            &dir_c,
            package::lod_cache::package_cache_key(&plain_pkg, &params),
        ))
        .expect("file from the heights");
        assert!(
            a[20..a.len() - 8] == c[20..c.len() - 8],
            "{name}: from the heights"
        );
        let _ = std::fs::remove_dir_all(&dir_c);
        let _ = std::fs::remove_file(&plain);
        let (hit, o) =
            package::lod_cache::bake_lod_package(&pkg, &params, &dir, clipsat::Progress::default())
                .expect("hit");
        assert_eq!(o, CacheOutcome::Hit, "{name}");
        assert_eq!(hit, resident, "{name}");
        drop(hit);
        // A damaged file is refused with its reason and baked again, never trusted.
        let mut bad = a.clone();
        let mid = bad.len() / 2;
        bad[mid] ^= 0x40;
        std::fs::write(&file, &bad).expect("damage");
        let (again, o) =
            package::lod_cache::bake_lod_package(&pkg, &params, &dir, clipsat::Progress::default())
                .expect("rebake");
        assert!(
            matches!(&o, CacheOutcome::Rebaked(r) if r.contains("checksum")),
            "{name}: {o:?}"
        );
        assert_eq!(again, resident, "{name}");
        assert_eq!(
            std::fs::read(&file).expect("rebaked"),
            a,
            "{name}: rebaked bytes"
        );
        for d in [&dir, &dir_b] {
            let _ = std::fs::remove_dir_all(d);
        }
        let _ = std::fs::remove_file(&out);
    }
}

/// `package::cached` (what `--stream` bakes a plain source with) gives a valid package: its bake writes
/// a temporary name, and the bake's second write (the LOD records) must not reuse that same name, which
/// truncated the file it was reading (every `--stream` of a plain source failed at 328a6a7 with
/// "checksum mismatch"). A second call finds the file without loading the source.
#[test]
fn cached_bake_of_a_plain_source_opens_and_is_found_again() {
    let dir = temp("cached");
    let _ = std::fs::remove_dir_all(&dir);
    let hm = synthetic(70, 45);
    let bar = clipsat::Progress::default();
    let load = || Ok(Box::new(source::Resident::new(hm.clone())));
    // An older format's package of the same terrain, left by an earlier release: removed by the bake.
    std::fs::create_dir_all(&dir).expect("dir");
    let stale = dir.join("terrain-0000000000005eed-v2.clipsat");
    std::fs::write(&stale, b"an old package").expect("stale file");
    let (path, baked) = package::cached(&dir, 0x5eed, load, bar).expect("cached bake");
    assert!(baked, "first call bakes");
    assert!(!stale.exists(), "the older format's package is removed");
    let pkg = Package::open(&path).expect("the cached package opens");
    assert_eq!(pkg.decode_level(0).expect("decodes").len(), 70 * 45);
    let again = package::cached(
        &dir,
        0x5eed,
        || -> clipsat::Result<Box<source::Resident<Heightmap>>> {
            panic!("a cached package must not load its source again")
        },
        bar,
    )
    .expect("found");
    assert_eq!(again, (path, false));
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .expect("dir")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name())
        .filter(|n| {
            n.to_string_lossy().contains(".tmp") || n.to_string_lossy().contains(".records")
        })
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

/// Two threads of one process baking the same terrain into an empty cache write different temporary
/// files (`temp_suffix`'s counter; the process id alone was shared) and both end with the same package.
#[test]
fn threads_baking_one_terrain_into_the_cache_agree() {
    let dir = temp("cached-threads");
    let _ = std::fs::remove_dir_all(&dir);
    let hm = synthetic(70, 45);
    let bake = || {
        let bar = clipsat::Progress::default();
        let load = || Ok(Box::new(source::Resident::new(hm.clone())));
        package::cached(&dir, 0x7ead, load, bar).expect("cached bake")
    };
    let (a, b) = std::thread::scope(|s| {
        let a = s.spawn(bake);
        let b = s.spawn(bake);
        (a.join().expect("thread a"), b.join().expect("thread b"))
    });
    assert_eq!(a.0, b.0, "one cache file");
    let pkg = Package::open(&a.0).expect("the cached package opens");
    assert_eq!(pkg.decode_level(0).expect("decodes").len(), 70 * 45);
    let leftovers = std::fs::read_dir(&dir)
        .expect("dir")
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp"))
        .count();
    assert_eq!(leftovers, 0, "temporary files left");
}

/// Every level of the decoded pyramid is within the bound of the filtered heights it stands for, not
/// only level 0: near-lossless steps (2N + 1 quanta at level 0 on lattice data, the largest step within
/// the bound above it) with the encoder's own reconstruction in the loop.
#[test]
fn every_level_is_within_the_bound() {
    let float = synthetic(150, 97);
    let lattice = {
        let hm = synthetic(150, 97);
        let h = hm.heights().iter().map(|v| v.round()).collect();
        Heightmap::new(Path::new("<integer>"), 150, 97, 25.0, h).expect("terrain")
    };
    for (name, hm) in [("float", &float), ("integer", &lattice)] {
        let pyramid = clipsat::bake::pyramid::Pyramid::build(hm);
        for max_error in [0.01, 0.5, 2.0, 7.5] {
            for codec in CodecKind::ALL {
                let out = temp(&format!(
                    "levels-{name}-{max_error}-{}.clipsat",
                    codec.name()
                ));
                let opts = BakeOptions {
                    max_error: Some(max_error),
                    codec,
                    tile: 32,
                    zstd_level: 3,
                    lod_tables: false,
                    ..BakeOptions::default()
                };
                let r = bake(hm, &out, &opts);
                let pkg = Package::open(&out).expect("open");
                if name == "integer" && max_error >= 0.5 {
                    // The source's metre lattice, level 0 stepping 2N + 1 metres.
                    assert_eq!(r.quantum, 1.0, "{name} {max_error}");
                    let n = max_error.floor() as u32;
                    assert_eq!(pkg.header().models[0].step, 2 * n + 1, "{name} {max_error}");
                    assert!(
                        r.max_error <= max_error.floor(),
                        "{name} {max_error}: {r:?}"
                    );
                }
                let decoded = pkg.to_pyramid().expect("decode");
                for l in 0..pyramid.len() {
                    let (a, b) = (decoded.level(l), pyramid.level(l));
                    for (&x, &y) in a.heights().iter().zip(b.heights()) {
                        let slack = f64::from(f32::EPSILON * y.abs().max(1.0));
                        let e = (f64::from(x) - f64::from(y)).abs();
                        assert!(
                            e <= max_error + slack,
                            "{name} {max_error} {codec:?} level {l}: {x} for {y}"
                        );
                    }
                }
                assert!(r.coarse_max_error <= max_error + 1e-3, "{r:?}");
                let _ = std::fs::remove_file(&out);
            }
        }
    }
}

/// Tiles whose bytes are replaced by noise with a matching CRC-32 (so the checksum lets them through):
/// decoding is an error naming the tile, or other heights, never a panic, for every codec.
#[test]
fn noise_with_a_valid_checksum_never_panics() {
    let hm = synthetic(97, 75);
    for codec in CodecKind::ALL {
        let out = temp(&format!("noise-{}.clipsat", codec.name()));
        let opts = BakeOptions {
            codec,
            tile: 16,
            zstd_level: 3,
            lod_tables: false,
            ..BakeOptions::default()
        };
        bake(&hm, &out, &opts);
        let good = std::fs::read(&out).expect("read");
        let header = Package::open(&out).expect("open").header().clone();
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        for trial in 0..60 {
            let mut bytes = good.clone();
            let mut h = header.clone();
            let k = (next() % h.tiles.len() as u64) as usize;
            let e = h.tiles[k];
            let tile = &mut bytes[e.offset as usize..(e.offset + u64::from(e.len)) as usize];
            match trial % 3 {
                // All noise, a few flipped bytes, or the first bytes (lengths, states) changed.
                0 => tile.iter_mut().for_each(|b| *b = next() as u8),
                1 => {
                    for _ in 0..3 {
                        let at = (next() % tile.len() as u64) as usize;
                        tile[at] ^= 1 << (next() % 8);
                    }
                }
                _ => {
                    let n = tile.len().min(6);
                    tile[..n].iter_mut().for_each(|b| *b = next() as u8);
                }
            }
            h.tiles[k].crc = crc32fast::hash(tile);
            let head = h.to_bytes();
            bytes[..head.len()].copy_from_slice(&head);
            std::fs::write(&out, &bytes).expect("write");
            let p = Package::open(&out).expect("the header is valid");
            if let Err(e) = p.to_heightmap() {
                assert!(e.to_string().contains("tile ("), "{codec:?}: {e}");
            }
        }
        let _ = std::fs::remove_file(&out);
    }
}
