//! Application (plots): line plots of measurements written as PNG (fly-through statistics, accuracy against
//! time), drawn with plotters. Text is Hack (a DejaVu-derived face) from `epaint_default_fonts` (egui's
//! built-in fonts) through plotters' ab_glyph backend: no system font is needed and no font file lives in
//! the repository. Hack rather than egui's Ubuntu Light: plotters 0.3.7's ab_glyph path drops each glyph's
//! left side bearing, which crowds a proportional face (`l` into its neighbours) but barely shows on a
//! monospaced one.

use std::path::Path;
use std::sync::OnceLock;

use clipsat::{Error, Result};
use plotters::prelude::*;
use plotters::style::FontStyle;

mod axis;
use axis::{usable, Axis, Range};

/// The family name the embedded font is registered under.
const FONT: &str = "clipsat-sans";

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

/// Registers the embedded font with plotters once; every later call answers the first one's result.
fn font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, epaint_default_fonts::HACK_REGULAR)
            .is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(Error::Invalid {
            what: "plot font".into(),
            reason: "the embedded Hack font does not parse".into(),
        })
    }
}

/// A plotters drawing error as a clipsat error (only font trouble can cause one on an in-memory bitmap).
fn drawing<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> Error {
    Error::Invalid {
        what: "plot".into(),
        reason: e.to_string(),
    }
}

/// Text sizes in pixels for a picture: labels, axis titles and the title grow with the picture.
struct Sizes {
    label: f64,
    desc: f64,
    title: f64,
}

impl Sizes {
    fn of(width: u32, height: u32) -> Self {
        // Not below 15 px: smaller, the glyph placement of plotters' ab_glyph path gets uneven.
        let label = (f64::from(width.min(height)) / 32.0).clamp(15.0, 48.0);
        Self {
            label,
            desc: label * 1.05,
            title: label * 1.3,
        }
    }
}

impl LinePlot {
    /// Renders the plot at `width` x `height` pixels and writes it as PNG to `path`.
    ///
    /// White background, grid, ticks with numeric labels, title, axis labels, legend (in the corner of
    /// the axes that hides the fewest points), optional log X (decades, with 2..9 as light grid lines) and a
    /// right-hand axis for series with `right_axis`. Non-finite points (and X <= 0 on a log axis) are
    /// skipped and break the line. The picture depends only on the plot, not on the machine.
    pub(crate) fn write_png(&self, path: &Path, width: u32, height: u32) -> Result<()> {
        let pixels = self.render(width, height)?;
        let img = image::RgbImage::from_raw(width, height, pixels)
            .ok_or_else(|| Error::format(path, "plot buffer has the wrong size"))?;
        img.save_with_format(path, image::ImageFormat::Png)
            .map_err(|e| Error::io(path, "cannot write plot", std::io::Error::other(e)))
    }

    /// Renders the plot into an RGB8 buffer, `width` x `height`.
    fn render(&self, width: u32, height: u32) -> Result<Vec<u8>> {
        if !(160..=16384).contains(&width) || !(120..=16384).contains(&height) {
            return Err(Error::Invalid {
                what: "plot size".into(),
                reason: format!("{width} x {height} pixels: need 160..=16384 x 120..=16384"),
            });
        }
        font()?;
        let sizes = Sizes::of(width, height);
        // At most 16384^2 x 3 bytes: fits a usize on every 64-bit target.
        let mut pixels = vec![255u8; width as usize * height as usize * 3];
        // Drawn twice when there is a legend: first without, to learn where the axes fall and so which
        // corner of them it would hide the least of, then with it there.
        let layout = self.paint(&mut pixels, width, height, &sizes, None)?;
        if let Some(corner) = layout.quietest_corner(self) {
            pixels.fill(255);
            self.paint(&mut pixels, width, height, &sizes, Some(corner))?;
        }
        Ok(pixels)
    }

    /// Paints the plot into `pixels` (RGB8, `width` x `height`), with the legend at `legend` if given.
    fn paint(
        &self,
        pixels: &mut [u8],
        width: u32,
        height: u32,
        sizes: &Sizes,
        legend: Option<SeriesLabelPosition>,
    ) -> Result<Layout> {
        let backend = BitMapBackend::<plotters::backend::RGBPixel>::with_buffer_and_format(
            pixels,
            (width, height),
        )
        .map_err(|e| Error::Invalid {
            what: "plot".into(),
            reason: e.to_string(),
        })?;
        let root = backend.into_drawing_area();
        let layout = self
            .draw(&root, sizes, legend)
            .and_then(|layout| root.present().map(|()| layout))
            .map_err(drawing)?;
        Ok(layout)
    }

    /// Draws the whole plot onto `root`, the legend at `legend` if given; returns where the axes and the
    /// legend's box (if any series is named) fall.
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, plotters::coord::Shift>,
        sizes: &Sizes,
        legend: Option<SeriesLabelPosition>,
    ) -> Result<Layout, DrawingAreaErrorKind<DB::ErrorType>> {
        let ink = RGBColor(40, 40, 40);
        let label_style = TextStyle::from((FONT, sizes.label).into_font()).color(&ink);
        let desc_style = TextStyle::from((FONT, sizes.desc).into_font()).color(&ink);
        let has_right = self.series.iter().any(|sr| sr.right_axis);

        let xr = Range::of(self.points(None).map(|p| p.0), self.x_log);
        let yl = Range::of(self.points(Some(false)).map(|p| p.1), false);
        let yr = Range::of(self.points(Some(true)).map(|p| p.1), false);
        let xt = xr.ticks(self.x_log);
        let ylt = yl.ticks(false);
        let yrt = yr.ticks(false);
        let x_axis = Axis::new(&xr, &xt, self.x_log);

        // Label areas sized from the widest tick label: the axis title, a gap, the labels, the tick marks.
        let widest = |ticks: &[(f64, String)]| {
            ticks
                .iter()
                .filter_map(|(_, t)| root.estimate_text_size(t, &label_style).ok())
                .map(|(w, _)| w)
                .max()
                .unwrap_or(0)
        };
        let pad = to_u32(sizes.label * 0.5);
        let y_area = |ticks: &[(f64, String)]| widest(ticks) + to_u32(sizes.desc * 1.2) + 2 * pad;
        let x_area = to_u32(sizes.label * 1.2 + sizes.desc * 1.2) + 2 * pad;

        let mut builder = ChartBuilder::on(root);
        builder
            .margin_top(to_u32(sizes.label))
            .margin_left(pad)
            .margin_bottom(pad)
            .margin_right(if has_right {
                pad
            } else {
                to_u32(sizes.label * 2.0)
            })
            .x_label_area_size(x_area)
            .y_label_area_size(y_area(&ylt))
            .right_y_label_area_size(if has_right { y_area(&yrt) } else { 0 });
        if !self.title.is_empty() {
            builder.caption(
                &self.title,
                TextStyle::from((FONT, sizes.title).into_font()).color(&BLACK),
            );
        }
        let mut chart = builder
            .build_cartesian_2d(x_axis.clone(), Axis::new(&yl, &ylt, false))?
            .set_secondary_coord(x_axis, Axis::new(&yr, &yrt, false));

        let grid = RGBColor(222, 222, 222);
        let minor = RGBColor(240, 240, 240);
        chart
            .configure_mesh()
            .x_desc(self.x_label.as_str())
            .y_desc(self.y_label.as_str())
            .label_style(label_style.clone())
            .axis_desc_style(desc_style.clone())
            .bold_line_style(grid)
            .light_line_style(minor)
            .axis_style(ink)
            .set_all_tick_mark_size(to_u32(sizes.label * 0.3).max(3))
            .draw()?;
        if has_right {
            chart
                .configure_secondary_axes()
                .y_desc(self.y2_label.as_str())
                .label_style(label_style.clone())
                .axis_desc_style(desc_style)
                .axis_style(ink)
                .draw()?;
        }

        // Each run of usable points is one polyline; a lone point is a dot.
        // Not thinner than 3 px from 600 px up: plotters fills a thick line as a polygon, and a near-vertical
        // one loses a pixel of its width.
        let stroke = (sizes.label / 6.0).round().clamp(2.0, 8.0);
        let stroke_px = to_u32(stroke);
        for sr in &self.series {
            let colour = RGBColor(sr.color[0], sr.color[1], sr.color[2]);
            let style = colour.stroke_width(stroke_px);
            let runs = self.runs(sr);
            let mut labelled = sr.name.is_empty();
            for run in runs {
                let anno = match (run.len(), sr.right_axis) {
                    (1, false) => chart.draw_series(dot(run[0], stroke_px, colour))?,
                    (1, true) => chart.draw_secondary_series(dot(run[0], stroke_px, colour))?,
                    (_, false) => {
                        chart.draw_series(joints(&run, stroke_px, colour))?;
                        chart.draw_series(segments(&run, style))?
                    }
                    (_, true) => {
                        chart.draw_secondary_series(joints(&run, stroke_px, colour))?;
                        chart.draw_secondary_series(segments(&run, style))?
                    }
                };
                if !labelled {
                    labelled = true;
                    let tag = if sr.right_axis { " (right)" } else { "" };
                    let swatch = to_i32(sizes.label * 1.6);
                    anno.label(format!("{}{tag}", sr.name))
                        .legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + swatch, y)], style)
                        });
                }
            }
        }

        // The legend's box, estimated as plotters lays it out: swatch area, then the widest name; one row
        // of text and spacing per entry.
        let names: Vec<String> = self
            .series
            .iter()
            .filter(|sr| !sr.name.is_empty())
            .map(|sr| format!("{}{}", sr.name, if sr.right_axis { " (right)" } else { "" }))
            .collect();
        let margin = to_u32(sizes.label * 0.8);
        let swatch_area = to_u32(sizes.label * 2.0);
        let (text_w, text_h) = names
            .iter()
            .filter_map(|n| root.estimate_text_size(n, &label_style).ok())
            .fold((0, 0), |(w, h), (tw, th)| (w.max(tw), h.max(th)));
        let legend_box = (!names.is_empty()).then(|| {
            let rows = u32::try_from(names.len()).unwrap_or(u32::MAX);
            (
                swatch_area + text_w + to_u32(sizes.label),
                rows.saturating_mul(text_h + to_u32(sizes.label * 0.4)) + to_u32(sizes.label * 0.6),
            )
        });
        if let Some(position) = legend {
            chart
                .configure_series_labels()
                .position(position)
                .margin(margin)
                .legend_area_size(swatch_area)
                .label_font(label_style)
                .background_style(WHITE.mix(0.8))
                .border_style(RGBColor(160, 160, 160))
                .draw()?;
        }
        let (xs, ys) = chart.plotting_area().get_pixel_range();
        Ok(Layout {
            axes: (xs, ys),
            units: [(xr.lo, xr.hi), (yl.lo, yl.hi), (yr.lo, yr.hi)],
            legend: legend_box,
            margin: to_i32(f64::from(margin)),
        })
    }

    /// The usable points of `sr` in plot units, split into runs at unusable ones.
    fn runs(&self, sr: &Series) -> Vec<Vec<(f64, f64)>> {
        let mut runs = Vec::new();
        let mut run = Vec::new();
        for &(x, y) in &sr.points {
            if usable(x, y, self.x_log) {
                run.push((if self.x_log { x.log10() } else { x }, y));
            } else if !run.is_empty() {
                runs.push(std::mem::take(&mut run));
            }
        }
        if !run.is_empty() {
            runs.push(run);
        }
        runs
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

/// Where a drawn plot's axes and legend fall, in pixels.
struct Layout {
    /// The plotting area: x and y pixel ranges.
    axes: (std::ops::Range<i32>, std::ops::Range<i32>),
    /// The axes' ranges in plot units: x, left y, right y.
    units: [(f64, f64); 3],
    /// The legend box's size, if any series is named.
    legend: Option<(u32, u32)>,
    /// The legend's distance from the corner of the axes.
    margin: i32,
}

impl Layout {
    /// The corner of the axes where the legend box hides the least of `plot`'s lines: the fewest points
    /// inside the box plus segments crossing it (the badness matplotlib's `loc="best"` counts). Ties go to
    /// the first of upper left, upper right, lower left, lower right. `None` without a legend.
    fn quietest_corner(&self, plot: &LinePlot) -> Option<SeriesLabelPosition> {
        let (bw, bh) = self.legend?;
        let (bw, bh) = (f64::from(bw), f64::from(bh));
        let (xs, ys) = &self.axes;
        let (x0, x1) = (f64::from(xs.start), f64::from(xs.end));
        let (y0, y1) = (f64::from(ys.start), f64::from(ys.end));
        let m = f64::from(self.margin);
        let (left, right) = (x0 + m, x1 - m - bw);
        let (top, bottom) = (y0 + m, y1 - m - bh);
        let corners = [
            (SeriesLabelPosition::UpperLeft, left, top),
            (SeriesLabelPosition::UpperRight, right, top),
            (SeriesLabelPosition::LowerLeft, left, bottom),
            (SeriesLabelPosition::LowerRight, right, bottom),
        ];
        let along = |v: f64, (lo, hi): (f64, f64)| (v - lo) / (hi - lo);
        // Every run of every series in pixels.
        let runs: Vec<Vec<(f64, f64)>> = plot
            .series
            .iter()
            .flat_map(|sr| {
                let y_units = self.units[if sr.right_axis { 2 } else { 1 }];
                plot.runs(sr).into_iter().map(move |run| {
                    run.into_iter()
                        .map(|(x, y)| {
                            (
                                x0 + along(x, self.units[0]) * (x1 - x0),
                                y1 - along(y, y_units) * (y1 - y0),
                            )
                        })
                        .collect()
                })
            })
            .collect();
        let badness = |&(_, bx, by): &(SeriesLabelPosition, f64, f64)| {
            let rect = (bx, by, bx + bw, by + bh);
            let inside =
                |p: (f64, f64)| p.0 >= rect.0 && p.0 <= rect.2 && p.1 >= rect.1 && p.1 <= rect.3;
            runs.iter()
                .map(|run| {
                    run.iter().filter(|&&p| inside(p)).count()
                        + run
                            .windows(2)
                            .filter(|w| segment_hits(w[0], w[1], rect))
                            .count()
                })
                .sum::<usize>()
        };
        let mut best: Option<(SeriesLabelPosition, usize)> = None;
        for c in &corners {
            let n = badness(c);
            if best.as_ref().is_none_or(|&(_, fewest)| n < fewest) {
                best = Some((c.0.clone(), n));
            }
        }
        best.map(|(position, _)| position)
    }
}

/// Whether the segment a-b meets the rectangle (x0, y0, x1, y1): Liang-Barsky clipping.
fn segment_hits(a: (f64, f64), b: (f64, f64), (x0, y0, x1, y1): (f64, f64, f64, f64)) -> bool {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-dx, a.0 - x0),
        (dx, x1 - a.0),
        (-dy, a.1 - y0),
        (dy, y1 - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return false;
            }
        } else {
            let t = q / p;
            if p < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
        }
    }
    t0 <= t1
}

/// A polyline as separate two-point paths. plotters mitres the joins of a thick `LineSeries`, and a line
/// that turns back on itself (a patch-count series whose time is not monotone) shoots a mitre spike far
/// past its points, out of the axes; [`joints`] rounds the joins instead.
fn segments(
    run: &[(f64, f64)],
    style: ShapeStyle,
) -> impl Iterator<Item = PathElement<(f64, f64)>> + '_ {
    run.windows(2)
        .map(move |w| PathElement::new(vec![w[0], w[1]], style))
}

/// Round joins for [`segments`]: a filled dot of the line's width at each inner point.
fn joints(
    run: &[(f64, f64)],
    stroke: u32,
    colour: RGBColor,
) -> impl Iterator<Item = Circle<(f64, f64), u32>> + '_ {
    let inner = &run[1..run.len().saturating_sub(1).max(1)];
    inner
        .iter()
        .map(move |&p| Circle::new(p, stroke.div_ceil(2), colour.filled()))
}

/// A lone point: a filled dot a little wider than the lines.
fn dot(p: (f64, f64), stroke: u32, colour: RGBColor) -> std::iter::Once<Circle<(f64, f64), u32>> {
    std::iter::once(Circle::new(p, stroke + 1, colour.filled()))
}

/// Rounds a pixel measure to the nearest integer (saturating; NaN gives 0).
#[expect(
    clippy::cast_possible_truncation,
    reason = "pixel measures: `as` saturates after `round`, as wanted"
)]
pub(super) fn to_i32(v: f64) -> i32 {
    v.round() as i32
}

/// Rounds a non-negative pixel measure to the nearest integer (saturating; negative and NaN give 0).
fn to_u32(v: f64) -> u32 {
    u32::try_from(to_i32(v).max(0)).unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::axis::format_number;
    use super::*;
    use plotters::coord::ranged1d::BoldPoints;
    use plotters::coord::ranged1d::ValueFormatter;

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
    fn writes_a_decodable_png_with_lines_and_text() {
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
        // The title is drawn: dark, anti-aliased text in the top band.
        let (mut dark, mut grey) = (0, 0);
        for y in 0..40 {
            for x in 0..800 {
                let v = img.get_pixel(x, y).0[0];
                dark += usize::from(v < 80);
                grey += usize::from((80..240).contains(&v));
            }
        }
        assert!(
            dark > 200 && grey > 100,
            "title: {dark} dark, {grey} grey pixels"
        );
    }

    /// A line that turns back on itself (as a patch-count series whose time is not monotone) stays within
    /// its points: no mitre spike out of the axes.
    #[test]
    fn a_line_that_turns_back_stays_within_its_points() {
        let red = [214, 39, 40];
        let plot = LinePlot {
            series: vec![
                Series {
                    name: "back".into(),
                    points: vec![(5.05, 0.0503), (4.44, 0.0504), (4.88, 0.0504)],
                    color: red,
                    right_axis: false,
                },
                Series {
                    name: "other".into(),
                    points: vec![(1.15, 0.0265), (1.47, 0.0265)],
                    color: [31, 119, 180],
                    right_axis: false,
                },
            ],
            ..LinePlot::default()
        };
        let (w, h) = (960, 600);
        font().expect("font");
        let sizes = Sizes::of(w, h);
        let mut pixels = vec![255u8; w as usize * h as usize * 3];
        let layout = plot.paint(&mut pixels, w, h, &sizes, None).expect("paint");
        let right = usize::try_from(layout.axes.0.end).expect("axes inside the image");
        let outside = pixels
            .chunks_exact(3)
            .enumerate()
            .filter(|(i, p)| i % w as usize > right && *p == red)
            .count();
        assert_eq!(outside, 0, "{outside} line pixels right of the axes");
    }

    #[test]
    fn deterministic_and_robust() {
        let a = sample().render(640, 400).unwrap();
        let b = sample().render(640, 400).unwrap();
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
                    (f64::NAN, 0.0),
                    (3.0, 1.0),
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
        let log = |lo: f64, hi: f64| {
            Range {
                lo: f64::log10(lo),
                hi: f64::log10(hi),
            }
            .ticks(true)
            .into_iter()
            .map(|t| t.1)
            .collect::<Vec<_>>()
        };
        assert_eq!(log(0.45, 9.0), ["0.5", "1", "2", "5"]);
        assert_eq!(log(2.3, 10.5), ["3", "4", "5", "6", "8", "10"]);
        assert_eq!(log(1.0, 1e4), ["1", "10", "100", "1000", "10000"]);
        assert_eq!(log(0.3, 15.0), ["0.5", "1", "2", "5", "10"]);
        let axis = Axis::new(&r, &t, false);
        assert_eq!(axis.format_ext(&10.0), "10");
        assert_eq!(axis.key_points(BoldPoints(8)).len(), t.len());
    }

    #[test]
    fn segments_meet_rectangles() {
        let r = (0.0, 0.0, 10.0, 10.0);
        assert!(segment_hits((-5.0, 5.0), (15.0, 5.0), r));
        assert!(segment_hits((2.0, 2.0), (3.0, 3.0), r));
        assert!(!segment_hits((-5.0, -5.0), (-1.0, 20.0), r));
        assert!(!segment_hits((11.0, 0.0), (20.0, 10.0), r));
        assert!(segment_hits((-1.0, 5.0), (5.0, -1.0), r));
    }

    #[test]
    fn legend_takes_the_quietest_corner() {
        // Two nearly equal series along the top, one along the bottom (the shape of `bench shading`).
        let line = |name: &str, y0: f64, color| Series {
            name: name.into(),
            points: (0..5)
                .map(|i| (5.0 + 8.0 * f64::from(i), y0 + 0.001 * f64::from(i).sqrt()))
                .collect(),
            color,
            right_axis: false,
        };
        let plot = LinePlot {
            series: vec![
                line("diffuse", 0.031, [31, 119, 180]),
                line("+visibility", 0.053, [255, 127, 14]),
                line("+specular", 0.0528, [44, 160, 44]),
            ],
            ..LinePlot::default()
        };
        font().unwrap();
        let mut pixels = vec![255u8; 960 * 600 * 3];
        let layout = plot
            .paint(&mut pixels, 960, 600, &Sizes::of(960, 600), None)
            .unwrap();
        let corner = layout.quietest_corner(&plot);
        assert!(
            matches!(
                corner,
                Some(SeriesLabelPosition::LowerLeft | SeriesLabelPosition::LowerRight)
            ),
            "{:?}",
            corner.map(|c| format!("{c:?}"))
        );
    }
}
