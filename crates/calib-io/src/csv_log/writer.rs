//! Writer of CSV logs, the inverse of [`CsvReader`](super::CsvReader).

use crate::Error;
use crate::atomic::AtomicFile;
use calib_core::{AngleUnit, Channel, Sample};
use std::io::Write;
use std::path::Path;

/// Writes [`Sample`]s as a CSV log that [`CsvReader`](super::CsvReader) reads back.
///
/// Columns: `t`, one per channel in the given order, then `session` if asked for (`-1` for
/// samples outside any session). Numbers are written in the shortest form that parses back to
/// the same `f64` (`ryu`), so time stamps, sessions and readings in the written unit survive a
/// round trip exactly; readings in radians come back within an ulp or two of the conversion to
/// and from the unit (exactly, for [`AngleUnit::Rad`]).
///
/// The log appears at its path only on [`CsvWriter::finish`]; a writer dropped before that (an
/// error, a panic) leaves no file behind. Samples the reader would reject — non-finite numbers,
/// time stamps not strictly increasing, the wrong number of values — are refused with an error,
/// so every finished log is readable.
///
/// ```
/// use calib_core::{AngleUnit, Channel, Sample};
/// use calib_io::csv_log::CsvWriter;
/// let dir = tempfile::tempdir()?;
/// let path = dir.path().join("sim.csv");
/// let ch = |n: &str| Channel { name: n.into(), unit: AngleUnit::Deg };
/// let mut w = CsvWriter::create(&path, &[ch("a"), ch("b")], AngleUnit::Deg, true)?;
/// w.write(&Sample { t: 0.5, values: vec![std::f64::consts::PI, 0.0], session: Some(0) })?;
/// w.finish()?;
/// assert_eq!(std::fs::read_to_string(&path)?, "t,a,b,session\n0.5,180.0,0.0,0\n");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct CsvWriter {
    file: AtomicFile,
    width: usize,
    unit: AngleUnit,
    with_session: bool,
    /// The line the next sample goes to (the header is line 1), for error messages.
    line: u64,
    prev_t: Option<f64>,
    /// One row, built here and written with a single call.
    row: Vec<u8>,
}

impl CsvWriter {
    /// Starts a log at `path` with these channels' names, readings written in `unit`.
    ///
    /// Each [`Channel::unit`] is ignored: every channel is written in `unit`, which is what a
    /// reader of the file must be told (`--unit`). Names must be non-empty, distinct, free of
    /// surrounding whitespace and not `t` or `session`, so that the reader finds the same
    /// channels; names holding commas or quotes are quoted.
    pub fn create(
        path: &Path,
        channels: &[Channel],
        unit: AngleUnit,
        with_session: bool,
    ) -> Result<Self, Error> {
        let refuse = |message: String| Error::Write {
            path: path.to_path_buf(),
            message,
        };
        if channels.is_empty() {
            return Err(refuse(
                "no channels to write; a log needs at least one channel".into(),
            ));
        }
        for (i, ch) in channels.iter().enumerate() {
            let name = ch.name.as_str();
            if name.is_empty() || name.trim() != name {
                return Err(refuse(format!(
                    "channel name `{name}` is empty or has surrounding whitespace, which the \
                     reader would trim; rename the channel"
                )));
            }
            if name == "t" || name == "session" {
                return Err(refuse(format!(
                    "channel name `{name}` is reserved for the time or session column; rename \
                     the channel"
                )));
            }
            if channels[..i].iter().any(|c| c.name == name) {
                return Err(refuse(format!(
                    "two channels are named `{name}`; channel names must be unique"
                )));
            }
        }
        let mut header = csv::Writer::from_writer(Vec::new());
        let names = std::iter::once("t")
            .chain(channels.iter().map(|c| c.name.as_str()))
            .chain(with_session.then_some("session"));
        header
            .write_record(names)
            .and_then(|()| header.flush().map_err(csv::Error::from))
            .map_err(|e| refuse(e.to_string()))?;
        let header = header
            .into_inner()
            .map_err(|e| refuse(e.error().to_string()))?;

        let mut file = AtomicFile::create(path)?;
        file.write_all(&header).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Ok(CsvWriter {
            file,
            width: channels.len(),
            unit,
            with_session,
            line: 2,
            prev_t: None,
            row: Vec::with_capacity(64),
        })
    }

    /// Appends one sample (readings in radians, converted to the log's unit).
    ///
    /// A sample's session is written only if the log was created `with_session`.
    pub fn write(&mut self, sample: &Sample) -> Result<(), Error> {
        let refuse = |message: String| Error::Write {
            path: self.file.target().to_path_buf(),
            message: format!("sample for line {}: {message}", self.line),
        };
        if sample.values.len() != self.width {
            return Err(refuse(format!(
                "{} values for a log of {} channels; give one reading per channel",
                sample.values.len(),
                self.width
            )));
        }
        if !sample.t.is_finite() {
            return Err(refuse(format!("time {} is not finite", sample.t)));
        }
        if let Some(prev) = self.prev_t {
            if sample.t <= prev {
                return Err(refuse(format!(
                    "time {} s is not after the previous sample's {prev} s; samples must be \
                     written in strictly increasing time order",
                    sample.t
                )));
            }
        }
        let mut num = ryu::Buffer::new();
        self.row.clear();
        self.row
            .extend_from_slice(num.format_finite(sample.t).as_bytes());
        for (i, &v) in sample.values.iter().enumerate() {
            let x = self.unit.from_rad(v);
            if !x.is_finite() {
                return Err(refuse(format!(
                    "reading {v} rad of channel {} is not finite in {}",
                    i + 1,
                    self.unit
                )));
            }
            self.row.push(b',');
            self.row.extend_from_slice(num.format_finite(x).as_bytes());
        }
        if self.with_session {
            self.row.push(b',');
            match sample.session {
                // Writing into a Vec cannot fail.
                Some(s) => {
                    let _ = write!(self.row, "{s}");
                }
                None => self.row.extend_from_slice(b"-1"),
            }
        }
        self.row.push(b'\n');
        self.file.write_all(&self.row).map_err(|source| Error::Io {
            path: self.file.target().to_path_buf(),
            source,
        })?;
        self.prev_t = Some(sample.t);
        self.line += 1;
        Ok(())
    }

    /// Completes the log and puts it in place (flush, fsync, rename).
    ///
    /// A log without samples is refused (and not written): the reader would reject it.
    pub fn finish(self) -> Result<(), Error> {
        if self.prev_t.is_none() {
            return Err(Error::Write {
                path: self.file.target().to_path_buf(),
                message: "no samples were written; a log needs at least one".into(),
            });
        }
        self.file.commit()
    }
}
