//! The `report.html` documents of the method commands, built from their results with
//! `calib-report`'s plot builders: one module per method.

pub mod csrr;
pub mod multihead;
pub mod reference;
pub mod shift_angle;
pub mod tdr;

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
