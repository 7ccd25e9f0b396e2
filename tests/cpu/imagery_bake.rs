//! Imagery's out-of-core bake (stages 0 and 1b): a reader's bands of rows give the whole image's texels
//! in every format, and the package baked band by band holds, tile for tile, the JPEG of the pyramid
//! made whole in memory (`ColorLevel::coarser`; residual levels against a reference reconstruction of
//! the level above), for sizes that end bands and tiles mid-way, and the cache hands out that
//! reconstruction.

use std::path::Path;

use clipsat::bake::imagery::ColorLevel;
use clipsat::package::imagery::{
    encode_jpeg, psnr, whole_quality, ImageryBakeReport, ImageryPackage, DEFAULT_QUALITY, TILE,
};
use clipsat::package::imagery_bake::{bake_imagery, bake_imagery_file};
use clipsat::package::imagery_cache::ImageryCache;
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

/// The residual tiles' prediction as a straightforward reference: the parent tile's texel under
/// (x, y) of its doubled tile, with its nearest neighbours toward (x, y), weighted 9, 3, 3, 1 (sixteenths,
/// rounded), neighbours past the parent tile's border clamped to it.
#[expect(
    clippy::cast_possible_truncation,
    reason = "a rounded mean of 8-bit values"
)]
fn reference_up(parent: &[u8], pw: u32, ph: u32, x: u32, y: u32, c: usize) -> i32 {
    let (i, j) = (x / 2, y / 2);
    let ni = if x % 2 == 1 {
        (i + 1).min(pw - 1)
    } else {
        i.max(1) - 1
    };
    let nj = if y % 2 == 1 {
        (j + 1).min(ph - 1)
    } else {
        j.max(1) - 1
    };
    let v = |a: u32, b: u32| f64::from(parent[((b * pw + a) * 3) as usize + c]);
    let sum = 9.0 * v(i, j) + 3.0 * v(ni, j) + 3.0 * v(i, nj) + v(ni, nj);
    (sum / 16.0 + 0.5).floor() as i32
}

/// Every tile of the package equals the JPEG of the same tile of the pyramid made whole in memory
/// (`ColorLevel::coarser`): odd levels and the coarsest as they are, the other even levels as residuals
/// against the reference reconstruction of the level above; and every tile the cache hands out equals
/// that reconstruction, bit for bit.
#[test]
fn the_band_by_band_bake_codes_the_whole_pyramid() {
    // 1030 x 1100: four levels; level 0 (residual) in bands of 512, 512 and 76 rows, level 2 (258 x 275,
    // residual of level 3) in one band of 275 rows, two tile rows.
    baked_as_the_reference(1030, 1100, 4);
    // 600 x 530: three levels; level 0 (residual) ends in a band of 18 rows, level 1 (300 x 265) in one
    // of 9, and level 2 (150 x 133) takes a band of 128 rows and one of 5.
    let (im, bytes, report) = baked_as_the_reference(600, 530, 3);
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

/// Bakes a `w` x `h` image of `levels` levels and checks it against the reference; returns the image,
/// the package and the report.
fn baked_as_the_reference(w: u32, h: u32, levels: u32) -> (Imagery, Vec<u8>, ImageryBakeReport) {
    let grid = Extent::of_grid(w, h, 1.0, (0.0, 0.0));
    let im =
        Imagery::from_rgb(Path::new("<bands>"), w, h, texels(w, h), &grid, None).expect("image");
    let (bytes, report) = bake_imagery(&im, DEFAULT_QUALITY, 7).expect("bake");
    assert_eq!(report.levels, levels);
    let package = ImageryPackage::from_bytes(Path::new("<bands>"), bytes.clone()).expect("package");
    let header = package.header().clone();
    // Even levels but the coarsest are residuals.
    assert_eq!(
        header.levels.iter().map(|l| l.residual).collect::<Vec<_>>(),
        (0..levels)
            .map(|l| l % 2 == 0 && l + 1 < levels)
            .collect::<Vec<_>>()
    );
    let mut levels = vec![ColorLevel {
        width: w,
        height: h,
        texels: im.texels().to_vec(),
    }];
    for _ in 1..header.levels.len() {
        let next = levels[levels.len() - 1].coarser();
        levels.push(next);
    }
    let jpeg_path = Path::new("<reference>");
    // Tile (tx, ty) of a level `width` x `height` texels (RGB8): its size and texels, row by row.
    let crop = |texels: &[u8], width: u32, height: u32, tx: u32, ty: u32| {
        let (tw, th) = (
            (width - tx * TILE).min(TILE),
            (height - ty * TILE).min(TILE),
        );
        let mut tile = Vec::new();
        for y in ty * TILE..ty * TILE + th {
            let at = ((y * width + tx * TILE) * 3) as usize;
            tile.extend_from_slice(&texels[at..at + (tw * 3) as usize]);
        }
        (tw, th, tile)
    };
    // The reference reconstruction of each level, coarsest first.
    let mut recon: Vec<Vec<u8>> = levels.iter().map(|l| vec![0; l.texels.len()]).collect();
    for li in (0..header.levels.len()).rev() {
        let l = header.levels[li];
        let level = &levels[li];
        assert_eq!(
            (l.width, l.height),
            (level.width, level.height),
            "level {li}"
        );
        for ty in 0..l.tiles_y {
            for tx in 0..l.tiles_x {
                let (tw, th, mut tile) = crop(&level.texels, l.width, l.height, tx, ty);
                // The parent tile as reconstructed, and each texel's prediction from it.
                let mut predicted = vec![0i32; tile.len()];
                if l.residual {
                    let p = header.levels[li + 1];
                    let (pw, ph, parent) = crop(&recon[li + 1], p.width, p.height, tx / 2, ty / 2);
                    for y in 0..th {
                        for x in 0..tw {
                            for c in 0..3 {
                                let (ux, uy) = ((tx % 2) * TILE + x, (ty % 2) * TILE + y);
                                let at = ((y * tw + x) * 3) as usize + c;
                                predicted[at] = reference_up(&parent, pw, ph, ux, uy, c);
                                let r = i32::from(tile[at]) - predicted[at] + 128;
                                tile[at] = r.clamp(0, 255) as u8;
                            }
                        }
                    }
                }
                // Residuals at the package's quality, whole levels a step above it.
                let quality = if l.residual {
                    DEFAULT_QUALITY
                } else {
                    whole_quality(DEFAULT_QUALITY)
                };
                let jpeg = encode_jpeg(jpeg_path, &tile, tw, th, quality).expect("encode");
                let e = header.tiles[l.first_tile + (ty * l.tiles_x + tx) as usize];
                let at = usize::try_from(e.offset).expect("offset");
                let stored = &bytes[at..at + e.len as usize];
                assert!(stored == jpeg.as_slice(), "level {li} tile ({tx}, {ty})");
                let mut decoded = image::load_from_memory(&jpeg)
                    .expect("decode")
                    .to_rgb8()
                    .into_raw();
                if l.residual {
                    for (d, p) in decoded.iter_mut().zip(&predicted) {
                        *d = (p + i32::from(*d) - 128).clamp(0, 255) as u8;
                    }
                }
                for y in 0..th {
                    let at = (((ty * TILE + y) * l.width + tx * TILE) * 3) as usize;
                    let row = (y * tw * 3) as usize;
                    recon[li][at..at + (tw * 3) as usize]
                        .copy_from_slice(&decoded[row..row + (tw * 3) as usize]);
                }
            }
        }
    }
    // The cache's tiles, finest first (each residual tile decodes its parent), are the reference's.
    let mut cache = ImageryCache::new(package, 64 << 20).expect("cache");
    cache.begin_frame();
    let mut budget = u64::MAX;
    let mut sq = 0u64;
    for (li, l) in header.levels.iter().enumerate() {
        for ty in 0..l.tiles_y {
            for tx in 0..l.tiles_x {
                let (tw, th, got) = cache
                    .fetch(li, tx, ty, &mut budget)
                    .expect("fetch")
                    .expect("resident");
                for y in 0..th {
                    let at = (((ty * TILE + y) * l.width + tx * TILE) * 3) as usize;
                    let row = (y * tw * 3) as usize;
                    let want = &recon[li][at..at + (tw * 3) as usize];
                    assert!(
                        &got[row..row + (tw * 3) as usize] == want,
                        "level {li} tile ({tx}, {ty}) row {y}"
                    );
                    if li == 0 {
                        sq += want
                            .iter()
                            .zip(&levels[0].texels[at..])
                            .map(|(a, b)| u64::from(a.abs_diff(*b)).pow(2))
                            .sum::<u64>();
                    }
                }
            }
        }
    }
    assert!(
        (psnr(sq, u64::from(w * h * 3)) - report.psnr_db).abs() < 1e-9,
        "{report:?}"
    );
    assert!(cache.stats().parents >= 1, "{:?}", cache.stats());
    (im, bytes, report)
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
