//! Stage 1b, the package: the imagery package, a companion of the terrain package that holds the colour
//! pyramid (`bake::imagery`) in tiles, each coded as a baseline JPEG (4:4:4, optimised Huffman tables,
//! quality [`DEFAULT_QUALITY`] for residual tiles and [`whole_quality`] of it for whole ones) with a
//! CRC-32, behind a checksummed header.
//!
//! The levels alternate: odd levels and the coarsest are stored whole ("intra"); every other even level
//! is stored as a residual against the level above, a Laplacian pyramid (Burt & Adelson 1983) closed on
//! the decoded parent like GC's compressed pyramid (Losasso & Hoppe 2004, section 7): a tile holds
//! `clamp(texel - up(parent) + 128, 0, 255)`, where `up` is the integer bilinear upsample of the one
//! decoded parent tile above it (`bake::imagery::up_at`). A residual tile so costs at most two JPEG
//! decodes, and the bake stays one pass (`imagery_bake.rs`). The format was chosen by measurement
//! (docs/guide.md "The imagery package"): qualities 75 and 80 take 7-8 % fewer bytes per texel than a
//! whole-image JPEG at quality 90 (4:2:0), all levels counted, at half a dB more, on both shared images.
//!
//! Layout, little-endian: magic `CSIMAGE\0`, version (u32), quality (u32), tile side (u32), level-0
//! width and height (u32), extent (4 x f64: west, south, east, north), source key (u64), level count
//! (u32), each level's width, height and kind (u32: 0 whole, 1 residual), each tile's offset (u64),
//! length and CRC-32 (u32), levels finest first and tiles row-major; then the header's CRC-32 (u32);
//! then the tiles.

use std::io::Cursor;
use std::path::{Path, PathBuf};

use image::ImageDecoder as _;

use super::format::{Reader, TileEntry};
use crate::bake::imagery::{from_residual, level_count, level_sizes, Parent};
use crate::source::imagery::Extent;
use crate::{Error, Result};

/// The file's first eight bytes.
pub const MAGIC: &[u8; 8] = b"CSIMAGE\0";
/// The format version this build writes and reads (1: every level whole, quality 80).
pub const VERSION: u32 = 2;
/// Texels on a side of a tile.
pub const TILE: u32 = 256;
/// The JPEG quality of the residual tiles (4:4:4): the measured choice, see the module's notes.
pub const DEFAULT_QUALITY: u8 = 75;
/// How much higher the whole levels' quality is than the residuals': a whole level is drawn and also
/// predicts the level below it, so its bits pay twice (docs/guide.md "Imagery").
pub const WHOLE_QUALITY_STEP: u8 = 5;

/// The quality of the whole levels' tiles for residual tiles at `quality`.
pub fn whole_quality(quality: u8) -> u8 {
    quality.saturating_add(WHOLE_QUALITY_STEP).min(100)
}
/// Bytes before the per-level table.
const FIXED: usize = 8 + 4 + 4 + 4 + 4 + 4 + 4 * 8 + 8 + 4;
/// Bytes of one tile entry.
const TILE_ENTRY: usize = 16;
/// Bytes of one level's entry: width, height, kind.
const LEVEL_ENTRY: usize = 12;

/// One level of the pyramid in the package.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ImageryLevel {
    /// Texel columns.
    pub width: u32,
    /// Texel rows.
    pub height: u32,
    /// Tiles per row.
    pub tiles_x: u32,
    /// Tile rows.
    pub tiles_y: u32,
    /// Index of the level's first tile in the tile table.
    pub first_tile: usize,
    /// Stored as residuals against the next coarser level (which is stored whole).
    pub residual: bool,
}

/// An imagery package's header.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageryHeader {
    /// JPEG quality of the residual tiles (the whole ones' is [`whole_quality`] of it).
    pub quality: u32,
    /// Tile side, texels.
    pub tile: u32,
    /// Level-0 texel columns.
    pub width: u32,
    /// Level-0 texel rows.
    pub height: u32,
    /// Where level 0 lies in the terrain's world frame (pixel-is-area).
    pub extent: Extent,
    /// The key of what it was baked from (the cache's name for it).
    pub key: u64,
    /// The levels, finest first.
    pub levels: Vec<ImageryLevel>,
    /// Every tile's place in the file and checksum.
    pub tiles: Vec<TileEntry>,
}

impl ImageryHeader {
    /// Bytes of the header, its CRC included.
    pub fn byte_len(&self) -> usize {
        FIXED + LEVEL_ENTRY * self.levels.len() + TILE_ENTRY * self.tiles.len() + 4
    }

    /// Metres per texel of `level` (east-west, north-south): level 0's doubled per level.
    pub fn texel_spacing(&self, level: usize) -> (f64, f64) {
        let (w, h) = self.extent.size();
        let scale = f64::from(1u32 << level.min(31));
        (
            w / f64::from(self.width) * scale,
            h / f64::from(self.height) * scale,
        )
    }

    /// Level-0 texels.
    pub fn texels(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }

    /// Bytes of the tiles.
    pub fn tile_bytes(&self) -> u64 {
        self.tiles.iter().map(|t| u64::from(t.len)).sum()
    }

    /// Whether any level is stored as residuals.
    pub fn has_residuals(&self) -> bool {
        self.levels.iter().any(|l| l.residual)
    }

    /// The levels and tile table of a pyramid over `width` x `height` texels, offsets left at 0: even
    /// levels but the coarsest are residuals.
    pub(super) fn layout(width: u32, height: u32, tile: u32) -> (Vec<ImageryLevel>, usize) {
        let mut first_tile = 0;
        let sizes = level_sizes(width, height);
        let count = sizes.len();
        let levels = sizes
            .into_iter()
            .enumerate()
            .map(|(i, (w, h))| {
                let l = ImageryLevel {
                    width: w,
                    height: h,
                    tiles_x: w.div_ceil(tile),
                    tiles_y: h.div_ceil(tile),
                    first_tile,
                    residual: i % 2 == 0 && i + 1 < count,
                };
                first_tile += l.tiles_x as usize * l.tiles_y as usize;
                l
            })
            .collect();
        (levels, first_tile)
    }

    pub(super) fn write(&self, out: &mut Vec<u8>) {
        let start = out.len();
        out.extend_from_slice(MAGIC);
        for v in [VERSION, self.quality, self.tile, self.width, self.height] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for v in self.extent.to_array() {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&self.key.to_le_bytes());
        let count = u32::try_from(self.levels.len()).unwrap_or(u32::MAX);
        out.extend_from_slice(&count.to_le_bytes());
        for l in &self.levels {
            out.extend_from_slice(&l.width.to_le_bytes());
            out.extend_from_slice(&l.height.to_le_bytes());
            out.extend_from_slice(&u32::from(l.residual).to_le_bytes());
        }
        for t in &self.tiles {
            out.extend_from_slice(&t.offset.to_le_bytes());
            out.extend_from_slice(&t.len.to_le_bytes());
            out.extend_from_slice(&t.crc.to_le_bytes());
        }
        let crc = crc32fast::hash(&out[start..]);
        out.extend_from_slice(&crc.to_le_bytes());
    }

    /// Parses and checks a header at the start of `bytes` (a file of `bytes.len()` bytes).
    fn parse(path: &Path, bytes: &[u8]) -> Result<Self> {
        let bad = |reason: String| Error::format(path, format!("imagery package: {reason}"));
        let mut r = Reader { bytes, at: 0 };
        if r.take(8).ok_or_else(|| bad("truncated".into()))? != MAGIC {
            return Err(bad("not an imagery package (wrong magic)".into()));
        }
        let mut u32s = [0u32; 5];
        for v in &mut u32s {
            *v = r.u32().ok_or_else(|| bad("truncated header".into()))?;
        }
        let [version, quality, tile, width, height] = u32s;
        if version != VERSION {
            return Err(bad(format!(
                "format version {version}, this build reads {VERSION}: bake it again"
            )));
        }
        if !(16..=4096).contains(&tile) || width < 2 || height < 2 {
            return Err(bad(format!(
                "tile {tile}, size {width} x {height} are out of range"
            )));
        }
        let mut e = [0f64; 4];
        for v in &mut e {
            *v = r.f64().ok_or_else(|| bad("truncated header".into()))?;
        }
        let extent =
            Extent::new(e[0], e[1], e[2], e[3]).map_err(|err| bad(format!("extent: {err}")))?;
        let key = r.u64().ok_or_else(|| bad("truncated header".into()))?;
        let count = r.u32().ok_or_else(|| bad("truncated header".into()))?;
        if count != level_count(width, height) {
            return Err(bad(format!(
                "{count} levels, a pyramid over {width} x {height} has {}",
                level_count(width, height)
            )));
        }
        let (levels, tile_count) = Self::layout(width, height, tile);
        for l in &levels {
            let (w, h, kind) = (r.u32(), r.u32(), r.u32());
            if (w, h) != (Some(l.width), Some(l.height)) {
                return Err(bad("level sizes do not follow the pyramid".into()));
            }
            // A residual level's parent is stored whole, so a tile takes at most two decodes.
            if kind != Some(u32::from(l.residual)) {
                return Err(bad(
                    "level kinds do not alternate as this build reads them".into(),
                ));
            }
        }
        let table_end = FIXED + LEVEL_ENTRY * levels.len() + TILE_ENTRY * tile_count + 4;
        if bytes.len() < table_end {
            return Err(bad(format!(
                "truncated: {} bytes, the header alone takes {table_end}",
                bytes.len()
            )));
        }
        let mut tiles = Vec::with_capacity(tile_count);
        for i in 0..tile_count {
            let t = TileEntry {
                offset: r.u64().ok_or_else(|| bad("truncated tile table".into()))?,
                len: r.u32().ok_or_else(|| bad("truncated tile table".into()))?,
                crc: r.u32().ok_or_else(|| bad("truncated tile table".into()))?,
            };
            let end = t.offset.checked_add(u64::from(t.len));
            if t.offset < table_end as u64 || end.is_none_or(|e| e > bytes.len() as u64) {
                return Err(bad(format!("tile {i} lies outside the file (truncated?)")));
            }
            tiles.push(t);
        }
        let crc = r.u32().ok_or_else(|| bad("truncated header".into()))?;
        if crc != crc32fast::hash(&bytes[..table_end - 4]) {
            return Err(bad("header checksum mismatch (damaged file)".into()));
        }
        Ok(Self {
            quality,
            tile,
            width,
            height,
            extent,
            key,
            levels,
            tiles,
        })
    }
}

/// What a bake wrote and how close it is to the source.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ImageryBakeReport {
    /// Bytes of the package.
    pub bytes: u64,
    /// Level-0 texels.
    pub texels: u64,
    /// Levels of the pyramid.
    pub levels: u32,
    /// Tiles of all levels.
    pub tiles: u32,
    /// Bytes of level 0's tiles per level-0 texel.
    pub level0_bytes_per_texel: f64,
    /// Bytes of the whole package per level-0 texel (the coarser levels add about a third).
    pub bytes_per_texel: f64,
    /// PSNR of level 0 decoded against the source, over RGB, dB.
    pub psnr_db: f64,
}

/// PSNR in dB of a sum of squared 8-bit errors over `n` values (infinite when exact).
pub fn psnr(sq_err: u64, n: u64) -> f64 {
    #[expect(clippy::cast_precision_loss, reason = "a measurement")]
    let mse = sq_err as f64 / n.max(1) as f64;
    10.0 * (255.0f64 * 255.0 / mse).log10()
}

/// Texels (columns, rows) of tile (tx, ty) of a level: `tile` but at the east and south edges.
fn tile_size(l: &ImageryLevel, tile: u32, tx: u32, ty: u32) -> (u32, u32) {
    (
        (l.width - tx * tile).min(tile),
        (l.height - ty * tile).min(tile),
    )
}

/// Codes `w` x `h` RGB8 texels (packed rows) as a baseline JPEG at `quality`: 4:4:4, Huffman tables
/// optimised for the tile (the `jpeg-encoder` crate; measured in docs/guide.md "The imagery package"),
/// checked by decoding it as the runtime does (`decode_jpeg`, zune-jpeg): where a block's mean colour
/// comes back more than `BLOCK_MEAN_SLACK` levels from the texels', the tile is coded again with the
/// standard tables. zune-jpeg 0.5 misreads some streams of optimised tables whose blocks are nearly all
/// one colour: a uniform tile of 9 to 176 texels a side, and a uniform residual tile, decoded from its
/// second or a later row of blocks on as (133, 0, 0) for (220, 30, 30), which other decoders read right
/// (land-cover classes, water, a scene's no-data collar; `tests/cpu/imagery_small.rs`).
pub fn encode_jpeg(path: &Path, texels: &[u8], w: u32, h: u32, quality: u8) -> Result<Vec<u8>> {
    if texels.len() as u64 != u64::from(w) * u64::from(h) * 3 {
        return Err(Error::format(
            path,
            format!("JPEG encoder: {} bytes for {w} x {h} RGB texels", texels.len()),
        ));
    }
    let coded = encode_jpeg_tables(path, texels, w, h, quality, true)?;
    let mut decoded = vec![0u8; texels.len()];
    if decode_jpeg(path, &coded, w, h, &mut decoded).is_ok()
        && max_block_mean_error(texels, &decoded, w, h) <= BLOCK_MEAN_SLACK
    {
        return Ok(coded);
    }
    let coded = encode_jpeg_tables(path, texels, w, h, quality, false)?;
    decode_jpeg(path, &coded, w, h, &mut decoded)?;
    let off = max_block_mean_error(texels, &decoded, w, h);
    if off > BLOCK_MEAN_SLACK {
        return Err(Error::format(
            path,
            format!(
                "imagery tile of {w} x {h}: the JPEG decoder reads a block {off} levels from what was \
                 coded, with optimised and with standard Huffman tables"
            ),
        ));
    }
    Ok(coded)
}

/// Names how a package's tiles are coded, in the cache key of a package baked from a file
/// (`engine::terrain`): packages baked before [`encode_jpeg`] checked its tiles against the decoder are
/// baked again. (How the file is read is `source::READ_REVISION`, in the same key.)
pub(crate) const TILE_CODER: &str = "tiles checked by decoding";

/// Levels by which an 8 x 8 block's mean colour may come back from [`encode_jpeg`]'s check: the DC
/// term's quantisation moves it by under a level at the qualities used (steps of 8 to 9 at quality 75, to
/// 4 at 100 where the whole levels are coded 5 steps above) and clamping the ringing of a hard edge
/// moves it by a few; a misread stream moved it by 87 (`tests/cpu/imagery_small.rs`). A block past it
/// only costs the tile its optimised tables.
const BLOCK_MEAN_SLACK: u32 = 16;

/// The largest difference, in levels, between the mean colours (per channel) of an 8 x 8 block (cut at
/// the tile's edge) of `a` and `b`, two `w` x `h` RGB8 images.
fn max_block_mean_error(a: &[u8], b: &[u8], w: u32, h: u32) -> u32 {
    let (w, h) = (w as usize, h as usize);
    let mut worst = 0u32;
    for by in (0..h).step_by(8) {
        for bx in (0..w).step_by(8) {
            let mut sums = [0i64; 3];
            let mut n = 0i64;
            for y in by..(by + 8).min(h) {
                for x in bx..(bx + 8).min(w) {
                    let at = (y * w + x) * 3;
                    for (c, sum) in sums.iter_mut().enumerate() {
                        *sum += i64::from(a[at + c]) - i64::from(b[at + c]);
                    }
                    n += 1;
                }
            }
            for sum in sums {
                let off = u32::try_from(sum.unsigned_abs().div_ceil(n.unsigned_abs().max(1))).unwrap_or(u32::MAX);
                worst = worst.max(off);
            }
        }
    }
    worst
}

/// [`encode_jpeg`]'s coding, with Huffman tables optimised for the tile or the standard ones.
fn encode_jpeg_tables(
    path: &Path,
    texels: &[u8],
    w: u32,
    h: u32,
    quality: u8,
    optimised: bool,
) -> Result<Vec<u8>> {
    let bad = |e: String| Error::format(path, format!("JPEG encoder: {e}"));
    let (Ok(w16), Ok(h16)) = (u16::try_from(w), u16::try_from(h)) else {
        return Err(bad(format!("a tile of {w} x {h} texels")));
    };
    let mut coded = Vec::new();
    let mut e = jpeg_encoder::Encoder::new(&mut coded, quality);
    e.set_sampling_factor(jpeg_encoder::SamplingFactor::F_1_1);
    e.set_optimized_huffman_tables(optimised);
    e.encode(texels, w16, h16, jpeg_encoder::ColorType::Rgb)
        .map_err(|err| bad(err.to_string()))?;
    Ok(coded)
}

/// Decodes a JPEG tile of `w` x `h` RGB texels into `out` (`w * h * 3` bytes).
pub(super) fn decode_jpeg(path: &Path, coded: &[u8], w: u32, h: u32, out: &mut [u8]) -> Result<()> {
    let bad = |e: String| {
        Error::format(
            path,
            format!("imagery tile: {}", crate::source::imagery::one_line(&e)),
        )
    };
    let d = image::codecs::jpeg::JpegDecoder::new(Cursor::new(coded)).map_err(|e| bad(e.to_string()))?;
    if d.dimensions() != (w, h) || d.color_type() != image::ColorType::Rgb8 {
        return Err(bad(format!(
            "holds {:?} {} x {}, the header says RGB {w} x {h}",
            d.color_type(),
            d.dimensions().0,
            d.dimensions().1
        )));
    }
    d.read_image(out).map_err(|e| bad(e.to_string()))
}

/// The package's bytes: a memory map of its file, or bytes baked in memory.
enum Store {
    Mapped(memmap2::Mmap),
    Owned(Vec<u8>),
}

impl std::ops::Deref for Store {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        match self {
            Self::Mapped(m) => m,
            Self::Owned(v) => v,
        }
    }
}

/// An imagery package, checked and ready to decode tiles from.
pub struct ImageryPackage {
    path: PathBuf,
    store: Store,
    header: ImageryHeader,
}

impl std::fmt::Debug for ImageryPackage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ImageryPackage")
            .field("path", &self.path)
            .field("header", &self.header)
            .finish_non_exhaustive()
    }
}

impl ImageryPackage {
    /// Opens and checks the imagery package at `path` (mapped, not read whole; a decoded tile's pages are
    /// dropped from the resident set).
    pub fn open(path: &Path) -> Result<Self> {
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot read", e))?;
        // SAFETY: the cache writes packages under a private name and renames them into place, so a
        // mapped file is never written; a file truncated by another program is caught by the checks of
        // the header (sizes) and of each tile (CRC) before its bytes are used.
        let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::io(path, "cannot map", e))?;
        let header = ImageryHeader::parse(path, &map)?;
        Ok(Self {
            path: path.to_path_buf(),
            store: Store::Mapped(map),
            header,
        })
    }

    /// A package from bytes in memory (`imagery_bake::bake_imagery`'s), checked as
    /// [`ImageryPackage::open`] checks a file; `path` names it in errors.
    pub fn from_bytes(path: &Path, bytes: Vec<u8>) -> Result<Self> {
        let header = ImageryHeader::parse(path, &bytes)?;
        Ok(Self {
            path: path.to_path_buf(),
            store: Store::Owned(bytes),
            header,
        })
    }

    /// Whether `path` starts with the imagery package's magic.
    pub fn is_imagery_package(path: &Path) -> bool {
        use std::io::Read as _;
        let mut magic = [0u8; 8];
        // Not a FIFO or device, which opening would wait on or read without end.
        path.is_file()
            && std::fs::File::open(path)
                .and_then(|mut f| f.read_exact(&mut magic))
                .is_ok()
            && &magic == MAGIC
    }

    /// The file it was opened from (or the name given to bytes in memory).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The checked header.
    pub fn header(&self) -> &ImageryHeader {
        &self.header
    }

    /// Bytes of the package.
    pub fn len(&self) -> u64 {
        self.store.len() as u64
    }

    /// Whether it holds no bytes (never: a checked package has a header).
    pub fn is_empty(&self) -> bool {
        self.store.is_empty()
    }

    /// The texels (columns, rows) of tile (tx, ty) of `level`, or `None` for a tile it does not hold.
    pub fn tile_size(&self, level: usize, tx: u32, ty: u32) -> Option<(u32, u32)> {
        let l = self.header.levels.get(level)?;
        (tx < l.tiles_x && ty < l.tiles_y).then(|| tile_size(l, self.header.tile, tx, ty))
    }

    /// The tile a residual tile (tx, ty) of `level` is predicted from: (level + 1, tx / 2, ty / 2);
    /// `None` for a tile stored whole.
    pub fn parent_of(&self, level: usize, tx: u32, ty: u32) -> Option<(usize, u32, u32)> {
        let l = self.header.levels.get(level)?;
        l.residual.then_some((level + 1, tx / 2, ty / 2))
    }

    /// Turns the decoded residuals of tile (tx, ty) of a residual `level` in `texels` (RGB8, its
    /// `w * h * 3` bytes) into the level's texels, predicted from `parent` (its parent tile's RGB8 as
    /// decoded, [`ImageryPackage::parent_of`]).
    pub fn add_prediction(&self, level: usize, tx: u32, ty: u32, parent: &[u8], texels: &mut [u8]) -> Result<()> {
        let Some(((pl, ptx, pty), (w, h))) = self.parent_of(level, tx, ty).zip(self.tile_size(level, tx, ty)) else {
            return Err(Error::Invalid {
                what: format!("imagery tile {level}/{tx}/{ty}"),
                reason: "not a residual tile of the package".into(),
            });
        };
        let Some((pw, ph)) = self.tile_size(pl, ptx, pty) else {
            return Err(Error::format(&self.path, format!("imagery tile {level}/{tx}/{ty}: no parent tile")));
        };
        let (n, pn) = (w as usize * h as usize * 3, pw as usize * ph as usize * 3);
        let (Some(texels), Some(parent)) = (texels.get_mut(..n), parent.get(..pn)) else {
            return Err(Error::Capacity { what: "imagery tile buffer", capacity: texels.len().min(parent.len()) });
        };
        let t = self.header.tile;
        let p = Parent { texels: parent, stride: pw as usize, width: pw, height: ph };
        from_residual(&p, (tx % 2) * t, (ty % 2) * t, w, h, texels);
        Ok(())
    }

    /// Decodes tile (tx, ty) of `level` into the level's texels (RGB8, as [`ImageryPackage::decode_tile`]):
    /// a residual tile's parent decoded into `parent` (a tile's RGB8 bytes) and the prediction added. For
    /// whole decodes outside the tile cache (a rebuilt texture, the CPU twin, the tests).
    pub fn decode_texels(
        &self,
        level: usize,
        tx: u32,
        ty: u32,
        out: &mut [u8],
        parent: &mut [u8],
    ) -> Result<(u32, u32)> {
        let size = self.decode_tile(level, tx, ty, out)?;
        if let Some((pl, ptx, pty)) = self.parent_of(level, tx, ty) {
            self.decode_tile(pl, ptx, pty, parent)?;
            self.add_prediction(level, tx, ty, parent, out)?;
        }
        Ok(size)
    }

    /// Decodes tile (tx, ty) of `level` as stored (a residual level's residuals) into `out` (RGB8,
    /// row-major, at least `w * h * 3` bytes) after checking its CRC; returns its size. Damage is an
    /// error naming the tile.
    pub fn decode_tile(&self, level: usize, tx: u32, ty: u32, out: &mut [u8]) -> Result<(u32, u32)> {
        let Some((w, h)) = self.tile_size(level, tx, ty) else {
            return Err(Error::Invalid {
                what: format!("imagery tile {level}/{tx}/{ty}"),
                reason: "not in the package".into(),
            });
        };
        let l = &self.header.levels[level];
        let entry = self.header.tiles[l.first_tile + (ty * l.tiles_x + tx) as usize];
        #[expect(
            clippy::cast_possible_truncation,
            reason = "checked against the file's length when the header was parsed"
        )]
        let coded = &self.store[entry.offset as usize..(entry.offset + u64::from(entry.len)) as usize];
        if crc32fast::hash(coded) != entry.crc {
            return Err(Error::format(
                &self.path,
                format!("imagery tile {level}/{tx}/{ty}: checksum mismatch (damaged file)"),
            ));
        }
        let n = w as usize * h as usize * 3;
        let Some(out) = out.get_mut(..n) else {
            return Err(Error::Capacity {
                what: "imagery tile buffer",
                capacity: out.len(),
            });
        };
        decode_jpeg(&self.path, coded, w, h, out).map_err(|e| match e {
            Error::Format { path, reason } => Error::Format {
                path,
                reason: format!("{reason} (tile {level}/{tx}/{ty})"),
            },
            other => other,
        })?;
        // The tile's pages leave this process's resident set (they stay in the kernel's page cache), so
        // a long flight over a large image holds no more of its file than the tile cache's budget.
        if let Store::Mapped(map) = &self.store {
            #[expect(clippy::cast_possible_truncation, reason = "within the map, as above")]
            crate::bake::mapped::drop_read(map, entry.offset as usize, entry.len as usize);
        }
        Ok((w, h))
    }
}
