//! Shift-angle readings: the autocollimator readings `ε_ij` of the shift-angle paper's eq. (3).
//!
//! CSV with header `shift_deg,start_face,step,reading_arcsec` (any column order, no other
//! columns): one row per reading, `step` = `i` (1..n), `start_face` = `j` (1..n), `shift_deg` = `S`.
//! The number of faces `n` is the largest `step` (or the caller's `faces`). Every start face given
//! at a shift needs one reading per step `1..n`; a shift may hold any set of start faces.

use crate::Error;
use calib_core::shift_angle::{Readings, Shift, StartFaceRow};
use std::collections::BTreeMap;
use std::path::Path;

const COLUMNS: [&str; 4] = ["shift_deg", "start_face", "step", "reading_arcsec"];

/// `(value, line)` per step, per start face, per shift key (shift in µ°).
type Table = BTreeMap<i64, (f64, BTreeMap<usize, BTreeMap<usize, (f64, u64)>>)>;

/// Reads shift-angle readings from `path`. `faces`, where given, is the polygon's number of
/// faces, checked against the readings.
pub fn read_readings(path: &Path, faces: Option<usize>) -> Result<Readings, Error> {
    let file = std::fs::File::open(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_readings(file, path, faces)
}

/// [`read_readings`] from any reader; `path` names it in errors.
pub fn parse_readings(
    input: impl std::io::Read,
    path: &Path,
    faces: Option<usize>,
) -> Result<Readings, Error> {
    let csv_err = |line: u64, column: Option<&str>, message: String| {
        crate::error::csv_error(path, line, column, message)
    };
    let (mut reader, headers) = crate::error::csv_with_headers(input, path)?;
    let mut index = [usize::MAX; 4];
    for (pos, name) in headers.iter().enumerate() {
        match COLUMNS.iter().position(|c| *c == name) {
            Some(k) if index[k] == usize::MAX => index[k] = pos,
            Some(_) => return Err(csv_err(1, Some(name), "the column appears twice".into())),
            None => {
                return Err(csv_err(
                    1,
                    Some(name),
                    format!(
                        "unknown column; shift-angle readings have exactly the columns {}",
                        COLUMNS.join(",")
                    ),
                ));
            }
        }
    }
    if let Some(k) = index.iter().position(|&i| i == usize::MAX) {
        return Err(csv_err(
            1,
            None,
            format!(
                "missing column `{}`; the header must be {}",
                COLUMNS[k],
                COLUMNS.join(",")
            ),
        ));
    }
    let mut table: Table = BTreeMap::new();
    let mut max_step = 0;
    let mut max_face = (0, 0u64);
    for record in reader.records() {
        let record = record.map_err(|e| {
            let line = e.position().map(|p| p.line()).unwrap_or(0);
            csv_err(line, None, e.to_string())
        })?;
        let line = record.position().map(|p| p.line()).unwrap_or(0);
        let field = |k: usize| record.get(index[k]).unwrap_or("");
        let number = |k: usize| -> Result<f64, Error> {
            field(k)
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    csv_err(
                        line,
                        Some(COLUMNS[k]),
                        format!("`{}` is not a finite number", field(k)),
                    )
                })
        };
        let integer = |k: usize| -> Result<usize, Error> {
            field(k)
                .parse::<usize>()
                .ok()
                .filter(|&v| v >= 1)
                .ok_or_else(|| {
                    csv_err(
                        line,
                        Some(COLUMNS[k]),
                        format!("`{}` is not a whole number ≥ 1", field(k)),
                    )
                })
        };
        let shift = number(0)?;
        let (face, step, value) = (integer(1)?, integer(2)?, number(3)?);
        let key = (shift * 1e6).round() as i64;
        let steps = table
            .entry(key)
            .or_insert((shift, BTreeMap::new()))
            .1
            .entry(face)
            .or_default();
        if let Some((_, first)) = steps.insert(step, (value, line)) {
            return Err(csv_err(
                line,
                None,
                format!(
                    "duplicate reading: shift {shift}°, start face {face}, step {step} was already given at line {first}; keep one (average repeated readings first)"
                ),
            ));
        }
        max_step = max_step.max(step);
        if face > max_face.0 {
            max_face = (face, line);
        }
    }
    if table.is_empty() {
        return Err(Error::Empty {
            path: path.to_path_buf(),
        });
    }
    let data_err = |message: String| Error::Data {
        path: path.to_path_buf(),
        message,
    };
    let n = match faces {
        Some(f) if f != max_step => {
            return Err(data_err(format!(
                "the polygon has {f} faces (the `faces` option) but the largest step in the readings is {max_step}; every start face needs steps 1..{f}"
            )));
        }
        Some(f) => f,
        None => max_step,
    };
    if max_face.0 > n {
        return Err(csv_err(
            max_face.1,
            Some("start_face"),
            format!(
                "start face {} but the largest step, the number of faces, is {n}; a polygon of {n} faces has start faces 1..{n}",
                max_face.0
            ),
        ));
    }
    let mut shifts = Vec::with_capacity(table.len());
    for (shift_deg, rows) in table.into_values() {
        let mut out = Vec::with_capacity(rows.len());
        for (face, steps) in rows {
            // Name at most 10 steps: a stray huge `step` must not build a huge message. Every
            // step is ≤ n here, so n − len counts the absent ones.
            let mut missing: Vec<String> = (1..=n)
                .filter(|s| !steps.contains_key(s))
                .take(10)
                .map(|s| s.to_string())
                .collect();
            if n - steps.len() > 10 {
                missing.push("…".into());
            }
            if !missing.is_empty() {
                return Err(data_err(format!(
                    "shift {shift_deg}°, start face {face}: no reading at step {}; every start face measured at a shift needs one reading per step 1..{n} (a full revolution)",
                    missing.join(", ")
                )));
            }
            out.push(StartFaceRow {
                start_face: face,
                readings_arcsec: steps.into_values().map(|(v, _)| v).collect(),
            });
        }
        shifts.push(Shift {
            shift_deg,
            rows: out,
        });
    }
    Readings::new(n, shifts).map_err(|e| data_err(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Readings, Error> {
        parse_readings(text.as_bytes(), Path::new("r.csv"), None)
    }

    fn full(n: usize, shifts: &[(f64, &[usize])]) -> String {
        let mut s = String::from("shift_deg,start_face,step,reading_arcsec\n");
        for (shift, faces) in shifts {
            for f in *faces {
                for i in 1..=n {
                    s += &format!("{shift},{f},{i},{}\n", 0.01 * (i * f) as f64);
                }
            }
        }
        s
    }

    #[test]
    fn reads_full_and_partial_shifts() {
        let r = parse(&full(4, &[(0.0, &[1, 2, 3, 4]), (30.0, &[1])])).unwrap();
        assert_eq!(r.faces(), 4);
        assert_eq!(r.shifts().len(), 2);
        assert_eq!(r.shifts()[1].rows.len(), 1);
        assert_eq!(r.shifts()[0].rows[2].readings_arcsec[1], 0.06);
    }

    #[test]
    fn errors_name_the_line_and_what_to_do() {
        let mut text = full(4, &[(0.0, &[1, 2])]);
        text += "0,2,3,1.0\n";
        let e = parse(&text).unwrap_err().to_string();
        assert!(
            e.contains("line 10") && e.contains("line 8") && e.contains("duplicate"),
            "{e}"
        );

        let text = full(4, &[(0.0, &[1, 2])]).replace("0,2,3,0.06\n", "");
        let e = parse(&text).unwrap_err().to_string();
        assert!(e.contains("start face 2: no reading at step 3"), "{e}");

        let text = full(4, &[(0.0, &[1, 5])]);
        let e = parse(&text).unwrap_err().to_string();
        assert!(e.contains("start face 5") && e.contains("line 6"), "{e}");

        let e = parse_readings(
            full(4, &[(0.0, &[1, 2])]).as_bytes(),
            Path::new("r.csv"),
            Some(24),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("24 faces") && e.contains("largest step in the readings is 4"),
            "{e}"
        );

        let e = parse("shift_deg,start_face,step,reading_arcsec\n0,1,1,0\n0,2,1000000000,0\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("step 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, …;"), "{e}");

        let e = parse("shift_deg,start_face,step,reading\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("column `reading`") && e.contains("line 1"),
            "{e}"
        );

        let e = parse("shift_deg,start_face,step,reading_arcsec\n0,1,x,2\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2, column `step`"), "{e}");
        assert!(matches!(
            parse("shift_deg,start_face,step,reading_arcsec\n"),
            Err(Error::Empty { .. })
        ));
    }
}
