//! `clipsat info` on a tile mosaic that streams (`--fill-height`) describes it from a pass over its rows,
//! a band at a time, rather than loading it whole: the same size, spacing, height range and geographic
//! extent as the mosaic loaded whole.

use super::{clipsat, geotiff_tile as tile, scratch_in};

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
