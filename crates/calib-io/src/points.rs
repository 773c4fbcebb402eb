//! A tolerant reader of error tables on any grid, for `calib compare`.
//!
//! Reads any CSV with columns `angle_deg` and `error_arcsec`, and optionally `u_arcsec` (standard
//! uncertainty) and `expanded_uncertainty_arcsec`; other columns (`correction_arcsec`, …) are
//! ignored. calib's correction tables, `encoder.csv` of the shift-angle method and hand-made
//! tables all qualify. Angles need not be uniform or sorted; an empty uncertainty field means
//! "not given" for that row. Lines starting with `#` are skipped; a range table's
//! `# range_deg: LO to HI` line ([`crate::table`]) gives the table's [`PointTable::range`].

use crate::Error;
use std::io::{BufRead as _, Read as _};
use std::path::Path;

/// One row of a point table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point {
    /// Angle, degrees.
    pub angle_deg: f64,
    /// Error, arcsec.
    pub error_arcsec: f64,
    /// Standard uncertainty, arcsec, where given.
    pub u_arcsec: Option<f64>,
    /// Expanded uncertainty, arcsec, where given.
    pub expanded_uncertainty_arcsec: Option<f64>,
}

/// The rows of a point table, in file order.
#[derive(Debug, Clone, PartialEq)]
pub struct PointTable {
    /// The rows.
    pub points: Vec<Point>,
    /// A range table's range `(lo, hi)`, degrees; `None` for a table over the whole turn.
    pub range: Option<(f64, f64)>,
}

/// Reads a point table from `path`.
pub fn read_points(path: &Path) -> Result<PointTable, Error> {
    let file = std::fs::File::open(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_points(file, path)
}

/// [`read_points`] from any reader; `path` names it in errors.
pub fn parse_points(input: impl std::io::Read, path: &Path) -> Result<PointTable, Error> {
    let csv_err = |line: u64, column: Option<&str>, message: String| {
        crate::error::csv_error(path, line, column, message)
    };
    // Streamed, not read whole: a table is held row by row up to the point limit. The first
    // line (a range table's marker) is read ahead and given back to the CSV reader.
    let mut input = std::io::BufReader::new(input);
    let mut head = Vec::new();
    input
        .by_ref()
        .take(crate::limits::MAX_CSV_LINE_BYTES as u64)
        .read_until(b'\n', &mut head)
        .map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
    let first = String::from_utf8_lossy(&head).trim().to_string();
    let range = match first.strip_prefix("# range_deg:") {
        Some(rest) => {
            let w: Vec<&str> = rest.split_whitespace().collect();
            match w.as_slice() {
                [lo, "to", hi, ..] => lo.parse::<f64>().ok().zip(hi.parse::<f64>().ok()),
                _ => None,
            }
            .filter(|(lo, hi)| lo.is_finite() && hi > lo)
            .map(Some)
            .ok_or_else(|| {
                csv_err(
                    1,
                    None,
                    format!("`{first}` is not a range line; a range table starts with `# range_deg: LO to HI`"),
                )
            })?
        }
        None => None,
    };
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(head.as_slice().chain(input));
    let headers = reader
        .headers()
        .map_err(|e| csv_err(1, None, e.to_string()))?
        .clone();
    let find = |name: &str| headers.iter().position(|h| h == name);
    let (Some(angle), Some(error)) = (find("angle_deg"), find("error_arcsec")) else {
        return Err(csv_err(
            1,
            None,
            "a point table needs the columns `angle_deg` and `error_arcsec` (and optionally `u_arcsec`, `expanded_uncertainty_arcsec`)".into(),
        ));
    };
    let (u, expanded) = (find("u_arcsec"), find("expanded_uncertainty_arcsec"));
    let mut points = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| {
            let line = e.position().map(|p| p.line()).unwrap_or(0);
            csv_err(line, None, e.to_string())
        })?;
        let line = record.position().map(|p| p.line()).unwrap_or(0);
        // Held to the limit of the tables calib writes, before the row is held.
        if points.len() >= crate::limits::MAX_TABLE_POINTS {
            return Err(csv_err(line, None, crate::table::too_many_rows()));
        }
        let number = |col: usize| -> Result<Option<f64>, Error> {
            let text = record.get(col).unwrap_or("");
            if text.is_empty() {
                return Ok(None);
            }
            match text.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(Some(v)),
                _ => Err(csv_err(
                    line,
                    Some(&headers[col]),
                    format!("`{text}` is not a finite number"),
                )),
            }
        };
        let required = |col: usize| -> Result<f64, Error> {
            number(col)?.ok_or_else(|| csv_err(line, Some(&headers[col]), "empty field".into()))
        };
        let nonnegative = |col: Option<usize>| -> Result<Option<f64>, Error> {
            match col.map(number).transpose()?.flatten() {
                Some(v) if v < 0.0 => Err(csv_err(
                    line,
                    col.map(|c| &headers[c]),
                    format!("an uncertainty cannot be negative ({v})"),
                )),
                v => Ok(v),
            }
        };
        points.push(Point {
            angle_deg: required(angle)?,
            error_arcsec: required(error)?,
            u_arcsec: nonnegative(u)?,
            expanded_uncertainty_arcsec: nonnegative(expanded)?,
        });
    }
    if points.is_empty() {
        return Err(Error::Empty {
            path: path.to_path_buf(),
        });
    }
    Ok(PointTable { points, range })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `rows` rows of a point table, made as they are read (no file, nothing held).
    struct Rows {
        next: usize,
        rows: usize,
        pending: Vec<u8>,
    }

    impl std::io::Read for Rows {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            while self.pending.len() < buf.len() && self.next <= self.rows {
                let row = if self.next == 0 {
                    "angle_deg,error_arcsec\n".to_string()
                } else {
                    format!("{},0\n", self.next)
                };
                self.pending.extend_from_slice(row.as_bytes());
                self.next += 1;
            }
            let n = buf.len().min(self.pending.len());
            buf[..n].copy_from_slice(&self.pending[..n]);
            self.pending.drain(..n);
            Ok(n)
        }
    }

    /// Issue 33: a 10⁷-row table took 6.85 GB in `compare`; now the row beyond the limit is
    /// refused as it is read.
    #[test]
    fn tables_beyond_the_point_limit_are_refused_as_they_are_read() {
        let rows = |rows| Rows {
            next: 0,
            rows,
            pending: Vec::new(),
        };
        let limit = crate::limits::MAX_TABLE_POINTS;
        let err = parse_points(rows(limit + 1), Path::new("big.csv"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains(&format!("line {}", limit + 2)) && err.contains("more than 3600000 rows"),
            "{err}"
        );
        assert_eq!(
            parse_points(rows(limit), Path::new("big.csv"))
                .unwrap()
                .points
                .len(),
            limit
        );
    }

    #[test]
    fn reads_optional_columns_and_ignores_others() {
        let t = parse_points(
            "angle_deg,error_arcsec,correction_arcsec,u_arcsec\n0,1.5,-1.5,0.1\n7.5,-2,2,\n"
                .as_bytes(),
            Path::new("m.csv"),
        )
        .unwrap();
        assert_eq!(t.points.len(), 2);
        assert_eq!(t.points[0].u_arcsec, Some(0.1));
        assert_eq!(t.points[1].u_arcsec, None);
        assert_eq!(t.points[1].expanded_uncertainty_arcsec, None);
    }

    #[test]
    fn errors_name_file_line_and_column() {
        let e = parse_points(
            "angle_deg,error_arcsec\n0,1\n1,abc\n".as_bytes(),
            Path::new("m.csv"),
        )
        .unwrap_err()
        .to_string();
        assert_eq!(
            e,
            "m.csv: line 3, column `error_arcsec`: `abc` is not a finite number"
        );
        let e = parse_points("angle,error\n0,1\n".as_bytes(), Path::new("m.csv"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 1") && e.contains("angle_deg"), "{e}");
        let e = parse_points(
            "angle_deg,error_arcsec,u_arcsec\n0,1,-0.1\n".as_bytes(),
            Path::new("m.csv"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("negative") && e.contains("u_arcsec"), "{e}");
    }
}
