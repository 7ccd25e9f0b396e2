//! Stage 1b, the package: the imagery package baked out of core. The source is read a band of
//! [`TILE`] rows at a time ([`ImageryRows`]); each level holds one band, which is coded into a row of
//! JPEG tiles when full and halved into the next coarser level's band (`bake::imagery::halve_rows`, GC
//! section 3's box-filtered "additional images"). Memory is about two bands of level 0, `2 x 256 x width
//! x 3` bytes, whatever the image's height: 25 MB for a 16384-texel-wide image (docs/guide.md
//! "Imagery"). The tiles land in the file in the order they are finished (levels
//! interleaved); the header, written last at the file's start, says where each lies.

use std::io::{Seek, SeekFrom, Write};
use std::path::Path;

use super::format::TileEntry;
use super::imagery::{
    decode_jpeg, psnr, ImageryBakeReport, ImageryHeader, ImageryLevel, ImageryPackage, TILE, VERSION,
};
use crate::bake::imagery::halve_rows;
use crate::progress::Progress;
use crate::source::imagery::Imagery;
use crate::source::imagery_rows::ImageryRows;
use crate::{Error, Result};

/// Bakes what `rows` reads (from its first row) into an imagery package written to `out` at its
/// current position 0: tiles coded at JPEG `quality`, `key` recorded in the header. With `measure`,
/// level 0's tiles are decoded again for the report's PSNR against the source.
pub fn bake_imagery_rows<W: Write + Seek>(
    rows: &mut ImageryRows,
    quality: u8,
    key: u64,
    measure: bool,
    out: &mut W,
    progress: Progress<'_>,
) -> Result<ImageryBakeReport> {
    let (width, height) = rows.size();
    let (levels, tile_count) = ImageryHeader::layout(width, height, TILE);
    let mut header = ImageryHeader {
        quality: u32::from(quality),
        tile: TILE,
        width,
        height,
        extent: rows.extent(),
        key,
        levels,
        tiles: vec![TileEntry::default(); tile_count],
    };
    let path = rows.path().to_path_buf();
    let write_err = |e: std::io::Error| Error::io(&path, "cannot write the imagery package baked from", e);
    let head = header.byte_len() as u64;
    out.seek(SeekFrom::Start(head)).map_err(write_err)?;
    let mut coder = Coder {
        out,
        at: head,
        quality,
        path: &path,
        measure,
        sq_err: 0,
        level0_bytes: 0,
    };
    // One band per level and the rows of each level coded so far.
    let mut bands: Vec<Vec<u8>> = header
        .levels
        .iter()
        .map(|l| Vec::with_capacity(TILE as usize * l.width as usize * 3))
        .collect();
    let mut done = vec![0u32; header.levels.len()];
    let mut meter = progress.task("baking imagery", u64::from(height));
    while done[0] < height {
        let n = TILE.min(height - done[0]);
        bands[0].resize(n as usize * width as usize * 3, 0);
        rows.read_rows(&mut bands[0])?;
        // Code the band, halve it into the next level, and go on down while that level's band is full.
        let mut l = 0;
        loop {
            let level = header.levels[l];
            // At most TILE rows.
            let band_rows = u32::try_from(bands[l].len() / (level.width as usize * 3)).unwrap_or(TILE);
            coder.tile_row(&mut header, l, done[l] / TILE, &bands[l], band_rows)?;
            done[l] += band_rows;
            if l + 1 == bands.len() {
                break;
            }
            let (fine, coarse) = bands.split_at_mut(l + 1);
            halve_rows(&fine[l], level.width, band_rows, &mut coarse[0]);
            fine[l].clear();
            let next = header.levels[l + 1];
            let next_rows = coarse[0].len() / (next.width as usize * 3);
            let full = next_rows == TILE as usize
                || done[l + 1] as usize + next_rows == next.height as usize;
            if !full {
                break;
            }
            l += 1;
        }
        meter.inc(u64::from(n));
    }
    meter.finish();
    let mut bytes = Vec::with_capacity(header.byte_len());
    header.write(&mut bytes);
    let Coder {
        out,
        at,
        sq_err,
        level0_bytes,
        ..
    } = coder;
    out.seek(SeekFrom::Start(0)).map_err(write_err)?;
    out.write_all(&bytes).map_err(write_err)?;
    out.flush().map_err(write_err)?;
    let texels = header.texels();
    #[expect(clippy::cast_precision_loss, reason = "ratios for a report")]
    Ok(ImageryBakeReport {
        bytes: at,
        texels,
        levels: u32::try_from(header.levels.len()).unwrap_or(u32::MAX),
        tiles: u32::try_from(tile_count).unwrap_or(u32::MAX),
        level0_bytes_per_texel: level0_bytes as f64 / texels as f64,
        bytes_per_texel: at as f64 / texels as f64,
        psnr_db: if measure {
            psnr(sq_err, texels * 3)
        } else {
            f64::NAN
        },
    })
}

/// Bakes `imagery` into an imagery package in memory, with the PSNR of level 0 measured.
pub fn bake_imagery(imagery: &Imagery, quality: u8, key: u64) -> Result<(Vec<u8>, ImageryBakeReport)> {
    let mut rows = ImageryRows::held(imagery.clone());
    let mut out = std::io::Cursor::new(Vec::new());
    let report = bake_imagery_rows(&mut rows, quality, key, true, &mut out, Progress::default())?;
    Ok((out.into_inner(), report))
}

/// Bakes what `rows` reads into the imagery package at `path`, written through a locked temporary
/// renamed into place (`crate::temp`): a bake killed midway leaves no file at `path`, and the next
/// write into the folder removes the temporary it left.
pub fn bake_imagery_file(
    rows: &mut ImageryRows,
    quality: u8,
    key: u64,
    measure: bool,
    path: &Path,
    progress: Progress<'_>,
) -> Result<ImageryBakeReport> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        crate::temp::sweep(dir);
    }
    let tmp =
        crate::temp::TempFile::create(path.with_extension(format!("tmp{}", crate::temp_suffix())))?;
    let report = {
        let mut out = std::io::BufWriter::new(&tmp.file);
        bake_imagery_rows(rows, quality, key, measure, &mut out, progress)?
    };
    tmp.persist(path)?;
    Ok(report)
}

/// The imagery package for the image `open` reads, in the cache folder `dir`, named by `key`: baked
/// there out of core on first use and opened.
pub fn cached_imagery(
    dir: &Path,
    key: u64,
    open: impl FnOnce() -> Result<ImageryRows>,
    progress: Progress<'_>,
) -> Result<ImageryPackage> {
    let path = dir.join(format!(
        "imagery-{}-v{VERSION}.clipsat-imagery",
        crate::hash::hex(key)
    ));
    if let Ok(p) = ImageryPackage::open(&path) {
        if p.header().key == key {
            return Ok(p);
        }
    }
    let mut rows = open()?;
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, "cannot create folder", e))?;
    bake_imagery_file(&mut rows, super::imagery::DEFAULT_QUALITY, key, false, &path, progress)?;
    ImageryPackage::open(&path)
}

/// Codes rows of tiles into the package.
struct Coder<'a, W> {
    out: &'a mut W,
    /// Where the next tile lands in the file.
    at: u64,
    quality: u8,
    path: &'a Path,
    measure: bool,
    sq_err: u64,
    level0_bytes: u64,
}

/// One tile coded: its JPEG and, where measured, its squared error against the source.
type Coded = (Vec<u8>, u64);

impl<W: Write + Seek> Coder<'_, W> {
    /// Codes tile row `ty` of level `l` from `band`, its `rows` rows, and records each tile in `header`.
    /// The row's tiles are coded on every core (`write::threads`), each thread a run of neighbours, and
    /// written in order: a tile's JPEG does not depend on which thread made it.
    fn tile_row(
        &mut self,
        header: &mut ImageryHeader,
        l: usize,
        ty: u32,
        band: &[u8],
        rows: u32,
    ) -> Result<()> {
        let level: ImageryLevel = header.levels[l];
        let measure = self.measure && l == 0;
        let (quality, path) = (self.quality, self.path);
        let code = |tx: u32, scratch: &mut Vec<u8>, decoded: &mut Vec<u8>| -> Result<Coded> {
            let tw = (level.width - tx * TILE).min(TILE);
            let stride = level.width as usize * 3;
            scratch.clear();
            for y in 0..rows as usize {
                let at = y * stride + (tx * TILE) as usize * 3;
                scratch.extend_from_slice(&band[at..at + tw as usize * 3]);
            }
            let mut coded = Vec::new();
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut coded, quality)
                .encode(scratch, tw, rows, image::ExtendedColorType::Rgb8)
                .map_err(|e| Error::format(path, format!("JPEG encoder: {e}")))?;
            let mut sq = 0;
            if measure {
                decoded.resize(scratch.len(), 0);
                decode_jpeg(path, &coded, tw, rows, decoded)?;
                sq = scratch
                    .iter()
                    .zip(decoded.iter())
                    .map(|(a, b)| u64::from(a.abs_diff(*b)).pow(2))
                    .sum::<u64>();
            }
            Ok((coded, sq))
        };
        let tiles: Vec<u32> = (0..level.tiles_x).collect();
        let per = tiles.len().div_ceil(super::threads()).max(1);
        let coded: Vec<Coded> = std::thread::scope(|s| {
            let handles: Vec<_> = tiles
                .chunks(per)
                .map(|run| {
                    s.spawn(move || {
                        let (mut scratch, mut decoded) = (Vec::new(), Vec::new());
                        run.iter()
                            .map(|&tx| code(tx, &mut scratch, &mut decoded))
                            .collect::<Result<Vec<_>>>()
                    })
                })
                .collect();
            let mut all = Vec::with_capacity(tiles.len());
            for h in handles {
                all.extend(h.join().expect("an imagery tile encoder thread panicked")?);
            }
            Ok::<_, Error>(all)
        })?;
        for (tx, (jpeg, sq)) in (0..).zip(coded) {
            self.out
                .write_all(&jpeg)
                .map_err(|e| Error::io(self.path, "cannot write the imagery package baked from", e))?;
            let i = level.first_tile + (ty * level.tiles_x + tx) as usize;
            header.tiles[i] = TileEntry {
                offset: self.at,
                len: u32::try_from(jpeg.len()).unwrap_or(u32::MAX),
                crc: crc32fast::hash(&jpeg),
            };
            self.at += jpeg.len() as u64;
            if l == 0 {
                self.level0_bytes += jpeg.len() as u64;
                self.sq_err += sq;
            }
        }
        Ok(())
    }
}
