//! Stage 3, the GPU: one frame of the renderer: upload the clipmap's rectangles, draw the draw list, read
//! back the image.

use super::{terrain_pipeline, ObjectKind, Renderer, SLOT};
use crate::gpu::readback::Image;
use crate::gpu::shaders;
use crate::plan::clipmap::Clipmap;
use crate::plan::cull::{self, DrawParams, DrawStats};
use crate::plan::lod::LodMode;
use crate::plan::uniforms::{
    data_extent_rel, draw_uniform, lod_draw_uniform, to_f32x4, DrawUniform, Globals,
};
use crate::profile::DRAW_SLOT_BYTES;
use crate::shading::debug_view::DebugView;
use crate::{Camera, Error, Result};

/// Per-frame switches.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameOptions {
    /// Clear colour (display-encoded RGBA).
    pub clear: [f64; 4],
    /// GC 6.2 transition morphing (off: every vertex takes its own level's z).
    pub morph: bool,
    /// Frustum culling of blocks (off: every block is drawn).
    pub cull: bool,
    /// Skirts on level boundaries (off only to show the cracks they close).
    pub skirts: bool,
    /// How blocks choose their level. `Distance` draws each ring at its own level (the plain geometry
    /// clipmap); the SAT modes draw each LOD block at the level [`crate::plan::lod::Lod::select`] chose (the
    /// renderer needs [`Renderer::set_lod`]), unmorphed, with skirts where levels change.
    pub lod: LodMode,
    /// The SAT modes' screen-space error bound, pixels; None: the profile's `view.epsilon_px`.
    pub epsilon_px: Option<f32>,
    /// What the fragment shader shows: the normal shading or a debug view (level colours, wireframe).
    /// The first frame drawn in a debug view creates its program and pipeline, once.
    pub debug: DebugView,
}

impl Default for FrameOptions {
    fn default() -> Self {
        Self {
            clear: crate::shading::basic::SKY,
            morph: true,
            cull: true,
            skirts: true,
            lod: LodMode::Distance,
            epsilon_px: None,
            debug: DebugView::Normal,
        }
    }
}

/// What one frame did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameStats {
    /// Draw calls.
    pub draws: u32,
    /// Blocks drawn, culled, and skirts drawn.
    pub cull: DrawStats,
    /// Triangles submitted (the zero-area ones of clamped blocks included).
    pub triangles: u64,
    /// `write_texture` calls this frame.
    pub uploads: u32,
    /// Bytes they copied.
    pub upload_bytes: u64,
    /// Whether the whole texture was re-sent (first frame, or frames were skipped).
    pub full_upload: bool,
    /// SAT modes: LOD blocks whose wanted level is finer than the held data (see
    /// [`crate::plan::lod::LodFrame::blocks_clamped`]); 0 in distance mode.
    pub blocks_clamped: u32,
}

impl Renderer<'_> {
    /// Brings the height texture up to the clipmap's last frame: that frame's `uploads` when it directly
    /// follows the one last synced, nothing when it is the same, every level in full otherwise (the first
    /// frame of a clipmap that has run before, or frames that were never uploaded).
    pub fn upload(&mut self, clipmap: &Clipmap) -> Result<FrameStats> {
        let frame = clipmap.frame();
        let mut stats = FrameStats::default();
        let incremental = match self.synced {
            Some(i) if i == frame.index => return Ok(stats),
            Some(i) => i + 1 == frame.index,
            None => frame.index == 0,
        };
        let gpu = self.gpu;
        let s = self.size;
        let write = |stats: &mut FrameStats, level: u32, x: u32, y: u32, w: u32, h: u32| {
            let ring = clipmap.ring(level);
            gpu.queue().write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &self.heights,
                    mip_level: 0,
                    origin: wgpu::Origin3d { x, y, z: level },
                    aspect: wgpu::TextureAspect::All,
                },
                ring.bytes(),
                wgpu::TexelCopyBufferLayout {
                    offset: (u64::from(y) * u64::from(s) + u64::from(x)) * 8,
                    bytes_per_row: Some(s * 8),
                    rows_per_image: Some(h),
                },
                wgpu::Extent3d {
                    width: w,
                    height: h,
                    depth_or_array_layers: 1,
                },
            );
            stats.uploads += 1;
            stats.upload_bytes += u64::from(w) * u64::from(h) * 8;
        };
        gpu.scoped("clipmap upload", || {
            if incremental {
                for u in &frame.uploads {
                    write(&mut stats, u.level, u.tex_x, u.tex_y, u.w, u.h);
                }
            } else {
                stats.full_upload = true;
                for level in 0..self.levels {
                    write(&mut stats, level, 0, 0, s, s);
                }
            }
            Ok(())
        })?;
        self.synced = Some(frame.index);
        Ok(stats)
    }

    /// Builds the draw list of the clipmap's last frame seen from `camera`, writes the uniforms and renders
    /// into the colour target (call [`Renderer::upload`] first; [`render_frame`] does both).
    pub fn draw(
        &mut self,
        clipmap: &Clipmap,
        camera: &Camera,
        opts: &FrameOptions,
    ) -> Result<FrameStats> {
        let aspect = f64::from(self.width) / f64::from(self.height);
        let params = DrawParams {
            block_quads: self.block_quads,
            max_draws: self.max_draws,
            cull: opts.cull,
            skirts: opts.skirts,
            aspect,
            extent: data_extent_rel(clipmap, camera, self.data_lattice),
        };
        let sat = opts.lod != LodMode::Distance;
        let mut blocks_clamped = 0;
        let cull = if sat {
            let lod = self.lod.as_mut().ok_or_else(|| Error::Arg {
                arg: "--lod".into(),
                reason: format!(
                    "`{}` needs the SAT LOD tables (Renderer::set_lod)",
                    opts.lod
                ),
            })?;
            if let Some(e) = opts.epsilon_px {
                lod.set_epsilon_px(f64::from(e));
            }
            lod.select(clipmap.frame(), camera, opts.lod, &mut self.lod_frame)?;
            blocks_clamped = self.lod_frame.blocks_clamped;
            cull::build_lod_draws(clipmap, camera, &params, &self.lod_frame, &mut self.draws)?
        } else {
            cull::build_draws(clipmap, camera, &params, &mut self.draws)?
        };
        let mut triangles = 0u64;
        for (k, d) in self.draws.iter().enumerate() {
            let u = if sat {
                lod_draw_uniform(clipmap, camera, d, self.n, self.size)
            } else {
                draw_uniform(clipmap, camera, d, self.n, self.size)
            };
            let at = k * SLOT;
            self.slots[at..at + std::mem::size_of::<DrawUniform>()]
                .copy_from_slice(bytemuck::bytes_of(&u));
            triangles += u64::from(self.index_count(d) / 3);
        }
        if triangles > u64::from(self.max_triangles) {
            return Err(Error::Capacity {
                what: "triangles per frame (budget.max_triangles)",
                capacity: self.max_triangles as usize,
            });
        }
        let globals = Globals {
            view_proj: camera.view_proj_relative(aspect).to_cols_array(),
            shading: self.shading,
            params: [
                // SAT modes draw each block's own level unmorphed (skirts close the level changes), so the
                // surface is the PL(H_L) the error bound is about.
                if opts.morph && !sat { 1.0 } else { 0.0 },
                self.skirt_floor,
                self.probe_size[0] as f32,
                self.probe_size[1] as f32,
            ],
            extent: to_f32x4(data_extent_rel(clipmap, camera, self.data_lattice)),
        };
        self.last_globals = globals;
        self.ensure_debug_pipeline(opts.debug)?;
        let used = self.draws.len() * SLOT;
        let gpu = self.gpu;
        gpu.scoped("clipmap frame", || {
            let queue = gpu.queue();
            queue.write_buffer(&self.globals, 0, bytemuck::bytes_of(&globals));
            if used > 0 {
                queue.write_buffer(&self.draw_slots, 0, &self.slots[..used]);
            }
            let mut encoder =
                gpu.device()
                    .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                        label: Some("clipmap frame"),
                    });
            {
                let mut pass = crate::gpu::clear_pass(
                    &mut encoder,
                    "clipmap",
                    &self.color_view,
                    &self.depth_view,
                    opts.clear,
                );
                // A debug view replaces the shading, SG included.
                match (opts.debug.code(), &self.sg) {
                    (0, Some(sg)) => {
                        pass.set_pipeline(&sg.pipeline);
                        pass.set_bind_group(2, &sg.group, &[]);
                    }
                    (0, None) => pass.set_pipeline(&self.pipeline),
                    (k, _) => pass.set_pipeline(
                        self.debug_pipelines[k as usize - 1]
                            .as_ref()
                            .expect("ensure_debug_pipeline made it"),
                    ),
                }
                pass.set_bind_group(0, &self.group0, &[]);
                let mut bound = None;
                for (k, d) in self.draws.iter().enumerate() {
                    let m = self.mesh(d.kind);
                    if bound != Some(d.kind) {
                        pass.set_vertex_buffer(0, m.vertices.slice(..));
                        pass.set_index_buffer(m.indices.slice(..), wgpu::IndexFormat::Uint16);
                        bound = Some(d.kind);
                    }
                    let offset = u32::try_from(k as u64 * DRAW_SLOT_BYTES)
                        .expect("draw slots fit a u32 offset");
                    pass.set_bind_group(1, &self.group1, &[offset]);
                    pass.draw_indexed(self.index_range(d), 0, 0..1);
                }
            }
            gpu.queue().submit([encoder.finish()]);
            Ok(())
        })?;
        Ok(FrameStats {
            draws: u32::try_from(self.draws.len()).expect("draws <= MAX_DRAWS"),
            cull,
            triangles,
            blocks_clamped,
            ..FrameStats::default()
        })
    }

    /// Makes `view`'s program and pipeline on its first use (noted in the ledger; no memory).
    fn ensure_debug_pipeline(&mut self, view: DebugView) -> Result<()> {
        let k = match view.code() {
            0 => return Ok(()),
            k => k as usize - 1,
        };
        if self.debug_pipelines[k].is_some() {
            return Ok(());
        }
        let gpu = self.gpu;
        let pipeline = gpu.scoped("clipmap debug view", || {
            let device = gpu.device();
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("clipmap.wgsl (debug view)"),
                source: wgpu::ShaderSource::Wgsl(shaders::clipmap_view(view).into()),
            });
            Ok(terrain_pipeline(
                device,
                &self.pipeline_layout,
                &module,
                "fs_main",
            ))
        })?;
        self.ledger
            .note("clipmap debug view pipeline", ObjectKind::RenderPipeline, 0);
        self.debug_pipelines[k] = Some(pipeline);
        Ok(())
    }

    /// Reads the colour target back (into the preallocated buffer) as a tight RGBA8 image.
    pub fn read_image(&self) -> Result<Image> {
        let gpu = self.gpu;
        gpu.scoped("clipmap readback", || {
            let mut encoder =
                gpu.device()
                    .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                        label: Some("clipmap readback"),
                    });
            encoder.copy_texture_to_buffer(
                self.color.as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer: &self.readback,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(self.padded_row),
                        rows_per_image: Some(self.height),
                    },
                },
                self.color.size(),
            );
            gpu.queue().submit([encoder.finish()]);
            Ok(())
        })?;
        let rows =
            crate::gpu::readback::map_rows(gpu, &self.readback, self.padded_row, self.width * 4)?;
        Ok(Image {
            width: self.width,
            height: self.height,
            rgba: rows,
        })
    }

    /// Diagnostic (allocates a buffer; not for the frame loop): every layer of the height texture read
    /// back, `size x size` (z, z_c) texels per level, row-major, as the GPU holds them.
    pub fn read_heights(&self) -> Result<Vec<Vec<[f32; 2]>>> {
        let gpu = self.gpu;
        let s = self.size;
        let padded = (s * 8).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let mut out = Vec::new();
        for level in 0..self.levels {
            let buffer = gpu.scoped("height readback", || {
                let device = gpu.device();
                let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("height readback"),
                    size: u64::from(padded) * u64::from(s),
                    usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                    mapped_at_creation: false,
                });
                let mut encoder = device.create_command_encoder(&Default::default());
                encoder.copy_texture_to_buffer(
                    wgpu::TexelCopyTextureInfo {
                        texture: &self.heights,
                        mip_level: 0,
                        origin: wgpu::Origin3d {
                            x: 0,
                            y: 0,
                            z: level,
                        },
                        aspect: wgpu::TextureAspect::All,
                    },
                    wgpu::TexelCopyBufferInfo {
                        buffer: &buffer,
                        layout: wgpu::TexelCopyBufferLayout {
                            offset: 0,
                            bytes_per_row: Some(padded),
                            rows_per_image: Some(s),
                        },
                    },
                    wgpu::Extent3d {
                        width: s,
                        height: s,
                        depth_or_array_layers: 1,
                    },
                );
                gpu.queue().submit([encoder.finish()]);
                Ok(buffer)
            })?;
            let bytes = crate::gpu::readback::map_rows(gpu, &buffer, padded, s * 8)?;
            out.push(bytemuck::pod_collect_to_vec(&bytes));
        }
        Ok(out)
    }
}

/// One rendered frame.
#[derive(Clone, Debug)]
pub struct RenderedFrame {
    /// The read-back image.
    pub image: Image,
    /// [`Image::hash`] of it.
    pub image_hash: u64,
    /// What the frame did.
    pub stats: FrameStats,
}

/// Upload, draw and read back the clipmap's last frame: what `clipsat render` and `clipsat fly --render`
/// call once per [`Clipmap::update`].
pub fn render_frame(
    renderer: &mut Renderer<'_>,
    clipmap: &Clipmap,
    camera: &Camera,
    opts: &FrameOptions,
) -> Result<RenderedFrame> {
    let up = renderer.upload(clipmap)?;
    let mut stats = renderer.draw(clipmap, camera, opts)?;
    stats.uploads = up.uploads;
    stats.upload_bytes = up.upload_bytes;
    stats.full_upload = up.full_upload;
    let image = renderer.read_image()?;
    Ok(RenderedFrame {
        image_hash: image.hash(),
        image,
        stats,
    })
}
