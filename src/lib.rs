//! clipsat: fixed-budget terrain rendering for OpenGL ES 3.0 class GPUs.
//!
//! Data flows one way, and each module holds one stage:
//!
//! ```text
//! source (files, procedural) -> Heightmap
//!   -> bake (pyramid, error SATs, normal and visibility SATs; cached)
//!   -> per-frame plan (CPU, pure, allocation-free: clipmap update, LOD, culling, draw list, frame hash)
//!   -> gpu (wgpu on the GLES 3.0 floor) -> image -> image hash
//! ```
//!
//! Everything is sized at start-up from a budget [`Profile`]; per-frame work is bounded in samples and
//! primitives, and deterministic.

pub mod bake;
pub mod budget;
pub mod camera;
pub mod clipmap;
pub mod cull;
mod error;
pub mod flight;
pub mod frame;
pub mod gpu;
pub mod hash;
mod heightmap;
pub mod horizon;
pub mod lod;
pub mod mesh;
pub mod plot;
pub mod profile;
pub mod pyramid;
pub mod renderer;
pub mod sat;
pub mod scene;
pub mod sg;
pub mod shading;
pub mod source;
pub mod synthesis;

pub use camera::Camera;
pub use error::{Error, Result};
pub use heightmap::Heightmap;
pub use profile::Profile;

/// Where the shared terrain data lives: `$CLIPSAT_DATA`, else `../shared/data` beside the crate.
pub fn data_dir() -> std::path::PathBuf {
    std::env::var_os("CLIPSAT_DATA")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data"))
}
