//! Stage 0, the source: imagery read a band of rows at a time, as RGB8, for the out-of-core imagery bake
//! (docs/guide.md "Imagery"). A non-interlaced PNG is read row by row and a TIFF a row of chunks (strips
//! or tiles, chunky or planar) at a time, so an image far larger than memory bakes in a few bands' worth
//! of it. A JPEG or an interlaced PNG cannot be read by rows with the decoders at hand: it is decoded whole
//! (within `ImageryOptions::max_texels`) and handed out by rows. Every path gives the texels
//! [`Imagery::load`](super::imagery::Imagery::load) holds, which reads through this reader too.

use std::io::BufReader;
use std::path::{Path, PathBuf};

use super::imagery::{check_jpeg_end, check_size, one_line, place, Extent, Imagery, ImageryOptions};
use crate::{Error, Param, Result};

/// An imagery file opened for reading by rows: its size and placement known, its texels not yet read.
pub struct ImageryRows {
    path: PathBuf,
    width: u32,
    height: u32,
    extent: Extent,
    /// The next row of the file [`ImageryRows::read_rows`] reads.
    next: u32,
    reader: Reader,
    /// Texels made near-square: the file's rows or columns resampled (`Stretch`), where its texels are
    /// at least twice as long one way as the other over its extent.
    stretch: Option<Box<super::imagery_stretch::Stretch>>,
    /// The texel limit it was opened under, which a stretch keeps to.
    max_texels: u64,
}

impl std::fmt::Debug for ImageryRows {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ImageryRows")
            .field("path", &self.path)
            .field("size", &(self.width, self.height))
            .field("extent", &self.extent)
            .field("next", &self.next)
            .field("stretched", &self.stretch.as_ref().map(|s| s.size()))
            .finish_non_exhaustive()
    }
}

enum Reader {
    /// A non-interlaced PNG, expanded to 8 or 16 bits a sample (palette and low depths to 8).
    Png {
        reader: Box<png::Reader<BufReader<std::fs::File>>>,
        channels: usize,
        wide: bool,
        levels: Levels,
    },
    /// A TIFF, a row of chunks decoded into `band` (RGB8) at a time.
    Tiff(Box<TiffRows>),
    /// Texels held whole (a JPEG, an interlaced PNG, an image given in memory).
    Held(Vec<u8>),
}

/// A TIFF's chunk rows.
struct TiffRows {
    dec: tiff::decoder::Decoder<BufReader<std::fs::File>>,
    /// Chunk size (a strip is the image's width), chunks across, samples a texel.
    chunk: (u32, u32),
    across: u32,
    channels: usize,
    /// A JPEG-compressed TIFF's chunks, decoded by the JPEG decoder rather than the TIFF one.
    jpeg: Option<super::tiff_jpeg::JpegChunks>,
    /// Bits a sample, 8 or 16.
    bits: u8,
    /// How its samples become 8-bit colour.
    levels: Levels,
    /// Chunks a plane, where each sample lies in a plane of its own (planar configuration); 0: chunky.
    plane: u32,
    /// The decoded row of chunks `band_row`, RGB8.
    band: Vec<u8>,
    band_row: Option<u32>,
}

impl ImageryRows {
    /// Opens `path` (PNG, JPEG or TIFF) and places it as [`Imagery::load`](super::imagery::Imagery::load)
    /// does, with its checks: the declared size against `options.max_texels` before anything is
    /// allocated, at least 2 x 2 texels, an extent that overlaps `grid`. Damage past the header is found
    /// while the rows are read.
    pub fn open(path: &Path, grid: &Extent, options: &ImageryOptions) -> Result<Self> {
        let magic = magic(path)?;
        let (width, height, reader) = if super::tiff::has_magic(&magic) {
            open_tiff(path, options)?
        } else if magic.starts_with(b"\x89PNG") {
            match open_png(path, options)? {
                Some(opened) => opened,
                None => decode_whole(path, options, image::ImageFormat::Png)?,
            }
        } else if magic.starts_with(&[0xFF, 0xD8, 0xFF]) {
            check_jpeg_end(path)?;
            decode_whole(path, options, image::ImageFormat::Jpeg)?
        } else {
            return Err(Error::format(
                path,
                "not a PNG, JPEG or TIFF image (unknown signature)",
            ));
        };
        let mut rows = Self::placed(path, width, height, reader, grid, options.extent)?;
        rows.max_texels = options.max_texels;
        Ok(rows)
    }

    /// An image held in memory, read by rows.
    pub fn held(image: Imagery) -> Self {
        let (width, height) = image.size();
        Self {
            path: image.path().to_path_buf(),
            width,
            height,
            extent: image.extent(),
            next: 0,
            reader: Reader::Held(image.into_texels()),
            stretch: None,
            max_texels: super::imagery::DEFAULT_MAX_IMAGERY_TEXELS,
        }
    }

    fn placed(
        path: &Path,
        width: u32,
        height: u32,
        reader: Reader,
        grid: &Extent,
        extent: Option<Extent>,
    ) -> Result<Self> {
        Ok(Self {
            path: path.to_path_buf(),
            width,
            height,
            extent: place(path, grid, extent)?,
            next: 0,
            reader,
            stretch: None,
            max_texels: super::imagery::DEFAULT_MAX_IMAGERY_TEXELS,
        })
    }

    /// The file it reads.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Texels (columns, rows) it gives: the file's, or after [`ImageryRows::near_square`] where its
    /// texels are at least twice as long one way as the other over its extent, the file's with the long
    /// side's texels cut into the nearest whole factor.
    pub fn size(&self) -> (u32, u32) {
        self.stretch.as_ref().map_or((self.width, self.height), |s| s.size())
    }

    /// Where it lies in the terrain's world frame.
    pub fn extent(&self) -> Extent {
        self.extent
    }

    /// From here on, reads the image with near-square texels where its texels are at least twice as
    /// long one way as the other over its extent (`imagery_stretch.rs`), within the texel limit it was
    /// opened under: what the imagery bake reads, for the colour rings. Before any row is read;
    /// [`ImageryRows::size`] then gives the new size.
    pub fn near_square(&mut self) {
        if self.next == 0 && self.stretch.is_none() {
            self.stretch = super::imagery_stretch::Stretch::new(
                self.width,
                self.height,
                &self.extent,
                self.max_texels,
            );
        }
    }

    /// Reads the next `out.len() / (3 width)` rows of [`ImageryRows::size`], in order from the north
    /// edge, as RGB8. Refused: a length that is not whole rows, rows past the last, and a file damaged in
    /// the rows it reads.
    pub fn read_rows(&mut self, out: &mut [u8]) -> Result<()> {
        let Some(mut st) = self.stretch.take() else {
            return self.read_file_rows(out);
        };
        let (path, file) = (self.path.clone(), (self.width, self.height));
        let done = st.read(&path, file, out, &mut |rows| self.read_file_rows(rows));
        self.stretch = Some(st);
        done
    }

    /// The file's next `out.len() / (3 width)` rows, as RGB8.
    fn read_file_rows(&mut self, out: &mut [u8]) -> Result<()> {
        let w = self.width as usize * 3;
        let rows = out.len().checked_div(w).unwrap_or(0);
        let end = u64::from(self.next) + rows as u64;
        if rows * w != out.len() || end > u64::from(self.height) {
            return Err(Error::format(
                &self.path,
                format!(
                    "{} bytes asked from row {}: whole rows of {w} bytes up to row {} are read",
                    out.len(),
                    self.next,
                    self.height
                ),
            ));
        }
        let y0 = self.next;
        match &mut self.reader {
            Reader::Held(texels) => {
                let at = y0 as usize * w;
                out.copy_from_slice(&texels[at..at + out.len()]);
            }
            Reader::Png {
                reader,
                channels,
                wide,
                levels,
            } => {
                for orow in out.chunks_exact_mut(w) {
                    let row = reader
                        .next_row()
                        .map_err(|e| Error::format(&self.path, format!("corrupt or truncated PNG: {}", one_line(&e))))?
                        .ok_or_else(|| Error::format(&self.path, "truncated PNG: rows missing"))?;
                    to_rgb8(&self.path, row.data(), (*channels, *wide), levels, orow)?;
                }
            }
            Reader::Tiff(t) => {
                for (y, orow) in (y0..).zip(out.chunks_exact_mut(w)) {
                    let cr = y / t.chunk.1;
                    if t.band_row != Some(cr) {
                        t.load(&self.path, cr, self.width, self.height)?;
                    }
                    let r = (y - cr * t.chunk.1) as usize;
                    orow.copy_from_slice(&t.band[r * w..(r + 1) * w]);
                }
            }
        }
        // `end` is at most `height`, a u32.
        self.next = u32::try_from(end).unwrap_or(self.height);
        Ok(())
    }

    /// Every row left, as RGB8 (what [`Imagery`] holds); texels held from the start are handed over,
    /// not copied.
    pub fn read_all(mut self) -> Result<Vec<u8>> {
        if let (Reader::Held(texels), 0, None) = (&mut self.reader, self.next, &self.stretch) {
            return Ok(std::mem::take(texels));
        }
        let ((width, height), next) = match &self.stretch {
            Some(st) => (st.size(), st.next()),
            None => ((self.width, self.height), self.next),
        };
        let mut texels = vec![0u8; (height - next) as usize * width as usize * 3];
        self.read_rows(&mut texels)?;
        Ok(texels)
    }
}

/// A file's first bytes.
fn magic(path: &Path) -> Result<[u8; 8]> {
    use std::io::Read as _;
    let mut magic = [0u8; 8];
    super::regular_file(path, "cannot read")?;
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot read", e))?;
    let mut n = 0;
    while n < magic.len() {
        match f.read(&mut magic[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(Error::io(path, "cannot read", e)),
        }
    }
    Ok(magic)
}

/// Refuses a declared size past the limit, before anything is allocated, saying what a higher limit
/// would cost: a file read by rows (`streamed`) holds a band of its width, one decoded whole all of it.
fn check_limit(
    path: &Path,
    width: u32,
    height: u32,
    options: &ImageryOptions,
    streamed: bool,
) -> Result<()> {
    let texels = u64::from(width) * u64::from(height);
    if texels > options.max_texels {
        let cost = if streamed {
            "it is read 256 rows at a time, so a higher limit costs memory for its width alone (about \
             1.5 KB a texel of it)"
        } else {
            "it is decoded whole, 3 bytes a texel (a non-interlaced PNG or a TIFF would be read by rows)"
        };
        return Err(Error::param(
            Param::MaxImageryTexels,
            format!(
                "{}: declared size {width} x {height} = {texels} texels is over the limit of {} \
                 texels; {cost}",
                path.display(),
                options.max_texels
            ),
        ));
    }
    check_size(path, width, height)
}

/// A PNG's row reader, or `None` for an interlaced PNG (decoded whole instead).
fn open_png(path: &Path, options: &ImageryOptions) -> Result<Option<(u32, u32, Reader)>> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot read", e))?;
    let mut decoder = png::Decoder::new(BufReader::new(file));
    decoder.set_transformations(png::Transformations::EXPAND);
    let reader = decoder.read_info().map_err(|e| {
        Error::format(path, format!("cannot read the image header: {}", one_line(&e)))
    })?;
    let info = reader.info();
    let (width, height) = (info.width, info.height);
    check_limit(path, width, height, options, !info.interlaced)?;
    if info.interlaced {
        return Ok(None);
    }
    let (colour, depth) = reader.output_color_type();
    let channels = super::png::channels(colour)
        .ok_or_else(|| Error::format(path, "PNG palette not expanded"))?;
    let wide = depth == png::BitDepth::Sixteen;
    let levels = Levels::new(path, options.range, wide)?;
    Ok(Some((
        width,
        height,
        Reader::Png {
            reader: Box::new(reader),
            channels,
            wide,
            levels,
        },
    )))
}

/// A JPEG or an interlaced PNG decoded whole (the decoders read no rows), within the texel limit.
fn decode_whole(
    path: &Path,
    options: &ImageryOptions,
    format: image::ImageFormat,
) -> Result<(u32, u32, Reader)> {
    let open = || -> Result<image::ImageReader<BufReader<std::fs::File>>> {
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot read", e))?;
        Ok(image::ImageReader::with_format(BufReader::new(file), format))
    };
    let (width, height) = open()?
        .into_dimensions()
        .map_err(|e| Error::format(path, format!("cannot read the image header: {}", one_line(&e))))?;
    check_limit(path, width, height, options, false)?;
    let mut reader = open()?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(width);
    limits.max_image_height = Some(height);
    // The decoded image at 16 bits a channel with alpha, and as much again for the decoder's own.
    limits.max_alloc = Some((u64::from(width) * u64::from(height)).saturating_mul(16));
    reader.limits(limits);
    let undecodable =
        |e: image::ImageError| Error::format(path, format!("cannot decode the image: {}", one_line(&e)));
    let mut decoder = reader.into_decoder().map_err(undecodable)?;
    // A JPEG's EXIF orientation: its texels as every viewer shows them (a camera's or an editor's JPEG
    // stores them rotated or mirrored and says so), not as stored; but for one placed by a world file,
    // which describes the texels as stored (GDAL reads them so).
    let georeferenced = || matches!(super::georef::GeoRef::of_imagery(path), Ok(Some(_)));
    let orientation = if format == image::ImageFormat::Jpeg && !georeferenced() {
        image::ImageDecoder::orientation(&mut decoder).unwrap_or(image::metadata::Orientation::NoTransforms)
    } else {
        image::metadata::Orientation::NoTransforms
    };
    let mut decoded = image::DynamicImage::from_decoder(decoder).map_err(undecodable)?;
    if (decoded.width(), decoded.height()) != (width, height) {
        return Err(Error::format(
            path,
            format!(
                "the header says {width} x {height} texels, the data {} x {}",
                decoded.width(),
                decoded.height()
            ),
        ));
    }
    decoded.apply_orientation(orientation);
    let (width, height) = (decoded.width(), decoded.height());
    let texels = match options.range {
        None => decoded.into_rgb8().into_raw(),
        Some(_) => {
            // Through the table of the file's own sample depth.
            let wide = decoded.color().bytes_per_pixel() > decoded.color().channel_count();
            let levels = Levels::new(path, options.range, wide)?;
            if wide {
                decoded.into_rgb16().into_raw().into_iter().map(|v| levels.map(v)).collect()
            } else {
                let mut t = decoded.into_rgb8().into_raw();
                levels.apply8(&mut t);
                t
            }
        }
    };
    Ok((width, height, Reader::Held(texels)))
}

/// How stored samples become 8-bit colour: [`ImageryOptions::range`] mapped linearly onto 0..255 (a
/// table of the file's sample values), or without one 8-bit samples as they are and 16-bit ones rounded
/// to 8 bits.
struct Levels {
    wide: bool,
    table: Option<Box<[u8]>>,
}

impl Levels {
    /// The levels of a file of 16-bit (`wide`) or 8-bit samples; a range past what its samples hold is
    /// refused, naming the file.
    fn new(path: &Path, range: Option<(f64, f64)>, wide: bool) -> Result<Self> {
        let top = if wide { 65535.0 } else { 255.0 };
        let table = match range {
            None => None,
            Some((lo, hi)) => {
                if hi > top {
                    return Err(Error::param(
                        Param::ImageryRange,
                        format!(
                            "{}: holds {} samples (0 to {top}); the range {lo} to {hi} passes them",
                            path.display(),
                            if wide { "16-bit" } else { "8-bit" }
                        ),
                    ));
                }
                let n: u32 = if wide { 65536 } else { 256 };
                Some(
                    (0..n)
                        .map(|v| {
                            let t = ((f64::from(v) - lo) / (hi - lo)).clamp(0.0, 1.0);
                            #[expect(
                                clippy::cast_possible_truncation,
                                clippy::cast_sign_loss,
                                reason = "rounded within 0..=255"
                            )]
                            let b = (t * 255.0).round() as u8;
                            b
                        })
                        .collect(),
                )
            }
        };
        Ok(Self { wide, table })
    }

    /// Sample `v` (8-bit files: 0..=255) as 8 bits.
    fn map(&self, v: u16) -> u8 {
        match &self.table {
            Some(t) => t[usize::from(v).min(t.len() - 1)],
            None if self.wide => to8(v),
            None => u8::try_from(v).unwrap_or(u8::MAX),
        }
    }

    /// 8-bit samples mapped in place (nothing to do without a range).
    fn apply8(&self, bytes: &mut [u8]) {
        if let Some(t) = &self.table {
            for b in bytes {
                *b = t[usize::from(*b)];
            }
        }
    }
}

/// A 16-bit sample rounded to 8 bits, as the `image` crate rounds.
fn to8(v: u16) -> u8 {
    u8::try_from((u32::from(v) + 128) / 257).unwrap_or(u8::MAX)
}

/// One row of `channels` samples a texel (grey, grey + alpha, RGB, RGBA; 8 bits, or 16 big-endian:
/// `wide`) into RGB8 through `levels`, alpha dropped.
fn to_rgb8(
    path: &Path,
    data: &[u8],
    (channels, wide): (usize, bool),
    levels: &Levels,
    out: &mut [u8],
) -> Result<()> {
    let bytes = if wide { 2 } else { 1 };
    if data.len() < out.len() / 3 * channels * bytes {
        return Err(Error::format(path, "corrupt PNG: a short row"));
    }
    for (i, o) in out.chunks_exact_mut(3).enumerate() {
        let sample = |c: usize| {
            let at = (i * channels + c) * bytes;
            if wide {
                levels.map(u16::from_be_bytes([data[at], data[at + 1]]))
            } else {
                levels.map(u16::from(data[at]))
            }
        };
        if channels < 3 {
            o.fill(sample(0));
        } else {
            o.copy_from_slice(&[sample(0), sample(1), sample(2)]);
        }
    }
    Ok(())
}

/// A TIFF's chunk-row reader: 8- or 16-bit grey, RGB or RGBA, chunky or planar.
fn open_tiff(path: &Path, options: &ImageryOptions) -> Result<(u32, u32, Reader)> {
    use tiff::decoder::Limits;
    use tiff::ColorType;
    let bad = |e: &dyn std::fmt::Display| {
        Error::format(
            path,
            format!("corrupt, truncated or unsupported TIFF: {}", one_line(e)),
        )
    };
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot read", e))?;
    let mut dec = tiff::decoder::Decoder::new(BufReader::new(file)).map_err(|e| bad(&e))?;
    let (width, height) = dec.dimensions().map_err(|e| bad(&e))?;
    check_limit(path, width, height, options, true)?;
    let jpeg = super::tiff_jpeg::JpegChunks::read(path, &mut dec)?;
    // A JPEG stream says itself what colour it holds (`tiff_jpeg.rs`): 8 bits, made RGB.
    let colour = if jpeg.is_some() {
        ColorType::RGB(8)
    } else {
        dec.colortype().map_err(|e| {
            // tiff 0.11 refuses colour-mapped files outright (PhotometricInterpretation 3).
            let palette = dec
                .find_tag(tiff::tags::Tag::PhotometricInterpretation)
                .ok()
                .flatten()
                .and_then(|v| v.into_u16().ok())
                == Some(3);
            if palette {
                Error::format(
                    path,
                    "imagery TIFF is colour-mapped (a palette), which is not read; expand it to \
                     RGB, for example with `gdal_translate -expand rgb -co COMPRESS=DEFLATE IN \
                     OUT.tif`",
                )
            } else {
                bad(&e)
            }
        })?
    };
    let channels = match colour {
        ColorType::Gray(8 | 16) => 1,
        ColorType::RGB(8 | 16) => 3,
        ColorType::RGBA(8 | 16) => 4,
        other => {
            return Err(Error::format(
                path,
                format!(
                    "imagery TIFF is {other:?}: 8- or 16-bit grey, RGB or RGBA (or JPEG-compressed) \
                     are read; convert it, for example with `gdal_translate -ot Byte -expand rgb \
                     -co COMPRESS=DEFLATE IN OUT.tif` (after `-scale` for float samples)"
                ),
            ))
        }
    };
    // tiff 0.11 drops samples past the colour's (RGB and a near-infrared band, as NAIP has, not an alpha)
    // before undoing a horizontal predictor, which it then undoes at the wrong stride: garbage colours.
    let mut short = |tag| dec.find_tag(tag).ok().flatten().and_then(|v| v.into_u16().ok());
    let samples = short(tiff::tags::Tag::SamplesPerPixel).unwrap_or(1);
    if jpeg.is_none() && short(tiff::tags::Tag::Predictor) == Some(2) && usize::from(samples) > channels {
        return Err(Error::format(
            path,
            format!(
                "imagery TIFF of {samples} bands with a horizontal predictor, which the TIFF decoder \
                 misreads past the {channels} colour bands; keep those bands, for example with \
                 `gdal_translate -b 1 -b 2 -b 3 -co COMPRESS=DEFLATE IN OUT.tif`"
            ),
        ));
    }
    let chunk = dec.chunk_dimensions();
    if chunk.0 == 0 || chunk.1 == 0 {
        return Err(Error::format(path, "TIFF chunks of zero size"));
    }
    // A tile may pass the image's edge (a small image in one tile), but not by more than a usual tile:
    // one chunk is decoded at a time, and its size, not the image's, would bound it.
    let most = |side: u32| side.max(4096).next_multiple_of(16);
    if chunk.0 > most(width) || chunk.1.min(height) > most(height) {
        return Err(Error::format(
            path,
            format!(
                "TIFF tiles of {} x {} for {width} x {height} texels; tile it again, for example with \
                 `gdal_translate -co TILED=YES -co COMPRESS=DEFLATE IN OUT.tif`",
                chunk.0, chunk.1
            ),
        ));
    }
    let count = super::tiff::chunk_count(&mut dec).map_err(|e| bad(&e))?;
    let (across, down) = (width.div_ceil(chunk.0), height.div_ceil(chunk.1));
    let per_plane = u64::from(across) * u64::from(down);
    let plane = if u64::from(count) == per_plane {
        0
    } else if u64::from(count) == per_plane * channels as u64 {
        u32::try_from(per_plane).unwrap_or(u32::MAX)
    } else {
        return Err(Error::format(
            path,
            format!(
                "TIFF has {count} chunks of {} x {} for {width} x {height} texels",
                chunk.0, chunk.1
            ),
        ));
    };
    // One chunk of 16-bit samples with alpha, decoded, and as much again for the decoder.
    let mut limits = Limits::default();
    let chunk_bytes = u64::from(chunk.0) * u64::from(chunk.1) * 8;
    limits.decoding_buffer_size = usize::try_from(chunk_bytes).unwrap_or(usize::MAX).saturating_add(1 << 20);
    limits.intermediate_buffer_size = limits.decoding_buffer_size;
    let band = vec![0u8; width as usize * 3 * chunk.1.min(height) as usize];
    // A JPEG-compressed TIFF decodes to 8-bit samples.
    let levels = Levels::new(path, options.range, colour.bit_depth() > 8 && jpeg.is_none())?;
    Ok((
        width,
        height,
        Reader::Tiff(Box::new(TiffRows {
            dec: dec.with_limits(limits),
            chunk,
            across,
            channels,
            jpeg,
            bits: colour.bit_depth(),
            levels,
            plane,
            band,
            band_row: None,
        })),
    ))
}

impl TiffRows {
    /// Decodes row `cr` of chunks into `band`, RGB8.
    fn load(&mut self, path: &Path, cr: u32, width: u32, height: u32) -> Result<()> {
        use tiff::decoder::DecodingResult;
        let w3 = width as usize * 3;
        // Planar (RGB or RGBA: one plane each): the alpha plane is not read.
        let planes: u32 = if self.plane == 0 { 1 } else { 3 };
        for cx in 0..self.across {
            let (dw, dh) = (
                self.chunk.0.min(width - cx * self.chunk.0) as usize,
                self.chunk.1.min(height - cr * self.chunk.1) as usize,
            );
            let x0 = (cx * self.chunk.0) as usize;
            if let Some(jpeg) = &mut self.jpeg {
                // A whole tile, or a strip (the last one may be cut to the image).
                let index = cr * self.across + cx;
                let (cw, ch, texels) = jpeg.decode(path, index, self.chunk)?;
                let cw = cw as usize;
                if cw < dw || (ch as usize) < dh {
                    return Err(Error::format(
                        path,
                        format!("TIFF chunk {index} is a JPEG of {cw} x {ch} for {dw} x {dh} texels"),
                    ));
                }
                for r in 0..dh {
                    let row = &mut self.band[r * w3 + x0 * 3..r * w3 + (x0 + dw) * 3];
                    row.copy_from_slice(&texels[r * cw * 3..(r * cw + dw) * 3]);
                    self.levels.apply8(row);
                }
                continue;
            }
            for p in 0..planes {
                let index = cr * self.across + cx + self.plane * p;
                // Chunky: every sample of a texel here; planar: sample `p` only.
                let spt = if self.plane == 0 { self.channels } else { 1 };
                let row_samples = self.chunk.0.saturating_mul(u32::try_from(spt).unwrap_or(u32::MAX));
                let chunk = super::tiff::read_chunk_stored(&mut self.dec, index, row_samples, self.bits)
                    .map_err(|e| {
                        Error::format(
                            path,
                            format!("corrupt, truncated or unsupported TIFF: {}", one_line(&e)),
                        )
                    })?;
                let (len, at): (usize, Box<dyn Fn(usize) -> u8 + '_>) = match &chunk {
                    DecodingResult::U8(v) => (v.len(), Box::new(|i| self.levels.map(u16::from(v[i])))),
                    DecodingResult::U16(v) => (v.len(), Box::new(|i| self.levels.map(v[i]))),
                    _ => {
                        return Err(Error::format(
                            path,
                            "imagery TIFF samples are not 8- or 16-bit integers",
                        ))
                    }
                };
                // Rows are the chunk's stored width apart (`read_chunk_stored`); the last may be cut.
                let stride = self.chunk.0 as usize;
                if len < (stride * (dh - 1) + dw) * spt {
                    return Err(Error::format(
                        path,
                        format!("TIFF chunk {index} decoded to {len} samples for {dw} x {dh}"),
                    ));
                }
                for r in 0..dh {
                    let row = &mut self.band[r * w3 + x0 * 3..r * w3 + (x0 + dw) * 3];
                    for (c, o) in row.chunks_exact_mut(3).enumerate() {
                        let s = (r * stride + c) * spt;
                        match (self.plane, self.channels) {
                            (0, 1) => o.fill(at(s)),
                            (0, _) => o.copy_from_slice(&[at(s), at(s + 1), at(s + 2)]),
                            // Planar: sample p is channel p (alpha, p = 3, is dropped).
                            _ => o[p as usize] = at(s),
                        }
                    }
                }
            }
        }
        self.band_row = Some(cr);
        Ok(())
    }
}

impl Imagery {
    /// Reads a PNG, JPEG or TIFF whole ([`ImageryRows`]) and places it over `options.extent`, or over
    /// `grid` (the height grid's extent, [`Extent::of_grid`]) without one. Refused, with the file and the
    /// reason: another format, a declared size over `options.max_texels` (before allocating), fewer
    /// than 2 x 2 texels, a truncated or corrupt file, an extent that shares no area with `grid`.
    pub fn load(path: &Path, grid: &Extent, options: &ImageryOptions) -> Result<Self> {
        let rows = ImageryRows::open(path, grid, options)?;
        let ((width, height), extent) = (rows.size(), rows.extent());
        Imagery::from_rgb(path, width, height, rows.read_all()?, &extent, Some(extent))
    }
}
