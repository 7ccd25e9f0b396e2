//! Test data for tile mosaics (docs/guide.md "Tile mosaics"): there are no adjacent tiles in the shared
//! data, so the shared SRTM tile (`N57E011.hgt`, 1201^2 at 3") is cut into SRTM-style tiles that share
//! their edge rows and columns with their neighbours, written as `.hgt` or GeoTIFF with their
//! georeference into a temporary folder at test time. A cut-out is placed where the test says (its data
//! need not stay where the Earth has it), and a coarser grid is made by upsampling it bilinearly, so a
//! 1201^2 tile also makes 2 x 2 tiles of 1201^2 (or 3601^2, `make_mosaic`).

#![expect(
    clippy::cast_possible_truncation,
    clippy::cast_precision_loss,
    reason = "test grids: a few thousand samples a side, int16 heights, whole degrees"
)]

use std::path::{Path, PathBuf};

/// A north-up grid of int16 heights placed in degrees.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Grid {
    pub(super) w: usize,
    pub(super) h: usize,
    /// Row-major, row 0 north.
    pub(super) z: Vec<i16>,
    /// Longitude of column 0 and latitude of row 0 (sample centres), degrees.
    pub(super) west: f64,
    pub(super) north: f64,
    /// Degrees between samples, both ways.
    pub(super) step: f64,
}

impl Grid {
    /// The shared tile `N57E011.hgt`, or `None` (printed) when the data is missing outside CI.
    pub(super) fn shared_tile() -> Option<Grid> {
        let path = crate::shared_file("N57E011.hgt")?;
        let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let z: Vec<i16> = bytes
            .chunks_exact(2)
            .map(|c| i16::from_be_bytes([c[0], c[1]]))
            .collect();
        assert_eq!(z.len(), 1201 * 1201, "N57E011.hgt is a 3\" tile");
        Some(Grid {
            w: 1201,
            h: 1201,
            z,
            west: 11.0,
            north: 58.0,
            step: 1.0 / 1200.0,
        })
    }

    pub(super) fn get(&self, x: usize, y: usize) -> i16 {
        self.z[y * self.w + x]
    }

    /// The `w` x `h` samples from column `x0`, row `y0`, where they were.
    pub(super) fn crop(&self, x0: usize, y0: usize, w: usize, h: usize) -> Grid {
        let z = (y0..y0 + h)
            .flat_map(|y| (x0..x0 + w).map(move |x| (x, y)))
            .map(|(x, y)| self.get(x, y))
            .collect();
        Grid {
            w,
            h,
            z,
            west: self.west + x0 as f64 * self.step,
            north: self.north - y0 as f64 * self.step,
            step: self.step,
        }
    }

    /// The same samples placed elsewhere: column 0 at `west`, row 0 at `north`, `step` degrees apart.
    pub(super) fn placed(mut self, west: f64, north: f64, step: f64) -> Grid {
        (self.west, self.north, self.step) = (west, north, step);
        self
    }

    /// `k` times as many steps each way, interpolated bilinearly and rounded (the corners kept).
    pub(super) fn upsampled(&self, k: usize) -> Grid {
        let (w, h) = ((self.w - 1) * k + 1, (self.h - 1) * k + 1);
        let mut z = Vec::with_capacity(w * h);
        for y in 0..h {
            let (y0, fy) = (
                (y / k).min(self.h - 2),
                (y - (y / k).min(self.h - 2) * k) as f64 / k as f64,
            );
            for x in 0..w {
                let (x0, fx) = (
                    (x / k).min(self.w - 2),
                    (x - (x / k).min(self.w - 2) * k) as f64 / k as f64,
                );
                let s = |dx: usize, dy: usize| f64::from(self.get(x0 + dx, y0 + dy));
                let top = s(0, 0) * (1.0 - fx) + s(1, 0) * fx;
                let bottom = s(0, 1) * (1.0 - fx) + s(1, 1) * fx;
                z.push((top * (1.0 - fy) + bottom * fy).round() as i16);
            }
        }
        Grid {
            w,
            h,
            z,
            west: self.west,
            north: self.north,
            step: self.step / k as f64,
        }
    }

    /// Every `k`th sample each way (a coarser tile over the same ground).
    pub(super) fn decimated(&self, k: usize) -> Grid {
        assert!((self.w - 1).is_multiple_of(k) && (self.h - 1).is_multiple_of(k));
        let (w, h) = ((self.w - 1) / k + 1, (self.h - 1) / k + 1);
        let z = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| self.get(x * k, y * k))
            .collect();
        Grid {
            w,
            h,
            z,
            west: self.west,
            north: self.north,
            step: self.step * k as f64,
        }
    }

    /// The tiles of `side` samples it is cut into, row by row from the north-west, neighbours sharing
    /// their edge row or column (SRTM's layout): (column, row) of each and the tile.
    pub(super) fn tiles(&self, side: usize) -> Vec<((usize, usize), Grid)> {
        let stride = side - 1;
        assert!((self.w - 1).is_multiple_of(stride) && (self.h - 1).is_multiple_of(stride));
        let mut out = Vec::new();
        for ty in 0..(self.h - 1) / stride {
            for tx in 0..(self.w - 1) / stride {
                out.push(((tx, ty), self.crop(tx * stride, ty * stride, side, side)));
            }
        }
        out
    }
}

/// Writes `g` as an SRTM tile in `dir`, named by its south-west corner (`N57E011.hgt`); it must be a whole
/// degree of 1201^2 or 3601^2 samples on whole degrees.
pub(super) fn write_hgt(dir: &Path, g: &Grid) -> PathBuf {
    assert!(g.w == g.h && (g.w == 1201 || g.w == 3601));
    assert!((g.step * (g.w - 1) as f64 - 1.0).abs() < 1e-9);
    let (lat, lon) = ((g.north - 1.0).round() as i32, g.west.round() as i32);
    let name = format!(
        "{}{:02}{}{:03}.hgt",
        if lat >= 0 { 'N' } else { 'S' },
        lat.abs(),
        if lon >= 0 { 'E' } else { 'W' },
        lon.abs()
    );
    let path = dir.join(name);
    let bytes: Vec<u8> = g.z.iter().flat_map(|v| v.to_be_bytes()).collect();
    std::fs::write(&path, bytes).expect("write hgt");
    path
}

/// Writes `g` as an int16 GeoTIFF at `path`: geographic (WGS 84, EPSG 4326), pixel-is-point, the
/// tiepoint on sample (0, 0), GDAL nodata `nodata` where given; `epsg` replaces 4326 (a projected code
/// makes the file say it is projected).
pub(super) fn write_geotiff(path: &Path, g: &Grid, nodata: Option<i16>, epsg: u16) -> PathBuf {
    write_geotiff_as(path, g, nodata, epsg, true)
}

/// [`write_geotiff`], pixel-is-point or (as GDAL writes most DEMs) pixel-is-area with the tiepoint on
/// the raster's north-west corner, half a step out from sample (0, 0).
pub(super) fn write_geotiff_as(
    path: &Path,
    g: &Grid,
    nodata: Option<i16>,
    epsg: u16,
    point: bool,
) -> PathBuf {
    use tiff::encoder::{colortype::GrayI16, TiffEncoder};
    use tiff::tags::Tag;
    let file = std::fs::File::create(path).expect("create tiff");
    let mut enc = TiffEncoder::new(file).expect("tiff encoder");
    let mut img = enc
        .new_image::<GrayI16>(g.w as u32, g.h as u32)
        .expect("tiff image");
    let projected = epsg != 4326;
    // Header, then (key, location, count, value): model type, raster type 2 (pixel-is-point), the CRS.
    let keys: [u16; 16] = [
        1,
        1,
        0,
        3,
        1024,
        0,
        1,
        if projected { 1 } else { 2 },
        1025,
        0,
        1,
        if point { 2 } else { 1 },
        if projected { 3072 } else { 2048 },
        0,
        1,
        epsg,
    ];
    let enc_tags = img.encoder();
    enc_tags
        .write_tag(Tag::GeoKeyDirectoryTag, &keys[..])
        .expect("geokeys");
    enc_tags
        .write_tag(Tag::ModelPixelScaleTag, &[g.step, g.step, 0.0][..])
        .expect("pixel scale");
    enc_tags
        .write_tag(
            Tag::ModelTiepointTag,
            &if point {
                [0.0, 0.0, 0.0, g.west, g.north, 0.0]
            } else {
                [
                    0.0,
                    0.0,
                    0.0,
                    g.west - g.step / 2.0,
                    g.north + g.step / 2.0,
                    0.0,
                ]
            }[..],
        )
        .expect("tiepoint");
    if let Some(v) = nodata {
        enc_tags
            .write_tag(Tag::GdalNodata, v.to_string().as_str())
            .expect("nodata");
    }
    img.write_data(&g.z).expect("tiff data");
    path.to_path_buf()
}

/// Writes the tiles of `side` that `g` is cut into as GeoTIFFs in `dir` (`tile_X_Y.tif`).
pub(super) fn write_geotiff_tiles(dir: &Path, g: &Grid, side: usize) -> Vec<PathBuf> {
    g.tiles(side)
        .iter()
        .map(|((x, y), t)| write_geotiff(&dir.join(format!("tile_{x}_{y}.tif")), t, None, 4326))
        .collect()
}

/// Writes a 2 x 2 mosaic of SRTM tiles of `side` (1201 or 3601) in `dir/tiles` and the same data merged
/// into one GeoTIFF, `dir/merged.tif`: the shared tile upsampled to 2 (side - 1) + 1 samples a side over
/// 2 x 2 degrees, north-west corner at 59 N 11 E. For the measurements in docs/guide.md: run
/// `CLIPSAT_MOSAIC_OUT=DIR CLIPSAT_MOSAIC_SIDE=3601 cargo test --test cpu mosaic::make::make_mosaic --
/// --ignored`. `CLIPSAT_MOSAIC_TILES=N` also cuts the same grid into N x N GeoTIFF tiles in
/// `DIR/tiles-N`. `CLIPSAT_MOSAIC_GRID=N` makes N x N SRTM tiles instead of 2 x 2 (the tile upsampled N
/// (side - 1) / 1200 times).
#[test]
#[ignore = "writes a measurement mosaic where CLIPSAT_MOSAIC_OUT says"]
fn make_mosaic() {
    let out = PathBuf::from(std::env::var("CLIPSAT_MOSAIC_OUT").expect("CLIPSAT_MOSAIC_OUT"));
    let side: usize = std::env::var("CLIPSAT_MOSAIC_SIDE")
        .map_or(Ok(1201), |s| s.parse())
        .expect("CLIPSAT_MOSAIC_SIDE");
    let Some(src) = Grid::shared_tile() else {
        return;
    };
    let grid: usize = std::env::var("CLIPSAT_MOSAIC_GRID")
        .map_or(Ok(2), |s| s.parse())
        .expect("CLIPSAT_MOSAIC_GRID");
    let world = src.upsampled((grid * (side - 1)) / 1200).placed(
        11.0,
        57.0 + grid as f64,
        1.0 / (side - 1) as f64,
    );
    let tiles = out.join("tiles");
    std::fs::create_dir_all(&tiles).expect("mkdir");
    for (_, t) in world.tiles(side) {
        write_hgt(&tiles, &t);
    }
    if grid == 2 {
        write_geotiff(&out.join("merged.tif"), &world, None, 4326);
    }
    if let Ok(n) = std::env::var("CLIPSAT_MOSAIC_TILES") {
        let n: usize = n.parse().expect("CLIPSAT_MOSAIC_TILES");
        let dir = out.join(format!("tiles-{n}"));
        std::fs::create_dir_all(&dir).expect("mkdir");
        write_geotiff_tiles(&dir, &world, (world.w - 1) / n + 1);
    }
}
