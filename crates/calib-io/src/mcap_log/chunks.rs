//! Reading a chunked MCAP file's chunks on worker threads, several at a time.
//!
//! A chunk's records depend on nothing before it, so its bytes can be read, checked and
//! decompressed anywhere. [`Chunked`] walks the top-level records of the data section on the
//! reader's thread (reading their bytes and the data section's CRC-32 as it goes), hands each
//! chunk to one of [`workers`] threads in turn, and hands the records on in file order: from a
//! chunk once its worker has decompressed it, checked it against the CRC its header records and
//! checked that its records fill it exactly. Decompression, about a third of reading a zstd log,
//! thereby runs beside the decoding of the messages. On Unix the worker also reads the chunk's
//! bytes, at their offset (`pread`), and hashes them for the data section's CRC, which the walk
//! puts together in file order (CRC-32 combination): the kernel's copy of the file's bytes,
//! a fifth of the reader thread's time on a 10⁷-message log, runs beside the decoding too.
//! Elsewhere the walk reads them.
//!
//! # Only where it changes nothing
//! The records handed on are exactly those the streaming reader
//! ([`Checked`](super::records::Checked)) hands on, in the same order; it is used only where
//! that is certain. At the first thing the streaming reader treats in any special way — a chunk
//! whose CRC does not match, that cannot be decompressed, whose records do not fill it, of another
//! compression than zstd or none, larger than [`MAX_PARALLEL_CHUNK_BYTES`]; a record running past
//! the end of the file; a data section CRC that does not match; a footer before the data end
//! record — it reports [`Fallback`], and the caller reads the file again with the streaming
//! reader, skipping the messages it has already handed on. Damaged files pay one more read of
//! what came before the damage; every message, error and recovery stays the streaming reader's.
//!
//! # Every record, for a copy
//! The reader needs only schemas, channels and messages; `calib apply`, which copies a log,
//! needs every record the streaming reader hands on ([`Chunked::every_record`]): then the
//! top-level header, metadata, attachments, message indexes and private records are handed on
//! too, in file order, and the records handed on are exactly the streaming reader's up to the
//! data end record. A caller that falls back can then skip as many records as it was handed.
//!
//! # Only the chunks needed, from an object store
//! A log read from an object store ([`Chunked::indexed`]) is not walked: the summary's chunk
//! index says where the chunks are and which channels each holds, so only the chunks holding a
//! channel the reader reads are fetched, each in one request by its worker, after the schema
//! and channel records of the summary. The chunks' own CRCs are checked as above; the data
//! section's CRC, which covers every byte, cannot be (the bytes between chunks are not
//! fetched). A chunk that is not as expected falls back as above (see `McapReader`).
//!
//! # Memory
//! At most [`AHEAD`] chunks per worker are in flight, each at most [`MAX_PARALLEL_CHUNK_BYTES`]
//! compressed and decompressed; their buffers are reused from chunk to chunk.

use std::collections::VecDeque;
use std::io::{self, BufReader, Read, Seek, SeekFrom, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;

use mcap::records::op;

use crate::limits::MAX_PARALLEL_CHUNK_BYTES;
use crate::source::{ByteSource, SourceCursor};

/// Chunks decompressed ahead per worker: one being handed on while the next is decompressed.
pub const AHEAD: usize = 2;

/// Read buffer of the walk over the top-level records (chunks are read past it).
const READ_BUFFER: usize = 64 * 1024;

/// Length of a record's opcode and length prefix.
const PREFIX: usize = 9;

/// Worker threads: as many as the machine has cores, at most two (the reader's own thread
/// decodes the messages beside them).
pub fn workers() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get().min(2))
}

/// The walk met something only the streaming reader handles exactly (see the module docs).
#[derive(Debug)]
pub(crate) struct Fallback;

/// A chunk record's body for a worker — at offset `at` of the file, `len` bytes, read into
/// `body` by the worker (on Unix) or by the walk — and a buffer to decompress it into.
struct Job {
    at: u64,
    len: usize,
    body: Vec<u8>,
    out: Vec<u8>,
}

/// A worker's result: the buffers back, `out` holding the chunk's records if `ok`, and the
/// CRC-32 of the chunk record's body, for the data section's.
struct Done {
    body: Vec<u8>,
    out: Vec<u8>,
    ok: bool,
    crc: crc32fast::Hasher,
}

struct Worker {
    jobs: SyncSender<Job>,
    done: Receiver<Done>,
    thread: JoinHandle<()>,
}

/// What the walk found next in the data section, in file order.
enum Planned {
    /// A chunk, sent to the next worker in turn.
    Chunk,
    /// A top-level schema, channel or message record.
    Record(u8, Vec<u8>),
    /// The data end record, its CRC matched.
    End(Vec<u8>),
    Fallback,
}

/// The data section's records, chunks decompressed on worker threads (see the module docs).
pub(crate) struct Chunked {
    file: BufReader<SourceCursor>,
    /// Reading from the chunk index: the chunks still to fetch (offset and length of each
    /// chunk record), in file order; `None` when walking the data section.
    index: Option<VecDeque<(u64, u64)>>,
    len: u64,
    /// Offset of the next top-level record.
    pos: u64,
    /// CRC-32 of the data section's bytes up to the body of the first chunk in flight (to
    /// `pos` when none is).
    crc: crc32fast::Hasher,
    /// For each chunk in flight, in order, the CRC-32 of the bytes walked after its body up to
    /// the next one's body (or to `pos`): with each chunk's own, taken back in order, they
    /// complete `crc`.
    after: VecDeque<crc32fast::Hasher>,
    /// Bytes walked, shared with the reader (where the walk has got to).
    consumed: Arc<AtomicU64>,
    workers: Vec<Worker>,
    plan: VecDeque<Planned>,
    /// Chunks sent to the workers and not yet taken back.
    in_flight: usize,
    /// Chunks sent so far: the next one goes to worker `sent % workers`.
    sent: usize,
    /// Chunks taken back so far: the next one comes from worker `taken % workers`.
    taken: usize,
    /// The walk has planned the data end or a fallback: nothing follows.
    walked: bool,
    /// The records of the chunk being handed on, and the offset of the next one.
    current: Vec<u8>,
    at: usize,
    /// The top-level record last handed on.
    record: Vec<u8>,
    /// Buffers to reuse for chunk bodies and decompressed chunks.
    spare: Vec<Vec<u8>>,
    /// Hand on every top-level record, not only schemas, channels and messages.
    every: bool,
}

/// A little-endian `u64` at `at`, if the bytes are there.
fn u64_at(bytes: &[u8], at: usize) -> Option<u64> {
    let b = bytes.get(at..at.checked_add(8)?)?;
    Some(u64::from_le_bytes(b.try_into().ok()?))
}

fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes(b.try_into().ok()?))
}

/// Whether `records` is a sequence of whole records that may lie in a chunk, none longer than
/// the streaming reader's record length limit.
fn tiles(mut records: &[u8], file_len: u64) -> bool {
    while !records.is_empty() {
        let limit = crate::limits::mcap_record_limit(file_len) as u64;
        let Some(n) = u64_at(records, 1).filter(|&n| n <= limit) else {
            return false;
        };
        if !super::records::may_be_in_chunk(records[0]) {
            return false;
        }
        let next = usize::try_from(n)
            .ok()
            .and_then(|n| n.checked_add(PREFIX))
            .and_then(|end| records.get(end..));
        match next {
            Some(next) => records = next,
            None => return false,
        }
    }
    true
}

/// Decompresses the chunk record `body` into `out`; true if its records are exactly what the
/// streaming reader hands on without error: the header is whole, the compression zstd or none,
/// the records decompress to the size the header gives, match its CRC (if it records one) and
/// fill it exactly.
fn decode_chunk(
    body: &[u8],
    file_len: u64,
    zstd: &mut Option<zstd::bulk::Decompressor<'static>>,
    out: &mut Vec<u8>,
) -> Option<()> {
    // Start and end time, uncompressed size, CRC, compression (u32-prefixed), compressed size.
    let uncompressed_size = u64_at(body, 16)?;
    let crc = u32_at(body, 24)?;
    let name_len = usize::try_from(u32_at(body, 28)?).ok()?;
    let name_end = 32usize.checked_add(name_len)?;
    let compression = body.get(32..name_end)?;
    let compressed_size = usize::try_from(u64_at(body, name_end)?).ok()?;
    let data_start = name_end + 8;
    let data = body.get(data_start..data_start.checked_add(compressed_size)?)?;
    out.clear();
    match compression {
        b"" => out.extend_from_slice(data),
        b"zstd" => {
            let size = usize::try_from(uncompressed_size)
                .ok()
                .filter(|&n| n <= MAX_PARALLEL_CHUNK_BYTES)?;
            out.reserve(size);
            let decompressor = match zstd {
                Some(d) => d,
                None => zstd.insert(zstd::bulk::Decompressor::new().ok()?),
            };
            let written = decompressor.decompress_to_buffer(data, out).ok()?;
            (written == size).then_some(())?;
        }
        _ => return None,
    }
    (crc == 0 || crc32fast::hash(out) == crc).then_some(())?;
    tiles(out, file_len).then_some(())
}

/// Reads a chunk record's body of `len` bytes at offset `at` of `file` into `body` (one
/// positioned read, or one request to an object store); false if the file no longer holds them.
fn read_chunk(file: &dyn ByteSource, body: &mut Vec<u8>, at: u64, len: usize) -> bool {
    body.resize(len, 0);
    file.read_exact_at(at, body).is_ok()
}

fn work(file: Arc<dyn ByteSource>, jobs: Receiver<Job>, done: SyncSender<Done>, file_len: u64) {
    let mut zstd = None;
    while let Ok(mut job) = jobs.recv() {
        let mut crc = crc32fast::Hasher::new();
        let ok = read_chunk(&*file, &mut job.body, job.at, job.len) && {
            crc.update(&job.body);
            decode_chunk(&job.body, file_len, &mut zstd, &mut job.out).is_some()
        };
        let result = Done {
            body: job.body,
            out: job.out,
            ok,
            crc,
        };
        // The reader has gone: stop.
        if done.send(result).is_err() {
            return;
        }
    }
}

/// Hashes what is written to it.
struct Hashing<'a>(&'a mut crc32fast::Hasher);

impl Write for Hashing<'_> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0.update(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl Chunked {
    /// Walks `file` (of `len` bytes) from its start with `workers` worker threads; `None` if it
    /// does not start with the MCAP magic or no thread can be started.
    pub(crate) fn new(
        file: SourceCursor,
        len: u64,
        consumed: Arc<AtomicU64>,
        workers: usize,
    ) -> Option<Self> {
        Self::walking(file, len, consumed, workers, false)
    }

    /// Reads the chunk records at `chunks` (offset and length of each, in file order) of
    /// `file` and nothing else, after handing on `definitions` (the summary's schema and channel
    /// records), with `workers` worker threads (see the module docs); `None` if no thread can be
    /// started.
    pub(crate) fn indexed(
        file: SourceCursor,
        chunks: Vec<(u64, u64)>,
        definitions: Vec<(u8, Vec<u8>)>,
        consumed: Arc<AtomicU64>,
        workers: usize,
    ) -> Option<Self> {
        let len = file.source().len();
        let bodies: Vec<(u64, u64)> = chunks
            .iter()
            .map(|&(at, n)| (at + PREFIX as u64, n.saturating_sub(PREFIX as u64)))
            .collect();
        file.source().plan(&bodies);
        let mut chunked = Self::start(file, len, consumed, workers, false)?;
        chunked.index = Some(chunks.into());
        chunked.plan = definitions
            .into_iter()
            .map(|(opcode, body)| Planned::Record(opcode, body))
            .collect();
        Some(chunked)
    }

    /// [`new`](Self::new), handing on every top-level record of the data section as the streaming
    /// reader does (see the module docs).
    pub(crate) fn every_record(
        file: SourceCursor,
        len: u64,
        consumed: Arc<AtomicU64>,
        workers: usize,
    ) -> Option<Self> {
        Self::walking(file, len, consumed, workers, true)
    }

    fn walking(
        file: SourceCursor,
        len: u64,
        consumed: Arc<AtomicU64>,
        workers: usize,
        every: bool,
    ) -> Option<Self> {
        let mut chunked = Self::start(file, len, consumed, workers, every)?;
        let mut magic = [0u8; 8];
        chunked.file.read_exact(&mut magic).ok()?;
        (magic == mcap::MAGIC).then_some(())?;
        chunked.crc.update(&magic);
        chunked.pos = magic.len() as u64;
        chunked.consumed.store(chunked.pos, Ordering::Relaxed);
        Some(chunked)
    }

    /// The workers started, nothing read.
    fn start(
        mut file: SourceCursor,
        len: u64,
        consumed: Arc<AtomicU64>,
        workers: usize,
        every: bool,
    ) -> Option<Self> {
        file.seek(SeekFrom::Start(0)).ok()?;
        // The workers' handle: a positioned read leaves the walk's offset alone.
        let shared = Arc::clone(file.source());
        let file = BufReader::with_capacity(READ_BUFFER, file);
        let mut pool = Vec::with_capacity(workers);
        for i in 0..workers.max(1) {
            let (jobs, job_rx) = sync_channel::<Job>(AHEAD);
            let (done_tx, done) = sync_channel::<Done>(AHEAD);
            let shared = Arc::clone(&shared);
            let thread = std::thread::Builder::new()
                .name(format!("calib-chunks-{i}"))
                .spawn(move || work(shared, job_rx, done_tx, len))
                .ok()?;
            pool.push(Worker { jobs, done, thread });
        }
        Some(Chunked {
            file,
            index: None,
            len,
            pos: 0,
            crc: crc32fast::Hasher::new(),
            after: VecDeque::new(),
            consumed,
            workers: pool,
            plan: VecDeque::new(),
            in_flight: 0,
            sent: 0,
            taken: 0,
            walked: false,
            current: Vec::new(),
            at: 0,
            record: Vec::new(),
            spare: Vec::new(),
            every,
        })
    }

    /// Reads the body of a record of `n` bytes (checked to lie within the file) into a buffer.
    fn read_body(&mut self, n: u64) -> Option<Vec<u8>> {
        let mut body = self.spare.pop().unwrap_or_default();
        body.clear();
        let read = (&mut self.file).take(n).read_to_end(&mut body).ok()?;
        (read as u64 == n).then_some(body)
    }

    /// The walk's share of a chunk record's body of `n` bytes: it steps over it (its worker
    /// reads it) and returns a buffer for it.
    fn chunk_body(&mut self, n: u64) -> Option<Vec<u8>> {
        self.file.seek_relative(i64::try_from(n).ok()?).ok()?;
        Some(self.spare.pop().unwrap_or_default())
    }

    /// The next chunk the index lists, sent to a worker; the data end (unchecked) after the
    /// last.
    fn next_indexed(&mut self) -> Option<Planned> {
        let Some((offset, length)) = self.index.as_mut()?.pop_front() else {
            // No CRC recorded: the data section's cannot be checked without all its bytes.
            return Some(Planned::End(vec![0; 4]));
        };
        let len = usize::try_from(length.checked_sub(PREFIX as u64)?)
            .ok()
            .filter(|&n| n <= MAX_PARALLEL_CHUNK_BYTES)?;
        let body = self.spare.pop().unwrap_or_default();
        let out = self.spare.pop().unwrap_or_default();
        let at = offset.checked_add(PREFIX as u64)?;
        let worker = &self.workers[self.sent % self.workers.len()];
        worker.jobs.send(Job { at, len, body, out }).ok()?;
        self.after.push_back(crc32fast::Hasher::new());
        self.sent += 1;
        self.in_flight += 1;
        self.pos = offset + length;
        self.consumed.store(self.pos, Ordering::Relaxed);
        Some(Planned::Chunk)
    }

    /// Where the bytes the walk reads are hashed: after the last chunk in flight, if any.
    fn hasher(&mut self) -> &mut crc32fast::Hasher {
        self.after.back_mut().unwrap_or(&mut self.crc)
    }

    /// Walks to the next top-level record that is handed on; `None` where the streaming reader
    /// must take over.
    fn walk(&mut self) -> Option<Planned> {
        if self.index.is_some() {
            return self.next_indexed();
        }
        loop {
            let mut head = [0u8; PREFIX];
            self.file.read_exact(&mut head).ok()?;
            let opcode = head[0];
            let n = u64_at(&head, 1)?;
            let end = self
                .pos
                .checked_add(PREFIX as u64)?
                .checked_add(n)
                .filter(|&end| end <= self.len)?;
            let planned = match opcode {
                // Its CRC is checked when it is taken from the plan, after every chunk before it.
                op::DATA_END => {
                    let body = self.read_body(n)?;
                    u32_at(&body, 0)?;
                    Some(Planned::End(body))
                }
                // The streaming reader reads on past a footer in the data section.
                op::FOOTER => return None,
                op::CHUNK => {
                    let len = usize::try_from(n)
                        .ok()
                        .filter(|&n| n <= MAX_PARALLEL_CHUNK_BYTES)?;
                    let body = self.chunk_body(n)?;
                    self.hasher().update(&head);
                    let out = self.spare.pop().unwrap_or_default();
                    let at = self.pos + PREFIX as u64;
                    let worker = &self.workers[self.sent % self.workers.len()];
                    worker.jobs.send(Job { at, len, body, out }).ok()?;
                    self.after.push_back(crc32fast::Hasher::new());
                    self.sent += 1;
                    self.in_flight += 1;
                    Some(Planned::Chunk)
                }
                op::SCHEMA | op::CHANNEL | op::MESSAGE => {
                    let body = self.read_body(n)?;
                    self.hasher().update(&head);
                    self.hasher().update(&body);
                    Some(Planned::Record(opcode, body))
                }
                _ if self.every => {
                    let body = self.read_body(n)?;
                    self.hasher().update(&head);
                    self.hasher().update(&body);
                    Some(Planned::Record(opcode, body))
                }
                // The header, message indexes, attachments, metadata: read only for the CRC.
                _ => {
                    self.hasher().update(&head);
                    let hasher = self.after.back_mut().unwrap_or(&mut self.crc);
                    let mut hashing = Hashing(hasher);
                    let hashed = io::copy(&mut (&mut self.file).take(n), &mut hashing).ok()?;
                    (hashed == n).then_some(())?;
                    None
                }
            };
            self.pos = end;
            self.consumed.store(end, Ordering::Relaxed);
            if planned.is_some() {
                return planned;
            }
        }
    }

    /// The next record (opcode and body), in the order the streaming reader hands them on, up
    /// to the data end record; [`Fallback`] where the streaming reader must take over.
    pub(crate) fn next_record(&mut self) -> Result<(u8, &[u8]), Fallback> {
        enum From {
            Chunk(usize, usize),
            Record,
        }
        let (opcode, from) = loop {
            if self.at < self.current.len() {
                // The worker checked that the records fill the chunk.
                let at = self.at;
                let n = u64_at(&self.current, at + 1).and_then(|n| usize::try_from(n).ok());
                let start = at + PREFIX;
                let end = n.and_then(|n| start.checked_add(n)).ok_or(Fallback)?;
                self.at = end;
                break (self.current[at], From::Chunk(start, end));
            }
            while !self.walked && self.in_flight < AHEAD * self.workers.len() {
                let planned = self.walk().unwrap_or(Planned::Fallback);
                self.walked = matches!(planned, Planned::End(_) | Planned::Fallback);
                self.plan.push_back(planned);
            }
            match self.plan.pop_front() {
                Some(Planned::Chunk) => {
                    let worker = &self.workers[self.taken % self.workers.len()];
                    let done = worker.done.recv().map_err(|_| Fallback)?;
                    self.taken += 1;
                    self.in_flight -= 1;
                    self.crc.combine(&done.crc);
                    let after = self.after.pop_front().ok_or(Fallback)?;
                    self.crc.combine(&after);
                    self.spare.push(done.body);
                    let emptied = std::mem::replace(&mut self.current, done.out);
                    self.spare.push(emptied);
                    self.at = 0;
                    if !done.ok {
                        self.walked = true;
                        self.plan.clear();
                        return Err(Fallback);
                    }
                }
                Some(Planned::Record(opcode, body)) => {
                    let emptied = std::mem::replace(&mut self.record, body);
                    self.spare.push(emptied);
                    break (opcode, From::Record);
                }
                Some(Planned::End(body)) => {
                    // Every chunk before it is back: `crc` is the whole data section's.
                    let saved = u32_at(&body, 0).ok_or(Fallback)?;
                    if saved != 0 && saved != self.crc.clone().finalize() {
                        self.walked = true;
                        self.plan.clear();
                        return Err(Fallback);
                    }
                    self.record = body;
                    break (op::DATA_END, From::Record);
                }
                Some(Planned::Fallback) | None => return Err(Fallback),
            }
        };
        Ok(match from {
            From::Chunk(start, end) => (opcode, &self.current[start..end]),
            From::Record => (opcode, &self.record[..]),
        })
    }
}

impl Drop for Chunked {
    fn drop(&mut self) {
        // Closing both channels stops each worker after the chunk it is decompressing.
        for worker in std::mem::take(&mut self.workers) {
            let Worker { jobs, done, thread } = worker;
            drop(jobs);
            drop(done);
            let _ = thread.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ReadOptions;
    use crate::mcap_log::read::McapReader;
    use crate::mcap_log::{DEFAULT_TOPIC, McapWriter};
    use calib_core::{AngleUnit, Channel, Sample};
    use std::fs::File;
    use std::path::Path;

    fn cursor(path: &Path) -> SourceCursor {
        SourceCursor::new(Arc::new(crate::source::FileSource::open(path).unwrap()))
    }

    /// A JointState log of three joints, `n` messages in 1 MiB zstd chunks (about 10 000
    /// messages each).
    fn log(path: &Path, n: usize) {
        let channels: Vec<Channel> = ["a", "b", "c"]
            .iter()
            .map(|name| Channel {
                name: name.to_string(),
                unit: AngleUnit::Rad,
            })
            .collect();
        let mut writer = McapWriter::create(path, &channels, DEFAULT_TOPIC).unwrap();
        for i in 0..n {
            let x = i as f64 * 1e-3;
            let sample = Sample {
                t: 1.0 + x,
                values: vec![x, x.sin(), -x],
                session: None,
            };
            writer.write(&sample).unwrap();
        }
        writer.finish().unwrap();
    }

    /// Offsets and lengths of the top-level chunk records of MCAP `bytes`.
    fn chunk_records(bytes: &[u8]) -> Vec<(usize, usize)> {
        top_level(bytes, op::CHUNK)
    }

    /// Offsets and lengths of the data section's top-level records of opcode `opcode`.
    fn top_level(bytes: &[u8], opcode: u8) -> Vec<(usize, usize)> {
        let mut at = 8;
        let mut found = Vec::new();
        while at + PREFIX <= bytes.len() && bytes[at] != op::DATA_END {
            let len = u64_at(bytes, at + 1).unwrap() as usize;
            if bytes[at] == opcode {
                found.push((at, PREFIX + len));
            }
            at += PREFIX + len;
        }
        found
    }

    /// Everything a reader yields, errors as text, and what it noticed.
    fn read(path: &Path, opts: &ReadOptions, parallel_chunks: usize) -> (Vec<String>, String) {
        let mut reader = McapReader::open_with(path, opts, parallel_chunks).unwrap();
        let items = reader
            .by_ref()
            .map(|item| match item {
                Ok(sample) => format!("{:?}", sample),
                Err(e) => e.to_string(),
            })
            .collect();
        let noticed = format!("{:?} {:?}", reader.diagnostics(), reader.alignment());
        (items, noticed)
    }

    #[test]
    fn chunks_read_in_parallel_hand_on_the_streaming_readers_records() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.mcap");
        log(&path, 40_000);
        let len = std::fs::metadata(&path).unwrap().len();
        let linear = |skip_damaged| {
            let file = File::open(&path).unwrap();
            let options = mcap::sans_io::LinearReaderOptions::default()
                .with_skip_end_magic(true)
                .with_record_length_limit(len as usize);
            super::super::records::Checked::new(BufReader::new(file), options, skip_damaged)
        };
        for workers in [1, 2] {
            let consumed = Arc::new(AtomicU64::new(0));
            let mut chunked = Chunked::new(cursor(&path), len, consumed, workers).unwrap();
            let mut checked = linear(false);
            let mut records = 0;
            loop {
                let (opcode, data) = chunked.next_record().expect("no fallback");
                // The streaming reader also hands on the header and the message indexes, which
                // the stream skips.
                let expected = loop {
                    let (opcode, data) = checked.next_record().unwrap().unwrap();
                    if matches!(
                        opcode,
                        op::SCHEMA | op::CHANNEL | op::MESSAGE | op::DATA_END
                    ) {
                        break (opcode, data);
                    }
                };
                assert_eq!((opcode, data), (expected.0, expected.1.as_slice()));
                records += 1;
                if opcode == op::DATA_END {
                    break;
                }
            }
            assert!(records > 40_000, "{records} records");
        }
        // The reader uses them, with the same samples.
        assert!(chunk_records(&std::fs::read(&path).unwrap()).len() >= 3);
        let opts = ReadOptions::default();
        assert_eq!(read(&path, &opts, 2), read(&path, &opts, usize::MAX));
    }

    /// Damage in a later chunk: the streaming reader takes over and everything read — samples,
    /// the error, the chunks skipped with `skip_damaged` — is the streaming reader's alone.
    #[test]
    fn damage_reads_exactly_as_the_streaming_reader_reads_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.mcap");
        log(&path, 40_000);
        let good = std::fs::read(&path).unwrap();
        let chunks = chunk_records(&good);
        assert!(chunks.len() >= 3, "{} chunks", chunks.len());
        let (at, len) = chunks[2];
        // A message index after the third chunk: only the data section's CRC can tell, at its
        // end (the workers hash the chunks, the walk the rest, in file order).
        let (index, _) = *top_level(&good, op::MESSAGE_INDEX)
            .iter()
            .find(|&&(offset, _)| offset > at)
            .expect("a message index after the third chunk");
        let cases = [
            ("data", at + len / 2),
            ("crc", at + 9 + 24),
            ("index", index + PREFIX + 2),
        ];
        for (name, offset) in cases {
            let mut bytes = good.clone();
            bytes[offset] ^= 0x10;
            let bad = dir.path().join(format!("{name}.mcap"));
            std::fs::write(&bad, &bytes).unwrap();
            for skip_damaged in [false, true] {
                let opts = ReadOptions {
                    skip_damaged,
                    ..ReadOptions::default()
                };
                let (items, noticed) = read(&bad, &opts, 2);
                let streaming = read(&bad, &opts, usize::MAX);
                assert!(
                    streaming == (items.clone(), noticed.clone()),
                    "{name}: {noticed}"
                );
                let errors = items.iter().filter(|i| !i.starts_with("Sample")).count();
                // A damaged chunk is skipped where asked; a data section that does not match
                // its CRC is an error either way.
                let expected = usize::from(!skip_damaged || name == "index");
                assert_eq!(errors, expected, "{name}: {noticed}");
                assert!(items.len() > 10_000, "{name}: {} items", items.len());
            }
            // The walk itself stops at the damage: at the chunk, or at the data end record
            // for the index, after every chunk before it has been handed on.
            let consumed = Arc::new(AtomicU64::new(0));
            let len = bytes.len() as u64;
            let mut chunked = Chunked::new(cursor(&bad), len, consumed, 2).unwrap();
            let mut messages = 0;
            let stopped = loop {
                match chunked.next_record() {
                    Ok((op::DATA_END, _)) => break false,
                    Ok((opcode, _)) => messages += usize::from(opcode == op::MESSAGE),
                    Err(Fallback) => break true,
                }
            };
            assert!(stopped, "{name}: read to the end");
            assert_eq!(
                messages == 40_000,
                name == "index",
                "{name}: {messages} messages"
            );
        }
    }

    #[test]
    fn chunks_are_checked_as_the_streaming_reader_checks_them() {
        let mut zstd = None;
        let mut out = Vec::new();
        // An uncompressed chunk of one record (opcode 5, 2 bytes).
        let records = [5u8, 2, 0, 0, 0, 0, 0, 0, 0, 0xAB, 0xCD];
        let chunk = |crc: u32, records: &[u8], compressed_size: u64| {
            let mut body = vec![0u8; 16];
            body.extend_from_slice(&(records.len() as u64).to_le_bytes());
            body.extend_from_slice(&crc.to_le_bytes());
            body.extend_from_slice(&0u32.to_le_bytes());
            body.extend_from_slice(&compressed_size.to_le_bytes());
            body.extend_from_slice(records);
            body
        };
        let crc = crc32fast::hash(&records);
        let n = records.len() as u64;
        assert!(decode_chunk(&chunk(crc, &records, n), 100, &mut zstd, &mut out).is_some());
        assert_eq!(out, records);
        // No CRC recorded: not checked.
        assert!(decode_chunk(&chunk(0, &records, n), 100, &mut zstd, &mut out).is_some());
        // A CRC that does not match; a record cut short; a size beyond the body; a record
        // longer than the file.
        assert!(decode_chunk(&chunk(crc ^ 1, &records, n), 100, &mut zstd, &mut out).is_none());
        assert!(decode_chunk(&chunk(0, &records[..10], 10), 100, &mut zstd, &mut out).is_none());
        assert!(decode_chunk(&chunk(0, &records, n + 1), 100, &mut zstd, &mut out).is_none());
        let mut long = records;
        long[1..9].copy_from_slice(&200u64.to_le_bytes());
        assert!(decode_chunk(&chunk(0, &long, n), 100, &mut zstd, &mut out).is_none());
        // Not whole: every prefix of the header.
        let whole = chunk(crc, &records, n);
        for cut in 0..40 {
            assert!(decode_chunk(&whole[..cut], 100, &mut zstd, &mut out).is_none());
        }
    }
}
