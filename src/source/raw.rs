//! Stage 0, the source: headerless raw height files (little-endian u16 or f32, dimensions given).

use std::path::Path;

use super::{check_size, to_f32, LoadOptions, RawFormat, DEFAULT_SPACING_M};
use crate::{Error, Heightmap, Param, Result};

/// Loads a raw file laid out as [`LoadOptions::raw`] says; its length must match exactly.
///
/// u16 samples are scaled by [`LoadOptions::height_scale`] (default 0.1 m, as for 16-bit PNG); f32
/// samples are metres. Both get [`LoadOptions::height_offset`]. Spacing: [`LoadOptions::spacing`], else
/// [`DEFAULT_SPACING_M`].
pub(super) fn load(path: &Path, len: u64, opts: &LoadOptions) -> Result<Heightmap> {
    let Some(layout) = opts.raw else {
        return Err(Error::format(
            path,
            format!(
                "a raw file has no header: give its dimensions and sample format with `{}`",
                Param::RawLayout
            ),
        ));
    };
    let samples = check_size(path, layout.width.into(), layout.height.into(), opts)?;
    let (bytes_per, name) = match layout.format {
        RawFormat::U16 => (2u64, "u16"),
        RawFormat::F32 => (4u64, "f32"),
    };
    let expected = samples as u64 * bytes_per;
    if len != expected {
        return Err(Error::SizeMismatch {
            path: path.into(),
            actual: len,
            expected: format!(
                "{expected} bytes ({} x {} {name})",
                layout.width, layout.height
            ),
        });
    }
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, "cannot read", e))?;
    if bytes.len() as u64 != expected {
        return Err(Error::SizeMismatch {
            path: path.into(),
            actual: bytes.len() as u64,
            expected: format!("{expected} bytes (the length when first checked)"),
        });
    }
    let offset = opts.height_offset;
    let heights: Vec<f32> = match layout.format {
        RawFormat::U16 => {
            let scale = opts.height_scale.map_or(0.1, f64::from);
            let off = f64::from(offset);
            bytes
                .chunks_exact(2)
                .map(|c| to_f32(f64::from(u16::from_le_bytes([c[0], c[1]])) * scale + off))
                .collect()
        }
        // Non-finite samples stay so, and `Heightmap::new` refuses them with their position.
        RawFormat::F32 => bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]) + offset)
            .collect(),
    };
    drop(bytes);
    Heightmap::new(
        path,
        layout.width,
        layout.height,
        opts.spacing.unwrap_or(DEFAULT_SPACING_M),
        heights,
    )
}
