//! Stage 0, the source: PNG height maps. Greyscale (8 or 16 bit; RGB/RGBA/palette files whose channels are
//! all equal count as grey, as many tools export them): height = value * scale + offset. RGB(A) files in
//! the web-map encodings (Mapbox Terrain-RGB, Terrarium) when [`LoadOptions::png_encoding`] says so.

use std::io::{BufReader, Read};
use std::path::Path;

use image::codecs::png::PngDecoder;
use image::{ColorType, ImageDecoder, Limits};

use super::{check_size, to_f32, LoadOptions, PngEncoding, DEFAULT_SPACING_M};
use crate::{Error, Result};
use crate::source::Heightmap;

/// The PNG signature.
pub(super) const MAGIC: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1A, b'\n'];

/// How the option is named in errors (the binary maps the field to its flag).
const OPTION: &str = "PNG encoding (`LoadOptions::png_encoding`)";

/// Loads a PNG height map. PNG carries no spacing: [`LoadOptions::spacing`], else [`DEFAULT_SPACING_M`].
/// For grey files the default height scale is 0.1 m per unit for 16-bit files (the Puget Sound
/// convention) and 1 m for 8-bit ones; the web-map encodings give metres themselves.
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
    let bit_depth = head[24];
    let samples = check_size(path, width.into(), height.into(), opts)?;
    if opts.png_encoding != PngEncoding::Grey && opts.height_scale.is_some() {
        return Err(Error::format(
            path,
            format!(
                "a height scale does not apply to {}: the encoding gives metres (only the offset is added)",
                opts.png_encoding
            ),
        ));
    }

    let file = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot open", e))?;
    let mut limits = Limits::default();
    limits.max_image_width = Some(width);
    limits.max_image_height = Some(height);
    // Output (8 bytes a pixel at most, RGBA16) plus the decoder's own buffers.
    limits.max_alloc = Some((samples as u64).saturating_mul(8) + (64 << 20));
    let decoder =
        PngDecoder::with_limits(BufReader::new(file), limits).map_err(|e| corrupt(path, &e))?;
    let colour = decoder.color_type();
    let (channels, wide) = match colour {
        ColorType::L8 => (1, false),
        ColorType::La8 => (2, false),
        ColorType::Rgb8 => (3, false),
        ColorType::Rgba8 => (4, false),
        ColorType::L16 => (1, true),
        ColorType::La16 => (2, true),
        ColorType::Rgb16 => (3, true),
        ColorType::Rgba16 => (4, true),
        other => {
            return Err(Error::format(
                path,
                format!("PNG decodes as {other:?} (bit depth {bit_depth}): not a height map"),
            ))
        }
    };
    let total = usize::try_from(decoder.total_bytes()).map_err(|_| Error::TooLarge {
        path: path.into(),
        width: width.into(),
        height: height.into(),
        samples: samples as u64,
        limit: opts.max_samples,
    })?;
    let mut bytes = vec![0u8; total];
    decoder
        .read_image(&mut bytes)
        .map_err(|e| corrupt(path, &e))?;
    // The decoder hands 16-bit samples over in native byte order.
    let pixel = |p: usize| rgb(&bytes, p, channels, wide.then_some(u16::from_ne_bytes));
    let offset = f64::from(opts.height_offset);
    let void = |v: f64| super::is_nodata(opts.nodata, v);
    let mut heights: Vec<f32> = match opts.png_encoding {
        PngEncoding::Grey => {
            if channels >= 3 {
                if let Some(p) = (0..samples).find(|&p| {
                    let [r, g, b] = pixel(p);
                    r != g || g != b
                }) {
                    return Err(unequal_channels(
                        path,
                        &format!("{colour:?}"),
                        pixel(p),
                        (p % width as usize, p / width as usize),
                    ));
                }
            }
            let default_scale = if wide { 0.1 } else { 1.0 };
            let scale = opts.height_scale.map_or(default_scale, f64::from);
            // In f64, so that 0.1 m units land on the nearest f32 (whole metres exactly, as a TIFF holds them).
            (0..samples)
                .map(|p| {
                    let v = f64::from(pixel(p)[0]);
                    if void(v) {
                        f32::NAN
                    } else {
                        to_f32(v * scale + offset)
                    }
                })
                .collect()
        }
        encoding => {
            if channels < 3 || wide {
                return Err(Error::format(
                    path,
                    format!(
                        "PNG is {colour:?}, but the {OPTION} {encoding} needs 8-bit RGB or RGBA; \
                         for a grey height map use grey"
                    ),
                ));
            }
            (0..samples)
                .map(|p| {
                    let [r, g, b] = pixel(p);
                    let v = encoding.decode(r, g, b);
                    if void(v) {
                        f32::NAN
                    } else {
                        to_f32(v + offset)
                    }
                })
                .collect()
        }
    };
    drop(bytes);
    let filled = super::fill_voids(path, width as usize, &mut heights)?;
    Ok(Heightmap::new(
        path,
        width,
        height,
        opts.spacing.unwrap_or(DEFAULT_SPACING_M),
        heights,
    )?
    .with_voids_filled(filled))
}

/// Pixel `p`'s R, G, B (grey repeated) from samples of `channels` a pixel: bytes, or with `wide` the
/// 16-bit samples in the byte order it decodes.
fn rgb(bytes: &[u8], p: usize, channels: usize, wide: Option<fn([u8; 2]) -> u16>) -> [u16; 3] {
    let value = |i: usize| -> u16 {
        match wide {
            Some(decode) => decode([bytes[2 * i], bytes[2 * i + 1]]),
            None => bytes[i].into(),
        }
    };
    let base = p * channels;
    match channels {
        1 | 2 => [value(base); 3],
        _ => [value(base), value(base + 1), value(base + 2)],
    }
}

/// The refusal of a grey PNG whose channels differ at `(column, row)`: `colour` is the file's colour type.
fn unequal_channels(
    path: &Path,
    colour: &str,
    [r, g, b]: [u16; 3],
    (x, y): (usize, usize),
) -> Error {
    Error::format(
        path,
        format!(
            "PNG is {colour} with unequal channels (R, G, B = {r}, {g}, {b} at column {x}, row {y}), so it \
             is not a grey height map; if it is a web-map elevation tile, set the {OPTION} to terrain-rgb \
             or terrarium"
        ),
    )
}

fn corrupt(path: &Path, e: &image::ImageError) -> Error {
    Error::format(path, format!("corrupt or truncated PNG: {e}"))
}

/// Opens a PNG to be read a band of rows at a time with the png crate's row reader (the same decoding as
/// [`load`]: `Transformations::EXPAND`, 16-bit samples big-endian in the file). Interlaced files, and any
/// file whose form [`load`] refuses or treats specially, are loaded whole instead, so the samples and
/// errors are [`load`]'s.
pub(super) fn open_rows(
    path: &Path,
    opts: &LoadOptions,
    magic: &[u8],
) -> Result<Box<dyn super::RowSource>> {
    // Voids (a nodata value given) are filled over the whole grid.
    match Rows::open(path, opts, magic).filter(|_| opts.nodata.is_none()) {
        Some(rows) => Ok(Box::new(rows)),
        None => Ok(Box::new(super::Resident::new(load(path, opts, magic)?))),
    }
}

/// A non-interlaced PNG read row by row; the samples are the ones [`load`] gives.
struct Rows {
    reader: png::Reader<BufReader<std::fs::File>>,
    grid: super::RowGrid,
    channels: usize,
    wide: bool,
    encoding: PngEncoding,
    scale: f64,
    offset: f64,
    /// The next row the reader gives.
    next: u32,
}

impl Rows {
    /// The row reader, or `None` where [`load`] should read the file.
    fn open(path: &Path, opts: &LoadOptions, magic: &[u8]) -> Option<Self> {
        if !magic.starts_with(&MAGIC)
            || (opts.png_encoding != PngEncoding::Grey && opts.height_scale.is_some())
        {
            return None;
        }
        let file = std::fs::File::open(path).ok()?;
        let mut decoder = png::Decoder::new(BufReader::new(file));
        decoder.set_transformations(png::Transformations::EXPAND);
        let reader = decoder.read_info().ok()?;
        let info = reader.info();
        let (width, height) = (info.width, info.height);
        if info.interlaced || check_size(path, width.into(), height.into(), opts).is_err() {
            return None;
        }
        let (colour, depth) = reader.output_color_type();
        let channels = channels(colour)?;
        let wide = match depth {
            png::BitDepth::Eight => false,
            png::BitDepth::Sixteen => true,
            _ => return None,
        };
        if opts.png_encoding != PngEncoding::Grey && (channels < 3 || wide) {
            return None;
        }
        let default_scale = if wide { 0.1 } else { 1.0 };
        Some(Self {
            reader,
            grid: super::RowGrid {
                width,
                height,
                spacing: opts.spacing.unwrap_or(DEFAULT_SPACING_M),
                ew_spacing: opts.spacing.unwrap_or(DEFAULT_SPACING_M),
                origin: (0.0, 0.0),
                path: path.into(),
            },
            channels,
            wide,
            encoding: opts.png_encoding,
            scale: opts.height_scale.map_or(default_scale, f64::from),
            offset: f64::from(opts.height_offset),
            next: 0,
        })
    }
}

impl super::RowSource for Rows {
    fn grid(&self) -> &super::RowGrid {
        &self.grid
    }

    fn read_rows(&mut self, y0: u32, out: &mut [f32]) -> Result<()> {
        super::check_band(self, y0, out)?;
        if y0 != self.next {
            return Err(Error::format(
                &self.grid.path,
                format!(
                    "PNG rows are read in order: row {y0} asked, {} next",
                    self.next
                ),
            ));
        }
        let w = self.grid.width as usize;
        let (channels, wide) = (self.channels, self.wide);
        for (y, orow) in (y0..).zip(out.chunks_exact_mut(w)) {
            let row = self
                .reader
                .next_row()
                .map_err(|e| {
                    Error::format(&self.grid.path, format!("corrupt or truncated PNG: {e}"))
                })?
                .ok_or_else(|| Error::format(&self.grid.path, "truncated PNG: rows missing"))?;
            let data = row.data();
            if data.len() < w * channels * if wide { 2 } else { 1 } {
                return Err(Error::format(&self.grid.path, "corrupt PNG: a short row"));
            }
            for (x, o) in orow.iter_mut().enumerate() {
                // The row reader hands 16-bit samples over as the file stores them, big-endian.
                let [r, g, b] = rgb(data, x, channels, wide.then_some(u16::from_be_bytes));
                *o = match self.encoding {
                    PngEncoding::Grey => {
                        if r != g || g != b {
                            let colour = format!(
                                "{}{}",
                                if channels == 4 { "Rgba" } else { "Rgb" },
                                if wide { 16 } else { 8 }
                            );
                            return Err(unequal_channels(
                                &self.grid.path,
                                &colour,
                                [r, g, b],
                                (x, y as usize),
                            ));
                        }
                        to_f32(f64::from(r) * self.scale + self.offset)
                    }
                    encoding => to_f32(encoding.decode(r, g, b) + self.offset),
                };
            }
            self.next = y + 1;
        }
        Ok(())
    }
}

/// Samples a texel of a PNG row the reader hands out (expanded: a palette is never handed out).
pub(super) fn channels(colour: png::ColorType) -> Option<usize> {
    match colour {
        png::ColorType::Grayscale => Some(1),
        png::ColorType::GrayscaleAlpha => Some(2),
        png::ColorType::Rgb => Some(3),
        png::ColorType::Rgba => Some(4),
        png::ColorType::Indexed => None,
    }
}
