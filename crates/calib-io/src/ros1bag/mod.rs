//! ROS 1 bags (format 2.0): what `rosbag record` writes, and what most public robot datasets
//! hold.
//!
//! A bag is one file: the line `#ROSBAG V2.0`, a bag header record (padded to 4096 bytes) giving
//! `index_pos`, `conn_count` and `chunk_count`, then the chunks, each followed by its index
//! data records, and at `index_pos` the index section: a connection record per connection
//! (topic, `type`, `md5sum`, the full `message_definition`), then a chunk info record per
//! chunk (its position, first and last message time, messages per connection). A chunk holds
//! connection and message data records, compressed whole with `bz2` or `lz4` (the LZ4 frame
//! format) or not at all; a message data record is a connection ID, the receive `time`, and the
//! message serialized in the ROS 1 wire format. (`docs/recordings.md` shows the layout.)
//!
//! # What calib reads
//! Each message becomes the [`mcap::Message`] `mcap convert` makes of it (channel message
//! encoding `ros1`, schema encoding `ros1msg`, schema name the connection's `type`, schema data
//! its `message_definition`, log time the record's `time`) and goes to the ROS 2 layer the MCAP
//! and rosbag2 readers hand their messages to (`calib_io::ros2`, private): `sensor_msgs/JointState`
//! and the `std_msgs` scalars are read, other topics listed and skipped, channels named and
//! aligned as for any recording.
//!
//! # Order and memory
//! The index gives the connections (so the topics are known before a message is read) and the
//! chunks. Messages are handed on in `time` order, as ROS 1's own readers give them: the chunks
//! are taken in order of their first message's time, a chunk's messages sorted by time (equal
//! times in their order in the chunk), and where chunks overlap in time their messages are
//! merged. One decompressed chunk is held at a time where chunks follow one another in time
//! (as `rosbag record` writes them), a few where they overlap, at most
//! [`MAX_ROS1_HELD_BYTES`](crate::limits::MAX_ROS1_HELD_BYTES); the file is never read whole.
//!
//! # No index, or cut short
//! A bag whose recording did not close has `index_pos` 0; a file cut short has its index
//! beyond its end. Either is read by scanning its records front to back first (every chunk
//! decompressed once to learn its connections and times), with a warning; a file cut inside a
//! chunk gives the records of that chunk before the cut, and the reader reports where the
//! file broke off ([`crate::Truncation`]).

mod chunks;
mod layout;
pub(crate) mod records;

use std::borrow::Cow;
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap, HashSet};
use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use calib_core::{AngleUnit, Channel, SampleBatch};

use self::layout::{Chunk, Failure as LayoutFailure, Layout, Loaded};
use crate::mcap_log::JOINT_STATE_SCHEMA;
use crate::naming::ChannelName;
use crate::progress::ReadProgress;
use crate::ros2::PEEK_WINDOW;
use crate::ros2::encoding::Encoding;
use crate::ros2::registry::{Registry, TopicInfo};
use crate::ros2::samples::{Failure, Ros2Reader, Samples};
use crate::{Error, ReadDiagnostics, ReadOptions, Truncation};

/// Read buffer of the file: large enough that a chunk costs few system calls.
const READ_BUFFER: usize = 256 * 1024;

/// An [`Error::Ros1Bag`].
fn bag_error(
    path: &Path,
    byte_offset: Option<u64>,
    message_index: Option<u64>,
    topic: Option<&str>,
    message: String,
) -> Error {
    Error::Ros1Bag {
        path: path.to_path_buf(),
        byte_offset,
        message_index,
        topic: topic.map(str::to_string),
        message,
    }
}

/// The error of reading the layout or a chunk.
fn layout_error(path: &Path, failure: LayoutFailure) -> Error {
    match failure {
        LayoutFailure::Io(source) => Error::Io {
            path: path.to_path_buf(),
            source,
        },
        LayoutFailure::At(at, message) => bag_error(path, Some(at), None, None, message),
    }
}

/// A chunk being handed on, and its next message.
struct Slot {
    loaded: Loaded,
    next: usize,
    /// The chunk's record offset, for errors.
    pos: u64,
}

/// The messages of every chunk in time order (see the [module docs](self)).
struct Merge {
    /// Chunk indices by their first message's time (then their place in the file).
    order: Vec<usize>,
    /// The next of `order` to load.
    next: usize,
    slots: Vec<Slot>,
    free: Vec<usize>,
    /// Per chunk being handed on: its next message's time, its place in `order`, its slot.
    heap: BinaryHeap<Reverse<(u64, usize, usize)>>,
    /// Decompressed bytes held.
    held: usize,
}

impl Merge {
    fn new(chunks: &[Chunk]) -> Self {
        let mut order: Vec<usize> = (0..chunks.len()).collect();
        order.sort_by_key(|&k| (chunks[k].start, chunks[k].pos));
        Merge {
            order,
            next: 0,
            slots: Vec::new(),
            free: Vec::new(),
            heap: BinaryHeap::new(),
            held: 0,
        }
    }

    /// The next message, as its slot and entry: loads every chunk whose first message is due
    /// before the earliest message held; `None` once every chunk is spent.
    fn next(
        &mut self,
        file: &mut BufReader<File>,
        len: u64,
        chunks: &[Chunk],
    ) -> Result<Option<(usize, usize)>, LayoutFailure> {
        while let Some(&k) = self.order.get(self.next) {
            let due = self
                .heap
                .peek()
                .is_none_or(|Reverse((t, _, _))| chunks[k].start <= *t);
            if !due {
                break;
            }
            let s = self.free.pop().unwrap_or_else(|| {
                self.slots.push(Slot {
                    loaded: Loaded::default(),
                    next: 0,
                    pos: 0,
                });
                self.slots.len() - 1
            });
            let slot = &mut self.slots[s];
            layout::load_chunk(file, len, chunks[k].pos, &mut slot.loaded, |_, _| Ok(()))?;
            slot.next = 0;
            slot.pos = chunks[k].pos;
            match slot.loaded.entries.first() {
                Some(first) => {
                    self.heap.push(Reverse((first.time, self.next, s)));
                    self.held += slot.loaded.buf.len();
                }
                None => self.free.push(s),
            }
            self.next += 1;
            if self.held > crate::limits::MAX_ROS1_HELD_BYTES {
                return Err(LayoutFailure::At(
                    chunks[k].pos,
                    format!(
                        "the chunks overlap in time so much that putting their messages in \
                         time order would hold more than {} bytes of them at once; rewrite the \
                         bag in time order with `rosbag filter in.bag out.bag True`",
                        crate::limits::MAX_ROS1_HELD_BYTES
                    ),
                ));
            }
        }
        let Some(Reverse((_, o, s))) = self.heap.pop() else {
            return Ok(None);
        };
        let slot = &mut self.slots[s];
        let i = slot.next;
        slot.next += 1;
        match slot.loaded.entries.get(slot.next) {
            Some(e) => self.heap.push(Reverse((e.time, o, s))),
            None => {
                // Its bytes stay until the slot is loaded again, after this message is used.
                self.held -= slot.loaded.buf.len();
                self.free.push(s);
            }
        }
        Ok(Some((s, i)))
    }
}

/// The message of entry `i` of slot `s` of `merge`, as `mcap convert` makes it: on the channel
/// of its connection (found in `conn_of`, among `channels`).
fn message_of<'a>(
    merge: &'a Merge,
    conn_of: &HashMap<u32, usize>,
    channels: &[Arc<mcap::Channel<'static>>],
    s: usize,
    i: usize,
) -> Result<mcap::Message<'a>, String> {
    let loaded = &merge.slots[s].loaded;
    let e = loaded.entries[i];
    let k = conn_of.get(&e.conn).copied().ok_or_else(|| {
        format!(
            "the message names connection {}, which the bag does not define; the bag is \
             damaged (`rosbag reindex` may repair it)",
            e.conn
        )
    })?;
    Ok(mcap::Message {
        channel: Arc::clone(&channels[k]),
        sequence: 0,
        log_time: e.time,
        publish_time: e.time,
        data: Cow::Borrowed(&loaded.buf[e.start..e.end]),
    })
}

/// Reads a ROS 1 bag (format 2.0) as a stream of [`Sample`](calib_core::Sample)s (see the
/// [module docs](self)).
pub struct Ros1BagReader {
    path: PathBuf,
    file: BufReader<File>,
    len: u64,
    chunks: Vec<Chunk>,
    /// Each connection's index by its ID.
    conn_of: HashMap<u32, usize>,
    /// One MCAP channel per connection, as `mcap convert` makes of it.
    channels: Vec<Arc<mcap::Channel<'static>>>,
    /// The channels, the selection and the samples in progress, shared with the other readers.
    samples: Samples,
    merge: Merge,
    /// Messages handed on so far (every topic).
    index: u64,
    progress: ReadProgress,
    /// Where the file is cut short.
    cut: Option<u64>,
    warnings: Vec<String>,
    done: bool,
    failed: bool,
}

/// The channel `mcap convert` makes of a connection; `id` its index among the bag's.
fn channel_of(c: &layout::Connection, id: u16) -> mcap::Channel<'static> {
    mcap::Channel {
        id,
        topic: c.topic.clone(),
        schema: Some(Arc::new(mcap::Schema {
            id: id.saturating_add(1),
            name: c.kind.clone(),
            encoding: "ros1msg".into(),
            data: Cow::Owned(c.definition.clone()),
        })),
        message_encoding: "ros1".into(),
        metadata: Default::default(),
    }
}

impl Ros1BagReader {
    /// Opens a ROS 1 bag and fixes its channel list: the connections and chunks from its index
    /// (or a scan, see the [module docs](self)), then the first messages of each topic calib
    /// reads, which name its channels.
    ///
    /// Errors if the file is not a bag of format 2.0, a record is damaged, no topic holds
    /// JointState or `std_msgs` scalar messages, or a topic's first message is bad.
    pub fn open(path: &Path, opts: &ReadOptions) -> Result<Self, Error> {
        let io = |source| Error::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = File::open(path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        if len == 0 {
            return Err(bag_error(
                path,
                None,
                None,
                None,
                "the file is empty (0 bytes); was the recording stopped before it wrote \
                 anything?"
                    .into(),
            ));
        }
        let mut file = BufReader::with_capacity(READ_BUFFER, file);
        let shown = path.display().to_string();
        let Layout {
            connections,
            chunks,
            warnings,
            cut,
        } = layout::read(&mut file, len, &shown).map_err(|f| layout_error(path, f))?;
        let mut conn_of = HashMap::with_capacity(connections.len());
        let mut channels = Vec::with_capacity(connections.len());
        for (k, c) in connections.iter().enumerate() {
            // At most MAX_TOPICS connections, checked as they were read.
            let id = u16::try_from(k).unwrap_or(u16::MAX);
            conn_of.insert(c.id, k);
            channels.push(Arc::new(channel_of(c, id)));
        }
        // Messages per connection, as the chunk infos count them.
        let mut counts = vec![0u64; connections.len()];
        for chunk in &chunks {
            for &(id, n) in &chunk.counts {
                if let Some(&k) = conn_of.get(&id) {
                    counts[k] += u64::from(n);
                }
            }
        }
        let mut registry = Registry::default();
        let mut expected = HashSet::new();
        for (channel, &n) in channels.iter().zip(&counts) {
            if n == 0 {
                continue;
            }
            if Encoding::of(channel).is_some() {
                expected.insert(channel.topic.clone());
            } else {
                registry.ignore(channel);
            }
        }
        let mut reader = Ros1BagReader {
            path: path.to_path_buf(),
            file,
            len,
            merge: Merge::new(&chunks),
            chunks,
            conn_of,
            channels,
            samples: Samples::new(Registry::default(), opts, "message"),
            index: 0,
            progress: ReadProgress::messages(counts.iter().sum()),
            cut,
            warnings,
            done: false,
            failed: false,
        };
        let scale = opts.unit.unwrap_or(AngleUnit::Deg).radians_per_unit();
        reader.peek(&mut registry, expected.len(), scale)?;
        registry
            .read_wanted_fields(&opts.fields, scale)
            .map_err(|(topic, m)| bag_error(path, None, None, Some(&topic), m))?;
        if registry.topics.is_empty() {
            return Err(reader.no_topic_error(&registry));
        }
        reader.samples = Samples::new(registry, opts, "message");
        reader.merge = Merge::new(&reader.chunks);
        Ok(reader)
    }

    /// Reads messages in time order until each of the `expected` topics calib reads has shown
    /// its first message and [`PEEK_WINDOW`] more have passed (to the end while a topic's
    /// messages carry different joint sets), learning each topic's channels.
    fn peek(&mut self, registry: &mut Registry, expected: usize, scale: f64) -> Result<(), Error> {
        let mut after_all: Option<u64> = None;
        let mut index = 0u64;
        while let Some((s, i)) = self.next_message()? {
            let message = self
                .message(s, i)
                .map_err(|m| self.error_at(s, index, None, m))?;
            registry
                .learn(&message, scale)
                .map_err(|m| self.error_at(s, index, Some(&message.channel.topic), m))?;
            index += 1;
            if let Some(n) = &mut after_all {
                *n += 1;
            } else if registry.topics.len() == expected {
                after_all = Some(0);
            }
            let subset = registry.topics.iter().any(|t| t.subset);
            if after_all.is_some_and(|n| n >= PEEK_WINDOW) && !subset {
                break;
            }
        }
        Ok(())
    }

    /// The next message's slot and entry, in time order.
    fn next_message(&mut self) -> Result<Option<(usize, usize)>, Error> {
        self.merge
            .next(&mut self.file, self.len, &self.chunks)
            .map_err(|f| layout_error(&self.path, f))
    }

    /// The message of entry `i` of slot `s`, as `mcap convert` makes it.
    fn message(&self, s: usize, i: usize) -> Result<mcap::Message<'_>, String> {
        message_of(&self.merge, &self.conn_of, &self.channels, s, i)
    }

    /// An error about message `index`, of slot `s`'s chunk.
    fn error_at(&self, s: usize, index: u64, topic: Option<&str>, message: String) -> Error {
        let pos = self.merge.slots[s].pos;
        bag_error(&self.path, Some(pos), Some(index), topic, message)
    }

    /// Why a bag yields no channel: it is cut before its first message, holds none, or no
    /// topic of a type calib reads.
    fn no_topic_error(&self, registry: &Registry) -> Error {
        if let Some(at) = self.cut.filter(|_| registry.ignored.is_empty()) {
            return bag_error(
                &self.path,
                Some(at),
                None,
                None,
                format!(
                    "the file is cut short here, of {} bytes, before its first JointState or \
                     scalar message (a recording that stopped early, or a partial copy); copy \
                     the file again or record again",
                    self.len
                ),
            );
        }
        if registry.ignored.is_empty() {
            return Error::Empty {
                path: self.path.clone(),
            };
        }
        let found: Vec<String> = registry
            .ignored
            .iter()
            .map(|t| format!("{} ({})", t.topic, t.schema))
            .collect();
        bag_error(
            &self.path,
            None,
            None,
            None,
            format!(
                "no topic holds sensor_msgs/JointState ({JOINT_STATE_SCHEMA} in ROS 2) or \
                 std_msgs scalar messages (found: {}); record the encoders as JointState",
                crate::limits::listed(&found)
            ),
        )
    }

    /// Warnings about how the bag was read (no index: a scan).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The selected channels, in the order of each sample's values.
    pub fn channels(&self) -> &[Channel] {
        self.samples.channels()
    }

    /// The names of every channel of the bag, in raw order.
    pub fn names(&self) -> &[ChannelName] {
        self.samples.names()
    }

    /// Every topic of the bag: those read with their channels, then those skipped, with the
    /// messages read so far.
    pub fn topics(&self) -> Vec<TopicInfo> {
        self.samples.topics()
    }

    /// What the reader noticed so far: where a file cut short broke off (once read).
    pub fn diagnostics(&self) -> &ReadDiagnostics {
        &self.samples.diagnostics
    }

    /// Decodes the message of slot `s`, entry `i`, appending to `out` the samples it completes.
    fn step(&mut self, s: usize, i: usize, out: &mut SampleBatch) -> Result<(), Error> {
        let index = self.index;
        let key = i64::try_from(index).unwrap_or(i64::MAX);
        let message = message_of(&self.merge, &self.conn_of, &self.channels, s, i)
            .map_err(|m| self.error_at(s, index, None, m))?;
        let stepped = self.samples.step(&message, key, out);
        stepped.map_err(|failure| {
            let (topic, m) = match failure {
                Failure::NewTopic => (
                    None,
                    "this topic has no message in the bag's index, so its channels were not \
                     known when the bag was opened; the index is damaged (`rosbag reindex` \
                     repairs it)"
                        .into(),
                ),
                Failure::Message { joint, message: m } => (joint, m),
            };
            let topic = topic.unwrap_or_else(|| message.channel.topic.clone());
            self.error_at(s, index, Some(&topic), m)
        })
    }
}

impl Ros2Reader for Ros1BagReader {
    fn samples(&self) -> &Samples {
        &self.samples
    }

    fn samples_mut(&mut self) -> &mut Samples {
        &mut self.samples
    }

    fn progress(&self) -> ReadProgress {
        self.progress.clone()
    }

    fn fill(&mut self, out: &mut SampleBatch, max: usize) -> Result<(), Error> {
        while out.len() < max && !self.done && !self.failed {
            let next = match self.next_message() {
                Ok(next) => next,
                Err(e) => {
                    self.failed = true;
                    return Err(e);
                }
            };
            let Some((s, i)) = next else {
                self.done = true;
                if let Some(byte_offset) = self.cut {
                    self.samples.diagnostics.truncated = Some(Truncation {
                        byte_offset,
                        messages_read: self.index,
                    });
                }
                self.samples.finish(out);
                continue;
            };
            let stepped = self.step(s, i, out);
            self.index += 1;
            self.progress.set(self.index);
            if let Err(e) = stepped {
                self.failed = true;
                return Err(e);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use crate::{LogReader, ReadOptions};

    /// Header fields as a bag holds them: each a `u32` length and `name=value`.
    fn fields(list: &[(&str, &[u8])]) -> Vec<u8> {
        let mut out = Vec::new();
        for (name, value) in list {
            out.extend(((name.len() + 1 + value.len()) as u32).to_le_bytes());
            out.extend(name.as_bytes());
            out.push(b'=');
            out.extend(*value);
        }
        out
    }

    /// A record: `list` as its header, then `data`.
    fn record(list: &[(&str, &[u8])], data: &[u8]) -> Vec<u8> {
        let header = fields(list);
        let mut out = (header.len() as u32).to_le_bytes().to_vec();
        out.extend(header);
        out.extend((data.len() as u32).to_le_bytes());
        out.extend(data);
        out
    }

    fn time(s: u32) -> [u8; 8] {
        let mut t = [0u8; 8];
        t[..4].copy_from_slice(&s.to_le_bytes());
        t
    }

    /// A bag of one `std_msgs/Float64` topic whose uncompressed chunks hold `(time s, value)`
    /// messages, with its index.
    fn bag(chunks: &[&[(u32, f64)]]) -> Vec<u8> {
        let conn = 0u32.to_le_bytes();
        let connection = record(
            &[("op", &[7]), ("conn", &conn), ("topic", b"/x")],
            &fields(&[("topic", b"/x"), ("type", b"std_msgs/Float64")]),
        );
        let mut out = b"#ROSBAG V2.0\n".to_vec();
        let header_at = out.len();
        out.extend(vec![0u8; 4096]);
        let mut infos = Vec::new();
        for messages in chunks {
            let mut plain = connection.clone();
            for (t, v) in *messages {
                let fields: [(&str, &[u8]); 3] =
                    [("op", &[2]), ("conn", &conn), ("time", &time(*t))];
                plain.extend(record(&fields, &v.to_le_bytes()));
            }
            let pos = (out.len() as u64).to_le_bytes();
            let size = (plain.len() as u32).to_le_bytes();
            out.extend(record(
                &[("op", &[5]), ("compression", b"none"), ("size", &size)],
                &plain,
            ));
            let first = messages.iter().map(|m| m.0).min().unwrap_or(0);
            let last = messages.iter().map(|m| m.0).max().unwrap_or(0);
            let mut counts = conn.to_vec();
            counts.extend((messages.len() as u32).to_le_bytes());
            infos.push(record(
                &[
                    ("op", &[6]),
                    ("ver", &1u32.to_le_bytes()),
                    ("chunk_pos", &pos),
                    ("start_time", &time(first)),
                    ("end_time", &time(last)),
                    ("count", &1u32.to_le_bytes()),
                ],
                &counts,
            ));
        }
        let index_pos = (out.len() as u64).to_le_bytes();
        out.extend(&connection);
        for info in &infos {
            out.extend(info);
        }
        let chunk_count = (infos.len() as u32).to_le_bytes();
        let list: [(&str, &[u8]); 4] = [
            ("op", &[3]),
            ("index_pos", &index_pos),
            ("conn_count", &1u32.to_le_bytes()),
            ("chunk_count", &chunk_count),
        ];
        // Padded to 4096 bytes, as `rosbag record` writes it.
        let header = record(&list, &vec![b' '; 4096 - 8 - fields(&list).len()]);
        out[header_at..header_at + header.len()].copy_from_slice(&header);
        out
    }

    /// Values and times (s) of every sample of `bytes` read as a bag, or the error.
    fn read(bytes: &[u8]) -> Result<Vec<(f64, f64)>, String> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.bag");
        std::fs::write(&path, bytes).unwrap();
        let opts = ReadOptions {
            unit: Some(calib_core::AngleUnit::Rad),
            ..ReadOptions::default()
        };
        let log = LogReader::open(&path, &opts).map_err(|e| e.to_string())?;
        log.map(|s| s.map(|s| (s.t, s.values[0])).map_err(|e| e.to_string()))
            .collect()
    }

    #[test]
    fn overlapping_chunks_are_merged_in_time_order() {
        // Chunks overlapping in time, one of them out of order inside, and a later chunk that
        // starts before the second ends.
        let a: &[(u32, f64)] = &[(1, 1.0), (5, 5.0), (3, 3.0)];
        let b: &[(u32, f64)] = &[(2, 2.0), (4, 4.0), (6, 6.0)];
        let c: &[(u32, f64)] = &[(7, 7.0), (8, 8.0)];
        let got = read(&bag(&[a, c, b])).unwrap();
        let want: Vec<(f64, f64)> = (1..=8).map(|k| (f64::from(k), f64::from(k))).collect();
        assert_eq!(got, want);
    }

    #[test]
    fn an_index_that_miscounts_falls_back_to_a_scan() {
        let a: &[(u32, f64)] = &[(1, 1.0), (2, 2.0)];
        let mut bytes = bag(&[a]);
        // The bag header's chunk_count, 1, made 2: the index is not believed.
        let at = bytes
            .windows(12)
            .position(|w| w == b"chunk_count=")
            .unwrap();
        bytes[at + 12] = 2;
        assert_eq!(read(&bytes).unwrap(), [(1.0, 1.0), (2.0, 2.0)]);
    }
}
