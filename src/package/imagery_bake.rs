//! Stage 1b, the package: the imagery package baked out of core. The source is read a band of
//! [`TILE`] rows at a time ([`ImageryRows`]); each level's rows are halved into the next coarser
//! level's band as they arrive (`bake::imagery::halve_rows`, GC section 3's box-filtered "additional
//! images"). A level stored whole is coded into a row of JPEG tiles when its band of [`TILE`] rows is
//! full, and decoded again where the level below is a residual of it; a residual level holds two tile
//! rows, which wait for the row of parent tiles above them to be coded and decoded, then are coded as
//! residuals against it (closed loop: the prediction is the parent as the runtime decodes it). Memory is
//! the bands, about 2.9 KB per texel of level 0's width (512 rows of level 0, a band and its decoded copy
//! of level 1, and so on up), whatever the image's height: 47 MB for a 16384-texel-wide image (docs/guide.md "The imagery package"). The tiles land in the file
//! in the order they are finished (levels interleaved); the header, written last at the file's start,
//! says where each lies.

use std::io::{Seek, SeekFrom, Write};
use std::path::Path;

use super::format::TileEntry;
use super::imagery::{
    decode_jpeg, encode_jpeg, psnr, ImageryBakeReport, ImageryHeader, ImageryLevel, ImageryPackage,
    TILE, VERSION,
};
use crate::bake::imagery::{from_residual, halve_rows, to_residual, Parent};
use crate::progress::Progress;
use crate::source::imagery::Imagery;
use crate::source::imagery_rows::ImageryRows;
use crate::{Error, Result};

/// Bakes what `rows` reads (from its first row) into an imagery package written to `out` at its
/// current position 0: tiles coded at JPEG `quality`, `key` recorded in the header. With `measure`,
/// level 0's tiles are decoded again for the report's PSNR against the source. An image whose texels
/// are at least twice as long one way as the other is baked with near-square texels
/// ([`ImageryRows::near_square`]): the colour rings are square in texels.
pub fn bake_imagery_rows<W: Write + Seek>(
    rows: &mut ImageryRows,
    quality: u8,
    key: u64,
    measure: bool,
    out: &mut W,
    progress: Progress<'_>,
) -> Result<ImageryBakeReport> {
    rows.near_square();
    let (width, height) = rows.size();
    let (levels, tile_count) = ImageryHeader::layout(width, height, TILE);
    let header = ImageryHeader {
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
    let count = header.levels.len();
    // One band per level (two tile rows for a residual level: they wait for their parents' tile row),
    // and a whole level's band as decoded where the level below is a residual of it.
    let bands = header
        .levels
        .iter()
        .map(|l| {
            let rows = if l.residual { 2 * TILE } else { TILE };
            Vec::with_capacity(rows as usize * l.width as usize * 3)
        })
        .collect();
    let decoded = (0..count)
        .map(|l| {
            let child = l > 0 && header.levels[l - 1].residual;
            let rows = if child { TILE as usize } else { 0 };
            Vec::with_capacity(rows * header.levels[l].width as usize * 3)
        })
        .collect();
    let mut bake = Bake {
        coder: Coder {
            out,
            at: head,
            quality,
            path: &path,
            measure,
            sq_err: 0,
            level0_bytes: 0,
        },
        header,
        bands,
        decoded,
        done: vec![0; count],
    };
    let mut read = 0;
    let mut meter = progress.task("baking imagery", u64::from(height));
    while read < height {
        let n = TILE.min(height - read);
        let start = bake.bands[0].len();
        bake.bands[0].resize(start + n as usize * width as usize * 3, 0);
        rows.read_rows(&mut bake.bands[0][start..])?;
        read += n;
        bake.arrived(0, start)?;
        meter.inc(u64::from(n));
    }
    meter.finish();
    let Bake { coder, header, .. } = bake;
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

/// The bake's state: the levels' bands of rows not yet coded, the decoded band of each level a
/// residual level is predicted from, and the rows of each level coded so far.
struct Bake<'a, W> {
    coder: Coder<'a, W>,
    header: ImageryHeader,
    bands: Vec<Vec<u8>>,
    decoded: Vec<Vec<u8>>,
    done: Vec<u32>,
}

impl<W: Write + Seek> Bake<'_, W> {
    /// Rows of level `l` have arrived at the end of its band, from byte `start` on: an even count but
    /// at the level's end, so halving them alone gives the coarser level's rows. Codes what is complete.
    fn arrived(&mut self, l: usize, start: usize) -> Result<()> {
        let level = self.header.levels[l];
        let stride = level.width as usize * 3;
        let band_rows = u32::try_from(self.bands[l].len() / stride).unwrap_or(u32::MAX);
        let at_end = self.done[l] + band_rows == level.height;
        if level.residual {
            // The new rows' means go up now; the band is coded once its parents' tile row is.
            let new_rows = u32::try_from((self.bands[l].len() - start) / stride).unwrap_or(0);
            let parent_start = self.bands[l + 1].len();
            let (fine, coarse) = self.bands.split_at_mut(l + 1);
            halve_rows(&fine[l][start..], level.width, new_rows, &mut coarse[0]);
            self.arrived(l + 1, parent_start)?;
            if band_rows == 2 * TILE || at_end {
                let first = band_rows.min(TILE);
                let ty = self.done[l] / TILE;
                let (head, tail) = self.bands[l].split_at(first as usize * stride);
                let parent = (&self.decoded[l + 1][..], self.header.levels[l + 1].width);
                self.coder.tile_row(&mut self.header, l, ty, head, first, Some((parent, 0)), None)?;
                if band_rows > first {
                    let rows = band_rows - first;
                    let below = Some((parent, TILE));
                    self.coder.tile_row(&mut self.header, l, ty + 1, tail, rows, below, None)?;
                }
                self.done[l] += band_rows;
                self.bands[l].clear();
            }
            return Ok(());
        }
        if band_rows < TILE && !at_end {
            return Ok(());
        }
        let keep = (l > 0 && self.header.levels[l - 1].residual).then_some(&mut self.decoded[l]);
        let ty = self.done[l] / TILE;
        self.coder.tile_row(&mut self.header, l, ty, &self.bands[l], band_rows, None, keep)?;
        self.done[l] += band_rows;
        if l + 1 < self.bands.len() {
            let parent_start = self.bands[l + 1].len();
            let (fine, coarse) = self.bands.split_at_mut(l + 1);
            halve_rows(&fine[l], level.width, band_rows, &mut coarse[0]);
            self.bands[l].clear();
            self.arrived(l + 1, parent_start)?;
        } else {
            self.bands[l].clear();
        }
        Ok(())
    }
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

/// One tile coded: its JPEG, where measured its squared error against the source, and where kept its
/// texels as decoded.
type Coded = (Vec<u8>, u64, Vec<u8>);

/// A residual tile row's parents: the decoded band of the level above (RGB8), its width in texels, and
/// the row of the doubled parent tiles the tile row starts at (0 or [`TILE`]).
type Parents<'a> = Option<((&'a [u8], u32), u32)>;

impl<W: Write + Seek> Coder<'_, W> {
    /// Codes tile row `ty` of level `l` from `band`, its `rows` rows (as residuals against `parents`
    /// where given), and records each tile in `header`; with `keep`, the row's texels as decoded land
    /// there. The row's tiles are coded on every core (`package::threads`), each thread a run of
    /// neighbours, and written in order: a tile's JPEG does not depend on which thread made it.
    #[expect(clippy::too_many_arguments, reason = "one tile row's inputs, all used")]
    fn tile_row(
        &mut self,
        header: &mut ImageryHeader,
        l: usize,
        ty: u32,
        band: &[u8],
        rows: u32,
        parents: Parents<'_>,
        keep: Option<&mut Vec<u8>>,
    ) -> Result<()> {
        let level: ImageryLevel = header.levels[l];
        let measure = self.measure && l == 0;
        let keeping = keep.is_some();
        let (quality, path) = (self.quality, self.path);
        let stride = level.width as usize * 3;
        let code = |tx: u32, scratch: &mut Vec<u8>| -> Result<Coded> {
            let tw = (level.width - tx * TILE).min(TILE);
            scratch.clear();
            for y in 0..rows as usize {
                let at = y * stride + (tx * TILE) as usize * 3;
                scratch.extend_from_slice(&band[at..at + tw as usize * 3]);
            }
            // The parent tile (tx / 2) within the decoded band above, and this tile's place in its
            // upsample.
            let parent = parents.map(|((texels, width), oy)| {
                let px = tx / 2 * TILE;
                let p = Parent {
                    texels: &texels[px as usize * 3..],
                    stride: width as usize,
                    width: (width - px).min(TILE),
                    height: u32::try_from(texels.len() / (width as usize * 3)).unwrap_or(0),
                };
                (p, (tx % 2) * TILE, oy)
            });
            if let Some((p, ox, oy)) = &parent {
                to_residual(p, *ox, *oy, tw, rows, scratch);
            }
            let q = if parent.is_some() {
                quality
            } else {
                super::imagery::whole_quality(quality)
            };
            let coded = encode_jpeg(path, scratch, tw, rows, q)?;
            let (mut sq, mut decoded) = (0, Vec::new());
            if measure || keeping {
                decoded.resize(scratch.len(), 0);
                decode_jpeg(path, &coded, tw, rows, &mut decoded)?;
                if let Some((p, ox, oy)) = &parent {
                    from_residual(p, *ox, *oy, tw, rows, &mut decoded);
                }
            }
            if measure {
                for (y, got) in decoded.chunks_exact(tw as usize * 3).enumerate() {
                    let at = y * stride + (tx * TILE) as usize * 3;
                    sq += band[at..at + got.len()]
                        .iter()
                        .zip(got)
                        .map(|(a, b)| u64::from(a.abs_diff(*b)).pow(2))
                        .sum::<u64>();
                }
            }
            if !keeping {
                decoded = Vec::new();
            }
            Ok((coded, sq, decoded))
        };
        let tiles: Vec<u32> = (0..level.tiles_x).collect();
        let per = tiles.len().div_ceil(super::threads()).max(1);
        let coded: Vec<Coded> = std::thread::scope(|s| {
            let handles: Vec<_> = tiles
                .chunks(per)
                .map(|run| {
                    s.spawn(move || {
                        let mut scratch = Vec::new();
                        run.iter()
                            .map(|&tx| code(tx, &mut scratch))
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
        let mut keep = keep;
        if let Some(k) = keep.as_deref_mut() {
            k.clear();
            k.resize(rows as usize * stride, 0);
        }
        for (tx, (jpeg, sq, decoded)) in (0..).zip(coded) {
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
            if let Some(k) = keep.as_deref_mut() {
                let row = decoded.len() / rows.max(1) as usize;
                for (y, got) in decoded.chunks_exact(row.max(1)).enumerate() {
                    let at = y * stride + (tx * TILE) as usize * 3;
                    k[at..at + got.len()].copy_from_slice(got);
                }
            }
        }
        Ok(())
    }
}
