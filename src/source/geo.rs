//! Stage 0, the source: where a geographic grid (degrees) lies on the globe, and how far the one metric
//! frame it is drawn in (an equirectangular projection about its middle row) is from true lengths away
//! from that row (docs/guide.md "Tile mosaics", "One metric frame").

use std::path::Path;

use super::{metres_per_degree_latitude, metres_per_degree_longitude};

/// A geographic grid's extent, degrees: the latitudes of its north and south sample rows, the longitudes
/// of its west and east sample columns, and the latitude its metres are taken at (its middle row: N-S
/// spacing the meridian arc there, E-W spacing the parallel's arc there).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GeoExtent {
    /// Latitude of row 0's samples.
    pub north: f64,
    /// Latitude of the last row's samples.
    pub south: f64,
    /// Longitude of column 0's samples.
    pub west: f64,
    /// Longitude of the last column's samples: past 180 for a grid across the antimeridian (a mosaic of
    /// `N00E179.hgt` and `N00W180.hgt` runs from 179 to 181), so that it is always east of `west`.
    pub east: f64,
    /// Latitude of the metric frame: the middle row's.
    pub frame_lat: f64,
}

impl GeoExtent {
    /// The extent of a `size` (columns, rows) grid whose sample (0, 0), the north-west one, lies at
    /// `first` (longitude, latitude) and whose samples are `step` (east, south) degrees apart; None for a
    /// grid that does not lie within -90..=90 degrees of latitude or has no finite extent.
    pub fn of_grid(first: (f64, f64), step: (f64, f64), size: (u32, u32)) -> Option<Self> {
        let east = first.0 + step.0 * f64::from(size.0.saturating_sub(1));
        let south = first.1 - step.1 * f64::from(size.1.saturating_sub(1));
        let e = Self {
            north: first.1,
            south,
            west: first.0,
            east,
            frame_lat: 0.5 * (first.1 + south),
        };
        let finite = [e.north, e.south, e.west, e.east].iter().all(|v| v.is_finite());
        (finite && e.south <= e.north && e.south >= -90.0 && e.north <= 90.0).then_some(e)
    }

    /// Drawn over true E-W length, less 1, at latitude `lat` ([`ew_length_error`] about the frame's).
    pub fn ew_error(&self, lat: f64) -> f64 {
        ew_length_error(self.frame_lat, lat)
    }

    /// Drawn over true N-S length, less 1, at latitude `lat` ([`ns_length_error`] about the frame's).
    pub fn ns_error(&self, lat: f64) -> f64 {
        ns_length_error(self.frame_lat, lat)
    }

    /// The largest |N-S error| over the grid's rows (the meridian arc is shortest at the equator, which
    /// the extent may cross, so the rows are sampled rather than the edges only).
    pub fn ns_error_max(&self) -> f64 {
        (0..=256)
            .map(|i| {
                let lat = self.south + (self.north - self.south) * f64::from(i) / 256.0;
                self.ns_error(lat).abs()
            })
            .fold(0.0, f64::max)
    }
}

/// The south-west corner (latitude, longitude) of an SRTM tile named like `N57E011` or
/// `s12w077.SRTMGL1`, degrees.
pub(super) fn hgt_corner(path: &Path) -> Option<(f64, f64)> {
    let stem = path.file_stem()?.to_str()?;
    let b = stem.as_bytes();
    let sign = |c: u8, pos: u8, neg: u8| match c.to_ascii_uppercase() {
        c if c == pos => Some(1.0),
        c if c == neg => Some(-1.0),
        _ => None,
    };
    let lat: u8 = stem.get(1..3)?.parse().ok()?;
    let lon: u16 = stem.get(4..7)?.parse().ok()?;
    let (lat, lon) = (
        sign(*b.first()?, b'N', b'S')? * f64::from(lat),
        sign(*b.get(3)?, b'E', b'W')? * f64::from(lon),
    );
    ((-90.0..90.0).contains(&lat) && (-180.0..180.0).contains(&lon)).then_some((lat, lon))
}

/// The N-S and E-W sample spacing, metres, of a geographic grid (the file at `path`) whose samples are
/// `step` (N-S, E-W) degrees apart and whose middle row lies at latitude `lat`: the meridian's and the
/// parallel's arcs there, the one metric frame it is drawn in. A middle row past a pole is a georeference
/// damaged or not in degrees: clamped to the pole, where a degree of longitude is 0 m, such a grid was
/// drawn about 10^16 times as wide as long.
pub(crate) fn spacing_at(path: &Path, lat: f64, step: (f64, f64)) -> crate::Result<(f32, f32)> {
    if !(-90.0..=90.0).contains(&lat) {
        return Err(crate::Error::format(
            path,
            format!(
                "a geographic grid whose middle row lies at latitude {lat} degrees, past the poles: \
                 its georeference is damaged or not in degrees"
            ),
        ));
    }
    Ok((
        super::to_f32(step.0 * metres_per_degree_latitude(lat)),
        super::to_f32(step.1 * metres_per_degree_longitude(lat)),
    ))
}

/// How much longer than true an E-W length at latitude `lat` is drawn in a frame whose degree of
/// longitude is the parallel's arc at `lat0`: drawn / true - 1 (negative: drawn short). Infinite at
/// the poles, where a degree of longitude has no length.
pub fn ew_length_error(lat0: f64, lat: f64) -> f64 {
    metres_per_degree_longitude(lat0) / metres_per_degree_longitude(lat) - 1.0
}

/// As [`ew_length_error`], N-S: the frame's degree of latitude is the meridian arc at `lat0`.
pub fn ns_length_error(lat0: f64, lat: f64) -> f64 {
    metres_per_degree_latitude(lat0) / metres_per_degree_latitude(lat) - 1.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mosaic_from_57_to_59_north() {
        // Four 1" tiles, N57E011 to N58E012: 7201 samples a side, 1/3600 degree apart.
        let step = 1.0 / 3600.0;
        let e = GeoExtent::of_grid((11.0, 59.0), (step, step), (7201, 7201)).unwrap();
        assert_eq!((e.south, e.north, e.frame_lat), (57.0, 59.0, 58.0));
        assert!((e.east - 13.0).abs() < 1e-9);
        // Drawn short at the south edge, long at the north edge (118.27 km drawn for 2 degrees of
        // longitude against 121.54 and 114.95 km true).
        assert!((e.ew_error(57.0) * 100.0 - -2.697).abs() < 1e-3);
        assert!((e.ew_error(59.0) * 100.0 - 2.884).abs() < 1e-3);
        assert!((e.ns_error_max() * 100.0 - 0.0160).abs() < 1e-4);
        assert_eq!(e.ew_error(58.0), 0.0);
    }

    #[test]
    fn srtm_names() {
        assert_eq!(hgt_corner(Path::new("a/N57E011.hgt")), Some((57.0, 11.0)));
        assert_eq!(
            hgt_corner(Path::new("s12w077.SRTMGL1.hgt")),
            Some((-12.0, -77.0))
        );
        assert_eq!(hgt_corner(Path::new("tile.hgt")), None);
        assert_eq!(hgt_corner(Path::new("N57X011.hgt")), None);
    }

    #[test]
    fn at_the_equator() {
        // 2 degrees about the equator: the parallel's arc changes as cos, so E-W within 0.016 %.
        let e = GeoExtent::of_grid((0.0, 1.0), (0.5, 0.5), (5, 5)).unwrap();
        assert_eq!(e.frame_lat, 0.0);
        assert!((e.ew_error(1.0) * 100.0 - 0.0151).abs() < 1e-4);
        assert_eq!(e.ew_error(-1.0), e.ew_error(1.0));
        // The meridian arc is shortest at the equator: N-S drawn short at both edges, by 3e-6.
        assert!(e.ns_error(1.0) < 0.0 && e.ns_error_max() < 1e-5);
        assert!(GeoExtent::of_grid((0.0, 91.0), (1.0, 1.0), (3, 3)).is_none());
        assert!(ew_length_error(0.0, 90.0) > 1e9);
    }
}
