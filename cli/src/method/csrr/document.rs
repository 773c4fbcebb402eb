//! The report of `calib csrr`.

use crate::document::{arcsec, harmonics_table, num, provenance};
use calib_core::ErrorMap;
use calib_core::Report;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::csrr::{Calibration, Method};
use calib_core::report::csrr::ILL_CONDITIONED;
use calib_report::plots::{self, MapLayers, OrderMarks, TimelinePanel};
use calib_report::trace::Trace;
use calib_report::{Document, Section, Span, Table};

/// The truth maps of A and B, where given (`--truth`).
type Truth<'a> = Option<(&'a ErrorMap, &'a ErrorMap)>;

/// `layers` compared with what channel A (`a = true`) or B is checked against: its truth map,
/// else the reference's reading at every sample (drawn binned over the angle).
fn compared(layers: MapLayers, cal: &Calibration, truth: Truth, a: bool) -> MapLayers {
    if let Some((ta, tb)) = truth {
        return layers.compared_with("truth", plots::map_points(if a { ta } else { tb }));
    }
    let Some(r) = cal.reference.as_ref() else {
        return layers;
    };
    let pts = if a {
        &r.a_vs_reference
    } else {
        &r.b_vs_reference
    };
    layers.compared_with_samples(
        "reference measurement",
        pts.iter()
            .map(|(x, e)| (x.to_degrees(), e * ARCSEC_PER_RAD))
            .collect(),
    )
}

/// Whether an order is in the maps: not left out as blind and, with the joint method, kept
/// above the noise.
fn kept(cal: &Calibration, order: usize) -> bool {
    cal.excluded.iter().all(|e| e.order != order)
        && (cal.method != Method::Joint || cal.orders.contains(&order))
}

/// The document. `trace` holds three channels: A's and B's rotation (revolutions, unwrapped)
/// and their relative angle (degrees).
pub fn document(
    names: (&str, &str),
    cal: &Calibration,
    report: &Report,
    trace: &Trace,
    truth: Truth,
) -> Document {
    let (na, nb) = names;
    let mut doc = Document::new(
        &format!("CSRR self-calibration of `{na}` and `{nb}`"),
        provenance(report),
    );
    doc.warnings = report.warnings.clone();
    doc.push(summary(names, cal, report));
    doc.push(sessions(names, cal, trace));
    for (name, map, a) in [(na, &cal.a, true), (nb, &cal.b, false)] {
        let mut layers = MapLayers::of(map);
        let u = cal
            .uncertainty
            .as_ref()
            .map(|(ua, ub)| if a { ua } else { ub });
        if let Some(u) = u {
            let (band_name, band) = crate::document::uncertainty_band(map, u);
            layers = layers.with_band(&band_name, band);
        }
        layers = compared(layers, cal, truth, a);
        let mut s = Section::new(&format!("Sensor {name}")).figure(plots::error_map(
            &format!("map-{name}"),
            name,
            &layers,
        ));
        if let Some(z) = plots::dominant_order(map)
            .and_then(|h| plots::zoom(&format!("zoom-{name}"), name, &layers, h))
        {
            s = s.figure(z);
        }
        if let Some(ch) = report.channels.get(name) {
            s = s.table(harmonics_table(name, ch, |o| kept(cal, o)));
        }
        if let Some(u) = u {
            s = s.table(crate::document::uncertainty_table(name, u));
        }
        doc.push(s);
    }
    doc.push(spectrum(names, cal));
    if let Some(r) = &cal.reference {
        let y: Vec<(usize, f64)> = r.effective_range.iter().map(|e| (e.order, e.y)).collect();
        let table = r.effective_range.iter().zip(&r.eps_theta).fold(
            Table::new(
                "Sampling non-uniformity ε_θ and the paper method's predicted residual, per order",
                &[
                    "order Ω",
                    "m_Ω (″)",
                    "|Y_Ω| (1)",
                    &format!("|Y|·A {na} (″)"),
                    &format!("|Y|·A {nb} (″)"),
                ],
            ),
            |t, (e, m)| {
                t.row([
                    e.order.to_string(),
                    num(m.amplitude_arcsec, 4),
                    num(e.y, 5),
                    num(e.predicted_a_arcsec, 4),
                    num(e.predicted_b_arcsec, 4),
                ])
            },
        );
        doc.push(
            Section::new("Reference encoder check")
                .text(&format!(
                    "Largest |map − map against the reference|: {} ″ ({na}), {} ″ ({nb}); the \
                     reference's own error is part of the difference.",
                    arcsec(r.a_max_diff_arcsec, 3),
                    arcsec(r.b_max_diff_arcsec, 3)
                ))
                .figure(plots::y_chart("effective-range", &y))
                .table(table),
        );
    }
    doc
}

fn summary(names: (&str, &str), cal: &Calibration, report: &Report) -> Section {
    let solver = match cal.method {
        Method::Joint => "joint least squares",
        Method::Paper => "paper (eqs. 4–7)",
    };
    let mut t = Table::new("Result", &["quantity", "value"])
        .row(["solver".to_string(), solver.to_string()])
        .row(["sessions used".to_string(), cal.sessions.len().to_string()])
        .row(["orders".to_string(), super::summary::orders_text(cal)]);
    if let Some(r) = cal.residual_rms {
        t = t
            .row([
                "fit residual RMS per sample (″)".to_string(),
                num(r * ARCSEC_PER_RAD, 4),
            ])
            .row(["solver iterations".to_string(), cal.iterations.to_string()]);
    }
    if let Some(adv) = cal.advice {
        t = t.row([
            "one more session at (°)".to_string(),
            format!(
                "{:.1} (would raise the worst observability to {:.2})",
                adv.extra_rotation.to_degrees(),
                adv.min_observability
            ),
        ]);
    }
    let mut channels = Table::new(
        "Maps (error = reading − true angle, zero mean)",
        &[
            "channel",
            "table",
            "peak to peak (″)",
            "RMS (″)",
            "after correction, peak to peak (″)",
        ],
    );
    for name in [names.0, names.1] {
        if let Some(ch) = report.channels.get(name) {
            let after = ch.after_correction.as_ref().map_or(
                "— (no truth or reference)".to_string(),
                |a| match (&a.reference_split, a.against.as_str()) {
                    (Some(s), _) => format!(
                        "{} against the reference: its own error explains {}, the rest is {}",
                        arcsec(a.peak_to_peak_arcsec, 3),
                        arcsec(s.reference_error_arcsec, 3),
                        arcsec(s.rest_arcsec, 3)
                    ),
                    (None, "reference") => format!(
                        "{} against the reference (its own error included)",
                        arcsec(a.peak_to_peak_arcsec, 3)
                    ),
                    (None, against) => {
                        format!("{} against the {against}", arcsec(a.peak_to_peak_arcsec, 3))
                    }
                },
            );
            channels = channels.row([
                name.to_string(),
                ch.table.clone(),
                arcsec(ch.peak_to_peak_arcsec, 3),
                arcsec(ch.rms_arcsec, 3),
                after,
            ]);
        }
    }
    Section::new("Summary").table(t).table(channels)
}

/// The session timeline and the sessions' table, both on the trace's clock (report.json gives
/// the sessions on the log's own clock, stamps since 1970 where the log has them).
fn sessions(names: (&str, &str), cal: &Calibration, trace: &Trace) -> Section {
    let spans: Vec<Span> = cal
        .sessions
        .iter()
        .map(|s| Span {
            from: s.start_s,
            to: s.end_s,
            label: format!("#{}", s.index),
        })
        .collect();
    let fig = plots::timeline(
        "timeline",
        "Session timeline",
        &format!(
            "Top: rotation of {} and {} (revolutions, unwrapped); bottom: their relative angle. \
             Shaded: the sessions used, numbered as in the table.",
            names.0, names.1
        ),
        trace,
        &[
            TimelinePanel {
                label: "rotation (rev)".into(),
                channels: vec![0, 1],
            },
            TimelinePanel {
                label: format!("{} − {} (°)", names.0, names.1),
                channels: vec![2],
            },
        ],
        &spans,
    );
    let table = cal.sessions.iter().fold(
        Table::new(
            "Sessions (times on the timeline's clock)",
            &[
                "#",
                "start (s)",
                "end (s)",
                "revolutions",
                "samples",
                "relative rotation Δ (°)",
            ],
        ),
        |t, s| {
            t.row([
                s.index.to_string(),
                num(s.start_s, 3),
                num(s.end_s, 3),
                num(s.revolutions, 2),
                s.samples.to_string(),
                num(s.relative_rotation.to_degrees(), 4),
            ])
        },
    );
    Section::new("Sessions").figure(fig).table(table)
}

fn spectrum(names: (&str, &str), cal: &Calibration) -> Section {
    let marks = OrderMarks {
        blind: cal.excluded.iter().map(|e| e.order).collect(),
        ill_conditioned: cal.ill_conditioned_orders(),
        ill_conditioned_name: format!("ill-conditioned (observability < {ILL_CONDITIONED})"),
    };
    let max = cal.max_order.max(1);
    let fig = plots::spectrum(
        "spectrum",
        &[
            (names.0, plots::amplitudes(&cal.a, max)),
            (names.1, plots::amplitudes(&cal.b, max)),
        ],
        &marks,
    );
    let mut s = Section::new("Harmonic spectrum").figure(fig);
    if !cal.excluded.is_empty() {
        s = s.table(cal.excluded.iter().fold(
            Table::new(
                "Orders left out: the sessions' relative rotations cannot separate them",
                &["order", "observability (0 blind … 1 ideal)"],
            ),
            |t, e| t.row([e.order.to_string(), num(e.observability, 4)]),
        ));
    }
    s
}
