//! Stages 1-2, the imagery bake and package: small, odd-sized and uniform images come back from the
//! package as they went in (the runtime's JPEG decoder, zune-jpeg, misread some tiles of optimised
//! Huffman tables; `package::imagery::encode_jpeg` checks each tile and codes it again).

use std::path::Path;

use clipsat::package::imagery::ImageryPackage;
use clipsat::package::imagery_bake::{bake_imagery, bake_imagery_rows};
use clipsat::source::imagery::{Extent, Imagery};

/// A uniform image of `w` x `h` texels of `rgb`, baked at quality 75 and every tile of every level
/// decoded: the worst channel's distance from `rgb`, levels.
fn worst_after_bake(w: u32, h: u32, rgb: [u8; 3]) -> u8 {
    let texels = rgb.repeat((w * h) as usize);
    let grid = Extent::new(0.0, 0.0, 1000.0, 1000.0).expect("extent");
    let im = Imagery::from_rgb(Path::new("<uniform>"), w, h, texels, &grid, None).expect("image");
    let (bytes, _) = bake_imagery(&im, 75, 1).expect("bake");
    let p = ImageryPackage::from_bytes(Path::new("<uniform>"), bytes).expect("package");
    let mut out = vec![0u8; 256 * 256 * 3];
    let mut parent = vec![0u8; 256 * 256 * 3];
    let mut worst = 0;
    for (level, l) in p.header().levels.clone().iter().enumerate() {
        for ty in 0..l.tiles_y {
            for tx in 0..l.tiles_x {
                let (tw, th) = p
                    .decode_texels(level, tx, ty, &mut out, &mut parent)
                    .expect("decode");
                for t in out[..(tw * th * 3) as usize].chunks_exact(3) {
                    for (a, b) in t.iter().zip(rgb) {
                        worst = worst.max(a.abs_diff(b));
                    }
                }
            }
        }
    }
    worst
}

/// A uniform tile of 16 texels was read back as (133, 0, 0) for (220, 30, 30) from its second row of
/// blocks on (draped as a dark south half), as were sides of 9 to 176 and uniform residual tiles.
#[test]
fn uniform_images_come_back_uniform() {
    for (w, h) in [
        (8, 8),
        (16, 16),
        (33, 9),
        (64, 64),
        (100, 100),
        (176, 40),
        (257, 20),
    ] {
        for rgb in [[220, 30, 30], [0, 0, 0], [40, 120, 200]] {
            let worst = worst_after_bake(w, h, rgb);
            assert!(
                worst <= 3,
                "{w} x {h} of {rgb:?}: a texel {worst} levels off"
            );
        }
    }
}

/// The drape reaches the image's own edge. A ring handed a pixel to the next coarser one over 4 texels
/// inside its held region's border, the image's edge included, where no coarser ring holds anything:
/// the outer 4.5 texels of the coarsest ring took the terrain's colour (a 2 x 2 image was drawn at an
/// eighth of its colour at most, a 16 x 16 land-cover map lost more than half its area). Now the
/// imagery's weight is whole up to the image's edge and nothing past it, in every ring, the taps kept
/// on the edge texels (a clamp-to-edge filter), and the edge cut at the image's extent over a pixel's
/// footprint.
#[test]
fn the_drape_reaches_the_image_edge() {
    use clipsat::plan::color_rings::ColorRings;
    use clipsat::profile::ImageryBudget;
    use clipsat::twin::imagery::{decode, ImageryTwin};
    use glam::Vec3;

    let budget = ImageryBudget {
        ring: 256,
        levels: 3,
        texels_per_frame: 1 << 20,
        tiles_per_frame: 8,
        cache_bytes: 8 * (3 * 256 * 256 + 64) + 4 * 64,
    };
    // (image side, texels): a one-level 16 x 16, a 2 x 2, and a 600 x 600 of 3 levels (the rings over
    // its edge are clamped inside the image).
    for n in [16u32, 2, 600] {
        let rgb = [200u8, 40, 20];
        let texels = rgb.repeat((n * n) as usize);
        let grid = Extent::new(0.0, 0.0, 6000.0, 6000.0).expect("extent");
        let im = Imagery::from_rgb(Path::new("<edge>"), n, n, texels, &grid, None).expect("image");
        let (bytes, _) = bake_imagery(&im, 90, 1).expect("bake");
        let p = ImageryPackage::from_bytes(Path::new("<edge>"), bytes).expect("package");
        let mut rings = ColorRings::new(p, &budget).expect("rings");
        // The eye near the south-west corner; 40 frames: every ring whole and faded in.
        let (x, y) = (300.0f32, 400.0f32);
        for _ in 0..40 {
            rings.update(f64::from(x), f64::from(y)).expect("update");
        }
        let twin = ImageryTwin::new(&rings, f64::from(x), f64::from(y)).expect("twin");
        let base = Vec3::new(0.1, 0.5, 0.1);
        let want = Vec3::new(
            decode(f32::from(rgb[0]) / 255.0),
            decode(f32::from(rgb[1]) / 255.0),
            decode(f32::from(rgb[2]) / 255.0),
        );
        let texel = 6000.0 / n as f32;
        // Points inside the image by a footprint from each edge (the cut is smoothed over half of one),
        // near the eye and far from it; footprints of a metre (level 0) and of a texel.
        for fp in [1.0f32, texel] {
            let d = fp;
            for (px, py) in [
                (d, 3000.0),
                (3000.0, d),
                (6000.0 - d, 3000.0),
                (3000.0, 6000.0 - d),
                (d, d),
            ] {
                let rel = [px - x, py - y];
                let got = twin.albedo(rel, fp, base);
                assert!(
                    (got - want).abs().max_element() < 0.02,
                    "{n}^2 image at ({px}, {py}), footprint {fp}: albedo {got} for {want}"
                );
            }
        }
        // Past the edge by a footprint: the terrain's own colour.
        for (px, py) in [
            (-2.0, 400.0),
            (300.0, -2.0),
            (6002.0, 400.0),
            (300.0, 6002.0),
        ] {
            let got = twin.albedo([px - x, py - y], 1.0, base);
            assert!(
                (got - base).abs().max_element() < 1e-6,
                "{n}^2: ({px}, {py}) drew {got}"
            );
        }
    }
}

/// A fresh scratch folder for one test.
fn scratch(name: &str) -> std::path::PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("imagery_small")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch folder");
    dir
}

/// The file's texel (linear, centres aligned, clamped at the ends) that a side of `n` texels cut `k`
/// ways samples at resampled texel `i`: `values` interpolated.
fn expected(values: &[u8], k: usize, i: usize) -> f64 {
    let s = ((i as f64 + 0.5) / k as f64 - 0.5).max(0.0);
    let j = (0..values.len())
        .rev()
        .find(|&j| j as f64 <= s)
        .unwrap_or(0);
    let f = s - j as f64;
    let next = f64::from(values[(j + 1).min(values.len() - 1)]);
    f64::from(values[j]) * (1.0 - f) + next * f
}

/// An image whose texels are 16 times longer one way than the other over its extent (4 x 64 or 64 x 4
/// over a square) is read as it is, and baked with its long texels cut into 16: 64 x 64 near-square texels, linear between
/// the file's texel centres. Its rings had held only their short span of the fine axis, and the pixels
/// past it took coarser rings, 2^l times the file's texel on the coarse axis: a 257 x 4099 marker image
/// over a square terrain rendered 3.35 levels from the 1024^2 same-layout image on average (5477 pixels
/// past 16 levels), 0.53 (312) once near-square. Texels under twice as long one way are read as they are.
#[test]
fn long_texels_are_cut_near_square() {
    use clipsat::source::imagery::ImageryOptions;
    use clipsat::source::imagery_rows::ImageryRows;

    let dir = scratch("long_texels");
    let grid = Extent::new(0.0, 0.0, 640.0, 640.0).expect("extent");
    let values = [0u8, 160, 80, 240];
    for (w, h) in [(4u32, 64u32), (64, 4)] {
        let img = image::RgbImage::from_fn(w, h, |x, y| {
            let v = values[(if w == 4 { x } else { y }) as usize];
            image::Rgb([v, 255 - v, 7])
        });
        let path = dir.join(format!("long_{w}x{h}.png"));
        img.save(&path).expect("png");
        // Read as it is, and baked near-square.
        let im = Imagery::load(&path, &grid, &ImageryOptions::default()).expect("load");
        assert_eq!(im.size(), (w, h));
        let mut rows = ImageryRows::open(&path, &grid, &ImageryOptions::default()).expect("open");
        let mut package = std::io::Cursor::new(Vec::new());
        bake_imagery_rows(
            &mut rows,
            75,
            1,
            false,
            &mut package,
            clipsat::Progress::default(),
        )
        .expect("bake");
        let p =
            ImageryPackage::from_bytes(Path::new("<long>"), package.into_inner()).expect("package");
        assert_eq!((p.header().width, p.header().height), (64, 64), "{w} x {h}");
        let mut rows = ImageryRows::open(&path, &grid, &ImageryOptions::default()).expect("open");
        rows.near_square();
        assert_eq!(rows.size(), (64, 64), "{w} x {h}");
        let texels = rows.read_all().expect("rows");
        for y in 0..64usize {
            for x in 0..64usize {
                let i = if w == 4 { x } else { y };
                let want = expected(&values, 16, i);
                let got = &texels[(y * 64 + x) * 3..(y * 64 + x) * 3 + 3];
                assert!(
                    (f64::from(got[0]) - want).abs() <= 0.5 + 1e-9
                        && (f64::from(got[1]) - (255.0 - want)).abs() <= 0.5 + 1e-9
                        && got[2] == 7,
                    "{w} x {h} at ({x}, {y}): {got:?} for {want}"
                );
            }
        }
        // Within the texel limit only: 4 x 64 = 256 texels may not become 4096.
        let tight = ImageryOptions {
            max_texels: 1024,
            ..ImageryOptions::default()
        };
        let mut rows = ImageryRows::open(&path, &grid, &tight).expect("open");
        rows.near_square();
        assert_eq!(
            rows.size(),
            (64.min(w * 4), 64.min(h * 4)),
            "{w} x {h} capped"
        );
    }
    // 3001 x 1777 over a square: texels 1.69 times longer N-S, read as they are.
    let path = dir.join("odd.png");
    image::RgbImage::new(3001, 1777).save(&path).expect("png");
    let mut rows = ImageryRows::open(&path, &grid, &ImageryOptions::default()).expect("open");
    rows.near_square();
    assert_eq!(rows.size(), (3001, 1777));
}

/// A texel (column, row) as shown and its colour.
type Shown = ((i64, i64), [u8; 3]);

/// A JPEG of `w` x `h` stored texels (`rgb` of each), with an EXIF APP1 naming `orientation`.
fn jpeg_with_orientation(path: &Path, w: u16, h: u16, rgb: &[u8], orientation: u16) {
    // "Exif\0\0", a little-endian TIFF header, one IFD of one entry: Orientation (0x0112), SHORT, 1.
    let mut exif = b"Exif\0\0II*\0".to_vec();
    exif.extend_from_slice(&8u32.to_le_bytes());
    exif.extend_from_slice(&1u16.to_le_bytes());
    exif.extend_from_slice(&0x0112u16.to_le_bytes());
    exif.extend_from_slice(&3u16.to_le_bytes());
    exif.extend_from_slice(&1u32.to_le_bytes());
    exif.extend_from_slice(&orientation.to_le_bytes());
    exif.extend_from_slice(&[0, 0, 0, 0, 0, 0]);
    let mut e = jpeg_encoder::Encoder::new_file(path, 95).expect("jpeg file");
    e.add_app_segment(1, exif).expect("exif");
    e.encode(rgb, w, h, jpeg_encoder::ColorType::Rgb)
        .expect("encode");
}

/// A JPEG is read as viewers show it: its EXIF orientation applied. A marker image stored upside down
/// with Orientation 3, as cameras and editors write them, was draped upside down (its magenta dot at
/// (7661, 7699) m for (2560, 2560)); one stored on its side with Orientation 6 was draped on its side.
#[test]
fn jpeg_exif_orientation_is_applied() {
    use clipsat::source::imagery::ImageryOptions;

    let dir = scratch("exif");
    let grid = Extent::new(0.0, 0.0, 640.0, 640.0).expect("extent");
    let (red, blue) = ([230u8, 20, 20], [20u8, 20, 230]);
    // Stored 16 x 8: the left half red, the right half blue.
    let stored: Vec<u8> = (0..8)
        .flat_map(|_| (0..16).flat_map(|x| if x < 8 { red } else { blue }))
        .collect();
    let near = |got: [u8; 3], want: [u8; 3]| got.iter().zip(want).all(|(a, b)| a.abs_diff(b) <= 24);
    // (orientation, size as shown, (texel, colour) pairs as shown).
    let cases: [(u16, (u32, u32), [Shown; 2]); 3] = [
        (1, (16, 8), [((0, 0), red), ((15, 0), blue)]),
        // 180 degrees: left and right swap.
        (3, (16, 8), [((0, 0), blue), ((15, 7), red)]),
        // 90 degrees clockwise: the stored left half is shown on top.
        (6, (8, 16), [((0, 0), red), ((7, 15), blue)]),
    ];
    for (orientation, size, texels) in cases {
        let path = dir.join(format!("o{orientation}.jpg"));
        jpeg_with_orientation(&path, 16, 8, &stored, orientation);
        let im = Imagery::load(&path, &grid, &ImageryOptions::default()).expect("load");
        assert_eq!(im.size(), size, "orientation {orientation}");
        for ((x, y), want) in texels {
            let got = im.texel(x, y);
            assert!(
                near(got, want),
                "orientation {orientation}: ({x}, {y}) is {got:?}, not {want:?}"
            );
        }
    }
    // Placed by a world file, which describes the texels as stored (GDAL's reading): kept so.
    let path = dir.join("placed.jpg");
    jpeg_with_orientation(&path, 16, 8, &stored, 3);
    std::fs::write(dir.join("placed.jgw"), "40\n0\n0\n-40\n20\n620\n").expect("world file");
    let im = Imagery::load(&path, &grid, &ImageryOptions::default()).expect("load");
    assert!(near(im.texel(0, 0), red), "{:?}", im.texel(0, 0));
}
