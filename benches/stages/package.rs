//! Package decode benchmarks (stage 1b): whole-pyramid decode per codec against a memcpy of the decoded
//! bytes, and one full 256 x 256 level through the tile cache.
//!
//! Run with `cargo bench --bench stages -- "decode_|cache_|stream_fill"`. Uses `ps_height_1k.png` from the test terrains' folder (`$CLIPSAT_DATA`) (skipped with a reason
//! when missing) and a synthetic 1025^2 terrain.

use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Duration;

use clipsat::package::{self, BakeOptions, CodecKind, Package, TileCache};
use clipsat::source::Heightmap;
use clipsat::source::{self, LoadOptions};
use criterion::{criterion_group, Criterion, Throughput};

fn hills() -> Heightmap {
    let size = 1025u32;
    let heights = (0..size)
        .flat_map(|v| (0..size).map(move |u| (u as f32, v as f32)))
        .map(|(x, y)| (400.0 + 300.0 * (x / 37.0).sin() * (y / 53.0).cos()).round())
        .collect();
    Heightmap::new(Path::new("<bench>"), size, size, 30.0, heights).expect("bench terrain")
}

fn terrains() -> Vec<(String, Heightmap)> {
    let mut out = vec![("hills1025".to_string(), hills())];
    let path = clipsat::data_dir().join("ps_height_1k.png");
    if path.is_file() {
        let opts = LoadOptions {
            spacing: Some(160.0),
            ..LoadOptions::default()
        };
        out.push((
            "ps_height_1k".into(),
            source::load(&path, &opts).expect("ps_height_1k"),
        ));
    } else {
        eprintln!("skipping ps_height_1k: {} is missing", path.display());
    }
    out
}

fn baked(name: &str, hm: &Heightmap, codec: CodecKind) -> PathBuf {
    let out = std::env::temp_dir().join(format!(
        "clipsat-bench-{}-{name}-{}.clipsat",
        std::process::id(),
        codec.name()
    ));
    let opts = BakeOptions {
        codec,
        ..BakeOptions::default()
    };
    package::bake(hm, &out, &opts, clipsat::Progress::default()).expect("bake");
    out
}

/// The whole pyramid decoded, per codec, against a memcpy of the same decoded bytes.
fn decode(c: &mut Criterion) {
    for (name, hm) in terrains() {
        for codec in CodecKind::ALL {
            let path = baked(&name, &hm, codec);
            let pkg = Package::open(&path).expect("open");
            let samples: u64 = pkg
                .header()
                .levels
                .iter()
                .map(|l| u64::from(l.width) * u64::from(l.height))
                .sum();
            let mut group = c.benchmark_group(format!("decode_{name}_{}", codec.name()));
            group
                .sample_size(10)
                .warm_up_time(Duration::from_secs(1))
                .measurement_time(Duration::from_secs(3))
                .throughput(Throughput::Elements(samples));
            group.bench_function("pyramid", |b| {
                b.iter(|| black_box(pkg.decode_level0().expect("decode")));
            });
            let src = vec![7i32; usize::try_from(samples).expect("fits")];
            let mut dst = vec![0i32; src.len()];
            group.bench_function("memcpy", |b| {
                b.iter(|| {
                    dst.copy_from_slice(black_box(&src));
                    black_box(&dst);
                });
            });
            group.finish();
            let _ = std::fs::remove_file(&path);
        }
    }
}

/// One full 256 x 256 region of level 0 through a cold cache: its tiles and their coarser tiles decoded
/// (GC table 1's "decompress a full level", n = 255).
fn full_level(c: &mut Criterion) {
    let hm = hills();
    let path = baked("level", &hm, CodecKind::Zstd);
    let mut group = c.benchmark_group("cache_full_level_256");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3))
        .throughput(Throughput::Elements(256 * 256));
    // The coarser levels are resident (the clipmap fills coarse to fine); level 0's 16 tiles are decoded.
    group.bench_function("level0_tiles", |b| {
        b.iter_batched(
            || {
                let pkg = Package::open(&path).expect("open");
                let mut cache = TileCache::new(pkg, 8 << 20, "bench").expect("cache");
                let mut budget = u64::MAX;
                assert!(cache
                    .ensure_rect(1, (127, 127, 259, 259), &mut budget)
                    .expect("decode"));
                cache
            },
            |mut cache| {
                let mut budget = u64::MAX;
                assert!(cache
                    .ensure_rect(0, (256, 256, 512, 512), &mut budget)
                    .expect("decode"));
                black_box(cache.units(0, 300, 300));
                cache
            },
            criterion::BatchSize::LargeInput,
        );
    });
    group.finish();
    let _ = std::fs::remove_file(&path);
}

/// Decode plus fill, one core: a desktop clipmap (n = 255, 11 levels) streamed from the package through a
/// fresh cache (rings plus 8 MiB of tiles, built outside the timing) and filled from nothing: every
/// level's tiles decoded and every texel written (GC table 1: 8 ms to decompress a full level). Per level:
/// the time over 11.
fn refill(c: &mut Criterion) {
    use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
    use clipsat::profile::Profile;
    let hm = hills();
    let path = baked("refill", &hm, CodecKind::Zstd);
    let mut profile = Profile::load("desktop").expect("profile");
    profile.budget.update_samples_per_frame = u32::MAX;
    profile.budget.cpu_memory_bytes = profile.cpu_split().rings + (8 << 20);
    let eye = glam::DVec3::new(15e3, 15e3, 400.0 + 300.0 + 50.0);
    let s = u64::from(profile.clip_size());
    let levels = u64::from(profile.clipmap.levels);
    let fresh = || {
        let pkg = Package::open(&path).expect("open");
        Clipmap::streamed(pkg, &profile, ClipmapOptions::default()).expect("streamed clipmap")
    };
    let mut probe = fresh();
    probe.update(eye).expect("update");
    eprintln!(
        "refill: {} samples decoded by a cold fill",
        probe.decoded_samples()
    );
    let mut group = c.benchmark_group(format!("stream_fill_desktop_{levels}x{s}x{s}"));
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4))
        .throughput(Throughput::Elements(s * s * levels));
    group.bench_function("decode_and_fill", |b| {
        b.iter_batched(
            fresh,
            |mut clipmap| {
                black_box(clipmap.update(eye).expect("update").hash);
                clipmap
            },
            criterion::BatchSize::LargeInput,
        );
    });
    group.finish();
    let _ = std::fs::remove_file(&path);
}

criterion_group!(benches, decode, full_level, refill);
