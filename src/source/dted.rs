//! Stage 0, the source: DTED level 0, 1 and 2 cells (`.dt0`/`.dt1`/`.dt2`, MIL-PRF-89020B), the
//! elevation format of military and flight simulators.
//!
//! Read by hand rather than through the `dted2` crate (the one DTED reader on crates.io): it skips the
//! records' checksums, so a damaged cell would load silently, and its errors are parser codes that name
//! neither the record nor the field. Here every data record's sentinel, counts and checksum are checked and
//! a bad one is named by its column.

use std::path::Path;

use super::{
    check_size, fill_voids, height, metres_per_degree_latitude, metres_per_degree_longitude,
    to_f32, LoadOptions,
};
use crate::{Error, Result};
use crate::source::Heightmap;

/// The user header label's first bytes.
pub(super) const MAGIC: &[u8; 4] = b"UHL1";

/// Bytes of the user header label (UHL), data set identification (DSI) and accuracy description (ACC)
/// records before the first data record.
const UHL: usize = 80;
const DSI: usize = 648;
const ACC: usize = 2700;

/// A data record's sentinel byte (octal 252).
const SENTINEL: u8 = 0xAA;

/// The void marker, -32767 in signed magnitude.
const VOID: i32 = -32767;

/// A header field: `len` ASCII characters at `at`, trimmed.
fn field<'a>(path: &Path, bytes: &'a [u8], at: usize, len: usize, what: &str) -> Result<&'a str> {
    bytes
        .get(at..at + len)
        .and_then(|b| std::str::from_utf8(b).ok())
        .map(str::trim)
        .ok_or_else(|| Error::format(path, format!("the DTED header's {what} is not ASCII text")))
}

/// A header number.
fn number(path: &Path, bytes: &[u8], at: usize, len: usize, what: &str) -> Result<u32> {
    let f = field(path, bytes, at, len, what)?;
    f.parse().map_err(|_| {
        Error::format(
            path,
            format!("the DTED header's {what} `{f}` is not a number"),
        )
    })
}

/// A latitude or longitude `DDDMMSSH` (degrees, minutes, seconds, hemisphere), degrees.
fn angle(path: &Path, bytes: &[u8], at: usize, what: &str) -> Result<f64> {
    let f = field(path, bytes, at, 8, what)?;
    let bad = || {
        Error::format(
            path,
            format!("the DTED header's {what} `{f}` is not DDDMMSSH"),
        )
    };
    let (digits, hemi) = f.split_at(f.len().checked_sub(1).ok_or_else(bad)?);
    let sign = match hemi {
        "N" | "E" => 1.0,
        "S" | "W" => -1.0,
        _ => return Err(bad()),
    };
    if digits.len() != 7 || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return Err(bad());
    }
    let n = |r: std::ops::Range<usize>| digits[r].parse::<f64>().map_err(|_| bad());
    Ok(sign * (n(0..3)? + n(3..5)? / 60.0 + n(5..7)? / 3600.0))
}

/// Loads a DTED cell: its records are columns, west to east, each from south to north, of signed-magnitude
/// big-endian metres; -32767 marks a void, filled from its neighbours and counted. The spacing comes from
/// the header's intervals (tenths of an arc-second) at the cell's middle latitude; E-W is recorded
/// ([`Heightmap::ew_spacing`]; DTED itself widens the longitude interval at high latitudes).
/// [`LoadOptions::spacing`] overrides it; [`LoadOptions::height_scale`] (default 1) and the offset apply.
pub(super) fn load(path: &Path, len: u64, opts: &LoadOptions) -> Result<Heightmap> {
    let head_len = UHL + DSI + ACC;
    let mut head = vec![0u8; head_len];
    {
        use std::io::Read;
        let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot open", e))?;
        f.read_exact(&mut head).map_err(|_| {
            Error::format(
                path,
                format!("truncated DTED cell: under {head_len} header bytes"),
            )
        })?;
    }
    if !head.starts_with(MAGIC) {
        return Err(Error::format(
            path,
            "not a DTED cell: it does not start with the user header label `UHL1`",
        ));
    }
    if &head[UHL..UHL + 3] != b"DSI" || &head[UHL + DSI..UHL + DSI + 3] != b"ACC" {
        return Err(Error::format(
            path,
            "damaged DTED cell: the DSI and ACC records are not where the standard puts them",
        ));
    }
    // The cell is placed at the origin like every source; its longitude is reported (`GeoExtent`).
    let lon0 = angle(path, &head, 4, "longitude of origin")?;
    let lat0 = angle(path, &head, 12, "latitude of origin")?;
    let lon_int = number(path, &head, 20, 4, "longitude interval")?;
    let lat_int = number(path, &head, 24, 4, "latitude interval")?;
    let cols = number(path, &head, 47, 4, "number of longitude lines")?;
    let rows = number(path, &head, 51, 4, "number of latitude points")?;
    check_size(path, cols.into(), rows.into(), opts)?;
    if lon_int == 0 || lat_int == 0 {
        return Err(Error::format(path, "the DTED header gives a zero interval"));
    }
    let record = 12 + 2 * rows as usize;
    let expected = head_len as u64 + u64::from(cols) * record as u64;
    if len < expected {
        return Err(Error::SizeMismatch {
            path: path.into(),
            actual: len,
            expected: format!("at least {expected} bytes ({cols} columns of {rows} points)"),
        });
    }
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, "cannot read", e))?;
    let data = bytes.get(head_len..).unwrap_or_default();
    if (data.len() as u64) < expected - head_len as u64 {
        return Err(Error::SizeMismatch {
            path: path.into(),
            actual: bytes.len() as u64,
            expected: format!("{len} bytes (the length when first checked)"),
        });
    }
    let (w, h) = (cols as usize, rows as usize);
    let mut heights = super::zeroed_samples(path, w * h)?;
    let (scale, offset) = (
        opts.height_scale.map_or(1.0, f64::from),
        f64::from(opts.height_offset),
    );
    for (x, rec) in data.chunks_exact(record).take(w).enumerate() {
        let bad =
            |why: String| Error::format(path, format!("damaged DTED cell: column {x}: {why}"));
        if rec[0] != SENTINEL {
            return Err(bad(format!(
                "record sentinel {:#04x}, expected 0xaa",
                rec[0]
            )));
        }
        let lon_count = u16::from_be_bytes([rec[4], rec[5]]);
        if usize::from(lon_count) != x {
            return Err(bad(format!("the record says it is column {lon_count}")));
        }
        let body = record - 4;
        let sum: u32 = rec[..body].iter().map(|&b| u32::from(b)).sum();
        let stored = u32::from_be_bytes([rec[body], rec[body + 1], rec[body + 2], rec[body + 3]]);
        if sum != stored {
            return Err(bad(format!(
                "checksum {stored:#x}, the bytes sum to {sum:#x}"
            )));
        }
        for (k, c) in rec[8..body].chunks_exact(2).enumerate() {
            let raw = u16::from_be_bytes([c[0], c[1]]);
            let v = i32::from(raw & 0x7fff) * if raw & 0x8000 != 0 { -1 } else { 1 };
            // Points run south to north; row 0 is north.
            let y = h - 1 - k;
            let void = v == VOID || super::is_nodata(opts.nodata, f64::from(v));
            heights[y * w + x] = height(path, f64::from(v), void, scale, offset, (x, y))?;
        }
    }
    drop(bytes);
    let filled = fill_voids(path, w, &mut heights)?;
    let (spacing, ew) = match opts.spacing {
        Some(s) => (s, s),
        None => {
            let (dlat, dlon) = (f64::from(lat_int) / 36_000.0, f64::from(lon_int) / 36_000.0);
            let lat = (lat0 + f64::from(rows - 1) * dlat * 0.5).clamp(-90.0, 90.0);
            (
                to_f32(dlat * metres_per_degree_latitude(lat)),
                to_f32(dlon * metres_per_degree_longitude(lat)),
            )
        }
    };
    let (dlat, dlon) = (f64::from(lat_int) / 36_000.0, f64::from(lon_int) / 36_000.0);
    // The origin is the south-west sample.
    let north = lat0 + f64::from(rows - 1) * dlat;
    let geo = super::GeoExtent::of_grid((lon0, north), (dlon, dlat), (cols, rows));
    Ok(Heightmap::new(path, cols, rows, spacing, heights)?
        .with_voids_filled(filled)
        .with_ew_spacing(ew)
        .with_geo(geo))
}
