//! Generic look-up tables for firmware of one's own: `lut-f32-rad`, `lut-i16`, `lut-u16`,
//! `lut-i8` (one value per line), `c-array` (a C header) and `csv`.
//!
//! Every one holds the **correction** (`−error`) at reading `i·360/N`, to be interpolated linearly
//! and periodically and added to the reading (a range table: at `LO + i·(HI − LO)/(N − 1)`, not
//! periodic, readings outside the range left alone). Integer tables carry a scale in arcseconds per
//! code: `correction = code × scale` (`lut-u16`: `(code − 32768) × scale`), the scale the one
//! given or the smallest that holds the table, never one that saturates.

use super::{ExportError, ExportOptions, Format, Rendered, quantize};
use crate::table::push_fixed;
use calib_core::TableMap;
use calib_core::angle::ARCSEC_PER_RAD;
use std::fmt::Write as _;

/// Renders `target` (errors in radians, one per entry of the output grid spread over `source`'s
/// whole turn or range, [`TableMap::grid_deg`]) in one of the generic formats.
pub(super) fn render(
    source: &TableMap,
    target: &[f64],
    opts: &ExportOptions,
) -> Result<Rendered, ExportError> {
    let n = target.len();
    let c: Vec<f64> = target.iter().map(|e| -e * ARCSEC_PER_RAD).collect();
    let mut lines = Vec::new();
    let mut body = String::new();
    // The corrections as the consumer will read them, arcseconds. Writing into a String cannot
    // fail: the results of writeln! are ignored.
    let read_back: Vec<f64> = match opts.format {
        Format::LutF32Rad => {
            lines.push(format!("units: radians (f32), one per line, {n} lines"));
            let values: Vec<f32> = c.iter().map(|v| (v / ARCSEC_PER_RAD) as f32).collect();
            for v in &values {
                let _ = writeln!(body, "{v:e}");
            }
            values
                .iter()
                .map(|&v| f64::from(v) * ARCSEC_PER_RAD)
                .collect()
        }
        Format::LutI16 | Format::LutU16 | Format::LutI8 => {
            let (max_code, offset, kind) = match opts.format {
                Format::LutI16 => (i64::from(i16::MAX), 0, "int16"),
                Format::LutU16 => (i64::from(i16::MAX), 32768, "uint16 offset binary"),
                _ => (i64::from(i8::MAX), 0, "int8"),
            };
            let (scale, codes) = quantize(&c, max_code, opts.scale_arcsec)?;
            lines.push(format!("units: {kind} codes, one per line, {n} lines"));
            lines.push(if offset == 0 {
                format!("scale: correction_arcsec = code * {scale:e}")
            } else {
                format!("scale: correction_arcsec = (code - {offset}) * {scale:e}")
            });
            for k in &codes {
                let _ = writeln!(body, "{}", k + offset);
            }
            codes.iter().map(|&k| k as f64 * scale).collect()
        }
        Format::CArray => {
            lines.push("units: arcseconds (float)".into());
            let _ = writeln!(body, "#define CALIB_CORRECTION_POINTS {n}");
            let _ = writeln!(
                body,
                "#define CALIB_CORRECTION_STEP_DEG {:e}",
                source.step_deg(n)
            );
            if let Some((lo, hi)) = source.range_deg() {
                let _ = writeln!(body, "#define CALIB_CORRECTION_START_DEG {lo:e}");
                let _ = writeln!(body, "#define CALIB_CORRECTION_END_DEG {hi:e}");
            }
            let _ = writeln!(
                body,
                "static const float calib_correction_arcsec[CALIB_CORRECTION_POINTS] = {{"
            );
            let written: Vec<String> = c.iter().map(|v| format!("{v:.6}")).collect();
            for chunk in written.chunks(8) {
                let row: Vec<String> = chunk.iter().map(|v| format!("{v}f")).collect();
                let _ = writeln!(body, "    {},", row.join(", "));
            }
            let _ = writeln!(body, "}};");
            written
                .iter()
                .map(|v| f64::from(v.parse::<f32>().unwrap_or(f32::NAN)))
                .collect()
        }
        _ => {
            lines.push("units: degrees, arcseconds".into());
            let _ = writeln!(body, "angle_deg,correction_arcsec");
            let written: Vec<String> = c.iter().map(|v| format!("{v:.6}")).collect();
            for (i, v) in written.iter().enumerate() {
                // As the correction table writes its angles: a grid point at the reading 0 of a
                // range across it is `0.000000`, never `-0.000000`.
                push_fixed(&mut body, source.grid_deg(i, n));
                let _ = writeln!(body, ",{v}");
            }
            written
                .iter()
                .map(|v| v.parse().unwrap_or(f64::NAN))
                .collect()
        }
    };
    Ok(Rendered {
        lines,
        body,
        decoded: read_back.iter().map(|c| -c / ARCSEC_PER_RAD).collect(),
    })
}

#[cfg(test)]
mod tests {
    use crate::export::{ExportOptions, Format, export};
    use calib_core::TableMap;
    use calib_core::angle::ARCSEC_PER_RAD;
    use calib_core::{ErrorMap, FourierSeries, Harmonic, RangeMap};

    /// 10″ at order 3, 2″ at 7 on 360 points: |correction| ≤ 12″.
    fn table() -> ErrorMap {
        let hs = [
            Harmonic::from_arcsec_deg(3, 10.0, 20.0),
            Harmonic::from_arcsec_deg(7, 2.0, 0.0),
        ];
        ErrorMap::from_series(&FourierSeries::from_harmonics(&hs, 7), 360)
    }

    /// The body's numbers, comments and the CSV header skipped.
    fn numbers(text: &str) -> Vec<f64> {
        text.lines()
            .filter(|l| !l.starts_with('#') && !l.starts_with("angle"))
            .map(|l| l.rsplit(',').next().unwrap().parse().unwrap())
            .collect()
    }

    #[test]
    fn a_range_across_zero_is_exported_on_its_tables_signed_grid() {
        let d = f64::to_radians;
        // −30°…30° as a range table reads it (330° + 60 steps of 1°), resampled to 31 entries.
        let values = (0..61).map(|i| f64::from(i) / ARCSEC_PER_RAD).collect();
        let range = RangeMap::new(d(330.0), d(1.0), values).unwrap();
        let mut opts = ExportOptions::new(Format::Csv, "t");
        opts.points = Some(31);
        let out = export(&TableMap::from(range), &opts).unwrap();
        let angles: Vec<&str> = out
            .text
            .lines()
            .filter(|l| !l.starts_with('#') && !l.starts_with("angle"))
            .map(|l| l.split(',').next().unwrap())
            .collect();
        assert_eq!(angles.len(), 31);
        assert_eq!(
            (angles[0], angles[15], angles[30]),
            ("-30.000000", "0.000000", "30.000000")
        );
        assert!(
            out.header
                .iter()
                .any(|l| l.starts_with("range: -30.000000 to 30.000000 deg"))
        );
        // Every second point of the 1° grid, mean removed: the line 2i − 30″ (zero mean).
        for (i, c) in numbers(&out.text).iter().enumerate() {
            assert!((c + (2.0 * i as f64 - 30.0)).abs() < 1e-6, "entry {i}: {c}");
        }
    }

    #[test]
    fn every_generic_table_reads_back_within_its_quantum() {
        let map = table();
        let want: Vec<f64> = map.values().iter().map(|e| -e * ARCSEC_PER_RAD).collect();
        for (format, offset) in [
            (Format::LutI8, 0.0),
            (Format::LutI16, 0.0),
            (Format::LutU16, 32768.0),
            (Format::LutF32Rad, 0.0),
            (Format::Csv, 0.0),
        ] {
            let out = export(
                &TableMap::from(map.clone()),
                &ExportOptions::new(format, "t"),
            )
            .unwrap();
            let scale = out
                .header
                .iter()
                .find_map(|l| l.strip_prefix("scale: "))
                .map(|l| l.rsplit(' ').next().unwrap().parse::<f64>().unwrap());
            let (unit, tol) = match (format, scale) {
                (Format::LutF32Rad, _) => (ARCSEC_PER_RAD, 12.0 * 6e-8),
                // Half a code.
                (_, Some(scale)) => (scale, scale / 2.0),
                // 6 decimals.
                _ => (1.0, 5e-7),
            };
            let got = numbers(&out.text);
            assert_eq!(got.len(), 360, "{format:?}");
            for (g, w) in got.iter().zip(&want) {
                assert!(
                    ((g - offset) * unit - w).abs() <= tol * (1.0 + 1e-9),
                    "{format:?}"
                );
            }
            // Every order kept and no resampling: nothing to compare, no fit line.
            assert!(out.fit.is_none());
        }
    }
}
