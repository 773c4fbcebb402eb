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

/// An angle in arcseconds with `decimals` decimals, and in degrees too where it is large
/// enough that arcseconds alone are hard to picture (from 0.1°): `2608.1 (0.72°)`.
pub fn arcsec(v: f64, decimals: usize) -> String {
    if v.is_finite() && v.abs() >= 360.0 {
        format!("{} ({}°)", num(v, decimals), num(v / 3600.0, 2))
    } else {
        num(v, decimals)
    }
}

/// The harmonics table of a channel (largest first, as in `report.json`), without the orders
/// the map does not hold (`kept` false, or an amplitude of zero): the summary says they were
/// left out, and a row of zeros under "largest" contradicts it.
pub fn harmonics_table(name: &str, ch: &ChannelReport, kept: impl Fn(usize) -> bool) -> Table {
    ch.harmonics
        .iter()
        .filter(|h| kept(h.order) && h.amplitude_arcsec > 0.0)
        .fold(
            Table::new(
                &format!("Largest harmonics of {name}: amplitude·cos(order·θ + phase)"),
                &["order (cycles/rev)", "amplitude (″)", "phase (°)"],
            ),
            |t, h| {
                t.row([
                    h.order.to_string(),
                    arcsec(h.amplitude_arcsec, 4),
                    num(h.phase_deg, 2),
                ])
            },
        )
}

/// The expanded uncertainty `U = 2u` of a map (angle °, U ″), and its legend.
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
    (calib_report::plots::band_name("2"), band)
}

/// The uncertainty budget of a channel's map, GUM style: each component's type and its size
/// over the table (RMS and largest), then the combined standard uncertainty; the caption ties
/// these u to the U = 2u the figures draw.
pub fn uncertainty_table(name: &str, u: &calib_core::uncertainty::MapUncertainty) -> Table {
    let arcsec_per_rad = calib_core::angle::ARCSEC_PER_RAD;
    let t = u.components.iter().fold(
        Table::new(
            &format!(
                "Uncertainty budget of {name}'s map (standard uncertainties u; the map's figure \
                 draws U = 2u, and the band ±2u around a residual)"
            ),
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
                num(c.rms() * arcsec_per_rad, 4),
                num(largest * arcsec_per_rad, 4),
            ])
        },
    );
    t.row([
        "combined standard uncertainty u".to_string(),
        String::new(),
        num(u.rms() * arcsec_per_rad, 4),
        num(u.max() * arcsec_per_rad, 4),
    ])
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::HarmonicReport;

    #[test]
    fn large_angles_are_also_in_degrees() {
        assert_eq!(arcsec(2608.0, 0), "2608 (0.72°)");
        assert_eq!(arcsec(-400.0, 1), "-400.0 (-0.11°)");
        assert_eq!(arcsec(25.0, 3), "25.000");
        assert_eq!(arcsec(f64::NAN, 3), "—");
    }

    /// Issue 31: the table listed orders the summary said were not kept, with amplitude 0.
    #[test]
    fn harmonics_table_lists_only_the_orders_the_map_holds() {
        let h = |order, amplitude_arcsec| HarmonicReport {
            order,
            amplitude_arcsec,
            phase_deg: 0.0,
        };
        let ch = ChannelReport {
            table: "a.csv".into(),
            points: 3600,
            peak_to_peak_arcsec: 1.0,
            rms_arcsec: 1.0,
            harmonics: vec![h(8, 20.0), h(3, 1.0), h(5, 0.5), h(2, 0.0)],
            after_correction: None,
        };
        let t = harmonics_table("a", &ch, |o| o != 3);
        let orders: Vec<&str> = t.rows.iter().map(|r| r[0].as_str()).collect();
        assert_eq!(orders, ["8", "5"]);
    }
}
