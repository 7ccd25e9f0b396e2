//! What the `bench` subcommands share.

/// The benchmark terrains: shared file, spacing and height scale overrides (PNG needs both).
pub(crate) const TERRAINS: [(&str, Option<f32>, Option<f32>); 3] = [
    ("ps_height_1k.png", Some(160.0), Some(0.1)),
    ("n07_w006_3arc_v2.tif", None, None),
    ("srtm_bigtujunga30m_utm11.tif", None, None),
];
