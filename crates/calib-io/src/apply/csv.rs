//! CSV logs: one field of each row rewritten, every other byte copied.
//!
//! The file is split into records by hand (RFC 4180: a record ends at a line end outside
//! quotes) so that each record's raw bytes, and the raw span of each field, are known: the
//! `csv` crate hands out unquoted fields, from which the original bytes cannot be rebuilt. The
//! field syntax accepted is the [`CsvReader`](crate::csv_log::CsvReader)'s: surrounding spaces,
//! a UTF-8 byte order mark, blank lines, quoted fields, and its dialects
//! ([`crate::csv_log::dialect`]): the separator (`,` `;` tab) and the lines before the header are
//! found as the reader finds them, and copied as they are, so the output keeps the input's
//! dialect.

use super::Readings;
use crate::Error;
use crate::atomic::AtomicFile;
use crate::csv_log::dialect::{self, Dialect};
use crate::csv_log::parse_f64;
use crate::error::csv_error;
use crate::limits::{LineLimit, line_too_long};
use calib_core::AngleUnit;
use calib_core::correction::Correction;
use std::borrow::Cow;
use std::fs::File;
use std::io::{BufRead, BufReader, Write};
use std::ops::Range as Span;
use std::path::{Path, PathBuf};

const UTF8_BOM: &[u8] = b"\xEF\xBB\xBF";

/// Records of a CSV file with their raw bytes and field spans.
struct Records {
    path: PathBuf,
    input: BufReader<LineLimit<File>>,
    /// The current record's bytes, line end included.
    record: Vec<u8>,
    /// The raw span of each field in `record` (quotes and spaces included, line end excluded).
    fields: Vec<Span<usize>>,
    /// 1-based line on which the current record starts.
    line: u64,
    /// Lines the current record spans.
    lines: u64,
    /// The field separator.
    separator: u8,
}

impl Records {
    /// Opens `path`; its dialect (separator, records before the header) from its start.
    fn open(path: &Path) -> Result<(Self, Dialect), Error> {
        let io = |source| Error::Io {
            path: path.to_path_buf(),
            source,
        };
        let (file, dialect) = dialect::open(path).map_err(io)?;
        if !dialect.is_plain() {
            return Err(csv_error(
                path,
                1,
                None,
                format!(
                    "this file is laid out as {}: the methods read it, but `apply` rewrites only \
                     CSV logs with one header row and `,` `;` or tab separators; apply the table \
                     to a copy in that layout (as `calib simulate` writes)",
                    dialect.describe()
                ),
            ));
        }
        let records = Records {
            path: path.to_path_buf(),
            input: BufReader::with_capacity(1 << 16, LineLimit::new(file)),
            record: Vec::new(),
            fields: Vec::new(),
            line: 0,
            lines: 1,
            separator: dialect.separator,
        };
        Ok((records, dialect))
    }

    /// Reads the next record; `false` at the end of the file. A blank line is a record with no
    /// fields.
    fn next(&mut self) -> Result<bool, Error> {
        self.line += self.lines;
        self.record.clear();
        self.lines = 0;
        loop {
            let n = self
                .input
                .read_until(b'\n', &mut self.record)
                .map_err(|source| match line_too_long(&source) {
                    Some(long) => Error::Csv {
                        path: self.path.clone(),
                        line: long.line,
                        channel: None,
                        message: long.to_string(),
                    },
                    None => Error::Io {
                        path: self.path.clone(),
                        source,
                    },
                })?;
            if n == 0 {
                break;
            }
            self.lines += 1;
            // A line end inside quotes belongs to the field: read on.
            let quotes = self.record.iter().filter(|&&b| b == b'"').count();
            if quotes % 2 == 0 {
                break;
            }
        }
        if self.record.is_empty() {
            return Ok(false);
        }
        self.split();
        Ok(true)
    }

    /// Fills `fields` with the raw spans of the record's fields.
    fn split(&mut self) {
        self.fields.clear();
        let mut end = self.record.len();
        while end > 0 && matches!(self.record[end - 1], b'\n' | b'\r') {
            end -= 1;
        }
        if end == 0 {
            return;
        }
        let mut start = 0;
        let mut quoted = false;
        for (i, &b) in self.record[..end].iter().enumerate() {
            match b {
                b'"' => quoted = !quoted,
                b if b == self.separator && !quoted => {
                    self.fields.push(start..i);
                    start = i + 1;
                }
                _ => {}
            }
        }
        self.fields.push(start..end);
    }

    /// Field `i`'s value: spaces trimmed, quotes removed.
    fn field(&self, i: usize) -> Cow<'_, [u8]> {
        let raw = self.record[self.fields[i].clone()].trim_ascii();
        match raw.strip_prefix(b"\"").and_then(|r| r.strip_suffix(b"\"")) {
            Some(inner) if inner.windows(2).any(|w| w == b"\"\"") => {
                let mut out = Vec::with_capacity(inner.len());
                let mut bytes = inner.iter();
                while let Some(&b) = bytes.next() {
                    out.push(b);
                    if b == b'"' {
                        bytes.next();
                    }
                }
                Cow::Owned(out)
            }
            Some(inner) => Cow::Borrowed(inner),
            None => Cow::Borrowed(raw),
        }
    }

    /// Whether the current record has a field reading `name` (spaces around it aside).
    fn has_field(&self, name: &str) -> bool {
        (0..self.fields.len()).any(|i| self.field(i).trim_ascii() == name.as_bytes())
    }

    fn error(&self, column: Option<&str>, message: String) -> Error {
        csv_error(&self.path, self.line, column, message)
    }
}

/// A record of the log as [`walk`] hands it on.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Row {
    /// A line before the header, or a blank line.
    Other,
    /// The header, and the channel's column in it.
    Header(usize),
    /// A data row: the channel's column and its value (in the file's unit).
    Data(usize, f64),
}

/// A pass over the log: `each(records, row)` for every record, in order (see [`Row`]).
fn walk(
    path: &Path,
    channel: &str,
    mut each: impl FnMut(&Records, Row) -> Result<(), Error>,
) -> Result<(), Error> {
    let (mut records, dialect) = Records::open(path)?;
    // The lines before the header (instrument, date, …) are copied as they are: `skip`
    // records, not counting blank lines (which the dialect's reader passes over).
    let mut skipped = 0;
    while skipped < dialect.skip {
        if !records.next()? {
            break;
        }
        if !records.fields.is_empty() {
            skipped += 1;
        }
        each(&records, Row::Other)?;
    }
    // The header is the first record that is not a blank line.
    loop {
        if !records.next()? {
            return Err(records.error(
                None,
                "the file is empty; a CSV log needs a header row such as `t,a,b`".into(),
            ));
        }
        if !records.fields.is_empty() {
            break;
        }
        each(&records, Row::Other)?;
    }
    let names: Vec<String> = (0..records.fields.len())
        .map(|i| {
            let f = records.field(i);
            let f = if i == 0 {
                f.strip_prefix(UTF8_BOM).unwrap_or(&f).to_vec()
            } else {
                f.into_owned()
            };
            String::from_utf8_lossy(f.trim_ascii()).into_owned()
        })
        .collect();
    let time = dialect::time_column(&names, None, None).map(|(i, _)| i);
    let is_channel = |i: usize| Some(i) != time && names[i] != "session";
    let column = (0..names.len())
        .find(|&i| names[i] == channel && is_channel(i))
        .ok_or_else(|| {
            let channels: Vec<&str> = (0..names.len())
                .filter(|&i| is_channel(i))
                .map(|i| names[i].as_str())
                .collect();
            records.error(
                Some(channel),
                format!(
                    "no channel `{channel}` in the header (it has: {}); pick one of those names",
                    channels.join(", ")
                ),
            )
        })?;
    each(&records, Row::Header(column))?;
    while records.next()? {
        if records.fields.is_empty() {
            each(&records, Row::Other)?;
            continue;
        }
        if records.fields.len() != names.len() {
            return Err(records.error(
                None,
                format!(
                    "the row has {} fields but the header has {} columns ({}); give every row \
                     exactly one field per header column",
                    records.fields.len(),
                    names.len(),
                    names.join(", ")
                ),
            ));
        }
        let raw = records.field(column);
        let value = parse_f64(&raw).filter(|v| v.is_finite()).ok_or_else(|| {
            records.error(
                Some(channel),
                format!(
                    "reading `{}` is not a finite number; repair or remove the row",
                    String::from_utf8_lossy(raw.trim_ascii())
                ),
            )
        })?;
        each(&records, Row::Data(column, value))?;
    }
    Ok(())
}

/// The range of the channel's readings.
pub(super) fn scan(path: &Path, channel: &str, unit: AngleUnit) -> Result<Readings, Error> {
    let mut range = Readings::new(unit);
    walk(path, channel, |_, row| {
        if let Row::Data(_, x) = row {
            range.add(x, unit);
        }
        Ok(())
    })?;
    Ok(range)
}

/// Decimals enough to hold 0.001″ in `unit`: a corrected reading never loses its correction to
/// rounding.
fn resolving_decimals(unit: AngleUnit) -> usize {
    let step = unit
        .from_rad(0.001 / calib_core::angle::ARCSEC_PER_RAD)
        .abs();
    (-step.log10()).ceil().clamp(0.0, 17.0) as usize
}

/// `value` written as the file writes the reading it replaces (`field`'s raw bytes): as many
/// decimals (at least [`resolving_decimals`]) and the same decimal mark, so the corrected column
/// reads like the others. `None` for a field in another notation (an exponent, quotes), which
/// gets the shortest form that reads back exactly.
fn as_written(value: f64, field: &[u8], unit: AngleUnit) -> Option<String> {
    let field = std::str::from_utf8(field).ok()?.trim();
    if !field
        .bytes()
        .all(|b| b.is_ascii_digit() || matches!(b, b'-' | b'+' | b'.' | b','))
    {
        return None;
    }
    let mark = if field.contains(',') { ',' } else { '.' };
    let decimals = field
        .rsplit_once(mark)
        .map_or(0, |(_, d)| d.len())
        .max(resolving_decimals(unit));
    Some(format!("{value:.decimals$}").replace('.', &mark.to_string()))
}

/// Writes `output` with the channel's readings corrected; returns how many. With `keep`, the
/// channel's field stays as it was and a field is added after it: `keep` in the header, the
/// corrected reading in every row.
pub(super) fn rewrite(
    input: &Path,
    output: &Path,
    channel: &str,
    fix: &Correction,
    keep: Option<&str>,
) -> Result<u64, Error> {
    let mut out = AtomicFile::create(output)?;
    let io = |source| Error::Io {
        path: output.to_path_buf(),
        source,
    };
    let mut count = 0u64;
    let mut number = ryu::Buffer::new();
    walk(input, channel, |records, row| {
        let (column, x) = match row {
            Row::Other => return out.write_all(&records.record).map_err(io),
            Row::Header(column) => {
                let Some(name) = keep else {
                    return out.write_all(&records.record).map_err(io);
                };
                if records.has_field(name) {
                    return Err(records.error(
                        Some(name),
                        format!(
                            "the header has a column `{name}` already, where the `keep` option \
                             would add the corrected `{channel}`; rename that column or leave out the `keep` option"
                        ),
                    ));
                }
                let end = records.fields[column].end;
                out.write_all(&records.record[..end])
                    .and_then(|()| out.write_all(&[records.separator]))
                    .and_then(|()| out.write_all(name.as_bytes()))
                    .and_then(|()| out.write_all(&records.record[end..]))
                    .map_err(io)?;
                return Ok(());
            }
            Row::Data(column, x) => (column, x),
        };
        let span = records.fields[column].clone();
        let field = &records.record[span.clone()];
        let corrected = fix.apply(x);
        let text = as_written(corrected, field, fix.unit())
            .unwrap_or_else(|| number.format_finite(corrected).to_string());
        if keep.is_some() {
            out.write_all(&records.record[..span.end])
                .and_then(|()| out.write_all(&[records.separator]))
        } else {
            out.write_all(&records.record[..span.start])
        }
        .and_then(|()| out.write_all(text.as_bytes()))
        .and_then(|()| out.write_all(&records.record[span.end..]))
        .map_err(io)?;
        count += 1;
        Ok(())
    })?;
    out.commit()?;
    Ok(count)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corrected_readings_are_written_as_the_file_writes_them() {
        // As many decimals as the reading replaced…
        assert_eq!(
            as_written(1.234_567_890_123, b"1.230000000", AngleUnit::Rad).as_deref(),
            Some("1.234567890")
        );
        // …but never so few that the correction rounds away (0.001″ in degrees: 7 decimals).
        assert_eq!(
            as_written(12.500_277_8, b"12.5", AngleUnit::Deg).as_deref(),
            Some("12.5002778")
        );
        // A decimal comma stays a comma.
        assert_eq!(
            as_written(-0.25, b" -0,2500000 ", AngleUnit::Deg).as_deref(),
            Some("-0,2500000")
        );
        // Other notations get the shortest exact form.
        assert_eq!(as_written(1.0, b"1e-3", AngleUnit::Rad), None);
        assert_eq!(as_written(1.0, b"\"1.0\"", AngleUnit::Rad), None);
    }
}
