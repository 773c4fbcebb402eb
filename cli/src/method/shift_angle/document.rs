//! The report of `calib shift-angle`.

use crate::document::{harmonics_table, num, provenance};
use calib_core::Report;
use calib_core::shift_angle::{Method, Readings, ShiftAngleResult};
use calib_core::uncertainty::BudgetResult;
use calib_report::plots::{self, MapLayers, OrderMarks};
use calib_report::{Document, Section, Table};

/// The document: summary, encoder map, polygon, fit residuals.
pub fn document(
    readings: &Readings,
    result: &ShiftAngleResult,
    budget: Option<&BudgetResult>,
    report: &Report,
) -> Document {
    let n = readings.faces();
    let mut doc = Document::new(
        &format!("Shift-angle calibration of an encoder with a {n}-face polygon"),
        provenance(report),
    );
    doc.warnings = report.warnings.clone();
    doc.push(summary(readings, result, budget, report));
    doc.push(encoder(n, result, budget, report));
    doc.push(polygon(result));
    doc.push(residuals(result));
    doc
}

/// The encoder's map with its uncertainty band: the budget's expanded uncertainty where given,
/// else twice the fit's standard uncertainty (none for the paper's method).
fn encoder_layers(result: &ShiftAngleResult, budget: Option<&BudgetResult>) -> MapLayers {
    let points: Vec<(f64, f64)> = result
        .points
        .iter()
        .map(|p| (p.angle_deg, p.error_arcsec))
        .collect();
    let band = match budget {
        Some(b) => Some((
            calib_report::plots::band_name(&format!("{:.3}, budget", b.coverage_factor)),
            vec![b.expanded_uncertainty; points.len()],
        )),
        None => result
            .points
            .iter()
            .map(|p| p.u_arcsec.map(|u| 2.0 * u))
            .collect::<Option<Vec<f64>>>()
            .map(|u| (calib_report::plots::band_name("2, fit"), u)),
    };
    let layers = MapLayers::of_points(points.clone());
    match band {
        Some((name, half)) => layers.with_band(
            &name,
            points.iter().zip(half).map(|(p, h)| (p.0, h)).collect(),
        ),
        None => layers,
    }
}

/// The encoder's error: its map, and where the points are a uniform grid its zoom, spectrum
/// (orders that are multiples of the `n` faces blind) and harmonics.
fn encoder(
    n: usize,
    result: &ShiftAngleResult,
    budget: Option<&BudgetResult>,
    report: &Report,
) -> Section {
    let layers = encoder_layers(result, budget);
    let mut enc = Section::new("Encoder error")
        .text(&format!(
            "The encoder's error α (reading − true angle, zero mean) at each of the {} measured \
             angles.",
            result.points.len()
        ))
        .figure(plots::error_map("map-encoder", "encoder", &layers));
    let uniform = report
        .channels
        .get("encoder")
        .filter(|c| !c.harmonics.is_empty())
        .zip(result.uniform_map());
    if let Some((ch, map)) = uniform {
        if let Some(z) = plots::dominant_order(&map)
            .and_then(|h| plots::zoom("zoom-encoder", "encoder", &layers, h))
        {
            enc = enc.figure(z);
        }
        let max_order = (map.len() / 2).saturating_sub(1).clamp(1, 4 * n);
        enc = enc
            .figure(plots::spectrum(
                "spectrum",
                &[("encoder", plots::amplitudes(&map, max_order))],
                &OrderMarks {
                    blind: (1..=max_order).filter(|h| h % n == 0).collect(),
                    ..OrderMarks::default()
                },
            ))
            .table(harmonics_table("the encoder", ch, |o| o % n != 0));
    }
    enc
}

/// The polygon's pitch deviations, as bars and a table.
fn polygon(result: &ShiftAngleResult) -> Section {
    let beta: Vec<(usize, f64)> = result
        .polygon
        .iter()
        .map(|f| (f.face, f.pitch_deviation_arcsec))
        .collect();
    let table = result.polygon.iter().fold(
        Table::new(
            "Pitch deviations β (pitch angle − 360°/n; Σβ = 0)",
            &["face", "β (″)", "standard uncertainty u (″)"],
        ),
        |t, f| {
            t.row([
                f.face.to_string(),
                num(f.pitch_deviation_arcsec, 4),
                f.u_arcsec.map_or("—".into(), |u| num(u, 4)),
            ])
        },
    );
    Section::new("Polygon")
        .figure(plots::bar_chart(
            "polygon",
            "Pitch deviations of the polygon",
            "Each face's pitch angle minus 360°/n, calibrated together with the encoder.",
            "face",
            "pitch deviation β (″)",
            &beta,
        ))
        .table(table)
}

/// The residuals of every reading, one series per start face (or one for all beyond four), and
/// the sin-fit check.
fn residuals(result: &ShiftAngleResult) -> Section {
    let mut by_face: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for r in &result.reading_residuals {
        let name = format!("start face {}", r.start_face);
        match by_face.iter_mut().find(|(n, _)| *n == name) {
            Some((_, v)) => v.push((r.angle_deg, r.residual_arcsec)),
            None => by_face.push((name, vec![(r.angle_deg, r.residual_arcsec)])),
        }
    }
    if by_face.len() > 4 {
        let all = by_face.into_iter().flat_map(|(_, v)| v).collect();
        by_face = vec![("every reading".to_string(), all)];
    }
    let series: Vec<(&str, Vec<(f64, f64)>)> = by_face
        .iter()
        .map(|(n, v)| (n.as_str(), v.clone()))
        .collect();
    Section::new("Fit residuals")
        .figure(plots::scatter(
            "residuals",
            "Residuals of the fit, per reading",
            "Autocollimator reading minus the fitted model, at the encoder angle of the reading: \
             noise should look the same everywhere; a lone outlier is a misread. A shift read \
             from one start face only has no redundancy: its readings fit exactly (residual 0).",
            ("encoder angle (°)", "residual (″)"),
            &series,
        ))
        .table(sin_fit_table(result))
}

/// The sin-fit check of the paper's section 3.1, per shift.
fn sin_fit_table(result: &ShiftAngleResult) -> Table {
    result.sin_fit.shifts.iter().fold(
        Table::new(
            &format!(
                "Sin-fit check (section 3.1): A = {} ″, B = {} rad fitted at S = {}°",
                num(result.sin_fit.amplitude_arcsec, 4),
                num(result.sin_fit.phase_rad, 4),
                result.sin_fit.reference_shift_deg
            ),
            &[
                "shift S (°)",
                "start face",
                "U_fit (″)",
                "U (″)",
                "U_fit − U (″)",
                "residual RMS (″)",
            ],
        ),
        |t, s| {
            t.row([
                s.shift_deg.to_string(),
                s.start_face.to_string(),
                num(s.u_fit_arcsec, 4),
                num(s.u_estimate_arcsec, 4),
                num(s.difference_arcsec, 5),
                num(s.residual_rms_arcsec, 4),
            ])
        },
    )
}

fn summary(
    readings: &Readings,
    result: &ShiftAngleResult,
    budget: Option<&BudgetResult>,
    report: &Report,
) -> Section {
    let n = readings.faces();
    let r = &result.residuals;
    let mut t = Table::new("Result", &["quantity", "value"])
        .row([
            "estimator".to_string(),
            match result.method {
                Method::Joint => "joint least-squares fit".to_string(),
                Method::Paper => "the paper's two steps".to_string(),
            },
        ])
        .row(["faces n".to_string(), n.to_string()])
        .row(["shifts".to_string(), readings.shifts().len().to_string()])
        .row(["readings".to_string(), readings.len().to_string()]);
    if let Some(enc) = report.channels.get("encoder") {
        t = t
            .row(["encoder points".to_string(), enc.points.to_string()])
            .row([
                "encoder error, peak to peak (″)".to_string(),
                num(enc.peak_to_peak_arcsec, 4),
            ])
            .row(["encoder error, RMS (″)".to_string(), num(enc.rms_arcsec, 4)]);
    }
    t = t
        .row(["residual RMS (″)".to_string(), num(r.rms_arcsec, 4)])
        .row([
            "experimental standard deviation of a reading σ̂ (″)".to_string(),
            r.sigma_arcsec
                .map_or("— (no redundancy)".into(), |s| num(s, 4)),
        ])
        .row(["residual degrees of freedom".to_string(), r.dof.to_string()])
        .row([
            "largest residual (″)".to_string(),
            format!(
                "{} at shift {}°, start face {}, step {}",
                num(r.max_abs_arcsec, 4),
                r.max_at_shift_deg,
                r.max_at_start_face,
                r.max_at_step
            ),
        ])
        .row([
            "blind harmonic orders".to_string(),
            format!("multiples of {n} ({n}, {}, …)", 2 * n),
        ]);
    if let Some(b) = budget {
        t = t
            .row([
                "combined standard uncertainty u_c (″)".to_string(),
                num(b.combined_standard_uncertainty, 4),
            ])
            .row([
                "effective degrees of freedom ν_eff".to_string(),
                b.effective_dof.map_or("∞".into(), |d| d.to_string()),
            ])
            .row(["coverage factor k".to_string(), num(b.coverage_factor, 3)])
            .row([
                format!("expanded uncertainty U ({} %) (″)", b.level * 100.0),
                num(b.expanded_uncertainty, 4),
            ]);
    }
    Section::new("Summary").table(t)
}
