//! Plot builders for calibration reports: each returns a [`Figure`] with labelled axes (units
//! included) from calibration results, so that a method adds its plots in a few lines.
//!
//! Angles are in degrees and errors in arcseconds on every axis, as in the tables.

use crate::chart::{Axis, Chart, Colour, Figure, Level, Mark, Series, Span};
use crate::trace::Trace;
use calib_core::ErrorMap;
use calib_core::angle::ARCSEC_PER_RAD;

/// Most points drawn per line; longer lines are reduced to the minimum and maximum of buckets,
/// which keeps every peak.
pub const MAX_LINE_POINTS: usize = 2400;

/// `points` (sorted by x) reduced to at most [`MAX_LINE_POINTS`]: each of `MAX/2` buckets of
/// consecutive points becomes its minimum and its maximum, in x order.
pub fn decimate(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    if points.len() <= MAX_LINE_POINTS {
        return points.to_vec();
    }
    let buckets = MAX_LINE_POINTS / 2;
    let mut out = Vec::with_capacity(MAX_LINE_POINTS);
    for k in 0..buckets {
        let chunk = &points[k * points.len() / buckets..(k + 1) * points.len() / buckets];
        let lo = chunk.iter().copied().min_by(|a, b| a.1.total_cmp(&b.1));
        let hi = chunk.iter().copied().max_by(|a, b| a.1.total_cmp(&b.1));
        if let (Some(lo), Some(hi)) = (lo, hi) {
            if lo.0 <= hi.0 {
                out.extend([lo, hi]);
            } else {
                out.extend([hi, lo]);
            }
        }
    }
    out
}

/// A map as points `(angle °, error ″)`.
pub fn map_points(map: &ErrorMap) -> Vec<(f64, f64)> {
    (0..map.len())
        .map(|i| {
            (
                map.grid_angle(i).to_degrees(),
                map.values()[i] * ARCSEC_PER_RAD,
            )
        })
        .collect()
}

/// What an error-map figure shows: the calibrated map and, optionally, what to compare it with
/// and the map's expanded uncertainty.
#[derive(Debug, Clone, PartialEq)]
pub struct MapLayers {
    /// The calibrated map, `(angle °, error ″)` sorted by angle.
    pub map: Vec<(f64, f64)>,
    /// A truth or a reference measurement of the same error, `(angle °, error ″)`, and its name;
    /// its difference to the map (the residual after correction) gets a panel of its own.
    pub comparison: Option<(String, Vec<(f64, f64)>)>,
    /// Whether the comparison is raw samples (a reference read at every sample), drawn as
    /// their mean and spread per bin of angle rather than through every point.
    pub samples: bool,
    /// The expanded uncertainty `(angle °, U ″)` of the map, and its name: a band around zero
    /// on the residual panel, where a residual is read against it, and a small panel of its own.
    pub band: Option<(String, Vec<(f64, f64)>)>,
}

/// The name of a map's expanded uncertainty in every method's figures, for coverage factor `k`
/// (and how it was found, e.g. `2.160, budget`): the legend of its own panel, and after `± ` of
/// the band around zero on a residual panel ([`band_legend`]).
pub fn band_name(k: &str) -> String {
    format!("expanded uncertainty U (k = {k})")
}

/// The legend of the band `±U` around zero, from the name of `U`.
pub fn band_legend(name: &str) -> String {
    format!("± {name}")
}

impl MapLayers {
    /// The layers of a map alone.
    pub fn of(map: &ErrorMap) -> Self {
        MapLayers::of_points(map_points(map))
    }
    /// The layers of a map given as points.
    pub fn of_points(map: Vec<(f64, f64)>) -> Self {
        MapLayers {
            map,
            comparison: None,
            samples: false,
            band: None,
        }
    }
    /// With a truth or reference map (builder style).
    pub fn compared_with(mut self, name: &str, points: Vec<(f64, f64)>) -> Self {
        self.comparison = Some((name.to_string(), points));
        self.samples = false;
        self
    }
    /// With a reference's readings at every sample (builder style): drawn binned over angle.
    pub fn compared_with_samples(mut self, name: &str, points: Vec<(f64, f64)>) -> Self {
        self.comparison = Some((name.to_string(), points));
        self.samples = true;
        self
    }
    /// With the expanded uncertainty `(angle °, U ″)` (builder style).
    pub fn with_band(mut self, name: &str, half_widths: Vec<(f64, f64)>) -> Self {
        self.band = Some((name.to_string(), half_widths));
        self
    }
    /// The comparison minus the map at each comparison point (the map interpolated linearly,
    /// periodically over 360°): what is left after correcting by the map.
    pub fn residual(&self) -> Option<Vec<(f64, f64)>> {
        let (_, cmp) = self.comparison.as_ref()?;
        Some(
            cmp.iter()
                .filter_map(|&(x, y)| interpolate(&self.map, x).map(|m| (x, y - m)))
                .collect(),
        )
    }
    /// The map, with the comparison drawn on top of it (dashed, so the map shows through).
    fn chart(&self, channel: &str, span: Option<(f64, f64)>) -> Chart {
        let inside = |p: &&(f64, f64)| span.is_none_or(|(lo, hi)| p.0 >= lo && p.0 <= hi);
        let pick =
            |v: &[(f64, f64)]| decimate(&v.iter().filter(inside).copied().collect::<Vec<_>>());
        let mut chart = Chart::new(angle_axis(channel, span), Axis::linear("error (″)")).with(
            Series::new("calibrated map", Mark::Line, Colour::Blue, pick(&self.map)),
        );
        if let Some((name, cmp)) = &self.comparison {
            // A bin's mean of the samples themselves would flatten (or alias) the orders whose
            // period is near the bin's width: the map plus the residual's bin means,
            // interpolated at every map point, keeps them.
            let (name, points) = match (self.samples, self.residual()) {
                (true, Some(res)) => {
                    let (bins, width) = binned(&res);
                    let means: Vec<(f64, f64)> = bins.iter().map(|b| (b.x, b.mean)).collect();
                    (
                        format!("{name} (map + mean residual per {width}° bin)"),
                        self.map
                            .iter()
                            .filter_map(|&(x, m)| interpolate(&means, x).map(|r| (x, m + r)))
                            .collect(),
                    )
                }
                _ => (name.clone(), cmp.clone()),
            };
            chart = chart.with(Series::new(
                &name,
                Mark::Dashed,
                Colour::Green,
                pick(&points),
            ));
        }
        chart
    }
    /// The residual around zero with the band ±U it is read against; a sampled comparison as
    /// its mean per bin and the bin's spread (±1 standard deviation of its samples).
    fn residual_chart(&self, channel: &str, span: Option<(f64, f64)>) -> Option<Chart> {
        let res = self.residual()?;
        let (name, _) = self.comparison.as_ref()?;
        let mut chart = self.band_chart(
            Chart::new(angle_axis(channel, span), Axis::linear("residual (″)")),
            span,
        );
        let label = format!("{name} − calibrated map");
        chart = match self.samples {
            true => {
                let (bins, width) = binned(&res);
                chart
                    .with(Series::band(
                        "±1 s of the samples in each bin",
                        Colour::Orange,
                        bins.iter().map(|b| (b.x, b.mean - b.s)),
                        bins.iter().map(|b| (b.x, b.mean + b.s)),
                    ))
                    .with(Series::new(
                        &format!("{label} (mean per {width}° bin)"),
                        Mark::Line,
                        Colour::Red,
                        bins.iter().map(|b| (b.x, b.mean)),
                    ))
            }
            false => chart.with(Series::new(&label, Mark::Line, Colour::Red, decimate(&res))),
        };
        Some(chart)
    }
    /// `chart` with the band ±U around zero, where there is one.
    fn band_chart(&self, chart: Chart, span: Option<(f64, f64)>) -> Chart {
        let Some((name, band)) = &self.band else {
            return chart;
        };
        let band: Vec<(f64, f64)> = band
            .iter()
            .filter(|p| span.is_none_or(|(lo, hi)| p.0 >= lo && p.0 <= hi))
            .copied()
            .collect();
        let lower: Vec<(f64, f64)> = band.iter().map(|&(x, u)| (x, -u)).collect();
        chart.with(Series::band(
            &band_legend(name),
            Colour::Grey,
            decimate(&lower),
            decimate(&band),
        ))
    }
    /// The expanded uncertainty over the angle, a small panel under the map: at ±25″ of map a
    /// band of 0.01″ around it cannot be seen.
    fn uncertainty_chart(&self, channel: &str, span: Option<(f64, f64)>) -> Option<Chart> {
        let (name, band) = self.band.as_ref()?;
        let inside: Vec<(f64, f64)> = band
            .iter()
            .filter(|p| span.is_none_or(|(lo, hi)| p.0 >= lo && p.0 <= hi))
            .copied()
            .collect();
        let top = inside.iter().map(|p| p.1).fold(0.0, f64::max);
        let inside = decimate(&inside);
        Some(
            Chart::new(
                angle_axis(channel, span),
                Axis::linear("U (″)").with_range(0.0, if top > 0.0 { top * 1.15 } else { 1.0 }),
            )
            .with(Series::band(
                name,
                Colour::Grey,
                inside.iter().map(|p| (p.0, 0.0)),
                inside.iter().copied(),
            ))
            .with_height(0.6),
        )
    }
    /// Every panel of a map figure: the map, the residual, the uncertainty.
    fn panels(&self, channel: &str, span: Option<(f64, f64)>) -> Vec<Chart> {
        std::iter::once(self.chart(channel, span))
            .chain(self.residual_chart(channel, span))
            .chain(self.uncertainty_chart(channel, span))
            .collect()
    }
}

/// The x axis of a map: the channel's reading over a whole turn or over `span`.
fn angle_axis(channel: &str, span: Option<(f64, f64)>) -> Axis {
    let (lo, hi) = span.unwrap_or((0.0, 360.0));
    Axis::linear(&format!("reading of {channel} (°)")).with_range(lo, hi)
}

/// Samples a bin of a sampled comparison should hold, for a mean and a spread worth drawing.
const PER_BIN: usize = 50;

/// `points` (angle °, ″) binned over a turn, and the bins' width (°) as written in a legend:
/// 360 bins (1°) at least, 3600 (0.1°) at most, else [`PER_BIN`] samples a bin.
fn binned(points: &[(f64, f64)]) -> (Vec<crate::binning::Bin>, String) {
    let bins = (points.len() / PER_BIN).clamp(360, 3600);
    (
        crate::binning::bin(points, bins, 360.0),
        calib_core::report::trimmed(360.0 / bins as f64, 3),
    )
}

/// `f(x)` from points sorted by x, linearly, periodic over 360° (a range map's points may pass
/// 360°: an `x` within the points' own span is used as it is).
fn interpolate(points: &[(f64, f64)], x: f64) -> Option<f64> {
    let (first, last) = (points.first()?, points.last()?);
    let x = if x >= first.0 && x <= last.0 {
        x
    } else {
        x.rem_euclid(360.0)
    };
    let i = points.partition_point(|p| p.0 <= x);
    let (a, b) = match i {
        0 => ((last.0 - 360.0, last.1), *first),
        i if i == points.len() => (*last, (first.0 + 360.0, first.1)),
        i => (points[i - 1], points[i]),
    };
    let w = b.0 - a.0;
    Some(if w > 0.0 {
        a.1 + (b.1 - a.1) * (x - a.0) / w
    } else {
        a.1
    })
}

/// The error map of `channel` over 0–360°, with the comparison of `layers` on top; below it the
/// residual after correction (where there is a comparison) against the band ±U, and the
/// expanded uncertainty U over the angle (where there is one).
pub fn error_map(id: &str, channel: &str, layers: &MapLayers) -> Figure {
    let mut caption = format!(
        "Error of {channel} (reading − true angle, zero mean) over one revolution of its own reading; \
         the correction table is its negative."
    );
    if let Some((name, _)) = &layers.comparison {
        caption += &format!(
            " Middle panel: {name} minus the calibrated map, the error left after correction"
        );
        caption += match (layers.samples, layers.band.is_some()) {
            (true, true) => {
                ", as its mean per bin of angle with the spread of the samples, against ±U."
            }
            (true, false) => ", as its mean per bin of angle with the spread of the samples.",
            (false, true) => ", against ±U.",
            (false, false) => ".",
        };
    }
    if layers.band.is_some() {
        caption += " Bottom panel: the map's expanded uncertainty U.";
    }
    Figure::stacked(
        id,
        &format!("Error map of {channel}"),
        &caption,
        layers.panels(channel, None),
    )
}

/// The error map of `channel` over the range `lo`–`hi`° its readings covered (a joint that never
/// turned a whole revolution), with the panels of [`error_map`].
pub fn range_error_map(id: &str, channel: &str, layers: &MapLayers, lo: f64, hi: f64) -> Figure {
    let mut caption = format!(
        "Error of {channel} (reading − true angle, zero mean over the range) over the range {lo:.3}°–{hi:.3}° \
         of its own reading that the run covered; outside it the table says nothing. The correction table is its \
         negative."
    );
    if layers.band.is_some() {
        caption += " Bottom panel: the map's expanded uncertainty U.";
    }
    Figure::stacked(
        id,
        &format!("Error map of {channel}"),
        &caption,
        layers.panels(channel, Some((lo, hi))),
    )
}

/// A zoom of the error map on one period of harmonic order `order` (from 0° to 360°/order), the
/// map drawn at full resolution; `None` for order 0 or 1 (the whole circle is already shown).
pub fn zoom(id: &str, channel: &str, layers: &MapLayers, order: usize) -> Option<Figure> {
    if order < 2 {
        return None;
    }
    let period = 360.0 / order as f64;
    Some(Figure::new(
        id,
        &format!(
            "{channel}: one period of order {order} (0–{}°)",
            calib_core::report::trimmed(period, 4)
        ),
        &format!(
            "The error map of {channel} over one period of its dominant harmonic, order {order}, \
             in detail."
        ),
        layers.chart(channel, Some((0.0, period))),
    ))
}

/// The dominant order of a map: the order of its largest harmonic of order 2 or more.
pub fn dominant_order(map: &ErrorMap) -> Option<usize> {
    map.series()
        .harmonics()
        .into_iter()
        .filter(|h| h.order >= 2)
        .max_by(|a, b| a.amplitude.total_cmp(&b.amplitude))
        .filter(|h| h.amplitude > 0.0)
        .map(|h| h.order)
}

/// Harmonic amplitudes `(order, amplitude ″)` of a map, orders `1..=max_order`.
pub fn amplitudes(map: &ErrorMap, max_order: usize) -> Vec<(usize, f64)> {
    map.series()
        .harmonics()
        .into_iter()
        .filter(|h| h.order <= max_order)
        .map(|h| (h.order, h.amplitude * ARCSEC_PER_RAD))
        .collect()
}

/// Orders marked in a spectrum.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OrderMarks {
    /// Orders the method cannot see (left out of the maps).
    pub blind: Vec<usize>,
    /// Orders it sees badly (noise amplified), with the meaning of "badly" for the legend.
    pub ill_conditioned: Vec<usize>,
    /// Legend text of the ill-conditioned marks.
    pub ill_conditioned_name: String,
}

/// The harmonic spectrum of one or more channels: amplitude per order on a logarithmic axis,
/// blind and ill-conditioned orders marked along the bottom. Amplitudes below 10⁻⁵ of the largest
/// are drawn at that floor.
pub fn spectrum(id: &str, channels: &[(&str, Vec<(usize, f64)>)], marks: &OrderMarks) -> Figure {
    let largest = channels
        .iter()
        .flat_map(|(_, a)| a.iter().map(|p| p.1))
        .filter(|a| a.is_finite())
        .fold(0.0f64, f64::max);
    let top = if largest > 0.0 { largest } else { 1.0 };
    let floor = top * 1e-5;
    let max_order = channels
        .iter()
        .flat_map(|(_, a)| a.iter().map(|p| p.0))
        .chain(marks.blind.iter().copied())
        .chain(marks.ill_conditioned.iter().copied())
        .max()
        .unwrap_or(1);
    let width = 0.8 / channels.len().max(1) as f64;
    let mut chart = Chart::new(
        Axis::linear("harmonic order (cycles per revolution)")
            .with_range(0.0, max_order as f64 + 1.0),
        Axis::log("amplitude (″)").with_range(floor * 0.5, top * 2.0),
    );
    let colours = [Colour::Blue, Colour::Orange, Colour::Purple, Colour::Green];
    for (k, (name, amps)) in channels.iter().enumerate() {
        let shift = (k as f64 - (channels.len() as f64 - 1.0) / 2.0) * width;
        chart = chart.with(Series::new(
            name,
            Mark::Bars { width },
            colours[k % colours.len()],
            amps.iter()
                .filter(|p| p.1 > floor)
                .map(|&(h, a)| (h as f64 + shift, a)),
        ));
    }
    let at_floor = |orders: &[usize]| {
        orders
            .iter()
            .map(|&h| (h as f64, floor))
            .collect::<Vec<_>>()
    };
    if !marks.blind.is_empty() {
        chart = chart.with(Series::new(
            "blind order (left out)",
            Mark::Crosses,
            Colour::Red,
            at_floor(&marks.blind),
        ));
    }
    if !marks.ill_conditioned.is_empty() {
        chart = chart.with(Series::new(
            &marks.ill_conditioned_name,
            Mark::Dots,
            Colour::Orange,
            at_floor(&marks.ill_conditioned),
        ));
    }
    let names: Vec<&str> = channels.iter().map(|c| c.0).collect();
    Figure::new(
        id,
        &format!("Harmonic spectrum of {}", names.join(" and ")),
        "Amplitude of each harmonic order of the error map (log scale). Crosses along the bottom: \
         orders the method cannot see; dots: orders it sees only with amplified noise.",
        chart,
    )
}

/// One panel of a timeline: a y label (with the unit) and the trace channels drawn in it.
#[derive(Debug, Clone, PartialEq)]
pub struct TimelinePanel {
    /// Y axis label, with the unit.
    pub label: String,
    /// Indices of the trace's channels.
    pub channels: Vec<usize>,
}

/// A timeline of a log: panels of decimated traces over time, the given spans (sessions, in the
/// log's own time stamps) shaded in every panel. Time runs in seconds from the log's first sample.
pub fn timeline(
    id: &str,
    title: &str,
    caption: &str,
    trace: &Trace,
    panels: &[TimelinePanel],
    spans: &[Span],
) -> Figure {
    let colours = [Colour::Blue, Colour::Orange, Colour::Purple, Colour::Green];
    let t0 = trace.start().unwrap_or(0.0);
    let spans: Vec<Span> = spans
        .iter()
        .map(|s| Span {
            from: s.from - t0,
            to: s.to - t0,
            label: s.label.clone(),
        })
        .collect();
    let charts = panels
        .iter()
        .map(|p| {
            let mut chart = Chart::new(
                Axis::linear("time from log start (s)"),
                Axis::linear(&p.label),
            );
            chart.spans = spans.clone();
            for (k, &c) in p.channels.iter().enumerate() {
                chart = chart.with(Series::new(
                    trace.names().get(c).map_or("", |s| s.as_str()),
                    Mark::Line,
                    colours[k % colours.len()],
                    trace.series(c),
                ));
            }
            chart
        })
        .collect();
    let mut f = Figure::stacked(id, title, caption, charts);
    f.panel_height = 300;
    f
}

/// The seed paper's effective-range chart (Fig. 2): `|Y_Ω|` per order, log scale, against its
/// 1 % line (the paper method reliable below) and 100 % line.
pub fn y_chart(id: &str, y: &[(usize, f64)]) -> Figure {
    let ys = y.iter().map(|p| p.1).filter(|v| *v > 0.0 && v.is_finite());
    let lo = ys.clone().fold(0.005f64, f64::min) * 0.5;
    let hi = ys.fold(2.0f64, f64::max) * 2.0;
    let max_order = y.iter().map(|p| p.0).max().unwrap_or(1);
    let mut chart = Chart::new(
        Axis::linear("order Ω (cycles per revolution)")
            .with_range(0.0, max_order as f64 * 1.05 + 1.0),
        Axis::log("|Y_Ω| (1)").with_range(lo, hi),
    )
    .with(Series::new(
        "|Y_Ω| at the largest orders of ε_θ",
        Mark::Dots,
        Colour::Blue,
        y.iter().map(|&(h, v)| (h as f64, v)),
    ));
    chart.levels = vec![
        Level {
            y: 0.01,
            name: "1 %: paper method reliable below".into(),
            colour: Colour::Green,
        },
        Level {
            y: 1.0,
            name: "100 %".into(),
            colour: Colour::Red,
        },
    ];
    Figure::new(
        id,
        "Effective range of the paper method: |Y_Ω| per order",
        "|Y_Ω| = π²·Ω·m_Ω from the sampling non-uniformity ε_θ measured by the reference (seed paper \
         eqs. 18–20, Fig. 2). Where |Y_Ω| exceeds 1 %, the paper method's map is off by |Y_Ω| times \
         the error's amplitude at that order; the joint method does not depend on it.",
        chart,
    )
}

/// A bar chart of values over integer categories (faces, sessions, …).
pub fn bar_chart(
    id: &str,
    title: &str,
    caption: &str,
    x_label: &str,
    y_label: &str,
    bars: &[(usize, f64)],
) -> Figure {
    let lo = bars.iter().map(|b| b.0).min().unwrap_or(0) as f64;
    let hi = bars.iter().map(|b| b.0).max().unwrap_or(1) as f64;
    Figure::new(
        id,
        title,
        caption,
        Chart::new(
            Axis::linear(x_label).with_range(lo - 0.7, hi + 0.7),
            Axis::linear(y_label),
        )
        .with(Series::new(
            "",
            Mark::Bars { width: 0.6 },
            Colour::Blue,
            bars.iter().map(|&(k, v)| (k as f64, v)),
        )),
    )
}

/// Points `(x, y)` as a scatter chart (e.g. residuals per reading).
pub fn scatter(
    id: &str,
    title: &str,
    caption: &str,
    axes: (&str, &str),
    series: &[(&str, Vec<(f64, f64)>)],
) -> Figure {
    let colours = [Colour::Blue, Colour::Orange, Colour::Purple, Colour::Green];
    let mut chart = Chart::new(Axis::linear(axes.0), Axis::linear(axes.1));
    for (k, (name, pts)) in series.iter().enumerate() {
        chart = chart.with(Series::new(
            name,
            Mark::Dots,
            colours[k % colours.len()],
            pts.clone(),
        ));
    }
    Figure::new(id, title, caption, chart)
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::{FourierSeries, Harmonic};

    fn map() -> ErrorMap {
        let s = FourierSeries::from_harmonics(
            &[
                Harmonic::from_arcsec_deg(1, 3.0, 0.0),
                Harmonic::from_arcsec_deg(8, 20.0, 30.0),
            ],
            8,
        );
        ErrorMap::from_series(&s, 36000)
    }

    #[test]
    fn decimation_keeps_peaks_and_bounds_points() {
        let m = map();
        let pts = map_points(&m);
        let d = decimate(&pts);
        assert!(d.len() <= MAX_LINE_POINTS);
        let max = |v: &[(f64, f64)]| v.iter().map(|p| p.1).fold(f64::MIN, f64::max);
        assert_eq!(max(&d), max(&pts));
        assert!(d.windows(2).all(|w| w[0].0 <= w[1].0));
    }

    #[test]
    fn residual_is_comparison_minus_map() {
        let m = map();
        let shifted: Vec<(f64, f64)> = map_points(&m)
            .into_iter()
            .step_by(100)
            .map(|(x, y)| (x, y + 1.0))
            .chain([(360.0, m.values()[0] * ARCSEC_PER_RAD + 1.0)])
            .collect();
        let layers = MapLayers::of(&m).compared_with("truth", shifted);
        let res = layers.residual().unwrap();
        assert_eq!(res.len(), 361);
        assert!(
            res.iter().all(|r| (r.1 - 1.0).abs() < 1e-9),
            "{:?}",
            &res[..3]
        );
    }

    #[test]
    fn dominant_order_skips_order_one() {
        assert_eq!(dominant_order(&map()), Some(8));
        assert_eq!(amplitudes(&map(), 8).len(), 8);
    }

    #[test]
    fn zoom_spans_one_period() {
        let f = zoom("z", "a", &MapLayers::of(&map()), 8).unwrap();
        assert_eq!(f.panels[0].x.range, Some((0.0, 45.0)));
        let line = &f.panels[0].series[0].points;
        assert!(line.len() > 4000 / 2 && line.iter().all(|p| p.0 <= 45.0));
        assert!(zoom("z", "a", &MapLayers::of(&map()), 1).is_none());
    }
}
