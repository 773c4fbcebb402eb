//! What the `report.html` documents of the methods share (each method's own document is in its
//! folder, `crate::method::<m>::document`), built with `calib-report`'s plot builders.

use calib_core::{ChannelReport, Report};
use calib_report::{Provenance, Table};

/// The provenance of a report: version, method, inputs and command line, as in `report.json`.
pub fn provenance(report: &Report) -> Provenance {
    Provenance {
        calib_version: report.calib_version.clone(),
        method: report.method.clone(),
        inputs: report.inputs.clone(),
        command_line: report.command_line.clone(),
    }
}

/// A number with `decimals` decimals, or `—` when it is not finite.
pub fn num(v: f64, decimals: usize) -> String {
    if v.is_finite() {
        format!("{v:.decimals$}")
    } else {
        "—".into()
    }
}

/// The harmonics table of a channel (largest first, as in `report.json`).
pub fn harmonics_table(name: &str, ch: &ChannelReport) -> Table {
    ch.harmonics.iter().fold(
        Table::new(
            &format!("Largest harmonics of {name}: amplitude·cos(order·θ + phase)"),
            &["order (cycles/rev)", "amplitude (″)", "phase (°)"],
        ),
        |t, h| {
            t.row([
                h.order.to_string(),
                num(h.amplitude_arcsec, 4),
                num(h.phase_deg, 2),
            ])
        },
    )
}

/// The band `±2u` around a map (angle °, half-width ″), and its name.
pub fn uncertainty_band(
    map: &calib_core::ErrorMap,
    u: &calib_core::uncertainty::MapUncertainty,
) -> (String, Vec<(f64, f64)>) {
    let band = (0..map.len())
        .map(|i| {
            (
                map.grid_angle(i).to_degrees(),
                2.0 * u.u[i] * calib_core::angle::ARCSEC_PER_RAD,
            )
        })
        .collect();
    ("±2u (standard uncertainty u, k = 2)".to_string(), band)
}

/// The uncertainty budget of a channel's map, GUM style: each component's type and its size
/// over the table (RMS and largest), then the combined standard uncertainty.
pub fn uncertainty_table(name: &str, u: &calib_core::uncertainty::MapUncertainty) -> Table {
    let arcsec = calib_core::angle::ARCSEC_PER_RAD;
    let t = u.components.iter().fold(
        Table::new(
            &format!("Uncertainty budget of {name}'s map (standard uncertainties)"),
            &["component", "type", "RMS over the table (″)", "largest (″)"],
        ),
        |t, c| {
            let largest = c.u.iter().copied().fold(0.0, f64::max);
            t.row([
                c.name.clone(),
                match c.evaluation {
                    calib_core::uncertainty::Evaluation::TypeA => "A".to_string(),
                    calib_core::uncertainty::Evaluation::TypeB => "B".to_string(),
                },
                num(c.rms() * arcsec, 4),
                num(largest * arcsec, 4),
            ])
        },
    );
    t.row([
        "combined standard uncertainty u".to_string(),
        String::new(),
        num(u.rms() * arcsec, 4),
        num(u.max() * arcsec, 4),
    ])
}
