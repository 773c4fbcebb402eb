//! Streaming reader of CSV logs.

use super::dialect::{self, Dialect, Header, TimeUnit, WHITESPACE};
use super::fields::{self, Decimal, line_of, parse_f64, parse_f64_comma, parse_integer};
use super::time_step::{TimeStep, UnitFrom};
use crate::limits::LineLimit;
use crate::progress::ReadProgress;
use crate::{Error, ReadDiagnostics, ReadOptions};
use calib_core::reference_points::Approach;
use calib_core::{AngleUnit, Channel, Sample};
use csv::ByteRecord;
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::iter::FusedIterator;
use std::path::{Path, PathBuf};

/// Reads a CSV log as a stream of [`Sample`]s, one row at a time.
///
/// The header names the columns: the time (`t` in seconds, or as [`super::dialect`] finds it;
/// required), `session` (integer, optional; negative means "no session") and one column per
/// channel, in any order. The separator and any lines before the header are found by
/// [`dialect::sniff`]. Readings are converted from
/// [`ReadOptions::unit`] (degrees if `None`) to radians and otherwise passed through: wrapped and
/// accumulated readings alike, since unwrapping is the core's job.
///
/// [`CsvReader::open`] reads the header and the first row, so a file with no header, no `t`
/// column or no data rows is rejected before any sample is produced. The iterator then yields one
/// sample per row; the first bad row yields an error and ends the stream (what follows a bad row
/// cannot be trusted to be in order).
///
/// ```
/// use calib_io::{ReadOptions, csv_log::CsvReader};
/// let dir = tempfile::tempdir()?;
/// let path = dir.path().join("run.csv");
/// std::fs::write(&path, "t,a,b\n0.0,90,180\n0.1,90.5,180.5\n")?;
/// let reader = CsvReader::open(&path, &ReadOptions::default())?;
/// assert_eq!(reader.channels()[1].name, "b");
/// let samples = reader.collect::<Result<Vec<_>, _>>()?;
/// assert_eq!(samples.len(), 2);
/// assert!((samples[0].values[0] - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct CsvReader {
    path: PathBuf,
    reader: Records,
    /// Reused for every row: no allocation per row but the sample's own values.
    record: ByteRecord,
    /// `record` holds a row read ahead by `open` (the first data row) that is yet to be yielded.
    pending: bool,
    /// The stream has ended, at the end of the file or after an error.
    done: bool,
    names: Vec<String>,
    channels: Vec<Channel>,
    time: Time,
    /// Where the time column's stamps are counted from, if not from 0.
    origin: Option<Origin>,
    /// Data rows read so far.
    rows: u64,
    /// Numbers are written with a decimal comma.
    decimal_comma: bool,
    /// An empty reading is a channel without a sample in this row (NaN in the sample).
    sparse: bool,
    /// The file has no time column: a list of stationary points, in row order.
    point_list: bool,
    /// A point list's `direction` column ([`super::direction`]).
    direction_col: Option<usize>,
    /// The direction of approach each row of a point list states, in row order (empty without
    /// a `direction` column).
    directions: Vec<Option<Approach>>,
    dialect: Dialect,
    session_col: Option<usize>,
    /// Bytes of the file read so far, of its size.
    progress: ReadProgress,
    /// The column of each channel, in the order of `channels`.
    value_cols: Vec<usize>,
    rad_per_unit: f64,
    /// Pass stamps that repeat or go back through (for `inspect`, which reports them).
    allow_unordered_time: bool,
    /// The previous row's time stamp and position, for the monotonicity check and its message.
    prev: Option<(f64, csv::Position)>,
    /// The time column's steps between the first rows (`None` without a time column).
    time_step: Option<TimeStep>,
    diagnostics: ReadDiagnostics,
}

/// Where a row's time stamp comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Time {
    /// A column, in units of `scale` seconds.
    Column { col: usize, scale: f64 },
    /// The row index times `period` seconds (TwinCAT's `SampleTime`; 1 for a point list).
    Index { period: f64 },
}

/// Where a time column's stamps are counted from, in its unit, when not from 0.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Origin {
    /// Integer stamps too large for an `f64` to hold exactly (beyond 2⁵³: nanoseconds since 1970,
    /// FILETIME ticks): the first row's, from which every stamp is counted in integers; the log's
    /// time starts at 0.
    FirstRow(i128),
    /// Stamps beyond [`ORIGIN_FROM_S`](crate::stamps::ORIGIN_FROM_S) (seconds since 1970,
    /// ~1.7·10⁹ s, whose doubles are 2.4·10⁻⁷ s apart): the first row's whole number of units,
    /// from which every stamp's whole part is counted before its fraction is added, so each
    /// keeps its digits; reports add it back ([`CsvReader::time_origin_s`]).
    Whole(i128),
}

/// The records of the file, split as its dialect says.
#[derive(Debug)]
enum Records {
    Csv(csv::Reader<LineLimit<File>>),
    Whitespace(Words),
}

/// Records of fields separated by runs of spaces and tabs, one per non-blank line.
#[derive(Debug)]
struct Words {
    input: BufReader<LineLimit<File>>,
    line: Vec<u8>,
    /// Byte offset of the next line.
    offset: u64,
    records: u64,
}

impl Records {
    fn open(file: File, dialect: &Dialect) -> Self {
        if dialect.separator == WHITESPACE {
            Records::Whitespace(Words {
                input: BufReader::with_capacity(1 << 16, LineLimit::new(file)),
                line: Vec::new(),
                offset: 0,
                records: 0,
            })
        } else {
            Records::Csv(fields::csv_reader_with(file, dialect.separator))
        }
    }

    /// The byte offset of the next record.
    fn position(&self) -> u64 {
        match self {
            Records::Csv(r) => r.position().byte(),
            Records::Whitespace(w) => w.offset,
        }
    }

    /// Reads the next record into `record`; `false` at the end of the file.
    fn read(&mut self, path: &Path, record: &mut ByteRecord) -> Result<bool, Error> {
        match self {
            Records::Csv(r) => r
                .read_byte_record(record)
                .map_err(|e| fields::from_csv(path, e)),
            Records::Whitespace(w) => loop {
                w.line.clear();
                let start = w.offset;
                let n = w
                    .input
                    .read_until(b'\n', &mut w.line)
                    .map_err(|e| fields::from_io(path, e))?;
                if n == 0 {
                    return Ok(false);
                }
                w.offset += n as u64;
                record.clear();
                for word in w.line.split(u8::is_ascii_whitespace) {
                    if !word.is_empty() {
                        record.push_field(word);
                    }
                }
                if record.is_empty() {
                    continue;
                }
                w.records += 1;
                // The line's start: where errors count its line from.
                let mut pos = csv::Position::new();
                pos.set_byte(start).set_record(w.records);
                record.set_position(Some(pos));
                return Ok(true);
            },
        }
    }
}

impl CsvReader {
    /// Opens a CSV log, reads its header and checks that it has at least one data row.
    ///
    /// Errors name the file and line: a missing or unreadable file, an empty file, a header
    /// without `t` or without any channel column, duplicate or empty column names, a header
    /// without data rows. The rows' contents are checked as the iterator reaches them.
    pub fn open(path: &Path, opts: &ReadOptions) -> Result<Self, Error> {
        let io = |source| Error::Io {
            path: path.to_path_buf(),
            source,
        };
        let (file, dialect) = dialect::open(path).map_err(io)?;
        let mut reader = Records::open(file, &dialect);
        let mut record = ByteRecord::new();
        let name_record = match &dialect.header {
            Header::Properties(p) => Some(p.name_record),
            Header::UnknownProperties { name_record, .. } => Some(*name_record),
            _ => None,
        };
        // The line of TwinCAT's `Name` row, for the messages that name it.
        let mut name_line = 1;
        for k in 0..dialect.skip {
            reader.read(path, &mut record)?;
            if Some(k) == name_record {
                name_line = line_of(path, &record);
            }
        }
        let err = |line, channel: Option<&str>, message: String| Error::Csv {
            path: path.to_path_buf(),
            line,
            channel: channel.map(str::to_string),
            message,
        };
        let check_columns = |columns: usize, line| {
            if columns > crate::limits::MAX_CSV_COLUMNS {
                return Err(err(
                    line,
                    None,
                    format!(
                        "the header has {columns} columns, more than the {} calib reads (a \
                         column per channel); keep the time and the encoders' columns",
                        crate::limits::MAX_CSV_COLUMNS
                    ),
                ));
            }
            Ok(())
        };
        let empty = || {
            err(
                1,
                None,
                "the file is empty; a CSV log needs a header row such as `t,a,b` and one row \
                 per sample"
                    .into(),
            )
        };
        // The column names, the units row's units, and the header's line (0 if it has none).
        let (names, units, header_line) = match &dialect.header {
            Header::Row { units } => {
                if !reader.read(path, &mut record)? {
                    return Err(empty());
                }
                check_columns(record.len(), line_of(path, &record))?;
                let names = fields::header_names(path, &record)?;
                let line = line_of(path, &record);
                if units.is_some() {
                    reader.read(path, &mut record)?;
                }
                (names, units.clone(), line)
            }
            Header::None { columns } => ((1..=*columns).map(|i| i.to_string()).collect(), None, 0),
            Header::UnknownProperties {
                channels, fields, ..
            } => {
                return Err(err(
                    name_line,
                    None,
                    format!(
                        "this is a TwinCAT Scope export whose `Name` row names {channels} \
                         channel{} but whose data rows hold {fields} fields; calib reads the \
                         rows as one field per channel, or a FILETIME time stamp then one field \
                         per channel. Export the channels again on one time base with a single \
                         time column (or none), or save them as a plain CSV `t,a,b`",
                        if *channels == 1 { "" } else { "s" }
                    ),
                ));
            }
            Header::Properties(p) => {
                twincat_names_are_unique(path, name_line, p)?;
                let mut names = p.names.clone();
                if p.filetime {
                    names.insert(0, "FILETIME".to_string());
                }
                let mut units = p.units.clone();
                if p.filetime {
                    units.insert(0, "100ns".to_string());
                }
                (names, Some(units), 0)
            }
        };
        check_columns(names.len(), header_line)?;
        let unit_of = |i: usize| units.as_ref().and_then(|u| u.get(i));
        let filetime = matches!(&dialect.header, Header::Properties(p) if p.filetime);
        let found = if filetime && opts.time_column.is_none() {
            Some(match opts.time_unit {
                Some(unit) => (0, unit, UnitFrom::Option),
                None => (0, TimeUnit::Ticks, UnitFrom::UnitsRow),
            })
        } else {
            dialect::time_column(&names, opts.time_column.as_deref(), None).map(|(i, _)| {
                // --time-unit, else the name's suffix, else the units row's entry, else seconds.
                let row_unit =
                    || unit_of(i).and_then(|u| TimeUnit::from_suffix(dialect::unbracket(u)));
                match (opts.time_unit, dialect::time_unit_of(&names[i]), row_unit()) {
                    (Some(unit), _, _) => (i, unit, UnitFrom::Option),
                    (None, Some(unit), _) => (i, unit, UnitFrom::Name),
                    (None, None, Some(unit)) => (i, unit, UnitFrom::UnitsRow),
                    (None, None, None) => (i, TimeUnit::S, UnitFrom::Default),
                }
            })
        };
        let time_step = found.map(|(col, unit, from)| TimeStep::new(&names[col], unit, from));
        let mut point_list = false;
        let time = match (found, &dialect.header) {
            (Some((col, unit, _)), _) => Time::Column {
                col,
                scale: unit.seconds(),
            },
            (None, Header::Properties(p)) if opts.time_column.is_none() => Time::Index {
                period: p.sample_time_s.ok_or_else(|| {
                    err(
                        1,
                        None,
                        "this TwinCAT Scope export has neither a time column nor a SampleTime \
                         row; export it with its time stamps"
                            .into(),
                    )
                })?,
            },
            (None, _) if opts.allow_point_list && opts.time_column.is_none() => {
                point_list = true;
                Time::Index { period: 1.0 }
            }
            (None, _) => {
                return Err(err(
                    header_line.max(1),
                    None,
                    match &opts.time_column {
                        Some(wanted) => format!(
                            "the header has no column `{wanted}` (it has: {}); give the `time_column` \
                             option one of those names",
                            names.join(", ")
                        ),
                        None => format!(
                            "the {} has no time column (it has: {}); name it `t` (seconds), \
                             `time` or `timestamp` (with a unit such as ` [ms]`), or name it with \
                             the `time_column` option. A file without time is a list of stationary points, \
                             which `calib reference` and `calib inspect` read",
                            if header_line == 0 { "file" } else { "header" },
                            names.join(", ")
                        ),
                    },
                ));
            }
        };
        let t_col = match time {
            Time::Column { col, .. } => Some(col),
            Time::Index { .. } => None,
        };
        // The readings' unit: --unit, else the one every channel's unit-row entry names.
        let row_unit = {
            let channel_units: Vec<Option<calib_core::AngleUnit>> = (0..names.len())
                .filter(|&i| Some(i) != t_col && names[i] != "session")
                .map(|i| unit_of(i).and_then(|u| dialect::angle_unit(u)))
                .collect();
            match channel_units.first() {
                Some(Some(first)) if channel_units.iter().all(|u| u.as_ref() == Some(first)) => {
                    Some(*first)
                }
                _ => None,
            }
        };
        let unit = opts.unit.or(row_unit).unwrap_or(AngleUnit::Deg);
        let mut session_col = None;
        let direction_col = names
            .iter()
            .position(|n| point_list && super::direction::is_direction_column(n));
        let mut channels = Vec::new();
        let mut value_cols = Vec::new();
        for (i, name) in names.iter().enumerate() {
            if Some(i) == t_col || Some(i) == direction_col {
                continue;
            }
            if name == "session" {
                session_col = Some(i);
            } else {
                channels.push(Channel {
                    name: name.clone(),
                    unit,
                });
                value_cols.push(i);
            }
        }
        if channels.is_empty() {
            return Err(err(
                header_line.max(1),
                None,
                format!(
                    "the header has no channel columns (it has: {}); add one column of readings \
                     per sensor, named by the sensor",
                    names.join(", ")
                ),
            ));
        }
        let read = reader.read(path, &mut record)?;
        // TwinCAT Scope ends its exports with a line `EOF`.
        let end_marker = matches!(dialect.header, Header::Properties(_))
            && record.len() == 1
            && record[0].trim_ascii() == b"EOF";
        if !read || end_marker {
            return Err(match header_line {
                0 => empty(),
                line => err(
                    line + 1,
                    None,
                    "the log has a header but no data rows; it needs one row per sample".into(),
                ),
            });
        }
        let size = std::fs::metadata(path).map_or(0, |m| m.len());
        Ok(CsvReader {
            progress: ReadProgress::new(size),
            path: path.to_path_buf(),
            reader,
            record,
            pending: true,
            done: false,
            names,
            channels,
            time,
            origin: None,
            rows: 0,
            decimal_comma: dialect.decimal_comma,
            sparse: dialect.sparse,
            point_list,
            direction_col,
            directions: Vec::new(),
            dialect,
            session_col,
            value_cols,
            rad_per_unit: unit.radians_per_unit(),
            allow_unordered_time: opts.allow_unordered_time,
            prev: None,
            time_step,
            diagnostics: ReadDiagnostics::default(),
        })
    }

    /// Whether the file has no time column: a list of stationary points in row order (read only
    /// with [`ReadOptions::allow_point_list`]), whose samples are timed by their row index
    /// (0, 1, 2, … s).
    pub fn is_point_list(&self) -> bool {
        self.point_list
    }

    /// The direction of approach each row of a point list states (`None` where its cell is
    /// empty), in row order, read so far; `None` for a file without a `direction` column
    /// ([`super::direction`]).
    pub fn directions(&self) -> Option<&[Option<Approach>]> {
        self.direction_col.map(|_| self.directions.as_slice())
    }

    /// Whether rows leave a channel's cell empty where it has no sample: its samples then hold
    /// NaN there, and each channel is a series of its own to be aligned ([`crate::align`]).
    pub fn is_sparse(&self) -> bool {
        self.sparse
    }

    /// How the file is laid out.
    pub fn dialect(&self) -> &Dialect {
        &self.dialect
    }

    /// Whether the log has a `session` column marking CSRR sessions.
    pub fn has_session_column(&self) -> bool {
        self.session_col.is_some()
    }

    /// The log's channels, in column order (without `t` and `session`).
    pub fn channels(&self) -> &[Channel] {
        &self.channels
    }

    /// The time column and the steps between its first rows' stamps, read so far (`None` for a
    /// file without a time column).
    pub fn time_step(&self) -> Option<&TimeStep> {
        self.time_step.as_ref()
    }

    /// How far the reader has got through the file: a handle to read from another thread.
    pub fn progress(&self) -> ReadProgress {
        self.progress.clone()
    }

    /// What the reader noticed; a CSV log has nothing to report beyond its errors, so this is
    /// always the default.
    pub fn diagnostics(&self) -> &ReadDiagnostics {
        &self.diagnostics
    }

    fn error(&self, column: Option<usize>, message: String) -> Error {
        Error::Csv {
            path: self.path.clone(),
            line: line_of(&self.path, &self.record),
            channel: column.map(|c| self.names[c].clone()),
            message,
        }
    }

    /// Whether the record read is TwinCAT Scope's `EOF` line, which ends its exports.
    fn is_end_marker(&self) -> bool {
        matches!(self.dialect.header, Header::Properties(_))
            && self.record.len() == 1
            && self.record[0].trim_ascii() == b"EOF"
    }

    /// A field's number, in the file's decimal mark.
    #[inline]
    fn number(&self, field: &[u8]) -> Option<f64> {
        if self.decimal_comma {
            parse_f64_comma(field)
        } else {
            parse_f64(field)
        }
    }

    /// The stamp, seconds on the file's clock, from which its rows' times are counted: the first
    /// row's whole units where its stamps are beyond 2²¹ s (24 days), else 0 (integer stamps
    /// beyond 2⁵³ start at 0: they are counted from the first row's).
    pub fn time_origin_s(&self) -> f64 {
        match (self.origin, self.time) {
            (Some(Origin::Whole(whole)), Time::Column { scale, .. }) => whole as f64 * scale,
            _ => 0.0,
        }
    }

    /// The origin the first row's time `raw`, in units of `scale` seconds, chooses for every
    /// row, and that time counted from it.
    fn first_time(&self, raw: &[u8], scale: f64) -> (Option<Origin>, Option<f64>) {
        // Beyond 2^53 an `f64` cannot hold every integer: count from the first. (Not seconds:
        // that many seconds are a unit mistake, refused below.)
        if let Some(v) = parse_integer(raw).filter(|v| v.unsigned_abs() > 1 << 53 && scale < 1.0) {
            return (Some(Origin::FirstRow(v)), Some(0.0));
        }
        let Some(t) = self.number(raw) else {
            return (None, None);
        };
        let s = t * scale;
        if s.abs() < crate::stamps::ORIGIN_FROM_S as f64 || crate::limits::time_problem(s).is_some()
        {
            return (None, Some(t));
        }
        match Decimal::parse(raw, self.decimal_comma) {
            Some(d) => (Some(Origin::Whole(d.whole())), d.since(d.whole())),
            None => (None, Some(t)),
        }
    }

    /// The time `raw` counted from `origin` whole units, its digits kept ([`Decimal::since`]; a
    /// number with an exponent, which has no digits to keep, as a double).
    fn since(&self, origin: i128, raw: &[u8]) -> Option<f64> {
        match Decimal::parse(raw, self.decimal_comma) {
            Some(d) => d.since(origin),
            None => self.number(raw).map(|t| t - origin as f64),
        }
    }

    /// The sample in `self.record`.
    fn parse_row(&mut self) -> Result<Sample, Error> {
        let record = &self.record;
        if record.len() != self.names.len() {
            return Err(fields::wrong_width(&self.path, record, &self.names));
        }
        let field = |c: usize| record.get(c).unwrap_or_default();

        let t = match self.time {
            Time::Index { period } => self.rows as f64 * period,
            Time::Column { col, scale } => {
                let raw_t = field(col);
                let number = match self.origin {
                    Some(Origin::FirstRow(origin)) => {
                        parse_integer(raw_t).map(|v| (v - origin) as f64)
                    }
                    Some(Origin::Whole(origin)) => self.since(origin, raw_t),
                    None if self.rows == 0 => {
                        let (origin, t) = self.first_time(raw_t, scale);
                        self.origin = origin;
                        t
                    }
                    None => self.number(raw_t),
                };
                let t = number.map(|t| t * scale).ok_or_else(|| {
                    let message = match self.origin {
                        Some(Origin::FirstRow(origin)) => format!(
                            "`{}` is not a whole number, but the first row's time stamp {origin} \
                             is; such stamps are counted from the first exactly, in integers: \
                             give every row's stamp as a whole number",
                            fields::show(raw_t)
                        ),
                        Some(Origin::Whole(_)) | None => fields::not_a_number(raw_t, "the time"),
                    };
                    self.error(Some(col), message)
                })?;
                if !t.is_finite() {
                    return Err(self.error(
                        Some(col),
                        format!(
                            "time `{}` is not a finite number; every row needs a real time stamp",
                            fields::show(raw_t)
                        ),
                    ));
                }
                t
            }
        };
        let t_col = match self.time {
            Time::Column { col, .. } => col,
            Time::Index { .. } => 0,
        };
        if let Some(problem) = crate::limits::time_problem(t) {
            return Err(self.error(Some(t_col), problem));
        }
        if let Some((prev_t, prev_pos)) = &self.prev {
            let prev_t = *prev_t;
            if t <= prev_t && !self.allow_unordered_time {
                let what = if t == prev_t {
                    "repeats"
                } else {
                    "goes back before"
                };
                let prev_line = fields::line_at(&self.path, prev_pos);
                // Stamps counted from an origin: the row's as written, the previous one's on the
                // file's clock (a double there may round their difference away).
                let origin = self.time_origin_s();
                let (t, prev_t) = if origin == 0.0 {
                    (t.to_string(), prev_t.to_string())
                } else {
                    (fields::show(field(t_col)), (prev_t + origin).to_string())
                };
                return Err(self.error(
                    Some(t_col),
                    format!(
                        "time stamp {t} s {what} the previous row's {prev_t} s (line {prev_line}); \
                         rows must be in strictly increasing time order: sort the log by `t` and \
                         remove duplicate rows"
                    ),
                ));
            }
        }

        let mut values = Vec::with_capacity(self.value_cols.len());
        for &c in &self.value_cols {
            let raw = field(c);
            if self.sparse && raw.trim_ascii().is_empty() {
                values.push(f64::NAN);
                continue;
            }
            let v = self
                .number(raw)
                .ok_or_else(|| self.error(Some(c), fields::not_a_number(raw, "a reading")))?;
            let rad = v * self.rad_per_unit;
            if let Some(problem) = crate::limits::reading_problem(fields::Shown(raw), v, rad) {
                return Err(self.error(Some(c), problem));
            }
            values.push(rad);
        }

        let direction = match self.direction_col {
            None => None,
            Some(c) => super::direction::parse(field(c)).map_err(|_| {
                self.error(
                    Some(c),
                    format!(
                        "`{}` is not a direction of approach; {}",
                        fields::show(field(c)),
                        super::direction::EXPECTED
                    ),
                )
            })?,
        };
        let session = match self.session_col {
            None => None,
            Some(c) => {
                let raw = field(c);
                let s: i64 = std::str::from_utf8(raw.trim_ascii())
                    .ok()
                    .and_then(|s| s.parse().ok())
                    .ok_or_else(|| {
                        self.error(
                            Some(c),
                            format!(
                                "session `{}` is not an integer; mark each row with its session \
                                 number (0, 1, …) or a negative number for rows outside any \
                                 session",
                                fields::show(raw)
                            ),
                        )
                    })?;
                if s < 0 {
                    None
                } else {
                    Some(u32::try_from(s).map_err(|_| {
                        self.error(
                            Some(c),
                            format!(
                                "session {s} is too large (at most {}); number sessions from 0",
                                u32::MAX
                            ),
                        )
                    })?)
                }
            }
        };
        self.rows += 1;
        if self.direction_col.is_some() {
            self.directions.push(direction);
        }
        if let Some(steps) = &mut self.time_step {
            steps.push(t, &values);
        }
        // The header and the rows always have positions; the default only satisfies the type.
        self.prev = Some((
            t,
            record
                .position()
                .cloned()
                .unwrap_or_else(csv::Position::new),
        ));
        Ok(Sample { t, values, session })
    }
}

impl Iterator for CsvReader {
    type Item = Result<Sample, Error>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        if self.pending {
            self.pending = false;
        } else {
            match self.reader.read(&self.path, &mut self.record) {
                Ok(true) if self.is_end_marker() => {
                    self.done = true;
                    return None;
                }
                Ok(true) => self.progress.set(self.reader.position()),
                Ok(false) => {
                    self.done = true;
                    return None;
                }
                Err(e) => {
                    self.done = true;
                    return Some(Err(e));
                }
            }
        }
        let sample = self.parse_row();
        self.done = sample.is_err();
        Some(sample)
    }
}

impl FusedIterator for CsvReader {}

/// Refuses a TwinCAT Scope export naming two channels alike (two axes' `fActPosition`, say), as
/// a header row with two columns of one name is refused ([`fields::header_names`]): a channel
/// option could not say which it means. The message names both columns, their `SymbolName`s
/// (the PLC variables, which tell them apart) and the `Name` row's line.
fn twincat_names_are_unique(path: &Path, line: u64, p: &dialect::Properties) -> Result<(), Error> {
    // Columns count the FILETIME column where the rows have one.
    let column = |i: usize| i + 1 + usize::from(p.filetime);
    for (j, name) in p.names.iter().enumerate() {
        let Some(i) = p.names[..j].iter().position(|n| n == name) else {
            continue;
        };
        let symbols = match (p.symbols.get(i), p.symbols.get(j)) {
            (Some(a), Some(b)) if !a.is_empty() && !b.is_empty() && a != b => {
                format!(" (SymbolName `{a}` and `{b}`)")
            }
            _ => String::new(),
        };
        return Err(Error::Csv {
            path: path.to_path_buf(),
            line,
            channel: Some(name.clone()),
            message: format!(
                "TwinCAT channels {} and {} (columns {} and {}) are both named `{name}`{symbols}; \
                 calib would not know which one a channel option means. Give each channel its \
                 own name in TwinCAT Scope (the channel's Name property, e.g. after its \
                 SymbolName) and export again, or edit the `Name` row on line {line} so every \
                 name is unique",
                i + 1,
                j + 1,
                column(i),
                column(j),
            ),
        });
    }
    Ok(())
}
