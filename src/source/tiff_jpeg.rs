//! Stage 0, the source: the chunks of a JPEG-compressed TIFF (compression 7, as orthophoto GeoTIFFs and
//! COGs store colour), each decoded by the `image` crate's JPEG decoder, which converts its colour space
//! as the stream says (YCbCr at any subsampling, RGB with an Adobe marker as libtiff writes it for
//! PHOTOMETRIC=RGB, greyscale, CMYK) and upsamples its chroma. The `tiff` crate's own JPEG path hands
//! YCbCr back unconverted and fails on libtiff's RGB tiles ("Unimplemented colorspace mapping from RGB
//! to CMYK"), so only the chunks' bytes come from the TIFF's tags here.

use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use tiff::decoder::{ChunkType, Decoder};
use tiff::tags::Tag;

use super::imagery::one_line;
use crate::{Error, Result};

/// TIFF Compression: 6 is the old-style JPEG (TIFF 6.0, withdrawn), 7 the JPEG of TIFF Technical Note 2.
const OLD_JPEG: u16 = 6;
const JPEG: u16 = 7;

/// Where a JPEG-compressed TIFF's chunks lie, and the tables they share.
pub(super) struct JpegChunks {
    file: std::io::BufReader<std::fs::File>,
    file_len: u64,
    offsets: Vec<u64>,
    counts: Vec<u64>,
    /// JPEGTables: a stream of the quantisation and Huffman tables, SOI to EOI, that each chunk's
    /// abbreviated stream leaves out.
    tables: Option<Vec<u8>>,
}

impl JpegChunks {
    /// The chunks of `dec`'s image, read from `path`, where it is JPEG-compressed; `None` otherwise.
    /// Refused: old-style JPEG, planar samples, offsets and byte counts that do not match.
    pub(super) fn read<R: Read + Seek>(path: &Path, dec: &mut Decoder<R>) -> Result<Option<Self>> {
        let compression = dec
            .find_tag(Tag::Compression)
            .ok()
            .flatten()
            .and_then(|v| v.into_u16().ok());
        match compression {
            Some(JPEG) => {}
            Some(OLD_JPEG) => {
                return Err(Error::format(
                    path,
                    "TIFF of old-style JPEG compression (6), which is not read; convert it, for \
                     example with `gdal_translate -co COMPRESS=DEFLATE IN OUT.tif`",
                ))
            }
            _ => return Ok(None),
        }
        let planar = dec
            .find_tag(Tag::PlanarConfiguration)
            .ok()
            .flatten()
            .and_then(|v| v.into_u16().ok());
        if planar == Some(2) {
            return Err(Error::format(
                path,
                "JPEG-compressed TIFF with planar samples, which is not read; convert it, for \
                 example with `gdal_translate -co COMPRESS=JPEG -co INTERLEAVE=PIXEL IN OUT.tif`",
            ));
        }
        let (offsets_tag, counts_tag) = match dec.get_chunk_type() {
            ChunkType::Strip => (Tag::StripOffsets, Tag::StripByteCounts),
            ChunkType::Tile => (Tag::TileOffsets, Tag::TileByteCounts),
        };
        let mut u64s = |tag| -> Option<Vec<u64>> { dec.find_tag(tag).ok().flatten()?.into_u64_vec().ok() };
        let (Some(offsets), Some(counts)) = (u64s(offsets_tag), u64s(counts_tag)) else {
            return Err(Error::format(
                path,
                "JPEG-compressed TIFF without its chunks' offsets and byte counts",
            ));
        };
        if offsets.len() != counts.len() {
            return Err(Error::format(
                path,
                format!(
                    "TIFF has {} chunk offsets and {} byte counts",
                    offsets.len(),
                    counts.len()
                ),
            ));
        }
        let tables = dec
            .find_tag(Tag::JPEGTables)
            .ok()
            .flatten()
            .and_then(|v| v.into_u8_vec().ok());
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot read", e))?;
        let file_len = file
            .metadata()
            .map_err(|e| Error::io(path, "cannot read", e))?
            .len();
        Ok(Some(Self {
            file: std::io::BufReader::new(file),
            file_len,
            offsets,
            counts,
            tables,
        }))
    }

    /// Decodes chunk `index` as RGB8: its (width, height) as coded and its texels. Refused: a chunk past
    /// the file's end, one that is not a whole JPEG stream (no start or end-of-image marker: a cut
    /// stream decodes to grey rather than failing), one the decoder refuses, and one whose header declares
    /// more than `most` (the chunk's size), before anything is allocated for it.
    pub(super) fn decode(
        &mut self,
        path: &Path,
        index: u32,
        most: (u32, u32),
    ) -> Result<(u32, u32, Vec<u8>)> {
        let i = index as usize;
        let (Some(&offset), Some(&count)) = (self.offsets.get(i), self.counts.get(i)) else {
            return Err(Error::format(path, format!("TIFF has no chunk {index}")));
        };
        if offset.checked_add(count).is_none_or(|end| end > self.file_len) {
            return Err(Error::format(
                path,
                format!("truncated TIFF: chunk {index} ({count} bytes at {offset}) runs past the end"),
            ));
        }
        let len = usize::try_from(count).map_err(|_| Error::format(path, "a TIFF chunk too large"))?;
        let mut chunk = vec![0u8; len];
        self.file
            .seek(SeekFrom::Start(offset))
            .and_then(|_| self.file.read_exact(&mut chunk))
            .map_err(|e| Error::io(path, "cannot read", e))?;
        let whole = |s: &[u8]| s.starts_with(&[0xFF, 0xD8]) && s.windows(2).any(|w| w == [0xFF, 0xD9]);
        if !whole(&chunk) {
            return Err(Error::format(
                path,
                format!(
                    "corrupt TIFF: chunk {index} is not a whole JPEG stream (start or end marker \
                     missing)"
                ),
            ));
        }
        let stream = match &self.tables {
            // The tables' stream without its EOI, then the chunk's without its SOI.
            Some(t) if whole(t) => {
                let mut s = Vec::with_capacity(t.len() + chunk.len());
                s.extend_from_slice(&t[..t.len() - 2]);
                s.extend_from_slice(&chunk[2..]);
                s
            }
            _ => chunk,
        };
        let bad = |e: &dyn std::fmt::Display| {
            Error::format(
                path,
                format!("corrupt JPEG in TIFF chunk {index}: {}", one_line(e)),
            )
        };
        let mut decoder = image::codecs::jpeg::JpegDecoder::new(std::io::Cursor::new(stream))
            .map_err(|e| bad(&e))?;
        let (w, h) = image::ImageDecoder::dimensions(&decoder);
        if w > most.0 || h > most.1 {
            return Err(Error::format(
                path,
                format!(
                    "corrupt TIFF: chunk {index} is a JPEG of {w} x {h}, larger than its {} x {}",
                    most.0, most.1
                ),
            ));
        }
        let mut limits = image::Limits::default();
        limits.max_alloc = Some((u64::from(w) * u64::from(h)).saturating_mul(16));
        image::ImageDecoder::set_limits(&mut decoder, limits).map_err(|e| bad(&e))?;
        let decoded = image::DynamicImage::from_decoder(decoder).map_err(|e| bad(&e))?;
        Ok((w, h, decoded.into_rgb8().into_raw()))
    }
}
