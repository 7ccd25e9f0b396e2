//! What the `bench` subcommands share.

/// The benchmark terrains: shared file, spacing and height scale overrides (PNG needs both).
pub(crate) const TERRAINS: [(&str, Option<f32>, Option<f32>); 3] = [
    ("ps_height_1k.png", Some(160.0), Some(0.1)),
    ("n07_w006_3arc_v2.tif", None, None),
    ("srtm_bigtujunga30m_utm11.tif", None, None),
];

/// The shared terrains `bench all` measures when present: file, spacing and height scale overrides (PNG
/// needs both).
pub(crate) const SHARED: [(&str, Option<f32>, Option<f32>); 6] = [
    ("ps_height_1k.png", Some(160.0), Some(0.1)),
    ("n07_w006_3arc_v2.tif", None, None),
    ("srtm_bigtujunga30m_utm11.tif", None, None),
    ("aletsch_200m.tif", None, None),
    ("lidar_pkg_dem_1m_400x400.tif", None, None),
    ("N57E011.hgt", None, None),
];

/// Bytes as MiB with two decimals, for the reports.
pub(crate) fn mib(bytes: u64) -> String {
    format!("{:.2} MiB", bytes as f64 / (1024.0 * 1024.0))
}

/// Plot colours, one per terrain.
pub(crate) const COLORS: [[u8; 3]; 7] = [
    [31, 119, 180],
    [214, 39, 40],
    [44, 160, 44],
    [148, 103, 189],
    [255, 127, 14],
    [140, 86, 75],
    [120, 120, 120],
];
