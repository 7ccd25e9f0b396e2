//! Stage 3, the GPU: test instrument for the SG fragment shading. Runs the WGSL `sg_shade`
//! (`shaders_gles/sg_probe.wgsl`) on known inputs, one per pixel of a W x 1 Rgba32Uint target, and reads
//! back the exact bits of each result, for comparison with the CPU twin [`crate::shading::shade`] (the
//! scene's sky table bound as the renderer binds it; with visibility the light table's texel of each case
//! computed on the CPU, [`crate::shading::texel_light`], as the renderer writes it).

use glam::Vec3;
use wgpu::util::DeviceExt;

use crate::bake::horizon::MAX_AZIMUTHS;
use crate::gpu::shaders::{self, SgSceneUniform, SgVariant};
use crate::gpu::Gpu;
use crate::profile::{SG_SKY_LAYERS, SG_SKY_SIDE};
use crate::shading::scene::Scene;
use crate::shading::{texel_light, Patches, SkyTable};
use crate::{Error, Result};

/// One probe input: what the fragment shader knows after its SAT fetches.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeCase {
    /// Box-averaged mean normal.
    pub r: Vec3,
    /// Unit direction to the eye.
    pub view: Vec3,
    /// Box-averaged horizon angles (D of them, D <= 16); empty: visibility off. With visibility the probe
    /// hands the GPU [`crate::shading::texel_light`] of them.
    pub horizon: heapless::Vec<f32, 16>,
}

/// Most cases per probe run (the target's width).
pub const MAX_CASES: usize = 2048;

/// Evaluates the GPU shading of `scene` with `patches` for every case (all cases share one D, that of the
/// first). Returns linear RGB per case.
pub fn shade_gpu(
    gpu: &Gpu,
    scene: &Scene,
    patches: Patches,
    cases: &[ProbeCase],
) -> Result<Vec<Vec3>> {
    if cases.is_empty() || cases.len() > MAX_CASES {
        return Err(Error::Invalid {
            what: "probe cases".into(),
            reason: format!("{} cases, need 1..={MAX_CASES}", cases.len()),
        });
    }
    let d = cases[0].horizon.len();
    if cases.iter().any(|c| c.horizon.len() != d)
        || d > MAX_AZIMUTHS as usize
        || !d.is_multiple_of(4)
    {
        return Err(Error::Invalid {
            what: "probe cases".into(),
            reason: "every case needs the same number of horizon angles, a multiple of 4 up to 16"
                .into(),
        });
    }
    let width = u32::try_from(cases.len()).expect("<= MAX_CASES");
    let variant = SgVariant {
        patches,
        visibility: scene.effects.visibility && d > 0,
        specular: scene.effects.specular,
        // The probe returns the unfogged shade.
        fog: false,
        omit: shaders::SgOmit::None,
    };
    let uniform = SgSceneUniform::new(scene, u32::try_from(d).expect("<= 16"))?;
    // The view-independent part with visibility: what the light table would hold for the case
    // (`shading::texel_light`, on the CPU as the renderer computes it).
    let sky_table = SkyTable::new(scene, patches);
    // Rows: r (w: the horizon's sine toward the first sun), view, the light texel (rgb: diffuse, a: the
    // horizon's mean sine); without visibility w and a are -2.
    let mut texels = vec![[0.0f32; 4]; cases.len() * 3];
    for (i, c) in cases.iter().enumerate() {
        let light = variant.visibility.then(|| {
            let sines: heapless::Vec<f32, 16> = c.horizon.iter().map(|a| a.sin()).collect();
            texel_light(c.r, &sines, scene, &sky_table)
        });
        let (sun_sin, texel) = light.map_or((-2.0, [0.0, 0.0, 0.0, -2.0]), |t| {
            (
                t.sun_sin,
                [t.diffuse.x, t.diffuse.y, t.diffuse.z, t.mean_sin],
            )
        });
        texels[i] = [c.r.x, c.r.y, c.r.z, sun_sin];
        texels[cases.len() + i] = [c.view.x, c.view.y, c.view.z, 0.0];
        texels[2 * cases.len() + i] = texel;
    }
    let device = gpu.device();
    let bytes = gpu.scoped("sg probe", || {
        let inputs = device.create_texture_with_data(
            gpu.queue(),
            &wgpu::TextureDescriptor {
                label: Some("sg probe inputs"),
                ..crate::gpu::texture_2d(
                    width,
                    3,
                    1,
                    wgpu::TextureFormat::Rgba32Float,
                    wgpu::TextureUsages::empty(),
                )
            },
            wgpu::util::TextureDataOrder::LayerMajor,
            bytemuck::cast_slice(&texels),
        );
        let sky = device.create_texture_with_data(
            gpu.queue(),
            &wgpu::TextureDescriptor {
                label: Some("sg probe sky_table"),
                ..crate::gpu::texture_2d(
                    SG_SKY_SIDE * SG_SKY_LAYERS,
                    SG_SKY_SIDE,
                    1,
                    wgpu::TextureFormat::Rgba32Float,
                    wgpu::TextureUsages::empty(),
                )
            },
            wgpu::util::TextureDataOrder::LayerMajor,
            bytemuck::cast_slice(sky_table.texels()),
        );
        let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("sg probe scene"),
            contents: bytemuck::bytes_of(&uniform),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("sg_probe.wgsl"),
            source: wgpu::ShaderSource::Wgsl(shaders::sg_probe(variant).into()),
        });
        let target = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("sg probe target"),
            ..crate::gpu::render_target(
                width,
                1,
                wgpu::TextureFormat::Rgba32Uint,
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            )
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("sg probe"),
            layout: None,
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_probe"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_probe"),
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
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("sg probe"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(
                        &inputs.create_view(&Default::default()),
                    ),
                },
                wgpu::BindGroupEntry {
                    binding: shaders::SKY_TABLE_PROBE.1,
                    resource: wgpu::BindingResource::TextureView(
                        &sky.create_view(&Default::default()),
                    ),
                },
            ],
        });
        let padded = (width * 16).div_ceil(256) * 256;
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("sg probe readback"),
            size: u64::from(padded),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let view = target.create_view(&Default::default());
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("sg probe"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &view,
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
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.draw(0..3, 0..1);
        }
        encoder.copy_texture_to_buffer(
            target.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded),
                    rows_per_image: Some(1),
                },
            },
            target.size(),
        );
        gpu.queue().submit([encoder.finish()]);
        crate::gpu::readback::map_rows(gpu, &readback, padded, width * 16)
    })?;
    let px: &[[f32; 4]] = bytemuck::cast_slice(&bytes);
    Ok(px.iter().map(|p| Vec3::new(p[0], p[1], p[2])).collect())
}
