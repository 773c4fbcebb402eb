//! The chart every ISO 230-2 report carries: at each target position, the mean positioning
//! deviation of each direction and its ±2s interval, so that systematic deviation, reversal and
//! repeatability are read off one picture.

use crate::chart::{Axis, Chart, Colour, Figure, Mark, Series};

/// One direction at one target: mean deviation and the standard deviation of its passes, ″.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Direction {
    /// Mean deviation `x̄`, ″.
    pub mean: f64,
    /// Standard deviation `s` of the passes, ″ (`None` with fewer than two passes).
    pub s: Option<f64>,
}

/// One target position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Target {
    /// The target, degrees of the reading.
    pub angle: f64,
    /// Increasing readings (`None`: no pass).
    pub up: Option<Direction>,
    /// Decreasing readings.
    pub down: Option<Direction>,
}

impl Target {
    /// The mean of the directions' means (the one there is with one direction), ″.
    fn bidirectional_mean(&self) -> f64 {
        let means: Vec<f64> = [self.up, self.down]
            .iter()
            .flatten()
            .map(|d| d.mean)
            .collect();
        means.iter().sum::<f64>() / means.len().max(1) as f64
    }
}

/// ISO 230-2's deviation chart of `channel` over `x_range` (°): per direction its mean
/// deviation through the targets (a dot at each) and the band `x̄ ± 2s`. Below, the same
/// relative to each target's bidirectional mean: against a systematic deviation of hundreds of
/// arcseconds the reversal and the ±2s bands are too thin to see in the first panel.
pub fn targets_chart(id: &str, channel: &str, targets: &[Target], x_range: (f64, f64)) -> Figure {
    let axis = || {
        Axis::linear(&format!("target position, reading of {channel} (°)"))
            .with_range(x_range.0, x_range.1)
    };
    let absolute = panel(
        Chart::new(axis(), Axis::linear("positioning deviation (″)")),
        targets,
        |_| 0.0,
    );
    let relative = panel(
        Chart::new(axis(), Axis::linear("deviation − bidirectional mean (″)")),
        targets,
        Target::bidirectional_mean,
    );
    Figure::stacked(
        id,
        &format!("ISO 230-2 positioning deviations of {channel}"),
        "Top: at each target position, the mean deviation x̄ of the passes in each direction and the \
         interval x̄ ± 2s (s: standard deviation of the passes). Bottom: the same less the target's \
         bidirectional mean, so that the reversal B (the gap between the two means) and the \
         repeatability R = 4s (the width of a band) can be read (ISO 230-2:2014, fig. 1).",
        vec![absolute, relative],
    )
}

/// `chart` with both directions drawn, each less `offset` of its target.
fn panel(mut chart: Chart, targets: &[Target], offset: fn(&Target) -> f64) -> Chart {
    type Side = fn(&Target) -> Option<Direction>;
    let sides: [(&str, Side, Colour); 2] = [
        ("increasing ↑", |t| t.up, Colour::Blue),
        ("decreasing ↓", |t| t.down, Colour::Orange),
    ];
    for (name, side, colour) in sides {
        let with_s: Vec<(f64, f64, f64)> = targets
            .iter()
            .filter_map(|t| side(t).and_then(|d| Some((t.angle, d.mean - offset(t), d.s?))))
            .collect();
        if !with_s.is_empty() {
            chart = chart.with(Series::band(
                &format!("{name} x̄ ± 2s"),
                colour,
                with_s.iter().map(|&(x, m, s)| (x, m - 2.0 * s)),
                with_s.iter().map(|&(x, m, s)| (x, m + 2.0 * s)),
            ));
        }
        let means: Vec<(f64, f64)> = targets
            .iter()
            .filter_map(|t| side(t).map(|d| (t.angle, d.mean - offset(t))))
            .collect();
        chart = chart
            .with(Series::new(
                &format!("{name} mean deviation x̄"),
                Mark::Line,
                colour,
                means.clone(),
            ))
            .with(Series::new("", Mark::Dots, colour, means));
    }
    chart
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_dot_per_target_and_direction_and_a_band_each() {
        let targets: Vec<Target> = (0..8)
            .map(|k| Target {
                angle: 45.0 * k as f64,
                up: Some(Direction {
                    mean: 1.0,
                    s: Some(0.1),
                }),
                down: (k > 0).then_some(Direction {
                    mean: -1.0,
                    s: None,
                }),
            })
            .collect();
        let f = targets_chart("iso", "dut", &targets, (0.0, 360.0));
        assert_eq!(f.panels.len(), 2);
        let series = &f.panels[1].series;
        let relative: Vec<f64> = series[1].points.iter().map(|p| p.1).collect();
        assert_eq!(relative[0], 0.0, "one direction: its own mean");
        assert!(relative[1..].iter().all(|&d| d == 1.0), "{relative:?}");
        let dots: usize = series
            .iter()
            .filter(|s| s.mark == Mark::Dots)
            .map(|s| s.points.len())
            .sum();
        assert_eq!(dots, 8 + 7);
        let bands = series
            .iter()
            .filter(|s| matches!(s.mark, Mark::Band { .. }))
            .count();
        assert_eq!(bands, 1, "no band where s is not known");
        let svg = f.to_svg().unwrap();
        assert!(svg.contains("positioning deviation (″)") && svg.contains("<polygon"));
    }
}
