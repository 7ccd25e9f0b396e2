//! Stage 0, the source: a mosaic of DEM tiles (SRTM `.hgt`, GeoTIFF) named by a folder, a list file or a
//! glob pattern, placed by their georeference on one grid and read as one terrain (docs/guide.md "Tile
//! mosaics"). This file names and places the tiles; `rows.rs` reads them a band of rows at a time.

use std::path::{Path, PathBuf};

use super::{
    check_size, fill_voids, to_f32,
    GeoExtent, Heightmap, LoadOptions, RowGrid, RowSource,
};
use crate::source::georef::GeoRef;
use crate::{Error, Result};

mod rows;
mod vrt;

pub(crate) use rows::Mosaic;
pub use rows::MAX_OPEN_TILES;

/// How far (in steps of the mosaic's grid) a tile's first sample may lie from a grid point and still count
/// as on it: GeoTIFF georeferences are decimal numbers (a half pixel of 1/3600 degree, say).
const GRID_TOLERANCE: f64 = 1e-3;

/// The tile formats a mosaic reads, by extension.
const TILE_EXTENSIONS: [&str; 3] = ["hgt", "tif", "tiff"];

/// Whether `path` names a mosaic rather than one file: a folder, a `.txt` list of tiles, a GDAL `.vrt`
/// mosaic, or a glob pattern (`*`, `?` or `[`) that is not itself the name of a file.
pub(crate) fn is_mosaic(path: &Path) -> bool {
    if path.is_dir() {
        return true;
    }
    if path.exists() {
        return matches!(extension(path).as_str(), "txt" | "vrt");
    }
    path.to_str().is_some_and(|s| s.contains(['*', '?', '[']))
}

/// The lower-case extension of `path`.
fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default()
}

/// The tiles a mosaic names, in its order: a folder's `.hgt`, `.tif` and `.tiff` files sorted by name (not
/// its subfolders); a list file's lines (paths relative to the list's folder; blank lines and lines
/// starting with `#` skipped); a VRT's sources, last first (`vrt.rs`); a glob pattern's matching files,
/// sorted by name. Also returns the list file or VRT, whose edits change the mosaic too.
pub(crate) fn tile_paths(spec: &Path) -> Result<(Vec<PathBuf>, Option<PathBuf>)> {
    let mut tiles = Vec::new();
    if spec.is_file() && extension(spec) == "vrt" {
        let v = vrt::Vrt::read(spec)?;
        let tiles = v.sources.into_iter().map(|s| s.path).collect();
        return Ok((tiles, Some(spec.to_path_buf())));
    }
    if spec.is_dir() {
        let entries = std::fs::read_dir(spec).map_err(|e| Error::io(spec, "cannot list", e))?;
        for entry in entries {
            let path = entry.map_err(|e| Error::io(spec, "cannot list", e))?.path();
            if path.is_file() && TILE_EXTENSIONS.contains(&extension(&path).as_str()) {
                tiles.push(path);
            }
        }
        tiles.sort();
        if tiles.is_empty() {
            return Err(Error::format(
                spec,
                format!(
                    "a folder of tiles with no DEM tile in it (.hgt, .tif or .tiff files){}",
                    empty_folder_hint(spec)
                ),
            ));
        }
        return Ok((tiles, None));
    }
    if spec.is_file() {
        let bytes = std::fs::read(spec).map_err(|e| Error::io(spec, "cannot read", e))?;
        let text = String::from_utf8(bytes).map_err(|_| {
            Error::format(
                spec,
                "a list of tiles that is not UTF-8 text (one path a line): save it as UTF-8",
            )
        })?;
        // The byte-order mark a list saved by Windows Notepad starts with is no part of its first path
        // (that tile had been missing, its name printed as if it were right).
        let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
        let base = spec.parent().unwrap_or(Path::new(""));
        for line in text.lines().map(str::trim) {
            if !line.is_empty() && !line.starts_with('#') {
                tiles.push(base.join(line));
            }
        }
        if tiles.is_empty() {
            return Err(Error::format(
                spec,
                "a list of tiles that names none (one path a line)",
            ));
        }
        return Ok((tiles, Some(spec.to_path_buf())));
    }
    let pattern = spec.to_str().unwrap_or_default();
    let matches = glob::glob(pattern).map_err(|e| {
        Error::format(spec, format!("not a valid glob pattern of tiles: {e}"))
    })?;
    for m in matches {
        let path = m.map_err(|e| {
            let path = e.path().to_path_buf();
            Error::io(path, "cannot read", e.into())
        })?;
        if path.is_file() {
            tiles.push(path);
        }
    }
    tiles.sort();
    if tiles.is_empty() {
        return Err(Error::format(
            spec,
            "the glob pattern matches no file (no DEM tile to read)",
        ));
    }
    Ok((tiles, None))
}

/// What to do with a folder that holds no tile itself: where its subfolders do (`N00W001.SRTMGL1.hgt/`
/// as unzipping each download into a folder of its name gives), the glob that names them; where it
/// holds zip or gzip files (`N00W001.hgt.gz`), to unpack them. Empty where neither.
fn empty_folder_hint(dir: &Path) -> String {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return String::new();
    };
    let (mut zips, mut nested) = (0usize, None);
    for path in entries.filter_map(|e| e.ok().map(|e| e.path())) {
        if path.is_file() && matches!(extension(&path).as_str(), "zip" | "gz") {
            zips += 1;
        } else if path.is_dir() && nested.is_none() {
            let inner = std::fs::read_dir(&path).into_iter().flatten().filter_map(|e| e.ok());
            nested = inner
                .map(|e| e.path())
                .find(|p| p.is_file() && TILE_EXTENSIONS.contains(&extension(p).as_str()));
        }
    }
    if let Some(tile) = nested {
        let ext = extension(&tile);
        return format!(
            "; its subfolders hold tiles (like {}), which a folder does not read: give them as a quoted \
             glob, '{}'",
            tile.display(),
            dir.join("*").join(format!("*.{ext}")).display()
        );
    }
    if zips > 0 {
        return format!(
            "; it holds {zips} compressed file(s) (.zip, .gz), which are not read: unpack them into it"
        );
    }
    String::new()
}

/// The coordinate system of a tile: geographic (degrees) or projected, and its EPSG code where known.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Crs {
    geographic: bool,
    epsg: Option<u16>,
}

impl Crs {
    /// Whether the two may share a mosaic: both geographic or both projected, and the same EPSG code where
    /// both name one.
    fn agrees(self, other: Self) -> bool {
        self.geographic == other.geographic
            && (self.epsg.is_none() || other.epsg.is_none() || self.epsg == other.epsg)
    }
}

impl std::fmt::Display for Crs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let kind = if self.geographic {
            "geographic"
        } else {
            "projected"
        };
        match self.epsg {
            Some(code) => write!(f, "{kind}, EPSG {code}"),
            None => write!(f, "{kind}, no EPSG code"),
        }
    }
}

/// One tile as its file places it.
#[derive(Clone, Debug)]
struct TileMeta {
    path: PathBuf,
    /// An SRTM `.hgt` (else a GeoTIFF).
    hgt: bool,
    /// Samples (columns, rows).
    size: (u32, u32),
    /// Model units between samples, (east, south).
    step: (f64, f64),
    /// The model position of sample (0, 0), the north-west one: (x, y).
    first: (f64, f64),
    crs: Crs,
}

/// GTModelTypeGeoKey: 1 projected, 2 geographic.
const MODEL_TYPE_KEY: u16 = 1024;

impl TileMeta {
    fn read(path: &Path) -> Result<Self> {
        let meta = std::fs::metadata(path).map_err(|e| Error::io(path, "cannot read tile", e))?;
        if !meta.is_file() {
            return Err(Error::format(path, "a tile that is not a regular file"));
        }
        match extension(path).as_str() {
            "hgt" => Self::hgt(path, meta.len()),
            "tif" | "tiff" => Self::geotiff(path),
            other => Err(Error::format(
                path,
                format!("a tile of format `.{other}`: a mosaic reads SRTM .hgt and GeoTIFF tiles"),
            )),
        }
    }

    /// An SRTM tile: 1 degree square, its south-west corner named by the file (`N57E011.hgt`), 1201 or
    /// 3601 samples a side, sample centres on the degree lines (pixel-is-point).
    fn hgt(path: &Path, len: u64) -> Result<Self> {
        let (side, _) = super::hgt::tile_side(path, len)?;
        let (lat, lon) = super::geo::hgt_corner(path).ok_or_else(|| {
            Error::format(
                path,
                "an SRTM tile in a mosaic must be named by its south-west corner, like N57E011.hgt",
            )
        })?;
        let step = 1.0 / f64::from(side - 1);
        Ok(Self {
            path: path.into(),
            hgt: true,
            size: (side, side),
            step: (step, step),
            first: (lon, lat + 1.0),
            crs: Crs {
                geographic: true,
                epsg: Some(4326),
            },
        })
    }

    /// A GeoTIFF placed by its ModelPixelScale and ModelTiepoint (pixel-is-area or pixel-is-point).
    fn geotiff(path: &Path) -> Result<Self> {
        let geo = GeoRef::read(path).ok_or_else(|| {
            Error::format(
                path,
                "a GeoTIFF tile without a usable georeference (ModelPixelScale and ModelTiepoint, \
                 north up): a mosaic places its tiles by it",
            )
        })?;
        let geographic = match geo.crs {
            Some((2048, _)) => true,
            Some(_) => false,
            None => model_type(path) == Some(2),
        };
        // Degrees on the globe (a pixel's slack past a pole, a turn either way of longitude for tiles
        // given in 0..360 or across the antimeridian): past them a georeference is damaged or not in
        // degrees, and tiles at a longitude of 1e15 had been joined into a mosaic of no meaning.
        let (w, n) = geo.corner;
        let (e, s) = (
            w + geo.scale.0 * f64::from(geo.size.0),
            n - geo.scale.1 * f64::from(geo.size.1),
        );
        if geographic
            && !(n <= 90.0 + geo.scale.1 && s >= -90.0 - geo.scale.1 && w >= -360.0 && e <= 720.0)
        {
            return Err(Error::format(
                path,
                format!(
                    "a geographic tile from {w} to {e} degrees east and {s} to {n} north: not on the \
                     globe, its georeference is damaged or not in degrees"
                ),
            ));
        }
        Ok(Self {
            path: path.into(),
            hgt: false,
            size: geo.size,
            step: geo.scale,
            first: (
                geo.corner.0 + 0.5 * geo.scale.0,
                geo.corner.1 - 0.5 * geo.scale.1,
            ),
            crs: Crs {
                geographic,
                epsg: geo.crs.map(|(_, code)| code),
            },
        })
    }
}

/// A TIFF's GTModelTypeGeoKey, where it has one.
pub(super) fn model_type(path: &Path) -> Option<u16> {
    let file = std::fs::File::open(path).ok()?;
    let mut dec = tiff::decoder::Decoder::new(std::io::BufReader::new(file)).ok()?;
    let keys = dec
        .find_tag(tiff::tags::Tag::GeoKeyDirectoryTag)
        .ok()
        .flatten()?
        .into_u16_vec()
        .ok()?;
    keys.get(4..)?
        .chunks_exact(4)
        .find(|e| e[0] == MODEL_TYPE_KEY && e[1] == 0)
        .map(|e| e[3])
}

/// A tile placed on the mosaic's grid.
#[derive(Clone, Debug)]
struct Placed {
    meta: TileMeta,
    /// The grid column and row of its sample (0, 0).
    col0: u32,
    row0: u32,
    /// The last grid column and row it covers (inclusive).
    col1: u32,
    row1: u32,
    /// Grid steps per tile step, (columns, rows): 1 for a tile of the finest spacing.
    k: (f64, f64),
}

/// The mosaic's grid and its tiles in the order they are read: the finest first, ties by the order given.
#[derive(Clone, Debug)]
struct Layout {
    grid: RowGrid,
    tiles: Vec<Placed>,
    /// Where a geographic mosaic lies on the globe.
    geo: Option<GeoExtent>,
}

/// Places the tiles named by `spec` on one grid ([`Layout`]).
fn layout(spec: &Path, opts: &LoadOptions) -> Result<Layout> {
    if let Some(h) = opts.fill_height.filter(|h| !h.is_finite()) {
        return Err(Error::format(
            spec,
            format!("a fill height of {h} m: it must be finite"),
        ));
    }
    // A VRT read once, its sources the tiles (read twice, a VRT edited between had more sources than
    // tiles); a folder named `*.vrt` is a folder of tiles (it had been read as a VRT's file).
    let vrt = if spec.is_file() && extension(spec) == "vrt" {
        Some(vrt::Vrt::read(spec)?)
    } else {
        None
    };
    let paths = match &vrt {
        Some(v) => v.sources.iter().map(|s| s.path.clone()).collect(),
        None => tile_paths(spec)?.0,
    };
    let mut metas = paths
        .iter()
        .map(|p| TileMeta::read(p))
        .collect::<Result<Vec<_>>>()?;
    if let Some(v) = &vrt {
        // Each source where the VRT puts it is where its own georeference does.
        for (i, m) in metas.iter().enumerate() {
            let (west, north) = (m.first.0 - 0.5 * m.step.0, m.first.1 + 0.5 * m.step.1);
            let area = [
                west,
                north,
                west + f64::from(m.size.0) * m.step.0,
                north - f64::from(m.size.1) * m.step.1,
            ];
            v.check_placed(spec, i, area, m.step, GRID_TOLERANCE)?;
        }
    }
    let first = &metas[0];
    for m in &metas[1..] {
        if !m.crs.agrees(first.crs) {
            return Err(Error::format(
                &m.path,
                format!(
                    "this tile's coordinate system ({}) is not that of {} ({}): the tiles of a mosaic \
                     share one; reproject them",
                    m.crs,
                    first.path.display(),
                    first.crs
                ),
            ));
        }
    }
    if metas[0].crs.geographic {
        unwrap_longitudes(&mut metas);
    }
    let fine = metas.iter().fold((f64::MAX, f64::MAX), |(x, y), m| {
        (x.min(m.step.0), y.min(m.step.1))
    });
    if let Some(v) = &vrt {
        v.check_resolution(spec, fine, GRID_TOLERANCE)?;
    }
    let west = metas.iter().map(|m| m.first.0).fold(f64::MAX, f64::min);
    let north = metas.iter().map(|m| m.first.1).fold(f64::MIN, f64::max);
    let mut tiles = Vec::with_capacity(metas.len());
    let (mut width, mut height) = (0u64, 0u64);
    for meta in metas {
        let on_grid = |offset: f64, step: f64, axis: &str| -> Result<u64> {
            let at = offset / step;
            if !at.is_finite() || (at - at.round()).abs() > GRID_TOLERANCE || at > 1e12 {
                return Err(Error::format(
                    &meta.path,
                    format!(
                        "this tile's first sample lies {:.4} of a step {axis} off the mosaic's grid (the \
                         finest tile's spacing, {step} units, from its north-west sample): the tiles \
                         must align to a common grid",
                        (at - at.round()).abs()
                    ),
                ));
            }
            #[expect(
                clippy::cast_possible_truncation,
                clippy::cast_sign_loss,
                reason = "a finite, non-negative value under 1e12"
            )]
            Ok(at.round() as u64)
        };
        let col0 = on_grid(meta.first.0 - west, fine.0, "east")?;
        let row0 = on_grid(north - meta.first.1, fine.1, "south")?;
        let k = (meta.step.0 / fine.0, meta.step.1 / fine.1);
        #[expect(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "a finite, non-negative count of steps, checked against the size limit below"
        )]
        let span = |n: u32, k: f64| ((f64::from(n - 1) * k + GRID_TOLERANCE).floor()) as u64;
        if meta.size.0 < 2 || meta.size.1 < 2 {
            return Err(Error::format(&meta.path, "a tile of fewer than 2 x 2 samples"));
        }
        let col1 = col0.saturating_add(span(meta.size.0, k.0));
        let row1 = row0.saturating_add(span(meta.size.1, k.1));
        width = width.max(col1.saturating_add(1));
        height = height.max(row1.saturating_add(1));
        let narrow = |v: u64| u32::try_from(v).unwrap_or(u32::MAX);
        tiles.push(Placed {
            meta,
            col0: narrow(col0),
            row0: narrow(row0),
            col1: narrow(col1),
            row1: narrow(row1),
            k,
        });
    }
    check_size(spec, width, height, opts)?;
    let (width, height) = (u32::try_from(width), u32::try_from(height));
    let (Ok(width), Ok(height)) = (width, height) else {
        return Err(Error::format(spec, "a mosaic of more than 2^32 columns or rows"));
    };
    // The finest first; a stable sort keeps the order given among equals.
    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "a positive ratio of spacings, rounded to compare within 1e-6"
    )]
    tiles.sort_by_key(|t| (t.k.0 * t.k.1 * 1e6).round() as u64);
    let geographic = tiles[0].meta.crs.geographic;
    let (spacing, ew_spacing) = match opts.spacing {
        Some(s) => (s, s),
        // As a GeoTIFF of the merged grid gives them (`tiff.rs`): the meridian and parallel arcs at the
        // middle row's latitude.
        None if geographic => {
            let mid_row = f64::from(height - 1) / 2.0;
            super::geo::spacing_at(spec, north - mid_row * fine.1, (fine.1, fine.0))?
        }
        None => (to_f32(fine.1), to_f32(fine.0)),
    };
    let geo = if geographic {
        GeoExtent::of_grid((west, north), fine, (width, height))
    } else {
        None
    };
    Ok(Layout {
        geo,
        grid: RowGrid {
            width,
            height,
            spacing,
            ew_spacing,
            origin: (0.0, 0.0),
            path: spec.to_path_buf(),
        },
        tiles,
    })
}

/// Moves geographic tiles by whole turns of longitude so that the mosaic is cut where the globe has the
/// widest band of longitudes without a tile: tiles on both sides of the antimeridian (`N00E179.hgt` and
/// `N00W180.hgt`) lie side by side, 2 degrees wide rather than 360, their longitudes running on past 180
/// east. Tiles given in 0..360 degrees join those given in -180..180 alike. A mosaic that the cut leaves
/// as given (the widest empty band is the one across the antimeridian) is not moved at all.
fn unwrap_longitudes(metas: &mut [TileMeta]) {
    // Each tile's sample columns as an interval of longitude from its west sample, that in 0..360.
    let mut spans: Vec<(f64, f64)> = metas
        .iter()
        .map(|m| {
            let a = m.first.0.rem_euclid(360.0);
            (a, a + m.step.0 * f64::from(m.size.0.saturating_sub(1)))
        })
        .collect();
    spans.sort_by(|x, y| x.0.total_cmp(&y.0));
    let Some(&(first, _)) = spans.first() else {
        return;
    };
    // The widest gap between the intervals in order, the one from the last round to the first included.
    let reach = spans.iter().map(|s| s.1).fold(f64::MIN, f64::max);
    let (mut west, mut widest) = (first, first + 360.0 - reach);
    let mut end = f64::MIN;
    for &(a, b) in &spans {
        if end > f64::MIN && a - end > widest {
            (west, widest) = (a, a - end);
        }
        end = end.max(b);
    }
    // West of the cut in -180..180.
    if west >= 180.0 {
        west -= 360.0;
    }
    for m in metas {
        let lon = west + (m.first.0 - west).rem_euclid(360.0);
        let turns = ((lon - m.first.0) / 360.0).round();
        if turns != 0.0 {
            m.first.0 += turns * 360.0;
        }
    }
}

/// The georeference of heights that are a tile mosaic or one SRTM `.hgt` tile, for placing GeoTIFF imagery
/// by it (`source::heights_georef`): the mosaic's grid (its finest spacing from its north-west sample) or
/// the tile's, in the tiles' coordinate system. `None` where the heights cannot be placed (a tile not named
/// by its corner, a mosaic refused).
pub(crate) fn georef(spec: &Path) -> Option<GeoRef> {
    let (size, step, first, crs) = if is_mosaic(spec) {
        let l = layout(spec, &LoadOptions::default()).ok()?;
        let step = l.tiles.iter().fold((f64::MAX, f64::MAX), |(x, y), t| {
            (x.min(t.meta.step.0), y.min(t.meta.step.1))
        });
        let west = l.tiles.iter().map(|t| t.meta.first.0).fold(f64::MAX, f64::min);
        let north = l.tiles.iter().map(|t| t.meta.first.1).fold(f64::MIN, f64::max);
        let crs = l.tiles.first()?.meta.crs;
        ((l.grid.width, l.grid.height), step, (west, north), crs)
    } else {
        let m = TileMeta::read(spec).ok()?;
        (m.size, m.step, m.first, m.crs)
    };
    // GeographicTypeGeoKey or ProjectedCSTypeGeoKey, as `GeoRef::read` names them.
    let key = if crs.geographic { 2048 } else { 3072 };
    Some(GeoRef {
        size,
        scale: step,
        corner: (first.0 - 0.5 * step.0, first.1 + 0.5 * step.1),
        crs: crs.epsg.map(|code| (key, code)),
        geographic: Some(crs.geographic),
    })
}

/// Opens the mosaic `spec` names to be read a band of rows at a time: out of core where every sample
/// has data (or [`LoadOptions::fill_height`] gives one); otherwise, its no-data samples are filled from
/// their neighbours over the whole grid, as a single file's voids are, and it is read whole.
pub(crate) fn open_rows(spec: &Path, opts: &LoadOptions) -> Result<Box<dyn RowSource>> {
    let mut mosaic = Mosaic::new(layout(spec, opts)?, opts);
    if opts.fill_height.is_some() || !mosaic.has_no_data()? {
        mosaic.refuse_no_data();
        return Ok(Box::new(mosaic));
    }
    Ok(Box::new(super::Resident::new(whole(mosaic)?)))
}

/// Where the mosaic `spec` names lies on the globe (None: tiles in a projected system), from its tiles'
/// headers alone.
pub(crate) fn geo(spec: &Path, opts: &LoadOptions) -> Result<Option<GeoExtent>> {
    Ok(layout(spec, opts)?.geo)
}

/// Loads the mosaic `spec` names whole.
pub(crate) fn load(spec: &Path, opts: &LoadOptions) -> Result<Heightmap> {
    let layout = layout(spec, opts)?;
    let geo = layout.geo;
    Ok(whole(Mosaic::new(layout, opts))?.with_geo(geo))
}

/// Whether every tile of the mosaic `spec` holds whole numbers by its sample type (an SRTM tile, an
/// integer GeoTIFF) at the grid's own spacing (a coarser tile is interpolated between them): a package
/// set's quantum follows it, the same whichever tile a bake reads first.
pub(crate) fn integer_tiles(spec: &Path, opts: &LoadOptions) -> Result<bool> {
    let l = layout(spec, opts)?;
    Ok(l.tiles.iter().all(|t| {
        let fine = t.k == (1.0, 1.0);
        fine && (t.meta.hgt || integer_tiff(&t.meta.path))
    }))
}

/// Whether a TIFF's samples are integers (SampleFormat 1 or 2, the default 1), read from its header.
fn integer_tiff(path: &Path) -> bool {
    let Ok(file) = std::fs::File::open(path) else {
        return false;
    };
    let Ok(mut dec) = tiff::decoder::Decoder::new(std::io::BufReader::new(file)) else {
        return false;
    };
    match dec.find_tag(tiff::tags::Tag::SampleFormat) {
        Ok(None) => true,
        Ok(Some(v)) => v.into_u16_vec().is_ok_and(|f| f.iter().all(|&f| f == 1 || f == 2)),
        Err(_) => false,
    }
}

/// A tile's file and its rectangle on the mosaic's grid: first and last column and row, inclusive.
pub(crate) type TileRect = (PathBuf, [u32; 4]);

/// A tile mosaic's grid and each tile's rectangle on it (first and last column and row, inclusive), in
/// the order the mosaic reads them: the cells of a package set (`package::set_bake`).
pub(crate) fn cells(spec: &Path, opts: &LoadOptions) -> Result<(RowGrid, Vec<TileRect>)> {
    let l = layout(spec, opts)?;
    let tiles = l
        .tiles
        .iter()
        .map(|t| (t.meta.path.clone(), [t.col0, t.row0, t.col1, t.row1]))
        .collect();
    Ok((l.grid, tiles))
}

/// The grid rectangle `[x0, y0, x1, y1]` (inclusive) of the mosaic `spec`, read from the tiles `sources`
/// alone (all that reach it where `None`); samples with no data are [`LoadOptions::fill_height`], or
/// filled from their neighbours inside the rectangle (as one file's voids are). The last column and row,
/// where none of the sources reaches them (tiles that abut rather than share their edges) and they are
/// not the grid's, repeat the ones before: a package set's cell reads its own tiles alone.
pub(crate) fn window(
    spec: &Path,
    opts: &LoadOptions,
    [x0, y0, x1, y1]: [u32; 4],
    sources: Option<&[PathBuf]>,
) -> Result<Heightmap> {
    let mut l = layout(spec, opts)?;
    if x1 >= l.grid.width || y1 >= l.grid.height || x0 >= x1 || y0 >= y1 {
        return Err(Error::format(
            spec,
            format!("no rectangle {x0}..={x1} x {y0}..={y1} in the grid"),
        ));
    }
    l.tiles.retain(|t| {
        t.col0 <= x1
            && t.col1 >= x0
            && t.row0 <= y1
            && t.row1 >= y0
            && sources.is_none_or(|s| s.contains(&t.meta.path))
    });
    let reach = |x: u32, y: u32| {
        l.tiles
            .iter()
            .any(|t| t.col0 <= x && x <= t.col1 && t.row0 <= y && y <= t.row1)
    };
    // Not at the grid's last column or row: the mosaic's samples there (a seam past a coarser tile's
    // east or south sample, the fill height) are level 0's, and no next part holds them.
    let (last_x, last_y) = (x1 + 1 == l.grid.width, y1 + 1 == l.grid.height);
    let edge_x: Vec<bool> = (y0..=y1).map(|y| !last_x && !reach(x1, y)).collect();
    let edge_y: Vec<bool> = (x0..=x1).map(|x| !last_y && !reach(x, y1)).collect();
    let g = l.grid.clone();
    let mut mosaic = Mosaic::new(l, opts);
    let (gw, w, h) = (
        g.width as usize,
        (x1 - x0 + 1) as usize,
        (y1 - y0 + 1) as usize,
    );
    let mut heights = super::zeroed_samples(&g.path, w * h)?;
    let mut band = vec![0f32; gw * rows::BAND_ROWS as usize];
    let mut y = y0;
    while y <= y1 {
        let n = rows::BAND_ROWS.min(y1 - y + 1);
        let band = &mut band[..gw * n as usize];
        mosaic.read_rows(y, band)?;
        for (r, row) in band.chunks_exact(gw).enumerate() {
            let at = ((y - y0) as usize + r) * w;
            heights[at..at + w].copy_from_slice(&row[x0 as usize..=x1 as usize]);
        }
        y += n;
    }
    for (r, &far) in edge_x.iter().enumerate() {
        if far {
            heights[r * w + w - 1] = heights[r * w + w - 2];
        }
    }
    for (c, &far) in edge_y.iter().enumerate() {
        if far {
            heights[(h - 1) * w + c] = heights[(h - 2) * w + c];
        }
    }
    let voids = if heights.iter().any(|v| v.is_nan()) {
        fill_voids(&g.path, w, &mut heights)?
    } else {
        0
    };
    Ok(
        Heightmap::new(&g.path, x1 - x0 + 1, y1 - y0 + 1, g.spacing, heights)?
            .with_voids_filled(voids)
            .with_ew_spacing(g.ew_spacing),
    )
}

/// Every row of `mosaic`, its no-data samples filled from their neighbours.
fn whole(mut mosaic: Mosaic) -> Result<Heightmap> {
    let g = mosaic.grid().clone();
    let w = g.width as usize;
    let mut heights = super::zeroed_samples(&g.path, w * g.height as usize)?;
    for (i, band) in heights.chunks_mut(w * rows::BAND_ROWS as usize).enumerate() {
        let y0 = u32::try_from(i).unwrap_or(u32::MAX).saturating_mul(rows::BAND_ROWS);
        mosaic.read_rows(y0, band)?;
    }
    let voids = fill_voids(&g.path, w, &mut heights)?;
    Ok(
        Heightmap::new(&g.path, g.width, g.height, g.spacing, heights)?
            .with_voids_filled(voids)
            .with_ew_spacing(g.ew_spacing),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mosaic_names() {
        assert!(is_mosaic(Path::new("tiles/*.hgt")));
        assert!(is_mosaic(Path::new("/")));
        assert!(!is_mosaic(Path::new("no/such/file.hgt")));
    }
}
