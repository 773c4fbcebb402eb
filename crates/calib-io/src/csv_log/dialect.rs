//! CSV dialects as lab software writes them: the separator, the decimal mark, lines before the
//! header, a units row, files without a header, TwinCAT Scope's property block, and the name
//! and unit of the time column.
//!
//! TwinCAT Scope, LabVIEW, oscilloscopes and DAQ tools write `;` or tab separators, a few lines
//! of metadata (instrument, date, sample rate) before the header, and a time column called
//! `Time [s]`, `time`, `timestamp_ms`, …; MATLAB and `numpy.savetxt` write numbers separated by
//! spaces without any header. This module finds, from the first [`SNIFF_BYTES`] of the file:
//! - the **separator**: `,`, `;` or tab, whichever gives a header with the most columns; runs of
//!   spaces and tabs ([`WHITESPACE`]) where none of these gives one;
//! - the **decimal mark**: a comma where the separator is not one and the data rows hold
//!   numbers such as `1,25` ([`Dialect::decimal_comma`]);
//! - **sparse rows** ([`Dialect::sparse`]): data rows with empty cells (a plotting tool's export
//!   where each channel has its own stamps) make each channel a series of its own;
//! - the **header** ([`Header`]):
//!   - a row: the first line whose fields (at least two) are all non-numeric and that is
//!     followed by a line of as many fields, most of them numeric (a bad field in the first row
//!     is then reported at its line and column, not as a missing header); the lines before it
//!     are skipped. A line of units between the header and the data (`s,deg,deg`: every field
//!     empty or a time or angle unit, bare or in brackets) is skipped too, its time and angle
//!     units taken where no option gives them;
//!   - TwinCAT Scope's property block ([`Properties`]): a `Name` row naming the channels
//!     followed by rows of channel properties (`Data-Type`, `SampleTime`, `Unit`, …) and, after
//!     them, the data rows: the first column a Windows FILETIME (100 ns ticks since 1601) if the
//!     data rows have one field more than there are channels, else the time is the row index
//!     times `SampleTime` (ms);
//!   - none: the first line is already numeric (a matrix of numbers); the columns are named
//!     `1`, `2`, … and the file has no time column.
//! - the **time column** ([`time_column`]): the one `--time-column` names, else one whose name
//!   is `t`, `time` or `timestamp` or the word for time in German, French, Spanish, Italian,
//!   Polish, Japanese or Chinese ([`TIME_NAMES`]: `Zeit [s]`), any case, bare or with a unit
//!   suffix ` [s]`, `[ms]`, ` (us)`, `_ns`, …; its unit from `--time-unit`, the suffix or a
//!   units row, else from the first stamp's magnitude where it is a date since 1970 in ms, µs or
//!   ns ([`epoch_unit`]), else seconds.
//!
//! A file in which no header can be found this way (a header with no data rows, say) is read as
//! the plain dialect — `,` and the header on line 1 — so that its errors stay the usual ones.

use super::fields::{parse_f64, parse_f64_comma};
use calib_core::AngleUnit;
use std::fs::File;
use std::io::{self, Read, Seek};
use std::path::Path;

/// Bytes of the file's start that the separator and header are found in: metadata blocks are a
/// few lines, and a header with its first data row is rarely longer than a few kilobytes.
pub const SNIFF_BYTES: usize = 64 * 1024;

/// Records of the file's start searched for the header.
const SNIFF_RECORDS: usize = 256;

/// The separators tried, in order of preference on a tie.
const SEPARATORS: [u8; 3] = [b',', b';', b'\t'];

/// The separator that stands for runs of spaces and tabs (leading and trailing ones ignored).
pub const WHITESPACE: u8 = b' ';

/// Rows of a TwinCAT property block looked through for its `Data-Type` or `SampleTime` row.
const PROPERTY_ROWS: usize = 64;

/// How a CSV file is laid out.
#[derive(Debug, Clone, PartialEq)]
pub struct Dialect {
    /// The field separator; [`WHITESPACE`] for runs of spaces and tabs.
    pub separator: u8,
    /// Records (non-blank lines) before the header, skipped; for [`Header::None`] and
    /// [`Header::Properties`], before the first data row.
    pub skip: usize,
    /// Numbers are written with a decimal comma (`1,25`); never with the `,` separator.
    pub decimal_comma: bool,
    /// Data rows leave a channel's cell empty where it has no sample (PlotJuggler, Foxglove):
    /// each channel is a series of its own (only with [`Header::Row`]).
    pub sparse: bool,
    /// Where the column names come from.
    pub header: Header,
}

/// Where a file's column names come from.
#[derive(Debug, Clone, PartialEq)]
pub enum Header {
    /// The record after the skipped ones; `units` holds the units row that follows it, if any.
    Row {
        /// The units row's fields, trimmed (one per column).
        units: Option<Vec<String>>,
    },
    /// No header: the columns are named `1`, `2`, … .
    None {
        /// Fields of the first data row.
        columns: usize,
    },
    /// TwinCAT Scope's property block.
    Properties(Properties),
    /// A TwinCAT Scope property block whose data rows hold neither one field per channel nor a
    /// FILETIME column and one per channel (a time column per channel, say): refused by the
    /// reader, which says what it found, rather than read as some other layout.
    UnknownProperties {
        /// The channels the `Name` row names.
        channels: usize,
        /// Fields of the first data row.
        fields: usize,
        /// Records (non-blank lines) before the `Name` row.
        name_record: usize,
    },
}

/// What a TwinCAT Scope export's property block says of its channels.
#[derive(Debug, Clone, PartialEq)]
pub struct Properties {
    /// The channels' names (the `Name` row).
    pub names: Vec<String>,
    /// The channels' units (the `Unit` row; `(None)` where none is set), if the row is there.
    pub units: Vec<String>,
    /// The first channel's `SampleTime`, seconds (the row gives ms), if given.
    pub sample_time_s: Option<f64>,
    /// The data rows start with a FILETIME column (one field more than there are channels).
    pub filetime: bool,
    /// The channels' `SymbolName`s (the PLC variables), if the row is there: what tells two
    /// channels of one name apart.
    pub symbols: Vec<String>,
    /// Records (non-blank lines) before the `Name` row, for messages that name its line.
    pub name_record: usize,
}

impl Default for Dialect {
    fn default() -> Self {
        Dialect {
            separator: b',',
            skip: 0,
            decimal_comma: false,
            sparse: false,
            header: Header::Row { units: None },
        }
    }
}

impl Dialect {
    /// A few words naming the layout, for messages and `inspect`.
    pub fn describe(&self) -> String {
        if self.header == (Header::None { columns: 1 }) {
            return "one number per line, no header (column 1)".to_string();
        }
        let separator = match self.separator {
            b',' => "`,`",
            b';' => "`;`",
            b'\t' => "tab",
            _ => "whitespace",
        };
        let layout = match &self.header {
            Header::Row { units: None } => "a header row",
            Header::Row { units: Some(_) } => "a header row and a units row",
            Header::None { .. } => "no header (columns 1, 2, …)",
            Header::Properties(p) if p.filetime => {
                "TwinCAT Scope's property block, FILETIME time stamps"
            }
            Header::Properties(_) => "TwinCAT Scope's property block, time from SampleTime",
            Header::UnknownProperties { .. } => {
                "TwinCAT Scope's property block, data rows of an unknown layout"
            }
        };
        format!(
            "{separator}-separated{}{}, {layout}",
            if self.decimal_comma {
                ", decimal commas"
            } else {
                ""
            },
            if self.sparse {
                ", sparse rows (each channel its own series)"
            } else {
                ""
            }
        )
    }

    /// The plain dialect calib writes: `,`, a header row and nothing else before the data.
    pub fn is_plain(&self) -> bool {
        self.separator != WHITESPACE
            && !self.decimal_comma
            && !self.sparse
            && self.header == Header::Row { units: None }
    }
}

/// The unit of a time column.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimeUnit {
    /// Seconds.
    S,
    /// Milliseconds.
    Ms,
    /// Microseconds.
    Us,
    /// Nanoseconds.
    Ns,
    /// Ticks of 100 ns (Windows FILETIME, .NET).
    Ticks,
}

impl TimeUnit {
    /// Seconds per unit.
    pub fn seconds(self) -> f64 {
        match self {
            TimeUnit::S => 1.0,
            TimeUnit::Ms => 1e-3,
            TimeUnit::Us => 1e-6,
            TimeUnit::Ns => 1e-9,
            TimeUnit::Ticks => 1e-7,
        }
    }

    /// The unit a suffix names: `s`, `ms`, `us`, `µs`, `ns`, `100ns` (any case).
    pub fn from_suffix(s: &str) -> Option<Self> {
        match s.to_ascii_lowercase().as_str() {
            "s" | "sec" => Some(TimeUnit::S),
            "ms" => Some(TimeUnit::Ms),
            "us" | "µs" | "μs" => Some(TimeUnit::Us),
            "ns" => Some(TimeUnit::Ns),
            "100ns" | "ticks" => Some(TimeUnit::Ticks),
            _ => None,
        }
    }
}

impl TimeUnit {
    /// The unit's name in a sentence: `seconds`, `milliseconds`, …
    pub fn name(self) -> &'static str {
        match self {
            TimeUnit::S => "seconds",
            TimeUnit::Ms => "milliseconds",
            TimeUnit::Us => "microseconds",
            TimeUnit::Ns => "nanoseconds",
            TimeUnit::Ticks => "100 ns ticks",
        }
    }

    /// The unit as the `time_unit` option takes it: `s`, `ms`, `us`, `ns`, `100ns`.
    pub fn suffix(self) -> &'static str {
        match self {
            TimeUnit::S => "s",
            TimeUnit::Ms => "ms",
            TimeUnit::Us => "us",
            TimeUnit::Ns => "ns",
            TimeUnit::Ticks => "100ns",
        }
    }
}

impl std::str::FromStr for TimeUnit {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        TimeUnit::from_suffix(s)
            .ok_or_else(|| format!("unknown time unit `{s}`; use s, ms, us, ns or 100ns"))
    }
}

/// An angle unit as a units row or a TwinCAT `Unit` row writes it: `deg`, `°`, `rad`, …,
/// bare or in brackets.
pub fn angle_unit(text: &str) -> Option<AngleUnit> {
    match unbracket(text) {
        "°" | "degree" | "Degree" | "DEG" | "Deg" => Some(AngleUnit::Deg),
        u => u.parse().ok(),
    }
}

/// `text` trimmed and without one pair of surrounding brackets.
pub(crate) fn unbracket(text: &str) -> &str {
    let t = text.trim();
    t.strip_prefix('[')
        .and_then(|r| r.strip_suffix(']'))
        .or_else(|| t.strip_prefix('(').and_then(|r| r.strip_suffix(')')))
        .unwrap_or(t)
        .trim()
}

/// Opens `path` and finds its dialect from its first [`SNIFF_BYTES`]; the file is handed back
/// rewound to its start. A named pipe (or another stream that cannot be rewound) is refused
/// with `read_twice`'s message, not left to fail with the system's "Illegal seek".
pub fn open(path: &Path) -> io::Result<(File, Dialect)> {
    // Looked at before opening: opening a pipe waits for a writer.
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() && !meta.is_dir() {
        return Err(crate::error::read_twice("log"));
    }
    let mut file = File::open(path)?;
    let mut head = Vec::with_capacity(SNIFF_BYTES);
    (&mut file)
        .take(SNIFF_BYTES as u64)
        .read_to_end(&mut head)?;
    file.rewind()?;
    Ok((file, sniff(&head)))
}

/// A sniffed record: its fields.
type Fields = Vec<Vec<u8>>;

/// The first [`SNIFF_RECORDS`] records of `head` split at `separator` as the reader splits them
/// (blank lines skipped).
fn records(head: &[u8], separator: u8) -> Vec<Fields> {
    if separator == WHITESPACE {
        return head
            .split(|&b| b == b'\n' || b == b'\r')
            .map(|line| {
                line.split(u8::is_ascii_whitespace)
                    .filter(|w| !w.is_empty())
                    .map(<[u8]>::to_vec)
                    .collect::<Fields>()
            })
            .filter(|r| !r.is_empty())
            .take(SNIFF_RECORDS)
            .collect();
    }
    csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .delimiter(separator)
        .from_reader(head)
        .byte_records()
        .take(SNIFF_RECORDS)
        .map_while(Result::ok)
        .map(|r| r.iter().map(<[u8]>::to_vec).collect())
        .collect()
}

/// The dialect of a file starting with `head` (see the [module docs](self)).
pub fn sniff(head: &[u8]) -> Dialect {
    let mut best: Option<(usize, Dialect)> = None;
    for separator in SEPARATORS {
        let records = records(head, separator);
        if let Some(d) = properties(&records, separator) {
            return d;
        }
        if let Some(d) = header_row(&records, separator) {
            let columns = records[d.skip].len();
            if best.as_ref().is_none_or(|(c, _)| columns > *c) {
                best = Some((columns, d));
            }
        }
    }
    if let Some((_, d)) = best {
        return d;
    }
    if let Some(d) = header_row(&records(head, WHITESPACE), WHITESPACE) {
        return d;
    }
    // No header: a matrix of numbers, the separator that gives the most columns.
    let mut best: Option<(usize, Dialect)> = None;
    for separator in SEPARATORS.into_iter().chain([WHITESPACE]) {
        let records = records(head, separator);
        let Some(first) = records.first() else {
            continue;
        };
        let comma = separator != b',';
        let width = first.len();
        let matrix = records
            .iter()
            .take(8)
            .all(|r| r.len() == width && r.iter().all(|f| number(f, comma)));
        if matrix && best.as_ref().is_none_or(|(c, _)| width > *c) {
            best = Some((
                width,
                Dialect {
                    separator,
                    skip: 0,
                    decimal_comma: comma && has_comma_numbers(&records),
                    sparse: false,
                    header: Header::None { columns: width },
                },
            ));
        }
    }
    best.map(|(_, d)| d).unwrap_or_default()
}

/// Whether the data rows `data` under `header` are sparse: a time and at least two channels
/// (`width ≥ 3`), some row with an empty cell, and every column filled in some row. A point
/// list's `direction` column ([`super::direction`]), whose empty cells mean "from the order of
/// the points", does not count.
fn sparse(data: &[Fields], header: &Fields) -> bool {
    let width = header.len();
    let rows = || data.iter().filter(|d| d.len() == width);
    let empty = |f: &Vec<u8>| f.trim_ascii().is_empty();
    let counted: Vec<usize> = (0..width)
        .filter(|&c| {
            !std::str::from_utf8(&header[c]).is_ok_and(super::direction::is_direction_column)
        })
        .collect();
    width >= 3
        && rows().any(|d| counted.iter().any(|&c| empty(&d[c])))
        && (0..width).all(|c| rows().any(|d| !empty(&d[c])))
}

/// Whether `field` is a number (with a decimal comma if `comma`).
fn number(field: &[u8], comma: bool) -> bool {
    parse_f64(field).is_some() || (comma && parse_f64_comma(field).is_some())
}

/// Whether most of `record`'s non-empty fields are numbers (empty ones are a sparse row's
/// channels without a sample).
fn numeric(record: &Fields, comma: bool) -> bool {
    let filled = record.iter().filter(|f| !f.trim_ascii().is_empty()).count();
    2 * record.iter().filter(|f| number(f, comma)).count() > filled
}

/// Whether some field of `records` is a number written with a decimal comma.
fn has_comma_numbers(records: &[Fields]) -> bool {
    records
        .iter()
        .flatten()
        .any(|f| f.contains(&b',') && parse_f64_comma(f).is_some())
}

/// The header-row dialect of `records`, if one has a header row followed by data.
fn header_row(records: &[Fields], separator: u8) -> Option<Dialect> {
    let comma = separator != b',';
    let names = |r: &Fields| {
        r.len() >= 2
            && r.iter()
                .all(|f| !f.trim_ascii().is_empty() && !number(f, comma))
    };
    for (i, r) in records.iter().enumerate() {
        if !names(r) {
            continue;
        }
        let data = |j: usize| {
            records
                .get(j)
                .is_some_and(|d| d.len() == r.len() && numeric(d, comma))
        };
        let units = records.get(i + 1).filter(|u| {
            u.len() == r.len()
                && u.iter().all(|f| is_unit(f))
                && u.iter().any(|f| !f.trim_ascii().is_empty())
        });
        let (units, first_data) = match units {
            Some(u) if data(i + 2) => (
                Some(
                    u.iter()
                        .map(|f| String::from_utf8_lossy(f.trim_ascii()).into_owned())
                        .collect(),
                ),
                i + 2,
            ),
            _ if data(i + 1) => (None, i + 1),
            _ => continue,
        };
        return Some(Dialect {
            separator,
            skip: i,
            decimal_comma: comma && has_comma_numbers(&records[first_data..]),
            sparse: sparse(&records[first_data..], r),
            header: Header::Row { units },
        });
    }
    None
}

/// Whether a units row's field names a unit (or is empty).
fn is_unit(field: &[u8]) -> bool {
    let Ok(text) = std::str::from_utf8(field) else {
        return false;
    };
    let u = unbracket(text);
    u.is_empty() || u == "-" || TimeUnit::from_suffix(u).is_some() || angle_unit(u).is_some()
}

/// TwinCAT Scope's dialect, if `records` hold its property block (see the [module docs](self)).
fn properties(records: &[Fields], separator: u8) -> Option<Dialect> {
    let text = |f: &[u8]| String::from_utf8_lossy(f.trim_ascii()).into_owned();
    let key = |r: &Fields| r.first().map(|f| text(f)).unwrap_or_default();
    let comma = separator != b',';
    // A property row starts with its name; a data row with a number (a single channel's rows
    // without a time column hold that number alone).
    let is_data = |r: &Fields| r.first().is_some_and(|f| number(f, comma)) && numeric(r, comma);
    for (i, r) in records.iter().enumerate() {
        if key(r) != "Name" {
            continue;
        }
        // The block ends at the data or at the next `Name` row: the export's title line
        // (`Name;<title>;`) heads the file's own metadata, not the channels' properties.
        let block: Vec<&Fields> = records[i + 1..]
            .iter()
            .take_while(|r| !is_data(r) && key(r) != "Name")
            .take(PROPERTY_ROWS)
            .collect();
        if !block
            .iter()
            .any(|r| matches!(key(r).as_str(), "Data-Type" | "SampleTime"))
        {
            continue;
        }
        let mut names: Vec<String> = r[1..].iter().map(|f| text(f)).collect();
        while names.last().is_some_and(String::is_empty) {
            names.pop();
        }
        let data = i + 1 + block.len();
        let width = records.get(data)?.len();
        let filetime = if width == names.len() + 1 {
            true
        } else if width == names.len() {
            false
        } else {
            return Some(Dialect {
                separator,
                skip: data,
                decimal_comma: false,
                sparse: false,
                header: Header::UnknownProperties {
                    channels: names.len(),
                    fields: width,
                    name_record: i,
                },
            });
        };
        let row = |name: &str| -> Vec<String> {
            block
                .iter()
                .find(|r| key(r) == name)
                .map(|r| r[1..].iter().map(|f| text(f)).collect())
                .unwrap_or_default()
        };
        let sample_time_s = row("SampleTime")
            .first()
            .and_then(|s| s.replace(',', ".").parse::<f64>().ok())
            .filter(|s| s.is_finite() && *s > 0.0)
            .map(|ms| ms * 1e-3);
        return Some(Dialect {
            separator,
            skip: data,
            decimal_comma: comma && has_comma_numbers(&records[data..]),
            sparse: false,
            header: Header::Properties(Properties {
                names,
                units: row("Unit"),
                sample_time_s,
                filetime,
                symbols: row("SymbolName"),
                name_record: i,
            }),
        });
    }
    None
}

/// The time column among `names` and its unit: the one `wanted` names, else the first whose name
/// is `t`, `time` or `timestamp` with an optional unit suffix. `unit` overrides the suffix's unit.
/// `None` if there is none.
pub fn time_column(
    names: &[String],
    wanted: Option<&str>,
    unit: Option<TimeUnit>,
) -> Option<(usize, TimeUnit)> {
    let (i, suffix_unit) = match wanted {
        Some(w) => {
            let i = names.iter().position(|n| n == w)?;
            (i, parse_time_name(w).and_then(|(_, u)| u))
        }
        None => {
            // An exact `t` first: the plain dialect's name.
            let i = names
                .iter()
                .position(|n| n == "t")
                .or_else(|| names.iter().position(|n| parse_time_name(n).is_some()))?;
            (i, parse_time_name(&names[i]).and_then(|(_, u)| u))
        }
    };
    Some((i, unit.or(suffix_unit).unwrap_or(TimeUnit::S)))
}

/// A column among `names` whose name looks like a time column's but is not one calib takes by
/// itself (`Timestamp (UTC)`, `elapsed_time`, `Zeitstempel`): the first whose name holds one of
/// the words of [`TIME_NAMES`] (but `t`) or `stamp`, any case. Named in the error of a file
/// without a time column, with the option that reads it.
pub fn looks_like_time(names: &[String]) -> Option<&str> {
    names
        .iter()
        .find(|n| {
            let lower = n.to_lowercase();
            TIME_NAMES[..2]
                .iter()
                .chain(&TIME_NAMES[3..])
                .chain(&["stamp"])
                .any(|w| lower.contains(w))
        })
        .map(String::as_str)
}

/// Stamps since 1970 (Unix time) are taken as dates from 1990-01-01 (631,152,000 s) …
const EPOCH_FROM_S: f64 = 631_152_000.0;
/// … to 2100-01-01 (4,102,444,800 s): in s, ms, µs and ns these ranges are 1000× apart and
/// each spans a factor of 6.5, so at most one unit holds a given stamp.
const EPOCH_TO_S: f64 = 4_102_444_800.0;

/// The unit in which `stamp`, a time column's number, is a date between 1990 and 2100 counted
/// since 1970 (s ~1.7·10⁹, ms ~1.7·10¹², µs ~1.7·10¹⁵, ns ~1.7·10¹⁸), and that year; `None`
/// if it is one in none (a time from the start of the run, a FILETIME).
pub fn epoch_unit(stamp: f64) -> Option<(TimeUnit, i32)> {
    [TimeUnit::S, TimeUnit::Ms, TimeUnit::Us, TimeUnit::Ns]
        .into_iter()
        .map(|u| (u, stamp * u.seconds()))
        .find(|(_, s)| (EPOCH_FROM_S..EPOCH_TO_S).contains(s))
        // The mean Gregorian year: 365.2425 days.
        .map(|(u, s)| (u, 1970 + (s / 31_556_952.0).floor() as i32))
}

/// The unit a time column's name gives (`time_ms`, `Time [s]`), if it gives one.
pub(crate) fn time_unit_of(name: &str) -> Option<TimeUnit> {
    parse_time_name(name).and_then(|(_, u)| u)
}

/// The words a time column is named by, bare or with a unit suffix: English (`timestamp`,
/// `time`, `t`), German (`Zeit`: LabVIEW and TwinCAT exports in German), French (`temps`),
/// Spanish (`tiempo`), Italian and Portuguese (`tempo`), Polish (`czas`), Japanese (`時間`) and
/// Chinese (`时间`); any case.
pub const TIME_NAMES: [&str; 10] = [
    "timestamp",
    "time",
    "t",
    "zeit",
    "temps",
    "tiempo",
    "tempo",
    "czas",
    "時間",
    "时间",
];

/// A time column's name split into its base (one of [`TIME_NAMES`]) and unit suffix
/// (` [s]`, `(ms)`, `_us`, …), if it is one.
fn parse_time_name(name: &str) -> Option<(&'static str, Option<TimeUnit>)> {
    // PlotJuggler's `__time`.
    let name = name.trim().trim_start_matches('_');
    let lower = name.to_ascii_lowercase();
    for base in TIME_NAMES {
        let Some(rest) = lower.strip_prefix(base) else {
            continue;
        };
        if rest.is_empty() {
            return Some((base, None));
        }
        let rest = rest.trim_start();
        let suffix = rest
            .strip_prefix('[')
            .and_then(|r| r.strip_suffix(']'))
            .or_else(|| rest.strip_prefix('(').and_then(|r| r.strip_suffix(')')))
            .or_else(|| rest.strip_prefix('_'))
            .or_else(|| rest.strip_prefix('/'));
        if let Some(unit) = suffix.and_then(|s| TimeUnit::from_suffix(s.trim())) {
            return Some((base, Some(unit)));
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn separators_and_metadata_lines_are_found() {
        assert_eq!(sniff(b"t,a,b\n0,1,2\n"), Dialect::default());
        let twincat = b"Name;Scope Project\nDate;2026-11-30\n\nTime [s];enc_a;enc_b\n0.000;1.5;2.5\n0.001;1.6;2.6\n";
        // The blank line is not a record: the header is the third record.
        assert_eq!(
            sniff(twincat),
            Dialect {
                separator: b';',
                skip: 2,
                ..Dialect::default()
            }
        );
        let tabs = b"# DAQ export\ntime\ta\tb\tc\n0\t1\t2\t3\n";
        assert_eq!(
            sniff(tabs),
            Dialect {
                separator: b'\t',
                skip: 1,
                ..Dialect::default()
            }
        );
        // No data row: the plain dialect, whose reader reports what is missing.
        assert_eq!(sniff(b"t;a;b\n"), Dialect::default());
    }

    #[test]
    fn lab_dialects_are_found() {
        let d = sniff(b"Time [s];a;b\r\n0,001;1,5;-2,25\r\n0,002;1,6;2\r\n");
        assert_eq!((d.separator, d.decimal_comma), (b';', true));
        let d = sniff(b"t\ta\n0\t1,5\n");
        assert_eq!((d.separator, d.decimal_comma), (b'\t', true));
        // Integers only: nothing says the mark is a comma.
        assert!(!sniff(b"t;a\n0;1\n").decimal_comma);
        let d = sniff(b"  t   a  b\n 0.0  1.5 2\n");
        assert_eq!((d.separator, d.skip), (WHITESPACE, 0));
        assert_eq!(d.header, Header::Row { units: None });
        // numpy.savetxt / MATLAB: no header at all.
        let d = sniff(b"100.5 -65.9 336.5\n97.2 -65.9 336.5\n");
        assert_eq!(d.separator, WHITESPACE);
        assert_eq!(d.header, Header::None { columns: 3 });
        assert_eq!(sniff(b"79.9\n83.4\n").header, Header::None { columns: 1 });
        // A units row between the header and the data.
        let d = sniff(b"t,a,b\nms,deg,[deg]\n0,1,2\n");
        assert_eq!(d.skip, 0);
        assert_eq!(
            d.header,
            Header::Row {
                units: Some(vec!["ms".into(), "deg".into(), "[deg]".into()])
            }
        );
        // Metadata of the header's width is not taken for units.
        let d = sniff(b"Instrument;Foo;Bar\nTime [s];a;b\n0;1;2\n");
        assert_eq!((d.skip, d.header), (1, Header::Row { units: None }));
        // CR-only line ends.
        assert_eq!(sniff(b"t,a\r0,1\r1,2\r"), Dialect::default());
        // PlotJuggler: a channel's cell empty where it has no sample.
        let d = sniff(b"__time,/a,/b,/c\n0.0,1.5,,\n0.005,,2.5,\n0.01,1.6,,3\n");
        assert!(d.sparse && d.header == Header::Row { units: None });
        assert!(!sniff(b"t,a\n0,1\n").sparse);
    }

    #[test]
    fn twincat_property_block_is_read() {
        let head = b"Name;Scope;\r\nStarttime of export;132900081483250000;Tuesday;13:55\r\n\r\n\
            Name;fActPosition (Internal Counter);fActVelocity;fActPosition (Resolver)\r\n\
            Data-Type;REAL64;REAL64;REAL64\r\nSampleTime;10;10;10\r\nIndexGroup;61462;61462;16448\r\n\
            Unit;(None);deg/s;deg\r\n\r\n\
            132900081483250000;0;0;-0.071\r\n132900081483350000;0;0;-0.072\r\n";
        let d = sniff(head);
        assert_eq!((d.separator, d.skip), (b';', 7));
        let Header::Properties(p) = d.header else {
            panic!("{d:?}")
        };
        assert_eq!(
            p.names,
            [
                "fActPosition (Internal Counter)",
                "fActVelocity",
                "fActPosition (Resolver)"
            ]
        );
        assert_eq!(p.units, ["(None)", "deg/s", "deg"]);
        assert_eq!(p.sample_time_s, Some(0.01));
        assert!(p.filetime);
        // Without the time column: as many fields as channels.
        let head = b"Name;a;b\nSampleTime;2;2\n\n0,5;1\n0,6;1,1\n";
        let Header::Properties(p) = sniff(head).header else {
            panic!()
        };
        assert!(!p.filetime);
        assert_eq!(p.sample_time_s, Some(0.002));
    }

    /// The property block and preamble of an export, with `names` on its channel `Name` row and
    /// the title line first if `title`.
    fn twincat_head(title: bool, names: &str, columns: usize) -> String {
        let row = |key: &str, v: &str| format!("{key}{}\r\n", format!(";{v}").repeat(columns));
        let mut o = String::new();
        if title {
            o.push_str("Name;Scope Project;\r\nFile;C:\\scope.csv;\r\n");
            o.push_str("Starttime of export;132900081483250000;Tuesday;13:55\r\n\r\n");
        }
        o.push_str(&format!("Name;{names}\r\n"));
        o.push_str(&row("Data-Type", "REAL64"));
        o.push_str(&row("SampleTime", "10"));
        o.push_str(&row("SymbolName", "MAIN.x"));
        o.push_str(&row("Unit", "(None)"));
        o.push_str("\r\n");
        o
    }

    /// A single channel without a time column: every row holds one number, and the data start
    /// right after the property block, however long the file (not 64 rows into the block,
    /// which took the first data rows for properties), with or without the title line.
    #[test]
    fn twincat_single_channel_rows_are_data() {
        for title in [false, true] {
            let mut text = twincat_head(title, "fActPosition", 1);
            for k in 0..300 {
                text.push_str(&format!("{}\r\n", k as f64 * 0.5));
            }
            let d = sniff(text.as_bytes());
            let Header::Properties(p) = &d.header else {
                panic!("{d:?}")
            };
            assert_eq!(p.names, ["fActPosition"]);
            assert!(!p.filetime);
            // Records before the data: the block's 5 (and the title's 3).
            assert_eq!(d.skip, 5 + 3 * usize::from(title), "title {title}");
        }
    }

    /// The export's title line (`Name;<title>;`) is not the channels' `Name` row: a 2-channel
    /// export without time keeps its channel names and has no FILETIME column.
    #[test]
    fn twincat_title_line_is_not_the_channels_name_row() {
        let mut text = twincat_head(true, "ref;dut", 2);
        text.push_str("0,5;0,6\r\n1;1,1\r\n");
        let Header::Properties(p) = sniff(text.as_bytes()).header else {
            panic!()
        };
        assert_eq!(p.names, ["ref", "dut"]);
        assert!(!p.filetime);
        assert_eq!(p.name_record, 3);
    }

    /// Data rows of neither width (a time column per channel) are a TwinCAT layout calib does
    /// not read, said as such, not a header row `Data-Type;REAL64;REAL64`.
    #[test]
    fn twincat_rows_of_another_width_are_an_unknown_layout() {
        let mut text = twincat_head(true, "a;b", 2);
        text.push_str("0;1;0;2\r\n0,01;1;0,01;2\r\n");
        assert_eq!(
            sniff(text.as_bytes()).header,
            Header::UnknownProperties {
                channels: 2,
                fields: 4,
                name_record: 3
            }
        );
    }

    #[test]
    fn time_columns_by_name_and_unit() {
        let names = |n: &[&str]| n.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let h = names(&["a", "Time [s]", "b"]);
        assert_eq!(time_column(&h, None, None), Some((1, TimeUnit::S)));
        assert_eq!(
            time_column(&names(&["timestamp_ms", "a"]), None, None),
            Some((0, TimeUnit::Ms))
        );
        assert_eq!(
            time_column(&names(&["a", "time (us)"]), None, None),
            Some((1, TimeUnit::Us))
        );
        assert_eq!(
            time_column(&names(&["t", "time_ns"]), None, None),
            Some((0, TimeUnit::S))
        );
        assert_eq!(
            time_column(&names(&["stamp", "a"]), Some("stamp"), Some(TimeUnit::Ns)),
            Some((0, TimeUnit::Ns))
        );
        assert_eq!(time_column(&names(&["tilt", "temp"]), None, None), None);
        assert_eq!(
            time_column(&names(&["__time", "/a"]), None, None),
            Some((0, TimeUnit::S))
        );
        assert_eq!(time_column(&names(&["a"]), Some("t"), None), None);
        // Other languages.
        for (name, unit) in [
            ("Zeit [s]", TimeUnit::S),
            ("temps (ms)", TimeUnit::Ms),
            ("Tiempo", TimeUnit::S),
            ("tempo_us", TimeUnit::Us),
            ("czas [ns]", TimeUnit::Ns),
            ("時間", TimeUnit::S),
            ("时间 [ms]", TimeUnit::Ms),
        ] {
            assert_eq!(
                time_column(&names(&["a", name]), None, None),
                Some((1, unit)),
                "{name}"
            );
        }
        assert_eq!(time_column(&names(&["temperature", "a"]), None, None), None);
        assert_eq!(
            looks_like_time(&names(&["a", "Timestamp (UTC)"])),
            Some("Timestamp (UTC)")
        );
        assert_eq!(looks_like_time(&names(&["a", "temperature"])), None);
    }

    #[test]
    fn stamps_since_1970_say_their_unit() {
        assert_eq!(epoch_unit(1.764e9), Some((TimeUnit::S, 2025)));
        assert_eq!(epoch_unit(1.764e12), Some((TimeUnit::Ms, 2025)));
        assert_eq!(epoch_unit(1.764e15), Some((TimeUnit::Us, 2025)));
        assert_eq!(epoch_unit(1.764e18), Some((TimeUnit::Ns, 2025)));
        // 1990 and 2099 in ns; 1989 and 2100 in none.
        assert_eq!(epoch_unit(6.32e17).map(|(u, _)| u), Some(TimeUnit::Ns));
        assert_eq!(epoch_unit(4.1e18).map(|(u, _)| u), Some(TimeUnit::Ns));
        assert_eq!(epoch_unit(6.3e17), None);
        assert_eq!(epoch_unit(4.2e18), None);
        // Times from a run's start, and a FILETIME (100 ns ticks since 1601: 1974 in ns).
        assert_eq!(epoch_unit(12.5), None);
        assert_eq!(epoch_unit(1.329e17), None);
    }
}
