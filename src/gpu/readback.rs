//! Stage 3 -> image: read an RGBA8 render target back into tightly packed rows, hash it, save it.

use std::path::Path;
use std::sync::mpsc;

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
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| Error::gpu("readback: waiting for the GPU", e))?;
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
