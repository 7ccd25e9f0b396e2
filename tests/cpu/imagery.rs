//! Imagery (issue 43), stages 0 to 1b without a GPU: PNG and JPEG read and placed over the height grid
//! (pixel-is-area, corner to corner), bad files refused with an error naming them, the colour pyramid
//! baked into JPEG tiles and read back through the fixed tile cache, damage caught by the checksums.
//!
//! The shared images' size and PSNR against JPEG quality 90 run with
//! `cargo test --test cpu imagery:: -- --ignored` (about 30 s in a debug build).

use std::path::{Path, PathBuf};

use clipsat::package::color_blocks::ColorFormat;
use clipsat::package::imagery::{psnr, ImageryPackage, DEFAULT_QUALITY};
use clipsat::package::imagery_bake::bake_imagery;
use clipsat::package::imagery_cache::ImageryCache;
use clipsat::source::imagery::{Extent, Imagery, ImageryOptions};
use clipsat::{Error, Param};

/// A fresh scratch folder for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("imagery")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch folder");
    dir
}

/// The extent of a 65 x 33 grid at 10 m: 640 x 320 m.
fn grid() -> Extent {
    Extent::of_grid(65, 33, 10.0, (0.0, 0.0))
}

/// A smooth, deterministic RGB test image.
fn pattern(w: u32, h: u32) -> Vec<u8> {
    let mut v = Vec::with_capacity(w as usize * h as usize * 3);
    for y in 0..h {
        for x in 0..w {
            let byte = |v: u32| u8::try_from(v % 256).expect("a byte");
            let r = byte(x * 255 / w.max(2));
            let g = byte(y * 255 / h.max(2));
            let b = byte((x + y) * 3) / 2 + 60;
            v.extend_from_slice(&[r, g, b]);
        }
    }
    v
}

fn save(dir: &Path, name: &str, w: u32, h: u32, color: image::ColorType) -> PathBuf {
    let path = dir.join(name);
    let rgb = image::RgbImage::from_raw(w, h, pattern(w, h)).expect("image");
    let img = image::DynamicImage::ImageRgb8(rgb);
    let img = match color {
        image::ColorType::L8 => image::DynamicImage::ImageLuma8(img.to_luma8()),
        image::ColorType::Rgba8 => image::DynamicImage::ImageRgba8(img.to_rgba8()),
        image::ColorType::Rgb16 => image::DynamicImage::ImageRgb16(img.to_rgb16()),
        _ => img,
    };
    img.save(&path).expect("save image");
    path
}

fn load(path: &Path) -> clipsat::Result<Imagery> {
    Imagery::load(path, &grid(), &ImageryOptions::default())
}

#[test]
fn png_and_jpeg_are_read_and_placed_corner_to_corner() {
    let dir = scratch("read");
    for (name, color) in [
        ("rgb.png", image::ColorType::Rgb8),
        ("grey.png", image::ColorType::L8),
        ("rgba.png", image::ColorType::Rgba8),
        ("rgb16.png", image::ColorType::Rgb16),
        ("rgb.jpg", image::ColorType::Rgb8),
    ] {
        let path = save(&dir, name, 32, 16, color);
        let im = load(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(im.size(), (32, 16), "{name}");
        // Pixel-is-area over the grid's extent: 640 m / 32 texels = 20 m, 320 m / 16 = 20 m.
        assert_eq!(im.extent(), grid(), "{name}");
        assert_eq!(im.texel_spacing(), (20.0, 20.0), "{name}");
        if name == "rgb.png" || name == "rgb16.png" {
            assert_eq!(im.texels(), pattern(32, 16).as_slice(), "{name} is exact");
        }
    }
    // A palette PNG is expanded.
    let path = dir.join("palette.png");
    let file = std::fs::File::create(&path).expect("create");
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), 4, 2);
    enc.set_color(png::ColorType::Indexed);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_palette(vec![255, 0, 0, 0, 255, 0]);
    let mut w = enc.write_header().expect("header");
    w.write_image_data(&[0, 1, 0, 1, 1, 0, 1, 0])
        .expect("palette data");
    drop(w);
    let im = load(&path).expect("palette PNG");
    assert_eq!(im.texel(0, 0), [255, 0, 0]);
    assert_eq!(im.texel(1, 0), [0, 255, 0]);
    // An explicit extent overrides the grid's, and only has to overlap it.
    let path = save(&dir, "placed.png", 4, 4, image::ColorType::Rgb8);
    let extent = Extent::parse("-100,-100,100,100").expect("extent");
    let opts = ImageryOptions {
        extent: Some(extent),
        ..ImageryOptions::default()
    };
    let im = Imagery::load(&path, &grid(), &opts).expect("placed");
    assert_eq!(im.extent(), extent);
    assert_eq!(im.texel_spacing(), (50.0, 50.0));
}

/// Whether `e` is a [`Error::Format`] naming `path`.
fn is_format_for(e: &Error, path: &Path) -> bool {
    matches!(e, Error::Format { path: p, .. } if p == path)
}

#[test]
fn bad_imagery_is_a_clear_error() {
    let dir = scratch("bad");
    // Too small to place.
    for (w, h) in [(1, 1), (1, 7), (7, 1)] {
        let path = save(&dir, &format!("{w}x{h}.png"), w, h, image::ColorType::Rgb8);
        let e = load(&path).expect_err("tiny image");
        assert!(is_format_for(&e, &path), "{w} x {h}: {e}");
        assert!(e.to_string().contains("at least 2 x 2"), "{e}");
    }
    // Truncated and corrupt PNG and JPEG.
    let png = std::fs::read(save(&dir, "good.png", 64, 64, image::ColorType::Rgb8)).expect("read");
    let jpg = std::fs::read(save(&dir, "good.jpg", 64, 64, image::ColorType::Rgb8)).expect("read");
    let mut corrupt_png = png.clone();
    let mid = corrupt_png.len() / 2;
    for b in &mut corrupt_png[mid..mid + 16] {
        *b ^= 0x5A;
    }
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("truncated.png", png[..png.len() / 2].to_vec()),
        ("header-only.png", png[..40].to_vec()),
        ("corrupt.png", corrupt_png),
        ("truncated.jpg", jpg[..jpg.len() / 2].to_vec()),
        ("header-only.jpg", jpg[..200.min(jpg.len())].to_vec()),
        ("empty.png", Vec::new()),
        ("text.png", b"not an image at all".to_vec()),
    ];
    for (name, bytes) in cases {
        let path = dir.join(name);
        std::fs::write(&path, bytes).expect("write");
        let e = load(&path).expect_err(name);
        assert!(is_format_for(&e, &path), "{name}: {e}");
    }
    // A header declaring 100000 x 100000 texels, refused before allocating (the file holds no data).
    let path = dir.join("huge.png");
    std::fs::write(&path, png_header(100_000, 100_000)).expect("write");
    let e = load(&path).expect_err("huge");
    assert!(
        matches!(
            e,
            Error::Param {
                param: Param::MaxImageryTexels,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("100000 x 100000"), "{e}");
    // The same for a JPEG whose frame header declares 60000 x 60000.
    let mut huge = jpg.clone();
    let sof = huge
        .windows(2)
        .position(|w| w == [0xFF, 0xC0])
        .expect("SOF0");
    huge[sof + 5..sof + 9].copy_from_slice(&[0xEA, 0x60, 0xEA, 0x60]);
    let path = dir.join("huge.jpg");
    std::fs::write(&path, huge).expect("write");
    let e = load(&path).expect_err("huge jpeg");
    assert!(
        matches!(
            e,
            Error::Param {
                param: Param::MaxImageryTexels,
                ..
            }
        ),
        "{e}"
    );
    // A missing file is an I/O error naming it.
    let path = dir.join("missing.png");
    assert!(matches!(load(&path), Err(Error::Io { .. })));
    // Imagery that does not overlap the terrain, and unusable extents.
    let path = save(&dir, "far.png", 4, 4, image::ColorType::Rgb8);
    for text in ["1000,1000,2000,2000", "-50,0,0,320", "0,0,0,0"] {
        let extent = Extent::parse(text);
        let e = extent
            .and_then(|extent| {
                Imagery::load(
                    &path,
                    &grid(),
                    &ImageryOptions {
                        extent: Some(extent),
                        ..ImageryOptions::default()
                    },
                )
            })
            .expect_err(text);
        assert!(
            matches!(
                e,
                Error::Param {
                    param: Param::ImageryExtent,
                    ..
                }
            ),
            "{text}: {e}"
        );
    }
    for text in ["1,2,3", "a,b,c,d", "0,0,nan,1", "0,0,inf,1"] {
        assert!(Extent::parse(text).is_err(), "{text}");
    }
}

/// A PNG signature, an IHDR declaring `w` x `h` 8-bit RGB, an IDAT of an empty zlib stream, and IEND:
/// a header with (almost) no data.
fn png_header(w: u32, h: u32) -> Vec<u8> {
    let mut out = vec![0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A];
    let mut chunk = |kind: &[u8; 4], data: &[u8]| {
        out.extend_from_slice(&u32::try_from(data.len()).expect("len").to_be_bytes());
        let mut body = kind.to_vec();
        body.extend_from_slice(data);
        out.extend_from_slice(&body);
        out.extend_from_slice(&crc32fast::hash(&body).to_be_bytes());
    };
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    chunk(b"IHDR", &ihdr);
    chunk(b"IDAT", &[0x78, 0x9C, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01]);
    chunk(b"IEND", &[]);
    out
}

/// A 600 x 300 image baked: three levels (600, 300, 150 wide), 21 tiles... read back tile by tile
/// through a cache, close to the source, and damage in any place is an error naming it.
#[test]
fn pyramid_bakes_into_checked_tiles() {
    let (w, h) = (600, 300);
    let im = Imagery::from_rgb(
        Path::new("<pattern>"),
        w,
        h,
        pattern(w, h),
        &Extent::of_grid(601, 301, 2.0, (0.0, 0.0)),
        None,
    )
    .expect("imagery");
    let (bytes, report) = bake_imagery(&im, DEFAULT_QUALITY, 7).expect("bake");
    assert_eq!(report.levels, 3);
    // Level 0: 3 x 2 tiles; level 1 (300 x 150): 2 x 1; level 2 (150 x 75): 1.
    assert_eq!(report.tiles, 9);
    assert!(report.psnr_db > 35.0, "{report:?}");
    let pkg = ImageryPackage::from_bytes(Path::new("<baked>"), bytes.clone()).expect("package");
    let header = pkg.header().clone();
    assert_eq!(header.key, 7);
    assert_eq!(header.texel_spacing(0), (2.0, 2.0));
    assert_eq!(header.texel_spacing(2), (8.0, 8.0));
    assert_eq!(
        header
            .levels
            .iter()
            .map(|l| (l.width, l.height))
            .collect::<Vec<_>>(),
        vec![(600, 300), (300, 150), (150, 75)]
    );
    // Decoded through the cache: level 0's texels within JPEG's error of the source.
    let mut cache = ImageryCache::new(pkg, 64 << 20).expect("cache");
    assert_eq!(cache.slot_count(), 9, "at most one slot a tile");
    cache.begin_frame();
    let mut budget = u64::MAX;
    let mut sq = 0u64;
    let src = pattern(w, h);
    for ty in 0..2 {
        for tx in 0..3 {
            let (tw, th, texels) = cache
                .fetch(0, tx, ty, &mut budget)
                .expect("fetch")
                .expect("resident");
            for y in 0..th {
                for x in 0..tw {
                    let (gx, gy) = ((tx * 256 + x) as usize, (ty * 256 + y) as usize);
                    for c in 0..3 {
                        let a = src[(gy * w as usize + gx) * 3 + c];
                        let b = texels[((y * tw + x) * 3) as usize + c];
                        sq += u64::from(a.abs_diff(b)).pow(2);
                    }
                }
            }
        }
    }
    let p = psnr(sq, u64::from(w * h * 3));
    assert!((p - report.psnr_db).abs() < 1e-9, "{p} vs {report:?}");
    // Damage: a tile's byte, the header, a truncated file.
    let first = header.tiles[0];
    let mut tile_damage = bytes.clone();
    tile_damage[usize::try_from(first.offset).expect("offset") + 40] ^= 1;
    let pkg =
        ImageryPackage::from_bytes(Path::new("<damaged>"), tile_damage.clone()).expect("header ok");
    let e = pkg
        .decode_tile(0, 0, 0, &mut vec![0; 256 * 256 * 3])
        .expect_err("tile damage");
    assert!(e.to_string().contains("tile 0/0/0: checksum"), "{e}");
    // A residual tile through the cache: damage in it or in its parent is an error naming that tile.
    let parent = header.tiles[header.levels[1].first_tile];
    let mut parent_damage = bytes.clone();
    parent_damage[usize::try_from(parent.offset).expect("offset") + 40] ^= 1;
    for (damaged, name) in [(tile_damage, "tile 0/0/0"), (parent_damage, "tile 1/0/0")] {
        let pkg = ImageryPackage::from_bytes(Path::new("<damaged>"), damaged).expect("header ok");
        let mut cache = ImageryCache::new(pkg, 64 << 20).expect("cache");
        cache.begin_frame();
        let mut budget = u64::MAX;
        let e = cache.fetch(0, 0, 0, &mut budget).expect_err("damage");
        assert!(e.to_string().contains(name), "{name}: {e}");
    }
    // An older format (version 1: every level whole) is refused, to be baked again; level kinds that do
    // not alternate are refused.
    let mut old = bytes.clone();
    old[8..12].copy_from_slice(&1u32.to_le_bytes());
    let e = ImageryPackage::from_bytes(Path::new("<old>"), old).expect_err("version 1");
    assert!(
        e.to_string().contains("version 1") && e.to_string().contains("bake it again"),
        "{e}"
    );
    let mut kinds = bytes.clone();
    // Level 0's kind: after the fixed header (72 bytes) and its width and height.
    kinds[80..84].copy_from_slice(&0u32.to_le_bytes());
    let e = ImageryPackage::from_bytes(Path::new("<kinds>"), kinds).expect_err("kinds");
    assert!(e.to_string().contains("level kinds"), "{e}");
    let mut head_damage = bytes.clone();
    head_damage[30] ^= 1;
    let e = ImageryPackage::from_bytes(Path::new("<damaged>"), head_damage).expect_err("header");
    assert!(
        e.to_string().contains("checksum") || e.to_string().contains("extent"),
        "{e}"
    );
    for cut in [0, 7, 100, header.byte_len(), bytes.len() - 1] {
        let e = ImageryPackage::from_bytes(Path::new("<cut>"), bytes[..cut].to_vec())
            .expect_err("truncated");
        assert!(matches!(e, Error::Format { .. }), "cut at {cut}: {e}");
    }
}

/// The cache's bytes follow the budget, never the image: a budget of two slots holds two tiles of a
/// large pyramid; a frame's texel budget refuses a decode it cannot pay for; eviction is LRU by frame.
#[test]
fn cache_is_bounded_by_its_budget() {
    let (w, h) = (1024, 600);
    let im = Imagery::from_rgb(
        Path::new("<pattern>"),
        w,
        h,
        pattern(w, h),
        &Extent::of_grid(1025, 601, 1.0, (0.0, 0.0)),
        None,
    )
    .expect("imagery");
    let (bytes, _) = bake_imagery(&im, 50, 1).expect("bake");
    let pkg = ImageryPackage::from_bytes(Path::new("<baked>"), bytes).expect("package");
    let tiles = pkg.header().tiles.len() as u64;
    // Level 0 is stored as residuals of level 1 (512 x 300, 2 x 2 tiles, stored whole): in RGB8 slots a
    // parent shares the slots (two at least, a parent and its child); in blocks the cache keeps a
    // parent LRU of its own, counted in its bytes.
    assert!(pkg.header().levels[0].residual && !pkg.header().levels[1].residual);
    assert_eq!(ImageryCache::parent_bytes(&pkg, ColorFormat::Rgba8), 0);
    assert_eq!(ImageryCache::min_slots(&pkg, ColorFormat::Rgba8), 2);
    assert!(ImageryCache::parent_bytes(&pkg, ColorFormat::Bc1) > 0);
    let budget = 2 * ImageryCache::slot_bytes(&pkg) + 4 * tiles;
    let mut cache = ImageryCache::new(pkg, budget).expect("cache");
    assert_eq!(cache.slot_count(), 2);
    assert!(cache.bytes() <= budget);
    cache.begin_frame();
    let mut budget = 256 * 256 + 10;
    assert!(cache.fetch(1, 0, 0, &mut budget).expect("fetch").is_some());
    assert_eq!(budget, 10);
    assert!(
        cache.fetch(1, 1, 0, &mut budget).expect("fetch").is_none(),
        "over the texel budget"
    );
    let mut budget = u64::MAX;
    assert!(cache.fetch(1, 1, 0, &mut budget).expect("fetch").is_some());
    assert!(
        cache.fetch(1, 0, 1, &mut budget).expect("fetch").is_none(),
        "both slots used this frame"
    );
    cache.begin_frame();
    assert!(cache.fetch(1, 1, 0, &mut budget).expect("fetch").is_some());
    assert!(cache.fetch(1, 0, 1, &mut budget).expect("fetch").is_some());
    let s = cache.stats();
    assert_eq!((s.decoded, s.hits, s.evictions, s.refused), (3, 1, 1, 2));
    // One decode a frame (gles3-low's tiles_per_frame): a residual tile whose parent is not held takes
    // the parent this frame and answers None, and the next frame decodes it; its neighbour under the
    // same parent takes one decode. A parent already in a slot is not decoded again.
    cache.begin_frame();
    let mut decodes = 1;
    assert!(cache
        .fetch_counted(0, 2, 2, &mut budget, &mut decodes)
        .expect("fetch")
        .is_none());
    assert_eq!((decodes, cache.stats().parents), (0, 1));
    cache.begin_frame();
    let mut decodes = 1;
    assert!(cache
        .fetch_counted(0, 2, 2, &mut budget, &mut decodes)
        .expect("fetch")
        .is_some());
    assert_eq!(decodes, 0);
    cache.begin_frame();
    let mut decodes = 1;
    assert!(cache
        .fetch_counted(0, 3, 2, &mut budget, &mut decodes)
        .expect("fetch")
        .is_some());
    cache.begin_frame();
    let mut decodes = 2;
    assert!(cache.fetch(1, 0, 0, &mut budget).expect("fetch").is_some());
    assert!(cache
        .fetch_counted(0, 0, 0, &mut budget, &mut decodes)
        .expect("fetch")
        .is_some());
    assert_eq!(decodes, 1, "the parent read from its slot");
    let s = cache.stats();
    assert_eq!((s.parents, s.decoded), (1, 8), "{s:?}");
    // Not even one slot: refused when built.
    let pkg = ImageryPackage::from_bytes(
        Path::new("<baked>"),
        bake_imagery(&im, 50, 1).expect("bake").0,
    )
    .expect("package");
    assert!(matches!(
        ImageryCache::new(pkg, 1000),
        Err(Error::Capacity { .. })
    ));
}

/// The shared images baked: the whole package (every level, per level-0 texel) takes at most 95 % of the
/// bytes a texel of a whole-image JPEG at quality 90 (4:2:0, libjpeg), level 0 at a PSNR at least 0.25
/// dB higher (the figures: Puget Sound 0.411 B at 29.93 dB, Grand Canyon 0.255 B at 36.19 dB;
/// measured: 0.371 B at 30.45 dB and 0.226 B at 36.71 dB, docs/guide.md "The imagery package").
#[test]
#[ignore = "about 30 s in a debug build: cargo test --test cpu imagery:: -- --ignored"]
fn shared_images_beat_jpeg_q90() {
    for (image, heights, size, jpeg_bytes, jpeg_db) in [
        (
            "imagery/ps_texture_1k.png",
            "ps_height_1k.png",
            1025,
            0.411,
            29.93,
        ),
        (
            "imagery/gcanyon_color_1024.png",
            "imagery/gcanyon_elev_1200.png",
            1200,
            0.255,
            36.19,
        ),
    ] {
        let path = clipsat::data_dir().join(image);
        if !path.is_file() || !clipsat::data_dir().join(heights).is_file() {
            let msg = format!("shared data file {} is missing", path.display());
            assert!(
                std::env::var("CI").as_deref() != Ok("true"),
                "{msg} (CI=true requires it; set CLIPSAT_DATA)"
            );
            eprintln!("skipping: {msg}");
            continue;
        }
        let grid = Extent::of_grid(size, size, 1.0, (0.0, 0.0));
        let im = Imagery::load(&path, &grid, &ImageryOptions::default()).expect("load");
        let (_, r) = bake_imagery(&im, DEFAULT_QUALITY, 0).expect("bake");
        eprintln!("{image}: {r:?}");
        assert!(r.bytes_per_texel <= 0.95 * jpeg_bytes, "{image}: {r:?}");
        assert!(r.psnr_db >= jpeg_db + 0.25, "{image}: {r:?}");
    }
}

/// (Geo)TIFF imagery: 8-bit RGB, 16-bit RGB (rounded to 8 bits), 8-bit RGBA and 16-bit grey, placed as
/// a plain image; a truncated TIFF and a float one are refused, a huge declared size before allocating.
#[test]
fn tiff_imagery_is_read() {
    use tiff::encoder::{colortype, TiffEncoder};
    let dir = scratch("tiff");
    let (w, h) = (6u32, 4u32);
    let rgb = pattern(w, h);
    let write = |name: &str, f: &dyn Fn(&mut TiffEncoder<&mut std::fs::File>)| {
        let path = dir.join(name);
        let mut file = std::fs::File::create(&path).expect("create");
        let mut enc = TiffEncoder::new(&mut file).expect("encoder");
        f(&mut enc);
        path
    };
    let p8 = write("rgb8.tif", &|e| {
        e.write_image::<colortype::RGB8>(w, h, &rgb).expect("write");
    });
    let wide: Vec<u16> = rgb.iter().map(|&v| u16::from(v) * 257).collect();
    let p16 = write("rgb16.tif", &|e| {
        e.write_image::<colortype::RGB16>(w, h, &wide)
            .expect("write");
    });
    let rgba: Vec<u8> = rgb.chunks(3).flat_map(|c| [c[0], c[1], c[2], 7]).collect();
    let pa = write("rgba8.tif", &|e| {
        e.write_image::<colortype::RGBA8>(w, h, &rgba)
            .expect("write");
    });
    let grey: Vec<u16> = (0..w * h)
        .map(|i| u16::try_from(i * 2570).expect("u16"))
        .collect();
    let pg = write("grey16.tif", &|e| {
        e.write_image::<colortype::Gray16>(w, h, &grey)
            .expect("write");
    });
    for path in [&p8, &p16, &pa] {
        let im = load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert_eq!(im.size(), (w, h));
        assert_eq!(im.texels(), rgb.as_slice(), "{}", path.display());
        assert_eq!(im.extent(), grid());
    }
    let im = load(&pg).expect("grey");
    assert_eq!(im.texel(1, 0), [10, 10, 10]);
    // Refused: truncated, float samples, too many texels.
    let bytes = std::fs::read(&p8).expect("read");
    let cut = dir.join("cut.tif");
    std::fs::write(&cut, &bytes[..bytes.len() / 3]).expect("write");
    assert!(is_format_for(&load(&cut).expect_err("cut"), &cut));
    let float = write("float.tif", &|e| {
        e.write_image::<colortype::RGB32Float>(w, h, &vec![0.5f32; (w * h * 3) as usize])
            .expect("write");
    });
    assert!(is_format_for(&load(&float).expect_err("float"), &float));
    let small = ImageryOptions {
        max_texels: 10,
        ..ImageryOptions::default()
    };
    assert!(matches!(
        Imagery::load(&p8, &grid(), &small),
        Err(Error::Param {
            param: Param::MaxImageryTexels,
            ..
        })
    ));
}

/// Writes a GeoTIFF of `w` x `h` with a pixel scale `s`, a tiepoint of pixel (0, 0) at `tie` and the
/// GeoKeys `keys` (entries of key, 0, 1, value).
pub(crate) fn geotiff<C: tiff::encoder::colortype::ColorType>(
    path: &Path,
    w: u32,
    h: u32,
    data: &[C::Inner],
    s: f64,
    tie: (f64, f64),
    keys: &[(u16, u16)],
) where
    [C::Inner]: tiff::encoder::TiffValue,
{
    use tiff::tags::Tag;
    let mut file = std::fs::File::create(path).expect("create");
    let mut enc = tiff::encoder::TiffEncoder::new(&mut file).expect("encoder");
    let mut img = enc.new_image::<C>(w, h).expect("image");
    img.encoder()
        .write_tag(Tag::ModelPixelScaleTag, &[s, s, 0.0][..])
        .expect("scale");
    img.encoder()
        .write_tag(
            Tag::ModelTiepointTag,
            &[0.0, 0.0, 0.0, tie.0, tie.1, 0.0][..],
        )
        .expect("tiepoint");
    let count = u16::try_from(keys.len()).expect("keys");
    let mut dir = vec![1u16, 1, 0, count];
    for (k, v) in keys {
        dir.extend_from_slice(&[*k, 0, 1, *v]);
    }
    img.encoder()
        .write_tag(Tag::GeoKeyDirectoryTag, &dir[..])
        .expect("geokeys");
    img.write_data(data).expect("data");
}

/// 11 x 11 GeoTIFF heights at 30 m, flat, in `dir`: their north-west pixel's corner at (500000, 4000300)
/// in the system the GeoKeys `keys` name, so their south-west sample's centre is 15 m in from it.
fn utm_heights(dir: &Path, keys: &[(u16, u16)]) -> PathBuf {
    let heights = dir.join("heights.tif");
    geotiff::<tiff::encoder::colortype::Gray32Float>(
        &heights,
        11,
        11,
        &[100.0f32; 121],
        30.0,
        (500_000.0, 4_000_300.0),
        keys,
    );
    heights
}

/// A GeoTIFF image over GeoTIFF heights is placed by both georeferences: 11 x 11 heights at 30 m whose
/// south-west sample centre is the world's origin, a 20 x 10 image at 15 m covering their northern half
/// from the west sample's centre, so (0, 150, 300, 300) m; through the library (`TerrainOptions`) too. A
/// pixel-is-point image moves half a pixel; another coordinate system is refused.
#[test]
fn geotiff_imagery_is_placed_by_its_georeference() {
    use clipsat::source::georef::{georef_extent, GeoRef};
    use tiff::encoder::colortype::RGB8;
    let dir = scratch("georef");
    let utm = [(1024, 1), (1025, 1), (3072, 32611)];
    let heights = utm_heights(&dir, &utm);
    let image = dir.join("image.tif");
    let rgb = pattern(20, 10);
    geotiff::<RGB8>(&image, 20, 10, &rgb, 15.0, (500_015.0, 4_000_285.0), &utm);
    let (h, i) = (
        GeoRef::read(&heights).expect("heights"),
        GeoRef::read(&image).expect("image"),
    );
    let e = georef_extent(&image, &h, &i, 30.0, (0.0, 0.0), h.size.0).expect("extent");
    assert_eq!(e, Extent::new(0.0, 150.0, 300.0, 300.0).expect("extent"));
    let terrain = clipsat::Terrain::open_with(
        &heights,
        &clipsat::TerrainOptions::default().imagery(image.clone()),
    )
    .expect("terrain");
    assert_eq!(terrain.imagery().expect("imagery").header().extent, e);
    // Pixel-is-point: the tiepoint is a pixel's centre, so the image lies half a pixel (7.5 m) west and north.
    let point = dir.join("point.tif");
    geotiff::<RGB8>(
        &point,
        20,
        10,
        &rgb,
        15.0,
        (500_015.0, 4_000_285.0),
        &[(1024, 1), (1025, 2), (3072, 32611)],
    );
    let p = georef_extent(
        &point,
        &h,
        &GeoRef::read(&point).expect("point"),
        30.0,
        (0.0, 0.0),
        h.size.0,
    )
    .expect("extent");
    assert_eq!(p, Extent::new(-7.5, 157.5, 292.5, 307.5).expect("extent"));
    // Another UTM zone: refused, naming both.
    let other = dir.join("other.tif");
    geotiff::<RGB8>(
        &other,
        20,
        10,
        &rgb,
        15.0,
        (500_015.0, 4_000_285.0),
        &[(1024, 1), (3072, 32612)],
    );
    let e = georef_extent(
        &other,
        &h,
        &GeoRef::read(&other).expect("other"),
        30.0,
        (0.0, 0.0),
        h.size.0,
    )
    .expect_err("another coordinate system");
    assert!(
        e.to_string().contains("32612") && e.to_string().contains("32611"),
        "{e}"
    );
    let e =
        clipsat::Terrain::open_with(&heights, &clipsat::TerrainOptions::default().imagery(other))
            .expect_err("another coordinate system");
    assert!(
        matches!(
            e,
            Error::Param {
                param: Param::ImageryExtent,
                ..
            }
        ),
        "{e}"
    );
}

/// A PNG or JPEG orthophoto with a world file (`.pgw`, `.jgw`, `.wld`) over GeoTIFF heights is placed by
/// it as a GeoTIFF image would be: the heights and image of `geotiff_imagery_is_placed_by_its_georeference`
/// (20 x 10 texels at 15 m from the west sample's centre over the northern half: (0, 150, 300, 300) m),
/// the world file naming the north-west pixel's centre. A rotated or unreadable world file is refused,
/// naming it; a `.prj` saying geographic over projected heights is refused as another kind of system.
#[test]
fn world_files_place_plain_images() {
    use clipsat::source::georef::GeoRef;
    let dir = scratch("world_file");
    let utm = [(1024, 1), (1025, 1), (3072, 32611)];
    let heights = utm_heights(&dir, &utm);
    let world = "15.0\n0.0\n0.0\n-15.0\n500022.5\n4000277.5\n";
    let want = Extent::new(0.0, 150.0, 300.0, 300.0).expect("extent");
    for (name, sidecar, color) in [
        ("photo.png", "photo.pgw", image::ColorType::Rgb8),
        ("photo.jpg", "photo.jgw", image::ColorType::Rgb8),
        ("other.png", "other.wld", image::ColorType::L8),
    ] {
        let image = save(&dir, name, 20, 10, color);
        assert!(GeoRef::of_imagery(&image)
            .expect("no world file yet")
            .is_none());
        std::fs::write(dir.join(sidecar), world).expect("world file");
        let g = GeoRef::of_imagery(&image)
            .expect("read")
            .expect("a georeference");
        assert_eq!(
            (g.size, g.scale, g.corner),
            ((20, 10), (15.0, 15.0), (500_015.0, 4_000_285.0))
        );
        let terrain = clipsat::Terrain::open_with(
            &heights,
            &clipsat::TerrainOptions::default().imagery(image.clone()),
        )
        .expect("terrain");
        assert_eq!(
            terrain.imagery().expect("imagery").header().extent,
            want,
            "{name}"
        );
    }
    let image = save(&dir, "bad.png", 20, 10, image::ColorType::Rgb8);
    for (text, what) in [
        ("15.0\n0.5\n0.0\n-15.0\n500022.5\n4000277.5\n", "rotates"),
        ("15.0\n0.0\n0.0\n", "six numbers"),
        (
            "15.0\n0.0\nzero\n-15.0\n500022.5\n4000277.5\n",
            "six numbers",
        ),
    ] {
        std::fs::write(dir.join("bad.pgw"), text).expect("world file");
        let e = GeoRef::of_imagery(&image).expect_err(what);
        assert!(
            e.to_string().contains("bad.pgw") && e.to_string().contains(what),
            "{e}"
        );
    }
    std::fs::write(dir.join("bad.pgw"), world).expect("world file");
    std::fs::write(
        dir.join("bad.prj"),
        "GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\"]]",
    )
    .expect("prj");
    let e =
        clipsat::Terrain::open_with(&heights, &clipsat::TerrainOptions::default().imagery(image))
            .expect_err("geographic over projected");
    assert!(e.to_string().contains("geographic"), "{e}");
}

/// `ImageryOptions::range` maps stored samples linearly onto 0..255: a 16-bit image of 12-bit values draws
/// nearly black without it (4095 rounds to 16) and whole with 0..4095; 8-bit files take it in their own
/// values; a range past the file's samples, or not 0 <= low < high <= 65535, is refused.
#[test]
fn imagery_range_maps_samples() {
    let dir = scratch("range");
    let (w, h) = (16u32, 4u32);
    let grey: Vec<u16> = (0..w * h)
        .map(|i| u16::try_from(i % w * 273).expect("12 bits"))
        .collect();
    let wide = dir.join("wide.png");
    image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, grey)
        .expect("image")
        .save(&wide)
        .expect("save");
    let narrow = save(&dir, "narrow.png", w, h, image::ColorType::L8);
    let load_with = |p: &Path, range| {
        Imagery::load(
            p,
            &grid(),
            &ImageryOptions {
                range,
                ..ImageryOptions::default()
            },
        )
    };
    let max = |t: Vec<u8>| t.into_iter().max().expect("texels");
    let plain = load_with(&wide, None).expect("plain").into_texels();
    assert_eq!(max(plain), 16);
    let stretched = load_with(&wide, Some((0.0, 4095.0)))
        .expect("range")
        .into_texels();
    assert_eq!((stretched[0], stretched[3 * 15]), (0, 255));
    let n = load_with(&narrow, Some((0.0, 255.0)))
        .expect("identity")
        .into_texels();
    assert_eq!(n, load_with(&narrow, None).expect("plain").into_texels());
    let e = load_with(&narrow, Some((0.0, 4095.0))).expect_err("past 8 bits");
    assert!(e.to_string().contains("8-bit"), "{e}");
    for bad in [(5.0, 5.0), (-1.0, 10.0), (0.0, 70000.0), (f64::NAN, 1.0)] {
        assert!(
            clipsat::source::imagery::check_range(bad).is_err(),
            "{bad:?}"
        );
    }
}

/// The colour rings' block formats on the shared images (a measurement): each format's own PSNR over RGB
/// against the source (level 0 encoded in 256^2 tiles as the tile cache encodes them, decoded as the
/// twin decodes them), and the encode time a tile. `cargo test --test cpu imagery::block_formats --
/// --ignored --nocapture`.
#[test]
#[ignore = "a measurement on the shared data: cargo test --test cpu imagery::block_formats -- --ignored --nocapture"]
fn block_formats_on_the_shared_images() {
    use clipsat::package::color_blocks::{round_trip, ColorFormat};
    for (image, size) in [
        ("imagery/ps_texture_1k.png", 1025),
        ("imagery/gcanyon_color_1024.png", 1200),
    ] {
        let path = clipsat::data_dir().join(image);
        if !path.is_file() {
            eprintln!("skipping: {} is missing", path.display());
            continue;
        }
        let grid = Extent::of_grid(size, size, 1.0, (0.0, 0.0));
        let src = Imagery::load(&path, &grid, &ImageryOptions::default()).expect("load");
        for format in [ColorFormat::Bc1, ColorFormat::Etc2Rgb8] {
            let r = round_trip(format, &src, 256).expect("round trip");
            println!(
                "{image}: {} {:.2} dB over RGB against the source, 0.5 B/texel on the GPU, {:.1} ms to encode a 256^2 tile ({} tiles)",
                format.name(),
                r.psnr(),
                r.encode_secs * 1000.0 / f64::from(r.tiles),
                r.tiles
            );
        }
    }
}

/// A geographic GeoTIFF image over geographic heights drawn with `--resample-ew`: the E-W mapping follows
/// the resampled rows. 21 x 11 heights at 3" near 60 N have E-W cells about half their N-S ones, so their
/// rows are drawn with 11 columns; an image from the first sample's centre to the last's covers the drawn
/// grid corner to corner.
#[test]
fn geographic_imagery_follows_resampled_rows() {
    use clipsat::source::imagery::ImageryOptions;
    use clipsat::source::{LoadOptions, TerrainSpec};
    use tiff::encoder::colortype::{Gray32Float, RGB8};
    let dir = scratch("georef_ew");
    let wgs84 = [(1024, 2), (1025, 1), (2048, 4326)];
    let s = 1.0 / 1200.0;
    let heights = dir.join("heights.tif");
    geotiff::<Gray32Float>(&heights, 21, 11, &[100.0f32; 231], s, (10.0, 60.0), &wgs84);
    let image = dir.join("image.tif");
    let rgb = pattern(20, 10);
    geotiff::<RGB8>(
        &image,
        20,
        10,
        &rgb,
        s,
        (10.0 + 0.5 * s, 60.0 - 0.5 * s),
        &wgs84,
    );
    let load = LoadOptions {
        resample_ew: true,
        ..LoadOptions::default()
    };
    let terrain = clipsat::Terrain::from_spec(
        &TerrainSpec::File(heights),
        &load,
        None,
        true,
        clipsat::Progress::default(),
    )
    .expect("terrain")
    .with_imagery(
        &image,
        &ImageryOptions::default(),
        clipsat::Progress::default(),
    )
    .expect("imagery");
    let h = terrain.heights();
    assert_eq!(
        (h.width(), h.height()),
        (11, 11),
        "rows resampled to square cells"
    );
    let grid = Extent::of_grid(h.width(), h.height(), f64::from(h.spacing()), h.origin());
    let e = terrain.imagery().expect("imagery").header().extent;
    for (got, want) in e.to_array().into_iter().zip(grid.to_array()) {
        assert!(
            (got - want).abs() < 1e-6,
            "{e} against the drawn grid {grid}"
        );
    }
}

/// GeoTIFF imagery over SRTM `.hgt` heights, one tile or a mosaic of them, is placed by georeference: the
/// tiles' grid from their names (samples on whole 3" lines from the named corner, EPSG 4326) mapped as the
/// heights are drawn. It had been stretched over the whole terrain as a plain image.
#[test]
fn geotiff_imagery_is_placed_over_hgt_tiles() {
    use clipsat::source::georef::georef_extent;
    use clipsat::source::heights_georef;
    let dir = scratch("hgt_georef");
    let tile: Vec<u8> = std::iter::repeat_n(100i16.to_be_bytes(), 1201 * 1201)
        .flatten()
        .collect();
    std::fs::write(dir.join("N46E008.hgt"), &tile).expect("write");
    std::fs::write(dir.join("N46E009.hgt"), &tile).expect("write");
    let one = heights_georef(&dir.join("N46E008.hgt")).expect("a tile's georeference");
    let all = heights_georef(&dir).expect("a mosaic's georeference");
    let step = 1.0 / 1200.0;
    for (h, width) in [(&one, 1201), (&all, 2401)] {
        assert_eq!(h.size, (width, 1201));
        assert_eq!(h.scale, (step, step));
        assert!((h.corner.0 - (8.0 - step / 2.0)).abs() < 1e-12, "{h:?}");
        assert!((h.corner.1 - (47.0 + step / 2.0)).abs() < 1e-12, "{h:?}");
        assert_eq!((h.crs, h.geographic), (Some((2048, 4326)), Some(true)));
    }
    // A 4 x 4 image of 3" texels, its north-west corner 200" east and 150" south of the tile's.
    let image = dir.join("image.tif");
    let keys = [(1024, 2), (1025, 1), (2048, 4326)];
    let tie = (8.0 + 200.0 / 3600.0, 46.5 - 150.0 / 3600.0);
    geotiff::<tiff::encoder::colortype::RGB8>(&image, 4, 4, &[50; 48], step, tie, &keys);
    let i = clipsat::source::georef::GeoRef::read(&image).expect("a georeference");
    for (h, width) in [(&one, 1201), (&all, 2401)] {
        let e = georef_extent(&image, h, &i, 90.0, (0.0, 0.0), width).expect("placed");
        let want = [6000.0, 49140.0, 6360.0, 49500.0];
        for (got, want) in e.to_array().iter().zip(want) {
            assert!((got - want).abs() < 1e-6, "{e} against {want:?}");
        }
    }
}
