//! The terrain inside an engine's frame: the engine's camera matrices in its own y-up world, reverse-Z
//! with an infinite far plane, an sRGB colour target, and the engine's own mesh drawn in the same pass
//! with the same depth buffer.
//!
//! The engine here is a few lines of wgpu: its world has y up, the terrain's frame (z up) is placed in it
//! by a rotation, its camera is a view matrix and a `perspective_infinite_reverse_rh` projection, and its
//! pass clears depth to 0 and tests with `Greater`. clipsat takes the matrices
//! (`Camera::from_matrices`, `Camera::in_terrain_frame`), draws into the pass, and the engine draws a
//! marker (an orange diamond) where the ray under the screen's centre meets the terrain, with the
//! engine's own view-projection. Where the terrain is in front of the marker, the marker is hidden.
//!
//! ```sh
//! cargo run --release --example engine       # writes out/engine.png
//! CLIPSAT_GPU=vulkan cargo run --release --features vulkan --example engine
//! ```

use clipsat::{Camera, Profile, RenderOptions, Terrain, TerrainRenderer};
use glam::{DMat4, DVec3, Mat4};

#[path = "support/mod.rs"]
mod support;
use support::{own_device, read_back, target};

type Error = Box<dyn std::error::Error>;

/// The sky, display-encoded (what `clipsat render` clears to); an sRGB target is cleared with its
/// linear value.
const SKY: [f64; 3] = [0.63, 0.76, 0.90];

/// The marker's half-diagonal, metres: an octahedron |x| + |y| + |z| <= `MARKER_M` about its centre.
pub(crate) const MARKER_M: f64 = 250.0;

/// The marker: an octahedron, its vertices on the engine world's axes from its centre (`centre.w` away).
const MARKER_WGSL: &str = "
struct U { view_proj: mat4x4<f32>, centre: vec4<f32> };
@group(0) @binding(0) var<uniform> u: U;
@vertex fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let axes = array(vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0), vec3(0.0, 0.0, 1.0));
    // 8 faces of 3 vertices: face f takes the signs of its bits on the three axes.
    let f = i / 3u;
    let k = i % 3u;
    let s = vec3(select(1.0, -1.0, (f & 1u) != 0u), select(1.0, -1.0, (f & 2u) != 0u),
                 select(1.0, -1.0, (f & 4u) != 0u));
    let p = axes[k] * s[k] * u.centre.w;
    return u.view_proj * vec4(u.centre.xyz + p, 1.0);
}
@fragment fn fs() -> @location(0) vec4<f32> { return vec4(1.0, 0.5, 0.0, 1.0); }
";

/// How the engine's frame is set up.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Setup {
    /// Reverse-Z with an infinite far plane; otherwise conventional depth, far plane at 100 km.
    pub reverse_z: bool,
    /// An sRGB colour target (`Rgba8UnormSrgb`); otherwise `Rgba8Unorm`.
    pub srgb: bool,
    /// The depth target's format.
    pub depth: wgpu::TextureFormat,
    /// Draw the marker.
    pub marker: bool,
}

/// One frame read back: width, height, RGBA8 rows from the top, as the target stores them.
pub(crate) type Pixels = (u32, u32, Vec<u8>);

/// The terrain's frame in the engine's y-up world: z up becomes y up (x stays east, y north becomes -z).
pub(crate) fn terrain_to_world() -> DMat4 {
    DMat4::from_rotation_x(-std::f64::consts::FRAC_PI_2)
}

/// The engine's camera in its world: above the procedural terrain's south-west, looking north-east
/// and down, with a little roll.
pub(crate) fn engine_view() -> DMat4 {
    let place = terrain_to_world();
    let eye = place.transform_point3(DVec3::new(900.0, 300.0, 3300.0));
    let target = place.transform_point3(DVec3::new(2700.0, 2700.0, 1100.0));
    let up = place.transform_vector3(DVec3::new(0.1, 0.0, 1.0));
    DMat4::look_at_rh(eye, target, up)
}

/// The engine's projection for a `size` frame.
pub(crate) fn engine_projection(size: (u32, u32), reverse_z: bool) -> DMat4 {
    let aspect = f64::from(size.0) / f64::from(size.1);
    let fov = 55f64.to_radians();
    if reverse_z {
        DMat4::perspective_infinite_reverse_rh(fov, aspect, 1.0)
    } else {
        DMat4::perspective_rh(fov, aspect, 1.0, 1.0e5)
    }
}

/// What [`render`] drew: the frame, the camera clipsat drew with (terrain frame), the renderer (for its
/// queries), and the marker's centre (terrain frame) when it was drawn.
pub(crate) struct Frame {
    pub pixels: Pixels,
    pub camera: Camera,
    pub renderer: TerrainRenderer,
    pub marker: Option<[f64; 3]>,
}

/// Draws the procedural terrain (257 x 257 samples, 30 m apart, cached in `cache`) on `gles3-mid` with
/// SAT LOD at a 1 px bound (met in this view), as the engine sets up its frame; with `setup.marker`, the marker where the ray under the
/// screen's centre meets the terrain (`TerrainRenderer::raycast`).
pub(crate) fn render(
    cache: &std::path::Path,
    size: (u32, u32),
    setup: Setup,
) -> Result<Frame, Error> {
    let (device, queue) = own_device()?;
    let color_format = if setup.srgb {
        wgpu::TextureFormat::Rgba8UnormSrgb
    } else {
        wgpu::TextureFormat::Rgba8Unorm
    };
    let profile = Profile::load("gles3-mid")?;
    let terrain = Terrain::procedural(1, 257, 30.0, Some(cache))?;
    let options = RenderOptions::default()
        .color_format(color_format)
        .depth_format(setup.depth)
        .reverse_z(setup.reverse_z)
        .sat_lod_px(1.0);
    let mut renderer = TerrainRenderer::new(&device, &queue, terrain, &profile, &options)?;

    // The engine's matrices, in its world; clipsat's camera in the terrain's frame.
    let (view, proj) = (engine_view(), engine_projection(size, setup.reverse_z));
    let camera = Camera::from_matrices(view.to_cols_array_2d(), proj.to_cols_array_2d())?
        .in_terrain_frame(terrain_to_world().to_cols_array_2d())?;
    renderer.warm_up(&queue, &camera, size)?;
    renderer.prepare(&queue, &camera, size)?;

    let color = target(&device, color_format, size.0, size.1, true);
    let depth = target(&device, setup.depth, size.0, size.1, false);
    // The ray under the screen's centre: from the eye along the look direction, in the terrain's frame.
    let (eye, target) = (camera.eye(), camera.target());
    let look = [target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]];
    let hit = if setup.marker {
        renderer.raycast(eye, look, 1.0e6)?
    } else {
        None
    };
    let marker_draw = hit.map(|h| {
        // The marker with the engine's own view-projection, in its own world.
        let centre = terrain_to_world().transform_point3(DVec3::from(h.point));
        #[expect(clippy::cast_possible_truncation, reason = "metres as f32")]
        let r = MARKER_M as f32;
        MarkerDraw::new(
            &device,
            &queue,
            color_format,
            setup,
            (proj * view).as_mat4(),
            centre.as_vec3().extend(r).to_array(),
        )
    });
    let sky = if setup.srgb {
        SKY.map(srgb_to_linear)
    } else {
        SKY
    };
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("engine pass"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &color.create_view(&Default::default()),
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color {
                        r: sky[0],
                        g: sky[1],
                        b: sky[2],
                        a: 1.0,
                    }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth.create_view(&Default::default()),
                depth_ops: Some(wgpu::Operations {
                    // Reverse-Z clears to 0 (infinitely far), conventional depth to 1.
                    load: wgpu::LoadOp::Clear(if setup.reverse_z { 0.0 } else { 1.0 }),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: setup
                    .depth
                    .has_stencil_aspect()
                    .then_some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(0),
                        store: wgpu::StoreOp::Discard,
                    }),
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        renderer.render(&mut pass);
        if let Some(m) = &marker_draw {
            m.draw(&mut pass);
        }
    }
    queue.submit([encoder.finish()]);
    let rgba = read_back(&device, &queue, &color)?;
    Ok(Frame {
        pixels: (size.0, size.1, rgba),
        camera,
        renderer,
        marker: hit.map(|h| h.point),
    })
}

/// sRGB's decoding of a display-encoded value.
fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The engine's own mesh: the marker's pipeline and uniform.
struct MarkerDraw {
    pipeline: wgpu::RenderPipeline,
    bind: wgpu::BindGroup,
}

impl MarkerDraw {
    fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        color: wgpu::TextureFormat,
        setup: Setup,
        view_proj: Mat4,
        centre: [f32; 4],
    ) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("marker"),
            source: wgpu::ShaderSource::Wgsl(MARKER_WGSL.into()),
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("marker"),
            layout: None,
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: Some(wgpu::DepthStencilState {
                format: setup.depth,
                depth_write_enabled: Some(true),
                depth_compare: Some(if setup.reverse_z {
                    wgpu::CompareFunction::Greater
                } else {
                    wgpu::CompareFunction::Less
                }),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs"),
                compilation_options: Default::default(),
                targets: &[Some(color.into())],
            }),
            multiview_mask: None,
            cache: None,
        });
        let mut bytes = Vec::with_capacity(80);
        for f in view_proj.to_cols_array().iter().chain(&centre) {
            bytes.extend_from_slice(&f.to_le_bytes());
        }
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("marker uniform"),
            size: 80,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        queue.write_buffer(&buffer, 0, &bytes);
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("marker"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: buffer.as_entire_binding(),
            }],
        });
        Self { pipeline, bind }
    }

    fn draw(&self, pass: &mut wgpu::RenderPass<'_>) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind, &[]);
        pass.draw(0..24, 0..1);
    }
}

fn main() -> std::process::ExitCode {
    let setup = Setup {
        reverse_z: true,
        srgb: true,
        depth: wgpu::TextureFormat::Depth32Float,
        marker: true,
    };
    let run = || -> Result<(), Error> {
        std::fs::create_dir_all("out")?;
        let size = (640, 360);
        let mut frame = render(std::path::Path::new("out/cache"), size, setup)?;
        let (w, h, rgba) = &frame.pixels;
        image::save_buffer(
            "out/engine.png",
            rgba,
            *w,
            *h,
            image::ExtendedColorType::Rgba8,
        )?;
        let [ex, ey, ez] = frame.camera.eye();
        println!("out/engine.png, seen from ({ex:.0}, {ey:.0}, {ez:.0}) m in the terrain's frame");
        if let Some([x, y, z]) = frame.marker {
            // The data's height under the hit: the ray query and the height query agree.
            let ground = frame.renderer.height_at(x, y)?.unwrap_or(f64::NAN);
            println!("the marker at ({x:.1}, {y:.1}, {z:.2}) m; the terrain's height there {ground:.2} m");
        }
        Ok(())
    };
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::from(2)
        }
    }
}
