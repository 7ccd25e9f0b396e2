//! Stage 3, the GPU: draped imagery, the colour clipmap's GPU side (`shaders_gles/imagery.wgsl`): one 2D
//! array texture of `ring^2 x layers` texels (a layer a level, and GL's spare:
//! `ImageryBudget::layers`), RGBA8, or BC1 / ETC2 RGB8 blocks where the device has them
//! ([`Renderer::imagery_format`]), its uniform, a bind group (group 2) and the imagery
//! variant of the four fragment programs. Created once by [`Renderer::enable_imagery`] for a terrain
//! with imagery (counted in the ledger, [`crate::profile::Profile::imagery_gpu_bytes`]); a renderer
//! without it creates, binds and compiles none of this. Each frame [`Renderer::prepare_imagery`] writes
//! the plan's colour uploads ([`ColorRings::uploads`]) and the uniform, and creates nothing.

use super::sg::{programs, SgPrograms};
use super::{array_texture, terrain_pipeline, Ledgered, Renderer, FRAGMENT_ENTRIES};
use crate::gpu::shaders::{self, SgVariant};
use crate::package::color_blocks::ColorFormat;
use crate::plan::color_rings::{ColorRings, ColorUpload, ImageryUniform};
use crate::plan::fragment::FRAGMENT_PATHS;
use crate::{Error, Result};

/// The colour rings' texture format for `format`: all filterable on GLES 3.0, all unorm (no sRGB
/// decode: the shader decodes the display-encoded colour itself, whatever the format).
fn texture_format(format: ColorFormat) -> wgpu::TextureFormat {
    match format {
        ColorFormat::Rgba8 => wgpu::TextureFormat::Rgba8Unorm,
        ColorFormat::Bc1 => wgpu::TextureFormat::Bc1RgbaUnorm,
        ColorFormat::Etc2Rgb8 => wgpu::TextureFormat::Etc2Rgb8Unorm,
    }
}

/// The device feature a format needs (none for RGBA8).
fn feature(format: ColorFormat) -> wgpu::Features {
    match format {
        ColorFormat::Rgba8 => wgpu::Features::empty(),
        ColorFormat::Bc1 => wgpu::Features::TEXTURE_COMPRESSION_BC,
        ColorFormat::Etc2Rgb8 => wgpu::Features::TEXTURE_COMPRESSION_ETC2,
    }
}
/// Bytes of the imagery uniform.
const UNIFORM_BYTES: u64 = std::mem::size_of::<ImageryUniform>() as u64;

/// The imagery's GPU objects.
#[derive(Debug)]
pub(super) struct ImageryState {
    texture: wgpu::Texture,
    _sampler: wgpu::Sampler,
    uniform: wgpu::Buffer,
    _layout: wgpu::BindGroupLayout,
    pub(super) group: wgpu::BindGroup,
    pub(super) pipelines: [wgpu::RenderPipeline; FRAGMENT_PATHS],
    /// Under SG shading: the SG variant drawn with imagery and its programs (group 3).
    pub(super) sg: Option<(SgVariant, SgPrograms)>,
    pub(super) ring: u32,
    pub(super) levels: u32,
    pub(super) format: ColorFormat,
}

impl Renderer {
    /// The colour rings' format on `device`, from the features it was created with (clipsat requests
    /// none): BC1 where it has `TEXTURE_COMPRESSION_BC` (desktop GPUs), else ETC2 RGB8 where it has
    /// `TEXTURE_COMPRESSION_ETC2` (GLES 3.0 devices, most mobile ones), else RGBA8; RGBA8 whenever
    /// `rgba8` is set. The block formats take 0.5 byte a texel, RGBA8 4.
    pub fn imagery_format(device: &wgpu::Device, rgba8: bool) -> ColorFormat {
        let has = device.features();
        if rgba8 {
            ColorFormat::Rgba8
        } else if has.contains(feature(ColorFormat::Bc1)) {
            ColorFormat::Bc1
        } else if has.contains(feature(ColorFormat::Etc2Rgb8)) {
            ColorFormat::Etc2Rgb8
        } else {
            ColorFormat::Rgba8
        }
    }

    /// Creates the colour rings (`ring^2 x layers` texels in `format`), their uniform, bind group and the imagery
    /// programs, once: frames then draw the terrain's albedo from the imagery under basic shading (and
    /// its fog), and under SG shading the diffuse term of the SG variant drawn now scaled by the imagery's
    /// albedo over the scene's k_d (the bind group at 3, after the SG tables'; a variant switched to later
    /// by [`Renderer::set_sg_effects`] draws without imagery). Refused a second time, past the
    /// device's limits, or in a format the device lacks.
    pub fn enable_imagery(
        &mut self,
        device: &wgpu::Device,
        ring: u32,
        levels: u32,
        format: ColorFormat,
    ) -> Result<()> {
        let refuse = |reason: &str| Error::Invalid {
            what: "imagery".into(),
            reason: reason.into(),
        };
        if self.imagery.is_some() {
            return Err(refuse("the renderer's imagery is already set up"));
        }
        if !device.features().contains(feature(format)) {
            return Err(Error::Unsupported {
                limit: match format {
                    ColorFormat::Bc1 => "TEXTURE_COMPRESSION_BC",
                    _ => "TEXTURE_COMPRESSION_ETC2",
                },
                needed: 1,
                available: 0,
            });
        }
        let limits = device.limits();
        let layers = crate::profile::ImageryBudget::layers(levels);
        if layers > limits.max_texture_array_layers || levels == 0 {
            return Err(Error::Unsupported {
                limit: "max_texture_array_layers",
                needed: u64::from(layers),
                available: u64::from(limits.max_texture_array_layers),
            });
        }
        if ring > limits.max_texture_dimension_2d {
            return Err(Error::Unsupported {
                limit: "max_texture_dimension_2d",
                needed: u64::from(ring),
                available: u64::from(limits.max_texture_dimension_2d),
            });
        }
        let mut dev = Ledgered::new(device);
        let texture = dev.texture(
            "imagery rings",
            &array_texture(ring, layers, texture_format(format), wgpu::TextureUsages::COPY_SRC),
        );
        let view = dev.view(
            "imagery rings view",
            &texture,
            &wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2Array),
                ..Default::default()
            },
        );
        // Bilinear, wrapping: the ring's toroidal addresses are its texels modulo the ring, which the
        // repeat mode gives for free.
        let sampler = dev.sampler(
            "imagery sampler",
            &wgpu::SamplerDescriptor {
                address_mode_u: wgpu::AddressMode::Repeat,
                address_mode_v: wgpu::AddressMode::Repeat,
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                ..Default::default()
            },
        );
        let uniform = dev.buffer(
            "imagery uniform",
            UNIFORM_BYTES,
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        );
        let layout = dev.bind_group_layout(
            "imagery layout",
            &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: wgpu::BufferSize::new(UNIFORM_BYTES),
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2Array,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        );
        let group = dev.bind_group(
            "imagery group",
            &layout,
            &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniform.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::Sampler(&sampler),
                },
            ],
        );
        let module = dev.shader_module("clipmap.wgsl (imagery)", shaders::clipmap_imagery());
        let pipeline_layout = dev.pipeline_layout(
            "imagery pipeline layout",
            &[
                Some(&self._group0_layout),
                Some(&self._group1_layout),
                Some(&layout),
            ],
        );
        let targets = self.targets;
        let pipelines = FRAGMENT_ENTRIES.map(|(label, entry)| {
            terrain_pipeline(&mut dev, label, &pipeline_layout, &module, entry, &targets)
        });
        let sg = self.sg.as_ref().map(|sg| {
            let module = dev.shader_module(
                "sg_clipmap.wgsl (imagery)",
                shaders::sg_clipmap_imagery(sg.variant),
            );
            let layout = dev.pipeline_layout(
                "sg imagery pipeline layout",
                &[
                    Some(&self._group0_layout),
                    Some(&self._group1_layout),
                    Some(&sg._layout),
                    Some(&layout),
                ],
            );
            (sg.variant, programs(&mut dev, &module, &layout, &targets))
        });
        self.ledger.extend(&dev.finish());
        self.imagery = Some(ImageryState {
            texture,
            _sampler: sampler,
            uniform,
            _layout: layout,
            group,
            pipelines,
            sg,
            ring,
            levels,
            format,
        });
        Ok(())
    }

    /// Whether frames draw imagery ([`Renderer::enable_imagery`], and no debug view).
    pub fn draws_imagery(&self) -> bool {
        self.imagery.is_some() && self.debug.code() == 0
    }

    /// The colour rings' texture, where imagery is set up.
    pub fn imagery_texture(&self) -> Option<&wgpu::Texture> {
        self.imagery.as_ref().map(|i| &i.texture)
    }

    /// Writes `rings`' uploads of its last update into the colour rings and its uniform with the eye at
    /// world (x, y); creates nothing. Refused for rings of another size than set up.
    pub fn prepare_imagery(
        &self,
        queue: &wgpu::Queue,
        rings: &ColorRings,
        (x, y): (f64, f64),
    ) -> Result<()> {
        let Some(state) = &self.imagery else {
            return Err(Error::Invalid {
                what: "imagery".into(),
                reason: "the renderer has no imagery set up (Renderer::enable_imagery)".into(),
            });
        };
        if rings.ring() != state.ring
            || rings.level_count() > state.levels
            || rings.format() != state.format
        {
            return Err(Error::Invalid {
                what: "imagery".into(),
                reason: format!(
                    "rings of {} x {} levels in {} for a texture of {} x {} in {}",
                    rings.ring(),
                    rings.level_count(),
                    rings.format().name(),
                    state.ring,
                    state.levels,
                    state.format.name()
                ),
            });
        }
        for u in rings.uploads() {
            let bytes = usize::try_from(state.format.bytes(u.w, u.h)).unwrap_or(usize::MAX);
            let texels = &rings.staging()[u.offset..u.offset + bytes];
            write_colour(queue, &state.texture, state.format, u, texels);
        }
        queue.write_buffer(&state.uniform, 0, bytemuck::bytes_of(&rings.uniform(x, y)));
        Ok(())
    }
}

impl Renderer {
    /// The colour rings' format, where imagery is set up.
    pub fn imagery_texture_format(&self) -> Option<ColorFormat> {
        self.imagery.as_ref().map(|i| i.format)
    }
}

/// One colour upload: `u.w x u.h` texels at (u.x, u.y) of layer `u.level`, in `format`'s layout (RGBA8
/// rows packed, or rows of 4 x 4 blocks: `bytes_per_row` counts a row of blocks, x, y, w and h are
/// multiples of 4).
fn write_colour(
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
    format: ColorFormat,
    u: &ColorUpload,
    rgba: &[u8],
) {
    queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d {
                x: u.x,
                y: u.y,
                z: u.level,
            },
            aspect: wgpu::TextureAspect::All,
        },
        rgba,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(format.row_bytes(u.w)),
            rows_per_image: Some(u.h.div_ceil(format.block())),
        },
        wgpu::Extent3d {
            width: u.w,
            height: u.h,
            depth_or_array_layers: 1,
        },
    );
}

impl Renderer {
    /// Writes every texel `rings` hold into a texture made again ([`ColorRings::restore`]), after a lost
    /// device: the frames after it draw what they would have.
    pub fn restore_imagery(&self, queue: &wgpu::Queue, rings: &ColorRings) -> Result<()> {
        let Some(state) = &self.imagery else {
            return Ok(());
        };
        rings.restore(|u, rgba| {
            write_colour(queue, &state.texture, state.format, u, rgba);
            Ok(())
        })
    }
}
