//! Stage 2: the drawn surface's twin (`plan::drawn`, which `TerrainRenderer::drawn_height_at` answers
//! with) against the vertex shader's twin (`twin::clipmap::cpu_vertex`) at the vertices of every block
//! drawn with distance LOD's morph: the same height, morph included, within the rounding of the twin's
//! f32 eye-relative position.

use clipsat::plan::camera::Camera;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::cull::DrawKind;
use clipsat::plan::drawn::{drawn_height, Drawn};
use clipsat::plan::frame_plan::{LodSetup, PlanParams, Planner};
use clipsat::plan::mesh;
use clipsat::profile::Profile;
use clipsat::source::procedural::{generate, ProceduralParams};
use clipsat::twin::clipmap::cpu_vertex;
use glam::DVec3;

#[test]
fn drawn_height_is_the_vertex_twins_at_every_morphed_vertex() {
    let hm = generate(&ProceduralParams {
        size: 257,
        spacing: 30.0,
        ..ProceduralParams::default()
    })
    .expect("terrain");
    let profile = Profile::load("gles3-low").expect("profile");
    let mut cm = Clipmap::new(&hm, &profile, ClipmapOptions::default()).expect("clipmap");
    let mut planner = Planner::new(&profile, &cm, LodSetup::Distance).expect("planner");
    let mut plan = planner.new_plan();
    let extent = f64::from(hm.width() - 1) * f64::from(hm.spacing());
    let (_, hi) = hm.range();
    let eye = DVec3::new(extent * 0.45, extent * 0.55, f64::from(hi) + 50.0);
    let cam = Camera::new(eye, eye + DVec3::new(900.0, 400.0, -300.0), 60.0)
        .and_then(|c| c.with_clip(2.0, 6.0e5))
        .expect("camera");
    cm.fill_at(eye, 64).expect("fill");
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
