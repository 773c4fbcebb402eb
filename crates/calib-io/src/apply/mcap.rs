//! MCAP logs: every record copied, the channel's messages rewritten in place.
//!
//! # Reading
//! A log whose summary lists [`PARALLEL_CHUNKS`] chunks or more has its data section read as the
//! MCAP reader reads it ([`Chunked`]): chunks checked against their CRCs and decompressed on
//! worker threads, every record handed on in file order; its summary section, which the copy
//! does not need but whose damage the streaming reader reports, is then read by the streaming
//! reader. At the first irregularity (a damaged chunk, lz4 chunks, a chunk over
//! [`MAX_PARALLEL_CHUNK_BYTES`](crate::limits::MAX_PARALLEL_CHUNK_BYTES), …) the streaming
//! reader reads the file again from its start, skipping the records already copied, so every
//! error, truncation and damaged chunk left out is its own. The streaming reader is the `mcap`
//! crate's sans-io [`LinearReader`](mcap::sans_io::LinearReader) through a buffered file:
//! chunks decompressed one at a time, records handed over one by one. Either way memory is
//! bounded by a few chunks. Records of the summary section (which repeats schemas and channels,
//! and indexes the data) are not copied: the writer writes a new summary for the new chunks.
//!
//! [`PARALLEL_CHUNKS`]: crate::mcap_log::read::PARALLEL_CHUNKS
//!
//! # Writing
//! Messages are gathered in batches (their data in one reused buffer) and handed to the
//! writer; for a log read in parallel, to a thread that owns the writer, so that the writer's
//! work runs beside reading and correcting. The writer is
//! [`ChunkWriter`](crate::mcap_log::chunk_write::ChunkWriter) for zstd and uncompressed chunks
//! (the new chunks compressed on worker threads for a log read in parallel, on the writer's own
//! thread otherwise), the `mcap` crate's writer for lz4 chunks and logs without chunks: the two
//! write the same bytes for the same calls. The writer is called with the same records in the
//! same order either way, so the output's bytes are the same as writing message by message on
//! one thread.
//!
//! # Finding the channel
//! A CDR JointState message is parsed in full only when its layout differs from the last one
//! that held the channel (see [`Layout`]): in a log of one publisher, once.

use super::Readings;
use crate::atomic::AtomicFile;
use crate::mcap_log::cdr::{JointFormat, JointState, Place};
use crate::mcap_log::chunk_write::ChunkWriter;
use crate::mcap_log::chunks::{self, Chunked, Fallback};
use crate::mcap_log::json::field_spans;
use crate::mcap_log::read::read_summary;
use crate::mcap_log::records::{self, Checked, StreamError};
use crate::ros2::encoding::Encoding;
use crate::{DamagedChunk, Error, Truncation};
use calib_core::AngleUnit;
use calib_core::correction::Correction;
use mcap::records::{Channel, Header, MessageHeader, Metadata, Record, SchemaHeader, op};
use mcap::sans_io::LinearReaderOptions;
use mcap::{Compression, McapError, McapResult, WriteOptions, Writer};
use std::borrow::Cow;
use std::collections::HashMap;
use std::fs::File;
use std::io::{self, BufReader, Seek, SeekFrom};
use std::ops::Range as Span;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;

/// Where a message holds the channel's readings, and their values.
enum Hit {
    /// A position of a JointState message, radians, and where it lies in the message.
    Joint { place: Place, value: f64 },
    /// The spans of the field's numbers in a JSON message (a key may repeat), in the JSON unit.
    Json { fields: Vec<(Span<usize>, f64)> },
}

/// Length of a message record's header: channel ID, sequence, log time, publish time.
const MESSAGE_HEADER: usize = 2 + 4 + 8 + 8;

/// A channel record's topic and, if calib reads its messages, how.
struct Topic {
    name: String,
    encoding: Option<Encoding>,
}

fn mcap_error(path: &Path, index: Option<u64>, channel: Option<&str>, message: String) -> Error {
    Error::Mcap {
        path: path.to_path_buf(),
        message_index: index,
        channel: channel.map(str::to_string),
        message,
    }
}

/// Where the records of a pass come from (see the module docs). Unboxed: one per pass.
#[allow(clippy::large_enum_variant)]
enum Source {
    /// Chunks decompressed on worker threads, every top-level record handed on, up to the data
    /// end record; the bytes walked so far.
    Chunked(Chunked, Arc<AtomicU64>),
    /// The streaming reader: from the start of the file, or, after the chunks read in parallel
    /// have reached the data end record, from there (the summary section).
    Linear(Checked<BufReader<File>>),
}

/// The streaming reader of `file` from byte `at`: from the start, or past the data end record
/// (then it expects no magic there).
fn linear(mut file: File, len: u64, at: u64, skip_damaged: bool) -> io::Result<Source> {
    file.seek(SeekFrom::Start(at))?;
    Ok(Source::Linear(Checked::new(
        BufReader::with_capacity(256 * 1024, file),
        LinearReaderOptions::default()
            .with_skip_start_magic(at > 0)
            // The readers' record length limit: the same messages as they read.
            .with_record_length_limit(crate::limits::mcap_record_limit(len)),
        skip_damaged,
    )))
}

/// What a pass has learnt of the log so far.
struct Walk<'a> {
    path: &'a Path,
    channel: &'a str,
    schemas: HashMap<u16, String>,
    /// By channel ID: a vector lookup per message.
    topics: Vec<Option<Topic>>,
    /// The topic carrying the channel, once met: a name on two topics is ambiguous.
    carrier: Option<String>,
    /// Messages met so far.
    messages: u64,
    /// The last CDR JointState message that held the channel (see [`Layout`]).
    layout: Option<Layout>,
}

/// A CDR JointState message holding the channel, on channel ID `channel_id`. Another message of
/// that channel of the same length whose bytes equal this one's but in the header's stamp and
/// the `position` elements parses the same — the same names, counts and offsets; no field
/// checked by the parse but the positions differs, and the stamp is not checked — so its reading
/// is at the same place, found without parsing it.
struct Layout {
    channel_id: u16,
    message: Vec<u8>,
    /// The `position` elements' span.
    positions: Span<usize>,
    place: Place,
}

/// Bytes 4–12 of a CDR JointState: the header's stamp, after the encapsulation header.
const STAMP: Span<usize> = 4..12;

impl Layout {
    /// Whether `data`, a message of channel `channel_id`, has this layout.
    fn fits(&self, channel_id: u16, data: &[u8]) -> bool {
        let m = &self.message;
        channel_id == self.channel_id
            && data.len() == m.len()
            && data[..STAMP.start] == m[..STAMP.start]
            && data[STAMP.end..self.positions.start] == m[STAMP.end..self.positions.start]
            && data[self.positions.end..] == m[self.positions.end..]
    }
}

impl Walk<'_> {
    /// Parses one record and hands it to `each` (see [`walk`]).
    fn record(
        &mut self,
        opcode: u8,
        data: &[u8],
        each: &mut impl FnMut(&Record, u64, Option<Hit>) -> Result<(), Error>,
    ) -> Result<(), Error> {
        let (path, channel, messages) = (self.path, self.channel, self.messages);
        let record = match opcode {
            // A message's header as `mcap::parse_record` reads it, without its per-field parsing
            // (a message too short for one goes there for its error): channel ID, sequence, log
            // time, publish time.
            op::MESSAGE if data.len() >= MESSAGE_HEADER => {
                let u64_at =
                    |i: usize| u64::from_le_bytes(data[i..i + 8].try_into().unwrap_or_default());
                Ok(Record::Message {
                    header: MessageHeader {
                        channel_id: u16::from_le_bytes([data[0], data[1]]),
                        sequence: u32::from_le_bytes(data[2..6].try_into().unwrap_or_default()),
                        log_time: u64_at(6),
                        publish_time: u64_at(14),
                    },
                    data: Cow::Borrowed(&data[MESSAGE_HEADER..]),
                })
            }
            _ => mcap::parse_record(opcode, data),
        }
        .map_err(|e| {
            mcap_error(
                path,
                Some(messages),
                None,
                format!("a record cannot be parsed ({e}); repair the file with `mcap recover`"),
            )
        })?;
        let mut hit = None;
        match &record {
            Record::Schema { header, .. } => {
                self.schemas.insert(header.id, header.name.clone());
            }
            Record::Channel(c) => {
                self.layout = None;
                let schema = self.schemas.get(&c.schema_id).map_or("", String::as_str);
                let id = usize::from(c.id);
                if self.topics.len() <= id {
                    self.topics.resize_with(id + 1, || None);
                }
                self.topics[id] = Some(Topic {
                    name: c.topic.clone(),
                    encoding: Encoding::from_names(&c.message_encoding, schema),
                });
            }
            Record::Message { header, data } => {
                let topic = self.topics.get(usize::from(header.channel_id));
                let topic = topic.and_then(Option::as_ref).ok_or_else(|| {
                    mcap_error(
                        path,
                        Some(messages),
                        None,
                        format!(
                            "the message's channel ID {} has no channel record before it; \
                             repair the file with `mcap recover`",
                            header.channel_id
                        ),
                    )
                })?;
                if matches!(topic.encoding, Some(Encoding::Scalar(_))) && topic.name == channel {
                    return Err(mcap_error(
                        path,
                        Some(messages),
                        Some(&topic.name),
                        "calib apply corrects JointState and JSON channels, not std_msgs \
                         scalar topics; correct the readings where they are published"
                            .into(),
                    ));
                }
                // A qualified name `TOPIC/NAME` names the joint or field `NAME` of that topic
                // only; a short name, the one of any topic carrying it.
                let member = channel
                    .strip_prefix(topic.name.as_str())
                    .and_then(|rest| rest.strip_prefix('/'))
                    .unwrap_or(channel);
                let error = |m| mcap_error(path, Some(messages), Some(&topic.name), m);
                hit = match &self.layout {
                    Some(layout) if layout.fits(header.channel_id, data) => {
                        let value = layout.place.read(data);
                        Some(Hit::Joint {
                            place: layout.place,
                            value: finite(value, member).map_err(error)?,
                        })
                    }
                    _ => {
                        let (hit, layout) = find(topic.encoding, data, member).map_err(error)?;
                        if let Some((positions, place)) = layout {
                            self.layout = Some(Layout {
                                channel_id: header.channel_id,
                                message: data.to_vec(),
                                positions,
                                place,
                            });
                        }
                        hit
                    }
                };
                if hit.is_some() {
                    match &self.carrier {
                        Some(other) if *other != topic.name => {
                            return Err(mcap_error(
                                path,
                                Some(messages),
                                Some(channel),
                                format!(
                                    "the channel appears on two topics (`{other}` and `{}`); \
                                     calib cannot tell which to correct: rename one of them",
                                    topic.name
                                ),
                            ));
                        }
                        Some(_) => {}
                        None => self.carrier = Some(topic.name.clone()),
                    }
                }
            }
            _ => {}
        }
        each(&record, messages, hit)?;
        if matches!(record, Record::Message { .. }) {
            self.messages += 1;
        }
        Ok(())
    }

    /// The error (or, for a file cut short, the truncation) the streaming reader stopped with;
    /// `consumed`: the bytes of the file it had read.
    fn stopped(&self, e: StreamError, consumed: u64) -> Result<Truncation, Error> {
        let messages = self.messages;
        Err(match e {
            StreamError::Mcap(McapError::UnexpectedEof) => {
                return Ok(Truncation {
                    byte_offset: consumed,
                    messages_read: messages,
                });
            }
            StreamError::Mcap(McapError::Io(source)) => Error::Io {
                path: self.path.to_path_buf(),
                source,
            },
            e @ (StreamError::Damaged(_) | StreamError::DataCrc) => mcap_error(
                self.path,
                Some(messages),
                None,
                format!(
                    "{e}; nothing was written: run with the `skip_damaged` option to leave the \
                     damaged chunk's messages out of the output, or repair the file"
                ),
            ),
            e => mcap_error(
                self.path,
                Some(messages),
                None,
                format!(
                    "the file is damaged here ({e}); repair it with `mcap recover` and apply \
                     to the repaired file"
                ),
            ),
        })
    }
}

/// One pass over the log's records in file order, each chunk's records after its CRC matched
/// (see the `records` module). `each(record, index, hit)` gets every record; for a message,
/// `index` is its 0-based position among the messages and `hit` says where it holds the
/// channel's readings, if it does. Returns where the file breaks off, if it does, and the damaged
/// chunks left out (with `skip_damaged`; otherwise the first is an error).
///
/// A log whose summary lists `parallel_chunks` chunks or more has its data section read by
/// [`Chunked`] (chunks decompressed and checked on worker threads) and its summary section by
/// the streaming reader; at the first irregularity in the data section the streaming reader
/// reads the file again from its start and skips the records already handed to `each`, so that
/// every record, error, truncation and damaged chunk is the streaming reader's own.
fn walk(
    path: &Path,
    channel: &str,
    skip_damaged: bool,
    parallel_chunks: usize,
    mut each: impl FnMut(&Record, u64, Option<Hit>) -> Result<(), Error>,
) -> Result<(Option<Truncation>, Vec<DamagedChunk>), Error> {
    let io = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut file = File::open(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    let parallel =
        records::read_summary(&mut file, len).is_some_and(|s| s.chunks >= parallel_chunks);
    let chunked = parallel
        .then(|| {
            let consumed = Arc::new(AtomicU64::new(0));
            let source = crate::source::FileSource::new(file.try_clone().ok()?).ok()?;
            let chunked = Chunked::every_record(
                crate::source::SourceCursor::new(Arc::new(source)),
                len,
                Arc::clone(&consumed),
                chunks::workers(),
            )?;
            Some(Source::Chunked(chunked, consumed))
        })
        .flatten();
    let mut source = match chunked {
        Some(chunked) => chunked,
        None => linear(file.try_clone().map_err(io)?, len, 0, skip_damaged).map_err(io)?,
    };
    let mut walk = Walk {
        path,
        channel,
        schemas: HashMap::new(),
        topics: Vec::new(),
        carrier: None,
        messages: 0,
        layout: None,
    };
    // Records handed on from the chunks read in parallel, which the streaming reader skips if
    // it takes over; where the streaming reader started.
    let (mut handed, mut skip, mut base) = (0u64, 0u64, 0u64);
    loop {
        match &mut source {
            Source::Chunked(chunked, consumed) => match chunked.next_record() {
                Ok((opcode, data)) => {
                    walk.record(opcode, data, &mut each)?;
                    handed += 1;
                    if opcode == op::DATA_END {
                        base = consumed.load(Ordering::Relaxed);
                        source = linear(file.try_clone().map_err(io)?, len, base, skip_damaged)
                            .map_err(io)?;
                    }
                }
                Err(Fallback) => {
                    source =
                        linear(file.try_clone().map_err(io)?, len, 0, skip_damaged).map_err(io)?;
                    skip = handed;
                }
            },
            Source::Linear(records) => match records.next_record() {
                None => return Ok((None, std::mem::take(&mut records.damaged))),
                Some(Ok(_)) if skip > 0 => skip -= 1,
                Some(Ok((opcode, data))) => walk.record(opcode, &data, &mut each)?,
                Some(Err(e)) => {
                    let truncated = walk.stopped(e, base + records.consumed)?;
                    return Ok((Some(truncated), std::mem::take(&mut records.damaged)));
                }
            },
        }
    }
}

/// `value`, the position of joint `channel`, if it is finite.
fn finite(value: f64, channel: &str) -> Result<f64, String> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(format!(
            "the position of joint `{channel}` is {value}, not a finite number; cut the damaged \
             part out of the recording"
        ))
    }
}

/// What [`find`] found: the hit, and for a CDR JointState holding the channel, the span of its
/// `position` elements and the reading's place (a [`Layout`]).
type Found = (Option<Hit>, Option<(Span<usize>, Place)>);

/// Where `data` (a message of this encoding) holds `channel`'s readings, if it does.
fn find(encoding: Option<Encoding>, data: &[u8], channel: &str) -> Result<Found, String> {
    match encoding {
        // A scalar topic's channel is the topic itself, refused by the caller.
        None | Some(Encoding::Scalar(_) | Encoding::Field) => Ok((None, None)),
        Some(Encoding::JointState(format)) => {
            let message = JointState::parse_as(data, format).map_err(|e| e.to_string())?;
            let Some(index) = message.joint(channel) else {
                return Ok((None, None));
            };
            if format == JointFormat::Dynamic {
                return Err(format!(
                    "joint `{channel}` is carried by DynamicJointState messages, which calib \
                     apply does not rewrite; correct a JointState or JSON channel"
                ));
            }
            let place = message.place(index).ok_or_else(|| {
                format!(
                    "the JointState message names {} joints but has {} positions, none for \
                     joint `{channel}`; the publisher must give a position for every joint",
                    message.name_count,
                    message.position_count()
                )
            })?;
            let value = finite(place.read(data), channel)?;
            let layout = (format == JointFormat::Cdr).then(|| (message.positions_span(), place));
            Ok((Some(Hit::Joint { place, value }), layout))
        }
        Some(Encoding::Json) => {
            let spans = field_spans(data, channel)?;
            if spans.is_empty() {
                return Ok((None, None));
            }
            let mut fields = Vec::with_capacity(spans.len());
            for span in spans {
                let text = std::str::from_utf8(&data[span.clone()]).unwrap_or("");
                let value = text.parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(|| {
                    format!(
                        "field `{channel}` is `{text}`, not a number; every message must give a \
                         number for the channel"
                    )
                })?;
                fields.push((span, value));
            }
            Ok((Some(Hit::Json { fields }), None))
        }
    }
}

/// The range of the channel's readings: radians for JointState, `json_unit` for JSON. The chunks
/// of a log whose summary lists `parallel_chunks` chunks or more are read in parallel (see
/// [`walk`]; [`PARALLEL_CHUNKS`](crate::mcap_log::read::PARALLEL_CHUNKS) but in tests).
pub(super) fn scan(
    path: &Path,
    channel: &str,
    json_unit: AngleUnit,
    skip_damaged: bool,
    parallel_chunks: usize,
) -> Result<Readings, Error> {
    let mut range = Readings::new(json_unit);
    walk(path, channel, skip_damaged, parallel_chunks, |_, _, hit| {
        match hit {
            Some(Hit::Joint { value, .. }) => range.add(value, AngleUnit::Rad),
            Some(Hit::Json { fields }) => {
                for (_, v) in fields {
                    range.add(v, json_unit);
                }
            }
            None => {}
        }
        Ok(())
    })?;
    Ok(range)
}

/// What [`rewrite`] did.
pub(super) struct Rewritten {
    pub readings: u64,
    pub copied: u64,
    pub truncated: Option<Truncation>,
    pub damaged: Vec<DamagedChunk>,
    /// With `keep`: the topics the corrected messages were copied to.
    pub beside: Vec<String>,
}

/// The channels `keep` adds: one per input channel carrying the readings, on
/// [`corrected_topic`](super::corrected_topic) with the same schema, encoding and metadata. Their
/// IDs count down from the largest, away from the input's, which count up from 0 or 1.
struct Companions {
    /// The input's channels by ID, as their records came.
    channels: HashMap<u16, mcap::records::Channel>,
    /// The companion of each input channel given one.
    added: HashMap<u16, u16>,
    next: u16,
}

impl Companions {
    fn new() -> Self {
        Companions {
            channels: HashMap::new(),
            added: HashMap::new(),
            next: u16::MAX,
        }
    }

    /// The companion of channel `id`, and its channel record if it is new (to be written before
    /// its first message); `None` for a channel whose record was not met or when IDs run out.
    fn of(&mut self, id: u16) -> Option<(u16, Option<mcap::records::Channel>)> {
        if let Some(&c) = self.added.get(&id) {
            return Some((c, None));
        }
        let input = self.channels.get(&id)?;
        let companion = self.next;
        if self.channels.contains_key(&companion) {
            return None;
        }
        self.next -= 1;
        self.added.insert(id, companion);
        Some((
            companion,
            Some(mcap::records::Channel {
                id: companion,
                topic: super::corrected_topic(&input.topic),
                ..input.clone()
            }),
        ))
    }
}

/// How the copy is written.
enum Plan {
    /// Chunks compressed with zstd (or not compressed, `zstd` false) by [`ChunkWriter`], on
    /// worker threads for a log read in parallel.
    Chunks { zstd: bool },
    /// lz4 chunks, or no chunks: the `mcap` crate's writer with these options.
    Crate(WriteOptions),
}

/// How to write a copy of the log at `path`: its chunks' compression as its summary lists them
/// (zstd if it has no summary), with its header's profile and library. Also whether the summary
/// lists `parallel_chunks` chunks or more (then the log is read in parallel, and written on a
/// thread of its own with its chunks compressed on worker threads).
fn plan(path: &Path, parallel_chunks: usize) -> Result<(Plan, bool), Error> {
    let mut file = File::open(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let len = file
        .metadata()
        .map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?
        .len();
    let summary = read_summary(&mut file, len);
    let parallel = summary
        .as_ref()
        .is_some_and(|s| s.chunk_indexes.len() >= parallel_chunks);
    let zstd = Plan::Chunks { zstd: true };
    let plan = match summary {
        Some(summary) => match summary.chunk_indexes.first() {
            Some(chunk) => match chunk.compression.as_str() {
                "lz4" => Plan::Crate(WriteOptions::new().compression(Some(Compression::Lz4))),
                "" => Plan::Chunks { zstd: false },
                _ => zstd,
            },
            None if summary.stats.is_some_and(|s| s.message_count > 0) => {
                Plan::Crate(WriteOptions::new().use_chunks(false))
            }
            None => zstd,
        },
        None => zstd,
    };
    Ok((plan, parallel))
}

/// The writer of the copy for `plan`, its file started with `header` (the input's profile and
/// library).
fn sink(
    plan: Plan,
    header: &Header,
    file: AtomicFile,
    threaded: bool,
) -> Result<Box<dyn Sink>, McapError> {
    Ok(match plan {
        Plan::Chunks { zstd } => Box::new(ChunkWriter::new(
            file,
            header,
            zstd,
            WriteOptions::DEFAULT_CHUNK_SIZE,
            if threaded { chunks::workers() } else { 0 },
        )?),
        Plan::Crate(options) => Box::new(
            options
                .profile(header.profile.clone())
                .library(header.library.clone())
                // zstd (never used here) on the calling thread.
                .compression_threads(0)
                .create(file)?,
        ),
    })
}

/// The calls the copy makes of its writer: [`ChunkWriter`] or the `mcap` crate's, which take
/// the same calls and write the same bytes.
trait Sink: Send {
    fn schema(&mut self, header: &SchemaHeader, data: &[u8]) -> McapResult<()>;
    fn channel(&mut self, c: &Channel) -> McapResult<()>;
    fn message(&mut self, header: &MessageHeader, data: &[u8]) -> McapResult<()>;
    fn metadata(&mut self, m: &Metadata) -> McapResult<()>;
    fn attach(&mut self, a: &mcap::Attachment) -> McapResult<()>;
    fn private(&mut self, opcode: u8, data: &[u8]) -> McapResult<()>;
    /// Writes the summary and footer.
    fn finish(&mut self) -> McapResult<()>;
    fn into_file(self: Box<Self>) -> AtomicFile;
}

impl Sink for ChunkWriter<AtomicFile> {
    fn schema(&mut self, header: &SchemaHeader, data: &[u8]) -> McapResult<()> {
        self.add_schema_with_id(header.id, &header.name, &header.encoding, data)
            .map(drop)
    }
    fn channel(&mut self, c: &Channel) -> McapResult<()> {
        self.add_channel_with_id(
            c.id,
            c.schema_id,
            &c.topic,
            &c.message_encoding,
            &c.metadata,
        )
        .map(drop)
    }
    fn message(&mut self, header: &MessageHeader, data: &[u8]) -> McapResult<()> {
        self.write_to_known_channel(header, data)
    }
    fn metadata(&mut self, m: &Metadata) -> McapResult<()> {
        self.write_metadata(m)
    }
    fn attach(&mut self, a: &mcap::Attachment) -> McapResult<()> {
        ChunkWriter::attach(self, a)
    }
    fn private(&mut self, opcode: u8, data: &[u8]) -> McapResult<()> {
        self.write_private_record(opcode, data)
    }
    fn finish(&mut self) -> McapResult<()> {
        ChunkWriter::finish(self)
    }
    fn into_file(self: Box<Self>) -> AtomicFile {
        self.into_inner()
    }
}

impl Sink for Writer<AtomicFile> {
    fn schema(&mut self, header: &SchemaHeader, data: &[u8]) -> McapResult<()> {
        self.add_schema_with_id(header.id, &header.name, &header.encoding, data)
            .map(drop)
    }
    fn channel(&mut self, c: &Channel) -> McapResult<()> {
        self.add_channel_with_id(
            c.id,
            c.schema_id,
            &c.topic,
            &c.message_encoding,
            &c.metadata,
        )
        .map(drop)
    }
    fn message(&mut self, header: &MessageHeader, data: &[u8]) -> McapResult<()> {
        self.write_to_known_channel(header, data)
    }
    fn metadata(&mut self, m: &Metadata) -> McapResult<()> {
        self.write_metadata(m)
    }
    fn attach(&mut self, a: &mcap::Attachment) -> McapResult<()> {
        Writer::attach(self, a)
    }
    fn private(&mut self, opcode: u8, data: &[u8]) -> McapResult<()> {
        self.write_private_record(opcode, data, Default::default())
    }
    fn finish(&mut self) -> McapResult<()> {
        Writer::finish(self).map(drop)
    }
    fn into_file(self: Box<Self>) -> AtomicFile {
        self.into_inner()
    }
}

/// Messages for the writer, gathered so that it is handed them in bulk: their headers, and their
/// data one after another in one buffer (reused from batch to batch: no allocation per message).
#[derive(Default)]
struct Batch {
    /// The index among the log's messages of the first.
    first: u64,
    /// Each message's header and the end of its data in `data`.
    headers: Vec<(MessageHeader, usize)>,
    data: Vec<u8>,
}

impl Batch {
    /// Bytes or messages gathered before the batch is handed on, whichever comes first.
    const BYTES: usize = 256 * 1024;
    const MESSAGES: usize = 4096;

    fn full(&self) -> bool {
        self.data.len() >= Self::BYTES || self.headers.len() >= Self::MESSAGES
    }
}

/// What the writer is handed, in file order.
enum Out {
    Messages(Batch),
    /// A schema, channel, metadata, attachment or private record.
    Record(Record<'static>),
}

/// A copy of `record` to hand to the writer if the copy keeps it: a schema, channel, metadata,
/// attachment or private record.
fn copied(record: &Record) -> Option<Record<'static>> {
    let owned = |data: &Cow<[u8]>| Cow::Owned(data.to_vec());
    Some(match record {
        Record::Schema { header, data } => Record::Schema {
            header: header.clone(),
            data: owned(data),
        },
        Record::Channel(c) => Record::Channel(c.clone()),
        Record::Metadata(m) => Record::Metadata(m.clone()),
        Record::Attachment { header, data, crc } => Record::Attachment {
            header: header.clone(),
            data: owned(data),
            crc: *crc,
        },
        Record::Unknown { opcode, data } => Record::Unknown {
            opcode: *opcode,
            data: owned(data),
        },
        _ => return None,
    })
}

/// A write that failed: the index of the message, if it was one, and the error.
type Failed = (Option<u64>, McapError);

/// Writes `out`: the calls the copy makes of its writer, in order.
fn write(w: &mut dyn Sink, out: &Out) -> Result<(), Failed> {
    let record = match out {
        Out::Messages(batch) => {
            let mut from = 0;
            for (i, (header, end)) in batch.headers.iter().enumerate() {
                w.message(header, &batch.data[from..*end])
                    .map_err(|e| (Some(batch.first + i as u64), e))?;
                from = *end;
            }
            return Ok(());
        }
        Out::Record(record) => record,
    };
    let result = match record {
        Record::Schema { header, data } => w.schema(header, data),
        Record::Channel(c) => w.channel(c),
        Record::Metadata(m) => w.metadata(m),
        Record::Attachment { header, data, .. } => w.attach(&mcap::Attachment {
            log_time: header.log_time,
            create_time: header.create_time,
            name: header.name.clone(),
            media_type: header.media_type.clone(),
            data: Cow::Borrowed(data),
        }),
        Record::Unknown { opcode, data } => w.private(*opcode, data),
        // Not handed here (see `copied`).
        _ => Ok(()),
    };
    result.map_err(|e| (None, e))
}

/// What the writer's thread gives back: the writer, and its first error.
type Written = (Box<dyn Sink>, Result<(), Failed>);

/// Records handed to the writer's thread and not yet written.
const QUEUE: usize = 4;

/// The writer of the copy: called in turn (a log read by the streaming reader), or on a thread
/// of its own (a log whose chunks are read in parallel), so that the writer's work — above all
/// compressing the new chunks — runs beside reading and correcting the log. The calls, and so
/// the output's bytes, are the same either way.
struct Output {
    /// Called in turn.
    inline: Option<Box<dyn Sink>>,
    /// To the thread.
    queue: Option<SyncSender<Out>>,
    /// Batches written, back from the thread for reuse.
    spent: Option<Receiver<Batch>>,
    thread: Option<JoinHandle<Written>>,
    /// A batch to reuse (inline).
    spare: Option<Batch>,
}

/// The error of a writer's thread that ended without an answer (it panicked).
fn thread_failed() -> Failed {
    (
        None,
        McapError::Io(io::Error::other("the thread writing the output stopped")),
    )
}

impl Output {
    /// Writes with `writer`: on a thread of its own with `threaded`, if it can be started.
    fn new(writer: Box<dyn Sink>, threaded: bool) -> io::Result<Self> {
        let mut output = Output {
            inline: None,
            queue: None,
            spent: None,
            thread: None,
            spare: None,
        };
        if !threaded {
            output.inline = Some(writer);
            return Ok(output);
        }
        let (queue, todo) = sync_channel::<Out>(QUEUE);
        let (spend, spent) = sync_channel::<Batch>(QUEUE);
        let thread = std::thread::Builder::new()
            .name("calib-apply-write".into())
            .spawn(move || {
                let mut writer = writer;
                while let Ok(out) = todo.recv() {
                    if let Err(e) = write(writer.as_mut(), &out) {
                        return (writer, Err(e));
                    }
                    if let Out::Messages(batch) = out {
                        // A full return queue: the batch is dropped, the reader makes another.
                        let _ = spend.try_send(batch);
                    }
                }
                (writer, Ok(()))
            })?;
        output.queue = Some(queue);
        output.spent = Some(spent);
        output.thread = Some(thread);
        Ok(output)
    }

    /// An empty batch, reused where one has come back.
    fn batch(&mut self, first: u64) -> Batch {
        let mut batch = match (&self.spent, self.spare.take()) {
            (_, Some(batch)) => batch,
            (Some(spent), None) => spent.try_recv().unwrap_or_default(),
            (None, None) => Batch::default(),
        };
        batch.first = first;
        batch.headers.clear();
        batch.data.clear();
        batch
    }

    /// Writes `out` (or hands it to the thread).
    fn put(&mut self, out: Out) -> Result<(), Failed> {
        if let Some(w) = self.inline.as_mut() {
            write(w.as_mut(), &out)?;
            if let Out::Messages(batch) = out {
                self.spare = Some(batch);
            }
            return Ok(());
        }
        let sent = self.queue.as_ref().map(|queue| queue.send(out));
        match sent {
            Some(Ok(())) => Ok(()),
            // The thread has stopped at an error: its error.
            _ => Err(self.join().err().unwrap_or_else(thread_failed)),
        }
    }

    /// The writer, once everything handed on is written; the first error of the thread.
    fn join(&mut self) -> Result<Box<dyn Sink>, Failed> {
        if let Some(w) = self.inline.take() {
            return Ok(w);
        }
        self.queue = None;
        let (writer, result) = self
            .thread
            .take()
            .ok_or_else(thread_failed)?
            .join()
            .map_err(|_| thread_failed())?;
        result.map(|()| writer)
    }
}

impl Drop for Output {
    fn drop(&mut self) {
        // An error elsewhere: the thread stops, and the temporary output is removed before the
        // error is reported.
        let _ = self.join();
    }
}

/// Writes `output`, a copy of `input` with the channel's readings corrected: JointState
/// positions by `joint_fix` (radians), JSON fields by `json_fix`. A log whose summary lists
/// `parallel_chunks` chunks or more is read in parallel and written on a thread of its own.
pub(super) fn rewrite(
    input: &Path,
    output: &Path,
    channel: &str,
    fix: (&Correction, &Correction),
    skip_damaged: bool,
    keep: bool,
    parallel_chunks: usize,
) -> Result<Rewritten, Error> {
    let (joint_fix, json_fix) = fix;
    let mut companions = Companions::new();
    let mut out: Option<Output> = None;
    let mut batch = Batch::default();
    let mut done = Rewritten {
        readings: 0,
        copied: 0,
        truncated: None,
        damaged: Vec::new(),
        beside: Vec::new(),
    };
    let mut number = ryu::Buffer::new();
    let fail = |(index, e): Failed| match e {
        McapError::Io(source) => Error::Io {
            path: output.to_path_buf(),
            source,
        },
        e => mcap_error(
            output,
            index,
            None,
            format!("cannot write the MCAP file ({e})"),
        ),
    };
    let each = |record: &Record, index: u64, hit: Option<Hit>| {
        let w = match (record, out.as_mut()) {
            (Record::Header(header), None) => {
                let (plan, threaded) = plan(input, parallel_chunks)?;
                let writer = sink(plan, header, AtomicFile::create(output)?, threaded)
                    .map_err(|e| fail((None, e)))?;
                out = Some(Output::new(writer, threaded).map_err(|e| fail((None, e.into())))?);
                return Ok(());
            }
            (_, Some(w)) => w,
            (_, None) => {
                return Err(mcap_error(
                    input,
                    None,
                    None,
                    "the file has no header record; repair it with `mcap recover`".into(),
                ));
            }
        };
        if let Record::Channel(c) = record {
            companions.channels.insert(c.id, c.clone());
        }
        let Record::Message { header, data } = record else {
            // The rest is structure (chunks, indexes, summary, footer) the writer makes anew, or
            // a second header, which the specification does not allow and which is dropped.
            let Some(copy) = copied(record) else {
                return Ok(());
            };
            if !batch.headers.is_empty() {
                let next = w.batch(index);
                w.put(Out::Messages(std::mem::replace(&mut batch, next)))
                    .map_err(fail)?;
            }
            return w.put(Out::Record(copy)).map_err(fail);
        };
        let mut header = *header;
        if let (true, Some(_)) = (keep, &hit) {
            // The original first, unchanged; the corrected copy follows on the companion.
            let (companion, new) = companions.of(header.channel_id).ok_or_else(|| {
                mcap_error(
                    input,
                    Some(index),
                    None,
                    "the `keep` option needs a channel for the corrected copies and the log uses \
                     every channel ID, or its message comes before its channel record; correct it \
                     without the `keep` option"
                        .into(),
                )
            })?;
            if let Some(channel) = new {
                done.beside.push(channel.topic.clone());
                if !batch.headers.is_empty() {
                    let next = w.batch(index);
                    w.put(Out::Messages(std::mem::replace(&mut batch, next)))
                        .map_err(fail)?;
                }
                w.put(Out::Record(Record::Channel(channel))).map_err(fail)?;
            }
            if batch.headers.is_empty() {
                batch.first = index;
            }
            batch.data.extend_from_slice(data);
            batch.headers.push((header, batch.data.len()));
            header.channel_id = companion;
        }
        if batch.headers.is_empty() {
            batch.first = index;
        }
        let start = batch.data.len();
        match hit {
            None => {
                batch.data.extend_from_slice(data);
                done.copied += 1;
            }
            Some(Hit::Joint { place, value }) => {
                batch.data.extend_from_slice(data);
                place.write(&mut batch.data[start..], joint_fix.apply(value));
                done.readings += 1;
            }
            Some(Hit::Json { fields }) => {
                let mut from = 0;
                for (span, value) in &fields {
                    batch.data.extend_from_slice(&data[from..span.start]);
                    batch
                        .data
                        .extend_from_slice(number.format_finite(json_fix.apply(*value)).as_bytes());
                    from = span.end;
                }
                batch.data.extend_from_slice(&data[from..]);
                done.readings += fields.len() as u64;
            }
        }
        batch.headers.push((header, batch.data.len()));
        if batch.full() {
            let next = w.batch(index + 1);
            w.put(Out::Messages(std::mem::replace(&mut batch, next)))
                .map_err(fail)?;
        }
        Ok(())
    };
    (done.truncated, done.damaged) = walk(input, channel, skip_damaged, parallel_chunks, each)?;
    let Some(mut out) = out else {
        return Err(Error::Empty {
            path: input.to_path_buf(),
        });
    };
    if !batch.headers.is_empty() {
        out.put(Out::Messages(batch)).map_err(fail)?;
    }
    let mut writer = out.join().map_err(fail)?;
    writer.finish().map_err(|e| fail((None, e)))?;
    writer.into_file().commit()?;
    Ok(done)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcap_log::JOINT_STATE_MSGDEF;
    use crate::mcap_log::read::PARALLEL_CHUNKS;
    use calib_core::ErrorMap;
    use calib_core::correction::Wrapping;
    use std::collections::BTreeMap;

    /// A little-endian CDR JointState of joints `a` and `b`.
    fn joint_state(i: u32, a: f64, b: f64) -> Vec<u8> {
        let mut m = vec![0u8, 1, 0, 0];
        m.extend(i.to_le_bytes()); // stamp.sec
        m.extend(0u32.to_le_bytes()); // stamp.nanosec
        m.extend(1u32.to_le_bytes()); // frame_id "" and padding to 4
        m.extend([0, 0, 0, 0]);
        m.extend(2u32.to_le_bytes());
        m.extend(2u32.to_le_bytes());
        m.extend(*b"a\0\0\0");
        m.extend(2u32.to_le_bytes());
        m.extend(*b"b\0\0\0");
        m.extend(2u32.to_le_bytes()); // ends 40 bytes after the origin: 8-aligned already
        m.extend(a.to_le_bytes());
        m.extend(b.to_le_bytes());
        m.extend(0u32.to_le_bytes());
        m.extend(0u32.to_le_bytes());
        m
    }

    /// A JointState log of `n` messages in zstd chunks of about 4 KiB (60 messages), with
    /// metadata, an attachment and a private record between chunks.
    fn log(path: &Path, n: u32) {
        let file = std::io::BufWriter::new(File::create(path).unwrap());
        let mut w = WriteOptions::new()
            .profile("ros2")
            .compression(Some(Compression::Zstd))
            .chunk_size(Some(4096))
            .create(file)
            .unwrap();
        let schema = w
            .add_schema(
                "sensor_msgs/msg/JointState",
                "ros2msg",
                JOINT_STATE_MSGDEF.as_bytes(),
            )
            .unwrap();
        let js = w
            .add_channel(schema, "/joint_states", "cdr", &BTreeMap::new())
            .unwrap();
        for i in 0..n {
            let a = (f64::from(i) * 1e-3).rem_euclid(std::f64::consts::TAU);
            let header = MessageHeader {
                channel_id: js,
                sequence: i,
                log_time: 1_000_000 + u64::from(i),
                publish_time: 1_000_000 + u64::from(i),
            };
            w.write_to_known_channel(&header, &joint_state(i, a, a.sin()))
                .unwrap();
            match i {
                500 => w
                    .write_metadata(&mcap::records::Metadata {
                        name: "run".into(),
                        metadata: BTreeMap::from([("operator".into(), "kim".into())]),
                    })
                    .unwrap(),
                1500 => w
                    .attach(&mcap::Attachment {
                        log_time: 5,
                        create_time: 6,
                        name: "rig.urdf".into(),
                        media_type: "text/xml".into(),
                        data: Cow::Borrowed(b"<robot/>"),
                    })
                    .unwrap(),
                2500 => w
                    .write_private_record(0x90, b"vendor", Default::default())
                    .unwrap(),
                _ => {}
            }
        }
        w.finish().unwrap();
    }

    /// A little-endian CDR JointState of joints `names` with `positions` and `velocity`.
    fn joint_state_of(i: u32, names: &[&str], positions: &[f64], velocity: &[f64]) -> Vec<u8> {
        // Pads to a multiple of `n` from the CDR origin, after the 4-byte encapsulation.
        let align = |m: &mut Vec<u8>, n: usize| {
            while (m.len() - 4) % n != 0 {
                m.push(0);
            }
        };
        let mut m = vec![0u8, 1, 0, 0];
        m.extend(i.to_le_bytes());
        m.extend((i * 7).to_le_bytes());
        m.extend(1u32.to_le_bytes());
        m.push(0);
        align(&mut m, 4);
        m.extend((names.len() as u32).to_le_bytes());
        for name in names {
            m.extend((name.len() as u32 + 1).to_le_bytes());
            m.extend(name.as_bytes());
            m.push(0);
            align(&mut m, 4);
        }
        for values in [positions, velocity, &[]] {
            m.extend((values.len() as u32).to_le_bytes());
            if !values.is_empty() {
                align(&mut m, 8);
            }
            for v in values {
                m.extend(v.to_le_bytes());
            }
        }
        m
    }

    /// Joint `a` of a log whose messages change layout — the joints' order, a velocity that
    /// differs from message to message, a name that changes length — is corrected in every
    /// message, wherever it lies, and every other byte copied; a position that is not finite,
    /// after a thousand messages of the same layout, is an error naming its message.
    #[test]
    fn a_joint_is_found_in_every_message_whatever_its_layout() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("layouts.mcap");
        let a = |i: u32| 0.001 * f64::from(i);
        let message = |i: u32, nan_at: Option<u32>| {
            let x = if Some(i) == nan_at { f64::NAN } else { a(i) };
            match i / 1000 {
                0 => joint_state_of(i, &["a", "b"], &[x, 1.0], &[]),
                1 => joint_state_of(i, &["b", "a"], &[1.0, x], &[]),
                2 => joint_state_of(i, &["a", "b"], &[x, 1.0], &[f64::from(i), 0.5]),
                _ => joint_state_of(i, &["a", "bearing"], &[x, 1.0], &[]),
            }
        };
        let write = |nan_at: Option<u32>| {
            let file = std::io::BufWriter::new(File::create(&path).unwrap());
            let mut w = WriteOptions::new()
                .profile("ros2")
                .chunk_size(Some(4096))
                .create(file)
                .unwrap();
            let schema = w
                .add_schema(
                    "sensor_msgs/msg/JointState",
                    "ros2msg",
                    JOINT_STATE_MSGDEF.as_bytes(),
                )
                .unwrap();
            let js = w
                .add_channel(schema, "/joint_states", "cdr", &BTreeMap::new())
                .unwrap();
            for i in 0..4000 {
                let header = MessageHeader {
                    channel_id: js,
                    sequence: i,
                    log_time: u64::from(i),
                    publish_time: u64::from(i),
                };
                w.write_to_known_channel(&header, &message(i, nan_at))
                    .unwrap();
            }
            w.finish().unwrap();
        };
        write(None);
        let map = ErrorMap::new((0..72).map(|i| 1e-5 * f64::from(1 + i % 7)).collect());
        let fix = Correction::new(map, AngleUnit::Rad, Wrapping::Positive);
        for parallel_chunks in [PARALLEL_CHUNKS, usize::MAX] {
            let out = dir.path().join(format!("out-{parallel_chunks}.mcap"));
            let done = rewrite(
                &path,
                &out,
                "a",
                (&fix, &fix),
                false,
                false,
                parallel_chunks,
            )
            .unwrap();
            assert_eq!(done.readings, 4000);
            let bytes = std::fs::read(&out).unwrap();
            let copied: Vec<_> = mcap::MessageStream::new(&bytes)
                .unwrap()
                .map(|m| m.unwrap().data.into_owned())
                .collect();
            assert_eq!(copied.len(), 4000);
            for (i, got) in (0..4000).zip(&copied) {
                let expected = message(i, None);
                let js = JointState::parse(&expected).unwrap();
                let place = js.place(js.joint("a").unwrap()).unwrap();
                let mut want = expected.clone();
                place.write(&mut want, fix.apply(a(i)));
                assert!(*got == want, "message {i}");
                assert_ne!(*got, expected, "message {i} corrected");
            }
        }
        write(Some(1500));
        let out = dir.path().join("nan.mcap");
        let e = rewrite(
            &path,
            &out,
            "a",
            (&fix, &fix),
            false,
            false,
            PARALLEL_CHUNKS,
        )
        .err()
        .unwrap()
        .to_string();
        assert!(
            e.contains("not a finite number") && e.contains("1500"),
            "{e}"
        );
        assert!(!out.exists());
    }

    /// Offsets and lengths of the top-level chunk records of MCAP `bytes`.
    fn chunk_records(bytes: &[u8]) -> Vec<(usize, usize)> {
        let mut at = 8;
        let mut found = Vec::new();
        while at + 9 <= bytes.len() && bytes[at] != op::DATA_END {
            let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
            if bytes[at] == op::CHUNK {
                found.push((at, 9 + len));
            }
            at += 9 + len;
        }
        found
    }

    /// `calib apply` of `path` (joint `a`, a 72-point map) with chunks read in parallel where
    /// the log has `parallel_chunks` or more: what it reports (or its error) and the output.
    fn apply(path: &Path, skip_damaged: bool, parallel_chunks: usize) -> (String, Vec<u8>) {
        let out = path.with_extension(format!("out-{parallel_chunks}.mcap"));
        let map = ErrorMap::new((0..72).map(|i| 1e-5 * f64::from(i % 7)).collect());
        let fix = Correction::new(map, AngleUnit::Rad, Wrapping::Positive);
        let done =
            scan(path, "a", AngleUnit::Deg, skip_damaged, parallel_chunks).and_then(|range| {
                let done = rewrite(
                    path,
                    &out,
                    "a",
                    (&fix, &fix),
                    skip_damaged,
                    false,
                    parallel_chunks,
                )?;
                Ok((range, done))
            });
        match done {
            Ok((range, done)) => (
                format!(
                    "{range:?} {} {} {:?} {:?}",
                    done.readings, done.copied, done.truncated, done.damaged
                ),
                std::fs::read(&out).unwrap(),
            ),
            Err(e) => {
                assert!(!out.exists(), "{e}: no output");
                (e.to_string(), Vec::new())
            }
        }
    }

    /// Chunks read in parallel hand on every record the streaming reader hands on, up to the
    /// data end record.
    #[test]
    fn every_record_of_the_data_section_is_handed_on_as_the_streaming_reader_does() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.mcap");
        log(&path, 3000);
        let len = std::fs::metadata(&path).unwrap().len();
        let Source::Linear(mut linear) = linear(File::open(&path).unwrap(), len, 0, false).unwrap()
        else {
            unreachable!("the streaming reader")
        };
        let consumed = Arc::new(AtomicU64::new(0));
        let mut chunked = Chunked::every_record(
            crate::source::SourceCursor::new(Arc::new(
                crate::source::FileSource::open(&path).unwrap(),
            )),
            len,
            consumed,
            2,
        )
        .unwrap();
        let mut opcodes = Vec::new();
        loop {
            let (opcode, data) = chunked.next_record().expect("no fallback");
            let expected = linear.next_record().unwrap().unwrap();
            assert_eq!((opcode, data), (expected.0, expected.1.as_slice()));
            opcodes.push(opcode);
            if opcode == op::DATA_END {
                break;
            }
        }
        for opcode in [
            op::HEADER,
            op::METADATA,
            op::ATTACHMENT,
            0x90,
            op::MESSAGE_INDEX,
        ] {
            assert!(opcodes.contains(&opcode), "{opcode:#x}");
        }
        assert_eq!(opcodes.iter().filter(|&&o| o == op::MESSAGE).count(), 3000);
    }

    /// The copy of a log of many chunks is the same, byte for byte, whether its chunks are read
    /// in parallel and it is written on a thread of its own or it is read and written in turn
    /// — and so are the errors, truncation and damaged chunks left out.
    #[test]
    fn chunks_read_in_parallel_give_the_streaming_readers_copy() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.mcap");
        log(&path, 3000);
        let good = std::fs::read(&path).unwrap();
        let chunks = chunk_records(&good);
        assert!(chunks.len() >= 40, "{} chunks", chunks.len());
        let streaming = apply(&path, false, usize::MAX);
        assert_eq!(apply(&path, false, PARALLEL_CHUNKS), streaming);
        assert!(streaming.0.contains(" 3000 0 None []"), "{}", streaming.0);
        // The copy holds every message, metadata record and attachment.
        let copy = mcap::MessageStream::new(&streaming.1).unwrap().count();
        assert_eq!(copy, 3000);
        let summary = mcap::Summary::read(&streaming.1).unwrap().unwrap();
        assert_eq!(
            (
                summary.metadata_indexes.len(),
                summary.attachment_indexes.len()
            ),
            (1, 1)
        );
        // A damaged chunk: its compressed data, or its CRC.
        let (at, len) = chunks[chunks.len() / 2];
        for (name, offset) in [("data", at + len - 8), ("crc", at + 9 + 24)] {
            let mut bytes = good.clone();
            bytes[offset] ^= 0x10;
            let bad = dir.path().join(format!("{name}.mcap"));
            std::fs::write(&bad, &bytes).unwrap();
            for skip_damaged in [false, true] {
                let streaming = apply(&bad, skip_damaged, usize::MAX);
                assert_eq!(apply(&bad, skip_damaged, PARALLEL_CHUNKS), streaming);
                if skip_damaged {
                    assert!(
                        streaming.0.contains("DamagedChunk"),
                        "{name}: {}",
                        streaming.0
                    );
                } else {
                    assert!(
                        streaming.0.contains("the `skip_damaged` option"),
                        "{name}: {}",
                        streaming.0
                    );
                }
            }
        }
        // A truncated file: no summary, so the streaming reader (the writer called in turn).
        let cut = dir.path().join("cut.mcap");
        std::fs::write(&cut, &good[..good.len() * 2 / 3]).unwrap();
        let streaming = apply(&cut, false, usize::MAX);
        assert_eq!(apply(&cut, false, PARALLEL_CHUNKS), streaming);
        assert!(streaming.0.contains("Some(Truncation"), "{}", streaming.0);
    }
}
