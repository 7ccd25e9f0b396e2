//! `clipsat view`, the window's GPU side: the wgpu instance on the X11 display, the window's surface, the
//! device on that surface's adapter, the depth target and the public [`TerrainRenderer`] drawing into the
//! surface's pass. Nothing is read back: each frame is presented by the GL backend (a framebuffer blit and
//! `eglSwapBuffers`).
//!
//! Which GL context the window gets: wgpu's EGL code asks Mesa for desktop OpenGL 3.3 first and takes
//! OpenGL ES only when that fails. For `--gpu strict` and `auto` the view caps Mesa's desktop GL at 3.0
//! (`MESA_GL_VERSION_OVERRIDE=3.0`), so the 3.3 request fails and wgpu falls back to OpenGL ES, and pins
//! the ES version at 3.0 (`MESA_GLES_VERSION_OVERRIDE=3.0`, as the headless strict context does): the
//! window then draws in exactly the GLES 3.0 context of a phone. What it got is checked from GL_VERSION.

use std::sync::Arc;

use crate::app::cmd::args::GpuArg;
use clipsat::{
    Camera, Error, FrameStats, Profile, RenderOptions, Result, Terrain, TerrainRenderer,
};
use winit::dpi::PhysicalSize;
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::window::Window;

/// The view's depth attachment format.
pub(super) const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The Mesa variables that make wgpu's EGL code fall back to an OpenGL ES 3.0 context (see the file
/// comment); a value the user set is kept.
const GLES_ONLY: [(&str, &str); 2] = [
    ("MESA_GL_VERSION_OVERRIDE", "3.0"),
    ("MESA_GLES_VERSION_OVERRIDE", "3.0"),
];

pub(super) fn window_error(what: &str, e: impl Into<clipsat::BoxError>) -> Error {
    Error::Gpu {
        action: format!("clipsat view: {what}"),
        source: Some(e.into()),
    }
}

/// Asks Mesa for a GLES 3.0 window context unless `mode` is [`GpuArg::Gl`]. Call before anything
/// creates a GL context in this process (Mesa reads the variables once) and before threads start.
pub(super) fn ask_for_gles(mode: GpuArg) {
    if mode == GpuArg::Gl {
        return;
    }
    for (var, value) in GLES_ONLY {
        if std::env::var_os(var).is_none() {
            std::env::set_var(var, value);
        }
    }
}

/// wgpu's GL backend on the event loop's X11 display, through EGL: the instance needs the display to
/// make window surfaces.
pub(super) fn instance(mode: GpuArg, event_loop: &EventLoop<()>) -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_with_display_handle(Box::new(
        event_loop.owned_display_handle(),
    ));
    desc.backends = wgpu::Backends::GL;
    if mode != GpuArg::Gl {
        desc.backend_options.gl.gles_minor_version = wgpu::Gles3MinorVersion::Version0;
    }
    wgpu::Instance::new(desc.with_env())
}

/// The window, its wgpu surface, the device on that surface's adapter, the depth target and the terrain
/// renderer: everything that exists only once the window does.
pub(super) struct Presenter {
    pub(super) window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    pub(super) config: wgpu::SurfaceConfiguration,
    device: wgpu::Device,
    queue: wgpu::Queue,
    depth: wgpu::TextureView,
    pub(super) renderer: TerrainRenderer,
    /// The context wgpu got: GL_VERSION (`OpenGL ES 3.0 Mesa ...` or a desktop version) and GL_RENDERER.
    pub(super) context: String,
    /// Whether that is exactly OpenGL ES 3.0.
    pub(super) gles30: bool,
}

/// What happened to one frame.
pub(super) enum Presented {
    Shown(FrameStats),
    /// The surface had no frame to give (occluded, timed out, or reconfigured after being lost).
    Skipped,
}

impl Presenter {
    /// Opens the window of `size` pixels, its surface on `instance`, an adapter able to present to it and
    /// a device with the GLES 3.0 downlevel limits, and builds the terrain renderer on it with
    /// `options` (the surface's formats set here). `--gpu strict` refuses any context but OpenGL ES 3.0;
    /// `auto` says so and goes on.
    pub(super) fn open(
        instance: &wgpu::Instance,
        event_loop: &ActiveEventLoop,
        size: (u32, u32),
        mode: GpuArg,
        terrain: (Terrain, &Profile, RenderOptions<'_>),
    ) -> Result<Self> {
        let (w, h) = size;
        let attrs = Window::default_attributes()
            .with_title("clipsat view")
            .with_inner_size(PhysicalSize::new(w, h));
        let window = Arc::new(
            event_loop
                .create_window(attrs)
                .map_err(|e| window_error("cannot create the window", e))?,
        );
        let surface = instance
            .create_surface(window.clone())
            .map_err(|e| window_error("cannot create the wgpu surface", e))?;
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::None,
            force_fallback_adapter: false,
            compatible_surface: Some(&surface),
            apply_limit_buckets: false,
        }))
        .map_err(|e| Error::NoAdapter {
            reason: format!(
                "wgpu GL backend on the window ({})",
                if mode == GpuArg::Gl {
                    "wgpu's own GL context"
                } else {
                    "OpenGL ES 3.0 asked for; `--gpu gl` takes what wgpu picks"
                }
            ),
            source: Some(Box::new(e)),
        })?;
        let info = adapter.get_info();
        let gles30 = info.driver_info.starts_with("OpenGL ES 3.0");
        let context = format!("{}, {}", info.driver_info, info.name);
        match mode {
            GpuArg::Strict if !gles30 => {
                return Err(Error::NoAdapter {
                    reason: format!(
                        "--gpu strict: the window's context is `{context}`, not OpenGL ES 3.0 \
                         (--gpu auto draws on it anyway)"
                    ),
                    source: None,
                })
            }
            GpuArg::Auto if !gles30 => eprintln!(
                "clipsat view: no OpenGL ES 3.0 context on this display; drawing on `{context}` \
                 instead (--gpu strict refuses it)"
            ),
            _ => {}
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("clipsat view"),
            required_features: wgpu::Features::empty(),
            required_limits: wgpu::Limits::downlevel_webgl2_defaults(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::MemoryUsage,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| Error::NoAdapter {
            reason: "request_device on the GLES 3.0 floor".into(),
            source: Some(Box::new(e)),
        })?;
        let caps = surface.get_capabilities(&adapter);
        // The renderer writes display-encoded colour, as into the headless Rgba8Unorm target: prefer a
        // non-sRGB format so the window shows the same bytes.
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| !f.is_srgb())
            .or_else(|| caps.formats.first().copied())
            .ok_or_else(|| window_error("surface", "no texture format can present"))?;
        let size = window.inner_size();
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            format,
            color_space: wgpu::SurfaceColorSpace::Auto,
            width: size.width.max(1),
            height: size.height.max(1),
            desired_maximum_frame_latency: 2,
            present_mode: wgpu::PresentMode::AutoNoVsync,
            alpha_mode: wgpu::CompositeAlphaMode::Auto,
            view_formats: vec![],
        };
        surface.configure(&device, &config);
        let depth = depth_view(&device, &config);
        let (terrain, profile, options) = terrain;
        let options = options.color_format(format).depth_format(DEPTH_FORMAT);
        let renderer = TerrainRenderer::new(&device, &queue, terrain, profile, &options)?;
        // Without a window manager (Xvfb) nothing else gives the window the keyboard.
        window.focus_window();
        Ok(Self {
            window,
            surface,
            config,
            device,
            queue,
            depth,
            renderer,
            context,
            gles30,
        })
    }

    /// Follows a window resize (the planner's aspect follows in the caller).
    pub(super) fn resize(&mut self, width: u32, height: u32) {
        self.config.width = width.max(1);
        self.config.height = height.max(1);
        self.surface.configure(&self.device, &self.config);
        self.depth = depth_view(&self.device, &self.config);
    }

    /// A new terrain renderer on this device for the surface's formats (a terrain opened again, with
    /// `options`), in place of the one drawn.
    pub(super) fn rebuild(
        &mut self,
        terrain: Terrain,
        profile: &Profile,
        options: RenderOptions<'_>,
    ) -> Result<()> {
        let options = options
            .color_format(self.config.format)
            .depth_format(DEPTH_FORMAT);
        self.renderer =
            TerrainRenderer::new(&self.device, &self.queue, terrain, profile, &options)?;
        Ok(())
    }

    /// Sets the renderer's frame options (`TerrainRenderer::set_frame_options`).
    pub(super) fn set_frame_options(&mut self, options: clipsat::FrameOptions) -> Result<()> {
        self.renderer.set_frame_options(&self.queue, options)
    }

    /// Prepares the frame of `camera`, clears the surface's next frame to `clear`, draws the terrain
    /// into that pass and presents it.
    pub(super) fn draw(&mut self, camera: &Camera, clear: [f64; 4]) -> Result<Presented> {
        let viewport = (self.config.width, self.config.height);
        let stats = self.renderer.prepare(&self.queue, camera, viewport)?;
        let target = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                return Ok(Presented::Skipped)
            }
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                self.surface.configure(&self.device, &self.config);
                return Ok(Presented::Skipped);
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                return Err(window_error(
                    "surface",
                    "validation error acquiring the frame",
                ))
            }
        };
        let view = target.texture.create_view(&Default::default());
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("clipsat view frame"),
            });
        {
            let [r, g, b, a] = clear;
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("clipsat view"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                // Conventional depth (the renderer's default): cleared to 1.
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
            self.renderer.render(&mut pass);
        }
        self.queue.submit([encoder.finish()]);
        self.queue.present(target);
        Ok(Presented::Shown(stats))
    }
}

/// The depth target of the surface's size: made at start and on a resize only.
fn depth_view(device: &wgpu::Device, config: &wgpu::SurfaceConfiguration) -> wgpu::TextureView {
    device
        .create_texture(&wgpu::TextureDescriptor {
            label: Some("clipsat view depth"),
            size: wgpu::Extent3d {
                width: config.width,
                height: config.height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        })
        .create_view(&Default::default())
}
