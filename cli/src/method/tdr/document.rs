//! The report of `calib tdr`.

use crate::document::{arcsec, harmonics_table, num, provenance};
use calib_core::Report;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::tdr::TdrCalibration;
use calib_report::plots::{self, MapLayers, OrderMarks};
use calib_report::{Axis, Chart, Colour, Document, Figure, Mark, Section, Series, Table};

/// Points the fitted speed is drawn with over the coast.
const SPEED_POINTS: usize = 600;

/// The document: the encoder's map (against the reference when one was logged), its spectrum,
/// the coast that produced it and the orders whose amplitude changes with speed as a drag would.
pub fn document(
    channel: &str,
    reference: Option<&str>,
    cal: &TdrCalibration,
    report: &Report,
) -> Document {
    let driven = cal.driven.is_some();
    let (kind, run) = if driven {
        ("Driven-run", "Run")
    } else {
        ("Spin-down", "Coast")
    };
    let mut doc = Document::new(
        &format!("{kind} self-calibration of `{channel}` (TDR)"),
        provenance(report),
    );
    doc.warnings = report.warnings.clone();
    let rpm = |w: f64| num(w.abs() * 60.0 / std::f64::consts::TAU, 1);
    let facts = Table::new(run, &["quantity", "value"])
        .row(["revolutions used".to_string(), num(cal.revolutions, 1)])
        .row([
            "speed, start → end (r/min)".to_string(),
            format!("{} → {}", rpm(cal.speed_start), rpm(cal.speed_end)),
        ])
        .row(["samples used".to_string(), cal.samples_used.to_string()])
        .row([
            "fit residual RMS (″)".to_string(),
            num(cal.residual_rms * ARCSEC_PER_RAD, 4),
        ]);
    doc.push(Section::new("Summary").table(facts));
    doc.push(Section::new(run).figure(coast(channel, cal)));

    let (band_name, band) = crate::document::uncertainty_band(&cal.map, &cal.uncertainty);
    let mut layers = MapLayers::of(&cal.map).with_band(&band_name, band);
    if let (Some(r), Some(name)) = (&cal.reference, reference) {
        layers = layers.compared_with(
            &format!("{channel} − {name} (reference)"),
            plots::map_points(&r.map),
        );
    }
    let mut s = Section::new(&format!("Error map of {channel}"))
        .text(&if driven {
            format!(
                "Error = {channel}'s reading − the fitted smooth motion (zero mean), as a function \
                 of its reading. The motor's cogging and torque ripple shake the shaft at its \
                 orders (k × 6 × pole pairs): at one speed they cannot be told from the encoder's \
                 error and are left out of the map and listed; with passes at two or more speeds \
                 they are separated by their 1/ω² dependence (report.json details.driven)."
            )
        } else {
            format!(
                "Error = {channel}'s reading − the fitted free motion (zero mean), as a function of \
                 its reading. An angle-dependent drag torque (rolling bearings, cogging) shakes the \
                 shaft periodically in angle; its imprint grows as 1/ω², so where the coast's speed \
                 range allows it is fitted and separated from the map (see the drag table)."
            )
        })
        .figure(plots::error_map(
            &format!("map-{channel}"),
            channel,
            &layers,
        ));
    if let Some(z) = plots::dominant_order(&cal.map)
        .and_then(|h| plots::zoom(&format!("zoom-{channel}"), channel, &layers, h))
    {
        s = s.figure(z);
    }
    if let Some(ch) = report.channels.get(channel) {
        s = s.table(harmonics_table(channel, ch, |o| cal.orders.contains(&o)));
    }
    s = s.table(crate::document::uncertainty_table(
        channel,
        &cal.uncertainty,
    ));
    doc.push(s);
    let marks = if cal.drag_separation.separated {
        OrderMarks {
            blind: Vec::new(),
            ill_conditioned: cal.drag.iter().map(|d| d.deceleration.order).collect(),
            ill_conditioned_name: "drag separated here".into(),
        }
    } else {
        OrderMarks {
            blind: Vec::new(),
            ill_conditioned: cal
                .speed_dependence
                .iter()
                .map(|d| d.harmonic.order)
                .collect(),
            ill_conditioned_name: "changes with speed like a drag".into(),
        }
    };
    if !cal.drag.is_empty() {
        let mut table = Table::new(
            "Angle-dependent drag separated from the map",
            &[
                "order",
                "deceleration (rad/s²)",
                "phase (°)",
                "imprint at mean 1/ω² (″)",
                "u (″)",
            ],
        );
        for d in &cal.drag {
            let h = d.deceleration.to_report();
            table = table.row([
                h.order.to_string(),
                num(d.deceleration.amplitude, 5),
                num(h.phase_deg, 1),
                arcsec(d.imprint * ARCSEC_PER_RAD, 4),
                num(d.u_imprint * ARCSEC_PER_RAD, 4),
            ]);
        }
        doc.push(
            Section::new("Drag")
                .text(&format!(
                    "The shaft's deceleration a_h·cos(hθ + φ) shakes it by a_h/(h·ω)² at order h; \
                     fitted jointly with the map over the coast's speed range (1/ω² varies by \
                     {:.0} % RMS) and removed from it.",
                    100.0 * cal.drag_separation.variation
                ))
                .figure(drag(channel, cal))
                .table(table),
        );
    }
    let orders = cal.series.max_order().max(1);
    doc.push(Section::new("Harmonic spectrum").figure(plots::spectrum(
        "spectrum",
        &[(channel, plots::amplitudes(&cal.map, orders))],
        &marks,
    )));
    doc
}

/// The coast the map came from: the speed measured over it against the fitted free motion's,
/// and what the fit left of the readings over time (a drift or a step there is an effect the
/// model lacks: a drive still engaged, a knock, a clock jump).
fn coast(channel: &str, cal: &TdrCalibration) -> Figure {
    let m = &cal.motion;
    let t0 = m.t_start;
    let rpm = 60.0 / std::f64::consts::TAU;
    let time = || Axis::linear("time from the coast's start (s)").with_range(0.0, m.t_end - t0);
    let fitted = (0..=SPEED_POINTS).map(|i| {
        let t = t0 + (m.t_end - t0) * i as f64 / SPEED_POINTS as f64;
        (t - t0, m.eval(t).1.abs() * rpm)
    });
    let speed = Chart::new(time(), Axis::linear("speed (r/min)"))
        .with(Series::new(
            "measured (mean over each interval)",
            Mark::Dots,
            Colour::Grey,
            cal.coast.iter().map(|b| (b.t - t0, b.speed * rpm)),
        ))
        .with(Series::new(
            "fitted free motion",
            Mark::Line,
            Colour::Blue,
            fitted,
        ));
    let residual = Chart::new(time(), Axis::linear("fit residual (″)"))
        .with(Series::band(
            "smallest to largest in each interval",
            Colour::Orange,
            cal.coast
                .iter()
                .map(|b| (b.t - t0, b.residual_min * ARCSEC_PER_RAD)),
            cal.coast
                .iter()
                .map(|b| (b.t - t0, b.residual_max * ARCSEC_PER_RAD)),
        ))
        .with(Series::new(
            "mean in each interval",
            Mark::Line,
            Colour::Red,
            cal.coast
                .iter()
                .map(|b| (b.t - t0, b.residual_mean * ARCSEC_PER_RAD)),
        ));
    let mut f = Figure::stacked(
        "coast",
        &format!("The coast of {channel}"),
        &format!(
            "Top: the shaft's speed over the coast used ({} samples in {} intervals), measured \
             from the readings and from the fitted free motion (a smooth polynomial of degree {}). \
             Bottom: the final fit's residual (reading − motion − map − drag) over time; it should \
             be flat noise.",
            cal.samples_used,
            cal.coast.len(),
            m.degree
        ),
        vec![speed, residual],
    );
    f.panel_height = 300;
    f
}

/// The drag separated from the map, as the deceleration it puts on the shaft over one turn.
fn drag(channel: &str, cal: &TdrCalibration) -> Figure {
    let points = (0..=720).map(|i| {
        let deg = i as f64 * 0.5;
        let theta = deg.to_radians();
        let a: f64 = cal.drag.iter().map(|d| d.deceleration.eval(theta)).sum();
        (deg, a)
    });
    Figure::new(
        "drag",
        &format!("Angle-dependent drag on the shaft of {channel}"),
        "The deceleration Σ a_h·cos(hθ + φ_h) fitted jointly with the map and removed from it, over \
         one turn of the reading: bearings and cogging drag the shaft harder at some angles.",
        Chart::new(
            Axis::linear(&format!("reading of {channel} (°)")).with_range(0.0, 360.0),
            Axis::linear("deceleration (rad/s²)"),
        )
        .with(Series::new(
            "drag deceleration",
            Mark::Line,
            Colour::Purple,
            points,
        )),
    )
}
