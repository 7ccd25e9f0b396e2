//! Stage 0, the source: TIFF encodings that real heights and orthophotos come in and the `tiff` crate's
//! encoder does not write (tiles, JPEG compression, a palette), built here byte by byte: tiled LZW with
//! padded edge tiles, JPEG-in-TIFF tiles (YCbCr, grey; one declaring more than its tile refused), BigTIFF
//! imagery, and a palette TIFF refused with how to expand it.

use std::path::Path;

use clipsat::source::imagery::{Extent, Imagery, ImageryOptions};
use clipsat::source::{self, LoadOptions, RowSource};
use clipsat::Error;

use crate::TempDir;

/// Writes a little-endian tiled TIFF: `w` x `h` samples in tiles of `tile`^2 (`chunks` in row order, as
/// stored), with the SHORT tags `shorts` (BitsPerSample, Compression, Photometric, SamplesPerPixel...).
fn tiled_tiff(
    path: &Path,
    size: (u32, u32),
    tile: u32,
    shorts: &[(u16, &[u16])],
    chunks: &[Vec<u8>],
) {
    chunked_tiff(path, size, Some(tile), shorts, chunks);
}

/// Writes a little-endian TIFF of chunks: tiles of `tile`^2, or without a tile size one strip of TIFF's
/// default rows per strip, 2^32 - 1 (the tag's value when a writer leaves it out).
fn chunked_tiff(
    path: &Path,
    (w, h): (u32, u32),
    tile: Option<u32>,
    shorts: &[(u16, &[u16])],
    chunks: &[Vec<u8>],
) {
    let mut out: Vec<u8> = b"II*\0\0\0\0\0".to_vec();
    let len = |out: &Vec<u8>| u32::try_from(out.len()).expect("a small file");
    let mut offsets = Vec::new();
    for c in chunks {
        offsets.push(len(&out));
        out.extend_from_slice(c);
        if out.len() % 2 == 1 {
            out.push(0);
        }
    }
    let longs = |v: &[u32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let counts: Vec<u32> = chunks
        .iter()
        .map(|c| u32::try_from(c.len()).expect("a small tile"))
        .collect();
    let n = u32::try_from(chunks.len()).expect("a few tiles");
    // (tag, type, count, value bytes): type 3 SHORT, 4 LONG.
    let mut tags: Vec<(u16, u16, u32, Vec<u8>)> =
        vec![(256, 4, 1, longs(&[w])), (257, 4, 1, longs(&[h]))];
    match tile {
        Some(tile) => tags.extend([
            (322, 4, 1, longs(&[tile])),
            (323, 4, 1, longs(&[tile])),
            (324, 4, n, longs(&offsets)),
            (325, 4, n, longs(&counts)),
        ]),
        None => tags.extend([
            (273, 4, n, longs(&offsets)),
            (278, 4, 1, longs(&[u32::MAX])),
            (279, 4, n, longs(&counts)),
        ]),
    }
    for (tag, values) in shorts {
        let bytes = values.iter().flat_map(|x| x.to_le_bytes()).collect();
        tags.push((
            *tag,
            3,
            u32::try_from(values.len()).expect("few values"),
            bytes,
        ));
    }
    tags.sort_by_key(|t| t.0);
    let mut entries = Vec::new();
    for (tag, ty, count, mut bytes) in tags {
        if bytes.len() > 4 {
            let at = len(&out);
            out.extend_from_slice(&bytes);
            if out.len() % 2 == 1 {
                out.push(0);
            }
            bytes = at.to_le_bytes().to_vec();
        } else {
            bytes.resize(4, 0);
        }
        entries.push((tag, ty, count, bytes));
    }
    let ifd = len(&out);
    out[4..8].copy_from_slice(&ifd.to_le_bytes());
    out.extend_from_slice(
        &u16::try_from(entries.len())
            .expect("few tags")
            .to_le_bytes(),
    );
    for (tag, ty, count, bytes) in entries {
        out.extend_from_slice(&tag.to_le_bytes());
        out.extend_from_slice(&ty.to_le_bytes());
        out.extend_from_slice(&count.to_le_bytes());
        out.extend_from_slice(&bytes);
    }
    out.extend_from_slice(&0u32.to_le_bytes());
    std::fs::write(path, out).expect("write TIFF");
}

/// The tiles of a `w` x `h` image of `bytes`-byte texels given by `texel`, padded with zeros to whole
/// tiles of `tile`^2, each coded by `code`.
fn tiles(
    (w, h): (u32, u32),
    tile: u32,
    bytes: usize,
    texel: &dyn Fn(u32, u32) -> Vec<u8>,
    code: &dyn Fn(&[u8]) -> Vec<u8>,
) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    for ty in 0..h.div_ceil(tile) {
        for tx in 0..w.div_ceil(tile) {
            let mut raw = Vec::new();
            for y in ty * tile..(ty + 1) * tile {
                for x in tx * tile..(tx + 1) * tile {
                    if x < w && y < h {
                        raw.extend(texel(x, y));
                    } else {
                        raw.extend(std::iter::repeat_n(0u8, bytes));
                    }
                }
            }
            out.push(code(&raw));
        }
    }
    out
}

fn lzw(raw: &[u8]) -> Vec<u8> {
    weezl::encode::Encoder::with_tiff_size_switch(weezl::BitOrder::Msb, 8)
        .encode(raw)
        .expect("LZW")
}

fn imagery(path: &Path) -> clipsat::Result<Imagery> {
    let grid = Extent::of_grid(65, 33, 10.0, (0.0, 0.0));
    Imagery::load(path, &grid, &ImageryOptions::default())
}

/// Tiled LZW files whose right-hand tiles are padded: tiff 0.11 read such a tile short when asked for
/// its data width alone ("no lzw end code found", image-rs/image-tiff#395); these sizes and contents hit
/// it. Imagery (RGB8) and heights (int16), whole and by rows.
#[test]
fn tiled_lzw_with_padded_edge_tiles_is_read() {
    let dir = TempDir::new("tiff_inputs", "tiled_lzw");
    let (w, h) = (17u32, 20u32);
    let rgb = |x: u32, y: u32| -> Vec<u8> {
        let byte = |v: u32| u8::try_from(v % 256).expect("a byte");
        vec![byte(x * 4), byte(y * 4), byte(x + y)]
    };
    let path = dir.join("rgb_lzw_tiled.tif");
    let chunks = tiles((w, h), 16, 3, &rgb, &lzw);
    let shorts: [(u16, &[u16]); 4] = [(258, &[8, 8, 8]), (259, &[5]), (262, &[2]), (277, &[3])];
    tiled_tiff(&path, (w, h), 16, &shorts, &chunks);
    let im = imagery(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(im.size(), (w, h));
    let want: Vec<u8> = (0..h)
        .flat_map(|y| (0..w).flat_map(move |x| rgb(x, y)))
        .collect();
    assert_eq!(im.texels(), want.as_slice());

    let height = |x: u32, y: u32| -> i16 { i16::try_from(x * 37 + y * 11).expect("small") - 300 };
    let path = dir.join("i16_lzw_tiled.tif");
    let chunks = tiles(
        (w, h),
        16,
        2,
        &|x, y| height(x, y).to_le_bytes().to_vec(),
        &lzw,
    );
    let shorts: [(u16, &[u16]); 5] = [
        (258, &[16]),
        (259, &[5]),
        (262, &[1]),
        (277, &[1]),
        (339, &[2]),
    ];
    tiled_tiff(&path, (w, h), 16, &shorts, &chunks);
    let opts = LoadOptions {
        spacing: Some(10.0),
        ..LoadOptions::default()
    };
    let want: Vec<f32> = (0..h)
        .flat_map(|y| (0..w).map(move |x| f32::from(height(x, y))))
        .collect();
    assert_heights(&path, &opts, &want);
}

/// JPEG-compressed TIFF imagery, as orthophotos and COGs come: YCbCr 4:2:0 tiles (the JFIF streams a
/// JPEG encoder writes), converted to RGB; a greyscale JPEG TIFF too.
#[test]
fn jpeg_tiff_imagery_is_read() {
    let dir = TempDir::new("tiff_inputs", "jpeg");
    let (w, h) = (40u32, 24u32);
    let rgb = |x: u32, y: u32| -> Vec<u8> {
        let byte = |v: u32| u8::try_from(v.min(255)).expect("a byte");
        vec![byte(x * 6), byte(y * 10), byte(200 - x * 2)]
    };
    let jpeg = |raw: &[u8], colour: jpeg_encoder::ColorType| -> Vec<u8> {
        let mut coded = Vec::new();
        let mut e = jpeg_encoder::Encoder::new(&mut coded, 95);
        e.set_sampling_factor(jpeg_encoder::SamplingFactor::F_2_2);
        e.encode(raw, 16, 16, colour).expect("JPEG");
        coded
    };
    let path = dir.join("ycbcr_jpeg.tif");
    let chunks = tiles((w, h), 16, 3, &rgb, &|raw| {
        jpeg(raw, jpeg_encoder::ColorType::Rgb)
    });
    let shorts: [(u16, &[u16]); 5] = [
        (258, &[8, 8, 8]),
        (259, &[7]),
        (262, &[6]),
        (277, &[3]),
        (530, &[2, 2]),
    ];
    tiled_tiff(&path, (w, h), 16, &shorts, &chunks);
    let im = imagery(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(im.size(), (w, h));
    let want: Vec<u8> = (0..h)
        .flat_map(|y| (0..w).flat_map(move |x| rgb(x, y)))
        .collect();
    let diff: Vec<u32> = im
        .texels()
        .iter()
        .zip(&want)
        .map(|(&a, &b)| u32::from(a.abs_diff(b)))
        .collect();
    let mean = f64::from(diff.iter().sum::<u32>()) / diff.len() as f64;
    assert!(
        mean < 4.0,
        "mean error {mean} levels: colours not converted from YCbCr"
    );

    let grey = |x: u32, y: u32| vec![u8::try_from((x * 5 + y * 3) % 256).expect("a byte")];
    let path = dir.join("grey_jpeg.tif");
    let chunks = tiles((w, h), 16, 1, &grey, &|raw| {
        jpeg(raw, jpeg_encoder::ColorType::Luma)
    });
    let shorts: [(u16, &[u16]); 4] = [(258, &[8]), (259, &[7]), (262, &[1]), (277, &[1])];
    tiled_tiff(&path, (w, h), 16, &shorts, &chunks);
    let im = imagery(&path).unwrap_or_else(|e| panic!("{e}"));
    let [g, ..] = im.texel(7, 3);
    assert!(g.abs_diff(44) <= 3, "grey texel {g}, expected about 44");

    // A tile whose JPEG declares more than the tile: refused before it is decoded.
    let path = dir.join("big_jpeg_tile.tif");
    let mut coded = Vec::new();
    jpeg_encoder::Encoder::new(&mut coded, 90)
        .encode(&[128u8; 64 * 64], 64, 64, jpeg_encoder::ColorType::Luma)
        .expect("JPEG");
    tiled_tiff(&path, (16, 16), 16, &shorts, &[coded]);
    match imagery(&path) {
        Err(Error::Format { path: p, reason }) => {
            assert_eq!(p, path);
            assert!(reason.contains("larger than its 16 x 16"), "{reason}");
        }
        other => panic!("an oversized JPEG tile gave {other:?}"),
    }
}

/// A colour-mapped TIFF is refused with how to expand it; a BigTIFF is read like a TIFF.
#[test]
fn palette_tiff_is_refused_and_bigtiff_read() {
    let dir = TempDir::new("tiff_inputs", "palette");
    let path = dir.join("palette.tif");
    let map: Vec<u16> = (0..3 * 256)
        .map(|i| u16::try_from(i % 256 * 257).expect("u16"))
        .collect();
    let chunks = tiles(
        (4, 4),
        16,
        1,
        &|x, _| vec![u8::try_from(x).expect("a byte")],
        &<[u8]>::to_vec,
    );
    let shorts: [(u16, &[u16]); 5] = [
        (258, &[8]),
        (259, &[1]),
        (262, &[3]),
        (277, &[1]),
        (320, &map),
    ];
    tiled_tiff(&path, (4, 4), 16, &shorts, &chunks);
    match imagery(&path) {
        Err(Error::Format { path: p, reason }) => {
            assert_eq!(p, path);
            assert!(reason.contains("-expand rgb"), "{reason}");
        }
        other => panic!("a palette TIFF gave {other:?}"),
    }

    let path = dir.join("big.tif");
    let rgb: Vec<u8> = (0..4 * 3 * 3)
        .map(|i| u8::try_from(i * 7).expect("a byte"))
        .collect();
    let mut file = std::fs::File::create(&path).expect("create");
    tiff::encoder::TiffEncoder::new_big(&mut file)
        .expect("BigTIFF")
        .write_image::<tiff::encoder::colortype::RGB8>(4, 3, &rgb)
        .expect("write");
    drop(file);
    let im = imagery(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(im.texels(), rgb.as_slice());
}

/// A user-defined projection (GDAL's ProjectedCSTypeGeoKey 32767: an Albers or Lambert grid without an
/// EPSG code) names the geographic system it is based on too, and is projected all the same: two such
/// tiles make a mosaic in metres (they had been read as degrees, 3350 km a sample and 0 m E-W), and
/// geographic imagery over them is refused as another kind of system (it had been placed as if its
/// degrees were metres, then refused as missing the terrain).
#[test]
fn user_defined_projection_is_projected() {
    use crate::imagery::geotiff;
    use clipsat::source::georef::{georef_extent, GeoRef};
    use tiff::encoder::colortype::{Gray16, RGB8};
    let dir = TempDir::new("tiff_inputs", "albers");
    let tiles = dir.join("tiles");
    std::fs::create_dir_all(&tiles).expect("tiles folder");
    let albers = [(1024, 1), (1025, 1), (3072, 32767), (2048, 4269)];
    let z: Vec<u16> = (100..120).collect();
    let (a, b) = (tiles.join("a.tif"), tiles.join("b.tif"));
    geotiff::<Gray16>(&a, 5, 4, &z, 30.0, (-2.0e6, 2.5e6), &albers);
    geotiff::<Gray16>(&b, 5, 4, &z, 30.0, (-2.0e6 + 120.0, 2.5e6), &albers);
    let hm = source::load(&tiles, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((hm.width(), hm.height()), (9, 4));
    assert_eq!((hm.spacing(), hm.ew_spacing()), (30.0, 30.0));
    let heights = GeoRef::read(&a).expect("a georeference");
    assert_eq!((heights.crs, heights.geographic), (None, Some(false)));
    let image = dir.join("degrees.tif");
    let geographic = [(1024, 2), (1025, 1), (2048, 4269)];
    geotiff::<RGB8>(&image, 4, 4, &[9; 48], 0.001, (-100.0, 40.0), &geographic);
    let degrees = GeoRef::read(&image).expect("a georeference");
    assert_eq!(
        (degrees.crs, degrees.geographic),
        (Some((2048, 4269)), Some(true))
    );
    let e = georef_extent(&image, &heights, &degrees, 30.0, (0.0, 0.0), 5)
        .expect_err("degrees over metres");
    assert!(
        e.to_string()
            .contains("geographic (degrees) and the heights' projected"),
        "{e}"
    );
}

/// Four bands with a horizontal predictor: with an alpha band they are read (alpha dropped); with a band
/// past the colour that is not alpha (NAIP's near-infrared), tiff 0.11 undoes the predictor at the wrong
/// stride, so the file is refused with how to keep the colour bands, rather than drawn as garbage.
#[test]
fn four_bands_with_a_predictor() {
    let dir = TempDir::new("tiff_inputs", "bands");
    let (w, h) = (20u32, 16u32);
    let rgbn = |x: u32, y: u32| -> Vec<u8> {
        let byte = |v: u32| u8::try_from(v % 256).expect("a byte");
        vec![byte(x * 9), byte(y * 13), byte(x * y), 200]
    };
    // Horizontal differencing, sample by sample, along each row of a tile.
    let predict = |raw: &[u8]| -> Vec<u8> {
        let mut out = raw.to_vec();
        for row in out.chunks_mut(16 * 4) {
            for i in (4..row.len()).rev() {
                row[i] = row[i].wrapping_sub(row[i - 4]);
            }
        }
        out
    };
    let chunks = tiles((w, h), 16, 4, &rgbn, &predict);
    let want: Vec<u8> = (0..h)
        .flat_map(|y| (0..w).flat_map(move |x| rgbn(x, y)[..3].to_vec()))
        .collect();
    for (extra, readable) in [(2u16, true), (0, false)] {
        let path = dir.join(format!("rgb_extra{extra}.tif"));
        let shorts: [(u16, &[u16]); 6] = [
            (258, &[8, 8, 8, 8]),
            (259, &[1]),
            (262, &[2]),
            (277, &[4]),
            (317, &[2]),
            (338, &[extra]),
        ];
        tiled_tiff(&path, (w, h), 16, &shorts, &chunks);
        match (imagery(&path), readable) {
            (Ok(im), true) => assert_eq!(im.texels(), want.as_slice()),
            (Err(Error::Format { reason, .. }), false) => {
                assert!(reason.contains("-b 1 -b 2 -b 3"), "{reason}");
            }
            (other, _) => panic!("ExtraSamples {extra} gave {other:?}"),
        }
    }
}

/// One strip of TIFF's default rows per strip (2^32 - 1, the RowsPerStrip tag's value when a writer
/// leaves it out), LZW-coded: heights whole and by rows, and imagery, are read.
#[test]
fn one_strip_of_default_rows_is_read() {
    let dir = TempDir::new("tiff_inputs", "one_strip");
    let (w, h) = (7u32, 5u32);
    let heights: Vec<i16> = (0..35).map(|i| i * 3 - 20).collect();
    let raw: Vec<u8> = heights.iter().flat_map(|v| v.to_le_bytes()).collect();
    let path = dir.join("heights.tif");
    let shorts: [(u16, &[u16]); 5] = [
        (258, &[16]),
        (259, &[5]),
        (262, &[1]),
        (277, &[1]),
        (339, &[2]),
    ];
    chunked_tiff(&path, (w, h), None, &shorts, &[lzw(&raw)]);
    let opts = LoadOptions {
        spacing: Some(10.0),
        ..LoadOptions::default()
    };
    let want: Vec<f32> = heights.iter().map(|&v| f32::from(v)).collect();
    assert_heights(&path, &opts, &want);

    let rgb: Vec<u8> = (0..w * h * 3)
        .map(|i| u8::try_from(i).expect("a byte"))
        .collect();
    let path = dir.join("imagery.tif");
    let shorts: [(u16, &[u16]); 4] = [(258, &[8, 8, 8]), (259, &[5]), (262, &[2]), (277, &[3])];
    chunked_tiff(&path, (w, h), None, &shorts, &[lzw(&rgb)]);
    let im = imagery(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(im.texels(), rgb.as_slice());
}

/// The heights `path` gives, loaded whole and read by rows: both `want`.
fn assert_heights(path: &Path, opts: &LoadOptions, want: &[f32]) {
    let hm = source::load(path, opts).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(hm.heights(), want);
    let mut rows = source::open_rows(path, opts).unwrap_or_else(|e| panic!("{e}"));
    let mut got = vec![0.0f32; want.len()];
    rows.read_rows(0, &mut got)
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(got, want);
}
