//! Proves the whole frame-planning path allocates nothing: `Clipmap::update`, SAT LOD selection and
//! `cull::build_draws` / `build_lod_draws` under a counting global allocator, on every shipped profile and
//! every camera path. Its own test binary (the global allocator is per binary); counting is per thread, so
//! the tests may run in parallel.

use clipsat::bake::lod_tables::P;
use clipsat::bake::{bake_lod, BakeParams};
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::cull::{build_draws, build_lod_draws, DrawList, DrawParams};
use clipsat::plan::flight::{Flight, Path};
use clipsat::plan::lod::{Lod, LodFrame, LodMode};
use clipsat::source::procedural::{generate, ProceduralParams};
use clipsat::Profile;

mod counting_alloc;
use counting_alloc::count;

/// The renderer's draw parameters for `cam`: culling and skirts on, the data's extent (last sample at
/// `data_lattice` data cells, `k` level-0 cells each) relative to the eye.
fn draw_params(
    cm: &Clipmap,
    cam: &clipsat::Camera,
    prof: &Profile,
    data_lattice: (f64, f64),
    k: f64,
) -> DrawParams {
    let p = cm.eye_lattice(cam.eye);
    let g0 = cm.g0();
    DrawParams {
        block_quads: (prof.clipmap.n + 1) / 4,
        max_draws: prof.budget.max_draws,
        cull: true,
        skirts: true,
        aspect: f64::from(prof.view.width) / f64::from(prof.view.height),
        extent: [
            -p.0 * g0,
            -(data_lattice.1 * k - p.1) * g0,
            (data_lattice.0 * k - p.0) * g0,
            p.1 * g0,
        ],
    }
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
    let data_lattice = (f64::from(hm.width() - 1), f64::from(hm.height() - 1));
    for name in ["gles3-low", "gles3-mid", "desktop"] {
        let prof = Profile::load(name).expect("shipped profile");
        for synth_levels in [0, 1] {
            let mut cm =
                Clipmap::new(&hm, &prof, ClipmapOptions { synth_levels }).expect("clipmap");
            let k = f64::from(1u32 << synth_levels);
            let mut draws = DrawList::new();
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
                        let params = draw_params(&cm, &cam, &prof, data_lattice, k);
                        build_draws(&cm, &cam, &params, &mut draws).expect("draws");
                        frames += 1;
                    }
                });
                assert_eq!(
                    n, 0,
                    "{name} synth {synth_levels} {path}: {n} allocations in {frames} planned frames"
                );
                assert!(!draws.is_empty(), "{name} {path}: nothing drawn");
            }
        }
    }
}

/// The SAT LOD half of the planning path: `Lod::select` and `build_lod_draws` in each SAT estimator.
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
    let params = BakeParams {
        p: P,
        levels: prof.clipmap.levels,
        synth_levels: 0,
        g0: cm.g0(),
    };
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("alloc-lod-cache");
    let (tables, _) = bake_lod(&hm, cm.pyramid(), &params, &dir, false).expect("LOD tables");
    let lod = Lod::for_clipmap(tables, &prof, &cm, &hm);
    let mut lod_frame = LodFrame::new_boxed();
    let mut draws = DrawList::new();
    let data_lattice = (f64::from(hm.width() - 1), f64::from(hm.height() - 1));
    let flight = Flight::new(Path::Figure8, 120.0, &hm).expect("flight");
    for f in 0..5 {
        cm.update(flight.camera(f).eye).expect("update");
    }
    for mode in [LodMode::Sat, LodMode::SatConservative, LodMode::Exact] {
        let n = count(|| {
            for f in 5..40 {
                let cam = flight.camera(f);
                cm.update(cam.eye).expect("update");
                lod.select(cm.frame(), &cam, mode, &mut lod_frame)
                    .expect("select");
                let params = draw_params(&cm, &cam, &prof, data_lattice, 1.0);
                build_lod_draws(&cm, &cam, &params, &lod_frame, &mut draws).expect("draws");
            }
        });
        assert_eq!(n, 0, "{mode:?}: {n} allocations in 35 planned frames");
    }
}
