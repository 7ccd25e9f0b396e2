//! Stage 2, draped imagery's colour rings (`plan::color_rings`): an update allocates nothing, moving or
//! still, once the tiles it reads are in the cache (a decode allocates inside the JPEG decoder, charged to
//! the frame's tile budget).

use std::path::Path;

use clipsat::package::color_blocks::ColorFormat;
use clipsat::package::imagery::ImageryPackage;
use clipsat::package::imagery_bake::bake_imagery;
use clipsat::plan::color_rings::ColorRings;
use clipsat::profile::ImageryBudget;
use clipsat::source::imagery::{Extent, Imagery};

use crate::counting_alloc::count;

#[test]
fn colour_updates_allocate_nothing() {
    let n = 600u32;
    let texels: Vec<u8> = (0..n * n * 3)
        .map(|i| u8::try_from(i % 251).expect("byte"))
        .collect();
    let grid = Extent::of_grid(n + 1, n + 1, 1.0, (0.0, 0.0));
    let im = Imagery::from_rgb(Path::new("<alloc>"), n, n, texels, &grid, None).expect("image");
    let (bytes, _) = bake_imagery(&im, 80, 0).expect("bake");
    // Every tile fits the cache (9 + 4 + 1, and in blocks 4 parent tiles for level 0's residuals), so
    // after a first pass nothing is decoded again.
    let budget = ImageryBudget {
        ring: 256,
        levels: 3,
        texels_per_frame: 16384,
        tiles_per_frame: 4,
        cache_bytes: 20 * (3 * 256 * 256 + 64) + 4096,
    };
    // RGBA8 rings, and rings of BC1 and ETC2 blocks (a tile encoded when decoded).
    for format in [ColorFormat::Rgba8, ColorFormat::Bc1, ColorFormat::Etc2Rgb8] {
        let pkg = ImageryPackage::from_bytes(Path::new("<alloc>"), bytes.clone()).expect("package");
        let mut rings = ColorRings::with_format(pkg, &budget, format).expect("rings");
        let eye = |i: u32| (100.0 + 3.0 * f64::from(i), 500.0 - 2.0 * f64::from(i));
        // First pass: fills and decodes.
        for i in 0..150 {
            let (x, y) = eye(i);
            rings.update(x, y).expect("update");
        }
        // Second pass over the same path: every tile resident, the rings move and write.
        let mut written = 0;
        for i in 0..150 {
            let (x, y) = eye(i);
            let mut texels = 0;
            let allocations = count(|| {
                texels = rings.update(x, y).expect("update").texels;
            });
            written += texels;
            assert_eq!(allocations, 0, "{format:?}: frame {i} allocated");
        }
        assert!(written > 0, "the second pass wrote nothing");
        assert_eq!(rings.cache().stats().evictions, 0);
    }
}
