//! The summary `calib csrr` prints: the sessions, orders, uncertainty and each sensor's map.

use super::Args;
use crate::output::table_name;
use crate::summary::{TextTable, ending, key_values};
use calib_core::Report;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::csrr::{Calibration, Method};
use calib_core::reference_cal::Latency;
use std::fmt::Write;
use std::path::Path;

/// The orders line of the summaries: the range tested, how many of them the significance rule
/// kept (joint solver) and how many the sessions cannot see.
pub(super) fn orders_text(cal: &Calibration) -> String {
    match cal.method {
        Method::Joint => format!(
            "1–{} tested, {} kept above the noise, {} left out",
            cal.max_order,
            cal.orders.len(),
            cal.excluded.len()
        ),
        Method::Paper => format!("1–{} ({} left out)", cal.max_order, cal.excluded.len()),
    }
}

pub(super) fn render_summary(
    args: &Args,
    out: &Path,
    cal: &Calibration,
    report: &Report,
) -> String {
    let mut o = String::new();
    let method = match cal.method {
        Method::Joint => "joint least squares",
        Method::Paper => "paper (eqs. 4–7)",
    };
    let _ = writeln!(
        o,
        "CSRR self-calibration of `{}` and `{}` — {method}\n",
        args.a, args.b
    );
    let deltas: Vec<String> = cal
        .sessions
        .iter()
        .map(|s| format!("{:.1}°", s.relative_rotation.to_degrees()))
        .collect();
    let revs = cal
        .sessions
        .iter()
        .map(|s| s.revolutions)
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), r| {
            (lo.min(r), hi.max(r))
        });
    let mut facts = vec![(
        "sessions",
        format!(
            "{} of {:.2}–{:.2} revolutions at Δ = {}",
            cal.sessions.len(),
            revs.0,
            revs.1,
            if deltas.len() > 8 {
                format!("{}, …", deltas[..8].join(", "))
            } else {
                deltas.join(", ")
            }
        ),
    )];
    if let Some(tol) = cal.segmentation.relative_tol {
        facts.push((
            "found",
            format!(
                "from the motion: `{} − {}` periodic in the shaft angle within {:.4}° per revolution ({})",
                args.a,
                args.b,
                tol.to_degrees(),
                if args.session_tol.is_some() {
                    "--session-tol"
                } else {
                    "from the sessions' own scatter"
                }
            ),
        ));
    }
    if let Some(l) = cal.latency.filter(|l| l.applied != 0.0) {
        let older = if l.applied > 0.0 { &args.b } else { &args.a };
        facts.push((
            "latency",
            format!(
                "`{older}`'s samples {:.3} ms older, removed ({}){}",
                l.applied.abs() * 1e3,
                match l.mode {
                    Latency::Auto =>
                        format!("found from the sessions, {} readings of the log", l.passes),
                    Latency::Fixed(_) => "--latency".to_string(),
                },
                l.u_applied
                    .map_or(String::new(), |u| format!("; u {:.3} µs", u * 1e6))
            ),
        ));
    }
    match cal.residual_rms {
        Some(r) => {
            facts.push(("orders", orders_text(cal)));
            facts.push((
                "fit residual",
                format!(
                    "{:.4}″ RMS per sample, {} iterations",
                    r * ARCSEC_PER_RAD,
                    cal.iterations
                ),
            ));
        }
        None => facts.push((
            "map points",
            format!(
                "{} map points (one per session), orders below {}",
                cal.paper_points.len(),
                cal.max_order
            ),
        )),
    }
    if let Some((ua, ub)) = &cal.uncertainty {
        facts.push((
            "uncertainty u",
            format!(
                "max {:.4}″ rms {:.4}″ ({}), max {:.4}″ rms {:.4}″ ({}) — standard, at every table point",
                ua.max() * ARCSEC_PER_RAD,
                ua.rms() * ARCSEC_PER_RAD,
                args.a,
                ub.max() * ARCSEC_PER_RAD,
                ub.rms() * ARCSEC_PER_RAD,
                args.b
            ),
        ));
    }
    if let Some(r) = &cal.reference {
        facts.push((
            "vs reference",
            format!(
                "max |difference| {:.3}″ ({}), {:.3}″ ({})",
                r.a_max_diff_arcsec, args.a, r.b_max_diff_arcsec, args.b
            ),
        ));
        if let Some(worst) = r.effective_range.iter().max_by(|x, y| {
            x.predicted_a_arcsec
                .max(x.predicted_b_arcsec)
                .total_cmp(&y.predicted_a_arcsec.max(y.predicted_b_arcsec))
        }) {
            facts.push((
                "sampling",
                format!(
                    "non-uniformity: worst order for the paper method {} (|Y| = {:.4}, predicted residual |Y|·A {:.3}″ as published, {:.3}″ to first order)",
                    worst.order,
                    worst.y,
                    worst.predicted_a_arcsec.max(worst.predicted_b_arcsec),
                    worst.first_order_a_arcsec.max(worst.first_order_b_arcsec)
                ),
            ));
        }
    }
    o += &key_values(&facts);
    let mut t = TextTable::new(&["channel", "p-p before", "→ after", "rms", "largest orders"]);
    for name in [&args.a, &args.b] {
        let ch = &report.channels[name];
        let top: Vec<String> = ch
            .harmonics
            .iter()
            .take(3)
            .map(|h| format!("{}: {:.3}″", h.order, h.amplitude_arcsec))
            .collect();
        let after = ch.after_correction.as_ref().map_or("—".to_string(), |a| {
            let split = a.reference_split.as_ref().map_or(String::new(), |s| {
                format!(
                    " = reference's own {:.3}″ + rest {:.3}″",
                    s.reference_error_arcsec, s.rest_arcsec
                )
            });
            format!("{:.3}″ vs {}{split}", a.peak_to_peak_arcsec, a.against)
        });
        t.row(vec![
            name.clone(),
            format!("{:.3}″", ch.peak_to_peak_arcsec),
            after,
            format!("{:.3}″", ch.rms_arcsec),
            if top.is_empty() {
                "none above the noise".to_string()
            } else {
                top.join(", ")
            },
        ]);
    }
    let _ = writeln!(o, "\n{}", t.render().trim_end());
    if report
        .channels
        .values()
        .all(|c| c.after_correction.is_none())
    {
        let _ = writeln!(
            o,
            "  (→ after: the error left after correction, known with --truth DIR or --ref NAME)"
        );
    } else if report.channels.values().any(|c| {
        c.after_correction
            .as_ref()
            .is_some_and(|a| a.against == "reference" && a.reference_split.is_none())
    }) {
        let _ = writeln!(
            o,
            "  (→ after vs reference: measured by the reference, so it holds the reference's own \
             error too; --ref-table FILE splits it off)"
        );
    }
    let files = vec![
        table_name(&args.a),
        table_name(&args.b),
        "report.json".to_string(),
    ];
    o += &ending(
        &report.warnings,
        out,
        &files,
        "error maps, spectrum with blind orders, session timeline",
    );
    o
}
