//! Imagery's out-of-core bake (stages 0 and 1b): a reader's bands of rows give the whole image's texels
//! in every format, and the package baked band by band holds, tile for tile, the JPEG of the pyramid
//! made whole in memory (`ColorLevel::coarser`), for sizes that end bands and tiles mid-way.

use std::path::Path;

use clipsat::bake::imagery::ColorLevel;
use clipsat::package::imagery::{ImageryPackage, DEFAULT_QUALITY, TILE};
use clipsat::package::imagery_bake::{bake_imagery, bake_imagery_file};
use clipsat::source::imagery::{Extent, Imagery, ImageryOptions};
use clipsat::source::imagery_rows::ImageryRows;

use super::TempDir;

/// A deterministic RGB image with detail at every scale (so JPEG tiles differ where texels do).
fn texels(w: u32, h: u32) -> Vec<u8> {
    let mut v = Vec::with_capacity((w * h * 3) as usize);
    let mut s = 0x9E37_79B9u32;
    for y in 0..h {
        for x in 0..w {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            let noise = (s >> 24) as u8 / 8;
            v.extend_from_slice(&[
                ((x * 7 + y) % 200) as u8 + noise,
                ((y * 5) % 220) as u8 + noise,
                ((x ^ y) % 180) as u8 + noise,
            ]);
        }
    }
    v
}

/// Every tile of the package equals the JPEG of the same tile of the pyramid made whole in memory.
#[test]
fn the_band_by_band_bake_codes_the_whole_pyramid() {
    // 600 x 530: three levels; level 0 ends in a band of 18 rows, level 1 (300 x 265) in one of 9, and
    // level 2 (150 x 133) takes a band of 128 rows and one of 5.
    let (w, h) = (600u32, 530u32);
    let grid = Extent::of_grid(w, h, 1.0, (0.0, 0.0));
    let im =
        Imagery::from_rgb(Path::new("<bands>"), w, h, texels(w, h), &grid, None).expect("image");
    let (bytes, report) = bake_imagery(&im, DEFAULT_QUALITY, 7).expect("bake");
    assert_eq!(report.levels, 3);
    let package = ImageryPackage::from_bytes(Path::new("<bands>"), bytes.clone()).expect("package");
    let header = package.header();
    let mut level = ColorLevel {
        width: w,
        height: h,
        texels: im.texels().to_vec(),
    };
    for (li, l) in header.levels.iter().enumerate() {
        assert_eq!(
            (l.width, l.height),
            (level.width, level.height),
            "level {li}"
        );
        for ty in 0..l.tiles_y {
            for tx in 0..l.tiles_x {
                let (tw, th) = (
                    (l.width - tx * TILE).min(TILE),
                    (l.height - ty * TILE).min(TILE),
                );
                let mut tile = Vec::new();
                for y in ty * TILE..ty * TILE + th {
                    let at = ((y * l.width + tx * TILE) * 3) as usize;
                    tile.extend_from_slice(&level.texels[at..at + (tw * 3) as usize]);
                }
                let mut jpeg = Vec::new();
                image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, DEFAULT_QUALITY)
                    .encode(&tile, tw, th, image::ExtendedColorType::Rgb8)
                    .expect("encode");
                let e = header.tiles[l.first_tile + (ty * l.tiles_x + tx) as usize];
                let at = usize::try_from(e.offset).expect("offset");
                let stored = &bytes[at..at + e.len as usize];
                assert!(stored == jpeg.as_slice(), "level {li} tile ({tx}, {ty})");
            }
        }
        level = level.coarser();
    }
    // The file bake writes the same bytes, through a temporary renamed into place.
    let dir = TempDir::new("imagery_bake", "bake");
    let out = dir.join("bands.clipsat-imagery");
    let mut rows = ImageryRows::held(im.clone());
    let r = bake_imagery_file(
        &mut rows,
        DEFAULT_QUALITY,
        7,
        true,
        &out,
        clipsat::Progress::default(),
    )
    .expect("file bake");
    assert_eq!(std::fs::read(&out).expect("read"), bytes);
    assert_eq!(r, report);
    assert_eq!(
        std::fs::read_dir(&*dir).expect("list").count(),
        1,
        "no temporary left"
    );
}

/// A file read in bands of 7 rows gives the texels of the whole read, for PNG (8 and 16 bits), JPEG and
/// TIFF in strips; rows past the end are refused.
#[test]
fn bands_of_rows_equal_the_whole_image() {
    use tiff::encoder::{colortype, TiffEncoder};
    let dir = TempDir::new("imagery_bake", "rows");
    let (w, h) = (67u32, 45u32);
    let rgb = texels(w, h);
    let grid = Extent::of_grid(w, h, 1.0, (0.0, 0.0));
    let mut files = Vec::new();
    for (name, img) in [
        (
            "rgb.png",
            image::DynamicImage::ImageRgb8(
                image::RgbImage::from_raw(w, h, rgb.clone()).expect("img"),
            ),
        ),
        (
            "rgb.jpg",
            image::DynamicImage::ImageRgb8(
                image::RgbImage::from_raw(w, h, rgb.clone()).expect("img"),
            ),
        ),
    ] {
        let path = dir.join(name);
        img.save(&path).expect("save");
        files.push(path);
        let path16 = dir.join(format!("16{name}"));
        if name.ends_with("png") {
            image::DynamicImage::ImageRgb16(img.to_rgb16())
                .save(&path16)
                .expect("save");
            files.push(path16);
        }
    }
    let path = dir.join("strips.tif");
    let mut file = std::fs::File::create(&path).expect("create");
    let mut enc = TiffEncoder::new(&mut file).expect("encoder");
    let mut image = enc.new_image::<colortype::RGB8>(w, h).expect("image");
    image.rows_per_strip(4).expect("strips");
    image.write_data(&rgb).expect("write");
    files.push(path);
    for path in &files {
        let whole = Imagery::load(path, &grid, &ImageryOptions::default()).expect("whole");
        let mut rows = ImageryRows::open(path, &grid, &ImageryOptions::default()).expect("rows");
        let mut got = Vec::new();
        let mut band = vec![0u8; 7 * w as usize * 3];
        for y in (0..h).step_by(7) {
            band.resize(7.min(h - y) as usize * w as usize * 3, 0);
            rows.read_rows(&mut band).expect("band");
            got.extend_from_slice(&band);
        }
        assert!(got == whole.texels(), "{}", path.display());
        if !path.to_string_lossy().ends_with("jpg") {
            assert!(got == rgb, "{} is exact", path.display());
        }
        let past = rows
            .read_rows(&mut vec![0u8; w as usize * 3])
            .expect_err("past the end");
        assert!(past.to_string().contains("whole rows"), "{past}");
    }
}

/// A planar RGB TIFF (each channel in a plane of its own, one strip a plane): read as the chunky one.
#[test]
#[expect(
    clippy::cast_possible_truncation,
    reason = "offsets in a file of a few hundred bytes"
)]
fn a_planar_tiff_is_read() {
    let dir = TempDir::new("imagery_bake", "planar");
    let (w, h) = (5u32, 3u32);
    let rgb = texels(w, h);
    let n = (w * h) as usize;
    // Little-endian TIFF: the header, three planes, the bits per sample, the strip table, then the IFD.
    let mut f = b"II*\0".to_vec();
    f.extend_from_slice(&0u32.to_le_bytes()); // the IFD's offset, set below
    let planes_at = f.len() as u32;
    for c in 0..3 {
        f.extend(rgb.iter().skip(c).step_by(3));
    }
    let bits_at = f.len() as u32;
    f.extend_from_slice(&[8, 0, 8, 0, 8, 0]);
    let offsets_at = f.len() as u32;
    for c in 0..3u32 {
        f.extend_from_slice(&(planes_at + c * n as u32).to_le_bytes());
    }
    let counts_at = f.len() as u32;
    for _ in 0..3 {
        f.extend_from_slice(&(n as u32).to_le_bytes());
    }
    let ifd = f.len() as u32;
    f[4..8].copy_from_slice(&ifd.to_le_bytes());
    // (tag, type: 3 SHORT or 4 LONG, count, value or offset)
    let tags: [(u16, u16, u32, u32); 10] = [
        (256, 4, 1, w),
        (257, 4, 1, h),
        (258, 3, 3, bits_at),
        (259, 3, 1, 1),
        (262, 3, 1, 2),
        (273, 4, 3, offsets_at),
        (277, 3, 1, 3),
        (278, 4, 1, h),
        (279, 4, 3, counts_at),
        (284, 3, 1, 2),
    ];
    f.extend_from_slice(&(tags.len() as u16).to_le_bytes());
    for (tag, kind, count, value) in tags {
        f.extend_from_slice(&tag.to_le_bytes());
        f.extend_from_slice(&kind.to_le_bytes());
        f.extend_from_slice(&count.to_le_bytes());
        f.extend_from_slice(&value.to_le_bytes());
    }
    f.extend_from_slice(&0u32.to_le_bytes());
    let path = dir.join("planar.tif");
    std::fs::write(&path, &f).expect("write");
    let grid = Extent::of_grid(w, h, 1.0, (0.0, 0.0));
    let im = Imagery::load(&path, &grid, &ImageryOptions::default()).expect("planar TIFF");
    assert!(im.texels() == rgb.as_slice(), "planar texels");
}
