//! `clipsat info` on tile mosaics laid out as real tile sets are: SRTM tiles named in lower case on both
//! sides of the antimeridian.

use super::{clipsat, scratch_in};

/// `n00e179.hgt` and `n00w180.hgt` (3", flat) read as one terrain 2 degrees wide, from 179 E to 179 W:
/// it had been 432001 x 1201 samples, 39807 km across from 180 W to 180 E.
#[test]
fn info_on_tiles_across_the_antimeridian() {
    let dir = scratch_in("real_tiles", "antimeridian");
    let heights: Vec<u8> = std::iter::repeat_n(12i16.to_be_bytes(), 1201 * 1201)
        .flatten()
        .collect();
    for name in ["n00e179.hgt", "n00w180.hgt"] {
        std::fs::write(dir.join(name), &heights).expect("write tile");
    }
    let t = dir.to_str().expect("utf-8 path");
    let out = clipsat(&["info", "--terrain", t, "--fill-height", "0"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("samples   2401 x 1201 "), "{text}");
    assert!(
        text.contains("extent    0.000 N .. 1.000 N, 179.000 E .. 179.000 W"),
        "{text}"
    );
    let out = clipsat(&["info", "--terrain", t, "--fill-height", "0", "--json"]);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let geo = &json["geographic"];
    assert_eq!(
        (geo["west_deg"].as_f64(), geo["east_deg"].as_f64()),
        (Some(179.0), Some(181.0))
    );
}
