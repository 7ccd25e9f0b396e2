//! Stage 1b, the package: validated reading of a `.clipsat` file through a memory map.
//!
//! [`Package::open`] checks the header (magic, version, checksum, dimensions, tile table inside the file);
//! [`Package::decode_tile`] checks a tile's CRC-32 before decoding it and its decoded length after. Any
//! mismatch is an [`Error::Format`] naming the file, the level and the tile.

use std::path::{Path, PathBuf};

use super::codec::{self, Decoder, Entropy, Predictor, TileScratch, U_BORDER};
use super::format::{CodecKind, Header};
use super::predict::LevelModel;
use super::rans::DecodeTables;
use super::set::{index_path, Index};
use crate::source::Heightmap;
use crate::{Error, Result};

/// An open package: the validated header and a read-only map of the file.
pub struct Package {
    path: PathBuf,
    header: Header,
    map: memmap2::Mmap,
    /// The rANS tables' lookup form (the `rans` codec).
    tables: Option<DecodeTables>,
    /// A package set's parts and top ([`super::set`]): `header` is then the whole terrain's, and `map`
    /// the index file's.
    set: Option<Box<Parts>>,
}

impl std::fmt::Debug for Package {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Package")
            .field("path", &self.path)
            .field("header", &self.header)
            .finish_non_exhaustive()
    }
}

/// Scratch for decoding tiles of one package without allocating: the byte-plane codec's state, U over a
/// tile and its border, the tile walk's buffers.
pub struct TileDecoder {
    decoder: Decoder,
    predictor: Predictor,
    u: Vec<i64>,
    tile: TileScratch,
    /// Whether each decode drops its payload's pages ([`Package::decode_tile`]); off for a sweep that
    /// drops the whole package's pages itself ([`TileDecoder::sweeping`]).
    trim_each: bool,
}

impl TileDecoder {
    /// This decoder for a reader that drops the package's pages itself every so often ([`Package::trim`]):
    /// its decodes leave their pages mapped. Each drop makes every core flush its address cache; one per
    /// decoded tile cost the LOD tables' bake on 2 cores about 0.3 CPU-seconds of a 16-tile mosaic's bake.
    pub(crate) fn sweeping(mut self) -> Self {
        self.trim_each = false;
        self
    }

    /// The byte size of this scratch for a package with tile side `tile` (for memory budgets).
    pub fn bytes(tile: u32) -> u64 {
        let t = u64::from(tile);
        let e = t + 2 * U_BORDER as u64;
        let p = e / 2 + 4;
        // Planes (4 B/sample), U with its border (8 B/sample), the predictor's gathered and row
        // scratch (8 B each), the tile walk's buffers.
        4 * t * t + 8 * e * e + 8 * p * p + 8 * p * e + TileScratch::bytes(tile)
    }
}

/// The coarse samples (x0, y0, x1, y1), end exclusive and not clamped, that decoding the fine tile at
/// (x0, y0) of size tw x th reads: the 4-point stencils of U over the tile and its border.
pub fn coarse_rect((x0, y0): (u32, u32), (tw, th): (u32, u32)) -> (i64, i64, i64, i64) {
    let b = U_BORDER as i64;
    let (x0, y0) = (i64::from(x0) - b, i64::from(y0) - b);
    let (w, h) = (i64::from(tw) + 2 * b, i64::from(th) + 2 * b);
    (
        (x0 >> 1) - 1,
        (y0 >> 1) - 1,
        (x0 >> 1) - 1 + w / 2 + 4,
        (y0 >> 1) - 1 + h / 2 + 4,
    )
}

/// True when `path` starts with the package magic (so any extension works, `.clipsat` by convention), or
/// is a package set's index or its folder ([`super::set`]).
pub fn is_package(path: &Path) -> bool {
    if super::set::is_set(path) {
        return true;
    }
    use std::io::Read;
    let mut magic = [0u8; 8];
    // Not a FIFO or device, which opening would wait on or read without end.
    path.is_file()
        && std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut magic))
        .is_ok_and(|()| magic == super::format::MAGIC)
}

impl Package {
    /// Maps and validates the package at `path`, or opens the package set whose index (or folder) it is.
    pub fn open(path: &Path) -> Result<Self> {
        Self::open_with(path, true)
    }

    /// [`Package::open`]; `lookup`: whether to build the rANS tables' lookup form (a set's parts share a
    /// few instead, `Parts::lookups`).
    fn open_with(path: &Path, lookup: bool) -> Result<Self> {
        if super::set::is_set(path) {
            let (header, parts) = Parts::open(path)?;
            let index = super::set::index_path(path);
            let file = std::fs::File::open(&index).map_err(|e| Error::io(&index, "cannot open", e))?;
            // SAFETY: as below, a read-only private map.
            let map = unsafe { memmap2::Mmap::map(&file) }
                .map_err(|e| Error::io(&index, "cannot map", e))?;
            return Ok(Self {
                path: path.to_path_buf(),
                header,
                map,
                tables: None,
                set: Some(Box::new(parts)),
            });
        }
        // A folder, a FIFO or a device is no package: mapping one fails obscurely, opening a FIFO waits.
        if !std::fs::metadata(path).map_err(|e| Error::io(path, "cannot open", e))?.is_file() {
            return Err(Error::format(path, "not a clipsat package: not a regular file"));
        }
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot open", e))?;
        let len = file
            .metadata()
            .map_err(|e| Error::io(path, "cannot read", e))?
            .len();
        // SAFETY: the map is read-only and private to this process; a file truncated underneath it by
        // another process is outside what any reader can defend against (the same holds for read(2)).
        let map =
            unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::io(path, "cannot map", e))?;
        if Header::peek_len(&map).is_none() {
            return Err(Error::format(
                path,
                "not a clipsat package (bad magic or shorter than its header)",
            ));
        }
        let header = Header::parse(path, &map, len)?;
        let tables = header
            .tables
            .as_ref()
            .filter(|_| lookup)
            .map(DecodeTables::new);
        Ok(Self {
            path: path.to_path_buf(),
            header,
            map,
            tables,
            set: None,
        })
    }

    /// The validated header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Bytes of the file.
    pub fn file_bytes(&self) -> u64 {
        self.set
            .as_ref()
            .map_or(self.map.len() as u64, |s| s.file_bytes())
    }


    /// Drops the mapped pages of bytes `offset .. offset + len` from this process's resident set
    /// ([`Package::trim`]). Best effort.
    fn trim_range(&self, offset: usize, len: usize) {
        crate::bake::mapped::drop_resident(&self.map, offset, len);
    }

    /// Drops the pages a read of bytes `offset .. offset + len` made resident
    /// ([`crate::bake::mapped::drop_read`]).
    fn trim_read(&self, offset: usize, len: usize) {
        crate::bake::mapped::drop_read(&self.map, offset, len);
    }

    /// Drops the package's mapped pages from this process's resident set (they stay in the kernel's page
    /// cache; the next read faults them back in, unchanged): a reader that sweeps the whole file, such as
    /// the LOD tables' bake, calls it as it goes so the file's pages do not add up. Best effort.
    pub fn trim(&self) {
        if let Some(s) = &self.set {
            s.trim();
        }
        self.trim_range(0, self.map.len());
    }

    /// Decoding scratch for this package's tiles (allocates once).
    pub fn tile_decoder(&self) -> Result<TileDecoder> {
        let t = self.header.tile as usize;
        let e = t + 2 * U_BORDER;
        Ok(TileDecoder {
            decoder: Decoder::new(self.header.codec, t * t)
                .map_err(|e| Error::io(&self.path, "cannot start the tile decoder", e))?,
            predictor: Predictor::new(self.header.tile + 2 * codec::U_BORDER_U32),
            u: vec![0; e * e],
            tile: TileScratch::new(self.header.tile),
            trim_each: true,
        })
    }

    /// Decodes tile (tx, ty) of `level` into `out` (tw * th heights in quantum units, row-major), with the
    /// coarser level's reconstructed heights from `coarse` (clamped to that level by the caller; it reads
    /// the coarse samples of [`coarse_rect`]; never called for the coarsest level). Allocation-free.
    pub fn decode_tile(
        &self,
        scratch: &mut TileDecoder,
        level: usize,
        (tx, ty): (u32, u32),
        coarse: impl Fn(i64, i64) -> i64,
        out: &mut [i32],
    ) -> Result<()> {
        match &self.set {
            Some(s) => s.decode_tile(scratch, level, (tx, ty), coarse, out),
            None => self.decode_own(scratch, level, (tx, ty), coarse, out),
        }
    }

    /// [`Package::decode_tile`] of this file's own tiles (a set's top, or a package).
    pub(super) fn decode_own(
        &self,
        scratch: &mut TileDecoder,
        level: usize,
        tile: (u32, u32),
        coarse: impl Fn(i64, i64) -> i64,
        out: &mut [i32],
    ) -> Result<()> {
        self.decode_with(self.tables.as_ref(), scratch, level, tile, coarse, out)
    }

    /// [`Package::decode_own`] with the rANS tables' lookup form `tables` (this file's own, or one a set
    /// shares among its parts).
    fn decode_with(
        &self,
        tables: Option<&DecodeTables>,
        scratch: &mut TileDecoder,
        level: usize,
        (tx, ty): (u32, u32),
        coarse: impl Fn(i64, i64) -> i64,
        out: &mut [i32],
    ) -> Result<()> {
        let bad = |reason: &str| {
            Error::format(
                &self.path,
                format!("level {level} tile ({tx}, {ty}): {reason}"),
            )
        };
        let entry = self
            .header
            .tile(level, tx, ty)
            .ok_or_else(|| bad("no such tile"))?;
        let (x0, y0, tw, th) = self.header.tile_rect(level, tx, ty);
        let n = tw as usize * th as usize;
        let out = out
            .get_mut(..n)
            .ok_or_else(|| bad("output smaller than the tile"))?;
        // The header validated offset + len against the file length.
        let start = usize::try_from(entry.offset).map_err(|_| bad("offset beyond memory"))?;
        let payload = &self.map[start..start + entry.len as usize];
        if crc32fast::hash(payload) != entry.crc {
            return Err(bad("checksum mismatch (damaged tile)"));
        }
        let (tw, th) = (tw as usize, th as usize);
        let (uw, uh) = (tw + 2 * U_BORDER, th + 2 * U_BORDER);
        let u = &mut scratch.u[..uw * uh];
        if level + 1 == self.header.levels.len() {
            // The coarsest level has no coarser one: U is 0, its neighbours predict it.
            u.fill(0);
        } else {
            let b = U_BORDER as i64;
            // A part's U stops short of the coarser level's last row and column (Header::part).
            let (rx, ry) = self.header.u_reach(level);
            scratch.predictor.predict(
                |i, j| coarse(i.min(rx), j.min(ry)),
                (i64::from(x0) - b, i64::from(y0) - b),
                (uw, uh),
                u,
            );
        }
        let entropy = match (tables, self.header.tables.is_some()) {
            (Some(t), _) => Entropy::Rans(t),
            (None, false) => Entropy::Planes(&mut scratch.decoder),
            (None, true) => unreachable!("a rans package decodes with its tables' lookup form"),
        };
        let decoded = codec::decode(
            &self.header.models[level],
            entropy,
            payload,
            u,
            (tw, th),
            &mut scratch.tile,
            out,
        )
        .map_err(bad);
        // The payload's pages leave the resident set once decoded (they stay in the kernel's page cache):
        // a long flight's decodes do not add the package's pages up.
        if scratch.trim_each {
            self.trim_read(start, entry.len as usize);
        }
        decoded
    }

    /// Decodes record tile (tx, ty) of data level `k`'s SAT LOD records ([`super::lod_tiles`]) into its
    /// max codes and mean codes (sized by the caller from [`super::lod_tiles::RecordGrid`]). A package
    /// without records, a checksum mismatch or a payload that does not decode to the tile's cells is an
    /// [`Error::Format`] naming the level and the tile.
    pub fn decode_record_tile(
        &self,
        dec: &mut super::codec::Decoder,
        k: u32,
        (tx, ty): (u32, u32),
        max: &mut [u8],
        mean: &mut [u8],
        scratch: &mut Vec<i32>,
    ) -> Result<()> {
        let bad = |reason: &str| {
            Error::format(
                &self.path,
                format!("LOD table level {k} tile ({tx}, {ty}): {reason}"),
            )
        };
        let lod = self
            .header
            .lod
            .as_ref()
            .ok_or_else(|| bad("the package has no LOD tables"))?;
        let lv = lod.level(k).ok_or_else(|| bad("no such level"))?;
        if !lv.stored {
            return Err(bad(
                "the level's records are derived from the heights, not stored",
            ));
        }
        let g = lv.grid;
        if tx >= g.tiles_x || ty >= g.tiles_y {
            return Err(bad("no such tile"));
        }
        let entry = lod.tiles[lv.first_tile + (ty * g.tiles_x + tx) as usize];
        // The header validated offset + len against the file length.
        let start = usize::try_from(entry.offset).map_err(|_| bad("offset beyond memory"))?;
        let payload = &self.map[start..start + entry.len as usize];
        if crc32fast::hash(payload) != entry.crc {
            return Err(bad("checksum mismatch (damaged tile)"));
        }
        let decoded = super::lod_tiles::decode_tile(dec, payload, max, mean, scratch);
        self.trim_read(start, entry.len as usize);
        decoded.map_err(bad)
    }

    /// Decodes the whole pyramid, coarse to fine, and returns level 0 in quantum units (allocates the
    /// terrain: for tools and tests, not for streaming).
    pub fn decode_level0(&self) -> Result<Vec<i32>> {
        self.decode_level(0)
    }

    /// Every level decoded, in metres, as the streamed rings read them (allocates the whole pyramid: a
    /// bake-time step, for the SAT LOD tables of a package).
    pub fn to_pyramid(&self) -> Result<crate::bake::pyramid::Pyramid> {
        let mut levels = Vec::with_capacity(self.header.levels.len());
        self.decode_levels(0, |lk, units| {
            let d = self.header.levels[lk];
            let m = units.iter().map(|&v| self.metres(v)).collect();
            levels.push((d.width, d.height, m));
        })?;
        levels.reverse();
        Ok(crate::bake::pyramid::Pyramid::from_levels(levels))
    }

    /// Decodes levels coarse to fine down to `stop` and returns that level in quantum units (allocates it).
    pub fn decode_level(&self, stop: usize) -> Result<Vec<i32>> {
        self.decode_levels(stop, |_, _| ())
    }

    /// [`Package::decode_level`], handing each level (coarse to fine) to `each` as it is decoded.
    fn decode_levels(&self, stop: usize, mut each: impl FnMut(usize, &[i32])) -> Result<Vec<i32>> {
        let mut scratch = self.tile_decoder()?;
        let levels = &self.header.levels;
        let mut coarse: Vec<i32> = Vec::new();
        let (mut cw, mut ch) = (0i64, 0i64);
        let mut tile = vec![0i32; self.header.tile as usize * self.header.tile as usize];
        for lk in (stop.min(levels.len() - 1)..levels.len()).rev() {
            let d = levels[lk];
            let mut level = vec![0i32; d.width as usize * d.height as usize];
            for ty in 0..d.tiles_y {
                for tx in 0..d.tiles_x {
                    let c = |a: i64, b: i64| -> i64 {
                        if cw == 0 {
                            return 0;
                        }
                        #[expect(
                            clippy::cast_possible_truncation,
                            reason = "clamped into the level"
                        )]
                        let idx = (b.clamp(0, ch - 1) * cw + a.clamp(0, cw - 1)) as usize;
                        i64::from(coarse[idx])
                    };
                    self.decode_tile(&mut scratch, lk, (tx, ty), c, &mut tile)?;
                    let (x0, y0, tw, th) = self.header.tile_rect(lk, tx, ty);
                    for (r, row) in tile[..(tw * th) as usize]
                        .chunks_exact(tw as usize)
                        .enumerate()
                    {
                        let at = (y0 as usize + r) * d.width as usize + x0 as usize;
                        level[at..at + tw as usize].copy_from_slice(row);
                    }
                }
            }
            each(lk, &level);
            coarse = level;
            (cw, ch) = (i64::from(d.width), i64::from(d.height));
        }
        Ok(coarse)
    }

    /// Height in metres of `k` quantum units, as every reader converts it.
    #[inline]
    pub fn metres(&self, k: i32) -> f32 {
        #[expect(clippy::cast_possible_truncation, reason = "heights are f32")]
        let h = (f64::from(k) * self.header.quantum) as f32;
        h
    }

    /// The finest level with at most `max_samples` samples as a [`Heightmap`] covering the same ground
    /// (spacing 2^k times the data's, its south-west corner placed so the rows line up with the data's):
    /// a bounded stand-in for the terrain where only its rough shape is needed (a camera path's clearance).
    pub fn coarse_heightmap(&self, max_samples: u64) -> Result<Heightmap> {
        let h = &self.header;
        let k = h
            .levels
            .iter()
            .position(|l| u64::from(l.width) * u64::from(l.height) <= max_samples)
            .unwrap_or(h.levels.len() - 1);
        let d = h.levels[k];
        let heights = self
            .decode_level(k)?
            .into_iter()
            .map(|v| self.metres(v))
            .collect();
        let scale = f64::from(1u32 << k);
        let spacing = f64::from(h.spacing) * scale;
        // Level row (height - 1) sits on data row (height - 1) 2^k, at or past the data's south edge.
        let south =
            (f64::from(d.height - 1) * scale - f64::from(h.height - 1)) * f64::from(h.spacing);
        #[expect(clippy::cast_possible_truncation, reason = "a spacing in metres")]
        let hm = Heightmap::new(&self.path, d.width, d.height, spacing as f32, heights)?;
        Ok(hm.with_origin(h.origin.0, h.origin.1 - south))
    }

    /// The decoded level 0 as a [`Heightmap`] (allocates the whole terrain; the non-streaming path).
    pub fn to_heightmap(&self) -> Result<Heightmap> {
        let k = self.decode_level0()?;
        let heights = k.into_iter().map(|v| self.metres(v)).collect();
        let h = &self.header;
        Ok(
            Heightmap::new(&self.path, h.width, h.height, h.spacing, heights)?
                .with_origin(h.origin.0, h.origin.1),
        )
    }
}

// A package set's parts, read as one package ([`super::set`]): here beside `Package`, which holds them.

/// An open set: its parts and top, and where each level's tiles are.
pub(super) struct Parts {
    /// Levels the parts hold (K + 1).
    part_levels: usize,
    /// Part column starts and part row starts, grid samples.
    columns: Vec<u32>,
    rows: Vec<u32>,
    tile: u32,
    parts: Vec<Package>,
    top: Package,
    /// The rANS tables' lookup form of the parts decoded last, [`LOOKUPS`] of them made at open and
    /// filled in place for the part a decode needs (`rans` sets; empty otherwise): a part's own would
    /// take 164 KiB each, 64 MiB for 400 parts.
    lookups: Vec<std::sync::Mutex<Lookup>>,
    /// Stamps the lookups' uses, for the least recently used.
    clock: std::sync::atomic::AtomicU64,
}

/// How many parts' lookup tables a set holds at once: a decoding thread's each and a few more (the tiles
/// a frame decodes lie in a few parts).
const LOOKUPS: usize = 12;

/// One shared lookup form: which part's tables it holds and when it was last used.
struct Lookup {
    part: Option<usize>,
    used: u64,
    tables: DecodeTables,
}

/// Where a tile of the set lies.
enum Route {
    /// Tile (tx, ty) of part `p`, whose origin at the coarser level is (cx, cy).
    Part {
        p: usize,
        tile: (u32, u32),
        coarse: (i64, i64),
    },
    /// The top's level.
    Top(usize),
}

impl Parts {
    /// Opens the set at `path` (an index or its folder): every part and the top, checked against the
    /// index and each other. Returns the whole terrain's header and the parts.
    pub(super) fn open(path: &Path) -> Result<(Header, Self)> {
        let index_file = index_path(path);
        let index = Index::read(&index_file)?;
        let dir = index_file.parent().unwrap_or(Path::new("."));
        let bad = |reason: String| Error::format(&index_file, format!("package set: {reason}"));
        let codec = CodecKind::parse(&index.codec)
            .map_err(|_| bad(format!("unknown tile codec `{}`", index.codec)))?;
        // The whole terrain's level sizes; its header, whose tile table grows with the grid the index
        // names, is made once every part has matched its cell (each part's table lies in its file).
        let sizes = super::format::level_sizes(index.width, index.height);
        let k = index.part_levels as usize - 1;
        if k + 1 >= sizes.len() {
            return Err(bad(format!(
                "parts of {} levels leave no level to a top over {} levels",
                index.part_levels,
                sizes.len()
            )));
        }
        let level_tile = u64::from(index.tile) << k;
        for &s in index.columns.iter().chain(&index.rows) {
            if u64::from(s) % level_tile != 0 {
                return Err(bad(format!(
                    "a part starts at {s}, not a multiple of {level_tile} (a level-{k} tile)"
                )));
            }
        }
        // A part or the top that names a set (this index, its folder) would open the set again, without
        // end: each is one package file.
        let file = |name: &str, what: &str| {
            let path = dir.join(name);
            if super::set::is_set(&path) {
                return Err(bad(format!(
                    "its {what} `{name}` is a package set's index or folder, not a package file"
                )));
            }
            Ok(path)
        };
        let top = Package::open(&file(&index.top, "top")?)?;
        let kd = sizes[k + 1];
        let th = top.header();
        if (th.width, th.height) != kd
            || th.levels.len() + k + 1 != sizes.len()
            || th.tile != index.tile
            || th.codec != codec
            || th.quantum.to_bits() != index.quantum.to_bits()
            || th.part != 0
        {
            return Err(Error::format(
                top.path(),
                format!(
                    "not this set's top: {} x {} in {} levels of {}-sample tiles, the set's level {} is \
                     {} x {} (bake the set again)",
                    th.width,
                    th.height,
                    th.levels.len(),
                    th.tile,
                    k + 1,
                    kd.0,
                    kd.1
                ),
            ));
        }
        let mut parts = Vec::with_capacity(index.parts.len());
        let mut range = (f32::INFINITY, f32::NEG_INFINITY);
        for (n, entry) in index.parts.iter().enumerate() {
            let (i, j) = (n % index.columns.len(), n / index.columns.len());
            let (x0, y0, x1, y1) = index.cell(i, j);
            // Another cell's part of the same size would read as this one's, wrong samples and no error.
            let own = super::set::part_file((x0, y0), &entry.key);
            if entry.file != own {
                return Err(bad(format!(
                    "part ({i}, {j}) is `{}`, not its cell's `{own}` (bake the set again)",
                    entry.file
                )));
            }
            let p = Package::open_with(&file(&entry.file, "part")?, false)?;
            let h = p.header();
            if !index.fits_part(n, h, codec) {
                return Err(Error::format(
                    p.path(),
                    format!(
                        "not part ({i}, {j}) of this set: {} x {} samples, {} levels (part {}), expected \
                         {} x {}, {} levels (bake the set again)",
                        h.width,
                        h.height,
                        h.levels.len(),
                        h.part,
                        x1 - x0 + 1,
                        y1 - y0 + 1,
                        index.part_levels
                    ),
                ));
            }
            range = (range.0.min(h.range.0), range.1.max(h.range.1));
            parts.push(p);
        }
        let mut world = Header::new(
            index.width,
            index.height,
            index.spacing,
            index.origin,
            index.quantum,
            codec,
            index.tile,
        );
        world.max_error = index.max_error;
        // Each part's header and tile table, the top, and the shared lookups (not a part's own).
        let lookups: Vec<_> = match top.header().tables.as_ref() {
            Some(t) => (0..LOOKUPS)
                .map(|_| {
                    std::sync::Mutex::new(Lookup {
                        part: None,
                        used: 0,
                        tables: DecodeTables::new(t),
                    })
                })
                .collect(),
            None => Vec::new(),
        };
        let own = |p: &Package| {
            let h = p.header();
            h.resident_bytes() - u64::from(h.tables.is_some()) * DecodeTables::BYTES
        };
        world.set_bytes = parts.iter().map(own).sum::<u64>()
            + top.header().resident_bytes()
            + lookups.len() as u64 * DecodeTables::BYTES;
        world.range = range;
        world.models = (0..world.levels.len())
            .map(|l| {
                if l <= k {
                    LevelModel::plain(parts[0].header().models[l].step)
                } else {
                    th.models[l - k - 1].clone()
                }
            })
            .collect();
        let set = Self {
            part_levels: k + 1,
            columns: index.columns,
            rows: index.rows,
            tile: index.tile,
            parts,
            top,
            lookups,
            clock: std::sync::atomic::AtomicU64::new(0),
        };
        for (l, d) in world.levels.clone().iter().enumerate() {
            for ty in 0..d.tiles_y {
                for tx in 0..d.tiles_x {
                    let entry = match set.route(l, tx, ty) {
                        Route::Part { p, tile, .. } => set.parts[p].header().tile(l, tile.0, tile.1),
                        Route::Top(j) => set.top.header().tile(j, tx, ty),
                    };
                    world.tiles[d.first_tile + (ty * d.tiles_x + tx) as usize] = entry
                        .ok_or_else(|| bad(format!("level {l} tile ({tx}, {ty}) is in no part")))?;
                }
            }
        }
        Ok((world, set))
    }

    /// The part or top level that holds tile (tx, ty) of `level`.
    fn route(&self, level: usize, tx: u32, ty: u32) -> Route {
        if level >= self.part_levels {
            return Route::Top(level - self.part_levels);
        }
        let t = u64::from(self.tile) << level;
        // The last part whose first tile is at or before the tile's.
        let find = |starts: &[u32], at: u32| {
            starts
                .partition_point(|&s| u64::from(s) / t <= u64::from(at))
                .saturating_sub(1)
        };
        let (i, j) = (find(&self.columns, tx), find(&self.rows, ty));
        #[expect(clippy::cast_possible_truncation, reason = "a tile index under the level's")]
        let (fx, fy) = (
            (u64::from(self.columns[i]) / t) as u32,
            (u64::from(self.rows[j]) / t) as u32,
        );
        let shift = level + 1;
        Route::Part {
            p: j * self.columns.len() + i,
            tile: (tx - fx, ty - fy),
            coarse: (
                i64::from(self.columns[i] >> shift),
                i64::from(self.rows[j] >> shift),
            ),
        }
    }

    /// [`Package::decode_tile`] of the set: the tile decoded by its part (its coarser level read from
    /// the whole terrain's, at the part's place) or by the top.
    pub(super) fn decode_tile(
        &self,
        scratch: &mut TileDecoder,
        level: usize,
        (tx, ty): (u32, u32),
        coarse: impl Fn(i64, i64) -> i64,
        out: &mut [i32],
    ) -> Result<()> {
        match self.route(level, tx, ty) {
            Route::Top(j) => self.top.decode_own(scratch, j, (tx, ty), coarse, out),
            Route::Part {
                p,
                tile,
                coarse: (cx, cy),
            } => {
                let part = &self.parts[p];
                let coarse = |i: i64, j: i64| coarse(cx + i.max(0), cy + j.max(0));
                match part.header().tables.as_ref() {
                    None => part.decode_with(None, scratch, level, tile, coarse, out),
                    Some(t) => {
                        let lookup = self.lookup(p, t);
                        part.decode_with(Some(&lookup.tables), scratch, level, tile, coarse, out)
                    }
                }
            }
        }
    }

    /// A shared lookup holding part `p`'s tables `t`, locked for the caller: one that holds them already
    /// and is free, else the free one used least recently, filled with them (in place), else (every one
    /// busy) the one `p` falls to, once free.
    fn lookup(&self, p: usize, t: &super::rans::Tables) -> std::sync::MutexGuard<'_, Lookup> {
        use std::sync::atomic::Ordering;
        use std::sync::{PoisonError, TryLockError};
        let now = self.clock.fetch_add(1, Ordering::Relaxed);
        fn try_lock(m: &std::sync::Mutex<Lookup>) -> Option<std::sync::MutexGuard<'_, Lookup>> {
            match m.try_lock() {
                Ok(g) => Some(g),
                Err(TryLockError::Poisoned(e)) => Some(e.into_inner()),
                Err(TryLockError::WouldBlock) => None,
            }
        }
        let mut best: Option<std::sync::MutexGuard<'_, Lookup>> = None;
        for m in &self.lookups {
            let Some(g) = try_lock(m) else { continue };
            if g.part == Some(p) {
                let mut g = g;
                g.used = now;
                return g;
            }
            if best.as_ref().is_none_or(|b| g.used < b.used) {
                best = Some(g);
            }
        }
        let mut g = best.unwrap_or_else(|| {
            self.lookups[p % self.lookups.len()]
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
        });
        if g.part != Some(p) {
            g.tables.fill(t);
            g.part = Some(p);
        }
        g.used = now;
        g
    }

    /// Bytes of every file of the set.
    pub(super) fn file_bytes(&self) -> u64 {
        self.parts
            .iter()
            .chain(std::iter::once(&self.top))
            .map(Package::file_bytes)
            .sum()
    }

    /// [`Package::trim`] of every file.
    pub(super) fn trim(&self) {
        for p in self.parts.iter().chain(std::iter::once(&self.top)) {
            p.trim();
        }
    }
}
