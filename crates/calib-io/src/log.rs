//! Any log calib reads, behind one interface: [`LogReader`] and [`LogWriter`].

use crate::align::{AlignOptions, Alignment};
use crate::csv_log::{CsvReader, CsvWriter};
use crate::mcap_log::{DEFAULT_TOPIC, McapReader, McapWriter, TopicInfo};
use crate::naming::{self, ChannelLookup, ChannelName};
use crate::rosbag::{self, BagReader, SQLITE_MAGIC, Storage};
use crate::{Error, ReadDiagnostics, ReadOptions};
use calib_core::{AngleUnit, Channel, Sample};
use std::io::Read;
use std::path::Path;

/// The formats calib reads and writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LogFormat {
    /// CSV with a header row.
    Csv,
    /// MCAP.
    Mcap,
    /// A rosbag2 bag: a bag directory (`metadata.yaml`, `.db3` or `.mcap` splits) or a `.db3`
    /// file. Read only.
    Rosbag,
}

const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

impl LogFormat {
    /// The format's usual file extension: `csv` or `mcap`.
    pub fn name(self) -> &'static str {
        match self {
            LogFormat::Csv => "csv",
            LogFormat::Mcap => "mcap",
            LogFormat::Rosbag => "db3",
        }
    }

    /// The format of a file to write, from its extension.
    pub fn for_output(path: &Path) -> Result<Self, Error> {
        match extension(path).as_deref() {
            Some("csv") => Ok(LogFormat::Csv),
            Some("mcap") => Ok(LogFormat::Mcap),
            _ => Err(Error::UnknownFormat {
                path: path.to_path_buf(),
            }),
        }
    }

    /// The format of an existing log: a bag directory ([`rosbag::is_bag_dir`]: it holds
    /// `metadata.yaml` or `.db3` files), else the file's extension (`.csv`, `.mcap`, `.db3`), or
    /// for an unknown extension its first bytes (MCAP's or SQLite's magic number). Any other
    /// directory is [`Error::UnknownFormat`].
    pub fn detect(path: &Path) -> Result<Self, Error> {
        if path.is_dir() {
            return if rosbag::is_bag_dir(path) {
                Ok(LogFormat::Rosbag)
            } else {
                Err(Error::UnknownFormat {
                    path: path.to_path_buf(),
                })
            };
        }
        if let Ok(format) = Self::for_output(path) {
            return Ok(format);
        }
        if extension(path).as_deref() == Some("db3") {
            return Ok(LogFormat::Rosbag);
        }
        let mut head = [0u8; 16];
        let mut file = std::fs::File::open(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let n = file.read(&mut head).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        if head[..n].starts_with(MCAP_MAGIC) {
            Ok(LogFormat::Mcap)
        } else if &head[..n] == SQLITE_MAGIC {
            Ok(LogFormat::Rosbag)
        } else {
            Err(Error::UnknownFormat {
                path: path.to_path_buf(),
            })
        }
    }
}

fn extension(path: &Path) -> Option<String> {
    path.extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
}

/// A streaming reader of any supported log.
///
/// It opens with every channel of the log selected; [`select`](Self::select) narrows the samples
/// to the channels a method needs, in its order, aligned on the first one's clock (see
/// [`crate::align`]). Channels are found by name with [`resolve`](Self::resolve) (see
/// [`crate::naming`]).
pub struct LogReader {
    inner: Inner,
    names: Vec<ChannelName>,
    /// CSV: the selected columns and their channels (MCAP selects itself).
    selection: Option<(Vec<usize>, Vec<Channel>)>,
    /// A bag directory of MCAP storage without `metadata.yaml`: the warning to give.
    bag_warnings: Vec<String>,
}

enum Inner {
    Csv(CsvReader),
    Mcap(McapReader),
    Bag(BagReader),
}

impl LogReader {
    /// Opens a log, choosing the reader by [`LogFormat::detect`].
    pub fn open(path: &Path, opts: &ReadOptions) -> Result<Self, Error> {
        let mut bag_warnings = Vec::new();
        let inner = match LogFormat::detect(path)? {
            LogFormat::Csv => Inner::Csv(CsvReader::open(path, opts)?),
            LogFormat::Mcap => Inner::Mcap(McapReader::open(path, opts)?),
            LogFormat::Rosbag => {
                let found = rosbag::bag_files(path)?;
                match found.storage {
                    Storage::Sqlite3(files) => {
                        Inner::Bag(BagReader::open(path, files, found.warnings, opts)?)
                    }
                    Storage::Mcap(file) => {
                        let reader = McapReader::open(&file, opts)?;
                        bag_warnings = found.warnings;
                        Inner::Mcap(reader)
                    }
                }
            }
        };
        let names = match &inner {
            Inner::Csv(r) => r
                .channels()
                .iter()
                .map(|c| ChannelName::plain(&c.name))
                .collect(),
            Inner::Mcap(r) => r.names().to_vec(),
            Inner::Bag(r) => r.names().to_vec(),
        };
        Ok(LogReader {
            inner,
            names,
            selection: None,
            bag_warnings,
        })
    }

    /// The names of every channel of the log, selected or not: the indices
    /// [`select`](Self::select) takes.
    pub fn names(&self) -> &[ChannelName] {
        &self.names
    }

    /// The index of the channel `name` names (a qualified name, or a short one no other channel
    /// shares).
    pub fn resolve(&self, name: &str) -> Result<usize, ChannelLookup> {
        naming::resolve(&self.names, name)
    }

    /// Reads only `channels` (indices into [`names`](Self::names)), in this order, aligned on the
    /// first one's stamps. Call it before reading any sample.
    pub fn select(&mut self, channels: &[usize], opts: AlignOptions) {
        match &mut self.inner {
            Inner::Csv(r) => {
                let all = r.channels();
                let chosen = channels.iter().map(|&i| all[i].clone()).collect();
                self.selection = Some((channels.to_vec(), chosen));
            }
            Inner::Mcap(r) => r.select(channels, opts),
            Inner::Bag(r) => r.select(channels, opts),
        }
    }

    /// The channels of each sample, in the order of its values.
    pub fn channels(&self) -> &[Channel] {
        match (&self.inner, &self.selection) {
            (_, Some((_, chosen))) => chosen,
            (Inner::Csv(r), None) => r.channels(),
            (Inner::Mcap(r), None) => r.channels(),
            (Inner::Bag(r), None) => r.channels(),
        }
    }

    /// Whether the log marks CSRR sessions (a CSV `session` column).
    pub fn has_session_marks(&self) -> bool {
        match &self.inner {
            Inner::Csv(r) => r.has_session_column(),
            Inner::Mcap(_) | Inner::Bag(_) => false,
        }
    }

    /// What the reader noticed so far (complete once the iterator is exhausted).
    pub fn diagnostics(&self) -> &ReadDiagnostics {
        match &self.inner {
            Inner::Csv(r) => r.diagnostics(),
            Inner::Mcap(r) => r.diagnostics(),
            Inner::Bag(r) => r.diagnostics(),
        }
    }

    /// How the channels were aligned on the first one's clock (complete once the iterator is
    /// exhausted); `None` for a CSV log, whose rows hold every channel at one stamp.
    pub fn alignment(&self) -> Option<Alignment> {
        match &self.inner {
            Inner::Csv(_) => None,
            Inner::Mcap(r) => Some(r.alignment()),
            Inner::Bag(r) => Some(r.alignment()),
        }
    }

    /// The log's topics with their type, encoding, message count, rate and channels (those
    /// skipped too); empty for a CSV log.
    pub fn topics(&self) -> Vec<TopicInfo> {
        match &self.inner {
            Inner::Csv(_) => Vec::new(),
            Inner::Mcap(r) => r.topics(),
            Inner::Bag(r) => r.topics(),
        }
    }

    /// Notes for the user about parts of the log that were not read (topics of other schemas).
    pub fn notes(&self) -> Vec<String> {
        let ignored = match &self.inner {
            Inner::Csv(_) => return Vec::new(),
            Inner::Mcap(r) => r.ignored_topics(),
            Inner::Bag(r) => r.ignored_topics(),
        };
        ignored
            .iter()
            .map(|t| {
                format!(
                    "topic `{}` ({}, {}) is not JointState, a std_msgs scalar or JSON and was \
                     skipped",
                    t.topic, t.schema, t.message_encoding
                )
            })
            .collect()
    }

    /// Warnings the user must see once the log has been read: truncation, and samples dropped
    /// because a channel could not be aligned on the clock.
    pub fn warnings(&self, path: &Path) -> Vec<String> {
        let d = self.diagnostics();
        let mut w = match &self.inner {
            Inner::Bag(r) => r.warnings().to_vec(),
            _ => self.bag_warnings.clone(),
        };
        if let Some(t) = &d.truncated {
            w.push(format!(
                "{}: the log ends early at byte {} (a crashed recording?): the {} messages before the break were used",
                path.display(),
                t.byte_offset,
                t.messages_read
            ));
        }
        if let Some(a) = self.alignment() {
            for c in &a.channels {
                if c.dropped > 0 {
                    w.push(format!(
                        "{}: {} of {} sample(s) of the clock `{}` were dropped because channel `{}` could not be aligned there (no sample of it within --max-gap {:.6} s on both sides, or before its first or after its last sample)",
                        path.display(),
                        c.dropped,
                        a.clock_samples,
                        a.clock,
                        c.channel,
                        c.max_gap_s
                    ));
                }
                if c.out_of_order > 0 {
                    w.push(format!(
                        "{}: {} sample(s) of channel `{}` were not used because their stamp did not increase",
                        path.display(),
                        c.out_of_order,
                        c.channel
                    ));
                }
            }
        }
        w
    }
}

impl Iterator for LogReader {
    type Item = Result<Sample, Error>;
    fn next(&mut self) -> Option<Self::Item> {
        match &mut self.inner {
            Inner::Csv(r) => {
                let sample = r.next()?;
                Some(match (sample, &self.selection) {
                    (Ok(mut s), Some((columns, _))) => {
                        s.values = columns.iter().map(|&i| s.values[i]).collect();
                        Ok(s)
                    }
                    (other, _) => other,
                })
            }
            Inner::Mcap(r) => r.next(),
            Inner::Bag(r) => r.next(),
        }
    }
}

/// A writer of any supported log format; the output appears only on [`LogWriter::finish`].
pub enum LogWriter {
    /// CSV, readings in degrees.
    Csv(CsvWriter),
    /// MCAP, JointState on one topic, readings in radians (boxed: the MCAP writer is large).
    Mcap(Box<McapWriter>),
}

impl LogWriter {
    /// Creates a log at `path`, the format from its extension (`.csv` or `.mcap`).
    pub fn create(path: &Path, channels: &[Channel], with_session: bool) -> Result<Self, Error> {
        Ok(match LogFormat::for_output(path)? {
            LogFormat::Csv => LogWriter::Csv(CsvWriter::create(
                path,
                channels,
                AngleUnit::Deg,
                with_session,
            )?),
            LogFormat::Mcap => {
                LogWriter::Mcap(Box::new(McapWriter::create(path, channels, DEFAULT_TOPIC)?))
            }
            // `for_output` names no format calib cannot write.
            LogFormat::Rosbag => {
                return Err(Error::UnknownFormat {
                    path: path.to_path_buf(),
                });
            }
        })
    }
    /// Writes one sample.
    pub fn write(&mut self, sample: &Sample) -> Result<(), Error> {
        match self {
            LogWriter::Csv(w) => w.write(sample),
            LogWriter::Mcap(w) => w.write(sample),
        }
    }
    /// Completes the file and moves it into place.
    pub fn finish(self) -> Result<(), Error> {
        match self {
            LogWriter::Csv(w) => w.finish(),
            LogWriter::Mcap(w) => w.finish(),
        }
    }
}
