//! The report of `calib multihead`.

use crate::document::{harmonics_table, num, provenance};
use calib_core::Report;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::multihead::{Method, MultiheadCalibration};
use calib_report::plots::{self, MapLayers, OrderMarks};
use calib_report::{Document, Section, Table};

/// The document: the scale's map as the first head reads it, its spectrum with the blind and
/// weakly seen orders marked, and every head's estimated angle error.
pub fn document(first: &str, cal: &MultiheadCalibration, report: &Report) -> Document {
    let method = match cal.method {
        Method::Joint => "joint least squares of every head",
        Method::Eda => "equal-division average per head set (EDA)",
    };
    let mut doc = Document::new(
        &format!("Multi-head self-calibration of the scale read by `{first}` — {method}"),
        provenance(report),
    );
    doc.warnings = report.warnings.clone();
    let orders = |o: &[calib_core::multihead::ExcludedOrder]| {
        if o.is_empty() {
            "none".to_string()
        } else {
            o.iter()
                .map(|e| e.order.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        }
    };
    let facts = Table::new("Run", &["quantity", "value"])
        .row(["heads".to_string(), cal.heads.len().to_string()])
        .row([
            "revolutions of the first head".to_string(),
            num(cal.revolutions, 2),
        ])
        .row(["samples used".to_string(), cal.samples.to_string()])
        .row([
            "highest order fitted".to_string(),
            cal.max_order.to_string(),
        ])
        .row(["blind orders (left out)".to_string(), orders(&cal.blind)])
        .row([
            "weakly seen orders (left out)".to_string(),
            orders(&cal.ill_conditioned),
        ])
        .row([
            "fit residual RMS per sample (″)".to_string(),
            cal.residual_rms
                .map_or("—".into(), |r| num(r * ARCSEC_PER_RAD, 4)),
        ]);
    let heads = cal.heads.iter().fold(
        Table::new(
            "Heads: nominal angle and estimated angle error (actual − nominal)",
            &["head", "nominal (°)", "angle error (″)", "residual RMS (″)"],
        ),
        |t, h| {
            t.row([
                h.name.clone(),
                num(h.nominal.to_degrees(), 6),
                num(h.angle_error * ARCSEC_PER_RAD, 4),
                h.residual_rms
                    .map_or("—".into(), |r| num(r * ARCSEC_PER_RAD, 4)),
            ])
        },
    );
    doc.push(Section::new("Summary").table(facts).table(heads));

    let (band_name, band) = crate::document::uncertainty_band(&cal.map, &cal.uncertainty);
    let layers = MapLayers::of(&cal.map).with_band(&band_name, band);
    let mut s = Section::new(&format!("Error map of the scale as `{first}` reads it"))
        .text(&format!(
            "Error = {first}'s reading − true angle (zero mean), as a function of {first}'s \
             reading. Blind orders are not in the map: their part of the scale's error is unknown."
        ))
        .figure(plots::error_map(&format!("map-{first}"), first, &layers));
    if let Some(z) = plots::dominant_order(&cal.map)
        .and_then(|h| plots::zoom(&format!("zoom-{first}"), first, &layers, h))
    {
        s = s.figure(z);
    }
    if let Some(ch) = report.channels.get(first) {
        s = s.table(harmonics_table(first, ch, |o| {
            cal.blind.iter().all(|b| b.order != o)
        }));
    }
    s = s.table(crate::document::uncertainty_table(first, &cal.uncertainty));
    doc.push(s);
    let marks = OrderMarks {
        blind: cal.blind.iter().map(|e| e.order).collect(),
        ill_conditioned: cal.ill_conditioned.iter().map(|e| e.order).collect(),
        ill_conditioned_name: "seen too weakly".into(),
    };
    doc.push(Section::new("Harmonic spectrum").figure(plots::spectrum(
        "spectrum",
        &[(first, plots::amplitudes(&cal.map, cal.max_order.max(1)))],
        &marks,
    )));
    doc
}
