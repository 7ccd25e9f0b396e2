//! Stage 0, tile mosaics: tiles cut from the shared SRTM tile (`make.rs`) read back as one terrain, sample
//! for sample, and baked into the very package the same data merged into one file bakes into; missing
//! tiles, mixed resolutions, the overlap rule and bad input.

mod make;
mod real_tiles;
mod set;

use crate::TempDir;
use std::path::Path;

use clipsat::package::{self, BakeOptions};
use clipsat::source::{self, LoadOptions, RowSource};
use make::{write_geotiff, write_geotiff_as, write_geotiff_tiles, write_hgt, Grid};

fn temp_dir(test: &str) -> TempDir {
    let dir = TempDir::new("mosaic", test);
    std::fs::create_dir_all(dir.join("tiles")).expect("create temp dir");
    dir
}

/// Every sample of `path` read through the out-of-core reader, and its grid.
fn read_all(path: &Path, opts: &LoadOptions) -> (source::RowGrid, Vec<f32>) {
    let mut rows =
        source::open_rows(path, opts).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let g = rows.grid().clone();
    let mut out = vec![0.0f32; g.width as usize * g.height as usize];
    // Bands of 7 rows, so that bands start inside tiles and cross their borders.
    for (y0, band) in (0..).step_by(7).zip(out.chunks_mut(g.width as usize * 7)) {
        rows.read_rows(y0, band).expect("read rows");
    }
    (g, out)
}

fn as_f32(g: &Grid) -> Vec<f32> {
    g.z.iter().map(|&v| f32::from(v)).collect()
}

/// 2 x 2 SRTM `.hgt` tiles (1201^2 at 3", sharing edge rows) read as one: the 2401^2 grid they were cut
/// from, sample for sample, through a folder, a list file (in another order) and a glob; the spacing the
/// merged GeoTIFF gives; the whole load equal to the rows.
#[test]
fn hgt_tiles_join_exactly() {
    let Some(src) = Grid::shared_tile() else {
        return;
    };
    let dir = temp_dir("hgt");
    let world = src.upsampled(2).placed(11.0, 59.0, 1.0 / 1200.0);
    let mut names = Vec::new();
    for (_, t) in world.tiles(1201) {
        names.push(write_hgt(&dir.join("tiles"), &t));
    }
    let merged = write_geotiff(&dir.join("merged.tif"), &world, None, 4326);
    let opts = LoadOptions::default();
    let (mg, want) = read_all(&merged, &opts);
    assert_eq!(want, as_f32(&world));

    let list = dir.join("tiles.txt");
    let lines: Vec<String> = names
        .iter()
        .rev()
        .map(|p| format!("tiles/{}", p.file_name().unwrap().to_string_lossy()))
        .collect();
    std::fs::write(&list, format!("# the four tiles\n{}\n\n", lines.join("\n"))).unwrap();
    let glob = dir.join("tiles").join("N5*.hgt");
    for spec in [dir.join("tiles"), list, glob] {
        assert!(source::is_mosaic(&spec), "{}", spec.display());
        let (g, got) = read_all(&spec, &opts);
        assert_eq!((g.width, g.height), (2401, 2401), "{}", spec.display());
        assert_eq!((g.spacing, g.ew_spacing), (mg.spacing, mg.ew_spacing));
        assert!(
            got == want,
            "{}: the mosaic differs from its source",
            spec.display()
        );
    }
    let whole = source::load(&dir.join("tiles"), &opts).expect("load");
    assert_eq!(whole.heights(), &want[..]);
    assert_eq!(whole.voids_filled(), 0);
    // Where it lies and the latitude its metres are taken at, as the merged file says.
    let geo = *whole.geo().expect("a mosaic in degrees");
    let merged_geo = *source::load(&merged, &opts)
        .unwrap()
        .geo()
        .expect("a GeoTIFF in degrees");
    for (a, b) in [
        (geo.south, 57.0),
        (geo.north, 59.0),
        (geo.west, 11.0),
        (geo.east, 13.0),
        (geo.frame_lat, 58.0),
        (merged_geo.south, 57.0),
        (merged_geo.north, 59.0),
        (merged_geo.west, 11.0),
        (merged_geo.frame_lat, 58.0),
    ] {
        assert!((a - b).abs() < 1e-9, "{geo:?} {merged_geo:?}");
    }
    // Resampled E-W as the merged file is.
    let ew = LoadOptions {
        resample_ew: true,
        ..LoadOptions::default()
    };
    let (g, got) = read_all(&dir.join("tiles"), &ew);
    let (mg, want) = read_all(&merged, &ew);
    assert_eq!((g.width, g.ew_spacing), (mg.width, mg.ew_spacing));
    assert!(g.width < 1400, "about cos 58 of 2401 columns: {}", g.width);
    assert!(got == want);
    // Resampling keeps the extent; metres given by hand leave none.
    let resampled = source::load(&dir.join("tiles"), &ew).unwrap();
    assert_eq!(resampled.geo(), Some(&geo));
    let by_hand = LoadOptions {
        spacing: Some(30.0),
        fill_height: Some(0.0),
        ..LoadOptions::default()
    };
    assert_eq!(
        source::load(&dir.join("tiles"), &by_hand).unwrap().geo(),
        None
    );
}

/// The package baked from 2 x 2 GeoTIFF tiles of 301^2 is byte for byte the package baked from the same
/// data merged into one GeoTIFF, with and without `resample_ew`.
#[test]
fn mosaic_bakes_the_merged_files_package() {
    let Some(src) = Grid::shared_tile() else {
        return;
    };
    let dir = temp_dir("bake");
    // The coast, east of the tile's middle, as 1" data.
    let world = src
        .crop(600, 300, 601, 601)
        .placed(11.5, 57.75, 1.0 / 3600.0);
    write_geotiff_tiles(&dir.join("tiles"), &world, 301);
    let merged = write_geotiff(&dir.join("merged.tif"), &world, None, 4326);
    for resample_ew in [false, true] {
        let opts = LoadOptions {
            resample_ew,
            ..LoadOptions::default()
        };
        let mut bytes = Vec::new();
        for (name, path) in [("mosaic", dir.join("tiles")), ("merged", merged.clone())] {
            let out = dir.join(format!("{name}-{resample_ew}.clipsat"));
            let mut rows = source::open_rows(&path, &opts).expect("open rows");
            package::bake_source(
                &mut *rows,
                &out,
                &BakeOptions::default(),
                Default::default(),
            )
            .expect("bake");
            bytes.push(std::fs::read(&out).expect("read package"));
        }
        assert!(
            bytes[0] == bytes[1],
            "resample_ew {resample_ew}: the packages differ"
        );
    }
}

/// A missing tile (the sea in SRTM) reads as the fill height where one is given, out of core; by default
/// it is no data, filled from its neighbours as the merged file's nodata samples are.
#[test]
fn missing_tile_reads_as_fill_or_no_data() {
    let Some(src) = Grid::shared_tile() else {
        return;
    };
    let dir = temp_dir("missing");
    let world = src
        .crop(600, 300, 201, 201)
        .placed(11.5, 57.75, 1.0 / 3600.0);
    let tiles = write_geotiff_tiles(&dir.join("tiles"), &world, 101);
    std::fs::remove_file(&tiles[3]).unwrap();
    let fill = LoadOptions {
        fill_height: Some(-7.0),
        ..LoadOptions::default()
    };
    let (_, got) = read_all(&dir.join("tiles"), &fill);
    for y in 0..201 {
        for x in 0..201 {
            let want = if x > 100 && y > 100 {
                -7.0
            } else {
                f32::from(world.get(x, y))
            };
            assert_eq!(got[y * 201 + x], want, "({x}, {y})");
        }
    }
    // No data: as the merged file with the quadrant marked nodata.
    let mut holed = world.clone();
    for y in 101..201 {
        for x in 101..201 {
            holed.z[y * 201 + x] = -32768;
        }
    }
    let merged = write_geotiff(&dir.join("merged.tif"), &holed, Some(-32768), 4326);
    let opts = LoadOptions::default();
    let (_, got) = read_all(&dir.join("tiles"), &opts);
    let (_, want) = read_all(&merged, &opts);
    assert!(got.iter().all(|v| v.is_finite()));
    assert!(
        got == want,
        "the filled mosaic differs from the filled merged file"
    );
    let whole = source::load(&dir.join("tiles"), &opts).expect("load");
    assert_eq!(whole.voids_filled(), 100 * 100);
}

/// A 3" tile beside 1" ones: the mosaic takes the finest spacing, the 3" tile's samples land exactly and
/// the samples between are bilinear; where tiles overlap the finest wins, then the first given.
#[test]
fn mixed_resolution_and_overlap_rule() {
    let Some(src) = Grid::shared_tile() else {
        return;
    };
    let dir = temp_dir("mixed");
    let world = src
        .crop(600, 300, 121, 121)
        .placed(11.5, 57.75, 1.0 / 3600.0);
    let tiles = world.tiles(61);
    for ((x, y), t) in &tiles {
        let t = if (*x, *y) == (1, 1) {
            t.decimated(3)
        } else {
            t.clone()
        };
        write_geotiff(&dir.join(format!("tiles/t{x}{y}.tif")), &t, None, 4326);
    }
    let (g, got) = read_all(&dir.join("tiles"), &LoadOptions::default());
    assert_eq!((g.width, g.height), (121, 121));
    let at = |x: usize, y: usize| got[y * 121 + x];
    let w = |x: usize, y: usize| f32::from(world.get(x, y));
    // The shared edges come from the 1" neighbours, the 3" tile's own samples exactly.
    for i in 0..121 {
        assert_eq!(at(60, i), w(60, i));
        assert_eq!(at(i, 60), w(i, 60));
    }
    for y in (60..121).step_by(3) {
        for x in (60..121).step_by(3) {
            assert_eq!(at(x, y), w(x, y), "({x}, {y})");
        }
    }
    // Between them, bilinear: a third of the way east and two thirds south of (63, 63).
    let (a, b, c, d) = (w(63, 63), w(66, 63), w(63, 66), w(66, 66));
    let top = f64::from(a) * 2.0 / 3.0 + f64::from(b) / 3.0;
    let bottom = f64::from(c) * 2.0 / 3.0 + f64::from(d) / 3.0;
    let want = top / 3.0 + bottom * 2.0 / 3.0;
    assert!(
        (f64::from(at(64, 65)) - want).abs() < 1e-3,
        "{} vs {want}",
        at(64, 65)
    );

    // Two 1" tiles covering the same ground with other heights: the first in the list wins.
    let other = Grid {
        z: world.z.iter().map(|v| v + 100).collect(),
        ..world.clone()
    };
    let a = write_geotiff(&dir.join("a.tif"), &world, None, 4326);
    let b = write_geotiff(&dir.join("b.tif"), &other, None, 4326);
    for (order, want) in [([&a, &b], &world), ([&b, &a], &other)] {
        let list = dir.join("two.txt");
        let names: Vec<String> = order.iter().map(|p| p.display().to_string()).collect();
        std::fs::write(&list, names.join("\n")).unwrap();
        let (_, got) = read_all(&list, &LoadOptions::default());
        assert_eq!(got, as_f32(want));
    }
}

/// Bad input is refused with a message that names the problem: a folder with no DEM, tiles of another
/// coordinate system, a tile off the common grid, an unreadable tile, a glob that matches nothing, a
/// list that names a missing file.
#[test]
fn bad_mosaics_are_refused() {
    let dir = temp_dir("bad");
    let g = Grid {
        w: 11,
        h: 11,
        z: (0..121).collect(),
        west: 11.0,
        north: 58.0,
        step: 1.0 / 3600.0,
    };
    let refused = |spec: &Path, needle: &str| {
        let e = source::open_rows(spec, &LoadOptions::default())
            .err()
            .unwrap_or_else(|| panic!("{}: accepted", spec.display()));
        assert!(e.to_string().contains(needle), "{}: {e}", spec.display());
        let e = source::load(spec, &LoadOptions::default()).expect_err("load");
        assert!(e.to_string().contains(needle), "{}: {e}", spec.display());
    };
    let nan_fill = LoadOptions {
        fill_height: Some(f32::NAN),
        ..LoadOptions::default()
    };
    let e = source::open_rows(&dir.join("tiles"), &nan_fill)
        .err()
        .expect("NaN fill");
    assert!(e.to_string().contains("must be finite"), "{e}");
    std::fs::write(dir.join("tiles/readme.md"), "no tiles here").unwrap();
    refused(&dir.join("tiles"), "no DEM tile");
    refused(&dir.join("tiles/*.hgt"), "matches no file");
    refused(&dir.join("tiles/[.hgt"), "glob pattern");
    std::fs::write(dir.join("empty.txt"), "# nothing\n").unwrap();
    refused(&dir.join("empty.txt"), "names none");
    std::fs::write(dir.join("missing.txt"), "tiles/nope.tif\n").unwrap();
    refused(&dir.join("missing.txt"), "cannot read tile");

    let case = |name: &str, tiles: &[(&str, Grid, u16)], needle: &str| {
        let sub = dir.join(name);
        std::fs::create_dir_all(&sub).unwrap();
        for (file, t, epsg) in tiles {
            write_geotiff(&sub.join(file), t, None, *epsg);
        }
        refused(&sub, needle);
    };
    let east = g.clone().placed(11.0 + 10.0 / 3600.0, 58.0, g.step);
    case(
        "crs",
        &[("a.tif", g.clone(), 4326), ("b.tif", east.clone(), 32632)],
        "coordinate system",
    );
    case(
        "crs-code",
        &[("a.tif", g.clone(), 4326), ("b.tif", east.clone(), 4258)],
        "EPSG 4258",
    );
    let off = g.clone().placed(11.0 + 10.5 / 3600.0, 58.0, g.step);
    case(
        "offgrid",
        &[("a.tif", g.clone(), 4326), ("b.tif", off, 4326)],
        "common grid",
    );

    let sub = dir.join("unreadable");
    std::fs::create_dir_all(&sub).unwrap();
    write_geotiff(&sub.join("a.tif"), &g, None, 4326);
    std::fs::write(sub.join("N58E011.hgt"), [0u8; 100]).unwrap();
    refused(&sub, "25934402 bytes");
    std::fs::remove_file(sub.join("N58E011.hgt")).unwrap();
    std::fs::write(sub.join("b.tif"), b"II*\0garbage").unwrap();
    refused(&sub, "b.tif");
    std::fs::write(sub.join("b.tif"), b"not a tiff at all").unwrap();
    refused(&sub, "georeference");
}

/// `Terrain::open` takes a folder of tiles and bakes it into the cache folder, and `fill_height` through
/// `TerrainOptions`.
#[test]
fn terrain_opens_a_folder_of_tiles() {
    let dir = temp_dir("terrain");
    let g = Grid {
        w: 65,
        h: 65,
        z: (0..65 * 65).map(|i: i16| i % 65 + i / 65).collect(),
        west: 11.0,
        north: 58.0,
        step: 1.0 / 3600.0,
    };
    let tiles = write_geotiff_tiles(&dir.join("tiles"), &g, 33);
    std::fs::remove_file(&tiles[0]).unwrap();
    let cache = dir.join("cache");
    let opts = clipsat::TerrainOptions::default()
        .cache_dir(&cache)
        .fill_height(-1.0);
    let t = clipsat::Terrain::open_with(dir.join("tiles"), &opts).expect("open");
    assert!(t.is_streamed());
    assert_eq!(t.size(), (65, 65));
    assert_eq!(t.height_range().0, -1.0);
    let again = clipsat::Terrain::bake(dir.join("tiles/*.tif"), &opts).expect("bake");
    assert!(again.starts_with(&cache));
}

/// More tiles across than readers stay open ([`source::MAX_OPEN_TILES`]): readers are closed and opened
/// again band after band, and the mosaic still reads its grid sample for sample.
#[test]
fn more_tiles_across_than_open_readers() {
    let dir = temp_dir("many");
    let across = source::MAX_OPEN_TILES + 4;
    let w = 10 * across + 1;
    let g = Grid {
        w,
        h: 31,
        z: (0..w * 31)
            .map(|i| i16::try_from(i % 997).unwrap())
            .collect(),
        west: 11.0,
        north: 58.0,
        step: 1.0 / 3600.0,
    };
    let tiles = write_geotiff_tiles(&dir.join("tiles"), &g, 11);
    assert_eq!(tiles.len(), across * 3);
    let (_, got) = read_all(&dir.join("tiles"), &LoadOptions::default());
    assert_eq!(got, as_f32(&g));
}

/// Pixel-is-area GeoTIFF tiles (the tiepoint on the raster's corner, as GDAL writes most DEMs) are placed
/// by their sample centres, as pixel-is-point ones are, and may be mixed with them.
#[test]
fn pixel_is_area_tiles_place_alike() {
    let dir = temp_dir("area");
    let g = Grid {
        w: 41,
        h: 41,
        z: (0..41 * 41).map(|i: i16| i % 41 * 3 - i / 41).collect(),
        west: 11.25,
        north: 57.5,
        step: 1.0 / 3600.0,
    };
    for (i, ((x, y), t)) in g.tiles(21).into_iter().enumerate() {
        write_geotiff_as(
            &dir.join(format!("tiles/t{x}{y}.tif")),
            &t,
            None,
            4326,
            i % 2 == 0,
        );
    }
    let (grid, got) = read_all(&dir.join("tiles"), &LoadOptions::default());
    assert_eq!((grid.width, grid.height), (41, 41));
    // An empty band is no rows, at either end.
    let mut rows = source::open_rows(&dir.join("tiles"), &LoadOptions::default()).expect("open");
    rows.read_rows(0, &mut []).expect("empty band");
    rows.read_rows(41, &mut []).expect("empty band at the end");
    assert_eq!(got, as_f32(&g));
}

/// A VRT over `tiles` (file, DstRect x and y offsets, size) as `gdalbuildvrt` writes one, with a
/// `GeoTransform` from `g`'s north-west sample and `extra` inside each source.
fn write_vrt(path: &Path, g: &Grid, tiles: &[(&str, usize, usize, usize)], extra: &str) {
    let mut xml = format!(
        "<VRTDataset rasterXSize=\"{}\" rasterYSize=\"{}\">\n  <SRS>EPSG:4326</SRS>\n  \
         <GeoTransform> {:.17e}, {:.17e}, 0.0, {:.17e}, 0.0, {:.17e}</GeoTransform>\n  \
         <VRTRasterBand dataType=\"Int16\" band=\"1\">\n    <NoDataValue>-32768</NoDataValue>\n",
        g.w,
        g.h,
        g.west - g.step / 2.0,
        g.step,
        g.north + g.step / 2.0,
        -g.step
    );
    for (file, x, y, side) in tiles {
        xml += &format!(
            "    <ComplexSource>\n      <SourceFilename relativeToVRT=\"1\">{file}</SourceFilename>\n      \
             <SourceBand>1</SourceBand>\n      <SrcRect xOff=\"0\" yOff=\"0\" xSize=\"{side}\" ySize=\"{side}\" />\n      \
             <DstRect xOff=\"{x}\" yOff=\"{y}\" xSize=\"{side}\" ySize=\"{side}\" />\n{extra}    </ComplexSource>\n"
        );
    }
    xml += "  </VRTRasterBand>\n</VRTDataset>\n";
    std::fs::write(path, xml).expect("write vrt");
}

/// A GDAL VRT mosaic reads as its tiles do (and, where tiles of one resolution overlap, the later source
/// wins, as in GDAL); a VRT that moves, crops, rescales or filters its tiles is refused, naming it.
#[test]
fn a_gdal_vrt_reads_as_its_tiles() {
    let dir = temp_dir("vrt");
    let g = Grid {
        w: 21,
        h: 21,
        z: (0..441).map(|v| (v * 7 % 1000) as i16).collect(),
        west: 11.0,
        north: 58.0,
        step: 1.0 / 3600.0,
    };
    let mut tiles = Vec::new();
    for ((tx, ty), t) in g.tiles(11) {
        let name = format!("tile_{tx}_{ty}.tif");
        write_geotiff_as(&dir.join("tiles").join(&name), &t, None, 4326, false);
        tiles.push((format!("tiles/{name}"), tx * 10, ty * 10));
    }
    let sources: Vec<(&str, usize, usize, usize)> = tiles
        .iter()
        .map(|(f, x, y)| (f.as_str(), *x, *y, 11))
        .collect();
    let vrt = dir.join("world.vrt");
    write_vrt(&vrt, &g, &sources, "");
    assert!(source::is_mosaic(&vrt));
    let (vg, got) = read_all(&vrt, &LoadOptions::default());
    let (fg, want) = read_all(&dir.join("tiles"), &LoadOptions::default());
    assert_eq!((vg.width, vg.height), (21, 21));
    assert_eq!((vg.spacing, vg.ew_spacing), (fg.spacing, fg.ew_spacing));
    assert!(
        got == want && got == as_f32(&g),
        "the VRT reads as the folder"
    );
    assert!(
        source::input_files(&vrt).expect("inputs").contains(&vrt),
        "the VRT keys the cache"
    );

    // Overlap: a second copy of the north-west tile, 1000 m higher, listed last, wins there.
    let high = Grid {
        z: g.tiles(11)[0].1.z.iter().map(|v| v + 1000).collect(),
        ..g.tiles(11)[0].1.clone()
    };
    write_geotiff_as(&dir.join("tiles/high.tif"), &high, None, 4326, false);
    let over = dir.join("over.vrt");
    let mut with_high = sources.clone();
    with_high.push(("tiles/high.tif", 0, 0, 11));
    write_vrt(&over, &g, &with_high, "");
    let (_, got) = read_all(&over, &LoadOptions::default());
    assert_eq!(got[0], f32::from(g.z[0] + 1000), "the last source wins");
    assert_eq!(
        got[20],
        f32::from(g.z[20]),
        "elsewhere the tiles read as before"
    );

    let refused = |name: &str, needle: &str| {
        let path = dir.join(name);
        let e = source::open_rows(&path, &LoadOptions::default())
            .err()
            .unwrap_or_else(|| panic!("{name}: accepted"));
        // The VRT is named, or the tile it names where that is what fails.
        let named = e.to_string().contains(name) || e.to_string().contains("tile_9_9");
        assert!(e.to_string().contains(needle) && named, "{name}: {e}");
    };
    let mut moved = sources.clone();
    moved[1].1 += 1;
    write_vrt(&dir.join("moved.vrt"), &g, &moved, "");
    refused("moved.vrt", "moves, crops or resamples");
    write_vrt(
        &dir.join("scaled.vrt"),
        &g,
        &sources,
        "      <ScaleRatio>2</ScaleRatio>\n",
    );
    refused("scaled.vrt", "rescales");
    let text = std::fs::read_to_string(&vrt).expect("read");
    let edits = [
        (
            "two_bands.vrt",
            text.replace("</VRTDataset>", "<VRTRasterBand band=\"2\"/></VRTDataset>"),
            "2 bands",
        ),
        (
            "averaged.vrt",
            text.replace("ComplexSource>", "AveragedSource>"),
            "filters or averages",
        ),
        (
            "zip.vrt",
            text.replace(">tiles/tile_0_0", ">/vsizip/tiles/tile_0_0"),
            "virtual file system",
        ),
        (
            "missing.vrt",
            text.replace("tile_1_1", "tile_9_9"),
            "cannot read tile",
        ),
        (
            "band2.vrt",
            text.replacen("<SourceBand>1", "<SourceBand>2", 1),
            "band 2",
        ),
        (
            "crop.vrt",
            text.replacen("SrcRect xOff=\"0\"", "SrcRect xOff=\"3\"", 1),
            "cropped",
        ),
        (
            "rotated.vrt",
            text.replacen(", 0.0, ", ", 0.5, ", 1),
            "rotated",
        ),
        (
            "warped.vrt",
            text.replace("<VRTDataset ", "<VRTDataset subClass=\"VRTWarpedDataset\" "),
            "resamples",
        ),
        ("broken.vrt", text[..text.len() / 2].to_string(), "not XML"),
        // Values GDAL maps (it had read them raw).
        (
            "exponent.vrt",
            text.replacen(
                "</ComplexSource>",
                "<Exponent>2</Exponent></ComplexSource>",
                1,
            ),
            "<Exponent> maps its heights",
        ),
        (
            "palette.vrt",
            text.replacen(
                "</ComplexSource>",
                "<ColorTableComponent>1</ColorTableComponent></ComplexSource>",
                1,
            ),
            "<ColorTableComponent> maps its heights",
        ),
    ];
    for (name, body, needle) in edits {
        std::fs::write(dir.join(name), body).expect("write");
        refused(name, needle);
    }
    // Saved as UTF-16 with its byte-order mark (Notepad's "Unicode"): said so, not a reader's "stream
    // did not contain valid UTF-8".
    let utf16: Vec<u8> = [0xff, 0xfe]
        .into_iter()
        .chain(text.encode_utf16().flat_map(u16::to_le_bytes))
        .collect();
    std::fs::write(dir.join("utf16.vrt"), utf16).expect("write");
    refused("utf16.vrt", "not UTF-8 text");
}

/// A VRT whose `GeoTransform` or `DstRect` holds NaN, and tiles whose steps are too small for metres in
/// an f32, are refused naming the file: a NaN compared false with every bound and passed the checks on
/// where the VRT puts its tiles, and a mosaic of steps of 1e-300 degrees streamed with a spacing of 0 m.
#[test]
fn non_finite_places_and_spacings_are_refused() {
    let dir = temp_dir("non-finite");
    let g = Grid {
        w: 11,
        h: 11,
        z: (0..121).collect(),
        west: 11.0,
        north: 58.0,
        step: 1.0 / 3600.0,
    };
    write_geotiff_as(&dir.join("tiles/a.tif"), &g, None, 4326, false);
    let refused = |path: &Path, needle: &str| {
        let e = source::open_rows(path, &LoadOptions::default())
            .err()
            .unwrap_or_else(|| panic!("{}: accepted", path.display()));
        let e = e.to_string();
        assert!(
            e.contains(needle) && e.contains(&path.display().to_string()),
            "{}: {e}",
            path.display()
        );
    };
    let tile = [("tiles/a.tif", 0, 0, 11)];
    let vrt = dir.join("a.vrt");
    write_vrt(&vrt, &g, &tile, "");
    read_all(&vrt, &LoadOptions::default());
    let nan = Grid {
        step: f64::NAN,
        ..g.clone()
    };
    write_vrt(&dir.join("nan.vrt"), &nan, &tile, "");
    refused(&dir.join("nan.vrt"), "six finite numbers");
    let text = std::fs::read_to_string(&vrt).expect("read");
    for (name, from, to, needle) in [
        (
            "dst.vrt",
            "DstRect xOff=\"0\"",
            "DstRect xOff=\"nan\"",
            "<DstRect>",
        ),
        (
            "src.vrt",
            "SrcRect xOff=\"0\"",
            "SrcRect xOff=\"nan\"",
            "<SrcRect>",
        ),
    ] {
        std::fs::write(dir.join(name), text.replacen(from, to, 1)).expect("write");
        refused(&dir.join(name), needle);
    }

    let tiny = dir.join("tiny");
    std::fs::create_dir_all(&tiny).expect("create");
    let step = Grid { step: 1e-300, ..g };
    write_geotiff_as(&tiny.join("a.tif"), &step, None, 4326, false);
    refused(&tiny, "sample spacing");
}

/// A folder of tiles whose name ends in `.vrt` reads as a folder of tiles: it had been read as a VRT's
/// file ("cannot read: Is a directory").
#[test]
fn a_folder_named_like_a_vrt_is_a_folder() {
    let dir = temp_dir("vrt-folder");
    let g = Grid {
        w: 21,
        h: 11,
        z: (0..231).collect(),
        west: 11.0,
        north: 58.0,
        step: 1.0 / 3600.0,
    };
    let folder = dir.join("tiles.vrt");
    std::fs::create_dir_all(&folder).expect("create");
    write_geotiff_tiles(&folder, &g, 11);
    assert!(source::is_mosaic(&folder));
    let (grid, got) = read_all(&folder, &LoadOptions::default());
    assert_eq!((grid.width, grid.height), (21, 11));
    assert_eq!(got, as_f32(&g));
}

/// A list of tiles saved by Windows Notepad reads: its byte-order mark is no part of the first path (that
/// tile had been missing, its name printed as if it were right), its lines end in CR LF; one saved as
/// UTF-16 is refused saying it is not UTF-8.
#[test]
fn a_list_with_a_byte_order_mark_reads() {
    let dir = temp_dir("bom");
    let g = Grid {
        w: 21,
        h: 11,
        z: (0..231).collect(),
        west: 11.0,
        north: 58.0,
        step: 1.0 / 3600.0,
    };
    write_geotiff_tiles(&dir.join("tiles"), &g, 11);
    let list = dir.join("tiles.txt");
    std::fs::write(
        &list,
        "\u{feff}tiles/tile_0_0.tif\r\ntiles/tile_1_0.tif\r\n",
    )
    .expect("write");
    let (_, got) = read_all(&list, &LoadOptions::default());
    assert_eq!(got, as_f32(&g));
    let utf16: Vec<u8> = "\u{feff}tiles/tile_0_0.tif\r\n"
        .encode_utf16()
        .flat_map(u16::to_le_bytes)
        .collect();
    std::fs::write(&list, utf16).expect("write");
    let e = source::open_rows(&list, &LoadOptions::default())
        .err()
        .expect("a UTF-16 list")
        .to_string();
    assert!(e.contains("not UTF-8") && e.contains("tiles.txt"), "{e}");
}

/// A geographic grid whose rows lie past a pole (a latitude of 1000 degrees: a georeference damaged or
/// not in degrees) is refused naming the file, loaded or streamed: its latitude was clamped to the pole,
/// where a degree of longitude is 0 m, and `info` drew it 1.6e16 times as wide. A mosaic's tile past a
/// pole, or at a longitude of 1e15 (joined before into a mosaic of no meaning), is refused too.
#[test]
fn a_geographic_grid_past_the_poles_is_refused() {
    let dir = temp_dir("past-poles");
    let g = Grid {
        w: 11,
        h: 11,
        z: (0..121).collect(),
        west: 11.0,
        north: 1000.0,
        step: 1.0 / 3600.0,
    };
    let one = write_geotiff(&dir.join("one.tif"), &g, None, 4326);
    write_geotiff_tiles(&dir.join("tiles"), &g, 6);
    let far = Grid {
        west: 1e15,
        north: 58.0,
        ..g.clone()
    };
    std::fs::create_dir_all(dir.join("far")).expect("create");
    write_geotiff_tiles(&dir.join("far"), &far, 6);
    for (path, needle) in [
        (one, "past the poles"),
        (dir.join("tiles"), "not on the globe"),
        (dir.join("far"), "not on the globe"),
    ] {
        let load = source::load(&path, &LoadOptions::default()).map(|_| ());
        let rows = source::open_rows(&path, &LoadOptions::default()).map(|_| ());
        for (how, r) in [("load", load), ("stream", rows)] {
            let e = r
                .err()
                .unwrap_or_else(|| panic!("{how} {}: accepted", path.display()))
                .to_string();
            assert!(e.contains(needle), "{how} {}: {e}", path.display());
        }
    }
}
