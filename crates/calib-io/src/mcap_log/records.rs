//! The MCAP records calib reads — schemas, channels, messages and statistics — with every length
//! field inside a record checked against the record's own length before it is parsed.
//!
//! The `mcap` crate parses a string or byte field by reserving the length its `u32` prefix claims,
//! so a damaged file whose channel topic claims 4 GB makes it allocate 4 GB (found by fuzzing).
//! Record lengths themselves are bounded by the reader options (no record longer than the file or
//! its chunk). Here the records' inner fields are walked first and parsed only when every length
//! fits; records calib does not need (attachments, metadata, indexes) are skipped unparsed.
//!
//! # Checksums
//! Every reader path goes through [`Checked`], which checks the CRC-32 the file records for each
//! chunk (over its uncompressed records) and for the whole data section. A chunk's records are held
//! back until the chunk has ended and its CRC matched, so nothing from a damaged chunk reaches a
//! calibration: one flipped bit in a zstd chunk can decompress to other, valid-looking readings.
//! A damaged chunk is an error naming its byte offset and its messages' log times, or, when the
//! caller asks to skip damaged chunks, it is left out and listed in
//! [`ReadDiagnostics::damaged_chunks`](crate::ReadDiagnostics::damaged_chunks). A chunk cut short
//! by the end of the file cannot be checked: its records before the cut are handed on as the
//! truncation recovery promises, and the file is reported cut.

use std::borrow::Cow;
use std::collections::{HashMap, VecDeque};
use std::fmt;
use std::io::{self, BufReader, Read, Seek, SeekFrom};
use std::sync::Arc;

use mcap::read::ChannelAccumulator;
use mcap::records::{Record, op};
use mcap::sans_io::{ChunkSpan, LinearReadEvent, LinearReader, LinearReaderOptions};
use mcap::{McapError, Message};

use super::chunks::{Chunked, Fallback};

/// Length of a message record's header: channel ID, sequence, log time, publish time.
const MESSAGE_HEADER: usize = 2 + 4 + 8 + 8;

/// Why the stream stopped.
#[derive(Debug)]
pub(crate) enum StreamError {
    /// Reported by the `mcap` crate.
    Mcap(McapError),
    /// A field's length exceeds what is left of its record.
    Length(String),
    /// A chunk whose records do not match its CRC or cannot be decoded.
    Damaged(crate::DamagedChunk),
    /// The data section does not match its CRC, though every chunk matched its own: a record
    /// outside the chunks is damaged.
    DataCrc,
    /// Chunks read in parallel met what only the streaming reader handles exactly: read the
    /// file again with it (see [`super::chunks`]).
    Fallback,
}

impl fmt::Display for StreamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StreamError::Mcap(e) => write!(f, "{e}"),
            StreamError::Length(m) => f.write_str(m),
            StreamError::Damaged(d) => write!(f, "{d}"),
            StreamError::DataCrc => f.write_str(
                "the data section does not match the CRC recorded in its data end record: a \
                 record outside the chunks is damaged",
            ),
            StreamError::Fallback => f.write_str("the file must be read again record by record"),
        }
    }
}

impl From<McapError> for StreamError {
    fn from(e: McapError) -> Self {
        StreamError::Mcap(e)
    }
}

/// Walks a record body field by field.
struct Fields<'a> {
    body: &'a [u8],
    pos: usize,
    record: &'static str,
}

impl Fields<'_> {
    fn skip(&mut self, n: usize, field: &str) -> Result<(), StreamError> {
        let left = self.body.len() - self.pos;
        if n > left {
            return Err(StreamError::Length(format!(
                "the {} record's {field} claims {n} bytes but only {left} remain in the record",
                self.record
            )));
        }
        self.pos += n;
        Ok(())
    }
    fn u32(&mut self, field: &str) -> Result<usize, StreamError> {
        let at = self.pos;
        self.skip(4, field)?;
        let bytes: [u8; 4] = self.body[at..at + 4].try_into().unwrap_or_default();
        Ok(u32::from_le_bytes(bytes) as usize)
    }
    /// A `u32`-prefixed string or byte array.
    fn prefixed(&mut self, field: &str) -> Result<(), StreamError> {
        let n = self.u32(field)?;
        self.skip(n, field)
    }
    /// A `u32`-byte-length-prefixed map of strings to strings.
    fn string_map(&mut self, field: &str) -> Result<(), StreamError> {
        let n = self.u32(field)?;
        let end = self.pos;
        self.skip(n, field)?;
        let mut inner = Fields {
            body: &self.body[end..end + n],
            pos: 0,
            record: self.record,
        };
        while inner.pos < n {
            inner.prefixed(field)?;
            inner.prefixed(field)?;
        }
        Ok(())
    }
}

/// Whether a record of `opcode` may lie inside a chunk: the MCAP format puts schemas, channels
/// and messages there, and leaves room for records it does not define (skipped); the records
/// that frame the file (header, footer, chunk, indexes, data end, ...) may not.
pub(crate) fn may_be_in_chunk(opcode: u8) -> bool {
    matches!(opcode, op::SCHEMA | op::CHANNEL | op::MESSAGE) || opcode > op::DATA_END
}

/// The MCAP name of a record type, for messages.
fn opcode_name(opcode: u8) -> String {
    let name = match opcode {
        op::HEADER => "header",
        op::FOOTER => "footer",
        op::CHUNK => "chunk",
        op::MESSAGE_INDEX => "message index",
        op::CHUNK_INDEX => "chunk index",
        op::ATTACHMENT => "attachment",
        op::ATTACHMENT_INDEX => "attachment index",
        op::STATISTICS => "statistics",
        op::METADATA => "metadata",
        op::METADATA_INDEX => "metadata index",
        op::SUMMARY_OFFSET => "summary offset",
        op::DATA_END => "data end",
        _ => return format!("{opcode:#04x}"),
    };
    name.to_string()
}

/// Checks the inner lengths of a schema or channel record.
fn check(opcode: u8, body: &[u8]) -> Result<(), StreamError> {
    match opcode {
        op::SCHEMA => {
            let mut f = Fields {
                body,
                pos: 0,
                record: "schema",
            };
            f.skip(2, "id")?;
            f.prefixed("name")?;
            f.prefixed("encoding")?;
            f.prefixed("data")
        }
        op::CHANNEL => {
            let mut f = Fields {
                body,
                pos: 0,
                record: "channel",
            };
            f.skip(4, "id")?;
            f.prefixed("topic")?;
            f.prefixed("message encoding")?;
            f.string_map("metadata")
        }
        _ => Ok(()),
    }
}

/// The CRC-checked top-level and chunk records of an MCAP stream, in file order, each as its
/// opcode and body (see the module docs).
pub(crate) struct Checked<R> {
    source: R,
    reader: LinearReader,
    /// Records of the chunk being read, held until it has ended with a matching CRC, each with
    /// the bytes read from `source` when the reader gave it.
    held: VecDeque<(u8, Vec<u8>, u64)>,
    /// Records ready to be handed on, likewise.
    ready: VecDeque<(u8, Vec<u8>, u64)>,
    /// The error to give once `ready` is drained; nothing follows it.
    failed: Option<StreamError>,
    ended: bool,
    skip_damaged: bool,
    /// Damaged chunks left out (only with `skip_damaged`).
    pub(crate) damaged: Vec<crate::DamagedChunk>,
    /// Bytes read from `source`.
    pub(crate) consumed: u64,
    /// `consumed` when the reader gave the record last handed on: the bytes that record came
    /// from end before it (where a truncated file's readable data ends).
    pub(crate) consumed_at_last: u64,
}

impl<R: Read> Checked<R> {
    /// Reads `source` from its start; with `skip_damaged`, damaged chunks are left out instead
    /// of ending the stream with an error.
    pub(crate) fn new(source: R, options: LinearReaderOptions, skip_damaged: bool) -> Self {
        let options = options
            .with_validate_chunk_crcs(true)
            .with_validate_data_section_crc(true);
        Checked {
            source,
            reader: LinearReader::new_with_options(options),
            held: VecDeque::new(),
            ready: VecDeque::new(),
            failed: None,
            ended: false,
            skip_damaged,
            damaged: Vec::new(),
            consumed: 0,
            consumed_at_last: 0,
        }
    }

    pub(crate) fn into_inner(self) -> R {
        self.source
    }

    /// Notes the chunk `span` as damaged by `error` (`in_chunk`: met inside the chunk, which is
    /// then abandoned to skip it; a CRC mismatch is met after it): skipped, or the end of the
    /// stream.
    fn damaged(&mut self, span: Option<ChunkSpan>, error: McapError, in_chunk: bool) {
        let damage = crate::DamagedChunk::new(span, self.reader.position(), &error);
        self.note_damage(damage, in_chunk);
    }

    /// [`damaged`](Self::damaged), for a reason the `mcap` crate does not check.
    fn damaged_because(&mut self, span: Option<ChunkSpan>, reason: String, in_chunk: bool) {
        let damage = crate::DamagedChunk::because(span, self.reader.position(), reason);
        self.note_damage(damage, in_chunk);
    }

    fn note_damage(&mut self, damage: crate::DamagedChunk, in_chunk: bool) {
        self.held.clear();
        if self.skip_damaged && (!in_chunk || self.reader.skip_chunk()) {
            self.damaged.push(damage);
        } else {
            self.failed = Some(StreamError::Damaged(damage));
        }
    }

    /// The next record, after its chunk (if it is in one) has been checked.
    pub(crate) fn next_record(&mut self) -> Option<Result<(u8, Vec<u8>), StreamError>> {
        loop {
            if let Some((opcode, data, consumed)) = self.ready.pop_front() {
                self.consumed_at_last = consumed;
                return Some(Ok((opcode, data)));
            }
            if let Some(e) = self.failed.take() {
                self.ended = true;
                return Some(Err(e));
            }
            if self.ended {
                return None;
            }
            let event = match self.reader.next_event() {
                None => {
                    // A chunk that ended the stream ended without error: its CRC matched.
                    self.ready.append(&mut self.held);
                    self.ended = true;
                    continue;
                }
                Some(event) => event,
            };
            let error = match event {
                Ok(LinearReadEvent::ReadRequest(need)) => {
                    let read = loop {
                        match self.source.read(self.reader.insert(need)) {
                            Ok(n) => break n,
                            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                            Err(e) => {
                                self.ready.clear();
                                self.held.clear();
                                self.failed = Some(McapError::Io(e).into());
                                break 0;
                            }
                        }
                    };
                    if self.failed.is_none() {
                        self.consumed += read as u64;
                        self.reader.notify_read(read);
                    }
                    continue;
                }
                Ok(LinearReadEvent::Record { opcode, data }) => {
                    let record = (opcode, data.to_vec(), self.consumed);
                    if self.reader.in_chunk() && !may_be_in_chunk(opcode) {
                        // A data end record inside a chunk would end the data section for the
                        // methods while `apply` read on past it: the chunk is damaged.
                        let span = self.reader.last_chunk();
                        let reason = format!(
                            "it holds a {} record, which the MCAP format allows only outside \
                             chunks",
                            opcode_name(opcode)
                        );
                        self.damaged_because(span, reason, true);
                        continue;
                    }
                    if self.reader.in_chunk() {
                        self.held.push_back(record);
                    } else {
                        // The chunk before this record (if any) ended with a matching CRC.
                        self.ready.append(&mut self.held);
                        self.ready.push_back(record);
                    }
                    continue;
                }
                Err(e) => e,
            };
            match error {
                McapError::UnexpectedEof => {
                    // The file is cut: a chunk cut short cannot be checked, and its records
                    // before the cut are kept, as truncation recovery promises.
                    self.ready.append(&mut self.held);
                    self.failed = Some(McapError::UnexpectedEof.into());
                }
                McapError::BadDataCrc { .. } => {
                    // Skipped chunks are the damage the data section's CRC finds; any other
                    // mismatch is damage outside the chunks.
                    self.ready.append(&mut self.held);
                    if self.damaged.is_empty() {
                        self.failed = Some(StreamError::DataCrc);
                    } else {
                        self.ended = true;
                    }
                }
                e @ McapError::BadChunkCrc { .. } => {
                    let span = self.reader.last_chunk();
                    self.damaged(span, e, false);
                }
                e if self.reader.in_chunk() => {
                    let span = self.reader.last_chunk();
                    self.damaged(span, e, true);
                }
                e => {
                    self.ready.append(&mut self.held);
                    self.failed = Some(e.into());
                }
            }
        }
    }
}

/// Where a [`Stream`]'s records come from. Unboxed: the stream itself lives boxed.
#[allow(clippy::large_enum_variant)]
enum Records<R> {
    /// The streaming reader, and the record it last handed on.
    Linear(Checked<R>, Vec<u8>),
    /// Chunks decompressed on worker threads.
    Chunked(Chunked),
}

/// A stream of messages from an MCAP file's data section, to its data end record.
pub(crate) struct Stream<R> {
    records: Records<R>,
    channels: ChannelAccumulator<'static>,
    /// The channels added so far by ID: a vector lookup per message.
    by_id: Vec<Option<Arc<mcap::Channel<'static>>>>,
    /// `Checked::consumed_at_last` when the last message was handed on.
    consumed_at_message: u64,
    /// A message's data buffer given back by the caller, to hold the next one's.
    spare: Vec<u8>,
    done: bool,
}

impl<R: Read> Stream<R> {
    /// The streaming reader over `source` (see [`Checked`]).
    pub(crate) fn new(source: R, options: LinearReaderOptions, skip_damaged: bool) -> Self {
        Self::over(Records::Linear(
            Checked::new(source, options, skip_damaged),
            Vec::new(),
        ))
    }

    /// Chunks decompressed on worker threads ([`Chunked`]); its [`Fallback`] is the stream's
    /// [`StreamError::Fallback`].
    pub(crate) fn chunked(chunked: Chunked) -> Self {
        Self::over(Records::Chunked(chunked))
    }

    fn over(records: Records<R>) -> Self {
        Stream {
            records,
            channels: ChannelAccumulator::default(),
            by_id: Vec::new(),
            consumed_at_message: 0,
            spare: Vec::new(),
            done: false,
        }
    }

    /// The source of the streaming reader (`None` for chunks read in parallel).
    pub(crate) fn into_inner(self) -> Option<R> {
        match self.records {
            Records::Linear(checked, _) => Some(checked.into_inner()),
            Records::Chunked(_) => None,
        }
    }

    /// The damaged chunks left out so far.
    pub(crate) fn damaged(&self) -> &[crate::DamagedChunk] {
        match &self.records {
            Records::Linear(checked, _) => &checked.damaged,
            Records::Chunked(_) => &[],
        }
    }

    /// The bytes read from the source when the reader gave the last message handed on (of the
    /// streaming reader: where a truncated file's readable data ends).
    pub(crate) fn consumed_at_last(&self) -> u64 {
        self.consumed_at_message
    }

    /// Takes back a message handed on, whose data buffer then holds the next message's: no
    /// allocation per message.
    pub(crate) fn recycle(&mut self, message: Message<'static>) {
        if let Cow::Owned(data) = message.data {
            self.spare = data;
        }
    }

    fn next_message(&mut self) -> Option<Result<Message<'static>, StreamError>> {
        loop {
            // With the streaming reader, where it was when it gave the record.
            let (opcode, data, consumed) = match &mut self.records {
                Records::Linear(checked, last) => match checked.next_record()? {
                    Ok((opcode, data)) => {
                        *last = data;
                        (opcode, last.as_slice(), Some(checked.consumed_at_last))
                    }
                    Err(e) => return Some(Err(e)),
                },
                Records::Chunked(chunked) => match chunked.next_record() {
                    Ok((opcode, data)) => (opcode, data, None),
                    Err(Fallback) => return Some(Err(StreamError::Fallback)),
                },
            };
            match opcode {
                // The summary after it is read separately; its damage must not cost the data.
                op::DATA_END => return None,
                op::SCHEMA | op::CHANNEL | op::MESSAGE => {}
                _ => continue,
            }
            if let Err(e) = check(opcode, data) {
                return Some(Err(e));
            }
            // A message's header, read here as `mcap::parse_record` reads it, without its
            // per-field parsing (a message too short for one goes there for its error): channel
            // ID, sequence, log time, publish time.
            if opcode == op::MESSAGE && data.len() >= MESSAGE_HEADER {
                let u64_at =
                    |i: usize| u64::from_le_bytes(data[i..i + 8].try_into().unwrap_or_default());
                let id = u16::from_le_bytes([data[0], data[1]]);
                let sequence = u32::from_le_bytes(data[2..6].try_into().unwrap_or_default());
                let channel = self.by_id.get(usize::from(id)).cloned().flatten();
                let Some(channel) = channel.or_else(|| self.channels.get(id)) else {
                    return Some(Err(McapError::UnknownChannel(sequence, id).into()));
                };
                if let Some(consumed) = consumed {
                    self.consumed_at_message = consumed;
                }
                return Some(Ok(Message {
                    channel,
                    sequence,
                    log_time: u64_at(6),
                    publish_time: u64_at(14),
                    data: Cow::Owned({
                        let mut buffer = std::mem::take(&mut self.spare);
                        buffer.clear();
                        buffer.extend_from_slice(&data[MESSAGE_HEADER..]);
                        buffer
                    }),
                }));
            }
            let record = match mcap::parse_record(opcode, data) {
                Ok(record) => record,
                Err(e) => return Some(Err(e.into())),
            };
            let added = match record {
                Record::Schema { header, data } => self
                    .channels
                    .add_schema(header, Cow::Owned(data.into_owned())),
                Record::Channel(channel) => {
                    let id = channel.id;
                    let added = self.channels.add_channel(channel);
                    if added.is_ok() {
                        let slot = usize::from(id);
                        if self.by_id.len() <= slot {
                            self.by_id.resize(slot + 1, None);
                        }
                        self.by_id[slot] = self.channels.get(id);
                    }
                    added
                }
                _ => Ok(()),
            };
            if let Err(e) = added {
                return Some(Err(e.into()));
            }
        }
    }
}

impl<R: Read> Iterator for Stream<R> {
    type Item = Result<Message<'static>, StreamError>;

    /// The next message; after an error or the data end record, `None`.
    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let item = self.next_message();
        self.done = !matches!(item, Some(Ok(_)));
        item
    }
}

/// What calib needs from a file's summary section.
pub(crate) struct Summary {
    /// Every channel, by ID.
    pub channels: HashMap<u16, Arc<mcap::Channel<'static>>>,
    /// Messages per channel ID, if the summary has statistics.
    pub message_counts: Option<std::collections::BTreeMap<u16, u64>>,
    /// Chunks its chunk indexes list, each within the data section; 0 if any lies outside it
    /// (then the index is not to be trusted, and the file is read by the streaming reader).
    pub chunks: usize,
    /// The chunk indexes, in file order (empty where `chunks` is 0): for reading from an object
    /// store only the chunks a reader needs.
    pub chunk_index: Vec<ChunkEntry>,
    /// The summary's schema and channel records, opcode and body, in its order: a reader of
    /// chunks picked by the index learns every channel from them.
    pub definitions: Vec<(u8, Vec<u8>)>,
}

/// A chunk as the summary's chunk index lists it.
pub(crate) struct ChunkEntry {
    /// Offset of the chunk record in the file, and its length with opcode and length prefix.
    pub offset: u64,
    pub length: u64,
    /// The channels whose messages it holds; `None` where the writer wrote no message index
    /// (then it may hold any).
    pub channels: Option<Vec<u16>>,
}

/// The channel IDs of a chunk index's message index offsets map (`u32` byte length, then
/// `u16` channel ID and `u64` offset per entry); `None` if it is empty or malformed.
fn indexed_channels(rest: &[u8]) -> Option<Vec<u16>> {
    let n = usize::try_from(u32::from_le_bytes(rest.get(..4)?.try_into().ok()?)).ok()?;
    let map = rest.get(4..4usize.checked_add(n)?)?;
    (n > 0 && n % 10 == 0).then(|| {
        map.chunks_exact(10)
            .map(|e| u16::from_le_bytes([e[0], e[1]]))
            .collect()
    })
}

/// A CRC-32 as an [`io::Write`] sink.
struct Crc(crc32fast::Hasher);

impl io::Write for Crc {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0.update(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// The length of the footer record: opcode, length, summary start, summary offset start, CRC.
const FOOTER_LEN: u64 = 1 + 8 + 8 + 8 + 4;

/// Reads the summary section of a file of `len` bytes, found through its footer; `None` if it has
/// none or it is damaged (as in a truncated file). Reads only the schema, channel and statistics
/// records, each checked as in the data section.
pub(crate) fn read_summary<R: Read + Seek>(file: &mut R, len: u64) -> Option<Summary> {
    let magic = mcap::MAGIC.len() as u64;
    let footer_at = len.checked_sub(magic + FOOTER_LEN)?;
    if footer_at < magic {
        return None;
    }
    let mut tail = [0u8; (FOOTER_LEN + 8) as usize];
    file.seek(SeekFrom::Start(footer_at)).ok()?;
    file.read_exact(&mut tail).ok()?;
    if tail[0] != op::FOOTER || &tail[FOOTER_LEN as usize..] != mcap::MAGIC {
        return None;
    }
    let u64_at = |i: usize| u64::from_le_bytes(tail[i..i + 8].try_into().unwrap_or_default());
    let (start, offsets) = (u64_at(9), u64_at(17));
    let end = if offsets != 0 { offsets } else { footer_at };
    if start == 0 || start < magic || start > end || end > footer_at {
        return None;
    }
    // The summary's CRC covers it from its start to the footer's CRC field: a summary that does
    // not match is not used (the file is then read as if it had none), so that no channel or
    // message definition comes from damaged bytes.
    let crc = u32::from_le_bytes(tail[25..29].try_into().unwrap_or_default());
    if crc != 0 {
        file.seek(SeekFrom::Start(start)).ok()?;
        let mut hasher = Crc(crc32fast::Hasher::new());
        let covered = footer_at + 25 - start;
        if io::copy(&mut (&mut *file).take(covered), &mut hasher).ok()? != covered
            || hasher.0.finalize() != crc
        {
            return None;
        }
    }
    file.seek(SeekFrom::Start(start)).ok()?;
    let mut file = BufReader::new(file.take(end - start));
    let mut summary = Summary {
        channels: HashMap::new(),
        message_counts: None,
        chunks: 0,
        chunk_index: Vec::new(),
        definitions: Vec::new(),
    };
    let mut chunk_index_ok = true;
    let mut accumulator = ChannelAccumulator::default();
    let mut ids = Vec::new();
    let mut left = end - start;
    let mut head = [0u8; 9];
    let mut body = Vec::new();
    while left > 0 {
        file.read_exact(&mut head).ok()?;
        let n = u64::from_le_bytes(head[1..].try_into().unwrap_or_default());
        left = left.checked_sub(9)?.checked_sub(n)?;
        let opcode = head[0];
        if opcode == op::CHUNK_INDEX {
            // Start and end time, then the chunk's offset and length: the chunk must lie between
            // the magic and the summary.
            let mut fixed = [0u8; 32];
            let mut entry = None;
            let within = n >= 32 && file.read_exact(&mut fixed).is_ok() && {
                let u64_at =
                    |i: usize| u64::from_le_bytes(fixed[i..i + 8].try_into().unwrap_or_default());
                let (offset, length) = (u64_at(16), u64_at(24));
                entry = Some((offset, length));
                offset >= magic && offset.checked_add(length).is_some_and(|end| end <= start)
            };
            chunk_index_ok &= within;
            summary.chunks += 1;
            let rest = if n >= 32 { n - 32 } else { n };
            // `rest` fits: it is at most the summary's length, which is at most the file's.
            body.resize(usize::try_from(rest).ok()?, 0);
            file.read_exact(&mut body).ok()?;
            if let Some((offset, length)) = entry {
                summary.chunk_index.push(ChunkEntry {
                    offset,
                    length,
                    channels: indexed_channels(&body),
                });
            }
            continue;
        }
        if !matches!(opcode, op::SCHEMA | op::CHANNEL | op::STATISTICS) {
            io::copy(&mut (&mut file).take(n), &mut io::sink()).ok()?;
            continue;
        }
        // `n` fits: it is at most the summary's length, which is at most the file's.
        body.resize(usize::try_from(n).ok()?, 0);
        file.read_exact(&mut body).ok()?;
        check(opcode, &body).ok()?;
        if matches!(opcode, op::SCHEMA | op::CHANNEL) {
            summary.definitions.push((opcode, body.clone()));
        }
        match mcap::parse_record(opcode, &body).ok()? {
            Record::Schema { header, data } => accumulator
                .add_schema(header, Cow::Owned(data.into_owned()))
                .ok()?,
            Record::Channel(channel) => {
                ids.push(channel.id);
                accumulator.add_channel(channel).ok()?;
            }
            Record::Statistics(stats) => {
                summary.message_counts = Some(stats.channel_message_counts)
            }
            _ => {}
        }
    }
    for id in ids {
        summary.channels.insert(id, accumulator.get(id)?);
    }
    if !chunk_index_ok {
        summary.chunks = 0;
        summary.chunk_index.clear();
    }
    summary.chunk_index.sort_by_key(|c| c.offset);
    Some(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The channel record of the fuzz input `mcap-channel-topic-claims-2gb.mcap`, in short: a
    /// topic length claiming 2.2 GB is an error naming the field, before any allocation.
    #[test]
    fn a_topic_claiming_gigabytes_is_a_length_error() {
        let mut body = Vec::new();
        body.extend_from_slice(&1u16.to_le_bytes()); // id
        body.extend_from_slice(&1u16.to_le_bytes()); // schema id
        body.extend_from_slice(&2_248_146_957u32.to_le_bytes()); // topic length
        body.extend_from_slice(b"/joint_states");
        let err = check(op::CHANNEL, &body).unwrap_err().to_string();
        assert!(
            err.contains("channel record's topic claims 2248146957 bytes"),
            "{err}"
        );
    }
}
