//! What the examples share as any wgpu program would have it: a device on the GLES 3.0 limits, render
//! targets, and reading a colour target back. Nothing of clipsat's.

type Error = Box<dyn std::error::Error>;

/// A device the ordinary wgpu way, on the GLES 3.0 / WebGL2 limits: the GL backend, or with
/// `CLIPSAT_GPU=vulkan` the Vulkan one (an Android or Linux engine's usual device; wgpu built with its
/// `vulkan` feature). On GL Mesa is asked for exactly OpenGL ES 3.0, as `clipsat render --gpu gl` asks,
/// so both see the same driver.
pub(crate) fn own_device() -> Result<(wgpu::Device, wgpu::Queue), Error> {
    let (_instance, adapter) = own_adapter()?;
    device_on(&adapter)
}

/// The instance and adapter [`own_device`] takes its device from (keep the instance while the adapter
/// is used: a wgpu GL instance dropped beside a live one closes the process's EGL display).
pub(crate) fn own_adapter() -> Result<(wgpu::Instance, wgpu::Adapter), Error> {
    let vulkan = std::env::var("CLIPSAT_GPU").is_ok_and(|v| v.trim() == "vulkan");
    if !vulkan && std::env::var_os("MESA_GLES_VERSION_OVERRIDE").is_none() {
        std::env::set_var("MESA_GLES_VERSION_OVERRIDE", "3.0");
    }
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: if vulkan {
            wgpu::Backends::VULKAN
        } else {
            wgpu::Backends::GL
        },
        flags: wgpu::InstanceFlags::empty().with_env(),
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::None,
        force_fallback_adapter: false,
        compatible_surface: None,
        apply_limit_buckets: false,
    }))?;
    Ok((instance, adapter))
}

/// A device of `adapter` on the GLES 3.0 / WebGL2 limits, and its queue.
pub(crate) fn device_on(adapter: &wgpu::Adapter) -> Result<(wgpu::Device, wgpu::Queue), Error> {
    Ok(pollster::block_on(adapter.request_device(
        &wgpu::DeviceDescriptor {
            label: Some("own device"),
            required_features: wgpu::Features::empty(),
            required_limits: wgpu::Limits::downlevel_webgl2_defaults(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::MemoryUsage,
            trace: wgpu::Trace::Off,
        },
    ))?)
}

/// A render target; the colour one can be copied out.
pub(crate) fn target(
    device: &wgpu::Device,
    format: wgpu::TextureFormat,
    width: u32,
    height: u32,
    read: bool,
) -> wgpu::Texture {
    let mut usage = wgpu::TextureUsages::RENDER_ATTACHMENT;
    if read {
        usage |= wgpu::TextureUsages::COPY_SRC;
    }
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
}

/// The colour target's pixels, tightly packed (wgpu pads rows to 256 bytes).
pub(crate) fn read_back(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    color: &wgpu::Texture,
) -> Result<Vec<u8>, Error> {
    let (width, height) = (color.width(), color.height());
    let padded = (width * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("own read-back"),
        size: u64::from(padded) * u64::from(height),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    encoder.copy_texture_to_buffer(
        color.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: None,
            },
        },
        color.size(),
    );
    queue.submit([encoder.finish()]);
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    // Waits in slices: wgpu's GL backend ends any single wait after 2.15 s with a timeout, even one
    // asked to wait indefinitely; a frame that has not finished within a minute is reported.
    let start = std::time::Instant::now();
    loop {
        let slice = Some(std::time::Duration::from_secs(1));
        match device.poll(wgpu::PollType::Wait {
            submission_index: None,
            timeout: slice,
        }) {
            Err(wgpu::PollError::Timeout) if start.elapsed().as_secs() < 60 => {}
            done => {
                done?;
                break;
            }
        }
    }
    rx.recv()??;
    let view = buffer.get_mapped_range(..)?;
    let mut rgba = Vec::with_capacity((width * height * 4) as usize);
    for row in view.chunks_exact(padded as usize) {
        rgba.extend_from_slice(&row[..(width * 4) as usize]);
    }
    Ok(rgba)
}
