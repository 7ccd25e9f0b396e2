//! Shading, the per-scene bake: the sky table, the unshadowed diffuse integral of every broad light (sky
//! lobe) tabulated over the mean normal's direction and spread, so the fragment shader reads it with 8
//! fetches instead of integrating M x N patches per light per pixel (the per-patch SG x cosine integrals
//! tabulated once per scene in a small texture: docs/design.md, "Shading: reduced SG integration").
//!
//! With the horizon left out, a broad light's diffuse term (SAT paper eq. 11 over the patches of
//! `integrate.rs`'s product lobe, cut at the lowered tangent plane) depends only on the vMF fitted
//! to the pixel's mean normal r: its axis n and its mean resultant length |r| (kappa and the plane's drop
//! follow from |r|). The lights are fixed per scene, so the sum over them is one RGB function of three
//! parameters, computed once here on the CPU by the same patch integration:
//!
//! - n, hemi-octahedrally: p = n_xy / (|n_x| + |n_y| + n_z), (u, v) = (p_x + p_y, p_x - p_y) in [-1, 1]^2
//!   (continuous over the upper hemisphere; n_z < 0 is clamped to the border), [`SG_SKY_SIDE`]^2 texels
//!   at the grid's nodes (texel i at u = 2 i / (SIDE - 1) - 1);
//! - |r| as s = sqrt(1 - |r|), [`SG_SKY_LAYERS`] layers uniform in s over [S_MIN, S_MAX] (the plane's
//!   drop sqrt(2 / kappa) is nearly linear in s for |r| near 1, where most pixels are).
//!
//! Layer l of the RGBA32F texture is the SIDE x SIDE tile at x = l SIDE of a (SIDE LAYERS) x SIDE
//! texture; the shader blends 2 layers of 4 texels each (float textures are not filterable on GLES 3.0),
//! and [`SkyTable::lookup`] is its CPU twin. Horizon visibility is applied per pixel on top
//! (`integrate.rs` `occluded`), since it varies per texel of the terrain.

use glam::Vec3;

use super::integrate::{self, Patches};
use super::scene::Scene;
use super::sg::{Sg, Vmf, R_MAX, R_MIN};
pub use crate::profile::{SG_SKY_LAYERS, SG_SKY_SIDE};

/// Smallest s = sqrt(1 - |r|) of the table: |r| = [`R_MAX`].
pub const S_MIN: f32 = 0.01;
/// Largest s: |r| = 0 (clamped to [`R_MIN`] by the vMF).
pub const S_MAX: f32 = 1.0;

const SIDE: usize = SG_SKY_SIDE as usize;
const LAYERS: usize = SG_SKY_LAYERS as usize;

/// The sky table of one scene at one patch count: RGB (linear, before k_d / pi) per texel, alpha unused.
#[derive(Clone, Debug, PartialEq)]
pub struct SkyTable {
    patches: Patches,
    texels: Vec<[f32; 4]>,
}

/// The continuous texel coordinates (x, y in [0, SIDE - 1], layer in [0, LAYERS - 1]) of unit `n` and
/// mean resultant length `r_len`; the WGSL `sg_sky` computes the same.
#[expect(clippy::cast_precision_loss, reason = "small table sides")]
pub fn coords(n: Vec3, r_len: f32) -> (f32, f32, f32) {
    let inv = 1.0 / (n.x.abs() + n.y.abs() + n.z.max(0.0)).max(1e-30);
    let (px, py) = (n.x * inv, n.y * inv);
    let half = 0.5 * (SIDE - 1) as f32;
    let top = (SIDE - 1) as f32;
    let x = ((px + py) * half + half).clamp(0.0, top);
    let y = ((px - py) * half + half).clamp(0.0, top);
    let s = (1.0 - r_len.clamp(R_MIN, R_MAX)).sqrt();
    let l = ((s - S_MIN) * ((LAYERS - 1) as f32 / (S_MAX - S_MIN))).clamp(0.0, (LAYERS - 1) as f32);
    (x, y, l)
}

/// The unit normal at texel (i, j) (the inverse of [`coords`]' direction part).
#[expect(clippy::cast_precision_loss, reason = "small table sides")]
fn texel_normal(i: usize, j: usize) -> Vec3 {
    let u = 2.0 * i as f32 / (SIDE - 1) as f32 - 1.0;
    let v = 2.0 * j as f32 / (SIDE - 1) as f32 - 1.0;
    let (px, py) = (0.5 * (u + v), 0.5 * (u - v));
    Vec3::new(px, py, (1.0 - px.abs() - py.abs()).max(0.0)).normalize()
}

/// The mean resultant length of layer l.
#[expect(clippy::cast_precision_loss, reason = "small table sides")]
fn layer_len(l: usize) -> f32 {
    let s = S_MIN + (S_MAX - S_MIN) * l as f32 / (LAYERS - 1) as f32;
    1.0 - s * s
}

impl SkyTable {
    /// Integrates every broad light of `scene` (lambda below [`super::SHARP_LAMBDA`]) over `patches` at
    /// each texel: SIDE^2 LAYERS patch integrations per light, once per scene.
    pub fn new(scene: &Scene, patches: Patches) -> Self {
        let broad: Vec<&Sg> = scene
            .lights
            .iter()
            .filter(|l| l.lambda < super::SHARP_LAMBDA)
            .collect();
        let mut texels = vec![[0.0f32; 4]; SIDE * SIDE * LAYERS];
        if !broad.is_empty() {
            for l in 0..LAYERS {
                let len = layer_len(l);
                for j in 0..SIDE {
                    for i in 0..SIDE {
                        let vmf = Vmf::from_mean_normal(texel_normal(i, j) * len);
                        let mut sum = Vec3::ZERO;
                        for light in &broad {
                            sum += integrate::unshadowed(light, &vmf, patches);
                        }
                        texels[j * SIDE * LAYERS + l * SIDE + i] = [sum.x, sum.y, sum.z, 0.0];
                    }
                }
            }
        }
        Self { patches, texels }
    }

    /// The patch grid the table was integrated over.
    pub fn patches(&self) -> Patches {
        self.patches
    }

    /// The texels, row-major over a (SIDE LAYERS) x SIDE texture.
    pub fn texels(&self) -> &[[f32; 4]] {
        &self.texels
    }

    fn at(&self, l: usize, i: usize, j: usize) -> Vec3 {
        let t = self.texels[j * SIDE * LAYERS + l * SIDE + i];
        Vec3::new(t[0], t[1], t[2])
    }

    /// The table at unit `n` and mean resultant length `r_len`: bilinear in each of the two nearest
    /// layers, linear between them (the WGSL `sg_sky`, operation for operation).
    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "floors of coordinates clamped into the table"
    )]
    pub fn lookup(&self, n: Vec3, r_len: f32) -> Vec3 {
        let (x, y, l) = coords(n, r_len);
        let i = (x.floor() as usize).min(SIDE - 2);
        let j = (y.floor() as usize).min(SIDE - 2);
        let k = (l.floor() as usize).min(LAYERS - 2);
        #[expect(clippy::cast_precision_loss, reason = "small table sides")]
        let (fx, fy, fl) = (x - i as f32, y - j as f32, l - k as f32);
        let layer = |k: usize| {
            let a = mix(self.at(k, i, j), self.at(k, i + 1, j), fx);
            let b = mix(self.at(k, i, j + 1), self.at(k, i + 1, j + 1), fx);
            mix(a, b, fy)
        };
        mix(layer(k), layer(k + 1), fl)
    }
}

/// WGSL's mix.
fn mix(a: Vec3, b: Vec3, f: f32) -> Vec3 {
    a * (1.0 - f) + b * f
}
