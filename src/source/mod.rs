//! Stage 0, the source: terrain files and the built-in procedural terrain, all turned into a [`Heightmap`].
//!
//! Every loader checks sizes against [`LoadOptions::max_samples`] before it allocates, and names the file
//! and the problem in its error; none panics on any input.

use std::fmt;
use std::path::{Path, PathBuf};

use crate::{Error, Result};

/// The georeference of the heights at `path`, for placing GeoTIFF imagery by it (docs/guide.md
/// "Imagery"): a GeoTIFF's own tags, an SRTM `.hgt` tile's from its name and size, a tile mosaic's grid;
/// `None` for heights without one (PNG, raw, a package, a procedural terrain).
pub fn heights_georef(path: &Path) -> Option<georef::GeoRef> {
    let hgt = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("hgt"));
    if georef::set_index(path).is_some() {
        georef::GeoRef::of_set(path)
    } else if hgt || mosaic::is_mosaic(path) {
        mosaic::georef(path)
    } else {
        georef::GeoRef::read(path)
    }
}

/// How to read a terrain file. The defaults suit the common elevation formats as their files come.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadOptions {
    /// Sample spacing in metres, overriding (or supplying) what the file says.
    pub spacing: Option<f32>,
    /// Metres per stored unit for grey PNG and raw u16 (default: 0.1 for 16-bit, 1.0 for 8-bit).
    pub height_scale: Option<f32>,
    /// Metres added after scaling.
    pub height_offset: f32,
    /// Layout of a headerless raw file.
    pub raw: Option<RawLayout>,
    /// Most samples a file may declare; checked before allocating.
    pub max_samples: u64,
    /// How a PNG's pixels hold heights (grey values, or a web-map RGB encoding).
    pub png_encoding: PngEncoding,
    /// Resample each row of a grid whose E-W spacing differs from its N-S one (a geographic grid away
    /// from the equator, [`Heightmap::ew_spacing`], taken at the grid's middle row: a grid spanning many
    /// degrees of latitude needs a map projection instead) to square cells of the N-S spacing, so the
    /// terrain is drawn to scale (a tent filter along the row; fewer columns where E-W samples are
    /// denser). Off by default: such a grid is drawn with square cells, stretched E-W, as before (frame
    /// hashes recorded from it stay valid).
    pub resample_ew: bool,
    /// A stored sample value that marks a void, for a file that declares none or another one (it overrides
    /// the file's): compared with the value as stored, before the height scale and offset, as GDAL
    /// compares nodata (a PNG's grey level, or a web-map encoding's decoded metres); NaN matches NaN. Voids
    /// are filled from their neighbours and counted.
    pub nodata: Option<f64>,
    /// For a mosaic of tiles: the height, metres, that its samples no tile has data for (missing tiles,
    /// voids) read as. None: they are no data, filled from their neighbours as a single file's voids are
    /// (the mosaic is then read whole).
    pub fill_height: Option<f32>,
}

/// How a PNG's pixels hold heights.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PngEncoding {
    /// Grey values times the height scale: single-channel files, and RGB(A) or palette files whose
    /// channels are all equal. RGB with unequal channels is refused.
    #[default]
    Grey,
    /// Mapbox Terrain-RGB (8-bit RGB): h = -10000 + (R 65536 + G 256 + B) 0.1 metres.
    TerrainRgb,
    /// Terrarium (8-bit RGB): h = R 256 + G + B / 256 - 32768 metres.
    Terrarium,
}

impl PngEncoding {
    /// Every encoding, in the order of [`PngEncoding::NAMES`].
    pub const ALL: [PngEncoding; 3] = [Self::Grey, Self::TerrainRgb, Self::Terrarium];
    /// The names [`fmt::Display`] prints.
    pub const NAMES: [&'static str; 3] = ["grey", "terrain-rgb", "terrarium"];

    /// The height in metres of an RGB pixel (8-bit channels) under this encoding; [`PngEncoding::Grey`]
    /// reads R as metres.
    pub fn decode(self, r: u16, g: u16, b: u16) -> f64 {
        let (r, g, b) = (f64::from(r), f64::from(g), f64::from(b));
        match self {
            Self::Grey => r,
            // (v - 100000) / 10 is -10000 + v 0.1 with one rounding (the division), so a decimetre step
            // lands on the f64 nearest the true decimal.
            Self::TerrainRgb => ((r * 65536.0 + g * 256.0 + b) - 100_000.0) / 10.0,
            // Exact in f64: B / 256 is a power-of-two fraction.
            Self::Terrarium => r * 256.0 + g + b / 256.0 - 32768.0,
        }
    }
}

impl fmt::Display for PngEncoding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let i = Self::ALL.iter().position(|e| e == self).unwrap_or(0);
        f.write_str(Self::NAMES[i])
    }
}

/// The readers' revision: raised whenever a reader gives other samples or another placement for the
/// same files (a mosaic's seams, a georeference, a resampling), so that packages baked from a file by an
/// earlier reader are baked again rather than found in the cache (the keys of heights' and imagery's
/// packages include it). 1: the antimeridian, Copernicus and GLO-90 mosaic joins, imagery's EXIF
/// orientation and long texels.
pub const READ_REVISION: u32 = 1;

/// Default [`LoadOptions::max_samples`]: 2^30 samples, 4 GiB of f32 heights.
pub const DEFAULT_MAX_SAMPLES: u64 = 1 << 30;

impl Default for LoadOptions {
    fn default() -> Self {
        Self {
            spacing: None,
            height_scale: None,
            height_offset: 0.0,
            raw: None,
            max_samples: DEFAULT_MAX_SAMPLES,
            png_encoding: PngEncoding::Grey,
            resample_ew: false,
            nodata: None,
            fill_height: None,
        }
    }
}

/// The layout of a headerless raw file: little-endian samples, row-major, north-up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RawLayout {
    /// Samples per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Sample type.
    pub format: RawFormat,
}

/// Sample type of a raw file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RawFormat {
    /// Little-endian u16, scaled by the height scale.
    U16,
    /// Little-endian f32 metres.
    F32,
}

/// Where a terrain comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum TerrainSpec {
    /// The built-in procedural terrain.
    Procedural(crate::source::procedural::ProceduralParams),
    /// A file, its format told by extension (and magic number), or a mosaic of tiles: a folder, a `.txt`
    /// list or a glob pattern ([`is_mosaic`]).
    File(PathBuf),
}

mod asc;
mod bil;
mod dted;
pub mod geo;
mod heightmap;
mod hgt;
mod mosaic;
mod png;
pub mod georef;
pub mod imagery;
pub mod imagery_rows;
mod imagery_stretch;
pub mod procedural;
mod raw;
mod rows;
mod tiff;
mod tiff_jpeg;
mod xyz;

pub use geo::GeoExtent;
pub use heightmap::Heightmap;
pub use mosaic::MAX_OPEN_TILES;
pub(crate) use rows::check_band;
pub use rows::{Resident, RowGrid, RowSource};

impl TerrainSpec {
    /// Parses `--terrain`: `procedural[:seed=S,size=N,spacing=M]` (also `builtin`), else a file path.
    pub fn parse(text: &str) -> Result<Self> {
        let (head, params) = text.split_once(':').unwrap_or((text, ""));
        if head != "procedural" && head != "builtin" {
            return Ok(Self::File(PathBuf::from(text)));
        }
        let mut p = procedural::ProceduralParams::default();
        for kv in params.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let bad = |reason: String| Error::Invalid {
                what: "terrain".into(),
                reason,
            };
            let (k, v) = kv
                .split_once('=')
                .ok_or_else(|| bad(format!("`{kv}` is not key=value")))?;
            let num = |what: &str| bad(format!("{what} `{v}` is not a valid number"));
            match k {
                "seed" => p.seed = v.parse().map_err(|_| num("seed"))?,
                "size" => p.size = v.parse().map_err(|_| num("size"))?,
                "spacing" => p.spacing = v.parse().map_err(|_| num("spacing"))?,
                _ => {
                    return Err(bad(format!(
                        "unknown procedural parameter `{k}` (seed, size, spacing)"
                    )))
                }
            }
        }
        Ok(Self::Procedural(p))
    }
}

/// Loads a terrain file, choosing the format from its extension: `.png`, `.tif`/`.tiff`, `.hgt`,
/// `.dt0`/`.dt1`/`.dt2` (DTED), `.asc` (ESRI ASCII grid), `.xyz` (gridded XYZ points), `.flt`/`.bil`
/// (ESRI binary grids, with their `.hdr`), `.raw`/`.r16`/`.f32` (the raw ones need
/// [`LoadOptions::raw`]).
///
/// PNG and TIFF files must also start with their magic number. A file with another extension is
/// accepted when its magic number says PNG, TIFF or DTED. Spacing, when neither the file nor
/// [`LoadOptions::spacing`] gives it, is [`DEFAULT_SPACING_M`] for PNG and raw files; a GeoTIFF without
/// georeferencing needs `--spacing`.
pub fn load(path: &Path, opts: &LoadOptions) -> Result<Heightmap> {
    check_scale(path, opts)?;
    let mut hm = load_format(path, opts)?;
    if opts.spacing.is_some() {
        // Metres the caller gave are not the frame a geographic extent's numbers describe.
        hm = hm.with_geo(None);
    }
    Ok(if opts.resample_ew {
        resample_ew(hm)?
    } else {
        hm
    })
}

/// Whether `path` names a mosaic of DEM tiles read as one terrain rather than one file: a folder of
/// tiles, a `.txt` list of them (one path a line, relative to the list's folder), or a glob pattern
/// (docs/guide.md "Tile mosaics").
pub fn is_mosaic(path: &Path) -> bool {
    mosaic::is_mosaic(path)
}

/// Where a mosaic lies on the globe, from its tiles' headers (None: projected tiles); what
/// [`Heightmap::geo`] of the loaded mosaic says, without loading it.
pub fn mosaic_geo(path: &Path, opts: &LoadOptions) -> Result<Option<GeoExtent>> {
    mosaic::geo(path, opts)
}

/// A tile mosaic's grid and its tiles' rectangles on it, and a rectangle of it read alone: a package
/// set's cells (`package::set_bake`).
pub(crate) use mosaic::{
    cells as mosaic_cells, integer_tiles as mosaic_integer_tiles, window as mosaic_window,
};

/// The files `path` reads: the file itself, or a mosaic's tiles (and its list file): what a cache key
/// stamps.
pub fn input_files(path: &Path) -> Result<Vec<PathBuf>> {
    if !is_mosaic(path) {
        return Ok(vec![path.to_path_buf()]);
    }
    let (mut tiles, list) = mosaic::tile_paths(path)?;
    tiles.extend(list);
    Ok(tiles)
}

/// [`load`] before [`LoadOptions::resample_ew`].
fn load_format(path: &Path, opts: &LoadOptions) -> Result<Heightmap> {
    if is_mosaic(path) {
        return mosaic::load(path, opts);
    }
    let meta = regular_file(path, "cannot read")?;
    if meta.len() == 0 {
        return Err(Error::format(path, "file is empty"));
    }
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let magic = read_magic(path)?;
    match ext.as_str() {
        "png" => png::load(path, opts, &magic),
        "tif" | "tiff" => Ok(tiff::load(path, opts, &magic)?.with_geo(geotiff_extent(path))),
        "hgt" => hgt::load(path, meta.len(), opts),
        "asc" => asc::load(path, opts),
        "flt" | "bil" => bil::load(path, meta.len(), opts),
        "dt0" | "dt1" | "dt2" => dted::load(path, meta.len(), opts),
        "xyz" => xyz::load(path, opts),
        "raw" | "r16" | "f32" => raw::load(path, meta.len(), opts),
        _ if magic.starts_with(&png::MAGIC) => png::load(path, opts, &magic),
        _ if tiff::has_magic(&magic) => {
            Ok(tiff::load(path, opts, &magic)?.with_geo(geotiff_extent(path)))
        }
        _ if magic.starts_with(dted::MAGIC) => dted::load(path, meta.len(), opts),
        // A package is opened before any source (by its magic number): one named so without it is damaged.
        "clipsat" => Err(Error::format(
            path,
            "not a clipsat package: it does not start with the package magic number (damaged, or not \
             written by `clipsat bake`)",
        )),
        _ => Err(Error::format(
            path,
            format!(
                "unknown terrain format `.{ext}`: expected .png, .tif/.tiff, .hgt, .dt0/.dt1/.dt2, .asc, \
                 .xyz, .flt/.bil (with a .hdr), .raw/.r16/.f32 or a .clipsat package"
            ),
        )),
    }
}

/// The extent of a GeoTIFF whose GTModelTypeGeoKey says geographic (as the TIFF loader reads its
/// spacing in degrees then), placed by its ModelPixelScale and ModelTiepoint; None otherwise.
fn geotiff_extent(path: &Path) -> Option<GeoExtent> {
    if mosaic::model_type(path) != Some(2) {
        return None;
    }
    let g = georef::GeoRef::read(path)?;
    let first = (g.corner.0 + 0.5 * g.scale.0, g.corner.1 - 0.5 * g.scale.1);
    geo::GeoExtent::of_grid(first, g.scale, g.size)
}

/// Opens a terrain file to be read a band of rows at a time (the out-of-core bake's source): a raw file
/// or an ESRI binary grid is read by positioned reads, a GeoTIFF one row of strips or tiles at a time, a
/// non-interlaced PNG row by row (any of them with voids is loaded whole: they are filled over the whole
/// grid; a raw file or PNG given [`LoadOptions::nodata`] always is); the other files are
/// decoded whole by [`load`] (an SRTM tile or a DTED cell is at most 3601^2 samples; an ASCII grid or
/// an XYZ file is parsed a line at a time into its heights) and read from memory. A mosaic of tiles
/// ([`is_mosaic`]) is read a band at a time through its tiles, or whole where it has samples with no
/// data and no [`LoadOptions::fill_height`].
pub fn open_rows(path: &Path, opts: &LoadOptions) -> Result<Box<dyn RowSource>> {
    check_scale(path, opts)?;
    let rows = open_format_rows(path, opts)?;
    // As `Heightmap::new` refuses it for a load: a georeference of steps too small or too large for an
    // f32 of metres (a tile's 1e-300 degrees) had streamed on to a package header that was refused
    // naming the bake's temporary file.
    for spacing in [rows.grid().spacing, rows.grid().ew_spacing] {
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(Error::format(
                path,
                format!("sample spacing {spacing} m: must be finite and positive"),
            ));
        }
    }
    if !opts.resample_ew {
        return Ok(rows);
    }
    Ok(match rows::ResampledEw::new(rows) {
        Ok(r) => Box::new(r),
        Err(rows) => rows,
    })
}

/// [`open_rows`] before [`LoadOptions::resample_ew`].
fn open_format_rows(path: &Path, opts: &LoadOptions) -> Result<Box<dyn RowSource>> {
    if is_mosaic(path) {
        return mosaic::open_rows(path, opts);
    }
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    if matches!(ext.as_str(), "raw" | "r16" | "f32" | "flt" | "bil") {
        let meta = regular_file(path, "cannot read")?;
        if meta.len() == 0 {
            return Err(Error::format(path, "file is empty"));
        }
        if matches!(ext.as_str(), "flt" | "bil") {
            return bil::open_rows(path, meta.len(), opts);
        }
        if opts.nodata.is_none() {
            return Ok(Box::new(raw::Rows::open(path, meta.len(), opts)?));
        }
        // Voids are filled over the whole grid.
        return Ok(Box::new(Resident::new(load(path, opts)?)));
    }
    if matches!(ext.as_str(), "tif" | "tiff") {
        return tiff::open_rows(path, opts, &read_magic(path)?);
    }
    if ext == "png" {
        return png::open_rows(path, opts, &read_magic(path)?);
    }
    Ok(Box::new(Resident::new(load(path, opts)?)))
}

/// Spacing assumed for PNG and raw files when [`LoadOptions::spacing`] is not given, metres.
pub const DEFAULT_SPACING_M: f32 = 30.0;

/// Refuses a height scale, offset or fill height that is not finite: every sample would read NaN (and be
/// taken for a void) or infinite.
fn check_scale(path: &Path, opts: &LoadOptions) -> Result<()> {
    let given = [
        ("height scale", opts.height_scale),
        ("height offset", Some(opts.height_offset)),
        ("fill height", opts.fill_height),
    ];
    match given.iter().find(|(_, v)| v.is_some_and(|v| !v.is_finite())) {
        Some((what, Some(v))) => Err(Error::format(
            path,
            format!("{what} {v}: must be finite"),
        )),
        _ => Ok(()),
    }
}

/// The metadata of the file at `path` (`io`: what a failure to read it says), refused where it is not
/// a regular file: a folder, or a FIFO or device, which opening would wait on or read without end.
pub(crate) fn regular_file(path: &Path, io: &'static str) -> Result<std::fs::Metadata> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, io, e))?;
    if !meta.is_file() {
        return Err(Error::format(path, "not a regular file"));
    }
    Ok(meta)
}

/// The first (up to) 8 bytes of a file, for magic-number checks.
fn read_magic(path: &Path) -> Result<Vec<u8>> {
    use std::io::Read;
    regular_file(path, "cannot open")?;
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot open", e))?;
    let mut magic = Vec::with_capacity(8);
    f.take(8)
        .read_to_end(&mut magic)
        .map_err(|e| Error::io(path, "cannot read", e))?;
    Ok(magic)
}

/// Refuses `width` x `height` over [`LoadOptions::max_samples`], before anything is allocated.
fn check_size(path: &Path, width: u64, height: u64, opts: &LoadOptions) -> Result<usize> {
    let samples = width.saturating_mul(height);
    if samples > opts.max_samples {
        return Err(Error::TooLarge {
            path: path.into(),
            width,
            height,
            samples,
            limit: opts.max_samples,
        });
    }
    if width < 2 || height < 2 {
        return Err(Error::format(
            path,
            format!("{width} x {height} samples: need at least 2 x 2"),
        ));
    }
    usize::try_from(samples).map_err(|_| Error::TooLarge {
        path: path.into(),
        width,
        height,
        samples,
        limit: opts.max_samples,
    })
}

/// `n` zeroed height samples for `path`, or [`Error::Io`] (out of memory) where the allocator cannot give
/// them: a [`LoadOptions::max_samples`] raised past this machine's memory is refused with the file named,
/// not aborted on.
pub(crate) fn zeroed_samples(path: &Path, n: usize) -> Result<Vec<f32>> {
    let mut heights = Vec::new();
    heights.try_reserve_exact(n).map_err(|_| {
        let bytes = u128::try_from(n).unwrap_or(u128::MAX).saturating_mul(4);
        Error::io(
            path,
            "cannot hold its heights in memory",
            std::io::Error::new(
                std::io::ErrorKind::OutOfMemory,
                format!("{n} samples ({bytes} bytes) do not fit"),
            ),
        )
    })?;
    heights.resize(n, 0.0);
    Ok(heights)
}

/// Rounds metres to the f32 a [`Heightmap`] holds; out-of-range values become infinite and are refused
/// later as [`Error::NonFinite`].
#[expect(
    clippy::cast_possible_truncation,
    reason = "f64 to f32 rounding is the intent; overflow shows up as infinity"
)]
fn to_f32(v: f64) -> f32 {
    v as f32
}

/// Replaces the void samples, marked NaN, by the mean of their nearest valid neighbours; returns how many.
///
/// Voids are filled in waves outward from the valid samples: each wave takes the mean of the 4-neighbours
/// known before it, in a fixed order, so the result is deterministic. Callers must have refused genuine
/// NaN and infinite samples already. An all-void grid is an error.
fn fill_voids(path: &Path, width: usize, heights: &mut [f32]) -> Result<u64> {
    let n = heights.len();
    let voids = heights.iter().filter(|h| h.is_nan()).count();
    if voids == 0 {
        return Ok(0);
    }
    if voids == n {
        return Err(Error::format(path, "every sample is void (nodata)"));
    }
    let rows = n / width;
    let neighbours = |i: usize| {
        let (x, y) = (i % width, i / width);
        [
            (x > 0).then(|| i - 1),
            (x + 1 < width).then(|| i + 1),
            (y > 0).then(|| i - width),
            (y + 1 < rows).then(|| i + width),
        ]
    };
    // `queued` marks voids already in a wave, so each is filled exactly once.
    let mut queued = vec![false; n];
    let mut wave: Vec<usize> = Vec::new();
    for i in 0..n {
        if heights[i].is_nan()
            && neighbours(i)
                .iter()
                .flatten()
                .any(|&j| !heights[j].is_nan())
        {
            queued[i] = true;
            wave.push(i);
        }
    }
    let mut values: Vec<f32> = Vec::new();
    while !wave.is_empty() {
        values.clear();
        for &i in &wave {
            let (mut sum, mut count) = (0.0f64, 0u32);
            for j in neighbours(i).into_iter().flatten() {
                if !heights[j].is_nan() {
                    sum += f64::from(heights[j]);
                    count += 1;
                }
            }
            // Every wave member has a known neighbour: that is how it got into the wave.
            values.push(to_f32(sum / f64::from(count.max(1))));
        }
        for (&i, &v) in wave.iter().zip(&values) {
            heights[i] = v;
        }
        let mut next = Vec::new();
        for &i in &wave {
            for j in neighbours(i).into_iter().flatten() {
                if heights[j].is_nan() && !queued[j] {
                    queued[j] = true;
                    next.push(j);
                }
            }
        }
        next.sort_unstable();
        wave = next;
    }
    Ok(voids as u64)
}

/// Sample `v` at `(column, row)` in metres: NaN for a void (for [`fill_voids`]), and a non-finite height
/// that is not a void refused, since filling would otherwise spread it.
pub(super) fn height(
    path: &Path,
    v: f64,
    void: bool,
    scale: f64,
    offset: f64,
    (x, y): (usize, usize),
) -> Result<f32> {
    if void {
        return Ok(f32::NAN);
    }
    let h = to_f32(v * scale + offset);
    if !h.is_finite() {
        return Err(Error::NonFinite {
            path: path.into(),
            x: u32::try_from(x).unwrap_or(u32::MAX),
            y: u32::try_from(y).unwrap_or(u32::MAX),
            value: h,
        });
    }
    Ok(h)
}

/// Whether stored value `v` is the void marker `nodata`: NaN matches NaN, and others within a relative
/// 1e-6 (GDAL prints float nodata such as -3.4028e38 in decimal, not bit-exact).
pub(super) fn is_nodata(nodata: Option<f64>, v: f64) -> bool {
    match nodata {
        None => false,
        Some(nd) if nd.is_nan() => v.is_nan(),
        Some(nd) => v == nd || (v - nd).abs() <= 1e-6 * nd.abs(),
    }
}

/// How far from 1 the E-W over N-S spacing ratio may be for cells to count as square (left as they are).
pub const SQUARE_CELLS_TOLERANCE: f64 = 1e-3;

/// Columns of a `width`-sample row of E-W spacing `ew` resampled to spacing `ns`, keeping its ends, and
/// the E-W spacing they then have (within half a column of `ns`); None where the cells are square
/// ([`SQUARE_CELLS_TOLERANCE`]).
pub(crate) fn resampled_width(width: u32, ns: f32, ew: f32) -> Option<(u32, f32)> {
    let ratio = f64::from(ew) / f64::from(ns);
    if !ratio.is_finite() || ratio <= 0.0 || (ratio - 1.0).abs() <= SQUARE_CELLS_TOLERANCE {
        return None;
    }
    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "a positive column count, capped at u32::MAX"
    )]
    let w = ((f64::from(width - 1) * ratio)
        .round()
        .min(f64::from(u32::MAX - 1)) as u32)
        .max(1)
        + 1;
    let spacing = f64::from(ew) * f64::from(width - 1) / f64::from(w - 1);
    (w != width).then_some((w, to_f32(spacing)))
}

/// Resamples `src` (one row) into `dst` with a tent filter: output column x sits at source column
/// x (len(src) - 1) / (len(dst) - 1), and takes the samples within max(1, that step) of it, weighted by
/// how near they are (so it averages where it drops samples and interpolates linearly where it adds).
pub(crate) fn resample_row(src: &[f32], dst: &mut [f32]) {
    let (n, m) = (src.len(), dst.len());
    assert!(n >= 2 && m >= 2, "rows of at least 2 samples");
    #[expect(clippy::cast_precision_loss, reason = "row lengths are below 2^32")]
    let step = (n - 1) as f64 / (m - 1) as f64;
    let half = step.max(1.0);
    for (x, out) in dst.iter_mut().enumerate() {
        #[expect(clippy::cast_precision_loss, reason = "row lengths are below 2^32")]
        let s = x as f64 * step;
        #[expect(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "clamped to the row"
        )]
        let (lo, hi) = (
            (s - half).ceil().max(0.0) as usize,
            ((s + half).floor() as usize).min(n - 1),
        );
        let (mut sum, mut weight) = (0.0f64, 0.0f64);
        for (i, z) in src.iter().enumerate().take(hi + 1).skip(lo) {
            #[expect(clippy::cast_precision_loss, reason = "row lengths are below 2^32")]
            let w = 1.0 - (i as f64 - s).abs() / half;
            if w > 0.0 {
                sum += w * f64::from(*z);
                weight += w;
            }
        }
        *out = to_f32(sum / weight);
    }
}

/// `hm` with every row resampled to square cells of its N-S spacing ([`LoadOptions::resample_ew`]);
/// as it is where its cells are square already.
fn resample_ew(hm: Heightmap) -> Result<Heightmap> {
    let Some((w2, ew)) = resampled_width(hm.width(), hm.spacing(), hm.ew_spacing()) else {
        return Ok(hm);
    };
    let (w, h) = (hm.width() as usize, hm.height() as usize);
    let mut out = zeroed_samples(Path::new("<resampled>"), w2 as usize * h)?;
    for (src, dst) in hm
        .heights()
        .chunks_exact(w)
        .zip(out.chunks_exact_mut(w2 as usize))
    {
        resample_row(src, dst);
    }
    let (x, y) = hm.origin();
    Ok(
        Heightmap::new(Path::new("<resampled>"), w2, hm.height(), hm.spacing(), out)?
            .with_voids_filled(hm.voids_filled())
            .with_ew_spacing(ew)
            .with_origin(x, y)
            .with_geo(hm.geo().copied()),
    )
}

/// Metres per degree of longitude at latitude `lat_deg` (the parallel's radius on the WGS84 ellipsoid:
/// pi / 180 a cos phi / sqrt(1 - e^2 sin^2 phi)).
pub fn metres_per_degree_longitude(lat_deg: f64) -> f64 {
    const A: f64 = 6_378_137.0;
    const E2: f64 = 6.694_379_990_14e-3;
    let phi = lat_deg.to_radians();
    std::f64::consts::PI / 180.0 * A * phi.cos() / (1.0 - E2 * phi.sin().powi(2)).sqrt()
}

/// Metres per degree of latitude at latitude `lat_deg` (the meridian arc on the WGS84 ellipsoid, series
/// form: 111132.954 - 559.822 cos 2phi + 1.175 cos 4phi).
pub fn metres_per_degree_latitude(lat_deg: f64) -> f64 {
    let phi = lat_deg.to_radians();
    111_132.954 - 559.822 * (2.0 * phi).cos() + 1.175 * (4.0 * phi).cos()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fills_voids_from_neighbours() {
        let nan = f32::NAN;
        let mut h = vec![1.0, nan, 3.0, nan, nan, nan, 7.0, nan, 9.0];
        let n = fill_voids(Path::new("t"), 3, &mut h).unwrap();
        assert_eq!(n, 5);
        assert_eq!(h[1], 2.0);
        assert_eq!(h[3], 4.0);
        assert_eq!(h[4], 5.0);
        assert!(h.iter().all(|v| v.is_finite()));
        let mut all = vec![nan; 4];
        assert!(fill_voids(Path::new("t"), 2, &mut all).is_err());
    }

    #[test]
    fn rows_resample_with_a_tent_filter() {
        // Halving a ramp keeps it (interior), doubling interpolates it, and the ends stay put.
        let ramp: Vec<f32> = (0..9).map(|i| i as f32 * 2.0).collect();
        let mut half = [0.0f32; 5];
        resample_row(&ramp, &mut half);
        assert_eq!(&half[1..4], &[4.0, 8.0, 12.0]);
        let mut double = [0.0f32; 17];
        resample_row(&ramp, &mut double);
        assert!(double.iter().enumerate().all(|(x, z)| *z == x as f32));
        // A spike is averaged, not dropped, when columns are dropped.
        let mut spike = [0.0f32; 9];
        spike[4] = 9.0;
        resample_row(&spike, &mut half);
        assert_eq!(half.iter().sum::<f32>(), 4.5);
        assert_eq!(resampled_width(1201, 92.8, 50.0).map(|(w, _)| w), Some(648));
        assert_eq!(resampled_width(1201, 30.0, 30.02), None, "within 0.1 %");
        assert_eq!(
            resampled_width(2, 100.0, 1.0),
            None,
            "never under 2 columns"
        );
    }

    #[test]
    fn parallel_arc() {
        // 1 degree of longitude: 111320 m at the equator, 55800 m at 60 degrees.
        assert!((metres_per_degree_longitude(0.0) - 111_319.5).abs() < 1.0);
        assert!((metres_per_degree_longitude(60.0) - 55_800.0).abs() < 10.0);
    }

    #[test]
    fn meridian_arc() {
        // 1 degree of latitude: 110574 m at the equator, 111694 m at the poles.
        assert!((metres_per_degree_latitude(0.0) - 110_574.3).abs() < 1.0);
        assert!((metres_per_degree_latitude(90.0) - 111_693.9).abs() < 1.0);
    }

    #[test]
    fn samples_past_memory_are_an_error() {
        // More bytes than any allocator gives: an error naming the file, not an abort.
        let err = zeroed_samples(Path::new("big.hgt"), usize::MAX / 2).unwrap_err();
        assert!(matches!(err, Error::Io { .. }), "{err}");
        assert!(err.to_string().starts_with("big.hgt: cannot hold"), "{err}");
        assert_eq!(zeroed_samples(Path::new("s"), 3).ok(), Some(vec![0.0; 3]));
    }
}
