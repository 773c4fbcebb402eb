//! The report of `calib reference`.

use crate::document::{harmonics_table, num, provenance};
use calib_core::Report;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::reference_cal::{ReferenceCalibration, TableMap};
use calib_report::plots::{self, MapLayers, OrderMarks};
use calib_report::{Axis, Chart, Colour, Document, Figure, Mark, Section, Series, Table};

/// Coverage factor of the band drawn around the map.
const K: f64 = 2.0;

/// The ISO 230-2 figures with their symbols and meaning, in the order of `Iso230_2::arcsec`.
fn iso_label(key: &str) -> &'static str {
    match key {
        "systematic_up" => "E↑ systematic positioning deviation, increasing",
        "systematic_down" => "E↓ systematic positioning deviation, decreasing",
        "systematic" => "E bidirectional systematic positioning deviation",
        "mean_bidirectional" => "M mean bidirectional positioning deviation",
        "reversal" => "B reversal value (largest)",
        "mean_reversal" => "B̄ mean reversal value",
        "repeatability_up" => "R↑ unidirectional repeatability, increasing",
        "repeatability_down" => "R↓ unidirectional repeatability, decreasing",
        "repeatability" => "R bidirectional repeatability",
        "accuracy_up" => "A↑ unidirectional accuracy, increasing",
        "accuracy_down" => "A↓ unidirectional accuracy, decreasing",
        "accuracy" => "A bidirectional accuracy",
        _ => "",
    }
}

/// The document.
pub fn document(
    dut: &str,
    reference: &str,
    cal: &ReferenceCalibration,
    report: &Report,
) -> Document {
    let mut doc = Document::new(
        &format!("Calibration of `{dut}` against the reference `{reference}`"),
        provenance(report),
    );
    doc.warnings = report.warnings.clone();
    let u_max = cal.u.iter().fold(0.0f64, |m, u| m.max(*u)) * ARCSEC_PER_RAD;
    // Next to every u: whether it leaves the reference out.
    let excludes = if super::summary::excludes_reference(report) {
        ", u excludes the reference"
    } else {
        ""
    };
    let facts = Table::new("Run", &["quantity", "value"])
        .row(["revolutions".to_string(), num(cal.revolutions, 2)])
        .row([
            "passes per point (fewest), increasing / decreasing".to_string(),
            format!("{} / {}", cal.min_passes.0, cal.min_passes.1),
        ])
        .row([
            format!("largest standard uncertainty u (″){excludes}"),
            num(u_max, 4),
        ])
        .row([
            "map".to_string(),
            match (cal.map.range(), cal.gap) {
                (Some((lo, hi)), _) => format!(
                    "range table, {}° to {}° of the DUT's reading",
                    num(lo.to_degrees(), 3),
                    num(hi.to_degrees(), 3)
                ),
                (None, Some(g)) => format!(
                    "whole turn; {}° never reached from {}°, bridged by interpolation",
                    num(g.size.to_degrees(), 3),
                    num(g.from.to_degrees(), 3)
                ),
                (None, None) => "whole turn".to_string(),
            },
        ])
        .row([
            "ISO 230-2 target positions".to_string(),
            cal.targets.len().to_string(),
        ]);
    let iso = cal.iso.arcsec().into_iter().fold(
        Table::new(
            "ISO 230-2 figures (— where the data cannot give them)",
            &["figure", "value (″)"],
        ),
        |t, (k, v)| {
            t.row([
                iso_label(k).to_string(),
                v.map_or("—".into(), |v| num(v, 4)),
            ])
        },
    );
    doc.push(Section::new("Summary").table(facts).table(iso));

    let points: Vec<(f64, f64)> = (0..cal.map.len())
        .map(|i| {
            (
                cal.map.grid_angle(i).to_degrees(),
                cal.map.values()[i] * ARCSEC_PER_RAD,
            )
        })
        .collect();
    let span = cal
        .map
        .range()
        .map(|(lo, hi)| (lo.to_degrees(), hi.to_degrees()));
    let band: Vec<(f64, f64)> = points
        .iter()
        .zip(&cal.u)
        .map(|(p, u)| (p.0, K * u * ARCSEC_PER_RAD))
        .collect();
    let layers = MapLayers::of_points(points.clone())
        .with_band(&format!("expanded uncertainty (k = {K}){excludes}"), band);
    let mut s = Section::new(&format!("Error map of {dut}")).text(&format!(
        "Error = {dut} − {reference} (mean of both directions, zero mean), as a function of \
         {dut}'s reading; the reference's own error is part of it."
    ));
    match &cal.map {
        TableMap::Turn(map) => {
            s = s.figure(plots::error_map(&format!("map-{dut}"), dut, &layers));
            if let Some(z) = plots::dominant_order(map)
                .and_then(|h| plots::zoom(&format!("zoom-{dut}"), dut, &layers, h))
            {
                s = s.figure(z);
            }
        }
        TableMap::Range(m) => {
            s = s.figure(plots::range_error_map(
                &format!("map-{dut}"),
                dut,
                &layers,
                m.start().to_degrees(),
                m.end().to_degrees(),
            ));
        }
    }
    if cal.min_passes.0 > 0 && cal.min_passes.1 > 0 {
        s = s.figure(directions(dut, cal, &points, span));
    }
    if let (Some(ch), TableMap::Turn(_)) = (report.channels.get(dut), &cal.map) {
        s = s.table(harmonics_table(dut, ch));
    }
    doc.push(s);
    if let TableMap::Turn(map) = &cal.map {
        let orders = (map.len() / 2).saturating_sub(1).clamp(1, 200);
        doc.push(Section::new("Harmonic spectrum").figure(plots::spectrum(
            "spectrum",
            &[(dut, plots::amplitudes(map, orders))],
            &OrderMarks::default(),
        )));
    }
    doc
}

/// Each direction's mean deviation minus the bidirectional map: the residual after correcting
/// by the map, direction by direction (half the reversal, with opposite signs).
fn directions(
    dut: &str,
    cal: &ReferenceCalibration,
    map: &[(f64, f64)],
    span: Option<(f64, f64)>,
) -> Figure {
    let side = |stats: &[calib_core::reference_cal::PointStats]| {
        plots::decimate(
            &map.iter()
                .zip(stats)
                .filter(|(_, s)| s.n > 0)
                .map(|(p, s)| (p.0, s.mean * ARCSEC_PER_RAD - p.1))
                .collect::<Vec<_>>(),
        )
    };
    Figure::new(
        &format!("directions-{dut}"),
        &format!("{dut}: each direction against the corrected map"),
        "Mean deviation of the passes in each direction minus the bidirectional map: what is left \
         after correction when turning one way only (the reversal B is their difference).",
        Chart::new(
            {
                let (lo, hi) = span.unwrap_or((0.0, 360.0));
                Axis::linear(&format!("reading of {dut} (°)")).with_range(lo, hi)
            },
            Axis::linear("deviation − map (″)"),
        )
        .with(Series::new(
            "increasing",
            Mark::Line,
            Colour::Blue,
            side(&cal.up),
        ))
        .with(Series::new(
            "decreasing",
            Mark::Line,
            Colour::Orange,
            side(&cal.down),
        )),
    )
}
