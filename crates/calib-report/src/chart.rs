//! A small chart model (axes, series, shaded spans, reference lines) and its rendering with
//! plotters to SVG or PNG.
//!
//! Every coordinate passes [`Series::new`]'s guard: non-finite points are dropped (and, on a
//! logarithmic axis, non-positive values), so no rendered plot holds a NaN or an infinity.

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::ops::Range;

/// Why a figure could not be drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct PlotError(pub String);

impl std::fmt::Display for PlotError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "cannot draw a plot: {}", self.0)
    }
}

impl std::error::Error for PlotError {}

/// The colours of series, distinguishable in print and for the common colour blindnesses
/// (Okabe–Ito).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Colour {
    /// The calibrated result.
    Blue,
    /// A second sensor or a comparison.
    Orange,
    /// A truth or a reference.
    Green,
    /// Warnings: blind orders, limits.
    Red,
    /// Context: raw data, uncertainty.
    Grey,
    /// A third series.
    Purple,
}

impl Colour {
    fn rgb(self) -> RGBColor {
        match self {
            Colour::Blue => RGBColor(0, 114, 178),
            Colour::Orange => RGBColor(230, 159, 0),
            Colour::Green => RGBColor(0, 158, 115),
            Colour::Red => RGBColor(213, 94, 0),
            Colour::Grey => RGBColor(110, 110, 110),
            Colour::Purple => RGBColor(204, 121, 167),
        }
    }
}

/// How a series is drawn.
#[derive(Debug, Clone, PartialEq)]
pub enum Mark {
    /// A solid line through the points, in x order.
    Line,
    /// A dashed line.
    Dashed,
    /// A vertical bar from the axis's base to each point, this wide (in x units).
    Bars {
        /// Bar width, x units.
        width: f64,
    },
    /// A dot at each point.
    Dots,
    /// A cross at each point.
    Crosses,
    /// A filled band between the points (lower edge) and these upper points (same x).
    Band {
        /// The upper edge.
        upper: Vec<(f64, f64)>,
    },
}

/// One series of a chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// How it is drawn.
    pub mark: Mark,
    /// Its colour.
    pub colour: Colour,
    /// The points `(x, y)`, all finite.
    pub points: Vec<(f64, f64)>,
}

fn finite(points: impl IntoIterator<Item = (f64, f64)>) -> Vec<(f64, f64)> {
    points
        .into_iter()
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect()
}

impl Series {
    /// A series; points with a non-finite coordinate are dropped.
    pub fn new(
        name: &str,
        mark: Mark,
        colour: Colour,
        points: impl IntoIterator<Item = (f64, f64)>,
    ) -> Self {
        let mark = match mark {
            Mark::Band { upper } => Mark::Band {
                upper: finite(upper),
            },
            other => other,
        };
        Series {
            name: name.to_string(),
            mark,
            colour,
            points: finite(points),
        }
    }
    /// A band between `lower` and `upper` (same x values).
    pub fn band(
        name: &str,
        colour: Colour,
        lower: impl IntoIterator<Item = (f64, f64)>,
        upper: impl IntoIterator<Item = (f64, f64)>,
    ) -> Self {
        Series::new(
            name,
            Mark::Band {
                upper: upper.into_iter().collect(),
            },
            colour,
            lower,
        )
    }
    fn all_points(&self) -> impl Iterator<Item = &(f64, f64)> {
        let upper: &[(f64, f64)] = match &self.mark {
            Mark::Band { upper } => upper,
            _ => &[],
        };
        self.points.iter().chain(upper)
    }
}

/// A scale of an axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scale {
    /// Linear.
    Linear,
    /// Logarithmic (positive values only).
    Log,
}

/// An axis: its label (with the unit) and scale, and optionally a fixed range.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// Label, with the unit in parentheses, e.g. `angle (°)`.
    pub label: String,
    /// Scale.
    pub scale: Scale,
    /// Fixed range; from the data when `None`.
    pub range: Option<(f64, f64)>,
}

impl Axis {
    /// A linear axis fitted to the data.
    pub fn linear(label: &str) -> Self {
        Axis {
            label: label.to_string(),
            scale: Scale::Linear,
            range: None,
        }
    }
    /// A logarithmic axis fitted to the data.
    pub fn log(label: &str) -> Self {
        Axis {
            scale: Scale::Log,
            ..Axis::linear(label)
        }
    }
    /// This axis with a fixed range (ignored unless finite and increasing).
    pub fn with_range(mut self, lo: f64, hi: f64) -> Self {
        self.range = (lo.is_finite() && hi.is_finite() && lo < hi).then_some((lo, hi));
        self
    }
}

/// A shaded interval of x (e.g. a session), with a short label drawn at its top.
#[derive(Debug, Clone, PartialEq)]
pub struct Span {
    /// Start.
    pub from: f64,
    /// End.
    pub to: f64,
    /// Label.
    pub label: String,
}

/// A horizontal reference line across the chart (e.g. a limit), named in the legend.
#[derive(Debug, Clone, PartialEq)]
pub struct Level {
    /// Its y value.
    pub y: f64,
    /// Legend text.
    pub name: String,
    /// Its colour.
    pub colour: Colour,
}

/// One panel: two axes and what is drawn in them.
#[derive(Debug, Clone, PartialEq)]
pub struct Chart {
    /// The x axis.
    pub x: Axis,
    /// The y axis.
    pub y: Axis,
    /// Series, drawn in order (later ones on top).
    pub series: Vec<Series>,
    /// Shaded x intervals, drawn first.
    pub spans: Vec<Span>,
    /// Horizontal reference lines.
    pub levels: Vec<Level>,
    /// Height relative to the figure's other panels (1 by default): a panel that only
    /// qualifies another, as the uncertainty under a map, is drawn smaller.
    pub height: f64,
}

impl Chart {
    /// An empty chart on these axes.
    pub fn new(x: Axis, y: Axis) -> Self {
        Chart {
            x,
            y,
            series: Vec::new(),
            spans: Vec::new(),
            levels: Vec::new(),
            height: 1.0,
        }
    }
    /// This chart at `height` times the figure's panel height (builder style; ignored unless
    /// positive and finite).
    pub fn with_height(mut self, height: f64) -> Self {
        if height.is_finite() && height > 0.0 {
            self.height = height;
        }
        self
    }
    /// Adds a series (builder style).
    pub fn with(mut self, series: Series) -> Self {
        self.series.push(series);
        self
    }
    fn x_range(&self) -> Range<f64> {
        if let Some((lo, hi)) = self.x.range {
            return lo..hi;
        }
        let xs = self
            .series
            .iter()
            .flat_map(|s| s.all_points().map(|p| p.0))
            .chain(self.spans.iter().flat_map(|s| [s.from, s.to]));
        let (lo, hi) = extent(xs);
        let pad = self
            .series
            .iter()
            .filter_map(|s| match s.mark {
                Mark::Bars { width } => Some(width),
                _ => None,
            })
            .fold(0.0, f64::max);
        padded(lo - pad, hi + pad, Scale::Linear, 0.0)
    }
    fn y_range(&self) -> Range<f64> {
        if let Some((lo, hi)) = self.y.range {
            return lo..hi;
        }
        let log = self.y.scale == Scale::Log;
        let ys = self
            .series
            .iter()
            .flat_map(|s| s.all_points().map(|p| p.1))
            .chain(self.levels.iter().map(|l| l.y))
            .filter(|y| !log || *y > 0.0);
        let (mut lo, hi) = extent(ys);
        let bars = self
            .series
            .iter()
            .any(|s| matches!(s.mark, Mark::Bars { .. }));
        if bars && !log {
            lo = lo.min(0.0);
        }
        padded(lo, hi.max(lo), self.y.scale, 0.06)
    }
}

/// `(min, max)` of finite values; `(0, 0)` when there are none.
fn extent(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if lo <= hi { (lo, hi) } else { (0.0, 0.0) }
}

/// A non-empty range around `[lo, hi]`, with a margin of `pad` of its width.
fn padded(lo: f64, hi: f64, scale: Scale, pad: f64) -> Range<f64> {
    match scale {
        Scale::Log => {
            let (lo, hi) = if lo > 0.0 { (lo, hi) } else { (1e-3, 1.0) };
            let (lo, hi) = if hi > lo * 1.5 {
                (lo, hi)
            } else {
                (lo / 2.0, hi * 2.0)
            };
            let f = (hi / lo).powf(pad);
            lo / f..hi * f
        }
        Scale::Linear => {
            let w = hi - lo;
            if w > 0.0 {
                lo - pad * w..hi + pad * w
            } else {
                let half = if lo == 0.0 { 1.0 } else { lo.abs() * 0.1 };
                lo - half..hi + half
            }
        }
    }
}

/// A figure: a title and one or more panels stacked vertically.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// A short name, unique within a document: the HTML anchor and the file stem with `--plots`.
    pub id: String,
    /// Title drawn above the panels.
    pub title: String,
    /// What to look at, shown under the figure in HTML.
    pub caption: String,
    /// The panels, top to bottom.
    pub panels: Vec<Chart>,
    /// Width, pixels.
    pub width: u32,
    /// Height of each panel, pixels.
    pub panel_height: u32,
}

/// Default width of figures, pixels.
pub const WIDTH: u32 = 1000;
/// Default height of a panel, pixels.
pub const PANEL_HEIGHT: u32 = 360;
const TITLE_HEIGHT: u32 = 36;

impl Figure {
    /// A figure of one panel, at the default size.
    pub fn new(id: &str, title: &str, caption: &str, chart: Chart) -> Self {
        Figure::stacked(id, title, caption, vec![chart])
    }
    /// A figure of several panels, stacked.
    pub fn stacked(id: &str, title: &str, caption: &str, panels: Vec<Chart>) -> Self {
        Figure {
            id: id.to_string(),
            title: title.to_string(),
            caption: caption.to_string(),
            panels,
            width: WIDTH,
            panel_height: PANEL_HEIGHT,
        }
    }
    /// Heights of the panels, pixels, top to bottom (one panel's height when there are none).
    fn heights(&self) -> Vec<u32> {
        let h = f64::from(self.panel_height);
        match self.panels.is_empty() {
            true => vec![self.panel_height],
            false => self
                .panels
                .iter()
                .map(|c| (c.height * h).round() as u32)
                .collect(),
        }
    }
    /// Size in pixels.
    pub fn size(&self) -> (u32, u32) {
        (
            self.width,
            TITLE_HEIGHT + self.heights().iter().sum::<u32>(),
        )
    }
    /// The figure as a standalone SVG document.
    pub fn to_svg(&self) -> Result<String, PlotError> {
        crate::register_fonts()?;
        let mut out = String::new();
        {
            let root = SVGBackend::with_string(&mut out, self.size()).into_drawing_area();
            self.draw(&root).map_err(|e| PlotError(e.to_string()))?;
            root.present().map_err(|e| PlotError(e.to_string()))?;
        }
        Ok(out)
    }
    /// The figure as a PNG image.
    pub fn to_png(&self) -> Result<Vec<u8>, PlotError> {
        use image::ImageEncoder;
        crate::register_fonts()?;
        let (w, h) = self.size();
        let mut rgb = vec![0u8; w as usize * h as usize * 3];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
            self.draw(&root).map_err(|e| PlotError(e.to_string()))?;
            root.present().map_err(|e| PlotError(e.to_string()))?;
        }
        let mut png = Vec::new();
        image::codecs::png::PngEncoder::new(&mut png)
            .write_image(&rgb, w, h, image::ColorType::Rgb8)
            .map_err(|e| PlotError(e.to_string()))?;
        Ok(png)
    }

    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
        root.fill(&WHITE)?;
        let body = root.titled(&self.title, ("sans-serif", 22).into_font())?;
        let mut breaks = Vec::new();
        let mut top = 0;
        for h in self.heights() {
            top += h as i32;
            breaks.push(top);
        }
        breaks.pop();
        let panels = body.split_by_breakpoints::<i32, i32, _, _>([], breaks);
        for (chart, area) in self.panels.iter().zip(&panels) {
            let x = chart.x_range();
            let y = chart.y_range();
            match chart.y.scale {
                Scale::Linear => draw_panel(area, chart, x, y.clone(), y)?,
                Scale::Log => draw_panel(area, chart, x, y.clone().log_scale(), y)?,
            }
        }
        Ok(())
    }
}

/// How the ticks of one axis are written: all as plain decimals or all as powers of ten, so
/// that `1e-4` never stands beside `0.001` on one axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TickStyle {
    /// Few decimals, no trailing zeros.
    Plain,
    /// `2e-4`, `1e6`.
    Powers,
}

impl TickStyle {
    /// Plain where every tick of `range` can be written with at most four decimals and under
    /// 10⁵; on a logarithmic axis, where its smallest value is at least 10⁻³ too.
    fn of(range: &Range<f64>, scale: Scale) -> Self {
        let largest = range.start.abs().max(range.end.abs());
        let smallest = match scale {
            Scale::Log => range.start.min(range.end),
            Scale::Linear => largest,
        };
        if largest < 1e5 && smallest >= 1e-3 {
            TickStyle::Plain
        } else {
            TickStyle::Powers
        }
    }

    /// A tick label. A linear axis's zero tick comes out of the step arithmetic as ±1e-16 or so:
    /// below 1e-12 (far under any amplitude drawn, in arcseconds or degrees) a tick is zero.
    fn label(self, v: f64) -> String {
        if v.abs() < 1e-12 {
            return "0".into();
        }
        match self {
            TickStyle::Plain => calib_core::report::trimmed(v, 4),
            TickStyle::Powers => format!("{v:.0e}"),
        }
    }
}

fn draw_panel<DB, Y>(
    area: &DrawingArea<DB, Shift>,
    chart: &Chart,
    x: Range<f64>,
    y: Y,
    y_range: Range<f64>,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>>
where
    DB: DrawingBackend,
    Y: AsRangedCoord<Value = f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let entries: Vec<(&str, &Mark, Colour)> = chart
        .series
        .iter()
        .filter(|s| !s.name.is_empty())
        .map(|s| (s.name.as_str(), &s.mark, s.colour))
        .chain(
            chart
                .levels
                .iter()
                .filter(|l| (y_range.start..=y_range.end).contains(&l.y))
                .map(|l| (l.name.as_str(), &Mark::Dashed, l.colour)),
        )
        .collect();
    let (legend_area, plot_area) = if entries.is_empty() {
        (None, area.clone())
    } else {
        let (top, rest) = area.split_vertically(LEGEND_HEIGHT);
        (Some(top), rest)
    };
    if let Some(top) = legend_area {
        draw_legend(&top, &entries)?;
    }
    let area = &plot_area;
    let mut ctx = ChartBuilder::on(area)
        .margin(12)
        .margin_right(24)
        .x_label_area_size(46)
        .y_label_area_size(78)
        .build_cartesian_2d(x.clone(), y)?;
    let (x_ticks, y_ticks) = (
        TickStyle::of(&x, Scale::Linear),
        TickStyle::of(&y_range, chart.y.scale),
    );
    ctx.configure_mesh()
        .x_desc(&chart.x.label)
        .y_desc(&chart.y.label)
        .x_label_formatter(&|v| x_ticks.label(*v))
        .y_label_formatter(&|v| y_ticks.label(*v))
        .y_labels(((10.0 * chart.height).round() as usize).clamp(3, 10))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 16))
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(215, 215, 215))
        .draw()?;
    let (ylo, yhi) = (y_range.start, y_range.end);
    for span in &chart.spans {
        let (from, to) = (span.from.max(x.start), span.to.min(x.end));
        if from >= to {
            continue;
        }
        ctx.draw_series(std::iter::once(Rectangle::new(
            [(from, ylo), (to, yhi)],
            Colour::Blue.rgb().mix(0.10).filled(),
        )))?;
        ctx.draw_series(std::iter::once(Text::new(
            span.label.clone(),
            (from, yhi),
            ("sans-serif", 15).into_font().color(&RGBColor(0, 70, 120)),
        )))?;
    }
    for s in &chart.series {
        let c = s.colour.rgb();
        match &s.mark {
            Mark::Line => ctx.draw_series(LineSeries::new(s.points.clone(), c.stroke_width(2)))?,
            Mark::Dashed => ctx.draw_series(DashedLineSeries::new(
                s.points.clone(),
                8,
                5,
                c.stroke_width(2),
            ))?,
            Mark::Bars { width } => {
                // With a thousand orders on the axis a bar 0.8 orders wide is under a pixel and
                // the renderer drops it (`width="0"` in SVG): the largest harmonics vanished.
                // Every bar is drawn at least MIN_BAR_PX wide.
                let pixels = ctx.plotting_area().get_pixel_range().0;
                let per_pixel = (x.end - x.start) / f64::from((pixels.end - pixels.start).max(1));
                let width = width.max(MIN_BAR_PX * per_pixel);
                let base = if ylo > 0.0 {
                    ylo
                } else {
                    0.0f64.clamp(ylo, yhi)
                };
                ctx.draw_series(s.points.iter().map(|&(px, py)| {
                    Rectangle::new(
                        [
                            (px - width / 2.0, base),
                            (px + width / 2.0, py.clamp(ylo, yhi)),
                        ],
                        c.filled(),
                    )
                }))?
            }
            Mark::Dots => {
                ctx.draw_series(s.points.iter().map(|&p| Circle::new(p, 3, c.filled())))?
            }
            Mark::Crosses => ctx.draw_series(
                s.points
                    .iter()
                    .map(|&p| Cross::new(p, 5, c.stroke_width(2))),
            )?,
            Mark::Band { upper } => {
                let outline: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .chain(upper.iter().rev().copied())
                    .collect();
                ctx.draw_series(std::iter::once(Polygon::new(outline, c.mix(0.25).filled())))?
            }
        };
    }
    for level in &chart.levels {
        if !(ylo..=yhi).contains(&level.y) {
            continue;
        }
        ctx.draw_series(DashedLineSeries::new(
            [(x.start, level.y), (x.end, level.y)],
            8,
            5,
            level.colour.rgb().stroke_width(2),
        ))?;
    }
    Ok(())
}

/// The narrowest bar drawn, pixels: a bar below a pixel wide is not drawn at all.
const MIN_BAR_PX: f64 = 2.0;

/// Height of the legend row above a panel, pixels.
const LEGEND_HEIGHT: u32 = 26;

/// The legend as one row of entries above the plot, where it never hides data.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(&str, &Mark, Colour)],
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let font = ("sans-serif", 14).into_font();
    let style = TextStyle::from(font.clone()).pos(Pos::new(HPos::Left, VPos::Center));
    let y = LEGEND_HEIGHT as i32 / 2 + 2;
    let mut x = 90;
    for (name, mark, colour) in entries {
        let c = colour.rgb();
        match mark {
            Mark::Line => area.draw(&PathElement::new([(x, y), (x + 22, y)], c.stroke_width(2)))?,
            Mark::Dashed => {
                area.draw(&PathElement::new([(x, y), (x + 8, y)], c.stroke_width(2)))?;
                area.draw(&PathElement::new(
                    [(x + 13, y), (x + 22, y)],
                    c.stroke_width(2),
                ))?;
            }
            Mark::Bars { .. } => area.draw(&Rectangle::new(
                [(x + 4, y - 6), (x + 18, y + 6)],
                c.filled(),
            ))?,
            Mark::Band { .. } => area.draw(&Rectangle::new(
                [(x, y - 6), (x + 22, y + 6)],
                c.mix(0.25).filled(),
            ))?,
            Mark::Dots => area.draw(&Circle::new((x + 11, y), 4, c.filled()))?,
            Mark::Crosses => area.draw(&Cross::new((x + 11, y), 5, c.stroke_width(2)))?,
        }
        area.draw(&Text::new(name.to_string(), (x + 28, y), style.clone()))?;
        let (w, _) = area.estimate_text_size(name, &style)?;
        x += 28 + w as i32 + 24;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_finite_points_never_reach_a_plot() {
        let s = Series::new(
            "x",
            Mark::Line,
            Colour::Blue,
            [
                (0.0, 1.0),
                (f64::NAN, 2.0),
                (1.0, f64::INFINITY),
                (2.0, 3.0),
            ],
        );
        assert_eq!(s.points, vec![(0.0, 1.0), (2.0, 3.0)]);
    }

    #[test]
    fn ranges_are_never_empty() {
        let empty = Chart::new(Axis::linear("x"), Axis::log("y"));
        let (x, y) = (empty.x_range(), empty.y_range());
        assert!(x.start < x.end && y.start < y.end && y.start > 0.0);
        let flat = Chart::new(Axis::linear("x"), Axis::linear("y")).with(Series::new(
            "",
            Mark::Line,
            Colour::Blue,
            [(1.0, 5.0), (1.0, 5.0)],
        ));
        let (x, y) = (flat.x_range(), flat.y_range());
        assert!(x.start < 1.0 && x.end > 1.0 && y.start < 5.0 && y.end > 5.0);
    }

    #[test]
    fn bars_of_a_thousand_orders_all_have_a_width() {
        let amps = (1..=1000).map(|h| (h as f64, 1.0 + h as f64 / 100.0));
        let chart = Chart::new(
            Axis::linear("order").with_range(0.0, 1001.0),
            Axis::log("amplitude").with_range(0.5, 20.0),
        )
        .with(Series::new(
            "a",
            Mark::Bars { width: 0.4 },
            Colour::Blue,
            amps,
        ));
        let svg = Figure::new("spectrum", "spectrum", "", chart)
            .to_svg()
            .expect("renders");
        let bars = svg.matches("<rect").count();
        assert!(bars >= 1000, "{bars} rectangles for 1000 bars");
        assert!(
            !svg.contains("width=\"0\""),
            "a bar of zero width was drawn"
        );
    }

    #[test]
    fn ticks_are_short() {
        let plain = TickStyle::of(&(-25.0..120.0), Scale::Linear);
        assert_eq!(plain.label(0.5), "0.5");
        assert_eq!(plain.label(120.0), "120");
        assert_eq!(plain.label(-2.2e-16), "0");
        let tiny = TickStyle::of(&(-2e-5..2e-5), Scale::Linear);
        assert_eq!(tiny.label(-0.00001), "-1e-5");
        assert_eq!(tiny.label(0.0), "0");
    }

    /// A log axis from 10⁻⁴ to 10 wrote `1e-4` beside `0.001` and `10`: one style per axis.
    #[test]
    fn one_axis_has_one_tick_style() {
        let log = TickStyle::of(&(1e-4..10.0), Scale::Log);
        let labels: Vec<String> = [1e-4, 1e-3, 1.0, 10.0].map(|v| log.label(v)).to_vec();
        assert_eq!(labels, ["1e-4", "1e-3", "1e0", "1e1"]);
        let plain = TickStyle::of(&(1e-3..10.0), Scale::Log);
        assert_eq!(plain.label(1e-3), "0.001");
    }

    #[test]
    fn a_small_panel_is_drawn_smaller() {
        let chart = || Chart::new(Axis::linear("x"), Axis::linear("y"));
        let f = Figure::stacked("f", "f", "", vec![chart(), chart().with_height(0.5)]);
        assert_eq!(f.size().1, TITLE_HEIGHT + PANEL_HEIGHT * 3 / 2);
        assert!(f.to_svg().is_ok());
    }
}
