//! Stage 3, the GPU: the brute-force reference renderer, the ground truth the clipmap renderer is judged
//! against. It draws the full-resolution grid: every heightmap sample is a vertex, two triangles per cell,
//! u32 indices, basic shading (`shaders_gles/basic_shading.wgsl`) and a Depth32Float depth buffer.
//!
//! Triangles split each cell along its north-west to south-east diagonal: (u, v)-(u+1, v+1) in grid
//! coordinates.

use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use wgpu::util::DeviceExt;

use super::readback::{self, Image};
use super::shaders;
use super::Gpu;
use crate::shading::basic::{BasicShading, SKY};
use crate::{Error, Result};
use crate::plan::camera::Camera;
use crate::source::Heightmap;

/// The brute-force program's uniforms; mirrors `Globals` in `shaders_gles/brute.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Globals {
    /// Camera-relative view-projection.
    pub view_proj: [f32; 16],
    /// x, y: column and row of the anchor sample; z: samples per row; w: unused.
    pub grid: [i32; 4],
    /// xyz: world position of the anchor sample at height 0 minus the eye (m); w: sample spacing (m).
    pub anchor_rel: [f32; 4],
    /// Basic shading parameters.
    pub shading: BasicShading,
}
const _: () = assert!(std::mem::size_of::<Globals>() == 144);

/// Bytes per vertex: height, normal east, normal north (f32 each).
const VERTEX_BYTES: u64 = 12;

const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// Render targets of one size, kept between frames.
#[derive(Debug)]
struct Targets {
    color: wgpu::Texture,
    depth: wgpu::TextureView,
}

/// The full-resolution grid of one terrain on the GPU. Borrows the [`Gpu`] it lives on, so it cannot
/// outlive it or leave its thread.
#[derive(Debug)]
pub struct BruteForce<'g> {
    gpu: &'g Gpu,
    pipeline: wgpu::RenderPipeline,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    uniforms: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    index_count: u32,
    targets: Option<(u32, u32, Targets)>,
    columns: u32,
    rows: u32,
    spacing: f64,
    shading: BasicShading,
}

/// One rendered frame.
#[derive(Clone, Debug)]
pub struct Frame {
    /// The read-back image.
    pub image: Image,
    /// [`Image::hash`] of it.
    pub image_hash: u64,
    /// Triangles drawn.
    pub triangles: u64,
}

impl<'g> BruteForce<'g> {
    /// Uploads `hm` as a full-resolution mesh. Refuses, with [`Error::Gpu`], a terrain whose buffers
    /// exceed the GLES 3.0 floor's limits (buffer size, and 2^24 - 1 as the largest index where the
    /// device lacks full 32-bit indices).
    pub fn new(gpu: &'g Gpu, hm: &Heightmap) -> Result<Self> {
        let (columns, rows) = (hm.width(), hm.height());
        let vertex_count = u64::from(columns) * u64::from(rows);
        let cells = u64::from(columns - 1) * u64::from(rows - 1);
        let index_count = cells * 6;
        let limits = gpu.device().limits();
        let full_u32 = gpu
            .adapter()
            .get_downlevel_capabilities()
            .flags
            .contains(wgpu::DownlevelFlags::FULL_DRAW_INDEX_UINT32);
        let max_index = if full_u32 {
            u64::from(u32::MAX)
        } else {
            (1 << 24) - 1
        };
        let too_big = |what: String| {
            Error::gpu_msg(format!(
                "terrain {columns} x {rows} is too large for the brute-force reference on the GLES 3.0 \
                 floor: {what}; use a smaller terrain (the clipmap renderer has no such limit)"
            ))
        };
        if vertex_count - 1 > max_index {
            return Err(too_big(format!(
                "{vertex_count} vertices, but indices stop at {max_index}"
            )));
        }
        for (what, bytes) in [
            ("vertex", vertex_count * VERTEX_BYTES),
            ("index", index_count * 4),
        ] {
            if bytes > limits.max_buffer_size {
                return Err(too_big(format!(
                    "the {what} buffer needs {bytes} bytes, the limit is {}",
                    limits.max_buffer_size
                )));
            }
        }
        let index_count = u32::try_from(index_count)
            .map_err(|_| too_big(format!("{index_count} indices do not fit a u32 draw")))?;

        let vertex_data = vertex_data(hm);
        let index_data = index_data(columns, rows);
        let (ex, ey) = hm.extent_m();
        let slope = crate::shading::basic::mean_slope(
            hm.heights(),
            hm.width() as usize,
            f64::from(hm.spacing()),
        );
        let shading = BasicShading::for_terrain(hm.range(), ex.hypot(ey), slope);

        gpu.scoped("brute-force set-up", || {
            let device = gpu.device();
            let vertices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("brute vertices"),
                contents: bytemuck::cast_slice(&vertex_data),
                usage: wgpu::BufferUsages::VERTEX,
            });
            let indices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("brute indices"),
                contents: bytemuck::cast_slice(&index_data),
                usage: wgpu::BufferUsages::INDEX,
            });
            let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("brute globals"),
                size: std::mem::size_of::<Globals>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("brute globals"),
                entries: &[wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: wgpu::BufferSize::new(
                            std::mem::size_of::<Globals>() as u64
                        ),
                    },
                    count: None,
                }],
            });
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("brute globals"),
                layout: &layout,
                entries: &[wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniforms.as_entire_binding(),
                }],
            });
            let pipeline = pipeline(device, &layout);
            Ok(Self {
                gpu,
                pipeline,
                vertices,
                indices,
                uniforms,
                bind_group,
                index_count,
                targets: None,
                columns,
                rows,
                spacing: f64::from(hm.spacing()),
                shading,
            })
        })
    }

    /// Triangles one frame draws: 2 per grid cell.
    pub fn triangles(&self) -> u64 {
        u64::from(self.index_count / 3)
    }

    /// Renders the grid from `camera` into a `width` x `height` image and reads it back.
    pub fn render(&mut self, camera: &Camera, width: u32, height: u32) -> Result<Frame> {
        let gpu = self.gpu;
        let max = gpu.device().limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(Error::gpu_msg(format!(
                "image size {width} x {height}: each side must be 1..={max} on the GLES 3.0 floor"
            )));
        }
        let globals = self.globals(camera, f64::from(width) / f64::from(height));
        gpu.scoped("brute-force frame", || {
            if !matches!(self.targets, Some((w, h, _)) if w == width && h == height) {
                self.targets = Some((width, height, targets(gpu.device(), width, height)));
            }
            let Some((_, _, targets)) = &self.targets else {
                unreachable!("targets were just created");
            };
            gpu.queue()
                .write_buffer(&self.uniforms, 0, bytemuck::bytes_of(&globals));
            let color_view = targets.color.create_view(&Default::default());
            let mut encoder =
                gpu.device()
                    .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                        label: Some("brute frame"),
                    });
            {
                let mut pass =
                    super::clear_pass(&mut encoder, "brute", &color_view, &targets.depth, SKY);
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &self.bind_group, &[]);
                pass.set_vertex_buffer(0, self.vertices.slice(..));
                pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..self.index_count, 0, 0..1);
            }
            gpu.queue().submit([encoder.finish()]);
            Ok(())
        })?;
        let Some((_, _, targets)) = &self.targets else {
            unreachable!("targets exist after a frame");
        };
        let image = readback::read_rgba8(gpu, &targets.color)?;
        Ok(Frame {
            image_hash: image.hash(),
            image,
            triangles: self.triangles(),
        })
    }

    /// Uniforms for `camera`: the anchor is the grid sample nearest the eye, clamped into the grid, so
    /// positions near the viewer are small f32 numbers.
    #[expect(
        clippy::cast_possible_truncation,
        reason = "f64 -> f32 is the intended GPU precision once offsets are camera-relative; \
                  col and row are clamped integers inside a u32 grid"
    )]
    fn globals(&self, camera: &Camera, aspect: f64) -> Globals {
        let s = self.spacing;
        let eye = camera.eye;
        let col = (eye.x / s).round().clamp(0.0, f64::from(self.columns - 1));
        let row_from_south = (eye.y / s).round().clamp(0.0, f64::from(self.rows - 1));
        let row = f64::from(self.rows - 1) - row_from_south;
        let anchor = DVec3::new(col * s, row_from_south * s, 0.0) - eye;
        Globals {
            view_proj: camera.view_proj_relative(aspect).to_cols_array(),
            grid: [
                col as i32,
                row as i32,
                i32::try_from(self.columns).unwrap_or(i32::MAX),
                0,
            ],
            anchor_rel: [
                anchor.x as f32,
                anchor.y as f32,
                anchor.z as f32,
                self.spacing as f32,
            ],
            shading: self.shading,
        }
    }
}

impl Drop for BruteForce<'_> {
    fn drop(&mut self) {
        // The buffers are GL objects of this Gpu's context: make it current before they go.
        self.gpu.bind();
    }
}

/// Per sample: height, then the east and north components of the unit normal from central differences
/// on the full-resolution grid (one-sided at the border).
fn vertex_data(hm: &Heightmap) -> Vec<[f32; 3]> {
    let (w, h) = (i64::from(hm.width()), i64::from(hm.height()));
    let s = hm.spacing();
    let mut out = Vec::with_capacity(hm.heights().len());
    for v in 0..h {
        for u in 0..w {
            let (u0, u1) = ((u - 1).max(0), (u + 1).min(w - 1));
            let (v0, v1) = ((v - 1).max(0), (v + 1).min(h - 1));
            let dzdx = (hm.at_clamped(u1, v) - hm.at_clamped(u0, v)) / ((u1 - u0) as f32 * s);
            // Row index grows southward, so north is v - 1.
            let dzdy = (hm.at_clamped(u, v0) - hm.at_clamped(u, v1)) / ((v1 - v0) as f32 * s);
            let n = glam::Vec3::new(-dzdx, -dzdy, 1.0).normalize();
            out.push([hm.at_clamped(u, v), n.x, n.y]);
        }
    }
    out
}

/// Two triangles per cell, split along (u, v)-(u+1, v+1), wound counter-clockwise seen from above.
fn index_data(columns: u32, rows: u32) -> Vec<u32> {
    let mut out = Vec::with_capacity((columns as usize - 1) * (rows as usize - 1) * 6);
    for v in 0..rows - 1 {
        for u in 0..columns - 1 {
            let nw = v * columns + u;
            let ne = nw + 1;
            let sw = nw + columns;
            let se = sw + 1;
            // Seen from above with north up: nw -> sw -> se and nw -> se -> ne are counter-clockwise.
            out.extend_from_slice(&[nw, sw, se, nw, se, ne]);
        }
    }
    out
}

fn targets(device: &wgpu::Device, width: u32, height: u32) -> Targets {
    let texture = |label, format, usage| {
        device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            ..crate::gpu::render_target(width, height, format, usage)
        })
    };
    let color = texture(
        "brute color",
        COLOR_FORMAT,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
    );
    let depth = texture(
        "brute depth",
        DEPTH_FORMAT,
        wgpu::TextureUsages::RENDER_ATTACHMENT,
    )
    .create_view(&Default::default());
    Targets { color, depth }
}

fn pipeline(device: &wgpu::Device, layout: &wgpu::BindGroupLayout) -> wgpu::RenderPipeline {
    let source = shaders::brute();
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("brute.wgsl"),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("brute"),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("brute"),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: VERTEX_BYTES,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &wgpu::vertex_attr_array![0 => Float32x3],
            })],
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            front_face: wgpu::FrontFace::Ccw,
            // A height field seen from below shows its back faces; drawing both sides keeps it solid.
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
            module: &module,
            entry_point: Some("fs_main"),
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mesh_of_a_tilted_plane() {
        // z = 2 x + 3 y over a 4 x 3 grid of 10 m cells: every normal is (-2, -3, 1) normalised.
        let (w, h, s) = (4u32, 3u32, 10.0f32);
        let heights = (0..w * h)
            .map(|i| {
                let (u, v) = ((i % w) as f32, (i / w) as f32);
                2.0 * u * s + 3.0 * (h as f32 - 1.0 - v) * s
            })
            .collect();
        let hm =
            Heightmap::new(std::path::Path::new("<plane>"), w, h, s, heights).expect("valid plane");
        let n = glam::Vec3::new(-2.0, -3.0, 1.0).normalize();
        for (i, [z, nx, ny]) in vertex_data(&hm).into_iter().enumerate() {
            assert_eq!(z, hm.heights()[i]);
            assert!((nx - n.x).abs() < 1e-6 && (ny - n.y).abs() < 1e-6, "{i}");
        }
        let idx = index_data(w, h);
        assert_eq!(idx.len(), 3 * 2 * 6);
        assert_eq!(&idx[..6], &[0, 4, 5, 0, 5, 1]);
        assert!(idx.iter().all(|&i| i < w * h));
    }
}
