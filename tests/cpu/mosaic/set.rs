//! Stage 1b, package sets: a tile mosaic baked as one part a tile and a top (`package::set_bake`), read
//! back as one package: level 0 exactly the mosaic's, the coarser levels within the bound of the one
//! package's away from the cells' borders, a bake again that re-bakes only a changed tile's cell, and a
//! cell-by-cell bake (a cluster's) that writes the same files.

use std::path::Path;

use super::make::{write_geotiff_tiles, Grid};
use super::{read_all, temp_dir};
use clipsat::package::{self, set_bake, BakeOptions, Package};
use clipsat::source::{self, LoadOptions};

/// Every file of a set's folder, by name, and its bytes.
fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .expect("read set folder")
        .map(|e| {
            let e = e.expect("entry");
            (
                e.file_name().to_string_lossy().to_string(),
                std::fs::read(e.path()).expect("read"),
            )
        })
        .collect();
    v.sort();
    v
}

/// 2 x 2 GeoTIFF tiles of 513^2 sharing their edges, 1" data around the coast of the shared SRTM tile
/// (upsampled), in `DIR/tiles` of a fresh folder for `test`: the folder, the grid they were cut from and
/// the tiles' paths (north-west, north-east, south-west, south-east).
fn coast_tiles(test: &str) -> Option<(crate::TempDir, Grid, Vec<std::path::PathBuf>)> {
    let src = Grid::shared_tile()?;
    let dir = temp_dir(test);
    let world = src
        .upsampled(2)
        .crop(700, 400, 1025, 1025)
        .placed(11.25, 57.8, 1.0 / 3600.0);
    let paths = write_geotiff_tiles(&dir.join("tiles"), &world, 513);
    Some((dir, world, paths))
}

/// `tiles` baked as a set in `set` with the default options: the bake's report and the set's plan.
fn bake_default(tiles: &Path, set: &Path) -> (set_bake::SetReport, set_bake::SetPlan) {
    let (load, opts) = (LoadOptions::default(), BakeOptions::default());
    let report =
        set_bake::bake_set(tiles, &load, &opts, set, Default::default()).expect("bake the set");
    (
        report,
        set_bake::plan(tiles, &load, &opts, set).expect("plan"),
    )
}

#[test]
fn a_package_set_reads_as_its_mosaic() {
    let Some((dir, world, _)) = coast_tiles("set") else {
        return;
    };
    let tiles = dir.join("tiles");
    let load = LoadOptions::default();
    let set = dir.join("set");
    let report = set_bake::bake_set(
        &tiles,
        &load,
        &BakeOptions::default(),
        &set,
        Default::default(),
    )
    .expect("bake the set");
    assert_eq!((report.cells, report.baked, report.removed), (4, 4, 0));
    assert_eq!((report.tile, report.part_levels), (64, 3));

    // Level 0 is the mosaic's, sample for sample (integer heights are stored losslessly).
    let pkg = Package::open(&set).expect("open the set");
    assert!(package::is_package(&set));
    let h = pkg.header();
    assert_eq!((h.width, h.height), (1025, 1025));
    let (_, want) = read_all(&tiles, &load);
    let got: Vec<f32> = pkg
        .decode_level0()
        .expect("decode")
        .into_iter()
        .map(|k| pkg.metres(k))
        .collect();
    assert!(got == want, "the set's level 0 differs from its mosaic");
    // Imagery over the set is placed by the tiles' georeference, which the index keeps.
    assert_eq!(source::heights_georef(&set), source::heights_georef(&tiles));
    assert!(source::heights_georef(&set).is_some());

    // The coarser levels against the one package of the same mosaic: within both bounds and the
    // filter's share of them away from the cells' borders (where a part's levels are filtered from its
    // own cell alone).
    let whole = dir.join("whole.clipsat");
    let mut rows = source::open_rows(&tiles, &load).expect("rows");
    package::bake_source(
        &mut *rows,
        &whole,
        &BakeOptions {
            lod_tables: false,
            ..BakeOptions::default()
        },
        Default::default(),
    )
    .expect("bake one package");
    let one = Package::open(&whole).expect("open");
    assert_eq!(one.header().levels.len(), h.levels.len());
    for l in 1..h.levels.len() {
        let (a, b) = (
            pkg.decode_level(l).expect("set level"),
            one.decode_level(l).expect("package level"),
        );
        let d = h.levels[l];
        // Cells start every 512 samples: 512 >> l at this level.
        let border = 512 >> l;
        let mut worst = 0i32;
        for y in 0..d.height as usize {
            for x in 0..d.width as usize {
                let near = |v: usize| border > 0 && (v % border < 3 || border - v % border < 3);
                if l <= 2 && (near(x) || near(y)) {
                    continue;
                }
                let i = y * d.width as usize + x;
                worst = worst.max((a[i] - b[i]).abs());
            }
        }
        assert!(worst <= 2, "level {l}: {worst} m from the one package's");
    }

    // A bake again keeps every part; a changed tile bakes its own cell again and the top, and no other.
    let again = set_bake::bake_set(
        &tiles,
        &load,
        &BakeOptions::default(),
        &set,
        Default::default(),
    )
    .expect("bake again");
    assert_eq!((again.baked, again.removed), (0, 0));
    let before = files(&set);
    let (_, mut changed) = world
        .tiles(513)
        .into_iter()
        .find(|(at, _)| *at == (1, 0))
        .expect("tile (1, 0)");
    for v in &mut changed.z[1000..1100] {
        *v += 7;
    }
    super::make::write_geotiff(&tiles.join("tile_1_0.tif"), &changed, None, 4326);
    let third = set_bake::bake_set(
        &tiles,
        &load,
        &BakeOptions::default(),
        &set,
        Default::default(),
    )
    .expect("bake after a change");
    assert_eq!(
        (third.baked, third.removed),
        (1, 2),
        "one part and the top replaced"
    );
    let after = files(&set);
    let kept = before.iter().filter(|f| after.contains(f)).count();
    assert_eq!(kept, 3, "the three other parts kept, byte for byte");

    // A cluster's way: every cell on its own, then the top and index: the same files.
    let cells = dir.join("cells");
    let mut plan = set_bake::plan(&tiles, &load, &BakeOptions::default(), &cells).expect("plan");
    for n in (0..plan.cells.len()).rev() {
        set_bake::bake_cell(&plan, n, Default::default()).expect("bake a cell");
    }
    set_bake::finish(&mut plan, Default::default()).expect("finish");
    assert!(
        files(&cells) == after,
        "a cell-by-cell bake wrote other files"
    );

    // Damage is named: a part missing, a part of another set.
    let part = set.join(&plan.index.parts[0].file);
    std::fs::remove_file(&part).expect("remove a part");
    let err = Package::open(&set).expect_err("a part missing").to_string();
    assert!(err.contains(&plan.index.parts[0].file), "{err}");
    let mut plan2 = set_bake::plan(&tiles, &load, &BakeOptions::default(), &set).expect("plan");
    let err = set_bake::finish(&mut plan2, Default::default())
        .expect_err("finish with a part missing")
        .to_string();
    assert!(err.contains("1 of 4 parts are not baked"), "{err}");
}

/// A missing tile's cell (the sea in SRTM) is the fill height, and refused without one.
#[test]
fn a_set_fills_a_missing_tile() {
    let Some((dir, _, paths)) = coast_tiles("set-missing") else {
        return;
    };
    std::fs::remove_file(&paths[3]).expect("remove the south-east tile");
    let tiles = dir.join("tiles");
    let set = dir.join("set");
    let err = set_bake::bake_set(
        &tiles,
        &LoadOptions::default(),
        &BakeOptions::default(),
        &set,
        Default::default(),
    )
    .expect_err("a cell without a tile or a fill height")
    .to_string();
    assert!(err.contains("no tile covers cell 3"), "{err}");
    let fill = LoadOptions {
        fill_height: Some(-5.0),
        ..LoadOptions::default()
    };
    set_bake::bake_set(
        &tiles,
        &fill,
        &BakeOptions::default(),
        &set,
        Default::default(),
    )
    .expect("bake with a fill height");
    let pkg = Package::open(&set).expect("open");
    let level0 = pkg.decode_level0().expect("decode");
    // The south-east cell's inside (off its shared edges) is the fill height.
    let at = |x: usize, y: usize| pkg.metres(level0[y * 1025 + x]);
    assert_eq!(at(800, 800), -5.0);
    assert_eq!(at(1024, 1024), -5.0);
    let (_, want) = read_all(&tiles, &fill);
    assert_eq!(at(100, 900), want[900 * 1025 + 100]);
}

/// Tiles whose starts no tile side and level divide, and `--resample-ew`, are refused with what to do.
#[test]
fn a_set_refuses_what_it_cannot_cut() {
    let Some(src) = Grid::shared_tile() else {
        return;
    };
    let dir = temp_dir("set-refused");
    let world = src.crop(0, 0, 203, 203).placed(11.0, 58.0, 1.0 / 3600.0);
    write_geotiff_tiles(&dir.join("tiles"), &world, 102);
    let err = set_bake::plan(
        &dir.join("tiles"),
        &LoadOptions::default(),
        &BakeOptions::default(),
        &dir.join("set"),
    )
    .expect_err("tiles every 101 samples")
    .to_string();
    assert!(err.contains("bake the mosaic into one package"), "{err}");
    // One tile is one cell, too small for the tile side: it had said the tiles start every 0 samples.
    let one = dir.join("one.txt");
    std::fs::write(&one, "tiles/tile_0_0.tif\n").expect("write a list");
    let err = set_bake::plan(
        &one,
        &LoadOptions::default(),
        &BakeOptions::default(),
        &dir.join("set"),
    )
    .expect_err("one small cell")
    .to_string();
    assert!(
        err.contains("one cell of 102 x 102 samples") && !err.contains("every 0 samples"),
        "{err}"
    );
    // Tiles every 32 samples on a grid too small for 16-sample tiles: refused for its size, not as if
    // no side divided 32.
    let small = src.crop(0, 0, 65, 65).placed(11.0, 58.0, 1.0 / 3600.0);
    std::fs::create_dir_all(dir.join("small")).expect("create");
    write_geotiff_tiles(&dir.join("small"), &small, 33);
    let sixteen = BakeOptions {
        tile: 16,
        ..BakeOptions::default()
    };
    let err = set_bake::plan(
        &dir.join("small"),
        &LoadOptions::default(),
        &sixteen,
        &dir.join("set"),
    )
    .expect_err("a grid of 65 samples")
    .to_string();
    assert!(
        err.contains("grid of 65 x 65 samples is too small"),
        "{err}"
    );
    let ew = LoadOptions {
        resample_ew: true,
        ..LoadOptions::default()
    };
    let err = set_bake::plan(
        &dir.join("tiles"),
        &ew,
        &BakeOptions::default(),
        &dir.join("set"),
    )
    .expect_err("resample_ew")
    .to_string();
    assert!(err.contains("resampling the rows east-west"), "{err}");
}

/// A missing tile's cell takes the samples of its west and north edges from the tiles that share them,
/// as the mosaic does: they had been the fill height, the land ending one sample short of its tile (a
/// cliff along the sea's cell in a render that the one package did not have).
#[test]
fn a_missing_tiles_cell_keeps_its_neighbours_edges() {
    let Some((dir, _, paths)) = coast_tiles("set-missing-edges") else {
        return;
    };
    std::fs::remove_file(&paths[3]).expect("remove the south-east tile");
    let tiles = dir.join("tiles");
    let set = dir.join("set");
    let fill = LoadOptions {
        fill_height: Some(-5.0),
        ..LoadOptions::default()
    };
    set_bake::bake_set(
        &tiles,
        &fill,
        &BakeOptions::default(),
        &set,
        Default::default(),
    )
    .expect("bake with a fill height");
    let pkg = Package::open(&set).expect("open");
    let level0 = pkg.decode_level0().expect("decode");
    let (_, want) = read_all(&tiles, &fill);
    for i in 512..1025 {
        for (x, y) in [(512, i), (i, 512)] {
            assert_eq!(
                pkg.metres(level0[y * 1025 + x]),
                want[y * 1025 + x],
                "sample ({x}, {y}) on the missing tile's edge"
            );
        }
    }
}

/// A part's key holds neither the grid's size nor the tiles' paths as spelt: tiles added east bake their
/// own cells and the top alone (every part had been baked again, the grid's width in every key), and
/// the same folder named another way (`tiles/.`, or relative from elsewhere) bakes nothing again.
#[test]
fn a_set_bakes_again_only_what_changed() {
    let Some(src) = Grid::shared_tile() else {
        return;
    };
    let dir = temp_dir("set-grows");
    // 3 x 2 tiles of 513^2; the first two columns baked, then the third added.
    let world = src
        .upsampled(2)
        .crop(700, 400, 1537, 1025)
        .placed(11.25, 57.8, 1.0 / 3600.0);
    std::fs::create_dir_all(dir.join("all")).expect("create a folder");
    let all = write_geotiff_tiles(&dir.join("all"), &world, 513);
    let tiles = dir.join("tiles");
    let copy = |east: bool| {
        for p in &all {
            let name = p.file_name().expect("a tile's name");
            if name.to_string_lossy().starts_with("tile_2_") == east {
                std::fs::copy(p, tiles.join(name)).expect("copy a tile");
            }
        }
    };
    copy(false);
    let set = dir.join("set");
    let bake = |spec: &Path| {
        set_bake::bake_set(
            spec,
            &LoadOptions::default(),
            &BakeOptions::default(),
            &set,
            Default::default(),
        )
        .expect("bake the set")
    };
    assert_eq!(bake(&tiles).baked, 4);
    assert_eq!(
        bake(&tiles.join(".")).baked,
        0,
        "the same tiles named another way"
    );
    copy(true);
    let grown = bake(&tiles);
    assert_eq!(
        (grown.cells, grown.baked),
        (6, 2),
        "the east column's cells alone"
    );
}

/// Copernicus tiles as they come across 50 N: each starts on its degree line without sharing an edge,
/// 720 samples a degree south of it and 480 columns north (here a fifth of GLO-30's). The set's level 0
/// is the mosaic's, sample for sample: the column between a north tile's last sample and the next
/// tile's first, which the mosaic reads as linear between them, included.
#[test]
fn a_set_of_copernicus_tiles_reads_as_its_mosaic() {
    let dir = temp_dir("set-copernicus");
    let tiles = dir.join("tiles");
    for (lat, lon, cols) in [
        (51.0, 8.0, 480),
        (51.0, 9.0, 480),
        (50.0, 8.0, 720),
        (50.0, 9.0, 720),
    ] {
        super::real_tiles::copernicus_tile(
            &tiles.join(format!("N{}E00{lon}.tif", lat - 1.0)),
            (lon, lat),
            (cols, 720),
            super::real_tiles::slope,
        );
    }
    let load = LoadOptions::default();
    let set = dir.join("set");
    set_bake::bake_set(
        &tiles,
        &load,
        &BakeOptions::default(),
        &set,
        Default::default(),
    )
    .expect("bake the set");
    let pkg = Package::open(&set).expect("open the set");
    let (g, want) = read_all(&tiles, &load);
    let w = g.width as usize;
    let level0 = pkg.decode_level0().expect("decode");
    let bound = pkg.header().max_error * 1.01;
    for (i, (&k, &v)) in level0.iter().zip(&want).enumerate() {
        let got = pkg.metres(k);
        assert!(
            f64::from((got - v).abs()) <= bound,
            "sample ({}, {}): {got}, the mosaic's {v}",
            i % w,
            i / w
        );
    }
}

/// A part cut short (a disk full, a copy stopped) or with a damaged header is baked again by the next
/// bake: it had stood (its first bytes were a package's), and every bake after failed on it by name
/// until it was removed by hand.
#[test]
fn a_damaged_part_is_baked_again() {
    let Some((dir, _, _)) = coast_tiles("set-damaged") else {
        return;
    };
    let (tiles, set) = (dir.join("tiles"), dir.join("set"));
    let bake = || bake_default(&tiles, &set);
    let (_, plan) = bake();
    let whole = files(&set);
    let (cut, header) = (plan.part_path(1), plan.part_path(2));
    let len = std::fs::metadata(&cut).expect("a part").len();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&cut)
        .and_then(|f| f.set_len(len / 2))
        .expect("cut a part short");
    let mut bytes = std::fs::read(&header).expect("a part");
    bytes[20] ^= 0xff;
    std::fs::write(&header, bytes).expect("damage a part's header");
    let (again, _) = bake();
    assert_eq!(again.baked, 2, "the two damaged parts baked again");
    assert!(files(&set) == whole, "the set as it was");

    // A damaged index is an error that names it, never a panic or an allocation the size of the grid it
    // claims (a tile side of 0 divided by zero; a width of 2^32 - 1 asked for billions of tile entries).
    let index = set.join(package::set::INDEX_NAME);
    let text = std::fs::read_to_string(&index).expect("the index");
    let with = |key: &str, value: &str| -> String {
        let mut done = false;
        text.lines()
            .map(|l| {
                if !done && l.starts_with(&format!("{key} = ")) {
                    done = true;
                    format!("{key} = {value}")
                } else {
                    l.to_string()
                }
            })
            .collect::<Vec<_>>()
            .join("\n")
    };
    for (key, value) in [
        ("tile", "0"),
        ("tile", "6"),
        ("tile", "1000000"),
        ("width", "4294967295"),
        ("height", "4000000000"),
        ("spacing", "nan"),
        ("spacing", "-30.0"),
        ("origin", "[nan, 0.0]"),
        ("quantum", "0.0"),
        ("max_error", "inf"),
        ("part_levels", "0"),
        ("part_levels", "4000000000"),
        ("codec", "\"bogus\""),
        ("format", "2"),
        ("columns", "[0, 512, 512]"),
        ("rows", "[]"),
        // The georef table's: imagery over the set is placed by it.
        ("scale", "[0.0, 0.0]"),
        ("corner", "[nan, 59.0]"),
    ] {
        let damaged = with(key, value);
        assert_ne!(damaged, text, "{key} is in the index");
        std::fs::write(&index, &damaged).expect("damage the index");
        let err = Package::open(&set)
            .expect_err(&format!("{key} = {value}"))
            .to_string();
        assert!(
            err.contains(package::set::INDEX_NAME) || err.contains(".clipsat"),
            "{key} = {value}: {err}"
        );
    }
    for cut in [text.len() / 2, 10, 0] {
        std::fs::write(&index, &text[..cut]).expect("cut the index short");
        assert!(Package::open(&set).is_err(), "the index cut at {cut}");
    }
    std::fs::write(&index, &text).expect("the index again");
    assert!(Package::open(&set).is_ok());
}

/// An index whose top or part names a set (its own index, its folder) or a file that is no package (a
/// folder, a FIFO) is an error that names it: the set had opened itself again until the stack
/// overflowed, a folder failed as "cannot map: No such device", and a FIFO waited for a writer forever.
#[test]
fn a_set_index_names_only_package_files() {
    let Some((dir, _, _)) = coast_tiles("set-names") else {
        return;
    };
    let set = dir.join("set");
    set_bake::bake_set(
        &dir.join("tiles"),
        &LoadOptions::default(),
        &BakeOptions::default(),
        &set,
        Default::default(),
    )
    .expect("bake the set");
    let index = set.join(package::set::INDEX_NAME);
    let text = std::fs::read_to_string(&index).expect("the index");
    let top = text
        .lines()
        .find(|l| l.starts_with("top = "))
        .expect("a top")
        .to_string();
    let part = text
        .lines()
        .find(|l| l.starts_with("file = "))
        .expect("a part")
        .to_string();
    std::fs::create_dir_all(set.join("folder")).expect("a folder");
    let fifo = set.join("fifo.clipsat");
    #[cfg(unix)]
    let _ = std::process::Command::new("mkfifo").arg(&fifo).status();
    let names = [package::set::INDEX_NAME, "", ".", "../set", "folder"];
    let fifo_name = fifo.exists().then_some("fifo.clipsat");
    for name in names.into_iter().chain(fifo_name) {
        for (line, key) in [(&top, "top"), (&part, "file")] {
            let damaged = text.replacen(line.as_str(), &format!("{key} = \"{name}\""), 1);
            std::fs::write(&index, &damaged).expect("damage the index");
            // On a thread, so that a wait is a failure rather than a hang.
            let (tx, rx) = std::sync::mpsc::channel();
            let at = set.clone();
            std::thread::spawn(move || tx.send(Package::open(&at).map(|_| ())));
            let result = rx
                .recv_timeout(std::time::Duration::from_secs(20))
                .unwrap_or_else(|_| panic!("{key} = {name:?}: still opening after 20 s"));
            let err = result.expect_err(&format!("{key} = {name:?}")).to_string();
            assert!(
                err.contains(package::set::INDEX_NAME) || err.contains(name),
                "{key} = {name:?}: {err}"
            );
        }
    }
    // Another cell's part of the same size (every cell here is 513^2) read as this cell's.
    let parts: Vec<&str> = text.lines().filter(|l| l.starts_with("file = ")).collect();
    let swapped = text.replacen(parts[0], parts[3], 1);
    std::fs::write(&index, &swapped).expect("name another cell's part");
    let err = Package::open(&set)
        .expect_err("another cell's part")
        .to_string();
    assert!(err.contains("not its cell's"), "{err}");
    std::fs::write(&index, &text).expect("the index again");
    assert!(Package::open(&set).is_ok());
}

/// A package that is not its cell's part, under the part's name (a copy gone wrong), is baked again: it
/// had stood, and the top was made from it past the end of its level (a panic, "index out of bounds")
/// or from the wrong samples, a set that every bake after kept and no reader opened.
#[test]
fn a_part_that_is_not_its_cells_is_baked_again() {
    let Some((dir, _, _)) = coast_tiles("set-foreign") else {
        return;
    };
    let (tiles, set) = (dir.join("tiles"), dir.join("set"));
    let bake = || bake_default(&tiles, &set);
    let (_, plan) = bake();
    let whole = files(&set);
    // The whole mosaic's package in the south-east cell's place, and no top yet.
    let hm = source::load(&tiles, &LoadOptions::default()).expect("load the mosaic");
    let last = plan.cells.len() - 1;
    package::bake(
        &hm,
        &plan.part_path(last),
        &BakeOptions::default(),
        Default::default(),
    )
    .expect("bake the whole mosaic");
    for (name, _) in &whole {
        if name.starts_with("top-") {
            std::fs::remove_file(set.join(name)).expect("remove the top");
        }
    }
    let (again, _) = bake();
    assert_eq!(again.baked, 1, "the cell baked again");
    assert!(files(&set) == whole, "the set as it was");
    assert!(Package::open(&set).is_ok());
}
