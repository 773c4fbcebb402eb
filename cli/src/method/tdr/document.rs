//! The report of `calib tdr`.

use crate::document::{harmonics_table, num, provenance};
use calib_core::Report;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::tdr::TdrCalibration;
use calib_report::plots::{self, MapLayers, OrderMarks};
use calib_report::{Document, Section, Table};

/// The document: the encoder's map (against the reference when one was logged), its spectrum,
/// the coast that produced it and the orders whose amplitude changes with speed as a drag would.
pub fn document(
    channel: &str,
    reference: Option<&str>,
    cal: &TdrCalibration,
    report: &Report,
) -> Document {
    let mut doc = Document::new(
        &format!("Spin-down self-calibration of `{channel}` (TDR)"),
        provenance(report),
    );
    doc.warnings = report.warnings.clone();
    let rpm = |w: f64| num(w.abs() * 60.0 / std::f64::consts::TAU, 1);
    let facts = Table::new("Coast", &["quantity", "value"])
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

    let (band_name, band) = crate::document::uncertainty_band(&cal.map, &cal.uncertainty);
    let mut layers = MapLayers::of(&cal.map).with_band(&band_name, band);
    if let (Some(r), Some(name)) = (&cal.reference, reference) {
        layers = layers.compared_with(
            &format!("{channel} − {name} (reference)"),
            plots::map_points(&r.map),
        );
    }
    let mut s = Section::new(&format!("Error map of {channel}"))
        .text(&format!(
            "Error = {channel}'s reading − the fitted free motion (zero mean), as a function of \
             its reading. An angle-dependent drag torque (rolling bearings, cogging) shakes the \
             shaft periodically in angle; its imprint grows as 1/ω², so where the coast's speed range \
             allows it is fitted and separated from the map (see the drag table)."
        ))
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
        s = s.table(harmonics_table(channel, ch));
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
                num(d.imprint * ARCSEC_PER_RAD, 4),
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
