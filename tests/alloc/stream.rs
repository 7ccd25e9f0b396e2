//! Stage 2 over stage 1b: a long flight streamed from a package through a tile cache far smaller than the
//! terrain. Every frame's fill plus decode stays within the sample budget, the GC section 5 constraints
//! hold, nothing is allocated per frame (cache misses and evictions included), the hashes repeat run to
//! run, and every ring texel equals the package's own decode.
//!
//! The 16385^2 flight with its RSS bound is a command, not a test (it needs a release build and minutes):
//! `clipsat bake procedural:size=16385 --out big.clipsat && /usr/bin/time -v clipsat fly --terrain
//! big.clipsat --profile gles3-mid --frames 2000 --speed 2000`.

#![expect(
    clippy::cast_possible_truncation,
    reason = "the test terrain is an f64 formula stored as f32 heights; small test indices fit usize"
)]

use std::path::Path;

use clipsat::package::{self, BakeOptions, Package};
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::profile::ClipmapBudget;
use clipsat::profile::Profile;
use clipsat::source::Heightmap;
use glam::DVec3;

use crate::counting_alloc::count;

const SIZE: u32 = 1025;
const SPACING: f32 = 30.0;

fn terrain() -> Heightmap {
    let h = (0..SIZE * SIZE)
        .map(|k| {
            let (x, y) = (f64::from(k % SIZE), f64::from(k / SIZE));
            (400.0 + 250.0 * (x / 41.0).sin() * (y / 29.0).cos() + 20.0 * (x * y / 900.0).sin())
                as f32
        })
        .collect();
    Heightmap::new(Path::new("<stream>"), SIZE, SIZE, SPACING, h).expect("terrain")
}

fn profile() -> Profile {
    let mut p = Profile::load("gles3-low").expect("profile");
    p.clipmap = ClipmapBudget {
        n: 31,
        levels: 6,
        clip_margin: 4,
    };
    p.budget.update_samples_per_frame = 2048;
    // The rings' CPU copy plus the smallest tile cache: about 1 MiB, a quarter of the decoded level 0.
    p.budget.cpu_memory_bytes = p.cpu_split().rings + clipsat::profile::MIN_TILE_CACHE_BYTES;
    p.validate("stream test").expect("valid profile");
    p
}

/// A fast, wide path: circles over the whole terrain with a few jumps.
fn eye(t: u32) -> DVec3 {
    let extent = f64::from(SIZE - 1) * f64::from(SPACING);
    let c = extent * 0.5;
    let a = f64::from(t) * 0.013;
    let r = extent * (0.15 + 0.3 * (f64::from(t) * 0.002).sin().abs());
    let jump = if (t / 300) % 2 == 1 {
        extent * 0.2
    } else {
        0.0
    };
    DVec3::new(c + r * a.cos() + jump, c + r * a.sin(), 900.0)
}

/// Flies `frames` frames, checking the budget and constraints; returns every frame hash.
fn fly(cm: &mut Clipmap, frames: u32, budget: u32, hashes: &mut Vec<u64>) {
    fly_from(cm, 0..frames, budget, hashes);
}

/// The test terrain baked into `NAME` in a fresh temporary folder `DIR-PID`: (that folder, the package).
fn baked(dir: &str, name: &str) -> (std::path::PathBuf, std::path::PathBuf) {
    let dir = std::env::temp_dir().join(format!("{dir}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join(name);
    let opts = BakeOptions {
        max_error: Some(0.05),
        tile: 32,
        zstd_level: 3,
        ..BakeOptions::default()
    };
    package::bake(&terrain(), &path, &opts, clipsat::Progress::default()).expect("bake");
    (dir, path)
}

#[test]
fn long_flight_streams_within_budget_without_allocating() {
    let (dir, path) = baked("clipsat-stream", "stream.clipsat");
    let p = profile();
    let budget = p.budget.update_samples_per_frame;
    let open = || Package::open(&path).expect("open");
    let decoded_l0 = u64::from(SIZE) * u64::from(SIZE) * 4;
    let opts = ClipmapOptions::default();

    let mut a = Clipmap::streamed(open(), &p, opts).expect("streamed clipmap");
    let split = a.tile_cache().expect("streamed").split();
    assert!(
        split.budget * 3 < decoded_l0,
        "the cache ({} bytes) must be far smaller than the decoded terrain ({decoded_l0})",
        split.budget
    );
    let frames = 1500;
    let mut first = Vec::with_capacity(frames as usize);
    let mut second = Vec::with_capacity(frames as usize);
    // Warm-up outside the count, then the rest counted: misses, evictions and refusals included.
    fly(&mut a, 100, budget, &mut first);
    let before = a.tile_cache().expect("streamed").stats();
    let allocations = count(|| fly_from(&mut a, 100..frames, budget, &mut first));
    let after = a.tile_cache().expect("streamed").stats();
    assert_eq!(allocations, 0, "allocations while streaming");
    assert!(
        after.decoded > before.decoded && after.evictions > before.evictions,
        "the counted frames must miss and evict: {before:?} -> {after:?}"
    );

    // Every held texel equals the package's own decode of its level.
    let pkg = open();
    for l in 0..a.levels() {
        let lf = a.frame().levels[l as usize];
        let d = pkg.header().levels[l as usize];
        let full = pkg.decode_level(l as usize).expect("decode");
        let clip = lf.clip;
        for j in clip.y0..clip.y1() {
            for i in clip.x0..clip.x1() {
                let (x, y) = (
                    i.clamp(0, i64::from(d.width) - 1) as usize,
                    j.clamp(0, i64::from(d.height) - 1) as usize,
                );
                let want = pkg.metres(full[y * d.width as usize + x]);
                assert_eq!(a.ring(l).get(i, j)[0], want, "level {l} ({i}, {j})");
            }
        }
    }

    // Run to run: a fresh cache gives the same hashes.
    let mut b = Clipmap::streamed(open(), &p, opts).expect("streamed clipmap");
    fly(&mut b, frames, budget, &mut second);
    assert_eq!(first, second, "frame hashes differ between runs");
    let _ = std::fs::remove_dir_all(&dir);
}

/// [`fly`] over frames `range`.
fn fly_from(cm: &mut Clipmap, range: std::ops::Range<u32>, budget: u32, hashes: &mut Vec<u64>) {
    for t in range {
        let f = cm.update(eye(t)).expect("update");
        let (updated, hash) = (f.samples_updated, f.hash);
        let work = updated + cm.decoded_samples();
        assert!(work <= budget, "frame {t}: fill + decode {work} > {budget}");
        if let Err(v) = cm.check_constraints() {
            panic!("frame {t}: {v}");
        }
        hashes.push(hash);
    }
}

/// SAT LOD over a streamed package: the tables are read through a map of their cache file
/// (nothing owned), every frame's block levels equal those chosen from the same tables baked in memory
/// from the package's decoded pyramid, and planning allocates nothing while the map is trimmed each frame.
#[test]
fn sat_lod_streams_from_mapped_tables_without_allocating() {
    use clipsat::bake::lod_tables::{LodTables, P};
    use clipsat::bake::{BakeParams, CacheOutcome};
    use clipsat::package::lod_cache::bake_lod_package;
    use clipsat::plan::frame_plan::{LodSetup, PlanParams, Planner};
    use clipsat::plan::lod::{Lod, LodFrame, LodMode};

    let (dir, path) = baked("clipsat-stream-sat", "sat.clipsat");
    let p = profile();
    let open = || Package::open(&path).expect("open");
    let mut cm = Clipmap::streamed(open(), &p, ClipmapOptions::default()).expect("streamed");
    let params = BakeParams {
        p: P,
        levels: p.clipmap.levels,
        synth_levels: 0,
        g0: cm.g0(),
    };
    let cache = dir.join("lod-cache");
    let pkg = open();
    let coarse = pkg.coarse_heightmap(1 << 16).expect("coarse");
    let (tables, o) =
        bake_lod_package(&pkg, &params, &cache, clipsat::Progress::default()).expect("tables");
    assert_eq!(o, CacheOutcome::Baked);
    assert!(tables.is_mapped() && tables.owned_bytes() == 0, "mapped");
    let (hit, o) =
        bake_lod_package(&pkg, &params, &cache, clipsat::Progress::default()).expect("hit");
    assert_eq!(o, CacheOutcome::Hit);
    assert!(hit.is_mapped());
    // The same tables baked in memory from the decoded pyramid.
    let owned = clipsat::bake::bake_uncached(
        &pkg.to_pyramid().expect("pyramid"),
        &params,
        clipsat::Progress::default(),
    )
    .expect("owned");
    assert!(!owned.is_mapped() && owned.owned_bytes() > 0);
    assert_eq!(tables, owned, "mapped and in-memory tables differ");
    let mapped_lod = Lod::for_clipmap(tables, &p, &cm, &coarse);
    let owned_lod = Lod::for_clipmap(owned, &p, &cm, &coarse);
    let _: &LodTables = owned_lod.tables();
    let mut planner = Planner::new(
        &p,
        &cm,
        LodSetup::new(LodMode::SatConservative, Some(mapped_lod.clone())).expect("setup"),
    )
    .expect("planner");
    let mut plan = planner.new_plan();
    let mut want = LodFrame::new_boxed();
    let pp = PlanParams {
        epsilon_px: Some(2.0),
        ..PlanParams::default()
    };
    for t in 0..40 {
        cm.update(eye(t)).expect("update");
    }
    let mut frames = 0;
    for t in 40..400 {
        let e = eye(t);
        let cam = clipsat::plan::camera::Camera::new(e, e + DVec3::new(300.0, 200.0, -400.0), 60.0)
            .expect("cam");
        cm.update(e).expect("update");
        let n = count(|| planner.plan(&cm, &cam, &pp, &mut plan).expect("plan"));
        assert_eq!(n, 0, "frame {t}: {n} allocations");
        for mode in [LodMode::Sat, LodMode::SatConservative, LodMode::Exact] {
            let mut a = LodFrame::new_boxed();
            let (mut l1, mut l2) = (mapped_lod.clone(), owned_lod.clone());
            l1.set_epsilon_px(2.0);
            l2.set_epsilon_px(2.0);
            l1.select(cm.frame(), &cam, mode, &mut a).expect("select");
            l2.select(cm.frame(), &cam, mode, &mut want)
                .expect("select");
            assert_eq!(a, want, "frame {t} {mode:?}: levels differ");
        }
        frames += 1;
    }
    assert!(frames > 0 && !plan.lod_frame().blocks.is_empty());
    let _ = std::fs::remove_dir_all(&dir);
}

/// The detail pool over a streamed package: a flight in `sat-conservative` whose pool tiles
/// come from the package's tile cache. Tiles whose package tiles are not resident wait
/// (`DetailFrame::wanted`); the next update decodes them after the rings. Every frame's ring fill, decode
/// and pool fill together stay within the sample budget, planning and updating allocate nothing, the
/// plan hashes repeat run to run, and every pool tile written equals the package's own decode of its
/// level, so a streamed and a resident render of the package hold the same pool contents.
#[test]
fn detail_pool_streams_within_budget_without_allocating() {
    use clipsat::bake::lod_tables::P;
    use clipsat::bake::BakeParams;
    use clipsat::package::lod_cache::bake_lod_package;
    use clipsat::plan::detail::fill_tile;
    use clipsat::plan::frame_plan::{LodSetup, PlanParams, Planner};
    use clipsat::plan::lod::{Lod, LodMode};

    let (dir, path) = baked("clipsat-stream-pool", "pool.clipsat");
    let mut p = profile();
    p.budget.update_samples_per_frame = 8192;
    p.budget.detail_tiles = 24;
    p.budget.detail_tile_quads = 8;
    p.validate("stream pool test").expect("valid profile");
    let budget = u64::from(p.budget.update_samples_per_frame);
    let open = || Package::open(&path).expect("open");
    let pkg = open();
    let params = BakeParams {
        p: P,
        levels: p.clipmap.levels,
        synth_levels: 0,
        g0: f64::from(SPACING),
    };
    let (tables, _) = bake_lod_package(
        &pkg,
        &params,
        &dir.join("lod-cache"),
        clipsat::Progress::default(),
    )
    .expect("tables");
    let coarse = pkg.coarse_heightmap(1 << 16).expect("coarse");
    // The package's decoded levels: what every pool tile must hold, bit for bit.
    let levels: Vec<Vec<f32>> = (0..pkg.header().levels.len())
        .map(|l| {
            let full = pkg.decode_level(l).expect("decode");
            full.into_iter().map(|k| pkg.metres(k)).collect()
        })
        .collect();
    let pp = PlanParams {
        epsilon_px: Some(1.0),
        ..PlanParams::default()
    };
    let quads = p.detail_quads();
    let side = p.detail_side() as usize;
    let run = |check: bool| -> (Vec<u64>, u32, u64, u32) {
        let mut cm = Clipmap::streamed(open(), &p, ClipmapOptions::default()).expect("streamed");
        let lod = Lod::for_clipmap(tables.clone(), &p, &cm, &coarse);
        let setup = LodSetup::new(LodMode::SatConservative, Some(lod)).expect("setup");
        let mut planner = Planner::new(&p, &cm, setup).expect("planner");
        let mut plan = planner.new_plan();
        let mut tile = vec![[0.0f32; 2]; side * side];
        let (mut hashes, mut most, mut written, mut waited) = (Vec::with_capacity(400), 0, 0, 0);
        for t in 0..400u32 {
            // Slow along the circle, so the rings settle and the pool gets budget.
            let e = eye(t / 4);
            let cam =
                clipsat::plan::camera::Camera::new(e, e + DVec3::new(300.0, 200.0, -120.0), 60.0)
                    .and_then(|c| c.with_clip(2.0, 1.0e5))
                    .expect("cam");
            let n = count(|| {
                cm.update(e).expect("update");
                planner.plan(&cm, &cam, &pp, &mut plan).expect("plan");
                cm.request_samples(&plan.detail().wanted);
            });
            assert_eq!(n, 0, "frame {t}: {n} allocations");
            let f = cm.frame();
            let work = u64::from(f.samples_updated)
                + u64::from(cm.decoded_samples())
                + plan.detail().samples_updated;
            assert!(
                work <= budget,
                "frame {t}: fill + decode + pool {work} > {budget}"
            );
            hashes.push(plan.hash());
            most = most.max(plan.stats().detail_tiles_resident);
            waited += u32::from(!plan.detail().wanted.is_empty());
            for u in &plan.detail().uploads {
                written += 1;
                assert!(
                    fill_tile(&cm, &u.key, quads, &mut tile),
                    "frame {t}: {:?} ready",
                    u.key
                );
                if !check {
                    continue;
                }
                let l = pkg.header().levels[u.key.level as usize];
                let (i0, j0) = u.key.first_sample(quads);
                for (k, z) in tile.iter().enumerate() {
                    let (i, j) = (i0 + (k % side) as i64, j0 + (k / side) as i64);
                    let x = i.clamp(0, i64::from(l.width) - 1) as usize;
                    let y = j.clamp(0, i64::from(l.height) - 1) as usize;
                    let want = levels[u.key.level as usize][y * l.width as usize + x];
                    assert_eq!(z[0], want, "frame {t}: {:?} sample ({i}, {j})", u.key);
                }
            }
        }
        (hashes, most, written, waited)
    };
    let (first, most, written, waited) = run(true);
    eprintln!("pool: {most} tiles resident at most, {written} written, {waited} frames waited");
    assert!(
        most > 0 && written > 0 && waited > 0,
        "the pool filled from the package after waiting: {most} resident, {written} written, \
         {waited} frames waited"
    );
    let (second, _, _, _) = run(false);
    assert_eq!(first, second, "plan hashes differ between runs");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The test terrain as 4 x 4 projected GeoTIFF tiles of 257^2 sharing their edges, in `DIR-PID/tiles`,
/// baked as a package set in `DIR-PID/set` (16 parts: more than the set's shared rANS lookups): (that
/// folder, the set).
fn baked_set(dir: &str) -> (std::path::PathBuf, std::path::PathBuf) {
    use tiff::encoder::colortype::Gray32Float;
    use tiff::tags::Tag;
    let dir = std::env::temp_dir().join(format!("{dir}-{}", std::process::id()));
    let tiles = dir.join("tiles");
    std::fs::create_dir_all(&tiles).expect("temp dir");
    let t = terrain();
    let n = 257u32;
    for ty in 0..4 {
        for tx in 0..4 {
            let data: Vec<f32> = (0..n * n)
                .map(|i| {
                    let (x, y) = (tx * (n - 1) + i % n, ty * (n - 1) + i / n);
                    t.heights()[(y * SIZE + x) as usize]
                })
                .collect();
            let path = tiles.join(format!("t{tx}{ty}.tif"));
            let mut file = std::fs::File::create(&path).expect("create");
            let mut enc = tiff::encoder::TiffEncoder::new(&mut file).expect("encoder");
            let mut img = enc.new_image::<Gray32Float>(n, n).expect("image");
            let s = f64::from(SPACING);
            let (x0, y0) = (
                f64::from(tx * (n - 1)) * s,
                1e5 - f64::from(ty * (n - 1)) * s,
            );
            img.encoder()
                .write_tag(Tag::ModelPixelScaleTag, &[s, s, 0.0][..])
                .expect("scale");
            img.encoder()
                .write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, x0, y0, 0.0][..])
                .expect("tiepoint");
            // Projected model (UTM 33N), pixel-is-point.
            let keys: [u16; 12] = [1, 1, 0, 2, 1024, 0, 1, 1, 1025, 0, 1, 2];
            img.encoder()
                .write_tag(Tag::GeoKeyDirectoryTag, &keys[..])
                .expect("geokeys");
            img.write_data(&data).expect("data");
        }
    }
    let set = dir.join("set");
    let opts = BakeOptions {
        max_error: Some(0.05),
        tile: 32,
        zstd_level: 3,
        ..BakeOptions::default()
    };
    let load = clipsat::source::LoadOptions::default();
    package::set_bake::bake_set(&tiles, &load, &opts, &set, clipsat::Progress::default())
        .expect("bake the set");
    (dir, set)
}

/// A package set streams as a package does: within the budget, allocating nothing per frame while its
/// tiles' decodes take the shared rANS lookups for one part after another.
#[test]
fn a_package_set_streams_without_allocating() {
    let (dir, set) = baked_set("clipsat-stream-set");
    let mut p = profile();
    // The smallest tile cache beside the set's parts and shared lookups.
    p.budget.cpu_memory_bytes +=
        Package::open(&set).expect("open").header().set_bytes + (128 << 10);
    let budget = p.budget.update_samples_per_frame;
    let mut a = Clipmap::streamed(
        Package::open(&set).expect("open"),
        &p,
        ClipmapOptions::default(),
    )
    .expect("streamed clipmap");
    let frames = 1500;
    let mut hashes = Vec::with_capacity(frames as usize);
    fly(&mut a, 100, budget, &mut hashes);
    let before = a.tile_cache().expect("streamed").stats();
    let allocations = count(|| fly_from(&mut a, 100..frames, budget, &mut hashes));
    let after = a.tile_cache().expect("streamed").stats();
    assert_eq!(allocations, 0, "allocations while streaming a set");
    assert!(after.decoded > before.decoded, "{before:?} -> {after:?}");
    let mut b = Clipmap::streamed(
        Package::open(&set).expect("open"),
        &p,
        ClipmapOptions::default(),
    )
    .expect("streamed clipmap");
    let mut again = Vec::with_capacity(frames as usize);
    fly(&mut b, frames, budget, &mut again);
    assert_eq!(hashes, again, "frame hashes differ between runs");
    let _ = std::fs::remove_dir_all(&dir);
}
