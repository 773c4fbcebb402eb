//! The summary `calib shift-angle` prints: what was measured and fitted, the encoder's map and
//! the polygon.

use crate::summary::{TextTable, ending, key_values};
use calib_core::Report;
use calib_core::report::shift_angle::Spread;
use calib_core::shift_angle::{self, Method, ShiftAngleResult};
use calib_core::uncertainty::BudgetResult;
use calib_io::shift_angle::deg;
use std::fmt::Write as _;
use std::path::Path;

/// The summary: what was measured and fitted, then the encoder's map and the polygon.
pub(super) fn render_summary(
    out: &Path,
    readings: &shift_angle::Readings,
    result: &ShiftAngleResult,
    budget: Option<&BudgetResult>,
    report: &Report,
) -> String {
    let estimator = match result.method {
        Method::Joint => "joint least-squares fit",
        Method::Paper => "the paper's two steps",
    };
    let mut s = format!("shift-angle calibration ({estimator})\n\n");
    s += &key_values(&summary_facts(readings, result, budget));
    let table = summary_table(readings.faces(), result, report);
    let _ = writeln!(s, "\n{}", table.render().trim_end());
    s += &ending(
        &report.warnings,
        out,
        &[
            "encoder.csv".into(),
            "polygon.csv".into(),
            "report.json".into(),
        ],
        "encoder map with its uncertainty band, pitch deviations, fit residuals",
    );
    s
}

/// The facts above the summary's table: the readings, the fit, the blind orders, the sin-fit
/// check and the budget.
pub(super) fn summary_facts(
    readings: &shift_angle::Readings,
    result: &ShiftAngleResult,
    budget: Option<&BudgetResult>,
) -> Vec<(&'static str, String)> {
    let n = readings.faces();
    let shifts = readings.shifts();
    let r = &result.residuals;
    let mut facts = vec![
        (
            "readings",
            format!(
                "{} of a {n}-face polygon, {} shift(s) {}°…{}°",
                readings.len(),
                shifts.len(),
                deg(shifts[0].shift_deg),
                deg(shifts[shifts.len() - 1].shift_deg),
            ),
        ),
        (
            "fit residual",
            format!(
                "RMS {:.4}″{}, largest {:.4}″ at shift {}°, start face {}, step {}",
                r.rms_arcsec,
                r.sigma_arcsec
                    .map(|sigma| format!(", σ̂ {sigma:.4}″ ({} dof)", r.dof))
                    .unwrap_or_default(),
                r.max_abs_arcsec,
                deg(r.max_at_shift_deg),
                r.max_at_start_face,
                r.max_at_step
            ),
        ),
        (
            "blind",
            format!(
                "harmonic orders {n}, {}, … of the encoder error are invisible to this method",
                2 * n
            ),
        ),
    ];
    let sf = &result.sin_fit;
    facts.push((
        "sin-fit check",
        format!(
            "A = {:.4}″, B = {:.4} rad from S = {}°; max |U_fit − U| = {:.1e}″",
            sf.amplitude_arcsec,
            sf.phase_rad,
            deg(sf.reference_shift_deg),
            result.sin_fit_worst_difference()
        ),
    ));
    if let Some(b) = budget {
        facts.push((
            "budget",
            format!(
                "u_c = {:.4}″, ν_eff = {}, k = {:.3}, U = {:.4}″ ({} %), attached to every point",
                b.combined_standard_uncertainty,
                b.effective_dof
                    .map(|d| d.to_string())
                    .unwrap_or_else(|| "∞".into()),
                b.coverage_factor,
                b.expanded_uncertainty,
                b.level * 100.0
            ),
        ));
    }
    facts
}

/// The range of standard uncertainties, or `—` for none.
pub(super) fn u_range(spread: Option<Spread>) -> String {
    spread.map_or("—".to_string(), |u| format!("{:.4}…{:.4}″", u.min, u.max))
}

/// The summary's table: the encoder's map (from the report) and the polygon of `faces` faces.
pub(super) fn summary_table(faces: usize, result: &ShiftAngleResult, report: &Report) -> TextTable {
    let mut t = TextTable::new(&["", "points", "p-p", "rms", "fit u", "largest"]);
    if let Some(enc) = report.channels.get("encoder") {
        let top: Vec<String> = enc
            .harmonics
            .iter()
            .take(3)
            .map(|h| format!("order {} {:.4}″", h.order, h.amplitude_arcsec))
            .collect();
        t.row(vec![
            "encoder".into(),
            format!("{} points", enc.points),
            format!("{:.4}″", enc.peak_to_peak_arcsec),
            format!("{:.4}″", enc.rms_arcsec),
            u_range(result.point_u_spread()),
            top.join(", "),
        ]);
    }
    if let Some(beta) = result.pitch_spread() {
        t.row(vec![
            "polygon β".into(),
            format!("{faces} faces"),
            format!("{:.4}″", beta.max - beta.min),
            format!("{:.4}″", beta.rms),
            u_range(result.face_u_spread()),
            format!("{:+.4}″ … {:+.4}″ (Σβ = 0)", beta.min, beta.max),
        ]);
    }
    t
}
