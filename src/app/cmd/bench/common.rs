//! What the `bench` subcommands share.

use clipsat::{Error, Result};

/// The benchmark terrains: shared file, spacing and height scale overrides (PNG needs both).
pub(crate) const TERRAINS: [(&str, Option<f32>, Option<f32>); 3] = [
    ("ps_height_1k.png", Some(160.0), Some(0.1)),
    ("n07_w006_3arc_v2.tif", None, None),
    ("srtm_bigtujunga30m_utm11.tif", None, None),
];

/// Parses `--size` as WxH pixels, 1..=2048 each.
pub(crate) fn parse_size(text: &str) -> Result<(u32, u32)> {
    let bad = || Error::Arg {
        arg: "--size".into(),
        reason: format!("`{text}` is not WxH pixels (1..=2048 each)"),
    };
    let (a, b) = text.split_once(['x', 'X']).ok_or_else(bad)?;
    let p = |s: &str| {
        s.trim()
            .parse::<u32>()
            .ok()
            .filter(|v| (1..=2048).contains(v))
            .ok_or_else(bad)
    };
    Ok((p(a)?, p(b)?))
}
