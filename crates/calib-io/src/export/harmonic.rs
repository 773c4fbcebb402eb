//! The harmonic form of a table (`--format harmonic`), and the choice of orders any format can be
//! resynthesized from (`--harmonics N`, `--orders LIST`).
//!
//! # Harmonic form
//! `order,amplitude_arcsec,phase_deg` rows of the *correction* `c(θ) = −e(θ) = Σ A·cos(h·θ + φ)`,
//! θ the reading: the error's harmonics with their phases turned by 180°. Rows are sorted largest
//! first.
//!
//! # Choosing orders
//! A table's Fourier series ([`ErrorMap::series`]) holds orders `1..⌈N/2⌉−1`. Keeping some of them
//! and evaluating that series exactly at the output grid points is a smoothing that cannot
//! alias: resampling a table of 3600 points to a controller's 256 by interpolation folds every
//! order above 127 onto a lower one, while a series of orders below 128 is held exactly. The
//! header says which orders were kept and what the dropped ones amount to on the source table's
//! own grid — peak to peak and RMS of `table − kept series` — so the cost of the smoothing is
//! visible next to the [`super::Fit`].

use super::{ExportError, ExportOptions, corrections};
use calib_core::ErrorMap;
use calib_core::FourierSeries;
use calib_core::angle::{ARCSEC_PER_RAD, DEG_PER_RAD};
use std::f64::consts::PI;
use std::fmt::Write as _;

/// Which orders of a table's Fourier series to keep.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum Keep {
    /// Every order: the table as it is (resampled by interpolation if the size changes).
    #[default]
    All,
    /// The given number of orders of largest amplitude (among those the output grid holds).
    Largest(usize),
    /// These orders.
    Orders(Vec<usize>),
}

/// The orders chosen from a table and what was left out.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Chosen {
    /// The kept orders' series.
    pub series: FourierSeries,
    /// The kept orders, as chosen (largest first for [`Keep::Largest`], increasing otherwise).
    kept: Vec<usize>,
    /// How they were chosen.
    by: ChosenBy,
    /// Points of the output grid.
    points: usize,
    /// Orders of the table's series.
    orders: usize,
    /// Peak to peak of the table minus the kept series on the table's grid, radians.
    pub dropped_pp: f64,
    /// RMS of the same, radians.
    dropped_rms: f64,
    /// The largest dropped orders with their own peak to peak (twice the amplitude, radians),
    /// largest first, at most [`NAMED_DROPPED`].
    dropped_largest: Vec<(usize, f64)>,
}

/// How [`Chosen`] orders were chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
enum ChosenBy {
    /// [`Keep::Largest`], among orders 1 to the given one (those the output grid holds).
    Largest(usize),
    /// [`Keep::Orders`].
    Listed,
    /// [`Keep::All`] on a grid smaller than the table: every order up to the given one, the
    /// highest the output grid holds.
    Held(usize),
}

/// How many dropped orders a header names with their peak to peak.
const NAMED_DROPPED: usize = 5;

impl Chosen {
    /// The header line.
    pub fn describe(&self) -> String {
        let list = order_list(&self.kept);
        let chosen = match self.by {
            ChosenBy::Largest(limit) => format!(
                "kept the {} largest orders, {list} (among orders 1 to {limit}, those a {}-point \
                 table holds)",
                self.kept.len(),
                self.points
            ),
            ChosenBy::Listed => format!(
                "kept orders {list} ({} of the table's {})",
                self.kept.len(),
                self.orders
            ),
            ChosenBy::Held(limit) => format!(
                "kept every order a {}-entry table holds, 1 to {limit} (orders below {}/2), \
                 rather than fold the table's orders {} to {} onto them",
                self.points,
                self.points,
                limit + 1,
                self.orders
            ),
        };
        format!(
            "harmonics: {chosen}, resynthesized on the output grid; dropped: {}",
            self.dropped_summary()
        )
    }

    /// What was dropped: the largest dropped orders with their p-p, and all of them together.
    pub fn dropped_summary(&self) -> String {
        let named: Vec<String> = self
            .dropped_largest
            .iter()
            .map(|(h, pp)| format!("order {h} {:.6} arcsec p-p", pp * ARCSEC_PER_RAD))
            .collect();
        let count = self.orders - self.kept.len();
        let largest = if named.is_empty() {
            String::new()
        } else {
            format!("largest {}; ", named.join(", "))
        };
        format!(
            "{largest}the {count} orders together {:.6} arcsec peak-to-peak, {:.6} arcsec RMS",
            self.dropped_pp * ARCSEC_PER_RAD,
            self.dropped_rms * ARCSEC_PER_RAD
        )
    }
}

/// The orders `keep` chooses from `map` for an output grid of `points`, or `None` for
/// [`Keep::All`]. Listed orders must be in the table and below the output grid's Nyquist order
/// (`2h < points`); [`Keep::Largest`] chooses among those the grid holds.
pub(super) fn choose(
    map: &ErrorMap,
    keep: &Keep,
    points: usize,
) -> Result<Option<Chosen>, ExportError> {
    let series = map.series();
    let orders = series.max_order();
    let holds = (points - 1) / 2;
    let (kept, by) = match keep {
        Keep::All => return Ok(None),
        Keep::Largest(n) => {
            let limit = holds.min(orders);
            let candidates: Vec<usize> = (1..=limit).collect();
            (
                series.only(&candidates).largest_orders(*n),
                ChosenBy::Largest(limit),
            )
        }
        Keep::Orders(list) => {
            let mut list = list.clone();
            list.sort_unstable();
            list.dedup();
            if let Some(&order) = list.iter().find(|&&h| h == 0 || h > orders) {
                return Err(ExportError::NoSuchOrder {
                    order,
                    points: map.len(),
                    max: orders,
                });
            }
            if let Some(&order) = list.iter().find(|&&h| h > holds) {
                return Err(ExportError::AboveNyquist {
                    order,
                    points,
                    max: holds,
                });
            }
            (list, ChosenBy::Listed)
        }
    };
    Ok(Some(measure(map, &series, kept, by, points)))
}

/// Every order of `map` that a grid of `points` holds (below `points/2`), for a grid smaller
/// than the table: what [`Keep::All`] keeps there instead of folding the higher orders.
pub(super) fn choose_held(map: &ErrorMap, points: usize) -> Option<Chosen> {
    let series = map.series();
    let limit = ((points - 1) / 2).min(series.max_order());
    let kept = (1..=limit).collect();
    Some(measure(map, &series, kept, ChosenBy::Held(limit), points))
}

/// The kept orders of `series` (the series of `map`) and what the rest amount to on `map`'s grid.
fn measure(
    map: &ErrorMap,
    series: &FourierSeries,
    kept: Vec<usize>,
    by: ChosenBy,
    points: usize,
) -> Chosen {
    let orders = series.max_order();
    let mut is_kept = vec![false; orders + 1];
    kept.iter().for_each(|&h| is_kept[h] = true);
    let mut dropped_largest: Vec<(usize, f64)> = series
        .harmonics()
        .iter()
        // Tables hold 6 decimals of an arcsecond: below that an order is rounding, not error.
        .filter(|h| !is_kept[h.order] && h.amplitude * ARCSEC_PER_RAD >= 5e-7)
        .map(|h| (h.order, 2.0 * h.amplitude))
        .collect();
    dropped_largest.sort_by(|a, b| b.1.total_cmp(&a.1));
    dropped_largest.truncate(NAMED_DROPPED);
    let kept_series = series.only(&kept);
    let synthesized = ErrorMap::from_series(&kept_series, map.len());
    let dropped: Vec<f64> = map
        .values()
        .iter()
        .zip(synthesized.values())
        .map(|(e, s)| e - s)
        .collect();
    let max = dropped.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let min = dropped.iter().copied().fold(f64::INFINITY, f64::min);
    let rms = (dropped.iter().map(|d| d * d).sum::<f64>() / dropped.len() as f64).sqrt();
    Chosen {
        series: kept_series,
        kept,
        by,
        points,
        orders,
        dropped_pp: max - min,
        dropped_rms: rms,
        dropped_largest,
    }
}

/// A harmonic listing: its header lines, its rows, and the orders listed.
pub(super) struct Listing {
    /// The header lines.
    pub lines: Vec<String>,
    /// The rows, under their column names.
    pub body: String,
    /// The orders listed, largest first.
    pub orders: Vec<usize>,
}

/// `--format harmonic`: the header lines and the rows of the correction's harmonics.
///
/// [`Keep::All`] lists every order of at least `opts.min_amplitude_arcsec`, [`Keep::Largest`]
/// the largest orders, [`Keep::Orders`] the listed ones; the header gives the RMS of the rest.
/// A listing of no order (every order below `min_amplitude_arcsec`) is refused
/// ([`ExportError::NothingListed`]): it would correct nothing.
pub(super) fn listing(map: &ErrorMap, opts: &ExportOptions) -> Result<Listing, ExportError> {
    let n = map.len();
    // The correction is −error: same amplitudes, phases turned by 180°.
    let mut rows: Vec<(usize, f64, f64)> = map
        .series()
        .harmonics()
        .iter()
        .map(|h| {
            let phase = (h.phase + PI).rem_euclid(2.0 * PI);
            let phase = if phase > PI { phase - 2.0 * PI } else { phase };
            (h.order, h.amplitude * ARCSEC_PER_RAD, phase * DEG_PER_RAD)
        })
        .collect();
    let orders = rows.len();
    rows.sort_by(|a, b| b.1.total_cmp(&a.1));
    let largest = rows.first().map(|h| (h.0, h.1));
    let kept_line = match &opts.keep {
        Keep::All | Keep::Largest(_) => {
            let keep = match opts.keep {
                Keep::Largest(k) => k.min(orders),
                _ => rows
                    .iter()
                    .filter(|h| h.1 >= opts.min_amplitude_arcsec)
                    .count(),
            };
            rows.truncate(keep);
            format!("kept: {keep} of {orders} orders, largest first")
        }
        Keep::Orders(list) => {
            if let Some(&order) = list.iter().find(|&&h| h == 0 || h > orders) {
                return Err(ExportError::NoSuchOrder {
                    order,
                    points: n,
                    max: orders,
                });
            }
            rows.retain(|h| list.contains(&h.0));
            let mut listed: Vec<usize> = rows.iter().map(|h| h.0).collect();
            listed.sort_unstable();
            format!(
                "kept: orders {} ({} of {orders}), largest first",
                order_list(&listed),
                rows.len()
            )
        }
    };
    if rows.is_empty() {
        let (order, amplitude_arcsec) = largest.unwrap_or((0, 0.0));
        return Err(ExportError::NothingListed {
            min_amplitude_arcsec: opts.min_amplitude_arcsec,
            order,
            amplitude_arcsec,
        });
    }
    let total_ms = corrections(map).iter().map(|v| v * v).sum::<f64>() / n as f64;
    let kept_ms = rows.iter().map(|h| h.1 * h.1 / 2.0).sum::<f64>();
    let lines = vec![
        "units: amplitude arcseconds, phase degrees; correction(θ) = Σ amplitude·cos(order·θ + \
         phase), θ the reading"
            .to_string(),
        format!(
            "{kept_line}; dropped: {} orders, RMS {:.6} arcsec",
            orders - rows.len(),
            (total_ms - kept_ms).max(0.0).sqrt()
        ),
    ];
    let mut body = String::from("order,amplitude_arcsec,phase_deg\n");
    for (order, a, p) in &rows {
        // Writing into a String cannot fail.
        let _ = writeln!(body, "{order},{a:.6},{p:.6}");
    }
    Ok(Listing {
        lines,
        body,
        orders: rows.iter().map(|h| h.0).collect(),
    })
}

/// Orders written compactly, runs as ranges: `1-8, 72, 144`.
fn order_list(orders: &[usize]) -> String {
    let mut sorted = orders.to_vec();
    sorted.sort_unstable();
    let mut parts: Vec<String> = Vec::new();
    let mut i = 0;
    while i < sorted.len() {
        let mut j = i;
        while j + 1 < sorted.len() && sorted[j + 1] == sorted[j] + 1 {
            j += 1;
        }
        parts.push(if j > i + 1 {
            format!("{}-{}", sorted[i], sorted[j])
        } else if j == i + 1 {
            format!("{}, {}", sorted[i], sorted[j])
        } else {
            sorted[i].to_string()
        });
        i = j + 1;
    }
    parts.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::{Format, export};
    use calib_core::Harmonic;
    use calib_core::TableMap;

    /// 10″ at order 3, 2″ at 7, 0.05″ at 40, on 720 points.
    fn table() -> ErrorMap {
        let hs = [
            Harmonic::from_arcsec_deg(3, 10.0, 20.0),
            Harmonic::from_arcsec_deg(7, 2.0, 0.0),
            Harmonic::from_arcsec_deg(40, 0.05, 0.0),
        ];
        ErrorMap::from_series(&FourierSeries::from_harmonics(&hs, 40), 720)
    }

    #[test]
    fn orders_are_listed_compactly() {
        assert_eq!(
            order_list(&[72, 1, 2, 3, 4, 144, 6, 7]),
            "1-4, 6, 7, 72, 144"
        );
        assert_eq!(order_list(&[5]), "5");
    }

    #[test]
    fn kept_orders_are_resynthesized_and_the_rest_measured() {
        let map = table();
        let chosen = choose(&map, &Keep::Largest(2), 64).unwrap().unwrap();
        assert_eq!(chosen.kept, vec![3, 7]);
        // What is dropped is the 0.05″ order 40: 0.1″ peak to peak, 0.05/√2 RMS.
        assert!((chosen.dropped_pp * ARCSEC_PER_RAD - 0.1).abs() < 1e-9);
        assert!((chosen.dropped_rms * ARCSEC_PER_RAD - 0.05 / 2f64.sqrt()).abs() < 1e-9);
        let line = chosen.describe();
        assert!(
            line.contains("3, 7") && line.contains("0.100000 arcsec peak-to-peak"),
            "{line}"
        );
        // On 64 points order 40 would alias; the largest are chosen among orders 1 to 31.
        let chosen = choose(&map, &Keep::Largest(3), 64).unwrap().unwrap();
        assert!(!chosen.kept.contains(&40), "{:?}", chosen.kept);
        assert_eq!(
            choose(&map, &Keep::Orders(vec![3, 40]), 64).unwrap_err(),
            ExportError::AboveNyquist {
                order: 40,
                points: 64,
                max: 31
            }
        );
        assert!(matches!(
            choose(&map, &Keep::Orders(vec![400]), 64),
            Err(ExportError::NoSuchOrder { order: 400, .. })
        ));
        assert_eq!(choose(&map, &Keep::All, 64).unwrap(), None);
    }

    #[test]
    fn a_smoothed_export_holds_the_kept_orders_exactly() {
        let map = table();
        let mut opts = ExportOptions::new(Format::Csv, "t");
        opts.points = Some(64);
        opts.keep = Keep::Orders(vec![3, 7]);
        let out = export(&TableMap::from(map.clone()), &opts).unwrap();
        let kept = FourierSeries::from_harmonics(
            &[
                Harmonic::from_arcsec_deg(3, 10.0, 20.0),
                Harmonic::from_arcsec_deg(7, 2.0, 0.0),
            ],
            7,
        );
        let rows: Vec<(f64, f64)> = out
            .text
            .lines()
            .filter(|l| !l.starts_with('#') && !l.starts_with("angle"))
            .map(|l| {
                let (a, c) = l.split_once(',').unwrap();
                (a.parse().unwrap(), c.parse().unwrap())
            })
            .collect();
        assert_eq!(rows.len(), 64);
        for (deg, c) in rows {
            let want = -kept.eval(f64::to_radians(deg)) * ARCSEC_PER_RAD;
            // 6 decimals in the file.
            assert!((c - want).abs() < 1e-6, "{deg}: {c} vs {want}");
        }
        assert!(
            out.header
                .iter()
                .any(|l| l.starts_with("harmonics: kept orders 3, 7"))
        );
        // The fit to the source adds up the dropped 0.05″ of order 40, the interpolation between
        // 64 points, A·(hΔ)²/8 for each kept order (0.108″ and 0.118″), and 6-decimal rounding.
        let step = std::f64::consts::TAU / 64.0;
        let bound = (10.0 * (3.0 * step).powi(2) + 2.0 * (7.0 * step).powi(2)) / 8.0 + 0.05 + 1e-6;
        let fit = out.fit.unwrap();
        assert!(fit.max * ARCSEC_PER_RAD <= bound, "{fit:?} vs {bound}");
    }
}
