//! Stage 3, the GPU: the GLES 3.0 geometry clipmap renderer (Losasso & Hoppe 2004, "GC").
//!
//! [`Renderer::new`] creates every GPU object, sized from the profile, and records each in a [`Ledger`]
//! whose bytes equal [`Profile::footprint`]. A frame then creates nothing but a command encoder:
//!
//! 1. [`Renderer::upload`]: the frame's `uploads` (at most 4 sub-rectangles per level) go straight from
//!    [`Ring::bytes`] into one RG32F 2D array texture (S x S x L, toroidal) with `write_texture`, no copies.
//! 2. [`Renderer::draw`]: the draw list ([`crate::cull`]), one 256-byte uniform slot per draw (one
//!    `write_buffer`), one render pass with a Depth32Float buffer and the basic shading.
//! 3. [`Renderer::read_image`]: readback into the preallocated buffer.
//!
//! The vertex shader (`shaders_gles/clipmap.wgsl`) morphs z' = (1 - alpha) z + alpha z_c with GC 6.2's
//! alpha ([`crate::clipmap::morph_alpha`]) and derives normals from the geometry (GC 6.3); [`cpu_vertex`]
//! is its CPU twin.

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec4};
use wgpu::util::DeviceExt;

use crate::clipmap::{morph_alpha, Clipmap, Ring};
use crate::cull::{self, DrawKind, DrawList, DrawParams, DrawStats, MAX_DRAWS};
use crate::debug_view::DebugView;
use crate::frame::Rect;
use crate::gpu::readback::Image;
use crate::gpu::sat_textures::{SatTextures, ShadingBake, MAX_BOX_SIDE};
use crate::gpu::shaders::{self, BasicShading, SgSceneUniform, SgVariant};
use crate::gpu::Gpu;
use crate::horizon::DEFAULT_AZIMUTHS;
use crate::lod::{Lod, LodFrame, LodMode};
use crate::mesh::{self, Mesh, MeshVertex};
use crate::profile::{DRAW_SLOT_BYTES, GLOBALS_BYTES};
use crate::scene::Scene;
use crate::shading::Patches;
use crate::{Camera, Error, Heightmap, Profile, Result};

/// The renderer's global uniforms; mirrors `Globals` in `shaders_gles/clipmap.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Globals {
    /// Camera-relative view-projection.
    pub view_proj: [f32; 16],
    /// Basic shading parameters.
    pub shading: BasicShading,
    /// x: morph factor (1 on, 0 off); y: skirt floor (m); z, w: vertex-probe target size.
    pub params: [f32; 4],
    /// The data's horizontal extent relative to the eye (m): x min, y min, x max, y max. Fragments
    /// outside it are discarded.
    pub extent: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<Globals>() as u64 == GLOBALS_BYTES);

/// One draw's uniforms; mirrors `DrawUniform` in `shaders_gles/clipmap.wgsl`. Lattice values are relative
/// to the level's anchor, the first vertex of its active region.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct DrawUniform {
    /// xy: mesh origin; z: array layer; w: ring size S.
    pub origin: [i32; 4],
    /// Clamp rectangle, inclusive: x0, y0, x1, y1.
    pub bounds: [i32; 4],
    /// Active region, inclusive: x0, y0, x1, y1.
    pub active: [i32; 4],
    /// xy: texel of the anchor (anchor mod S).
    pub tex: [i32; 4],
    /// xyz: world position of the anchor at height 0 minus the eye (m); w: level spacing (m).
    pub anchor_rel: [f32; 4],
    /// xy: viewer (level units); z, w: (active w - 1) / 2, (active h - 1) / 2.
    pub morph: [f32; 4],
    /// x: transition width n / 10; y: n; zw: unused.
    pub morph_w: [f32; 4],
    /// SAT LOD snapped tiles ([`cull::Draw::fine`]): x: fine level; y: s, this level's spacing in fine
    /// lattice units (1: not snapped, and the fine fields repeat the ones above); zw: unused.
    pub fine: [i32; 4],
    /// Clamp rectangle in fine units, inclusive, fine-anchor-relative.
    pub fine_bounds: [i32; 4],
    /// xy: this level's anchor in fine units, fine-anchor-relative; zw: unused.
    pub fine_origin: [i32; 4],
    /// xyz: world position of the fine anchor at height 0 minus the eye (m); w: fine spacing (m).
    pub fine_rel: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<DrawUniform>() == 176);

impl DrawUniform {
    /// Fills the fine fields for a draw that is not snapped: the fine level is the draw's own.
    fn unsnapped(mut self) -> Self {
        self.fine = [self.origin[2], 1, 0, 0];
        self.fine_bounds = self.bounds;
        self.fine_origin = [0; 4];
        self.fine_rel = self.anchor_rel;
        self
    }
}

/// The loud clear colour of crack measurements: pure magenta, a colour the shading never makes.
pub const CRACK_CLEAR: [f64; 4] = [1.0, 0.0, 1.0, 1.0];

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
    /// clipmap); the SAT modes draw each LOD block at the level [`crate::lod::Lod::select`] chose (the
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
            clear: shaders::SKY,
            morph: true,
            cull: true,
            skirts: true,
            lod: LodMode::Distance,
            epsilon_px: None,
            debug: DebugView::Normal,
        }
    }
}

/// What a GPU object is, for the [`Ledger`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ObjectKind {
    /// A buffer (bytes counted).
    Buffer,
    /// A texture (bytes counted).
    Texture,
    /// A texture view.
    TextureView,
    /// A shader module.
    ShaderModule,
    /// A bind group layout.
    BindGroupLayout,
    /// A bind group.
    BindGroup,
    /// A pipeline layout.
    PipelineLayout,
    /// A render pipeline.
    RenderPipeline,
}

/// One object [`Renderer::new`] created.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LedgerEntry {
    /// Its label.
    pub label: &'static str,
    /// What it is.
    pub kind: ObjectKind,
    /// GPU memory it holds (0 for objects without storage).
    pub bytes: u64,
}

/// Every GPU object the renderer created and the bytes each holds; only [`Renderer::new`] writes it.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Ledger {
    entries: Vec<LedgerEntry>,
}

impl Ledger {
    fn note(&mut self, label: &'static str, kind: ObjectKind, bytes: u64) {
        self.entries.push(LedgerEntry { label, kind, bytes });
    }

    /// The objects, in creation order.
    pub fn entries(&self) -> &[LedgerEntry] {
        &self.entries
    }

    /// Objects created.
    pub fn count(&self) -> usize {
        self.entries.len()
    }

    /// Bytes of GPU memory held.
    pub fn bytes(&self) -> u64 {
        self.entries.iter().map(|e| e.bytes).sum()
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
    /// [`crate::lod::LodFrame::blocks_clamped`]); 0 in distance mode.
    pub blocks_clamped: u32,
}

const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
const HEIGHT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rg32Float;
/// Bytes per mesh vertex (Uint16x4).
const VERTEX_BYTES: u64 = std::mem::size_of::<MeshVertex>() as u64;
/// [`DRAW_SLOT_BYTES`] as a slice stride.
#[expect(clippy::cast_possible_truncation, reason = "256 fits every usize")]
const SLOT: usize = DRAW_SLOT_BYTES as usize;
/// Width of the vertex-probe target, pixels.
const PROBE_WIDTH: u32 = 64;

/// A static mesh on the GPU.
#[derive(Debug)]
struct GpuMesh {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    index_count: u32,
    vertex_count: u32,
}

/// The clipmap renderer. Borrows the [`Gpu`] it lives on.
#[derive(Debug)]
pub struct Renderer<'g> {
    gpu: &'g Gpu,
    ledger: Ledger,
    heights: wgpu::Texture,
    block: GpuMesh,
    skirt: GpuMesh,
    tile_skirt: GpuMesh,
    globals: wgpu::Buffer,
    draw_slots: wgpu::Buffer,
    // Layouts kept with the groups and pipeline made from them (ledgered objects live as long as the renderer).
    _group0_layout: wgpu::BindGroupLayout,
    _group1_layout: wgpu::BindGroupLayout,
    group0: wgpu::BindGroup,
    group1: wgpu::BindGroup,
    module: wgpu::ShaderModule,
    pipeline_layout: wgpu::PipelineLayout,
    pipeline: wgpu::RenderPipeline,
    /// The debug views' pipelines (index code - 1), made on first use.
    debug_pipelines: [Option<wgpu::RenderPipeline>; 2],
    color: wgpu::Texture,
    color_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    readback: wgpu::Buffer,
    padded_row: u32,
    width: u32,
    height: u32,
    n: u32,
    size: u32,
    levels: u32,
    block_quads: u32,
    max_draws: u32,
    max_triangles: u32,
    skirt_floor: f32,
    /// The data's last sample in level-0 lattice units (east, south).
    data_lattice: (f64, f64),
    shading: BasicShading,
    probe_size: [u32; 2],
    /// The draw list and its uniform bytes, allocated once.
    draws: Box<DrawList>,
    slots: Vec<u8>,
    /// The SAT LOD selector (set by [`Renderer::set_lod`]) and its per-frame output, allocated once.
    lod: Option<Lod>,
    lod_frame: Box<LodFrame>,
    /// The clipmap frame whose uploads the texture holds.
    synced: Option<u64>,
    last_globals: Globals,
    /// SG shading, when [`Renderer::set_sg`] chose it (else the basic shading).
    sg: Option<SgState>,
}

/// The GPU objects of one SG shading variant (design.md "Only the effects a scene calls for"): only the
/// tables the scene needs are baked and bound, only its effects compiled.
#[derive(Debug)]
struct SgState {
    variant: SgVariant,
    baked: Vec<&'static str>,
    bound: Vec<&'static str>,
    layout_entries: usize,
    _textures: SatTextures,
    _uniform: wgpu::Buffer,
    _layout: wgpu::BindGroupLayout,
    group: wgpu::BindGroup,
    pipeline: wgpu::RenderPipeline,
}

fn texture_bytes(desc: &wgpu::TextureDescriptor<'_>) -> u64 {
    let texel = desc
        .format
        .block_copy_size(Some(wgpu::TextureAspect::All))
        .unwrap_or(4);
    u64::from(desc.size.width)
        * u64::from(desc.size.height)
        * u64::from(desc.size.depth_or_array_layers)
        * u64::from(texel)
}

impl<'g> Renderer<'g> {
    /// Creates every buffer, texture and pipeline for `profile` (viewport `profile.view`) and the clipmap's
    /// terrain; nothing else is created until the renderer drops.
    pub fn new(gpu: &'g Gpu, profile: &Profile, clipmap: &Clipmap) -> Result<Self> {
        profile.validate(&profile.name)?;
        let c = &profile.clipmap;
        if clipmap.n() != c.n
            || clipmap.levels() != c.levels
            || clipmap.ring(0).size() != profile.clip_size()
        {
            return Err(Error::config(
                &profile.name,
                "clipmap",
                "the clipmap was built from a different profile",
            ));
        }
        if profile.budget.max_draws as usize > MAX_DRAWS {
            return Err(Error::config(
                &profile.name,
                "budget.max_draws",
                format!(
                    "{} exceeds the renderer's fixed capacity {MAX_DRAWS}",
                    profile.budget.max_draws
                ),
            ));
        }
        let limits = gpu.device().limits();
        if u64::from(limits.min_uniform_buffer_offset_alignment) > DRAW_SLOT_BYTES {
            return Err(Error::Gpu(format!(
                "uniform offset alignment {} exceeds the {DRAW_SLOT_BYTES}-byte draw slot",
                limits.min_uniform_buffer_offset_alignment
            )));
        }
        let layers = profile.height_layers();
        if layers > limits.max_texture_array_layers {
            return Err(Error::Gpu(format!(
                "{layers} height layers exceed the device's {}",
                limits.max_texture_array_layers
            )));
        }
        let (width, height) = (profile.view.width, profile.view.height);
        let size = profile.clip_size();
        let block_quads = profile.block_m();
        let block_mesh = mesh::block(block_quads);
        let skirt_mesh = mesh::skirt(c.n + 1);
        let tile_skirt_mesh = mesh::skirt_loops(block_quads);
        let probe_rows = u32::try_from(block_mesh.vertices.len().max(skirt_mesh.vertices.len()))
            .expect("u16-indexed meshes")
            .div_ceil(PROBE_WIDTH);

        // Shading and skirt floor from the data (pyramid level 0 is the terrain itself).
        let data = clipmap.pyramid().level(0);
        let (lo, hi) = data
            .heights()
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &z| {
                (a.min(z), b.max(z))
            });
        let spacing = clipmap.g0() * f64::from(1u32 << clipmap.synth_levels());
        let synth = f64::from(1u32 << clipmap.synth_levels());
        let data_lattice = (
            f64::from(data.width() - 1) * synth,
            f64::from(data.height() - 1) * synth,
        );
        let diagonal = f64::from(data.width()).hypot(f64::from(data.height())) * spacing;
        let shading = BasicShading::for_terrain((lo, hi), diagonal);
        #[expect(
            clippy::cast_possible_truncation,
            reason = "the level-0 spacing as an f32 metre offset"
        )]
        let skirt_floor = lo - (0.5 * (hi - lo)).max(10.0 * clipmap.g0() as f32);
        let padded_row = (width * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let max_draws = profile.budget.max_draws;

        gpu.scoped("clipmap renderer set-up", || {
            let device = gpu.device();
            let mut ledger = Ledger::default();
            let texture = |ledger: &mut Ledger, desc: wgpu::TextureDescriptor<'static>| {
                ledger.note(
                    desc.label.unwrap_or("texture"),
                    ObjectKind::Texture,
                    texture_bytes(&desc),
                );
                device.create_texture(&desc)
            };
            let heights = texture(
                &mut ledger,
                wgpu::TextureDescriptor {
                    label: Some("clipmap heights"),
                    size: wgpu::Extent3d {
                        width: size,
                        height: size,
                        depth_or_array_layers: layers,
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format: HEIGHT_FORMAT,
                    usage: wgpu::TextureUsages::TEXTURE_BINDING
                        | wgpu::TextureUsages::COPY_DST
                        | wgpu::TextureUsages::COPY_SRC,
                    view_formats: &[],
                },
            );
            let target = |label, format, usage| wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            };
            let color = texture(
                &mut ledger,
                target(
                    "clipmap color",
                    COLOR_FORMAT,
                    wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                ),
            );
            let depth = texture(
                &mut ledger,
                target(
                    "clipmap depth",
                    DEPTH_FORMAT,
                    wgpu::TextureUsages::RENDER_ATTACHMENT,
                ),
            );
            let heights_view = heights.create_view(&wgpu::TextureViewDescriptor {
                label: Some("clipmap heights"),
                dimension: Some(wgpu::TextureViewDimension::D2Array),
                ..Default::default()
            });
            ledger.note("clipmap heights view", ObjectKind::TextureView, 0);
            let color_view = color.create_view(&Default::default());
            ledger.note("clipmap color view", ObjectKind::TextureView, 0);
            let depth_view = depth.create_view(&Default::default());
            ledger.note("clipmap depth view", ObjectKind::TextureView, 0);

            let buffer = |ledger: &mut Ledger, label: &'static str, size: u64, usage| {
                ledger.note(label, ObjectKind::Buffer, size);
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size,
                    usage,
                    mapped_at_creation: false,
                })
            };
            let globals = buffer(
                &mut ledger,
                "clipmap globals",
                GLOBALS_BYTES,
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            );
            let draw_slots = buffer(
                &mut ledger,
                "clipmap draw slots",
                u64::from(max_draws) * DRAW_SLOT_BYTES,
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            );
            let readback = buffer(
                &mut ledger,
                "clipmap readback",
                u64::from(padded_row) * u64::from(height),
                wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            );
            let upload_mesh = |ledger: &mut Ledger, label: &'static str, m: &Mesh| {
                ledger.note(
                    label,
                    ObjectKind::Buffer,
                    m.vertices.len() as u64 * VERTEX_BYTES,
                );
                ledger.note(label, ObjectKind::Buffer, m.indices.len() as u64 * 2);
                GpuMesh {
                    vertices: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some(label),
                        contents: bytemuck::cast_slice(&m.vertices),
                        usage: wgpu::BufferUsages::VERTEX,
                    }),
                    indices: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some(label),
                        contents: bytemuck::cast_slice(&m.indices),
                        usage: wgpu::BufferUsages::INDEX,
                    }),
                    index_count: u32::try_from(m.indices.len()).expect("u16-indexed mesh"),
                    vertex_count: u32::try_from(m.vertices.len()).expect("u16-indexed mesh"),
                }
            };
            let block = upload_mesh(&mut ledger, "clipmap block mesh", &block_mesh);
            let skirt = upload_mesh(&mut ledger, "clipmap skirt mesh", &skirt_mesh);
            let tile_skirt = upload_mesh(&mut ledger, "clipmap tile skirt mesh", &tile_skirt_mesh);

            let group0_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("clipmap globals"),
                entries: &[
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
                    wgpu::BindGroupLayoutEntry {
                        binding: 1,
                        visibility: wgpu::ShaderStages::VERTEX,
                        ty: wgpu::BindingType::Texture {
                            sample_type: wgpu::TextureSampleType::Float { filterable: false },
                            view_dimension: wgpu::TextureViewDimension::D2Array,
                            multisampled: false,
                        },
                        count: None,
                    },
                ],
            });
            ledger.note("clipmap globals layout", ObjectKind::BindGroupLayout, 0);
            let draw_size = std::mem::size_of::<DrawUniform>() as u64;
            let group1_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("clipmap draw"),
                entries: &[wgpu::BindGroupLayoutEntry {
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
            });
            ledger.note("clipmap draw layout", ObjectKind::BindGroupLayout, 0);
            let group0 = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("clipmap globals"),
                layout: &group0_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: globals.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::TextureView(&heights_view),
                    },
                ],
            });
            ledger.note("clipmap globals group", ObjectKind::BindGroup, 0);
            let group1 = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("clipmap draw"),
                layout: &group1_layout,
                entries: &[wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &draw_slots,
                        offset: 0,
                        size: wgpu::BufferSize::new(draw_size),
                    }),
                }],
            });
            ledger.note("clipmap draw group", ObjectKind::BindGroup, 0);
            let source = shaders::clipmap();
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("clipmap.wgsl"),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            });
            ledger.note("clipmap.wgsl", ObjectKind::ShaderModule, 0);
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("clipmap"),
                bind_group_layouts: &[Some(&group0_layout), Some(&group1_layout)],
                immediate_size: 0,
            });
            ledger.note("clipmap pipeline layout", ObjectKind::PipelineLayout, 0);
            let pipeline = terrain_pipeline(device, &pipeline_layout, &module, "fs_main");
            ledger.note("clipmap pipeline", ObjectKind::RenderPipeline, 0);

            let mut draws: Box<DrawList> = Box::default();
            draws.clear();
            Ok(Self {
                gpu,
                ledger,
                heights,
                block,
                skirt,
                tile_skirt,
                globals,
                draw_slots,
                _group0_layout: group0_layout,
                _group1_layout: group1_layout,
                group0,
                group1,
                module,
                pipeline_layout,
                pipeline,
                debug_pipelines: [None, None],
                color,
                color_view,
                depth_view,
                readback,
                padded_row,
                width,
                height,
                n: c.n,
                size,
                levels: c.levels,
                block_quads,
                max_draws,
                max_triangles: profile.budget.max_triangles,
                skirt_floor,
                data_lattice,
                shading,
                probe_size: [PROBE_WIDTH, probe_rows],
                draws,
                slots: vec![0; max_draws as usize * SLOT],
                lod: None,
                lod_frame: LodFrame::new_boxed(),
                synced: None,
                last_globals: Globals::zeroed(),
                sg: None,
            })
        })
    }

    /// Switches the renderer to SG shading (SAT paper section 5) for `scene` over the terrain `hm` (the one
    /// the clipmap was built from), integrating over `patches`; `shadows: false` drops visibility even if
    /// the scene asks for it. Bakes (through the disk cache, [`ShadingBake::bake_cached`]), binds and compiles
    /// only what the scene needs ([`Scene::needs`]): no
    /// horizon maps or visibility texture without visibility, no specular code without specular. The SG
    /// objects are outside the profile's ledger (like the SAT LOD tables of [`Renderer::set_lod`]).
    pub fn set_sg(
        &mut self,
        hm: &Heightmap,
        scene: &Scene,
        patches: Patches,
        shadows: bool,
    ) -> Result<()> {
        let mut scene = scene.clone();
        scene.effects.visibility &= shadows;
        let max_side = self.gpu.device().limits().max_texture_dimension_2d;
        let (bake, _) = ShadingBake::bake_cached(
            hm,
            &scene.needs(),
            DEFAULT_AZIMUTHS,
            max_side,
            &crate::bake::default_cache_dir(),
        )?;
        self.set_sg_baked(hm, &scene, patches, &bake)
    }

    /// [`Renderer::set_sg`] with the tables already baked (e.g. one bake shared by several patch counts).
    /// Visibility is used when the scene asks for it and `bake` holds horizons.
    pub fn set_sg_baked(
        &mut self,
        hm: &Heightmap,
        scene: &Scene,
        patches: Patches,
        bake: &ShadingBake,
    ) -> Result<()> {
        let mut scene = scene.clone();
        scene.effects.visibility &= bake.azimuths() > 0;
        let needs = scene.needs();
        let variant = SgVariant {
            patches,
            visibility: needs.bind_visibility,
            specular: needs.specular_code,
        };
        let gpu = self.gpu;
        let device = gpu.device();
        let textures = SatTextures::upload(gpu, bake)?;
        let mut u = SgSceneUniform::new(&scene, bake.azimuths())?;
        #[expect(clippy::cast_precision_loss, reason = "grid sizes <= 16385")]
        let grid = [
            (hm.width() - 1) as f32,
            (hm.height() - 1) as f32,
            bake.step() as f32,
            MAX_BOX_SIDE as f32,
        ];
        u.grid = grid;
        let sg = gpu.scoped("sg shading set-up", || {
            let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("sg scene"),
                contents: bytemuck::bytes_of(&u),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let texture = |binding, dim| wgpu::BindGroupLayoutEntry {
                binding,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Uint,
                    view_dimension: dim,
                    multisampled: false,
                },
                count: None,
            };
            let mut entries = vec![
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                texture(1, wgpu::TextureViewDimension::D2),
            ];
            let mut resources = vec![
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniform.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(textures.normal_view()),
                },
            ];
            let mut bound = vec!["heights", "sat_normal"];
            if let (true, Some(view)) = (variant.visibility, textures.horizon_view()) {
                entries.push(texture(2, wgpu::TextureViewDimension::D2Array));
                resources.push(wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(view),
                });
                bound.push("sat_horizon");
            }
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("sg shading"),
                entries: &entries,
            });
            let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("sg shading"),
                layout: &layout,
                entries: &resources,
            });
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("sg_clipmap.wgsl"),
                source: wgpu::ShaderSource::Wgsl(shaders::sg_clipmap(variant).into()),
            });
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("clipmap sg"),
                bind_group_layouts: &[
                    Some(&self._group0_layout),
                    Some(&self._group1_layout),
                    Some(&layout),
                ],
                immediate_size: 0,
            });
            let pipeline = terrain_pipeline(device, &pipeline_layout, &module, "fs_sg");
            Ok(SgState {
                variant,
                baked: bake.baked().to_vec(),
                bound,
                layout_entries: entries.len(),
                _textures: textures,
                _uniform: uniform,
                _layout: layout,
                group,
                pipeline,
            })
        })?;
        self.sg = Some(sg);
        Ok(())
    }

    /// Back to the basic shading: drops the SG textures, bind group and pipeline ([`Renderer::set_sg`]).
    pub fn set_basic_shading(&mut self) {
        self.sg = None;
    }

    /// The names of the textures the current shading binds: `heights`, plus `sat_normal` and, with
    /// visibility, `sat_horizon` under SG shading.
    pub fn bound_textures(&self) -> &[&'static str] {
        match &self.sg {
            Some(sg) => &sg.bound,
            None => &["heights"],
        }
    }

    /// The maps baked for the current shading (none for basic shading).
    pub fn baked(&self) -> &[&'static str] {
        match &self.sg {
            Some(sg) => &sg.baked,
            None => &[],
        }
    }

    /// The SG shader variant in use, if any.
    pub fn sg_variant(&self) -> Option<SgVariant> {
        self.sg.as_ref().map(|s| s.variant)
    }

    /// Entries of the SG bind group layout (group 2), if SG shading is on: 2 without visibility, 3 with.
    pub fn sg_layout_entries(&self) -> Option<usize> {
        self.sg.as_ref().map(|s| s.layout_entries)
    }

    /// Every object [`Renderer::new`] created.
    pub fn ledger(&self) -> &Ledger {
        &self.ledger
    }

    /// Gives the renderer the SAT LOD selector the SAT modes need (built for this clipmap's terrain:
    /// [`Lod::for_clipmap`]).
    pub fn set_lod(&mut self, lod: Lod) {
        self.lod = Some(lod);
    }

    /// The SAT LOD selector, if set.
    pub fn lod(&self) -> Option<&Lod> {
        self.lod.as_ref()
    }

    /// The last SAT-mode frame's block levels (empty before one).
    pub fn lod_frame(&self) -> &LodFrame {
        &self.lod_frame
    }

    /// Triangles draw `d` submits (the zero-area ones of clamped blocks included).
    pub fn draw_triangles(&self, d: &cull::Draw) -> u32 {
        self.index_count(d) / 3
    }

    fn index_count(&self, d: &cull::Draw) -> u32 {
        let r = self.index_range(d);
        r.end - r.start
    }

    /// The part of its mesh's index buffer draw `d` draws.
    fn index_range(&self, d: &cull::Draw) -> std::ops::Range<u32> {
        match d.kind {
            DrawKind::Block => 0..mesh::block_prefix(d.quads.min(self.block_quads)),
            DrawKind::Skirt => 0..self.skirt.index_count,
            DrawKind::TileSkirt => mesh::skirt_loop_range(self.block_quads, d.quads),
        }
    }

    /// The last frame's draw list.
    pub fn draws(&self) -> &DrawList {
        &self.draws
    }

    /// The uniforms of the last frame's draw `i`.
    pub fn draw_uniform(&self, i: usize) -> DrawUniform {
        let at = i * SLOT;
        bytemuck::pod_read_unaligned(&self.slots[at..at + std::mem::size_of::<DrawUniform>()])
    }

    /// The last frame's global uniforms.
    pub fn globals(&self) -> &Globals {
        &self.last_globals
    }

    /// Image size, pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The basic shading parameters (the brute-force reference of the same terrain uses the same).
    pub fn shading(&self) -> BasicShading {
        self.shading
    }

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

    fn mesh(&self, kind: DrawKind) -> &GpuMesh {
        match kind {
            DrawKind::Block => &self.block,
            DrawKind::Skirt => &self.skirt,
            DrawKind::TileSkirt => &self.tile_skirt,
        }
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

impl Drop for Renderer<'_> {
    fn drop(&mut self) {
        // Its objects are GL objects of this Gpu's context: make it current before they go.
        self.gpu.bind();
    }
}

/// The uniforms of draw `d`: lattice values relative to the level's anchor (its active region's first
/// vertex), the anchor's position relative to the eye computed in f64.
#[expect(
    clippy::cast_possible_truncation,
    reason = "anchor-relative lattice offsets are below the ring size; f64 -> f32 after subtracting the eye \
              is the intended GPU precision"
)]
pub fn draw_uniform(
    clipmap: &Clipmap,
    camera: &Camera,
    d: &cull::Draw,
    n: u32,
    size: u32,
) -> DrawUniform {
    let a = clipmap.frame().levels[d.level as usize].active;
    let (ax, ay) = (a.x0, a.y0);
    let rel = |v: i64, o: i64| (v - o) as i32;
    let k = f64::from(1u32 << d.level);
    let p = clipmap.eye_lattice(camera.eye);
    let g0 = clipmap.g0();
    #[expect(
        clippy::cast_precision_loss,
        reason = "lattice coordinates are below 2^48"
    )]
    let (fx, fy) = (ax as f64, ay as f64);
    let s = i64::from(size);
    DrawUniform {
        origin: [
            rel(d.origin[0], ax),
            rel(d.origin[1], ay),
            d.level as i32,
            size as i32,
        ],
        bounds: [
            rel(d.bounds.x0, ax),
            rel(d.bounds.y0, ay),
            rel(d.bounds.x1() - 1, ax),
            rel(d.bounds.y1() - 1, ay),
        ],
        active: [0, 0, a.w as i32 - 1, a.h as i32 - 1],
        tex: [ax.rem_euclid(s) as i32, ay.rem_euclid(s) as i32, 0, 0],
        anchor_rel: [
            ((fx * k - p.0) * g0) as f32,
            (-(fy * k - p.1) * g0) as f32,
            (-camera.eye.z) as f32,
            (g0 * k) as f32,
        ],
        morph: [
            (p.0 / k - fx) as f32,
            (p.1 / k - fy) as f32,
            (a.w as f32 - 1.0) * 0.5,
            (a.h as f32 - 1.0) * 0.5,
        ],
        morph_w: [n as f32 / 10.0, n as f32, 0.0, 0.0],
        ..DrawUniform::default()
    }
    .unsnapped()
}

/// The uniforms of SAT LOD draw `d`: like [`draw_uniform`], but anchored at the level's clip region (a block
/// drawn finer than its ring lies outside that level's active region, inside its held data), with the
/// region for one-sided normals the clip region and no morph.
#[expect(
    clippy::cast_possible_truncation,
    reason = "clip-relative lattice offsets are below the ring size; f64 -> f32 after subtracting the eye \
              is the intended GPU precision"
)]
pub fn lod_draw_uniform(
    clipmap: &Clipmap,
    camera: &Camera,
    d: &cull::Draw,
    n: u32,
    size: u32,
) -> DrawUniform {
    let c = clipmap.frame().levels[d.level as usize].clip;
    let mut u = draw_uniform(clipmap, camera, d, n, size);
    let (ax, ay) = (c.x0, c.y0);
    let rel = |v: i64, o: i64| (v - o) as i32;
    let k = f64::from(1u32 << d.level);
    let p = clipmap.eye_lattice(camera.eye);
    let g0 = clipmap.g0();
    #[expect(
        clippy::cast_precision_loss,
        reason = "lattice coordinates are below 2^48"
    )]
    let (fx, fy) = (ax as f64, ay as f64);
    let s = i64::from(size);
    u.origin[0] = rel(d.origin[0], ax);
    u.origin[1] = rel(d.origin[1], ay);
    u.bounds = [
        rel(d.bounds.x0, ax),
        rel(d.bounds.y0, ay),
        rel(d.bounds.x1() - 1, ax),
        rel(d.bounds.y1() - 1, ay),
    ];
    u.active = [0, 0, c.w as i32 - 1, c.h as i32 - 1];
    u.tex = [ax.rem_euclid(s) as i32, ay.rem_euclid(s) as i32, 0, 0];
    u.anchor_rel[0] = ((fx * k - p.0) * g0) as f32;
    u.anchor_rel[1] = (-(fy * k - p.1) * g0) as f32;
    // alpha = 0 everywhere: the transition band starts past any lattice point.
    u.morph = [0.0, 0.0, 1.0e9, 1.0e9];
    if d.fine == d.level {
        return u.unsnapped();
    }
    // A snapped tile: `d.bounds` is in the fine level's lattice, anchored at that level's clip region; the
    // shader clamps to `fine_bounds` only, so `bounds` above is not used.
    let f = clipmap.frame().levels[d.fine as usize].clip;
    let shift = d.level - d.fine;
    let kf = f64::from(1u32 << d.fine);
    #[expect(
        clippy::cast_precision_loss,
        reason = "lattice coordinates are below 2^48"
    )]
    let (gx, gy) = (f.x0 as f64, f.y0 as f64);
    u.fine = [d.fine as i32, 1 << shift, 0, 0];
    u.fine_bounds = [
        rel(d.bounds.x0, f.x0),
        rel(d.bounds.y0, f.y0),
        rel(d.bounds.x1() - 1, f.x0),
        rel(d.bounds.y1() - 1, f.y0),
    ];
    u.fine_origin = [rel(ax << shift, f.x0), rel(ay << shift, f.y0), 0, 0];
    u.fine_rel = [
        ((gx * kf - p.0) * g0) as f32,
        (-(gy * kf - p.1) * g0) as f32,
        (-camera.eye.z) as f32,
        (g0 * kf) as f32,
    ];
    u
}

/// The data's horizontal extent relative to the eye (m), for [`Globals::extent`]: lattice x grows east and
/// lattice y south, so the north edge (lattice y 0) is the largest y.
fn data_extent_rel(clipmap: &Clipmap, camera: &Camera, data_lattice: (f64, f64)) -> [f64; 4] {
    let p = clipmap.eye_lattice(camera.eye);
    let g0 = clipmap.g0();
    [
        -p.0 * g0,
        -(data_lattice.1 - p.1) * g0,
        (data_lattice.0 - p.0) * g0,
        p.1 * g0,
    ]
}

#[expect(
    clippy::cast_possible_truncation,
    reason = "eye-relative metre offsets as f32, like every position the GPU sees"
)]
fn to_f32x4(v: [f64; 4]) -> [f32; 4] {
    v.map(|e| e as f32)
}

/// One vertex as the vertex shader computes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CpuVertex {
    /// Clip-space position.
    pub clip: [f32; 4],
    /// Position relative to the eye (m).
    pub rel: [f32; 3],
    /// Morphed height z' (m).
    pub height: f32,
    /// Morph weight alpha.
    pub alpha: f32,
}

/// The CPU twin of `clip_vertex` + `vs_main` in `shaders_gles/clipmap.wgsl`, in f32, with the CPU's
/// [`morph_alpha`] evaluated in the same anchor-relative coordinates, `ring` the draw's level's ring.
#[expect(
    clippy::cast_precision_loss,
    reason = "anchor-relative lattice offsets are small integers, exact in f32"
)]
pub fn cpu_vertex(globals: &Globals, u: &DrawUniform, ring: &Ring, v: MeshVertex) -> CpuVertex {
    let sn = u.fine[1];
    let qx = (u.fine_origin[0] + (u.origin[0] + i32::from(v[0])) * sn)
        .clamp(u.fine_bounds[0], u.fine_bounds[2])
        - u.fine_origin[0];
    let qy = (u.fine_origin[1] + (u.origin[1] + i32::from(v[1])) * sn)
        .clamp(u.fine_bounds[1], u.fine_bounds[3])
        - u.fine_origin[1];
    let s = u.origin[3];
    let fetch = |x: i32, y: i32| {
        let tx = (u.tex[0] + x) % s;
        let ty = (u.tex[1] + y) % s;
        ring.texels()[(ty * s + tx) as usize]
    };
    if qx % sn != 0 || qy % sn != 0 {
        let pf = (qx + u.fine_origin[0], qy + u.fine_origin[1]);
        return cpu_snapped_vertex(globals, u, &fetch, v, (qx, qy), pf);
    }
    let (px, py) = (qx / sn, qy / sn);
    let [z, zc] = fetch(px, py);
    let active = Rect {
        x0: 0,
        y0: 0,
        w: (u.active[2] + 1) as u32,
        h: (u.active[3] + 1) as u32,
    };
    let alpha = morph_alpha(
        px as f32,
        py as f32,
        [u.morph[0], u.morph[1]],
        &active,
        #[expect(
            clippy::cast_possible_truncation,
            reason = "n is stored exactly as an f32"
        )]
        {
            u.morph_w[1] as u32
        },
    ) * globals.params[0];
    let zm = (1.0 - alpha) * z + alpha * zc;
    placed(globals, v, u.anchor_rel, (px, py), zm, alpha)
}

/// The vertex at lattice point `p` of the lattice anchored at `anchor` (xyz: position relative to the eye,
/// w: spacing) with height `z`, a skirt's lower vertex hanging to the floor, as `clip_vertex` places it.
#[expect(
    clippy::cast_precision_loss,
    reason = "anchor-relative lattice offsets are small integers, exact in f32"
)]
fn placed(
    globals: &Globals,
    v: MeshVertex,
    anchor: [f32; 4],
    (px, py): (i32, i32),
    z: f32,
    alpha: f32,
) -> CpuVertex {
    let h = if v[2] != 0 {
        z.min(globals.params[1])
    } else {
        z
    };
    let g = anchor[3];
    let rel = [
        anchor[0] + px as f32 * g,
        anchor[1] + -(py as f32) * g,
        anchor[2] + h,
    ];
    let clip = Mat4::from_cols_array(&globals.view_proj) * Vec4::new(rel[0], rel[1], rel[2], 1.0);
    CpuVertex {
        clip: clip.to_array(),
        rel,
        height: z,
        alpha,
    }
}

/// [`cpu_vertex`] on a snapped tile's edge: the level's piecewise-linear surface at `q` (level units
/// times s, anchor-relative), placed at fine point `pf`, as the shader's `snapped_vertex`.
#[expect(
    clippy::cast_precision_loss,
    reason = "anchor-relative lattice offsets are small integers, exact in f32"
)]
fn cpu_snapped_vertex(
    globals: &Globals,
    u: &DrawUniform,
    fetch: &dyn Fn(i32, i32) -> [f32; 2],
    v: MeshVertex,
    (qx, qy): (i32, i32),
    pf: (i32, i32),
) -> CpuVertex {
    let s = u.fine[1];
    let (cx, cy) = (qx / s, qy / s);
    let (fx, fy) = (
        (qx - cx * s) as f32 / s as f32,
        (qy - cy * s) as f32 / s as f32,
    );
    let cmax = |b: i32, o: i32| (b - o + s - 1) / s;
    let (c1x, c1y) = (
        (cx + 1).min(cmax(u.fine_bounds[2], u.fine_origin[0])),
        (cy + 1).min(cmax(u.fine_bounds[3], u.fine_origin[1])),
    );
    let z00 = fetch(cx, cy)[0];
    let z11 = fetch(c1x, c1y)[0];
    let (dzx, dzy) = if fx >= fy {
        let z10 = fetch(c1x, cy)[0];
        (z10 - z00, z11 - z10)
    } else {
        let z01 = fetch(cx, c1y)[0];
        (z11 - z01, z01 - z00)
    };
    let z = z00 + fx * dzx + fy * dzy;
    placed(globals, v, u.fine_rel, pf, z, 0.0)
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

/// Clear-colour pixels inside the terrain's silhouette: in each pixel column, the pixels of colour `clear`
/// lying between the lowest and the highest pixel of any other colour. A watertight render has none.
pub fn crack_pixels(image: &Image, clear: [u8; 4]) -> u64 {
    let mut cracks = 0;
    for x in 0..image.width {
        let is_clear = |y: u32| image.pixel(x, y) == clear;
        let Some(top) = (0..image.height).find(|&y| !is_clear(y)) else {
            continue;
        };
        let bottom = (0..image.height)
            .rev()
            .find(|&y| !is_clear(y))
            .expect("a non-clear pixel exists");
        cracks += (top..=bottom).filter(|&y| is_clear(y)).count() as u64;
    }
    cracks
}

/// The measured screen-space error of a drawn frame ([`screen_error`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ScreenError {
    /// The largest projected vertical error over the measured samples, pixels.
    pub max_px: f64,
    /// The same over blocks whose selected level was not clamped to the held data (the ones the error
    /// bound is a promise about; equal to `max_px` in distance mode).
    pub max_px_unclamped: f64,
    /// Data samples measured (inside the frustum).
    pub samples: u64,
    /// Every `stride`-th sample in x and y was measured (1: all).
    pub stride: u32,
}

/// Most data samples [`screen_error`] visits; past it, it subsamples with a uniform stride.
pub const SCREEN_ERROR_SAMPLES: u64 = 1 << 22;

/// Measures the last frame's screen-space error (a measurement, not the frame path): for each data sample
/// under a drawn block of level L, the error map value e_L = |H_0 - PL(H_L)| (design.md "SAT LOD" 1, from
/// `lod`'s tables) projected at that sample's distance, e * [`Camera::pixels_per_metre`], for samples inside
/// the view frustum. The GC 6.2 morph of distance mode is not modelled (its vertices lie between levels L
/// and L + 1). Visits at most [`SCREEN_ERROR_SAMPLES`] samples (a uniform stride past it).
pub fn screen_error(
    renderer: &Renderer<'_>,
    clipmap: &Clipmap,
    camera: &Camera,
    lod: &Lod,
) -> ScreenError {
    let tables = lod.tables();
    let synth = lod.synth_levels();
    let data = clipmap.pyramid().level(0);
    let spacing = clipmap.g0() * f64::from(1u32 << clipmap.synth_levels());
    let (w, h) = (renderer.width, renderer.height);
    let frustum = cull::Frustum::new(camera, f64::from(w) / f64::from(h));
    // The data's last sample in level-0 lattice units.
    let last = (
        i64::from(data.width() - 1) << clipmap.synth_levels(),
        i64::from(data.height() - 1) << clipmap.synth_levels(),
    );
    let boxes = || {
        renderer
            .draws
            .iter()
            .filter(|d| d.kind == DrawKind::Block)
            .filter_map(move |d| {
                // In the fine lattice: a snapped tile is its level's surface cut at the piece's edge, so
                // its level's error map over the covered samples is exact.
                let c = d.covered(d.quads.max(1));
                let (l, f) = (d.level, d.fine);
                let (a, cc, b, dd) = (c.x0 << f, c.y0 << f, (c.x1() - 1) << f, (c.y1() - 1) << f);
                // Geometry past the data collapses onto its border (not a surface to measure).
                let inside = b >= 0 && dd >= 0 && a <= last.0 && cc <= last.1;
                inside.then(|| (l, d.clamped, tables.data_box(synth, a, cc, b, dd)))
            })
    };
    let total: u64 = boxes()
        .map(|(_, _, (x0, y0, x1, y1))| u64::from(x1 - x0) * u64::from(y1 - y0))
        .sum();
    let mut stride = 1u32;
    while total / u64::from(stride * stride) > SCREEN_ERROR_SAMPLES {
        stride += 1;
    }
    let mut out = ScreenError {
        stride,
        ..ScreenError::default()
    };
    let (ox, oy) = clipmap.origin();
    let top = oy + f64::from(data.height() - 1) * spacing;
    for (l, clamped, (x0, y0, x1, y1)) in boxes() {
        let errors = l
            .checked_sub(synth)
            .and_then(|k| tables.level(k))
            .and_then(|t| t.tables())
            .map(|(_, max)| max.values());
        let Some(errors) = errors else {
            // The data level or finer: no error against the data.
            continue;
        };
        // Aligned to the stride so overlapping boxes visit the same samples.
        for y in (y0.next_multiple_of(stride)..y1).step_by(stride as usize) {
            for x in (x0.next_multiple_of(stride)..x1).step_by(stride as usize) {
                let z = f64::from(data.at_clamped(i64::from(x), i64::from(y)));
                let rel = glam::DVec3::new(
                    ox + f64::from(x) * spacing - camera.eye.x,
                    top - f64::from(y) * spacing - camera.eye.y,
                    z - camera.eye.z,
                );
                if !frustum.intersects(rel, rel) {
                    continue;
                }
                let e = f64::from(errors[y as usize * tables.width as usize + x as usize]);
                out.samples += 1;
                let px = e * camera.pixels_per_metre(rel.length(), h);
                out.max_px = out.max_px.max(px);
                if !clamped {
                    out.max_px_unclamped = out.max_px_unclamped.max(px);
                }
            }
        }
    }
    out
}

/// Root-mean-square difference of two RGBA8 images of the same size over every pixel and the R, G, B
/// channels, in 0..255 units (None when the sizes differ).
pub fn image_rmse(a: &Image, b: &Image) -> Option<f64> {
    if a.width != b.width || a.height != b.height || a.rgba.len() != b.rgba.len() {
        return None;
    }
    let (mut sum, mut n) = (0.0f64, 0u64);
    for (p, q) in a.rgba.chunks_exact(4).zip(b.rgba.chunks_exact(4)) {
        for c in 0..3 {
            let d = f64::from(p[c]) - f64::from(q[c]);
            sum += d * d;
            n += 1;
        }
    }
    Some(if n == 0 { 0.0 } else { (sum / n as f64).sqrt() })
}

/// [`CRACK_CLEAR`] as RGBA8.
pub const CRACK_CLEAR_RGBA8: [u8; 4] = [255, 0, 255, 255];

fn terrain_pipeline(
    device: &wgpu::Device,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    fragment_entry: &str,
) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("clipmap"),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[Some(vertex_layout())],
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            front_face: wgpu::FrontFace::Ccw,
            // Skirts and terrain seen from below show back faces; draw both sides.
            cull_mode: None,
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some(fragment_entry),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: COLOR_FORMAT,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

fn vertex_layout() -> wgpu::VertexBufferLayout<'static> {
    const ATTRS: [wgpu::VertexAttribute; 1] = wgpu::vertex_attr_array![0 => Uint16x4];
    wgpu::VertexBufferLayout {
        array_stride: VERTEX_BYTES,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &ATTRS,
    }
}

/// Test instrument: runs the renderer's vertex shader over one draw of the last frame as points and reads
/// back the clip-space position of every mesh vertex, bit for bit (an Rgba32Uint target). Creates its own
/// pipeline and target (outside the renderer's ledger).
#[derive(Debug)]
pub struct VertexProbe {
    pipeline: wgpu::RenderPipeline,
    target: wgpu::Texture,
    view: wgpu::TextureView,
    buffer: wgpu::Buffer,
    size: [u32; 2],
}

impl VertexProbe {
    /// The probe for `renderer`'s pipeline layout and shader.
    pub fn new(renderer: &Renderer<'_>) -> Result<Self> {
        let gpu = renderer.gpu;
        let size = renderer.probe_size;
        gpu.scoped("vertex probe set-up", || {
            let device = gpu.device();
            let target = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("vertex probe"),
                size: wgpu::Extent3d {
                    width: size[0],
                    height: size[1],
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba32Uint,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            });
            let view = target.create_view(&Default::default());
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("vertex probe readback"),
                size: u64::from(size[0]) * 16 * u64::from(size[1]),
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            });
            let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("vertex probe"),
                layout: Some(&renderer.pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &renderer.module,
                    entry_point: Some("vs_capture"),
                    compilation_options: Default::default(),
                    buffers: &[Some(vertex_layout())],
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::PointList,
                    ..Default::default()
                },
                depth_stencil: None,
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &renderer.module,
                    entry_point: Some("fs_capture"),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: wgpu::TextureFormat::Rgba32Uint,
                        blend: None,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            });
            Ok(Self {
                pipeline,
                target,
                view,
                buffer,
                size,
            })
        })
    }

    /// The GPU's clip-space position of every vertex of the last frame's draw `index`, in mesh order.
    pub fn capture(&self, renderer: &Renderer<'_>, index: usize) -> Result<Vec<[f32; 4]>> {
        let gpu = renderer.gpu;
        let d = renderer.draws.get(index).ok_or_else(|| Error::Arg {
            arg: "draw index".into(),
            reason: format!("{index} is past the {} draws", renderer.draws.len()),
        })?;
        let m = renderer.mesh(d.kind);
        gpu.scoped("vertex probe", || {
            let mut encoder = gpu.device().create_command_encoder(&Default::default());
            {
                let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("vertex probe"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &self.view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    depth_stencil_attachment: None,
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                });
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &renderer.group0, &[]);
                let offset = u32::try_from(index as u64 * DRAW_SLOT_BYTES)
                    .expect("draw slots fit a u32 offset");
                pass.set_bind_group(1, &renderer.group1, &[offset]);
                pass.set_vertex_buffer(0, m.vertices.slice(..));
                pass.draw(0..m.vertex_count, 0..1);
            }
            encoder.copy_texture_to_buffer(
                self.target.as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer: &self.buffer,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(self.size[0] * 16),
                        rows_per_image: Some(self.size[1]),
                    },
                },
                self.target.size(),
            );
            gpu.queue().submit([encoder.finish()]);
            Ok(())
        })?;
        let bytes = crate::gpu::readback::map_rows(
            gpu,
            &self.buffer,
            self.size[0] * 16,
            self.size[0] * 16,
        )?;
        let texels: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&bytes);
        Ok(texels[..m.vertex_count as usize].to_vec())
    }
}
