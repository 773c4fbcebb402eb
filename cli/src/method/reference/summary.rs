//! The summary `calib reference` prints: the run, the DUT's map against the reference, latency
//! and reversal.

use super::Args;
use crate::summary::{TextTable, ending, key_values};
use calib_core::Report;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::reference_cal::{GearResult, LatencySource, RatioSource, ReferenceCalibration};
use std::fmt::Write;
use std::path::Path;

/// Whether the report's u leaves the reference out (its uncertainty not given).
pub(super) fn excludes_reference(report: &Report) -> bool {
    matches!(&report.details, calib_core::report::Details::Reference(d) if d.u_excludes_reference)
}

/// The summary; `points`: the number of points of a point list.
pub(super) fn render_summary(
    args: &Args,
    out: &Path,
    cal: &ReferenceCalibration,
    report: &Report,
    points: Option<usize>,
) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "Reference calibration of `{}` against `{}`\n",
        args.dut, args.reference
    );
    let iso: std::collections::BTreeMap<_, _> = cal.iso.arcsec().into_iter().collect();
    let fmt = |k: &str| {
        iso.get(k)
            .copied()
            .flatten()
            .map_or("—".to_string(), |v| format!("{v:.3}″"))
    };
    let u_max = cal.u.iter().fold(0.0f64, |m, u| m.max(*u)) * ARCSEC_PER_RAD;
    let coverage = match (cal.map.range(), cal.gap) {
        (Some((lo, hi)), _) => range_text(lo, hi),
        (None, Some(g)) => format!(
            "whole turn, {:.3}° never reached between {:.3}° and {:.3}° (bridged)",
            g.size.to_degrees(),
            g.from.to_degrees(),
            calib_core::angle::wrap_2pi(g.to).to_degrees()
        ),
        (None, None) => "whole turn".to_string(),
    };
    o += &key_values(&[
        match points {
            Some(n) => (
                "points",
                format!(
                    "{n} stationary points at {} targets, at least {} measurement(s) increasing, \
                     {} decreasing",
                    cal.targets.len(),
                    cal.min_passes.0,
                    cal.min_passes.1
                ),
            ),
            // A joint's run is its travel over the range, not revolutions it never made.
            None => (
                "run",
                match cal.map.range() {
                    Some(_) => format!(
                        "{:.1}° of travel, at least {} pass(es) increasing, {} decreasing",
                        cal.revolutions * 360.0,
                        cal.min_passes.0,
                        cal.min_passes.1
                    ),
                    None => format!(
                        "{:.2} revolutions, at least {} pass(es) increasing, {} decreasing",
                        cal.revolutions, cal.min_passes.0, cal.min_passes.1
                    ),
                },
            ),
        },
        ("map", coverage),
        ("latency", latency_text(cal)),
        (
            "ISO 230-2",
            format!(
                "{} targets: systematic E {}, reversal B {}, repeatability R {}, accuracy A {}",
                cal.targets.len(),
                fmt("systematic"),
                fmt("reversal"),
                fmt("repeatability"),
                fmt("accuracy")
            ),
        ),
    ]);
    if let Some(g) = &cal.gear {
        o += &key_values(&[("gear", gear_text(g))]);
    }
    if let Some(e) = cal.ends {
        o += &key_values(&[(
            "one direction",
            format!(
                "{} point(s) at the ends measured one way only: corrected by half the reversal next to them \
                 (at most {:.3}″, its u at most {:.3}″, in u_arcsec)",
                e.points,
                e.max_correction * ARCSEC_PER_RAD,
                e.max_u * ARCSEC_PER_RAD
            ),
        )]);
    }
    if let Some(q) = quantization_text(cal) {
        o += &key_values(&[("quantization", q)]);
    }
    if let Some(r) = &cal.ripple {
        let mut terms: Vec<_> = r.terms.iter().collect();
        terms.sort_by(|a, b| b.amplitude.total_cmp(&a.amplitude));
        let top: Vec<String> = terms
            .iter()
            .take(3)
            .map(|t| {
                format!(
                    "order {} ({}/electrical turn) {:.3}″ ± {:.3}″",
                    t.order,
                    t.harmonic,
                    t.amplitude * ARCSEC_PER_RAD,
                    t.u_amplitude * ARCSEC_PER_RAD
                )
            })
            .collect();
        o += &key_values(&[(
            "motor ripple",
            format!(
                "{} pole pairs, {:.3}″ peak-to-peak taken out of the map: {}",
                r.pole_pairs,
                r.peak_to_peak * ARCSEC_PER_RAD,
                top.join(", ")
            ),
        )]);
    }
    let ch = &report.channels[&args.dut];
    let top: Vec<String> = ch
        .harmonics
        .iter()
        .take(3)
        .map(|h| format!("{}: {:.3}″", h.order, h.amplitude_arcsec))
        .collect();
    let excludes = excludes_reference(report);
    let u_label = if excludes {
        "max u (excludes the reference)"
    } else {
        "max u"
    };
    let mut t = TextTable::new(&["channel", "p-p before", "rms", u_label, "largest orders"]);
    t.row(vec![
        args.dut.clone(),
        format!("{:.3}″", ch.peak_to_peak_arcsec),
        format!("{:.3}″", ch.rms_arcsec),
        format!("{u_max:.3}″"),
        if top.is_empty() {
            "— (a range has no harmonics)".to_string()
        } else {
            top.join(", ")
        },
    ]);
    let mut tables = vec![ch.table.clone()];
    if let Some(m) = cal.gear.as_ref().and_then(|g| g.reference_map.as_ref()) {
        let r = &report.channels[&args.reference];
        let u = m.u.iter().fold(0.0f64, |a, &u| a.max(u)) * ARCSEC_PER_RAD;
        let top: Vec<String> = r
            .harmonics
            .iter()
            .take(3)
            .map(|h| format!("{}: {:.3}″", h.order, h.amplitude_arcsec))
            .collect();
        t.row(vec![
            format!("{} (own turn)", args.reference),
            format!("{:.3}″", r.peak_to_peak_arcsec),
            format!("{:.3}″", r.rms_arcsec),
            format!("{u:.3}″"),
            top.join(", "),
        ]);
        tables.push(r.table.clone());
    }
    let _ = writeln!(o, "\n{}", t.render().trim_end());
    let _ = writeln!(
        o,
        "  (error = {} − {}, zero mean; every ISO 230-2 figure is in report.json and report.html)",
        args.dut, args.reference
    );
    tables.push("report.json".to_string());
    o += &ending(
        &report.warnings,
        out,
        &tables,
        if cal.map.range().is_some() {
            "error map over the range with its uncertainty band, each direction"
        } else {
            "error map with its uncertainty band, each direction, spectrum"
        },
    );
    o
}

/// The summary's line on a range: in the signed convention when it crosses the reading 0
/// (−40° to 95°, never above 360°), with the readings of a sensor that reads 0…360°.
pub(super) fn range_text(lo: f64, hi: f64) -> String {
    let span = (hi - lo).to_degrees();
    let (lo, hi) = (lo.to_degrees(), hi.to_degrees());
    if hi > 360.0 {
        format!(
            "range table from {:.3}° to {:.3}° ({span:.3}° of the DUT's reading across 0°, i.e. {lo:.3}°…360° and \
             0°…{:.3}° read in [0, 360); no whole turn)",
            lo - 360.0,
            hi - 360.0,
            hi - 360.0
        )
    } else {
        format!(
            "range table from {lo:.3}° to {hi:.3}° ({span:.3}° of the DUT's reading; no whole turn)"
        )
    }
}

/// The summary's line on a reference through a gear: the ratio, and what the run cannot split.
fn gear_text(g: &GearResult) -> String {
    let ratio = match (g.source, g.ratio_u) {
        (RatioSource::Estimated, Some(u)) => format!("ratio {:.6} ± {:.6} (estimated)", g.ratio, u),
        _ => format!("ratio {} (given)", g.ratio),
    };
    let map = match &g.reference_map {
        Some(m) => {
            let kept: Vec<String> = m
                .terms
                .iter()
                .filter(|t| t.kept)
                .map(|t| t.order.to_string())
                .collect();
            format!(
                "the reference's own error fitted to order {} over {:.1} of its turns, orders {} significant",
                m.terms.last().map_or(0, |t| t.order),
                g.reference_turns,
                if kept.is_empty() {
                    "none".to_string()
                } else {
                    kept.join(", ")
                }
            )
        }
        None => format!(
            "the reference turned {:.2} time(s): its error is not separated",
            g.reference_turns
        ),
    };
    let mut text = format!("{ratio}; {map}");
    if !g.coincident.is_empty() {
        let orders: Vec<String> = g
            .coincident
            .iter()
            .map(|c| c.dut_order.to_string())
            .collect();
        let _ = write!(
            text,
            "; the DUT's orders {} are the reference's: in its map",
            orders.join(", ")
        );
    }
    if g.line_in_ratio {
        text += "; over a range the DUT's straight-line part is in the ratio (the map has none)";
    }
    text
}

/// The summary's line on the lag between the channels.
pub(super) fn latency_text(cal: &ReferenceCalibration) -> String {
    let Some(l) = cal.latency else {
        return "assumed 0 (--latency 0)".to_string();
    };
    let ms = |s: f64| s * 1e3;
    match (l.source, l.fit) {
        (LatencySource::Given, _) => format!("{:.3} ms given (--latency), removed", ms(l.applied)),
        (LatencySource::Estimated, Some(f)) => format!(
            "the DUT lags the reference by {:.3} ± {:.3} ms (estimated, removed)",
            ms(f.tau),
            ms(f.u_tau)
        ),
        (LatencySource::Insignificant, Some(f)) => format!(
            "{:.3} ± {:.3} ms estimated: not different from 0, not removed",
            ms(f.tau),
            ms(f.u_tau)
        ),
        (LatencySource::Ambiguous, Some(f)) => format!(
            "not separable from backlash at one speed per direction: {:.1} ms, or a backlash of {:.1}″ (not removed)",
            ms(f.tau_if_no_backlash),
            f.reversal_if_no_latency * ARCSEC_PER_RAD
        ),
        _ => "the run cannot estimate it (too few points crossed twice, or time stamps out of order); not removed"
            .to_string(),
    }
}

/// The summary's `quantization` line: the DUT's quantum and what of it is in every u, where
/// that is at least 0.001″ (`None` otherwise).
pub(crate) fn quantization_text(cal: &ReferenceCalibration) -> Option<String> {
    let q = cal.quantization?;
    let u = q.u * ARCSEC_PER_RAD;
    (u >= 0.001).then(|| {
        let noise = match q.noise {
            Some(s) => format!("noise of {:.3}″ in front of it", s * ARCSEC_PER_RAD),
            None => "no point crossed twice in a direction, so no noise is known to dither it".to_string(),
        };
        format!(
            "the DUT reads in steps of {:.3}″ ({noise}): {u:.3}″ in every point's u_arcsec, the part of the \
             quantum no averaging of passes takes out",
            q.quantum * ARCSEC_PER_RAD
        )
    })
}
