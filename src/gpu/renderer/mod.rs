//! Stage 3, the GPU: the GLES 3.0 geometry clipmap renderer (Losasso & Hoppe 2004, "GC").
//!
//! [`Renderer::new`] creates every GPU object, sized from the profile, and records each in a [`Ledger`]
//! whose bytes equal [`Profile::footprint`]. A frame then creates nothing but a command encoder:
//!
//! 1. [`Renderer::upload`]: the frame's `uploads` (at most 4 sub-rectangles per level) go straight from
//!    [`Ring::bytes`](crate::plan::clipmap::Ring::bytes) into one RG32F 2D array texture (S x S x L, toroidal) with `write_texture`, no copies.
//! 2. [`Renderer::draw`]: the draw list ([`crate::plan::cull`]), one 256-byte uniform slot per draw (one
//!    `write_buffer`), one render pass with a Depth32Float buffer and the basic shading.
//! 3. [`Renderer::read_image`]: readback into the preallocated buffer.
//!
//! The vertex shader (`shaders_gles/clipmap.wgsl`) morphs z' = (1 - alpha) z + alpha z_c with GC 6.2's
//! alpha ([`crate::plan::clipmap::morph_alpha`]) and derives normals from the geometry (GC 6.3);
//! [`crate::twin::clipmap::cpu_vertex`] is its CPU twin. The uniforms it writes are packed by
//! [`crate::plan::uniforms`].
//!
//! Files: this one holds the type and its set-up; `frame.rs` upload, draw and read-back; `sg.rs` the SG
//! shading variant; `ledger.rs` the object ledger; `probe.rs` the vertex-probe test instrument.

mod frame;
mod ledger;
mod probe;
mod sg;

pub use frame::{render_frame, FrameOptions, FrameStats, RenderedFrame};
pub use ledger::{Ledger, LedgerEntry, ObjectKind};
pub use probe::VertexProbe;
use sg::SgState;

use bytemuck::Zeroable;
use wgpu::util::DeviceExt;

use crate::gpu::shaders;
use crate::gpu::Gpu;
use crate::plan::clipmap::Clipmap;
use crate::plan::cull::{self, DrawKind, DrawList, MAX_DRAWS};
use crate::plan::lod::{Lod, LodFrame};
use crate::plan::mesh::{self, Mesh, MeshVertex};
use crate::plan::uniforms::{DrawUniform, Globals};
use crate::profile::{DRAW_SLOT_BYTES, GLOBALS_BYTES};
use crate::shading::basic::BasicShading;
use crate::{Error, Profile, Result};

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

    fn mesh(&self, kind: DrawKind) -> &GpuMesh {
        match kind {
            DrawKind::Block => &self.block,
            DrawKind::Skirt => &self.skirt,
            DrawKind::TileSkirt => &self.tile_skirt,
        }
    }
}

impl Drop for Renderer<'_> {
    fn drop(&mut self) {
        // Its objects are GL objects of this Gpu's context: make it current before they go.
        self.gpu.bind();
    }
}

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
