//! Stage 3, the GPU: a test and self-test instrument that reads back, per pixel of a prepared frame, what
//! the fragment program shaded it with (its objects are made through its own [`Ledgered`], outside the
//! renderer's ledger), for the CPU twins to recompute the pixel's colour from (`twin::frame`).

use super::frame::ProbePrograms;
use super::{pipeline_to, Ledgered, Renderer, Targets, FRAGMENT_ENTRIES};
use crate::gpu::headless::Offscreen;
use crate::Result;

/// Each [`crate::plan::fragment::FragmentPath`]'s probe entry point in `clipmap.wgsl`, in discriminant
/// order (the same discards as [`FRAGMENT_ENTRIES`]).
const PROBE_ENTRIES: [&str; 4] = [
    "fs_probe_interior",
    "fs_probe_plain",
    "fs_probe_ring_data",
    "fs_probe_skirt",
];

/// What a frame's programs shaded each pixel with, row-major, `None` where nothing was drawn.
#[derive(Clone, Debug, Default)]
pub struct ProbedFrame {
    /// Pixels per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Per pixel: xyz the eye-relative position (m) the fragment interpolated; w the footprint the
    /// program computed from its derivatives (basic shading: metres; SG: data samples, `sg_footprint`).
    pub position: Vec<Option<[f32; 4]>>,
    /// Per pixel: basic shading's height and normal (`ring_data_inputs`, or the vertex values); SG's r
    /// (xyz, w the horizon's sine toward the first sun).
    pub inputs: Vec<[f32; 4]>,
}

/// The instrument: the renderer's draws of the prepared frame again, with probe programs into two
/// RGBA32 uint targets (the exact bits) and a depth target of the frame's format, so each pixel keeps the
/// fragment the frame shows.
#[derive(Debug)]
pub struct ShadingProbe {
    programs: ProbePrograms,
    targets: [wgpu::Texture; 2],
    views: [wgpu::TextureView; 2],
    depth: wgpu::TextureView,
    buffers: [wgpu::Buffer; 2],
    size: (u32, u32),
}

impl ShadingProbe {
    /// The probe for `offscreen`'s renderer (its shading variant) and viewport.
    pub fn new(offscreen: &Offscreen<'_>) -> Result<Self> {
        let gpu = offscreen.gpu();
        let renderer: &Renderer = offscreen.renderer();
        let (width, height) = offscreen.size();
        gpu.scoped("shading probe set-up", || {
            let mut dev = Ledgered::new(gpu.device());
            let target = |dev: &mut Ledgered<'_>, format, usage| {
                dev.texture(
                    "shading probe",
                    &crate::gpu::render_target(width, height, format, usage),
                )
            };
            let read = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
            let targets = [
                target(&mut dev, wgpu::TextureFormat::Rgba32Uint, read),
                target(&mut dev, wgpu::TextureFormat::Rgba32Uint, read),
            ];
            let depth = target(
                &mut dev,
                renderer.targets.depth,
                wgpu::TextureUsages::RENDER_ATTACHMENT,
            );
            let views = [
                dev.view("shading probe view", &targets[0], &Default::default()),
                dev.view("shading probe view", &targets[1], &Default::default()),
            ];
            let depth = dev.view("shading probe depth", &depth, &Default::default());
            let row = u64::from(width * 16).next_multiple_of(256);
            let buffers = [0, 1].map(|_| {
                dev.buffer(
                    "shading probe readback",
                    row * u64::from(height),
                    wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                )
            });
            let colour = [0, 1].map(|_| {
                Some(wgpu::ColorTargetState {
                    format: wgpu::TextureFormat::Rgba32Uint,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })
            });
            let t = Targets {
                samples: 1,
                ..renderer.targets
            };
            let basic = std::array::from_fn(|i| {
                pipeline_to(
                    &mut dev,
                    FRAGMENT_ENTRIES[i].0,
                    &renderer.pipeline_layout,
                    &renderer.module,
                    PROBE_ENTRIES[i],
                    &t,
                    &colour,
                )
            });
            let sg = renderer
                .sg
                .as_ref()
                .map(|sg| sg.probe_programs(&mut dev, &colour));
            Ok(Self {
                programs: ProbePrograms { basic, sg },
                targets,
                views,
                depth,
                buffers,
                size: (width, height),
            })
        })
    }

    /// Draws `offscreen`'s prepared frame (its last [`Offscreen::frame`]) with the probe programs and
    /// reads both targets back.
    pub fn capture(&self, offscreen: &Offscreen<'_>) -> Result<ProbedFrame> {
        let gpu = offscreen.gpu();
        let renderer = offscreen.renderer();
        let (width, height) = self.size;
        let row = (width * 16).next_multiple_of(256);
        gpu.scoped("shading probe", || {
            let mut encoder = gpu.device().create_command_encoder(&Default::default());
            {
                let colour = self.views.each_ref().map(|view| {
                    Some(wgpu::RenderPassColorAttachment {
                        view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                            store: wgpu::StoreOp::Store,
                        },
                    })
                });
                let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("shading probe"),
                    color_attachments: &colour,
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &self.depth,
                        depth_ops: Some(wgpu::Operations {
                            load: wgpu::LoadOp::Clear(1.0),
                            store: wgpu::StoreOp::Discard,
                        }),
                        stencil_ops: None,
                    }),
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                });
                renderer.record(&mut pass, Some(&self.programs));
            }
            for (t, b) in self.targets.iter().zip(&self.buffers) {
                encoder.copy_texture_to_buffer(
                    t.as_image_copy(),
                    wgpu::TexelCopyBufferInfo {
                        buffer: b,
                        layout: wgpu::TexelCopyBufferLayout {
                            offset: 0,
                            bytes_per_row: Some(row),
                            rows_per_image: Some(height),
                        },
                    },
                    t.size(),
                );
            }
            gpu.queue().submit([encoder.finish()]);
            Ok(())
        })?;
        let mut out = ProbedFrame {
            width,
            height,
            ..ProbedFrame::default()
        };
        let read = |b: &wgpu::Buffer| -> Result<Vec<[u32; 4]>> {
            let bytes = crate::gpu::readback::map_rows(gpu, b, row, width * 16)?;
            Ok(bytemuck::pod_collect_to_vec(&bytes))
        };
        let (position, inputs) = (read(&self.buffers[0])?, read(&self.buffers[1])?);
        // A drawn fragment writes its position; the clear leaves every bit 0, and a position exactly at
        // the eye (all +0.0) is never drawn (the near plane is in front of it).
        out.position = position
            .iter()
            .map(|p| (*p != [0; 4]).then(|| p.map(f32::from_bits)))
            .collect();
        out.inputs = inputs.iter().map(|p| p.map(f32::from_bits)).collect();
        Ok(out)
    }
}
