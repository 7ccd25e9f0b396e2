//! Stage 3 -> image: read an RGBA8 render target back into tightly packed rows, hash it, save it.

use std::path::Path;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use super::Gpu;
use crate::{hash, Error, Result};

/// A read-back frame: `width * height * 4` bytes, RGBA8, rows top to bottom, no padding.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    /// Pixels per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Tightly packed RGBA8 bytes.
    pub rgba: Vec<u8>,
}

impl Image {
    /// The image hash: [`hash::hash_bytes`] of the tight RGBA8 bytes (exact for a given driver).
    pub fn hash(&self) -> u64 {
        hash::hash_bytes(&self.rgba)
    }

    /// The pixel at column `x`, row `y` (row 0 at the top). Panics outside the image (a caller bug).
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside {}x{}",
            self.width,
            self.height
        );
        let i = (y as usize * self.width as usize + x as usize) * 4;
        [
            self.rgba[i],
            self.rgba[i + 1],
            self.rgba[i + 2],
            self.rgba[i + 3],
        ]
    }

    /// Writes the image as an 8-bit RGBA PNG.
    pub fn save_png(&self, path: &Path) -> Result<()> {
        image::save_buffer(
            path,
            &self.rgba,
            self.width,
            self.height,
            image::ExtendedColorType::Rgba8,
        )
        .map_err(|e| match e {
            image::ImageError::IoError(io) => Error::io(path, "cannot write", io),
            other => Error::io(path, "cannot write", std::io::Error::other(other)),
        })
    }
}

/// Copies an `Rgba8Unorm` texture (usage `COPY_SRC`) to the CPU, dropping wgpu's 256-byte row padding.
pub fn read_rgba8(gpu: &Gpu, texture: &wgpu::Texture) -> Result<Image> {
    gpu.scoped("readback", || {
        read_rgba8_on(gpu.device(), gpu.queue(), texture)
    })
}

/// [`read_rgba8`] on any device and queue (a caller's own; errors surface through its error scopes).
pub fn read_rgba8_on(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
) -> Result<Image> {
    if texture.format() != wgpu::TextureFormat::Rgba8Unorm {
        return Err(Error::gpu_msg(format!(
            "readback needs an Rgba8Unorm texture, got {:?}",
            texture.format()
        )));
    }
    let (width, height) = (texture.width(), texture.height());
    let tight = width as usize * 4;
    let padded = u32::try_from(tight.next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT as usize))
        .map_err(|_| Error::gpu_msg(format!("texture {width} px wide is too wide to read back")))?;
    let buffer = {
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: u64::from(padded) * u64::from(height),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("readback"),
        });
        encoder.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded),
                    rows_per_image: Some(height),
                },
            },
            texture.size(),
        );
        queue.submit([encoder.finish()]);
        buffer
    };
    let rgba = map_rows_on(
        device,
        &buffer,
        padded,
        u32::try_from(tight).unwrap_or(padded),
    )?;
    Ok(Image {
        width,
        height,
        rgba,
    })
}

/// Maps a MAP_READ `buffer` whose rows are `padded` bytes apart, copies the first `tight` bytes of each row
/// into one tightly packed vector, and unmaps it. Waits for the GPU.
pub fn map_rows(gpu: &Gpu, buffer: &wgpu::Buffer, padded: u32, tight: u32) -> Result<Vec<u8>> {
    map_rows_on(gpu.device(), buffer, padded, tight)
}

/// [`map_rows`] on any device.
pub fn map_rows_on(
    device: &wgpu::Device,
    buffer: &wgpu::Buffer,
    padded: u32,
    tight: u32,
) -> Result<Vec<u8>> {
    let (tx, rx) = mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        // The receiver outlives the poll below; a send error cannot happen.
        let _ = tx.send(r);
    });
    wait_for_gpu(device, gpu_wait_limit(), WAIT_SLICE)?;
    rx.try_recv()
        .map_err(|_| Error::gpu_msg("readback: map callback did not run"))?
        .map_err(|e| Error::gpu("readback: map failed", e))?;
    let mut out = Vec::new();
    {
        let view = buffer
            .get_mapped_range(..)
            .map_err(|e| Error::gpu("readback: mapped range", e))?;
        out.reserve(view.len() / padded as usize * tight as usize);
        for row in view.chunks_exact(padded as usize) {
            out.extend_from_slice(&row[..tight as usize]);
        }
    }
    buffer.unmap();
    Ok(out)
}

/// How long [`wait_for_gpu`] waits by default before it calls a frame hung.
pub const DEFAULT_GPU_WAIT: Duration = Duration::from_secs(60);

/// One poll's wait. wgpu's GL backend waits at most `i32::MAX` ns (2.15 s) in one poll whatever the poll
/// asks, even "indefinitely" (wgpu-hal 30 clamps `glClientWaitSync`'s timeout), and reports a longer
/// frame as a timeout; slices of 1 s keep that limit out of the way on every backend.
pub const WAIT_SLICE: Duration = Duration::from_secs(1);

/// The longest a read-back waits for the GPU: `CLIPSAT_GPU_WAIT_S` seconds if set (a slow device, or a
/// debugger), else [`DEFAULT_GPU_WAIT`].
pub fn gpu_wait_limit() -> Duration {
    std::env::var("CLIPSAT_GPU_WAIT_S")
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s > 0.0)
        .map_or(DEFAULT_GPU_WAIT, Duration::from_secs_f64)
}

/// What a [`wait_for_gpu`] took.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GpuWait {
    /// Wall time until the device was idle.
    pub elapsed: Duration,
    /// Polls made (each waits at most one slice).
    pub polls: u32,
}

/// Waits until the device has finished every submission, polling in slices of `slice` until `limit`:
/// a frame slower than one slice is waited for, and one that has not finished after `limit` is reported
/// as a hung frame, not as a wait that was too short (docs/real-drivers.md).
pub fn wait_for_gpu(device: &wgpu::Device, limit: Duration, slice: Duration) -> Result<GpuWait> {
    let t0 = Instant::now();
    let mut polls = 0u32;
    loop {
        polls = polls.saturating_add(1);
        let left = limit.saturating_sub(t0.elapsed());
        match device.poll(wgpu::PollType::Wait {
            submission_index: None,
            timeout: Some(slice.min(left)),
        }) {
            Ok(_) => {
                return Ok(GpuWait {
                    elapsed: t0.elapsed(),
                    polls,
                })
            }
            Err(wgpu::PollError::Timeout) if t0.elapsed() < limit => {}
            Err(wgpu::PollError::Timeout) => {
                return Err(Error::gpu_msg(format!(
                    "readback: the GPU did not finish a frame within {:.1} s ({polls} polls): a hung \
                     frame, or a device slower than that (set CLIPSAT_GPU_WAIT_S to wait longer)",
                    limit.as_secs_f64()
                )))
            }
            Err(e) => return Err(Error::gpu("readback: waiting for the GPU", e)),
        }
    }
}
