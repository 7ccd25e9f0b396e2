//! CPU twins of the shaders in `shaders_gles/`: the same arithmetic in f32 on the CPU, no wgpu, so tests
//! compare what the GPU computes against them.
//!
//! - [`clipmap`]: `shaders_gles/clipmap.wgsl` (vertex placement, morph, snapped tiles).
//! - [`shading`]: `data_surface` of `shaders_gles/clipmap.wgsl` (the data under a pixel, GC section 6).
//! - [`frame`]: a drawn frame's colours, `basic_shade` and `sg_colour` recomputed from what the shading
//!   probe read back, with the tolerance a conformant driver is held to.
//! - [`imagery`](mod@imagery): `shaders_gles/imagery.wgsl`, a pixel's albedo from the colour rings
//!   (draped imagery) at its position and footprint; [`imagery_check`] a whole imagery frame against it.
//! - [`border`]: what a frame must cover at the data's border (`outside_data`, `through_side`): the
//!   pixels whose ray meets the data, marched on the CPU.
//! - The SG integration of `shaders_gles/sg_shading.wgsl` has its twin in [`crate::shading::shade`]
//!   (with its f64 reference, [`crate::shading::reference()`]), beside the SG maths it shares; the sky
//!   table that both read is built once on the CPU by [`crate::shading::SkyTable::new`].

pub mod border;
pub mod clipmap;
pub mod frame;
pub mod imagery;
pub mod imagery_check;
pub mod shading;
