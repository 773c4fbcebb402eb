//! Streaming reader of CSV logs.

use super::dialect;
use super::fields::{self, line_of, parse_f64};
use crate::limits::LineLimit;
use crate::{Error, ReadDiagnostics, ReadOptions};
use calib_core::{AngleUnit, Channel, Sample};
use csv::ByteRecord;
use std::fs::File;
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
    reader: csv::Reader<LineLimit<File>>,
    /// Reused for every row: no allocation per row but the sample's own values.
    record: ByteRecord,
    /// `record` holds a row read ahead by `open` (the first data row) that is yet to be yielded.
    pending: bool,
    /// The stream has ended, at the end of the file or after an error.
    done: bool,
    names: Vec<String>,
    channels: Vec<Channel>,
    t_col: usize,
    /// Seconds per unit of the time column.
    t_scale: f64,
    session_col: Option<usize>,
    /// The column of each channel, in the order of `channels`.
    value_cols: Vec<usize>,
    rad_per_unit: f64,
    /// Pass stamps that repeat or go back through (for `inspect`, which reports them).
    allow_unordered_time: bool,
    /// The previous row's time stamp and position, for the monotonicity check and its message.
    prev: Option<(f64, csv::Position)>,
    diagnostics: ReadDiagnostics,
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
        let mut reader = fields::csv_reader_with(file, dialect.separator);
        let mut record = ByteRecord::new();
        let csv_err = |e| fields::from_csv(path, e);
        for _ in 0..dialect.skip {
            reader.read_byte_record(&mut record).map_err(csv_err)?;
        }
        let err = |line, channel: Option<&str>, message: String| Error::Csv {
            path: path.to_path_buf(),
            line,
            channel: channel.map(str::to_string),
            message,
        };
        if !reader.read_byte_record(&mut record).map_err(csv_err)? {
            return Err(err(
                1,
                None,
                "the file is empty; a CSV log needs a header row such as `t,a,b` and one row \
                 per sample"
                    .into(),
            ));
        }
        if record.len() > crate::limits::MAX_CSV_COLUMNS {
            return Err(err(
                line_of(path, &record),
                None,
                format!(
                    "the header has {} columns, more than the {} calib reads (a column per \
                     channel); keep the time and the encoders' columns",
                    record.len(),
                    crate::limits::MAX_CSV_COLUMNS
                ),
            ));
        }
        let names = fields::header_names(path, &record)?;
        let header_line = line_of(path, &record);
        let unit = opts.unit.unwrap_or(AngleUnit::Deg);
        let Some((t_col, t_unit)) =
            dialect::time_column(&names, opts.time_column.as_deref(), opts.time_unit)
        else {
            return Err(err(
                header_line,
                None,
                match &opts.time_column {
                    Some(wanted) => format!(
                        "the header has no column `{wanted}` (it has: {}); give --time-column \
                         one of those names",
                        names.join(", ")
                    ),
                    None => format!(
                        "the header has no time column (it has: {}); name it `t` (seconds), \
                         `time` or `timestamp` (with a unit such as ` [ms]`), or name it with \
                         --time-column",
                        names.join(", ")
                    ),
                },
            ));
        };
        let mut session_col = None;
        let mut channels = Vec::new();
        let mut value_cols = Vec::new();
        for (i, name) in names.iter().enumerate() {
            if i == t_col {
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
                header_line,
                None,
                format!(
                    "the header has no channel columns (it has: {}); add one column of readings \
                     per sensor, named by the sensor",
                    names.join(", ")
                ),
            ));
        }
        if !reader.read_byte_record(&mut record).map_err(csv_err)? {
            return Err(err(
                header_line + 1,
                None,
                "the log has a header but no data rows; it needs one row per sample".into(),
            ));
        }
        Ok(CsvReader {
            path: path.to_path_buf(),
            reader,
            record,
            pending: true,
            done: false,
            names,
            channels,
            t_col,
            t_scale: t_unit.seconds(),
            session_col,
            value_cols,
            rad_per_unit: unit.radians_per_unit(),
            allow_unordered_time: opts.allow_unordered_time,
            prev: None,
            diagnostics: ReadDiagnostics::default(),
        })
    }

    /// Whether the log has a `session` column marking CSRR sessions.
    pub fn has_session_column(&self) -> bool {
        self.session_col.is_some()
    }

    /// The log's channels, in column order (without `t` and `session`).
    pub fn channels(&self) -> &[Channel] {
        &self.channels
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

    /// The sample in `self.record`.
    fn parse_row(&mut self) -> Result<Sample, Error> {
        let record = &self.record;
        if record.len() != self.names.len() {
            return Err(fields::wrong_width(&self.path, record, &self.names));
        }
        let field = |c: usize| record.get(c).unwrap_or_default();

        let raw_t = field(self.t_col);
        let t = parse_f64(raw_t).map(|t| t * self.t_scale).ok_or_else(|| {
            self.error(
                Some(self.t_col),
                fields::not_a_number(raw_t, "the time (seconds)"),
            )
        })?;
        if !t.is_finite() {
            return Err(self.error(
                Some(self.t_col),
                format!(
                    "time `{}` is not a finite number; every row needs a real time stamp in \
                     seconds",
                    fields::show(raw_t)
                ),
            ));
        }
        if let Some(problem) = crate::limits::time_problem(t) {
            return Err(self.error(Some(self.t_col), problem));
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
                return Err(self.error(
                    Some(self.t_col),
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
            let v = parse_f64(raw)
                .ok_or_else(|| self.error(Some(c), fields::not_a_number(raw, "a reading")))?;
            let rad = v * self.rad_per_unit;
            if let Some(problem) = crate::limits::reading_problem(fields::Shown(raw), v, rad) {
                return Err(self.error(Some(c), problem));
            }
            values.push(rad);
        }

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
            match self.reader.read_byte_record(&mut self.record) {
                Ok(true) => {}
                Ok(false) => {
                    self.done = true;
                    return None;
                }
                Err(e) => {
                    self.done = true;
                    return Some(Err(fields::from_csv(&self.path, e)));
                }
            }
        }
        let sample = self.parse_row();
        self.done = sample.is_err();
        Some(sample)
    }
}

impl FusedIterator for CsvReader {}
