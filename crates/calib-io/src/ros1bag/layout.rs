//! Where a ROS 1 bag's connections and chunks are: from its index section (the bag header's
//! `index_pos` → the connection records, then a chunk info record per chunk), or, for a bag
//! without a usable index (a recording that did not close, a file cut short), from a scan of
//! its records front to back.

use std::collections::HashSet;
use std::fs::File;
use std::io::{self, BufReader, Read, Seek, SeekFrom};

use super::chunks::{self, Compression, Entry};
use super::records::{Fields, MAGIC, Op};
use crate::limits::{MAX_ROS1_CHUNK_BYTES, MAX_ROS1_HEADER_BYTES, MAX_TOPICS};

/// A connection: a topic as one publisher published it (a topic may have several).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Connection {
    /// Its `conn` ID, which messages name.
    pub(crate) id: u32,
    pub(crate) topic: String,
    /// The message type (`sensor_msgs/JointState`).
    pub(crate) kind: String,
    /// The full message definition (`ros1msg` text).
    pub(crate) definition: Vec<u8>,
}

/// A chunk: where it is and what it holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Chunk {
    /// The chunk record's offset in the file.
    pub(crate) pos: u64,
    /// Its messages' first and last `time`, ns.
    pub(crate) start: u64,
    pub(crate) end: u64,
    /// Messages per connection ID.
    pub(crate) counts: Vec<(u32, u32)>,
    /// The file ends inside it: its records up to the cut are read.
    pub(crate) cut: bool,
}

/// A bag's connections and chunks.
#[derive(Debug, Default)]
pub(crate) struct Layout {
    pub(crate) connections: Vec<Connection>,
    /// In file order.
    pub(crate) chunks: Vec<Chunk>,
    /// What the user should know about how they were found (no index: a scan).
    pub(crate) warnings: Vec<String>,
    /// Where the file is cut short: the offset of its first incomplete record.
    pub(crate) cut: Option<u64>,
}

/// Why the layout (or a chunk) cannot be read: where, and what is wrong.
#[derive(Debug)]
pub(crate) enum Failure {
    Io(io::Error),
    /// The record at this offset is bad.
    At(u64, String),
}

impl From<io::Error> for Failure {
    fn from(e: io::Error) -> Self {
        Failure::Io(e)
    }
}

/// A top-level record's header, and where its data lies.
struct Head {
    fields: Vec<u8>,
    data_at: u64,
    /// The data's length as the record declares it.
    data_len: u64,
}

impl Head {
    fn fields(&self) -> Fields<'_> {
        Fields::checked(&self.fields)
    }

    fn end(&self) -> u64 {
        self.data_at + self.data_len
    }
}

/// How reading a top-level record's header ended.
enum HeadRead {
    Head(Head),
    /// The file ends inside the record's header or length fields.
    Cut,
}

/// The bytes of the file at `at`, `n` of them (known to lie within it).
fn read_at(file: &mut BufReader<File>, at: u64, n: usize) -> io::Result<Vec<u8>> {
    file.seek(SeekFrom::Start(at))?;
    let mut buf = vec![0; n];
    file.read_exact(&mut buf)?;
    Ok(buf)
}

fn u32_at(file: &mut BufReader<File>, at: u64) -> io::Result<u32> {
    let mut b = [0u8; 4];
    file.seek(SeekFrom::Start(at))?;
    file.read_exact(&mut b)?;
    Ok(u32::from_le_bytes(b))
}

/// The header of the record at `at` of a file of `len` bytes: its length checked against the
/// file and [`MAX_ROS1_HEADER_BYTES`] before it is read, its fields checked.
fn read_head(file: &mut BufReader<File>, at: u64, len: u64) -> Result<HeadRead, Failure> {
    if at + 4 > len {
        return Ok(HeadRead::Cut);
    }
    let header_len = u64::from(u32_at(file, at)?);
    if header_len > MAX_ROS1_HEADER_BYTES as u64 {
        return Err(Failure::At(
            at,
            format!(
                "the record's header claims {header_len} bytes, more than any record of a ROS 1 \
                 bag ({MAX_ROS1_HEADER_BYTES}); the file is damaged here"
            ),
        ));
    }
    if at + 8 + header_len > len {
        return Ok(HeadRead::Cut);
    }
    let fields = read_at(file, at + 4, header_len as usize)?;
    Fields::parse(&fields).map_err(|m| Failure::At(at, m))?;
    let data_len = u64::from(u32_at(file, at + 4 + header_len)?);
    Ok(HeadRead::Head(Head {
        fields,
        data_at: at + 8 + header_len,
        data_len,
    }))
}

/// The data of a connection or chunk info record, at most [`MAX_ROS1_HEADER_BYTES`] and
/// within the file.
fn read_small_data(
    file: &mut BufReader<File>,
    head: &Head,
    at: u64,
    len: u64,
) -> Result<Vec<u8>, Failure> {
    if head.data_len > MAX_ROS1_HEADER_BYTES as u64 || head.end() > len {
        return Err(Failure::At(
            at,
            format!(
                "the record claims {} bytes of data, more than {}; the file is damaged here",
                head.data_len,
                if head.end() > len {
                    "the file holds after it"
                } else {
                    "any such record holds"
                }
            ),
        ));
    }
    Ok(read_at(file, head.data_at, head.data_len as usize)?)
}

/// The connection of a connection record (`fields`, `data`).
pub(crate) fn connection(fields: Fields<'_>, data: &[u8]) -> Result<Connection, String> {
    let id = fields.u32("conn")?;
    let topic = fields.text("topic")?.to_string();
    let more = Fields::parse(data).map_err(|m| format!("connection {id}'s data: {m}"))?;
    let kind = more
        .text("type")
        .map_err(|m| format!("connection {id} (`{topic}`): {m}"))?
        .to_string();
    let definition = more.get("message_definition").unwrap_or_default().to_vec();
    Ok(Connection {
        id,
        topic,
        kind,
        definition,
    })
}

/// The bag file's layout, from its index where it has a usable one, else from a scan (with a
/// warning saying why). `path` as messages show it.
pub(crate) fn read(file: &mut BufReader<File>, len: u64, path: &str) -> Result<Layout, Failure> {
    let mut magic = Vec::with_capacity(MAGIC.len());
    (&mut *file)
        .take(MAGIC.len() as u64)
        .read_to_end(&mut magic)?;
    if magic != MAGIC {
        return Err(Failure::At(0, not_v2(&magic)));
    }
    let at = MAGIC.len() as u64;
    let head = match read_head(file, at, len)? {
        HeadRead::Head(head) => head,
        HeadRead::Cut => {
            return Err(Failure::At(
                at,
                "the file ends inside the bag header record, before any chunk; copy the file \
                 again or record again"
                    .into(),
            ));
        }
    };
    let (index_pos, conn_count, chunk_count) =
        bag_header(head.fields()).map_err(|m| Failure::At(at, m))?;
    let first = head.end();
    let why_scan = if index_pos == 0 {
        "its bag header gives no index (index_pos 0: a recording that did not close)".to_string()
    } else if index_pos >= len || index_pos < first {
        format!(
            "its bag header places the index at byte {index_pos}, outside the file's records \
             ({first} to {len}): a file cut short, or a recording that did not close"
        )
    } else {
        match read_index(file, len, index_pos, first, (conn_count, chunk_count)) {
            Ok(layout) => return Ok(layout),
            Err(Failure::Io(e)) => return Err(Failure::Io(e)),
            Err(Failure::At(at, m)) => format!("its index is damaged at byte {at} ({m})"),
        }
    };
    let mut layout = scan(file, len, first)?;
    layout.warnings.push(format!(
        "{path}: {why_scan}; the {} chunk(s) were found by reading the whole file first, and \
         their messages are read in time order chunk by chunk (`rosbag reindex` writes the \
         index back)",
        layout.chunks.len()
    ));
    Ok(layout)
}

/// `index_pos`, `conn_count` and `chunk_count` of the bag header record's `fields`.
fn bag_header(fields: Fields<'_>) -> Result<(u64, u32, u32), String> {
    let op = fields.op()?;
    if op != Op::BagHeader {
        return Err(format!(
            "the first record is a {} record, not the bag header",
            op.name()
        ));
    }
    Ok((
        fields.u64("index_pos")?,
        fields.u32("conn_count")?,
        fields.u32("chunk_count")?,
    ))
}

/// What to say of a file that does not start with the magic of a format 2.0 bag.
fn not_v2(head: &[u8]) -> String {
    if head.starts_with(super::records::MAGIC_PREFIX) {
        let version: String = head[super::records::MAGIC_PREFIX.len()..]
            .iter()
            .take_while(|b| b.is_ascii_graphic())
            .map(|&b| char::from(b))
            .collect();
        return format!(
            "this is a ROS 1 bag of format version {version}; calib reads format 2.0, what \
             ROS 1 has written since 2010: rewrite it with `rosbag filter in.bag out.bag True` \
             (which writes 2.0), or convert it with `mcap convert`"
        );
    }
    format!(
        "not a ROS 1 bag: it does not start with `#ROSBAG V2.0` (it starts with {})",
        crate::limits::shown_bytes(head)
    )
}

/// The layout from the index at `index_pos`: `counts` connections then chunk info records,
/// every chunk within the records (from `first` to `index_pos`).
fn read_index(
    file: &mut BufReader<File>,
    len: u64,
    index_pos: u64,
    first: u64,
    (conn_count, chunk_count): (u32, u32),
) -> Result<Layout, Failure> {
    let mut layout = Layout::default();
    let mut at = index_pos;
    while at < len {
        let head = match read_head(file, at, len)? {
            HeadRead::Head(head) => head,
            HeadRead::Cut => return Err(Failure::At(at, "the record is cut short".into())),
        };
        let fields = head.fields();
        let data = read_small_data(file, &head, at, len)?;
        let bad = |m: String| Failure::At(at, m);
        match fields.op().map_err(bad)? {
            Op::Connection => {
                if layout.connections.len() >= MAX_TOPICS {
                    return Err(bad(too_many_connections()));
                }
                layout
                    .connections
                    .push(connection(fields, &data).map_err(bad)?);
            }
            Op::ChunkInfo => {
                let chunk = chunk_info(fields, &data).map_err(bad)?;
                if chunk.pos < first || chunk.pos >= index_pos {
                    return Err(bad(format!(
                        "it places a chunk at byte {}, outside the records ({first} to \
                         {index_pos})",
                        chunk.pos
                    )));
                }
                layout.chunks.push(chunk);
            }
            other => {
                return Err(bad(format!(
                    "a {} record in the index, which holds connections and chunk infos",
                    other.name()
                )));
            }
        }
        at = head.end();
    }
    if layout.connections.len() != conn_count as usize
        || layout.chunks.len() != chunk_count as usize
    {
        return Err(Failure::At(
            index_pos,
            format!(
                "it holds {} connection(s) and {} chunk info(s) where the bag header counts \
                 {conn_count} and {chunk_count}",
                layout.connections.len(),
                layout.chunks.len()
            ),
        ));
    }
    Ok(layout)
}

/// The chunk a chunk info record (`fields`, `data`) describes.
fn chunk_info(fields: Fields<'_>, data: &[u8]) -> Result<Chunk, String> {
    let ver = fields.u32("ver")?;
    if ver != 1 {
        return Err(format!("the chunk info's version is {ver}, not 1"));
    }
    let count = fields.u32("count")? as usize;
    if data.len() != count.saturating_mul(8) {
        return Err(format!(
            "the chunk info counts {count} connections in {} bytes (8 each)",
            data.len()
        ));
    }
    let counts = data
        .chunks_exact(8)
        .map(|p| {
            (
                u32::from_le_bytes([p[0], p[1], p[2], p[3]]),
                u32::from_le_bytes([p[4], p[5], p[6], p[7]]),
            )
        })
        .collect();
    Ok(Chunk {
        pos: fields.u64("chunk_pos")?,
        start: fields.time("start_time")?,
        end: fields.time("end_time")?,
        counts,
        cut: false,
    })
}

fn too_many_connections() -> String {
    format!(
        "the bag has more than {MAX_TOPICS} connections, more than calib reads; filter the \
         encoders' topics out with `rosbag filter`"
    )
}

/// A chunk read from the file: its decompressed bytes and message entries in time order.
#[derive(Default)]
pub(crate) struct Loaded {
    pub(crate) buf: Vec<u8>,
    pub(crate) entries: Vec<Entry>,
}

/// Reads the chunk record at `pos` into `into` (its buffers reused), handing each connection
/// record inside to `connection`; whether the file ends inside it (then its records up to
/// the cut are read).
pub(crate) fn load_chunk(
    file: &mut BufReader<File>,
    len: u64,
    pos: u64,
    into: &mut Loaded,
    connection: impl FnMut(Fields<'_>, &[u8]) -> Result<(), String>,
) -> Result<bool, Failure> {
    let head = match read_head(file, pos, len)? {
        HeadRead::Head(head) => head,
        HeadRead::Cut => {
            into.buf.clear();
            into.entries.clear();
            return Ok(true);
        }
    };
    let fields = head.fields();
    let bad = |m: String| Failure::At(pos, m);
    let op = fields.op().map_err(bad)?;
    if op != Op::Chunk {
        return Err(bad(format!(
            "a {} record where a chunk was expected",
            op.name()
        )));
    }
    let compression = Compression::of(fields.text("compression").map_err(bad)?).map_err(bad)?;
    let size = chunks::declared_size(fields.u32("size").map_err(bad)?).map_err(bad)?;
    if head.data_len > MAX_ROS1_CHUNK_BYTES as u64 {
        return Err(bad(format!(
            "the chunk claims {} bytes of data, more than the {MAX_ROS1_CHUNK_BYTES} calib \
             holds for one chunk; the file is damaged here",
            head.data_len
        )));
    }
    let cut = head.end() > len;
    file.seek(SeekFrom::Start(head.data_at))?;
    let stored = head.data_len.min(len - head.data_at);
    let decompressed =
        chunks::decompress((&mut *file).take(stored), compression, size, &mut into.buf);
    if let Err(m) = decompressed
        && !cut
    {
        return Err(bad(m));
    }
    chunks::entries(&into.buf, !cut, connection, &mut into.entries).map_err(|(at, m)| {
        bad(format!(
            "byte {at} of the chunk's {} decompressed bytes: {m}",
            into.buf.len()
        ))
    })?;
    Ok(cut)
}

/// The layout found by reading every record from `first` on: the connections as the chunks
/// (and any index records) hold them, each chunk's times and counts from its messages.
fn scan(file: &mut BufReader<File>, len: u64, first: u64) -> Result<Layout, Failure> {
    let mut layout = Layout::default();
    let mut known: HashSet<u32> = HashSet::new();
    let mut loaded = Loaded::default();
    let mut at = first;
    while at < len {
        let head = match read_head(file, at, len)? {
            HeadRead::Head(head) => head,
            HeadRead::Cut => {
                layout.cut = Some(at);
                break;
            }
        };
        let fields = head.fields();
        let bad = |m: String| Failure::At(at, m);
        let op = fields.op().map_err(bad)?;
        if op != Op::Chunk {
            let limit = if op == Op::IndexData {
                MAX_ROS1_CHUNK_BYTES
            } else {
                MAX_ROS1_HEADER_BYTES
            };
            if head.data_len > limit as u64 {
                return Err(bad(format!(
                    "the {} record claims {} bytes of data, more than any such record holds \
                     ({limit}); the file is damaged here",
                    op.name(),
                    head.data_len
                )));
            }
            if head.end() > len {
                layout.cut = Some(at);
                break;
            }
        }
        match op {
            Op::Chunk => {
                let mut added = Vec::new();
                let cut = load_chunk(file, len, at, &mut loaded, |f, data| {
                    added.push(connection(f, data)?);
                    Ok(())
                })?;
                for c in added {
                    add_connection(&mut layout, &mut known, c).map_err(bad)?;
                }
                let (Some(first_msg), Some(last_msg)) = (
                    loaded.entries.first().map(|e| e.time),
                    loaded.entries.last().map(|e| e.time),
                ) else {
                    if cut {
                        layout.cut = Some(at);
                        break;
                    }
                    at = head.end();
                    continue;
                };
                let mut counts: Vec<(u32, u32)> = Vec::new();
                for e in &loaded.entries {
                    match counts.iter_mut().find(|(id, _)| *id == e.conn) {
                        Some((_, n)) => *n += 1,
                        None => counts.push((e.conn, 1)),
                    }
                }
                layout.chunks.push(Chunk {
                    pos: at,
                    start: first_msg,
                    end: last_msg,
                    counts,
                    cut,
                });
                if cut {
                    layout.cut = Some(at);
                    break;
                }
            }
            Op::Connection => {
                let data = read_small_data(file, &head, at, len)?;
                let c = connection(fields, &data).map_err(bad)?;
                add_connection(&mut layout, &mut known, c).map_err(bad)?;
            }
            Op::IndexData | Op::ChunkInfo => {}
            other => {
                return Err(bad(format!(
                    "a {} record among the chunks; the file is damaged here",
                    other.name()
                )));
            }
        }
        at = head.end();
    }
    Ok(layout)
}

/// Adds connection `c` unless its ID is known.
fn add_connection(
    layout: &mut Layout,
    known: &mut HashSet<u32>,
    c: Connection,
) -> Result<(), String> {
    if !known.insert(c.id) {
        return Ok(());
    }
    if layout.connections.len() >= MAX_TOPICS {
        return Err(too_many_connections());
    }
    layout.connections.push(c);
    Ok(())
}
