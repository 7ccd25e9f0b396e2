//! `clipsat info` on a terrain in degrees: the one metric frame it is drawn in (equirectangular about its
//! middle row), how far that frame is from true lengths at its edges, and `--plot-projection`'s figure.

use std::path::Path;

use clipsat::source::geo::ew_length_error;
use clipsat::source::GeoExtent;
use clipsat::Result;
use serde_json::json;

use crate::app::plot::{LinePlot, Series};

/// The figure's size, pixels: small enough to commit beside the guide.
const PLOT_SIZE: (u32, u32) = (800, 450);

/// Latitudes the E-W reference curves are centred at (for a southern terrain, their southern twins).
const REFERENCES: [f64; 4] = [0.0, 30.0, 60.0, 75.0];

/// Points a curve is drawn with.
const STEPS: u32 = 24;

/// `58.000 N`, `12.500 S`.
fn lat_text(lat: f64) -> String {
    format!("{:.3} {}", lat.abs(), if lat < 0.0 { 'S' } else { 'N' })
}

/// `11.000 E`, `77.000 W`; a mosaic across the antimeridian runs on past 180 E, and 181 is `179.000 W`.
fn lon_text(lon: f64) -> String {
    let lon = (lon + 180.0).rem_euclid(360.0) - 180.0;
    format!("{:.3} {}", lon.abs(), if lon < 0.0 { 'W' } else { 'E' })
}

/// A length error as a signed percentage, to 0.01 %: one that rounds to zero is "+0.00 %", not "-0.00 %".
fn percent(e: f64) -> String {
    let p = (e * 10_000.0).round() / 100.0;
    format!("{:+.2} %", if p == 0.0 { 0.0 } else { p })
}

/// The text lines: where the terrain lies, and its frame's distortion at the edges. `stretch` is
/// [`clipsat::source::Heightmap::ew_stretch`]: where the cells are drawn square but not to scale (no
/// `--resample-ew`), the whole terrain is drawn that much wider on top of this.
pub(super) fn print(g: &GeoExtent, stretch: f64) {
    outln!(
        "extent    {} .. {}, {} .. {} (sample centres)",
        lat_text(g.south),
        lat_text(g.north),
        lon_text(g.west),
        lon_text(g.east)
    );
    let on_top = if (stretch - 1.0).abs() > clipsat::source::SQUARE_CELLS_TOLERANCE {
        " (to scale with --resample-ew; without it, times the E-W stretch above)"
    } else {
        ""
    };
    outln!(
        "projection equirectangular about {} (the middle row): E-W lengths {} at the south edge ({}), \
         {} at the north edge ({}); N-S within {:.3} %{on_top}",
        lat_text(g.frame_lat),
        percent(g.ew_error(g.south)),
        lat_text(g.south),
        percent(g.ew_error(g.north)),
        lat_text(g.north),
        g.ns_error_max() * 100.0
    );
}

/// The JSON summary's `geographic` object.
pub(super) fn json(g: &GeoExtent) -> serde_json::Value {
    json!({
        "north_deg": g.north,
        "south_deg": g.south,
        "west_deg": g.west,
        "east_deg": g.east,
        "frame_lat_deg": g.frame_lat,
        "ew_error_south": g.ew_error(g.south),
        "ew_error_north": g.ew_error(g.north),
        "ns_error_max": g.ns_error_max(),
    })
}

/// Points (latitude - centre, error %) of `err` over `centre` +- `half` degrees, leaving out latitudes
/// within a degree of a pole (where the E-W error has no bound).
fn curve(centre: f64, half: f64, err: impl Fn(f64) -> f64) -> Vec<(f64, f64)> {
    (0..=STEPS)
        .map(|i| -half + 2.0 * half * f64::from(i) / f64::from(STEPS))
        .filter(|d| (centre + d).abs() <= 89.0)
        .map(|d| (d, err(centre + d) * 100.0))
        .collect()
}

/// Writes `--plot-projection`'s figure to `out`: the E-W and N-S length errors across the terrain's
/// latitudes, against degrees from its middle row, and the E-W error of the same N-S extent about other
/// latitudes for scale.
pub(super) fn plot(g: &GeoExtent, out: &Path) -> Result<()> {
    let half = 0.5 * (g.north - g.south);
    let mut series = vec![
        Series {
            name: format!(
                "E-W, this terrain ({} .. {})",
                lat_text(g.south),
                lat_text(g.north)
            ),
            points: curve(g.frame_lat, half, |lat| g.ew_error(lat)),
            color: [31, 119, 180],
            right_axis: false,
        },
        Series {
            // Some hundred times smaller than E-W: on its own axis, or it would lie flat on zero.
            name: "N-S, this terrain".into(),
            points: curve(g.frame_lat, half, |lat| g.ns_error(lat)),
            color: [214, 39, 40],
            right_axis: true,
        },
    ];
    let sign = if g.frame_lat < 0.0 { -1.0 } else { 1.0 };
    let greys = [
        [150, 150, 150],
        [44, 160, 44],
        [148, 103, 189],
        [255, 127, 14],
    ];
    for (r, color) in REFERENCES.iter().zip(greys) {
        let centre = sign * r;
        series.push(Series {
            name: format!(
                "E-W, same extent about {}",
                lat_text(centre).replace(".000", "")
            ),
            points: curve(centre, half, |lat| ew_length_error(centre, lat)),
            color,
            right_axis: false,
        });
    }
    LinePlot {
        title: format!(
            "Equirectangular frame about {}: drawn / true length - 1",
            lat_text(g.frame_lat)
        ),
        x_label: "degrees of latitude from the middle row".into(),
        y_label: "E-W length error (%)".into(),
        y2_label: "N-S length error (%)".into(),
        x_log: false,
        series,
    }
    .write_png(out, PLOT_SIZE.0, PLOT_SIZE.1)
}

#[cfg(test)]
mod tests {
    use super::percent;

    #[test]
    fn an_error_that_rounds_to_zero_has_no_minus_sign() {
        assert_eq!(percent(-1.0e-7), "+0.00 %");
        assert_eq!(percent(-0.0), "+0.00 %");
        assert_eq!(percent(-0.027), "-2.70 %");
        assert_eq!(percent(0.0288), "+2.88 %");
    }
}
