//! Stages 1-2, the imagery bake and package: small, odd-sized and uniform images come back from the
//! package as they went in (the runtime's JPEG decoder, zune-jpeg, misread some tiles of optimised
//! Huffman tables; `package::imagery::encode_jpeg` checks each tile and codes it again).

use std::path::Path;

use clipsat::package::imagery::ImageryPackage;
use clipsat::package::imagery_bake::bake_imagery;
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
