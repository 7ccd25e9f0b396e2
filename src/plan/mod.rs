//! Stage 2, the per-frame plan: CPU only, pure and allocation-free after construction.
//!
//! In data-flow order:
//!
//! - [`flight`] and [`camera`]: the camera of frame i, a pure function of the path and i (no clock);
//! - [`budget`], [`clipmap`], [`ring`], [`synthesis`]: the budgeted coarse-to-fine toroidal update of every ring
//!   (GC sections 3-5 and 8), recorded in a [`frame::Frame`] with its hash;
//! - [`lod`]: SAT LOD block selection over the tables of [`crate::bake::lod_tables`];
//! - [`cull`]: frustum culling into the fixed-capacity draw list ([`heights`]: the culled tiles' height
//!   ranges, kept while their texels are unchanged);
//! - [`detail`]: the detail pool, finer tiles for the blocks SAT LOD wants finer than the rings hold;
//! - [`fragment`]: which fragment program each draw needs (the cheapest that gives the same pixels);
//! - [`uniforms`]: the packed `#[repr(C)]` uniforms each draw needs;
//! - [`uploads`]: which ring rectangles the GPU copy still lacks (the union over skipped frames);
//! - [`drawn`]: the CPU twin of the surface a plan draws, the height at a point;
//! - [`frame_plan`]: all of the above for one frame as a value, the [`frame_plan::FramePlan`] the GPU
//!   stage uploads and draws;
//! - [`mesh`]: the static block meshes (built once at start-up) the draws index;
//! - [`color_rings`]: the colour clipmap of draped imagery, its own rings moved toward the viewer coarse
//!   to fine under `[imagery]`'s texel budget (a terrain without imagery has none).

pub mod budget;
pub mod camera;
pub mod clipmap;
pub mod color_rings;
pub mod constraints;
pub mod cull;
pub mod detail;
pub mod drawn;
pub mod flight;
pub mod fragment;
pub mod frame;
pub mod frame_plan;
pub mod heights;
pub mod lod;
pub mod mesh;
pub mod morph;
pub mod ring;
pub mod stream;
pub mod synthesis;
pub mod uniforms;
pub mod uploads;

/// The slot of a fixed table for key `words`: every bit of every word mixed into the low bits (a
/// multiply alone left keys such as (1, -1) and (-1, 1) on one slot).
pub(crate) fn slot_hash(words: &[u64]) -> u64 {
    let mut h = 0x243f_6a88_85a3_08d3u64;
    for &w in words {
        h = (h ^ w).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        h ^= h >> 29;
    }
    h = h.wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h ^ (h >> 32)
}
