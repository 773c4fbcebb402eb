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
pub(crate) fn csv_reader_with<R: std::io::Read>(
    file: R,
    separator: u8,
) -> csv::Reader<LineLimit<R>> {
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

/// 1 + the line ends before `byte` and in the run of line ends that follows it. A line ends at
/// `\n`, `\r\n` or a lone `\r` (old Mac files).
fn physical_line(path: &Path, byte: u64) -> std::io::Result<u64> {
    let mut file = BufReader::with_capacity(1 << 16, File::open(path)?);
    let mut ends = 0u64;
    // The previous byte was a `\r` not yet counted (it may start a `\r\n`).
    let mut cr = false;
    let mut offset = 0u64;
    loop {
        let buf = file.fill_buf()?;
        if buf.is_empty() {
            return Ok(ends + u64::from(cr) + 1);
        }
        for (k, &b) in buf.iter().enumerate() {
            match b {
                b'\n' => {
                    ends += 1;
                    cr = false;
                }
                b'\r' => {
                    ends += u64::from(cr);
                    cr = true;
                }
                _ => {
                    ends += u64::from(cr);
                    cr = false;
                    if offset + k as u64 >= byte {
                        return Ok(ends + 1);
                    }
                }
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

/// A field written with a decimal comma (`-1,25`) parsed as an `f64`; fields without a comma as
/// [`parse_f64`]. `None` if it is not a number.
pub(crate) fn parse_f64_comma(field: &[u8]) -> Option<f64> {
    let field = field.trim_ascii();
    let Some(comma) = field.iter().position(|&b| b == b',') else {
        return parse_f64(field);
    };
    // One comma, no point: `1.234,5` (a thousands point) is not taken for a number.
    if field.len() > 64 || field.contains(&b'.') || field[comma + 1..].contains(&b',') {
        return None;
    }
    let mut buf = [0u8; 64];
    let buf = &mut buf[..field.len()];
    buf.copy_from_slice(field);
    buf[comma] = b'.';
    parse_f64(buf)
}

/// A field holding a whole number (an optional sign and up to 38 digits), as an `i128`.
#[inline]
pub(crate) fn parse_integer(field: &[u8]) -> Option<i128> {
    let f = field.trim_ascii();
    let digits = f
        .strip_prefix(b"-")
        .or_else(|| f.strip_prefix(b"+"))
        .unwrap_or(f);
    if digits.is_empty() || digits.len() > 38 || !digits.iter().all(u8::is_ascii_digit) {
        return None;
    }
    std::str::from_utf8(f).ok()?.parse().ok()
}

/// A plain decimal field (`-1700000000.25`; `-1700000000,25` with a decimal comma; no exponent):
/// its sign, whole part and fraction's digits, so that it can be counted from a whole number
/// without the rounding a double of the whole would make.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Decimal<'a> {
    negative: bool,
    /// The whole part, with the sign.
    whole: i128,
    fraction: &'a [u8],
}

impl<'a> Decimal<'a> {
    /// `field` as a plain decimal, `comma` its decimal separator where set; `None` if it is not
    /// one (an exponent, text, no digit).
    pub(crate) fn parse(field: &'a [u8], comma: bool) -> Option<Self> {
        let f = field.trim_ascii();
        let separator = if comma { b',' } else { b'.' };
        let (whole, fraction) = match f.iter().position(|&b| b == separator) {
            Some(i) => (&f[..i], &f[i + 1..]),
            None => (f, &f[f.len()..]),
        };
        let (negative, digits) = match whole.split_first() {
            Some((b'-', rest)) => (true, rest),
            Some((b'+', rest)) => (false, rest),
            _ => (false, whole),
        };
        if (digits.is_empty() && fraction.is_empty())
            || digits.len() > 38
            || !digits.iter().all(u8::is_ascii_digit)
            || !fraction.iter().all(u8::is_ascii_digit)
        {
            return None;
        }
        let whole: i128 = match digits {
            [] => 0,
            d => std::str::from_utf8(d).ok()?.parse().ok()?,
        };
        Some(Decimal {
            negative,
            whole: if negative { -whole } else { whole },
            fraction,
        })
    }

    /// The whole part, with the sign.
    pub(crate) fn whole(&self) -> i128 {
        self.whole
    }

    /// The number less `origin`, rounded once to a double where it is not negative — the double
    /// the same digits counted from `origin` would be read as — else its whole part's difference
    /// plus its fraction.
    pub(crate) fn since(&self, origin: i128) -> Option<f64> {
        let whole = self.whole - origin;
        // Up to 39 digits, the separator, and as many of the fraction's digits as fit (a double
        // holds 17).
        let mut buf = [0u8; 96];
        let mut text = std::io::Cursor::new(&mut buf[..]);
        std::io::Write::write_fmt(&mut text, format_args!("{}.", whole.unsigned_abs())).ok()?;
        let at = text.position() as usize;
        let kept = self.fraction.len().min(buf.len() - at);
        buf[at..at + kept].copy_from_slice(&self.fraction[..kept]);
        let digits = std::str::from_utf8(&buf[..at + kept]).ok()?;
        if !self.negative && whole >= 0 {
            return digits.parse().ok();
        }
        // A negative stamp, or one before the origin: the two parts apart.
        let fraction: f64 = match kept {
            0 => 0.0,
            _ => digits[at - 1..].parse().ok()?,
        };
        let fraction = if self.negative { -fraction } else { fraction };
        Some(whole as f64 + fraction)
    }
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

/// [`show`] as a [`std::fmt::Display`], formatted only when shown (fields are checked for every
/// row; only a refused one is printed).
pub(crate) struct Shown<'a>(pub &'a [u8]);

impl std::fmt::Display for Shown<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&show(self.0))
    }
}

/// What is wrong with a field that should hold a number, as the tail of an error message.
pub(crate) fn not_a_number(field: &[u8], what: &str) -> String {
    if field.trim_ascii().is_empty() {
        format!("the field is empty; {what} must be a number here")
    } else if parse_f64_comma(field).is_some() {
        format!(
            "`{}` is written with a decimal comma, but the rows before it were not; {what} must be \
             written the same way in every row (1.5 or, in a `;` or tab separated file, 1,5)",
            show(field)
        )
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

/// An I/O error while reading a CSV file as ours: a line too long is a CSV error at its line.
pub(crate) fn from_io(path: &Path, source: std::io::Error) -> Error {
    match line_too_long(&source) {
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
    fn decimals_count_from_a_whole_number_with_their_digits() {
        let since = |field: &[u8], comma: bool, origin: i128| {
            Decimal::parse(field, comma).and_then(|d| d.since(origin))
        };
        let d = Decimal::parse(b" 1700000000.000000001 ", false).unwrap();
        assert_eq!(d.whole(), 1_700_000_000);
        assert_eq!(d.since(1_700_000_000), Some(1e-9));
        // Rounded once, as the digits counted from the origin would be read.
        assert_eq!(
            since(b"1700000012.3456", false, 1_700_000_000),
            Some(12.3456)
        );
        assert_eq!(since(b"-12.5", false, 0), Some(-12.5));
        assert_eq!(since(b"-12.5", false, -13), Some(0.5));
        assert_eq!(since(b"12.5", false, 13), Some(-0.5));
        assert_eq!(since(b"+7", false, 0), Some(7.0));
        assert_eq!(since(b"-.25", false, 0), Some(-0.25));
        assert_eq!(since(b"3.", false, 1), Some(2.0));
        assert_eq!(since(b"3,75", true, 3), Some(0.75));
        for bad in [&b"1.7e9"[..], b"", b".", b"-", b"1.2.3", b"12a", b"3,75"] {
            assert_eq!(Decimal::parse(bad, false), None, "{bad:?}");
        }
    }

    #[test]
    fn numbers_tolerate_whitespace_and_reject_text() {
        assert_eq!(parse_f64(b" 1.5\t"), Some(1.5));
        assert_eq!(parse_f64(b"-3e-4"), Some(-3e-4));
        assert_eq!(parse_f64(b""), None);
        assert_eq!(parse_f64(b"1,5"), None);
        assert_eq!(parse_f64_comma(b" -1,5 "), Some(-1.5));
        assert_eq!(parse_f64_comma(b"2.5"), Some(2.5));
        assert_eq!(parse_f64_comma(b"1.234,5"), None);
        assert_eq!(parse_f64_comma(b"1,2,3"), None);
        assert_eq!(
            parse_integer(b"132900081483250000"),
            Some(132_900_081_483_250_000)
        );
        assert_eq!(parse_integer(b"-12"), Some(-12));
        assert_eq!(parse_integer(b"1.0"), None);
        assert_eq!(parse_integer(b"1e3"), None);
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
