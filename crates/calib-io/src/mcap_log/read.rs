//! [`McapReader`]: streaming an MCAP file into samples.
//!
//! # How the channel list is known at open
//! Samples carry one value per channel, so the channel list must be fixed before the first sample.
//! [`McapReader::open`] reads it in two steps:
//! 1. The **summary** (if the file has an intact one) lists every channel record: the reader keeps
//!    the topics whose messages it can read and that hold at least one message.
//! 2. A **peek pass** reads messages from the start until each of those topics has shown its first
//!    message, which gives the joint names (JointState) or numeric fields (JSON), and then
//!    [`PEEK_WINDOW`] messages more, which gather the joints of topics whose messages carry
//!    subsets of them (several publishers sharing `/joint_states`). Topics usually all appear in
//!    the first chunk, so this costs a chunk or two. Where a topic's messages do carry different
//!    joint sets, the peek pass reads on to the end of the file, so that no joint is missed.
//!    Without a summary (a truncated file, or a writer that wrote none) the set of topics is
//!    unknown, so the peek pass reads the whole file once.
//!
//! Topics are ordered by their first message in the file, channels by their first appearance
//! within a topic. Channels are named as [`crate::naming`] says: the joint name where unique in
//! the file, else `TOPIC/JOINT`.
//!
//! # Several topics, several clocks
//! Every message goes to an [`Aligner`]: the first selected channel sets the clock, every other
//! channel is interpolated at its stamps ([`crate::align`]); a channel at exactly the clock's
//! stamp is taken as it is. A log of one topic whose messages all carry every joint needs none
//! of this and is read straight through, message by message, as fast as before.
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
//! Where the summary's chunk index lists [`PARALLEL_CHUNKS`] chunks or more, each lying within
//! the data section, the chunks are decompressed and checked on worker threads instead, and
//! their records handed on in the same order ([`super::chunks`]); at the first irregularity the
//! streaming reader reads the file again from its start, skipping the messages already handed
//! on, so that every message, error and recovery is the streaming reader's.
//!
//! # Truncation
//! [`Truncation::byte_offset`] is where reading stopped (see the [`mcap_log`](super) docs): the
//! larger of the first incomplete top-level record's start and the bytes handed to the stream
//! when it gave its last message (which lies inside a chunk cut short).

use std::fs::File;
use std::io::{self, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use calib_core::{AngleUnit, Channel, Sample};
use mcap::McapError;
use mcap::sans_io::{LinearReaderOptions, SummaryReadEvent, SummaryReader, SummaryReaderOptions};

use super::cdr::{JointFormat, JointState, Scalar};
use super::chunks;
use super::json;
use super::msgdef::{Definition, Plan};
use super::records::{self, StreamError};
use super::{DYNAMIC_JOINT_STATE_SCHEMA, JOINT_STATE_SCHEMA};
use crate::align::{AlignOptions, Aligner, Alignment};
use crate::naming::{ChannelName, names_of};
use crate::stamps::StampOrder;
use crate::{DamagedChunk, Error, ReadDiagnostics, ReadOptions, TimeSource, Truncation};

/// Chunks a file's summary must list for them to be read on worker threads: a file of one chunk
/// gains nothing from it, and a small log should not pay for starting threads.
pub const PARALLEL_CHUNKS: usize = 2;

/// Messages the peek pass reads on after every topic has shown itself, gathering the joints of
/// topics whose messages carry subsets of them: several hundred messages of each of a few
/// publishers.
pub const PEEK_WINDOW: u64 = 4096;

/// Joint sets per topic whose channel positions are remembered (beyond it they are looked up
/// name by name): more publishers than any robot shares one topic between.
const LAYOUT_CACHE: usize = 64;

/// A topic of the file, as `calib inspect` lists it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, schemars::JsonSchema)]
pub struct TopicInfo {
    /// The topic.
    pub topic: String,
    /// Its message type (schema name; empty if it has none).
    pub schema: String,
    /// Its message encoding (`cdr`, `json`, …).
    pub message_encoding: String,
    /// Messages read (every message of the file once iteration has ended).
    pub messages: u64,
    /// Messages per second of log time, from the first to the last; `None` below two messages.
    pub rate_hz: Option<f64>,
    /// Its channels by the names the commands accept; empty for a topic calib does not read.
    pub channels: Vec<String>,
}

/// Messages and log-time span of one topic.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct TopicStats {
    pub(crate) messages: u64,
    pub(crate) first: u64,
    pub(crate) last: u64,
}

impl TopicStats {
    pub(crate) fn note(&mut self, log_time: u64) {
        if self.messages == 0 {
            self.first = log_time;
        }
        self.messages += 1;
        self.last = log_time;
    }

    pub(crate) fn rate_hz(&self) -> Option<f64> {
        (self.messages > 1 && self.last > self.first)
            .then(|| (self.messages - 1) as f64 / ((self.last - self.first) as f64 * 1e-9))
    }
}

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
    /// Every channel of the file, in raw order (topics, then joints).
    all_channels: Vec<Channel>,
    names: Vec<ChannelName>,
    /// The selected channels, in the order of each sample's values.
    channels: Vec<Channel>,
    time: TimeSource,
    aligner: Aligner,
    /// One topic whose messages carry every joint, each channel selected at most once: every
    /// message is a sample (its selected joints, exact on the same stamp), and the aligner is
    /// bypassed.
    fast: bool,
    /// Where the fast path's values come from: `None` for every channel in order, else the
    /// selected raw channels.
    pick: Option<Vec<usize>>,
    /// Samples emitted by the fast path (every channel exact).
    fast_samples: u64,
    /// One reading per raw channel of the current message, NaN where it carries none.
    raw: Vec<f64>,
    /// Messages taken from the stream so far (all topics).
    index: u64,
    diagnostics: ReadDiagnostics,
    /// The stream has ended (or failed): what the aligner holds is all that is left.
    done: bool,
    /// An error was yielded: the iteration is over.
    failed: bool,
    /// Reading chunks in parallel: the file, for the streaming reader to take over with.
    reopen: Option<File>,
    skip_damaged: bool,
    /// Messages the streaming reader skips after taking over: those handed on already.
    skip: u64,
    /// The raw index of the clock channel (the first selected).
    clock: usize,
    /// The clock's stamps so far (see [`crate::stamps`]).
    order: StampOrder,
    /// Pass on clock stamps that do not increase (`calib inspect` counts them).
    allow_unordered_time: bool,
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
        // No record is longer than the file or a limit; a corrupt length drives no allocation.
        .with_record_length_limit(crate::limits::mcap_record_limit(len));
    Ok((
        records::Stream::new(source, options, skip_damaged),
        consumed,
    ))
}

/// The stream of the whole file: with `parallel`, its chunks decompressed on worker threads (see
/// [`super::chunks`]) and a second handle on the file for the streaming reader to take over
/// with; else (or if no thread can be started) the streaming reader.
fn main_stream(
    file: File,
    len: u64,
    skip_damaged: bool,
    parallel: bool,
) -> io::Result<(Stream, Arc<AtomicU64>, Option<File>)> {
    let spare = parallel.then(|| file.try_clone().ok()).flatten();
    if let Some(spare) = spare {
        let consumed = Arc::new(AtomicU64::new(0));
        let workers = chunks::workers();
        if let Some(chunked) = chunks::Chunked::new(spare, len, Arc::clone(&consumed), workers) {
            return Ok((records::Stream::chunked(chunked), consumed, Some(file)));
        }
    }
    let (stream, consumed) = stream(file, len, skip_damaged)?;
    Ok((stream, consumed, None))
}

/// The file's summary as the `mcap` crate reads it (chunk indexes and statistics, which `calib
/// apply` copies the compression from), found by seeking to its footer; `None` if it has none or
/// it is damaged (as in a truncated file). Reading samples uses [`records::read_summary`].
pub(crate) fn read_summary(file: &mut File, len: u64) -> Option<mcap::Summary> {
    let options = SummaryReaderOptions::default()
        .with_file_size(len)
        .with_record_length_limit(crate::limits::mcap_record_limit(len));
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
    /// Joint positions by joint name: JointState (CDR or ROS 1) or DynamicJointState.
    JointState(JointFormat),
    Json,
    /// A `std_msgs` scalar (CDR): one channel, named after the topic.
    Scalar(Scalar),
    /// Numeric fields named by path (`TOPIC.field.path`), read through the message definition
    /// (see [`super::msgdef`]); added by [`Registry::read_fields`], never met by type.
    Field,
}

impl Encoding {
    pub(crate) fn of(channel: &mcap::Channel) -> Option<Self> {
        let schema = channel.schema.as_ref().map_or("", |s| s.name.as_str());
        Self::from_names(&channel.message_encoding, schema)
    }

    /// The encoding of a channel with this message encoding and schema name, if calib reads it.
    pub(crate) fn from_names(message_encoding: &str, schema: &str) -> Option<Self> {
        let joint_state = schema == JOINT_STATE_SCHEMA || schema == "sensor_msgs/JointState";
        match message_encoding {
            // ROS 1 style names appear in bags converted with older tools.
            "cdr" if joint_state => Some(Encoding::JointState(JointFormat::Cdr)),
            // `mcap convert` of a ROS 1 bag.
            "ros1" if joint_state => Some(Encoding::JointState(JointFormat::Ros1)),
            "cdr"
                if schema == DYNAMIC_JOINT_STATE_SCHEMA
                    || schema == "control_msgs/DynamicJointState" =>
            {
                Some(Encoding::JointState(JointFormat::Dynamic))
            }
            "json" => Some(Encoding::Json),
            "cdr" => Scalar::of_type(schema).map(Encoding::Scalar),
            _ => None,
        }
    }
}

pub(crate) struct Topic {
    pub(crate) name: String,
    pub(crate) schema: String,
    pub(crate) message_encoding: String,
    pub(crate) encoding: Encoding,
    /// JointState: the `name` block of the first message, compared byte for byte with later ones.
    name_block: Vec<u8>,
    /// The channel names: joint names or JSON fields.
    pub(crate) names: Vec<String>,
    /// Index of the topic's first channel among the file's.
    pub(crate) offset: usize,
    /// JointState: whether messages carry different joint sets.
    pub(crate) subset: bool,
    /// JointState: name blocks other than the first message's, with the channel of each name
    /// ([`NO_POSITION`] for a joint that has no channel).
    layouts: Vec<(Vec<u8>, Vec<usize>)>,
    /// DynamicJointState: joints met without a `position` interface, which are not channels.
    no_position: Vec<String>,
    /// Radians per unit of a JSON, scalar or field value.
    scale: f64,
    /// Field paths: the walk that reads them.
    plan: Option<Box<Plan>>,
    /// JSON: which channels a message has given, reused between messages.
    seen: Vec<bool>,
    pub(crate) stats: TopicStats,
}

#[derive(Debug, Clone, Copy)]
enum Slot {
    Unknown,
    Ignored(usize),
    Topic(usize),
}

/// Channel IDs resolved to topics.
#[derive(Default)]
pub(crate) struct Registry {
    /// Indexed by channel ID: a vector lookup per message instead of hashing the topic.
    slots: Vec<Slot>,
    pub(crate) topics: Vec<Topic>,
    pub(crate) ignored: Vec<IgnoredTopic>,
    pub(crate) ignored_stats: Vec<TopicStats>,
    /// The schema encoding and text of each skipped topic, for field paths.
    definitions: Vec<Option<(String, Vec<u8>)>>,
    /// The index of each topic read by name.
    topic_by_name: std::collections::HashMap<String, usize>,
    /// Whether each skipped topic's definition came from the data section.
    from_data: Vec<bool>,
    /// The index of each skipped topic by name: a lookup that does not grow with their number.
    ignored_by_name: std::collections::HashMap<String, usize>,
}

/// What a channel ID resolves to when first seen.
pub(crate) enum Resolved {
    Topic(usize),
    Ignored(usize),
    NewTopic(Encoding),
}

impl Registry {
    /// Every topic: those read with their channels (by the names in `names`), then those
    /// skipped. Message counts and rates are of the messages counted so far.
    pub(crate) fn topic_infos(&self, names: &[ChannelName]) -> Vec<TopicInfo> {
        let read = self.topics.iter().map(|t| TopicInfo {
            topic: t.name.clone(),
            schema: t.schema.clone(),
            message_encoding: t.message_encoding.clone(),
            messages: t.stats.messages,
            rate_hz: t.stats.rate_hz(),
            channels: names[t.offset..t.offset + t.names.len()]
                .iter()
                .map(|n| n.display.clone())
                .collect(),
        });
        let skipped = self
            .ignored
            .iter()
            .zip(&self.ignored_stats)
            .map(|(t, stats)| TopicInfo {
                topic: t.topic.clone(),
                schema: t.schema.clone(),
                message_encoding: t.message_encoding.clone(),
                messages: stats.messages,
                rate_hz: stats.rate_hz(),
                channels: Vec::new(),
            });
        read.chain(skipped).collect()
    }

    pub(crate) fn resolve(&mut self, channel: &mcap::Channel) -> Result<Resolved, String> {
        let id = usize::from(channel.id);
        if let Some(slot) = self.slots.get(id) {
            match slot {
                Slot::Topic(k) => return Ok(Resolved::Topic(*k)),
                Slot::Ignored(k) => return Ok(Resolved::Ignored(*k)),
                Slot::Unknown => {}
            }
        }
        if self.topics.len() + self.ignored.len() >= crate::limits::MAX_TOPICS {
            return Err(too_many_topics());
        }
        if self.slots.len() <= id {
            self.slots.resize(id + 1, Slot::Unknown);
        }
        let Some(encoding) = Encoding::of(channel) else {
            // A topic whose fields are read by path: first met after they were added.
            if let Some(k) = self
                .topic_by_name
                .get(&channel.topic)
                .copied()
                .filter(|&k| self.topics[k].encoding == Encoding::Field)
            {
                self.slots[id] = Slot::Topic(k);
                return Ok(Resolved::Topic(k));
            }
            let k = self.ignore(channel);
            self.slots[id] = Slot::Ignored(k);
            return Ok(Resolved::Ignored(k));
        };
        match self.topic_by_name.get(&channel.topic).copied() {
            Some(k) if self.topics[k].encoding == encoding => {
                self.slots[id] = Slot::Topic(k);
                Ok(Resolved::Topic(k))
            }
            Some(_) => Err(format!(
                "topic `{}` carries both JointState and JSON messages; calib cannot tell which \
                 to read: re-record or filter the topic to one message type",
                channel.topic
            )),
            None => Ok(Resolved::NewTopic(encoding)),
        }
    }

    /// Adds a topic read (from its first message).
    pub(crate) fn add_topic(&mut self, topic: Topic) {
        self.topic_by_name
            .insert(topic.name.clone(), self.topics.len());
        self.topics.push(topic);
    }

    /// Takes the message definition of skipped topic `k` from `channel` as the data section
    /// holds it, once: the summary's copy, which the summary's CRC may not cover, is replaced by
    /// the one the messages were written with.
    pub(crate) fn adopt_definition(&mut self, k: usize, channel: &mcap::Channel) {
        if self.from_data[k] {
            return;
        }
        self.from_data[k] = true;
        self.definitions[k] = channel
            .schema
            .as_ref()
            .map(|s| (s.encoding.clone(), s.data.to_vec()));
    }

    /// Lists a topic calib does not read; its index in the list.
    fn ignore(&mut self, channel: &mcap::Channel) -> usize {
        if let Some(&k) = self.ignored_by_name.get(&channel.topic) {
            return k;
        }
        self.ignored_by_name
            .insert(channel.topic.clone(), self.ignored.len());
        self.from_data.push(false);
        self.ignored.push(IgnoredTopic {
            topic: channel.topic.clone(),
            schema: schema_name(channel),
            message_encoding: channel.message_encoding.clone(),
        });
        self.ignored_stats.push(TopicStats::default());
        self.definitions.push(
            channel
                .schema
                .as_ref()
                .map(|s| (s.encoding.clone(), s.data.to_vec())),
        );
        self.ignored.len() - 1
    }

    /// Reads the names among `wanted` of the form `TOPIC.field.path` whose `TOPIC` is a topic
    /// calib skips otherwise (see [`read_fields`](Self::read_fields)); other names are left
    /// for [`crate::naming::resolve`] to judge. The error names the topic.
    pub(crate) fn read_wanted_fields(
        &mut self,
        wanted: &[String],
        scale: f64,
    ) -> Result<(), (String, String)> {
        let mut by_topic: Vec<(&str, Vec<String>)> = Vec::new();
        for name in wanted {
            let Some((topic, path)) = name.split_once('.') else {
                continue;
            };
            if path.is_empty() || !self.ignored.iter().any(|t| t.topic == topic) {
                continue;
            }
            match by_topic.iter_mut().find(|(t, _)| *t == topic) {
                Some((_, names)) if names.contains(name) => {}
                Some((_, names)) => names.push(name.clone()),
                None => by_topic.push((topic, vec![name.clone()])),
            }
        }
        for (topic, names) in by_topic {
            self.read_fields(topic, &names, scale)
                .map_err(|m| (topic.to_string(), m))?;
        }
        Ok(())
    }

    /// Reads the numeric fields `names` (`TOPIC.field.path`, all of topic `topic`, which calib
    /// skips otherwise) through the message definition the file carries for it: the topic moves
    /// from the skipped ones to those read. The error says why the topic or a path cannot be
    /// read.
    fn read_fields(&mut self, topic: &str, names: &[String], scale: f64) -> Result<(), String> {
        let Some(k) = self.ignored.iter().position(|t| t.topic == topic) else {
            return Err("the file has no such topic".into());
        };
        let skipped = &self.ignored[k];
        let text = match &self.definitions[k] {
            Some((encoding, text))
                if encoding == "ros2msg" && skipped.message_encoding == "cdr" =>
            {
                text
            }
            other => {
                return Err(format!(
                    "its messages are `{}` with a schema of encoding `{}`; calib reads fields \
                     by path only from CDR messages whose file carries their `ros2msg` message \
                     definition (as rosbag2 writes MCAP)",
                    skipped.message_encoding,
                    other.as_ref().map_or("none", |(e, _)| e.as_str())
                ));
            }
        };
        let text = std::str::from_utf8(text)
            .map_err(|_| "its message definition is not UTF-8 text".to_string())?;
        let definition = Definition::parse(&skipped.schema, text).map_err(|e| {
            format!(
                "its message definition ({}) does not parse: {e}; the recording's schema \
                 record is damaged or not a ros2msg text",
                skipped.schema
            )
        })?;
        let paths: Vec<String> = names
            .iter()
            .map(|n| n[topic.len() + 1..].to_string())
            .collect();
        let plan = definition.plan(&paths)?;
        let skipped = self.ignored.remove(k);
        self.ignored_stats.remove(k);
        self.definitions.remove(k);
        self.from_data.remove(k);
        self.ignored_by_name.remove(&skipped.topic);
        for j in self.ignored_by_name.values_mut() {
            if *j > k {
                *j -= 1;
            }
        }
        let new = self.topics.len();
        for slot in &mut self.slots {
            match *slot {
                Slot::Ignored(j) if j == k => *slot = Slot::Topic(new),
                Slot::Ignored(j) if j > k => *slot = Slot::Ignored(j - 1),
                _ => {}
            }
        }
        self.add_topic(Topic {
            name: skipped.topic,
            schema: skipped.schema,
            message_encoding: skipped.message_encoding,
            encoding: Encoding::Field,
            name_block: Vec::new(),
            names: names.to_vec(),
            offset: 0,
            subset: false,
            layouts: Vec::new(),
            no_position: Vec::new(),
            scale,
            plan: Some(Box::new(plan)),
            seen: Vec::new(),
            stats: TopicStats::default(),
        });
        Ok(())
    }
}

/// The error for a file with more than [`MAX_TOPICS`](crate::limits::MAX_TOPICS) topics.
pub(crate) fn too_many_topics() -> String {
    format!(
        "the file has more than {} topics, more than calib reads; record the encoders' topics \
         alone, or filter the file (`mcap filter`, `ros2 bag convert`)",
        crate::limits::MAX_TOPICS
    )
}

fn schema_name(channel: &mcap::Channel) -> String {
    channel
        .schema
        .as_ref()
        .map_or_else(String::new, |s| s.name.clone())
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
pub(crate) fn seconds(ns: i64) -> f64 {
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
        Self::open_with(path, opts, PARALLEL_CHUNKS)
    }

    /// [`open`](Self::open), reading the chunks on worker threads where the summary lists at
    /// least `parallel_chunks` of them.
    pub(crate) fn open_with(
        path: &Path,
        opts: &ReadOptions,
        parallel_chunks: usize,
    ) -> Result<Self, Error> {
        let io = |source| Error::Io {
            path: path.to_path_buf(),
            source,
        };
        let (mut file, len) = open_mcap(path)?;
        let mut registry = Registry::default();
        // No summary, or a truncated file (whose summary cannot be read): scan it all.
        let summary = records::read_summary(&mut file, len);
        if summary
            .as_ref()
            .is_some_and(|s| s.channels.len() > crate::limits::MAX_TOPICS)
        {
            return Err(mcap_error(path, None, None, too_many_topics()));
        }
        let parallel = summary
            .as_ref()
            .is_some_and(|s| s.chunks >= parallel_chunks);
        let expected = summary.and_then(|summary| expected_topics(&summary, &mut registry));
        let scale = opts.unit.unwrap_or(AngleUnit::Deg).radians_per_unit();
        let mut peek = Peek::default();
        let field_topics = field_topics(&opts.fields);
        // Topics read by field path take their definitions from the data section: peek for
        // them even where the summary lists no topic calib reads otherwise.
        if expected.as_ref().is_none_or(|e| !e.is_empty()) || !field_topics.is_empty() {
            let (stream, _) = stream(file, len, opts.skip_damaged).map_err(io)?;
            file = peek.learn_topics(
                path,
                stream,
                expected.as_deref(),
                &field_topics,
                &mut registry,
                scale,
            )?;
        }
        registry
            .read_wanted_fields(&opts.fields, scale)
            .map_err(|(topic, m)| mcap_error(path, None, Some(&topic), m))?;
        if registry.topics.is_empty() {
            return Err(no_topic_error(path, len, peek, &registry));
        }
        let (names, all_channels) = lay_out_channels(&mut registry, opts);
        let (stream, consumed, reopen) =
            main_stream(file, len, opts.skip_damaged, parallel).map_err(io)?;
        let width = all_channels.len();
        let mut reader = McapReader {
            path: path.to_path_buf(),
            stream: Box::new(stream),
            consumed,
            consumed_at_last: 0,
            len,
            registry,
            channels: Vec::new(),
            all_channels,
            names,
            time: opts.time,
            aligner: Aligner::new(vec![0], AlignOptions::default()),
            fast: false,
            pick: None,
            fast_samples: 0,
            raw: vec![f64::NAN; width],
            index: 0,
            diagnostics: ReadDiagnostics::default(),
            done: false,
            failed: false,
            reopen,
            skip_damaged: opts.skip_damaged,
            skip: 0,
            clock: 0,
            order: StampOrder::default(),
            allow_unordered_time: opts.allow_unordered_time,
        };
        let all: Vec<usize> = (0..width).collect();
        reader.select(&all, AlignOptions::default());
        Ok(reader)
    }

    /// The channels, in the order of each sample's values: those [selected](Self::select), by
    /// default every channel of the file (topics in the order of their first message, then the
    /// joints or fields within a topic).
    pub fn channels(&self) -> &[Channel] {
        &self.channels
    }

    /// The names of every channel of the file (not only the selected ones), in raw order: the
    /// indices [`select`](Self::select) takes.
    pub fn names(&self) -> &[ChannelName] {
        &self.names
    }

    /// Reads only `channels` (indices into [`names`](Self::names)), in this order, aligned on the
    /// first one's stamps as [`crate::align`] describes. Call it before reading any sample.
    pub fn select(&mut self, channels: &[usize], opts: AlignOptions) {
        let width = self.all_channels.len();
        let distinct = channels
            .iter()
            .enumerate()
            .all(|(k, c)| *c < width && !channels[..k].contains(c));
        self.fast = self.registry.topics.len() == 1 && !self.registry.topics[0].subset && distinct;
        self.pick = (!channels.iter().copied().eq(0..width)).then(|| channels.to_vec());
        self.aligner = Aligner::new(channels.to_vec(), opts);
        self.clock = channels.first().copied().unwrap_or(0);
        self.channels = channels
            .iter()
            .map(|&i| self.all_channels[i].clone())
            .collect();
    }

    /// How the selected channels were aligned on the first one's clock (complete once iteration
    /// has ended).
    pub fn alignment(&self) -> Alignment {
        let mut alignment = self.aligner.report(&self.all_names());
        alignment.clock_samples += self.fast_samples;
        alignment.samples += self.fast_samples;
        for c in &mut alignment.channels {
            c.exact += self.fast_samples;
        }
        alignment
    }

    fn all_names(&self) -> Vec<String> {
        self.names.iter().map(|n| n.display.clone()).collect()
    }

    /// Every topic of the file: those read with their channels, then those skipped. Message counts
    /// and rates are of the messages read so far (all of them once iteration has ended).
    pub fn topics(&self) -> Vec<TopicInfo> {
        self.registry.topic_infos(&self.names)
    }

    /// What the reader noticed so far: where a truncated file broke off (once iteration has
    /// ended).
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
            Ok(Resolved::Topic(k)) => k,
            Ok(Resolved::Ignored(k)) => {
                self.registry.ignored_stats[k].note(message.log_time);
                return Ok(None);
            }
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
        let topic = &mut self.registry.topics[k];
        topic.stats.note(message.log_time);
        if self.fast {
            // With a selection, every joint into the scratch row and the selected ones into the
            // sample; with every channel in order, straight into the sample.
            let (stamp, full, values) = match &self.pick {
                Some(pick) => {
                    self.raw.fill(f64::NAN);
                    let (stamp, full) = decode(topic, message, self.time, &mut self.raw)
                        .map_err(|(c, m)| fail(&c.unwrap_or_else(|| topic.name.clone()), m))?;
                    (stamp, full, pick.iter().map(|&i| self.raw[i]).collect())
                }
                None => {
                    let mut values = vec![f64::NAN; topic.names.len()];
                    let (stamp, full) = decode(topic, message, self.time, &mut values)
                        .map_err(|(c, m)| fail(&c.unwrap_or_else(|| topic.name.clone()), m))?;
                    (stamp, full, values)
                }
            };
            if values
                .get(self.clock_in_sample())
                .is_some_and(|v| !v.is_nan())
            {
                self.check_stamp(stamp, index)?;
            }
            if full {
                self.fast_samples += 1;
                return Ok(Some(Sample {
                    t: seconds(stamp),
                    values,
                    session: None,
                }));
            }
            // A message with a subset of the joints: from here on, through the aligner (which
            // is empty, so the order of samples is kept), which takes the whole row.
            self.fast = false;
            if self.pick.is_none() {
                self.raw.copy_from_slice(&values);
            }
            self.aligner.push(stamp, seconds(stamp), &self.raw, None);
            return Ok(self.aligner.pop());
        }
        let range = topic.offset..topic.offset + topic.names.len();
        self.raw.fill(f64::NAN);
        let (stamp, _) = decode(topic, message, self.time, &mut self.raw[range])
            .map_err(|(c, m)| fail(&c.unwrap_or_else(|| topic.name.clone()), m))?;
        if !self.raw[self.clock].is_nan() {
            self.check_stamp(stamp, index)?;
        }
        self.aligner.push(stamp, seconds(stamp), &self.raw, None);
        Ok(self.aligner.pop())
    }

    /// Where the clock channel sits in the fast path's values: first of a selection, else at
    /// its raw index.
    fn clock_in_sample(&self) -> usize {
        if self.pick.is_some() { 0 } else { self.clock }
    }

    /// Refuses a clock stamp that does not increase (see [`crate::stamps`]), unless told to
    /// pass it on.
    fn check_stamp(&mut self, stamp: i64, index: u64) -> Result<(), Error> {
        if self.allow_unordered_time {
            return Ok(());
        }
        let message = i64::try_from(index).unwrap_or(i64::MAX);
        self.order.check(stamp, message).map_err(|b| {
            let topic = self
                .registry
                .topics
                .iter()
                .find(|t| (t.offset..t.offset + t.names.len()).contains(&self.clock));
            mcap_error(
                &self.path,
                Some(index),
                topic.map(|t| t.name.as_str()),
                b.describe(&self.names[self.clock].display, "message", self.time),
            )
        })
    }

    /// Hands reading over from the chunks read in parallel to the streaming reader, from the
    /// start of the file, which skips the messages handed on already (see [`super::chunks`]).
    fn take_over(&mut self) -> Result<(), Error> {
        let io = |source| Error::Io {
            path: self.path.clone(),
            source,
        };
        let file = match self.reopen.take() {
            Some(file) => file,
            None => File::open(&self.path).map_err(io)?,
        };
        let (stream, consumed) = stream(file, self.len, self.skip_damaged).map_err(io)?;
        *self.stream = stream;
        self.consumed = consumed;
        self.skip = self.index;
        Ok(())
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

    /// The stream has ended: what the aligner holds can now be decided, and the damaged chunks
    /// left out are listed.
    fn finish(&mut self) {
        self.done = true;
        self.diagnostics.damaged_chunks = self.stream.damaged().to_vec();
        self.aligner.finish();
    }
}

impl Iterator for McapReader {
    type Item = Result<Sample, Error>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        loop {
            // The fast path leaves the aligner empty.
            if !self.fast
                && let Some(sample) = self.aligner.pop()
            {
                return Some(Ok(sample));
            }
            if self.done {
                return None;
            }
            let message = match self.stream.next() {
                Some(Ok(message)) => {
                    // Chunks are held until checked: where this message's bytes ended is where
                    // the reader was when it gave the message, not where the check got to.
                    self.consumed_at_last = self.stream.consumed_at_last();
                    if self.skip > 0 {
                        self.skip -= 1;
                        continue;
                    }
                    message
                }
                Some(Err(StreamError::Fallback)) => {
                    if let Err(e) = self.take_over() {
                        self.finish();
                        self.failed = true;
                        return Some(Err(e));
                    }
                    continue;
                }
                None => {
                    self.finish();
                    // The stream stops at the data end record, before the end of the file. It
                    // also ends cleanly when the file ends between two records (it is told to
                    // expect no end magic): then the data end record is missing.
                    if self.consumed.load(Ordering::Relaxed) >= self.len {
                        self.note_truncation();
                    }
                    continue;
                }
                Some(Err(e)) => {
                    self.finish();
                    // Reading stopped at the first incomplete record, or inside it (a cut chunk)
                    // where the last message came out.
                    if matches!(e, StreamError::Mcap(McapError::UnexpectedEof))
                        && self.note_truncation()
                    {
                        continue;
                    }
                    self.failed = true;
                    if matches!(e, StreamError::Damaged(_) | StreamError::DataCrc) {
                        return Some(Err(damaged_error(&self.path, self.index, &e)));
                    }
                    return Some(Err(mcap_error(
                        &self.path,
                        Some(self.index),
                        None,
                        format!(
                            "the file is damaged here ({e}); the messages before it were \
                             read: recover the rest with `mcap recover`"
                        ),
                    )));
                }
            };
            let index = self.index;
            self.index += 1;
            let stepped = self.step(&message, index);
            self.stream.recycle(message);
            match stepped {
                Ok(Some(sample)) => return Some(Ok(sample)),
                Ok(None) => {}
                Err(e) => {
                    self.failed = true;
                    return Some(Err(e));
                }
            }
        }
    }
}

/// Opens `path` and checks that it is an MCAP file: not empty, and starting with the magic.
/// Returns the file and its length.
fn open_mcap(path: &Path) -> Result<(File, u64), Error> {
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
    Ok((file, len))
}

/// What reading the first messages of a log found besides its topics.
#[derive(Default)]
struct Peek {
    /// Messages read.
    messages: u64,
    /// The error that ended the reading, at that message's index.
    damage: Option<(u64, StreamError)>,
    /// Damaged chunks skipped (`--skip-damaged`).
    skipped: Vec<DamagedChunk>,
}

impl Peek {
    /// Reads messages until every expected topic has shown itself and [`PEEK_WINDOW`] more
    /// messages have passed (all of them while a topic's messages carry subsets of its joints,
    /// or when the file has no summary to say which topics to expect), learning each topic
    /// from its first message. Returns the file, to be read again from its start.
    fn learn_topics(
        &mut self,
        path: &Path,
        mut peek: Stream,
        expected: Option<&[String]>,
        field_topics: &[&str],
        registry: &mut Registry,
        scale: f64,
    ) -> Result<File, Error> {
        // Messages since every expected topic showed itself.
        let mut after_all: Option<u64> = None;
        // Expected topics not met yet, counted down as each first message comes: a check per
        // message that does not grow with the number of topics.
        let mut unmet: std::collections::HashSet<&str> = expected
            .unwrap_or_default()
            .iter()
            .map(String::as_str)
            .collect();
        // Topics whose fields are read by path, until their definition from the data section
        // has been met.
        let mut unmet_fields: Vec<&str> = field_topics
            .iter()
            .copied()
            .filter(|t| expected.is_none() || registry.ignored_by_name.contains_key(*t))
            .collect();
        // Whether a topic's messages carry different joint sets (then every message is read).
        let mut subset = false;
        for (index, message) in (&mut peek).enumerate() {
            // Errors here are reported by the iteration, at the same message, unless no
            // usable topic comes before them.
            let message = match message {
                Ok(message) => message,
                Err(e) => {
                    self.damage = Some((index as u64, e));
                    break;
                }
            };
            self.messages += 1;
            let index = index as u64;
            let fail = |m| mcap_error(path, Some(index), Some(&message.channel.topic), m);
            match registry.resolve(&message.channel).map_err(fail)? {
                Resolved::NewTopic(encoding) => {
                    let topic = first_message(&message, encoding, scale).map_err(fail)?;
                    unmet.remove(topic.name.as_str());
                    registry.add_topic(topic);
                    // Resolve again to record the channel ID's slot.
                    registry.resolve(&message.channel).map_err(fail)?;
                }
                // A bad message is reported by the iteration, at the same message.
                Resolved::Topic(k) => {
                    let _ = registry.topics[k].learn(&message);
                    subset |= registry.topics[k].subset;
                }
                Resolved::Ignored(k) => {
                    registry.adopt_definition(k, &message.channel);
                    unmet_fields.retain(|t| *t != message.channel.topic);
                }
            }
            if let Some(n) = &mut after_all {
                *n += 1;
            } else if expected.is_some() && unmet.is_empty() {
                after_all = Some(0);
            }
            if after_all.is_some_and(|n| n >= PEEK_WINDOW) && unmet_fields.is_empty() && !subset {
                break;
            }
        }
        self.skipped = peek.damaged().to_vec();
        match peek.into_inner() {
            Some(source) => Ok(source.file.into_inner()),
            None => File::open(path).map_err(|source| Error::Io {
                path: path.to_path_buf(),
                source,
            }),
        }
    }
}

/// Why a log of `len` bytes yields no channel: every usable message is in a skipped damaged
/// chunk, the file is damaged or cut before its first usable message, it is empty, or none of
/// its topics holds a type calib reads.
fn no_topic_error(path: &Path, len: u64, peek: Peek, registry: &Registry) -> Error {
    if !peek.skipped.is_empty() {
        let list: Vec<String> = peek.skipped.iter().map(|c| c.to_string()).collect();
        return mcap_error(
            path,
            None,
            None,
            format!(
                "no JointState or JSON message is left once the damaged chunks are \
                 skipped (--skip-damaged): {}; repair the file or record again",
                list.join("; ")
            ),
        );
    }
    if let Some((index, e)) = peek.damage {
        if let StreamError::Damaged(_) = e {
            return damaged_error(path, index, &e);
        }
        if !matches!(e, StreamError::Mcap(McapError::UnexpectedEof)) {
            return mcap_error(
                path,
                Some(index),
                None,
                format!(
                    "the file is damaged here ({e}) before any JointState or JSON \
                     message; recover what is left with `mcap recover`"
                ),
            );
        }
    }
    // A file cut before its first usable message is cut, whatever else it holds: say so
    // rather than that it holds no samples.
    if let Some(at) = find_break(path) {
        return mcap_error(
            path,
            None,
            None,
            format!(
                "the file is cut short at byte {at} of {len}, before its first JointState \
                 or JSON message (a recording that stopped early, or a partial copy); \
                 copy the file again or record again"
            ),
        );
    }
    if peek.messages == 0 && registry.ignored.is_empty() {
        return Error::Empty {
            path: path.to_path_buf(),
        };
    }
    let found: Vec<String> = registry
        .ignored
        .iter()
        .map(|t| format!("{} ({}, {})", t.topic, t.schema, t.message_encoding))
        .collect();
    mcap_error(
        path,
        None,
        None,
        format!(
            "no topic holds {JOINT_STATE_SCHEMA} (cdr), std_msgs scalar (cdr) or JSON \
             messages (found: {}); record the encoders as JointState or JSON",
            if found.is_empty() {
                "no topics".to_string()
            } else {
                found.join(", ")
            }
        ),
    )
}

/// Places each topic's joints in a sample's values, one after the other in the order the
/// topics were found, and names them; returns the names and the channels with their units.
/// The bag reader lays out its topics the same way.
pub(crate) fn lay_out_channels(
    registry: &mut Registry,
    opts: &ReadOptions,
) -> (Vec<ChannelName>, Vec<Channel>) {
    let mut offset = 0;
    for topic in &mut registry.topics {
        topic.offset = offset;
        offset += topic.names.len();
    }
    let names = names_of(registry.topics.iter().flat_map(Topic::channel_names));
    let mut all_channels: Vec<Channel> = Vec::with_capacity(names.len());
    for topic in &registry.topics {
        let unit = match topic.encoding {
            Encoding::JointState(_) => AngleUnit::Rad,
            Encoding::Json | Encoding::Scalar(_) | Encoding::Field => {
                opts.unit.unwrap_or(AngleUnit::Deg)
            }
        };
        for _ in &topic.names {
            all_channels.push(Channel {
                name: names[all_channels.len()].display.clone(),
                unit,
            });
        }
    }
    (names, all_channels)
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

/// The topics calib reads that the summary lists with messages, to be met by the peek pass;
/// `None` if the summary lists such topics but claims none of them holds a message (a damaged or
/// wrongly written statistics record must not hide an intact log: the file is then scanned as if
/// it had no summary). Topics calib skips are listed in `registry`.
fn expected_topics(summary: &records::Summary, registry: &mut Registry) -> Option<Vec<String>> {
    let mut channels: Vec<_> = summary.channels.values().collect();
    channels.sort_by_key(|c| c.id);
    let mut topics = Vec::new();
    let mut seen = std::collections::HashSet::new();
    let mut claimed_empty = false;
    for channel in channels {
        let has_messages = summary
            .message_counts
            .as_ref()
            .and_then(|counts| counts.get(&channel.id))
            .is_none_or(|&n| n > 0);
        let readable = Encoding::of(channel).is_some();
        if !has_messages {
            claimed_empty |= readable;
            continue;
        }
        if !readable {
            registry.ignore(channel);
        } else if seen.insert(channel.topic.as_str()) {
            topics.push(channel.topic.clone());
        }
    }
    (!topics.is_empty() || !claimed_empty).then_some(topics)
}

/// The topics of the `TOPIC.field.path` names among `fields` (split at the first `.`, as
/// [`Registry::read_wanted_fields`] splits them), whose definitions the peek pass takes from the
/// data section.
fn field_topics(fields: &[String]) -> Vec<&str> {
    let mut topics = Vec::new();
    for name in fields {
        if let Some((topic, path)) = name.split_once('.')
            && !path.is_empty()
            && !topics.contains(&topic)
        {
            topics.push(topic);
        }
    }
    topics
}

/// The layout entry of a DynamicJointState joint without a `position` interface: no channel.
const NO_POSITION: usize = usize::MAX;

/// A topic's channels from its first message.
pub(crate) fn first_message(
    message: &mcap::Message,
    encoding: Encoding,
    scale: f64,
) -> Result<Topic, String> {
    let mut topic = Topic {
        name: message.channel.topic.clone(),
        schema: schema_name(&message.channel),
        message_encoding: message.channel.message_encoding.clone(),
        encoding,
        name_block: Vec::new(),
        names: Vec::new(),
        offset: 0,
        subset: false,
        layouts: Vec::new(),
        no_position: Vec::new(),
        plan: None,
        scale,
        seen: Vec::new(),
        stats: TopicStats::default(),
    };
    match encoding {
        Encoding::JointState(format) => {
            let js = JointState::parse_as(&message.data, format).map_err(|e| e.to_string())?;
            for (name, position) in js.names().zip(js.positions()) {
                let name = name.map_err(|e| e.to_string())?;
                if topic
                    .names
                    .iter()
                    .chain(&topic.no_position)
                    .any(|n| n == name)
                {
                    return Err(repeated_joint(name));
                }
                if format == JointFormat::Dynamic && position.is_nan() {
                    topic.no_position.push(name.to_string());
                } else {
                    topic.names.push(name.to_string());
                }
            }
            // The fast path takes the message's joints as the channels in order; with joints
            // left out, every message goes through its layout.
            if topic.no_position.is_empty() {
                topic.name_block = js.name_block.to_vec();
            }
        }
        Encoding::Json => {
            let mut fields = 0;
            json::for_each_field(&message.data, |key, value| {
                fields += 1;
                if fields > crate::limits::MAX_JSON_FIELDS {
                    return Err(format!(
                        "the topic's first JSON message has more than {} fields, more than \
                         calib reads in one message; publish one numeric field per encoder",
                        crate::limits::MAX_JSON_FIELDS
                    ));
                }
                if value.is_some() {
                    topic.names.push(key.to_string());
                }
                Ok(())
            })?;
            topic.seen = vec![false; topic.names.len()];
        }
        Encoding::Scalar(kind) => {
            kind.decode(&message.data).map_err(|e| e.to_string())?;
            topic.names.push(topic.name.clone());
        }
        // Added by name ([`Registry::read_fields`]), not from a first message.
        Encoding::Field => {}
    }
    if topic.names.is_empty() {
        return Err(match encoding {
            Encoding::JointState(JointFormat::Dynamic) => "the topic's first DynamicJointState \
                                                           message has no joint with a \
                                                           `position` interface"
                .into(),
            Encoding::JointState(_) => "the topic's first JointState message names no joints; \
                                     publish the encoders' names and positions"
                .into(),
            Encoding::Json | Encoding::Scalar(_) | Encoding::Field => {
                "the topic's first JSON message has no \
                                                     numeric field; publish one numeric field \
                                                     per encoder"
                    .into()
            }
        });
    }
    Ok(topic)
}

fn repeated_joint(name: &str) -> String {
    format!(
        "joint `{name}` appears twice in one message; a message can hold one position per \
         joint: fix the publisher"
    )
}

impl Topic {
    /// `(topic, name)` of each channel, as [`names_of`] takes them: a scalar topic's one
    /// channel is the topic itself.
    pub(crate) fn channel_names(&self) -> impl Iterator<Item = (Option<&str>, &str)> {
        let topic = match self.encoding {
            // Named in full: the topic itself, or `TOPIC.field.path`.
            Encoding::Scalar(_) | Encoding::Field => None,
            _ => Some(self.name.as_str()),
        };
        self.names.iter().map(move |n| (topic, n.as_str()))
    }

    /// Adds the joints of a later message the topic's first did not name (peek pass).
    pub(crate) fn learn(&mut self, message: &mcap::Message) -> Result<(), String> {
        let Encoding::JointState(format) = self.encoding else {
            return Ok(());
        };
        let js = JointState::parse_as(&message.data, format).map_err(|e| e.to_string())?;
        if js.name_block == self.name_block.as_slice() {
            return Ok(());
        }
        if format == JointFormat::Dynamic {
            // Joints without a `position` interface are not channels; a joint with one that the
            // first message lacked is a channel of its own series.
            for (name, position) in js.names().zip(js.positions()) {
                let name = name.map_err(|e| e.to_string())?;
                let known = self.names.iter().any(|n| n == name);
                if position.is_nan() {
                    if !known && !self.no_position.iter().any(|n| n == name) {
                        self.no_position.push(name.to_string());
                    }
                } else if !known {
                    self.names.push(name.to_string());
                    self.subset = true;
                }
            }
            return Ok(());
        }
        let mut names = Vec::with_capacity(js.name_count);
        for name in js.names() {
            let name = name.map_err(|e| e.to_string())?;
            if names.contains(&name) {
                return Err(repeated_joint(name));
            }
            names.push(name);
        }
        if names.len() == self.names.len() && names.iter().zip(&self.names).all(|(a, b)| a == b) {
            // The same names, serialized with other padding.
            return Ok(());
        }
        self.subset = true;
        for name in names {
            if !self.names.iter().any(|n| n == name) {
                self.names.push(name.to_string());
            }
        }
        Ok(())
    }

    /// The channel (within the topic) of each joint of `js`, whose name block differs from the
    /// first message's.
    fn layout(&mut self, js: &JointState) -> Result<Vec<usize>, String> {
        if let Some((_, layout)) = self.layouts.iter().find(|(b, _)| b == js.name_block) {
            return Ok(layout.clone());
        }
        let mut layout = Vec::with_capacity(js.name_count);
        for name in js.names() {
            let name = name.map_err(|e| e.to_string())?;
            let Some(i) = self.names.iter().position(|n| n == name).or_else(|| {
                self.no_position
                    .iter()
                    .any(|n| n == name)
                    .then_some(NO_POSITION)
            }) else {
                return Err(format!(
                    "joint `{name}` is new: the topic's joints [{}] were gathered from its \
                     first messages when the file was opened; calib needs every joint to \
                     appear early: split the recording where the joint set changes",
                    crate::limits::listed(&self.names)
                ));
            };
            if i != NO_POSITION && layout.contains(&i) {
                return Err(repeated_joint(name));
            }
            layout.push(i);
        }
        if self.layouts.len() < LAYOUT_CACHE {
            self.layouts.push((js.name_block.to_vec(), layout.clone()));
        }
        Ok(layout)
    }
}

/// Decodes a message of `topic` into `out` (radians, one slot per channel of the topic, left
/// as they are for channels the message does not carry) and returns its stamp in nanoseconds
/// and whether it carried every channel in the topic's order. Errors carry the channel
/// concerned (if not the topic) and the message.
pub(crate) fn decode(
    topic: &mut Topic,
    message: &mcap::Message,
    time: TimeSource,
    out: &mut [f64],
) -> Result<(i64, bool), (Option<String>, String)> {
    match topic.encoding {
        Encoding::JointState(format) => {
            let js =
                JointState::parse_as(&message.data, format).map_err(|e| (None, e.to_string()))?;
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
            // Fast path: the same names serialize to the same bytes.
            let layout = if js.name_block == topic.name_block.as_slice() {
                None
            } else {
                Some(topic.layout(&js).map_err(|m| (None, m))?)
            };
            let names = &topic.names;
            let mut put = |i: usize, rad: f64| match crate::limits::reading_problem(
                crate::limits::Readable(rad),
                rad,
                rad,
            ) {
                Some(problem) => Err((Some(names[i].clone()), problem)),
                None => {
                    out[i] = rad;
                    Ok(())
                }
            };
            // A DynamicJointState joint without a `position` interface carries no reading.
            let dynamic = format == JointFormat::Dynamic;
            let mut missing = false;
            let mut put = |i: usize, rad: f64| {
                if dynamic && rad.is_nan() {
                    missing = true;
                    return Ok(());
                }
                put(i, rad)
            };
            let full = if let Some(layout) = layout {
                for (&i, rad) in layout.iter().zip(js.positions()) {
                    if i != NO_POSITION {
                        put(i, rad)?;
                    }
                }
                layout
                    .iter()
                    .copied()
                    .filter(|&i| i != NO_POSITION)
                    .eq(0..names.len())
            } else {
                for (i, rad) in js.positions().enumerate() {
                    put(i, rad)?;
                }
                js.name_count == names.len()
            };
            let full = full && !missing;
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
            let stamp = if time == TimeSource::Log || (js.sec == 0 && js.nanosec == 0) {
                log_time_ns(message.log_time).map_err(|m| (None, m))?
            } else {
                js.sec * 1_000_000_000 + i64::from(js.nanosec)
            };
            Ok((stamp, full))
        }
        Encoding::Scalar(kind) => {
            let stamp = log_time_ns(message.log_time).map_err(|m| (None, m))?;
            let v = kind
                .decode(&message.data)
                .map_err(|e| (None, e.to_string()))?;
            let rad = v * topic.scale;
            if let Some(problem) = crate::limits::reading_problem(v, v, rad) {
                return Err((None, problem));
            }
            out[0] = rad;
            Ok((stamp, true))
        }
        Encoding::Field => {
            let Some(plan) = topic.plan.as_deref() else {
                return Err((None, "the topic's fields were never named".into()));
            };
            let header = plan
                .read(&message.data, out)
                .map_err(|e| (None, e.to_string()))?;
            for (i, slot) in out.iter_mut().enumerate() {
                let v = *slot;
                let rad = v * topic.scale;
                if let Some(problem) = crate::limits::reading_problem(v, v, rad) {
                    return Err((Some(topic.names[i].clone()), problem));
                }
                *slot = rad;
            }
            let stamp = match header {
                Some((sec, nanosec))
                    if time == TimeSource::Header
                        && (sec, nanosec) != (0, 0)
                        && nanosec < 1_000_000_000 =>
                {
                    sec * 1_000_000_000 + i64::from(nanosec)
                }
                _ => log_time_ns(message.log_time).map_err(|m| (None, m))?,
            };
            Ok((stamp, true))
        }
        Encoding::Json => {
            let stamp = log_time_ns(message.log_time).map_err(|m| (None, m))?;
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
                        crate::limits::listed(names)
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
            Ok((stamp, true))
        }
    }
}
