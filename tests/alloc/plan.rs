//! Proves the whole frame-planning path allocates nothing: `Clipmap::update` and `Planner::plan` (the
//! upload rectangles, SAT LOD selection, the draw list, the packed uniforms and the plan hash) under a
//! counting global allocator, on every shipped profile and every camera path. Its own test binary (the global allocator is per binary); counting is per thread, so
//! the tests may run in parallel.

use clipsat::bake::lod_tables::P;
use clipsat::bake::{bake_lod, BakeParams};
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::cull::DrawKind;
use clipsat::plan::flight::{Flight, Path};
use clipsat::plan::frame_plan::{LodSetup, PlanParams, Planner};
use clipsat::plan::lod::{Lod, LodMode};
use clipsat::profile::Profile;
use clipsat::source::procedural::{generate, ProceduralParams};
use clipsat::source::Heightmap;

use crate::counting_alloc::count;

/// The SAT LOD tables of `hm` for clipmap `cm` (baked once into the test cache folder).
fn lod_tables(hm: &Heightmap, prof: &Profile, cm: &Clipmap) -> Lod {
    let params = BakeParams {
        p: P,
        levels: prof.clipmap.levels,
        synth_levels: 0,
        g0: cm.g0(),
    };
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("alloc-lod-cache");
    let (tables, _) = bake_lod(
        hm,
        cm.pyramid(),
        &params,
        &dir,
        clipsat::Progress::default(),
    )
    .expect("LOD tables");
    Lod::for_clipmap(tables, prof, cm, hm)
}

#[test]
fn update_and_draw_list_allocate_nothing() {
    assert!(count(|| drop(std::hint::black_box(vec![1u8; 16]))) > 0);
    let hm = generate(&ProceduralParams {
        seed: 5,
        size: 513,
        spacing: 30.0,
    })
    .expect("procedural");
    for name in ["gles3-low", "gles3-mid", "desktop"] {
        let prof = Profile::load(name).expect("shipped profile");
        for synth_levels in [0, 1] {
            let mut cm =
                Clipmap::new(&hm, &prof, ClipmapOptions { synth_levels }).expect("clipmap");
            let mut planner = Planner::new(&prof, &cm, LodSetup::Distance).expect("planner");
            let mut plan = planner.new_plan();
            for path in [
                Path::Straight,
                Path::Circle,
                Path::Figure8,
                Path::Dive,
                Path::Teleport { every: 30 },
            ] {
                let flight = Flight::new(path, 150.0, &hm)
                    .expect("flight")
                    .with_fov_y_deg(f64::from(prof.view.fov_y_deg));
                // Warm-up outside the count: the first frames fill the rings.
                for f in 0..5 {
                    cm.update(flight.camera(f).eye).expect("update");
                }
                let mut frames = 0u32;
                let n = count(|| {
                    for f in 5..50 {
                        let cam = flight.camera(f);
                        cm.update(cam.eye).expect("update");
                        // Every other frame skipped, so the uploads are a union over two frames.
                        if f % 2 == 0 {
                            planner
                                .plan(&cm, &cam, &PlanParams::default(), &mut plan)
                                .expect("plan");
                        }
                        frames += 1;
                    }
                });
                assert_eq!(
                    n, 0,
                    "{name} synth {synth_levels} {path}: {n} allocations in {frames} planned frames"
                );
                assert!(!plan.draws().is_empty(), "{name} {path}: nothing drawn");
            }
        }
    }
}

/// The SAT LOD half of the planning path: `Planner::plan` in each SAT estimator.
#[test]
fn lod_selection_allocates_nothing() {
    let hm = generate(&ProceduralParams {
        seed: 5,
        size: 257,
        spacing: 30.0,
    })
    .expect("procedural");
    let prof = Profile::load("gles3-mid").expect("shipped profile");
    let mut cm = Clipmap::new(&hm, &prof, ClipmapOptions::default()).expect("clipmap");
    let lod = lod_tables(&hm, &prof, &cm);
    let flight = Flight::new(Path::Figure8, 120.0, &hm).expect("flight");
    for f in 0..5 {
        cm.update(flight.camera(f).eye).expect("update");
    }
    for mode in [LodMode::Sat, LodMode::SatConservative, LodMode::Exact] {
        let setup = LodSetup::new(mode, Some(lod.clone())).expect("tables");
        let mut planner = Planner::new(&prof, &cm, setup).expect("planner");
        let mut plan = planner.new_plan();
        let params = PlanParams {
            epsilon_px: Some(2.0),
            ..PlanParams::default()
        };
        let n = count(|| {
            for f in 5..40 {
                let cam = flight.camera(f);
                cm.update(cam.eye).expect("update");
                planner.plan(&cm, &cam, &params, &mut plan).expect("plan");
            }
        });
        assert!(!plan.lod_frame().blocks.is_empty(), "{mode:?}: no blocks");
        assert_eq!(n, 0, "{mode:?}: {n} allocations in 35 planned frames");
    }
}

/// The detail pool while it fills: at a tight epsilon on a flight, every frame keeps the ring
/// fill plus the pool's tiles within the update budget, the draw calls and triangles within theirs, the
/// refinement within its bound evaluations (its quadtrees carried from frame to frame), and allocates
/// nothing; the pool does fill and serve blocks, its cells drawn as instances (each call covers
/// the next draws of the list; a pool call's cells share level, mesh and size, one cell each; a stitched
/// run's unit calls cover its cells, one instance per unit); a second run of the same flight gives the
/// same plan hashes (deterministic).
#[test]
fn detail_pool_fills_within_budgets_without_allocating() {
    let hm = generate(&ProceduralParams {
        seed: 5,
        size: 257,
        spacing: 30.0,
    })
    .expect("procedural");
    let prof = Profile::load("gles3-mid").expect("shipped profile");
    let run = |counted: bool| -> (Vec<u64>, u32, u32, u32, usize) {
        let mut cm = Clipmap::new(&hm, &prof, ClipmapOptions::default()).expect("clipmap");
        let lod = lod_tables(&hm, &prof, &cm);
        let flight = Flight::new(Path::Figure8, 60.0, &hm).expect("flight");
        let setup = LodSetup::new(LodMode::SatConservative, Some(lod)).expect("tables");
        let mut planner = Planner::new(&prof, &cm, setup).expect("planner");
        let mut plan = planner.new_plan();
        let params = PlanParams {
            epsilon_px: Some(0.25),
            ..PlanParams::default()
        };
        let mut hashes = Vec::with_capacity(64);
        let (mut most_tiles, mut most_served, mut most_instances) = (0, 0, 0);
        let mut stitched_units = 0;
        let b = &prof.budget;
        let n = count(|| {
            for f in 0..48 {
                let cam = flight.camera(f);
                cm.update(cam.eye).expect("update");
                planner.plan(&cm, &cam, &params, &mut plan).expect("plan");
                let s = plan.stats();
                let spent = u64::from(cm.frame().samples_updated) + s.detail_samples_updated;
                assert!(
                    spent <= u64::from(b.update_samples_per_frame),
                    "frame {f}: {spent} samples"
                );
                assert!(s.draws <= b.max_draws, "frame {f}: {} draws", s.draws);
                assert!(
                    s.triangles <= u64::from(b.max_triangles),
                    "frame {f}: {} triangles",
                    s.triangles
                );
                assert!(s.detail_tiles_resident <= b.detail_tiles);
                assert!(
                    s.refine_evaluations <= u64::from(b.refine_bounds_per_frame),
                    "frame {f}: {} bound evaluations",
                    s.refine_evaluations
                );
                most_tiles = most_tiles.max(s.detail_tiles_resident);
                most_served = most_served.max(s.blocks_from_pool);
                let draws = plan.draws();
                let mut next = 0;
                let mut run = 0..0;
                let mut instances = 0;
                for c in plan.planned() {
                    instances += c.cells.len();
                    if matches!(c.kind, DrawKind::PoolUnit | DrawKind::PoolUnitSkirt) {
                        // A run of stitched cells of one level: one call per unit mesh its units use.
                        assert!(
                            c.draws == run || c.draws.start == next,
                            "frame {f}: unit calls cover their runs in order"
                        );
                        let d0 = draws[c.draws.start as usize];
                        for i in c.draws.clone() {
                            let d = draws[i as usize];
                            assert!(d.stitch != 0 && d.pool.is_some() && d.level == d0.level);
                        }
                        run = c.draws.clone();
                        next = c.draws.end;
                        stitched_units += c.cells.len();
                        continue;
                    }
                    assert_eq!(
                        c.draws.start, next,
                        "frame {f}: calls cover the draws in order"
                    );
                    next = c.draws.end;
                    if c.cells.is_empty() {
                        assert_eq!(c.draws.len(), 1, "frame {f}: one draw a call");
                        continue;
                    }
                    assert_eq!(c.cells.len(), c.draws.len(), "frame {f}: a cell per draw");
                    let d0 = draws[c.draws.start as usize];
                    for i in c.draws.clone() {
                        let d = draws[i as usize];
                        assert!(
                            d.pool.is_some()
                                && (d.level, d.kind, d.quads) == (d0.level, d0.kind, d0.quads)
                        );
                    }
                    most_instances = most_instances.max(c.instances());
                }
                assert_eq!(
                    next as usize,
                    draws.len(),
                    "frame {f}: every draw in a call"
                );
                let whole = draws
                    .iter()
                    .filter(|d| d.pool.is_some() && d.stitch == 0)
                    .count();
                assert!(plan.pool_cells().len() >= whole, "frame {f}");
                assert_eq!(plan.pool_cells().len(), instances, "frame {f}");
                assert_eq!(s.pool_cells as usize, instances, "frame {f}");
                hashes.push(plan.hash());
            }
        });
        if counted {
            assert_eq!(
                n, 0,
                "{n} allocations in 48 planned frames with the detail pool"
            );
        }
        (
            hashes,
            most_tiles,
            most_served,
            most_instances,
            stitched_units,
        )
    };
    let (first, tiles, served, instances, units) = run(true);
    assert!(
        tiles > 0 && served > 0,
        "the pool never filled ({tiles} tiles) or served ({served} blocks)"
    );
    assert!(instances > 1, "no pool call drew more than one cell");
    assert!(units > 0, "no cell was drawn stitched");
    let (second, _, _, _, _) = run(false);
    assert_eq!(first, second, "the same flight gave other plan hashes");
}
