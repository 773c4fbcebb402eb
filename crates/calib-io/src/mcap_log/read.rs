//! [`McapReader`]: streaming an MCAP file into samples.
//!
//! # How the channel list is known at open
//! Samples carry one value per channel, so the channel list must be fixed before the first sample.
//! [`McapReader::open`] reads it in two steps:
//! 1. The **summary** (if the file has an intact one) lists every channel record: the reader keeps
//!    the topics whose messages it can read and that hold at least one message.
//! 2. A **peek pass** reads messages from the start until each of those topics has shown its first
//!    message, which gives the joint names (JointState) or numeric fields (JSON). Topics usually
//!    all appear in the first chunk, so this costs one chunk. Without a summary (a truncated file,
//!    or a writer that wrote none) the set of topics is unknown, so the peek pass reads the whole
//!    file once.
//!
//! Topics are ordered by their first message in the file, channels by their order within it.
//!
//! # Streaming
//! The summary is read by seeking to the footer; the data section is then read front to back
//! through a buffered file reader by the `records` module's stream over the `mcap` crate's
//! linear reader, which holds at most one chunk at a time and checks every length inside a record
//! before parsing it. Memory is therefore bounded by the chunk size, whatever the length of the log (a
//! memory map would keep every page read resident: as much memory as the log is long). The
//! stream stops at the data end record, so a damaged or missing summary does not stop reading
//! the data.
//!
//! # Truncation
//! [`Truncation::byte_offset`] is where reading stopped (see the [`mcap_log`](super) docs): the
//! larger of the first incomplete top-level record's start and the bytes handed to the stream
//! when it gave its last message (which lies inside a chunk cut short).

use std::collections::VecDeque;
use std::fs::File;
use std::io::{self, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use calib_core::{AngleUnit, Channel, Sample};
use mcap::McapError;
use mcap::sans_io::{LinearReaderOptions, SummaryReadEvent, SummaryReader, SummaryReaderOptions};

use super::JOINT_STATE_SCHEMA;
use super::cdr::JointState;
use super::json;
use super::records::{self, StreamError};
use crate::{Error, ReadDiagnostics, ReadOptions, Truncation};

/// Messages each topic may hold while waiting for the other topics' messages at the same stamp.
/// Beyond it the oldest is dropped and counted as unjoined. 1024 messages cover a second of lag
/// at 1 kHz, more than a recorder buffers between topics.
pub const JOIN_QUEUE: usize = 1024;

/// A topic the reader skipped because its messages are neither JointState (CDR) nor JSON.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IgnoredTopic {
    /// The topic.
    pub topic: String,
    /// Its schema name (empty if it has none).
    pub schema: String,
    /// Its message encoding.
    pub message_encoding: String,
}

/// Reads an MCAP log as a stream of [`Sample`]s (see the [module docs](super) for what is read).
///
/// ```no_run
/// use calib_io::{ReadOptions, mcap_log::McapReader};
///
/// let mut reader = McapReader::open("run.mcap".as_ref(), &ReadOptions::default())?;
/// let names: Vec<String> = reader.channels().iter().map(|c| c.name.clone()).collect();
/// for sample in &mut reader {
///     let sample = sample?;
///     println!("{} {:?} {:?}", sample.t, names, sample.values);
/// }
/// if let Some(cut) = &reader.diagnostics().truncated {
///     eprintln!("warning: the log ends early at byte {}", cut.byte_offset);
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// The iterator ends after the first error it yields.
pub struct McapReader {
    path: PathBuf,
    /// Boxed: the stream's state is large, and the reader is moved around inside enums.
    stream: Box<Stream>,
    /// Bytes of the file handed to the stream so far (shared with its [`Source`]).
    consumed: Arc<AtomicU64>,
    /// `consumed` when the stream gave its last message: where the read data ends.
    consumed_at_last: u64,
    /// The file's length when opened.
    len: u64,
    registry: Registry,
    channels: Vec<Channel>,
    /// Messages taken from the stream so far (all topics).
    index: u64,
    diagnostics: ReadDiagnostics,
    /// Value buffers of joined messages, recycled to keep allocation off the join path.
    pool: Vec<Vec<f64>>,
    done: bool,
}

/// Read buffer of the stream: large enough that reading costs few system calls, small against
/// a chunk.
const READ_BUFFER: usize = 256 * 1024;

/// The file as the stream reads it, from the start, counting the bytes it hands on.
struct Source {
    file: BufReader<File>,
    consumed: Arc<AtomicU64>,
}

impl Read for Source {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.file.read(buf)?;
        self.consumed.fetch_add(n as u64, Ordering::Relaxed);
        Ok(n)
    }
}

type Stream = records::Stream<Source>;

/// A message stream over `file` from its start, and its count of bytes read.
fn stream(mut file: File, len: u64, skip_damaged: bool) -> io::Result<(Stream, Arc<AtomicU64>)> {
    file.seek(SeekFrom::Start(0))?;
    let consumed = Arc::new(AtomicU64::new(0));
    let source = Source {
        file: BufReader::with_capacity(READ_BUFFER, file),
        consumed: Arc::clone(&consumed),
    };
    let options = LinearReaderOptions::default()
        // The stream stops at the data end record; a file cut between two records just ends.
        .with_skip_end_magic(true)
        // No record can be longer than the file; a corrupt length must not drive an allocation.
        .with_record_length_limit(usize::try_from(len).unwrap_or(usize::MAX));
    Ok((
        records::Stream::new(source, options, skip_damaged),
        consumed,
    ))
}

/// The file's summary as the `mcap` crate reads it (chunk indexes and statistics, which `calib
/// apply` copies the compression from), found by seeking to its footer; `None` if it has none or
/// it is damaged (as in a truncated file). Reading samples uses [`records::read_summary`].
pub(crate) fn read_summary(file: &mut File, len: u64) -> Option<mcap::Summary> {
    let options = SummaryReaderOptions::default()
        .with_file_size(len)
        .with_record_length_limit(usize::try_from(len).unwrap_or(usize::MAX));
    let mut reader = SummaryReader::new_with_options(options);
    while let Some(event) = reader.next_event() {
        match event.ok()? {
            SummaryReadEvent::ReadRequest(n) => {
                let read = loop {
                    match file.read(reader.insert(n)) {
                        Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                        other => break other.ok()?,
                    }
                };
                reader.notify_read(read);
            }
            SummaryReadEvent::SeekRequest(to) => reader.notify_seeked(file.seek(to).ok()?),
        }
    }
    reader.finish()
}

/// How a topic's messages are decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Encoding {
    JointState,
    Json,
}

impl Encoding {
    fn of(channel: &mcap::Channel) -> Option<Self> {
        let schema = channel.schema.as_ref().map_or("", |s| s.name.as_str());
        Self::from_names(&channel.message_encoding, schema)
    }

    /// The encoding of a channel with this message encoding and schema name, if calib reads it.
    pub(crate) fn from_names(message_encoding: &str, schema: &str) -> Option<Self> {
        match message_encoding {
            // ROS 1 style names appear in bags converted with older tools.
            "cdr" if schema == JOINT_STATE_SCHEMA || schema == "sensor_msgs/JointState" => {
                Some(Encoding::JointState)
            }
            "json" => Some(Encoding::Json),
            _ => None,
        }
    }
}

struct Topic {
    name: String,
    encoding: Encoding,
    /// JointState: the `name` block of the first message, compared byte for byte with later ones.
    name_block: Vec<u8>,
    /// The channel names: joint names or JSON fields.
    names: Vec<String>,
    /// Radians per unit of a JSON value.
    scale: f64,
    /// JSON: which channels a message has given, reused between messages.
    seen: Vec<bool>,
    queue: VecDeque<(i64, Vec<f64>)>,
}

#[derive(Debug, Clone, Copy)]
enum Slot {
    Unknown,
    Ignored,
    Topic(usize),
}

/// Channel IDs resolved to topics.
struct Registry {
    /// Indexed by channel ID: a vector lookup per message instead of hashing the topic.
    slots: Vec<Slot>,
    topics: Vec<Topic>,
    ignored: Vec<IgnoredTopic>,
}

/// What a channel ID resolves to when first seen.
enum Resolved {
    Known(Option<usize>),
    NewTopic(Encoding),
}

impl Registry {
    fn resolve(&mut self, channel: &mcap::Channel) -> Result<Resolved, String> {
        let id = usize::from(channel.id);
        if let Some(slot) = self.slots.get(id) {
            match slot {
                Slot::Topic(k) => return Ok(Resolved::Known(Some(*k))),
                Slot::Ignored => return Ok(Resolved::Known(None)),
                Slot::Unknown => {}
            }
        }
        if self.slots.len() <= id {
            self.slots.resize(id + 1, Slot::Unknown);
        }
        let Some(encoding) = Encoding::of(channel) else {
            self.slots[id] = Slot::Ignored;
            self.ignore(channel);
            return Ok(Resolved::Known(None));
        };
        match self.topics.iter().position(|t| t.name == channel.topic) {
            Some(k) if self.topics[k].encoding == encoding => {
                self.slots[id] = Slot::Topic(k);
                Ok(Resolved::Known(Some(k)))
            }
            Some(_) => Err(format!(
                "topic `{}` carries both JointState and JSON messages; calib cannot tell which \
                 to read: re-record or filter the topic to one message type",
                channel.topic
            )),
            None => Ok(Resolved::NewTopic(encoding)),
        }
    }

    fn ignore(&mut self, channel: &mcap::Channel) {
        if !self.ignored.iter().any(|t| t.topic == channel.topic) {
            self.ignored.push(IgnoredTopic {
                topic: channel.topic.clone(),
                schema: channel
                    .schema
                    .as_ref()
                    .map_or_else(String::new, |s| s.name.clone()),
                message_encoding: channel.message_encoding.clone(),
            });
        }
    }
}

fn mcap_error(path: &Path, index: Option<u64>, channel: Option<&str>, message: String) -> Error {
    Error::Mcap {
        path: path.to_path_buf(),
        message_index: index,
        channel: channel.map(str::to_string),
        message,
    }
}

/// A stamp in nanoseconds as seconds, exact to the nanosecond for any time of this era.
fn seconds(ns: i64) -> f64 {
    const NS: i64 = 1_000_000_000;
    ns.div_euclid(NS) as f64 + ns.rem_euclid(NS) as f64 * 1e-9
}

fn log_time_ns(log_time: u64) -> Result<i64, String> {
    i64::try_from(log_time).map_err(|_| {
        format!("log time {log_time} ns is beyond the year 2262; the recorder's clock is wrong")
    })
}

/// The offset of the first incomplete top-level record, if the data section is cut short;
/// `None` if it is complete up to its data end record (or the file cannot be read again).
/// Reads only the records' 9-byte headers, skipping their bodies.
fn find_break(path: &Path) -> Option<u64> {
    const DATA_END: u8 = 0x0F;
    let file = File::open(path).ok()?;
    let len = file.metadata().ok()?.len();
    // Buffered: an unchunked file has a record per message, mostly skipped within the buffer.
    let mut file = BufReader::with_capacity(64 * 1024, file);
    let mut offset = mcap::MAGIC.len() as u64;
    let mut head = [0u8; 9];
    file.seek(SeekFrom::Start(offset)).ok()?;
    loop {
        if file.read_exact(&mut head).is_err() {
            return Some(offset);
        }
        let mut body = [0u8; 8];
        body.copy_from_slice(&head[1..]);
        let end = u64::from_le_bytes(body)
            .checked_add(offset + 9)
            .filter(|&end| end <= len);
        let Some(end) = end else {
            return Some(offset);
        };
        if head[0] == DATA_END {
            return None;
        }
        // `end - offset - 9` is the body's length, at most the file's: it fits in i64.
        file.seek_relative((end - offset - 9) as i64).ok()?;
        offset = end;
    }
}

impl McapReader {
    /// Opens an MCAP file and fixes its channel list (see the module docs of `calib_io::mcap_log` for how).
    ///
    /// Errors if the file cannot be read, is empty, is not MCAP, holds no JointState or JSON
    /// topic, names the same channel on two topics, or its first message of a topic is bad.
    pub fn open(path: &Path, opts: &ReadOptions) -> Result<Self, Error> {
        let io = |source| Error::Io {
            path: path.to_path_buf(),
            source,
        };
        let mut file = File::open(path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        if len == 0 {
            return Err(mcap_error(
                path,
                None,
                None,
                "the file is empty (0 bytes); was the recording stopped before it wrote anything?"
                    .into(),
            ));
        }
        let mut magic = [0u8; 8];
        let got = file.read(&mut magic).map_err(io)?;
        // A short first read is allowed by `Read`; finish it, stopping at the end of the file.
        let got = got
            + (&mut file)
                .take(8 - got as u64)
                .read(&mut magic[got..])
                .map_err(io)?;
        if !magic[..got].starts_with(mcap::MAGIC) {
            return Err(mcap_error(
                path,
                None,
                None,
                "not an MCAP file (it does not start with the MCAP magic bytes); calib reads \
                 MCAP logs from ROS 2 (rosbag2 with the mcap storage) or the mcap libraries"
                    .into(),
            ));
        }
        let mut registry = Registry {
            slots: Vec::new(),
            topics: Vec::new(),
            ignored: Vec::new(),
        };
        // No summary, or a truncated file (whose summary cannot be read): scan it all.
        let expected = records::read_summary(&mut file, len)
            .map(|summary| expected_topics(&summary, &mut registry));
        let scale = opts.unit.unwrap_or(AngleUnit::Deg).radians_per_unit();
        let mut messages = 0u64;
        let mut damage = None;
        let mut skipped = Vec::new();
        if expected.as_ref().is_none_or(|e| !e.is_empty()) {
            let (mut peek, _) = stream(file, len, opts.skip_damaged).map_err(io)?;
            for (index, message) in (&mut peek).enumerate() {
                // Errors here are reported by the iteration, at the same message, unless no
                // usable topic comes before them.
                let message = match message {
                    Ok(message) => message,
                    Err(e) => {
                        damage = Some((index as u64, e));
                        break;
                    }
                };
                messages += 1;
                let index = index as u64;
                let resolved = registry
                    .resolve(&message.channel)
                    .map_err(|m| mcap_error(path, Some(index), Some(&message.channel.topic), m))?;
                let Resolved::NewTopic(encoding) = resolved else {
                    continue;
                };
                let topic = first_message(&message, encoding, scale)
                    .map_err(|m| mcap_error(path, Some(index), Some(&message.channel.topic), m))?;
                registry.topics.push(topic);
                // Resolve again to record the channel ID's slot.
                registry
                    .resolve(&message.channel)
                    .map_err(|m| mcap_error(path, Some(index), Some(&message.channel.topic), m))?;
                if expected.as_ref().is_some_and(|e| {
                    e.iter()
                        .all(|t| registry.topics.iter().any(|k| &k.name == t))
                }) {
                    break;
                }
            }
            skipped = peek.damaged().to_vec();
            file = peek.into_inner().file.into_inner();
        }
        if registry.topics.is_empty() {
            if !skipped.is_empty() {
                let list: Vec<String> = skipped.iter().map(|c| c.to_string()).collect();
                return Err(mcap_error(
                    path,
                    None,
                    None,
                    format!(
                        "no JointState or JSON message is left once the damaged chunks are \
                         skipped (--skip-damaged): {}; repair the file or record again",
                        list.join("; ")
                    ),
                ));
            }
            if let Some((index, e)) = damage {
                if let StreamError::Damaged(_) = e {
                    return Err(damaged_error(path, index, &e));
                }
                if !matches!(e, StreamError::Mcap(McapError::UnexpectedEof)) {
                    return Err(mcap_error(
                        path,
                        Some(index),
                        None,
                        format!(
                            "the file is damaged here ({e}) before any JointState or JSON \
                             message; recover what is left with `mcap recover`"
                        ),
                    ));
                }
            }
            // A file cut before its first usable message is cut, whatever else it holds: say so
            // rather than that it holds no samples.
            if let Some(at) = find_break(path) {
                return Err(mcap_error(
                    path,
                    None,
                    None,
                    format!(
                        "the file is cut short at byte {at} of {len}, before its first JointState \
                         or JSON message (a recording that stopped early, or a partial copy); \
                         copy the file again or record again"
                    ),
                ));
            }
            if messages == 0 && registry.ignored.is_empty() {
                return Err(Error::Empty {
                    path: path.to_path_buf(),
                });
            }
            let found: Vec<String> = registry
                .ignored
                .iter()
                .map(|t| format!("{} ({}, {})", t.topic, t.schema, t.message_encoding))
                .collect();
            return Err(mcap_error(
                path,
                None,
                None,
                format!(
                    "no topic holds {JOINT_STATE_SCHEMA} (cdr) or JSON messages (found: {}); \
                     record the encoders as JointState or JSON",
                    if found.is_empty() {
                        "no topics".to_string()
                    } else {
                        found.join(", ")
                    }
                ),
            ));
        }
        let mut channels: Vec<Channel> = Vec::new();
        for (k, topic) in registry.topics.iter().enumerate() {
            let unit = match topic.encoding {
                Encoding::JointState => AngleUnit::Rad,
                Encoding::Json => opts.unit.unwrap_or(AngleUnit::Deg),
            };
            for name in &topic.names {
                if let Some(other) = registry.topics[..=k]
                    .iter()
                    .find(|t| t.names.contains(name) && (t.name != topic.name))
                    .or_else(|| {
                        // A name repeated within one message.
                        (topic.names.iter().filter(|n| *n == name).count() > 1).then_some(topic)
                    })
                {
                    return Err(mcap_error(
                        path,
                        None,
                        Some(name),
                        format!(
                            "the channel appears twice (on topics `{}` and `{}`); a sample can \
                             hold one reading per name: rename one of the joints",
                            other.name, topic.name
                        ),
                    ));
                }
                channels.push(Channel {
                    name: name.clone(),
                    unit,
                });
            }
        }
        let (stream, consumed) = stream(file, len, opts.skip_damaged).map_err(io)?;
        Ok(McapReader {
            path: path.to_path_buf(),
            stream: Box::new(stream),
            consumed,
            consumed_at_last: 0,
            len,
            registry,
            channels,
            index: 0,
            diagnostics: ReadDiagnostics::default(),
            pool: Vec::new(),
            done: false,
        })
    }

    /// The channels, in the order of each sample's values: topics in the order of their first
    /// message, then the names within a message.
    pub fn channels(&self) -> &[Channel] {
        &self.channels
    }

    /// What the reader noticed so far: unjoined messages, and (once iteration has ended) where a
    /// truncated file broke off.
    pub fn diagnostics(&self) -> &ReadDiagnostics {
        &self.diagnostics
    }

    /// Topics skipped because their messages are neither JointState nor JSON, in the order met.
    pub fn ignored_topics(&self) -> &[IgnoredTopic] {
        &self.registry.ignored
    }

    /// Decodes one message; a sample if it completes one.
    fn step(&mut self, message: &mcap::Message, index: u64) -> Result<Option<Sample>, Error> {
        let fail = |channel: &str, m: String| mcap_error(&self.path, Some(index), Some(channel), m);
        let k = match self.registry.resolve(&message.channel) {
            Ok(Resolved::Known(Some(k))) => k,
            Ok(Resolved::Known(None)) => return Ok(None),
            Ok(Resolved::NewTopic(_)) => {
                return Err(fail(
                    &message.channel.topic,
                    "this topic is missing from the file's summary, so its channels were not \
                     known when the file was opened; repair the file with `mcap recover`"
                        .into(),
                ));
            }
            Err(m) => return Err(fail(&message.channel.topic, m)),
        };
        let single = self.registry.topics.len() == 1;
        let topic = &mut self.registry.topics[k];
        let mut values = if single {
            Vec::with_capacity(topic.names.len())
        } else {
            let mut v = self.pool.pop().unwrap_or_default();
            v.clear();
            v
        };
        let stamp = decode(topic, message, &mut values).map_err(|(c, m)| {
            let c = c.unwrap_or_else(|| topic.name.clone());
            fail(&c, m)
        })?;
        if single {
            return Ok(Some(Sample {
                t: seconds(stamp),
                values,
                session: None,
            }));
        }
        if topic.queue.len() >= JOIN_QUEUE {
            if let Some((_, old)) = topic.queue.pop_front() {
                self.pool.push(old);
                self.diagnostics.unjoined_messages += 1;
            }
        }
        topic.queue.push_back((stamp, values));
        Ok(self.join())
    }

    /// A sample from the queue fronts once every topic has a message at the same stamp; messages
    /// older than another topic's front can never be joined and are dropped.
    fn join(&mut self) -> Option<Sample> {
        let topics = &mut self.registry.topics;
        loop {
            let mut newest = i64::MIN;
            for topic in topics.iter() {
                newest = newest.max(topic.queue.front()?.0);
            }
            let mut complete = true;
            for topic in topics.iter_mut() {
                while topic.queue.front().is_some_and(|(s, _)| *s < newest) {
                    if let Some((_, old)) = topic.queue.pop_front() {
                        self.pool.push(old);
                        self.diagnostics.unjoined_messages += 1;
                    }
                }
                complete &= topic.queue.front().is_some_and(|(s, _)| *s == newest);
            }
            if complete {
                let mut values = Vec::with_capacity(self.channels.len());
                for topic in topics.iter_mut() {
                    if let Some((_, v)) = topic.queue.pop_front() {
                        values.extend_from_slice(&v);
                        self.pool.push(v);
                    }
                }
                return Some(Sample {
                    t: seconds(newest),
                    values,
                    session: None,
                });
            }
        }
    }

    /// Records where reading stopped if the data section is cut short; whether it is.
    fn note_truncation(&mut self) -> bool {
        // Reading stopped at the first incomplete record, or inside it (a chunk cut short)
        // where the last message came out.
        let Some(byte_offset) = find_break(&self.path).map(|b| b.max(self.consumed_at_last)) else {
            return false;
        };
        self.diagnostics.truncated = Some(Truncation {
            byte_offset,
            messages_read: self.index,
        });
        true
    }

    /// Counts what is still waiting for a partner when the stream ends, and lists the damaged
    /// chunks left out.
    fn finish(&mut self) {
        self.done = true;
        self.diagnostics.damaged_chunks = self.stream.damaged().to_vec();
        for topic in &mut self.registry.topics {
            self.diagnostics.unjoined_messages += topic.queue.len() as u64;
            topic.queue.clear();
        }
    }
}

impl Iterator for McapReader {
    type Item = Result<Sample, Error>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        loop {
            let message = match self.stream.next() {
                Some(Ok(message)) => {
                    // Chunks are held until checked: where this message's bytes ended is where
                    // the reader was when it gave the message, not where the check got to.
                    self.consumed_at_last = self.stream.consumed_at_last();
                    message
                }
                None => {
                    self.finish();
                    // The stream stops at the data end record, before the end of the file. It
                    // also ends cleanly when the file ends between two records (it is told to
                    // expect no end magic): then the data end record is missing.
                    if self.consumed.load(Ordering::Relaxed) >= self.len {
                        self.note_truncation();
                    }
                    return None;
                }
                Some(Err(e)) => {
                    self.finish();
                    // Reading stopped at the first incomplete record, or inside it (a cut chunk)
                    // where the last message came out.
                    return match e {
                        StreamError::Mcap(McapError::UnexpectedEof) if self.note_truncation() => {
                            None
                        }
                        StreamError::Damaged(_) | StreamError::DataCrc => {
                            Some(Err(damaged_error(&self.path, self.index, &e)))
                        }
                        _ => Some(Err(mcap_error(
                            &self.path,
                            Some(self.index),
                            None,
                            format!(
                                "the file is damaged here ({e}); the messages before it were \
                                 read: recover the rest with `mcap recover`"
                            ),
                        ))),
                    };
                }
            };
            let index = self.index;
            self.index += 1;
            match self.step(&message, index) {
                Ok(Some(sample)) => return Some(Ok(sample)),
                Ok(None) => {}
                Err(e) => {
                    self.done = true;
                    return Some(Err(e));
                }
            }
        }
    }
}

/// The error for a damaged chunk or data section met after `index` messages.
fn damaged_error(path: &Path, index: u64, e: &StreamError) -> Error {
    let what = match e {
        StreamError::Damaged(_) => {
            "none of its messages were used: run with --skip-damaged to calibrate without them \
             (they are then listed in the report), or repair the file"
        }
        _ => "calib cannot tell which readings it changed: repair the file or record again",
    };
    mcap_error(path, Some(index), None, format!("{e}; {what}"))
}

/// The usable topics the summary lists with at least one message; ignored ones go to `registry`.
fn expected_topics(summary: &records::Summary, registry: &mut Registry) -> Vec<String> {
    let mut channels: Vec<_> = summary.channels.values().collect();
    channels.sort_by_key(|c| c.id);
    let mut topics = Vec::new();
    for channel in channels {
        let has_messages = summary
            .message_counts
            .as_ref()
            .and_then(|counts| counts.get(&channel.id))
            .is_none_or(|&n| n > 0);
        if !has_messages {
            continue;
        }
        if Encoding::of(channel).is_none() {
            registry.ignore(channel);
        } else if !topics.contains(&channel.topic) {
            topics.push(channel.topic.clone());
        }
    }
    topics
}

/// A topic's channels from its first message.
fn first_message(message: &mcap::Message, encoding: Encoding, scale: f64) -> Result<Topic, String> {
    let mut topic = Topic {
        name: message.channel.topic.clone(),
        encoding,
        name_block: Vec::new(),
        names: Vec::new(),
        scale,
        seen: Vec::new(),
        queue: VecDeque::new(),
    };
    match encoding {
        Encoding::JointState => {
            let js = JointState::parse(&message.data).map_err(|e| e.to_string())?;
            for name in js.names() {
                topic
                    .names
                    .push(name.map_err(|e| e.to_string())?.to_string());
            }
            topic.name_block = js.name_block.to_vec();
        }
        Encoding::Json => {
            json::for_each_field(&message.data, |key, value| {
                if value.is_some() {
                    topic.names.push(key.to_string());
                }
                Ok(())
            })?;
            topic.seen = vec![false; topic.names.len()];
        }
    }
    if topic.names.is_empty() {
        return Err(match encoding {
            Encoding::JointState => "the topic's first JointState message names no joints; \
                                     publish the encoders' names and positions"
                .into(),
            Encoding::Json => "the topic's first JSON message has no numeric field; publish \
                               one numeric field per encoder"
                .into(),
        });
    }
    Ok(topic)
}

/// Decodes a message of `topic` into `out` (radians, in the topic's channel order) and returns its
/// stamp in nanoseconds. Errors carry the channel concerned (if not the topic) and the message.
fn decode(
    topic: &mut Topic,
    message: &mcap::Message,
    out: &mut Vec<f64>,
) -> Result<i64, (Option<String>, String)> {
    match topic.encoding {
        Encoding::JointState => {
            let js = JointState::parse(&message.data).map_err(|e| (None, e.to_string()))?;
            if js.position_count() != js.name_count {
                return Err((
                    None,
                    format!(
                        "the JointState message has {} names but {} positions; the publisher \
                         must give a position for every joint",
                        js.name_count,
                        js.position_count()
                    ),
                ));
            }
            // Fast path: the same names serialize to the same bytes. Padding bytes may differ
            // between writers, so a mismatch is confirmed name by name.
            if js.name_block != topic.name_block.as_slice() && !same_names(&js, &topic.names) {
                let now: Vec<String> = js
                    .names()
                    .map(|n| n.unwrap_or("<not UTF-8>").to_string())
                    .collect();
                return Err((
                    None,
                    format!(
                        "the joint names changed from [{}] to [{}]; calib needs one joint set \
                         per topic: split the recording where the set changes",
                        topic.names.join(", "),
                        now.join(", ")
                    ),
                ));
            }
            let start = out.len();
            out.extend(js.positions());
            for (name, &rad) in topic.names.iter().zip(&out[start..]) {
                let shown = crate::limits::readable(rad);
                if let Some(problem) = crate::limits::reading_problem(shown, rad, rad) {
                    return Err((Some(name.clone()), problem));
                }
            }
            if js.nanosec >= 1_000_000_000 {
                return Err((
                    None,
                    format!(
                        "header.stamp.nanosec is {}, not below 10⁹; the publisher's stamps are \
                         broken (nanoseconds must be the fraction of the second)",
                        js.nanosec
                    ),
                ));
            }
            if js.sec == 0 && js.nanosec == 0 {
                log_time_ns(message.log_time).map_err(|m| (None, m))
            } else {
                Ok(i64::from(js.sec) * 1_000_000_000 + i64::from(js.nanosec))
            }
        }
        Encoding::Json => {
            let stamp = log_time_ns(message.log_time).map_err(|m| (None, m))?;
            out.resize(topic.names.len(), 0.0);
            topic.seen.iter_mut().for_each(|s| *s = false);
            let (names, seen, scale) = (&topic.names, &mut topic.seen, topic.scale);
            // Fields usually come in the first message's order: try the next expected one first.
            let mut next = 0;
            json::for_each_field(&message.data, |key, value| {
                let i = if names.get(next).is_some_and(|n| n == key) {
                    Some(next)
                } else {
                    names.iter().position(|n| n == key)
                };
                match (i, value) {
                    (Some(i), Some(v)) => {
                        let rad = v * scale;
                        if let Some(problem) = crate::limits::reading_problem(v, v, rad) {
                            return Err(format!("field `{key}`: {problem}"));
                        }
                        out[i] = rad;
                        seen[i] = true;
                        next = i + 1;
                        Ok(())
                    }
                    (Some(_), None) => Err(format!(
                        "field `{key}` is not a number in this message; every message must give \
                         a number for every channel"
                    )),
                    (None, Some(_)) => Err(format!(
                        "numeric field `{key}` is new (the topic's first message has [{}]); \
                         calib needs one channel set per topic: split the recording where it \
                         changes",
                        names.join(", ")
                    )),
                    (None, None) => Ok(()),
                }
            })
            .map_err(|m| (None, m))?;
            if let Some(i) = seen.iter().position(|s| !s) {
                return Err((
                    Some(names[i].clone()),
                    "the field is missing from this message; every message must give a number \
                     for every channel"
                        .into(),
                ));
            }
            Ok(stamp)
        }
    }
}

fn same_names(js: &JointState, names: &[String]) -> bool {
    js.name_count == names.len() && js.names().zip(names).all(|(a, b)| a.is_ok_and(|a| a == b))
}
