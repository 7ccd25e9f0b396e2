//! The embedding API: from a terrain and a budget profile to frames drawn in the caller's own wgpu
//! device and render pass, through the stages (source, bake, package, plan, gpu) without naming them.
//!
//! Five types do it: a [`Profile`] (the budget), a [`Terrain`] (a file or the procedural terrain,
//! streamed through a package baked into a cache folder on first use), a [`TerrainRenderer`] (built once
//! on the caller's device, with [`RenderOptions`] choosing SAT LOD and SG shading), and a [`Camera`] each
//! frame. The viewport is passed each frame, so a resize rebuilds nothing, and what the frames draw (the
//! LOD mode, a debug view, SG's switches: [`FrameOptions`]) is set between frames. The renderer also answers
//! exact height and ray queries of the data ([`TerrainRenderer::height_at`],
//! [`TerrainRenderer::raycast`], a [`RayHit`]) and the drawn surface's height
//! ([`TerrainRenderer::drawn_height_at`]).

mod camera;
mod options;
mod profile;
mod query;
mod query_state;
mod renderer;
pub mod setup;
mod terrain;

pub use camera::Camera;
pub use profile::Profile;
pub use query::RayHit;
pub use renderer::{FrameOptions, FrameStats, RenderOptions, TerrainRenderer};
#[cfg(feature = "internals")]
pub use renderer::Stages;
pub use terrain::{Terrain, TerrainOptions};
