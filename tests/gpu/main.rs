//! The GPU test binary: everything that renders, headless on the strict OpenGL ES 3.0 context (Mesa
//! llvmpipe through EGL), or with `CLIPSAT_GPU=vulkan` on wgpu's Vulkan backend (lavapipe), the same
//! binary. `render_support` holds the shared terrains, profiles and contexts. Run one module with
//! `cargo test --test gpu render_lod::`.

#[path = "../render_support/mod.rs"]
mod render_support;

mod budget;
mod conformance;
mod example_embed;
mod far_origin;
mod gpu_smoke;
mod imagery;
mod profile_props;
mod query;
mod render_clipmap;
mod render_debug;
mod render_goldens;
mod render_lod;
mod sg_gpu;
mod shading_data;
mod validation;
