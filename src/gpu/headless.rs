//! Stage 3, the GPU: clipsat's headless path, one user of the embeddable [`Renderer`]: the strict EGL
//! context ([`Gpu`]), offscreen colour and depth targets, a [`Planner`] and its preallocated
//! [`FramePlan`], read-back and the image hash. What `clipsat render`, `fly`, `bench`, `view` and the tests
//! draw with.
//!
//! Every wgpu call goes through [`Gpu`]'s accessors, which make its GL context current first (wgpu-hal's
//! external GLES adapter needs it current), and inside its error scopes ([`Gpu::scoped`]).

use crate::bake::horizon::DEFAULT_AZIMUTHS;
use crate::gpu::readback::Image;
use crate::gpu::renderer::{Ledger, Ledgered, PrepareStats, Renderer, RendererOptions, Shading};
use crate::package::shading_sats::ShadingBake;
use crate::gpu::Gpu;
use crate::plan::clipmap::Clipmap;
use crate::plan::cull::{self, DrawList, DrawStats};
use crate::plan::frame_plan::{FramePlan, LodSetup, PlanParams, Planner};
use crate::plan::lod::{Lod, LodFrame, LodMode};
use crate::plan::uniforms::{DrawUniform, Globals};
use crate::shading::basic::BasicShading;
use crate::shading::debug_view::DebugView;
use crate::shading::scene::Scene;
use crate::progress::Progress;
use crate::Result;
use crate::plan::camera::Camera;
use crate::source::Heightmap;
use crate::profile::Profile;

const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// What is fixed for an [`Offscreen`]'s life: the LOD mode (with its tables), the shading variant and the
/// debug view. Change them by building another `Offscreen`.
#[derive(Clone, Debug, Default)]
pub struct OffscreenOptions<'a> {
    /// How blocks choose their level.
    pub lod: LodSetup,
    /// The shading variant.
    pub shading: Shading<'a>,
    /// A debug view replacing the shading.
    pub debug: DebugView,
}

/// Per-frame switches: the plan's [`PlanParams`] and the clear colour.
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
    /// The SAT modes' screen-space error bound, pixels; None: the profile's `view.epsilon_px`.
    pub epsilon_px: Option<f32>,
}

impl Default for FrameOptions {
    fn default() -> Self {
        let p = PlanParams::default();
        Self {
            clear: crate::shading::basic::SKY,
            morph: p.morph,
            cull: p.cull,
            skirts: p.skirts,
            epsilon_px: p.epsilon_px,
        }
    }
}

impl FrameOptions {
    /// The plan's part.
    pub fn plan_params(&self) -> PlanParams {
        PlanParams {
            morph: self.morph,
            cull: self.cull,
            skirts: self.skirts,
            epsilon_px: self.epsilon_px,
            viewport: None,
        }
    }
}

/// What one frame did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Draw calls.
    pub draws: u32,
    /// Blocks drawn, culled, and skirts drawn.
    pub cull: DrawStats,
    /// Triangles submitted (the zero-area ones of clamped blocks included).
    pub triangles: u64,
    /// `write_texture` calls this frame.
    pub uploads: u32,
    /// Texels (samples) they copied.
    pub upload_samples: u64,
    /// Bytes they copied.
    pub upload_bytes: u64,
    /// Whether the whole texture was re-sent (a plan that did not follow the last one prepared).
    pub full_upload: bool,
    /// SAT modes: LOD blocks whose wanted level is finer than the held data (see
    /// [`crate::plan::lod::LodFrame::blocks_clamped`]); 0 in distance mode.
    pub blocks_clamped: u32,
    /// SAT modes: the largest screen-space bound, pixels, those blocks are drawn at (0 when none is:
    /// [`crate::plan::frame_plan::PlanStats::unmet_px`]).
    pub unmet_px: f32,
    /// Wall time of [`Planner::plan`] (LOD selection, culling, uniforms), nanoseconds.
    pub plan_ns: u64,
    /// SAT modes: blocks drawn from the detail pool.
    pub blocks_from_pool: u32,
    /// Detail pool cells drawn (instances of the pool's instanced draw calls).
    pub pool_cells: u32,
    /// Detail pool slots holding a tile.
    pub detail_tiles_resident: u32,
    /// Distinct detail tiles the plan's pool cells read.
    pub detail_tiles_needed: u32,
    /// Detail pool samples the plan wrote (charged to the update budget after the rings).
    pub detail_samples_updated: u64,
    /// SG table texels written (SG shading only): exactly the ring texels uploaded, so within the same
    /// budget.
    pub sg_samples: u64,
}

/// The tables [`Shading::Sg`] needs for `scene` over `hm` within `max_bytes` (a test's share), through
/// the binary's cache folder ([`crate::engine::setup::sg_tables`] with a profile's share), and the scene
/// as drawn (`shadows: false` drops visibility).
pub fn sg_bake(
    max_bytes: u64,
    hm: &Heightmap,
    scene: &Scene,
    shadows: bool,
) -> Result<(Scene, ShadingBake)> {
    let mut scene = scene.clone();
    scene.effects.visibility &= shadows;
    let (bake, _) = ShadingBake::bake_cached(
        hm,
        &scene.needs(),
        DEFAULT_AZIMUTHS,
        max_bytes,
        &crate::bake::default_cache_dir(),
        Progress::default(),
    )?;
    Ok((scene, bake))
}

/// Offscreen colour (RGBA8) and depth (32-bit float) targets of one size on a [`Gpu`], and the buffer
/// their colour is read back through: what a headless frame is drawn into, by the stages ([`Offscreen`])
/// or by a [`crate::TerrainRenderer`] (`clipsat render`). Created once; a frame allocates nothing.
#[derive(Debug)]
pub struct Targets<'g> {
    gpu: &'g Gpu,
    color: wgpu::Texture,
    color_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    readback: wgpu::Buffer,
    padded_row: u32,
    width: u32,
    height: u32,
    /// The targets and the read-back buffer.
    ledger: Ledger,
}

impl<'g> Targets<'g> {
    /// Targets of `width` x `height` pixels on `gpu`, in the formats [`Offscreen`]'s renderer draws.
    pub fn new(gpu: &'g Gpu, width: u32, height: u32) -> Result<Self> {
        let padded_row = (width * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        gpu.scoped("offscreen targets", || {
            let mut dev = Ledgered::new(gpu.device());
            let target = |format, usage| crate::gpu::render_target(width, height, format, usage);
            let color = dev.texture(
                "clipmap color",
                &target(
                    COLOR_FORMAT,
                    wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                ),
            );
            let depth = dev.texture(
                "clipmap depth",
                &target(DEPTH_FORMAT, wgpu::TextureUsages::RENDER_ATTACHMENT),
            );
            let color_view = dev.view("clipmap color view", &color, &Default::default());
            let depth_view = dev.view("clipmap depth view", &depth, &Default::default());
            let readback = dev.buffer(
                "clipmap readback",
                u64::from(padded_row) * u64::from(height),
                wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            );
            Ok(Self {
                gpu,
                color,
                color_view,
                depth_view,
                readback,
                padded_row,
                width,
                height,
                ledger: dev.ledger().clone(),
            })
        })
    }

    /// The colour target's format.
    pub fn color_format(&self) -> wgpu::TextureFormat {
        COLOR_FORMAT
    }

    /// The depth target's format (conventional depth, cleared to 1).
    pub fn depth_format(&self) -> wgpu::TextureFormat {
        DEPTH_FORMAT
    }

    /// (width, height), pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The targets' objects.
    pub fn ledger(&self) -> &Ledger {
        &self.ledger
    }

    /// One pass into the targets, cleared to `clear` (display-encoded RGBA) and depth 1, recorded by
    /// `record` and submitted, inside the [`Gpu`]'s error scopes.
    pub fn draw(
        &self,
        label: &str,
        clear: [f64; 4],
        record: impl FnOnce(&mut wgpu::RenderPass<'_>),
    ) -> Result<()> {
        let gpu = self.gpu;
        gpu.scoped(label, || {
            let mut encoder = gpu
                .device()
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
            {
                let mut pass = crate::gpu::clear_pass(
                    &mut encoder,
                    label,
                    &self.color_view,
                    &self.depth_view,
                    clear,
                );
                record(&mut pass);
            }
            gpu.queue().submit([encoder.finish()]);
            Ok(())
        })
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
}

impl Drop for Targets<'_> {
    fn drop(&mut self) {
        // Its objects are GL objects of this Gpu's context: make it current before they go.
        self.gpu.bind();
    }
}

/// The headless renderer; see the module doc. Borrows the [`Gpu`] it lives on.
#[derive(Debug)]
pub struct Offscreen<'g> {
    gpu: &'g Gpu,
    renderer: Renderer,
    planner: Planner,
    plan: FramePlan,
    /// The renderer's objects, then the targets'.
    ledger: Ledger,
    targets: Targets<'g>,
}

impl<'g> Offscreen<'g> {
    /// A renderer for `profile` (viewport `profile.view`) and `clipmap`'s terrain on `gpu`, with its
    /// targets; everything is created here, nothing per frame.
    pub fn new(
        gpu: &'g Gpu,
        profile: &Profile,
        clipmap: &Clipmap,
        options: OffscreenOptions<'_>,
    ) -> Result<Self> {
        let planner = Planner::new(profile, clipmap, options.lod)?;
        let plan = planner.new_plan();
        let (width, height) = (profile.view.width, profile.view.height);
        let renderer = gpu.scoped("clipmap renderer set-up", || {
            Renderer::new(
                gpu.device(),
                gpu.queue(),
                &RendererOptions {
                    color_format: COLOR_FORMAT,
                    depth_format: DEPTH_FORMAT,
                    reverse_z: false,
                    sample_count: 1,
                    shading: options.shading,
                    debug: options.debug,
                },
                profile,
            )
        })?;
        let targets = Targets::new(gpu, width, height)?;
        let mut ledger = renderer.ledger().clone();
        ledger.extend(targets.ledger());
        Ok(Self {
            gpu,
            renderer,
            planner,
            plan,
            ledger,
            targets,
        })
    }

    /// [`Offscreen::new`] with SG shading of `scene` over `hm` (the clipmap's terrain), integrated over
    /// `patches`, its tables baked first through the cache ([`sg_bake`]; `shadows: false` drops
    /// visibility), distance LOD.
    pub fn with_sg(
        gpu: &'g Gpu,
        profile: &Profile,
        clipmap: &Clipmap,
        hm: &Heightmap,
        scene: &Scene,
        patches: crate::shading::Patches,
        shadows: bool,
    ) -> Result<Self> {
        let (scene, bake) = sg_bake(profile.cpu_split().shading, hm, scene, shadows)?;
        Self::new(
            gpu,
            profile,
            clipmap,
            OffscreenOptions {
                shading: Shading::Sg(crate::gpu::renderer::SgShading {
                    scene: &scene,
                    patches,
                    bake: &bake,
                    omit: crate::gpu::shaders::SgOmit::None,
                }),
                ..OffscreenOptions::default()
            },
        )
    }

    /// The GPU it draws on.
    pub fn gpu(&self) -> &'g Gpu {
        self.gpu
    }

    /// The embeddable renderer inside.
    pub fn renderer(&self) -> &Renderer {
        &self.renderer
    }

    /// The embeddable renderer inside, to switch what it draws ([`Renderer::set_sg_enabled`]).
    pub fn renderer_mut(&mut self) -> &mut Renderer {
        &mut self.renderer
    }

    /// The planner.
    pub fn planner(&self) -> &Planner {
        &self.planner
    }

    /// The last frame's plan.
    pub fn plan(&self) -> &FramePlan {
        &self.plan
    }

    /// Every object created: the renderer's, then the targets' and read-back buffer's.
    pub fn ledger(&self) -> &Ledger {
        &self.ledger
    }

    /// The LOD mode.
    pub fn lod_mode(&self) -> LodMode {
        self.planner.lod_mode()
    }

    /// The SAT LOD selector, in the SAT modes.
    pub fn lod(&self) -> Option<&Lod> {
        self.planner.lod()
    }

    /// The last SAT-mode frame's block levels (empty before one).
    pub fn lod_frame(&self) -> &LodFrame {
        self.plan.lod_frame()
    }

    /// The last frame's draw list.
    pub fn draws(&self) -> &DrawList {
        self.plan.draws()
    }

    /// The uniforms of the last frame's draw `i`.
    pub fn draw_uniform(&self, i: usize) -> DrawUniform {
        self.plan.draw_uniform(i)
    }

    /// The last frame's global uniforms.
    pub fn globals(&self) -> &Globals {
        self.plan.globals()
    }

    /// Triangles draw `d` submits (the zero-area ones of clamped blocks included).
    pub fn draw_triangles(&self, d: &cull::Draw) -> u32 {
        let r = self.planner.index_range(d);
        (r.end - r.start) / 3
    }

    /// Image size, pixels.
    pub fn size(&self) -> (u32, u32) {
        self.targets.size()
    }

    /// The basic shading parameters (the brute-force reference of the same terrain uses the same).
    pub fn shading(&self) -> BasicShading {
        self.planner.shading()
    }

    /// The names of the textures the shading binds ([`Renderer::bound_textures`]).
    pub fn bound_textures(&self) -> &[&'static str] {
        self.renderer.bound_textures()
    }

    /// The maps baked for the shading ([`Renderer::baked`]).
    pub fn baked(&self) -> &[&'static str] {
        self.renderer.baked()
    }

    /// Plans `clipmap`'s last frame seen from `camera`, prepares it and draws it into the colour target
    /// (cleared first); [`Offscreen::read_image`] reads it back, [`render_frame`] does both.
    pub fn frame(
        &mut self,
        clipmap: &Clipmap,
        camera: &Camera,
        opts: &FrameOptions,
    ) -> Result<FrameStats> {
        let t = std::time::Instant::now();
        self.planner
            .plan(clipmap, camera, &opts.plan_params(), &mut self.plan)?;
        let plan_ns = u64::try_from(t.elapsed().as_nanos()).unwrap_or(u64::MAX);
        let gpu = self.gpu;
        let up: PrepareStats =
            gpu.scoped("clipmap frame", || self.renderer.prepare(gpu.queue(), clipmap, &self.plan))?;
        let renderer = &self.renderer;
        self.targets
            .draw("clipmap", opts.clear, |pass| renderer.render(pass))?;
        let p = self.plan.stats();
        Ok(FrameStats {
            draws: p.draws,
            cull: p.cull,
            triangles: p.triangles,
            uploads: up.uploads,
            upload_samples: up.upload_samples,
            upload_bytes: up.upload_bytes,
            full_upload: up.full_upload,
            blocks_clamped: p.blocks_clamped,
            unmet_px: p.unmet_px,
            plan_ns,
            blocks_from_pool: p.blocks_from_pool,
            pool_cells: p.pool_cells,
            detail_tiles_resident: p.detail_tiles_resident,
            detail_tiles_needed: p.detail_tiles_needed,
            detail_samples_updated: p.detail_samples_updated,
            sg_samples: up.sg_samples,
        })
    }

    /// Plans `clipmap`'s last frame and uploads it without drawing: what a caller runs to let the detail
    /// pool fill (e.g. `clipsat render` at a still camera). Returns the plan's detail tiles written.
    pub fn prepare_only(
        &mut self,
        clipmap: &Clipmap,
        camera: &Camera,
        opts: &FrameOptions,
    ) -> Result<u32> {
        self.planner
            .plan(clipmap, camera, &opts.plan_params(), &mut self.plan)?;
        let gpu = self.gpu;
        gpu.scoped("clipmap prepare", || {
            self.renderer.prepare(gpu.queue(), clipmap, &self.plan)
        })?;
        Ok(self.plan.stats().detail_uploads)
    }

    /// Reads the colour target back (into the preallocated buffer) as a tight RGBA8 image.
    pub fn read_image(&self) -> Result<Image> {
        self.targets.read_image()
    }

    /// Diagnostic (allocates a buffer per level, outside the ledger; not for the frame loop): every layer
    /// of the height texture read back, `size x size` (z, z_c) texels per level, row-major, as the GPU
    /// holds them.
    pub fn read_heights(&self) -> Result<Vec<Vec<[f32; 2]>>> {
        self.read_layers(self.renderer.heights())
    }

    /// Diagnostic, as [`Offscreen::read_heights`]: every ring's layer of the SG normal table
    /// (`size x size` RGBA32F texels: r, and with visibility the horizon's sine toward the first sun),
    /// under SG shading; an error otherwise.
    pub fn read_sg_normals(&self) -> Result<Vec<Vec<[f32; 4]>>> {
        let table = self
            .renderer
            .sg_normal_table()
            .ok_or_else(|| crate::Error::Invalid {
                what: "SG normal table".into(),
                reason: "the renderer does not shade with SG".into(),
            })?;
        self.read_layers(table)
    }

    /// The SG light table's layers in use (one per ring), each `clip_size^2` texels of RGBA16F bits,
    /// row-major: what `fs_sg` blends with visibility (`gpu/renderer/sg_tables.rs`).
    pub fn read_sg_light(&self) -> Result<Vec<Vec<[u16; 4]>>> {
        let table = self
            .renderer
            .sg_light_table()
            .ok_or_else(|| crate::Error::Invalid {
                what: "SG light table".into(),
                reason: "the renderer does not shade with SG visibility".into(),
            })?;
        self.read_layers(table)
    }

    /// The layers in use (one per ring) of square 2D array texture `texture`, whose texels are `T`s,
    /// row-major.
    fn read_layers<T: bytemuck::Pod>(&self, texture: &wgpu::Texture) -> Result<Vec<Vec<T>>> {
        let texel = u32::try_from(std::mem::size_of::<T>()).expect("a texel is a few bytes");
        let layers = self.renderer.levels();
        let gpu = self.gpu;
        let s = texture.width();
        let padded = (s * texel).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let mut out = Vec::new();
        for level in 0..layers {
            let buffer = gpu.scoped("layer readback", || {
                let mut dev = Ledgered::new(gpu.device());
                let buffer = dev.buffer(
                    "layer readback",
                    u64::from(padded) * u64::from(s),
                    wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                );
                let mut encoder = gpu.device().create_command_encoder(&Default::default());
                encoder.copy_texture_to_buffer(
                    wgpu::TexelCopyTextureInfo {
                        texture,
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
            let rows = crate::gpu::readback::map_rows(gpu, &buffer, padded, s * texel)?;
            out.push(bytemuck::pod_collect_to_vec(&rows));
        }
        Ok(out)
    }
}

impl Drop for Offscreen<'_> {
    fn drop(&mut self) {
        // Its objects are GL objects of this Gpu's context: make it current before they go.
        self.gpu.bind();
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

/// Plan, upload, draw and read back the clipmap's last frame: what `clipsat render` and `clipsat fly
/// --render` call once per [`Clipmap::update`].
pub fn render_frame(
    offscreen: &mut Offscreen<'_>,
    clipmap: &Clipmap,
    camera: &Camera,
    opts: &FrameOptions,
) -> Result<RenderedFrame> {
    let stats = offscreen.frame(clipmap, camera, opts)?;
    let image = offscreen.read_image()?;
    Ok(RenderedFrame {
        image_hash: image.hash(),
        image,
        stats,
    })
}
