//! CSV logs: one field of each row rewritten, every other byte copied.
//!
//! The file is split into records by hand (RFC 4180: a record ends at a line end outside
//! quotes) so that each record's raw bytes, and the raw span of each field, are known: the
//! `csv` crate hands out unquoted fields, from which the original bytes cannot be rebuilt. The
//! field syntax accepted is the [`CsvReader`](crate::csv_log::CsvReader)'s: surrounding spaces,
//! a UTF-8 byte order mark, blank lines, quoted fields, line ends `\n`, `\r\n` or `\r` alone
//! (old Mac files), and its dialects ([`crate::csv_log::dialect`]): the separator (`,` `;` tab),
//! the lines before the header, a units row, decimal commas, sparse rows and TwinCAT Scope's
//! property block are found as the reader finds them, and copied as they are, so the output keeps
//! the input's dialect. Two layouts are refused, each saying why: columns aligned by runs of
//! spaces (a rewritten field would shift the columns after it) and files without a header (no
//! column names the channel).

use super::Readings;
use crate::Error;
use crate::atomic::AtomicFile;
use crate::csv_log::dialect::{self, Dialect, Header, WHITESPACE};
use crate::csv_log::{parse_f64, parse_f64_comma};
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
    /// The byte that ends a line: `\n`, or `\r` in a file whose lines end with it alone.
    line_end: u8,
    /// Numbers are written with a decimal comma.
    decimal_comma: bool,
}

/// The bytes looked at to tell a file whose lines end with `\r` alone.
const LINE_END_SNIFF: u64 = 1 << 16;

/// The byte that ends `path`'s lines: `\r` where its start has a `\r` and no `\n` (old Mac
/// line ends, which the methods read), else `\n` (`\r\n` lines end at their `\n`).
fn line_end(path: &Path) -> std::io::Result<u8> {
    use std::io::Read as _;
    let mut head = Vec::new();
    File::open(path)?
        .take(LINE_END_SNIFF)
        .read_to_end(&mut head)?;
    Ok(if head.contains(&b'\r') && !head.contains(&b'\n') {
        b'\r'
    } else {
        b'\n'
    })
}

impl Records {
    /// Opens `path`; its dialect (separator, records before the header) from its start.
    fn open(path: &Path) -> Result<(Self, Dialect), Error> {
        let io = |source| Error::Io {
            path: path.to_path_buf(),
            source,
        };
        let (file, dialect) = dialect::open(path).map_err(io)?;
        let refused = if dialect.separator == WHITESPACE {
            Some(
                "its columns are aligned by runs of spaces, which a corrected field of another width would shift",
            )
        } else if matches!(dialect.header, Header::None { .. }) {
            Some("it has no header row naming the channel's column")
        } else {
            None
        };
        if let Some(why) = refused {
            return Err(csv_error(
                path,
                1,
                None,
                format!(
                    "this file is laid out as {}: the methods read it, but `apply` does not \
                     rewrite it ({why}); apply the table to a copy with a header row and `,` `;` \
                     or tab separators (as `calib simulate` writes)",
                    dialect.describe()
                ),
            ));
        }
        let line_end = line_end(path).map_err(io)?;
        let records = Records {
            path: path.to_path_buf(),
            input: BufReader::with_capacity(1 << 16, LineLimit::new(file)),
            record: Vec::new(),
            fields: Vec::new(),
            line: 0,
            lines: 1,
            separator: dialect.separator,
            line_end,
            decimal_comma: dialect.decimal_comma,
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
                .read_until(self.line_end, &mut self.record)
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
    /// The units row after the header, and the channel's column in it.
    Units(usize),
    /// A sparse row without a reading of the channel (its field empty), and the channel's column.
    Empty(usize),
    /// A data row: the channel's column and its value (in the file's unit).
    Data(usize, f64),
}

/// A pass over the log: `each(records, row)` for every record, in order (see [`Row`]). With
/// `keep` (a column to be added beside the channel's), a layout that has no header row to add
/// it to (TwinCAT Scope's property block) is refused.
fn walk(
    path: &Path,
    channel: &str,
    keep: bool,
    mut each: impl FnMut(&Records, Row) -> Result<(), Error>,
) -> Result<(), Error> {
    let (mut records, dialect) = Records::open(path)?;
    if keep && matches!(dialect.header, Header::Properties(_)) {
        return Err(records.error(
            None,
            "this TwinCAT Scope export names its channels in a block of property rows, where \
             the `keep` option cannot add a column; leave the `keep` option out (the channel is \
             corrected in place)"
                .into(),
        ));
    }
    // The lines before the header (instrument, date, …; TwinCAT's property block) are copied as
    // they are: `skip` records, not counting blank lines (which the dialect's reader passes
    // over).
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
    let (names, time) = match &dialect.header {
        Header::Properties(p) => {
            let names: Vec<String> = p
                .filetime
                .then(|| "FILETIME".to_string())
                .into_iter()
                .chain(p.names.iter().cloned())
                .collect();
            let time = if p.filetime {
                Some(0)
            } else {
                dialect::time_column(&names, None, None).map(|(i, _)| i)
            };
            (names, time)
        }
        _ => {
            let names = header_names(&mut records, &mut each)?;
            let time = dialect::time_column(&names, None, None).map(|(i, _)| i);
            (names, time)
        }
    };
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
    if let Header::Row { units } = &dialect.header {
        each(&records, Row::Header(column))?;
        if units.is_some() {
            // The units row: the first record after the header that is not a blank line.
            while records.next()? {
                if !records.fields.is_empty() {
                    each(&records, Row::Units(column))?;
                    break;
                }
                each(&records, Row::Other)?;
            }
        }
    }
    let twincat = matches!(dialect.header, Header::Properties(_));
    while records.next()? {
        if records.fields.is_empty() {
            each(&records, Row::Other)?;
            continue;
        }
        // TwinCAT Scope ends its exports with a line `EOF`.
        if twincat && records.fields.len() == 1 && &*records.field(0) == b"EOF" {
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
        if dialect.sparse && raw.trim_ascii().is_empty() {
            each(&records, Row::Empty(column))?;
            continue;
        }
        let number = if dialect.decimal_comma {
            parse_f64_comma(&raw)
        } else {
            parse_f64(&raw)
        };
        let value = number.filter(|v| v.is_finite()).ok_or_else(|| {
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

/// Reads up to the header (the first record that is not a blank line, the blank lines handed to
/// `each` as they come) and returns its names.
fn header_names(
    records: &mut Records,
    each: &mut impl FnMut(&Records, Row) -> Result<(), Error>,
) -> Result<Vec<String>, Error> {
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
        each(records, Row::Other)?;
    }
    Ok((0..records.fields.len())
        .map(|i| {
            let f = records.field(i);
            let f = if i == 0 {
                f.strip_prefix(UTF8_BOM).unwrap_or(&f).to_vec()
            } else {
                f.into_owned()
            };
            String::from_utf8_lossy(f.trim_ascii()).into_owned()
        })
        .collect())
}

/// The range of the channel's readings.
pub(super) fn scan(path: &Path, channel: &str, unit: AngleUnit) -> Result<Readings, Error> {
    let mut range = Readings::new(unit);
    walk(path, channel, false, |_, row| {
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
/// decimals (at least [`resolving_decimals`]) and the same decimal mark (`,` where
/// `decimal_comma` or the field has one), in the same notation (an exponent if the field has
/// one, as many mantissa decimals, at least those that resolve 0.001″) and within the same
/// quotes, so the corrected column reads like the others. `None` for a field that is none of
/// these (`inf`, text), which gets the shortest form that reads back exactly.
fn as_written(value: f64, field: &[u8], unit: AngleUnit, decimal_comma: bool) -> Option<String> {
    let field = std::str::from_utf8(field).ok()?.trim();
    if let Some(inner) = field.strip_prefix('"').and_then(|f| f.strip_suffix('"')) {
        return Some(format!(
            "\"{}\"",
            as_written(value, inner.as_bytes(), unit, decimal_comma)?
        ));
    }
    let plain = |f: &str| {
        !f.is_empty()
            && f.bytes()
                .all(|b| b.is_ascii_digit() || matches!(b, b'-' | b'+' | b'.' | b','))
    };
    let mark = if decimal_comma || field.contains(',') {
        ','
    } else {
        '.'
    };
    let decimals_of = |mantissa: &str| mantissa.rsplit_once(mark).map_or(0, |(_, d)| d.len());
    let resolving = resolving_decimals(unit);
    let text = if let Some((mantissa, exponent)) = field.split_once(['e', 'E']) {
        if !plain(mantissa) || exponent.parse::<i32>().is_err() {
            return None;
        }
        // Mantissa decimals that resolve 0.001″ at this value's magnitude.
        let magnitude = if value == 0.0 {
            0
        } else {
            value.abs().log10().floor() as i64
        };
        let needed = (resolving as i64 + magnitude).clamp(0, 17) as usize;
        let decimals = decimals_of(mantissa).max(needed);
        let written = format!("{value:.decimals$e}");
        if field.contains('E') {
            written.replace('e', "E")
        } else {
            written
        }
    } else {
        if !plain(field) {
            return None;
        }
        let decimals = decimals_of(field).max(resolving);
        format!("{value:.decimals$}")
    };
    Some(text.replace('.', &mark.to_string()))
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
    walk(input, channel, keep.is_some(), |records, row| {
        let (column, x) = match row {
            Row::Other => return out.write_all(&records.record).map_err(io),
            // The added column's unit is the channel's; a row without the channel's reading has
            // none of the corrected one either.
            Row::Units(column) | Row::Empty(column) => {
                if keep.is_none() {
                    return out.write_all(&records.record).map_err(io);
                }
                let span = records.fields[column].clone();
                let added: &[u8] = match row {
                    Row::Units(_) => &records.record[span.clone()],
                    _ => b"",
                };
                return out
                    .write_all(&records.record[..span.end])
                    .and_then(|()| out.write_all(&[records.separator]))
                    .and_then(|()| out.write_all(added))
                    .and_then(|()| out.write_all(&records.record[span.end..]))
                    .map_err(io);
            }
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
        let text = as_written(corrected, field, fix.unit(), records.decimal_comma)
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
        let deg = AngleUnit::Deg;
        // As many decimals as the reading replaced…
        assert_eq!(
            as_written(1.234_567_890_123, b"1.230000000", AngleUnit::Rad, false).as_deref(),
            Some("1.234567890")
        );
        // …but never so few that the correction rounds away (0.001″ in degrees: 7 decimals).
        assert_eq!(
            as_written(12.500_277_8, b"12.5", deg, false).as_deref(),
            Some("12.5002778")
        );
        // A decimal comma stays a comma, also in a field that has none (`12` in a file of
        // decimal commas).
        assert_eq!(
            as_written(-0.25, b" -0,2500000 ", deg, false).as_deref(),
            Some("-0,2500000")
        );
        assert_eq!(
            as_written(12.000_277_8, b"12", deg, true).as_deref(),
            Some("12,0002778")
        );
        // Text is not a reading's notation: the shortest exact form.
        assert_eq!(as_written(1.0, b"inf", AngleUnit::Rad, false), None);
    }

    /// A quoted field stays quoted, with its decimals (it was written in full precision,
    /// `4.242966911843782e-9`, unquoted); a field in exponent notation keeps it, with its
    /// mantissa's decimals or those that resolve 0.001″ (radians: 4.8e-9).
    #[test]
    fn quoted_and_exponent_fields_keep_their_notation() {
        let rad = AngleUnit::Rad;
        assert_eq!(
            as_written(0.123_456_789_04, b"\"0.123400000\"", rad, false).as_deref(),
            Some("\"0.123456789\"")
        );
        assert_eq!(
            as_written(1.234_567_8e-3, b"1.2e-3", rad, false).as_deref(),
            Some("1.234568e-3")
        );
        assert_eq!(
            as_written(1.234_567_8e-3, b"1.200000000E-03", rad, false).as_deref(),
            Some("1.234567800E-3")
        );
        assert_eq!(
            as_written(-2.5, b"\"-2,50e0\"", AngleUnit::Deg, true).as_deref(),
            Some("\"-2,5000000e0\"")
        );
    }
}
