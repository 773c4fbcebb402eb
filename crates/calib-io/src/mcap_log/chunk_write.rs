//! An MCAP writer whose chunks are compressed on worker threads and written in order.
//!
//! Why by hand: the `mcap` crate's [`Writer`](mcap::Writer) (0.26, the version calib uses)
//! compresses each chunk on the thread that calls it, and has no call that takes a chunk
//! compressed elsewhere. [`ChunkWriter`] frames the records itself, following the MCAP
//! specification (<https://mcap.dev/spec>): each record's opcode and length, chunks with their
//! message indexes, the data end record with the data section's CRC, the summary section
//! (schemas, channels, statistics, chunk, attachment and metadata indexes, summary offsets) and
//! the footer with the summary's CRC. The fields of each record are serialized by the crate's own
//! record types, and the records come in the order the crate's writer puts them, chunks closed
//! where it closes them (before the message that would start past the chunk size) and
//! compressed as it compresses them (zstd at its default level, streamed): the file is the same,
//! byte for byte, as the crate's writer makes with default options and the same calls — only
//! the compression runs on [`ChunkWriter::new`]'s `workers` threads while the caller goes on.
//!
//! Chunks go to the workers in turn (chunk `i` to worker `i % workers`) and are taken back in
//! the same turn, so they are written in the order they were closed whatever the threads'
//! timing; at most two per worker are in flight, which bounds memory to a few chunks.

use mcap::records::{
    AttachmentHeader, AttachmentIndex, Channel, ChunkHeader, ChunkIndex, DataEnd, Header,
    MessageHeader, MessageIndex, MessageIndexEntry, Metadata, MetadataIndex, SchemaHeader,
    Statistics, SummaryOffset, op,
};
use mcap::{McapError, McapResult};
use std::collections::{BTreeMap, VecDeque};
use std::io::{self, Cursor, Write};
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;
use zstd::stream::raw::{Encoder, Operation};
use zstd::stream::zio;

/// Appends `value`, serialized as the `mcap` crate serializes its records' fields.
fn put<T>(buf: &mut Vec<u8>, value: &T) -> io::Result<()>
where
    T: for<'a> binrw::BinWrite<Args<'a> = ()>,
{
    let end = buf.len() as u64;
    let mut cursor = Cursor::new(buf);
    cursor.set_position(end);
    value
        .write_le_args(&mut cursor, ())
        .map_err(io::Error::other)
}

/// Appends a record: `opcode`, its length, then what `body` appends.
fn record(
    buf: &mut Vec<u8>,
    opcode: u8,
    body: impl FnOnce(&mut Vec<u8>) -> io::Result<()>,
) -> io::Result<()> {
    let start = buf.len();
    buf.push(opcode);
    buf.extend_from_slice(&[0; 8]);
    body(buf)?;
    let len = (buf.len() - start - 9) as u64;
    buf[start + 1..start + 9].copy_from_slice(&len.to_le_bytes());
    Ok(())
}

/// Appends a message record.
fn message(buf: &mut Vec<u8>, header: &MessageHeader, data: &[u8]) {
    buf.push(op::MESSAGE);
    buf.extend_from_slice(&(22 + data.len() as u64).to_le_bytes());
    buf.extend_from_slice(&header.channel_id.to_le_bytes());
    buf.extend_from_slice(&header.sequence.to_le_bytes());
    buf.extend_from_slice(&header.log_time.to_le_bytes());
    buf.extend_from_slice(&header.publish_time.to_le_bytes());
    buf.extend_from_slice(data);
}

/// A schema record's fields.
#[derive(PartialEq)]
struct Schema {
    header: SchemaHeader,
    data: Vec<u8>,
}

fn schema_record(buf: &mut Vec<u8>, schema: &Schema) -> io::Result<()> {
    record(buf, op::SCHEMA, |buf| {
        put(buf, &schema.header)?;
        buf.extend_from_slice(&(schema.data.len() as u32).to_le_bytes());
        buf.extend_from_slice(&schema.data);
        Ok(())
    })
}

/// The smallest and largest of `bounds` and `t`.
fn widen(bounds: Option<(u64, u64)>, t: u64) -> Option<(u64, u64)> {
    Some(bounds.map_or((t, t), |(a, b)| (a.min(t), b.max(t))))
}

/// The chunk being filled.
#[derive(Default)]
struct Open {
    /// Its records, uncompressed.
    records: Vec<u8>,
    /// Each channel's messages: log time and offset in `records`.
    indexes: BTreeMap<u16, Vec<MessageIndexEntry>>,
    /// The smallest and largest log time of its messages.
    bounds: Option<(u64, u64)>,
}

/// A chunk's records and their compressed form and CRC, to and from a worker.
struct Job {
    records: Vec<u8>,
    compressed: Vec<u8>,
    /// The CRC-32 of `records`.
    crc: u32,
    result: io::Result<()>,
}

impl Job {
    /// Compresses the records (with `encoder`, if they are to be compressed) and hashes them.
    fn run(&mut self, encoder: Option<&mut Option<Encoder<'static>>>) {
        self.crc = crc32fast::hash(&self.records);
        if let Some(encoder) = encoder {
            self.result = compress(encoder, &self.records, &mut self.compressed);
        }
    }
}

/// Compresses `records` into `into` as one zstd frame, at zstd's default level, through the
/// streaming interface as the `mcap` crate's writer does (no content size in the frame header).
fn compress(
    encoder: &mut Option<Encoder<'static>>,
    records: &[u8],
    into: &mut Vec<u8>,
) -> io::Result<()> {
    let enc = match encoder.take() {
        Some(mut enc) => {
            enc.reinit()?;
            enc
        }
        None => Encoder::new(0)?,
    };
    into.clear();
    let mut w = zio::Writer::new(std::mem::take(into), enc);
    let result = w.write_all(records).and_then(|()| w.finish());
    let (out, enc) = w.into_inner();
    *into = out;
    *encoder = Some(enc);
    result
}

fn work(jobs: Receiver<Job>, done: SyncSender<Job>) {
    let mut encoder = None;
    while let Ok(mut job) = jobs.recv() {
        job.run(Some(&mut encoder));
        // The writer has gone: stop.
        if done.send(job).is_err() {
            return;
        }
    }
}

struct Worker {
    jobs: SyncSender<Job>,
    done: Receiver<Job>,
    thread: JoinHandle<()>,
}

/// A chunk closed and not yet written: where its compressed records are, and what the chunk
/// record and its indexes need besides.
struct Closed {
    indexes: BTreeMap<u16, Vec<MessageIndexEntry>>,
    bounds: Option<(u64, u64)>,
    /// With workers: the worker compressing it; without, the job done already.
    job: Result<usize, Job>,
}

/// Writes an MCAP file with the `mcap` crate writer's default options (see the module docs),
/// its chunks zstd-compressed (or not compressed, `zstd` false) on worker threads.
pub(crate) struct ChunkWriter<W: Write> {
    out: W,
    /// Bytes written so far.
    position: u64,
    /// CRC-32 of the data section written so far.
    data_crc: crc32fast::Hasher,
    zstd: bool,
    /// A chunk is closed before a message once its records pass this many bytes.
    chunk_size: u64,
    open: Option<Open>,
    workers: Vec<Worker>,
    /// The encoder without workers.
    encoder: Option<Encoder<'static>>,
    closed: VecDeque<Closed>,
    /// Chunks sent to the workers so far: the next goes to worker `sent % workers`.
    sent: usize,
    /// Buffers to reuse for records and compressed records.
    spare: Vec<Vec<u8>>,
    /// The record being written outside a chunk, and a chunk's tail (its message indexes).
    scratch: Vec<u8>,
    schemas: BTreeMap<u16, Schema>,
    channels: BTreeMap<u16, Channel>,
    chunk_indexes: Vec<ChunkIndex>,
    attachment_indexes: Vec<AttachmentIndex>,
    metadata_indexes: Vec<MetadataIndex>,
    bounds: Option<(u64, u64)>,
    message_counts: BTreeMap<u16, u64>,
}

impl<W: Write> ChunkWriter<W> {
    /// Starts the file: its magic and header record. Chunks are compressed on `workers` threads
    /// (none: on the caller's), with zstd unless `zstd` is false.
    pub(crate) fn new(
        out: W,
        header: &Header,
        zstd: bool,
        chunk_size: u64,
        workers: usize,
    ) -> McapResult<Self> {
        let workers = if zstd { workers } else { 0 };
        let mut pool = Vec::with_capacity(workers);
        for i in 0..workers {
            let (jobs, job_rx) = sync_channel::<Job>(1);
            let (done_tx, done) = sync_channel::<Job>(1);
            let thread = std::thread::Builder::new()
                .name(format!("calib-compress-{i}"))
                .spawn(move || work(job_rx, done_tx))?;
            pool.push(Worker { jobs, done, thread });
        }
        let mut w = ChunkWriter {
            out,
            position: 0,
            data_crc: crc32fast::Hasher::new(),
            zstd,
            chunk_size,
            open: None,
            workers: pool,
            encoder: None,
            closed: VecDeque::new(),
            sent: 0,
            spare: Vec::new(),
            scratch: Vec::new(),
            schemas: BTreeMap::new(),
            channels: BTreeMap::new(),
            chunk_indexes: Vec::new(),
            attachment_indexes: Vec::new(),
            metadata_indexes: Vec::new(),
            bounds: None,
            message_counts: BTreeMap::new(),
        };
        let mut buf = mcap::MAGIC.to_vec();
        record(&mut buf, op::HEADER, |buf| put(buf, header))?;
        w.data(&buf)?;
        Ok(w)
    }

    /// Writes `bytes` of the data section.
    fn data(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.out.write_all(bytes)?;
        self.data_crc.update(bytes);
        self.position += bytes.len() as u64;
        Ok(())
    }

    fn open(&mut self) -> &mut Open {
        self.open.get_or_insert_with(|| {
            let mut records = self.spare.pop().unwrap_or_default();
            records.clear();
            Open {
                records,
                ..Open::default()
            }
        })
    }

    /// Adds schema `id` to the current chunk, unless a schema of that ID and content was added
    /// already.
    pub(crate) fn add_schema_with_id(
        &mut self,
        id: u16,
        name: &str,
        encoding: &str,
        data: &[u8],
    ) -> McapResult<u16> {
        if id == 0 {
            return Err(McapError::InvalidSchemaId);
        }
        let schema = Schema {
            header: SchemaHeader {
                id,
                name: name.into(),
                encoding: encoding.into(),
            },
            data: data.to_vec(),
        };
        match self.schemas.get(&id) {
            Some(known) if *known == schema => return Ok(id),
            Some(_) => return Err(McapError::ConflictingSchemas(name.into())),
            None => {}
        }
        schema_record(&mut self.open().records, &schema)?;
        self.schemas.insert(id, schema);
        Ok(id)
    }

    /// Adds channel `id` to the current chunk, unless a channel of that ID and content was added
    /// already.
    pub(crate) fn add_channel_with_id(
        &mut self,
        id: u16,
        schema_id: u16,
        topic: &str,
        message_encoding: &str,
        metadata: &BTreeMap<String, String>,
    ) -> McapResult<u16> {
        if schema_id != 0 && !self.schemas.contains_key(&schema_id) {
            return Err(McapError::UnknownSchema(topic.into(), schema_id));
        }
        let channel = Channel {
            id,
            schema_id,
            topic: topic.into(),
            message_encoding: message_encoding.into(),
            metadata: metadata.clone(),
        };
        match self.channels.get(&id) {
            Some(known) if *known == channel => return Ok(id),
            Some(_) => return Err(McapError::ConflictingChannels(topic.into())),
            None => {}
        }
        record(&mut self.open().records, op::CHANNEL, |buf| {
            put(buf, &channel)
        })?;
        self.channels.insert(id, channel);
        Ok(id)
    }

    /// Adds a message of an added channel to the current chunk, closing it first if it has
    /// passed the chunk size.
    pub(crate) fn write_to_known_channel(
        &mut self,
        header: &MessageHeader,
        data: &[u8],
    ) -> McapResult<()> {
        if !self.channels.contains_key(&header.channel_id) {
            return Err(McapError::UnknownChannel(
                header.sequence,
                header.channel_id,
            ));
        }
        self.bounds = widen(self.bounds, header.log_time);
        *self.message_counts.entry(header.channel_id).or_insert(0) += 1;
        if self
            .open
            .as_ref()
            .is_some_and(|c| c.records.len() as u64 > self.chunk_size)
        {
            self.close()?;
        }
        let chunk = self.open();
        chunk.bounds = widen(chunk.bounds, header.log_time);
        chunk
            .indexes
            .entry(header.channel_id)
            .or_default()
            .push(MessageIndexEntry {
                log_time: header.log_time,
                offset: chunk.records.len() as u64,
            });
        message(&mut chunk.records, header, data);
        Ok(())
    }

    /// Writes a metadata record after the current chunk.
    pub(crate) fn write_metadata(&mut self, metadata: &Metadata) -> McapResult<()> {
        self.flush_chunks()?;
        let mut buf = std::mem::take(&mut self.scratch);
        buf.clear();
        record(&mut buf, op::METADATA, |buf| put(buf, metadata))?;
        self.metadata_indexes.push(MetadataIndex {
            offset: self.position,
            length: buf.len() as u64,
            name: metadata.name.clone(),
        });
        self.data(&buf)?;
        self.scratch = buf;
        Ok(())
    }

    /// Writes an attachment record after the current chunk.
    pub(crate) fn attach(&mut self, attachment: &mcap::Attachment) -> McapResult<()> {
        self.flush_chunks()?;
        let header = AttachmentHeader {
            log_time: attachment.log_time,
            create_time: attachment.create_time,
            name: attachment.name.clone(),
            media_type: attachment.media_type.clone(),
        };
        let mut buf = std::mem::take(&mut self.scratch);
        buf.clear();
        record(&mut buf, op::ATTACHMENT, |buf| {
            put(buf, &header)?;
            buf.extend_from_slice(&(attachment.data.len() as u64).to_le_bytes());
            buf.extend_from_slice(&attachment.data);
            // The CRC of the record's fields before it.
            let crc = crc32fast::hash(&buf[9..]);
            buf.extend_from_slice(&crc.to_le_bytes());
            Ok(())
        })?;
        self.attachment_indexes.push(AttachmentIndex {
            offset: self.position,
            length: buf.len() as u64,
            log_time: header.log_time,
            create_time: header.create_time,
            data_size: attachment.data.len() as u64,
            name: header.name,
            media_type: header.media_type,
        });
        self.data(&buf)?;
        self.scratch = buf;
        Ok(())
    }

    /// Writes a private record (`opcode` ≥ 0x80) after the current chunk.
    pub(crate) fn write_private_record(&mut self, opcode: u8, data: &[u8]) -> McapResult<()> {
        if opcode < 0x80 {
            return Err(McapError::PrivateRecordOpcodeIsReserved { opcode });
        }
        self.flush_chunks()?;
        let mut buf = std::mem::take(&mut self.scratch);
        buf.clear();
        record(&mut buf, opcode, |buf| {
            buf.extend_from_slice(data);
            Ok(())
        })?;
        self.data(&buf)?;
        self.scratch = buf;
        Ok(())
    }

    /// Closes the current chunk, if there is one: hands it to the next worker in turn (after
    /// writing the oldest if two per worker are in flight), or compresses and writes it.
    fn close(&mut self) -> McapResult<()> {
        let Some(chunk) = self.open.take() else {
            return Ok(());
        };
        let compressed = self.spare.pop().unwrap_or_default();
        let mut job = Job {
            records: chunk.records,
            compressed,
            crc: 0,
            result: Ok(()),
        };
        let job = if self.workers.is_empty() {
            job.run(self.zstd.then_some(&mut self.encoder));
            Err(job)
        } else {
            if self.closed.len() >= 2 * self.workers.len() {
                self.write_oldest()?;
            }
            let i = self.sent % self.workers.len();
            self.workers[i].jobs.send(job).map_err(|_| stopped())?;
            self.sent += 1;
            Ok(i)
        };
        self.closed.push_back(Closed {
            indexes: chunk.indexes,
            bounds: chunk.bounds,
            job,
        });
        if self.workers.is_empty() {
            self.write_oldest()?;
        }
        Ok(())
    }

    /// Closes the current chunk and writes every chunk closed.
    fn flush_chunks(&mut self) -> McapResult<()> {
        self.close()?;
        while !self.closed.is_empty() {
            self.write_oldest()?;
        }
        Ok(())
    }

    /// Writes the oldest closed chunk: its chunk record, then its message indexes.
    fn write_oldest(&mut self) -> McapResult<()> {
        let Some(chunk) = self.closed.pop_front() else {
            return Ok(());
        };
        let job = match chunk.job {
            Ok(i) => self.workers[i].done.recv().map_err(|_| stopped())?,
            Err(job) => job,
        };
        job.result?;
        let data = if self.zstd {
            &job.compressed
        } else {
            &job.records
        };
        let (start, end) = chunk.bounds.unwrap_or((0, 0));
        let header = ChunkHeader {
            message_start_time: start,
            message_end_time: end,
            uncompressed_size: job.records.len() as u64,
            uncompressed_crc: job.crc,
            compression: if self.zstd { "zstd" } else { "" }.into(),
            compressed_size: data.len() as u64,
        };
        let chunk_start_offset = self.position;
        let mut head = std::mem::take(&mut self.scratch);
        head.clear();
        head.push(op::CHUNK);
        head.extend_from_slice(&[0; 8]);
        put(&mut head, &header)?;
        let len = (head.len() - 9 + data.len()) as u64;
        head[1..9].copy_from_slice(&len.to_le_bytes());
        let chunk_length = head.len() as u64 + data.len() as u64;
        self.data(&head)?;
        self.data(data)?;
        head.clear();
        let indexes_start = self.position;
        let mut message_index_offsets = BTreeMap::new();
        for (channel_id, records) in chunk.indexes {
            message_index_offsets.insert(channel_id, indexes_start + head.len() as u64);
            let index = MessageIndex {
                channel_id,
                records,
            };
            record(&mut head, op::MESSAGE_INDEX, |buf| put(buf, &index))?;
        }
        self.data(&head)?;
        self.chunk_indexes.push(ChunkIndex {
            message_start_time: start,
            message_end_time: end,
            chunk_start_offset,
            chunk_length,
            message_index_offsets,
            message_index_length: head.len() as u64,
            compression: header.compression,
            compressed_size: header.compressed_size,
            uncompressed_size: header.uncompressed_size,
        });
        self.scratch = head;
        self.spare.push(job.records);
        self.spare.push(job.compressed);
        Ok(())
    }

    /// Writes the last chunk, the data end record, the summary section and the footer, and
    /// flushes. The writer is not to be called again.
    pub(crate) fn finish(&mut self) -> McapResult<()> {
        self.flush_chunks()?;
        let mut buf = std::mem::take(&mut self.scratch);
        buf.clear();
        let data_section_crc = std::mem::take(&mut self.data_crc).finalize();
        record(&mut buf, op::DATA_END, |buf| {
            put(buf, &DataEnd { data_section_crc })
        })?;
        // Where the next byte of `buf` lands in the file.
        let base = self.position;
        let at = |buf: &Vec<u8>| base + buf.len() as u64;
        let summary_from = buf.len();
        let summary_start = at(&buf);
        let mut offsets = Vec::new();
        let mut group = |buf: &Vec<u8>, opcode: u8, from: u64| {
            offsets.push(SummaryOffset {
                group_opcode: opcode,
                group_start: from,
                group_length: at(buf) - from,
            })
        };
        // Each group of the summary, as the crate's writer writes it.
        if !self.schemas.is_empty() {
            let from = at(&buf);
            for schema in self.schemas.values() {
                schema_record(&mut buf, schema)?;
            }
            group(&buf, op::SCHEMA, from);
        }
        if !self.channels.is_empty() {
            let from = at(&buf);
            for channel in self.channels.values() {
                record(&mut buf, op::CHANNEL, |buf| put(buf, channel))?;
            }
            group(&buf, op::CHANNEL, from);
        }
        let (start, end) = self.bounds.unwrap_or((0, 0));
        let statistics = Statistics {
            message_count: self.message_counts.values().sum(),
            schema_count: self.schemas.len() as u16,
            channel_count: self.channels.len() as u32,
            attachment_count: self.attachment_indexes.len() as u32,
            metadata_count: self.metadata_indexes.len() as u32,
            chunk_count: self.chunk_indexes.len() as u32,
            message_start_time: start,
            message_end_time: end,
            channel_message_counts: std::mem::take(&mut self.message_counts),
        };
        let from = at(&buf);
        record(&mut buf, op::STATISTICS, |buf| put(buf, &statistics))?;
        group(&buf, op::STATISTICS, from);
        if !self.chunk_indexes.is_empty() {
            let from = at(&buf);
            for index in &self.chunk_indexes {
                record(&mut buf, op::CHUNK_INDEX, |buf| put(buf, index))?;
            }
            group(&buf, op::CHUNK_INDEX, from);
        }
        if !self.attachment_indexes.is_empty() {
            let from = at(&buf);
            for index in &self.attachment_indexes {
                record(&mut buf, op::ATTACHMENT_INDEX, |buf| put(buf, index))?;
            }
            group(&buf, op::ATTACHMENT_INDEX, from);
        }
        if !self.metadata_indexes.is_empty() {
            let from = at(&buf);
            for index in &self.metadata_indexes {
                record(&mut buf, op::METADATA_INDEX, |buf| put(buf, index))?;
            }
            group(&buf, op::METADATA_INDEX, from);
        }
        let summary_offset_start = at(&buf);
        for offset in &offsets {
            record(&mut buf, op::SUMMARY_OFFSET, |buf| put(buf, offset))?;
        }
        // The footer: its CRC covers the summary section and the footer's fields before it.
        buf.push(op::FOOTER);
        buf.extend_from_slice(&20u64.to_le_bytes());
        buf.extend_from_slice(&summary_start.to_le_bytes());
        buf.extend_from_slice(&summary_offset_start.to_le_bytes());
        let summary_crc = crc32fast::hash(&buf[summary_from..]);
        buf.extend_from_slice(&summary_crc.to_le_bytes());
        buf.extend_from_slice(mcap::MAGIC);
        self.out.write_all(&buf)?;
        self.out.flush()?;
        self.position += buf.len() as u64;
        Ok(())
    }

    /// The output, once [`finish`](Self::finish)ed.
    pub(crate) fn into_inner(self) -> W {
        let ChunkWriter { out, workers, .. } = self;
        for Worker { jobs, done, thread } in workers {
            drop((jobs, done));
            let _ = thread.join();
        }
        out
    }
}

/// A worker that is gone (it panicked).
fn stopped() -> McapError {
    McapError::Io(io::Error::other("a thread compressing the output stopped"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use mcap::{Compression, WriteOptions};
    use std::borrow::Cow;

    /// The calls a copy makes, on either writer.
    trait Calls {
        fn schema(&mut self, id: u16, data: &[u8]) -> McapResult<u16>;
        fn channel(&mut self, id: u16, schema: u16, topic: &str) -> McapResult<u16>;
        fn message(&mut self, header: &MessageHeader, data: &[u8]) -> McapResult<()>;
        fn metadata(&mut self, m: &Metadata) -> McapResult<()>;
        fn attach(&mut self, a: &mcap::Attachment) -> McapResult<()>;
        fn private(&mut self, opcode: u8, data: &[u8]) -> McapResult<()>;
    }

    macro_rules! calls {
        ($t:ty, $private:expr) => {
            impl Calls for $t {
                fn schema(&mut self, id: u16, data: &[u8]) -> McapResult<u16> {
                    self.add_schema_with_id(id, "pkg/msg/Reading", "ros2msg", data)
                }
                fn channel(&mut self, id: u16, schema: u16, topic: &str) -> McapResult<u16> {
                    let metadata = BTreeMap::from([("qos".to_string(), "- depth: 10".to_string())]);
                    self.add_channel_with_id(id, schema, topic, "cdr", &metadata)
                }
                fn message(&mut self, header: &MessageHeader, data: &[u8]) -> McapResult<()> {
                    self.write_to_known_channel(header, data)
                }
                fn metadata(&mut self, m: &Metadata) -> McapResult<()> {
                    self.write_metadata(m)
                }
                fn attach(&mut self, a: &mcap::Attachment) -> McapResult<()> {
                    self.attach(a)
                }
                fn private(&mut self, opcode: u8, data: &[u8]) -> McapResult<()> {
                    $private(self, opcode, data)
                }
            }
        };
    }
    calls!(
        mcap::Writer<Cursor<Vec<u8>>>,
        |w: &mut mcap::Writer<Cursor<Vec<u8>>>, opcode, data| w.write_private_record(
            opcode,
            data,
            Default::default()
        )
    );
    calls!(
        ChunkWriter<Cursor<Vec<u8>>>,
        |w: &mut ChunkWriter<Cursor<Vec<u8>>>, opcode, data| w.write_private_record(opcode, data)
    );

    /// A log of `n` messages on two channels, messages of varied lengths (some longer than a
    /// chunk), a channel added late, metadata, an attachment and a private record between them,
    /// and the same schema and channel added twice; the errors of a conflicting schema and
    /// channel and of an unknown channel.
    fn log(w: &mut impl Calls, n: u32) {
        assert_eq!(w.schema(3, b"float64 x").unwrap(), 3);
        assert_eq!(w.schema(3, b"float64 x").unwrap(), 3);
        assert!(matches!(
            w.schema(3, b"float32 x"),
            Err(McapError::ConflictingSchemas(_))
        ));
        assert!(matches!(w.schema(0, b"x"), Err(McapError::InvalidSchemaId)));
        w.channel(0, 3, "/a").unwrap();
        w.channel(0, 3, "/a").unwrap();
        assert!(matches!(
            w.channel(0, 3, "/b"),
            Err(McapError::ConflictingChannels(_))
        ));
        assert!(matches!(
            w.channel(9, 4, "/b"),
            Err(McapError::UnknownSchema(..))
        ));
        let unknown = MessageHeader {
            channel_id: 7,
            sequence: 1,
            log_time: 0,
            publish_time: 0,
        };
        assert!(matches!(
            w.message(&unknown, b""),
            Err(McapError::UnknownChannel(1, 7))
        ));
        for i in 0..n {
            if i == n / 3 {
                w.schema(1, b"uint8[] data").unwrap();
                w.channel(65535, 1, "/b").unwrap();
            }
            let channel_id = if i >= n / 3 && i % 3 == 0 { 65535 } else { 0 };
            let len = match i % 97 {
                5 => 9000,
                _ => 20 + (i % 13) as usize,
            };
            let data: Vec<u8> = (0..len).map(|k| (k as u32 * 7 + i) as u8).collect();
            let header = MessageHeader {
                channel_id,
                sequence: i,
                // Not in order: chunk bounds are minima and maxima.
                log_time: 1_000_000 + u64::from(i ^ 5),
                publish_time: u64::from(i),
            };
            w.message(&header, &data).unwrap();
            match i % 700 {
                100 => w
                    .metadata(&Metadata {
                        name: format!("m{i}"),
                        metadata: BTreeMap::from([("k".into(), i.to_string())]),
                    })
                    .unwrap(),
                300 => w
                    .attach(&mcap::Attachment {
                        log_time: 5,
                        create_time: u64::from(i),
                        name: "rig.urdf".into(),
                        media_type: "text/xml".into(),
                        data: Cow::Borrowed(b"<robot/>"),
                    })
                    .unwrap(),
                500 => w.private(0x90, b"vendor").unwrap(),
                _ => {}
            }
        }
        assert!(matches!(
            w.private(0x10, b"reserved"),
            Err(McapError::PrivateRecordOpcodeIsReserved { .. })
        ));
    }

    fn crate_writer(zstd: bool, chunk_size: u64, n: u32) -> Vec<u8> {
        let mut w = WriteOptions::new()
            .profile("ros2")
            .library("rosbag2")
            .compression(zstd.then_some(Compression::Zstd))
            .chunk_size(Some(chunk_size))
            .compression_threads(0)
            .create(Cursor::new(Vec::new()))
            .unwrap();
        log(&mut w, n);
        w.finish().unwrap();
        w.into_inner().into_inner()
    }

    fn chunk_writer(zstd: bool, chunk_size: u64, n: u32, workers: usize) -> Vec<u8> {
        let header = Header {
            profile: "ros2".into(),
            library: "rosbag2".into(),
        };
        let mut w =
            ChunkWriter::new(Cursor::new(Vec::new()), &header, zstd, chunk_size, workers).unwrap();
        log(&mut w, n);
        w.finish().unwrap();
        w.into_inner().into_inner()
    }

    /// The same bytes as the `mcap` crate's writer makes of the same calls, whatever the number
    /// of threads compressing, with zstd or without compression, in small chunks (many, a
    /// message longer than a chunk) and the default size; and the file reads back.
    #[test]
    fn writes_the_bytes_of_the_crates_writer() {
        for zstd in [true, false] {
            for (chunk_size, n) in [(4096, 3000), (WriteOptions::DEFAULT_CHUNK_SIZE, 40_000)] {
                let expected = crate_writer(zstd, chunk_size, n);
                for workers in [0, 1, 2, 3] {
                    let got = chunk_writer(zstd, chunk_size, n, workers);
                    assert!(
                        got == expected,
                        "zstd {zstd}, chunks of {chunk_size} B, {workers} workers: {} B, \
                         expected {} B",
                        got.len(),
                        expected.len()
                    );
                }
                let summary = mcap::Summary::read(&expected).unwrap().unwrap();
                let stats = summary.stats.unwrap();
                assert_eq!(stats.message_count, u64::from(n));
                assert!(summary.chunk_indexes.len() > 3, "{zstd} {chunk_size}");
                assert_eq!(
                    mcap::MessageStream::new(&expected).unwrap().count(),
                    n as usize
                );
            }
        }
    }
}
