//! Stage 3, the GPU: a test instrument that reads back the vertex shader's clip-space output (its objects
//! are made through its own [`Ledgered`], outside the renderer's ledger).

use super::{vertex_buffers, Ledgered};
use crate::gpu::headless::Offscreen;
use crate::profile::{DRAW_SLOT_BYTES, POOL_CELL_BYTES};
use crate::{Error, Result};

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
    /// The probe for `offscreen`'s pipeline layout and shader.
    pub fn new(offscreen: &Offscreen<'_>) -> Result<Self> {
        let gpu = offscreen.gpu();
        let renderer = offscreen.renderer();
        let size = offscreen.planner().probe_size();
        gpu.scoped("vertex probe set-up", || {
            let mut dev = Ledgered::new(gpu.device());
            let target = dev.texture(
                "vertex probe",
                &crate::gpu::render_target(
                    size[0],
                    size[1],
                    wgpu::TextureFormat::Rgba32Uint,
                    wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                ),
            );
            let view = dev.view("vertex probe view", &target, &Default::default());
            let buffer = dev.buffer(
                "vertex probe readback",
                u64::from(size[0]) * 16 * u64::from(size[1]),
                wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            );
            let pipeline = dev.render_pipeline(
                "vertex probe",
                &wgpu::RenderPipelineDescriptor {
                    label: None,
                    layout: Some(&renderer.pipeline_layout),
                    vertex: wgpu::VertexState {
                        module: &renderer.module,
                        entry_point: Some("vs_capture"),
                        compilation_options: Default::default(),
                        buffers: &vertex_buffers(),
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
                },
            );
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
    pub fn capture(&self, offscreen: &Offscreen<'_>, index: usize) -> Result<Vec<[f32; 4]>> {
        let draws = offscreen.draws();
        if index >= draws.len() {
            return Err(Error::Invalid {
                what: "draw index".into(),
                reason: format!("{index} is past the {} draws", draws.len()),
            });
        }
        let (call, instance) = offscreen
            .plan()
            .call_of(index)
            .ok_or_else(|| Error::Invalid {
                what: "draw index".into(),
                reason: format!(
                    "draw {index} is a stitched cell: capture its units' calls (capture_instance)"
                ),
            })?;
        self.capture_instance(offscreen, call, instance)
    }

    /// The GPU's clip-space position of every vertex of the mesh of the last frame's call `call`, drawn
    /// as its instance `instance` (a stitched cell's unit, a pool cell, or 0 for any other call).
    pub fn capture_instance(
        &self,
        offscreen: &Offscreen<'_>,
        call: usize,
        instance: u32,
    ) -> Result<Vec<[f32; 4]>> {
        let gpu = offscreen.gpu();
        let renderer = offscreen.renderer();
        let planned = offscreen.plan().planned();
        let c = planned.get(call).ok_or_else(|| Error::Invalid {
            what: "draw call".into(),
            reason: format!("{call} is past the {} calls", planned.len()),
        })?;
        if instance >= c.instances() {
            return Err(Error::Invalid {
                what: "instance".into(),
                reason: format!("{instance} is past call {call}'s {}", c.instances()),
            });
        }
        let m = renderer.mesh(c.kind);
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
                let offset = u32::try_from(call as u64 * DRAW_SLOT_BYTES)
                    .expect("draw slots fit a u32 offset");
                pass.set_bind_group(1, &renderer.group1, &[offset]);
                pass.set_vertex_buffer(0, m.vertices.slice(..));
                // The draw's own cell as instance 0 (a pool call's instance `instance`; any other call
                // has one instance, 0).
                let at = u64::from(offscreen.plan().planned()[call].cells.start + instance);
                pass.set_vertex_buffer(1, renderer.pool_cells.slice(at * POOL_CELL_BYTES..));
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
