//! Shared pieces of the GPU test binary (`tests/gpu`): a GPU, terrains, profiles and camera paths.

#![expect(
    unreachable_pub,
    reason = "test support: `pub` items of a private module"
)]

use std::path::Path;

use clipsat::bake::lod_tables::P;
use clipsat::bake::{bake_lod, BakeParams};
use clipsat::gpu::{Gpu, GpuMode};
use clipsat::plan::camera::Camera;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::lod::Lod;
use clipsat::profile::Profile;
use clipsat::source::Heightmap;
use glam::DVec3;

/// The GPU the tests draw on: a strict OpenGL ES 3.0 context (Mesa llvmpipe), or the backend
/// `CLIPSAT_GPU` names (`vulkan`: wgpu's Vulkan backend, lavapipe, on the same GLES 3.0 limits); panics
/// with the fix when there is none.
pub fn strict() -> Gpu {
    let mode = GpuMode::from_env()
        .map(|m| m.expect("CLIPSAT_GPU names a GPU mode"))
        .unwrap_or(GpuMode::Strict);
    Gpu::new(mode).unwrap_or_else(|e| {
        panic!("{mode:?} GPU (run `bash .ci/setup`: Mesa's llvmpipe with EGL, and lavapipe): {e}")
    })
}

/// Whether the tests run on wgpu's Vulkan backend (`CLIPSAT_GPU=vulkan`).
pub fn on_vulkan() -> bool {
    matches!(GpuMode::from_env(), Some(Ok(GpuMode::Vulkan)))
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
    let (tables, _) = bake_lod(
        hm,
        cm.pyramid(),
        &params,
        &dir,
        clipsat::Progress::default(),
    )
    .expect("LOD tables");
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
