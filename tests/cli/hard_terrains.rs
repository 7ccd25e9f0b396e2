//! Hard terrains through the binary: a flat one a fraction of a millimetre across is drawn, as at any other
//! scale (the data border's 2 cm inset used to cut it away whole, and its default view's near plane lay
//! past the far one), and a non-finite height scale is refused by name rather than read as every sample a
//! void.

use std::path::Path;

use super::{clipsat, scratch_in};

/// An `n` x `n` 16-bit grey PNG of a gentle slope, at `path`.
fn slope_png(path: &Path, n: u16) {
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(
        u32::from(n),
        u32::from(n),
        |x, y| image::Luma([1000 + u16::try_from(x + y).expect("small")]),
    );
    img.save(path).expect("write the test PNG");
}

/// Pixels of `png` unlike its top-left one (the sky).
fn terrain_pixels(png: &Path) -> usize {
    let img = image::open(png).expect("a readable PNG").to_rgba8();
    let sky = *img.get_pixel(0, 0);
    img.pixels().filter(|p| **p != sky).count()
}

#[test]
fn a_terrain_a_millimetre_across_is_drawn() {
    let dir = scratch_in("hard_terrains", "millimetre");
    let src = dir.join("slope.png");
    slope_png(&src, 17);
    for spacing in ["1e-4", "1e-6"] {
        let out = dir.join(format!("{spacing}.png"));
        let run = clipsat(&[
            "render",
            "--terrain",
            src.to_str().expect("utf-8 path"),
            "--spacing",
            spacing,
            "--height-scale",
            "1e-6",
            "--size",
            "160x90",
            "--out",
            out.to_str().expect("utf-8 path"),
        ]);
        assert!(
            run.status.success(),
            "{spacing}: {}",
            String::from_utf8_lossy(&run.stderr)
        );
        let n = terrain_pixels(&out);
        assert!(n > 160 * 90 / 20, "{spacing} m: terrain covers {n} pixels");
    }
}

#[test]
fn a_non_finite_height_scale_is_refused_by_name() {
    let dir = scratch_in("hard_terrains", "scale");
    let src = dir.join("slope.png");
    slope_png(&src, 5);
    let run = clipsat(&[
        "info",
        src.to_str().expect("utf-8 path"),
        "--height-scale",
        "nan",
    ]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{err}");
    assert!(err.contains("height scale NaN: must be finite"), "{err}");
}
