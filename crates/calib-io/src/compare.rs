//! `compare.csv`, the point-by-point comparison `calib compare` writes:
//! `angle_deg,error1_arcsec,error2_arcsec,difference_arcsec,U1_arcsec,U2_arcsec,En`, one row per
//! compared angle. Angles as they are (shortest exact form), errors, differences and expanded
//! uncertainties with 6 decimals, the normalized error `En` with 4.

use calib_core::compare::Comparison;
use std::fmt::Write as _;

/// The header of `compare.csv`.
pub const HEADER: &str =
    "angle_deg,error1_arcsec,error2_arcsec,difference_arcsec,U1_arcsec,U2_arcsec,En";

/// `compare.csv` (see the [module docs](self)).
pub fn render_compare_csv(c: &Comparison) -> String {
    let mut s = format!("{HEADER}\n");
    for p in &c.points {
        let _ = writeln!(
            s,
            "{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.4}",
            p.angle_deg,
            p.error1_arcsec,
            p.error2_arcsec,
            p.difference_arcsec,
            p.expanded1_arcsec,
            p.expanded2_arcsec,
            p.en
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::compare::{MapPoint, compare};

    #[test]
    fn compare_csv_reads_back_as_written() {
        let map = |scale: f64| -> Vec<MapPoint> {
            (0..36)
                .map(|i| {
                    let angle_deg = 10.0 * i as f64 + 0.125;
                    MapPoint {
                        angle_deg,
                        error_arcsec: scale * (angle_deg.to_radians() * 3.0).sin(),
                        expanded_uncertainty_arcsec: 0.05 * scale,
                    }
                })
                .collect()
        };
        let c = compare(&map(1.0), &map(1.1), false).unwrap();
        let text = render_compare_csv(&c);
        let mut reader = csv::Reader::from_reader(text.as_bytes());
        assert_eq!(
            reader.headers().unwrap(),
            HEADER.split(',').collect::<Vec<_>>()
        );
        let rows: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
        assert_eq!(rows.len(), c.points.len());
        for (row, p) in rows.iter().zip(&c.points) {
            let v: Vec<f64> = row.iter().map(|f| f.parse().unwrap()).collect();
            // Angles exact; 6 decimals, and En 4: the rounding of the format.
            assert_eq!(v[0], p.angle_deg);
            let written = [
                p.error1_arcsec,
                p.error2_arcsec,
                p.difference_arcsec,
                p.expanded1_arcsec,
                p.expanded2_arcsec,
            ];
            for (read, x) in v[1..6].iter().zip(written) {
                assert!((read - x).abs() <= 5e-7, "{read} vs {x}");
            }
            assert!((v[6] - p.en).abs() <= 5e-5);
        }
    }
}
