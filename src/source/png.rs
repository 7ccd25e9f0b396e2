//! Stage 0, the source: 8- and 16-bit greyscale PNG height maps (height = value * scale + offset).

use std::io::{BufReader, Read};
use std::path::Path;

use image::codecs::png::PngDecoder;
use image::{ColorType, ImageDecoder, Limits};

use super::{check_size, to_f32, LoadOptions, DEFAULT_SPACING_M};
use crate::{Error, Heightmap, Result};

/// The PNG signature.
pub(super) const MAGIC: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1A, b'\n'];

/// Loads a greyscale PNG. PNG carries no spacing: [`LoadOptions::spacing`], else
/// [`DEFAULT_SPACING_M`]. The default height scale is 0.1 m per unit for 16-bit files (the Puget Sound
/// convention) and 1 m for 8-bit ones.
pub(super) fn load(path: &Path, opts: &LoadOptions, magic: &[u8]) -> Result<Heightmap> {
    if !magic.starts_with(&MAGIC) {
        return Err(Error::format(
            path,
            format!("wrong magic number for PNG: starts with {magic:02x?}, expected {MAGIC:02x?}"),
        ));
    }
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot open", e))?;
    // Read IHDR ourselves first: the dimensions are checked before the decoder allocates anything.
    let mut head = [0u8; 26];
    (&file)
        .take(26)
        .read_exact(&mut head)
        .map_err(|_| Error::format(path, "truncated PNG: no complete IHDR header"))?;
    if &head[12..16] != b"IHDR" {
        return Err(Error::format(path, "corrupt PNG: first chunk is not IHDR"));
    }
    let width = u32::from_be_bytes([head[16], head[17], head[18], head[19]]);
    let height = u32::from_be_bytes([head[20], head[21], head[22], head[23]]);
    let (bit_depth, colour) = (head[24], head[25]);
    let samples = check_size(path, width.into(), height.into(), opts)?;
    let kind = match colour {
        0 => "",
        2 => "RGB colour",
        3 => "palette colour",
        4 => "greyscale with alpha",
        6 => "RGBA colour",
        _ => "an unknown colour type",
    };
    if !kind.is_empty() {
        return Err(Error::format(
            path,
            format!("PNG is {kind}; height maps must be single-channel greyscale (8 or 16 bit)"),
        ));
    }

    let file = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot open", e))?;
    let mut limits = Limits::default();
    limits.max_image_width = Some(width);
    limits.max_image_height = Some(height);
    // Output (2 bytes a sample at most) plus the decoder's own buffers.
    limits.max_alloc = Some(samples as u64 * 2 + (64 << 20));
    let decoder =
        PngDecoder::with_limits(BufReader::new(file), limits).map_err(|e| corrupt(path, &e))?;
    let (scale, bytes_per_sample) = match decoder.color_type() {
        ColorType::L8 => (opts.height_scale.map_or(1.0, f64::from), 1),
        ColorType::L16 => (opts.height_scale.map_or(0.1, f64::from), 2),
        other => {
            return Err(Error::format(
                path,
                format!(
                    "PNG decodes as {other:?} (bit depth {bit_depth}, perhaps a tRNS chunk); height maps \
                     must be single-channel greyscale (8 or 16 bit) without transparency"
                ),
            ))
        }
    };
    let mut bytes = vec![0u8; samples * bytes_per_sample];
    decoder
        .read_image(&mut bytes)
        .map_err(|e| corrupt(path, &e))?;
    // In f64, so that 0.1 m units land on the nearest f32 (whole metres exactly, as a TIFF holds them).
    let offset = f64::from(opts.height_offset);
    let to_m = |v: u16| to_f32(f64::from(v) * scale + offset);
    let heights: Vec<f32> = if bytes_per_sample == 1 {
        bytes.iter().map(|&v| to_m(v.into())).collect()
    } else {
        // The decoder hands 16-bit samples over in native byte order.
        bytes
            .chunks_exact(2)
            .map(|c| to_m(u16::from_ne_bytes([c[0], c[1]])))
            .collect()
    };
    drop(bytes);
    Heightmap::new(
        path,
        width,
        height,
        opts.spacing.unwrap_or(DEFAULT_SPACING_M),
        heights,
    )
}

fn corrupt(path: &Path, e: &image::ImageError) -> Error {
    Error::format(path, format!("corrupt or truncated PNG: {e}"))
}
