//! Stage 3, the GPU: the GLES 3.0 geometry clipmap renderer (Losasso & Hoppe 2004, "GC") on the caller's
//! own device, drawing into the caller's own render pass (the egui-wgpu / glyphon pattern).
//!
//! [`Renderer::new`] takes a `&wgpu::Device`, a `&wgpu::Queue`, the [`RendererOptions`] fixed for its life
//! (target formats, sample count, shading variant, debug view) and the [`Profile`]; it creates every GPU
//! object once, through [`Ledgered`], whose ledger's bytes are the renderer's part of
//! [`Profile::footprint`] (heights, meshes, uniforms). A frame then creates nothing:
//!
//! 1. [`Renderer::prepare`]: the plan's upload rectangles ([`FramePlan::uploads`]) go straight from
//!    [`Ring::bytes`](crate::plan::clipmap::Ring::bytes) into one RG32F 2D array texture (S x S x L,
//!    toroidal) with `write_texture`, and under SG shading the same texels of the per-level shading
//!    tables (`sg_tables.rs`); the plan's uniforms go into the globals and draw-slot buffers.
//! 2. [`Renderer::render`]: the plan's draws recorded into the caller's `wgpu::RenderPass`.
//!
//! The plan itself is CPU work ([`crate::plan::frame_plan::Planner`]). [`crate::gpu::headless::Offscreen`]
//! is one user of this API: clipsat's strict EGL context, offscreen targets, read-back and image hash.
//!
//! The vertex shader (`shaders_gles/clipmap.wgsl`) morphs z' = (1 - alpha) z + alpha z_c with GC 6.2's
//! alpha ([`crate::plan::clipmap::morph_alpha`]) and derives normals from the geometry (GC 6.3);
//! [`crate::twin::clipmap::cpu_vertex`] is its CPU twin.
//!
//! Files: this one holds the type and its set-up; `frame.rs` prepare and render; `sg.rs` the SG shading
//! variant, `sg_tables.rs` its per-level tables; `imagery.rs` draped imagery's colour rings and programs;
//! `ledger.rs` the object ledger and [`Ledgered`]; `rebuild.rs` the renderer made again on a new device
//! after a lost one; `probe.rs` the vertex-probe test instrument.

mod frame;
mod imagery;
mod ledger;
#[cfg(feature = "internals")]
mod probe;
mod rebuild;
mod sg;
mod sg_tables;
#[cfg(feature = "internals")]
mod shading_probe;

pub use frame::PrepareStats;
pub use ledger::{texture_bytes, Ledger, LedgerEntry, Ledgered, ObjectKind};
#[cfg(feature = "internals")]
pub use probe::VertexProbe;
#[cfg(feature = "internals")]
pub use shading_probe::{ProbedFrame, ShadingProbe};
pub use sg::SgShading;
use sg::SgState;

use crate::gpu::shaders;
use crate::plan::cull::{DrawKind, MAX_DRAWS};
use crate::plan::fragment::FRAGMENT_PATHS;
use crate::plan::frame_plan::PlannedDraw;
use crate::plan::mesh::{self, Mesh, MeshVertex};
use crate::plan::uniforms::{DrawUniform, PoolCell};
use crate::profile::{DRAW_SLOT_BYTES, GLOBALS_BYTES, POOL_CELL_BYTES};
use crate::shading::debug_view::DebugView;
use crate::shading::scene::Scene;
use crate::shading::SkyTable;
use crate::{Error, Result};
use crate::profile::Profile;

#[cfg(doc)]
use crate::plan::frame_plan::FramePlan;

const HEIGHT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rg32Float;
/// The detail pool's format: z only (pool draws never morph), the same f32 heights as the rings.
const DETAIL_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rg32Float;
/// Bytes per mesh vertex (Uint16x4).
const VERTEX_BYTES: u64 = std::mem::size_of::<MeshVertex>() as u64;

/// How the terrain is shaded, fixed when the renderer is built.
#[derive(Clone, Copy, Debug, Default)]
pub enum Shading<'a> {
    /// The basic directional shading of `shaders_gles/basic_shading.wgsl`.
    #[default]
    Basic,
    /// Reduced SG shading (SAT paper section 5) of a scene over baked tables.
    Sg(SgShading<'a>),
}

/// What is fixed for a renderer's life (vello's `RendererOptions`; the per-frame switches are
/// [`crate::plan::frame_plan::PlanParams`]).
#[derive(Clone, Copy, Debug)]
pub struct RendererOptions<'a> {
    /// The colour attachment's format in the caller's pass.
    pub color_format: wgpu::TextureFormat,
    /// The depth attachment's format.
    pub depth_format: wgpu::TextureFormat,
    /// Reverse-Z: the terrain depth-tests with `Greater` (the pass cleared to 0); otherwise `Less`
    /// (cleared to 1). Each frame's camera must use the same convention.
    pub reverse_z: bool,
    /// The pass's sample count.
    pub sample_count: u32,
    /// The shading variant.
    pub shading: Shading<'a>,
    /// A debug view replacing the shading (level colours, wireframe); `Normal` draws the shading.
    pub debug: DebugView,
}

impl Default for RendererOptions<'_> {
    fn default() -> Self {
        Self {
            color_format: wgpu::TextureFormat::Rgba8Unorm,
            depth_format: wgpu::TextureFormat::Depth32Float,
            reverse_z: false,
            sample_count: 1,
            shading: Shading::Basic,
            debug: DebugView::Normal,
        }
    }
}

/// A static mesh on the GPU.
#[derive(Debug)]
struct GpuMesh {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    vertex_count: u32,
}

/// The clipmap renderer on a caller's device; see the module doc.
#[derive(Debug)]
pub struct Renderer {
    ledger: Ledger,
    heights: wgpu::Texture,
    /// The detail pool: tiles of `detail_atlas.side^2` RG32F (z, z_c) texels, placed by `detail_atlas`.
    detail: wgpu::Texture,
    detail_atlas: crate::profile::DetailAtlas,
    detail_quads: u32,
    /// One tile's samples, filled from the clipmap's source before each tile upload (allocated once).
    detail_staging: Vec<[f32; 2]>,
    /// The plan (`DetailFrame::seq`) whose pool the texture holds.
    detail_synced: Option<u64>,
    block: GpuMesh,
    skirt: GpuMesh,
    tile_skirt: GpuMesh,
    /// Detail pool cells with their skirts ([`mesh::pool_cells`]).
    pool_cell: GpuMesh,
    globals: wgpu::Buffer,
    draw_slots: wgpu::Buffer,
    /// The pool cells' per-instance fields ([`crate::plan::uniforms::PoolCell`]), one per instance of
    /// the pool's instanced draws.
    pool_cells: wgpu::Buffer,
    /// Cells the buffer holds.
    pool_cell_capacity: usize,
    // Layouts kept with the groups and pipelines made from them.
    _group0_layout: wgpu::BindGroupLayout,
    _group1_layout: wgpu::BindGroupLayout,
    group0: wgpu::BindGroup,
    group1: wgpu::BindGroup,
    module: wgpu::ShaderModule,
    pipeline_layout: wgpu::PipelineLayout,
    /// The caller's attachment formats and sample count.
    targets: Targets,
    /// The pipelines drawn, basic shading or the debug view's, indexed by [`crate::plan::fragment::FragmentPath`].
    pipelines: [wgpu::RenderPipeline; FRAGMENT_PATHS],
    sg: Option<SgState>,
    /// Draped imagery's colour rings and programs ([`Renderer::enable_imagery`]), for a terrain with it.
    imagery: Option<imagery::ImageryState>,
    /// Whether frames draw with the SG programs ([`Renderer::set_sg_enabled`]); the SG state is kept
    /// (and its level tables updated) either way.
    sg_enabled: bool,
    debug: DebugView,
    size: u32,
    levels: u32,
    max_draws: u32,
    /// The clipmap frame whose rectangles the texture holds.
    synced: Option<u64>,
    /// The prepared plan's draws, copied by [`Renderer::prepare`] (allocated once).
    prepared: Box<heapless::Vec<PlannedDraw, MAX_DRAWS>>,
    /// The profile it was built for, kept for [`Renderer::rebuild`].
    profile: Profile,
}

impl Renderer {
    /// Creates every buffer, texture and pipeline for `profile` on `device` (which must offer the GLES 3.0
    /// downlevel limits, [`wgpu::Limits::downlevel_webgl2_defaults`]); nothing else is created until the
    /// renderer drops. GPU validation errors surface through the device's error scopes or handler. The
    /// queue writes only the SG sky table (per scene, once); [`Renderer::prepare`] fills every other
    /// texture, the SG level tables included.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        options: &RendererOptions<'_>,
        profile: &Profile,
    ) -> Result<Self> {
        Self::build(device, queue, options, profile, None)
    }

    /// [`Renderer::new`], with the SG scene's sky table given (`rebuild.rs`) instead of integrated.
    fn build(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        options: &RendererOptions<'_>,
        profile: &Profile,
        sky: Option<&SkyTable>,
    ) -> Result<Self> {
        profile.validate(&profile.name)?;
        let c = &profile.clipmap;
        crate::plan::frame_plan::check_draw_capacity(profile)?;
        let limits = device.limits();
        if u64::from(limits.min_uniform_buffer_offset_alignment) > DRAW_SLOT_BYTES {
            return Err(Error::Unsupported {
                limit: "min_uniform_buffer_offset_alignment",
                needed: DRAW_SLOT_BYTES,
                available: u64::from(limits.min_uniform_buffer_offset_alignment),
            });
        }
        let layers = profile.height_layers();
        if layers > limits.max_texture_array_layers {
            return Err(Error::Unsupported {
                limit: "max_texture_array_layers",
                needed: u64::from(layers),
                available: u64::from(limits.max_texture_array_layers),
            });
        }
        let size = profile.clip_size();
        let block_quads = profile.block_m();
        let max_draws = profile.budget.max_draws;

        let mut dev = Ledgered::new(device);
        let heights = dev.texture(
            "clipmap heights",
            &array_texture(size, layers, HEIGHT_FORMAT, READ_BACK),
        );
        let heights_view = dev.view(
            "clipmap heights view",
            &heights,
            &wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2Array),
                ..Default::default()
            },
        );
        let detail_side = profile.detail_side();
        let atlas = profile.detail_atlas();
        let detail = dev.texture(
            "detail pool",
            &array_texture(
                atlas.layer_side(),
                atlas.layers,
                DETAIL_FORMAT,
                wgpu::TextureUsages::empty(),
            ),
        );
        let detail_view = dev.view(
            "detail pool view",
            &detail,
            &wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2Array),
                ..Default::default()
            },
        );
        let uniform = wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST;
        let globals = dev.buffer("clipmap globals", GLOBALS_BYTES, uniform);
        let draw_slots = dev.buffer(
            "clipmap draw slots",
            u64::from(max_draws) * DRAW_SLOT_BYTES,
            uniform,
        );
        // Pool cells are instances: the most one plan draws.
        let pool_cell_capacity = profile.pool_cell_capacity();
        let pool_cells = dev.buffer(
            "detail pool cells",
            pool_cell_capacity as u64 * POOL_CELL_BYTES,
            wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
        );
        let mut upload_mesh = |label: &'static str, m: &Mesh| GpuMesh {
            vertices: dev.buffer_init(
                label,
                bytemuck::cast_slice(&m.vertices),
                wgpu::BufferUsages::VERTEX,
            ),
            indices: dev.buffer_init(
                label,
                bytemuck::cast_slice(&m.indices),
                wgpu::BufferUsages::INDEX,
            ),
            vertex_count: u32::try_from(m.vertices.len()).expect("u16-indexed mesh"),
        };
        let block = upload_mesh("clipmap block mesh", &mesh::block(block_quads));
        let skirt = upload_mesh("clipmap skirt mesh", &mesh::skirt(c.n + 1));
        let tile_skirt = upload_mesh("clipmap tile skirt mesh", &mesh::skirt_loops(block_quads));
        let pool_cell = upload_mesh(
            "detail pool cell mesh",
            &mesh::pool_cells(profile.pool_mesh_quads()),
        );

        let group0_layout = dev.bind_group_layout(
            "clipmap globals layout",
            &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: wgpu::BufferSize::new(GLOBALS_BYTES),
                    },
                    count: None,
                },
                // The fragment stage shades from the finest ring holding the pixel (GC 6).
                array_entry(1, wgpu::ShaderStages::VERTEX_FRAGMENT),
                // Pool draws read their heights (vertex) and shade from them (fragment).
                array_entry(2, wgpu::ShaderStages::VERTEX_FRAGMENT),
            ],
        );
        let draw_size = std::mem::size_of::<DrawUniform>() as u64;
        let group1_layout = dev.bind_group_layout(
            "clipmap draw layout",
            &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                // The fragment stage reads the draw's level and lattice in the debug views.
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: true,
                    min_binding_size: wgpu::BufferSize::new(draw_size),
                },
                count: None,
            }],
        );
        let group0 = dev.bind_group(
            "clipmap globals group",
            &group0_layout,
            &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: globals.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&heights_view),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(&detail_view),
                },
            ],
        );
        let group1 = dev.bind_group(
            "clipmap draw group",
            &group1_layout,
            &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &draw_slots,
                    offset: 0,
                    size: wgpu::BufferSize::new(draw_size),
                }),
            }],
        );
        let module = dev.shader_module("clipmap.wgsl", shaders::clipmap());
        let pipeline_layout = dev.pipeline_layout(
            "clipmap pipeline layout",
            &[Some(&group0_layout), Some(&group1_layout)],
        );
        let targets = Targets::of(options);
        // One pipeline per fragment program (`FragmentPath`, the plan picks one per draw), from the
        // normal module or the debug view's.
        let debug_module = (options.debug != DebugView::Normal).then(|| {
            dev.shader_module(
                "clipmap.wgsl (debug view)",
                shaders::clipmap_view(options.debug),
            )
        });
        let shaded = debug_module.as_ref().unwrap_or(&module);
        let pipelines = FRAGMENT_ENTRIES.map(|(label, entry)| {
            terrain_pipeline(&mut dev, label, &pipeline_layout, shaded, entry, &targets)
        });
        let sg = match &options.shading {
            Shading::Basic => None,
            Shading::Sg(s) => Some(SgState::new(
                &mut dev,
                queue,
                profile,
                s,
                [&group0_layout, &group1_layout],
                &targets,
                sky,
            )?),
        };
        Ok(Self {
            ledger: dev.finish(),
            heights,
            detail,
            detail_quads: profile.detail_quads(),
            detail_atlas: atlas,
            detail_staging: vec![[0.0; 2]; detail_side as usize * detail_side as usize],
            detail_synced: None,
            block,
            skirt,
            tile_skirt,
            pool_cell,
            globals,
            draw_slots,
            pool_cells,
            pool_cell_capacity,
            _group0_layout: group0_layout,
            _group1_layout: group1_layout,
            group0,
            group1,
            module,
            pipeline_layout,
            targets,
            pipelines,
            sg,
            imagery: None,
            sg_enabled: true,
            debug: options.debug,
            size,
            levels: c.levels,
            max_draws,
            synced: None,
            prepared: Box::default(),
            profile: profile.clone(),
        })
    }

    /// Every object [`Renderer::new`] created.
    pub fn ledger(&self) -> &Ledger {
        &self.ledger
    }

    /// The ring height texture (S x S x levels, RG32F).
    pub fn heights(&self) -> &wgpu::Texture {
        &self.heights
    }

    /// The SG per-level normal table (`clip_size^2 x` [`Profile::sg_normal_layers`], RGBA32F), under SG
    /// shading.
    pub fn sg_normal_table(&self) -> Option<&wgpu::Texture> {
        self.sg.as_ref().map(|s| s.tables.normal())
    }

    /// The SG per-level light table (`clip_size^2 x` [`Profile::sg_light_layers`], RGBA16F), under SG
    /// shading with visibility.
    pub fn sg_light_table(&self) -> Option<&wgpu::Texture> {
        self.sg.as_ref().and_then(|s| s.tables.light())
    }

    /// Under SG shading, the scene as drawn (visibility as bound and as the effects switched now, fog
    /// fitted to the terrain), its sky table and the data's spacing (m) the shader's footprint uses:
    /// what a CPU twin of the frame shades with.
    pub fn sg_drawn(&self) -> Option<(Scene, &SkyTable, f32)> {
        self.sg.as_ref().map(|s| {
            let mut scene = s.scene.clone();
            scene.effects.visibility = s.variant.visibility;
            scene.effects.specular = s.variant.specular;
            scene.effects.fog = s.variant.fog;
            (scene, &s.sky, s.uniform.grid[0])
        })
    }

    /// Under SG shading, the shading tables the renderer fills its per-level tables from.
    pub fn sg_bake(&self) -> Option<&crate::package::shading_sats::ShadingBake> {
        self.sg.as_ref().map(|s| s.tables.bake())
    }

    /// Rings (array layers) in use.
    pub fn levels(&self) -> u32 {
        self.levels
    }

    /// Draws with SG shading (`true`, the default) or basic shading (`false`) from the next
    /// [`Renderer::render`], without creating or re-creating anything: a renderer made with
    /// [`Shading::Sg`] keeps its SG tables (still written by each prepare, so they are current when SG is
    /// switched back on) and its pipelines. No effect on a renderer made with basic shading.
    pub fn set_sg_enabled(&mut self, on: bool) {
        self.sg_enabled = on;
    }

    /// Draws the SG shading with `effects` (visibility, specular, fog) from the next
    /// [`Renderer::render`]: each must be one the scene it was built with asks for (else
    /// [`Error::Invalid`], and nothing changes). No table, buffer or binding is created or re-created:
    /// the level tables (the horizons included) are written by every prepare whatever is drawn, so an
    /// effect switched back on is current. A set of effects drawn for the first time compiles its two
    /// programs (a pipeline each, in the ledger at zero bytes); switching back to it creates nothing. No
    /// effect on a renderer made with basic shading.
    pub fn set_sg_effects(
        &mut self,
        device: &wgpu::Device,
        effects: crate::shading::scene::Effects,
    ) -> Result<()> {
        match self.sg.as_mut() {
            Some(sg) => sg.set_effects(device, &mut self.ledger, effects),
            None => Ok(()),
        }
    }

    /// Whether frames draw with SG shading: made with it and not switched off.
    pub fn sg_enabled(&self) -> bool {
        self.sg.is_some() && self.sg_enabled
    }

    /// The names of the textures the shading binds: `heights`, plus `level_normal`, `sky_table` and, with
    /// visibility, `level_light` under SG shading.
    pub fn bound_textures(&self) -> &[&'static str] {
        match &self.sg {
            Some(sg) => &sg.bound,
            None => &["heights"],
        }
    }

    /// The maps baked for the shading (none for basic shading).
    pub fn baked(&self) -> &[&'static str] {
        match &self.sg {
            Some(sg) => &sg.baked,
            None => &[],
        }
    }

    /// The SG shader variant drawn, if any ([`Renderer::set_sg_effects`] switches it).
    pub fn sg_variant(&self) -> Option<shaders::SgVariant> {
        self.sg.as_ref().map(|s| s.variant)
    }

    /// Entries of the SG bind group layout (group 2), under SG shading: 3 without visibility, 4 with.
    pub fn sg_layout_entries(&self) -> Option<usize> {
        self.sg.as_ref().map(|s| s.layout_entries)
    }

    fn mesh(&self, kind: DrawKind) -> &GpuMesh {
        match kind {
            DrawKind::Block => &self.block,
            DrawKind::Skirt => &self.skirt,
            DrawKind::TileSkirt => &self.tile_skirt,
            DrawKind::PoolCell | DrawKind::PoolUnit | DrawKind::PoolUnitSkirt => &self.pool_cell,
        }
    }
}

/// The caller's attachment formats and sample count, for every pipeline.
#[derive(Clone, Copy, Debug)]
struct Targets {
    color: wgpu::TextureFormat,
    depth: wgpu::TextureFormat,
    /// The depth test: `Greater` for reverse-Z, else `Less`.
    compare: wgpu::CompareFunction,
    samples: u32,
}

impl Targets {
    fn of(o: &RendererOptions<'_>) -> Self {
        Self {
            color: o.color_format,
            depth: o.depth_format,
            compare: if o.reverse_z {
                wgpu::CompareFunction::Greater
            } else {
                wgpu::CompareFunction::Less
            },
            samples: o.sample_count,
        }
    }

    /// What the shaders write for this colour target (`target_colour` in `shaders_gles/clipmap.wgsl`):
    /// 1 for an sRGB format, which encodes what it is given, else 0.
    fn encoding(&self) -> f32 {
        if self.color.is_srgb() {
            1.0
        } else {
            0.0
        }
    }
}

/// Each [`crate::plan::fragment::FragmentPath`]'s pipeline label and `clipmap.wgsl` entry point, in discriminant order.
const FRAGMENT_ENTRIES: [(&str, &str); FRAGMENT_PATHS] = [
    ("clipmap pipeline (interior)", "fs_interior"),
    ("clipmap pipeline (plain)", "fs_plain"),
    ("clipmap pipeline (ring data)", "fs_ring_data"),
    ("clipmap pipeline (skirt)", "fs_skirt"),
];

/// `usage` of every texture the tests read back (the heights, the SG tables), besides sampling and writing.
const READ_BACK: wgpu::TextureUsages = wgpu::TextureUsages::COPY_SRC;

/// A `side` x `side` 2D array texture of `layers` layers that the renderer writes (`COPY_DST`) and the
/// shaders read (`TEXTURE_BINDING`), plus `usage`: the rings, the detail pool and the SG tables.
fn array_texture(
    side: u32,
    layers: u32,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::TextureDescriptor<'static> {
    crate::gpu::texture_2d(side, side, layers, format, usage)
}

/// The layout entry of one such texture: float and unfilterable (GLES 3.0 filters no 32-bit float
/// format), read with `textureLoad`.
fn array_entry(binding: u32, visibility: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: wgpu::TextureViewDimension::D2Array,
            multisampled: false,
        },
        count: None,
    }
}

fn terrain_pipeline(
    dev: &mut Ledgered<'_>,
    label: &'static str,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    fragment_entry: &str,
    targets: &Targets,
) -> wgpu::RenderPipeline {
    let colour = [Some(wgpu::ColorTargetState {
        format: targets.color,
        blend: None,
        write_mask: wgpu::ColorWrites::ALL,
    })];
    pipeline_to(dev, label, layout, module, fragment_entry, targets, &colour)
}

/// A terrain pipeline (`vs_main`, both sides, depth `Less`) into `colour` targets and `targets`' depth
/// and sample count.
fn pipeline_to(
    dev: &mut Ledgered<'_>,
    label: &'static str,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    fragment_entry: &str,
    targets: &Targets,
    colour: &[Option<wgpu::ColorTargetState>],
) -> wgpu::RenderPipeline {
    dev.render_pipeline(
        label,
        &wgpu::RenderPipelineDescriptor {
            label: None,
            layout: Some(layout),
            vertex: wgpu::VertexState {
                module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &vertex_buffers(),
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                front_face: wgpu::FrontFace::Ccw,
                // Skirts and terrain seen from below show back faces; draw both sides.
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: targets.depth,
                depth_write_enabled: Some(true),
                depth_compare: Some(targets.compare),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: wgpu::MultisampleState {
                count: targets.samples,
                ..Default::default()
            },
            fragment: Some(wgpu::FragmentState {
                module,
                entry_point: Some(fragment_entry),
                compilation_options: Default::default(),
                targets: colour,
            }),
            multiview_mask: None,
            cache: None,
        },
    )
}

/// The mesh's vertices (slot 0) and the pool cells, one per instance (slot 1; `PoolCellIn` in
/// `shaders_gles/clipmap.wgsl`): every terrain pipeline reads both, a draw that is not the pool's reads
/// instance 0 and ignores it.
pub(super) fn vertex_buffers() -> [Option<wgpu::VertexBufferLayout<'static>>; 2] {
    const CELL: [wgpu::VertexAttribute; 4] = wgpu::vertex_attr_array![
        1 => Sint32x4, 2 => Sint32x4, 3 => Float32x4, 4 => Sint32x4
    ];
    [
        Some(vertex_layout()),
        Some(wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<PoolCell>() as u64,
            step_mode: wgpu::VertexStepMode::Instance,
            attributes: &CELL,
        }),
    ]
}

fn vertex_layout() -> wgpu::VertexBufferLayout<'static> {
    const ATTRS: [wgpu::VertexAttribute; 1] = wgpu::vertex_attr_array![0 => Uint16x4];
    wgpu::VertexBufferLayout {
        array_stride: VERTEX_BYTES,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &ATTRS,
    }
}
