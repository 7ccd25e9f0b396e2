//! Stage 3, the GPU: one frame of the renderer: [`Renderer::prepare`] uploads a plan (ring rectangles, pool
//! tiles, uniforms, pool cells), [`Renderer::render`] records its draw calls into the caller's render pass.

use super::sg::SgPrograms;
use super::Renderer;
use crate::plan::clipmap::Clipmap;
use crate::plan::fragment::FragmentPath;
use crate::plan::frame_plan::FramePlan;
use crate::profile::{DRAW_SLOT_BYTES, POOL_CELL_BYTES};
use crate::{Error, Result};

/// What [`Renderer::prepare`] sent.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PrepareStats {
    /// `write_texture` calls.
    pub uploads: u32,
    /// Texels (samples) they copied.
    pub upload_samples: u64,
    /// Bytes they copied.
    pub upload_bytes: u64,
    /// Whether every level was re-sent in full (only for a plan that does not follow the last one
    /// prepared, e.g. one from another planner).
    pub full_upload: bool,
    /// Detail pool tiles written; their samples are in `upload_samples`.
    pub detail_tiles: u32,
    /// SG table texels written (`sg_tables.rs`): the same texels as the ring rectangles, so the same
    /// per-frame sample budget; not in `upload_samples`.
    pub sg_samples: u64,
}

impl Renderer {
    /// Uploads `plan` (built by a [`crate::plan::frame_plan::Planner`] from `clipmap`'s last frame): its
    /// rectangles from `clipmap`'s rings into the height texture, and its uniforms. A plan of the frame
    /// already prepared uploads no rectangles; a plan that does not follow the last one prepared (its
    /// [`FramePlan::since`] is another frame) re-sends every level in full. Creates nothing.
    pub fn prepare(
        &mut self,
        queue: &wgpu::Queue,
        clipmap: &Clipmap,
        plan: &FramePlan,
    ) -> Result<PrepareStats> {
        let index = clipmap.frame().index;
        if plan.frame_index() != Some(index) {
            return Err(Error::StalePlan {
                planned: plan.frame_index(),
                current: index,
            });
        }
        if plan.planned().len() > self.max_draws as usize {
            return Err(Error::Capacity {
                what: "draw calls per frame (budget.max_draws)",
                capacity: self.max_draws as usize,
            });
        }
        if plan.pool_cells().len() > self.pool_cell_capacity {
            return Err(Error::Capacity {
                what: "detail pool cells per frame",
                capacity: self.pool_cell_capacity,
            });
        }
        let mut stats = PrepareStats::default();
        let s = self.size;
        let mut write = |level: u32, x: u32, y: u32, w: u32, h: u32| {
            let ring = clipmap.ring(level);
            queue.write_texture(
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
            stats.upload_samples += u64::from(w) * u64::from(h);
        };
        let mut sg_uploads = None;
        if self.synced != Some(index) {
            if plan.since().is_none() || plan.since() == self.synced {
                for u in plan.uploads() {
                    write(u.level, u.tex_x, u.tex_y, u.w, u.h);
                }
                sg_uploads = Some(Some(plan.uploads()));
            } else {
                stats.full_upload = true;
                for level in 0..self.levels {
                    write(level, 0, 0, s, s);
                }
                sg_uploads = Some(None);
            }
        }
        // The SG tables follow the rings' texels (sg_tables.rs).
        if let (Some(sg), Some(list)) = (self.sg.as_mut(), sg_uploads) {
            stats.sg_samples += sg.tables.upload(queue, clipmap, list);
        }
        stats.upload_bytes = stats.upload_samples * 8;
        self.synced = Some(index);
        self.prepare_detail(queue, clipmap, plan, &mut stats)?;
        // The plan's globals with the colour target's encoding, which the plan does not know.
        let mut globals = *plan.globals();
        globals.shading.sun_dir[3] = self.targets.encoding();
        queue.write_buffer(&self.globals, 0, bytemuck::bytes_of(&globals));
        let slots = plan.slot_bytes();
        if !slots.is_empty() {
            queue.write_buffer(&self.draw_slots, 0, slots);
        }
        let cells = plan.cell_bytes();
        if !cells.is_empty() {
            queue.write_buffer(&self.pool_cells, 0, cells);
        }
        self.prepared.clear();
        for d in plan.planned() {
            self.prepared.push(d.clone()).map_err(|_| Error::Capacity {
                what: "draws per frame",
                capacity: self.prepared.capacity(),
            })?;
        }
        Ok(stats)
    }

    /// Writes the plan's detail tiles, each filled from `clipmap`'s source into the staging buffer; a plan
    /// that does not follow the last one prepared re-sends every resident tile (an error for a streamed
    /// package whose tiles under one were evicted since: a streamed renderer prepares every plan).
    fn prepare_detail(
        &mut self,
        queue: &wgpu::Queue,
        clipmap: &Clipmap,
        plan: &FramePlan,
        stats: &mut PrepareStats,
    ) -> Result<()> {
        let d = plan.detail();
        if self.detail_synced == Some(d.seq) {
            return Ok(());
        }
        let chained = d.prev.is_some() && d.prev == self.detail_synced;
        let side = self.detail_atlas.side;
        let atlas = self.detail_atlas;
        let mut write = |slot: u32, key: &crate::plan::detail::TileKey| -> Result<()> {
            if !crate::plan::detail::fill_tile(
                clipmap,
                key,
                self.detail_quads,
                &mut self.detail_staging,
            ) {
                return Err(Error::Invalid {
                    what: "detail pool tile".into(),
                    reason: format!(
                        "level {} cell ({}, {}): its package tiles were evicted before this \
                         renderer re-sent it (a streamed renderer must prepare every plan)",
                        key.level, key.cx, key.cy
                    ),
                });
            }
            write_detail_tile(queue, &self.detail, atlas, &self.detail_staging, slot);
            let samples = u64::from(side) * u64::from(side);
            stats.uploads += 1;
            stats.upload_samples += samples;
            stats.upload_bytes += samples * 8;
            stats.detail_tiles += 1;
            Ok(())
        };
        if chained {
            for u in &d.uploads {
                write(u.slot, &u.key)?;
            }
        } else {
            for (slot, key) in d.resident.iter().enumerate() {
                if let Some(key) = key {
                    write(u32::try_from(slot).expect("slots <= DETAIL_CAPACITY"), key)?;
                }
            }
        }
        self.detail_synced = Some(d.seq);
        Ok(())
    }

    /// Records the prepared plan's draws into `pass` (whose attachments have the formats and sample count
    /// of [`super::RendererOptions`]). Sets its own pipeline, bind groups and buffers; creates nothing.
    pub fn render(&self, pass: &mut wgpu::RenderPass<'_>) {
        self.record(pass, None);
    }

    /// Whether frames draw with the SG programs (SG shading, switched on, no debug view).
    pub(super) fn draws_sg(&self) -> bool {
        self.sg.is_some() && self.sg_enabled && self.debug.code() == 0
    }

    /// [`Renderer::render`], with `probe`'s programs in place of the renderer's when given (the shading
    /// probe: the same draws, buffers and bind groups).
    pub(super) fn record(&self, pass: &mut wgpu::RenderPass<'_>, probe: Option<&ProbePrograms>) {
        // A debug view replaces the shading, SG included. Each draw is recorded with its own program,
        // set when it changes: basic shading's `FragmentPath`, SG's block or skirt program.
        let sg = match &self.sg {
            Some(sg) if self.draws_sg() => {
                pass.set_bind_group(2, &sg.group, &[]);
                Some(sg)
            }
            _ => None,
        };
        // Draped imagery under SG: the programs of the variant drawn, if built with the imagery.
        let sg_imagery = match (&self.imagery, sg) {
            (Some(i), Some(sg)) if probe.is_none() => match &i.sg {
                Some((v, programs)) if *v == sg.variant => {
                    pass.set_bind_group(3, &i.group, &[]);
                    Some(programs)
                }
                _ => None,
            },
            _ => None,
        };
        // Draped imagery: its programs in place of basic shading's (not under SG, a debug view or a probe).
        let imagery = match &self.imagery {
            Some(i) if sg.is_none() && probe.is_none() && self.draws_imagery() => {
                pass.set_bind_group(2, &i.group, &[]);
                Some(i)
            }
            _ => None,
        };
        pass.set_bind_group(0, &self.group0, &[]);
        let mut bound = None;
        let mut program = None;
        let mut cells_at = None;
        for (k, d) in self.prepared.iter().enumerate() {
            // A pool call's instances are its cells, from its first; any other draw reads instance 0.
            let at = u64::from(d.cells.start) * POOL_CELL_BYTES;
            if cells_at != Some(at) {
                pass.set_vertex_buffer(1, self.pool_cells.slice(at..));
                cells_at = Some(at);
            }
            let m = self.mesh(d.kind);
            if bound != Some(d.kind) {
                pass.set_vertex_buffer(0, m.vertices.slice(..));
                pass.set_index_buffer(m.indices.slice(..), wgpu::IndexFormat::Uint16);
                bound = Some(d.kind);
            }
            let (programs, pipelines) = match probe {
                Some(p) => (p.sg.as_ref(), &p.basic),
                None => (sg_imagery.or(sg.map(|s| s.programs())), &self.pipelines),
            };
            let pipeline = match (sg, programs) {
                (Some(_), Some(s)) if d.fragment == FragmentPath::Skirt => &s.skirt,
                (Some(_), Some(s)) => &s.block,
                _ => match imagery {
                    Some(i) => &i.pipelines[d.fragment as usize],
                    None => &pipelines[d.fragment as usize],
                },
            };
            if !program.is_some_and(|p| std::ptr::eq(p, pipeline)) {
                pass.set_pipeline(pipeline);
                program = Some(pipeline);
            }
            let offset =
                u32::try_from(k as u64 * DRAW_SLOT_BYTES).expect("draw slots fit a u32 offset");
            pass.set_bind_group(1, &self.group1, &[offset]);
            pass.draw_indexed(d.indices.clone(), 0, 0..d.instances());
        }
    }

    /// Forgets which frame the height texture holds: the next plan's rectangles are written as if first.
    pub fn reset_sync(&mut self) {
        self.synced = None;
        self.detail_synced = None;
    }
}

/// Writes `staging` (one detail tile's texels, filled by [`crate::plan::detail::fill_tile`]) into
/// `slot` of the pool's texture `detail`, placed by `atlas`.
pub(super) fn write_detail_tile(
    queue: &wgpu::Queue,
    detail: &wgpu::Texture,
    atlas: crate::profile::DetailAtlas,
    staging: &[[f32; 2]],
    slot: u32,
) {
    let side = atlas.side;
    let (z, x, y) = atlas.place(slot);
    queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture: detail,
            mip_level: 0,
            origin: wgpu::Origin3d { x, y, z },
            aspect: wgpu::TextureAspect::All,
        },
        bytemuck::cast_slice(staging),
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(side * 8),
            rows_per_image: Some(side),
        },
        wgpu::Extent3d {
            width: side,
            height: side,
            depth_or_array_layers: 1,
        },
    );
}

/// The programs a probe draws a prepared frame with: one per [`FragmentPath`], and the SG block and skirt
/// pair when the renderer draws SG.
#[derive(Debug)]
pub(super) struct ProbePrograms {
    pub(super) basic: [wgpu::RenderPipeline; crate::plan::fragment::FRAGMENT_PATHS],
    pub(super) sg: Option<SgPrograms>,
}
