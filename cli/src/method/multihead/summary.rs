//! The summary `calib multihead` prints: the heads, the orders and the scale's map.

use super::Args;
use crate::summary::TextTable;
use calib_core::Report;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::multihead::{Head, Method, MultiheadCalibration, Readings};
use std::fmt::Write;
use std::path::Path;

pub(super) fn readings_name(r: Option<Readings>) -> &'static str {
    match r {
        None => "reference",
        Some(Readings::RelativeToNominal) => "relative to nominal",
        Some(Readings::Raw) => "raw scale angle",
    }
}

/// A set's heads by name.
pub(super) fn set_names(set: &[usize], heads: &[Head]) -> Vec<String> {
    set.iter().map(|&j| heads[j].name.clone()).collect()
}

/// Orders as `84, 168, …` (the first 12, then how many more), or `none`.
pub(super) fn list_orders(orders: impl ExactSizeIterator<Item = usize>) -> String {
    let total = orders.len();
    if total == 0 {
        return "none".into();
    }
    let shown: Vec<String> = orders.take(12).map(|h| h.to_string()).collect();
    match total - shown.len() {
        0 => shown.join(", "),
        more => format!("{} and {more} more", shown.join(", ")),
    }
}

pub(super) fn render_summary(
    args: &Args,
    out: &Path,
    heads: &[Head],
    cal: &MultiheadCalibration,
    report: &Report,
) -> String {
    let mut o = String::new();
    let first = &heads[0].name;
    let method = match cal.method {
        Method::Joint => "joint least squares",
        Method::Eda => "equal-division average (eq. 9)",
    };
    let _ = writeln!(
        o,
        "Multi-head self-calibration of one scale read by {} heads — {method}",
        heads.len()
    );
    let _ = writeln!(
        o,
        "  {} samples, {:.2} revolutions of `{first}`, {} bins per revolution",
        cal.samples, cal.revolutions, cal.bins
    );
    let _ = writeln!(
        o,
        "\nheads (angles from `{first}`; angle error = actual − nominal, estimated)"
    );
    // The widths keep the layout of earlier versions while names fit; longer names widen the
    // column instead of pushing the rest of their row out of line.
    let mut table = TextTable::new(&[
        "head",
        "nominal °",
        "angle error ″",
        "residual ″",
        "readings",
    ])
    .min_widths(&[12, 11, 15, 12, 0]);
    for h in &cal.heads {
        let (error, residual) = match h.residual_rms {
            Some(r) => (
                format!("{:.4}", h.angle_error * ARCSEC_PER_RAD),
                format!("{:.4}", r * ARCSEC_PER_RAD),
            ),
            None => ("0 (origin)".to_string(), "—".to_string()),
        };
        table.row(vec![
            h.name.clone(),
            format!("{:.6}", h.nominal.to_degrees()),
            error,
            residual,
            readings_name(h.readings).to_string(),
        ]);
    }
    o += &table.render();
    if !cal.sets.is_empty() {
        let _ = writeln!(o, "\nEDA sets (each blind to multiples of its head count)");
        for (i, s) in cal.sets.iter().enumerate() {
            let n = s.heads.len();
            let _ = writeln!(
                o,
                "  {}: {:<40} N = {n} ({:.4}° apart)",
                i + 1,
                set_names(&s.heads, heads).join(", "),
                360.0 / n as f64
            );
        }
    }
    let ch = &report.channels[first];
    let top: Vec<String> = ch
        .harmonics
        .iter()
        .take(4)
        .map(|h| format!("{}: {:.3}″", h.order, h.amplitude_arcsec))
        .collect();
    // A map with no order above the noise lists none (its warning gives u).
    let top = if top.is_empty() {
        vec!["none above the noise".to_string()]
    } else {
        top
    };
    let _ = writeln!(
        o,
        "\nmap of the scale as `{first}` reads it (error = reading − true angle, zero mean)"
    );
    let _ = writeln!(
        o,
        "  p-p {:.4}″  rms {:.4}″  largest orders {}  → {}",
        cal.map.peak_to_peak() * ARCSEC_PER_RAD,
        ch.rms_arcsec,
        top.join(", "),
        out.join(&ch.table).display()
    );
    let _ = writeln!(
        o,
        "  standard uncertainty u of the table: max {:.4}″, rms {:.4}″ (budget in report.json)",
        cal.uncertainty.max() * ARCSEC_PER_RAD,
        cal.uncertainty.rms() * ARCSEC_PER_RAD
    );
    let residual = cal.residual_rms.map_or(String::new(), |r| {
        format!(", residual RMS {:.4}″ per sample", r * ARCSEC_PER_RAD)
    });
    let _ = writeln!(
        o,
        "\nfit: orders 1–{}{residual}, {} iterations",
        cal.max_order, cal.iterations
    );
    let who = match cal.method {
        Method::Joint => "no head pair sees them",
        Method::Eda => "no set sees them",
    };
    let _ = writeln!(
        o,
        "blind orders ({who}; the map lacks them): {}",
        list_orders(cal.blind.iter().map(|e| e.order))
    );
    if cal.method == Method::Joint {
        let _ = writeln!(
            o,
            "ill-conditioned orders left out (observability < {}): {}",
            args.min_observability,
            list_orders(cal.ill_conditioned.iter().map(|e| e.order))
        );
    }
    o += &crate::summary::ending(
        &report.warnings,
        out,
        &[ch.table.clone(), "report.json".to_string()],
        "the scale's map, its spectrum with the blind orders, every head's angle error",
    );
    o
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orders_are_listed_briefly() {
        assert_eq!(list_orders([84usize, 168].into_iter()), "84, 168");
        assert_eq!(list_orders(std::iter::empty()), "none");
        assert!(list_orders(1..21).ends_with("and 8 more"));
    }
}
