//! Stage 0, the source: every shared data file loads as its sidecar `.txt` describes, and every kind of
//! bad input gives its typed error, never a panic.

use crate::TempDir;
use std::path::{Path, PathBuf};

use clipsat::source::Heightmap;
use clipsat::source::{self, LoadOptions, RawFormat, RawLayout};
use clipsat::Error;

// ---- the shared data ----------------------------------------------------------------------------

/// What a sidecar `.txt` states about a file.
struct Expect {
    file: &'static str,
    width: u32,
    height: u32,
    /// Metres; checked within 1 %.
    spacing: f32,
    /// Range in metres as the sidecar prints it, and half its last printed digit.
    lo: f32,
    hi: f32,
    rounding: f32,
    /// Spacing to pass in: PNG carries none.
    spacing_opt: Option<f32>,
}

/// Loads a shared data file, or `None` (with a printed reason) when it is missing outside CI.
fn load_shared(name: &str, opts: &LoadOptions) -> Option<Heightmap> {
    let path = crate::shared_file(name)?;
    match source::load(&path, opts) {
        Ok(hm) => Some(hm),
        Err(e) => panic!("{name} failed to load: {e}"),
    }
}

fn check(e: &Expect) -> Option<Heightmap> {
    let opts = LoadOptions {
        spacing: e.spacing_opt,
        ..LoadOptions::default()
    };
    let hm = load_shared(e.file, &opts)?;
    assert_eq!(
        (hm.width(), hm.height()),
        (e.width, e.height),
        "{} dims",
        e.file
    );
    let rel = (hm.spacing() - e.spacing).abs() / e.spacing;
    assert!(
        rel <= 0.01,
        "{}: spacing {} m, sidecar says {} m",
        e.file,
        hm.spacing(),
        e.spacing
    );
    let (lo, hi) = hm.range();
    assert!(
        (lo - e.lo).abs() <= e.rounding && (hi - e.hi).abs() <= e.rounding,
        "{}: range {lo} .. {hi}, sidecar says {} .. {}",
        e.file,
        e.lo,
        e.hi
    );
    assert_eq!(hm.voids_filled(), 0, "{}: sidecar says no voids", e.file);
    Some(hm)
}

#[test]
fn puget_sound_png() {
    // PNG has no spacing: the sidecar's 160 m is passed in explicitly.
    check(&Expect {
        file: "ps_height_1k.png",
        width: 1025,
        height: 1025,
        spacing: 160.0,
        lo: 0.0,
        hi: 4379.8,
        rounding: 0.05,
        spacing_opt: Some(160.0),
    });
}

#[test]
fn kossou_tif_and_png_copy_agree_exactly() {
    // 3 arc-seconds of latitude; the sidecar's ~92.6 m is the 1852 m-per-arc-minute approximation.
    let tif = check(&Expect {
        file: "n07_w006_3arc_v2.tif",
        width: 1201,
        height: 1201,
        spacing: 92.6,
        lo: 145.0,
        hi: 546.0,
        rounding: 0.5,
        spacing_opt: None,
    });
    let png = check(&Expect {
        file: "n07_w006_3arc_v2_u16dm.png",
        width: 1201,
        height: 1201,
        spacing: 92.6,
        lo: 145.0,
        hi: 546.0,
        rounding: 0.5,
        spacing_opt: Some(92.6),
    });
    if let (Some(t), Some(p)) = (tif, png) {
        assert!(t.heights() == p.heights(), "PNG copy differs from the TIFF");
    }
}

#[test]
fn big_tujunga_tiled_tif_with_world_file_and_png_copy() {
    let tif = check(&Expect {
        file: "srtm_bigtujunga30m_utm11.tif",
        width: 1197,
        height: 643,
        spacing: 30.0,
        lo: 315.0,
        hi: 2295.0,
        rounding: 0.5,
        spacing_opt: None,
    });
    let png = check(&Expect {
        file: "srtm_bigtujunga30m_utm11_u16dm.png",
        width: 1197,
        height: 643,
        spacing: 30.0,
        lo: 315.0,
        hi: 2295.0,
        rounding: 0.5,
        spacing_opt: Some(30.0),
    });
    if let (Some(t), Some(p)) = (tif, png) {
        assert!(t.heights() == p.heights(), "PNG copy differs from the TIFF");
    }
}

#[test]
fn aletsch_f32_tif() {
    check(&Expect {
        file: "aletsch_200m.tif",
        width: 358,
        height: 310,
        spacing: 200.0,
        lo: 502.0,
        hi: 4216.3,
        rounding: 0.05,
        spacing_opt: None,
    });
}

#[test]
fn lidar_f32_tif() {
    check(&Expect {
        file: "lidar_pkg_dem_1m_400x400.tif",
        width: 400,
        height: 400,
        spacing: 1.0,
        lo: 379.66,
        hi: 410.76,
        rounding: 0.005,
        spacing_opt: None,
    });
}

#[test]
fn srtm_hgt() {
    check(&Expect {
        file: "N57E011.hgt",
        width: 1201,
        height: 1201,
        spacing: 92.6,
        lo: -6.0,
        hi: 163.0,
        rounding: 0.5,
        spacing_opt: None,
    });
}

// ---- fixtures -----------------------------------------------------------------------------------

fn temp_dir(test: &str) -> TempDir {
    TempDir::new("sources", test)
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).expect("write fixture");
    p
}

fn load(p: &Path) -> Result<Heightmap, Error> {
    source::load(p, &LoadOptions::default())
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

fn png_chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend_from_slice(&u32::try_from(data.len()).unwrap().to_be_bytes());
    let start = out.len();
    out.extend_from_slice(kind);
    out.extend_from_slice(data);
    let crc = crc32(&out[start..]);
    out.extend_from_slice(&crc.to_be_bytes());
}

/// A PNG whose IHDR declares `w` x `h` 16-bit grey, with a correct CRC and no image data.
fn png_header_only(w: u32, h: u32) -> Vec<u8> {
    let mut out = vec![0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1A, b'\n'];
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[16, 0, 0, 0, 0]);
    png_chunk(&mut out, b"IHDR", &ihdr);
    png_chunk(&mut out, b"IEND", &[]);
    out
}

/// An 8-bit palette PNG of `w` x `h` pixels with palette `rgb` and one index per pixel, its image data in
/// one stored (uncompressed) zlib block.
fn palette_png(w: u32, h: u32, rgb: &[[u8; 3]], index: impl Fn(u32, u32) -> u8) -> Vec<u8> {
    let mut out = vec![0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1A, b'\n'];
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 3, 0, 0, 0]);
    png_chunk(&mut out, b"IHDR", &ihdr);
    png_chunk(&mut out, b"PLTE", &rgb.concat());
    let mut raw = Vec::new();
    for y in 0..h {
        raw.push(0); // filter: none
        raw.extend((0..w).map(|x| index(x, y)));
    }
    let len = u16::try_from(raw.len()).unwrap();
    let mut zlib = vec![0x78, 0x01, 0x01];
    zlib.extend_from_slice(&len.to_le_bytes());
    zlib.extend_from_slice(&(!len).to_le_bytes());
    zlib.extend_from_slice(&raw);
    let (mut a, mut b) = (1u32, 0u32);
    for &v in &raw {
        a = (a + u32::from(v)) % 65521;
        b = (b + a) % 65521;
    }
    zlib.extend_from_slice(&((b << 16) | a).to_be_bytes());
    png_chunk(&mut out, b"IDAT", &zlib);
    png_chunk(&mut out, b"IEND", &[]);
    out
}

/// A small real 16-bit grey PNG, values 0..4095.
fn small_png16(dir: &Path) -> PathBuf {
    let img = image::ImageBuffer::<image::Luma<u16>, _>::from_fn(64, 48, |x, y| {
        image::Luma([u16::try_from((x * 64 + y) % 4096).unwrap()])
    });
    let p = dir.join("small16.png");
    img.save(&p).expect("save png");
    p
}

/// A little-endian TIFF declaring `w` x `h` int16 in one strip, hand-made so nothing is allocated.
fn tiff_header_only(w: u32, h: u32) -> Vec<u8> {
    let mut out = one_strip_tiff(w, h, (2, 16), 1, 64);
    out.resize(264, 0);
    out
}

/// The header and tags of a little-endian TIFF of `w` x `h` samples in one strip of `strip_bytes` bytes
/// at byte 200: `format` is (SampleFormat: 1 unsigned, 2 signed, 3 float; BitsPerSample), `compression`
/// the TIFF code (1 none, 50000 ZSTD). Hand-made for what the tiff crate's encoder does not write.
fn one_strip_tiff(
    w: u32,
    h: u32,
    (format, bits): (u32, u32),
    compression: u32,
    strip_bytes: u32,
) -> Vec<u8> {
    let mut out = b"II*\0".to_vec();
    out.extend_from_slice(&8u32.to_le_bytes());
    let entries: [(u16, u16, u32); 10] = [
        (256, 4, w),           // ImageWidth, LONG
        (257, 4, h),           // ImageLength
        (258, 3, bits),        // BitsPerSample, SHORT
        (259, 3, compression), // Compression
        (262, 3, 1),           // Photometric: BlackIsZero
        (273, 4, 200),         // StripOffsets
        (277, 3, 1),           // SamplesPerPixel
        (278, 4, h),           // RowsPerStrip
        (279, 4, strip_bytes), // StripByteCounts
        (339, 3, format),      // SampleFormat
    ];
    out.extend_from_slice(&u16::try_from(entries.len()).unwrap().to_le_bytes());
    for (tag, ty, v) in entries {
        out.extend_from_slice(&tag.to_le_bytes());
        out.extend_from_slice(&ty.to_le_bytes());
        out.extend_from_slice(&1u32.to_le_bytes());
        if ty == 3 {
            out.extend_from_slice(&u16::try_from(v).unwrap_or(0).to_le_bytes());
            out.extend_from_slice(&[0, 0]);
        } else {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out.extend_from_slice(&0u32.to_le_bytes());
    out.resize(200, 0);
    out
}

/// A float32 TIFF written with the tiff crate's encoder, with optional GDAL nodata and geo tags.
fn f32_tiff(dir: &Path, name: &str, w: u32, h: u32, data: &[f32], geo: bool) -> PathBuf {
    use tiff::encoder::{colortype::Gray32Float, TiffEncoder};
    use tiff::tags::Tag;
    let p = dir.join(name);
    let file = std::fs::File::create(&p).expect("create tiff");
    let mut enc = TiffEncoder::new(file).expect("tiff encoder");
    let mut img = enc.new_image::<Gray32Float>(w, h).expect("tiff image");
    img.encoder()
        .write_tag(Tag::GdalNodata, "-9999")
        .expect("nodata tag");
    if geo {
        // Geographic (GTModelTypeGeoKey = 2), 3 arc-second pixels, north-west corner at 8 N.
        let keys: [u16; 8] = [1, 1, 0, 1, 1024, 0, 1, 2];
        img.encoder()
            .write_tag(Tag::GeoKeyDirectoryTag, &keys[..])
            .expect("geokeys");
        let scale = [1.0 / 1200.0, 1.0 / 1200.0, 0.0f64];
        img.encoder()
            .write_tag(Tag::ModelPixelScaleTag, &scale[..])
            .expect("pixel scale");
        let tie = [0.0, 0.0, 0.0, -6.0, 8.0, 0.0f64];
        img.encoder()
            .write_tag(Tag::ModelTiepointTag, &tie[..])
            .expect("tiepoint");
    }
    img.write_data(data).expect("tiff data");
    p
}

/// Writes each `(name, bytes, needle)` into `dir` and checks that loading it is refused with a message
/// that contains `needle`.
fn assert_refused(dir: &Path, cases: &[(&str, &[u8], &str)]) {
    for &(name, bytes, needle) in cases {
        let e = load(&write(dir, name, bytes)).expect_err(name);
        assert!(e.to_string().contains(needle), "{name}: {e}");
    }
}

fn assert_format(r: Result<Heightmap, Error>, needle: &str) {
    match r {
        Err(Error::Format { reason, .. }) => assert!(
            reason.contains(needle),
            "reason `{reason}` does not mention `{needle}`"
        ),
        other => panic!("expected Error::Format mentioning `{needle}`, got {other:?}"),
    }
}

// ---- good fixtures ------------------------------------------------------------------------------

#[test]
fn png_scales_and_offsets() {
    let dir = temp_dir("png_scale");
    let p = small_png16(&dir);
    let hm = load(&p).unwrap();
    assert_eq!((hm.width(), hm.height(), hm.spacing()), (64, 48, 30.0));
    assert_eq!(hm.at(1, 2), 6.6); // value 66 at 0.1 m
    let opts = LoadOptions {
        height_scale: Some(2.0),
        height_offset: -5.0,
        spacing: Some(10.0),
        ..LoadOptions::default()
    };
    let hm = source::load(&p, &opts).unwrap();
    assert_eq!((hm.at(1, 2), hm.spacing()), (66.0 * 2.0 - 5.0, 10.0));

    let img8 = image::ImageBuffer::<image::Luma<u8>, _>::from_fn(8, 8, |x, _| {
        image::Luma([u8::try_from(x).unwrap()])
    });
    let p8 = dir.join("small8.png");
    img8.save(&p8).unwrap();
    assert_eq!(load(&p8).unwrap().at(7, 0), 7.0);

    // Unequal channels without an encoding: refused, naming the option that would read it.
    let mut rgb = image::RgbImage::new(8, 8);
    rgb.put_pixel(3, 2, image::Rgb([10, 11, 10]));
    let prgb = dir.join("rgb.png");
    rgb.save(&prgb).unwrap();
    assert_format(load(&prgb), "LoadOptions::png_encoding");
    assert_format(load(&prgb), "column 3, row 2");
}

#[expect(
    clippy::cast_possible_truncation,
    reason = "the loader's own rounding: metres in f64, once to f32"
)]
fn to_f32(v: f64) -> f32 {
    v as f32
}

/// RGB, RGBA and palette files whose channels are equal (as many tools export 8-bit height maps) read as
/// grey, at 8 and 16 bits, with the grey scales (1 m and 0.1 m per unit); alpha is ignored.
#[test]
fn png_rgb_with_equal_channels_reads_as_grey() {
    let dir = temp_dir("png_rgb_grey");
    let grey = |x: u32, y: u32| u8::try_from((x * 37 + y * 11) % 256).unwrap();
    let rgb = image::RgbImage::from_fn(9, 5, |x, y| image::Rgb([grey(x, y); 3]));
    let rgba = image::RgbaImage::from_fn(9, 5, |x, y| {
        let v = grey(x, y);
        image::Rgba([v, v, v, u8::try_from(x * 20).unwrap()])
    });
    let rgb16 = image::ImageBuffer::<image::Rgb<u16>, _>::from_fn(9, 5, |x, y| {
        image::Rgb([u16::from(grey(x, y)) * 257; 3])
    });
    let (p1, p2, p3) = (
        dir.join("rgb.png"),
        dir.join("rgba.png"),
        dir.join("rgb16.png"),
    );
    rgb.save(&p1).unwrap();
    rgba.save(&p2).unwrap();
    rgb16.save(&p3).unwrap();
    // A palette of greys, as some tools write 8-bit height maps; a coloured palette is refused.
    let greys: Vec<[u8; 3]> = (0..=255u8).map(|v| [v; 3]).collect();
    let p4 = write(&dir, "palette.png", &palette_png(9, 5, &greys, grey));
    let mut coloured = greys.clone();
    coloured[7] = [7, 8, 7];
    let p5 = write(
        &dir,
        "palette-colour.png",
        &palette_png(9, 5, &coloured, |_, _| 7),
    );
    assert_format(load(&p5), "png_encoding");
    // The bake's row reader gives the same samples, and the same refusal.
    for p in [&p1, &p2, &p3, &p4, &small_png16(&dir)] {
        assert_eq!(rows_of(p).3, load(p).unwrap().heights(), "{}", p.display());
    }
    let mut rows = source::open_rows(&p5, &LoadOptions::default()).expect("open rows");
    let mut all = vec![0.0f32; 45];
    match rows.read_rows(0, &mut all) {
        Err(Error::Format { reason, .. }) => assert!(reason.contains("png_encoding"), "{reason}"),
        other => panic!("expected a refusal, got {other:?}"),
    }
    for (p, scale) in [(&p1, 1.0f64), (&p2, 1.0), (&p3, 25.7), (&p4, 1.0)] {
        let hm = load(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert_eq!((hm.width(), hm.height()), (9, 5));
        for y in 0..5 {
            for x in 0..9 {
                let want = to_f32(f64::from(grey(x, y)) * scale);
                assert_eq!(hm.at(x, y), want, "{} ({x}, {y})", p.display());
            }
        }
    }
}

/// The web-map encodings decode exactly: hand-made 8-bit RGB(A) files with known pixels.
#[test]
fn png_web_map_encodings_decode_exactly() {
    use clipsat::source::PngEncoding;
    let dir = temp_dir("png_encodings");
    let with = |e: PngEncoding| LoadOptions {
        png_encoding: e,
        ..LoadOptions::default()
    };
    // Mapbox Terrain-RGB: h = -10000 + (R 65536 + G 256 + B) 0.1.
    let terrain_rgb: [([u8; 3], f32); 6] = [
        ([1, 134, 160], 0.0),   // 100000 -> 0 m
        ([0, 0, 0], -10000.0),  // the lowest
        ([1, 134, 161], 0.1),   // one step up
        ([1, 154, 40], 500.0),  // 105000
        ([2, 12, 178], 3432.2), // 134322
        ([255, 255, 255], 1_667_721.5),
    ];
    // Terrarium: h = R 256 + G + B / 256 - 32768.
    let terrarium: [([u8; 3], f32); 5] = [
        ([128, 0, 0], 0.0),
        ([128, 100, 128], 100.5),
        ([127, 255, 192], -0.25),
        ([0, 0, 0], -32768.0),
        ([141, 104, 64], 3432.25), // 36200.25 - 32768
    ];
    for (encoding, table) in [
        (PngEncoding::TerrainRgb, &terrain_rgb[..]),
        (PngEncoding::Terrarium, &terrarium[..]),
    ] {
        let w = u32::try_from(table.len()).unwrap();
        let rgb = image::RgbImage::from_fn(w, 2, |x, _| image::Rgb(table[x as usize].0));
        let rgba = image::RgbaImage::from_fn(w, 2, |x, _| {
            let [r, g, b] = table[x as usize].0;
            image::Rgba([r, g, b, 255])
        });
        let (p, pa) = (
            dir.join(format!("{encoding}.png")),
            dir.join(format!("{encoding}-a.png")),
        );
        rgb.save(&p).unwrap();
        rgba.save(&pa).unwrap();
        for file in [&p, &pa] {
            let hm = source::load(file, &with(encoding))
                .unwrap_or_else(|e| panic!("{}: {e}", file.display()));
            for (x, (px, want)) in table.iter().enumerate() {
                let x = u32::try_from(x).unwrap();
                assert_eq!(hm.at(x, 0), *want, "{encoding} {px:?}");
                assert_eq!(hm.at(x, 1), *want, "{encoding} {px:?}");
            }
        }
        // The same pixels as grey: unequal channels, refused.
        assert_format(load(&p), "png_encoding");
        // A height scale makes no sense for an encoding that gives metres.
        let scaled = LoadOptions {
            height_scale: Some(2.0),
            ..with(encoding)
        };
        assert_format(source::load(&p, &scaled), "height scale");
    }
    // An encoding on a grey file: refused, naming the option.
    let grey = image::GrayImage::new(4, 4);
    let pg = dir.join("grey.png");
    grey.save(&pg).unwrap();
    assert_format(
        source::load(&pg, &with(PngEncoding::Terrarium)),
        "needs 8-bit RGB",
    );
}

#[test]
fn tiff_nodata_filled_and_geographic_spacing() {
    let dir = temp_dir("tiff_nodata");
    let mut data: Vec<f32> = (0..16).map(|i| i as f32).collect();
    data[5] = -9999.0;
    data[6] = -9999.0;
    let p = f32_tiff(&dir, "voids.tif", 4, 4, &data, true);
    let hm = load(&p).unwrap();
    assert_eq!(hm.voids_filled(), 2);
    assert!(hm.heights().iter().all(|h| (0.0..16.0).contains(h)));
    // 1/1200 degree of latitude near 7.99 N is about 92.16 m.
    assert!((hm.spacing() - 92.16).abs() < 0.05, "{}", hm.spacing());
    // Pixel-is-area: the north-west sample's centre half a pixel in from the tiepoint's corner.
    let g = hm.geo().expect("a geographic GeoTIFF");
    let px = 1.0 / 1200.0;
    assert!(
        (g.north - (8.0 - 0.5 * px)).abs() < 1e-12 && (g.west - (-6.0 + 0.5 * px)).abs() < 1e-12
    );
    assert!(
        (g.south - (8.0 - 3.5 * px)).abs() < 1e-12
            && (g.frame_lat - (8.0 - 2.0 * px)).abs() < 1e-12
    );
    let five = LoadOptions {
        spacing: Some(5.0),
        ..LoadOptions::default()
    };
    assert_eq!(
        source::load(&p, &five).unwrap().geo(),
        None,
        "metres given by hand"
    );

    let p = f32_tiff(&dir, "nospacing.tif", 4, 4, &data, false);
    assert_format(load(&p), "TerrainOptions::spacing_m");
    let opts = LoadOptions {
        spacing: Some(5.0),
        ..LoadOptions::default()
    };
    assert_eq!(source::load(&p, &opts).unwrap().spacing(), 5.0);
}

/// Every row of `path` through the bake's reader ([`source::open_rows`]).
fn rows_of(path: &Path) -> (u32, u32, f32, Vec<f32>) {
    rows_with(path, &LoadOptions::default())
}

/// [`rows_of`] with `opts`.
fn rows_with(path: &Path, opts: &LoadOptions) -> (u32, u32, f32, Vec<f32>) {
    let mut rows = source::open_rows(path, opts).expect("open rows");
    let (w, h) = (rows.width(), rows.height());
    let mut all = vec![0.0f32; w as usize * h as usize];
    // In uneven bands, to cross strip boundaries.
    let mut y = 0;
    for band in [1u32, 7, 64].into_iter().cycle() {
        if y >= h {
            break;
        }
        let n = band.min(h - y);
        let at = y as usize * w as usize;
        rows.read_rows(y, &mut all[at..at + n as usize * w as usize])
            .expect("read rows");
        y += n;
    }
    (w, h, rows.spacing(), all)
}

#[test]
fn tiff_rows_read_by_chunks_match_the_whole_load() {
    let dir = temp_dir("tiff_rows");
    // Voids: the rows come from the whole load, voids filled.
    let mut data: Vec<f32> = (0..16).map(|i| i as f32).collect();
    data[5] = -9999.0;
    let p = f32_tiff(&dir, "voids.tif", 4, 4, &data, true);
    let hm = load(&p).unwrap();
    assert_eq!(rows_of(&p), (4, 4, hm.spacing(), hm.heights().to_vec()));
    // No voids, several strips: read a row of strips at a time.
    let (w, h) = (300u32, 101u32);
    let data: Vec<f32> = (0..w * h).map(|i| (i % 977) as f32 * 0.25).collect();
    let p = f32_tiff(&dir, "strips.tif", w, h, &data, true);
    let hm = load(&p).unwrap();
    assert_eq!(rows_of(&p), (w, h, hm.spacing(), hm.heights().to_vec()));
}

/// Every sample type elevation data comes in, and ZSTD strips (GDAL writes them with COMPRESS=ZSTD), load
/// to the same heights: int8, uint8 and uint32 through the encoder, float16 and a ZSTD float32 strip by hand.
#[test]
fn tiff_sample_types_and_zstd() {
    use tiff::encoder::{colortype, TiffEncoder};
    let dir = temp_dir("tiff_types");
    let (w, h) = (5u32, 3u32);
    let values: Vec<i8> = (0..15).map(|i| i8::try_from(i * 7 - 50).unwrap()).collect();
    let want: Vec<f32> = values.iter().map(|&v| f32::from(v)).collect();
    // Spacing from a world file beside each.
    let world = |name: &str| {
        write(
            &dir,
            &name.replace(".tif", ".tfw"),
            b"30\n0\n0\n-30\n0\n0\n",
        )
    };
    for name in ["i8.tif", "u8.tif", "u32.tif", "f16.tif", "zstd.tif"] {
        world(name);
    }
    let encoded = |name: &str, write: &dyn Fn(&mut TiffEncoder<std::fs::File>)| {
        let p = dir.join(name);
        let mut enc =
            TiffEncoder::new(std::fs::File::create(&p).expect("create")).expect("encoder");
        write(&mut enc);
        p
    };
    let i8_tif = encoded("i8.tif", &|e| {
        e.write_image::<colortype::GrayI8>(w, h, &values)
            .expect("i8");
    });
    let u8_tif = encoded("u8.tif", &|e| {
        let v: Vec<u8> = values.iter().map(|&v| v.abs_diff(0)).collect();
        e.write_image::<colortype::Gray8>(w, h, &v).expect("u8");
    });
    let u32_tif = encoded("u32.tif", &|e| {
        let v: Vec<u32> = values
            .iter()
            .map(|&v| 100_000 + u32::from(v.abs_diff(0)))
            .collect();
        e.write_image::<colortype::Gray32>(w, h, &v).expect("u32");
    });
    assert_eq!(load(&i8_tif).unwrap().heights(), &want[..]);
    let abs: Vec<f32> = want.iter().map(|v| v.abs()).collect();
    assert_eq!(load(&u8_tif).unwrap().heights(), &abs[..]);
    // Past u16's range, and exact in f32.
    let big: Vec<f32> = abs.iter().map(|v| 100_000.0 + v).collect();
    assert_eq!(load(&u32_tif).unwrap().heights(), &big[..]);
    // float16: every value here is exact in half precision.
    let mut f16_tif = one_strip_tiff(w, h, (3, 16), 1, w * h * 2);
    for v in &want {
        f16_tif.extend_from_slice(&half::f16::from_f32(*v).to_bits().to_le_bytes());
    }
    assert_eq!(
        load(&write(&dir, "f16.tif", &f16_tif)).unwrap().heights(),
        &want[..]
    );
    // A ZSTD-compressed float32 strip.
    let raw: Vec<u8> = want.iter().flat_map(|v| v.to_le_bytes()).collect();
    let packed = zstd::bulk::compress(&raw, 3).expect("zstd");
    let mut zstd_tif = one_strip_tiff(w, h, (3, 32), 50000, u32::try_from(packed.len()).unwrap());
    zstd_tif.extend_from_slice(&packed);
    let p = write(&dir, "zstd.tif", &zstd_tif);
    assert_eq!(load(&p).unwrap().heights(), &want[..]);
    // The bake's band reader agrees with the whole load.
    for p in [&i8_tif, &u32_tif, &p] {
        let hm = load(p).unwrap();
        assert_eq!(rows_of(p).3, hm.heights().to_vec(), "{}", p.display());
    }
}

/// A geographic grid records its E-W spacing (shorter than the N-S one away from the equator), and
/// `resample_ew` resamples its rows to square cells, the same through the bake's band reader as through
/// the whole load: a ramp along each row stays a ramp, and the grid keeps its true E-W extent.
#[test]
fn geographic_grids_resample_to_square_cells() {
    let dir = temp_dir("resample_ew");
    // 41 x 3 samples of 0.001 degrees at 60 N: E-W cells about half the N-S ones.
    let mut text =
        String::from("ncols 41\nnrows 3\nxllcorner 10\nyllcorner 59.9985\ncellsize 0.001\n");
    for j in 0..3 {
        let row: Vec<String> = (0..41).map(|i| format!("{}", i * 10 + j)).collect();
        text += &row.join(" ");
        text.push('\n');
    }
    let p = write(&dir, "geo.asc", text.as_bytes());
    write(&dir, "geo.prj", b"GEOGCRS[\"WGS 84\"]");
    let plain = load(&p).unwrap();
    let (ns, ew) = (f64::from(plain.spacing()), f64::from(plain.ew_spacing()));
    assert!((ns - 111.41).abs() < 0.05, "N-S {ns} m");
    assert!((ew - 55.80).abs() < 0.05, "E-W {ew} m");
    assert!((plain.ew_stretch() - ns / ew).abs() < 1e-12);
    let opts = LoadOptions {
        resample_ew: true,
        ..LoadOptions::default()
    };
    let square = source::load(&p, &opts).unwrap();
    // 40 E-W cells of 55.8 m are 20 cells of 111.4 m.
    assert_eq!((square.width(), square.height()), (21, 3));
    assert!(
        (square.ew_stretch() - 1.0).abs() < 0.01,
        "{}",
        square.ew_stretch()
    );
    let step = 40.0 / 20.0;
    for (x, z) in square.heights()[21..42].iter().enumerate() {
        // Row 1 is 10 i + 1 at source column i; inside the row the tent filter keeps a ramp exact.
        if (1..20).contains(&x) {
            assert!(
                (f64::from(*z) - (10.0 * x as f64 * step + 1.0)).abs() < 1e-3,
                "column {x}: {z}"
            );
        }
    }
    let mut rows = source::open_rows(&p, &opts).expect("open rows");
    assert_eq!((rows.width(), rows.height()), (21, 3));
    let mut all = vec![0.0f32; 21 * 3];
    rows.read_rows(0, &mut all[..21]).unwrap();
    rows.read_rows(1, &mut all[21..]).unwrap();
    assert_eq!(all, square.heights());
    // A projected grid, and the shared SRTM tile's recorded E-W spacing (its sidecar: ~50 m at 57.5 N).
    assert_eq!(
        load(&write(
            &dir,
            "m.asc",
            b"ncols 2\nnrows 2\ncellsize 5\n1 2 3 4\n"
        ))
        .unwrap()
        .ew_stretch(),
        1.0
    );
    if let Some(hm) = load_shared("N57E011.hgt", &LoadOptions::default()) {
        assert!((hm.ew_spacing() - 50.0).abs() < 0.1, "{}", hm.ew_spacing());
        // Placed by its name: sample rows on 57 and 58 N, its metres taken at 57.5 N.
        let g = hm.geo().expect("an SRTM tile named by its corner");
        for (a, b) in [
            (g.south, 57.0),
            (g.north, 58.0),
            (g.west, 11.0),
            (g.east, 12.0),
            (g.frame_lat, 57.5),
        ] {
            assert!((a - b).abs() < 1e-9, "{g:?}");
        }
    }
}

/// ESRI ASCII grids: samples wrapped over lines, voids filled and counted, the spacing from the cell size,
/// in degrees where the `.prj` is geographic; every malformed file refused naming the line or the count.
#[test]
fn ascii_grids() {
    let dir = temp_dir("asc");
    let hm = load(&write(
        &dir,
        "wrap.asc",
        b"NCOLS 3\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 10\nNODATA_value -9999\n1 2\n3 -9999 5\n6\n",
    ))
    .unwrap();
    assert_eq!((hm.width(), hm.height(), hm.spacing()), (3, 2, 10.0));
    // The void, the first sample of the second row, is the mean of its neighbours 1 (north) and 5 (east).
    assert_eq!(hm.heights(), &[1.0, 2.0, 3.0, 3.0, 5.0, 6.0]);
    assert_eq!(hm.voids_filled(), 1);
    // NaN declared as the void marker: filled, like any other.
    let nan = load(&write(
        &dir,
        "nan_voids.asc",
        b"ncols 2\nnrows 2\ncellsize 1\nNODATA_value nan\n1 nan\n3 5\n",
    ))
    .unwrap();
    assert_eq!(
        (nan.heights(), nan.voids_filled()),
        (&[1.0, 3.0, 3.0, 5.0][..], 1)
    );
    // Degrees: 3 arc-seconds at 46.5 N from a geographic .prj; refused without one.
    let deg =
        b"ncols 2\nnrows 2\nxllcenter 10\nyllcenter 46.5\ncellsize 0.000833333333\n1 2\n3 4\n";
    let no_prj = write(&dir, "deg.asc", deg);
    assert_format(load(&no_prj), "under 1 cm");
    let with_prj = write(&dir, "geo.asc", deg);
    write(&dir, "geo.prj", br#"GEOGCS["WGS 84",DATUM["WGS_1984"]]"#);
    let hm = load(&with_prj).unwrap();
    let s = hm.spacing();
    let g = hm.geo().expect("a grid in degrees");
    assert_eq!((g.west, g.south), (10.0, 46.5));
    assert!((g.north - (46.5 + 0.000833333333)).abs() < 1e-12);
    assert!(
        (s - 92.6).abs() < 0.1,
        "3 arc-seconds of latitude at 46.5 N: {s} m"
    );
    assert_refused(
        &dir,
        &[
            (
                "short.asc",
                &b"ncols 3\nnrows 2\ncellsize 10\n1 2 3\n4\n"[..],
                "4 samples where the header says 3 x 2",
            ),
            (
                "long.asc",
                b"ncols 2\nnrows 2\ncellsize 10\n1 2 3 4 5\n",
                "more samples than",
            ),
            (
                "word.asc",
                b"ncols 2\nnrows 2\ncellsize 10\n1 x\n",
                "line 4: sample `x`",
            ),
            (
                "key.asc",
                b"ncols 2\nnrows 2\nsize 10\n1 2\n",
                "unknown ASCII grid header key `size`",
            ),
            ("nocols.asc", b"nrows 1\ncellsize 10\n1 2\n", "no `ncols`"),
            (
                "cell.asc",
                b"ncols 2\nnrows 2\ncellsize -1\n1 2 3 4\n",
                "not a positive number",
            ),
            (
                "huge.asc",
                b"ncols 30000\nnrows 30000\ncellsize 1\n1 2 3\n",
                "3 samples where the header says 30000 x 30000",
            ),
            ("empty.asc", b"ncols 2\nnrows 2\ncellsize 1\n", "no samples"),
            (
                "nan.asc",
                b"ncols 2\nnrows 2\ncellsize 1\n1 nan 3 4\n",
                "write `NODATA_value nan`",
            ),
        ],
    );
}

/// Writes an ESRI binary grid `name` and the `.hdr` beside it.
fn write_gridded(dir: &Path, name: &str, data: &[u8], hdr: &[u8]) -> PathBuf {
    let p = write(dir, name, data);
    std::fs::write(p.with_extension("hdr"), hdr).expect("write header");
    p
}

/// ESRI binary grids with a `.hdr` (GridFloat `.flt`, BIL `.bil`): every sample type and byte order,
/// row padding and a skipped prefix, voids filled, the spacing from the header (in degrees with a
/// geographic `.prj`), the bake's row reader giving the same samples; malformed headers refused naming the
/// key.
#[test]
fn esri_binary_grids() {
    let dir = temp_dir("ehdr");
    let ints: [i16; 6] = [1, 2, 3, -4, 5, 6];
    let heights = ints.map(f32::from);
    // GridFloat, little-endian, with a void (the fifth sample) filled from its neighbours 2 (north),
    // -4 (west) and 6 (east).
    let mut flt: Vec<u8> = heights.iter().flat_map(|v| v.to_le_bytes()).collect();
    flt[16..20].copy_from_slice(&(-9999.0f32).to_le_bytes());
    let p = write_gridded(
        &dir,
        "grid.flt",
        &flt,
        b"ncols 3\nnrows 2\nxllcorner 500000\nyllcorner 4000000\ncellsize 10\nNODATA_value -9999\nbyteorder LSBFIRST\n",
    );
    let hm = load(&p).unwrap();
    assert_eq!((hm.width(), hm.height(), hm.spacing()), (3, 2, 10.0));
    assert_eq!(hm.heights(), &[1.0, 2.0, 3.0, -4.0, 4.0 / 3.0, 6.0]);
    assert_eq!(hm.voids_filled(), 1);
    // A void makes the bake read it whole; the rows are the load's either way.
    assert_eq!(rows_of(&p).3, hm.heights());
    // BIL, big-endian int16, 4 bytes skipped and each row padded to 8 bytes.
    let mut bil = vec![0xee; 4];
    for row in ints.chunks(3) {
        for v in row {
            bil.extend_from_slice(&v.to_be_bytes());
        }
        bil.extend_from_slice(&[0xee, 0xee]);
    }
    bil.truncate(bil.len() - 2);
    let p = write_gridded(
        &dir,
        "be.bil",
        &bil,
        b"BYTEORDER M\nLAYOUT BIL\nNROWS 2\nNCOLS 3\nNBANDS 1\nNBITS 16\nPIXELTYPE SIGNEDINT\nSKIPBYTES 4\nTOTALROWBYTES 8\nXDIM 25\nYDIM 25\nSOMEKEY ignored\n",
    );
    let hm = load(&p).unwrap();
    assert_eq!((hm.heights(), hm.spacing()), (&heights[..], 25.0));
    assert_eq!(rows_of(&p).3, hm.heights());
    // Unsigned bytes (ESRI's default type) need no byte order; 32-bit unsigned little-endian.
    let p = write_gridded(
        &dir,
        "u8.bil",
        &[1, 2, 3, 4],
        b"nrows 2\nncols 2\ncellsize 5\n",
    );
    assert_eq!(load(&p).unwrap().heights(), &[1.0, 2.0, 3.0, 4.0]);
    let u32s: Vec<u8> = [7u32, 8, 9, 4_000_000]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let p = write_gridded(
        &dir,
        "u32.bil",
        &u32s,
        b"nrows 2\nncols 2\nnbits 32\nbyteorder I\ncellsize 5\n",
    );
    assert_eq!(load(&p).unwrap().heights(), &[7.0, 8.0, 9.0, 4_000_000.0]);
    // 64-bit floats, big-endian.
    let f64s: Vec<u8> = [1.5f64, -2.25, 3.0, 1e4]
        .iter()
        .flat_map(|v| v.to_be_bytes())
        .collect();
    let p = write_gridded(
        &dir,
        "f64.bil",
        &f64s,
        b"nrows 2\nncols 2\nnbits 64\npixeltype float\nbyteorder M\ncellsize 5\n",
    );
    assert_eq!(load(&p).unwrap().heights(), &[1.5, -2.25, 3.0, 1e4]);
    // Degrees: 1 arc-second at 34.5 N (ULYMAP is the north-west sample's centre) with a geographic .prj.
    let p = write_gridded(
        &dir,
        "geo.bil",
        &[0, 1, 0, 2, 0, 3, 0, 4],
        b"BYTEORDER M\nNROWS 2\nNCOLS 2\nNBITS 16\nULXMAP -118\nULYMAP 34.5\nXDIM 0.000277777777778\nYDIM 0.000277777777778\n",
    );
    assert_format(load(&p), "under 1 cm");
    write(&dir, "geo.prj", br#"GEOGCS["WGS 84",DATUM["WGS_1984"]]"#);
    let hm = load(&p).unwrap();
    assert!((hm.spacing() - 30.8).abs() < 0.1, "{} m", hm.spacing());
    let g = hm.geo().expect("a grid in degrees");
    assert_eq!((g.north, g.west), (34.5, -118.0));
    assert!((g.south - (34.5 - 0.000277777777778)).abs() < 1e-12);
    assert!(
        hm.ew_spacing() < hm.spacing() * 0.83,
        "{} m E-W",
        hm.ew_spacing()
    );
    // Malformed: each refused, naming what is wrong.
    let four = [0u8; 8];
    for (name, hdr, data, needle) in [
        ("nohdr", None, &four[..], "cannot read the header"),
        (
            "order",
            Some(&b"nrows 2\nncols 2\nnbits 16\n"[..]),
            &four[..],
            "no byte order",
        ),
        (
            "bands",
            Some(b"nrows 2\nncols 2\nnbands 3\n"),
            &four[..],
            "3 bands",
        ),
        (
            "bits",
            Some(b"nrows 2\nncols 2\nnbits 12\nbyteorder I\n"),
            &four[..],
            "12-bit",
        ),
        (
            "type",
            Some(b"nrows 2\nncols 2\npixeltype complex\n"),
            &four[..],
            "PIXELTYPE `complex`",
        ),
        (
            "rows",
            Some(b"nrows two\nncols 2\n"),
            &four[..],
            "`nrows` value `two`",
        ),
        (
            "short",
            Some(b"nrows 3\nncols 3\ncellsize 1\n"),
            &four[..],
            "at least 9 bytes",
        ),
        (
            "envi",
            Some(b"ENVI\nsamples = 2\n"),
            &four[..],
            "ENVI header",
        ),
        (
            "pad",
            Some(b"nrows 2\nncols 4\ntotalrowbytes 2\n"),
            &four[..],
            "TOTALROWBYTES 2",
        ),
        (
            "cell",
            Some(b"nrows 2\nncols 4\n"),
            &four[..],
            "no cell size",
        ),
    ] {
        let p = write(&dir, &format!("{name}.bil"), data);
        if let Some(h) = hdr {
            write(&dir, &format!("{name}.hdr"), h);
        }
        let e = load(&p).expect_err(name);
        assert!(e.to_string().contains(needle), "{name}: {e}");
    }
}

/// A DTED cell: the user header label, blank DSI and ACC records, then one data record per column (west to
/// east), each from south to north in signed magnitude, with its checksum.
fn dted_cell(lat_origin: &str, lat_int: u32, lon_int: u32, columns: &[Vec<i16>]) -> Vec<u8> {
    let rows = columns[0].len();
    let mut f = format!(
        "UHL10100000E{lat_origin}{lon_int:04}{lat_int:04}NA  U  {:12}{:04}{:04}0{:24}",
        "",
        columns.len(),
        rows,
        ""
    )
    .into_bytes();
    assert_eq!(f.len(), 80);
    f.extend(b"DSI");
    f.resize(80 + 648, b' ');
    f.extend(b"ACC");
    f.resize(80 + 648 + 2700, b' ');
    for (x, col) in columns.iter().enumerate() {
        let x = u16::try_from(x).expect("a test cell's columns fit u16");
        // Sentinel, block count (3 bytes), longitude count.
        let mut rec = vec![0xAA, 0];
        rec.extend(x.to_be_bytes());
        rec.extend(x.to_be_bytes());
        rec.extend(0u16.to_be_bytes());
        for &v in col {
            let m = v.unsigned_abs() | if v < 0 { 0x8000 } else { 0 };
            rec.extend(m.to_be_bytes());
        }
        let sum: u32 = rec.iter().map(|&b| u32::from(b)).sum();
        rec.extend(sum.to_be_bytes());
        f.extend(rec);
    }
    f
}

/// DTED cells: columns turned into rows (north first), signed-magnitude heights, voids filled, the spacing
/// from the header's intervals at the cell's latitude (E-W recorded); a damaged record refused naming its
/// column.
#[test]
fn dted_cells() {
    let dir = temp_dir("dted");
    // Two columns of three points, south to north; -32767 is a void.
    let cols = vec![vec![10i16, -20, 30], vec![40, -32767, 60]];
    // 3 arc-seconds N-S, 6 E-W (DTED level 1 between 50 and 70 degrees), at 60 N.
    let cell = dted_cell("0600000N", 30, 60, &cols);
    let p = write(&dir, "n60.dt1", &cell);
    let hm = load(&p).unwrap();
    assert_eq!((hm.width(), hm.height()), (2, 3));
    // North row first: (30, 60), (-20, void), (10, 40). The void is the mean of 60, -20 and 40.
    assert_eq!(hm.heights(), &[30.0, 60.0, -20.0, 80.0 / 3.0, 10.0, 40.0]);
    assert_eq!(hm.voids_filled(), 1);
    assert!(
        (hm.spacing() - 92.84).abs() < 0.05,
        "{} m N-S",
        hm.spacing()
    );
    // The origin is the south-west sample: 60 N, 10 E; 2 rows of 3" north of it.
    let g = hm.geo().expect("a DTED cell is in degrees");
    assert_eq!((g.south, g.west), (60.0, 10.0));
    assert!(
        (g.north - (60.0 + 6.0 / 3600.0)).abs() < 1e-12
            && (g.east - (10.0 + 6.0 / 3600.0)).abs() < 1e-12
    );
    // 6 arc-seconds of longitude at 60 N are about as long as 3 of latitude.
    assert!(
        (hm.ew_spacing() / hm.spacing() - 1.0).abs() < 0.01,
        "{} m E-W",
        hm.ew_spacing()
    );
    // Found by its magic number under another name too.
    assert_eq!(
        load(&write(&dir, "cell.bin", &cell)).unwrap().heights(),
        hm.heights()
    );
    let at = 80 + 648 + 2700;
    let mut sum = cell.clone();
    sum[at + 8] ^= 1;
    let mut sentinel = cell.clone();
    sentinel[at + 18] = 0;
    let mut order = cell.clone();
    order[at + 18 + 5] = 7;
    let mut hemi = cell.clone();
    hemi[19] = b'X';
    assert_refused(
        &dir,
        &[
            ("sum.dt1", &sum[..], "column 0: checksum"),
            ("sentinel.dt1", &sentinel, "column 1: record sentinel 0x00"),
            ("order.dt1", &order, "says it is column 7"),
            ("hemi.dt1", &hemi, "latitude of origin `0600000X`"),
            ("short.dt1", &cell[..cell.len() - 1], "at least"),
            ("head.dt1", &cell[..100], "truncated DTED cell"),
        ],
    );
}

/// Gridded XYZ text: a header skipped, points in any order and separator, a missing point filled as a
/// void, the spacing from the points; points off the grid or twice on a cell refused naming the line.
#[test]
fn xyz_grids() {
    let dir = temp_dir("xyz");
    // A 3 x 2 grid at 2 m, south row first, one point (1002, 502) missing, a header and a comma line.
    let text = b"X Y Z\n1000 500 4\n1002 500 5\n1004,500,6\n1000 502 1\n\n1004\t502\t3\n";
    let hm = load(&write(&dir, "grid.xyz", text)).unwrap();
    assert_eq!((hm.width(), hm.height(), hm.spacing()), (3, 2, 2.0));
    // North row first; the void is the mean of its neighbours 1 (west), 3 (east) and 5 (south).
    assert_eq!(hm.heights(), &[1.0, 3.0, 3.0, 4.0, 5.0, 6.0]);
    assert_eq!(hm.voids_filled(), 1);
    assert_eq!(hm.geo(), None, "in metres");
    // In degrees (a geographic .prj): the points are the sample centres.
    write(&dir, "deg.prj", br#"GEOGCS["WGS 84",DATUM["WGS_1984"]]"#);
    let deg = load(&write(
        &dir,
        "deg.xyz",
        b"10 46 1\n10.5 46 2\n10 46.5 3\n10.5 46.5 4\n",
    ))
    .unwrap();
    let g = deg.geo().expect("a grid in degrees");
    assert_eq!(
        (g.west, g.east, g.south, g.north, g.frame_lat),
        (10.0, 10.5, 46.0, 46.5, 46.25)
    );
    // Coordinates rounded in the text still find the grid: 1/3 m steps written to the millimetre over 400
    // columns, north row first.
    let mut t = String::new();
    for row in 0..3 {
        for col in 0..400 {
            let x = 2_600_000.0 + f64::from(col) / 3.0;
            t.push_str(&format!(
                "{x:.3} {:.3} {}\n",
                1_200_000.0 - f64::from(row) / 3.0,
                col % 7
            ));
        }
    }
    let hm = load(&write(&dir, "rounded.xyz", t.as_bytes())).unwrap();
    assert_eq!((hm.width(), hm.height()), (400, 3));
    assert_eq!(hm.heights()[..8], [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 0.0]);
    assert_refused(
        &dir,
        &[
            (
                "off.xyz",
                &b"0 0 1\n2 0 1\n4 0 1\n0 2 1\n2 2 1\n4 2 1\n2.9 2 1\n"[..],
                "line 7: point (2.9, 2) is off the grid",
            ),
            (
                "twice.xyz",
                b"0 0 1\n1 0 1\n0 1 1\n1 1 1\n1 1 2\n",
                "line 5: a second point",
            ),
            ("short.xyz", b"0 0 1\n1 0\n", "line 2: expected `x y z`"),
            (
                "word.xyz",
                b"0 0 1\n1 0 x\n",
                "line 2: `1 0 x` is not three numbers",
            ),
            ("line.xyz", b"0 0 1\n1 0 1\n2 0 1\n", "not a grid"),
            (
                "stray.xyz",
                b"0 0 1\n1 0 1\n0 1 1\n1 1 1\n1000 1000 1\n",
                "5 points would span 1001 x 1001 cells",
            ),
        ],
    );
}

/// `LoadOptions::nodata`: a void marker for files that declare none; NaN matches NaN; the rows the bake
/// reads are the load's.
#[test]
fn nodata_option_marks_voids() {
    let dir = temp_dir("nodata");
    let with = |nd: f64| LoadOptions {
        nodata: Some(nd),
        spacing: Some(1.0),
        ..LoadOptions::default()
    };
    // A float32 TIFF with NaN voids and no nodata tag: refused naming the option, filled with it.
    let (w, h) = (3u32, 2u32);
    let vals = [1.0f32, f32::NAN, 3.0, 4.0, 5.0, 6.0];
    let mut tif = one_strip_tiff(w, h, (3, 32), 1, w * h * 4);
    tif.extend(vals.iter().flat_map(|v| v.to_le_bytes()));
    let p = write(&dir, "nan.tif", &tif);
    let e = load(&p).expect_err("NaN without a nodata value");
    assert!(
        e.to_string().contains("NaN as `TerrainOptions::nodata`"),
        "{e}"
    );
    let hm = source::load(&p, &with(f64::NAN)).unwrap();
    // The void is the mean of its neighbours 1 (west), 3 (east) and 5 (south).
    assert_eq!((hm.heights()[1], hm.voids_filled()), (3.0, 1));
    // A raw u16 file with 0 for voids, scaled after the comparison; the bake reads it whole.
    let raw: Vec<u8> = [10u16, 0, 30, 40]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let p = write(&dir, "voids.r16", &raw);
    let opts = LoadOptions {
        raw: Some(RawLayout {
            width: 2,
            height: 2,
            format: RawFormat::U16,
        }),
        height_scale: Some(0.5),
        nodata: Some(0.0),
        ..LoadOptions::default()
    };
    let hm = source::load(&p, &opts).unwrap();
    assert_eq!(
        (hm.heights(), hm.voids_filled()),
        (&[5.0, 12.5, 15.0, 20.0][..], 1)
    );
    assert_eq!(rows_with(&p, &opts).3, hm.heights());
    // A 16-bit grey PNG with 0 for voids (compared before the 0.1 m scale); the bake reads it whole.
    let vals = [10u16, 0, 30, 40, 50, 60];
    let png = image::ImageBuffer::<image::Luma<u16>, _>::from_fn(3, 2, |x, y| {
        image::Luma([vals[(y * 3 + x) as usize]])
    });
    let p = dir.join("voids.png");
    png.save(&p).expect("write png");
    let hm = source::load(&p, &with(0.0)).unwrap();
    assert_eq!((hm.heights()[1], hm.voids_filled()), (3.0, 1));
    assert_eq!(rows_with(&p, &with(0.0)).3, hm.heights());
    // An XYZ file with -9999 for voids; an ASCII grid whose header says -1 while the option says 2.
    let p = write(&dir, "v.xyz", b"0 0 1\n1 0 -9999\n0 1 3\n1 1 5\n");
    let hm = source::load(&p, &with(-9999.0)).unwrap();
    assert_eq!((hm.heights()[3], hm.voids_filled()), (3.0, 1));
    let p = write(
        &dir,
        "o.asc",
        b"ncols 2\nnrows 2\ncellsize 1\nNODATA_value -1\n-1 2\n3 4\n",
    );
    let hm = source::load(&p, &with(2.0)).unwrap();
    // The void (the 2) is the mean of its neighbours -1 (west) and 4 (south); -1 is a height.
    assert_eq!(
        (hm.heights()[0], hm.heights()[1], hm.voids_filled()),
        (-1.0, 1.5, 1)
    );
}

#[test]
fn raw_u16_and_f32() {
    let dir = temp_dir("raw_ok");
    let bytes: Vec<u8> = (0..12u16).flat_map(|v| (v * 10).to_le_bytes()).collect();
    let p = write(&dir, "t.r16", &bytes);
    let opts = LoadOptions {
        raw: Some(RawLayout {
            width: 4,
            height: 3,
            format: RawFormat::U16,
        }),
        ..LoadOptions::default()
    };
    let hm = source::load(&p, &opts).unwrap();
    assert_eq!((hm.width(), hm.height(), hm.at(3, 2)), (4, 3, 11.0));
    let bytes: Vec<u8> = (0..12)
        .flat_map(|v| (v as f32 * 0.5).to_le_bytes())
        .collect();
    let p = write(&dir, "t.f32", &bytes);
    let opts = LoadOptions {
        raw: Some(RawLayout {
            width: 4,
            height: 3,
            format: RawFormat::F32,
        }),
        ..LoadOptions::default()
    };
    assert_eq!(source::load(&p, &opts).unwrap().at(3, 2), 5.5);
}

#[test]
fn hgt_voids_filled_and_counted() {
    let dir = temp_dir("hgt_voids");
    let mut bytes = vec![0u8; 2_884_802];
    for (i, c) in bytes.chunks_exact_mut(2).enumerate() {
        let v: i16 = if i == 1201 * 600 + 600 { -32768 } else { 100 };
        c.copy_from_slice(&v.to_be_bytes());
    }
    let p = write(&dir, "S12W077.hgt", &bytes);
    let hm = load(&p).unwrap();
    assert_eq!((hm.voids_filled(), hm.at(600, 600)), (1, 100.0));
    assert!((hm.spacing() - 92.2).abs() < 0.2, "{}", hm.spacing());
}

// ---- bad input ----------------------------------------------------------------------------------

#[test]
fn empty_files() {
    let dir = temp_dir("empty");
    for name in ["e.png", "e.tif", "e.hgt", "e.raw"] {
        assert_format(load(&write(&dir, name, &[])), "empty");
    }
}

#[test]
fn wrong_magic() {
    let dir = temp_dir("magic");
    assert_format(load(&write(&dir, "x.png", b"GIF89a, not a png")), "magic");
    assert_format(
        load(&write(&dir, "x.tif", b"\x89PNG\r\n\x1a\n...")),
        "magic",
    );
    assert_format(load(&write(&dir, "x.dem", b"whatever")), ".png");
    // A package whose start is damaged says so, not "unknown format".
    assert_format(
        load(&write(&dir, "x.clipsat", b"CLIPSAX\0 damaged")),
        "not a clipsat package",
    );
}

#[test]
fn truncated_files() {
    let dir = temp_dir("truncated");
    let png = std::fs::read(small_png16(&dir)).unwrap();
    for cut in [png.len() / 2, 30, 12] {
        let p = write(&dir, "cut.png", &png[..cut]);
        assert_format(load(&p), "PNG");
    }
    let data: Vec<f32> = (0..64 * 64).map(|i| i as f32).collect();
    let tif = std::fs::read(f32_tiff(&dir, "full.tif", 64, 64, &data, true)).unwrap();
    for cut in [tif.len() / 2, tif.len() - 10, 6] {
        let p = write(&dir, "cut.tif", &tif[..cut]);
        assert_format(load(&p), "TIFF");
    }
    let p = write(&dir, "N00E000.hgt", &vec![0u8; 2_884_802 - 2]);
    match load(&p) {
        Err(Error::SizeMismatch {
            actual, expected, ..
        }) => {
            assert_eq!(actual, 2_884_800);
            assert!(expected.contains("2884802") && expected.contains("25934402"));
        }
        other => panic!("expected SizeMismatch, got {other:?}"),
    }
}

#[test]
fn huge_declared_dimensions_refused_before_allocating() {
    let dir = temp_dir("huge");
    let p = write(&dir, "huge.png", &png_header_only(100_000, 100_000));
    match load(&p) {
        Err(Error::TooLarge {
            width,
            height,
            samples,
            ..
        }) => assert_eq!((width, height, samples), (100_000, 100_000, 10_000_000_000)),
        other => panic!("expected TooLarge, got {other:?}"),
    }
    let p = write(&dir, "huge.tif", &tiff_header_only(100_000, 100_000));
    assert!(
        matches!(load(&p), Err(Error::TooLarge { .. })),
        "{:?}",
        load(&p)
    );
    // Within the limit, a header-only PNG is just truncated.
    let p = write(&dir, "small.png", &png_header_only(10, 10));
    assert_format(load(&p), "PNG");
    // A lower limit applies too.
    let opts = LoadOptions {
        max_samples: 1000,
        ..LoadOptions::default()
    };
    let p = small_png16(&dir);
    assert!(matches!(
        source::load(&p, &opts),
        Err(Error::TooLarge { .. })
    ));
}

#[test]
fn non_finite_samples_refused() {
    let dir = temp_dir("nonfinite");
    for (i, bad) in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY]
        .into_iter()
        .enumerate()
    {
        let mut data = vec![1.0f32; 12];
        data[4 + 2] = bad; // column 2, row 1
        let p = f32_tiff(&dir, &format!("bad{i}.tif"), 4, 3, &data, true);
        match load(&p) {
            Err(Error::NonFinite { x, y, .. }) => assert_eq!((x, y), (2, 1)),
            other => panic!("TIFF with {bad}: expected NonFinite, got {other:?}"),
        }
        let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        let p = write(&dir, &format!("bad{i}.f32"), &bytes);
        let opts = LoadOptions {
            raw: Some(RawLayout {
                width: 4,
                height: 3,
                format: RawFormat::F32,
            }),
            ..LoadOptions::default()
        };
        match source::load(&p, &opts) {
            Err(Error::NonFinite { x, y, .. }) => assert_eq!((x, y), (2, 1)),
            other => panic!("raw with {bad}: expected NonFinite, got {other:?}"),
        }
    }
}

#[test]
fn raw_size_problems() {
    let dir = temp_dir("raw_bad");
    let p = write(&dir, "t.raw", &[0u8; 24]);
    assert_format(load(&p), "LoadOptions::raw");
    let layout = |w, h| LoadOptions {
        raw: Some(RawLayout {
            width: w,
            height: h,
            format: RawFormat::U16,
        }),
        ..LoadOptions::default()
    };
    match source::load(&p, &layout(4, 4)) {
        Err(Error::SizeMismatch {
            actual, expected, ..
        }) => assert_eq!((actual, expected.as_str()), (24, "32 bytes (4 x 4 u16)")),
        other => panic!("expected SizeMismatch, got {other:?}"),
    }
    assert!(matches!(
        source::load(&p, &layout(1 << 20, 1 << 20)),
        Err(Error::TooLarge { .. })
    ));
    assert!(matches!(
        source::load(&dir.join("missing.raw"), &layout(4, 3)),
        Err(Error::Io { .. })
    ));
}
