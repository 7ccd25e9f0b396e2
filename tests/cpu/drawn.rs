//! Stage 2: the drawn surface's twin (`plan::drawn`, which `TerrainRenderer::drawn_height_at` answers
//! with) against the vertex shader's twins (`twin::clipmap::cpu_vertex`, `cpu_detail_vertex`) at the
//! vertices of every block drawn with distance LOD's morph, and of every block and detail pool cell SAT
//! LOD draws: the same height, morph included, within the rounding of the twin's f32 eye-relative
//! position.

use clipsat::plan::camera::Camera;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::cull::DrawKind;
use clipsat::plan::drawn::{drawn_height, Drawn};
use clipsat::plan::frame_plan::{LodSetup, PlanParams, Planner};
use clipsat::plan::mesh;
use clipsat::profile::Profile;
use clipsat::source::procedural::{generate, ProceduralParams};
use clipsat::source::Heightmap;
use clipsat::twin::clipmap::{cpu_detail_vertex, cpu_vertex, CpuVertex};
use glam::DVec3;

/// The procedural 257^2 terrain at 30 m on gles3-low, its clipmap filled at an eye 50 m above the highest
/// sample looking north-east and down: the frame both tests check.
fn scene() -> (Heightmap, Profile, Clipmap, DVec3, Camera) {
    let hm = generate(&ProceduralParams {
        size: 257,
        spacing: 30.0,
        ..ProceduralParams::default()
    })
    .expect("terrain");
    let profile = Profile::load("gles3-low").expect("profile");
    let mut cm = Clipmap::new(&hm, &profile, ClipmapOptions::default()).expect("clipmap");
    let extent = f64::from(hm.width() - 1) * f64::from(hm.spacing());
    let (_, hi) = hm.range();
    let eye = DVec3::new(extent * 0.45, extent * 0.55, f64::from(hi) + 50.0);
    let cam = Camera::new(eye, eye + DVec3::new(900.0, 400.0, -300.0), 60.0)
        .and_then(|c| c.with_clip(2.0, 6.0e5))
        .expect("camera");
    cm.fill_at(eye, 64).expect("fill");
    (hm, profile, cm, eye, cam)
}

#[test]
fn drawn_height_is_the_vertex_twins_at_every_morphed_vertex() {
    let (_, profile, cm, eye, cam) = scene();
    let mut planner = Planner::new(&profile, &cm, LodSetup::Distance).expect("planner");
    let mut plan = planner.new_plan();
    let params = PlanParams {
        viewport: Some((320, 180)),
        ..PlanParams::default()
    };
    planner.plan(&cm, &cam, &params, &mut plan).expect("plan");
    assert!(plan.globals().params[0] != 0.0, "distance LOD morphs");
    let block = mesh::block(profile.block_m());
    let (mut checked, mut morphed, mut worst) = (0u32, 0u32, 0.0f64);
    for (k, d) in plan.draws().iter().enumerate() {
        if d.kind != DrawKind::Block || d.stitch != 0 {
            continue;
        }
        let u = plan.draw_uniform(k);
        for v in &block.vertices {
            let c = cpu_vertex(plan.globals(), &u, cm.ring(d.level), *v);
            let (x, y) = (eye.x + f64::from(c.rel[0]), eye.y + f64::from(c.rel[1]));
            let (lu, lv) = cm.eye_lattice(DVec3::new(x, y, 0.0));
            let Drawn::Height(h) = drawn_height(&cm, &plan, profile.block_m(), lu, lv) else {
                panic!("draw {k}: nothing drawn at vertex {v:?} ({x}, {y})");
            };
            // The twin's eye-relative position is f32: up to a few ulp of its distance across a slope
            // of at most 4.
            let r = f64::from(c.rel[0].abs().max(c.rel[1].abs()));
            let tol = 1e-4 + 4.0 * 4.0 * r * f64::from(f32::EPSILON);
            let e = (h - f64::from(c.height)).abs();
            assert!(
                e <= tol,
                "draw {k} level {} vertex {v:?}: drawn {h}, twin {} (alpha {})",
                d.level,
                c.height,
                c.alpha
            );
            worst = worst.max(e);
            checked += 1;
            morphed += u32::from(c.alpha > 0.0);
        }
    }
    eprintln!("{checked} vertices, {morphed} morphed: drawn within {worst:.2e} m of the twin");
    assert!(morphed > 100, "{morphed} morphed vertices of {checked}");
}

/// The tolerance of a twin vertex's height against the drawn surface's at its position: its
/// eye-relative position is f32, up to a few ulp of its distance across a slope of at most 4.
fn tolerance(c: &CpuVertex) -> f64 {
    let r = f64::from(c.rel[0].abs().max(c.rel[1].abs()));
    1e-4 + 4.0 * 4.0 * r * f64::from(f32::EPSILON)
}

/// SAT LOD at 0.5 px, the detail pool filled at a still camera: every block (snapped tiles included)
/// and every pool cell drawn, at each of its surface vertices, against `drawn_height`. Inside a draw the
/// two agree; on its border the drawn surface is the highest of the draws that meet there (their skirts
/// close the step), so never below the vertex.
#[test]
fn drawn_height_is_the_vertex_twins_under_sat_lod() {
    use clipsat::bake::lod_tables::LodTables;
    use clipsat::plan::detail::fill_tile;
    use clipsat::plan::lod::{Lod, LodMode};

    let (hm, profile, mut cm, eye, cam) = scene();
    let tables = LodTables::build(cm.pyramid(), profile.clipmap.levels, 2, |_| {}).expect("tables");
    let lod = Lod::for_clipmap(tables, &profile, &cm, &hm);
    let mut planner = Planner::new(
        &profile,
        &cm,
        LodSetup::new(LodMode::SatConservative, Some(lod)).expect("setup"),
    )
    .expect("planner");
    let mut plan = planner.new_plan();
    let params = PlanParams {
        epsilon_px: Some(0.5),
        viewport: Some((320, 180)),
        ..PlanParams::default()
    };
    for _ in 0..256 {
        planner.plan(&cm, &cam, &params, &mut plan).expect("plan");
        let wrote = plan.stats().detail_uploads;
        if clipsat::engine::setup::pool_step(&mut cm, eye, &plan, wrote).expect("pool step") {
            break;
        }
    }
    planner.plan(&cm, &cam, &params, &mut plan).expect("plan");
    let m = profile.block_m();
    let block = mesh::block(m);
    let cells = mesh::pool_cells(profile.pool_mesh_quads());
    let quads = profile.detail_quads();
    let side = profile.detail_side() as usize;
    let atlas = profile.detail_atlas();
    let ls = atlas.layer_side() as usize;
    let mut tile = vec![[0.0f32; 2]; side * side];
    let mut layer = vec![[f32::NAN; 2]; ls * ls];
    let (mut inside, mut border, mut pool, mut worst) = (0u32, 0u32, 0u32, 0.0f64);
    for (k, d) in plan.draws().iter().enumerate() {
        let is_pool = d.kind == DrawKind::PoolCell;
        if d.stitch != 0 || !(d.kind == DrawKind::Block || is_pool) {
            continue;
        }
        let u = plan.draw_uniform(k);
        if let Some(slot) = d.pool {
            let key = plan.detail().resident[usize::from(slot)].expect("a drawn slot is resident");
            assert!(fill_tile(&cm, &key, quads, &mut tile), "resident source");
            layer.fill([f32::NAN; 2]);
            let (_, x0, y0) = atlas.place(u32::from(slot));
            for (r, row) in tile.chunks_exact(side).enumerate() {
                let at = (y0 as usize + r) * ls + x0 as usize;
                layer[at..at + side].copy_from_slice(row);
            }
        }
        let c = d.covered(m);
        let f = f64::from(1u32 << d.fine);
        let mesh = if is_pool { &cells } else { &block };
        // The surface's vertices (a skirt's lower edge is not the surface).
        for v in mesh.vertices.iter().filter(|v| v[2] == 0) {
            let t = if is_pool {
                cpu_detail_vertex(plan.globals(), &u, &layer, atlas.layer_side(), *v)
            } else {
                cpu_vertex(plan.globals(), &u, cm.ring(d.level), *v)
            };
            let (x, y) = (eye.x + f64::from(t.rel[0]), eye.y + f64::from(t.rel[1]));
            let (lu, lv) = cm.eye_lattice(DVec3::new(x, y, 0.0));
            #[expect(clippy::cast_precision_loss, reason = "lattice cells of the view")]
            let (x0, y0, x1, y1) = (
                c.x0 as f64 * f,
                c.y0 as f64 * f,
                (c.x1() - 1) as f64 * f,
                (c.y1() - 1) as f64 * f,
            );
            let slack = 1e-6 * f;
            if lu < x0 - slack || lu > x1 + slack || lv < y0 - slack || lv > y1 + slack {
                continue; // a vertex of the mesh past this draw's cell
            }
            let Drawn::Height(h) = drawn_height(&cm, &plan, m, lu, lv) else {
                panic!("draw {k}: nothing drawn at vertex {v:?} ({x}, {y})");
            };
            let tol = tolerance(&t);
            let e = h - f64::from(t.height);
            let on_border =
                lu <= x0 + slack || lu >= x1 - slack || lv <= y0 + slack || lv >= y1 - slack;
            if on_border {
                assert!(
                    e >= -tol,
                    "draw {k} level {} border vertex {v:?}: drawn {h} below the twin's {}",
                    d.level,
                    t.height
                );
                border += 1;
            } else {
                assert!(
                    e.abs() <= tol,
                    "draw {k} level {} (pool {is_pool}) vertex {v:?}: drawn {h}, twin {}",
                    d.level,
                    t.height
                );
                worst = worst.max(e.abs());
                inside += 1;
                pool += u32::from(is_pool);
            }
        }
    }
    eprintln!(
        "SAT LOD: {inside} inner vertices ({pool} of pool cells) within {worst:.2e} m of the twins, \
         {border} border vertices at or above them"
    );
    assert!(
        pool > 100 && inside > 1000,
        "{pool} pool vertices, {inside} inner"
    );
}
