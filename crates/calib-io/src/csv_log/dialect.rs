//! CSV dialects as lab software writes them: the separator, lines before the header, and the
//! name and unit of the time column.
//!
//! TwinCAT Scope, LabVIEW, oscilloscopes and DAQ tools write `;` or tab separators, a few lines
//! of metadata (instrument, date, sample rate) before the header, and a time column called
//! `Time [s]`, `time`, `timestamp_ms`, …. This module finds, from the first [`SNIFF_BYTES`] of the
//! file:
//! - the **separator**: `,`, `;` or tab, whichever gives a header with the most columns;
//! - the **header**: the first line whose fields (at least two) are all non-numeric and that is
//!   followed by a line of as many fields, most of them numeric (a bad field in the first row is
//!   then reported at its line and column, not as a missing header). The lines before it are
//!   skipped;
//! - the **time column** ([`time_column`]): the one `--time-column` names, else one whose name
//!   is `t`, `time` or `timestamp` (any case), bare or with a unit suffix ` [s]`, `[ms]`, ` (us)`,
//!   `_ns`, …; its unit from the suffix, or `--time-unit`, else seconds.
//!
//! A file in which no header can be found this way (a header with no data rows, say) is read as
//! the plain dialect — `,` and the header on line 1 — so that its errors stay the usual ones.

use super::fields::parse_f64;
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

/// How a CSV file is laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dialect {
    /// The field separator.
    pub separator: u8,
    /// Records (lines) before the header, skipped.
    pub skip: usize,
}

impl Default for Dialect {
    fn default() -> Self {
        Dialect {
            separator: b',',
            skip: 0,
        }
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
}

impl TimeUnit {
    /// Seconds per unit.
    pub fn seconds(self) -> f64 {
        match self {
            TimeUnit::S => 1.0,
            TimeUnit::Ms => 1e-3,
            TimeUnit::Us => 1e-6,
            TimeUnit::Ns => 1e-9,
        }
    }

    /// The unit a suffix names: `s`, `ms`, `us`, `µs`, `ns` (any case).
    pub fn from_suffix(s: &str) -> Option<Self> {
        match s.to_ascii_lowercase().as_str() {
            "s" | "sec" => Some(TimeUnit::S),
            "ms" => Some(TimeUnit::Ms),
            "us" | "µs" | "μs" => Some(TimeUnit::Us),
            "ns" => Some(TimeUnit::Ns),
            _ => None,
        }
    }
}

impl std::str::FromStr for TimeUnit {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        TimeUnit::from_suffix(s)
            .ok_or_else(|| format!("unknown time unit `{s}`; use s, ms, us or ns"))
    }
}

/// Opens `path` and finds its dialect from its first [`SNIFF_BYTES`]; the file is handed back
/// rewound to its start.
pub fn open(path: &Path) -> io::Result<(File, Dialect)> {
    let mut file = File::open(path)?;
    let mut head = Vec::with_capacity(SNIFF_BYTES);
    (&mut file)
        .take(SNIFF_BYTES as u64)
        .read_to_end(&mut head)?;
    file.rewind()?;
    Ok((file, sniff(&head)))
}

/// The dialect of a file starting with `head` (see the [module docs](self)).
pub fn sniff(head: &[u8]) -> Dialect {
    let mut best: Option<(usize, Dialect)> = None;
    for separator in SEPARATORS {
        let records: Vec<csv::ByteRecord> = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .delimiter(separator)
            .from_reader(head)
            .byte_records()
            .take(SNIFF_RECORDS)
            .map_while(Result::ok)
            .collect();
        let numeric =
            |r: &csv::ByteRecord| 2 * r.iter().filter(|f| parse_f64(f).is_some()).count() > r.len();
        let header = records.windows(2).position(|w| {
            w[0].len() >= 2
                && w[0].len() == w[1].len()
                && w[0]
                    .iter()
                    .all(|f| !f.trim_ascii().is_empty() && parse_f64(f).is_none())
                && numeric(&w[1])
        });
        if let Some(skip) = header {
            let columns = records[skip].len();
            if best.is_none_or(|(c, _)| columns > c) {
                best = Some((columns, Dialect { separator, skip }));
            }
        }
    }
    best.map(|(_, d)| d).unwrap_or_default()
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

/// A time column's name split into its base (`t`, `time`, `timestamp`) and unit suffix
/// (` [s]`, `(ms)`, `_us`, …), if it is one.
fn parse_time_name(name: &str) -> Option<(&str, Option<TimeUnit>)> {
    let name = name.trim();
    let lower = name.to_ascii_lowercase();
    for base in ["timestamp", "time", "t"] {
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
                skip: 2
            }
        );
        let tabs = b"# DAQ export\ntime\ta\tb\tc\n0\t1\t2\t3\n";
        assert_eq!(
            sniff(tabs),
            Dialect {
                separator: b'\t',
                skip: 1
            }
        );
        // No data row: the plain dialect, whose reader reports what is missing.
        assert_eq!(sniff(b"t;a;b\n"), Dialect::default());
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
        assert_eq!(time_column(&names(&["a"]), Some("t"), None), None);
    }
}
