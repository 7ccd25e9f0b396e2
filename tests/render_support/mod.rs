//! Shared pieces of the GPU test binary (`tests/gpu`): a GPU, terrains, profiles and camera paths.

#![expect(
    unreachable_pub,
    reason = "test support: `pub` items of a private module"
)]

use std::path::Path;

use clipsat::bake::lod_tables::P;
use clipsat::bake::{bake_lod, BakeParams};
use clipsat::gpu::{Gpu, GpuMode};
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::lod::Lod;
use clipsat::{Camera, Heightmap, Profile};
use glam::DVec3;

/// A strict OpenGL ES 3.0 context (Mesa llvmpipe); panics with the fix when there is none.
pub fn strict() -> Gpu {
    Gpu::new(GpuMode::Strict).unwrap_or_else(|e| {
        panic!("strict OpenGL ES 3.0 context on Mesa llvmpipe (run `bash .ci/setup`): {e}")
    })
}

/// A 513 x 513 terrain at 30 m with relief that does not depend on the procedural generator (a stub on
/// this branch): ridges, a valley below sea level and short waves, so every level has slopes.
pub fn relief() -> Heightmap {
    let n = 513u32;
    let heights = (0..n * n)
        .map(|i| {
            let (u, v) = ((i % n) as f32, (i / n) as f32);
            let ridge = 900.0 * (-((u - 300.0).powi(2) + (v - 200.0).powi(2)) / 9000.0).exp();
            let ridge2 = 600.0 * (-((u - 120.0).powi(2) + (v - 380.0).powi(2)) / 4000.0).exp();
            let waves =
                80.0 * (u * 0.071).sin() * (v * 0.053).cos() + 25.0 * (u * 0.31 + v * 0.17).sin();
            u * 0.8 + (512.0 - v) * 0.4 - 60.0 + ridge + ridge2 + waves
        })
        .collect();
    Heightmap::new(Path::new("<relief>"), n, n, 30.0, heights).expect("valid synthetic terrain")
}

/// A 257 x 257 terrain at 20 m: terraced steps and a cone (sharp creases, unlike `relief`).
pub fn terraces() -> Heightmap {
    let n = 257u32;
    let heights = (0..n * n)
        .map(|i| {
            let (u, v) = ((i % n) as f32, (i / n) as f32);
            let r = ((u - 128.0).powi(2) + (v - 128.0).powi(2)).sqrt();
            let cone = (400.0 - 3.0 * r).max(0.0);
            let steps = ((u + v) / 24.0).floor() * 35.0;
            cone + steps
        })
        .collect();
    Heightmap::new(Path::new("<terraces>"), n, n, 20.0, heights).expect("valid synthetic terrain")
}

/// A shipped profile with a small viewport (and optionally another update budget).
pub fn profile(name: &str, width: u32, height: u32, budget: Option<u32>) -> Profile {
    let mut p = Profile::load(name).expect("shipped profile");
    p.view.width = width;
    p.view.height = height;
    if let Some(b) = budget {
        p.budget.update_samples_per_frame = b;
    }
    p
}

pub fn clipmap(hm: &Heightmap, p: &Profile) -> Clipmap {
    Clipmap::new(hm, p, ClipmapOptions::default()).expect("clipmap")
}

/// The terrain height under (x, y) (nearest sample, clamped).
#[expect(
    clippy::cast_possible_truncation,
    reason = "rounded test coordinates, clamped on lookup"
)]
pub fn ground(hm: &Heightmap, x: f64, y: f64) -> f64 {
    let s = f64::from(hm.spacing());
    let u = (x / s).round() as i64;
    let v = (f64::from(hm.height() - 1) - y / s).round() as i64;
    f64::from(hm.at_clamped(u, v))
}

/// A camera at `eye` looking along `dir` (x east, y north, z up); clip planes that hold every ring.
pub fn camera(eye: DVec3, dir: DVec3) -> Camera {
    Camera::new(eye, eye + dir, 60.0)
        .and_then(|c| c.with_clip(2.0, 6.0e5))
        .expect("camera")
}

/// Frame `i` of a straight flight east-north-east at `speed` m per frame, `alt` m above the ground,
/// looking ahead and down; at frame `teleport` (if any) the path jumps 6 km north.
pub fn flight(hm: &Heightmap, i: u32, speed: f64, alt: f64, teleport: Option<u32>) -> Camera {
    let t = f64::from(i);
    let mut x = 900.0 + speed * t;
    let mut y = 2500.0 + 0.3 * speed * t;
    if teleport.is_some_and(|k| i >= k) {
        y += 6000.0;
        x -= 2000.0;
    }
    let z = ground(hm, x, y).max(0.0) + alt;
    camera(DVec3::new(x, y, z), DVec3::new(1.0, 0.3, -0.35))
}

/// Puget Sound 1k (160 m spacing, 0.1 m units) from the shared data, or `None` with a printed reason
/// when it is missing (a failure under `CI=true`).
pub fn puget() -> Option<Heightmap> {
    let path = clipsat::data_dir().join("ps_height_1k.png");
    if !path.exists() {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "{} is missing (shared data must be present on CI)",
            path.display()
        );
        eprintln!("skipping: {} is missing", path.display());
        return None;
    }
    let opts = clipsat::source::LoadOptions {
        spacing: Some(160.0),
        height_scale: Some(0.1),
        ..Default::default()
    };
    Some(clipsat::source::load(&path, &opts).expect("Puget Sound loads"))
}

/// The SAT LOD selector for `cm`'s terrain, with the bake cache in the test target folder.
pub fn lod(hm: &Heightmap, p: &Profile, cm: &Clipmap) -> Lod {
    let params = BakeParams {
        p: P,
        levels: p.clipmap.levels,
        synth_levels: cm.synth_levels(),
        g0: cm.g0(),
    };
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("lod-cache");
    let (tables, _) = bake_lod(hm, cm.pyramid(), &params, &dir, false).expect("LOD tables");
    Lod::for_clipmap(tables, p, cm, hm)
}

/// The headless renderer with distance LOD and basic shading.
pub fn renderer<'g>(
    gpu: &'g Gpu,
    p: &Profile,
    cm: &Clipmap,
) -> clipsat::gpu::headless::Offscreen<'g> {
    clipsat::gpu::headless::Offscreen::new(gpu, p, cm, Default::default()).expect("renderer")
}

/// The headless renderer in LOD `mode` (with `lod`'s tables for the SAT modes) and debug view `debug`.
pub fn renderer_in<'g>(
    gpu: &'g Gpu,
    p: &Profile,
    cm: &Clipmap,
    mode: clipsat::plan::lod::LodMode,
    lod: Option<&Lod>,
    debug: clipsat::shading::debug_view::DebugView,
) -> clipsat::gpu::headless::Offscreen<'g> {
    let lod = clipsat::plan::frame_plan::LodSetup::new(mode, lod.cloned()).expect("LOD tables");
    clipsat::gpu::headless::Offscreen::new(
        gpu,
        p,
        cm,
        clipsat::gpu::headless::OffscreenOptions {
            lod,
            debug,
            ..Default::default()
        },
    )
    .expect("renderer")
}

/// The height of the surface `draws` draw at level-0 lattice point (u, v) (fractional), the highest where
/// several blocks meet there (their skirts close the step between them); None where no block draws it.
/// Each block is its level's piecewise-linear surface of the data pyramid, split along the project's
/// (i, j)-(i+1, j+1) diagonal, as the clipmap shader draws it (SAT LOD draws do not morph).
#[expect(
    clippy::cast_possible_truncation,
    reason = "lattice cells of points in the view, far below 2^53"
)]
fn drawn_height(
    cm: &Clipmap,
    draws: &clipsat::plan::cull::DrawList,
    block_quads: u32,
    u: f64,
    v: f64,
) -> Option<f64> {
    use clipsat::plan::cull::DrawKind;
    let synth = cm.synth_levels();
    let mut best: Option<f64> = None;
    for d in draws.iter().filter(|d| d.kind == DrawKind::Block) {
        let c = d.covered(block_quads);
        let f = f64::from(1u32 << d.fine);
        let inside = u >= c.x0 as f64 * f
            && u <= (c.x1() - 1) as f64 * f
            && v >= c.y0 as f64 * f
            && v <= (c.y1() - 1) as f64 * f;
        let Some(k) = d.level.checked_sub(synth).filter(|_| inside) else {
            continue;
        };
        let s = f64::from(1u32 << d.level);
        let (x, y) = (u / s, v / s);
        let (i, j) = (x.floor() as i64, y.floor() as i64);
        let (fx, fy) = (x - i as f64, y - j as f64);
        let z = |a: i64, b: i64| f64::from(cm.pyramid().at(k, a, b));
        let h = if fx >= fy {
            z(i, j) + fx * (z(i + 1, j) - z(i, j)) + fy * (z(i + 1, j + 1) - z(i + 1, j))
        } else {
            z(i, j) + fx * (z(i + 1, j + 1) - z(i, j + 1)) + fy * (z(i, j + 1) - z(i, j))
        };
        best = Some(best.map_or(h, |b: f64| b.max(h)));
    }
    best
}

/// Whether the view ray through pixel (x, y) of `r`'s last frame passes below the surface its blocks draw
/// while inside the data (the fragment shader cuts everything beyond the data's border, inset as
/// `outside_data` insets it): a clear pixel there is a hole in the drawn surface. A ray that leaves the
/// data through its side above the surface sees past the terrain's edge: clear is right there, even with
/// terrain above it in the same pixel column (a far, higher part of the border seen over a near, low one).
#[expect(
    clippy::cast_possible_truncation,
    reason = "the step count is capped at 10^6"
)]
pub fn ray_below_drawn_surface(
    r: &clipsat::gpu::headless::Offscreen<'_>,
    cm: &Clipmap,
    cam: &Camera,
    block_quads: u32,
    (x, y): (u32, u32),
) -> bool {
    let g = r.globals();
    let (w, h) = r.size();
    let inv = glam::Mat4::from_cols_array(&g.view_proj)
        .as_dmat4()
        .inverse();
    let nx = (f64::from(x) + 0.5) / f64::from(w) * 2.0 - 1.0;
    let ny = 1.0 - (f64::from(y) + 0.5) / f64::from(h) * 2.0;
    let a = inv * glam::DVec4::new(nx, ny, 0.0, 1.0);
    let b = inv * glam::DVec4::new(nx, ny, 1.0, 1.0);
    let (a, b) = (a.truncate() / a.w, b.truncate() / b.w);
    let e = g.extent.map(f64::from);
    let tol = 0.02 + 4.0e-6 * e.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let (lo, hi) = ([e[0] + tol, e[1] + tol], [e[2] - tol, e[3] - tol]);
    let (eu, ev) = cm.eye_lattice(cam.eye);
    let g0 = cm.g0();
    let steps = ((b - a).truncate().length() / (g0 / 8.0)).ceil().min(1.0e6) as u32;
    (0..=steps).any(|i| {
        let p = a + (b - a) * (f64::from(i) / f64::from(steps.max(1)));
        let inside = (0..2).all(|k| p[k] >= lo[k] && p[k] <= hi[k]);
        inside
            && drawn_height(cm, r.draws(), block_quads, eu + p.x / g0, ev - p.y / g0)
                .is_some_and(|z| cam.eye.z + p.z < z)
    })
}
