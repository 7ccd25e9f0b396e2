//! Stage 3, the GPU: wgpu on the OpenGL ES 3.0 floor. The only stage that touches wgpu; beside it, the
//! embedding API (`engine/`) takes the caller's device, queue, formats and pass, and the viewer
//! (`app/cmd/view/`) its window's surface.
//!
//! Every device is created with [`wgpu::Limits::downlevel_webgl2_defaults`] (2048^2 textures, no compute,
//! no storage buffers): the GLES 3.0 floor everything must fit. [`GpuMode`] picks how the GL context is
//! made; the tests use [`GpuMode::Strict`], a real OpenGL ES 3.0 context.
//!
//! A [`Gpu`] is bound to the thread that made it (GL contexts are current per thread): keep the
//! renderer on the thread that made it. The type is neither `Send` nor `Sync`, so the compiler enforces it.

#[cfg(feature = "internals")]
pub mod brute;
#[cfg(unix)]
mod egl;
pub mod floor;
#[cfg(feature = "internals")]
pub mod headless;
pub mod readback;
pub mod renderer;
pub mod scope;
#[cfg(feature = "internals")]
pub mod sg_probe;
pub mod shaders;
pub mod validation;

use std::marker::PhantomData;
use std::sync::OnceLock;

use serde::Serialize;

use crate::{Error, Result};

/// How to obtain the GL context.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum GpuMode {
    /// A real OpenGL ES 3.0 context through EGL (surfaceless Mesa platform), wrapped by wgpu.
    ///
    /// Sets `MESA_GLES_VERSION_OVERRIDE=3.0` (unless already set) before EGL starts, so Mesa reports
    /// exactly ES 3.0 rather than the highest ES version it supports.
    Strict,
    /// wgpu's own GL backend, headless. On Mesa this is usually a desktop GL 4.5 context.
    Gl,
    /// wgpu's Vulkan backend, headless (the `vulkan` feature), on the same GLES 3.0 limits: the shaders
    /// go through naga's SPIR-V path instead of GLSL ES. Mesa's lavapipe on machines without a GPU.
    Vulkan,
    /// The mode `CLIPSAT_GPU` names (`strict`, `gl` or `vulkan`) if it is set; else [`GpuMode::Strict`]
    /// if it works, else [`GpuMode::Gl`].
    #[default]
    Auto,
}

/// The variable [`GpuMode::Auto`] reads: a test run or a user picks the backend without a flag.
pub const GPU_MODE_VAR: &str = "CLIPSAT_GPU";

impl GpuMode {
    /// The mode `CLIPSAT_GPU` names, if it is set (an error for a value that is no mode).
    pub fn from_env() -> Option<Result<Self>> {
        let v = std::env::var(GPU_MODE_VAR).ok()?;
        let v = v.trim();
        if v.is_empty() {
            return None;
        }
        Some(v.parse())
    }
}

impl std::str::FromStr for GpuMode {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        match s {
            "strict" => Ok(Self::Strict),
            "gl" => Ok(Self::Gl),
            "vulkan" => Ok(Self::Vulkan),
            "auto" => Ok(Self::Auto),
            other => Err(Error::Invalid {
                what: "GPU mode".into(),
                reason: format!("`{other}` is not auto, strict, gl or vulkan"),
            }),
        }
    }
}

/// What the adapter says about itself, for reports and goldens (image hashes are exact per driver).
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct AdapterReport {
    /// The renderer (GL_RENDERER), e.g. "llvmpipe (LLVM 15.0.6, 256 bits)".
    pub name: String,
    /// The wgpu backend, e.g. "Gl" or "Vulkan".
    pub backend: String,
    /// The GL version string (GL_VERSION), e.g. "OpenGL ES 3.0 Mesa 22.3.6"; on Vulkan, "Vulkan" and
    /// the driver's own description.
    pub gl_version: String,
    /// The driver and its version, e.g. "Mesa 22.3.6" (from the GL version string when wgpu has none).
    pub driver: String,
    /// wgpu's driver info field, verbatim.
    pub driver_info: String,
    /// Which [`GpuMode`] made the device: "strict", "gl" or "vulkan".
    pub mode: String,
    /// The PCI vendor id (0x10de NVIDIA, 0x13b5 ARM, 0x5143 Qualcomm; 0x10005 Mesa's software
    /// devices); 0 where the backend does not know it (GL).
    pub vendor: u32,
    /// The PCI device id; 0 where the backend does not know it.
    pub device: u32,
    /// The device type: "DiscreteGpu", "IntegratedGpu", "Cpu" (a software rasteriser), "VirtualGpu" or
    /// "Other".
    pub device_type: String,
    /// Whether the adapter offers compute shaders (a GLES 3.0 device does not).
    pub compute: bool,
    /// Whether the adapter offers storage buffers in vertex shaders (a GLES 3.0 device does not).
    pub vertex_storage: bool,
}

/// The wgpu objects, dropped before the GL context they live in.
#[derive(Debug)]
struct Handles {
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter: wgpu::Adapter,
    // Kept alive for the adapter's sake; never used after creation.
    _instance: wgpu::Instance,
}

/// A GPU device on the GLES 3.0 floor, with its queue. Not `Send`: keep it on the thread that made it.
#[derive(Debug)]
pub struct Gpu {
    handles: Option<Handles>,
    /// Declared after `handles`, so that it is destroyed after them (see `Drop`).
    #[cfg(unix)]
    strict: Option<egl::StrictContext>,
    report: AdapterReport,
    _not_send: PhantomData<*const ()>,
}

const NO_ADAPTER_HINT: &str = "install Mesa's llvmpipe with EGL: run `bash .ci/setup`, or \
     `apt-get install libegl1 libegl-mesa0 libgles2 libgl1-mesa-dri`";

impl Gpu {
    /// Creates a device in `mode`. [`Error::NoAdapter`] says how to get one when none exists.
    pub fn new(mode: GpuMode) -> Result<Self> {
        match mode {
            GpuMode::Strict => Self::new_strict(),
            GpuMode::Gl => Self::new_gl(),
            GpuMode::Vulkan => Self::new_vulkan(),
            GpuMode::Auto => match GpuMode::from_env() {
                Some(Ok(GpuMode::Auto)) | None => Self::new_auto(),
                Some(Ok(chosen)) => Self::new(chosen),
                Some(Err(e)) => Err(e),
            },
        }
    }

    /// Strict, else wgpu's GL backend.
    fn new_auto() -> Result<Self> {
        Self::new_strict().or_else(|strict| {
                Self::new_gl().map_err(|gl| {
                    Error::no_adapter(
                        format!(
                            "strict GLES 3.0: {}; wgpu GL: {}; {NO_ADAPTER_HINT}",
                            crate::error::with_sources(&strict),
                            crate::error::with_sources(&gl)
                        ),
                        None,
                    )
                })
        })
    }

    #[cfg(feature = "vulkan")]
    fn new_vulkan() -> Result<Self> {
        // Under `CLIPSAT_VALIDATION_LOG` (a test run) the Khronos validation layer checks every call.
        let mut flags = wgpu::InstanceFlags::empty().with_env();
        if validation::install_from_env() {
            flags |= wgpu::InstanceFlags::VALIDATION | wgpu::InstanceFlags::DEBUG;
        }
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::VULKAN,
            flags,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::None,
            force_fallback_adapter: false,
            compatible_surface: None,
            apply_limit_buckets: false,
        }))
        .map_err(|e| {
            Error::no_adapter(
                "wgpu Vulkan backend: no Vulkan device (install a Vulkan driver, e.g. Mesa's \
                 lavapipe: `apt-get install mesa-vulkan-drivers`)",
                Some(e.into()),
            )
        })?;
        Self::finish(
            instance,
            adapter,
            #[cfg(unix)]
            None,
            "vulkan",
        )
    }

    #[cfg(not(feature = "vulkan"))]
    fn new_vulkan() -> Result<Self> {
        Err(Error::no_adapter(
            "this build has no Vulkan backend: build clipsat with the `vulkan` feature",
            None,
        ))
    }

    /// What the adapter reports.
    pub fn report(&self) -> &AdapterReport {
        &self.report
    }

    /// Makes this GPU's GL context current on the calling thread. Every accessor does it; call it
    /// yourself before dropping wgpu resources when several `Gpu`s share a thread.
    pub fn bind(&self) {
        #[cfg(unix)]
        if let Some(ctx) = &self.strict {
            if let Err(e) = ctx.make_current() {
                panic!("GL context of this Gpu can no longer be made current: {e}");
            }
        }
    }

    fn handles(&self) -> &Handles {
        self.bind();
        self.handles.as_ref().expect("Gpu handles exist until drop")
    }

    /// The device (its GL context made current first).
    pub fn device(&self) -> &wgpu::Device {
        &self.handles().device
    }

    /// The queue (its GL context made current first).
    pub fn queue(&self) -> &wgpu::Queue {
        &self.handles().queue
    }

    /// The adapter (its GL context made current first).
    pub fn adapter(&self) -> &wgpu::Adapter {
        &self.handles().adapter
    }

    /// Runs `f` inside validation and out-of-memory error scopes, turning captured wgpu errors into
    /// [`Error::Gpu`] instead of wgpu's default panic.
    pub fn scoped<T>(&self, what: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
        let device = self.device();
        let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let out = f();
        let v = pollster::block_on(validation.pop());
        let o = pollster::block_on(oom.pop());
        match (v, o) {
            (Some(e), _) | (None, Some(e)) => Err(Error::gpu(what, e)),
            (None, None) => out,
        }
    }

    #[cfg(unix)]
    fn new_strict() -> Result<Self> {
        let ctx = egl::StrictContext::new()?;
        // No backends: the adapter comes from our context, and a GL instance of wgpu's own would open
        // (and on drop terminate) the same EGL display.
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::empty(),
            flags: wgpu::InstanceFlags::empty(),
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let options = wgpu::GlBackendOptions {
            gles_minor_version: wgpu::Gles3MinorVersion::Version0,
            ..Default::default()
        };
        // SAFETY: the context is current on this thread (StrictContext::new made it so) and outlives
        // every wgpu object: `Gpu::drop` re-binds it, drops the handles, then destroys it.
        let exposed =
            unsafe { wgpu_hal::gles::Adapter::new_external(|n| ctx.proc_address(n), options) }
                .ok_or_else(|| {
                    Error::no_adapter(
                        "wgpu could not use the OpenGL ES 3.0 context (GL_VERSION unparsable or \
                         below ES 3.0)",
                        None,
                    )
                })?;
        // SAFETY: the hal adapter is of the GLES backend this wgpu build enables.
        let adapter = unsafe { instance.create_adapter_from_hal(exposed) };
        Self::finish(instance, adapter, Some(ctx), "strict")
    }

    #[cfg(not(unix))]
    fn new_strict() -> Result<Self> {
        Err(Error::no_adapter(
            "the strict GLES 3.0 mode needs EGL (Linux/Unix)",
            None,
        ))
    }

    fn new_gl() -> Result<Self> {
        #[cfg(unix)]
        egl::pin_gles_version();
        let instance = gl_instance();
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::None,
            force_fallback_adapter: false,
            compatible_surface: None,
            apply_limit_buckets: false,
        }))
        .map_err(|e| Error::no_adapter(format!("wgpu GL backend; {NO_ADAPTER_HINT}"), Some(e.into())))?;
        Self::finish(
            instance,
            adapter,
            #[cfg(unix)]
            None,
            "gl",
        )
    }

    fn finish(
        instance: wgpu::Instance,
        adapter: wgpu::Adapter,
        #[cfg(unix)] strict: Option<egl::StrictContext>,
        mode: &str,
    ) -> Result<Self> {
        let limits = wgpu::Limits::downlevel_webgl2_defaults();
        let short = floor::shortfalls(&floor::check(&adapter));
        if !short.is_empty() {
            return Err(Error::no_adapter(
                format!(
                    "adapter {:?} is below the GLES 3.0 / WebGL2 floor: {}",
                    adapter.get_info().name,
                    short.join(", ")
                ),
                None,
            ));
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("clipsat"),
            // The texture compression the adapter has, for draped imagery's colour rings (the renderer
            // uses what a device was created with: `Renderer::imagery_format`); nothing else.
            required_features: adapter.features()
                & (wgpu::Features::TEXTURE_COMPRESSION_BC | wgpu::Features::TEXTURE_COMPRESSION_ETC2),
            required_limits: limits,
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::MemoryUsage,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| Error::no_adapter("request_device on the GLES 3.0 floor", Some(e.into())))?;
        let info = adapter.get_info();
        let flags = adapter.get_downlevel_capabilities().flags;
        let gl_version = if info.backend == wgpu::Backend::Vulkan {
            format!("Vulkan ({})", info.driver_info)
        } else {
            info.driver_info.clone()
        };
        let driver = if info.driver.is_empty() {
            driver_from_version(&gl_version)
        } else {
            info.driver.clone()
        };
        let report = AdapterReport {
            name: info.name.clone(),
            backend: format!("{:?}", info.backend),
            gl_version,
            driver,
            driver_info: info.driver_info.clone(),
            mode: mode.into(),
            vendor: info.vendor,
            device: info.device,
            device_type: format!("{:?}", info.device_type),
            compute: flags.contains(wgpu::DownlevelFlags::COMPUTE_SHADERS),
            vertex_storage: flags.contains(wgpu::DownlevelFlags::VERTEX_STORAGE),
        };
        Ok(Self {
            handles: Some(Handles {
                device,
                queue,
                adapter,
                _instance: instance,
            }),
            #[cfg(unix)]
            strict,
            report,
            _not_send: PhantomData,
        })
    }
}

impl Drop for Gpu {
    fn drop(&mut self) {
        // wgpu-hal's external GL adapter requires its context current while its objects drop.
        #[cfg(unix)]
        if let Some(ctx) = &self.strict {
            let _ = ctx.make_current();
        }
        self.handles = None;
        // `strict` drops next and destroys the context.
    }
}

/// A sampled 2D (array) texture, written by copies, one mip level: the shape of every table clipsat
/// binds (rings, detail pool, SG tables, sky table, probe inputs); `usage` adds to the two it always has.
pub(crate) fn texture_2d(
    width: u32,
    height: u32,
    layers: u32,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::TextureDescriptor<'static> {
    wgpu::TextureDescriptor {
        label: None,
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: layers,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST | usage,
        view_formats: &[],
    }
}

/// A single-sample 2D render target of one layer and mip level, with exactly `usage`: the colour, depth
/// and probe targets clipsat draws into.
pub(crate) fn render_target(
    width: u32,
    height: u32,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::TextureDescriptor<'static> {
    wgpu::TextureDescriptor {
        usage,
        ..texture_2d(width, height, 1, format, wgpu::TextureUsages::empty())
    }
}

/// wgpu's GL instance, one per process and never dropped.
///
/// EGL hands out one display per platform, shared by every context in the process. Dropping a wgpu GL
/// instance terminates that display (wgpu reference-counts only its own uses), which would destroy the
/// contexts of live strict-mode `Gpu`s too. Keeping the instance alive avoids that.
fn gl_instance() -> wgpu::Instance {
    static GL: OnceLock<wgpu::Instance> = OnceLock::new();
    GL.get_or_init(|| {
        wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::GL,
            flags: wgpu::InstanceFlags::empty().with_env(),
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        })
    })
    .clone()
}

/// The driver part of a GL version string: "OpenGL ES 3.0 Mesa 22.3.6" -> "Mesa 22.3.6".
fn driver_from_version(version: &str) -> String {
    if let Some(i) = version.find("Mesa") {
        return version[i..].trim().to_string();
    }
    let rest = version.strip_prefix("OpenGL ES ").unwrap_or(version);
    rest.split_once(' ')
        .map_or_else(String::new, |(_, tail)| tail.trim().to_string())
}

/// Begins the one kind of pass every renderer here draws: colour cleared to `clear` (RGBA, 0..1) and
/// stored, depth cleared to 1 and discarded after the pass.
pub fn clear_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    color: &wgpu::TextureView,
    depth: &wgpu::TextureView,
    clear: [f64; 4],
) -> wgpu::RenderPass<'e> {
    let [r, g, b, a] = clear;
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: color,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a }),
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: depth,
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn driver_from_gl_version() {
        assert_eq!(
            driver_from_version("OpenGL ES 3.0 Mesa 22.3.6"),
            "Mesa 22.3.6"
        );
        assert_eq!(
            driver_from_version("4.5 (Core Profile) Mesa 22.3.6"),
            "Mesa 22.3.6"
        );
        assert_eq!(
            driver_from_version(
                "OpenGL ES 3.2 V@0502.0 (GIT@d4cfdf3, Ic907de5ed0) (Date:09/30/20)"
            ),
            "V@0502.0 (GIT@d4cfdf3, Ic907de5ed0) (Date:09/30/20)"
        );
        assert!("bogus".parse::<GpuMode>().is_err());
        assert_eq!("strict".parse::<GpuMode>().ok(), Some(GpuMode::Strict));
    }
}
