//! Field-level helpers shared by the CSV log reader and the correction-table reader: the same
//! tolerance for whitespace and a BOM, the same number syntax and the same error wording.

use crate::Error;
use crate::limits::{LineLimit, MAX_CSV_LINE_BYTES, line_too_long};
use csv::ByteRecord;
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::Path;

const UTF8_BOM: &[u8] = b"\xEF\xBB\xBF";

/// A CSV reader configured as both readers want it.
///
/// `flexible`: rows with the wrong number of fields come through so the caller can say which row
/// and how many fields, rather than csv's generic message. No header handling: the caller reads the
/// header as the first record, so that it can strip a BOM and number lines itself.
pub(crate) fn csv_reader(file: File) -> csv::Reader<LineLimit<File>> {
    csv_reader_with(file, b',')
}

/// [`csv_reader`] with another field separator.
pub(crate) fn csv_reader_with(file: File, separator: u8) -> csv::Reader<LineLimit<File>> {
    csv::ReaderBuilder::new()
        .delimiter(separator)
        .has_headers(false)
        .flexible(true)
        // Bigger than csv's 8 KiB default: fewer read calls, measurably faster on large logs.
        .buffer_capacity(1 << 16)
        .from_reader(LineLimit::new(file))
}

/// The 1-based line of `path` on which `record` starts.
///
/// Not csv's own line count, which drifts on blank lines and CRLF line ends. csv's byte offset of
/// a record is exact but points at the end of the previous record, before any line ends and
/// blank lines that precede this one. Errors are rare, so the line is counted in the file itself
/// when an error is reported, never on the hot path. If the file can no longer be read, csv's
/// count is the best there is.
pub(crate) fn line_of(path: &Path, record: &ByteRecord) -> u64 {
    record.position().map_or(1, |p| line_at(path, p))
}

/// The 1-based line of `path` on which the record at `pos` starts (see [`line_of`]).
pub(crate) fn line_at(path: &Path, pos: &csv::Position) -> u64 {
    physical_line(path, pos.byte()).unwrap_or(pos.line())
}

/// 1 + the newlines before `byte` and in the run of line ends that follows it.
fn physical_line(path: &Path, byte: u64) -> std::io::Result<u64> {
    let mut file = BufReader::with_capacity(1 << 16, File::open(path)?);
    let mut newlines = 0u64;
    let mut offset = 0u64;
    loop {
        let buf = file.fill_buf()?;
        if buf.is_empty() {
            return Ok(newlines + 1);
        }
        let before = byte.saturating_sub(offset).min(buf.len() as u64) as usize;
        newlines += buf[..before].iter().filter(|&&b| b == b'\n').count() as u64;
        for &b in &buf[before..] {
            match b {
                b'\n' => newlines += 1,
                b'\r' => {}
                _ => return Ok(newlines + 1),
            }
        }
        let len = buf.len();
        offset += len as u64;
        file.consume(len);
    }
}

/// A field parsed as an `f64`, ignoring surrounding whitespace. `None` if it is not a number.
///
/// Accepts what Rust's `f64::from_str` accepts (`12`, `-1.5e-3`, `.5`, also `inf` and `NaN`,
/// which callers reject with their own message).
#[inline]
pub(crate) fn parse_f64(field: &[u8]) -> Option<f64> {
    std::str::from_utf8(field.trim_ascii()).ok()?.parse().ok()
}

/// A field as quoted in an error message: lossy UTF-8, cut short so one bad cell cannot flood
/// the terminal.
pub(crate) fn show(field: &[u8]) -> String {
    const MAX: usize = 40;
    let s = String::from_utf8_lossy(field.trim_ascii());
    if s.chars().count() > MAX {
        format!("{}…", s.chars().take(MAX).collect::<String>())
    } else {
        s.into_owned()
    }
}

/// What is wrong with a field that should hold a number, as the tail of an error message.
pub(crate) fn not_a_number(field: &[u8], what: &str) -> String {
    if field.trim_ascii().is_empty() {
        format!("the field is empty; {what} must be a number here")
    } else {
        format!(
            "`{}` is not a number; {what} must be a plain decimal number such as 12.5 or -3e-4",
            show(field)
        )
    }
}

/// The column names of a header record: trimmed, BOM removed, non-empty and distinct.
pub(crate) fn header_names(path: &Path, record: &ByteRecord) -> Result<Vec<String>, Error> {
    let line = line_of(path, record);
    let err = |channel: Option<String>, message: String| Error::Csv {
        path: path.to_path_buf(),
        line,
        channel,
        message,
    };
    let mut names: Vec<String> = Vec::with_capacity(record.len());
    for (i, field) in record.iter().enumerate() {
        let field = if i == 0 {
            field.strip_prefix(UTF8_BOM).unwrap_or(field)
        } else {
            field
        };
        let name = std::str::from_utf8(field.trim_ascii()).map_err(|_| {
            err(
                None,
                format!(
                    "header column {} is not valid UTF-8; save the file as UTF-8",
                    i + 1
                ),
            )
        })?;
        if name.is_empty() && record.len() == 1 {
            return Err(err(
                None,
                "the header row is empty; it must name the columns, such as `t,a,b`".into(),
            ));
        }
        if name.is_empty() {
            return Err(err(
                None,
                format!(
                    "header column {} has no name; give every column a name in the header row",
                    i + 1
                ),
            ));
        }
        if let Some(first) = names.iter().position(|n| n == name) {
            return Err(err(
                Some(name.to_string()),
                format!(
                    "columns {} and {} are both named `{name}`; rename one so every column name is \
                     unique",
                    first + 1,
                    i + 1
                ),
            ));
        }
        names.push(name.to_string());
    }
    Ok(names)
}

/// The error for a row whose field count differs from the header's.
pub(crate) fn wrong_width(path: &Path, record: &ByteRecord, names: &[String]) -> Error {
    Error::Csv {
        path: path.to_path_buf(),
        line: line_of(path, record),
        channel: None,
        message: format!(
            "the row has {} field{} but the header has {} column{} ({}); give every row exactly one \
             field per header column",
            record.len(),
            if record.len() == 1 { "" } else { "s" },
            names.len(),
            if names.len() == 1 { "" } else { "s" },
            names.join(", ")
        ),
    }
}

/// A `csv` crate error (an I/O failure while reading, in practice) as ours.
pub(crate) fn from_csv(path: &Path, e: csv::Error) -> Error {
    let line = e.position().map_or(0, |p| p.line());
    let message = e.to_string();
    match e.into_kind() {
        csv::ErrorKind::Io(source) => match line_too_long(&source) {
            Some(long) => Error::Csv {
                path: path.to_path_buf(),
                line: long.line,
                channel: None,
                message: format!(
                    "the line is longer than {MAX_CSV_LINE_BYTES} bytes, more than any log row: \
                     this is not a CSV log (a binary file, or one without line ends)"
                ),
            },
            None => Error::Io {
                path: path.to_path_buf(),
                source,
            },
        },
        _ => Error::Csv {
            path: path.to_path_buf(),
            line,
            channel: None,
            message,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_tolerate_whitespace_and_reject_text() {
        assert_eq!(parse_f64(b" 1.5\t"), Some(1.5));
        assert_eq!(parse_f64(b"-3e-4"), Some(-3e-4));
        assert_eq!(parse_f64(b""), None);
        assert_eq!(parse_f64(b"1,5"), None);
        assert_eq!(parse_f64(b"\xff"), None);
        assert!(parse_f64(b"NaN").unwrap().is_nan());
    }

    #[test]
    fn long_fields_are_cut_in_messages() {
        let long = "x".repeat(100);
        assert_eq!(show(long.as_bytes()).chars().count(), 41);
        assert!(not_a_number(b"  ", "a time").contains("empty"));
    }
}
