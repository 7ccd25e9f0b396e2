//! Stage 0, the source: ESRI ASCII grids (`.asc`, GDAL's AAIGrid): a header of `key value` lines, then
//! the samples as decimal numbers, row by row from north to south.

use std::io::BufRead;
use std::path::Path;

use super::{
    check_size, fill_voids, to_f32,
    GeoExtent, LoadOptions,
};
use crate::{Error, Result};
use crate::source::Heightmap;

/// The header: sizes, the lower-left reference, the cell size and the void marker.
#[derive(Debug, Default)]
struct Header {
    ncols: Option<u64>,
    nrows: Option<u64>,
    /// West edge (`xllcorner`) or west column's centre (`xllcenter`), in the grid's units.
    xll: Option<(f64, bool)>,
    /// South edge (`yllcorner`) or south row's centre (`yllcenter`), in the grid's units.
    yll: Option<(f64, bool)>,
    cellsize: Option<f64>,
    /// GDAL writes `dx`/`dy` for cells that are not square.
    dx: Option<f64>,
    dy: Option<f64>,
    nodata: Option<f64>,
}

/// Smallest cell size taken as metres when no `.prj` says the grid is in degrees: a grid this fine in
/// metres is not terrain, but one in degrees (3 arc-seconds is 0.00083) is common.
const MIN_METRES: f64 = 0.01;

/// Loads an ESRI ASCII grid, reading it line by line (the text is never held whole).
///
/// Keys are case-insensitive: `ncols`, `nrows`, `xllcorner`/`xllcenter`, `yllcorner`/`yllcenter`,
/// `cellsize` (or `dx` and `dy`) and the optional `NODATA_value`, whose samples are voids, filled from
/// their neighbours and counted. Cells are drawn square with the N-S size (the E-W one is recorded,
/// [`Heightmap::ew_spacing`]). A `.prj` beside the file whose WKT is geographic (`GEOGCS` or `GEOGCRS`
/// with no projection) puts the cell sizes in degrees: metres of meridian arc and of the parallel at the
/// grid's centre latitude. Without a `.prj`, a cell size under 1 cm is refused as probably degrees.
/// [`LoadOptions::spacing`] overrides all of this.
pub(super) fn load(path: &Path, opts: &LoadOptions) -> Result<Heightmap> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot open", e))?;
    let mut reader = std::io::BufReader::new(file);
    let mut line = String::new();
    let mut line_no = 0u64;
    let mut h = Header::default();
    // Header lines until the first line that starts with a number.
    loop {
        if !next_line(path, &mut reader, &mut line, &mut line_no)? {
            return Err(Error::format(
                path,
                "the ASCII grid has a header but no samples",
            ));
        }
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else {
            continue;
        };
        if key.parse::<f64>().is_ok() {
            break;
        }
        let value = words.next().ok_or_else(|| {
            Error::format(
                path,
                format!("line {line_no}: header key `{key}` has no value"),
            )
        })?;
        let num = || {
            value.parse::<f64>().map_err(|_| {
                Error::format(
                    path,
                    format!("line {line_no}: `{key}` value `{value}` is not a number"),
                )
            })
        };
        let count = || {
            value.parse::<u64>().map_err(|_| {
                Error::format(
                    path,
                    format!("line {line_no}: `{key}` value `{value}` is not a whole number"),
                )
            })
        };
        match key.to_ascii_lowercase().as_str() {
            "ncols" => h.ncols = Some(count()?),
            "nrows" => h.nrows = Some(count()?),
            "xllcorner" => h.xll = Some((num()?, false)),
            "xllcenter" => h.xll = Some((num()?, true)),
            "yllcorner" => h.yll = Some((num()?, false)),
            "yllcenter" => h.yll = Some((num()?, true)),
            "cellsize" => h.cellsize = Some(num()?),
            "dx" => h.dx = Some(num()?),
            "dy" => h.dy = Some(num()?),
            "nodata_value" => h.nodata = Some(num()?),
            _ => {
                return Err(Error::format(
                    path,
                    format!(
                        "line {line_no}: unknown ASCII grid header key `{key}` (expected ncols, nrows, \
                         xllcorner, yllcorner, cellsize, NODATA_value)"
                    ),
                ))
            }
        }
    }
    let missing = |key: &str| Error::format(path, format!("the ASCII grid header has no `{key}`"));
    let (width, height) = (
        h.ncols.ok_or_else(|| missing("ncols"))?,
        h.nrows.ok_or_else(|| missing("nrows"))?,
    );
    let samples = check_size(path, width, height, opts)?;
    let cell = h.dy.or(h.cellsize).ok_or_else(|| missing("cellsize"))?;
    if !(cell.is_finite() && cell > 0.0) {
        return Err(Error::format(
            path,
            format!("cell size {cell} is not a positive number"),
        ));
    }
    // Every sample takes at least two bytes of text ("0 "), so a header declaring more than the file can
    // hold reserves no more than the file's size (the count is checked at the end).
    let text_bytes = std::fs::metadata(path).map_or(0, |m| m.len());
    let mut heights: Vec<f32> =
        Vec::with_capacity(samples.min(usize::try_from(text_bytes / 2).unwrap_or(usize::MAX)));
    let mut voids = false;
    let (scale, offset) = (
        opts.height_scale.map_or(1.0, f64::from),
        f64::from(opts.height_offset),
    );
    // The first sample line is already in `line`.
    loop {
        for word in line.split_whitespace() {
            let v: f64 = word.parse().map_err(|_| {
                Error::format(
                    path,
                    format!("line {line_no}: sample `{word}` is not a number"),
                )
            })?;
            let i = heights.len();
            if i == samples {
                return Err(Error::format(
                    path,
                    format!("line {line_no}: more samples than ncols x nrows = {width} x {height}"),
                ));
            }
            let void = super::is_nodata(opts.nodata.or(h.nodata), v);
            voids |= void;
            let w = usize::try_from(width).unwrap_or(usize::MAX);
            heights.push(super::height(path, v, void, scale, offset, (i % w, i / w))?);
        }
        if !next_line(path, &mut reader, &mut line, &mut line_no)? {
            break;
        }
    }
    if heights.len() != samples {
        return Err(Error::format(
            path,
            format!(
                "{} samples where the header says {width} x {height} = {samples} (truncated file?)",
                heights.len()
            ),
        ));
    }
    let filled = if voids {
        fill_voids(
            path,
            usize::try_from(width).unwrap_or(usize::MAX),
            &mut heights,
        )?
    } else {
        0
    };
    let (spacing, ew) = match opts.spacing {
        Some(s) => (s, s),
        None => spacing(
            path,
            (h.dx.or(h.cellsize).unwrap_or(cell), cell),
            h.yll,
            height,
        )?,
    };
    // check_size bounded both sides by the sample limit, itself far under u32::MAX here.
    let (w, hh) = (
        u32::try_from(width).map_err(|_| Error::format(path, "ncols does not fit 32 bits"))?,
        u32::try_from(height).map_err(|_| Error::format(path, "nrows does not fit 32 bits"))?,
    );
    let cells = (h.dx.or(h.cellsize).unwrap_or(cell), cell);
    Ok(Heightmap::new(path, w, hh, spacing, heights)?
        .with_voids_filled(filled)
        .with_ew_spacing(ew)
        .with_geo(geo_extent(path, cells, (h.xll, h.yll), (w, hh))))
}

/// Reads the next line of `reader` into `line` (replacing it) and counts it; false at the end.
pub(super) fn next_line(
    path: &Path,
    reader: &mut impl BufRead,
    line: &mut String,
    line_no: &mut u64,
) -> Result<bool> {
    line.clear();
    let n = reader
        .read_line(line)
        .map_err(|e| Error::io(path, "cannot read", e))?;
    *line_no += 1;
    Ok(n > 0)
}

/// A grid's west or south edge, or (`true`) the centre of its first sample that way, in its units.
pub(super) type Edge = Option<(f64, bool)>;

/// Whether a `.prj`'s WKT is geographic: `GEOGCS` or `GEOGCRS` with no projection.
fn geographic_wkt(wkt: &str) -> bool {
    let wkt = wkt.to_ascii_uppercase();
    (wkt.contains("GEOGCS") || wkt.contains("GEOGCRS"))
        && !wkt.contains("PROJCS")
        && !wkt.contains("PROJCRS")
}

/// Where a `size` (columns, rows) grid of cell sizes `(dx, dy)` lies, degrees, where a `.prj` beside
/// `path` is geographic (as [`spacing`] reads it): `ll` is its west and south edges, or (`true`) its
/// south-west sample's centre; None without them.
pub(super) fn geo_extent(
    path: &Path,
    (dx, dy): (f64, f64),
    ll: (Edge, Edge),
    size: (u32, u32),
) -> Option<GeoExtent> {
    let (Some(x), Some(y)) = ll else {
        return None;
    };
    let prj = std::fs::read_to_string(path.with_extension("prj")).ok()?;
    if !geographic_wkt(&prj) {
        return None;
    }
    let centre = |(v, at_centre): (f64, bool), d: f64| if at_centre { v } else { v + 0.5 * d };
    let (west, south) = (centre(x, dx), centre(y, dy));
    let north = south + dy * f64::from(size.1.saturating_sub(1));
    GeoExtent::of_grid((west, north), (dx, dy), size)
}

/// The (N-S, E-W) spacing in metres from the cell sizes `(dx, dy)`: in degrees (of meridian arc and of
/// the parallel at the grid's centre) where a `.prj` beside the file is geographic.
pub(super) fn spacing(
    path: &Path,
    (dx, dy): (f64, f64),
    yll: Option<(f64, bool)>,
    rows: u64,
) -> Result<(f32, f32)> {
    let prj = std::fs::read_to_string(path.with_extension("prj")).ok();
    let geographic = prj.as_deref().is_some_and(geographic_wkt);
    #[expect(clippy::cast_precision_loss, reason = "a row count, far below 2^53")]
    let rows = rows as f64;
    if geographic {
        let lat = yll.map_or(0.0, |(y, centre)| {
            if centre {
                y + (rows - 1.0) * dy * 0.5
            } else {
                y + rows * dy * 0.5
            }
        });
        return super::geo::spacing_at(path, lat, (dy, dx));
    }
    if prj.is_none() && dy < MIN_METRES {
        return Err(Error::format(
            path,
            format!(
                "cell size {dy} is under 1 cm: in degrees? No .prj beside the file says so; give the \
                 spacing in metres with `LoadOptions::spacing`"
            ),
        ));
    }
    Ok((to_f32(dy), to_f32(dx)))
}
