//! Streaming reader of CSV logs.

use super::dialect::{self, Dialect, Header, TimeUnit, WHITESPACE};
use super::fields::{self, Decimal, line_of, parse_f64, parse_f64_comma, parse_integer};
use super::time_step::{TimeStep, UnitFrom};
use crate::limits::LineLimit;
use crate::progress::ReadProgress;
use crate::source::{ByteSource, FileSource, SourceCursor};
use crate::stamps::{Backward, StampOrder, Step};
use crate::{Error, ReadDiagnostics, ReadOptions};
use calib_core::reference_points::Approach;
use calib_core::{AngleUnit, Channel, Sample};
use csv::ByteRecord;
use std::io::{BufRead, BufReader, Read, Seek};
use std::iter::FusedIterator;
use std::path::{Path, PathBuf};
use std::sync::Arc;

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
    /// Pass stamps that repeat with other readings or go back through (for `inspect`, which
    /// reports them); exact duplicates are dropped all the same.
    allow_unordered_time: bool,
    /// The rows' stamps so far, keyed by each row's byte offset ([`crate::stamps`]): a row that
    /// repeats the previous one exactly is dropped, one that conflicts with it or goes back is
    /// refused.
    order: StampOrder<f64>,
    /// A sparse file's: each channel's stamps, where two channels may share a stamp on rows of
    /// their own.
    channel_orders: Vec<StampOrder<f64>>,
    /// Whether each channel is read (all until [`CsvReader::set_needed`]): a cell of a channel
    /// not read is not parsed, so an empty or unused column does not refuse the file.
    needed: Vec<bool>,
    /// The line from which the file was found sparse while reading (rows with empty cells after
    /// the part [`dialect::sniff`] saw), if it was.
    sparse_from_line: Option<u64>,
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
    Csv(csv::Reader<LineLimit<SourceCursor>>),
    Whitespace(Words),
}

/// Records of fields separated by runs of spaces and tabs, one per non-blank line.
#[derive(Debug)]
struct Words {
    input: BufReader<LineLimit<SourceCursor>>,
    line: Vec<u8>,
    /// Byte offset of the next line.
    offset: u64,
    records: u64,
}

impl Records {
    fn open(file: SourceCursor, dialect: &Dialect) -> Self {
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
        let source: Arc<dyn ByteSource> = Arc::new(FileSource::new(file).map_err(io)?);
        Self::open_with(path, SourceCursor::new(source), dialect, opts)
    }

    /// [`open`](Self::open) for a log whose bytes `source` holds (a URL's, streamed front to
    /// back), named `name` in messages.
    pub fn open_source(
        name: &Path,
        source: Arc<dyn ByteSource>,
        opts: &ReadOptions,
    ) -> Result<Self, Error> {
        let mut cursor = SourceCursor::new(source);
        let mut head = Vec::with_capacity(dialect::SNIFF_BYTES);
        (&mut cursor)
            .take(dialect::SNIFF_BYTES as u64)
            .read_to_end(&mut head)
            .map_err(|source| Error::Io {
                path: name.to_path_buf(),
                source,
            })?;
        cursor.rewind().map_err(|source| Error::Io {
            path: name.to_path_buf(),
            source,
        })?;
        Self::open_with(name, cursor, dialect::sniff(&head), opts)
    }

    fn open_with(
        path: &Path,
        file: SourceCursor,
        dialect: Dialect,
        opts: &ReadOptions,
    ) -> Result<Self, Error> {
        let size = file.source().len();
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
                    match (&opts.time_column, dialect::looks_like_time(&names)) {
                        (Some(wanted), _) => format!(
                            "the header has no column `{wanted}` (it has: {}); give the `time_column` \
                             option one of those names",
                            names.join(", ")
                        ),
                        (None, Some(like)) => format!(
                            "the {} has no column calib takes for time by itself (it has: {}); \
                             column `{like}` looks like one: read it with `time_column = {}` (and \
                             its unit with `time_unit = ms`, `us` or `ns` if it is not in \
                             seconds), or name it `t`, `time` or `timestamp` (with a unit such as \
                             ` [ms]`)",
                            if header_line == 0 { "file" } else { "header" },
                            names.join(", "),
                            quoted(like)
                        ),
                        (None, None) => format!(
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
        // A column whose unit nothing gave: stamps since 1970 in ms, µs or ns by their magnitude.
        let mut diagnostics = ReadDiagnostics::default();
        let mut time = time;
        let mut found = found;
        if let Some((col, _, UnitFrom::Default)) = found
            && let Some(first) = record.get(col).and_then(|f| {
                if dialect.decimal_comma {
                    parse_f64_comma(f)
                } else {
                    parse_f64(f)
                }
            })
            && let Some((unit, year)) = dialect::epoch_unit(first)
            && unit != TimeUnit::S
        {
            found = Some((col, unit, UnitFrom::Magnitude));
            time = Time::Column {
                col,
                scale: unit.seconds(),
            };
            diagnostics.time_unit = Some(calib_core::report::TimeUnitChoice {
                column: names[col].clone(),
                unit: unit.suffix().to_string(),
                reason: format!(
                    "the column names no unit and its first stamp, {}, is a date in {year} \
                     counted in {} since 1970 (in seconds it would be beyond the year 2100); \
                     say `time_unit = s` to read it in seconds",
                    fields::show(&record[col]),
                    unit.name()
                ),
            });
        }
        let time_step = found.map(|(col, unit, from)| TimeStep::new(&names[col], unit, from));
        let needed = vec![true; value_cols.len()];
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
            order: StampOrder::default(),
            channel_orders: Vec::new(),
            needed,
            sparse_from_line: None,
            time_step,
            diagnostics,
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
    /// NaN there, and each channel is a series of its own to be aligned ([`crate::align`]). A
    /// file whose first rows ([`dialect::SNIFF_BYTES`]) are all full becomes sparse at its
    /// first row that leaves a read channel's cell empty and fills another's
    /// ([`sparse_from_line`](Self::sparse_from_line)).
    pub fn is_sparse(&self) -> bool {
        self.sparse
    }

    /// The line from which the file was found sparse while reading, if it was found so only
    /// then (its start was full rows).
    pub fn sparse_from_line(&self) -> Option<u64> {
        self.sparse_from_line
    }

    /// Reads only the channels `channels` (indices into [`channels`](Self::channels)): the cells
    /// of the others are not parsed (their samples hold NaN there), so that a column the command
    /// does not use — an empty one, a comment — does not refuse the file.
    pub fn set_needed(&mut self, channels: &[usize]) {
        self.needed.iter_mut().for_each(|n| *n = false);
        for &c in channels {
            if let Some(n) = self.needed.get_mut(c) {
                *n = true;
            }
        }
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

    /// What the reader noticed so far: rows dropped as exact copies of the one before, the unit
    /// the time column was read in by its stamps' magnitude.
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

    /// The sample in `self.record`; `None` for a row dropped as a copy of the previous one.
    fn parse_row(&mut self) -> Result<Option<Sample>, Error> {
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
            return Err(self.error(Some(t_col), self.with_unit_hint(problem, t_col)));
        }

        let mut values = Vec::with_capacity(self.value_cols.len());
        for (k, &c) in self.value_cols.iter().enumerate() {
            let raw = field(c);
            if !self.needed[k] || (self.sparse && raw.trim_ascii().is_empty()) {
                values.push(f64::NAN);
                continue;
            }
            if raw.trim_ascii().is_empty() && self.turns_sparse(record) {
                self.sparse = true;
                self.sparse_from_line = Some(line_of(&self.path, record));
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
        if matches!(self.time, Time::Column { .. }) && !self.keep_stamp(t, t_col, &mut values)? {
            return Ok(None);
        }
        self.rows += 1;
        if self.direction_col.is_some() {
            self.directions.push(direction);
        }
        if let Some(steps) = &mut self.time_step {
            steps.push(t, &values);
        }
        Ok(Some(Sample { t, values, session }))
    }

    /// Whether the row in `self.record`, which leaves a read channel's cell empty, makes a file
    /// sparse that its first rows showed full ([`dialect::sniff`]'s rule: a time and at least
    /// two channels, and the row fills some read channel's cell).
    fn turns_sparse(&self, record: &ByteRecord) -> bool {
        !self.sparse
            && !self.point_list
            && self.value_cols.len() >= 2
            && self
                .value_cols
                .iter()
                .zip(&self.needed)
                .any(|(&c, &needed)| needed && !record[c].trim_ascii().is_empty())
    }

    /// Whether the row at `t` with `values` is kept ([`crate::stamps`]): a row that repeats the
    /// previous one exactly (stamp and readings) is dropped and counted; one that repeats its
    /// stamp with other readings, or goes back, is refused (passed on for `inspect`). In a
    /// sparse file each channel's cells are checked on their own, where two channels may share
    /// a stamp on rows of their own: a cell repeating its channel's previous one is emptied,
    /// and a row left without any is dropped; rows may repeat a stamp but not go back.
    fn keep_stamp(&mut self, t: f64, t_col: usize, values: &mut [f64]) -> Result<bool, Error> {
        let key = self.record.position().map_or(0, |p| p.byte() as i64);
        let allow = self.allow_unordered_time;
        if !self.sparse {
            return match self.order.check(t, key, values) {
                Ok(Step::New) => Ok(true),
                Ok(Step::Duplicate) => {
                    self.diagnostics.duplicates_dropped += 1;
                    Ok(false)
                }
                Err(_) if allow => Ok(true),
                Err(b) => Err(self.stamp_error(&b, t_col, None)),
            };
        }
        // Rows of any channels: a stamp may repeat (two channels at one time), not go back.
        match self.order.check(t, key, &[]) {
            Err(b) if b.conflict.is_none() && !allow => {
                return Err(self.stamp_error(&b, t_col, None));
            }
            _ => {}
        }
        if self.channel_orders.len() < values.len() {
            self.channel_orders
                .resize_with(values.len(), StampOrder::default);
        }
        let (mut new, mut copies) = (false, false);
        for (c, v) in values.iter_mut().enumerate() {
            if v.is_nan() {
                continue;
            }
            match self.channel_orders[c].check(t, key, &[*v]) {
                Ok(Step::New) => new = true,
                Ok(Step::Duplicate) => {
                    *v = f64::NAN;
                    copies = true;
                }
                Err(_) if allow => new = true,
                Err(b) => return Err(self.stamp_error(&b, t_col, Some(c))),
            }
        }
        if copies && !new {
            self.diagnostics.duplicates_dropped += 1;
            return Ok(false);
        }
        Ok(true)
    }

    /// The error of a row whose stamp repeats with other readings or goes back, found by
    /// `self.order` (or, with `channel`, by that channel's order in a sparse file).
    fn stamp_error(&self, b: &Backward<f64>, t_col: usize, channel: Option<usize>) -> Error {
        let mut at = csv::Position::new();
        at.set_byte(u64::try_from(b.previous_message).unwrap_or(0));
        let prev_line = fields::line_at(&self.path, &at);
        // Stamps counted from an origin: the row's as written, the previous one's on the
        // file's clock (a double there may round their difference away).
        let origin = self.time_origin_s();
        let (t, prev_t) = if origin == 0.0 {
            (b.stamp.to_string(), b.previous.to_string())
        } else {
            (
                fields::show(self.record.get(t_col).unwrap_or_default()),
                (b.previous + origin).to_string(),
            )
        };
        let column = &self.names[t_col];
        let previous = match channel {
            Some(c) => format!("channel `{}`'s previous sample", self.channels[c].name),
            None => "the previous row".to_string(),
        };
        let message = if b.conflict.is_some() {
            let shown = |v: f64| crate::limits::readable(v / self.rad_per_unit);
            let differences = match channel {
                Some(c) => b.differences(|_| self.channels[c].name.clone(), shown),
                None => b.differences(|i| self.channels[i].name.clone(), shown),
            };
            format!(
                "time stamp {t} s repeats {previous}'s {prev_t} s (line {prev_line}) with other \
                 readings ({differences}); a stamp's readings must be one row: keep the right \
                 one (a row repeating the one before exactly, a copy, is dropped by itself)"
            )
        } else {
            format!(
                "time stamp {t} s goes back before {previous}'s {prev_t} s (line {prev_line}); \
                 rows must be in increasing time order: sort the log by `{column}`"
            )
        };
        self.error(Some(t_col), message)
    }

    /// A time stamp's problem ([`crate::limits::time_problem`]) with the unit the column would
    /// be in for its stamps to be dates since 1970 where one makes them so.
    fn with_unit_hint(&self, problem: String, t_col: usize) -> String {
        let raw = self.record.get(t_col).unwrap_or_default();
        match self.number(raw).and_then(dialect::epoch_unit) {
            Some((unit, year)) => format!(
                "{problem}; in {}, the column `{}`'s stamps are dates in {year}: say \
                 `time_unit = {}`",
                unit.name(),
                self.names[t_col],
                unit.suffix()
            ),
            None => problem,
        }
    }
}

impl CsvReader {
    /// Reads the next record into `self.record`: `None` at the end of the file (or its `EOF`
    /// line), which ends the stream, as an error does.
    fn read_next(&mut self) -> Option<Result<(), Error>> {
        match self.reader.read(&self.path, &mut self.record) {
            Ok(true) if self.is_end_marker() => {
                self.done = true;
                None
            }
            Ok(true) => {
                self.progress.set(self.reader.position());
                Some(Ok(()))
            }
            Ok(false) => {
                self.done = true;
                None
            }
            Err(e) => {
                self.done = true;
                Some(Err(e))
            }
        }
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
            match self.read_next()? {
                Ok(()) => {}
                Err(e) => return Some(Err(e)),
            }
        }
        loop {
            match self.parse_row() {
                Ok(Some(sample)) => return Some(Ok(sample)),
                // A copy of the previous row, dropped: on to the next.
                Ok(None) => {}
                Err(e) => {
                    self.done = true;
                    return Some(Err(e));
                }
            }
            if let Err(e) = self.read_next()? {
                return Some(Err(e));
            }
        }
    }
}

impl FusedIterator for CsvReader {}

/// A column's name as a command-line argument takes it: in single quotes where it holds
/// anything a shell would split or expand (`'Timestamp (UTC)'`).
fn quoted(name: &str) -> String {
    if name
        .chars()
        .all(|c| c.is_alphanumeric() || matches!(c, '_' | '-' | '.' | '/'))
    {
        name.to_string()
    } else {
        format!("'{}'", name.replace('\'', r"'\''"))
    }
}

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
