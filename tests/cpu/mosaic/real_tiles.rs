//! Stage 0, tile mosaics laid out as real tile sets are: SRTM tiles on both sides of the antimeridian,
//! and Copernicus DEM tiles (each starting on its degree line, not sharing edge rows or columns with its
//! neighbours, 2400 columns a degree from 50 to 60 degrees of latitude beside 3600 below).

use std::path::Path;

use super::make::{write_geotiff, write_hgt, Grid};
use super::{read_all, temp_dir};
use crate::TempDir;
use clipsat::source::{self, LoadOptions, RowSource};

/// A north-up f32 GeoTIFF as a Copernicus DEM tile is: geographic (EPSG 4326), pixel-is-point, its
/// north-west sample on (`lon`, `lat`), `cols` x `rows` samples `1 / cols` and `1 / rows` degrees apart
/// over one degree, heights `z(lon, lat)`.
pub(super) fn copernicus_tile(
    path: &Path,
    (lon, lat): (f64, f64),
    (cols, rows): (u32, u32),
    z: fn(f64, f64) -> f32,
) {
    use tiff::encoder::colortype::Gray32Float;
    use tiff::tags::Tag;
    let (dx, dy) = (1.0 / f64::from(cols), 1.0 / f64::from(rows));
    let data: Vec<f32> = (0..rows)
        .flat_map(|r| (0..cols).map(move |c| (c, r)))
        .map(|(c, r)| z(lon + f64::from(c) * dx, lat - f64::from(r) * dy))
        .collect();
    let file = std::fs::File::create(path).expect("create tile");
    let mut enc = tiff::encoder::TiffEncoder::new(file).expect("encoder");
    let mut img = enc.new_image::<Gray32Float>(cols, rows).expect("image");
    img.encoder()
        .write_tag(Tag::ModelPixelScaleTag, &[dx, dy, 0.0][..])
        .expect("scale");
    img.encoder()
        .write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, lon, lat, 0.0][..])
        .expect("tiepoint");
    // Geographic model, pixel-is-point, WGS 84.
    let keys: [u16; 16] = [1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 2, 2048, 0, 1, 4326];
    img.encoder()
        .write_tag(Tag::GeoKeyDirectoryTag, &keys[..])
        .expect("geokeys");
    img.write_data(&data).expect("data");
}

/// Heights rising 360 m a degree east from 100 m at 8 E.
#[expect(
    clippy::cast_possible_truncation,
    reason = "heights of a few hundred metres"
)]
fn plane(lon: f64, _lat: f64) -> f32 {
    (100.0 + 360.0 * (lon - 8.0)) as f32
}

/// SRTM tiles east and west of the antimeridian (`n00e179.hgt`, `N00W180.hgt`, the names in either case)
/// lie side by side, 2 degrees wide from 179 E to 179 W: the mosaic had been 360 degrees wide, 432001 x
/// 1201 samples from 180 W to 180 E, nearly all of it no data (`clipsat info` on it had not finished after 120 s). A
/// pair of GeoTIFF tiles sharing the column on the antimeridian (180 in one, -180 in the other) join
/// there sample for sample.
#[test]
fn tiles_across_the_antimeridian_lie_side_by_side() {
    let dir = temp_dir("antimeridian");
    let tiles = dir.join("tiles");
    let flat = |west: f64| Grid {
        w: 1201,
        h: 1201,
        z: vec![7; 1201 * 1201],
        west,
        north: 1.0,
        step: 1.0 / 1200.0,
    };
    let east = write_hgt(&tiles, &flat(179.0));
    std::fs::rename(&east, tiles.join("n00e179.hgt")).expect("rename");
    write_hgt(&tiles, &flat(-180.0));
    let opts = LoadOptions {
        fill_height: Some(0.0),
        ..LoadOptions::default()
    };
    let geo = source::mosaic_geo(&tiles, &opts)
        .expect("mosaic")
        .expect("in degrees");
    assert_eq!(
        (geo.west, geo.east, geo.south, geo.north),
        (179.0, 181.0, 0.0, 1.0)
    );
    let rows = source::open_rows(&tiles, &opts).expect("open");
    assert_eq!((rows.grid().width, rows.grid().height), (2401, 1201));

    // 9 x 9 GeoTIFF tiles, 1/16 degree apart: 179.5 .. 180 E and 180 .. 179.5 W, heights rising east.
    let dir = temp_dir("antimeridian_tif");
    let world = Grid {
        w: 17,
        h: 9,
        z: (0..9).flat_map(|_| 100..117).collect(),
        west: 179.5,
        north: 0.5,
        step: 1.0 / 16.0,
    };
    let west_half = world.crop(0, 0, 9, 9);
    let east_half = world.crop(8, 0, 9, 9).placed(-180.0, 0.5, 1.0 / 16.0);
    write_geotiff(&dir.join("tiles/a.tif"), &east_half, None, 4326);
    write_geotiff(&dir.join("tiles/b.tif"), &west_half, None, 4326);
    let (g, got) = read_all(&dir.join("tiles"), &LoadOptions::default());
    assert_eq!((g.width, g.height), (17, 9));
    let want: Vec<f32> = world.z.iter().map(|&v| f32::from(v)).collect();
    assert_eq!(got, want);
}

/// Copernicus DEM tiles (here 36 rows a degree, and 36 or 24 columns: the 3600 and 2400 of GLO-30 at a
/// hundredth) start on their degree lines and do not share edge samples. Above 50 N the coarser E-W
/// tiles end 1.5 grid steps short of the next tile, and the grid column between was no data: with
/// `fill_height` 0 a trench of 0 m along every such tile's east edge, and at the mosaic's east edge. The
/// column between two tiles is now linear between them, and the one at the east edge (inside the last
/// sample's pixel) is that sample; heights planar in longitude read back as the plane.
#[test]
fn copernicus_tiles_join_without_a_seam() {
    let dir = temp_dir("copernicus");
    for (lat, cols) in [(50.0, 36), (51.0, 24)] {
        for lon in [8.0, 9.0] {
            let name = format!(
                "Copernicus_DSM_COG_10_N{:02}_00_E{:03}_00_DEM.tif",
                lat - 1.0,
                lon
            );
            copernicus_tile(&dir.join("tiles").join(name), (lon, lat), (cols, 36), plane);
        }
    }
    let opts = LoadOptions {
        fill_height: Some(-1000.0),
        ..LoadOptions::default()
    };
    let (g, got) = read_all(&dir.join("tiles"), &opts);
    assert_eq!((g.width, g.height), (72, 72));
    for (r, row) in (0u32..).zip(got.chunks_exact(72)) {
        for (c, &v) in (0u32..).zip(row) {
            let lon = if r < 36 && c == 71 {
                // The north-east tile's last sample, 9 + 23/24 E.
                9.0 + 23.0 / 24.0
            } else {
                8.0 + f64::from(c) / 36.0
            };
            assert!(
                (f64::from(v) - f64::from(plane(lon, 0.0))).abs() < 1e-3,
                "sample ({c}, {r}): {v}, the plane {}",
                plane(lon, 0.0)
            );
        }
    }
    // By default nothing is left to fill.
    let whole = source::load(&dir.join("tiles"), &LoadOptions::default()).expect("load");
    assert_eq!(whole.voids_filled(), 0);
}

/// A VRT over two Copernicus-style tiles (36 samples a degree) with `res` degrees a pixel, as
/// `gdalbuildvrt` writes one (pixel-is-point tiles: each pixel's corner half a step west and north of
/// its sample).
fn copernicus_vrt(dir: &Path, res: f64) -> std::path::PathBuf {
    let half = 0.5 / 36.0;
    let n = 36.0 / (res * 36.0);
    let mut xml = format!(
        "<VRTDataset rasterXSize=\"{}\" rasterYSize=\"{n}\">\n  <GeoTransform> {:e}, {res:e}, 0.0, {:e}, \
         0.0, {:e}</GeoTransform>\n  <VRTRasterBand dataType=\"Float32\" band=\"1\">\n",
        2.0 * n,
        8.0 - half,
        50.0 + half,
        -res
    );
    for (i, lon) in [8, 9].into_iter().enumerate() {
        xml += &format!(
            "    <ComplexSource>\n      <SourceFilename relativeToVRT=\"1\">tiles/N49E00{lon}.tif\
             </SourceFilename>\n      <SourceBand>1</SourceBand>\n      <SrcRect xOff=\"0\" yOff=\"0\" \
             xSize=\"36\" ySize=\"36\" />\n      <DstRect xOff=\"{}\" yOff=\"0\" xSize=\"{n}\" \
             ySize=\"{n}\" />\n    </ComplexSource>\n",
            i as f64 * n
        );
    }
    xml += "  </VRTRasterBand>\n</VRTDataset>\n";
    let path = dir.join(format!("res-{}.vrt", (1.0 / res).round()));
    std::fs::write(&path, xml).expect("write vrt");
    path
}

/// A GDAL VRT built at another resolution than its tiles' (`gdalbuildvrt -tr`, or its default
/// `-resolution average` over tiles of two spacings) is one GDAL reads resampled: it had been read at
/// the tiles' own spacing all the same (72 x 36 samples for a VRT of 36 x 18 pixels), as the guide
/// said it is not; it is refused with how to build it. Built at the tiles' resolution it is read.
#[test]
fn a_vrt_at_another_resolution_is_refused() {
    let dir = temp_dir("copernicus_vrt");
    for lon in [8.0, 9.0] {
        let name = format!("N49E00{lon}.tif");
        copernicus_tile(&dir.join("tiles").join(name), (lon, 50.0), (36, 36), plane);
    }
    let coarse = copernicus_vrt(&dir, 2.0 / 36.0);
    let err = source::open_rows(&coarse, &LoadOptions::default())
        .err()
        .expect("a resampling VRT is refused")
        .to_string();
    assert!(err.contains("-resolution highest"), "{err}");
    assert!(err.contains("res-18.vrt"), "{err}");
    let (g, _) = read_all(&copernicus_vrt(&dir, 1.0 / 36.0), &LoadOptions::default());
    assert_eq!((g.width, g.height), (72, 36));
}

/// Geographic imagery given in -180..180 degrees (`179.9 W .. 179.1 W`) over the mosaic of
/// `N00E179.hgt` and `N00W180.hgt`, whose longitudes run on past 180 E, is placed where it lies: 1.1 to
/// 1.9 degrees east of the mosaic's west column. It had been placed a turn away, 39685 km west of the
/// terrain, and refused as not overlapping it.
#[test]
fn imagery_over_the_antimeridian_is_placed_where_it_lies() {
    use clipsat::source::georef::{georef_extent, GeoRef};
    let dir = temp_dir("antimeridian_imagery");
    let tiles = dir.join("tiles");
    for west in [179.0, -180.0] {
        let flat = Grid {
            w: 1201,
            h: 1201,
            z: vec![7; 1201 * 1201],
            west,
            north: 1.0,
            step: 1.0 / 1200.0,
        };
        write_hgt(&tiles, &flat);
    }
    let heights = source::heights_georef(&tiles).expect("the mosaic's georeference");
    let image = GeoRef {
        size: (200, 200),
        scale: (0.004, 0.004),
        corner: (-179.9, 0.9),
        crs: None,
        geographic: Some(true),
    };
    // 100 m a grid step, the south-west sample at the origin.
    let e = georef_extent(
        &dir.join("image.png"),
        &heights,
        &image,
        100.0,
        (0.0, 0.0),
        2401,
    )
    .expect("placed");
    let metres = |degrees: f64| degrees * 1200.0 * 100.0;
    for (got, want) in [
        (e.west, metres(1.1)),
        (e.east, metres(1.9)),
        (e.south, metres(0.1)),
        (e.north, metres(0.9)),
    ] {
        assert!((got - want).abs() < 1e-3, "{e:?}");
    }
}

/// Heights rising 360 m a degree east and 720 m a degree north from 100 m at 8 E, 48 N.
#[expect(
    clippy::cast_possible_truncation,
    reason = "heights of a few thousand metres"
)]
pub(super) fn slope(lon: f64, lat: f64) -> f32 {
    (100.0 + 360.0 * (lon - 8.0) + 720.0 * (lat - 48.0)) as f32
}

/// A GLO-90 tile (here 12 samples a degree each way) among GLO-30 ones (36): it ends 3 grid steps short
/// of the next tile both ways, east and south. The two grid rows below it had been no data (with
/// `fill_height` -1000 m, a trench along its south edge); they, its east columns and the corner between
/// are now linear between the tiles, so heights planar in longitude and latitude read back as the plane.
/// At the mosaic's south edge (the tile south-west), the row inside its south samples' pixels takes
/// them, and the row past them is no data.
/// Four square Copernicus-style tiles of `slope` in `tiles/` of a new folder named `name`: 49-50 N by
/// 8-10 E, `sides` samples a degree, north-west, north-east, south-west, south-east.
fn square_tiles(name: &str, sides: [u32; 4]) -> TempDir {
    let dir = temp_dir(name);
    for ((lat, lon), side) in [(50.0, 8.0), (50.0, 9.0), (49.0, 8.0), (49.0, 9.0)]
        .into_iter()
        .zip(sides)
    {
        let name = format!("N{}E00{lon}.tif", lat - 1.0);
        copernicus_tile(
            &dir.join("tiles").join(name),
            (lon, lat),
            (side, side),
            slope,
        );
    }
    dir
}

#[test]
fn a_coarser_tile_joins_the_tiles_east_and_south() {
    let dir = square_tiles("glo90_edge", [36, 36, 12, 36]);
    let opts = LoadOptions {
        fill_height: Some(-1000.0),
        ..LoadOptions::default()
    };
    let (_, got) = read_all(&dir.join("tiles"), &opts);
    for c in 0..33u32 {
        // The tile's south samples lie at 48 + 1/12 N.
        let south = slope(8.0 + f64::from(c) / 36.0, 48.0 + 3.0 / 36.0);
        assert!(
            (got[70 * 72 + c as usize] - south).abs() < 1e-2,
            "column {c}"
        );
        assert_eq!(got[71 * 72 + c as usize], -1000.0, "column {c}");
    }

    let dir = square_tiles("glo90", [12, 36, 36, 36]);
    let opts = LoadOptions {
        fill_height: Some(-1000.0),
        ..LoadOptions::default()
    };
    let (g, got) = read_all(&dir.join("tiles"), &opts);
    assert_eq!((g.width, g.height), (72, 72));
    for (r, row) in (0u32..).zip(got.chunks_exact(72)) {
        for (c, &v) in (0u32..).zip(row) {
            let want = slope(8.0 + f64::from(c) / 36.0, 50.0 - f64::from(r) / 36.0);
            assert!(
                (v - want).abs() < 1e-2,
                "sample ({c}, {r}): {v}, the plane {want}"
            );
        }
    }
}

/// SRTM downloads come zipped (`N00W001.SRTMGL1.hgt.zip`); unzipped each into a folder of its name, the
/// tiles are one level down, and a folder of such folders was refused as holding no tile and nothing
/// more. The refusal now gives the glob that reads them (which does), and for a folder of zip (or
/// gzip) files says to unpack them.
#[test]
fn a_folder_of_unzipped_folders_names_the_glob() {
    let dir = temp_dir("unzipped");
    let tiles = dir.join("tiles");
    let inner = tiles.join("N00W001.SRTMGL3.hgt.zip");
    std::fs::create_dir_all(&inner).expect("mkdir");
    let flat = Grid {
        w: 1201,
        h: 1201,
        z: vec![3; 1201 * 1201],
        west: -1.0,
        north: 1.0,
        step: 1.0 / 1200.0,
    };
    write_hgt(&inner, &flat);
    let err = source::open_rows(&tiles, &LoadOptions::default())
        .err()
        .expect("a folder without tiles of its own is refused")
        .to_string();
    let glob = tiles.join("*").join("*.hgt");
    assert!(err.contains(&format!("'{}'", glob.display())), "{err}");
    let rows = source::open_rows(&glob, &LoadOptions::default()).expect("the glob reads them");
    assert_eq!(rows.grid().width, 1201);

    let zips = dir.join("zips");
    std::fs::create_dir_all(&zips).expect("mkdir");
    std::fs::write(zips.join("N00W001.SRTMGL1.hgt.zip"), b"PK").expect("write");
    let err = source::open_rows(&zips, &LoadOptions::default())
        .err()
        .expect("a folder of zip files is refused")
        .to_string();
    assert!(
        err.contains("1 compressed file(s) (.zip, .gz), which are not read: unpack them"),
        "{err}"
    );
}

/// An image that does not say whether it is geographic (a world file without a `.prj`) is moved by
/// turns of longitude only where its numbers can be degrees: a projected one (metres) over the same
/// heights stays where its numbers put it, off the terrain, and is not moved onto it.
#[test]
fn imagery_in_metres_is_not_moved_by_turns() {
    use clipsat::source::georef::{georef_extent, GeoRef};
    let dir = temp_dir("antimeridian_metres");
    let tiles = dir.join("tiles");
    let flat = Grid {
        w: 1201,
        h: 1201,
        z: vec![7; 1201 * 1201],
        west: 179.0,
        north: 1.0,
        step: 1.0 / 1200.0,
    };
    write_hgt(&tiles, &flat);
    let heights = source::heights_georef(&tiles).expect("the mosaic's georeference");
    let mut image = GeoRef {
        size: (100, 100),
        scale: (30.0, 30.0),
        corner: (500_000.0, 5_000_000.0),
        crs: None,
        geographic: None,
    };
    let at = |image: &GeoRef| {
        georef_extent(
            &dir.join("image.png"),
            &heights,
            image,
            100.0,
            (0.0, 0.0),
            1201,
        )
        .expect("an extent")
        .west
    };
    let west = at(&image);
    assert!(west > 1e9, "{west}");
    // The same numbers as degrees would be moved: 539.5 E is 179.5 E.
    image.corner = (539.5, 0.9);
    image.scale = (0.001, 0.001);
    assert!((at(&image) - 0.5 * 1200.0 * 100.0).abs() < 1e-3);
}
