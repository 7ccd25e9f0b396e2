//! Shading: the CPU twin of the fragment shader's reduced SG integration (SAT paper section 5,
//! algorithms 2 and 3; docs/design.md "Shading: reduced SG integration") and the f64 reference it is measured
//! against.
//!
//! [`shade`] is f32, allocation-free and written as the WGSL will be: fixed loops over lights, theta
//! bands and phi sectors, no library calls WGSL lacks. [`reference()`] integrates the same light transport
//! densely in f64 with the true clamped cosine (averaged over the vMF normal distribution) and ray-marched
//! visibility, so every approximation of [`shade`] shows up in its error.
//!
//! The approximations of [`shade`], each measured by `tests/cpu/shading.rs`:
//! - a sharp light (a sun, lambda >= [`SHARP_LAMBDA`]) is one direction: its integral times the
//!   vMF-averaged clamped cosine at its axis ([`vmf_cosine`], the vMF's moments with a Gaussian) times
//!   its fraction above the horizon;
//! - for the other lights the clamped cosine is one SG (lambda 2.133, mu 1.17; [`crate::shading::sg::COSINE_LAMBDA`]), widened by the vMF
//!   with [`sg::Sg::convolve_vmf`], and cut at the mean normal's tangent plane lowered by the vMF's angular
//!   spread ([`plane_drop`]);
//! - the broad lights' integral above the lowered plane is tabulated per scene over the mean normal's
//!   direction and |r| ([`SkyTable`], 32^2 x 16 texels, read bilinearly in two layers);
//! - what the horizon hides of it is subtracted per pair of baked azimuths: the wedge between the
//!   lowered plane and the horizon (the pair's mean sine), integrated over sin(elevation) by 2-point
//!   Gauss-Legendre; the horizon is held and interpolated as sines;
//! - specular: Fresnel = 1 (folded into k_s), the implicit geometry term G = (n.i)(n.o), so the BRDF is
//!   D(h) / 4; the cosine is taken at the product lobe's axis and visibility as the fraction of the lobe's
//!   one-sigma cap above the horizon: the first sun's at the sun's azimuth, every other lobe's (whose
//!   axis moves with the view) at the horizon's mean over the azimuths;
//! - with visibility, everything that does not depend on the view (the diffuse term of every light but
//!   the first sun with the horizon applied, the horizon's mean, the sun's horizon) is [`texel_light`],
//!   computed per texel of the renderer's per-level tables when the texel is written; the shader blends
//!   4 texels of it bilinearly rather than blending the inputs (r, horizons) and integrating per pixel,
//!   and adds the first sun's diffuse term per pixel, cut at the blended horizon sine toward it, so its
//!   shadow edges stay sharp within a texel. [`shade`] is
//!   [`texel_light`] then [`shade_pixel`] of one set of inputs.
//!
//! Files: `basic.rs` (the basic shading's parameters), `scene.rs` (lights, material, effects), `sg.rs` (spherical Gaussians and the vMF), `sky_table.rs` (the per-scene sky table), `integrate.rs`
//! ([`shade`], the CPU twin of `shaders_gles/sg_shading.wgsl`), `reference.rs` ([`reference()`], the f64
//! reference) and `debug_view.rs` (the debug views' CPU side).

pub mod basic;
pub mod debug_view;
mod integrate;
mod reference;
pub mod scene;
mod shade;
pub mod sg;
pub mod sky_table;

pub use integrate::{
    plane_drop, vmf_cosine, warped_ndf, Inputs, Patches, MAX_BANDS, MAX_SECTORS, SHARP_LAMBDA,
};
pub use shade::{shade, shade_pixel, shade_pixel_scaled, texel_light, TexelLight, TexelLighting};
pub use reference::{reference, HorizonTable, RefCosine, RefGrid, RefInputs};
pub use sky_table::SkyTable;
