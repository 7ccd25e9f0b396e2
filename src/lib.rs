//! clipsat: fixed-budget terrain rendering for OpenGL ES 3.0 class GPUs.
//!
//! clipsat draws large height fields on GPUs with no tessellation, no compute and no storage buffers
//! (Android-class GLES 3.0) inside a budget fixed at start-up, combining geometry clipmaps (Losasso &
//! Hoppe 2004), summed-area-table LOD and reduced spherical-Gaussian shading (Li et al. 2021). Every
//! buffer is sized once from a budget [`Profile`]; each frame's work is bounded in samples and
//! primitives, and each frame's plan has a deterministic 64-bit hash.
//!
//! # Embedding
//!
//! The terrain draws into **your** wgpu device and **your** render pass. A [`Terrain`] is opened once
//! (a file, streamed through a package baked into a cache folder on first use), a [`TerrainRenderer`] is
//! built once with [`RenderOptions`]; then per frame, [`TerrainRenderer::prepare`] with the camera and
//! the viewport, and [`TerrainRenderer::render`] into your pass. A resize changes only the viewport.
//!
//! ```no_run
//! use clipsat::{Profile, RenderOptions, Terrain, TerrainRenderer};
//! # fn frame(device: &wgpu::Device, queue: &wgpu::Queue, pass: &mut wgpu::RenderPass<'_>)
//! #     -> Result<(), clipsat::Error> {
//! let profile = Profile::load("gles3-mid")?;
//! let terrain = Terrain::open("N57E011.hgt", Some(std::path::Path::new("cache")))?;
//! let camera = terrain.default_camera()?;
//! let options = RenderOptions::default().sat_lod_px(1.0);
//! let mut renderer = TerrainRenderer::new(device, queue, terrain, &profile, &options)?;
//! // Per frame:
//! renderer.prepare(queue, &camera, (1920, 1080))?;
//! renderer.render(pass);
//! # Ok(())
//! # }
//! ```
//!
//! `examples/own_device.rs` is that, complete: its own device, targets and pass, through a resize.
//!
//! # Pipeline
//!
//! Data flows one way through the stages (ARCHITECTURE.md has the files and the invariants):
//!
//! ```text
//! source/   files (PNG, GeoTIFF, SRTM .hgt, DTED, ESRI grids, XYZ, raw) or procedural -> Heightmap
//!   -> bake/    height pyramid, SATs, LOD tables, horizons (cached)
//!   -> package/ the pyramid in compressed, checksummed tiles, read through a memory map into a fixed
//!               tile cache
//!   -> plan/    per frame, CPU, pure, allocation-free: budgeted clipmap update -> per-block LOD
//!               -> frustum cull -> draw list, packed uniforms -> plan hash
//!   -> gpu/     wgpu on the GLES 3.0 floor (the only stage that touches wgpu): upload, draw, shade
//! engine/   the embedding API above, over the stages (it takes the caller's device, queue and pass)
//! ```
//!
//! The stages' own modules are the internal API of the `clipsat` binary and the tests: public only with
//! the `internals` feature, and not covered by semver.

// Without `internals` the stages' modules are private: their `pub` items are the internal API of the
// binary, the tests and the benches, so the library alone leaves some of them unused and unreachable.
// Both lints still run on the `internals` build, which every test run compiles.
#![cfg_attr(
    not(feature = "internals"),
    expect(
        dead_code,
        unreachable_pub,
        unused_imports,
        reason = "the stages' internal API serves the binary and the tests (the `internals` feature)"
    )
)]

/// The stages' modules: private to the library's users, public with the `internals` feature (the
/// binary's, the tests', the benches').
macro_rules! stages {
    ($($name:ident),* $(,)?) => {$(
        #[cfg(feature = "internals")]
        pub mod $name;
        #[cfg(not(feature = "internals"))]
        mod $name;
    )*};
}

stages!(
    bake,
    engine,
    gpu,
    hash,
    package,
    plan,
    profile,
    profile_imagery,
    shading,
    source
);
// Measurements of drawn frames and the shaders' CPU twins: for tests and the binary only.
mod error;
#[cfg(feature = "internals")]
pub mod measure;
mod progress;
mod temp;
#[cfg(feature = "internals")]
pub mod twin;

pub use bake::lod_tables::LodMode;
pub use engine::{
    Camera, FrameOptions, FrameStats, Profile, RayHit, RenderOptions, Terrain, TerrainOptions,
    TerrainRenderer,
};
pub use error::{BoxError, Error, Param, Result};
pub use progress::{Progress, ProgressReport};
pub use shading::debug_view::DebugView;

/// The README's Rust blocks, compiled as doctests: its embedding example stays true to the API.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

/// The guide's Rust blocks, compiled as doctests.
#[cfg(doctest)]
#[doc = include_str!("../docs/guide.md")]
struct GuideDoctests;

#[cfg(feature = "internals")]
/// Where the shared terrain data lives: `$CLIPSAT_DATA`, else `../shared/data` beside the crate.
pub fn data_dir() -> std::path::PathBuf {
    std::env::var_os("CLIPSAT_DATA")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data"))
}

/// A temporary file name's suffix that no other live writer uses: the process id, so that processes
/// sharing a cache folder never write the same file, and a counter, so that threads of one process
/// (a library caller baking two terrains at once) do not either. Each cached file is written under such
/// a name and renamed into place; the bake's own temporaries are locked while they live, so that a
/// later run can remove those a killed bake left ([`temp`]).
pub(crate) fn temp_suffix() -> String {
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    format!("{}-{n}", std::process::id())
}
