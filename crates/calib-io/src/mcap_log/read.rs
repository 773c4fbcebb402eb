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
//! Every message goes to an [`Aligner`](crate::align::Aligner): the first selected channel sets
//! the clock, every other channel is interpolated at its stamps ([`crate::align`]); a channel at
//! exactly the clock's stamp is taken as it is. A log of one topic whose messages all carry every joint needs none
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

use std::collections::HashSet;
use std::fs::File;
use std::io::{self, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use calib_core::{AngleUnit, Channel, Sample, SampleBatch};
use mcap::McapError;
use mcap::sans_io::{LinearReaderOptions, SummaryReadEvent, SummaryReader, SummaryReaderOptions};

use super::JOINT_STATE_SCHEMA;
use super::chunks;
use super::records::{self, StreamError};
use crate::align::{AlignOptions, Alignment};
use crate::naming::ChannelName;
use crate::progress::ReadProgress;
use crate::ros2::PEEK_WINDOW;
use crate::ros2::encoding::Encoding;
use crate::ros2::registry::{IgnoredTopic, Registry, Resolved, TopicInfo, too_many_topics};
use crate::ros2::samples::{Failure, OneByOne, Ros2Reader, Samples};
use crate::source::{ByteSource, FileSource, SourceCursor};
use crate::{DamagedChunk, Error, ReadDiagnostics, ReadOptions, Truncation};

/// Chunks a file's summary must list for them to be read on worker threads: a file of one chunk
/// gains nothing from it, and a small log should not pay for starting threads.
pub const PARALLEL_CHUNKS: usize = 2;

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
    /// The file's bytes (a local file's, or an object's in a store).
    source: Arc<dyn ByteSource>,
    /// Chunks the chunk index let the reader leave out (an object store's log): the streaming
    /// reader cannot take over then, as it would count their messages.
    chunks_left_out: usize,
    /// Boxed: the stream's state is large, and the reader is moved around inside enums.
    stream: Box<Stream>,
    /// Bytes of the file handed to the stream so far (shared with its [`Source`]).
    consumed: Arc<AtomicU64>,
    /// `consumed` when the stream gave its last message: where the read data ends.
    consumed_at_last: u64,
    /// The file's length when opened.
    len: u64,
    /// Bytes of the file read so far, of `len`, for a progress line.
    progress: ReadProgress,
    /// The channels, the selection and the samples in progress, shared with the bag reader.
    samples: Samples,
    /// Messages taken from the stream so far (all topics).
    index: u64,
    /// The stream has ended (or failed): what the aligner holds is all that is left.
    done: bool,
    /// An error was yielded: the iteration is over.
    failed: bool,
    /// Reading chunks in parallel: the file, for the streaming reader to take over with.
    reopen: Option<SourceCursor>,
    skip_damaged: bool,
    /// Messages the streaming reader skips after taking over: those handed on already.
    skip: u64,
    /// The samples read but not yet handed on by [`Iterator::next`].
    one: OneByOne,
}

/// Read buffer of the stream: large enough that reading costs few system calls, small against
/// a chunk.
const READ_BUFFER: usize = 256 * 1024;

/// The file as the stream reads it, from the start, counting the bytes it hands on.
struct Source {
    file: BufReader<SourceCursor>,
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
fn stream(
    mut file: SourceCursor,
    len: u64,
    skip_damaged: bool,
) -> io::Result<(Stream, Arc<AtomicU64>)> {
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

/// How the data section is read.
enum Plan {
    /// Front to back by the streaming reader.
    Streaming,
    /// Front to back, chunks decompressed on worker threads.
    Parallel,
    /// Only these chunks (offset and length), after these schema and channel records, on this
    /// many worker threads (an object store's log; see [`super::chunks`]).
    Indexed(Vec<(u64, u64)>, Vec<(u8, Vec<u8>)>, usize),
}

/// The stream of the whole file: its chunks decompressed on worker threads (see
/// [`super::chunks`]) — all of them, or those `plan` lists — and a second handle on the file
/// for the streaming reader to take over with; else (or if no thread can be started) the
/// streaming reader.
fn main_stream(
    file: SourceCursor,
    len: u64,
    skip_damaged: bool,
    plan: Plan,
) -> io::Result<(Stream, Arc<AtomicU64>, Option<SourceCursor>)> {
    let consumed = Arc::new(AtomicU64::new(0));
    let spare = file.clone();
    let chunked = match plan {
        Plan::Streaming => None,
        Plan::Parallel => {
            chunks::Chunked::new(spare, len, Arc::clone(&consumed), chunks::workers())
        }
        Plan::Indexed(chunks, definitions, workers) => {
            chunks::Chunked::indexed(spare, chunks, definitions, Arc::clone(&consumed), workers)
        }
    };
    if let Some(chunked) = chunked {
        return Ok((records::Stream::chunked(chunked), consumed, Some(file)));
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

fn mcap_error(path: &Path, index: Option<u64>, channel: Option<&str>, message: String) -> Error {
    Error::Mcap {
        path: path.to_path_buf(),
        message_index: index,
        channel: channel.map(str::to_string),
        message,
    }
}

/// The offset of the first incomplete top-level record, if the data section is cut short;
/// `None` if it is complete up to its data end record (or the file cannot be read again).
/// Reads only the records' 9-byte headers, skipping their bodies.
fn find_break(source: &Arc<dyn ByteSource>) -> Option<u64> {
    const DATA_END: u8 = 0x0F;
    let file = SourceCursor::new(Arc::clone(source));
    let len = source.len();
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
        let parallel_chunks = if opts.one_thread {
            usize::MAX
        } else {
            PARALLEL_CHUNKS
        };
        Self::open_with(path, opts, parallel_chunks)
    }

    /// [`open`](Self::open) for a file whose bytes `source` holds, named `name` in messages.
    /// From an object store ([`ByteSource::is_remote`]) it reads the summary, the first chunks
    /// (to learn the topics) and then only the chunks its chunk index lists for the topics calib
    /// reads, each in one request (see [`crate::source`]).
    pub fn open_source(
        name: &Path,
        source: Arc<dyn ByteSource>,
        opts: &ReadOptions,
    ) -> Result<Self, Error> {
        let parallel_chunks = if opts.one_thread {
            usize::MAX
        } else {
            PARALLEL_CHUNKS
        };
        Self::open_from(name, source, opts, parallel_chunks)
    }

    /// [`open`](Self::open), reading the chunks on worker threads where the summary lists at
    /// least `parallel_chunks` of them.
    pub(crate) fn open_with(
        path: &Path,
        opts: &ReadOptions,
        parallel_chunks: usize,
    ) -> Result<Self, Error> {
        let source = FileSource::open(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::open_from(path, Arc::new(source), opts, parallel_chunks)
    }

    fn open_from(
        path: &Path,
        source: Arc<dyn ByteSource>,
        opts: &ReadOptions,
        parallel_chunks: usize,
    ) -> Result<Self, Error> {
        let io = |source| Error::Io {
            path: path.to_path_buf(),
            source,
        };
        let (mut file, len) = open_mcap(path, &source)?;
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
        let expected = summary
            .as_ref()
            .and_then(|summary| expected_topics(summary, &mut registry));
        let scale = opts.unit.unwrap_or(AngleUnit::Deg).radians_per_unit();
        let mut peek = Peek::default();
        let field_topics = field_topics(&opts.fields);
        // Topics read by field path take their definitions from the data section: peek for
        // them even where the summary lists no topic calib reads otherwise.
        if expected.as_ref().is_none_or(|e| !e.is_empty()) || !field_topics.is_empty() {
            // From an object store, the peek too reads only chunks of the topics it looks for.
            let indexed = match (&summary, &expected) {
                (Some(summary), Some(expected))
                    if source.is_remote() && !summary.chunk_index.is_empty() =>
                {
                    let topics = expected
                        .iter()
                        .map(String::as_str)
                        .chain(field_topics.iter().copied())
                        .collect();
                    let (chunks, _) = chunks_of(summary, &topics);
                    let consumed = Arc::new(AtomicU64::new(0));
                    let definitions = summary.definitions.clone();
                    chunks::Chunked::indexed(file.clone(), chunks, definitions, consumed, 1)
                        .map(records::Stream::chunked)
                }
                _ => None,
            };
            let stream = match indexed {
                Some(stream) => stream,
                None => stream(file, len, opts.skip_damaged).map_err(io)?.0,
            };
            let peeked = peek.learn_topics(
                path,
                stream,
                expected.as_deref(),
                &field_topics,
                &mut registry,
                scale,
            )?;
            file = peeked.unwrap_or_else(|| SourceCursor::new(Arc::clone(&source)));
        }
        registry
            .read_wanted_fields(&opts.fields, scale)
            .map_err(|(topic, m)| mcap_error(path, None, Some(&topic), m))?;
        if registry.topics.is_empty() {
            return Err(no_topic_error(path, &source, len, peek, &registry));
        }
        let mut chunks_left_out = 0;
        let plan = match summary.filter(|s| source.is_remote() && !s.chunk_index.is_empty()) {
            Some(summary) => {
                let read = registry.topics.iter().map(|t| t.name.as_str()).collect();
                let (chunks, left_out) = chunks_of(&summary, &read);
                chunks_left_out = left_out;
                let workers = if opts.one_thread {
                    1
                } else {
                    chunks::workers()
                };
                Plan::Indexed(chunks, summary.definitions, workers)
            }
            None if parallel => Plan::Parallel,
            None => Plan::Streaming,
        };
        let (stream, consumed, reopen) =
            main_stream(file, len, opts.skip_damaged, plan).map_err(io)?;
        Ok(McapReader {
            path: path.to_path_buf(),
            source,
            chunks_left_out,
            stream: Box::new(stream),
            consumed,
            consumed_at_last: 0,
            len,
            progress: ReadProgress::new(len),
            samples: Samples::new(registry, opts, "message"),
            index: 0,
            done: false,
            failed: false,
            reopen,
            skip_damaged: opts.skip_damaged,
            skip: 0,
            one: OneByOne::default(),
        })
    }

    /// The channels, in the order of each sample's values: those [selected](Self::select), by
    /// default every channel of the file (topics in the order of their first message, then the
    /// joints or fields within a topic).
    pub fn channels(&self) -> &[Channel] {
        self.samples.channels()
    }

    /// The names of every channel of the file (not only the selected ones), in raw order: the
    /// indices [`select`](Self::select) takes.
    pub fn names(&self) -> &[ChannelName] {
        self.samples.names()
    }

    /// Reads only `channels` (indices into [`names`](Self::names)), in this order, aligned on the
    /// first one's stamps as [`crate::align`] describes. Call it before reading any sample.
    pub fn select(&mut self, channels: &[usize], opts: AlignOptions) {
        self.samples.select(channels, opts);
    }

    /// How the selected channels were aligned on the first one's clock (complete once iteration
    /// has ended).
    pub fn alignment(&self) -> Alignment {
        self.samples.alignment()
    }

    /// Every topic of the file: those read with their channels, then those skipped. Message counts
    /// and rates are of the messages read so far (all of them once iteration has ended).
    pub fn topics(&self) -> Vec<TopicInfo> {
        self.samples.topics()
    }

    /// The stamp, s, from which the samples' times count: the whole second of the first
    /// message's stamp (see [`crate::LogReader::time_origin_s`]).
    pub fn time_origin_s(&self) -> f64 {
        self.samples.time_origin_s()
    }

    /// What the reader noticed so far: where a truncated file broke off (once iteration has
    /// ended).
    pub fn diagnostics(&self) -> &ReadDiagnostics {
        &self.samples.diagnostics
    }

    /// Topics skipped because their messages are neither JointState nor JSON, in the order met.
    pub fn ignored_topics(&self) -> &[IgnoredTopic] {
        self.samples.ignored_topics()
    }

    /// Decodes one message, appending to `out` the samples it completes.
    fn step(
        &mut self,
        message: &mcap::Message,
        index: u64,
        out: &mut SampleBatch,
    ) -> Result<(), Error> {
        let key = i64::try_from(index).unwrap_or(i64::MAX);
        self.samples.step(message, key, out).map_err(|failure| {
            let (channel, m) = match failure {
                Failure::NewTopic => (
                    None,
                    "this topic is missing from the file's summary, so its channels were not \
                     known when the file was opened; repair the file with `mcap recover`"
                        .into(),
                ),
                Failure::Message { joint, message: m } => (joint, m),
            };
            let channel = channel.unwrap_or_else(|| message.channel.topic.clone());
            mcap_error(&self.path, Some(index), Some(&channel), m)
        })
    }

    /// Hands reading over from the chunks read in parallel to the streaming reader, from the
    /// start of the file, which skips the messages handed on already (see [`super::chunks`]).
    fn take_over(&mut self) -> Result<(), Error> {
        let io = |source| Error::Io {
            path: self.path.clone(),
            source,
        };
        if self.chunks_left_out > 0 {
            return Err(mcap_error(
                &self.path,
                Some(self.index),
                None,
                format!(
                    "a chunk could not be read as the file's chunk index describes it \
                     (damaged, of a kind calib reads only front to back, or the connection \
                     failed), and {} chunk(s) without a channel calib reads were not fetched; \
                     try again, or download the log and read the local file",
                    self.chunks_left_out
                ),
            ));
        }
        let file = match self.reopen.take() {
            Some(file) => file,
            None => SourceCursor::new(Arc::clone(&self.source)),
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
        let Some(byte_offset) = find_break(&self.source).map(|b| b.max(self.consumed_at_last))
        else {
            return false;
        };
        self.samples.diagnostics.truncated = Some(Truncation {
            byte_offset,
            messages_read: self.index,
        });
        true
    }

    /// The stream has ended: what the aligner holds is decided and appended to `out`, and the
    /// damaged chunks left out are listed.
    fn finish(&mut self, out: &mut SampleBatch) {
        self.stop();
        self.samples.finish(out);
    }

    /// The stream has failed: the damaged chunks left out are listed, and what the aligner holds
    /// is not handed on (the error ends the log).
    fn stop(&mut self) {
        self.done = true;
        self.samples.diagnostics.damaged_chunks = self.stream.damaged().to_vec();
    }
}

impl Ros2Reader for McapReader {
    fn samples(&self) -> &Samples {
        &self.samples
    }

    fn progress(&self) -> ReadProgress {
        self.progress.clone()
    }

    fn samples_mut(&mut self) -> &mut Samples {
        &mut self.samples
    }

    fn fill(&mut self, out: &mut SampleBatch, max: usize) -> Result<(), Error> {
        while out.len() < max && !self.done && !self.failed {
            let message = match self.stream.next() {
                Some(Ok(message)) => {
                    // Chunks are held until checked: where this message's bytes ended is where
                    // the reader was when it gave the message, not where the check got to.
                    self.consumed_at_last = self.stream.consumed_at_last();
                    self.progress.set(self.consumed.load(Ordering::Relaxed));
                    if self.skip > 0 {
                        self.skip -= 1;
                        continue;
                    }
                    message
                }
                Some(Err(StreamError::Fallback)) => {
                    if let Err(e) = self.take_over() {
                        self.stop();
                        self.failed = true;
                        return Err(e);
                    }
                    continue;
                }
                None => {
                    self.finish(out);
                    // The stream stops at the data end record, before the end of the file. It
                    // also ends cleanly when the file ends between two records (it is told to
                    // expect no end magic): then the data end record is missing.
                    if self.consumed.load(Ordering::Relaxed) >= self.len {
                        self.note_truncation();
                    }
                    continue;
                }
                Some(Err(e)) => {
                    // Reading stopped at the first incomplete record, or inside it (a cut chunk)
                    // where the last message came out.
                    if matches!(e, StreamError::Mcap(McapError::UnexpectedEof))
                        && self.note_truncation()
                    {
                        self.finish(out);
                        continue;
                    }
                    self.stop();
                    self.failed = true;
                    if matches!(e, StreamError::Damaged(_) | StreamError::DataCrc) {
                        return Err(damaged_error(&self.path, self.index, &e));
                    }
                    return Err(mcap_error(
                        &self.path,
                        Some(self.index),
                        None,
                        format!(
                            "the file is damaged here ({e}); the messages before it were \
                             read: recover the rest with `mcap recover`"
                        ),
                    ));
                }
            };
            let index = self.index;
            self.index += 1;
            let stepped = self.step(&message, index, out);
            self.stream.recycle(message);
            if let Err(e) = stepped {
                self.failed = true;
                return Err(e);
            }
        }
        Ok(())
    }
}

impl Iterator for McapReader {
    type Item = Result<Sample, Error>;

    fn next(&mut self) -> Option<Self::Item> {
        let mut one = std::mem::take(&mut self.one);
        let next = one.next(self.samples.channels().len(), |batch| self.fill(batch, 1));
        self.one = one;
        next
    }
}

/// Opens `path` and checks that it is an MCAP file: not empty, and starting with the magic.
/// Returns the file and its length.
fn open_mcap(path: &Path, source: &Arc<dyn ByteSource>) -> Result<(SourceCursor, u64), Error> {
    let io = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut file = SourceCursor::new(Arc::clone(source));
    let len = source.len();
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

/// The chunks of `summary`'s index that hold a message of `topics` (offset and length of each
/// chunk record; a chunk whose index names no channel may hold any), and how many others it
/// lists.
fn chunks_of(summary: &records::Summary, topics: &HashSet<&str>) -> (Vec<(u64, u64)>, usize) {
    let wanted: HashSet<u16> = summary
        .channels
        .values()
        .filter(|c| topics.contains(c.topic.as_str()))
        .map(|c| c.id)
        .collect();
    let chunks: Vec<(u64, u64)> = summary
        .chunk_index
        .iter()
        .filter(|c| {
            c.channels
                .as_ref()
                .is_none_or(|ids| ids.iter().any(|id| wanted.contains(id)))
        })
        .map(|c| (c.offset, c.length))
        .collect();
    let left_out = summary.chunk_index.len() - chunks.len();
    (chunks, left_out)
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
    /// from its first message. Returns the file, to be read again from its start (`None` where
    /// the stream read chunks by the index: the caller opens it again).
    fn learn_topics(
        &mut self,
        path: &Path,
        mut peek: Stream,
        expected: Option<&[String]>,
        field_topics: &[&str],
        registry: &mut Registry,
        scale: f64,
    ) -> Result<Option<SourceCursor>, Error> {
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
            match registry.learn(&message, scale).map_err(fail)? {
                Resolved::NewTopic(_) => {
                    unmet.remove(message.channel.topic.as_str());
                }
                Resolved::Topic(k) => subset |= registry.topics[k].subset,
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
        Ok(peek.into_inner().map(|source| source.file.into_inner()))
    }
}

/// Why a log of `len` bytes yields no channel: every usable message is in a skipped damaged
/// chunk, the file is damaged or cut before its first usable message, it is empty, or none of
/// its topics holds a type calib reads.
fn no_topic_error(
    path: &Path,
    source: &Arc<dyn ByteSource>,
    len: u64,
    peek: Peek,
    registry: &Registry,
) -> Error {
    if !peek.skipped.is_empty() {
        let list: Vec<String> = peek.skipped.iter().map(|c| c.to_string()).collect();
        return mcap_error(
            path,
            None,
            None,
            format!(
                "no JointState or JSON message is left once the damaged chunks are \
                 skipped (the `skip_damaged` option): {}; repair the file or record again",
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
    if let Some(at) = find_break(source) {
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

/// The error for a damaged chunk or data section met after `index` messages.
fn damaged_error(path: &Path, index: u64, e: &StreamError) -> Error {
    let what = match e {
        StreamError::Damaged(_) => {
            "none of its messages were used: run with the `skip_damaged` option to calibrate without them \
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
