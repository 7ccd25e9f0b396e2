//! Per-frame plan benchmarks: clipmap update throughput against memcpy, and fly wall time per frame.
//!
//! Run with `cargo bench --bench stages -- "refill|fly_puget"`. Work is counted in samples (docs/design.md); these timings only show
//! what a sample costs on this machine.

use std::hint::black_box;
use std::path::Path as FsPath;
use std::time::Duration;

use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::flight::{Flight, Path};
use clipsat::profile::Profile;
use clipsat::profile::SHIPPED;
use clipsat::source::Heightmap;
use clipsat::source::{self, LoadOptions};
use criterion::{criterion_group, Criterion, Throughput};
use glam::DVec3;

/// Rolling synthetic terrain, 1025 x 1025 at 30 m: the refill bench needs no data files.
fn hills() -> Heightmap {
    let size = 1025u32;
    let heights = (0..size)
        .flat_map(|v| (0..size).map(move |u| (u as f32, v as f32)))
        .map(|(x, y)| 400.0 + 300.0 * (x / 37.0).sin() * (y / 53.0).cos())
        .collect();
    Heightmap::new(FsPath::new("<bench>"), size, size, 30.0, heights).expect("bench terrain")
}

/// (a) Every ring refilled from scratch each frame (the eye jumps farther than the coarsest ring spans),
/// against a plain copy of the same bytes: (n + 1 + 2 margin)^2 texels of 8 bytes (RG32F) per level.
fn full_refill(c: &mut Criterion) {
    let terrain = hills();
    let mut profile = Profile::load("desktop").expect("shipped profile");
    profile.budget.update_samples_per_frame = u32::MAX;
    let mut clipmap =
        Clipmap::new(&terrain, &profile, ClipmapOptions::default()).expect("desktop clipmap");
    let z = 400.0 + 300.0 + 50.0;
    let eyes = [DVec3::new(15e3, 15e3, z), DVec3::new(2e8, -3e8, z)];
    let frame = clipmap.update(eyes[0]).expect("first frame");
    let samples = u64::from(frame.samples_updated);
    let s = u64::from(profile.clip_size());
    let levels = u64::from(profile.clipmap.levels);
    assert_eq!(
        samples,
        s * s * levels,
        "a jump should refill every level in full"
    );

    let mut group = c.benchmark_group(format!(
        "refill_desktop_n{}_{levels}x{s}x{s}",
        profile.clipmap.n
    ));
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4))
        .throughput(Throughput::Elements(samples));
    let mut k = 0usize;
    group.bench_function("clipmap_update", |b| {
        b.iter(|| {
            k += 1;
            let f = clipmap.update(black_box(eyes[k % 2])).expect("update");
            black_box(f.hash)
        });
    });
    let bytes = usize::try_from(samples * 8).expect("bench buffer fits in memory");
    let src = vec![1u8; bytes];
    let mut dst = vec![0u8; bytes];
    group.bench_function("memcpy_same_bytes", |b| {
        b.iter(|| {
            dst.copy_from_slice(black_box(&src));
            black_box(dst[bytes / 2])
        });
    });
    group.finish();
}

/// (b) Wall time of one `fly` frame (camera + budgeted update) per shipped profile, Puget Sound at 400 m/frame.
fn fly_puget(c: &mut Criterion) {
    let path = clipsat::data_dir().join("ps_height_1k.png");
    if !path.exists() {
        eprintln!("skipping fly_puget: {} is missing", path.display());
        return;
    }
    let opts = LoadOptions {
        spacing: Some(160.0),
        ..LoadOptions::default()
    };
    let terrain = match source::load(&path, &opts) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("skipping fly_puget: {e}");
            return;
        }
    };
    let mut group = c.benchmark_group("fly_puget_400m_per_frame");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    for (name, _) in SHIPPED {
        let profile = Profile::load(name).expect("shipped profile");
        let flight = Flight::new(Path::Figure8, 400.0, &terrain)
            .expect("flight")
            .with_fov_y_deg(f64::from(profile.view.fov_y_deg));
        let mut clipmap =
            Clipmap::new(&terrain, &profile, ClipmapOptions::default()).expect("clipmap");
        let mut frame = 0u64;
        group.bench_function(name, |b| {
            b.iter(|| {
                let eye = flight.camera(frame).eye;
                frame += 1;
                black_box(clipmap.update(eye).expect("update").hash)
            });
        });
    }
    group.finish();
}

criterion_group!(benches, full_refill, fly_puget);
