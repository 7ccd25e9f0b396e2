//! Terrain in your own wgpu device and render pass, with SAT LOD, through a window resize.
//!
//! The example makes its own instance, adapter and device the ordinary wgpu way (the GL backend on the
//! GLES 3.0 limits), its own colour and depth targets and its own render pass. In that pass it clears,
//! draws something of its own (an orange triangle in the top-left corner), then the terrain. Halfway
//! through it "resizes": new targets at another size, and the same `TerrainRenderer` keeps drawing.
//!
//! clipsat's part is four types: a `Profile`, a `Terrain` (the procedural one, baked into a package in
//! a cache folder and streamed), a `TerrainRenderer` built once with `RenderOptions` (SAT LOD at 1 px);
//! and per frame two calls, `prepare` (with the frame's camera and viewport) and `render`.
//!
//! ```sh
//! cargo run --release --example own_device                 # writes out/own_device-*.png
//! CLIPSAT_OWN_DRAW=0 cargo run --release --example own_device   # terrain only
//! CLIPSAT_GPU=vulkan cargo run --release --features vulkan --example own_device   # wgpu's Vulkan
//! ```

use clipsat::{Profile, RenderOptions, Terrain, TerrainRenderer};

#[path = "support/mod.rs"]
mod support;
pub(crate) use support::{own_device, read_back, target};

type Error = Box<dyn std::error::Error>;

const COLOR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// The sky behind the terrain (the colour `clipsat render` clears to).
const SKY: wgpu::Color = wgpu::Color {
    r: 0.63,
    g: 0.76,
    b: 0.90,
    a: 1.0,
};

/// The example's own draw: a triangle in the top-left corner, in front of everything (depth 0).
const OWN_WGSL: &str = "
@vertex fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let p = array(vec2(-0.95, 0.95), vec2(-0.65, 0.95), vec2(-0.95, 0.55));
    return vec4(p[i], 0.0, 1.0);
}
@fragment fn fs() -> @location(0) vec4<f32> { return vec4(1.0, 0.5, 0.0, 1.0); }
";

/// One frame read back: width, height, tightly packed RGBA8 rows from the top.
pub(crate) type Pixels = (u32, u32, Vec<u8>);

/// Draws the procedural terrain (257 x 257 samples, cached in `cache`) with the `gles3-low` profile at
/// every size of `sizes` in turn, on one device and one `TerrainRenderer`: a window resized between
/// frames. With `own_draw`, the orange triangle first. Returns each frame's pixels.
pub(crate) fn render(
    cache: &std::path::Path,
    sizes: &[(u32, u32)],
    own_draw: bool,
) -> Result<Vec<Pixels>, Error> {
    let (device, queue) = own_device()?;
    let own = own_pipeline(&device);

    // clipsat, once: the budget, the terrain (baked into `cache` on first use, then streamed), and the
    // renderer on our device, with SAT LOD at a 1 px error bound.
    let profile = Profile::load("gles3-low")?;
    let terrain = Terrain::procedural(1, 257, 30.0, Some(cache))?;
    let camera = terrain.default_camera()?;
    let options = RenderOptions::default()
        .color_format(COLOR)
        .depth_format(DEPTH)
        .sat_lod_px(1.0);
    let mut terrain = TerrainRenderer::new(&device, &queue, terrain, &profile, &options)?;

    let mut frames = Vec::new();
    for &(width, height) in sizes {
        // A new size: our targets change; the terrain renderer is kept. The warm-up fills the detail
        // the new size needs before the frame (a flight would let it fill over the next frames).
        let (color, depth) = (
            target(&device, COLOR, width, height, true),
            target(&device, DEPTH, width, height, false),
        );
        terrain.warm_up(&queue, &camera, (width, height))?;
        // Per frame: prepare (the camera and viewport: plan and uploads), render into our pass.
        terrain.prepare(&queue, &camera, (width, height))?;
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = begin_pass(&mut encoder, &color, &depth);
            if own_draw {
                pass.set_pipeline(&own);
                pass.draw(0..3, 0..1);
            }
            terrain.render(&mut pass);
        }
        queue.submit([encoder.finish()]);
        frames.push((width, height, read_back(&device, &queue, &color)?));
    }
    Ok(frames)
}

/// The example's own pipeline: the orange triangle.
fn own_pipeline(device: &wgpu::Device) -> wgpu::RenderPipeline {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("own triangle"),
        source: wgpu::ShaderSource::Wgsl(OWN_WGSL.into()),
    });
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
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
    })
}

/// Our pass: sky-coloured clear, depth cleared to 1.
pub(crate) fn begin_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    color: &wgpu::Texture,
    depth: &wgpu::Texture,
) -> wgpu::RenderPass<'e> {
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("own pass"),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: &color.create_view(&Default::default()),
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(SKY),
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: &depth.create_view(&Default::default()),
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Clear(1.0),
                store: wgpu::StoreOp::Discard,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}

fn main() -> std::process::ExitCode {
    let own_draw = std::env::var("CLIPSAT_OWN_DRAW").map_or(true, |v| v != "0");
    let sizes = [(320, 180), (200, 200)];
    let run = || -> Result<(), Error> {
        std::fs::create_dir_all("out")?;
        for (width, height, rgba) in render(std::path::Path::new("out/cache"), &sizes, own_draw)? {
            let path = format!("out/own_device-{width}x{height}.png");
            image::save_buffer(&path, &rgba, width, height, image::ExtendedColorType::Rgba8)?;
            println!("{path}");
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
