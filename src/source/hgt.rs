//! Stage 0, the source: SRTM `.hgt` tiles (headerless big-endian int16, 1201^2 or 3601^2, void = -32768).

use std::path::Path;

use super::{
    check_size, fill_voids, metres_per_degree_latitude, metres_per_degree_longitude, to_f32,
    LoadOptions,
};
use crate::{Error, Result};
use crate::source::Heightmap;

/// SRTM's void marker.
const VOID: i16 = -32768;

/// An SRTM file's samples a side and sample spacing in arc-seconds, from its length: 1201 (SRTM3, 3") or
/// 3601 (SRTM1, 1"); any other length is refused.
pub(super) fn tile_side(path: &Path, len: u64) -> Result<(u32, f64)> {
    match len {
        2_884_802 => Ok((1201u32, 3.0)),
        25_934_402 => Ok((3601u32, 1.0)),
        _ => Err(Error::SizeMismatch {
            path: path.into(),
            actual: len,
            expected: "2884802 bytes (SRTM3, 1201 x 1201 int16) or 25934402 bytes \
                       (SRTM1, 3601 x 3601 int16)"
                .into(),
        }),
    }
}

/// Loads an SRTM tile; the side (1201 for 3", 3601 for 1") follows from the file length.
///
/// Cells are square here, with the N-S spacing: 3 or 1 arc-seconds of meridian arc in metres at the
/// tile's centre latitude (read from a name like `N57E011`; the equator if the name says nothing). The
/// true E-W spacing, about that times cos(latitude), is recorded ([`Heightmap::ew_spacing`]): a tile far
/// from the equator is drawn stretched E-W unless [`LoadOptions::resample_ew`]. [`LoadOptions::spacing`]
/// overrides both. Voids are filled from their neighbours and counted.
pub(super) fn load(path: &Path, len: u64, opts: &LoadOptions) -> Result<Heightmap> {
    let (side, arcsec) = tile_side(path, len)?;
    check_size(path, side.into(), side.into(), opts)?;
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, "cannot read", e))?;
    if bytes.len() as u64 != len {
        return Err(Error::SizeMismatch {
            path: path.into(),
            actual: bytes.len() as u64,
            expected: format!("{len} bytes (the length when first checked)"),
        });
    }
    let mut heights: Vec<f32> = bytes
        .chunks_exact(2)
        .map(|c| match i16::from_be_bytes([c[0], c[1]]) {
            VOID => f32::NAN,
            v if super::is_nodata(opts.nodata, f64::from(v)) => f32::NAN,
            v => f32::from(v),
        })
        .collect();
    drop(bytes);
    let voids = fill_voids(path, side as usize, &mut heights)?;
    let lat = latitude_from_name(path).map_or(0.0, |south| south + 0.5);
    let (spacing, ew) = match opts.spacing {
        Some(s) => (s, s),
        None => (
            to_f32(metres_per_degree_latitude(lat) * arcsec / 3600.0),
            to_f32(metres_per_degree_longitude(lat) * arcsec / 3600.0),
        ),
    };
    // Placed by its name alone (without one, where it lies is unknown).
    let step = 1.0 / f64::from(side - 1);
    let geo = super::geo::hgt_corner(path)
        .and_then(|(s, w)| super::GeoExtent::of_grid((w, s + 1.0), (step, step), (side, side)));
    Ok(Heightmap::new(path, side, side, spacing, heights)?
        .with_voids_filled(voids)
        .with_ew_spacing(ew)
        .with_geo(geo))
}

/// The south edge latitude of a tile named like `N57E011` or `s12w077`, degrees.
fn latitude_from_name(path: &Path) -> Option<f64> {
    let stem = path.file_stem()?.to_str()?;
    let b = stem.as_bytes();
    let sign = match b.first()?.to_ascii_uppercase() {
        b'N' => 1.0,
        b'S' => -1.0,
        _ => return None,
    };
    let digits = stem.get(1..3)?;
    let lat: u8 = digits.parse().ok()?;
    (lat <= 90).then_some(sign * f64::from(lat))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn latitude_names() {
        assert_eq!(latitude_from_name(Path::new("a/N57E011.hgt")), Some(57.0));
        assert_eq!(latitude_from_name(Path::new("s12w077.hgt")), Some(-12.0));
        assert_eq!(latitude_from_name(Path::new("tile.hgt")), None);
    }
}
