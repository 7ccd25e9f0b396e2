//! Stage 3, the GPU: the SG shading inputs per clipmap level (issue 16, "Memory"; GC section 6's normal
//! maps kept per level, like the heights).
//!
//! Two 2D array textures of the rings' size S, toroidal like the height texture (texel = lattice sample
//! mod S, one layer per ring):
//!
//! - `level_normal` (RGBA32F, [`Profile::sg_normal_layers`]): the vMF input r, the mean of the data's unit
//!   normals over the box of 2^k + 1 data samples centred on the sample of a ring k levels coarser than
//!   the data ([`ShadingBake::level_texel`]);
//! - `level_horizon` (RGBA16F, 4 azimuths a layer, [`Profile::sg_horizon_layers`]), only when the scene
//!   has visibility: the sines of the sample's D horizon angles (the shader needs no trigonometry per azimuth).
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

use super::{array_texture, Ledgered, PrepareStats, READ_BACK};
use crate::gpu::sat_textures::ShadingBake;
use crate::plan::clipmap::Clipmap;
use crate::plan::frame::Upload;
use crate::{Error, Profile, Result};

/// The normal table's format: f32 r, so |r| near 1 (kappa up to 1e4) keeps its precision.
const NORMAL_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
/// The horizon table's format: f16 sines, an error below 5e-4.
const HORIZON_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

/// The per-level tables, their views, the CPU bake they are filled from and the staging they are filled
/// through (allocated once).
#[derive(Debug)]
pub(super) struct SgTables {
    normal: wgpu::Texture,
    pub(super) normal_view: wgpu::TextureView,
    horizon: Option<wgpu::Texture>,
    pub(super) horizon_view: Option<wgpu::TextureView>,
    bake: ShadingBake,
    size: u32,
    levels: u32,
    /// Horizon layers per ring, ceil(D / 4) (0: no visibility).
    horizon_layers: u32,
    staging_normal: Vec<[f32; 4]>,
    staging_horizon: Vec<[u16; 4]>,
}

impl SgTables {
    /// Creates the tables for `profile` (`visibility`: with the horizon table of `bake`'s D azimuths).
    pub(super) fn new(
        dev: &mut Ledgered<'_>,
        profile: &Profile,
        bake: &ShadingBake,
        visibility: bool,
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
        let horizon = (d > 0).then(|| {
            make(
                "sg level_horizon",
                profile.sg_horizon_layers(d),
                HORIZON_FORMAT,
            )
        });
        let array = wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        };
        let normal_view = dev.view("sg level_normal view", &normal, &array);
        let horizon_view = horizon
            .as_ref()
            .map(|t| dev.view("sg level_horizon view", t, &array));
        let texels = size as usize * size as usize;
        let horizon_layers = d.div_ceil(4);
        Ok(Self {
            normal,
            normal_view,
            horizon,
            horizon_view,
            bake: bake.clone(),
            size,
            levels: profile.clipmap.levels,
            horizon_layers,
            staging_normal: vec![[0.0; 4]; texels],
            staging_horizon: vec![[0; 4]; texels * horizon_layers as usize],
        })
    }

    /// The normal table.
    pub(super) fn normal(&self) -> &wgpu::Texture {
        &self.normal
    }

    /// Horizon layers per ring (ceil(D / 4); 0 without visibility).
    pub(super) fn horizon_layers(&self) -> u32 {
        self.horizon_layers
    }

    /// Writes the tables' texels of `uploads` (the plan's ring rectangles), or of every ring when
    /// `None`, from the bake at the clipmap's current clip regions. Counts the samples in `stats`.
    pub(super) fn upload(
        &mut self,
        queue: &wgpu::Queue,
        clipmap: &Clipmap,
        uploads: Option<&[Upload]>,
        stats: &mut PrepareStats,
    ) {
        match uploads {
            Some(list) => {
                for u in list {
                    self.write(queue, clipmap, u);
                    stats.sg_samples += u64::from(u.w) * u64::from(u.h);
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
                    stats.sg_samples += u64::from(self.size) * u64::from(self.size);
                }
            }
        }
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
        let hl = self.horizon_layers as usize;
        let texels = u.w as usize * u.h as usize;
        for ty in 0..u.h {
            // The lattice row of the clip region stored in texel row tex_y + ty.
            let j = clip.y0 + (i64::from(u.tex_y + ty) - clip.y0).rem_euclid(s);
            for tx in 0..u.w {
                let i = clip.x0 + (i64::from(u.tex_x + tx) - clip.x0).rem_euclid(s);
                let (r, hz) = self.bake.level_texel(data_level, i, j);
                let at = ty as usize * u.w as usize + tx as usize;
                self.staging_normal[at] = [r.x, r.y, r.z, 0.0];
                for layer in 0..hl {
                    let mut px = [0u16; 4];
                    for (c, v) in px.iter_mut().enumerate() {
                        *v = half::f16::from_f32(hz.get(4 * layer + c).map_or(0.0, |a| a.sin()))
                            .to_bits();
                    }
                    self.staging_horizon[layer * texels + at] = px;
                }
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
        if let Some(horizon) = &self.horizon {
            for layer in 0..self.horizon_layers {
                let at = layer as usize * texels;
                queue.write_texture(
                    target(horizon, u.level * self.horizon_layers + layer),
                    bytemuck::cast_slice(&self.staging_horizon[at..at + texels]),
                    layout(8),
                    extent,
                );
            }
        }
    }
}
