//! The colour clipmap (issue 43, stage 2): rings of an imagery package moved toward the viewer under the
//! profile's texel and tile budgets. A mirror of the GPU texture, written by the plan's uploads alone,
//! holds in every ring's held region exactly the pyramid's decoded texels at their toroidal address;
//! every frame stays in budget; the hashes repeat run to run; a still camera ends with every ring whole.

use std::path::Path;

use clipsat::package::imagery::ImageryPackage;
use clipsat::package::imagery_bake::bake_imagery;
use clipsat::package::imagery_cache::ImageryCache;
use clipsat::plan::color_rings::ColorRings;
use clipsat::profile::ImageryBudget;
use clipsat::source::imagery::{Extent, Imagery};

/// A 1500 x 900 image over a 1501 x 901 grid at 2 m: four pyramid levels (1500, 750, 375, 188 wide).
fn package() -> ImageryPackage {
    let (w, h) = (1500u32, 900u32);
    let mut texels = Vec::with_capacity(w as usize * h as usize * 3);
    for y in 0..h {
        for x in 0..w {
            let byte = |v: u32| u8::try_from(v % 256).expect("a byte");
            texels.extend_from_slice(&[byte(x / 3), byte(y / 2), byte((x ^ y) / 5)]);
        }
    }
    let grid = Extent::of_grid(w + 1, h + 1, 2.0, (0.0, 0.0));
    let im = Imagery::from_rgb(Path::new("<rings>"), w, h, texels, &grid, None).expect("imagery");
    let (bytes, _) = bake_imagery(&im, 85, 3).expect("bake");
    ImageryPackage::from_bytes(Path::new("<rings>"), bytes).expect("package")
}

/// A small budget: rings of 256, 3 levels, 20000 texels and 1 tile a frame, 8 tile slots.
fn budget() -> ImageryBudget {
    ImageryBudget {
        ring: 256,
        levels: 3,
        texels_per_frame: 20_000,
        tiles_per_frame: 1,
        cache_bytes: 8 * (3 * 256 * 256 + 64) + 4 * 64,
    }
}

/// The GPU texture as the uploads leave it: `levels` layers of `ring^2` RGBA8.
struct Mirror {
    ring: usize,
    texels: Vec<u8>,
}

impl Mirror {
    fn apply(&mut self, rings: &ColorRings) {
        for u in rings.uploads() {
            let layer = u.level as usize * self.ring * self.ring * 4;
            for row in 0..u.h as usize {
                let src = u.offset + row * u.w as usize * 4;
                let dst = layer + ((u.y as usize + row) * self.ring + u.x as usize) * 4;
                self.texels[dst..dst + u.w as usize * 4]
                    .copy_from_slice(&rings.staging()[src..src + u.w as usize * 4]);
            }
        }
    }
}

/// Every texel of every ring's held region, read from the mirror at its toroidal address, equals the
/// package's decoded texel.
fn assert_rings_true(rings: &ColorRings, mirror: &Mirror, decoded: &[Vec<u8>], tag: &str) {
    let ring = mirror.ring as i64;
    for (level, texels) in decoded
        .iter()
        .enumerate()
        .take(rings.level_count() as usize)
    {
        let held = rings.held(level);
        let width = i64::from(rings.package().header().levels[level].width);
        for j in held.y0..held.y0 + held.h.max(0) {
            for i in held.x0..held.x0 + held.w.max(0) {
                let at = (level * mirror.ring * mirror.ring
                    + usize::try_from(j.rem_euclid(ring) * ring + i.rem_euclid(ring))
                        .expect("index"))
                    * 4;
                let src = usize::try_from((j * width + i) * 3).expect("index");
                assert_eq!(
                    &mirror.texels[at..at + 3],
                    &texels[src..src + 3],
                    "{tag}: level {level} texel ({i}, {j})"
                );
                assert_eq!(mirror.texels[at + 3], 255, "{tag}: alpha");
            }
        }
    }
}

/// Each level decoded whole from the package's tiles.
fn decode_all(p: &ImageryPackage) -> Vec<Vec<u8>> {
    let h = p.header();
    let mut out = Vec::new();
    let mut tile = vec![0u8; 256 * 256 * 3];
    let mut parent = tile.clone();
    for (level, l) in h.levels.iter().enumerate() {
        let mut texels = vec![0u8; l.width as usize * l.height as usize * 3];
        for ty in 0..l.tiles_y {
            for tx in 0..l.tiles_x {
                let (tw, th) = p
                    .decode_texels(level, tx, ty, &mut tile, &mut parent)
                    .expect("decode");
                for y in 0..th as usize {
                    let dst = ((ty as usize * 256 + y) * l.width as usize + tx as usize * 256) * 3;
                    texels[dst..dst + tw as usize * 3]
                        .copy_from_slice(&tile[y * tw as usize * 3..(y + 1) * tw as usize * 3]);
                }
            }
        }
        out.push(texels);
    }
    out
}

/// A flight across the image and past its edge: (x, y) of frame i, metres.
fn eye(i: u32) -> (f64, f64) {
    let t = f64::from(i);
    (
        200.0 + 23.0 * t,
        1700.0 - 9.0 * t + 300.0 * (t / 40.0).sin(),
    )
}

#[test]
fn rings_hold_the_pyramid_within_budget() {
    let pkg = package();
    let decoded = decode_all(&pkg);
    let b = budget();
    let mut rings = ColorRings::new(pkg, &b).expect("rings");
    assert_eq!(
        rings.level_count(),
        3,
        "the profile's levels, under the pyramid's 4"
    );
    let mut mirror = Mirror {
        ring: 256,
        texels: vec![0; 3 * 256 * 256 * 4],
    };
    let mut hashes = Vec::new();
    let mut current = 0;
    for i in 0..150 {
        let (x, y) = eye(i);
        let s = rings.update(x, y).expect("update");
        // A moving eye's rings keep up once filled (a large fill is not restarted by every move).
        current += u32::from(i >= 30 && s.stale_levels == 0);
        assert!(
            s.texels <= u64::from(b.texels_per_frame),
            "frame {i}: {s:?}"
        );
        assert!(s.tiles_decoded <= b.tiles_per_frame, "frame {i}: {s:?}");
        mirror.apply(&rings);
        assert_rings_true(&rings, &mirror, &decoded, &format!("frame {i}"));
        hashes.push(s.hash);
    }
    assert!(
        current > 60,
        "{current} of 120 moving frames had every ring current"
    );
    // A still camera over the image: every ring becomes whole.
    let (x, y) = (1500.0, 900.0);
    let mut frames = 0;
    while rings.update(x, y).expect("update").stale_levels > 0 {
        mirror.apply(&rings);
        frames += 1;
        assert!(frames < 200, "the rings never settle");
    }
    mirror.apply(&rings);
    assert_rings_true(&rings, &mirror, &decoded, "settled");
    assert!((0..3).all(|l| !rings.held(l).is_empty()));
    let views = rings.views(x, y);
    assert!(
        views[..3].iter().all(|v| v.held[2] > v.held[0]),
        "{views:?}"
    );
    assert!(views[3..].iter().all(|v| v.held[2] < v.held[0]));
    // The same flight again: the same hashes.
    let mut again = ColorRings::new(package(), &b).expect("rings");
    for (i, h) in hashes.iter().enumerate() {
        let (x, y) = eye(u32::try_from(i).expect("frame"));
        assert_eq!(again.update(x, y).expect("update").hash, *h, "frame {i}");
    }
}

#[test]
fn a_still_ring_moves_nothing_and_bad_eyes_are_refused() {
    let mut rings = ColorRings::new(package(), &budget()).expect("rings");
    for _ in 0..100 {
        rings.update(1000.0, 900.0).expect("update");
    }
    let s = rings.update(1000.0, 900.0).expect("update");
    assert_eq!((s.texels, s.uploads, s.stale_levels), (0, 0, 0), "{s:?}");
    assert!(rings.update(f64::NAN, 0.0).is_err());
    assert!(rings.update(1e300, 0.0).is_err());
    // A budget that does not validate is refused.
    let bad = ImageryBudget {
        ring: 300,
        ..budget()
    };
    assert!(ColorRings::new(package(), &bad).is_err());
}

/// Rings in a block format (BC1, ETC2 RGB8) over the same flight: every upload is whole 4 x 4 blocks
/// inside the ring (x, y, w, h multiples of 4), the texel budget is charged the padded texels, and the
/// GPU texture as the uploads leave it holds, for every texel of every held region (levels 375 and 188
/// wide end mid-block), the block the tile cache encodes for it; the staging is 0.5 byte a texel and the
/// hashes repeat run to run.
#[test]
#[expect(
    clippy::cast_possible_truncation,
    reason = "texel and tile indices of a test image"
)]
fn block_rings_write_whole_blocks() {
    use clipsat::package::color_blocks::{BlockEncoder, ColorFormat};
    let b = ImageryBudget {
        levels: 4,
        ..budget()
    };
    for format in [ColorFormat::Bc1, ColorFormat::Etc2Rgb8] {
        let pkg = package();
        // Each tile encoded whole, as the cache encodes it: (level, tx, ty) -> blocks.
        let mut encoder = BlockEncoder::new(format, 256);
        let mut tiles = std::collections::HashMap::new();
        let mut rgb = vec![0u8; 256 * 256 * 3];
        let mut parent = rgb.clone();
        for (level, l) in pkg.header().levels.iter().enumerate() {
            for ty in 0..l.tiles_y {
                for tx in 0..l.tiles_x {
                    let (tw, th) = pkg
                        .decode_texels(level, tx, ty, &mut rgb, &mut parent)
                        .expect("decode");
                    let mut out = vec![0u8; format.bytes(tw, th) as usize];
                    encoder.encode(&rgb, tw, th, &mut out).expect("encode");
                    tiles.insert((level, tx, ty), (tw, out));
                }
            }
        }
        let mut rings = ColorRings::with_format(pkg, &b, format).expect("rings");
        assert_eq!(rings.staging().len(), b.texels_per_frame as usize / 2);
        let ring = 256usize;
        let layer = (ring / 4) * (ring / 4) * 8;
        let mut mirror = vec![0u8; 4 * layer];
        let mut hashes = Vec::new();
        let check = |rings: &ColorRings, mirror: &mut Vec<u8>, tag: &str, verify: bool| {
            for u in rings.uploads() {
                assert!(
                    [u.x, u.y, u.w, u.h].iter().all(|v| v % 4 == 0)
                        && u.x + u.w <= 256
                        && u.y + u.h <= 256,
                    "{tag}: {u:?}"
                );
                let row = u.w as usize / 4 * 8;
                for by in 0..u.h as usize / 4 {
                    let src = u.offset + by * row;
                    let dst = u.level as usize * layer
                        + ((u.y as usize / 4 + by) * (ring / 4) + u.x as usize / 4) * 8;
                    mirror[dst..dst + row].copy_from_slice(&rings.staging()[src..src + row]);
                }
            }
            for level in (0..rings.level_count() as usize).filter(|_| verify) {
                let held = rings.held(level);
                for j in (held.y0..held.y0 + held.h.max(0)).step_by(4) {
                    for i in (held.x0..held.x0 + held.w.max(0)).step_by(4) {
                        let (i, j) = (i as usize, j as usize);
                        let (tw, blocks) = &tiles[&(level, (i / 256) as u32, (j / 256) as u32)];
                        let at = ((j % 256) / 4 * (*tw as usize).div_ceil(4) + (i % 256) / 4) * 8;
                        let m = level * layer + ((j % ring) / 4 * (ring / 4) + (i % ring) / 4) * 8;
                        assert_eq!(
                            &mirror[m..m + 8],
                            &blocks[at..at + 8],
                            "{tag}: level {level} block at ({i}, {j})"
                        );
                    }
                }
            }
        };
        for i in 0..150 {
            let (x, y) = eye(i);
            let s = rings.update(x, y).expect("update");
            assert!(
                s.texels <= u64::from(b.texels_per_frame),
                "frame {i}: {s:?}"
            );
            check(
                &rings,
                &mut mirror,
                &format!("{format:?} frame {i}"),
                i % 10 == 9,
            );
            hashes.push(s.hash);
        }
        let (x, y) = (2900.0, 100.0);
        let mut frames = 0;
        while rings.update(x, y).expect("update").stale_levels > 0 {
            check(&rings, &mut mirror, "settling", false);
            frames += 1;
            assert!(frames < 300, "the rings never settle");
        }
        check(&rings, &mut mirror, "settled", true);
        assert!((0..4).all(|l| !rings.held(l).is_empty()));
        // A budget that cannot hold the block format keeps RGBA8.
        for small in [
            ImageryBudget {
                cache_bytes: 300_000 + ImageryCache::parent_bytes(&package(), format),
                ..b
            },
            ImageryBudget {
                texels_per_frame: 1000,
                ..b
            },
        ] {
            let r = ColorRings::with_format(package(), &small, format).expect("rings");
            assert_eq!(r.format(), ColorFormat::Rgba8, "{small:?}");
        }
        let mut again = ColorRings::with_format(package(), &b, format).expect("rings");
        for (i, h) in hashes.iter().enumerate() {
            let (x, y) = eye(u32::try_from(i).expect("frame"));
            assert_eq!(again.update(x, y).expect("update").hash, *h, "frame {i}");
        }
    }
}
