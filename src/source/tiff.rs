//! Stage 0, the source: single-band GeoTIFF height maps (8, 16 and 32-bit integers, 16, 32 and 64-bit
//! floats; stripped or tiled; uncompressed, LZW, Deflate, PackBits or ZSTD), with spacing from a world
//! file or the GeoTIFF tags and GDAL nodata voids filled.

use std::io::BufReader;
use std::path::{Path, PathBuf};

use tiff::decoder::{Decoder, DecodingResult, Limits};
use tiff::tags::Tag;
use tiff::ColorType;

use super::{
    check_size, fill_voids, height,
    to_f32, LoadOptions,
};
use crate::{Error, Param, Result};
use crate::source::Heightmap;

/// Whether `magic` starts like a TIFF or BigTIFF file (`II*\0`, `MM\0*`, and the BigTIFF 43 forms).
pub(super) fn has_magic(magic: &[u8]) -> bool {
    matches!(
        magic.get(..4),
        Some([b'I', b'I', 42 | 43, 0] | [b'M', b'M', 0, 42 | 43])
    )
}

/// Decodes chunk `index` (a strip or tile) with its rows `row_samples` samples of `bits` apart: a tile's
/// full stored width, so a tile at the right edge comes with its padding, for the caller to crop. Asked
/// for the data's width alone, tiff 0.11 skips each row's padding through a reader that an LZW stream can
/// end short in (image-rs/image-tiff#395: "no lzw end code found" on valid tiled files). A strip has no
/// padding, and is read as it is (its rows per strip may be TIFF's default 2^32 - 1, which a stored
/// stride would overflow).
pub(super) fn read_chunk_stored<R: std::io::Read + std::io::Seek>(
    dec: &mut Decoder<R>,
    index: u32,
    row_samples: u32,
    bits: u8,
) -> tiff::TiffResult<DecodingResult> {
    if dec.get_chunk_type() == tiff::decoder::ChunkType::Strip {
        return dec.read_chunk(index);
    }
    let row_bytes = (u64::from(row_samples) * u64::from(bits)).div_ceil(8);
    let row_bytes = usize::try_from(row_bytes).map_err(|_| tiff::TiffError::LimitsExceeded)?;
    let mut out = DecodingResult::U8(Vec::new());
    dec.read_chunk_to_buffer(&mut out, index, row_bytes)?;
    Ok(out)
}

/// The chunks (strips or tiles, of every plane) the file holds: its offsets. `Decoder::strip_count`
/// overflows on TIFF's default rows per strip, 2^32 - 1, which a writer that leaves the tag out gives.
pub(super) fn chunk_count<R: std::io::Read + std::io::Seek>(
    dec: &mut Decoder<R>,
) -> tiff::TiffResult<u32> {
    let tag = match dec.get_chunk_type() {
        tiff::decoder::ChunkType::Strip => Tag::StripOffsets,
        tiff::decoder::ChunkType::Tile => Tag::TileOffsets,
    };
    let offsets = dec.get_tag(tag)?.into_u64_vec()?;
    u32::try_from(offsets.len()).map_err(|_| tiff::TiffError::IntSizeError)
}

/// GTModelTypeGeoKey: 1 projected, 2 geographic (degrees).
const GT_MODEL_TYPE_GEO_KEY: u16 = 1024;
const MODEL_TYPE_GEOGRAPHIC: u16 = 2;

/// Loads a single-band TIFF. Heights are `value * height_scale + height_offset` (scale default 1).
///
/// Spacing, first found: [`LoadOptions::spacing`]; a `.tfw` world file beside the file (its N-S pixel
/// size, line 4); the ModelPixelScaleTag's N-S size. When the GeoKeyDirectory says the model is
/// geographic, that size is in degrees and becomes metres of meridian arc at the grid's centre latitude
/// (from the tie point). Cells are taken as square with the N-S spacing. With none of these the load fails
/// and asks for `--spacing`. GDAL_NODATA samples are voids: filled from their neighbours and counted.
pub(super) fn load(path: &Path, opts: &LoadOptions, magic: &[u8]) -> Result<Heightmap> {
    // Decoded a row of chunks at a time, as the bake reads it ([`Rows`]), voids as NaN; the spacing is
    // looked for after the samples, so a sample's error comes first.
    let samples_first = LoadOptions {
        spacing: Some(opts.spacing.unwrap_or(1.0)),
        ..opts.clone()
    };
    let mut rows = Rows::open(path, &samples_first, magic)?;
    rows.keep_voids = true;
    let (width, height) = (rows.grid.width, rows.grid.height);
    let w = width as usize;
    // `check_size` bounded width x height when the file was opened.
    let mut heights = vec![0.0f32; w * height as usize];
    super::RowSource::read_rows(&mut rows, 0, &mut heights)?;
    let voids = fill_voids(path, w, &mut heights)?;
    let (spacing, ew) = match opts.spacing {
        Some(s) => (s, s),
        None => GeoTags::read(&mut rows.dec).spacing(path, height)?,
    };
    Ok(Heightmap::new(path, width, height, spacing, heights)?
        .with_voids_filled(voids)
        .with_ew_spacing(ew))
}

/// A TIFF opened and checked, its tags read, no sample decoded yet.
struct Opened {
    dec: Decoder<BufReader<std::fs::File>>,
    width: u32,
    height: u32,
    nodata: Option<f64>,
    geo: GeoTags,
}

/// Opens a single-band TIFF: magic, dimensions (within [`LoadOptions::max_samples`]), colour type, nodata
/// and the georeferencing tags.
fn open(path: &Path, opts: &LoadOptions, magic: &[u8]) -> Result<Opened> {
    if !has_magic(magic) {
        return Err(Error::format(
            path,
            format!(
                "wrong magic number for TIFF: starts with {magic:02x?}, expected `II*\\0` or `MM\\0*`"
            ),
        ));
    }
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot open", e))?;
    let mut dec = Decoder::new(BufReader::new(file)).map_err(|e| corrupt(path, &e))?;
    let (width, height) = dec.dimensions().map_err(|e| corrupt(path, &e))?;
    let samples = check_size(path, width.into(), height.into(), opts)?;
    let mut limits = Limits::default();
    // Room for the whole image at 8 bytes a sample; `check_size` already bounded it.
    limits.decoding_buffer_size = samples.saturating_mul(8).saturating_add(1 << 20);
    limits.intermediate_buffer_size = limits.decoding_buffer_size;
    let mut dec = dec.with_limits(limits);
    match dec.colortype().map_err(|e| corrupt(path, &e))? {
        ColorType::Gray(_) => {}
        other => {
            return Err(Error::format(
                path,
                format!("TIFF is {other:?}; height maps must have a single grey band"),
            ))
        }
    }
    let nodata = opts.nodata.or_else(|| {
        tag_ascii(&mut dec, Tag::GdalNodata)
            .and_then(|s| s.trim().trim_end_matches('\0').trim().parse::<f64>().ok())
    });
    let geo = GeoTags::read(&mut dec);
    Ok(Opened {
        dec,
        width,
        height,
        nodata,
        geo,
    })
}

/// The refusal of a sample type no elevation data uses.
fn unsupported(path: &Path, other: &DecodingResult) -> Error {
    Error::format(
        path,
        format!(
            "unsupported TIFF sample type {}: use int8, uint8, int16, uint16, int32, uint32, float16, \
             float32 or float64",
            sample_name(other)
        ),
    )
}

/// Opens a TIFF to be read a band of rows at a time: one row of strips or tiles is decoded at a time
/// (`Decoder::read_chunk`). A file with voids is loaded whole instead, since they are filled from
/// neighbours over the whole grid; finding out costs one extra pass over the chunks when the file
/// declares a nodata value or [`LoadOptions::nodata`] gives one.
pub(super) fn open_rows(
    path: &Path,
    opts: &LoadOptions,
    magic: &[u8],
) -> Result<Box<dyn super::RowSource>> {
    let mut rows = Rows::open(path, opts, magic)?;
    if rows.nodata.is_some() {
        for cr in 0..rows.chunk_rows {
            if rows.load_chunk_row(cr)? {
                return Ok(Box::new(super::Resident::new(load(path, opts, magic)?)));
            }
        }
    }
    Ok(Box::new(rows))
}

/// Opens a TIFF tile of a mosaic to be read a band of rows at a time, its voids read as NaN (the mosaic
/// decides what a void becomes, `mosaic.rs`).
pub(super) fn open_tile_rows(path: &Path, opts: &LoadOptions) -> Result<Box<dyn super::RowSource>> {
    let mut rows = Rows::open(path, opts, &super::read_magic(path)?)?;
    rows.keep_voids = true;
    Ok(Box::new(rows))
}

/// A TIFF read one row of chunks (strips or tiles) at a time; the samples are the ones [`load`] gives.
struct Rows {
    dec: Decoder<BufReader<std::fs::File>>,
    grid: super::RowGrid,
    nodata: Option<f64>,
    scale: f64,
    offset: f64,
    /// Chunk size (a strip is the image's width), chunks per row of chunks, rows of chunks.
    chunk: (u32, u32),
    chunks_across: u32,
    chunk_rows: u32,
    /// The decoded row of chunks `band_row`: `chunk.1` rows of `width` samples (voids NaN).
    band: Vec<f32>,
    band_row: Option<u32>,
    /// Whether voids are read as NaN (a mosaic's tile, [`open_tile_rows`]) rather than refused.
    keep_voids: bool,
    /// Bits a sample.
    bits: u8,
}

impl Rows {
    fn open(path: &Path, opts: &LoadOptions, magic: &[u8]) -> Result<Self> {
        let Opened {
            dec,
            width,
            height,
            nodata,
            geo,
            ..
        } = open(path, opts, magic)?;
        let (spacing, ew_spacing) = match opts.spacing {
            Some(s) => (s, s),
            None => geo.spacing(path, height)?,
        };
        let chunk = dec.chunk_dimensions();
        let mut dec = dec;
        let bits = dec.colortype().map_err(|e| corrupt(path, &e))?.bit_depth();
        let count = chunk_count(&mut dec).map_err(|e| corrupt(path, &e))?;
        if chunk.0 == 0 || chunk.1 == 0 {
            return Err(Error::format(path, "TIFF chunks of zero size"));
        }
        let (across, down) = (width.div_ceil(chunk.0), height.div_ceil(chunk.1));
        if u64::from(count) != u64::from(across) * u64::from(down) {
            return Err(Error::format(
                path,
                format!(
                    "TIFF has {count} chunks of {} x {} for {width} x {height} samples",
                    chunk.0, chunk.1
                ),
            ));
        }
        Ok(Self {
            dec,
            grid: super::RowGrid {
                width,
                height,
                spacing,
                ew_spacing,
                origin: (0.0, 0.0),
                path: path.into(),
            },
            nodata,
            scale: opts.height_scale.map_or(1.0, f64::from),
            offset: f64::from(opts.height_offset),
            chunk,
            chunks_across: across,
            chunk_rows: down,
            band: vec![0.0; width as usize * chunk.1.min(height) as usize],
            band_row: None,
            keep_voids: false,
            bits,
        })
    }

    /// Decodes row `cr` of chunks into `band`; returns whether it holds a void.
    fn load_chunk_row(&mut self, cr: u32) -> Result<bool> {
        let mut voids = false;
        let w = self.grid.width as usize;
        for cx in 0..self.chunks_across {
            let index = cr * self.chunks_across + cx;
            let (dw, dh) = (
                self.chunk.0.min(self.grid.width - cx * self.chunk.0) as usize,
                self.chunk.1.min(self.grid.height - cr * self.chunk.1) as usize,
            );
            let chunk = read_chunk_stored(&mut self.dec, index, self.chunk.0, self.bits)
                .map_err(|e| corrupt(&self.grid.path, &e))?;
            let stride = self.chunk.0 as usize;
            let (x0, y0) = ((cx * self.chunk.0) as usize, (cr * self.chunk.1) as usize);
            let (nodata, scale, offset) = (self.nodata, self.scale, self.offset);
            let mut put = |len: usize, at: &dyn Fn(usize) -> f64| -> Result<()> {
                // Rows are the chunk's stored width apart (`read_chunk_stored`); the last may be cut.
                if stride < dw || len < stride * (dh - 1) + dw {
                    return Err(Error::format(
                        &self.grid.path,
                        format!("TIFF chunk {index} decoded to {len} samples for {dw} x {dh}"),
                    ));
                }
                for r in 0..dh {
                    for c in 0..dw {
                        let v = at(r * stride + c);
                        let void = super::is_nodata(nodata, v);
                        voids |= void;
                        self.band[r * w + x0 + c] =
                            height(&self.grid.path, v, void, scale, offset, (x0 + c, y0 + r))?;
                    }
                }
                Ok(())
            };
            match &chunk {
                DecodingResult::I16(v) => put(v.len(), &|i| f64::from(v[i]))?,
                DecodingResult::U16(v) => put(v.len(), &|i| f64::from(v[i]))?,
                DecodingResult::I32(v) => put(v.len(), &|i| f64::from(v[i]))?,
                DecodingResult::U8(v) => put(v.len(), &|i| f64::from(v[i]))?,
                DecodingResult::F32(v) => put(v.len(), &|i| f64::from(v[i]))?,
                DecodingResult::F64(v) => put(v.len(), &|i| v[i])?,
                DecodingResult::U32(v) => put(v.len(), &|i| f64::from(v[i]))?,
                DecodingResult::I8(v) => put(v.len(), &|i| f64::from(v[i]))?,
                DecodingResult::F16(v) => put(v.len(), &|i| f64::from(v[i]))?,
                other => return Err(unsupported(&self.grid.path, other)),
            }
        }
        self.band_row = Some(cr);
        Ok(voids)
    }
}

impl super::RowSource for Rows {
    fn grid(&self) -> &super::RowGrid {
        &self.grid
    }

    fn read_rows(&mut self, y0: u32, out: &mut [f32]) -> Result<()> {
        super::check_band(self, y0, out)?;
        let w = self.grid.width as usize;
        for (y, row) in (y0..).zip(out.chunks_exact_mut(w)) {
            let cr = y / self.chunk.1;
            if self.band_row != Some(cr) && self.load_chunk_row(cr)? && !self.keep_voids {
                return Err(Error::format(
                    &self.grid.path,
                    format!("void samples in row {y} (a file with voids is loaded whole)"),
                ));
            }
            let r = (y - cr * self.chunk.1) as usize;
            row.copy_from_slice(&self.band[r * w..(r + 1) * w]);
        }
        Ok(())
    }
}

fn sample_name(r: &DecodingResult) -> &'static str {
    match r {
        DecodingResult::U8(_) => "uint8",
        DecodingResult::U16(_) => "uint16",
        DecodingResult::U32(_) => "uint32",
        DecodingResult::U64(_) => "uint64",
        DecodingResult::F16(_) => "float16",
        DecodingResult::F32(_) => "float32",
        DecodingResult::F64(_) => "float64",
        DecodingResult::I8(_) => "int8",
        DecodingResult::I16(_) => "int16",
        DecodingResult::I32(_) => "int32",
        DecodingResult::I64(_) => "int64",
    }
}

fn corrupt(path: &Path, e: &tiff::TiffError) -> Error {
    Error::format(path, format!("corrupt, truncated or unsupported TIFF: {e}"))
}

/// An optional ASCII tag; a malformed one reads as absent.
fn tag_ascii<R: std::io::Read + std::io::Seek>(dec: &mut Decoder<R>, tag: Tag) -> Option<String> {
    dec.find_tag(tag).ok().flatten()?.into_string().ok()
}

fn tag_f64s<R: std::io::Read + std::io::Seek>(dec: &mut Decoder<R>, tag: Tag) -> Option<Vec<f64>> {
    dec.find_tag(tag).ok().flatten()?.into_f64_vec().ok()
}

/// The georeferencing tags that matter for spacing.
struct GeoTags {
    pixel_scale: Option<Vec<f64>>,
    tiepoint: Option<Vec<f64>>,
    geographic: bool,
    world_file: Option<PathBuf>,
}

impl GeoTags {
    fn read<R: std::io::Read + std::io::Seek>(dec: &mut Decoder<R>) -> Self {
        let keys: Vec<u16> = dec
            .find_tag(Tag::GeoKeyDirectoryTag)
            .ok()
            .flatten()
            .and_then(|v| v.into_u16_vec().ok())
            .unwrap_or_default();
        // Header (4 shorts), then entries of (key, location, count, value); location 0 = value inline.
        let geographic = keys.get(4..).is_some_and(|entries| {
            entries.chunks_exact(4).any(|e| {
                e[0] == GT_MODEL_TYPE_GEO_KEY && e[1] == 0 && e[3] == MODEL_TYPE_GEOGRAPHIC
            })
        });
        Self {
            pixel_scale: tag_f64s(dec, Tag::ModelPixelScaleTag),
            tiepoint: tag_f64s(dec, Tag::ModelTiepointTag),
            geographic,
            world_file: None,
        }
    }

    /// (N-S, E-W) spacing in metres, or an error asking for `--spacing`. Geographic: degrees of meridian
    /// arc and of the parallel at the grid's middle row.
    fn spacing(mut self, path: &Path, rows: u32) -> Result<(f32, f32)> {
        self.world_file = ["tfw", "TFW", "tifw", "tiffw"]
            .iter()
            .map(|e| path.with_extension(e))
            .find(|p| p.is_file());
        let mid_row = f64::from(rows - 1) / 2.0;
        // (N-S pixel size, latitude of the grid's middle row if geographic, E-W pixel size)
        let found: Option<(f64, f64, f64)> = if let Some(tfw) = &self.world_file {
            let nums = super::georef::world_file_numbers(tfw)?;
            // Lines: x size, rotation, rotation, y size (negative), x and y of the first pixel's centre.
            Some((
                nums[3].abs(),
                nums[5] - mid_row * nums[3].abs(),
                nums[0].abs(),
            ))
        } else {
            self.pixel_scale
                .as_ref()
                .and_then(|s| s.get(1).copied())
                .filter(|s| *s > 0.0)
                .map(|sy| {
                    let lat = match self.tiepoint.as_deref() {
                        // (i, j, k, x, y, z): pixel (i, j) sits at model (x, y).
                        Some([_, j, _, _, y, ..]) => y - (mid_row - j) * sy,
                        _ => 0.0,
                    };
                    let sx = self.pixel_scale.as_ref().and_then(|s| s.first().copied());
                    (sy, lat, sx.unwrap_or(sy))
                })
        };
        let Some((size, lat, size_x)) = found.filter(|(s, _, _)| s.is_finite() && *s > 0.0) else {
            return Err(Error::format(
                path,
                format!(
                    "no sample spacing: the TIFF has no ModelPixelScale tag and no .tfw world file \
                     beside it; give one in metres with `{}`",
                    Param::Spacing
                ),
            ));
        };
        // A missing or odd E-W size: square cells.
        let size_x = if size_x.is_finite() && size_x > 0.0 {
            size_x
        } else {
            size
        };
        if self.geographic {
            return super::geo::spacing_at(path, lat, (size, size_x));
        }
        Ok((to_f32(size), to_f32(size_x)))
    }
}
