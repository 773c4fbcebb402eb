//! calib's one-value-a-line look-up tables (`lut-f32-rad`, `lut-i16`, `lut-u16`, `lut-i8`) and its
//! `csv` (`angle_deg,correction_arcsec`), read back.
//!
//! Lines starting with `#` are the header: integer tables take their scale from its `scale:` line
//! (`correction_arcsec = code * S`, or `(code - 32768) * S` for `lut-u16`), or from `--scale`
//! where the file has no header; a `range:` line marks a range table, which is refused. Every
//! table holds the correction: calib's error is its negation. `csv` rows must lie on the grid
//! `i·360/N` (within [`crate::table::GRID_TOLERANCE_DEG`]). A header after the entries (a
//! `# sign:`, `# grid:` or `# scale:` line, or csv's `angle_deg` row: calib writes them above
//! every table) starts a second table, refused with the lines of both: which one is on the
//! controller?

use super::{at, check_count, data, refuse_range};
use crate::Error;
use crate::export::Format;
use crate::table::GRID_TOLERANCE_DEG;
use calib_core::angle::ARCSEC_PER_RAD;
use std::path::Path;

/// The errors (radians) of a look-up table or calib csv, and notes.
pub(super) fn parse(
    text: &str,
    path: &Path,
    format: Format,
    scale: Option<f64>,
) -> Result<(Vec<f64>, Vec<String>), Error> {
    // The codes' type range and the offset of a zero correction.
    let (lo, hi, offset, kind) = match format {
        Format::LutI16 => (i64::from(i16::MIN), i64::from(i16::MAX), 0, "int16"),
        Format::LutU16 => (0, i64::from(u16::MAX), 32768, "uint16 offset binary"),
        Format::LutI8 => (i64::from(i8::MIN), i64::from(i8::MAX), 0, "int8"),
        _ => (0, 0, 0, ""),
    };
    let integer = hi > 0;
    let mut header_scale = None;
    let mut values = Vec::new();
    let mut angles = Vec::new();
    let mut first_row = None;
    for (k, raw) in text.lines().enumerate() {
        let line = k + 1;
        let row = raw.trim().trim_start_matches('\u{feff}');
        if let Some(first) = first_row
            && second_header(row, format)
        {
            return Err(at(
                path,
                line,
                format!(
                    "the file holds two tables: the first's entries start on line {first} and \
                     line {line} (`{row}`) starts another's header; calib cannot tell which one \
                     the controller holds (two exports pasted together?): keep one table in the \
                     file"
                ),
            ));
        }
        if let Some(comment) = row.strip_prefix('#') {
            let comment = comment.trim();
            if comment.starts_with("range:") {
                return Err(refuse_range(path, line));
            }
            if let Some(rest) = comment.strip_prefix("scale:") {
                header_scale = Some((scale_of(rest).ok_or_else(|| {
                    at(path, line, format!("`{row}` is not calib's scale line (`# scale: correction_arcsec = code * S`)"))
                })?, line));
            }
            continue;
        }
        if row.is_empty() || (format == Format::Csv && row.starts_with("angle_deg")) {
            continue;
        }
        check_count(path, line, values.len())?;
        first_row.get_or_insert(line);
        let field = if format == Format::Csv {
            let Some((angle, value)) = row.split_once(',') else {
                return Err(at(
                    path,
                    line,
                    format!("`{row}` is not an `angle_deg,correction_arcsec` row"),
                ));
            };
            let angle = angle.trim().parse::<f64>().ok().filter(|a| a.is_finite());
            angles
                .push(angle.ok_or_else(|| {
                    at(path, line, format!("`{row}`: the angle is not a number"))
                })?);
            value.trim()
        } else {
            row
        };
        let value = if integer {
            field
                .parse::<i64>()
                .ok()
                .filter(|c| (lo..=hi).contains(c))
                .map(|c| (c - offset) as f64)
                .ok_or_else(|| format!("`{field}` is not a {kind} code ({lo} to {hi})"))
        } else {
            let parsed = if format == Format::LutF32Rad {
                field.parse::<f32>().ok().map(f64::from)
            } else {
                field.parse::<f64>().ok()
            };
            parsed
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("`{field}` is not a finite number"))
        };
        values.push(value.map_err(|m| at(path, line, m))?);
    }
    let n = values.len();
    if format == Format::Csv
        && let Some(i) =
            (0..n).find(|&i| (angles[i] - 360.0 * i as f64 / n as f64).abs() > GRID_TOLERANCE_DEG)
    {
        return Err(data(
            path,
            format!(
                "row {} of {n} is at {}°, off the grid i·360/{n} = {}°: calib's csv has one row \
                 per entry i at reading i·360/N, from 0° up to but not including 360°",
                i + 1,
                angles[i],
                360.0 * i as f64 / n as f64
            ),
        ));
    }
    let (unit, note) = match format {
        Format::LutF32Rad => (
            1.0,
            format!("calib lut-f32-rad of {n} entries: the correction in radians"),
        ),
        Format::Csv => (
            1.0 / ARCSEC_PER_RAD,
            format!("calib csv of {n} rows: the correction in arcseconds"),
        ),
        _ => {
            let scale = match (header_scale, scale) {
                (Some((s, line)), Some(given)) if (s - given).abs() > 1e-9 * s.abs() => {
                    return Err(at(
                        path,
                        line,
                        format!(
                            "the header says {s} arcsec a code but the `scale_arcsec` option says {given}; \
                             leave the `scale_arcsec` option out (the header is the exporter's own)"
                        ),
                    ));
                }
                (Some((s, _)), _) => s,
                (None, Some(given)) => given,
                (None, None) => {
                    return Err(data(
                        path,
                        "the file has no `# scale:` header line, so its codes have no unit; give \
                         the arcseconds a code stands for with the `scale_arcsec` option (the exporter's scale; \
                         calib writes it in the header)"
                            .to_string(),
                    ));
                }
            };
            (
                scale / ARCSEC_PER_RAD,
                format!(
                    "calib lut ({kind}) of {n} entries at {scale:e} arcsec a code: the correction"
                ),
            )
        }
    };
    let errors = values.iter().map(|v| -v * unit).collect();
    Ok((errors, vec![note]))
}

/// Whether `row` is a line calib writes in a table's header, above its entries: `# sign:`,
/// `# grid:`, `# scale:`, or csv's `angle_deg` row.
fn second_header(row: &str, format: Format) -> bool {
    match row.strip_prefix('#') {
        Some(comment) => {
            let c = comment.trim_start();
            ["sign:", "grid:", "scale:"]
                .iter()
                .any(|k| c.starts_with(k))
        }
        None => format == Format::Csv && row.starts_with("angle_deg"),
    }
}

/// `S` of ` correction_arcsec = code * S` or ` correction_arcsec = (code - 32768) * S`.
fn scale_of(rest: &str) -> Option<f64> {
    let (_, factor) = rest.rsplit_once('*')?;
    factor
        .trim()
        .parse()
        .ok()
        .filter(|s: &f64| s.is_finite() && *s > 0.0)
}
