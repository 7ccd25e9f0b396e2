//! Stage 0, the source: ESRI binary grids described by a `.hdr` beside them (GDAL's EHdr): GridFloat
//! (`.flt`, USGS NED's format) and one-band BIL (`.bil`; SRTM tiles from USGS EarthExplorer).

use std::path::Path;

use super::{check_size, fill_voids, height, GeoExtent, LoadOptions, RowGrid};
use crate::{Error, Result};
use crate::source::Heightmap;

/// How a sample is stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Unsigned,
    Signed,
    Float,
}

/// The `.hdr`'s description of the samples.
#[derive(Clone, Debug)]
struct Layout {
    width: u32,
    height: u32,
    /// Bytes per sample (1, 2, 4 or 8).
    bytes: usize,
    kind: Kind,
    big_endian: bool,
    /// Bytes before the first row.
    skip: u64,
    /// Bytes from one row's start to the next (at least `width * bytes`).
    row_bytes: u64,
    nodata: Option<f64>,
}

/// The header's keys this loader reads (values as written; keys lower-cased). Others are ignored, as GDAL
/// ignores them.
#[derive(Debug, Default)]
struct Keys {
    ncols: Option<String>,
    nrows: Option<String>,
    nbands: Option<String>,
    nbits: Option<String>,
    pixeltype: Option<String>,
    byteorder: Option<String>,
    skipbytes: Option<String>,
    totalrowbytes: Option<String>,
    nodata: Option<String>,
    /// GridFloat's lower-left corner and cell size.
    xllcorner: Option<String>,
    xllcenter: Option<String>,
    yllcorner: Option<String>,
    yllcenter: Option<String>,
    cellsize: Option<String>,
    /// BIL's upper-left sample centre and cell sizes.
    ulxmap: Option<String>,
    ulymap: Option<String>,
    xdim: Option<String>,
    ydim: Option<String>,
}

/// Reads the `.hdr` beside `path`.
fn read_keys(path: &Path) -> Result<Keys> {
    let hdr = path.with_extension("hdr");
    let text = std::fs::read_to_string(&hdr).map_err(|e| {
        Error::io(
            &hdr,
            "cannot read the header an ESRI binary grid needs beside it",
            e,
        )
    })?;
    if text.trim_start().starts_with("ENVI") {
        return Err(Error::format(
            &hdr,
            "an ENVI header, not an ESRI one: convert the grid to GeoTIFF (gdal_translate)",
        ));
    }
    let mut k = Keys::default();
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let (Some(key), value) = (words.next(), words.next()) else {
            continue;
        };
        let slot = match key.to_ascii_lowercase().as_str() {
            "ncols" => &mut k.ncols,
            "nrows" => &mut k.nrows,
            "nbands" => &mut k.nbands,
            "nbits" => &mut k.nbits,
            "pixeltype" => &mut k.pixeltype,
            "byteorder" => &mut k.byteorder,
            "skipbytes" => &mut k.skipbytes,
            "totalrowbytes" => &mut k.totalrowbytes,
            "nodata" | "nodata_value" => &mut k.nodata,
            "xllcorner" => &mut k.xllcorner,
            "xllcenter" => &mut k.xllcenter,
            "yllcorner" => &mut k.yllcorner,
            "yllcenter" => &mut k.yllcenter,
            "cellsize" => &mut k.cellsize,
            "ulxmap" => &mut k.ulxmap,
            "ulymap" => &mut k.ulymap,
            "xdim" => &mut k.xdim,
            "ydim" => &mut k.ydim,
            _ => continue,
        };
        let value = value.ok_or_else(|| {
            Error::format(
                &hdr,
                format!("line {}: header key `{key}` has no value", n + 1),
            )
        })?;
        *slot = Some(value.to_owned());
    }
    Ok(k)
}

/// Parses header value `v` of `key` as a `what`, naming all three when it is not one.
fn parse<T: std::str::FromStr>(path: &Path, key: &str, v: &str, what: &str) -> Result<T> {
    v.parse().map_err(|_| {
        Error::format(
            path.with_extension("hdr"),
            format!("`{key}` value `{v}` is not a valid {what}"),
        )
    })
}

/// A count or size in the header.
fn count<T: std::str::FromStr>(path: &Path, key: &str, v: &str) -> Result<T> {
    parse(path, key, v, "whole number")
}

/// A number in the header.
fn number(path: &Path, key: &str, v: &str) -> Result<f64> {
    parse(path, key, v, "number")
}

/// The layout from the header, checked against the file's length `len`.
fn layout(path: &Path, len: u64, k: &Keys, opts: &LoadOptions) -> Result<Layout> {
    let hdr = path.with_extension("hdr");
    let missing = |key: &str| Error::format(&hdr, format!("the header has no `{key}`"));
    let flt = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("flt"));
    let width: u64 = count(
        path,
        "ncols",
        k.ncols.as_deref().ok_or_else(|| missing("ncols"))?,
    )?;
    let height: u64 = count(
        path,
        "nrows",
        k.nrows.as_deref().ok_or_else(|| missing("nrows"))?,
    )?;
    check_size(path, width, height, opts)?;
    if let Some(b) = &k.nbands {
        let bands: u64 = count(path, "nbands", b)?;
        if bands != 1 {
            return Err(Error::format(
                &hdr,
                format!(
                    "{bands} bands: a height grid has one (extract it with gdal_translate -b 1)"
                ),
            ));
        }
    }
    let bits: u32 = match &k.nbits {
        Some(b) => count(path, "nbits", b)?,
        None if flt => 32,
        None => 8,
    };
    let pixeltype = k.pixeltype.as_deref().map(str::to_ascii_lowercase);
    let kind = match pixeltype.as_deref() {
        _ if flt => Kind::Float,
        Some("float") => Kind::Float,
        Some("signedint") => Kind::Signed,
        // ESRI: unsigned unless PIXELTYPE says otherwise.
        Some("unsignedint") | None => Kind::Unsigned,
        Some(other) => {
            return Err(Error::format(
                &hdr,
                format!("PIXELTYPE `{other}`: expected SIGNEDINT, UNSIGNEDINT or FLOAT"),
            ))
        }
    };
    let bytes = match (kind, bits) {
        (Kind::Float, 32) => 4,
        (Kind::Float, 64) => 8,
        (Kind::Unsigned | Kind::Signed, 8 | 16 | 32) => bits as usize / 8,
        _ => {
            return Err(Error::format(
                &hdr,
                format!(
                    "{bits}-bit {kind:?} samples are not supported (8, 16 and 32-bit integers, \
                     32 and 64-bit floats are)"
                ),
            ))
        }
    };
    let order = k.byteorder.as_deref().map(str::to_ascii_uppercase);
    let big_endian =
        match order.as_deref() {
            Some("I" | "LSBFIRST") => false,
            Some("M" | "MSBFIRST") => true,
            None if bytes == 1 => false,
            Some(other) => {
                return Err(Error::format(
                    &hdr,
                    format!(
                    "BYTEORDER `{other}`: expected I or LSBFIRST (little-endian), M or MSBFIRST"
                ),
                ))
            }
            None => return Err(Error::format(
                &hdr,
                "the header gives no byte order: add `BYTEORDER I` (little-endian, as on x86) or \
                 `BYTEORDER M` (big-endian)",
            )),
        };
    let skip: u64 = match &k.skipbytes {
        Some(s) => count(path, "skipbytes", s)?,
        None => 0,
    };
    let packed = width * bytes as u64;
    let row_bytes: u64 = match &k.totalrowbytes {
        Some(s) => count(path, "totalrowbytes", s)?,
        None => packed,
    };
    if row_bytes < packed {
        return Err(Error::format(
            &hdr,
            format!("TOTALROWBYTES {row_bytes} is shorter than a row of {width} samples ({packed} bytes)"),
        ));
    }
    let nodata = match &k.nodata {
        _ if opts.nodata.is_some() => opts.nodata,
        Some(v) if v.eq_ignore_ascii_case("nan") => Some(f64::NAN),
        Some(v) => Some(number(path, "nodata", v)?),
        None => None,
    };
    // The last row need not carry its padding.
    let expected = (height - 1)
        .checked_mul(row_bytes)
        .and_then(|b| b.checked_add(skip)?.checked_add(packed));
    if expected != Some(len) && expected.is_none_or(|e| len < e) {
        return Err(Error::SizeMismatch {
            path: path.into(),
            actual: len,
            expected: format!(
                "at least {} bytes ({width} x {height}, {bits}-bit)",
                expected.unwrap_or(u64::MAX)
            ),
        });
    }
    let too_wide = |_| {
        Error::format(
            &hdr,
            format!("{width} x {height} samples do not fit 32 bits a side"),
        )
    };
    Ok(Layout {
        width: u32::try_from(width).map_err(too_wide)?,
        height: u32::try_from(height).map_err(too_wide)?,
        bytes,
        kind,
        big_endian,
        skip,
        row_bytes,
        nodata,
    })
}

/// The (N-S, E-W) spacing: [`LoadOptions::spacing`], else the header's cell sizes (in degrees where a
/// `.prj` says the grid is geographic, as for ASCII grids); and then where the grid lies, degrees.
fn spacing(
    path: &Path,
    k: &Keys,
    (cols, rows): (u32, u32),
    opts: &LoadOptions,
) -> Result<(f32, f32, Option<GeoExtent>)> {
    if let Some(s) = opts.spacing {
        return Ok((s, s, None));
    }
    let num =
        |key: &str, v: &Option<String>| v.as_deref().map(|v| number(path, key, v)).transpose();
    let (dx, dy, xll, yll) = if let Some(c) = num("cellsize", &k.cellsize)? {
        let xll = match (
            num("xllcorner", &k.xllcorner)?,
            num("xllcenter", &k.xllcenter)?,
        ) {
            (Some(x), _) => Some((x, false)),
            (None, Some(x)) => Some((x, true)),
            (None, None) => None,
        };
        let yll = match (
            num("yllcorner", &k.yllcorner)?,
            num("yllcenter", &k.yllcenter)?,
        ) {
            (Some(y), _) => Some((y, false)),
            (None, Some(y)) => Some((y, true)),
            (None, None) => None,
        };
        (c, c, xll, yll)
    } else {
        let (Some(dx), Some(dy)) = (num("xdim", &k.xdim)?, num("ydim", &k.ydim)?) else {
            return Err(Error::format(
                path.with_extension("hdr"),
                "the header gives no cell size (`cellsize`, or `xdim` and `ydim`): give the spacing in \
                 metres with `LoadOptions::spacing`",
            ));
        };
        // ULYMAP is the north-west sample's centre: the south row's centre lies rows - 1 cells south.
        let yll = num("ulymap", &k.ulymap)?.map(|y| (y - f64::from(rows - 1) * dy, true));
        let xll = num("ulxmap", &k.ulxmap)?.map(|x| (x, true));
        (dx, dy, xll, yll)
    };
    if !(dy.is_finite() && dy > 0.0 && dx.is_finite() && dx > 0.0) {
        return Err(Error::format(
            path.with_extension("hdr"),
            format!("cell size {dx} x {dy} is not positive"),
        ));
    }
    let (ns, ew) = super::asc::spacing(path, (dx, dy), yll, u64::from(rows))?;
    let geo = super::asc::geo_extent(path, (dx, dy), (xll, yll), (cols, rows));
    Ok((ns, ew, geo))
}

/// An ESRI binary grid read a band of rows at a time by positioned reads (the out-of-core bake's
/// source); voids come back NaN.
pub(super) struct Rows {
    file: std::fs::File,
    grid: RowGrid,
    layout: Layout,
    scale: f64,
    offset: f64,
    bytes: Vec<u8>,
    /// Where a grid in degrees lies.
    geo: Option<GeoExtent>,
}

impl Rows {
    pub(super) fn open(path: &Path, len: u64, opts: &LoadOptions) -> Result<Self> {
        let keys = read_keys(path)?;
        let layout = layout(path, len, &keys, opts)?;
        let (spacing, ew_spacing, geo) =
            spacing(path, &keys, (layout.width, layout.height), opts)?;
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot open", e))?;
        Ok(Self {
            file,
            grid: RowGrid {
                width: layout.width,
                height: layout.height,
                spacing,
                ew_spacing,
                origin: (0.0, 0.0),
                path: path.into(),
            },
            layout,
            scale: opts.height_scale.map_or(1.0, f64::from),
            offset: f64::from(opts.height_offset),
            bytes: Vec::new(),
            geo,
        })
    }

    /// The sample at `c` (its bytes) as a number.
    fn value(&self, c: &[u8]) -> f64 {
        let l = &self.layout;
        let mut b8 = [0u8; 8];
        b8[..l.bytes].copy_from_slice(c);
        if l.big_endian {
            b8[..l.bytes].reverse();
        }
        let b = [b8[0], b8[1], b8[2], b8[3]];
        match (l.kind, l.bytes) {
            (Kind::Float, 8) => f64::from_le_bytes(b8),
            (Kind::Float, _) => f64::from(f32::from_le_bytes(b)),
            (Kind::Unsigned, 1) => f64::from(b[0]),
            (Kind::Signed, 1) => f64::from(i8::from_le_bytes([b[0]])),
            (Kind::Unsigned, 2) => f64::from(u16::from_le_bytes([b[0], b[1]])),
            (Kind::Signed, 2) => f64::from(i16::from_le_bytes([b[0], b[1]])),
            (Kind::Unsigned, _) => f64::from(u32::from_le_bytes(b)),
            (Kind::Signed, _) => f64::from(i32::from_le_bytes(b)),
        }
    }
}

impl super::RowSource for Rows {
    fn grid(&self) -> &RowGrid {
        &self.grid
    }

    fn read_rows(&mut self, y0: u32, out: &mut [f32]) -> Result<()> {
        super::check_band(self, y0, out)?;
        let w = self.layout.width as usize;
        let packed = w * self.layout.bytes;
        let mut bytes = std::mem::take(&mut self.bytes);
        bytes.resize(packed, 0);
        for (r, row) in out.chunks_exact_mut(w).enumerate() {
            let y = u64::from(y0) + r as u64;
            let at = self.layout.skip + y * self.layout.row_bytes;
            super::rows::read_exact_at(&mut self.file, &self.grid.path, at, &mut bytes)?;
            for (x, (o, c)) in row
                .iter_mut()
                .zip(bytes.chunks_exact(self.layout.bytes))
                .enumerate()
            {
                let v = self.value(c);
                let void = super::is_nodata(self.layout.nodata, v);
                let at = (x, usize::try_from(y).unwrap_or(usize::MAX));
                *o = height(&self.grid.path, v, void, self.scale, self.offset, at)?;
            }
        }
        self.bytes = bytes;
        Ok(())
    }
}

/// Loads an ESRI binary grid whole, voids filled from their neighbours and counted.
///
/// The `.hdr` beside it gives `ncols`, `nrows`, the sample type (`NBITS`: 8, 16 or 32, or 64 for
/// floats; `PIXELTYPE`: `SIGNEDINT`, `UNSIGNEDINT` (ESRI's default) or `FLOAT`; a `.flt` is 32-bit
/// float), the byte order (`BYTEORDER` I/M or `byteorder` LSBFIRST/MSBFIRST; needed past 8 bits), and
/// optionally `SKIPBYTES`, `TOTALROWBYTES` and `NODATA`/`NODATA_value` ([`LoadOptions::nodata`] overrides
/// it). One band only. The spacing is `cellsize` or
/// `XDIM`/`YDIM`, in degrees where a `.prj` beside the file is geographic (as for ASCII grids);
/// [`LoadOptions::spacing`] overrides it. Heights are metres times [`LoadOptions::height_scale`] (1
/// by default) plus the offset.
pub(super) fn load(path: &Path, len: u64, opts: &LoadOptions) -> Result<Heightmap> {
    use super::RowSource;
    let mut rows = Rows::open(path, len, opts)?;
    let (w, h) = (rows.layout.width as usize, rows.layout.height);
    let mut heights = super::zeroed_samples(path, w * h as usize)?;
    rows.read_rows(0, &mut heights)?;
    let filled = fill_voids(path, w, &mut heights)?;
    Ok(
        Heightmap::new(path, rows.grid.width, h, rows.grid.spacing, heights)?
            .with_voids_filled(filled)
            .with_ew_spacing(rows.grid.ew_spacing)
            .with_geo(rows.geo),
    )
}

/// [`Rows`], or the whole grid from memory where it has voids (they are filled over the whole grid): a
/// grid with a nodata value is scanned for them first, a band at a time.
pub(super) fn open_rows(
    path: &Path,
    len: u64,
    opts: &LoadOptions,
) -> Result<Box<dyn super::RowSource>> {
    use super::RowSource;
    let mut rows = Rows::open(path, len, opts)?;
    if rows.layout.nodata.is_some() {
        let w = rows.layout.width as usize;
        let band = (1 << 20) / w.max(1);
        let band = band.clamp(1, rows.layout.height as usize);
        let mut buf = vec![0.0f32; band * w];
        let mut y = 0u32;
        while y < rows.layout.height {
            let n = (rows.layout.height - y).min(u32::try_from(band).unwrap_or(u32::MAX));
            let out = &mut buf[..n as usize * w];
            rows.read_rows(y, out)?;
            if out.iter().any(|v| v.is_nan()) {
                return Ok(Box::new(super::Resident::new(load(path, len, opts)?)));
            }
            y += n;
        }
    }
    Ok(Box::new(rows))
}
