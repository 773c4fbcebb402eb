//! The report of `calib reference`.

use crate::document::{arcsec, harmonics_table, num, provenance};
use calib_core::Report;
use calib_core::TableMap;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::reference_cal::{PointStats, ReferenceCalibration, Ripple};
use calib_report::iso230::{self, Direction, Target};
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
            match (cal.map.range_deg(), cal.gap) {
                (Some((lo, hi)), _) => format!(
                    "range table, {}° to {}° of the DUT's reading",
                    num(lo, 3),
                    num(hi, 3)
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
                v.map_or("—".into(), |v| arcsec(v, 4)),
            ])
        },
    );
    doc.push(Section::new("Summary").table(facts).table(iso));

    // A range's readings as its table writes them (−39.8° to 94.7° for a range across 0, not
    // 320.2° to 454.7°): its angles shifted by the whole turns between the two.
    let shift = match (cal.map.range_deg(), cal.map.range()) {
        (Some((lo, _)), Some((start, _))) => lo - start.to_degrees(),
        _ => 0.0,
    };
    let points: Vec<(f64, f64)> = (0..cal.map.len())
        .map(|i| {
            (
                cal.map.grid_angle(i).to_degrees() + shift,
                cal.map.values()[i] * ARCSEC_PER_RAD,
            )
        })
        .collect();
    let span = cal.map.range_deg();
    let band: Vec<(f64, f64)> = points
        .iter()
        .zip(&cal.u)
        .map(|(p, u)| (p.0, K * u * ARCSEC_PER_RAD))
        .collect();
    let band_name = format!("{}{excludes}", plots::band_name(&num(K, 0)));
    let layers = MapLayers::of_points(points.clone()).with_band(&band_name, band.clone());
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
            let (lo, hi) = m.ends_deg();
            s = s.figure(plots::range_error_map(
                &format!("map-{dut}"),
                dut,
                &layers,
                lo,
                hi,
            ));
        }
    }
    if cal.min_passes.0 > 0 && cal.min_passes.1 > 0 {
        s = s.figure(directions(dut, cal, &points, (&band_name, &band), span));
    }
    if let (Some(ch), TableMap::Turn(_)) = (report.channels.get(dut), &cal.map) {
        s = s.table(harmonics_table(dut, ch, |_| true));
    }
    doc.push(s);
    if let Some(r) = &cal.ripple {
        doc.push(ripple(reference, r));
    }
    if !cal.targets.is_empty() {
        doc.push(targets(dut, cal, span, shift));
    }
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

/// A commanded reference's motor ripple, fitted at `k × pole pairs` cycles per revolution and
/// taken out of the map: each term with its standard uncertainty.
fn ripple(reference: &str, r: &Ripple) -> Section {
    let table = r.terms.iter().fold(
        Table::new(
            "Ripple terms",
            &[
                "k (per electrical turn)",
                "order (per revolution)",
                "amplitude (″)",
                "u (″)",
                "phase (°)",
            ],
        ),
        |t, term| {
            t.row([
                term.harmonic.to_string(),
                term.order.to_string(),
                arcsec(term.amplitude * ARCSEC_PER_RAD, 3),
                arcsec(term.u_amplitude * ARCSEC_PER_RAD, 3),
                num(term.phase.to_degrees(), 1),
            ])
        },
    );
    Section::new("Motor ripple taken out")
        .text(&format!(
            "The reference `{reference}` is the angle the motor was commanded to, not where it \
             was: a motor with {} pole pairs lags and leads it periodically in the electrical \
             angle. That ripple ({}″ peak to peak over the map, fitted at {} grid points) was \
             fitted at k × {} cycles per revolution and taken out of the map; the encoder's own \
             error at those orders cannot be told from it.",
            r.pole_pairs,
            num(r.peak_to_peak * ARCSEC_PER_RAD, 3),
            r.fitted_points,
            r.pole_pairs
        ))
        .table(table)
}

/// ISO 230-2's section: the deviation chart over the targets and the per-target table.
/// `shift` (degrees) places the targets' angles in the table's convention, as the map's.
fn targets(dut: &str, cal: &ReferenceCalibration, span: Option<(f64, f64)>, shift: f64) -> Section {
    let side = |p: &PointStats| {
        (p.n > 0).then(|| Direction {
            mean: p.mean * ARCSEC_PER_RAD,
            s: p.s.map(|s| s * ARCSEC_PER_RAD),
        })
    };
    let points: Vec<Target> = cal
        .targets
        .iter()
        .map(|t| Target {
            angle: t.angle.to_degrees() + shift,
            up: side(&t.up),
            down: side(&t.down),
        })
        .collect();
    let cell = |v: Option<f64>| v.map_or("—".to_string(), |v| arcsec(v, 4));
    let table = points.iter().zip(&cal.targets).fold(
        Table::new(
            "ISO 230-2 statistics per target (— where a direction has no pass, or s fewer than two)",
            &[
                "target (°)",
                "passes ↑ / ↓",
                "mean deviation x̄↑ (″)",
                "mean deviation x̄↓ (″)",
                "s↑ (″)",
                "s↓ (″)",
                "reversal B = x̄↑ − x̄↓ (″)",
            ],
        ),
        |t, (p, raw)| {
            let reversal = p.up.zip(p.down).map(|(u, d)| u.mean - d.mean);
            t.row([
                num(p.angle, 3),
                format!("{} / {}", raw.up.n, raw.down.n),
                cell(p.up.map(|d| d.mean)),
                cell(p.down.map(|d| d.mean)),
                cell(p.up.and_then(|d| d.s)),
                cell(p.down.and_then(|d| d.s)),
                cell(reversal),
            ])
        },
    );
    Section::new("ISO 230-2 targets")
        .text(&format!(
            "Deviation = {dut} − reference at each target position, per direction of approach, \
             with the map's constant removed (as in the map)."
        ))
        .figure(iso230::targets_chart(
            &format!("iso-{dut}"),
            dut,
            &points,
            span.unwrap_or((0.0, 360.0)),
        ))
        .table(table)
}

/// Each direction's mean deviation minus the bidirectional map: the residual after correcting
/// by the map, direction by direction (half the reversal, with opposite signs), against the
/// band ±U it is read against.
fn directions(
    dut: &str,
    cal: &ReferenceCalibration,
    map: &[(f64, f64)],
    (band_name, band): (&str, &[(f64, f64)]),
    span: Option<(f64, f64)>,
) -> Figure {
    let side = |stats: &[PointStats]| {
        plots::decimate(
            &map.iter()
                .zip(stats)
                .filter(|(_, s)| s.n > 0)
                .map(|(p, s)| (p.0, s.mean * ARCSEC_PER_RAD - p.1))
                .collect::<Vec<_>>(),
        )
    };
    let (lo, hi) = span.unwrap_or((0.0, 360.0));
    Figure::new(
        &format!("directions-{dut}"),
        &format!("{dut} after correction: each direction against the map"),
        "Mean deviation of the passes in each direction minus the bidirectional map: what is left \
         after correction when turning one way only (the reversal B is their difference), \
         against the map's expanded uncertainty ±U around zero.",
        Chart::new(
            Axis::linear(&format!("reading of {dut} (°)")).with_range(lo, hi),
            Axis::linear("deviation − map (″)"),
        )
        .with(Series::band(
            &plots::band_legend(band_name),
            Colour::Grey,
            plots::decimate(&band.iter().map(|&(x, u)| (x, -u)).collect::<Vec<_>>()),
            plots::decimate(band),
        ))
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
