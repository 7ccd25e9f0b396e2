//! Stage 3, the GPU: the SG shading inputs per clipmap level (docs/design.md "Memory model"; GC section 6's normal
//! maps kept per level, like the heights).
//!
//! Two 2D array textures of the rings' size S, toroidal like the height texture (texel = lattice sample
//! mod S, one layer per ring):
//!
//! - `level_normal` (RGBA32F, [`Profile::sg_normal_layers`]): the vMF input r, the mean of the data's unit
//!   normals over the box of 2^k + 1 data samples centred on the sample of a ring k levels coarser than
//!   the data ([`ShadingBake::level_texel`]); with visibility, w is the horizon's sine toward the scene's
//!   first sun;
//! - `level_light` (RGBA16F, one layer per ring, [`Profile::sg_light_layers`]), only when the scene has
//!   visibility: the view-independent part of the shading at the sample
//!   ([`crate::shading::texel_light`] of its r and
//!   its D horizon angles, computed here on the CPU as the texel is written: every light's diffuse term
//!   but the first sun's with the horizon applied, and the horizon's mean sine), so the fragment shader blends 4 texels
//!   instead of fetching the D angles and integrating the horizon per pixel (the visibility
//!   precomputed per texel of each level). The scene's lights are fixed for
//!   the renderer's life, so the texels are too.
//!
//! Why not a SAT per level: a SAT entry sums everything before it, so it cannot be toroidal, and a ring
//! that moves by one column would have to rebuild its whole S^2 table (S^2 samples against the column's
//! S). The box means instead are per-sample values: the tables are written for exactly the texels of the
//! plan's ring uploads, under the same per-frame sample budget, and the fragment shader filters them by a
//! fixed 4 fetches (bilinear) on the level whose spacing matches the pixel's footprint, as a mip pyramid
//! would; the SAT paper's exact box survives in the bake, which stays in CPU memory.
//!
//! Created once from the profile and the scene's effects through [`Ledgered`], checked against
//! `budget.gpu_memory_bytes`; their bytes are [`Profile::sg_table_bytes`] for any terrain.

use super::{array_texture, Ledgered, READ_BACK};
use crate::package::shading_sats::ShadingBake;
use crate::plan::clipmap::Clipmap;
use crate::plan::frame::Upload;
use crate::shading::scene::Scene;
use crate::shading::{SkyTable, TexelLighting};
use crate::{Error, Result};
use crate::profile::Profile;

/// The normal table's format: f32 r, so |r| near 1 (kappa up to 1e4) keeps its precision.
const NORMAL_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
/// The light table's format: f16 radiance (relative error 5e-4) and sines (error below 5e-4).
const LIGHT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

/// The per-level tables, their views, the CPU bake they are filled from, what the light table's texels
/// are computed with, and the staging they are filled through (allocated once).
#[derive(Debug)]
pub(super) struct SgTables {
    normal: wgpu::Texture,
    pub(super) normal_view: wgpu::TextureView,
    light: Option<wgpu::Texture>,
    pub(super) light_view: Option<wgpu::TextureView>,
    bake: ShadingBake,
    /// The scene's lights and its sky table: the light table's inputs besides the bake.
    lighting: TexelLighting,
    sky: SkyTable,
    size: u32,
    levels: u32,
    staging_normal: Vec<[f32; 4]>,
    staging_light: Vec<[u16; 4]>,
}

impl SgTables {
    /// Creates the tables for `profile` (`visibility`: with the light table, from `bake`'s horizons),
    /// for `scene` and its sky table `sky`.
    pub(super) fn new(
        dev: &mut Ledgered<'_>,
        profile: &Profile,
        bake: &ShadingBake,
        visibility: bool,
        scene: &Scene,
        sky: &SkyTable,
    ) -> Result<Self> {
        let d = if visibility { bake.azimuths() } else { 0 };
        let need = dev
            .ledger()
            .bytes()
            .saturating_add(profile.sg_table_bytes(d));
        if need > profile.budget.gpu_memory_bytes {
            return Err(Error::config(
                &profile.name,
                "budget.gpu_memory_bytes",
                format!(
                    "the renderer with SG tables ({d} horizon azimuths) needs {need} bytes of GPU \
                     memory but the budget is {}",
                    profile.budget.gpu_memory_bytes
                ),
            ));
        }
        let size = profile.clip_size();
        let mut make = |label: &'static str, layers: u32, format| {
            dev.texture(label, &array_texture(size, layers, format, READ_BACK))
        };
        let normal = make("sg level_normal", profile.sg_normal_layers(), NORMAL_FORMAT);
        let light = (d > 0).then(|| {
            make(
                "sg level_light",
                profile.sg_light_layers(true),
                LIGHT_FORMAT,
            )
        });
        let array = wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        };
        let normal_view = dev.view("sg level_normal view", &normal, &array);
        let light_view = light
            .as_ref()
            .map(|t| dev.view("sg level_light view", t, &array));
        let texels = size as usize * size as usize;
        Ok(Self {
            normal,
            normal_view,
            staging_light: vec![[0; 4]; if light.is_some() { texels } else { 0 }],
            light,
            light_view,
            bake: bake.clone(),
            lighting: TexelLighting::new(scene),
            sky: sky.clone(),
            size,
            levels: profile.clipmap.levels,
            staging_normal: vec![[0.0; 4]; texels],
        })
    }

    /// The normal table.
    pub(super) fn normal(&self) -> &wgpu::Texture {
        &self.normal
    }

    /// The CPU bake the tables are filled from (kept for a rebuild on a new device).
    pub(super) fn bake(&self) -> &ShadingBake {
        &self.bake
    }

    /// The light table (with visibility).
    pub(super) fn light(&self) -> Option<&wgpu::Texture> {
        self.light.as_ref()
    }

    /// Writes the tables' texels of `uploads` (the plan's ring rectangles), or of every ring when
    /// `None`, from the bake at the clipmap's current clip regions. Returns the texels written.
    pub(super) fn upload(
        &mut self,
        queue: &wgpu::Queue,
        clipmap: &Clipmap,
        uploads: Option<&[Upload]>,
    ) -> u64 {
        let mut samples = 0;
        match uploads {
            Some(list) => {
                for u in list {
                    self.write(queue, clipmap, u);
                    samples += u64::from(u.w) * u64::from(u.h);
                }
            }
            None => {
                for level in 0..self.levels {
                    let whole = Upload {
                        level,
                        tex_x: 0,
                        tex_y: 0,
                        w: self.size,
                        h: self.size,
                    };
                    self.write(queue, clipmap, &whole);
                    samples += u64::from(self.size) * u64::from(self.size);
                }
            }
        }
        samples
    }

    /// Fills and writes one rectangle of ring `u.level`'s texels.
    fn write(&mut self, queue: &wgpu::Queue, clipmap: &Clipmap, u: &Upload) {
        let Some(lf) = clipmap.frame().levels.get(u.level as usize) else {
            return;
        };
        let clip = lf.clip;
        if clip.is_empty() || u.w == 0 || u.h == 0 {
            return;
        }
        let s = i64::from(self.size);
        let data_level = i32::try_from(u.level).unwrap_or(i32::MAX)
            - i32::try_from(clipmap.synth_levels()).unwrap_or(0);
        let light = self.light.is_some();
        let texels = u.w as usize * u.h as usize;
        let f16 = |x: f32| half::f16::from_f32(x).to_bits();
        for ty in 0..u.h {
            // The lattice row of the clip region stored in texel row tex_y + ty.
            let j = clip.y0 + (i64::from(u.tex_y + ty) - clip.y0).rem_euclid(s);
            for tx in 0..u.w {
                let i = clip.x0 + (i64::from(u.tex_x + tx) - clip.x0).rem_euclid(s);
                let (r, hz) = self.bake.level_texel(data_level, i, j);
                let at = ty as usize * u.w as usize + tx as usize;
                let mut w = 0.0;
                if light {
                    let sines: heapless::Vec<f32, 16> = hz.iter().map(|a| a.sin()).collect();
                    let t = self.lighting.texel(r, &sines, &self.sky);
                    w = t.sun_sin;
                    self.staging_light[at] = [
                        f16(t.diffuse.x),
                        f16(t.diffuse.y),
                        f16(t.diffuse.z),
                        f16(t.mean_sin),
                    ];
                }
                self.staging_normal[at] = [r.x, r.y, r.z, w];
            }
        }
        let extent = wgpu::Extent3d {
            width: u.w,
            height: u.h,
            depth_or_array_layers: 1,
        };
        let target = |texture, z| wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d {
                x: u.tex_x,
                y: u.tex_y,
                z,
            },
            aspect: wgpu::TextureAspect::All,
        };
        let layout = |texel_bytes: u32| wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(u.w * texel_bytes),
            rows_per_image: Some(u.h),
        };
        queue.write_texture(
            target(&self.normal, u.level),
            bytemuck::cast_slice(&self.staging_normal[..texels]),
            layout(16),
            extent,
        );
        if let Some(light) = &self.light {
            queue.write_texture(
                target(light, u.level),
                bytemuck::cast_slice(&self.staging_light[..texels]),
                layout(8),
                extent,
            );
        }
    }
}
