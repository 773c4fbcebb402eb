//! The shift-angle method's output tables: `encoder.csv` and `polygon.csv`.
//!
//! - `encoder.csv`: `angle_deg,error_arcsec,correction_arcsec,u_arcsec`, and with a budget
//!   `expanded_uncertainty_arcsec`; one row per measured angle, sorted. Angles with at most 9
//!   decimals (trailing zeros trimmed: shifts are usually whole or tenths of a degree), errors
//!   and uncertainties with 6. `u_arcsec` is the budget's combined standard uncertainty when a
//!   budget is given, else the fit's own; empty where there is none (the paper's method). The
//!   file reads back with [`crate::points`], as `calib compare` does.
//! - `polygon.csv`: `face,pitch_deviation_arcsec,u_arcsec`, one row per face, 6 decimals.

use crate::table::MAX_TABLE_ARCSEC;
use calib_core::shift_angle::ShiftAngleResult;
use calib_core::uncertainty::BudgetResult;
use std::fmt::Write as _;

/// A value no table may hold: non-finite, or beyond [`MAX_TABLE_ARCSEC`]. Extreme readings
/// solve to numbers no encoder or polygon has, and a wrong table is worse than none.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BadValue {
    /// An encoder point's error or uncertainty.
    #[error(
        "the encoder's error at {angle_deg:.6}° solves to {error_arcsec}″ (u {u_arcsec:?}), not a finite value within \
         ±{MAX_TABLE_ARCSEC}″: check the readings' unit (arcseconds) and values; no table was written"
    )]
    Encoder {
        /// The point's angle, degrees.
        angle_deg: f64,
        /// Its error, arcseconds.
        error_arcsec: f64,
        /// Its standard uncertainty, arcseconds.
        u_arcsec: Option<f64>,
    },
    /// A face's pitch deviation or uncertainty.
    #[error(
        "face {face}'s pitch deviation solves to {pitch_deviation_arcsec}″ (u {u_arcsec:?}), not a finite value within \
         ±{MAX_TABLE_ARCSEC}″: check the readings' unit (arcseconds) and values; no table was written"
    )]
    Polygon {
        /// The face, 1-based.
        face: usize,
        /// Its pitch deviation, arcseconds.
        pitch_deviation_arcsec: f64,
        /// Its standard uncertainty, arcseconds.
        u_arcsec: Option<f64>,
    },
}

/// Checks that every value of `result` can be written: the first one that cannot.
pub fn check_values(result: &ShiftAngleResult) -> Result<(), BadValue> {
    let bad = |v: f64| !v.is_finite() || v.abs() > MAX_TABLE_ARCSEC;
    if let Some(p) = result
        .points
        .iter()
        .find(|p| bad(p.error_arcsec) || p.u_arcsec.is_some_and(bad))
    {
        return Err(BadValue::Encoder {
            angle_deg: p.angle_deg,
            error_arcsec: p.error_arcsec,
            u_arcsec: p.u_arcsec,
        });
    }
    if let Some(f) = result
        .polygon
        .iter()
        .find(|f| bad(f.pitch_deviation_arcsec) || f.u_arcsec.is_some_and(bad))
    {
        return Err(BadValue::Polygon {
            face: f.face,
            pitch_deviation_arcsec: f.pitch_deviation_arcsec,
            u_arcsec: f.u_arcsec,
        });
    }
    Ok(())
}

/// `encoder.csv` (see the [module docs](self)).
pub fn render_encoder(result: &ShiftAngleResult, budget: Option<&BudgetResult>) -> String {
    let mut s = String::from("angle_deg,error_arcsec,correction_arcsec,u_arcsec");
    s += if budget.is_some() {
        ",expanded_uncertainty_arcsec\n"
    } else {
        "\n"
    };
    for p in &result.points {
        let u = match budget {
            Some(b) => Some(b.combined_standard_uncertainty),
            None => p.u_arcsec,
        };
        let _ = write!(
            s,
            "{},{:.6},{:.6},{}",
            deg(p.angle_deg),
            p.error_arcsec,
            -p.error_arcsec,
            opt(u)
        );
        match budget {
            Some(b) => {
                let _ = writeln!(s, ",{:.6}", b.expanded_uncertainty);
            }
            None => s.push('\n'),
        }
    }
    s
}

/// `polygon.csv` (see the [module docs](self)).
pub fn render_polygon(result: &ShiftAngleResult) -> String {
    let mut s = String::from("face,pitch_deviation_arcsec,u_arcsec\n");
    for f in &result.polygon {
        let _ = writeln!(
            s,
            "{},{:.6},{}",
            f.face,
            f.pitch_deviation_arcsec,
            opt(f.u_arcsec)
        );
    }
    s
}

/// A value with 6 decimals, or an empty field.
fn opt(v: Option<f64>) -> String {
    v.map(|v| format!("{v:.6}")).unwrap_or_default()
}

/// Degrees as `encoder.csv` writes them: at most 9 decimals, trailing zeros trimmed.
pub fn deg(v: f64) -> String {
    calib_core::report::trimmed(v, 9)
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::shift_angle::{Method, calibrate};
    use std::path::Path;

    /// The committed readings of the paper's 12-face polygon, calibrated by the joint fit.
    fn result() -> ShiftAngleResult {
        let path = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../testdata/shift-angle/readings.csv"
        ));
        let readings = crate::readings::read_readings(path, None).unwrap();
        calibrate(&readings, Method::Joint).unwrap()
    }

    /// A budget's result, as `--budget` attaches it to every point.
    fn budget() -> BudgetResult {
        BudgetResult {
            level: 0.95,
            combined_standard_uncertainty: 0.0531,
            effective_dof: Some(12),
            effective_dof_unrounded: Some(12.4),
            coverage_factor: 2.18,
            expanded_uncertainty: 0.115758,
            components: Vec::new(),
        }
    }

    #[test]
    fn encoder_csv_reads_back_as_written() {
        let result = result();
        for budget in [None, Some(budget())] {
            let text = render_encoder(&result, budget.as_ref());
            let table =
                crate::points::parse_points(text.as_bytes(), Path::new("encoder.csv")).unwrap();
            assert_eq!(table.points.len(), result.points.len());
            for (read, p) in table.points.iter().zip(&result.points) {
                // 9 decimals of the angle, 6 of the rest: the rounding of the format.
                assert!((read.angle_deg - p.angle_deg).abs() <= 5e-10);
                assert!((read.error_arcsec - p.error_arcsec).abs() <= 5e-7);
                let u = budget
                    .as_ref()
                    .map_or(p.u_arcsec, |b| Some(b.combined_standard_uncertainty));
                let (read_u, u) = (read.u_arcsec.unwrap(), u.unwrap());
                assert!((read_u - u).abs() <= 5e-7);
                assert_eq!(
                    read.expanded_uncertainty_arcsec,
                    budget.as_ref().map(|b| b.expanded_uncertainty)
                );
            }
        }
    }

    #[test]
    fn polygon_csv_reads_back_as_written() {
        let result = result();
        let text = render_polygon(&result);
        let mut reader = csv::Reader::from_reader(text.as_bytes());
        assert_eq!(
            reader.headers().unwrap(),
            vec!["face", "pitch_deviation_arcsec", "u_arcsec"]
        );
        let rows: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
        assert_eq!(rows.len(), result.polygon.len());
        for (row, f) in rows.iter().zip(&result.polygon) {
            assert_eq!(row[0].parse::<usize>().unwrap(), f.face);
            let beta: f64 = row[1].parse().unwrap();
            assert!((beta - f.pitch_deviation_arcsec).abs() <= 5e-7);
            assert_eq!(row[2].is_empty(), f.u_arcsec.is_none());
        }
    }

    #[test]
    fn values_no_table_may_hold_are_refused() {
        let mut result = result();
        assert_eq!(check_values(&result), Ok(()));
        result.polygon[2].pitch_deviation_arcsec = f64::NAN;
        let err = check_values(&result).unwrap_err().to_string();
        assert!(
            err.starts_with("face 3's pitch deviation solves to NaN″"),
            "{err}"
        );
    }
}
