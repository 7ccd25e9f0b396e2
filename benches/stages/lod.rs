//! SAT LOD benchmarks: per-frame CPU block selection (each mode) for a gles3-mid clipmap on the procedural
//! terrain, SAT build time per level, and the whole SAT plan per frame in a flight.
//!
//! Run with `cargo bench --bench stages -- lod_`.

use std::hint::black_box;
use std::time::Duration;

use clipsat::bake::lod_tables::{error_map, LevelTables, LodTables, P};
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::flight::{Flight, Path};
use clipsat::plan::lod::{Lod, LodFrame, LodMode};
use clipsat::profile::Profile;
use clipsat::source::procedural::{generate, ProceduralParams};
use criterion::{criterion_group, Criterion, Throughput};

/// (a) `Lod::select` per frame along a figure-8 at 50 m/frame, gles3-mid, procedural 1025^2 at 30 m.
fn select_per_frame(c: &mut Criterion) {
    let terrain = generate(&ProceduralParams::default()).expect("procedural terrain");
    let mut profile = Profile::load("gles3-mid").expect("shipped profile");
    profile.budget.update_samples_per_frame = u32::MAX;
    let mut clipmap = Clipmap::new(&terrain, &profile, ClipmapOptions::default()).expect("clipmap");
    let tables =
        LodTables::build(clipmap.pyramid(), profile.clipmap.levels, P, |_| {}).expect("tables");
    let lod = Lod::for_clipmap(tables, &profile, &clipmap, &terrain);
    let flight = Flight::new(Path::Figure8, 50.0, &terrain).expect("flight");
    // A fixed set of frames, updated once: the bench times selection only.
    let frames: Vec<_> = (0..32u64)
        .map(|i| {
            let cam = flight.camera(i * 40);
            let f = clipmap.update(cam.eye).expect("update").clone();
            (f, cam)
        })
        .collect();
    let mut out = LodFrame::new_boxed();
    let mut group = c.benchmark_group("lod_select_gles3_mid_procedural_1025");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    for mode in [
        LodMode::Distance,
        LodMode::Sat,
        LodMode::SatConservative,
        LodMode::Exact,
    ] {
        let mut k = 0usize;
        group.bench_function(mode.to_string(), |b| {
            b.iter(|| {
                k += 1;
                let (f, cam) = &frames[k % frames.len()];
                lod.select(f, cam, mode, &mut out).expect("select");
                black_box(out.blocks.len())
            });
        });
    }
    group.finish();
}

/// (b) Building one level's tables (SAT of (e/E)^p and max pyramid) on 1025^2 samples.
fn sat_build_per_level(c: &mut Criterion) {
    let terrain = generate(&ProceduralParams::default()).expect("procedural terrain");
    let pyramid = clipsat::bake::pyramid::Pyramid::build(&terrain);
    let errors = error_map(&pyramid, 3);
    let (w, h) = (terrain.width(), terrain.height());
    let mut group = c.benchmark_group("lod_bake_level_1025");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4))
        .throughput(Throughput::Elements(u64::from(w) * u64::from(h)));
    group.bench_function("error_map", |b| {
        b.iter(|| black_box(error_map(&pyramid, 3).len()))
    });
    group.bench_function("sat_and_max_pyramid", |b| {
        b.iter(|| {
            black_box(
                LevelTables::build(w, h, errors.clone(), P)
                    .expect("tables")
                    .e_max(),
            )
        })
    });
    group.finish();
}

/// (c) `Planner::plan` per frame, selection and the detail pool's refinement within its budget
/// (docs/plan-time.md), along a figure-8 at 50 m/frame (the planner carrying its state from frame to
/// frame; the clipmap's update is not timed), gles3-mid, procedural 1025^2 at 30 m, sat-conservative.
fn plan_per_frame(c: &mut Criterion) {
    use clipsat::plan::frame_plan::{LodSetup, PlanParams, Planner};
    let terrain = generate(&ProceduralParams::default()).expect("procedural terrain");
    let profile = Profile::load("gles3-mid").expect("shipped profile");
    let mut group = c.benchmark_group("lod_plan_gles3_mid_procedural_1025");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    for eps in [1.0f32, 2.0, 4.0] {
        let mut clipmap =
            Clipmap::new(&terrain, &profile, ClipmapOptions::default()).expect("clipmap");
        let tables =
            LodTables::build(clipmap.pyramid(), profile.clipmap.levels, P, |_| {}).expect("tables");
        let lod = Lod::for_clipmap(tables, &profile, &clipmap, &terrain);
        let setup = LodSetup::new(LodMode::SatConservative, Some(lod)).expect("tables");
        let mut planner = Planner::new(&profile, &clipmap, setup).expect("planner");
        let mut plan = planner.new_plan();
        let flight = Flight::new(Path::Figure8, 50.0, &terrain).expect("flight");
        let params = PlanParams {
            epsilon_px: Some(eps),
            ..PlanParams::default()
        };
        let mut f = 0u64;
        group.bench_function(format!("sat_conservative_{eps}px"), |b| {
            b.iter_custom(|iters| {
                let mut spent = Duration::ZERO;
                for _ in 0..iters {
                    let cam = flight.camera(f);
                    f += 1;
                    clipmap.update(cam.eye).expect("update");
                    let t = std::time::Instant::now();
                    planner
                        .plan(&clipmap, &cam, &params, &mut plan)
                        .expect("plan");
                    spent += t.elapsed();
                    clipmap.request_samples(&plan.detail().wanted);
                    black_box(plan.hash());
                }
                spent
            });
        });
    }
    group.finish();
}

criterion_group!(
    benches,
    select_per_frame,
    sat_build_per_level,
    plan_per_frame
);
