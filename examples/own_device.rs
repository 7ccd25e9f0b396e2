//! Terrain in your own wgpu device and render pass: this example creates its instance, adapter and device
//! the ordinary wgpu way (the GL backend, as `clipsat render --gpu gl` does), its own colour and depth
//! targets and its own render pass. In that pass it clears, draws something of its own (an orange triangle
//! in the top-left corner), then the terrain; it reads the image back and prints its hash.
//!
//! clipsat's part is three calls: [`Renderer::new`] once (on the caller's device), then per frame
//! [`Planner::plan`] (CPU, allocation-free), [`Renderer::prepare`] (uploads) and [`Renderer::render`]
//! (records into the caller's pass).
//!
//! ```sh
//! cargo run --release --example own_device                 # with the orange triangle
//! CLIPSAT_OWN_DRAW=0 cargo run --release --example own_device   # terrain only: the same hash as
//! clipsat render --gpu gl --terrain procedural:size=257 --profile gles3-low --size 320x180
//! ```

use clipsat::gpu::readback::{read_rgba8_on, Image};
use clipsat::gpu::renderer::{Renderer, RendererOptions};
use clipsat::hash::hex;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::frame_plan::{LodSetup, PlanParams, Planner};
use clipsat::source::procedural;
use clipsat::{Camera, Error, Heightmap, Profile, Result};

const COLOR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The example's own draw: a triangle in the top-left corner, in front of everything (depth 0).
const OWN_WGSL: &str = "
@vertex fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let p = array(vec2(-0.95, 0.95), vec2(-0.65, 0.95), vec2(-0.95, 0.55));
    return vec4(p[i], 0.0, 1.0);
}
@fragment fn fs() -> @location(0) vec4<f32> { return vec4(1.0, 0.5, 0.0, 1.0); }
";

/// Renders the default view of `terrain` with the `gles3-low` profile at `width` x `height` on a device
/// of this function's own; with `own_draw`, the orange triangle first.
pub(crate) fn render(
    terrain: &Heightmap,
    width: u32,
    height: u32,
    own_draw: bool,
) -> Result<Image> {
    let mut profile = Profile::load("gles3-low")?;
    (profile.view.width, profile.view.height) = (width, height);
    // The view `clipsat render` draws by default, after filling every level at the eye.
    let d = Camera::default_for(terrain)?;
    let camera = Camera::new(d.eye, d.target, f64::from(profile.view.fov_y_deg))?
        .with_clip(d.near, d.far)?;
    let mut clipmap = Clipmap::new(terrain, &profile, ClipmapOptions::default())?;
    for _ in 0..10_000 {
        let f = clipmap.update(camera.eye)?;
        if f.stale_levels == 0 && clipmap.pending_samples(camera.eye) == 0 {
            break;
        }
    }

    // The ordinary wgpu way: the GL backend, the GLES 3.0 / WebGL2 limits. Mesa is asked for exactly
    // OpenGL ES 3.0, as `clipsat --gpu gl` asks, so both see the same driver.
    if std::env::var_os("MESA_GLES_VERSION_OVERRIDE").is_none() {
        std::env::set_var("MESA_GLES_VERSION_OVERRIDE", "3.0");
    }
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::GL,
        flags: wgpu::InstanceFlags::empty().with_env(),
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::None,
        force_fallback_adapter: false,
        compatible_surface: None,
        apply_limit_buckets: false,
    }))
    .map_err(|e| Error::NoAdapter(format!("wgpu GL backend: {e}")))?;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("own device"),
        required_features: wgpu::Features::empty(),
        required_limits: wgpu::Limits::downlevel_webgl2_defaults(),
        experimental_features: wgpu::ExperimentalFeatures::disabled(),
        memory_hints: wgpu::MemoryHints::MemoryUsage,
        trace: wgpu::Trace::Off,
    }))
    .map_err(|e| Error::NoAdapter(format!("request_device: {e}")))?;

    // Our own targets and our own pipeline.
    let target = |format, usage| {
        device.create_texture(&wgpu::TextureDescriptor {
            label: Some("own target"),
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
        })
    };
    let color = target(
        COLOR,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
    );
    let depth = target(DEPTH, wgpu::TextureUsages::RENDER_ATTACHMENT);
    let (color_view, depth_view) = (
        color.create_view(&Default::default()),
        depth.create_view(&Default::default()),
    );
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("own triangle"),
        source: wgpu::ShaderSource::Wgsl(OWN_WGSL.into()),
    });
    let own = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("own triangle"),
        layout: None,
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Always),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs"),
            compilation_options: Default::default(),
            targets: &[Some(COLOR.into())],
        }),
        multiview_mask: None,
        cache: None,
    });

    // clipsat: a planner and its preallocated plan (CPU), the renderer on our device (GPU), built once.
    let mut planner = Planner::new(&profile, &clipmap, LodSetup::Distance)?;
    let mut plan = planner.new_plan();
    let mut terrain_renderer = Renderer::new(
        &device,
        &queue,
        &RendererOptions {
            color_format: COLOR,
            depth_format: DEPTH,
            sample_count: 1,
            ..RendererOptions::default()
        },
        &profile,
    )?;

    // One frame: plan, prepare, then our pass.
    planner.plan(&clipmap, &camera, &PlanParams::default(), &mut plan)?;
    terrain_renderer.prepare(&queue, &clipmap, &plan)?;
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let [r, g, b, a] = clipsat::shading::basic::SKY;
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("own pass"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth_view,
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
        if own_draw {
            pass.set_pipeline(&own);
            pass.draw(0..3, 0..1);
        }
        terrain_renderer.render(&mut pass);
    }
    queue.submit([encoder.finish()]);
    read_rgba8_on(&device, &queue, &color)
}

fn main() -> std::process::ExitCode {
    let own_draw = std::env::var("CLIPSAT_OWN_DRAW").map_or(true, |v| v != "0");
    let terrain = procedural::generate(&procedural::ProceduralParams {
        size: 257,
        ..procedural::ProceduralParams::default()
    });
    match terrain.and_then(|t| render(&t, 320, 180, own_draw)) {
        Ok(image) => {
            println!("image {}", hex(image.hash()));
            std::process::ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::from(2)
        }
    }
}
