//! Stage 0, tile mosaics laid out as real tile sets are: SRTM tiles on both sides of the antimeridian.

use super::make::{write_geotiff, write_hgt, Grid};
use super::{read_all, temp_dir};
use clipsat::source::{self, LoadOptions, RowSource};

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
