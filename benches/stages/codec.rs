//! Package codec benchmarks (stage 1b): decode ns per sample of whole pyramids, and decode plus fill of
//! one full 255 x 255 level through the tile cache (`docs/package-codec.md`, the speed goals).
//!
//! Run with `cargo bench --bench stages -- codec_`. Uses the shared terrains Big Tujunga and n07_w006
//! (skipped with a reason when missing) and a synthetic 1025^2 terrain; packages baked with the default
//! options (lossless on these integer-metre grids).

use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Duration;

use clipsat::package::{self, BakeOptions, Package, TileCache};
use clipsat::source::Heightmap;
use clipsat::source::{self, LoadOptions};
use criterion::{criterion_group, Criterion, Throughput};

fn terrains() -> Vec<(String, Heightmap)> {
    let size = 1025u32;
    let heights = (0..size)
        .flat_map(|v| (0..size).map(move |u| (u as f32, v as f32)))
        .map(|(x, y)| (400.0 + 300.0 * (x / 37.0).sin() * (y / 53.0).cos()).round())
        .collect();
    let hills = Heightmap::new(Path::new("<bench>"), size, size, 30.0, heights).expect("terrain");
    let mut out = vec![("hills1025".to_string(), hills)];
    for (name, file) in [
        ("bigtujunga", "srtm_bigtujunga30m_utm11.tif"),
        ("n07_w006", "n07_w006_3arc_v2.tif"),
    ] {
        let path = clipsat::data_dir().join(file);
        if path.is_file() {
            out.push((
                name.into(),
                source::load(&path, &LoadOptions::default()).expect(file),
            ));
        } else {
            eprintln!("skipping {name}: {} is missing", path.display());
        }
    }
    out
}

fn baked(name: &str, hm: &Heightmap) -> PathBuf {
    let out = std::env::temp_dir().join(format!(
        "clipsat-codec-bench-{}-{name}.clipsat",
        std::process::id()
    ));
    package::bake(
        hm,
        &out,
        &BakeOptions::default(),
        clipsat::Progress::default(),
    )
    .expect("bake");
    out
}

/// The whole pyramid decoded to level 0, per level-0 sample (what an image codec decodes the same grid
/// in), on one thread.
fn pyramid(c: &mut Criterion) {
    for (name, hm) in terrains() {
        let path = baked(&name, &hm);
        let pkg = Package::open(&path).expect("open");
        let mut group = c.benchmark_group(format!("codec_decode_{name}"));
        group
            .sample_size(10)
            .warm_up_time(Duration::from_secs(1))
            .measurement_time(Duration::from_secs(3))
            .throughput(Throughput::Elements(pkg.header().samples()));
        group.bench_function("pyramid_per_level0_sample", |b| {
            b.iter(|| black_box(pkg.decode_level0().expect("decode")));
        });
        group.finish();
        let _ = std::fs::remove_file(&path);
    }
}

/// One full 255 x 255 level: the level-0 tiles under a 255^2 window decoded through a cold cache (the
/// coarser levels resident, as the clipmap fills coarse to fine) and every sample copied into a ring.
fn full_level(c: &mut Criterion) {
    const N: u32 = 255;
    for (name, hm) in terrains() {
        let path = baked(&name, &hm);
        let (x0, y0) = ((hm.width() - N) / 2, (hm.height() - N) / 2);
        let mut group = c.benchmark_group(format!("codec_fill_{name}_255"));
        group
            .sample_size(10)
            .warm_up_time(Duration::from_secs(1))
            .measurement_time(Duration::from_secs(3))
            .throughput(Throughput::Elements(u64::from(N * N)));
        let mut ring = vec![0i32; (N * N) as usize];
        group.bench_function("decode_and_fill", |b| {
            b.iter_batched(
                || {
                    let pkg = Package::open(&path).expect("open");
                    let mut cache = TileCache::new(pkg, 64 << 20, "bench").expect("cache");
                    let mut budget = u64::MAX;
                    let (cx, cy) = (i64::from(x0 / 2) - 4, i64::from(y0 / 2) - 4);
                    let c1 = i64::from(N / 2 + 10);
                    assert!(cache
                        .ensure_rect(1, (cx, cy, cx + c1, cy + c1), &mut budget)
                        .expect("decode"));
                    cache
                },
                |mut cache| {
                    let mut budget = u64::MAX;
                    let rect = (
                        i64::from(x0),
                        i64::from(y0),
                        i64::from(x0 + N),
                        i64::from(y0 + N),
                    );
                    assert!(cache.ensure_rect(0, rect, &mut budget).expect("decode"));
                    for y in 0..N {
                        let mut x = 0;
                        while x < N {
                            let (sx, seg) = cache.row_segment(0, x0 + x, y0 + y).expect("resident");
                            let from = (x0 + x - sx) as usize;
                            let take = seg.len().saturating_sub(from).min((N - x) as usize);
                            let at = (y * N + x) as usize;
                            ring[at..at + take].copy_from_slice(&seg[from..from + take]);
                            x += u32::try_from(take).expect("at most N");
                        }
                    }
                    black_box(&ring);
                    cache
                },
                criterion::BatchSize::LargeInput,
            );
        });
        group.finish();
        let _ = std::fs::remove_file(&path);
    }
}

criterion_group!(benches, pyramid, full_level);
