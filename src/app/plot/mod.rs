//! Pictures of measurements: small line plots written as PNG (fly-through statistics, accuracy against time).

mod font;

use std::path::Path;

use crate::app::cmd::args::arg_error;
use clipsat::{Error, Result};

use font::glyph;

/// One named series of (x, y) points, drawn as a polyline.
#[derive(Clone, Debug)]
pub(crate) struct Series {
    /// Legend text.
    pub(crate) name: String,
    /// Points in data units.
    pub(crate) points: Vec<(f64, f64)>,
    /// RGB colour.
    pub(crate) color: [u8; 3],
    /// Plot against the right-hand axis instead of the left.
    pub(crate) right_axis: bool,
}

/// A line plot with a title, axis labels and a legend.
#[derive(Clone, Debug, Default)]
pub(crate) struct LinePlot {
    /// Title across the top.
    pub(crate) title: String,
    /// X axis label.
    pub(crate) x_label: String,
    /// Left Y axis label.
    pub(crate) y_label: String,
    /// Right Y axis label (used when a series has `right_axis`).
    pub(crate) y2_label: String,
    /// Log scale on the X axis.
    pub(crate) x_log: bool,
    /// The series.
    pub(crate) series: Vec<Series>,
}

impl LinePlot {
    /// Renders the plot at `width` x `height` pixels and writes it as PNG to `path`.
    ///
    /// White background, grid, ticks with numeric labels, title, axis labels, legend (in the corner of
    /// the axes that hides the fewest points), optional log X and a right-hand axis for series with `right_axis`. Non-finite points
    /// (and X <= 0 on a log axis) are skipped. The picture depends only on the plot, not on the machine.
    pub(crate) fn write_png(&self, path: &Path, width: u32, height: u32) -> Result<()> {
        let canvas = self.render(width, height)?;
        let img = image::RgbImage::from_raw(width, height, canvas.pixels)
            .ok_or_else(|| Error::format(path, "plot buffer has the wrong size"))?;
        img.save_with_format(path, image::ImageFormat::Png)
            .map_err(|e| Error::io(path, "cannot write plot", std::io::Error::other(e)))
    }

    /// Renders the plot into an RGB8 canvas.
    fn render(&self, width: u32, height: u32) -> Result<Canvas> {
        if !(160..=16384).contains(&width) || !(120..=16384).contains(&height) {
            return Err(arg_error(
                "plot size",
                format!("{width} x {height} pixels: need 160..=16384 x 120..=16384"),
            ));
        }
        let mut c = Canvas::new(width, height);
        // Font pixel size: 5x7 glyphs, doubled from about 360 px up.
        let s = ((width.min(height) + 100) / 230).clamp(1, 4) as i32;
        let (cw, ch) = (6 * s, 9 * s);
        let has_right = self.series.iter().any(|sr| sr.right_axis);

        let xr = Range::of(self.points(None).map(|p| p.0), self.x_log);
        let yl = Range::of(self.points(Some(false)).map(|p| p.1), false);
        let yr = Range::of(self.points(Some(true)).map(|p| p.1), false);
        let xt = xr.ticks(self.x_log);
        let ylt = yl.ticks(false);
        let yrt = yr.ticks(false);
        let label_w =
            |ticks: &[(f64, String)]| ticks.iter().map(|t| text_width(&t.1, s)).max().unwrap_or(0);

        let left = ch + label_w(&ylt) + 3 * s + 2 * s + 2 * cw / 3;
        let right = if has_right {
            ch + label_w(&yrt) + 3 * s + 2 * s + 2 * cw / 3
        } else {
            3 * cw
        };
        let top = if self.title.is_empty() {
            ch
        } else {
            3 * ch + ch / 2
        };
        let bottom = 2 * ch + ch / 2 + 3 * s;
        let (w, h) = (width as i32, height as i32);
        let plot = Rect {
            x0: left,
            y0: top,
            x1: w - right,
            y1: h - bottom,
        };
        if plot.x1 - plot.x0 < 40 || plot.y1 - plot.y0 < 40 {
            return Err(arg_error(
                "plot size",
                format!("{width} x {height} pixels leave no room for the axes"),
            ));
        }

        let grid = [232, 232, 232];
        let axis = [40, 40, 40];
        let px = |v: f64| plot.x0 as f64 + xr.frac(v, self.x_log) * (plot.x1 - plot.x0) as f64;
        let py = |r: &Range, v: f64| plot.y1 as f64 - r.frac(v, false) * (plot.y1 - plot.y0) as f64;

        // Grid and ticks.
        for (v, label) in &xt {
            let x = to_px(px(*v));
            c.vline(x, plot.y0, plot.y1, grid);
            c.vline(x, plot.y1, plot.y1 + 3 * s, axis);
            let tw = text_width(label, s);
            c.text(label, x - tw / 2, plot.y1 + 5 * s, s, axis);
        }
        if self.x_log {
            for v in xr.minor_log_ticks() {
                let x = to_px(px(v));
                c.vline(x, plot.y1, plot.y1 + 2 * s, axis);
            }
        }
        for (v, label) in &ylt {
            let y = to_px(py(&yl, *v));
            c.hline(plot.x0, plot.x1, y, grid);
            c.hline(plot.x0 - 3 * s, plot.x0, y, axis);
            let tw = text_width(label, s);
            c.text(label, plot.x0 - 5 * s - tw, y - 7 * s / 2, s, axis);
        }
        if has_right {
            for (v, label) in &yrt {
                let y = to_px(py(&yr, *v));
                c.hline(plot.x1, plot.x1 + 3 * s, y, axis);
                c.text(label, plot.x1 + 5 * s, y - 7 * s / 2, s, axis);
            }
        }
        // Frame.
        c.hline(plot.x0, plot.x1, plot.y0, axis);
        c.hline(plot.x0, plot.x1, plot.y1, axis);
        c.vline(plot.x0, plot.y0, plot.y1, axis);
        c.vline(plot.x1, plot.y0, plot.y1, axis);

        // Series, clipped to the frame.
        let thick = 0.75 + 0.5 * s as f64;
        for sr in &self.series {
            let yrange = if sr.right_axis { &yr } else { &yl };
            let mut prev: Option<(f64, f64)> = None;
            for &(x, y) in &sr.points {
                if !usable(x, y, self.x_log) {
                    prev = None;
                    continue;
                }
                let p = (px(x), py(yrange, y));
                match prev {
                    Some(q) => c.line(q, p, thick, sr.color, &plot),
                    // A lone point still shows.
                    None => c.line(p, p, thick, sr.color, &plot),
                }
                prev = Some(p);
            }
        }

        // Title, axis labels.
        if !self.title.is_empty() {
            // One size up, smaller if that would not fit the width.
            let ts = (1..=s + 1)
                .rev()
                .find(|&k| text_width(&self.title, k) <= w - 2 * cw)
                .unwrap_or(1);
            let tw = text_width(&self.title, ts);
            c.text(&self.title, (w - tw) / 2, ch, ts, [0, 0, 0]);
        }
        let xw = text_width(&self.x_label, s);
        c.text(
            &self.x_label,
            (plot.x0 + plot.x1 - xw) / 2,
            h - ch - s,
            s,
            axis,
        );
        let mid = (plot.y0 + plot.y1) / 2;
        let yw = text_width(&self.y_label, s);
        c.text_up(&self.y_label, s, mid + yw / 2, s, axis);
        if has_right {
            let y2w = text_width(&self.y2_label, s);
            c.text_up(&self.y2_label, w - ch, mid + y2w / 2, s, axis);
        }

        // Legend: a boxed list in the top-left corner of the axes.
        let named: Vec<&Series> = self
            .series
            .iter()
            .filter(|sr| !sr.name.is_empty())
            .collect();
        if !named.is_empty() {
            let tag = |sr: &Series| {
                if sr.right_axis && has_right {
                    " (right)"
                } else {
                    ""
                }
            };
            // The legend's box at font size k: (width, height).
            let boxed = |k: i32| {
                let lw = named
                    .iter()
                    .map(|sr| text_width(&sr.name, k) + text_width(tag(sr), k))
                    .max()
                    .unwrap_or(0);
                (
                    4 * 6 * k + 2 * 6 * k + lw,
                    to_i32(named.len()) * (11 * k) + 9 * k / 2,
                )
            };
            // Full size unless the box would cover more than an eighth of the axes.
            let (pw, ph) = (plot.x1 - plot.x0, plot.y1 - plot.y0);
            let s = (1..=s)
                .rev()
                .find(|&k| {
                    let (bw, bh) = boxed(k);
                    bw * bh * 8 <= pw * ph && bw <= pw - 4 * cw
                })
                .unwrap_or(1);
            let (cw, ch) = (6 * s, 9 * s);
            let swatch = 4 * cw;
            let row = ch + 2 * s;
            let (bw, bh) = boxed(s);
            // The corner of the axes that hides the fewest data points.
            let corners = [
                (plot.x0 + 2 * cw, plot.y0 + ch),
                (plot.x1 - 2 * cw - bw, plot.y0 + ch),
                (plot.x0 + 2 * cw, plot.y1 - ch - bh),
                (plot.x1 - 2 * cw - bw, plot.y1 - ch - bh),
            ];
            let hidden = |&(bx, by): &(i32, i32)| {
                let (bx, by) = (f64::from(bx), f64::from(by));
                self.series
                    .iter()
                    .flat_map(|sr| {
                        let yrange = if sr.right_axis { &yr } else { &yl };
                        sr.points
                            .iter()
                            .filter(|&&(x, y)| usable(x, y, self.x_log))
                            .map(move |&(x, y)| (px(x), py(yrange, y)))
                    })
                    .filter(|&(x, y)| {
                        x >= bx - 4.0
                            && x <= bx + f64::from(bw) + 4.0
                            && y >= by - 4.0
                            && y <= by + f64::from(bh) + 4.0
                    })
                    .count()
            };
            let (bx, by) = corners
                .iter()
                .min_by_key(|c| hidden(c))
                .copied()
                .unwrap_or(corners[0]);
            c.fill(bx, by, bx + bw, by + bh, [255, 255, 255]);
            c.hline(bx, bx + bw, by, [160, 160, 160]);
            c.hline(bx, bx + bw, by + bh, [160, 160, 160]);
            c.vline(bx, by, by + bh, [160, 160, 160]);
            c.vline(bx + bw, by, by + bh, [160, 160, 160]);
            for (i, sr) in named.iter().enumerate() {
                let ty = by + ch / 2 + to_i32(i) * row;
                let ly = f64::from(ty + 7 * s / 2);
                let whole = Rect {
                    x0: 0,
                    y0: 0,
                    x1: w,
                    y1: h,
                };
                let sx = f64::from(bx + cw / 2);
                c.line(
                    (sx, ly),
                    (sx + f64::from(swatch), ly),
                    thick,
                    sr.color,
                    &whole,
                );
                let name = format!("{}{}", sr.name, tag(sr));
                c.text(&name, bx + cw / 2 + swatch + cw / 2, ty, s, axis);
            }
        }
        Ok(c)
    }

    /// The usable points of the series on one axis (`Some(true)` right, `Some(false)` left) or all.
    fn points(&self, right: Option<bool>) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.series
            .iter()
            .filter(move |sr| right.is_none_or(|r| sr.right_axis == r))
            .flat_map(|sr| sr.points.iter().copied())
            .filter(|&(x, y)| usable(x, y, self.x_log))
    }
}

fn usable(x: f64, y: f64, x_log: bool) -> bool {
    x.is_finite() && y.is_finite() && (!x_log || x > 0.0)
}

/// An axis range in data units (log10 units for a log axis).
struct Range {
    lo: f64,
    hi: f64,
}

impl Range {
    fn of(values: impl Iterator<Item = f64>, log: bool) -> Self {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in values {
            let v = if log { v.log10() } else { v };
            lo = lo.min(v);
            hi = hi.max(v);
        }
        if !lo.is_finite() {
            return Self { lo: 0.0, hi: 1.0 };
        }
        if hi - lo <= f64::EPSILON * hi.abs().max(1.0) {
            let pad = if log { 0.5 } else { (lo.abs() * 0.1).max(1.0) };
            return Self {
                lo: lo - pad,
                hi: hi + pad,
            };
        }
        let pad = (hi - lo) * 0.04;
        Self {
            lo: lo - pad,
            hi: hi + pad,
        }
    }

    /// Position of `v` along the axis, 0 at `lo` and 1 at `hi`.
    fn frac(&self, v: f64, log: bool) -> f64 {
        let v = if log { v.log10() } else { v };
        (v - self.lo) / (self.hi - self.lo)
    }

    /// Tick values (in data units) and their labels: steps of 1, 2 or 5 x 10^k, about 5 to 10 ticks;
    /// decades on a log axis that spans at least two.
    fn ticks(&self, log: bool) -> Vec<(f64, String)> {
        if log && self.hi - self.lo >= 1.5 {
            let step = ((self.hi - self.lo) / 8.0).ceil().max(1.0);
            let mut k = (self.lo / step).ceil() * step;
            let mut out = Vec::new();
            while k <= self.hi + 1e-9 {
                let v = 10f64.powf(k);
                out.push((v, format_number(v, v)));
                k += step;
            }
            return out;
        }
        let (lo, hi) = if log {
            (10f64.powf(self.lo), 10f64.powf(self.hi))
        } else {
            (self.lo, self.hi)
        };
        let raw = (hi - lo) / 6.0;
        let mag = 10f64.powf(raw.log10().floor());
        let step = [1.0, 2.0, 5.0, 10.0]
            .iter()
            .map(|m| m * mag)
            .find(|st| *st >= raw)
            .unwrap_or(10.0 * mag);
        let mut out = Vec::new();
        let mut i = (lo / step).ceil();
        while i * step <= hi + step * 1e-9 && out.len() < 64 {
            // Snap tiny values to zero so "0" is printed, not "-1.1e-17".
            let v = if (i * step).abs() < step * 1e-9 {
                0.0
            } else {
                i * step
            };
            out.push((v, format_number(v, step)));
            i += 1.0;
        }
        out
    }

    /// 2..9 x 10^k inside a log range.
    fn minor_log_ticks(&self) -> Vec<f64> {
        let mut out = Vec::new();
        let mut k = self.lo.floor();
        while k <= self.hi && out.len() < 512 {
            for m in 2..10 {
                let v = f64::from(m) * 10f64.powf(k);
                let l = v.log10();
                if l >= self.lo && l <= self.hi {
                    out.push(v);
                }
            }
            k += 1.0;
        }
        out
    }
}

/// A tick label: as many decimals as `step` needs; scientific (`2.5e6`) for very large or small values.
fn format_number(v: f64, step: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e6).contains(&a) {
        let s = format!("{v:e}");
        // Trim long mantissas: 1.2345678e7 -> 1.23e7.
        return match s.split_once('e') {
            Some((m, e)) if m.len() > 5 => format!("{}e{e}", &m[..5].trim_end_matches('0')),
            _ => s,
        };
    }
    let decimals = usize::try_from(to_px(-step.abs().log10().floor()).clamp(0, 6)).unwrap_or(0);
    format!("{v:.decimals$}")
}

#[derive(Clone, Copy)]
struct Rect {
    x0: i32,
    y0: i32,
    x1: i32,
    y1: i32,
}

/// An RGB8 picture with the few drawing operations a plot needs.
struct Canvas {
    w: i32,
    h: i32,
    pixels: Vec<u8>,
}

impl Canvas {
    fn new(width: u32, height: u32) -> Self {
        Self {
            w: width as i32,
            h: height as i32,
            pixels: vec![255; width as usize * height as usize * 3],
        }
    }

    /// Blends `color` over pixel (x, y) with coverage `a` in [0, 1].
    fn blend(&mut self, x: i32, y: i32, color: [u8; 3], a: f64) {
        if x < 0 || y < 0 || x >= self.w || y >= self.h || a <= 0.0 {
            return;
        }
        let i = (y as usize * self.w as usize + x as usize) * 3;
        for (k, &c) in color.iter().enumerate() {
            let old = f64::from(self.pixels[i + k]);
            self.pixels[i + k] =
                u8::try_from(to_px(old + (f64::from(c) - old) * a.min(1.0)).clamp(0, 255))
                    .unwrap_or(255);
        }
    }

    fn fill(&mut self, x0: i32, y0: i32, x1: i32, y1: i32, color: [u8; 3]) {
        for y in y0..=y1 {
            for x in x0..=x1 {
                self.blend(x, y, color, 1.0);
            }
        }
    }

    fn hline(&mut self, x0: i32, x1: i32, y: i32, color: [u8; 3]) {
        self.fill(x0.min(x1), y, x0.max(x1), y, color);
    }

    fn vline(&mut self, x: i32, y0: i32, y1: i32, color: [u8; 3]) {
        self.fill(x, y0.min(y1), x, y0.max(y1), color);
    }

    /// An anti-aliased segment of width `thick` pixels, clipped to `clip`: coverage from the distance of
    /// each pixel centre to the segment.
    fn line(&mut self, a: (f64, f64), b: (f64, f64), thick: f64, color: [u8; 3], clip: &Rect) {
        let r = thick / 2.0;
        let x0 = to_px((a.0.min(b.0) - r - 1.0).floor().max(f64::from(clip.x0)));
        let x1 = to_px((a.0.max(b.0) + r + 1.0).ceil().min(f64::from(clip.x1)));
        let y0 = to_px((a.1.min(b.1) - r - 1.0).floor().max(f64::from(clip.y0)));
        let y1 = to_px((a.1.max(b.1) + r + 1.0).ceil().min(f64::from(clip.y1)));
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let len2 = dx * dx + dy * dy;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (fx, fy) = (f64::from(x), f64::from(y));
                let t = if len2 > 0.0 {
                    (((fx - a.0) * dx + (fy - a.1) * dy) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let (ex, ey) = (a.0 + t * dx - fx, a.1 + t * dy - fy);
                let d = (ex * ex + ey * ey).sqrt();
                self.blend(x, y, color, (r + 0.5 - d).clamp(0.0, 1.0));
            }
        }
    }

    /// Left-to-right text with its top-left corner at (x, y), each font pixel `s` x `s`.
    fn text(&mut self, text: &str, x: i32, y: i32, s: i32, color: [u8; 3]) {
        for (i, ch) in text.chars().enumerate() {
            let rows = glyph(ch);
            let gx = x + to_i32(i) * 6 * s;
            for (ry, bits) in rows.iter().enumerate() {
                for cx in 0..5 {
                    if bits & (0b10000 >> cx) != 0 {
                        let (px, py) = (gx + cx * s, y + to_i32(ry) * s);
                        self.fill(px, py, px + s - 1, py + s - 1, color);
                    }
                }
            }
        }
    }

    /// Bottom-to-top text (rotated 90 degrees anticlockwise) starting at (x, y_bottom).
    fn text_up(&mut self, text: &str, x: i32, y_bottom: i32, s: i32, color: [u8; 3]) {
        for (i, ch) in text.chars().enumerate() {
            let rows = glyph(ch);
            let gy = y_bottom - to_i32(i) * 6 * s;
            for (ry, bits) in rows.iter().enumerate() {
                for cx in 0..5 {
                    if bits & (0b10000 >> cx) != 0 {
                        // Glyph column -> up the page, glyph row -> right.
                        let (px, py) = (x + to_i32(ry) * s, gy - (cx + 1) * s);
                        self.fill(px, py, px + s - 1, py + s - 1, color);
                    }
                }
            }
        }
    }
}

/// Rounds a pixel coordinate to the nearest integer (saturating far off the canvas; NaN gives 0).
#[expect(
    clippy::cast_possible_truncation,
    reason = "pixel coordinates: `as` rounds toward zero after `round` and saturates, as wanted"
)]
fn to_px(v: f64) -> i32 {
    v.round() as i32
}

fn to_i32(n: usize) -> i32 {
    i32::try_from(n).unwrap_or(i32::MAX)
}

fn text_width(text: &str, s: i32) -> i32 {
    let n = to_i32(text.chars().count());
    if n == 0 {
        0
    } else {
        n * 6 * s - s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> LinePlot {
        let xs: Vec<f64> = (0..50).map(|i| 10f64.powf(f64::from(i) / 10.0)).collect();
        LinePlot {
            title: "Accuracy vs time (seed=1, p_95)".into(),
            x_label: "samples / frame".into(),
            y_label: "error [m]".into(),
            y2_label: "time (ms)".into(),
            x_log: true,
            series: vec![
                Series {
                    name: "Estimate".into(),
                    points: xs.iter().map(|&x| (x, 100.0 / (1.0 + x.sqrt()))).collect(),
                    color: [31, 119, 180],
                    right_axis: false,
                },
                Series {
                    name: "Conservative".into(),
                    points: xs
                        .iter()
                        .map(|&x| (x, 140.0 / (1.0 + x.sqrt()) + 2.0))
                        .collect(),
                    color: [214, 39, 40],
                    right_axis: false,
                },
                Series {
                    name: "cost".into(),
                    points: xs.iter().map(|&x| (x, 0.002 * x + 0.5)).collect(),
                    color: [44, 160, 44],
                    right_axis: true,
                },
            ],
        }
    }

    #[test]
    fn writes_a_decodable_non_blank_png() {
        let dir = std::env::temp_dir().join(format!("clipsat-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("plot.png");
        sample().write_png(&path, 800, 500).unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        let _ = std::fs::remove_dir_all(&dir);
        assert_eq!(img.dimensions(), (800, 500));
        let non_white = img.pixels().filter(|p| p.0 != [255, 255, 255]).count();
        assert!(non_white > 5_000, "only {non_white} drawn pixels");
        // Each series colour appears.
        for c in [[31, 119, 180], [214, 39, 40], [44, 160, 44]] {
            assert!(img.pixels().any(|p| p.0 == c), "colour {c:?} missing");
        }
    }

    #[test]
    fn deterministic_and_robust() {
        let a = sample().render(640, 400).unwrap().pixels;
        let b = sample().render(640, 400).unwrap().pixels;
        assert!(a == b);
        let empty = LinePlot::default();
        assert!(empty.render(300, 200).is_ok());
        let odd = LinePlot {
            series: vec![Series {
                name: "odd".into(),
                points: vec![
                    (f64::NAN, 1.0),
                    (1.0, f64::INFINITY),
                    (2.0, 2.0),
                    (2.0, 2.0),
                ],
                color: [0, 0, 0],
                right_axis: false,
            }],
            ..LinePlot::default()
        };
        assert!(odd.render(300, 200).is_ok());
        assert!(matches!(odd.render(10, 10), Err(Error::Invalid { .. })));
    }

    #[test]
    fn tick_labels() {
        assert_eq!(format_number(0.0, 1.0), "0");
        assert_eq!(format_number(2.5, 0.5), "2.5");
        assert_eq!(format_number(1500.0, 500.0), "1500");
        assert_eq!(format_number(2.0e7, 1.0e7), "2e7");
        let r = Range { lo: -0.3, hi: 10.2 };
        let t = r.ticks(false);
        assert_eq!(t.first().map(|t| t.1.as_str()), Some("0"));
        assert_eq!(t.last().map(|t| t.1.as_str()), Some("10"));
        for c in "0123456789.-+e%/():,_x=".chars() {
            assert!(
                font::FONT.iter().any(|(g, _)| *g == c),
                "glyph {c:?} missing"
            );
        }
    }
}
