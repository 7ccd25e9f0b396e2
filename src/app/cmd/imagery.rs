//! Application (CLI): what an imagery package holds, in words and as JSON, for `info`, `bake`, `render`
//! and `fly`.

use clipsat::package::imagery::ImageryPackage;
use serde_json::json;

/// The imagery package's header as JSON: file, size, extent, texel spacing per level, tiles, bytes.
pub(crate) fn imagery_json(p: &ImageryPackage) -> serde_json::Value {
    let h = p.header();
    let levels: Vec<_> = h
        .levels
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let (sx, sy) = h.texel_spacing(i);
            json!({
                "width": l.width,
                "height": l.height,
                "tiles": l.tiles_x * l.tiles_y,
                "texel_spacing_m": [sx, sy],
            })
        })
        .collect();
    #[expect(clippy::cast_precision_loss, reason = "a ratio for a report")]
    let per_texel = p.len() as f64 / h.texels() as f64;
    json!({
        "file": p.path().display().to_string(),
        "format": format!("clipsat imagery package v{}", clipsat::package::imagery::VERSION),
        "codec": format!("JPEG 4:4:4 quality {}", h.quality),
        "width": h.width,
        "height": h.height,
        "extent_m": h.extent.to_array(),
        "tile": h.tile,
        "levels": levels,
        "tiles": h.tiles.len(),
        "bytes": p.len(),
        "bytes_per_texel": per_texel,
    })
}

/// The imagery package in a few lines, as `clipsat info` prints it.
pub(crate) fn print_imagery(p: &ImageryPackage) {
    let h = p.header();
    let (sx, sy) = h.texel_spacing(0);
    outln!("imagery   {}", p.path().display());
    outln!(
        "texels    {} x {} at {sx:.3} x {sy:.3} m, extent {}",
        h.width,
        h.height,
        h.extent
    );
    #[expect(clippy::cast_precision_loss, reason = "a ratio for a report")]
    let per_texel = p.len() as f64 / h.texels() as f64;
    outln!(
        "stored    {} levels, {} tiles of {}^2, JPEG 4:4:4 quality {}, {} bytes ({per_texel:.3} B/texel)",
        h.levels.len(),
        h.tiles.len(),
        h.tile,
        h.quality,
        p.len()
    );
}
