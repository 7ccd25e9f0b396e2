//! clipsat: fixed-budget terrain rendering for OpenGL ES 3.0 class GPUs.
//!
//! clipsat renders large height fields on GPUs with no tessellation, no compute and no storage buffers
//! (Android-class GLES 3.0), inside a budget fixed at start-up. It combines three published techniques:
//!
//! - **geometry clipmaps** (Losasso & Hoppe 2004): nested rings of n x n vertices around the viewer, updated
//!   toroidally under a per-frame budget of samples ([`plan::clipmap`], [`plan::budget`]);
//! - **summed-area-table LOD** (Li et al. 2021, eq. 6 and algorithm 1): each block takes the coarsest level
//!   whose screen-space error bound, estimated in O(1) from SATs, stays under epsilon pixels ([`bake::sat`],
//!   [`bake::lod_tables`], [`plan::lod`]);
//! - **reduced spherical-Gaussian shading** (Li et al. 2021, section 5): SG lights, a vMF normal
//!   distribution and SAT-filtered visibility, integrated in closed form over 4 x 8 patches
//!   ([`shading::sg`], [`shading`], [`bake::horizon`], [`shading::scene`]).
//!
//! Everything is sized once from a budget [`Profile`]; per-frame work is bounded in samples and primitives,
//! and every frame has a deterministic 64-bit hash.
//!
//! # Pipeline
//!
//! Data flows one way, and each folder holds one stage (ARCHITECTURE.md has the files and invariants):
//!
//! ```text
//! source/   files (PNG, GeoTIFF, SRTM .hgt, ASCII grid, raw) or procedural -> Heightmap
//!   -> bake/    height pyramid, SATs, LOD tables, horizons (cached)
//!   -> package/ the pyramid as GC section 7 residuals in compressed, checksummed tiles (`clipsat bake`),
//!               read through a memory map into a fixed tile cache sized by `budget.cpu_memory_bytes`
//!   -> plan/    per frame, CPU, pure, allocation-free: camera path -> budgeted clipmap update
//!               -> per-block LOD -> frustum cull -> draw list, packed uniforms -> frame hash
//!   -> gpu/     wgpu on the GLES 3.0 floor (the only module that touches wgpu): upload, draw, shade,
//!               read back                                             -> image, image hash
//! shading/  the SG and basic shading maths (CPU side), twin/ the CPU twins of the shaders,
//! measure/  screen error, cracks and RMSE of drawn frames
//! ```
//!
//! The plan is a pure function of (terrain, profile, camera path, frame index), so `clipsat fly` runs it
//! without a GPU. The image hash is exact for a given driver.
//!
//! # Getting started, headless
//!
//! Render one frame of a small procedural terrain and read its hashes. On a machine without a GPU this runs
//! on Mesa llvmpipe through EGL (`bash .ci/setup` installs it).
//!
//! ```
//! use clipsat::gpu::headless::{render_frame, FrameOptions, Offscreen, OffscreenOptions};
//! use clipsat::gpu::{Gpu, GpuMode};
//! use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
//! use clipsat::plan::flight::{Flight, Path};
//! use clipsat::source::procedural::{generate, ProceduralParams};
//! use clipsat::Profile;
//!
//! # fn main() -> clipsat::Result<()> {
//! // A source: 257 x 257 samples at 30 m.
//! let terrain = generate(&ProceduralParams { size: 257, ..ProceduralParams::default() })?;
//! // The budget everything is sized from, with a small viewport.
//! let mut profile = Profile::load("gles3-low")?;
//! (profile.view.width, profile.view.height) = (160, 90);
//! // The per-frame plan: a camera from a flight path, a budgeted clipmap update, its frame hash.
//! let camera = Flight::new(Path::Figure8, 50.0, &terrain)?.camera(0);
//! let mut clipmap = Clipmap::new(&terrain, &profile, ClipmapOptions::default())?;
//! let plan_hash = clipmap.update(camera.eye)?.hash;
//! // The GPU: a strict OpenGL ES 3.0 context if Mesa offers one, and a renderer sized from the profile
//! // (LOD mode and shading fixed here: distance LOD, basic shading).
//! let gpu = Gpu::new(GpuMode::Auto)?;
//! let mut renderer = Offscreen::new(&gpu, &profile, &clipmap, OffscreenOptions::default())?;
//! // One frame: the plan (uploads, LOD, draws, uniforms) as a value, uploaded, drawn, read back.
//! let frame = render_frame(&mut renderer, &clipmap, &camera, &FrameOptions::default())?;
//! assert_eq!((frame.image.width, frame.image.height), (160, 90));
//! println!(
//!     "clipmap {plan_hash:016x}, plan {:016x}, image {:016x}",
//!     renderer.plan().hash(),
//!     frame.image_hash
//! );
//! # Ok(())
//! # }
//! ```
//!
//! `examples/embed.rs` does the same for three frames along a path, on the procedural terrain or a file.
//!
//! # On your own device, in your own render pass
//!
//! The renderer itself ([`gpu::renderer::Renderer`]) takes the caller's `wgpu::Device` and `wgpu::Queue`
//! (GLES 3.0 downlevel limits suffice) and records into the caller's `wgpu::RenderPass`, the pattern of
//! egui-wgpu and glyphon:
//!
//! ```text
//! let mut planner = Planner::new(&profile, &clipmap, LodSetup::Distance)?;   // CPU, once
//! let mut plan = planner.new_plan();                                           // preallocated, once
//! let mut terrain = Renderer::new(&device, &queue, &RendererOptions { color_format, .. }, &profile)?;
//! // per frame:
//! clipmap.update(camera.eye)?;
//! planner.plan(&clipmap, &camera, &PlanParams::default(), &mut plan)?;       // pure, allocation-free
//! terrain.prepare(&queue, &clipmap, &plan)?;                                   // uploads
//! terrain.render(&mut pass);                                                   // draws into your pass
//! ```
//!
//! `examples/own_device.rs` is that, complete: its own instance, adapter, device, targets and pass.

pub mod bake;
mod error;
pub mod gpu;
pub mod hash;
pub mod measure;
pub mod package;
pub mod plan;
pub mod profile;
pub mod shading;
pub mod source;
pub mod twin;

pub use error::{Error, Param, Result};
pub use plan::camera::Camera;
pub use profile::Profile;
pub use source::Heightmap;

/// Where the shared terrain data lives: `$CLIPSAT_DATA`, else `../shared/data` beside the crate.
pub fn data_dir() -> std::path::PathBuf {
    std::env::var_os("CLIPSAT_DATA")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data"))
}

/// A temporary file name's suffix that no other live writer uses: the process id, so that processes
/// sharing a cache folder never write the same file, and a counter, so that threads of one process
/// (a library caller baking two terrains at once) do not either. Each cached file is written under such
/// a name and renamed into place.
pub(crate) fn temp_suffix() -> String {
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    format!("{}-{n}", std::process::id())
}
