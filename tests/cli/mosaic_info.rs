//! `clipsat info` on a tile mosaic that streams (`--fill-height`) describes it from a pass over its rows,
//! a band at a time, rather than loading it whole: the same size, spacing, height range and geographic
//! extent as the mosaic loaded whole.

use std::path::Path;

use super::{clipsat, scratch_in};

/// A geographic (EPSG 4326) f32 GeoTIFF tile of `n` x `n` samples, pixel-is-point, its north-west sample
/// at (`lon`, `lat`), `step` degrees apart, heights from `z`.
fn tile(path: &Path, n: u32, (lon, lat): (f64, f64), step: f64, z: impl Fn(u32, u32) -> f32) {
    use tiff::encoder::colortype::Gray32Float;
    use tiff::tags::Tag;
    let data: Vec<f32> = (0..n * n).map(|i| z(i % n, i / n)).collect();
    let mut file = std::fs::File::create(path).expect("create");
    let mut enc = tiff::encoder::TiffEncoder::new(&mut file).expect("encoder");
    let mut img = enc.new_image::<Gray32Float>(n, n).expect("image");
    img.encoder()
        .write_tag(Tag::ModelPixelScaleTag, &[step, step, 0.0][..])
        .expect("scale");
    img.encoder()
        .write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, lon, lat, 0.0][..])
        .expect("tiepoint");
    // Geographic model, pixel-is-point, WGS 84.
    let keys: [u16; 16] = [1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 2, 2048, 0, 1, 4326];
    img.encoder()
        .write_tag(Tag::GeoKeyDirectoryTag, &keys[..])
        .expect("geokeys");
    img.write_data(&data).expect("data");
}

#[test]
fn info_streams_a_mosaic_with_the_loaded_figures() {
    let dir = scratch_in("mosaic_info", "two_tiles");
    let tiles = dir.join("tiles");
    std::fs::create_dir_all(&tiles).expect("folder");
    // Two 9 x 9 tiles sharing their edge column at 11.08 E (the same heights there), 0.01 degrees apart.
    let z = |x: u32, y: u32| 100.0 + 3.0 * x as f32 + 7.0 * y as f32;
    tile(&tiles.join("a.tif"), 9, (11.0, 58.0), 0.01, z);
    tile(&tiles.join("b.tif"), 9, (11.08, 58.0), 0.01, |x, y| {
        z(x + 8, y)
    });
    let t = tiles.to_str().expect("utf-8 path");
    let run = |extra: &[&str]| -> serde_json::Value {
        let mut a = vec!["info", "--terrain", t, "--json"];
        a.extend_from_slice(extra);
        let out = clipsat(&a);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_slice(&out.stdout).expect("JSON")
    };
    for resample in [&[][..], &["--resample-ew"][..]] {
        let loaded = run(resample);
        let streamed = run(&[resample, &["--fill-height", "0"][..]].concat());
        for key in [
            "width",
            "height",
            "spacing_m",
            "ew_spacing_m",
            "min_m",
            "max_m",
            "geographic",
        ] {
            assert_eq!(streamed[key], loaded[key], "{key} {resample:?}");
        }
        if resample.is_empty() {
            // The shared column once; the heights as written (the resampled rows are filtered).
            assert_eq!(loaded["width"], 17);
            assert_eq!(
                (loaded["min_m"].as_f64(), loaded["max_m"].as_f64()),
                (Some(100.0), Some(204.0))
            );
        }
        assert!(loaded["geographic"].is_object(), "{loaded}");
    }
}
